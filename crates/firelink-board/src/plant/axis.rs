//! One axis: amplifier, motor, transmission and load, integrated with a
//! fixed step; the encoder and temperature follow the motion.
//!
//! Integration per sub-step `h` (semi-implicit, unconditionally stable for
//! the stiff parts):
//! 1. Current: the commanded current (DAC code, current limit, and what
//!    the supply voltage can push against resistance and back-EMF) is
//!    approached with the exact first-order response of the current loop,
//!    `i += (i_cmd - i) (1 - exp(-2 pi f_bw h))`. A disabled amplifier
//!    commands zero current.
//! 2. Velocity: motor torque `kt i`, the joint load reflected through the
//!    gear ratio, Coulomb friction with stiction (at rest, the motor stays
//!    at rest while the driving torque does not exceed the friction) and
//!    viscous friction treated implicitly. Friction never reverses the
//!    motion within a step: a velocity crossing zero stops.
//! 3. Position from the new velocity, held inside the mechanical stops:
//!    a joint that reaches a stop stays there with zero velocity (an
//!    inelastic, rigid stop) while the drive pushes into it, and leaves it
//!    freely when the drive pulls away; the encoder records the edges
//!    crossed with interpolated times.
//! 4. Temperature: exact first-order response to the dissipated power.

use core::f64::consts::PI;

use super::encoder::Encoder;
use super::params::{AxisParams, DAC_ZERO};
use crate::time::SimTime;

/// Current below which the amplifier is considered to carry none, A.
const CURRENT_EPSILON: f64 = 1e-9;

/// State and parameters of one axis.
#[derive(Debug, Clone)]
pub struct Axis {
    params: AxisParams,
    /// Precomputed per-step factors.
    alpha_current: f64,
    alpha_thermal: f64,
    inertia: f64,
    counts_per_rad: f64,
    /// The mechanical stops as motor angles (lower, upper), rad.
    motor_stops: (f64, f64),
    // Inputs.
    dac: u16,
    enabled: bool,
    external_torque: f64,
    // State.
    current: f64,
    motor_angle: f64,
    motor_velocity: f64,
    temperature: f64,
    encoder: Encoder,
}

impl Axis {
    /// An axis at rest at its initial position, amplifier off, at ambient
    /// temperature; `step_s` is the integration step in seconds.
    pub fn new(params: &AxisParams, step_s: f64) -> Axis {
        let params = params.sanitized();
        let counts_per_rad = {
            let sign = if params.encoder.reversed { -1.0 } else { 1.0 };
            sign * f64::from(params.encoder.counts_per_rev) / (2.0 * PI)
        };
        let motor_angle = params.load.initial_position * params.load.gear_ratio;
        let encoder = Encoder::new(params.encoder.counts_per_rev, motor_angle * counts_per_rad);
        let motor_stops = {
            let n = params.load.gear_ratio;
            let from_lower = params.stops.lower.map(|l| l * n);
            let from_upper = params.stops.upper.map(|u| u * n);
            // A negative gear ratio swaps which motor angle is the lower stop.
            let (lo, hi) = if n > 0.0 {
                (from_lower, from_upper)
            } else {
                (from_upper, from_lower)
            };
            (lo.unwrap_or(f64::NEG_INFINITY), hi.unwrap_or(f64::INFINITY))
        };
        Axis {
            alpha_current: 1.0 - (-2.0 * PI * params.amplifier.bandwidth_hz * step_s).exp(),
            alpha_thermal: 1.0 - (-step_s / params.thermal.time_constant).exp(),
            inertia: params.motor_side_inertia(),
            counts_per_rad,
            motor_stops,
            dac: DAC_ZERO,
            enabled: false,
            external_torque: 0.0,
            current: 0.0,
            motor_angle,
            motor_velocity: 0.0,
            temperature: params.thermal.ambient_c,
            encoder,
            params,
        }
    }

    /// The (sanitized) parameters.
    pub fn params(&self) -> &AxisParams {
        &self.params
    }

