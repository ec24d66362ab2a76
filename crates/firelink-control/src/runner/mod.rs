//! The runner: one robot program's servo loop over a host [`Port`].
//!
//! [`Robot`] ties a configuration ([`IoConfig`]) to an [`IoSystem`]: each
//! actuator `(board_id, axis_id)` is mapped at setup to its board buffers,
//! and every [`Robot::cycle`] is
//!
//! 1. `io.read_all()`, then the checks: every expected board answered
//!    ([`Lifecycle::check_cycle`] with the miss reason turned into a
//!    [`FaultKind`]), no watchdog expired, power and amplifiers still on
//!    while Active;
//! 2. compute: encoder and pot to SI, a per-joint trajectory sample and PID
//!    to a current, the [`SafetyMonitor`], current to DAC bits;
//! 3. `io.write_all()`.
//!
//! Any fault moves the lifecycle to Fault and from then on every cycle
//! commands zero current with every amplifier off; the report says what
//! happened ([`Robot::fault`]).
//!
//! The cycle allocates nothing: every buffer is sized at setup and the
//! statistics go into preallocated vectors (the port may allocate: the
//! simulated bus builds packets).
//!
//! Time: the runner reads the port's clock ([`Port::now`], virtual on the
//! simulated bus); [`Pacing::WallClock`] and the compute-time measurement
//! also read the machine's monotonic clock. This is the one place below the
//! CLI that does.

pub(crate) mod joint;
pub(crate) mod velocity;

use joint::{Joint, Pacer};

use std::time::{Duration, Instant};

use firelink_host::io::{CycleReport, IoStats, IoSystem};
use firelink_host::{HostError, MissReason, Port};
use firelink_wire::board::MAX_BOARDS;
use firelink_wire::board::registers::SYSTEM_CLOCK_HZ;

use crate::config::{IoConfig, StopSearchConfig, StopSide};
use crate::fault::{FaultKind, FaultReport};
use crate::homing::{Homing, HomingError, HomingSettings, HomingStep};
use crate::label::{BoardSet, Label};
use crate::lifecycle::{Lifecycle, LifecycleError, PowerStatus, State};
use crate::pid::{Pid, PidError, PidGains};
use crate::safety::{JointSample, SafetyMonitor};
use crate::trajectory::{Motion, PointToPoint};

/// How cycles are paced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// As fast as the port allows; after each cycle the port waits out the
    /// rest of the period (virtual time on the simulated bus).
    Virtual,
    /// Paced by the machine's monotonic clock at the robot's rate: sleep
    /// until shortly before the deadline, then spin.
    WallClock,
}

/// Runner settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotSettings {
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Board watchdog period (zero disables it).
    pub watchdog: Duration,
    /// Homing sample counts.
    pub homing: HomingSettings,
    /// Cycles to wait for power and amplifiers before giving up.
    pub power_timeout_cycles: u32,
    /// Capacity of the per-cycle timing record (cycles beyond it are
    /// counted but not recorded).
    pub max_samples: usize,
}

impl Default for RobotSettings {
    fn default() -> Self {
        RobotSettings {
            rate_hz: 1000.0,
            watchdog: Duration::from_millis(20),
            homing: HomingSettings {
                averaging_samples: 20,
                verify_samples: 20,
            },
            power_timeout_cycles: 2000,
            max_samples: 1 << 20,
        }
    }
}

/// What can stop the runner outside the cycle.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RunnerError {
    /// The configuration does not fit the boards found.
    #[error("configuration: {0}")]
    Config(String),
    /// A port or I/O error outside the cycle.
    #[error("host: {0}")]
    Host(#[from] HostError),
    /// A refused lifecycle transition.
    #[error("lifecycle: {0:?}")]
    Lifecycle(#[from] LifecycleError),
    /// Homing failed.
    #[error("homing: {0:?}")]
    Homing(HomingError),
    /// Invalid PID gains in the configuration.
    #[error("PID gains: {0:?}")]
    Pid(PidError),
    /// A fault while running.
    #[error("{0}")]
    Fault(FaultReport),
    /// A stop search could not home the joint.
    #[error("{joint}: stop search: {problem}")]
    StopSearch {
        /// The joint.
        joint: Label,
        /// What went wrong.
        problem: StopSearchProblem,
    },
    /// Something did not happen in time.
    #[error("timed out waiting for {0}")]
    Timeout(&'static str),
}

/// Why a stop search failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum StopSearchProblem {
    /// The joint's configuration has no `simulation.homing.stop_search`.
    #[error("not configured for this joint")]
    NotConfigured,
    /// The joint travelled the whole search without stalling: there is no
    /// stop where one was expected (the dVRK console's "went past roll
    /// lower limit").
    #[error("no stop within {travel:.3} of travel")]
    NoStop {
        /// How far the setpoint travelled.
        travel: f64,
    },
}

/// What a stop search found: the joint stalled against its stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopFound {
    /// The joint.
    pub joint: Label,
    /// Where the encoder (homed from the pot) said the joint was when the
    /// stall was declared, before it was set to `stop_position`.
    pub stalled_at: f64,
    /// From the start of the search to there.
    pub travel: f64,
    /// |setpoint - position| then.
    pub following_error: f64,
    /// Current commanded then, A.
    pub commanded_current: f64,
    /// Current the amplifier measured then, A.
    pub measured_current: f64,
    /// Seconds from the start of the search.
    pub duration: f64,
    /// Where the encoder reads from now on (the configured stop position).
    pub stop_position: f64,
}

