//! The MainController's period: read every module, compute the walking
//! set-points, broadcast them, wait for the next period, with the
//! computer's computation and slack charged in virtual time as seed 002's
//! budget counts them.
//!
//! One period, from its start:
//!
//! ```text
//! read all modules (T_e) | slack (T_s) | compute (T_f) | slack (T_s) | QWRITE (T_g) | idle
//! ```
//!
//! which is inequality (1)'s `t(Te) + t(Tf) + t(Tg) + 2 t(Ts) < P` as the
//! seed's example adds it up. A period whose work does not fit is an
//! overrun: the next period starts late, at once, and the overrun counts
//! as an error.

use std::time::Duration;

use firelink_host::Port;
use firelink_host::mahru::{Feedback, MotionController, MotionError, Setpoints};
use firelink_wire::mahru::ModId;

use super::config::{MahruConfig, bounds, duration_us};
use super::gait::Gait;

/// The phases of one period, as measured on the port's clock.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PeriodTimes {
    /// Reading every module (`T_e`), us.
    pub read_us: f64,
    /// Computation as charged (`T_f`), us.
    pub compute_us: f64,
    /// Broadcasting the set-points (`T_g`), us.
    pub write_us: f64,
    /// From the start of the period to the end of the QWRITE, us.
    pub busy_us: f64,
}

/// (ModID, gravity torque, inertia) of every motor of `config`: the model
/// the set-points' torque feed-forward uses.
pub fn motor_models(config: &MahruConfig) -> Vec<(ModId, f64, f64)> {
    config
        .modules()
        .filter_map(|m| {
            let j = config.motor(ModId(m.mod_id))?;
            Some((ModId(m.mod_id), j.gravity_torque_nm, j.inertia))
        })
        .collect()
}

/// Every motor's set-point at `t` seconds of `gait`, with the model's
/// gravity and inertia torques fed forward (`motors` from
/// [`motor_models`]). With `moving` false the pose at `t` is held:
/// velocity and acceleration 0, gravity still fed forward.
pub fn gait_setpoints(
    gait: &Gait,
    motors: &[(ModId, f64, f64)],
    t: f64,
    moving: bool,
    setpoints: &mut Setpoints,
) {
    for &(id, gravity, inertia) in motors {
        let s = gait.setpoint(id, t);
        let (velocity, acceleration) = if moving {
            (s.velocity, s.acceleration)
        } else {
            (0.0, 0.0)
        };
        let torque = gravity * s.position.sin() + inertia * acceleration;
        setpoints.set(id, s.position, velocity, acceleration, torque);
    }
}

/// The MainController: the gait, the model feed-forward, the timing.
pub struct MainLoop {
    gait: Gait,
    /// (ModID, gravity torque, inertia) of every motor.
    motors: Vec<(ModId, f64, f64)>,
    period: Duration,
    compute: Duration,
    slack: Duration,
    setpoints: Setpoints,
    started: Option<Duration>,
    /// Periods run.
    pub periods: u64,
    /// Periods whose work did not fit.
    pub overruns: u64,
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

impl MainLoop {
    /// The main loop of `config` at `period`.
    pub fn new(config: &MahruConfig, period: Duration) -> MainLoop {
        MainLoop {
            gait: Gait::new(config),
            motors: motor_models(config),
            period,
            compute: duration_us(config.compute_us, bounds::PHASE_US),
            slack: duration_us(config.slack_us, bounds::PHASE_US),
            setpoints: Setpoints::default(),
            started: None,
            periods: 0,
            overruns: 0,
        }
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Seconds of walking so far (since the first period).
    pub fn walking_time<P: Port>(&self, controller: &MotionController<P>) -> f64 {
        self.started.map_or(0.0, |s| {
            controller.port().now().saturating_sub(s).as_secs_f64()
        })
    }

    /// Compute this period's set-points at walking time `t`: the gait,
    /// with the model's gravity and inertia torques fed forward.
    fn compute(&mut self, t: f64) {
        gait_setpoints(&self.gait, &self.motors, t, true, &mut self.setpoints);
    }

    /// Run one period on `controller` (running); `observe` sees the
    /// feedback read in it.
    ///
    /// # Errors
    /// What the controller reports (it has stopped the robot).
    pub fn period_once<P: Port>(
        &mut self,
        controller: &mut MotionController<P>,
        mut observe: impl FnMut(&Feedback),
    ) -> Result<PeriodTimes, MotionError> {
        let start = controller.port().now();
        let walking_since = *self.started.get_or_insert(start);
        controller.read_all()?;
        observe(controller.feedback());
        let read_end = controller.port().now();
        controller.port_mut().wait(self.slack);
        let compute_start = controller.port().now();
        let t = compute_start.saturating_sub(walking_since).as_secs_f64();
        self.compute(t);
        controller.port_mut().wait(self.compute);
        let compute_end = controller.port().now();
        controller.port_mut().wait(self.slack);
        let write_start = controller.port().now();
        controller.write_setpoints(&self.setpoints)?;
        let end = controller.port().now();
        self.periods += 1;
        let busy = end.saturating_sub(start);
        if busy > self.period {
            // Late: the next period starts at once.
            self.overruns += 1;
        } else {
            controller.port_mut().wait(self.period - busy);
        }
        Ok(PeriodTimes {
            read_us: us(read_end.saturating_sub(start)),
            compute_us: us(compute_end.saturating_sub(compute_start)),
            write_us: us(end.saturating_sub(write_start)),
            busy_us: us(busy),
        })
    }
}
