//! The runner: one robot program's servo loop over the host library's
//! abstract robot I/O ([`RobotIo`]), the same code for QLA boards
//! ([`IoSystem`](firelink_host::qla::io::IoSystem)) and seed 001's Snake nodes
//! ([`SnakeSystem`](firelink_host::snake::SnakeSystem)).
//!
//! [`Robot`] ties a configuration ([`IoConfig`]) to the axes of its I/O
//! system: each actuator `(board_id, axis_id)` is mapped to an axis once,
//! at setup, and every [`Robot::cycle`] is (ros2_control's read / update /
//! write)
//!
//! 1. `latch_all_inputs`, then the checks: every expected board answered
//!    ([`Lifecycle::check_cycle`], with the miss reason turned into a
//!    [`FaultKind`]), no watchdog expired, power and amplifiers still on
//!    while Active;
//! 2. compute: encoder and pot to SI (pots mounted on joints turned back
//!    into actuator space), homing offsets, velocity on the boards' own
//!    sample clock, a per-joint trajectory sample and PID to a current, the
//!    [`SafetyMonitor`], current to DAC code;
//! 3. `apply_all_outputs`.
//!
//! Any fault moves the lifecycle to Fault and from then on every cycle
//! commands zero current with every amplifier off, and tells each board
//! directly until it acknowledges; the report says what happened
//! ([`Robot::fault`]). Stop-search homing (the dVRK console's MTM roll) is
//! in [`Robot::search_stop`].
//!
//! The cycle allocates nothing: every buffer is sized at setup and the
//! statistics go into preallocated vectors (the port may allocate: the
//! simulated bus builds packets).
//!
//! Time: the runner reads the port's clock ([`RobotIo::now`], virtual on
//! the simulated bus); [`Pacing::WallClock`] and the compute-time
//! measurement also read the machine's monotonic clock. This is the one
//! place below the CLI that does.

pub(crate) mod joint;
mod record;
mod stop_search;
pub(crate) mod velocity;

pub(crate) use record::ArmAcc;
pub use record::{ArmTracking, CycleTimes, Percentiles};
pub use stop_search::{StopFound, StopSearchProblem};

use joint::{Joint, Pacer};

use std::time::{Duration, Instant};

use firelink_host::cycle_report::{CycleReport, IoStats};
use firelink_host::stop::{StopReason, StopRequest};
use firelink_host::{BoardStatus, HostError, MissReason, PowerDown, RobotIo, WatchdogSetting};
use firelink_wire::phy::SYSTEM_CLOCK_HZ;
use firelink_wire::qla::MAX_BOARDS;

use crate::config::{IoConfig, StopSearchConfig};
use crate::fault::{FaultKind, FaultReport};
use crate::homing::{Homing, HomingError, HomingSettings, HomingStep};
use crate::label::{BoardSet, Label};
use crate::lifecycle::{Lifecycle, LifecycleError, PowerStatus, State};
use crate::period::ServoPeriod;
use crate::pid::{Pid, PidError, PidGains};
use crate::safety::{JointSample, SafetyMonitor};
use crate::trajectory::{Motion, SinCosMemo};

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
    /// The servo period (its rate: [`ServoPeriod::rate_hz`]).
    pub period: ServoPeriod,
    /// Board watchdog.
    pub watchdog: WatchdogSetting,
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
            period: ServoPeriod::KHZ_1,
            watchdog: WatchdogSetting::default(),
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
    #[error("lifecycle: {0}")]
    Lifecycle(#[from] LifecycleError),
    /// Homing failed.
    #[error("homing: {0}")]
    Homing(HomingError),
    /// Invalid PID gains in the configuration.
    #[error("{0}")]
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
    /// A stop was requested (a signal, the caller): the loop returned
    /// between cycles.
    #[error("stopped by {0}")]
    Stopped(StopReason),
}

