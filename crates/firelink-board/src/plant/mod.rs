//! The physical plant behind a board: per axis a linear current amplifier,
//! a DC motor with friction, a gear train and a load between mechanical
//! stops, a quadrature encoder, a potentiometer (on its own joint or on a
//! joint several axes move) with an electrical range, current sense with
//! seeded noise and the amplifier temperature.
//!
//! Deterministic and driven by time passed in: the plant integrates up to
//! the time it is advanced to, exactly at that time, in spans of at most
//! one step ([`DEFAULT_STEP`], 100 us) that also break wherever an input
//! changes (DAC code, amplifier enable, external torque take effect at the
//! plant's clock, even between steps); `axis` explains the
//! integration. The same calls give the same motion bit for bit.
//! Measurement noise is a pure function of (seed, axis, step index), see
//! [`noise`].
//!
//! ```
//! use firelink_board::plant::{Plant, presets};
//! use firelink_board::time::{SimTime, SimDuration};
//! let mut plant = Plant::new(vec![presets::generic_motor()], 1, SimDuration::from_micros(5));
//! // 0.5 A into the motor for 50 ms.
//! let dac = 0x8000 + (0.5 / firelink_board::plant::QLA_AMPS_PER_BIT) as u16;
//! plant.axis_mut(0).unwrap().set_drive(dac, true);
//! plant.advance_to(SimTime::from_millis(50));
//! assert!(plant.axis(0).unwrap().joint_velocity() > 0.0);
//! assert!(plant.axis(0).unwrap().encoder().count() > 0);
//! ```

mod axis;
pub mod encoder;
pub mod noise;
mod params;
pub mod presets;

use axis::DecayMemo;
pub use axis::{Axis, Integrator};
pub use params::{
    AmplifierParams, AxisParams, CurrentSenseParams, DAC_ZERO, EncoderParams, GravityParams,
    HardStops, LoadParams, MotorParams, POT_FULL_SCALE_VOLTS, PotParams, QLA_AMPS_PER_BIT,
    QLA_FULL_SCALE_AMPS, SpringParams, SwitchParams, ThermalParams,
};

use crate::time::{SimDuration, SimTime};
use noise::{Noise, NoiseChannel, NoiseStream};

/// The default step, the longest span integrated at once: 100 us, the
/// firmware's safety tick. Spans are integrated exactly in the current loop
/// ([`Integrator::Exact`]), which agrees with the semi-implicit integration
/// at [`REFERENCE_STEP`] (the tests say how closely:
/// `tests/integration/plant_accuracy.rs`).
pub const DEFAULT_STEP: SimDuration = SimDuration(100_000_000);

/// The step of the reference integration ([`Integrator::SemiImplicitEuler`]):
/// 5 us, the model's step before the exact integration.
pub const REFERENCE_STEP: SimDuration = SimDuration(5_000_000);

/// All axes of one board, integrated together.
#[derive(Debug, Clone)]
pub struct Plant {
    axes: Vec<Axis>,
    step_ps: u64,
    /// The plant's clock: the latest time it was advanced (or moved) to.
    clock: SimTime,
    /// Per axis: the current-sense and the pot noise streams.
    noise: Vec<(NoiseStream, NoiseStream)>,
    /// The current loop's decays the current check last needed.
    decay: DecayMemo,
}

impl Plant {
    /// A plant with one axis per parameter set, seeded noise and a fixed
    /// grid step (at least 1 ns; [`DEFAULT_STEP`] is a good choice),
    /// integrated [exactly](Integrator::Exact).
    pub fn new(axes: Vec<AxisParams>, seed: u64, step: SimDuration) -> Plant {
        Plant::with_integrator(axes, seed, step, Integrator::Exact)
    }

