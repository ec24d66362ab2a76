//! Per-joint PID on position, with velocity feedforward and damping, output
//! current limited, anti-windup and an optional deadband.
//!
//! The control law, in SI units with the output in amperes:
//!
//! ```text
//! e  = deadband(setpoint.position - measured.position)
//! u  = kp e + ki ∫e dt + kd (setpoint.velocity - measured.velocity)
//!      + velocity_feedforward · setpoint.velocity + setpoint.feedforward
//! out = clamp(u, ±output_limit)
//! ```
//!
//! The derivative acts on the velocity error, not on the derivative of the
//! position error: no kick on setpoint steps, and pure damping when the
//! setpoint is still. Anti-windup is twofold: the integral term `ki ∫e dt`
//! never exceeds `integral_limit` amperes (clamping), and while the output is
//! saturated the integral is not advanced in the direction that deepens the
//! saturation (conditional integration).
//!
//! [`Pid::update`] takes the time step as an argument, never reads a clock
//! and never allocates. Bad input (NaN or infinite values, a negative or
//! non-finite `dt`) gives 0 A, leaves the integral untouched and sets
//! [`PidStatus::InvalidInput`] so the safety chain can react.

use serde::{Deserialize, Serialize};

/// PID gains. Position in rad (or m), current in A.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PidGains {
    /// Proportional gain, A/rad.
    pub kp: f64,
    /// Integral gain, A/(rad s).
    #[serde(default)]
    pub ki: f64,
    /// Derivative (damping) gain on the velocity error, A/(rad/s).
    #[serde(default)]
    pub kd: f64,
    /// Feedforward of the setpoint velocity, A/(rad/s) (e.g. viscous
    /// friction compensation).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub velocity_feedforward: f64,
    /// Largest |integral term|, amperes; the output limit when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integral_limit: Option<f64>,
    /// Position errors smaller than this are treated as zero, and larger ones
    /// are reduced by it (continuous, no jump at the edge).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub deadband: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl PidGains {
    /// Plain PD gains (no integral, no feedforward, no deadband).
    pub fn pd(kp: f64, kd: f64) -> PidGains {
        PidGains {
            kp,
            ki: 0.0,
            kd,
            velocity_feedforward: 0.0,
            integral_limit: None,
            deadband: 0.0,
        }
    }

    /// PID gains (no feedforward, no deadband, integral limited by the
    /// output limit).
    pub fn pid(kp: f64, ki: f64, kd: f64) -> PidGains {
        PidGains {
            ki,
            ..PidGains::pd(kp, kd)
        }
    }

    /// Checks that every gain is finite and non-negative.
    ///
    /// # Errors
    /// The first offending field.
    pub fn check(&self) -> Result<(), PidError> {
        let fields = [
            ("kp", self.kp),
            ("ki", self.ki),
            ("kd", self.kd),
            ("velocity_feedforward", self.velocity_feedforward),
            ("deadband", self.deadband),
            ("integral_limit", self.integral_limit.unwrap_or(0.0)),
        ];
        for (field, value) in fields {
            if !(value.is_finite() && value >= 0.0) {
                return Err(PidError { field, value });
            }
        }
        Ok(())
    }
}

/// A gain or limit that is negative, NaN or infinite.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("PID {field} = {} must be finite and >= 0", firelink_wire::human::Number(*value))]
pub struct PidError {
    /// The field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
}

/// Where the joint should be this cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Setpoint {
    /// Position, rad or m.
    pub position: f64,
    /// Velocity, rad/s or m/s.
    pub velocity: f64,
    /// Current added to the output (gravity, inertia or friction
    /// compensation computed elsewhere), A.
    pub feedforward: f64,
}

impl Setpoint {
    /// Hold still at `position`.
    pub fn hold(position: f64) -> Setpoint {
        Setpoint {
            position,
            velocity: 0.0,
            feedforward: 0.0,
        }
    }
}

/// What the joint is doing this cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measurement {
    /// Position, rad or m.
    pub position: f64,
    /// Velocity, rad/s or m/s.
    pub velocity: f64,
}

/// Outcome of the last [`Pid::update`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PidStatus {
    /// The output was within the limit.
    #[default]
    Ok,
    /// The unclamped output exceeded the limit and was clamped.
    Saturated,
    /// An input was NaN/infinite or `dt` was invalid: the output was 0 A.
    InvalidInput,
}

/// One joint's PID controller.
#[derive(Debug, Clone, PartialEq)]
pub struct Pid {
    gains: PidGains,
    output_limit: f64,
    /// ∫e dt, rad s.
    integral: f64,
    /// Largest |∫e dt| (`integral_bound`), worked out when the
    /// gains are set rather than divided out every cycle.
    bound: f64,
    status: PidStatus,
}