/// One robot program: configuration, I/O, lifecycle, controllers.
pub struct Robot<R: RobotIo> {
    io: R,
    settings: RobotSettings,
    /// Joints: `board` is the board ID, `axis` the I/O system's axis.
    joints: Vec<Joint>,
    pids: Vec<Pid>,
    arm_names: Vec<String>,
    arm_acc: Vec<ArmAcc>,
    /// Every joint's `(board ID, axis on the board, joint)`, in that
    /// order: the order the per-board checks report in.
    by_board: Vec<(u8, u8, usize)>,
    /// Per board ID: the axes its joints use (bit i = axis i), to check
    /// their amplifiers with one call per board; `None` when an axis is
    /// beyond 63 (then joint by joint).
    used_amps: Option<[u64; MAX_BOARDS]>,
    expected: BoardSet,
    life: Lifecycle,
    safety: SafetyMonitor,
    homing: Homing,
    samples: Vec<JointSample>,
    /// Per board ID: the boards' own clock at its last fresh sample,
    /// seconds (the read block's timestamp counts the 49.152 MHz clocks
    /// between samples). Velocities are differenced on this clock: it is
    /// when the encoders were sampled, whatever the host's or the
    /// network's jitter.
    sample_clock: [f64; MAX_BOARDS],
    /// Per board ID: the expected boards as the last latch found them
    /// (read once per cycle for the clock and the checks).
    board_status: [BoardStatus; MAX_BOARDS],
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
    /// Per I/O axis: the latch's encoder counts (0 where the I/O system
    /// has no reading) and pot codes (`None`: no reading), read for every
    /// axis in one call ([`RobotIo::axis_inputs`]).
    axis_counts: Vec<i32>,
    axis_pots: Vec<Option<u16>>,
    /// Per I/O axis: the cycle's DAC code, `None` for an axis no joint or
    /// brake drives; the joints' codes are put in in joint order, then the
    /// brakes' (a later one on the same axis wins), and written in one
    /// call ([`RobotIo::set_motor_commands`]).
    axis_codes: Vec<Option<u16>>,
    times: CycleTimes,
    cycle: u64,
    last_start: Option<Duration>,
    last_report: Option<CycleReport>,
    /// Boards that acknowledged the fault path's direct "amplifiers off"
    /// (bit i = board ID i), since the fault.
    disabled_acknowledged: u16,
    fault: Option<FaultReport>,
    pacer: Pacer,
    /// Checked between cycles by every loop of the runner.
    stop: StopRequest,
    /// What [`configure`](Robot::configure) found left by an earlier
    /// program.
    found_at_configure: Option<LeftOver>,
    /// The last power-down's findings.
    last_power_down: Option<PowerDown>,
    /// The robots' brakes, as the console drives them.
    brakes: Vec<BrakeChannel>,
    /// When the brakes were last released (power on), seconds.
    brakes_released_at: Option<f64>,
}

/// What [`Robot::configure`] found on the expected boards before taking
/// them over (bit i = board ID i): the state an earlier program that did
/// not power down (a crash, a `kill -9`, a lost link) left them in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LeftOver {
    /// Boards with motor power on.
    pub powered: u16,
    /// Boards with an amplifier on.
    pub amplifiers: u16,
    /// Of the boards found powered, those whose watchdog had timed out
    /// (STATUS bit 23: the earlier program stopped writing; it clears when
    /// motor power is next switched on, as the firmware allows). On an
    /// unpowered board the flag is the normal idle state (nobody writes to
    /// it) and is not reported.
    pub watchdog_timed_out: u16,
    /// Expected boards that did not answer.
    pub silent: u16,
    /// Expected boards this program itself energised before (e.g. ahead
    /// of a fault it is configuring out of): not read, not taken over.
    pub own: u16,
    /// The power-down this took, if any board was powered.
    pub powered_down: Option<PowerDown>,
}

impl LeftOver {
    /// Whether the boards were found as a clean start leaves them (power
    /// and amplifiers off).
    pub fn is_clean(&self) -> bool {
        self.powered == 0 && self.amplifiers == 0
    }
}

impl core::fmt::Display for LeftOver {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        use firelink_host::robot_io::board_list;
        if self.is_clean() {
            return if self.own != 0 {
                write!(
                    f,
                    "boards {} kept as this program left them (not taken over)",
                    board_list(self.own)
                )
            } else {
                f.write_str("boards found powered off")
            };
        }
        let mut parts = Vec::new();
        if self.powered != 0 {
            parts.push(format!(
                "motor power on at boards {}",
                board_list(self.powered)
            ));
        }
        if self.amplifiers != 0 {
            parts.push(format!(
                "amplifiers on at boards {}",
                board_list(self.amplifiers)
            ));
        }
        if self.watchdog_timed_out != 0 {
            parts.push(format!(
                "watchdog timed out at boards {}",
                board_list(self.watchdog_timed_out)
            ));
        }
        write!(
            f,
            "found {} (left by an earlier program that did not power down)",
            parts.join(", ")
        )?;
        if let Some(p) = &self.powered_down {
            write!(f, "; powered down: {p}")?;
        }
        if self.watchdog_timed_out != 0 {
            f.write_str("; the watchdog flag clears at the next power-on")?;
        }
        Ok(())
    }
}