    /// The same with another integration ([`Integrator::SemiImplicitEuler`]
    /// at [`REFERENCE_STEP`] is the reference).
    pub fn with_integrator(
        axes: Vec<AxisParams>,
        seed: u64,
        step: SimDuration,
        integrator: Integrator,
    ) -> Plant {
        let step_ps = step.0.max(1_000);
        Plant {
            axes: axes
                .iter()
                .map(|p| Axis::new(p, step_ps, integrator))
                .collect(),
            step_ps,
            clock: SimTime::ZERO,
            noise: {
                let noise = Noise::new(seed);
                (0..axes.len())
                    .map(|i| {
                        (
                            noise.stream(i, NoiseChannel::Current),
                            noise.stream(i, NoiseChannel::Pot),
                        )
                    })
                    .collect()
            },
            decay: DecayMemo::new(),
        }
    }

    /// The longest span integrated at once.
    pub fn step(&self) -> SimDuration {
        SimDuration(self.step_ps)
    }

    /// The plant's clock: the latest time it was advanced (or moved) to.
    /// Inputs set now take effect at this instant.
    pub fn time(&self) -> SimTime {
        self.clock
    }

    /// The measurement-noise sample index at the clock: a new sample every
    /// step.
    fn sample(&self) -> u64 {
        self.clock.0 / self.step_ps
    }

    /// The measurement-noise sample index at the clock (what
    /// [`measured_pot`](Self::measured_pot) and
    /// [`measured_current`](Self::measured_current) draw), for their
    /// `_at_sample` forms while the clock stays.
    pub(crate) fn noise_sample(&self) -> u64 {
        self.sample()
    }

    /// Number of axes.
    pub fn len(&self) -> usize {
        self.axes.len()
    }

    /// Whether the plant has no axis.
    pub fn is_empty(&self) -> bool {
        self.axes.is_empty()
    }

    /// One axis.
    pub fn axis(&self, index: usize) -> Option<&Axis> {
        self.axes.get(index)
    }

    /// One axis, to set its inputs (they take effect at the plant's
    /// clock, which the axis is handed first).
    pub fn axis_mut(&mut self, index: usize) -> Option<&mut Axis> {
        let clock = self.clock;
        let axis = self.axes.get_mut(index)?;
        axis.set_clock(clock);
        Some(axis)
    }

    /// All axes.
    pub fn axes(&self) -> &[Axis] {
        &self.axes
    }

    /// Let time pass up to `now` and show every axis's state exactly at
    /// `now`. Going back in time is a no-op.
    pub fn advance_to(&mut self, now: SimTime) {
        self.pass_to(now);
        let clock = self.clock;
        for axis in &mut self.axes {
            axis.set_clock(clock);
            axis.catch_up();
        }
    }

    /// Let time pass up to `now` without looking: inputs set next take
    /// effect at `now` (each axis integrates up to then first), but the axes
    /// show the state they were last integrated to until the next
    /// [`advance_to`](Self::advance_to); [`measured_current`](Self::measured_current)
    /// is exact at `now` regardless. Going back in time is a no-op. (The
    /// axes are handed the clock only when they are lent out to be
    /// changed or integrated: passing time touches none of them.)
    pub fn pass_to(&mut self, now: SimTime) {
        if now > self.clock {
            self.clock = now;
        }
    }

    /// The measured motor current of an axis: true current plus offset
    /// and seeded noise, A (0 for a missing axis).
    pub fn measured_current(&self, index: usize) -> f64 {
        self.measured_current_at_sample(index, self.sample())
    }

    /// [`measured_current`](Self::measured_current) with the noise sample
    /// at the clock, `sample` ([`noise_sample`](Self::noise_sample)),
    /// worked out once for a sample of several axes.
    #[inline]
    pub(crate) fn measured_current_at_sample(&self, index: usize, sample: u64) -> f64 {
        match (self.axes.get(index), self.noise.get(index)) {
            (Some(a), Some((current, _))) => {
                let cs = &a.params().current_sense;
                let n = if cs.noise_amps == 0.0 {
                    0.0
                } else {
                    current.gaussian(sample)
                };
                a.current_at_clock(self.clock) + cs.offset_amps + cs.noise_amps * n
            }
            _ => 0.0,
        }
    }