    /// Set the amplifier inputs: DAC code and whether it is enabled.
    pub fn set_drive(&mut self, dac: u16, enabled: bool) {
        self.dac = dac;
        self.enabled = enabled;
    }

    /// An external torque (force) applied at the joint, e.g. a hand
    /// pushing the arm; joint units.
    pub fn set_external_torque(&mut self, torque: f64) {
        self.external_torque = if torque.is_finite() { torque } else { 0.0 };
    }

    /// The DAC code currently applied.
    pub fn dac(&self) -> u16 {
        self.dac
    }

    /// Whether the amplifier is enabled.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// The current the DAC code commands (before limits), A.
    pub fn commanded_current(&self) -> f64 {
        (f64::from(self.dac) - f64::from(self.params.amplifier.zero_code))
            * self.params.amplifier.amps_per_bit
    }

    /// The true motor current, A.
    pub fn current(&self) -> f64 {
        self.current
    }

    /// Motor shaft angle, rad.
    pub fn motor_angle(&self) -> f64 {
        self.motor_angle
    }

    /// Motor shaft velocity, rad/s.
    pub fn motor_velocity(&self) -> f64 {
        self.motor_velocity
    }

    /// Joint position, joint units.
    pub fn joint_position(&self) -> f64 {
        self.motor_angle / self.params.load.gear_ratio
    }

    /// Joint velocity, joint units per second.
    pub fn joint_velocity(&self) -> f64 {
        self.motor_velocity / self.params.load.gear_ratio
    }

    /// Amplifier temperature, deg C.
    pub fn temperature(&self) -> f64 {
        self.temperature
    }

    /// The encoder.
    pub fn encoder(&self) -> &Encoder {
        &self.encoder
    }

    /// The potentiometer voltage without noise when the pot measures this
    /// joint: linear in the position, held at the ends of its electrical
    /// range (see [`AxisParams::pot_volts_at`]).
    pub fn pot_voltage(&self) -> f64 {
        self.params.pot_volts_at(self.joint_position())
    }

    /// Which mechanical stop the joint rests against, if any: `Some(false)`
    /// the lower, `Some(true)` the upper.
    pub fn at_stop(&self) -> Option<bool> {
        if self.motor_angle <= self.motor_stops.0 {
            Some(self.params.load.gear_ratio < 0.0)
        } else if self.motor_angle >= self.motor_stops.1 {
            Some(self.params.load.gear_ratio > 0.0)
        } else {
            None
        }
    }

    /// (negative limit, positive limit, home) switch states.
    pub fn switches(&self) -> (bool, bool, bool) {
        let q = self.joint_position();
        let s = &self.params.switches;
        (
            s.negative_limit.is_some_and(|l| q <= l),
            s.positive_limit.is_some_and(|l| q >= l),
            s.home.is_some_and(|h| q >= h),
        )
    }

    /// Joint load torque (gravity, spring, bias, external), joint units.
    fn load_torque(&self) -> f64 {
        let q = self.joint_position();
        let load = &self.params.load;
        let gravity = load
            .gravity
            .as_ref()
            .map_or(0.0, |g| -g.amplitude * (q + g.phase).sin());
        let spring = load
            .spring
            .as_ref()
            .map_or(0.0, |s| -s.stiffness * (q - s.rest));
        gravity + spring + load.bias + self.external_torque
    }

    fn target_current(&self) -> f64 {
        if !self.enabled || !self.params.has_motor {
            return 0.0;
        }
        let amp = &self.params.amplifier;
        let motor = &self.params.motor;
        let mut i = self
            .commanded_current()
            .clamp(-amp.current_limit, amp.current_limit);
        // Voltage headroom: R i + ke w must stay within the supply.
        let emf = motor.torque_constant * self.motor_velocity;
        let v = motor.resistance * i + emf;
        if v > amp.supply_voltage {
            i = (amp.supply_voltage - emf) / motor.resistance;
        } else if v < -amp.supply_voltage {
            i = (-amp.supply_voltage - emf) / motor.resistance;
        }
        i
    }