/// The joint-to-joint pot mixing of `config`'s robots (pots mounted on
/// joints, v6 coupling), or nothing when no robot has a coupling.
fn pot_mix(config: &IoConfig) -> Vec<(usize, usize, f64)> {
    let mut mix = Vec::new();
    if !config.robots.iter().any(|r| r.pot_coupling().is_some()) {
        return mix;
    }
    let mut base = 0;
    for r in &config.robots {
        let m = r.pot_coupling();
        for t in 0..r.actuators.len() {
            match &m {
                Some(m) => mix.extend(
                    (0..r.actuators.len())
                        .map(|s| (base + t, base + s, m.get(t, s)))
                        .filter(|&(_, _, w)| w != 0.0),
                ),
                None => mix.push((base + t, base + t, 1.0)),
            }
        }
        base += r.actuators.len();
    }
    mix
}

/// One brake's amplifier channel and the commands the console gives it:
/// `release` for `release_time` after power on, then `hold`; `engaged`
/// whenever the robot is not powered and running.
#[derive(Debug, Clone, Copy)]
struct BrakeChannel {
    axis: usize,
    release: u16,
    hold: u16,
    engaged: u16,
    release_time: f64,
}

impl BrakeChannel {
    /// The brake `b` on I/O axis `axis`.
    fn new(axis: usize, b: &crate::config::BrakeConfig) -> BrakeChannel {
        let f = b.drive.current_to_bits;
        let code = |amps: f64| {
            let c = (f.scale * amps + f.offset).round();
            if c.is_finite() {
                c.clamp(0.0, 65535.0) as u16
            } else {
                0x8000
            }
        };
        let release = b.opening_current().unwrap_or(0.0);
        BrakeChannel {
            axis,
            release: code(release),
            hold: code(b.holding_current().unwrap_or(release)),
            engaged: code(b.engaged_current.unwrap_or(0.0)),
            release_time: b.release_time.unwrap_or(0.0).max(0.0),
        }
    }
}

/// Of the `expected` boards, those that answered the cycle of `report`,
/// and the fault of the first (by ID) that did not: its miss reason turned
/// into a fault kind (a corrupt query is a sequence fault; anything else a
/// missed board, named with the robot `life` says owns it).
fn answered_boards(
    expected: BoardSet,
    life: &Lifecycle,
    report: &CycleReport,
) -> (BoardSet, Option<FaultKind>) {
    // (The boards with a miss reason, as `missed_boards` lists them: the
    // report's `missed` mask, which `CycleReport::note_miss` sets with
    // each reason, bit i = board ID i.)
    let answered = expected.minus(BoardSet(report.missed));
    let missing = expected.minus(answered).first().map(|id| {
        let reason = report.reasons.get(usize::from(id)).copied().flatten();
        match reason {
            Some(MissReason::CorruptQuery) => FaultKind::Sequence {
                board_id: id,
                expected: report
                    .query_seq
                    .get(usize::from(id))
                    .copied()
                    .filter(|&s| s != 0)
                    .unwrap_or(report.seq),
                received: 0xFFFF,
            },
            _ => FaultKind::MissedBoard {
                board_id: id,
                robot: life.board_owner(id),
            },
        }
    });
    (answered, missing)
}