/// Tracking error of one arm, over the cycles it was Active with a motion.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmTracking {
    /// Robot name from the configuration.
    pub name: String,
    /// Revolute joints: RMS error, radians.
    pub rms_rad: f64,
    /// Revolute joints: largest |error|, radians.
    pub max_rad: f64,
    /// Prismatic joints: RMS error, millimetres (0 without any).
    pub rms_mm: f64,
    /// Prismatic joints: largest |error|, millimetres.
    pub max_mm: f64,
    /// Joint samples taken.
    pub samples: u64,
}

/// Running tracking-error sums of one arm.
#[derive(Debug, Clone, Default)]
pub(crate) struct ArmAcc {
    sum_rad: f64,
    n_rad: u64,
    max_rad: f64,
    sum_m: f64,
    n_m: u64,
    max_m: f64,
}

impl ArmAcc {
    /// Add one joint's |setpoint - position|.
    pub(crate) fn add(&mut self, err: f64, prismatic: bool) {
        if prismatic {
            self.sum_m += err * err;
            self.n_m += 1;
            self.max_m = self.max_m.max(err);
        } else {
            self.sum_rad += err * err;
            self.n_rad += 1;
            self.max_rad = self.max_rad.max(err);
        }
    }

    /// The arm's tracking so far.
    pub(crate) fn tracking(&self, name: &str) -> ArmTracking {
        ArmTracking {
            name: name.to_string(),
            rms_rad: if self.n_rad > 0 {
                (self.sum_rad / self.n_rad as f64).sqrt()
            } else {
                0.0
            },
            max_rad: self.max_rad,
            rms_mm: if self.n_m > 0 {
                1e3 * (self.sum_m / self.n_m as f64).sqrt()
            } else {
                0.0
            },
            max_mm: 1e3 * self.max_m,
            samples: self.n_rad + self.n_m,
        }
    }
}

/// Median, p99 and max of a set of durations, microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Percentiles {
    /// Median.
    pub median: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
}

impl Percentiles {
    /// From samples (sorted in place).
    pub fn of(samples: &mut [f32]) -> Percentiles {
        if samples.is_empty() {
            return Percentiles::default();
        }
        samples.sort_by(f32::total_cmp);
        let at = |q: f64| {
            let i = ((samples.len() - 1) as f64 * q).round() as usize;
            f64::from(samples.get(i).copied().unwrap_or(0.0))
        };
        let mean = samples.iter().map(|&x| f64::from(x)).sum::<f64>() / samples.len() as f64;
        Percentiles {
            median: at(0.5),
            p99: at(0.99),
            max: at(1.0),
            mean,
        }
    }
}

/// Timing record of the cycles run.
#[derive(Debug, Clone, Default)]
pub struct CycleTimes {
    /// I/O time per cycle (read + write phases on the port's clock), us.
    pub io_us: Vec<f32>,
    /// Compute time per cycle (machine clock), us.
    pub compute_us: Vec<f32>,
    /// Cycle time = I/O + compute, us.
    pub cycle_us: Vec<f32>,
    /// Cycles not recorded (record full).
    pub dropped: u64,
    /// Wall-clock pacing: cycles that started after their deadline.
    pub overruns: u64,
    /// Compute time of the last cycle, us (kept when the record is full).
    pub last_compute_us: f32,
}

impl CycleTimes {
    /// An empty record with room for `cap` cycles.
    pub(crate) fn with_capacity(cap: usize) -> CycleTimes {
        CycleTimes {
            io_us: Vec::with_capacity(cap),
            compute_us: Vec::with_capacity(cap),
            cycle_us: Vec::with_capacity(cap),
            dropped: 0,
            overruns: 0,
            last_compute_us: 0.0,
        }
    }

    /// Record one cycle (allocation-free: beyond the capacity it is only
    /// counted).
    pub(crate) fn record(&mut self, io: Duration, compute: Duration) {
        let io_us = io.as_secs_f64() * 1e6;
        let c_us = compute.as_secs_f64() * 1e6;
        self.last_compute_us = c_us as f32;
        if self.io_us.len() < self.io_us.capacity() {
            self.io_us.push(io_us as f32);
            self.compute_us.push(c_us as f32);
            self.cycle_us.push((io_us + c_us) as f32);
        } else {
            self.dropped += 1;
        }
    }
}