impl Pid {
    /// A controller with `gains` whose output never exceeds
    /// `±output_limit` amperes (normally the drive's `maximum_current`).
    ///
    /// # Errors
    /// A gain or the limit is negative, NaN or infinite.
    pub fn new(gains: PidGains, output_limit: f64) -> Result<Pid, PidError> {
        gains.check()?;
        if !(output_limit.is_finite() && output_limit >= 0.0) {
            return Err(PidError {
                field: "output_limit",
                value: output_limit,
            });
        }
        let mut pid = Pid {
            gains,
            output_limit,
            integral: 0.0,
            bound: 0.0,
            status: PidStatus::Ok,
        };
        pid.bound = pid.integral_bound();
        Ok(pid)
    }

    /// The gains.
    pub fn gains(&self) -> &PidGains {
        &self.gains
    }

    /// Replaces the gains, keeping the integral state (bumpless only if `ki`
    /// is unchanged).
    ///
    /// # Errors
    /// A gain is negative, NaN or infinite; the old gains stay.
    pub fn set_gains(&mut self, gains: PidGains) -> Result<(), PidError> {
        gains.check()?;
        self.gains = gains;
        self.bound = self.integral_bound();
        self.integral = self.integral.clamp(-self.bound, self.bound);
        Ok(())
    }

    /// The output limit, amperes.
    pub fn output_limit(&self) -> f64 {
        self.output_limit
    }

    /// Forgets the integral and the status (call when the joint is enabled
    /// or a new motion starts from rest).
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.status = PidStatus::Ok;
    }

    /// Status of the last update.
    pub fn status(&self) -> PidStatus {
        self.status
    }

    /// Current contributed by the integral, amperes.
    pub fn integral_term(&self) -> f64 {
        self.gains.ki * self.integral
    }

    /// Largest |integral term|, amperes.
    fn integral_current_limit(&self) -> f64 {
        self.gains
            .integral_limit
            .map_or(self.output_limit, |l| l.min(self.output_limit))
    }

    /// Largest |∫e dt| that keeps the integral term within its limit.
    fn integral_bound(&self) -> f64 {
        if self.gains.ki > 0.0 {
            self.integral_current_limit() / self.gains.ki
        } else {
            0.0
        }
    }

    fn deadband(&self, e: f64) -> f64 {
        let db = self.gains.deadband;
        if db > 0.0 {
            e.signum() * (e.abs() - db).max(0.0)
        } else {
            e
        }
    }

    /// One control step over `dt` seconds: the current command, amperes,
    /// always finite and within `±output_limit`. (Inlined into the servo
    /// cycle's loop over the joints.)
    #[inline(always)]
    pub fn update(&mut self, setpoint: Setpoint, measured: Measurement, dt: f64) -> f64 {
        // Every input finite, all at once: `x * 0` is ±0 for a finite `x`
        // and NaN for an infinite or NaN one, and NaN spreads.
        let probe = (setpoint.position * 0.0 + setpoint.velocity * 0.0)
            + (setpoint.feedforward * 0.0 + measured.position * 0.0)
            + (measured.velocity * 0.0 + dt * 0.0);
        let inputs_ok = probe == 0.0 && dt >= 0.0;
        if !inputs_ok {
            self.status = PidStatus::InvalidInput;
            return 0.0;
        }
        let g = &self.gains;
        let e = self.deadband(setpoint.position - measured.position);
        let base = g.kp * e
            + g.kd * (setpoint.velocity - measured.velocity)
            + g.velocity_feedforward * setpoint.velocity
            + setpoint.feedforward;
        if base.is_nan() {
            // Finite inputs so large that inf - inf appeared.
            self.status = PidStatus::InvalidInput;
            return 0.0;
        }
        let bound = self.bound;
        let candidate = within(self.integral + e * dt, -bound, bound);
        let limit = self.output_limit;
        let with_candidate = base + g.ki * candidate;
        let pushes_deeper = with_candidate.abs() > limit
            && (candidate - self.integral).signum() == with_candidate.signum();
        if candidate.is_finite() && !pushes_deeper {
            self.integral = candidate;
        }
        let u = base + g.ki * self.integral;
        self.status = if u.abs() > limit {
            PidStatus::Saturated
        } else {
            PidStatus::Ok
        };
        within(u, -limit, limit)
    }
}