    /// Whether a step would change nothing but the temperature: at rest,
    /// no current, and the load either held by friction or pressing the
    /// joint into the stop it rests against.
    pub(crate) fn is_quiescent(&self) -> bool {
        if self.current != 0.0 || self.motor_velocity != 0.0 || self.target_current() != 0.0 {
            return false;
        }
        let push = self.load_torque() / self.params.load.gear_ratio;
        push.abs() <= self.params.motor.coulomb_friction
            || (push < 0.0 && self.motor_angle <= self.motor_stops.0)
            || (push > 0.0 && self.motor_angle >= self.motor_stops.1)
    }

    /// Advance `steps` sub-steps of `step_ps` picoseconds starting at
    /// `start` (the grid time of the first step).
    pub(crate) fn advance(&mut self, start: SimTime, step_ps: u64, steps: u64) {
        let h = step_ps as f64 * 1e-12;
        let mut t = start;
        for k in 0..steps {
            if self.is_quiescent() {
                self.settle_temperature(steps - k);
                return;
            }
            self.step(t, step_ps, h);
            t = SimTime(t.0.saturating_add(step_ps));
        }
    }

    fn step(&mut self, start: SimTime, step_ps: u64, h: f64) {
        // 1. Current loop.
        let target = self.target_current();
        self.current += (target - self.current) * self.alpha_current;
        if self.current.abs() < CURRENT_EPSILON && target == 0.0 {
            self.current = 0.0;
        }
        // 2. Velocity.
        let motor = &self.params.motor;
        let drive =
            motor.torque_constant * self.current + self.load_torque() / self.params.load.gear_ratio;
        let w = self.motor_velocity;
        let coulomb = motor.coulomb_friction;
        let new_w = if w == 0.0 && drive.abs() <= coulomb {
            0.0
        } else {
            let friction = if w != 0.0 {
                -coulomb * w.signum()
            } else {
                -coulomb * drive.signum()
            };
            let j = self.inertia;
            let candidate =
                (w + h * (drive + friction) / j) / (1.0 + h * motor.viscous_friction / j);
            if w != 0.0 && candidate.signum() != w.signum() {
                0.0
            } else {
                candidate
            }
        };
        self.motor_velocity = if new_w.is_finite() { new_w } else { 0.0 };
        // 3. Position inside the stops, and the encoder.
        let old_angle = self.motor_angle;
        let (lo, hi) = self.motor_stops;
        let angle = self.motor_angle + h * self.motor_velocity;
        if angle <= lo {
            self.motor_angle = lo;
            self.motor_velocity = self.motor_velocity.max(0.0);
        } else if angle >= hi {
            self.motor_angle = hi;
            self.motor_velocity = self.motor_velocity.min(0.0);
        } else {
            self.motor_angle = angle;
        }
        if self.motor_angle != old_angle {
            self.encoder.track(
                old_angle * self.counts_per_rad,
                self.motor_angle * self.counts_per_rad,
                start,
                step_ps,
            );
        }
        // 4. Temperature.
        self.settle_temperature_by(self.alpha_thermal);
    }

    fn steady_temperature(&self) -> f64 {
        let th = &self.params.thermal;
        let power = self.current * self.current * th.heat_resistance
            + if self.enabled { th.idle_power } else { 0.0 };
        th.ambient_c + power * th.thermal_resistance
    }

    fn settle_temperature_by(&mut self, alpha: f64) {
        self.temperature += (self.steady_temperature() - self.temperature) * alpha;
    }

    fn settle_temperature(&mut self, steps: u64) {
        // (1 - alpha)^n = exp(-n h / tau).
        let keep = (1.0 - self.alpha_thermal).powf(steps as f64);
        self.settle_temperature_by(1.0 - keep);
    }

    /// Encoder counts per motor radian (signed by the encoder direction).
    pub fn counts_per_rad(&self) -> f64 {
        self.counts_per_rad
    }
}