impl<R: RobotIo> Robot<R> {
    /// A robot for `config` over the axes of `io`.
    ///
    /// # Errors
    /// [`RunnerError::Config`] for an actuator whose board is not among
    /// the boards found or has no such axis (naming the joint); [`RunnerError::Pid`] for invalid gains. (A
    /// missing board is also what [`configure`](Self::configure) refuses,
    /// with the robot named.)
    pub fn new(io: R, config: &IoConfig, settings: RobotSettings) -> Result<Robot<R>, RunnerError> {
        let mut joints = Vec::new();
        let mut pids = Vec::new();
        let mut by_board = Vec::new();
        for j in config.joints() {
            let a = j.actuator;
            let Some(axis) = io.axis_index(a.board_id, a.axis_id) else {
                let found = BoardSet(io.boards()).contains(a.board_id);
                return Err(RunnerError::Config(if found {
                    format!(
                        "{}: board {} has no axis {}",
                        j.label.as_str(),
                        a.board_id,
                        a.axis_id
                    )
                } else {
                    format!(
                        "{}: board {} is not on the bus",
                        j.label.as_str(),
                        a.board_id
                    )
                }));
            };
            let gains = a
                .simulation
                .and_then(|s| s.pid)
                .unwrap_or_else(|| PidGains::pd(1.0, 0.05));
            pids.push(Pid::new(gains, a.drive.maximum_current).map_err(RunnerError::Pid)?);
            by_board.push((a.board_id, a.axis_id, joints.len()));
            joints.push(Joint::new(&j, usize::from(a.board_id), axis));
        }
        let mut brakes = Vec::new();
        let mut brake_amps = Vec::new();
        for r in &config.robots {
            for (bi, b) in r.brakes.iter().flatten().enumerate() {
                let Some(axis) = io.axis_index(b.board_id, b.axis_id) else {
                    return Err(RunnerError::Config(format!(
                        "{}: brake {bi}: board {} axis {} is not on the bus",
                        r.name, b.board_id, b.axis_id
                    )));
                };
                brake_amps.push((b.board_id, b.axis_id));
                brakes.push(BrakeChannel::new(axis, b));
            }
        }
        by_board.sort_unstable();
        let used_amps = by_board
            .iter()
            .map(|&(board, axis, _)| (board, axis))
            .chain(brake_amps.iter().copied())
            .try_fold([0u64; MAX_BOARDS], |mut used, (board, axis)| {
                let bit = 1u64.checked_shl(u32::from(axis))?;
                *used.get_mut(usize::from(board))? |= bit;
                Some(used)
            });
        let n = joints.len();
        // (Every joint's and brake's axis is below the axis count.)
        let axes = io.axis_count();
        let arm_names: Vec<String> = config.robots.iter().map(|r| r.name.clone()).collect();
        Ok(Robot {
            io,
            settings,
            joints,
            pids,
            arm_acc: vec![ArmAcc::default(); arm_names.len()],
            arm_names,
            by_board,
            used_amps,
            expected: config.board_set(),
            life: Lifecycle::from_config(config),
            safety: SafetyMonitor::from_config(config),
            homing: Homing::from_config(config, settings.homing),
            samples: vec![JointSample::default(); n],
            sample_clock: [0.0; MAX_BOARDS],
            board_status: [BoardStatus::default(); MAX_BOARDS],
            raw_pot: vec![0.0; n],
            pot_mix: pot_mix(config),
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
            axis_counts: vec![0; axes],
            axis_pots: vec![None; axes],
            axis_codes: vec![None; axes],
            times: CycleTimes::with_capacity(settings.max_samples),
            cycle: 0,
            last_start: None,
            last_report: None,
            disabled_acknowledged: 0,
            fault: None,
            pacer: Pacer::default(),
            stop: StopRequest::process(),
            found_at_configure: None,
            last_power_down: None,
            brakes,
            brakes_released_at: None,
        })
    }

    /// The I/O system.
    pub fn io(&self) -> &R {
        &self.io
    }

    /// The I/O system, mutable (fault injection, register access,
    /// hardware-specific calls).
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

    /// The label of joint `i` (`ROBOT[k]`).
    pub fn joint_label(&self, i: usize) -> Option<Label> {
        self.joints.get(i).map(|j| j.label)
    }

