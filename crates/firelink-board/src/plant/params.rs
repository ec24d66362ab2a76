//! Physical parameters of one axis: amplifier, motor, transmission, load
//! and its mechanical stops, encoder, potentiometer, current sense and
//! amplifier temperature.
//!
//! All values are SI at the place named: motor-side quantities at the motor
//! shaft, joint-side quantities at the joint. A joint may be revolute (its
//! unit is the radian) or prismatic (the metre); the gear ratio is always
//! motor radians per joint unit, so the same model serves both.

use core::f64::consts::PI;

/// The QLA's current range: the DAC and the current-sense ADC both span
/// +-6.25 A over 16 bits (`fpga-board.md` section 3, register ADC).
pub const QLA_FULL_SCALE_AMPS: f64 = 6.25;

/// Amperes per DAC or current-ADC count on the QLA: 12.5 A / 65536.
pub const QLA_AMPS_PER_BIT: f64 = 2.0 * QLA_FULL_SCALE_AMPS / 65536.0;

/// The DAC code commanding zero current (`fpga-board.md` section 3).
pub use firelink_wire::qla::registers::DAC_ZERO;

/// Full-scale voltage of the QLA potentiometer ADC (16 bits over 0..4.5 V).
pub const POT_FULL_SCALE_VOLTS: f64 = 4.5;

/// A linear current amplifier: DAC code to commanded current, a current
/// limit and a first-order current-loop bandwidth, limited by the supply.
#[derive(Debug, Clone, PartialEq)]
pub struct AmplifierParams {
    /// Commanded amperes per DAC count away from `zero_code`.
    pub amps_per_bit: f64,
    /// The DAC code at which this amplifier delivers no current: nominally
    /// [`DAC_ZERO`], a few counts off on a real QLA (what a calibrated
    /// configuration's `current_to_bits.offset` records).
    pub zero_code: u16,
    /// Largest current magnitude the amplifier delivers, A.
    pub current_limit: f64,
    /// Closed-loop current bandwidth, Hz (first order).
    pub bandwidth_hz: f64,
    /// Motor supply voltage, V: the current cannot exceed what the supply
    /// can push against the winding resistance and the back-EMF.
    pub supply_voltage: f64,
}

/// A brushed DC motor.
#[derive(Debug, Clone, PartialEq)]
pub struct MotorParams {
    /// Torque constant, N m / A (also the back-EMF constant, V s / rad).
    pub torque_constant: f64,
    /// Terminal resistance, ohm.
    pub resistance: f64,
    /// Rotor inertia, kg m^2.
    pub rotor_inertia: f64,
    /// Viscous friction at the motor shaft, N m s / rad.
    pub viscous_friction: f64,
    /// Coulomb (dry) friction at the motor shaft, N m; also the breakaway
    /// torque (stiction).
    pub coulomb_friction: f64,
}

/// Gravity acting on a revolute joint: `torque = -amplitude * sin(q + phase)`.
#[derive(Debug, Clone, PartialEq)]
pub struct GravityParams {
    /// Peak gravity torque at the joint, N m (or force, N, for a
    /// prismatic joint).
    pub amplitude: f64,
    /// Phase, rad: the joint angle at which gravity is zero is `-phase`.
    pub phase: f64,
}

/// A linear spring at the joint: `torque = -stiffness * (q - rest)`.
#[derive(Debug, Clone, PartialEq)]
pub struct SpringParams {
    /// Stiffness, N m / rad (N / m for a prismatic joint).
    pub stiffness: f64,
    /// Rest position, joint units.
    pub rest: f64,
}

/// What the motor drives through its transmission.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadParams {
    /// Motor radians per joint unit (rad or m). 1 for a direct drive.
    pub gear_ratio: f64,
    /// Inertia at the joint, kg m^2 (mass, kg, for a prismatic joint).
    pub inertia: f64,
    /// Optional gravity load.
    pub gravity: Option<GravityParams>,
    /// Optional spring load.
    pub spring: Option<SpringParams>,
    /// Constant torque (force) at the joint, e.g. gravity on an inclined
    /// prismatic stage.
    pub bias: f64,
    /// Joint position at power-up, joint units.
    pub initial_position: f64,
}