/// `x` limited to `[lo, hi]` (NaN stays NaN): [`f64::clamp`] for bounds
/// known to be in order (the controller's are, from construction), without
/// its check of them on every call of the servo cycle.
#[inline(always)]
fn within(x: f64, lo: f64, hi: f64) -> f64 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::PointToPoint;
    use proptest::prelude::*;

    /// A rigid joint: J a = kt i - b v + load, integrated in virtual time
    /// with 10 sub-steps per servo cycle.
    struct Joint {
        pos: f64,
        vel: f64,
        inertia: f64,
        kt: f64,
        damping: f64,
        load: f64,
    }

    impl Joint {
        fn step(&mut self, current: f64, dt: f64) {
            let h = dt / 10.0;
            for _ in 0..10 {
                let acc = (self.kt * current - self.damping * self.vel + self.load) / self.inertia;
                self.vel += acc * h;
                self.pos += self.vel * h;
            }
        }
        fn measure(&self) -> Measurement {
            Measurement {
                position: self.pos,
                velocity: self.vel,
            }
        }
    }

    fn joint() -> Joint {
        Joint {
            pos: 0.0,
            vel: 0.0,
            inertia: 0.01,
            kt: 1.0,
            damping: 0.0,
            load: 0.0,
        }
    }

    #[test]
    fn tracks_a_double_integrator_through_a_move() {
        // Double integrator J = 0.01 kg m^2, 1 N m/A, 1 kHz servo.
        let mut j = joint();
        let mut pid = Pid::new(PidGains::pid(40.0, 200.0, 1.2), 2.0).unwrap();
        let traj = PointToPoint::new(0.0, 1.0, 2.0, 20.0).unwrap();
        let dt = 1e-3;
        let mut worst: f64 = 0.0;
        for k in 0..2000 {
            let t = k as f64 * dt;
            let s = traj.sample(t);
            let sp = Setpoint {
                position: s.position,
                velocity: s.velocity,
                // Inertia feedforward: J a / kt.
                feedforward: j.inertia * s.acceleration / j.kt,
            };
            let i = pid.update(sp, j.measure(), dt);
            j.step(i, dt);
            worst = worst.max((s.position - j.pos).abs());
        }
        // Stated tolerance: within 5 mrad during the move, 0.1 mrad at rest.
        assert!(worst < 5e-3, "worst tracking error {worst}");
        assert!((j.pos - 1.0).abs() < 1e-4, "final {}", j.pos);
        assert!(j.vel.abs() < 1e-3);
    }

    #[test]
    fn integral_removes_a_constant_load() {
        let mut j = Joint {
            load: -0.3, // N m, like gravity
            damping: 0.05,
            ..joint()
        };
        let mut pid = Pid::new(PidGains::pid(30.0, 300.0, 1.0), 2.0).unwrap();
        for _ in 0..3000 {
            let i = pid.update(Setpoint::hold(0.5), j.measure(), 1e-3);
            j.step(i, 1e-3);
        }
        assert!((j.pos - 0.5).abs() < 1e-4, "pos {}", j.pos);
        // The integral carries the load: 0.3 N m / 1 N m/A.
        assert!((pid.integral_term() - 0.3).abs() < 1e-2);
    }

    #[test]
    fn tracks_a_first_order_plant() {
        // A heavily damped motor: velocity = k i (first order in position).
        let k = 2.0;
        let mut pos = 0.0;
        let mut pid = Pid::new(PidGains::pid(50.0, 2000.0, 0.0), 1.0).unwrap();
        let dt = 1e-3;
        for _ in 0..1000 {
            let m = Measurement {
                position: pos,
                velocity: 0.0,
            };
            let i = pid.update(Setpoint::hold(0.2), m, dt);
            pos += k * i * dt;
        }
        assert!((pos - 0.2).abs() < 1e-5, "pos {pos}");
    }

    #[test]
    fn anti_windup_bounds_the_integral_and_limits_overshoot() {
        // The joint is blocked for 2 s far from its setpoint, then released.
        let gains = PidGains {
            integral_limit: Some(0.5),
            ..PidGains::pid(20.0, 100.0, 1.0)
        };
        let mut pid = Pid::new(gains, 2.0).unwrap();
        let mut j = joint();
        for _ in 0..2000 {
            let i = pid.update(Setpoint::hold(1.0), j.measure(), 1e-3);
            assert!(pid.integral_term().abs() <= 0.5 + 1e-12);
            assert!(i.abs() <= 2.0);
            // blocked: no motion
        }
        assert_eq!(pid.status(), PidStatus::Saturated);
        // Conditional integration: saturated by P alone, so nothing was
        // integrated at all.
        assert_eq!(pid.integral_term(), 0.0);
        let mut peak: f64 = 0.0;
        for _ in 0..3000 {
            let i = pid.update(Setpoint::hold(1.0), j.measure(), 1e-3);
            j.step(i, 1e-3);
            peak = peak.max(j.pos);
        }
        assert!(peak < 1.15, "overshoot after release: {peak}");
        assert!((j.pos - 1.0).abs() < 1e-3);
    }

    #[test]
    fn deadband_is_continuous() {
        let gains = PidGains {
            deadband: 0.01,
            ..PidGains::pd(10.0, 0.0)
        };
        let mut pid = Pid::new(gains, 5.0).unwrap();
        let at = |pid: &mut Pid, e: f64| {
            pid.update(
                Setpoint::hold(e),
                Measurement {
                    position: 0.0,
                    velocity: 0.0,
                },
                1e-3,
            )
        };
        assert_eq!(at(&mut pid, 0.005), 0.0);
        assert_eq!(at(&mut pid, -0.01), 0.0);
        assert!((at(&mut pid, 0.02) - 0.1).abs() < 1e-12);
        assert!((at(&mut pid, -0.03) + 0.2).abs() < 1e-12);
    }

    #[test]
    fn invalid_input_gives_zero_and_keeps_state() {
        let mut pid = Pid::new(PidGains::pid(10.0, 10.0, 1.0), 1.0).unwrap();
        let m = Measurement::default();
        pid.update(Setpoint::hold(0.05), m, 0.01);
        let before = pid.integral_term();
        assert!(before > 0.0);
        for (sp, dt) in [
            (Setpoint::hold(f64::NAN), 0.001),
            (Setpoint::hold(0.0), -1.0),
            (Setpoint::hold(0.0), f64::INFINITY),
            (Setpoint::hold(f64::INFINITY), 0.001),
        ] {
            assert_eq!(pid.update(sp, m, dt), 0.0);
            assert_eq!(pid.status(), PidStatus::InvalidInput);
            assert_eq!(pid.integral_term(), before);
        }
        pid.reset();
        assert_eq!(pid.integral_term(), 0.0);
        assert_eq!(pid.status(), PidStatus::Ok);
    }

    #[test]
    fn rejects_bad_gains() {
        assert_eq!(
            Pid::new(PidGains::pd(-1.0, 0.0), 1.0).unwrap_err().field,
            "kp"
        );
        assert_eq!(
            Pid::new(PidGains::pd(1.0, f64::NAN), 1.0)
                .unwrap_err()
                .field,
            "kd"
        );
        assert_eq!(
            Pid::new(PidGains::pd(1.0, 0.0), f64::INFINITY)
                .unwrap_err()
                .field,
            "output_limit"
        );
        let mut pid = Pid::new(PidGains::pd(1.0, 0.0), 1.0).unwrap();
        assert!(pid.set_gains(PidGains::pid(1.0, -2.0, 0.0)).is_err());
        assert_eq!(pid.gains().ki, 0.0);
    }

    fn any_f64() -> impl Strategy<Value = f64> {
        prop_oneof![
            4 => -1e3..1e3f64,
            1 => Just(f64::NAN),
            1 => Just(f64::INFINITY),
            1 => Just(f64::NEG_INFINITY),
            1 => Just(f64::MAX),
            1 => Just(-f64::MAX),
            1 => any::<f64>(),
        ]
    }

    proptest! {
        #[test]
        fn output_always_finite_and_within_limits(
            kp in 0.0..1e4f64, ki in 0.0..1e4f64, kd in 0.0..1e3f64,
            ilim in proptest::option::of(0.0..10.0f64),
            limit in 0.0..10.0f64,
            steps in proptest::collection::vec((any_f64(), any_f64(), any_f64(), any_f64(), any_f64(), any_f64()), 1..40),
        ) {
            let gains = PidGains { integral_limit: ilim, velocity_feedforward: 0.1, ..PidGains::pid(kp, ki, kd) };
            let mut pid = Pid::new(gains, limit).unwrap();
            let ibound = ilim.map_or(limit, |l| l.min(limit));
            for (sp, sv, ff, mp, mv, dt) in steps {
                let out = pid.update(
                    Setpoint { position: sp, velocity: sv, feedforward: ff },
                    Measurement { position: mp, velocity: mv },
                    dt,
                );
                prop_assert!(out.is_finite());
                prop_assert!(out.abs() <= limit);
                prop_assert!(pid.integral_term().is_finite());
                prop_assert!(pid.integral_term().abs() <= ibound * (1.0 + 1e-12));
            }
        }
    }
}
