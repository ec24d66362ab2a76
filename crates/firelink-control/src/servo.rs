//! A servo program over the abstract robot I/O of seed 001 (Fig. 18's top
//! layer, [`RobotIo`]): the same control code drives QLA boards
//! ([`firelink_host::io::IoSystem`]) and Snake nodes
//! ([`firelink_host::snake::SnakeSystem`]).
//!
//! [`Servo`] maps every actuator of a configuration to an axis of the I/O
//! system at setup; each [`Servo::cycle`] then is
//!
//! 1. `latch_all_inputs`, and the checks: every expected board answered
//!    (the miss becomes a [`FaultKind`]), no watchdog expired, power and
//!    amplifiers still on while Active;
//! 2. compute: encoder and pot to SI through the configuration, homing
//!    offsets, velocity on the boards' own sample clock, a trajectory
//!    sample and PID per joint, the [`SafetyMonitor`], current to DAC
//!    code;
//! 3. `apply_all_outputs`.
//!
//! The lifecycle (configure, power on, home, activate, motion, shutdown,
//! fault with every output safe and the boards told directly) is the one
//! of [`crate::runner`], whose `Robot` does the same for QLA boards with
//! the broadcast protocol's specifics; this one knows only the trait.
//! The cycle allocates nothing.

use std::time::{Duration, Instant};

use firelink_host::RobotIo;
use firelink_host::io::CycleReport;
use firelink_wire::board::MAX_BOARDS;
use firelink_wire::snake::registers::SYSTEM_CLOCK_HZ;

use crate::config::IoConfig;
use crate::fault::{FaultKind, FaultReport};
use crate::homing::{Homing, HomingStep};
use crate::label::{BoardSet, Label};
use crate::lifecycle::{Lifecycle, LifecycleError, PowerStatus, State};
use crate::pid::{Pid, PidGains};
use crate::runner::joint::{self, Joint, Pacer};
use crate::runner::{ArmAcc, ArmTracking, CycleTimes, Pacing, RobotSettings, RunnerError};
use crate::safety::{JointSample, SafetyMonitor};
use crate::trajectory::Motion;

/// A servo program: configuration, I/O, lifecycle, controllers.
pub struct Servo<R: RobotIo> {
    io: R,
    settings: RobotSettings,
    /// Joints; `board` is the board ID, `axis` the I/O system's axis.
    joints: Vec<Joint>,
    pids: Vec<Pid>,
    arm_names: Vec<String>,
    arm_acc: Vec<ArmAcc>,
    expected: BoardSet,
    life: Lifecycle,
    safety: SafetyMonitor,
    homing: Homing,
    samples: Vec<JointSample>,
    /// Per board ID: the board's own clock at its last sample, seconds.
    sample_clock: [f64; MAX_BOARDS],
    pot: Vec<f64>,
    enc: Vec<f64>,
    times: CycleTimes,
    cycle: u64,
    last_start: Option<Duration>,
    last_report: Option<CycleReport>,
    disabled_acknowledged: u16,
    fault: Option<FaultReport>,
    pacer: Pacer,
}

impl<R: RobotIo> Servo<R> {
    /// A servo for `config` over the axes of `io`.
    ///
    /// # Errors
    /// [`RunnerError::Config`] for a rate that is not positive, or an
    /// actuator whose board or axis `io` does not have (naming the joint);
    /// [`RunnerError::Pid`] for invalid gains.
    pub fn new(io: R, config: &IoConfig, settings: RobotSettings) -> Result<Servo<R>, RunnerError> {
        if !(settings.rate_hz.is_finite() && settings.rate_hz > 0.0) {
            return Err(RunnerError::Config(format!(
                "rate must be > 0 Hz, not {}",
                settings.rate_hz
            )));
        }
        let mut joints = Vec::new();
        let mut pids = Vec::new();
        for j in config.joints() {
            let a = j.actuator;
            let Some(axis) = io.axis_index(a.board_id, a.axis_id) else {
                return Err(RunnerError::Config(format!(
                    "{}: board {} axis {} is not among the boards found",
                    j.label.as_str(),
                    a.board_id,
                    a.axis_id
                )));
            };
            let gains = a
                .simulation
                .and_then(|s| s.pid)
                .unwrap_or_else(|| PidGains::pd(1.0, 0.05));
            pids.push(Pid::new(gains, a.drive.maximum_current).map_err(RunnerError::Pid)?);
            joints.push(Joint::new(&j, usize::from(a.board_id), axis));
        }
        let n = joints.len();
        let arm_names: Vec<String> = config.robots.iter().map(|r| r.name.clone()).collect();
        Ok(Servo {
            io,
            settings,
            joints,
            pids,
            arm_acc: vec![ArmAcc::default(); arm_names.len()],
            arm_names,
            expected: config.board_set(),
            life: Lifecycle::from_config(config),
            safety: SafetyMonitor::from_config(config),
            homing: Homing::from_config(config, settings.homing),
            samples: vec![JointSample::default(); n],
            sample_clock: [0.0; MAX_BOARDS],
            pot: vec![0.0; n],
            enc: vec![0.0; n],
            times: CycleTimes::with_capacity(settings.max_samples),
            cycle: 0,
            last_start: None,
            last_report: None,
            disabled_acknowledged: 0,
            fault: None,
            pacer: Pacer::default(),
        })
    }