/// The mechanical (hard) stops of a joint, joint units. A joint driven
/// into a stop stops there: the motion into the stop is lost (an
/// inelastic, rigid stop), the motor stalls and its current is whatever
/// the amplifier delivers; motion away from the stop is free.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HardStops {
    /// The joint cannot go below this position.
    pub lower: Option<f64>,
    /// The joint cannot go above this position.
    pub upper: Option<f64>,
}

impl HardStops {
    /// Stops at `lower` and `upper`.
    pub fn new(lower: f64, upper: f64) -> HardStops {
        HardStops {
            lower: Some(lower),
            upper: Some(upper),
        }
    }

    /// `q` moved inside the stops.
    pub fn clamp(&self, q: f64) -> f64 {
        let q = self.lower.map_or(q, |l| q.max(l));
        self.upper.map_or(q, |u| q.min(u))
    }
}

/// An incremental quadrature encoder on the motor shaft.
#[derive(Debug, Clone, PartialEq)]
pub struct EncoderParams {
    /// Quadrature counts per motor revolution (4 x lines).
    pub counts_per_rev: u32,
    /// Count down when the motor turns in its positive direction.
    pub reversed: bool,
}

/// An analog potentiometer: its wiper voltage is linear in the position
/// it measures, `offset_volts + volts_per_unit * position`, between the
/// ends of its electrical range, where it stays.
#[derive(Debug, Clone, PartialEq)]
pub struct PotParams {
    /// Volts per joint unit.
    pub volts_per_unit: f64,
    /// Volts at joint position 0.
    pub offset_volts: f64,
    /// Standard deviation of the reading noise, V.
    pub noise_volts: f64,
    /// The electrical range of the wiper, V (lower end, upper end): past
    /// its ends the voltage stays at the end. At most the ADC's range
    /// (0 to [`POT_FULL_SCALE_VOLTS`]).
    pub electrical_range: (f64, f64),
    /// What the pot measures, as weights of the positions of this board's
    /// axes (axis index, weight): a pot mounted on a joint that several
    /// actuators move (the dVRK MTM's coupled joints). Empty: the pot
    /// measures its own axis.
    pub measures: Vec<(usize, f64)>,
}

/// The amplifier's current-sense channel.
#[derive(Debug, Clone, PartialEq)]
pub struct CurrentSenseParams {
    /// Constant offset of the measured current, A.
    pub offset_amps: f64,
    /// Standard deviation of the measurement noise, A.
    pub noise_amps: f64,
}

/// Amplifier temperature: a first-order thermal model of one amplifier
/// (a QLA channel's linear power op amp on its heat sink). The power it
/// dissipates, `i^2 heat_resistance` plus `idle_power` while enabled,
/// drives its temperature towards `ambient_c + power x
/// thermal_resistance` with time constant `time_constant`, integrated
/// exactly over the time the plant is advanced by (no clock of its own).
/// The board's sensors (one MAX6576 per pair of channels) read the hotter
/// of their two.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalParams {
    /// Ambient temperature, deg C.
    pub ambient_c: f64,
    /// Effective resistance turning current into heat in the amplifier, ohm.
    pub heat_resistance: f64,
    /// Heat dissipated while the amplifier is enabled, W.
    pub idle_power: f64,
    /// Thermal resistance to ambient, K / W.
    pub thermal_resistance: f64,
    /// Thermal time constant, s.
    pub time_constant: f64,
}

/// Limit and home switches, by joint position.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SwitchParams {
    /// The negative limit switch is active at or below this position.
    pub negative_limit: Option<f64>,
    /// The positive limit switch is active at or above this position.
    pub positive_limit: Option<f64>,
    /// The home switch is active at or above this position.
    pub home: Option<f64>,
}