    /// The arm names, in configuration order.
    pub fn arm_names(&self) -> &[String] {
        &self.arm_names
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

    /// Joint `i`'s position by its potentiometer, in actuator space (NaN
    /// for a joint without a pot), as of the last cycle.
    pub fn potentiometer(&self, i: usize) -> Option<f64> {
        self.pot.get(i).copied()
    }

    /// The current joint `i`'s amplifier measured, A, as of the last cycle
    /// (`None` when its board did not answer).
    pub fn measured_current(&self, i: usize) -> Option<f64> {
        let j = self.joints.get(i)?;
        if !self.io.board_answered(j.board as u8) {
            return None;
        }
        let bits = self.io.motor_current(j.axis).ok()?;
        Some(j.drive.bits_to_current(bits))
    }

    /// Timing record.
    pub fn times(&self) -> &CycleTimes {
        &self.times
    }

    /// The period, seconds.
    pub fn period(&self) -> f64 {
        self.settings.period.as_secs_f64()
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

    /// Forget the tracking statistics (e.g. after homing).
    pub fn reset_tracking(&mut self) {
        self.arm_acc.fill(ArmAcc::default());
    }

    /// Boards found, as a set.
    pub fn found(&self) -> BoardSet {
        BoardSet(self.io.boards())
    }

    /// Power and amplifier state of the boards found, as of the last
    /// latch: powered when a board answered with its motor power on;
    /// amplifiers enabled when it answered with every amplifier a joint
    /// uses on.
    pub fn power_status(&self) -> PowerStatus {
        let mut s = PowerStatus {
            powered: BoardSet::EMPTY,
            amplifiers_enabled: BoardSet::EMPTY,
        };
        for id in (0..MAX_BOARDS as u8).filter(|id| self.found().contains(*id)) {
            if self.io.powered(id) {
                s.powered.insert(id);
            }
            let all = self
                .by_board
                .iter()
                .filter(|&&(board, ..)| board == id)
                .all(|&(.., i)| self.amplifier_on(i));
            if self.io.board_answered(id) && all {
                s.amplifiers_enabled.insert(id);
            }
        }
        s
    }

    /// Whether joint `i`'s amplifier was on at the last latch (its board
    /// answering).
    fn amplifier_on(&self, i: usize) -> bool {
        self.joints
            .get(i)
            .is_some_and(|j| self.io.amplifier_enabled(j.axis).unwrap_or(false))
    }

    /// Whether any used amplifier is on, on the boards that answered the
    /// last latch (a board that does not answer cannot say; its own
    /// watchdog turns its amplifiers off).
    pub fn any_amp_on(&self) -> bool {
        (0..self.joints.len()).any(|i| self.amplifier_on(i))
    }

    /// Unconfigured -> Configured: every expected board was found; the
    /// boards are read once, and any an earlier program left powered or
    /// with an amplifier on (a crash, a `kill -9`) are powered down first
    /// ([`LeftOver`], also kept in
    /// [`found_at_configure`](Self::found_at_configure)); then the board
    /// watchdogs are set. A watchdog flag latched by that earlier program
    /// is harmless while power is off and clears at power-on.
    ///
    /// # Errors
    /// The lifecycle's refusal (the first missing board, with its robot);
    /// port errors setting the watchdog.
    pub fn configure(&mut self) -> Result<LeftOver, RunnerError> {
        self.check_stop()?;
        self.life.configure(self.found())?;
        let left = self.take_over();
        self.io.set_watchdog(self.settings.watchdog)?;
        Ok(left)
    }

    /// Read the expected boards once; power down any left energised by
    /// another program (boards this program energised itself, e.g. before
    /// a fault it is now configuring out of, are its own business: not
    /// read, not reported).
    fn take_over(&mut self) -> LeftOver {
        let mut left = LeftOver {
            own: self.expected.0 & self.io.energised(),
            ..LeftOver::default()
        };
        let others = self.expected.0 & !left.own;
        if others == 0 {
            self.found_at_configure = Some(left);
            return left;
        }
        self.io.latch_all_inputs();
        for id in self.expected.iter().filter(|id| others & (1 << id) != 0) {
            let s = self.io.board_status(id);
            let bit = 1u16 << id;
            if !s.answered {
                left.silent |= bit;
                continue;
            }
            if s.powered && self.io.switches_power() {
                left.powered |= bit;
            }
            if s.amplifiers != 0 {
                left.amplifiers |= bit;
            }
            if s.watchdog_expired && (s.powered || s.amplifiers != 0) {
                left.watchdog_timed_out |= bit;
            }
        }
        if left.powered | left.amplifiers != 0 {
            let done = self.io.power_down();
            self.last_power_down = Some(done);
            left.powered_down = Some(done);
        }
        self.found_at_configure = Some(left);
        left
    }

    /// What [`configure`](Self::configure) found left by an earlier program.
    pub fn found_at_configure(&self) -> Option<&LeftOver> {
        self.found_at_configure.as_ref()
    }

    /// The request every loop of this robot obeys (by default the
    /// process's own, which [`firelink_host::stop::install_signal_handlers`]
    /// sets on SIGINT, SIGTERM and SIGHUP).
    pub fn stop_request(&self) -> &StopRequest {
        &self.stop
    }

    /// Obey `stop` instead of the process's request.
    pub fn set_stop_request(&mut self, stop: StopRequest) {
        self.stop = stop;
    }

    /// [`RunnerError::Stopped`] once a stop was requested.
    fn check_stop(&self) -> Result<(), RunnerError> {
        match self.stop.reason() {
            Some(reason) => Err(RunnerError::Stopped(reason)),
            None => Ok(()),
        }
    }

    /// A cycle, unless a stop was requested: the loops' step (the check is
    /// one atomic load).
    pub(crate) fn step_unless_stopped(&mut self, pacing: Pacing) -> Result<(), RunnerError> {
        self.check_stop()?;
        self.step(pacing)
    }

    /// Motor power on the expected boards, then every used amplifier,
    /// waiting (cycling) until the boards report them.
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
            return Err(RunnerError::Lifecycle(LifecycleError::NotConfigured {
                state: self.life.state(),
            }));
        }
        let expected = self.expected;
        self.io.set_power(expected.0, true);
        self.wait_for("motor power", each, |s| {
            expected.minus(s.powered).is_empty()
        })?;
        for j in &self.joints {
            let _ = self.io.set_amplifier_enable(j.axis, true);
        }
        // The brakes are released as the arm is powered.
        for b in &self.brakes {
            let _ = self.io.set_amplifier_enable(b.axis, true);
        }
        self.brakes_released_at = Some(self.now());
        self.wait_for("amplifiers", each, |s| {
            expected.minus(s.amplifiers_enabled).is_empty()
        })
    }