    /// The I/O system.
    pub fn io(&self) -> &R {
        &self.io
    }

    /// The I/O system, mutable (fault injection, hardware-specific calls).
    pub fn io_mut(&mut self) -> &mut R {
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

    /// Cycles run.
    pub fn cycles(&self) -> u64 {
        self.cycle
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// Joint `i`'s label (`ROBOT[k]`).
    pub fn joint_label(&self, i: usize) -> Option<Label> {
        self.joints.get(i).map(|j| j.label)
    }

    /// Joint `i`'s measured position (homed), rad or m.
    pub fn position(&self, i: usize) -> Option<f64> {
        self.joints.get(i).map(|j| j.position)
    }

    /// Joint `i`'s setpoint, rad or m.
    pub fn setpoint(&self, i: usize) -> Option<f64> {
        self.joints.get(i).map(|j| j.setpoint)
    }

    /// Joint `i`'s commanded motor current, A (0 unless Active).
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
        self.io.now().as_secs_f64()
    }

    /// Per-arm tracking errors so far.
    pub fn tracking(&self) -> Vec<ArmTracking> {
        self.arm_names
            .iter()
            .zip(&self.arm_acc)
            .map(|(name, a)| a.tracking(name))
            .collect()
    }

    /// Forget the tracking statistics.
    pub fn reset_tracking(&mut self) {
        self.arm_acc.fill(ArmAcc::default());
    }

    /// Boards found, as a set.
    pub fn found(&self) -> BoardSet {
        BoardSet(self.io.boards())
    }

    /// Power and amplifier state of the expected boards at the last latch.
    pub fn power_status(&self) -> PowerStatus {
        let mut s = PowerStatus {
            powered: BoardSet::EMPTY,
            amplifiers_enabled: BoardSet::EMPTY,
        };
        for id in (0..MAX_BOARDS as u8).filter(|id| self.expected.contains(*id)) {
            if self.io.powered(id) {
                s.powered.insert(id);
            }
            let all = self
                .joints
                .iter()
                .filter(|j| j.board == usize::from(id))
                .all(|j| self.io.amplifier_enabled(j.axis).unwrap_or(false));
            if self.io.board_answered(id) && all {
                s.amplifiers_enabled.insert(id);
            }
        }
        s
    }

    /// Whether any used amplifier is on, on the boards that answered.
    pub fn any_amp_on(&self) -> bool {
        self.joints
            .iter()
            .any(|j| self.io.amplifier_enabled(j.axis).unwrap_or(false))
    }

    /// Unconfigured -> Configured: every expected board was found; the
    /// boards' watchdogs are set.
    ///
    /// # Errors
    /// The lifecycle's refusal; port errors setting the watchdog.
    pub fn configure(&mut self) -> Result<(), RunnerError> {
        self.life.configure(self.found())?;
        self.io.set_watchdog(self.settings.watchdog)?;
        Ok(())
    }

    /// Motor power on, then every used amplifier, cycling until the boards
    /// report them.
    ///
    /// # Errors
    /// Not Configured; a fault while waiting; [`RunnerError::Timeout`].
    pub fn power_on(&mut self) -> Result<(), RunnerError> {
        if self.life.state() != State::Configured {
            return Err(RunnerError::Lifecycle(LifecycleError::NotActive {
                state: self.life.state(),
            }));
        }
        let expected = self.expected;
        self.io.set_power(true);
        self.wait_for("motor power", |s| expected.minus(s.powered).is_empty())?;
        for i in 0..self.joints.len() {
            if let Some(axis) = self.joints.get(i).map(|j| j.axis) {
                let _ = self.io.set_amplifier_enable(axis, true);
            }
        }
        self.wait_for("amplifiers", |s| {
            expected.minus(s.amplifiers_enabled).is_empty()
        })
    }

    fn wait_for(
        &mut self,
        what: &'static str,
        done: impl Fn(&PowerStatus) -> bool,
    ) -> Result<(), RunnerError> {
        for _ in 0..self.settings.power_timeout_cycles {
            self.step(Pacing::Virtual)?;
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
        let h = self.settings.homing;
        let limit = 10 * (h.averaging_samples + h.verify_samples) + 10;
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

    /// Start `motion` on joint `i` now (absolute, homed positions).
    ///
    /// # Errors
    /// Not Active; a joint that does not exist.
    pub fn set_motion(&mut self, i: usize, motion: Motion) -> Result<(), RunnerError> {
        self.life.require_motion()?;
        let now = self.now();
        joint::start_motion(&mut self.joints, i, motion, now)?;
        self.safety.restart_timers();
        Ok(())
    }

    /// Active -> Configured (if Active), then every output safe and power
    /// off, over a few cycles.
    ///
    /// # Errors
    /// Never today (faults while powering off are expected).
    pub fn shutdown(&mut self) -> Result<(), RunnerError> {
        if self.life.state() == State::Active {
            self.life.deactivate()?;
        }
        self.io.set_all_safe();
        self.io.set_power(false);
        for _ in 0..3 {
            let _ = self.step(Pacing::Virtual);
        }
        Ok(())
    }

    /// Run `cycles` cycles, calling `progress` every `every` cycles (0:
    /// never).
    ///
    /// # Errors
    /// The first fault ([`RunnerError::Fault`]).
    pub fn run(
        &mut self,
        cycles: u64,
        pacing: Pacing,
        every: u64,
        mut progress: impl FnMut(&Servo<R>),
    ) -> Result<(), RunnerError> {
        self.pacer.restart();
        for k in 0..cycles {
            self.step(pacing)?;
            if every > 0 && (k + 1) % every == 0 {
                progress(self);
            }
        }
        Ok(())
    }

    /// One paced cycle: with [`Pacing::Virtual`] the port waits out the
    /// rest of the period after the cycle; with [`Pacing::WallClock`] the
    /// machine's clock paces the start.
    ///
    /// # Errors
    /// A fault detected in this cycle (or latched before).
    pub fn step(&mut self, pacing: Pacing) -> Result<(), RunnerError> {
        let period = Duration::from_secs_f64(self.period());
        self.pacer.before_cycle(pacing, period, &mut self.times);
        let started = self.io.now();
        let r = self.cycle();
        // A bus reset renumbers nodes: find the boards again between
        // cycles (a failed attempt is retried after the next cycle).
        let _ = self.io.recover();
        let spent = self.io.now().saturating_sub(started);
        if let Some(rest) = Pacer::rest(pacing, period, spent) {
            self.io.wait(rest);
        }
        r.map_err(RunnerError::Fault)
    }

    /// One cycle: latch, check, compute, apply. Allocation-free.
    ///
    /// # Errors
    /// The fault detected (or latched earlier): outputs are then safe.
    pub fn cycle(&mut self) -> Result<(), FaultReport> {
        self.cycle += 1;
        let report = *self.io.latch_all_inputs();
        let compute_start = Instant::now();
        let now = report.started.as_secs_f64();
        let dt = match self.last_start {
            Some(t) => report.started.saturating_sub(t).as_secs_f64(),
            None => self.period(),
        }
        .clamp(0.1 * self.period(), 10.0 * self.period());
        self.last_start = Some(report.started);
        for (id, clock) in self.sample_clock.iter_mut().enumerate() {
            if let Some(ts) = self.io.timestamp(id as u8) {
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
            self.io.set_all_safe();
        }
        let compute = compute_start.elapsed();
        if self.life.state() == State::Fault {
            let pending = self.expected.0 & !self.disabled_acknowledged;
            if pending != 0 {
                self.disabled_acknowledged |= self.io.disable_amplifiers_acknowledged(pending);
            }
        }
        let report = *self.io.apply_all_outputs();
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
        let mut answered = self.expected;
        for (id, _) in report.missed_boards() {
            answered = answered.minus(BoardSet::EMPTY.with(id));
        }
        if let Some(id) = self.expected.minus(answered).first() {
            let kind = FaultKind::MissedBoard {
                board_id: id,
                robot: self.life.board_owner(id),
            };
            self.raise(kind, now);
            return;
        }
        if let Err(r) = self.life.check_cycle(answered, now, self.cycle) {
            if self.fault.is_none() {
                self.fault = Some(r);
            }
            return;
        }
        let active = self.life.state() == State::Active;
        let mut found = None;
        for id in (0..MAX_BOARDS as u8).filter(|id| self.expected.contains(*id)) {
            let powered = self.io.powered(id);
            if self.io.watchdog_expired(id) && (active || powered) {
                found = Some(FaultKind::Watchdog { board_id: id });
                break;
            }
            if active && !powered {
                found = Some(FaultKind::Power { board_id: id });
                break;
            }
        }
        if found.is_none() && active {
            found = self
                .joints
                .iter()
                .find(|j| !self.io.amplifier_enabled(j.axis).unwrap_or(false))
                .map(|j| FaultKind::Amplifier {
                    board_id: j.board as u8,
                    axis_id: self.io.axis_location(j.axis).map_or(0, |(_, axis)| axis),
                });
        }
        if let Some(kind) = found {
            self.raise(kind, now);
        }
    }

    fn compute(&mut self, now: f64, dt: f64) {
        let active = self.life.state() == State::Active;
        for (i, j) in self.joints.iter_mut().enumerate() {
            let counts = self.io.encoder_position(j.axis).unwrap_or(0);
            let sampled = self.sample_clock.get(j.board).copied().unwrap_or(now);
            let u = j.update(
                counts,
                self.io.analog_position(j.axis).ok(),
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
            if let Some(p) = self.pot.get_mut(i) {
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
        for j in &self.joints {
            let _ = self.io.set_motor_command(j.axis, j.command(active));
        }
    }
}