/// Everything about one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisParams {
    /// A short name for traces, e.g. `"PSM J1"`.
    pub name: String,
    /// Whether a motor is connected; without one the amplifier drives no
    /// current (an MTM gripper channel, an unused channel).
    pub has_motor: bool,
    /// The current amplifier.
    pub amplifier: AmplifierParams,
    /// The motor.
    pub motor: MotorParams,
    /// Transmission and load.
    pub load: LoadParams,
    /// The encoder.
    pub encoder: EncoderParams,
    /// The potentiometer.
    pub pot: PotParams,
    /// The current sense.
    pub current_sense: CurrentSenseParams,
    /// The amplifier temperature model.
    pub thermal: ThermalParams,
    /// Limit and home switches.
    pub switches: SwitchParams,
    /// Mechanical stops of the joint.
    pub stops: HardStops,
}

impl Default for AmplifierParams {
    /// The QLA's linear amplifier: +-6.25 A over 16 bits, about 2 kHz, 24 V.
    fn default() -> Self {
        AmplifierParams {
            amps_per_bit: QLA_AMPS_PER_BIT,
            zero_code: DAC_ZERO,
            current_limit: QLA_FULL_SCALE_AMPS,
            bandwidth_hz: 2_000.0,
            supply_voltage: 24.0,
        }
    }
}

impl Default for PotParams {
    /// 1 V per joint unit around the middle of the 0..4.5 V range.
    fn default() -> Self {
        PotParams {
            volts_per_unit: 1.0,
            offset_volts: POT_FULL_SCALE_VOLTS / 2.0,
            noise_volts: 0.0005,
            electrical_range: (0.0, POT_FULL_SCALE_VOLTS),
            measures: Vec::new(),
        }
    }
}

impl Default for CurrentSenseParams {
    /// About 3 ADC counts of noise, no offset.
    fn default() -> Self {
        CurrentSenseParams {
            offset_amps: 0.0,
            noise_amps: 0.0006,
        }
    }
}

impl Default for ThermalParams {
    /// A QLA channel in a ventilated dVRK controller box:
    /// - 25 deg C inside the box (the dVRK's QLA test expects 20 to 40 deg C
    ///   at rest);
    /// - 0.5 W while enabled: the power op amp's quiescent current (some
    ///   20 mA) across the supply;
    /// - 2 ohm: a linear stage drops the supply less the motor's voltage at
    ///   the motor's current; for a stalled or slow dVRK motor on a 12-36 V
    ///   supply that is a few volts per ampere, lumped as a resistance;
    /// - 4 K/W to the air (its share of the heat sink with the box's fan):
    ///   1 A held for minutes warms the amplifier by about 10 K;
    /// - 60 s: the heat sink's time constant.
    fn default() -> Self {
        ThermalParams {
            ambient_c: 25.0,
            heat_resistance: 2.0,
            idle_power: 0.5,
            thermal_resistance: 4.0,
            time_constant: 60.0,
        }
    }
}