/// One robot program: configuration, I/O, lifecycle, controllers.
pub struct Robot<P: Port> {
    io: IoSystem<P>,
    settings: RobotSettings,
    joints: Vec<Joint>,
    pids: Vec<Pid>,
    arm_names: Vec<String>,
    arm_acc: Vec<ArmAcc>,
    /// Per board index: axes used (bit mask), board ID.
    used_axes: Vec<(u8, u8)>,
    expected: BoardSet,
    life: Lifecycle,
    safety: SafetyMonitor,
    homing: Homing,
    samples: Vec<JointSample>,
    /// Per board (index in the I/O system): the boards' own clock at its
    /// last fresh sample, seconds (the read block's timestamp counts the
    /// 49.152 MHz clocks between samples). Velocities are differenced on
    /// this clock: it is when the encoders were sampled, whatever the
    /// host's or the network's jitter.
    sample_clock: Vec<f64>,
    /// Per joint: the pot position as read (where the pot is mounted).
    raw_pot: Vec<f64>,
    /// Pots in actuator space: `pot[t] += w * raw_pot[s]` for each
    /// (t, s, w); empty when no robot has a pot coupling (then `pot` is
    /// `raw_pot`).
    pot_mix: Vec<(usize, usize, f64)>,
    /// Per joint: its stop search, if it homes by one (kept out of the
    /// cycle's data).
    stop_searches: Vec<Option<StopSearchConfig>>,
    pot: Vec<f64>,
    enc: Vec<f64>,
    times: CycleTimes,
    cycle: u64,
    last_start: Option<Duration>,
    last_report: Option<CycleReport>,
    /// Boards that acknowledged the fault path's direct "amplifiers off"
    /// (bit i = board ID i), since the fault.
    disabled_acknowledged: u16,
    fault: Option<FaultReport>,
    pacer: Pacer,
}

impl<P: Port> Robot<P> {
    /// A robot for `config` over the boards of `io`.
    ///
    /// # Errors
    /// [`RunnerError::Config`] when an actuator's board is not among the
    /// boards found or has no such axis; [`RunnerError::Pid`] for invalid
    /// gains. (A missing board is also what [`configure`](Self::configure)
    /// refuses, with the robot named.)
    pub fn new(
        io: IoSystem<P>,
        config: &IoConfig,
        settings: RobotSettings,
    ) -> Result<Robot<P>, RunnerError> {
        if !(settings.rate_hz.is_finite() && settings.rate_hz > 0.0) {
            return Err(RunnerError::Config(format!(
                "rate must be > 0 Hz, not {}",
                settings.rate_hz
            )));
        }
        let mut joints = Vec::new();
        let mut pids = Vec::new();
        let arm_names: Vec<String> = config.robots.iter().map(|r| r.name.clone()).collect();
        let mut used_axes: Vec<(u8, u8)> =
            io.boards().iter().map(|b| (0u8, b.board_id())).collect();
        for j in config.joints() {
            let a = j.actuator;
            let Some(board) = io.boards().iter().position(|b| b.board_id() == a.board_id) else {
                return Err(RunnerError::Config(format!(
                    "{}: board {} is not on the bus",
                    j.label.as_str(),
                    a.board_id
                )));
            };
            let axes = io.boards().get(board).map_or(0, |b| b.axes());
            if usize::from(a.axis_id) >= axes {
                return Err(RunnerError::Config(format!(
                    "{}: board {} has {} axes, no axis {}",
                    j.label.as_str(),
                    a.board_id,
                    axes,
                    a.axis_id
                )));
            }
            if let Some(u) = used_axes.get_mut(board) {
                u.0 |= 1 << a.axis_id;
            }
            let gains = a
                .simulation
                .and_then(|s| s.pid)
                .unwrap_or_else(|| PidGains::pd(1.0, 0.05));
            pids.push(Pid::new(gains, a.drive.maximum_current).map_err(RunnerError::Pid)?);
            joints.push(Joint::new(&j, board, usize::from(a.axis_id)));
        }
        let n = joints.len();
        let cap = settings.max_samples;
        // Pots mounted on joints (v6 coupling) are read in actuator space.
        let mut pot_mix = Vec::new();
        if config.robots.iter().any(|r| r.pot_coupling().is_some()) {
            let mut base = 0;
            for r in &config.robots {
                let m = r.pot_coupling();
                for t in 0..r.actuators.len() {
                    match &m {
                        Some(m) => pot_mix.extend(
                            (0..r.actuators.len())
                                .map(|s| (base + t, base + s, m.get(t, s)))
                                .filter(|&(_, _, w)| w != 0.0),
                        ),
                        None => pot_mix.push((base + t, base + t, 1.0)),
                    }
                }
                base += r.actuators.len();
            }
        }
        Ok(Robot {
            io,
            settings,
            joints,
            pids,
            arm_acc: vec![ArmAcc::default(); arm_names.len()],
            arm_names,
            used_axes,
            expected: config.board_set(),
            life: Lifecycle::from_config(config),
            safety: SafetyMonitor::from_config(config),
            homing: Homing::from_config(config, settings.homing),
            samples: vec![JointSample::default(); n],
            sample_clock: vec![0.0; MAX_BOARDS],
            raw_pot: vec![0.0; n],
            pot_mix,
            stop_searches: config
                .joints()
                .map(|j| {
                    j.actuator
                        .simulation
                        .and_then(|s| s.homing)
                        .and_then(|h| h.stop_search)
                })
                .collect(),
            pot: vec![0.0; n],
            enc: vec![0.0; n],
            times: CycleTimes::with_capacity(cap),
            cycle: 0,
            last_start: None,
            last_report: None,
            disabled_acknowledged: 0,
            fault: None,
            pacer: Pacer::default(),
        })
    }