    /// The amplifiers of the axes the joints use on (no other axis),
    /// waiting (cycling, calling `each` after every cycle) until the
    /// boards report them: from Configured once every expected board has
    /// motor power, or from Active (where they are on already).
    ///
    /// # Errors
    /// [`LifecycleError::NotPowered`] (the first expected board without
    /// motor power) in Configured; [`LifecycleError::NotActive`] in
    /// Unconfigured or Fault; a fault or [`RunnerError::Timeout`] while
    /// waiting.
    pub fn enable_amplifiers_observed(
        &mut self,
        each: &mut dyn FnMut(&Self),
    ) -> Result<(), RunnerError> {
        match self.life.state() {
            State::Active => {}
            State::Configured => {
                if let Some(id) = self.expected.minus(self.power_status().powered).first() {
                    let robot = self.life.board_owner(id);
                    return Err(LifecycleError::NotPowered {
                        board_id: id,
                        robot,
                    }
                    .into());
                }
            }
            state => return Err(LifecycleError::NotConfigured { state }.into()),
        }
        for j in &self.joints {
            let _ = self.io.set_amplifier_enable(j.axis, true);
        }
        let expected = self.expected;
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
            let r = self.step_unless_stopped(Pacing::Virtual);
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
        let h = self.settings.homing;
        let limit = 10 * (h.averaging_samples + h.verify_samples) + 10;
        for _ in 0..limit {
            self.step_unless_stopped(Pacing::Virtual)?;
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

    /// Stream one servo point to joint `i` (CRTK `servo_jp`): the point
    /// replaces the joint's motion, but unlike
    /// [`set_motion`](Self::set_motion) the safety monitor's grace timers
    /// keep running: a stream of points is one motion, and a following
    /// error that lasts across points trips as it would in one move.
    ///
    /// # Errors
    /// As [`set_motion`](Self::set_motion).
    pub fn servo_point(
        &mut self,
        i: usize,
        point: crate::trajectory::ServoPoint,
    ) -> Result<(), RunnerError> {
        self.life.require_motion()?;
        let now = self.now();
        joint::start_motion(&mut self.joints, i, Motion::Servo(point), now)
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

    /// Active -> Configured (if Active), then the one power-down rule on
    /// every board found ([`RobotIo::power_down`]: amplifiers off, then
    /// motor power off, the watchdog left running); returns what the
    /// boards said afterwards. Also the way out after a fault. Runs
    /// whatever the stop request says.
    ///
    /// # Errors
    /// Never today (the findings say which boards did not answer).
    pub fn shutdown(&mut self) -> Result<PowerDown, RunnerError> {
        if self.life.state() == State::Active {
            self.life.deactivate()?;
        }
        let done = self.io.power_down();
        self.last_power_down = Some(done);
        Ok(done)
    }

    /// The last power-down's findings (shutdown, or configure's take-over).
    pub fn last_power_down(&self) -> Option<&PowerDown> {
        self.last_power_down.as_ref()
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
        mut progress: impl FnMut(&Robot<R>),
    ) -> Result<(), RunnerError> {
        self.pacer.restart();
        for k in 0..cycles {
            self.step_unless_stopped(pacing)?;
            if progress_every > 0 && (k + 1) % progress_every == 0 {
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
        let period = self.settings.period.as_duration();
        self.pacer.before_cycle(pacing, period, &mut self.times);
        let started = self.io.now();
        let r = self.cycle();
        // A bus reset renumbers nodes: find the boards again between
        // cycles, never inside one (a failed attempt is retried after the
        // next cycle).
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
        // What the checks need of the latch's report, read where it is
        // (no copy of the report).
        let latched = self.io.latch_all_inputs();
        let compute_start = Instant::now();
        let started = latched.started;
        let (answered, missing) = answered_boards(self.expected, &self.life, latched);
        let now = started.as_secs_f64();
        let dt = match self.last_start {
            Some(t) => started.saturating_sub(t).as_secs_f64(),
            None => self.period(),
        }
        .clamp(0.1 * self.period(), 10.0 * self.period());
        self.last_start = Some(started);
        // (Only the boards the joints are on: no other clock is read.)
        for id in self.expected.iter() {
            let status = self.io.board_status(id);
            if let Some(s) = self.board_status.get_mut(usize::from(id)) {
                *s = status;
            }
            let clock = self.sample_clock.get_mut(usize::from(id));
            if let (Some(clock), Some(ts)) = (clock, status.timestamp) {
                // A board that reports no timestamp: the host's interval.
                *clock += if ts == 0 {
                    dt
                } else {
                    f64::from(ts) / f64::from(SYSTEM_CLOCK_HZ)
                };
            }
        }
        self.check(answered, missing, now);
        self.compute(now, dt);
        if self.life.state() == State::Fault {
            self.io.set_all_safe();
        }
        let compute = compute_start.elapsed();
        if self.life.state() == State::Fault {
            // The broadcast command below says "amplifiers off"; a packet
            // lost on the bus must not leave them on: tell each board that
            // has not acknowledged it yet, directly (inside the cycle, so
            // its errors are in the cycle's report).
            let pending = self.expected.0 & !self.disabled_acknowledged;
            if pending != 0 {
                self.disabled_acknowledged |= self.io.disable_amplifiers_acknowledged(pending);
            }
        }
        let report = self.last_report.insert(*self.io.apply_all_outputs());
        let io_time = report.io_time();
        self.times.record(io_time, compute);
        match self.fault {
            Some(f) => Err(f),
            None => Ok(()),
        }
    }

    fn raise(&mut self, kind: FaultKind, now: f64) {
        let r = self.life.fault(FaultReport::new(now, self.cycle, kind));
        self.keep_first(r);
    }

    /// Keep `r` unless a fault was reported before.
    fn keep_first(&mut self, r: FaultReport) {
        if self.fault.is_none() {
            self.fault = Some(r);
        }
    }

    /// The cycle's checks of the boards: `answered` and `missing` are
    /// what [`answered_boards`] found in the latch's report.
    fn check(&mut self, answered: BoardSet, missing: Option<FaultKind>, now: f64) {
        if !self.life.reads_inputs() {
            return;
        }
        if let Some(kind) = missing {
            self.raise(kind, now);
            return;
        }
        // Lifecycle's own working-counter check (records nothing new here).
        if let Err(r) = self.life.check_cycle(answered, now, self.cycle) {
            self.keep_first(r);
            return;
        }
        if let Some(kind) = self.board_fault() {
            self.raise(kind, now);
        }
    }

    /// The first expected board (by ID) whose watchdog expired, whose
    /// power went off while Active, or one of whose used amplifiers went
    /// off while Active (its lowest axis).
    fn board_fault(&self) -> Option<FaultKind> {
        let active = self.life.state() == State::Active;
        // `by_board` is sorted by board ID: each board's joints are the
        // next run of it (walked once per cycle, not once per board).
        let mut joints = self.by_board.as_slice();
        for id in self.expected.iter() {
            // (As the cycle's latch found it.)
            let status = self
                .board_status
                .get(usize::from(id))
                .copied()
                .unwrap_or_default();
            let powered = status.powered;
            // Before power is on a timed-out watchdog is harmless (nothing
            // to turn off); from power on, it is a fault.
            if status.watchdog_expired && (active || powered) {
                return Some(FaultKind::Watchdog { board_id: id });
            }
            if !active {
                continue;
            }
            if !powered {
                return Some(FaultKind::Power { board_id: id });
            }
            if let Some(used) = &self.used_amps {
                let used = used.get(usize::from(id)).copied().unwrap_or(0);
                let off = used & !status.amplifiers;
                if off != 0 {
                    let axis_id = off.trailing_zeros() as u8;
                    return Some(FaultKind::Amplifier {
                        board_id: id,
                        axis_id,
                    });
                }
                continue;
            }
            let below = joints.iter().take_while(|&&(board, ..)| board < id).count();
            let from = joints.get(below..).unwrap_or_default();
            let on = from.iter().take_while(|&&(board, ..)| board == id).count();
            let (of_board, rest) = from.split_at(on);
            joints = rest;
            let off = of_board.iter().find(|&&(_, _, i)| !self.amplifier_on(i));
            if let Some(&(board_id, axis_id, _)) = off {
                return Some(FaultKind::Amplifier { board_id, axis_id });
            }
        }
        None
    }

    /// Pots mounted on joints: every joint's pot position as read
    /// (`raw_pot`) turned into actuator space through the robots' pot
    /// couplings.
    fn mix_pots(&mut self) {
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
        // Each joint's cycle (measure, setpoint, control) depends on no
        // other joint's, except through the pot coupling: without one,
        // each joint's measure and control in one pass over the joints
        // (one loop's overhead instead of three), its setpoint planned in
        // that pass too unless Active (then in a pass before); with one,
        // every joint is measured before the pots are mixed and the joints
        // controlled.
        self.io
            .axis_inputs(&mut self.axis_counts, &mut self.axis_pots);
        // The sinusoids' sines and cosines of this cycle, each angle
        // computed once (the same bits for every joint at that angle).
        let mut memo = SinCosMemo::default();
        if active && !coupled {
            // Active, a joint's setpoint depends on its motion and the
            // time alone, not on its measurement: every setpoint first, in
            // a loop of its own (the trajectories' calls, `sincos`, then
            // interrupt a short loop rather than the long one below, which
            // needs every value it keeps live around them). Otherwise the
            // setpoint is the position just measured.
            for j in self.joints.iter_mut() {
                j.plan(now, true, &mut memo);
            }
        }
        let joints = self.joints.iter_mut().zip(&mut self.samples);
        let pots = self
            .enc
            .iter_mut()
            .zip(&mut self.pot)
            .zip(&mut self.raw_pot);
        let joints = joints.zip(pots).zip(self.pids.iter_mut());
        if coupled {
            for (((j, s), ((e, _), raw)), _) in joints {
                let counts = self.axis_counts.get(j.axis).copied().unwrap_or(0);
                let sampled = self.sample_clock.get(j.board).copied().unwrap_or(now);
                *e = j.measure(counts, sampled, s);
                // Pots on joints are read where they are, then mixed.
                *raw = j.pot_position(self.axis_pots.get(j.axis).copied().flatten());
            }
            // The pot reads the joint; the safety monitor compares the
            // encoder with it in actuator space.
            self.mix_pots();
            for j in self.joints.iter_mut() {
                j.plan(now, active, &mut memo);
            }
            let joints = self.joints.iter_mut().zip(&mut self.samples);
            for (i, ((j, s), p)) in joints.zip(&self.pot).enumerate() {
                let (pid, acc) = (self.pids.get_mut(i), self.arm_acc.get_mut(j.arm));
                j.control(dt, active, *p, pid, acc, s);
            }
        } else {
            // (Active, the setpoints were planned above.)
            for (((j, s), ((e, p), _)), pid) in joints {
                let counts = self.axis_counts.get(j.axis).copied().unwrap_or(0);
                let sampled = self.sample_clock.get(j.board).copied().unwrap_or(now);
                *e = j.measure(counts, sampled, s);
                let pot = j.pot_position(self.axis_pots.get(j.axis).copied().flatten());
                *p = pot;
                if !active {
                    j.plan(now, false, &mut memo);
                }
                j.control(dt, active, pot, Some(pid), self.arm_acc.get_mut(j.arm), s);
            }
        }
        if active {
            if let Some(r) = self.safety.check(now, self.cycle, &self.samples) {
                let r = self.life.fault(r);
                self.keep_first(r);
            }
        }
        let active = self.life.state() == State::Active;
        // (Joints first, then the brakes: a later code on an axis wins.)
        for j in &self.joints {
            if let Some(code) = self.axis_codes.get_mut(j.axis) {
                *code = Some(j.command(active));
            }
        }
        let running = matches!(self.life.state(), State::Active | State::Configured);
        let since = self.brakes_released_at.filter(|_| running).map(|t| now - t);
        for b in &self.brakes {
            if let Some(code) = self.axis_codes.get_mut(b.axis) {
                *code = Some(match since {
                    Some(t) if t < b.release_time => b.release,
                    Some(_) => b.hold,
                    None => b.engaged,
                });
            }
        }
        self.io.set_motor_commands(&self.axis_codes);
    }
}