impl AxisParams {
    /// A copy with every value made usable: non-finite or negative values
    /// replaced by safe ones, so the integrator never sees NaN or a zero
    /// inertia. Called by the plant on construction.
    pub fn sanitized(&self) -> AxisParams {
        fn pos(v: f64, fallback: f64) -> f64 {
            if v.is_finite() && v > 0.0 {
                v
            } else {
                fallback
            }
        }
        fn non_neg(v: f64) -> f64 {
            if v.is_finite() && v > 0.0 { v } else { 0.0 }
        }
        fn finite(v: f64) -> f64 {
            if v.is_finite() { v } else { 0.0 }
        }
        let mut p = self.clone();
        p.amplifier.amps_per_bit = pos(p.amplifier.amps_per_bit, QLA_AMPS_PER_BIT);
        p.amplifier.current_limit = non_neg(p.amplifier.current_limit);
        p.amplifier.bandwidth_hz = pos(p.amplifier.bandwidth_hz, 2_000.0);
        p.amplifier.supply_voltage = non_neg(p.amplifier.supply_voltage);
        p.motor.torque_constant = non_neg(p.motor.torque_constant);
        p.motor.resistance = pos(p.motor.resistance, 1.0);
        p.motor.rotor_inertia = pos(p.motor.rotor_inertia, 1e-6);
        p.motor.viscous_friction = non_neg(p.motor.viscous_friction);
        p.motor.coulomb_friction = non_neg(p.motor.coulomb_friction);
        p.load.gear_ratio = if p.load.gear_ratio.is_finite() && p.load.gear_ratio != 0.0 {
            p.load.gear_ratio
        } else {
            1.0
        };
        p.load.inertia = non_neg(p.load.inertia);
        if let Some(g) = &mut p.load.gravity {
            g.amplitude = finite(g.amplitude);
            g.phase = finite(g.phase);
        }
        if let Some(s) = &mut p.load.spring {
            s.stiffness = non_neg(s.stiffness);
            s.rest = finite(s.rest);
        }
        p.load.bias = finite(p.load.bias);
        p.load.initial_position = finite(p.load.initial_position);
        p.encoder.counts_per_rev = p.encoder.counts_per_rev.max(4);
        p.pot.volts_per_unit = finite(p.pot.volts_per_unit);
        p.pot.offset_volts = finite(p.pot.offset_volts);
        p.pot.noise_volts = non_neg(p.pot.noise_volts);
        let (lo, hi) = p.pot.electrical_range;
        let lo = if lo.is_finite() {
            lo.clamp(0.0, POT_FULL_SCALE_VOLTS)
        } else {
            0.0
        };
        let hi = if hi.is_finite() {
            hi.clamp(0.0, POT_FULL_SCALE_VOLTS)
        } else {
            POT_FULL_SCALE_VOLTS
        };
        p.pot.electrical_range = if lo < hi {
            (lo, hi)
        } else {
            (0.0, POT_FULL_SCALE_VOLTS)
        };
        p.pot.measures.retain(|(_, w)| w.is_finite() && *w != 0.0);
        p.current_sense.offset_amps = finite(p.current_sense.offset_amps);
        p.current_sense.noise_amps = non_neg(p.current_sense.noise_amps);
        p.thermal.ambient_c = finite(p.thermal.ambient_c);
        p.thermal.heat_resistance = non_neg(p.thermal.heat_resistance);
        p.thermal.idle_power = non_neg(p.thermal.idle_power);
        p.thermal.thermal_resistance = non_neg(p.thermal.thermal_resistance);
        p.thermal.time_constant = pos(p.thermal.time_constant, 60.0);
        for v in [
            &mut p.switches.negative_limit,
            &mut p.switches.positive_limit,
            &mut p.switches.home,
        ] {
            if v.is_some_and(|x| !x.is_finite()) {
                *v = None;
            }
        }
        for v in [&mut p.stops.lower, &mut p.stops.upper] {
            if v.is_some_and(|x| !x.is_finite()) {
                *v = None;
            }
        }
        if let (Some(l), Some(u)) = (p.stops.lower, p.stops.upper) {
            if l >= u {
                p.stops = HardStops::default();
            }
        }
        p.load.initial_position = p.stops.clamp(p.load.initial_position);
        p
    }

    /// Effective inertia seen at the motor shaft, kg m^2.
    pub fn motor_side_inertia(&self) -> f64 {
        let n = self.load.gear_ratio;
        self.motor.rotor_inertia + self.load.inertia / (n * n)
    }

    /// The wiper voltage at joint (or measured) position `q`, before
    /// noise: linear, held at the ends of the electrical range.
    pub fn pot_volts_at(&self, q: f64) -> f64 {
        let (lo, hi) = self.pot.electrical_range;
        let v = self.pot.offset_volts + self.pot.volts_per_unit * q;
        if v.is_nan() { lo } else { v.clamp(lo, hi) }
    }

    /// The positions where the pot reaches the ends of its electrical
    /// range, (lower, upper) in joint units; `None` for a pot that does
    /// not move (zero gain).
    pub fn pot_position_range(&self) -> Option<(f64, f64)> {
        let k = self.pot.volts_per_unit;
        if k == 0.0 || !k.is_finite() {
            return None;
        }
        let (lo, hi) = self.pot.electrical_range;
        let a = (lo - self.pot.offset_volts) / k;
        let b = (hi - self.pot.offset_volts) / k;
        Some((a.min(b), a.max(b)))
    }

    /// Encoder counts per joint unit.
    pub fn counts_per_joint_unit(&self) -> f64 {
        let sign = if self.encoder.reversed { -1.0 } else { 1.0 };
        sign * f64::from(self.encoder.counts_per_rev) * self.load.gear_ratio / (2.0 * PI)
    }
}