    /// The I/O system.
    pub fn io(&self) -> &IoSystem<P> {
        &self.io
    }

    /// The I/O system, mutable (fault injection, register access).
    pub fn io_mut(&mut self) -> &mut IoSystem<P> {
        &mut self.io
    }

    /// The lifecycle state.
    pub fn state(&self) -> State {
        self.life.state()
    }

    /// The first fault, if one happened.
    pub fn fault(&self) -> Option<&FaultReport> {
        self.fault.as_ref()
    }

    /// The last cycle's I/O report.
    pub fn last_report(&self) -> Option<&CycleReport> {
        self.last_report.as_ref()
    }

    /// I/O error counters.
    pub fn io_stats(&self) -> &IoStats {
        self.io.stats()
    }

    /// Cycles run.
    pub fn cycles(&self) -> u64 {
        self.cycle
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// Joint `i`'s measured position (homed), rad or m.
    pub fn position(&self, i: usize) -> Option<f64> {
        self.joints.get(i).map(|j| j.position)
    }

    /// Joint `i`'s estimated velocity, rad/s or m/s (over the
    /// measured time span of the last few cycles, late ones included).
    pub fn velocity(&self, i: usize) -> Option<f64> {
        self.joints.get(i).map(|j| j.velocity.velocity())
    }

    /// Joint `i`'s setpoint, rad or m.
    pub fn setpoint(&self, i: usize) -> Option<f64> {
        self.joints.get(i).map(|j| j.setpoint)
    }

    /// Joint `i`'s commanded motor current, amps (0 unless Active).
    pub fn commanded_current(&self, i: usize) -> Option<f64> {
        self.joints.get(i).map(|j| j.current)
    }

    /// Timing record.
    pub fn times(&self) -> &CycleTimes {
        &self.times
    }

    /// The period, seconds.
    pub fn period(&self) -> f64 {
        1.0 / self.settings.rate_hz
    }

    /// Seconds on the port's clock.
    pub fn now(&self) -> f64 {
        self.io.port().now().as_secs_f64()
    }

    /// Per-arm tracking errors so far.
    pub fn tracking(&self) -> Vec<ArmTracking> {
        self.arm_names
            .iter()
            .zip(&self.arm_acc)
            .map(|(name, a)| a.tracking(name))
            .collect()
    }

    /// Forget the tracking statistics (e.g. after homing).
    pub fn reset_tracking(&mut self) {
        self.arm_acc.fill(ArmAcc::default());
    }

    /// Boards found, as a set.
    pub fn found(&self) -> BoardSet {
        self.io.boards().iter().map(|b| b.board_id()).collect()
    }

    /// Power and amplifier state of the expected boards from the last read.
    pub fn power_status(&self) -> PowerStatus {
        let mut s = PowerStatus {
            powered: BoardSet::EMPTY,
            amplifiers_enabled: BoardSet::EMPTY,
        };
        for (b, &(mask, id)) in self.io.boards().iter().zip(&self.used_axes) {
            if b.is_valid() && b.power_enabled() {
                s.powered.insert(id);
            }
            let all = (0..4usize)
                .filter(|a| mask & (1 << a) != 0)
                .all(|a| b.amp_enabled(a));
            if b.is_valid() && all {
                s.amplifiers_enabled.insert(id);
            }
        }
        s
    }

    /// Unconfigured -> Configured: every expected board was found; sets the
    /// board watchdogs.
    ///
    /// # Errors
    /// The lifecycle's refusal (the first missing board, with its robot);
    /// port errors setting the watchdog.
    pub fn configure(&mut self) -> Result<(), RunnerError> {
        self.life.configure(self.found())?;
        self.io.set_watchdog(self.settings.watchdog)?;
        Ok(())
    }

    /// Motor power and relay on, then every used amplifier, waiting (cycling)
    /// until the boards report them.
    ///
    /// # Errors
    /// Not Configured; a fault while waiting; [`RunnerError::Timeout`].
    pub fn power_on(&mut self) -> Result<(), RunnerError> {
        self.power_on_observed(&mut |_| {})
    }

    /// [`power_on`](Self::power_on), calling `each` after every cycle it
    /// runs (a soak or a monitor keeps watching while it waits).
    ///
    /// # Errors
    /// As [`power_on`](Self::power_on).
    pub fn power_on_observed(&mut self, each: &mut dyn FnMut(&Self)) -> Result<(), RunnerError> {
        if self.life.state() != State::Configured {
            return Err(RunnerError::Lifecycle(LifecycleError::NotActive {
                state: self.life.state(),
            }));
        }
        let expected = self.expected;
        for b in self.io.boards_mut() {
            if expected.contains(b.board_id()) {
                b.set_power(true);
                b.set_relay(true);
            }
        }
        self.wait_for("motor power", each, |s| {
            expected.minus(s.powered).is_empty()
        })?;
        let used = self.used_axes.clone();
        for (b, &(mask, _)) in self.io.boards_mut().iter_mut().zip(&used) {
            for a in 0..4usize {
                if mask & (1 << a) != 0 {
                    let _ = b.set_amp_enable(a, true);
                }
            }
        }
        self.wait_for("amplifiers", each, |s| {
            expected.minus(s.amplifiers_enabled).is_empty()
        })
    }

    fn wait_for(
        &mut self,
        what: &'static str,
        each: &mut dyn FnMut(&Self),
        done: impl Fn(&PowerStatus) -> bool,
    ) -> Result<(), RunnerError> {
        for _ in 0..self.settings.power_timeout_cycles {
            let r = self.step(Pacing::Virtual);
            each(self);
            r?;
            if done(&self.power_status()) {
                return Ok(());
            }
        }
        Err(RunnerError::Timeout(what))
    }

    /// Home against the potentiometers (software offsets), cycling.
    ///
    /// # Errors
    /// Homing failed; a fault; a time-out.
    pub fn home(&mut self) -> Result<(), RunnerError> {
        self.homing.start();
        let limit = 10
            * (self.settings.homing.averaging_samples + self.settings.homing.verify_samples)
            + 10;
        for _ in 0..limit {
            self.step(Pacing::Virtual)?;
            match self.homing.step(&self.pot, &self.enc) {
                HomingStep::PreloadReady => self
                    .homing
                    .use_software_offsets()
                    .map_err(RunnerError::Homing)?,
                HomingStep::Done => {
                    joint::apply_offsets(
                        &mut self.joints,
                        self.homing.applied_offsets(),
                        &self.enc,
                    );
                    return Ok(());
                }
                HomingStep::Failed(e) => return Err(RunnerError::Homing(e)),
                _ => {}
            }
        }
        Err(RunnerError::Timeout("homing"))
    }

    /// Fault -> Unconfigured: the fault is acknowledged; from here the
    /// robot is configured and powered again as at start-up (homing
    /// offsets are kept). Returns the cleared report.
    ///
    /// # Errors
    /// Not in Fault.
    pub fn clear_fault(&mut self) -> Result<FaultReport, RunnerError> {
        let report = self.life.clear_fault()?;
        self.fault = None;
        self.disabled_acknowledged = 0;
        for (j, pid) in self.joints.iter_mut().zip(self.pids.iter_mut()) {
            j.motion = Motion::Hold(j.position);
            pid.reset();
        }
        Ok(report)
    }

    /// Boards that acknowledged the fault path's direct "amplifiers off"
    /// since the fault (bit i = board ID i).
    pub fn disable_acknowledged(&self) -> u16 {
        self.disabled_acknowledged
    }

    /// Configured -> Active: every joint holds where it is.
    ///
    /// # Errors
    /// The lifecycle's refusal (no power, amplifiers off, wrong state).
    pub fn activate(&mut self) -> Result<(), RunnerError> {
        self.life.activate(self.power_status())?;
        let now = self.now();
        joint::hold_all(&mut self.joints, &mut self.pids, now);
        self.safety.restart_timers();
        Ok(())
    }

    /// Start `motion` on joint `i` now (positions are absolute, homed).
    ///
    /// # Errors
    /// [`LifecycleError::NotActive`] unless Active;
    /// [`RunnerError::Config`] for a joint that does not exist.
    pub fn set_motion(&mut self, i: usize, motion: Motion) -> Result<(), RunnerError> {
        self.life.require_motion()?;
        let now = self.now();
        joint::start_motion(&mut self.joints, i, motion, now)?;
        self.safety.restart_timers();
        Ok(())
    }

    /// Active -> Configured (if Active), then amplifiers, power and relay
    /// off; a few cycles to apply it. Also the way out after a fault.
    ///
    /// # Errors
    /// Port errors are in the cycle reports; this only fails if cycling
    /// cannot go on (never today).
    pub fn shutdown(&mut self) -> Result<(), RunnerError> {
        if self.life.state() == State::Active {
            self.life.deactivate()?;
        }
        for b in self.io.boards_mut() {
            b.safe_outputs();
            b.set_power(false);
            b.set_relay(false);
        }
        for _ in 0..3 {
            // Faults during shutdown are expected (power going off).
            let _ = self.step(Pacing::Virtual);
        }
        Ok(())
    }

    /// Run `cycles` cycles with `pacing`, calling `progress` every
    /// `progress_every` cycles (0: never).
    ///
    /// # Errors
    /// The first fault ([`RunnerError::Fault`]).
    pub fn run(
        &mut self,
        cycles: u64,
        pacing: Pacing,
        progress_every: u64,
        mut progress: impl FnMut(&Robot<P>),
    ) -> Result<(), RunnerError> {
        self.pacer.restart();
        for k in 0..cycles {
            self.step(pacing)?;
            if progress_every > 0 && (k + 1) % progress_every == 0 {
                progress(self);
            }
        }
        Ok(())
    }

    /// One paced cycle.
    ///
    /// # Errors
    /// A fault detected in this cycle (or latched before).
    pub fn step(&mut self, pacing: Pacing) -> Result<(), RunnerError> {
        let period = Duration::from_secs_f64(self.period());
        self.pacer.before_cycle(pacing, period, &mut self.times);
        let started = self.io.port().now();
        let r = self.cycle();
        // A bus reset renumbers nodes: scan again between cycles, never
        // inside one (a failed scan is retried after the next cycle).
        if self.io.needs_rescan() {
            let _ = self.io.recover();
        }
        let spent = self.io.port().now().saturating_sub(started);
        if let Some(rest) = Pacer::rest(pacing, period, spent) {
            self.io.port_mut().wait(rest);
        }
        r.map_err(RunnerError::Fault)
    }

    /// One cycle: read, check, compute, write. Allocation-free.
    ///
    /// # Errors
    /// The fault detected (or latched earlier): outputs are then safe.
    pub fn cycle(&mut self) -> Result<(), FaultReport> {
        self.cycle += 1;
        let report = *self.io.read_all();
        let compute_start = Instant::now();
        let now = report.started.as_secs_f64();
        let dt = match self.last_start {
            Some(t) => (report.started.saturating_sub(t)).as_secs_f64(),
            None => self.period(),
        }
        .clamp(0.1 * self.period(), 10.0 * self.period());
        self.last_start = Some(report.started);
        for (clock, b) in self.sample_clock.iter_mut().zip(self.io.boards()) {
            if b.is_valid() {
                let ts = b.timestamp();
                // A board that reports no timestamp: the host's interval.
                *clock += if ts == 0 {
                    dt
                } else {
                    f64::from(ts) / f64::from(SYSTEM_CLOCK_HZ)
                };
            }
        }
        self.check(&report, now);
        self.compute(now, dt);
        if self.life.state() == State::Fault {
            for b in self.io.boards_mut() {
                b.safe_outputs();
            }
        }
        let compute = compute_start.elapsed();
        if self.life.state() == State::Fault {
            // The broadcast command below says "amplifiers off"; a packet
            // lost on the bus must not leave them on: tell each board that
            // has not acknowledged it yet, directly (inside the cycle, so
            // its errors are in the cycle's report).
            let expected = self.expected.0 & !self.disabled_acknowledged;
            if expected != 0 {
                self.disabled_acknowledged |= self.io.disable_amplifiers_acknowledged(expected);
            }
        }
        let report = *self.io.write_all();
        self.last_report = Some(report);
        self.times.record(report.io_time(), compute);
        match self.fault {
            Some(f) => Err(f),
            None => Ok(()),
        }
    }

    fn raise(&mut self, kind: FaultKind, now: f64) {
        let r = self.life.fault(FaultReport::new(now, self.cycle, kind));
        if self.fault.is_none() {
            self.fault = Some(r);
        }
    }

    fn check(&mut self, report: &CycleReport, now: f64) {
        if !self.life.reads_inputs() {
            return;
        }
        // Missed boards, with the reason turned into a fault kind.
        let mut answered = self.expected;
        for (id, _) in report.missed_boards() {
            answered = answered.minus(BoardSet::EMPTY.with(id));
        }
        if let Some(id) = self.expected.minus(answered).first() {
            let reason = report.reasons.get(usize::from(id)).copied().flatten();
            let kind = match reason {
                Some(MissReason::CorruptQuery) => FaultKind::Sequence {
                    board_id: id,
                    expected: report.seq,
                    received: 0xFFFF,
                },
                _ => FaultKind::MissedBoard {
                    board_id: id,
                    robot: self.life.board_owner(id),
                },
            };
            self.raise(kind, now);
            return;
        }
        // Lifecycle's own working-counter check (records nothing new here).
        if let Err(r) = self.life.check_cycle(answered, now, self.cycle) {
            if self.fault.is_none() {
                self.fault = Some(r);
            }
            return;
        }
        let active = self.life.state() == State::Active;
        let mut found = None;
        for (b, &(mask, id)) in self.io.boards().iter().zip(&self.used_axes) {
            if !self.expected.contains(id) {
                continue;
            }
            // Before power is on a timed-out watchdog is harmless (nothing
            // to turn off); from power on, it is a fault.
            if b.watchdog_expired() && (active || b.power_enabled()) {
                found = Some(FaultKind::Watchdog { board_id: id });
                break;
            }
            if active && !b.power_enabled() {
                found = Some(FaultKind::Power { board_id: id });
                break;
            }
            if active {
                if let Some(axis) =
                    (0..4u8).find(|&a| mask & (1 << a) != 0 && !b.amp_enabled(usize::from(a)))
                {
                    found = Some(FaultKind::Amplifier {
                        board_id: id,
                        axis_id: axis,
                    });
                    break;
                }
            }
        }
        if let Some(kind) = found {
            self.raise(kind, now);
        }
    }

    /// Pots mounted on joints: every joint's pot position read, then
    /// turned into actuator space through the robots' pot couplings.
    fn read_coupled_pots(&mut self) {
        for (raw, j) in self.raw_pot.iter_mut().zip(&self.joints) {
            let bits = self
                .io
                .boards()
                .get(j.board)
                .and_then(|b| b.pot_bits(j.axis));
            *raw = j.pot_position(bits);
        }
        self.pot.fill(0.0);
        for &(t, s, w) in &self.pot_mix {
            if let (Some(p), Some(r)) = (self.pot.get_mut(t), self.raw_pot.get(s)) {
                *p += w * r;
            }
        }
    }

    fn compute(&mut self, now: f64, dt: f64) {
        let active = self.life.state() == State::Active;
        let coupled = !self.pot_mix.is_empty();
        if coupled {
            self.read_coupled_pots();
        }
        for (i, j) in self.joints.iter_mut().enumerate() {
            let Some(b) = self.io.boards().get(j.board) else {
                continue;
            };
            let counts = b.encoder_counts(j.axis).unwrap_or(0);
            let sampled = self.sample_clock.get(j.board).copied().unwrap_or(now);
            let mut u = j.update(
                counts,
                b.pot_bits(j.axis),
                sampled,
                now,
                dt,
                active,
                self.pids.get_mut(i),
                self.arm_acc.get_mut(j.arm),
            );
            if let Some(e) = self.enc.get_mut(i) {
                *e = u.raw;
            }
            if coupled {
                // The pot reads the joint; the safety monitor compares the
                // encoder with it in actuator space.
                let pot = self.pot.get(i).copied().unwrap_or(f64::NAN);
                u.sample.potentiometer =
                    (j.pot.is_some() && active && pot.is_finite()).then_some(pot);
            } else if let Some(p) = self.pot.get_mut(i) {
                *p = u.pot;
            }
            if let Some(s) = self.samples.get_mut(i) {
                *s = u.sample;
            }
        }
        if active {
            if let Some(r) = self.safety.check(now, self.cycle, &self.samples) {
                let r = self.life.fault(r);
                if self.fault.is_none() {
                    self.fault = Some(r);
                }
            }
        }
        let active = self.life.state() == State::Active;
        let boards = self.io.boards_mut();
        for j in &self.joints {
            if let Some(b) = boards.get_mut(j.board) {
                let _ = b.set_dac(j.axis, j.command(active));
            }
        }
    }

    /// Add `delta` (rad or m) to joint `i`'s setpoint offset: its motion is
    /// replaced by a hold at the current setpoint plus `delta` (fault
    /// injection: a following-error step).
    ///
    /// # Errors
    /// As [`set_motion`](Self::set_motion).
    pub fn step_setpoint(&mut self, i: usize, delta: f64) -> Result<(), RunnerError> {
        let sp = self.setpoint(i).unwrap_or(0.0);
        self.set_motion(i, Motion::Hold(sp + delta))
    }

    /// Joint `i`'s position by its potentiometer, in actuator space (NaN
    /// for a joint without a pot), as of the last cycle.
    pub fn potentiometer(&self, i: usize) -> Option<f64> {
        self.pot.get(i).copied()
    }

    /// The current joint `i`'s amplifier measured, A, as of the last cycle
    /// (`None` when its board did not answer).
    pub fn measured_current(&self, i: usize) -> Option<f64> {
        let j = self.joints.get(i)?;
        let b = self.io.boards().get(j.board).filter(|b| b.is_valid())?;
        Some(j.drive.bits_to_current(b.current_bits(j.axis)?))
    }

    /// The joints whose configuration homes them by a stop search.
    pub fn stop_search_joints(&self) -> impl Iterator<Item = usize> + '_ {
        self.stop_searches
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_some())
            .map(|(i, _)| i)
    }

    /// Home joint `i` by its stop search: see
    /// [`search_stop_observed`](Self::search_stop_observed).
    ///
    /// # Errors
    /// As [`search_stop_observed`](Self::search_stop_observed).
    pub fn search_stop(&mut self, i: usize) -> Result<StopFound, RunnerError> {
        self.search_stop_observed(i, &mut |_| {})
    }

    /// Home joint `i` by a stop search, as the dVRK console homes the MTM
    /// roll: from where it is, its setpoint moves towards the stop at the
    /// configured constant velocity, reached with the configured
    /// acceleration (the other joints hold), with its position-limit,
    /// following-error and current-saturation checks off, until the
    /// following error passes `stall_error`: the joint has stalled against
    /// the stop. The encoder is then declared to read `stop_position` (the
    /// joint's offset changes), the joint holds there and its checks are
    /// back on; a move away from the stop is free. `each` is called after
    /// every cycle.
    ///
    /// # Errors
    /// Not Active; no such joint; [`StopSearchProblem::NotConfigured`];
    /// [`StopSearchProblem::NoStop`] when the whole travel passes without a
    /// stall; a fault while searching (the checks are back on in any case).
    pub fn search_stop_observed(
        &mut self,
        i: usize,
        each: &mut dyn FnMut(&Self),
    ) -> Result<StopFound, RunnerError> {
        self.life.require_motion()?;
        let j = *self
            .joints
            .get(i)
            .ok_or_else(|| RunnerError::Config(format!("no joint {i}")))?;
        let Some(search) = self.stop_searches.get(i).copied().flatten() else {
            return Err(RunnerError::StopSearch {
                joint: j.label,
                problem: StopSearchProblem::NotConfigured,
            });
        };
        let direction = match search.side {
            StopSide::Lower => -1.0,
            StopSide::Upper => 1.0,
        };
        let start = j.position;
        let search_move = PointToPoint::new(
            start,
            start + direction * search.max_travel,
            search.velocity,
            search.acceleration,
        )
        .map_err(|e| RunnerError::Config(format!("{}: stop search: {e:?}", j.label)))?;
        let horizon = search_move.duration();
        let started = self.now();
        self.safety.allow_stall(i, true);
        let found = self
            .set_motion(i, Motion::PointToPoint(search_move))
            .and_then(|()| self.run_search(i, &search, started, horizon, each));
        self.safety.allow_stall(i, false);
        let (stalled_at, following_error, commanded_current, duration) = found?;
        let measured_current = self.measured_current(i).unwrap_or(f64::NAN);
        let now = self.now();
        if let Some(j) = self.joints.get_mut(i) {
            j.offset += search.stop_position - stalled_at;
            j.position = search.stop_position;
            j.setpoint = search.stop_position;
            j.motion = Motion::Hold(search.stop_position);
            j.motion_start = now;
            j.velocity.reset();
        }
        if let Some(pid) = self.pids.get_mut(i) {
            pid.reset();
        }
        self.safety.restart_timers();
        Ok(StopFound {
            joint: j.label,
            stalled_at,
            travel: (stalled_at - start).abs(),
            following_error,
            commanded_current,
            measured_current,
            duration,
            stop_position: search.stop_position,
        })
    }

    /// Cycles until joint `i` stalls: (position, following error, current
    /// command, seconds since `started`).
    fn run_search(
        &mut self,
        i: usize,
        search: &StopSearchConfig,
        started: f64,
        horizon: f64,
        each: &mut dyn FnMut(&Self),
    ) -> Result<(f64, f64, f64, f64), RunnerError> {
        // Past the end of the travel, give the joint a moment to catch up.
        let give_up = horizon + 1.0;
        loop {
            let r = self.step(Pacing::Virtual);
            each(self);
            r?;
            let Some(j) = self.joints.get(i) else {
                return Err(RunnerError::Config(format!("no joint {i}")));
            };
            let error = (j.setpoint - j.position).abs();
            let elapsed = self.now() - started;
            if error > search.stall_error {
                return Ok((j.position, error, j.current, elapsed));
            }
            if elapsed > give_up {
                return Err(RunnerError::StopSearch {
                    joint: j.label,
                    problem: StopSearchProblem::NoStop {
                        travel: search.max_travel,
                    },
                });
            }
        }
    }

    /// The label of joint `i`.
    pub fn joint_label(&self, i: usize) -> Option<Label> {
        self.joints.get(i).map(|j| j.label)
    }

    /// The arm names, in configuration order.
    pub fn arm_names(&self) -> &[String] {
        &self.arm_names
    }

    /// Whether any used amplifier is on, on the boards that answered the
    /// last read (a board that does not answer cannot say; its own
    /// watchdog turns its amplifiers off).
    pub fn any_amp_on(&self) -> bool {
        self.io
            .boards()
            .iter()
            .zip(&self.used_axes)
            .filter(|(b, _)| b.is_valid())
            .any(|(b, &(mask, _))| (0..4).any(|a| mask & (1 << a) != 0 && b.amp_enabled(a)))
    }
}