    /// The measured motor current of an axis without its noise, A, and how
    /// far the noise can take it (the noise's [`noise::MAX_DEVIATE`]
    /// standard deviations): [`measured_current`](Self::measured_current)
    /// is within that of it. (Mutable only to remember the current loop's
    /// decays, which the axes commanded together share, and the axis's
    /// target current, which the span it integrates next needs.)
    pub fn measured_current_range(&mut self, index: usize) -> (f64, f64) {
        let (decay, clock) = (&mut self.decay, self.clock);
        self.axes.get_mut(index).map_or((0.0, 0.0), |a| {
            let current = a.current_at_clock_memo(clock, decay);
            let cs = &a.params().current_sense;
            (current + cs.offset_amps, cs.noise_amps * noise::MAX_DEVIATE)
        })
    }

    /// The position the potentiometer of an axis measures: its own joint,
    /// or the weighted positions of the axes it is coupled to
    /// ([`PotParams::measures`]); joint units.
    pub fn pot_position(&self, index: usize) -> f64 {
        let Some(a) = self.axes.get(index) else {
            return 0.0;
        };
        let terms = &a.params().pot.measures;
        if terms.is_empty() {
            return a.joint_position();
        }
        terms
            .iter()
            .map(|&(k, w)| w * self.axes.get(k).map_or(0.0, Axis::joint_position))
            .sum()
    }

    /// The potentiometer voltage of an axis without noise: the wiper at
    /// [`pot_position`](Self::pot_position), held at the ends of its
    /// electrical range, V.
    pub fn pot_voltage(&self, index: usize) -> f64 {
        self.axes
            .get(index)
            .map_or(0.0, |a| a.params().pot_volts_at(self.pot_position(index)))
    }

    /// The measured potentiometer voltage of an axis, with seeded noise,
    /// clamped to the ADC range, V.
    pub fn measured_pot(&self, index: usize) -> f64 {
        self.measured_pot_at_sample(index, self.sample())
    }

    /// [`measured_pot`](Self::measured_pot) with the noise sample at the
    /// clock, `sample` ([`noise_sample`](Self::noise_sample)), worked out
    /// once for a sample of several axes.
    pub(crate) fn measured_pot_at_sample(&self, index: usize, sample: u64) -> f64 {
        match (self.axes.get(index), self.noise.get(index)) {
            (Some(a), Some((_, pot))) => {
                let sd = a.params().pot.noise_volts;
                let n = if sd == 0.0 { 0.0 } else { pot.gaussian(sample) };
                (self.pot_voltage(index) + sd * n).clamp(0.0, POT_FULL_SCALE_VOLTS)
            }
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A motor that cannot turn (huge dry friction): no back-EMF.
    fn locked() -> AxisParams {
        let mut p = presets::generic_motor();
        p.motor.coulomb_friction = 1.0e3;
        p
    }

    fn amps_to_dac(amps: f64) -> u16 {
        (f64::from(DAC_ZERO) + amps / QLA_AMPS_PER_BIT)
            .round()
            .clamp(0.0, 65535.0) as u16
    }

    #[test]
    fn split_calls_change_the_motion_only_in_the_last_digits() {
        // One call for 20 ms against a call every 37 us: the current loop
        // is exact whatever the spans; only the terms held over a span
        // (here the supply's headroom at speed) see where they break.
        let mut a = Plant::new(vec![presets::generic_motor()], 3, DEFAULT_STEP);
        let mut b = a.clone();
        a.axis_mut(0).unwrap().set_drive(amps_to_dac(0.3), true);
        b.axis_mut(0).unwrap().set_drive(amps_to_dac(0.3), true);
        a.advance_to(SimTime::from_millis(20));
        for us in (0..=20_000).step_by(37) {
            b.advance_to(SimTime::from_micros(us));
        }
        b.advance_to(SimTime::from_millis(20));
        let (x, y) = (a.axis(0).unwrap(), b.axis(0).unwrap());
        let angle = x.motor_angle();
        assert!(angle > 0.1, "{angle}");
        assert!((angle - y.motor_angle()).abs() <= 1e-4 * angle);
        assert!(x.encoder().count().abs_diff(y.encoder().count()) <= 1);
        assert!((x.motor_velocity() - y.motor_velocity()).abs() <= 1e-4 * x.motor_velocity());
        assert!((a.measured_current(0) - b.measured_current(0)).abs() <= 1e-6);
        let (fa, fb) = (
            x.encoder().fields(SimTime::from_millis(20)),
            y.encoder().fields(SimTime::from_millis(20)),
        );
        assert!(fa.period.clocks.abs_diff(fb.period.clocks) <= fa.period.clocks / 1000 + 2);
        // The same calls give the same motion, bit for bit.
        let mut c = Plant::new(vec![presets::generic_motor()], 3, DEFAULT_STEP);
        c.axis_mut(0).unwrap().set_drive(amps_to_dac(0.3), true);
        for us in (0..=20_000).step_by(37) {
            c.advance_to(SimTime::from_micros(us));
        }
        c.advance_to(SimTime::from_millis(20));
        assert_eq!(c.axis(0).unwrap().motor_angle(), y.motor_angle());
        assert_eq!(c.measured_current(0), b.measured_current(0));
    }

    #[test]
    fn current_follows_command_with_bandwidth() {
        let mut p = Plant::new(vec![locked()], 0, DEFAULT_STEP);
        p.axis_mut(0).unwrap().set_drive(amps_to_dac(1.0), true);
        let bw = p.axis(0).unwrap().params().amplifier.bandwidth_hz;
        let tau = 1.0 / (2.0 * core::f64::consts::PI * bw);
        p.advance_to(SimTime((tau * 1e12) as u64));
        let i = p.axis(0).unwrap().current();
        // One time constant: 63 %.
        assert!((i - 0.632).abs() < 0.05, "{i}");
        p.advance_to(SimTime::from_millis(5));
        assert!((p.axis(0).unwrap().current() - 1.0).abs() < 1e-3);
        // Disabled: decays to zero.
        p.axis_mut(0).unwrap().set_drive(amps_to_dac(1.0), false);
        p.advance_to(SimTime::from_millis(10));
        assert_eq!(p.axis(0).unwrap().current(), 0.0);
    }

    #[test]
    fn constant_torque_accelerates_as_expected() {
        let mut params = presets::generic_motor();
        params.motor.viscous_friction = 0.0;
        params.motor.coulomb_friction = 0.0;
        let mut p = Plant::new(vec![params.clone()], 0, DEFAULT_STEP);
        p.axis_mut(0).unwrap().set_drive(amps_to_dac(0.2), true);
        p.advance_to(SimTime::from_millis(20));
        let axis = p.axis(0).unwrap();
        let j = params.motor_side_inertia();
        let i = axis.current();
        assert!((i - 0.2).abs() < 0.01, "{i}");
        // w ~ kt i t / J (ignoring the 80 us current rise).
        let expected = params.motor.torque_constant * 0.2 * 0.02 / j;
        let w = axis.motor_velocity();
        assert!((w - expected).abs() / expected < 0.02, "{w} vs {expected}");
        // The encoder count agrees with the shaft angle.
        let counts = axis.motor_angle() * axis.counts_per_rad();
        assert_eq!(axis.encoder().count(), counts.floor() as i64);
    }

    #[test]
    fn stiction_holds_small_torques() {
        let mut p = Plant::new(vec![presets::generic_motor()], 0, DEFAULT_STEP);
        let tc = p.axis(0).unwrap().params().motor.coulomb_friction;
        let kt = p.axis(0).unwrap().params().motor.torque_constant;
        p.axis_mut(0)
            .unwrap()
            .set_drive(amps_to_dac(0.5 * tc / kt), true);
        p.advance_to(SimTime::from_millis(50));
        assert_eq!(p.axis(0).unwrap().motor_velocity(), 0.0);
        assert_eq!(p.axis(0).unwrap().encoder().count(), 0);
    }

    #[test]
    fn gravity_pulls_an_unpowered_joint_down() {
        let mut params = presets::generic_motor();
        params.load.gravity = Some(GravityParams {
            amplitude: 2.0,
            phase: 0.0,
        });
        params.load.initial_position = 0.5;
        let mut p = Plant::new(vec![params], 0, DEFAULT_STEP);
        p.advance_to(SimTime::from_millis(100));
        assert!(p.axis(0).unwrap().joint_position() < 0.5);
    }

    #[test]
    fn temperature_rises_with_current() {
        let mut p = Plant::new(vec![locked()], 0, DEFAULT_STEP);
        p.axis_mut(0).unwrap().set_drive(amps_to_dac(3.0), true);
        let t0 = p.axis(0).unwrap().temperature();
        p.advance_to(SimTime::from_millis(2000));
        assert!(p.axis(0).unwrap().temperature() > t0 + 0.5);
    }

    #[test]
    fn temperature_follows_the_first_order_model() {
        // 1 A held in a stalled motor with the default amplifier: 2.5 W
        // (2 ohm of heat, 0.5 W idle) through 4 K/W, 60 s: after one time
        // constant 25 + 10 (1 - 1/e); the same however the time is split.
        let t = ThermalParams::default();
        let expected = |s: f64| {
            let steady = t.ambient_c + (2.0 * 1.0 + 0.5) * t.thermal_resistance;
            steady + (t.ambient_c - steady) * (-s / t.time_constant).exp()
        };
        let mut a = Plant::new(vec![locked()], 0, DEFAULT_STEP);
        a.axis_mut(0).unwrap().set_drive(amps_to_dac(1.0), true);
        let mut b = a.clone();
        a.advance_to(SimTime::from_millis(60_000));
        for k in 1..=600u64 {
            b.advance_to(SimTime::from_millis(100 * k));
        }
        let (ta, tb) = (
            a.axis(0).unwrap().temperature(),
            b.axis(0).unwrap().temperature(),
        );
        assert!(
            (ta - expected(60.0)).abs() < 0.01,
            "{ta} {}",
            expected(60.0)
        );
        assert!((ta - tb).abs() < 1e-9, "{ta} {tb}");
        // Power off: back towards ambient.
        a.axis_mut(0).unwrap().set_drive(DAC_ZERO, false);
        a.advance_to(SimTime::from_millis(600_000));
        assert!((a.axis(0).unwrap().temperature() - t.ambient_c).abs() < 0.01);
    }

    /// A free-running generic motor with stops at +-0.3 rad.
    fn stopped(gear: f64) -> AxisParams {
        let mut p = presets::generic_motor();
        p.load.gear_ratio = gear;
        p.stops = HardStops::new(-0.3, 0.3);
        p
    }

    #[test]
    fn a_joint_driven_into_a_stop_stalls_there() {
        for gear in [50.0, -50.0] {
            let mut p = Plant::new(vec![stopped(gear)], 0, DEFAULT_STEP);
            // Drive towards negative joint positions whatever the gear sign.
            let amps = -0.8 * gear.signum();
            p.axis_mut(0).unwrap().set_drive(amps_to_dac(amps), true);
            p.advance_to(SimTime::from_millis(300));
            let a = p.axis(0).unwrap();
            assert_eq!(a.joint_position(), -0.3, "gear {gear}");
            assert_eq!(a.motor_velocity(), 0.0);
            assert_eq!(a.at_stop(), Some(false));
            // Stalled: no back-EMF, the full command flows.
            assert!((a.current() - amps).abs() < 1e-3, "{}", a.current());
            let count = a.encoder().count();
            p.advance_to(SimTime::from_millis(400));
            assert_eq!(p.axis(0).unwrap().encoder().count(), count);
            // The encoder agrees with the shaft at the stop.
            let a = p.axis(0).unwrap();
            assert_eq!(
                a.encoder().count(),
                (a.motor_angle() * a.counts_per_rad()).floor() as i64
            );
            // Pulling away moves freely.
            p.axis_mut(0).unwrap().set_drive(amps_to_dac(-amps), true);
            p.advance_to(SimTime::from_millis(450));
            let a = p.axis(0).unwrap();
            assert!(a.joint_position() > -0.3, "gear {gear}");
            assert_eq!(a.at_stop(), None);
            // And stops at the other end.
            p.advance_to(SimTime::from_millis(1200));
            assert_eq!(p.axis(0).unwrap().joint_position(), 0.3);
            assert_eq!(p.axis(0).unwrap().at_stop(), Some(true));
        }
    }

    #[test]
    fn the_pot_follows_the_joint_up_to_its_stops() {
        let mut params = stopped(50.0);
        params.pot.noise_volts = 0.0;
        let mut p = Plant::new(vec![params.clone()], 0, DEFAULT_STEP);
        p.axis_mut(0).unwrap().set_drive(amps_to_dac(-1.0), true);
        for ms in (0..=400).step_by(5) {
            p.advance_to(SimTime::from_millis(ms));
            let q = p.axis(0).unwrap().joint_position();
            let v = p.measured_pot(0);
            let from_pot = (v - params.pot.offset_volts) / params.pot.volts_per_unit;
            assert!((from_pot - q).abs() < 1e-12, "{from_pot} vs {q}");
        }
        // The wiper stays at its electrical end beyond it.
        let mut narrow = params;
        narrow.pot.electrical_range = (2.0, 2.4);
        assert_eq!(narrow.pot_volts_at(-10.0), 2.0);
        assert_eq!(narrow.pot_volts_at(10.0), 2.4);
        let (lo, hi) = narrow.pot_position_range().unwrap();
        assert!((narrow.pot_volts_at(lo) - 2.0).abs() < 1e-12);
        assert!((narrow.pot_volts_at(hi) - 2.4).abs() < 1e-12);
    }

    #[test]
    fn a_pot_can_measure_a_coupled_joint() {
        let mut a = presets::generic_motor();
        a.load.initial_position = 0.2;
        let mut b = presets::generic_motor();
        b.load.initial_position = 0.5;
        // Axis 1's pot measures joint = q1 - q0 (an MTM elbow).
        b.pot.measures = vec![(1, 1.0), (0, -1.0), (9, 2.0)];
        b.pot.noise_volts = 0.0;
        let p = Plant::new(vec![a, b.clone()], 0, DEFAULT_STEP);
        assert!((p.pot_position(1) - 0.3).abs() < 1e-12);
        assert!((p.pot_position(0) - 0.2).abs() < 1e-12);
        let v = b.pot.offset_volts + b.pot.volts_per_unit * 0.3;
        assert!((p.measured_pot(1) - v).abs() < 1e-12);
    }

    #[test]
    fn resting_on_a_stop_under_gravity_is_quiescent() {
        let mut params = stopped(50.0);
        // A constant load pulling the joint down (a weight on a slope).
        params.load.bias = -2.0;
        params.load.initial_position = 0.1;
        let mut p = Plant::new(vec![params], 0, DEFAULT_STEP);
        p.advance_to(SimTime::from_millis(2000));
        let a = p.axis(0).unwrap();
        assert_eq!(a.joint_position(), -0.3);
        assert_eq!(a.motor_velocity(), 0.0);
        assert!(a.is_quiescent());
    }

    #[test]
    fn stops_are_sanitized_and_hold_the_initial_position() {
        let mut params = presets::generic_motor();
        params.stops = HardStops::new(0.5, -0.5);
        assert_eq!(params.sanitized().stops, HardStops::default());
        params.stops = HardStops {
            lower: Some(f64::NAN),
            upper: Some(0.1),
        };
        params.load.initial_position = 0.7;
        let s = params.sanitized();
        assert_eq!(s.stops.lower, None);
        assert_eq!(s.load.initial_position, 0.1);
    }

    #[test]
    fn noise_is_seeded() {
        let a = Plant::new(vec![presets::generic_motor()], 11, DEFAULT_STEP);
        let b = Plant::new(vec![presets::generic_motor()], 11, DEFAULT_STEP);
        let c = Plant::new(vec![presets::generic_motor()], 12, DEFAULT_STEP);
        assert_eq!(a.measured_current(0), b.measured_current(0));
        assert_ne!(a.measured_current(0), c.measured_current(0));
        assert_eq!(a.measured_current(5), 0.0);
    }
}
