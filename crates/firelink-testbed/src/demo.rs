//! The demo program every robot shares: configure, power on, home, follow
//! trajectories on every arm ([`motion_for`]), optionally inject a fault
//! half way, power off, and return a typed [`DemoReport`]. The dVRK's run
//! ([`crate::dvrk::demo`]) and the Snake system's
//! ([`crate::snake::demo`]) drive it ([`run_program`] over [`DemoIo`]).
//!
//! This is the library behind `firelink demo` and the Python package's
//! `run_demo`: callers choose the port ([`PortSpec`]), the options
//! (the robot's, e.g. [`crate::dvrk::demo::DemoOptions`]) and what to do
//! with progress ([`DemoProgress`]); the
//! report serialises to the JSON `firelink demo --json` prints, and
//! [`DemoReport::verdict`] says whether the run did what it was asked.
//!
//! Faults are a plan ([`FaultScript`]): a named preset ([`DemoFault`],
//! `--fault NAME`) or a script of the caller's (`--faults SCRIPT`), applied
//! by the port's [`FaultTarget`] (the rig's on `sim`, the emulator's on
//! `emulate`, the host's side on any other link) when the servo loop
//! reaches each entry's moment. In the demo, `start` is the first cycle of
//! the motion (after homing), `cycle=N` counts the motion's cycles from
//! there, and the fault moment (`t=` counts from it) is half way through
//! the motion. Following error, a motion fault rather than a wire fault,
//! is the demo's own.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;
use std::time::{Duration, Instant};

use serde::Serialize;

use firelink_bus::{DetailReport, SimDuration};
use firelink_control::config::IoConfig;
use firelink_control::runner::{
    CycleTimes, Pacing, Percentiles, Robot, RobotSettings, RunnerError,
};
use firelink_control::trajectory::{Motion, PointToPoint, Sinusoid};
use firelink_control::{FaultKind, FaultReport, ServoPeriod};
use firelink_host::cycle_report::IoStats;
use firelink_host::{Port, PowerDown, RobotIo, WatchdogSetting};
use firelink_wire::packet::Tcode;

use crate::TestbedError;
use crate::fault_script::{
    BoardFault, FaultMoment, FaultScript, FaultTarget, Occurrence, PacketEffect, PacketSelector,
    ScriptEntry, ScriptedFault,
};
pub use crate::port_spec::PortSpec;

/// The fault the demo injects half way through its motion: a named preset
/// whose wire and host part is a [`FaultScript`] ([`DemoFault::script`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DemoFault {
    /// No fault: the run must end without one.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Nothing: the run must end without a fault")
    )]
    None,
    /// The host stops sending for three watchdog periods
    /// (`host-pause@t=0us:for=...`).
    #[cfg_attr(
        feature = "clap",
        value(help = "The host stops sending for three watchdog periods")
    )]
    StopHost,
    /// The next broadcast query is corrupted on the wire
    /// (`corrupt@t=0us:tcode=0x0,offset=0x1800,count=1`): one bit of it,
    /// drawn from the run's seed, is flipped, so its CRC fails and the
    /// boards drop it; the query is lost (no board sees a changed value)
    /// and the host misses that cycle's answers.
    #[cfg_attr(
        feature = "clap",
        value(help = "The next broadcast query is corrupted on the wire")
    )]
    CorruptQuery,
    /// Board 4 stops answering for good (`mute@t=0us:id=4`; PSM1's first
    /// board in seed 000's dVRK; the ECM's DQLA in
    /// `configs/dvrk-dqla-rev9.json`).
    #[cfg_attr(
        feature = "clap",
        value(help = "PSM1's first board stops answering for good")
    )]
    BoardLoss,
    /// Joint 0's setpoint jumps further than it can follow (a motion
    /// fault, not a wire fault: no script).
    #[cfg_attr(
        feature = "clap",
        value(help = "Joint 0's setpoint jumps further than it can follow")
    )]
    FollowingError,
}

impl DemoFault {
    /// Every fault, in the order the CLI lists them.
    pub const ALL: [DemoFault; 5] = [
        DemoFault::None,
        DemoFault::StopHost,
        DemoFault::CorruptQuery,
        DemoFault::BoardLoss,
        DemoFault::FollowingError,
    ];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            DemoFault::None => "none",
            DemoFault::StopHost => "stop-host",
            DemoFault::CorruptQuery => "corrupt-query",
            DemoFault::BoardLoss => "board-loss",
            DemoFault::FollowingError => "following-error",
        }
    }

    /// Its wire and host faults, all at the fault moment; `watchdog` is the
    /// boards' period (a stopped host stays silent for three of them).
    pub fn script(self, watchdog: Duration) -> FaultScript {
        let now = FaultMoment::After(SimDuration::ZERO);
        let fault = match self {
            DemoFault::None | DemoFault::FollowingError => return FaultScript::new(),
            DemoFault::StopHost => ScriptedFault::HostPause(watchdog * 3),
            // The broadcast query: a quadlet write to the hub's query
            // register, lost to the CRC error of one flipped bit.
            DemoFault::CorruptQuery => ScriptedFault::Packets {
                effect: PacketEffect::Corrupt,
                select: PacketSelector {
                    tcode: Some(Tcode::WriteQuadletRequest),
                    dest: None,
                    offset: Some(0x1800),
                },
                occurrence: Occurrence::Count(1),
            },
            DemoFault::BoardLoss => ScriptedFault::Board(BoardFault::Mute(LOST_BOARD)),
        };
        FaultScript::new().with(now, fault)
    }
}

impl fmt::Display for DemoFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DemoFault {
    type Err = TestbedError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        DemoFault::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                TestbedError::Config(format!(
                    "unknown fault {s:?}: none, stop-host, corrupt-query, board-loss, following-error"
                ))
            })
    }
}

/// What the real-time setup of the calling thread achieved (the front end
/// asks for it, [`RealtimeStatus::take`]; the run only reports it).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct RealtimeStatus {
    /// Whether real-time settings were asked for at all.
    pub requested: bool,
    /// SCHED_FIFO at this priority, if it was granted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sched_fifo_priority: Option<i32>,
    /// mlockall succeeded.
    pub memory_locked: bool,
    /// The timer slack is 1 ns.
    pub timer_slack_1ns: bool,
    /// Why the others did not happen.
    pub errors: Vec<String>,
}

impl RealtimeStatus {
    /// Take the real-time settings for the calling thread (SCHED_FIFO at
    /// `priority`, locked memory, a 1 ns timer slack;
    /// [`crate::realtime::setup`]) and say what was granted; `spinning`:
    /// the thread's port reads spin (no SCHED_FIFO where real-time threads
    /// are throttled).
    pub fn take(priority: i32, spinning: bool) -> RealtimeStatus {
        let s = crate::realtime::setup(priority, spinning);
        RealtimeStatus {
            requested: true,
            sched_fifo_priority: s.sched_fifo,
            memory_locked: s.memory_locked,
            timer_slack_1ns: s.timer_slack_1ns,
            errors: s.errors,
        }
    }
}

/// What the demo is doing, for a progress display.
#[derive(Debug, Clone, PartialEq)]
pub enum DemoProgress {
    /// Boards found.
    Found {
        /// Boards.
        boards: usize,
        /// The port's name.
        port: String,
        /// Why this protocol.
        reason: String,
        /// The protocol in use.
        protocol: &'static str,
    },
    /// The watchdog is off: the caller should say so loudly.
    WatchdogOff,
    /// The boards were found as an earlier program left them (powered,
    /// amplifiers on, watchdog timed out) and taken over: what was found
    /// and done.
    TookOver(String),
    /// Boards configured.
    Configured,
    /// Power is on, at this port time (s).
    Powered(f64),
    /// Every joint homed and the robot active, at this port time (s).
    Homed(f64),
    /// A periodic tick while moving.
    Tick {
        /// Port time, s.
        t: f64,
        /// Cycles so far.
        cycles: u64,
        /// Median I/O time over the last 2000 cycles, us.
        io_median_us: f64,
        /// Errors so far.
        errors: u64,
    },
    /// The fault is being injected: the preset's name, or the script's
    /// entries now due.
    Injecting(String),
    /// The robot faulted.
    Fault(String),
    /// After the fault: the state and whether any amplifier is on.
    SafetyChain {
        /// Robot state.
        state: String,
        /// Any amplifier still on.
        amplifiers_on: bool,
    },
    /// Powered off, after this much wall time (s).
    PoweredOff(f64),
}

/// Median, p99, max and mean of a time series, microseconds (two decimals).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TimeStats {
    /// Median.
    pub median: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
}

impl TimeStats {
    pub(crate) fn of(samples: &mut [f32]) -> TimeStats {
        let p = Percentiles::of(samples);
        TimeStats {
            median: round2(p.median),
            p99: round2(p.p99),
            max: round2(p.max),
            mean: round2(p.mean),
        }
    }
}

fn round2(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

/// One arm's tracking error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackingDetail {
    /// Revolute joints: RMS error, rad.
    pub rms_rad: f64,
    /// Revolute joints: largest error, rad.
    pub max_rad: f64,
    /// Prismatic joints: RMS error, mm.
    pub prismatic_rms_mm: f64,
    /// Prismatic joints: largest error, mm.
    pub prismatic_max_mm: f64,
    /// Joint samples.
    pub samples: u64,
}

/// Errors by kind over the run: the host library's counters and their total.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorCounts {
    /// All errors.
    pub total: u64,
    /// By kind.
    #[serde(flatten)]
    pub by_kind: IoStats,
}

/// The I/O errors by kind, in one line (the demo's tables).
impl fmt::Display for ErrorCounts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = &self.by_kind;
        write!(
            f,
            "errors: total {}  timeouts {}  sequence {}  corrupt queries {}  bus resets {}  bad packets {}  nacks {}",
            self.total,
            e.timeouts,
            e.sequence_errors,
            e.corrupt_queries,
            e.bus_resets,
            e.bad_packets,
            e.nacks
        )
    }
}

impl From<&IoStats> for ErrorCounts {
    fn from(s: &IoStats) -> Self {
        ErrorCounts {
            total: s.total_errors(),
            by_kind: *s,
        }
    }
}

/// The watchdog setting and which boards' watchdogs expired.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WatchdogReport {
    /// Period, ms (0: off).
    pub period_ms: f64,
    /// Boards whose watchdog had expired at the end of the motion.
    pub expired_boards: Vec<u8>,
    /// Boards that did not answer at the end of the motion: whether their
    /// watchdog expired is not known.
    pub unknown_boards: Vec<u8>,
}

/// What the boards said after the final power-down (board IDs).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct PowerDownReport {
    /// Answered with motor power and every amplifier off.
    pub off: Vec<u8>,
    /// Did not answer: state unknown.
    pub unknown: Vec<u8>,
    /// Answered still powered or with an amplifier on.
    pub still_on: Vec<u8>,
    /// The watchdog had been off and was set back to its default period.
    pub watchdog_restored: bool,
}

fn ids(mask: u16) -> Vec<u8> {
    (0..16u8).filter(|id| mask & (1 << id) != 0).collect()
}

impl From<&PowerDown> for PowerDownReport {
    fn from(p: &PowerDown) -> Self {
        PowerDownReport {
            off: ids(p.off),
            unknown: ids(p.unknown),
            still_on: ids(p.still_on),
            watchdog_restored: p.watchdog_restored,
        }
    }
}

/// Board IDs for people: `0-3, 6`, or `none`.
fn board_ids(ids: &[u8]) -> String {
    let mask = ids.iter().fold(0u16, |m, id| {
        m | 1u16.checked_shl(u32::from(*id)).unwrap_or(0)
    });
    if mask == 0 {
        "none".into()
    } else {
        firelink_host::robot_io::board_list(mask)
    }
}

/// The fault the robot raised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FaultSummary {
    /// The fault's kind, e.g. `MissedBoard`.
    pub kind: String,
    /// The board it names, if any.
    pub board: Option<u8>,
    /// Port time, s.
    pub time_s: f64,
    /// Cycle.
    pub cycle: u64,
    /// One line for people.
    pub text: String,
}

impl From<&FaultReport> for FaultSummary {
    fn from(f: &FaultReport) -> Self {
        let kind = format!("{:?}", f.kind);
        let name = kind.split([' ', '{', '(']).next().unwrap_or("").to_string();
        let board = match f.kind {
            FaultKind::MissedBoard { board_id, .. }
            | FaultKind::Sequence { board_id, .. }
            | FaultKind::Watchdog { board_id }
            | FaultKind::Power { board_id }
            | FaultKind::Amplifier { board_id, .. } => Some(board_id),
            _ => None,
        };
        FaultSummary {
            kind: name,
            board,
            time_s: f.time,
            cycle: f.cycle,
            text: f.to_string(),
        }
    }
}

/// What a demo run did; serialises to `firelink demo --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoReport {
    /// The port's name.
    pub port: String,
    /// Boards found.
    pub boards: usize,
    /// Axes driven.
    pub axes: usize,
    /// Firmware of the first board.
    pub firmware: Option<u32>,
    /// I/O protocol used.
    pub protocol: String,
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// `virtual` or `realtime`.
    pub pacing: String,
    /// Servo cycles run.
    pub cycles: u64,
    /// Cycles after homing.
    pub motion_cycles: u64,
    /// Time on the port's clock at the end, s.
    pub port_time_s: f64,
    /// Wall time of the run, s.
    pub wall_time_s: f64,
    /// Virtual seconds per wall second.
    pub speed_vs_real_time: f64,
    /// Whole cycle time, us.
    pub cycle_time_us: TimeStats,
    /// I/O part of the cycle, us.
    pub io_time_us: TimeStats,
    /// Computation part of the cycle, us.
    pub compute_time_us: TimeStats,
    /// Late cycles (wall-clock pacing).
    pub overruns: u64,
    /// The calling thread's real-time settings.
    pub realtime: RealtimeStatus,
    /// RMS tracking error per arm over its revolute joints, rad.
    pub tracking_error: BTreeMap<String, f64>,
    /// What `tracking_error` measures.
    pub tracking_error_unit: &'static str,
    /// Tracking error per arm, every figure.
    pub tracking_error_detail: BTreeMap<String, TrackingDetail>,
    /// I/O errors by kind.
    pub errors: ErrorCounts,
    /// Watchdog.
    pub watchdog: WatchdogReport,
    /// The fault injected: the preset's name (`none` for none), or the
    /// script's text.
    pub fault_injected: String,
    /// The fault the robot raised, if any.
    pub fault: Option<FaultSummary>,
    /// State at the end of the motion.
    pub state_after_run: String,
    /// After a fault: whether any amplifier of the boards that answered
    /// was still on (those in `boards_not_answering` cannot say).
    pub amplifiers_on_after_fault: Option<bool>,
    /// Boards not answering at the end of the motion: their amplifier and
    /// watchdog state is unknown.
    pub boards_not_answering: Vec<u8>,
    /// What the boards said after the final power-down.
    pub power_down: PowerDownReport,
    /// Final state (after power-off).
    pub state: String,
    /// On the simulated bus: what ran at which level of detail (cycles
    /// and packets fast or at the packet level, and why).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<DetailReport>,
}

impl DemoReport {
    /// Whether the run did what it was asked: no fault when none was
    /// injected; with one injected, the fault detected and every amplifier
    /// off afterwards. The error says what went wrong.
    pub fn verdict(&self) -> Result<(), String> {
        let injected = self.fault_injected != DemoFault::None.name();
        match (&self.fault, injected) {
            (None, true) => Err(format!(
                "the injected fault {} was not detected",
                self.fault_injected
            )),
            (Some(_), false) => Err("the run ended in a fault".into()),
            (Some(_), true) if self.amplifiers_on_after_fault == Some(true) => {
                Err("amplifiers still on after the fault".into())
            }
            _ if !self.power_down.still_on.is_empty() => Err(format!(
                "boards {} still report power or an amplifier on after the power-down",
                board_ids(&self.power_down.still_on)
            )),
            _ => Ok(()),
        }
    }
}

impl fmt::Display for DemoReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let arms: Vec<&str> = self.tracking_error.keys().map(String::as_str).collect();
        writeln!(f, "Firelink demo: {} axes ({})", self.axes, arms.join(", "))?;
        writeln!(
            f,
            "  port {}  boards {}  axes {}  firmware {}  protocol {}  rate {} Hz  pacing {}",
            self.port,
            self.boards,
            self.axes,
            self.firmware.map_or("?".to_string(), |v| v.to_string()),
            self.protocol,
            self.rate_hz,
            self.pacing
        )?;
        writeln!(
            f,
            "  cycles {} ({} with motion), {:.3} s on the port's clock, {:.2} s wall ({:.2}x real time)",
            self.cycles,
            self.motion_cycles,
            self.port_time_s,
            self.wall_time_s,
            self.speed_vs_real_time
        )?;
        writeln!(
            f,
            "  late cycles (started over half a period late, wall-clock pacing): {}",
            self.overruns
        )?;
        if let Some(detail) = &self.detail {
            writeln!(f, "  {detail}")?;
        }
        for (name, p) in [
            ("cycle time", &self.cycle_time_us),
            ("I/O time", &self.io_time_us),
            ("compute", &self.compute_time_us),
        ] {
            writeln!(
                f,
                "  {name:<10} median {:8.2} us  p99 {:8.2} us  max {:8.2} us",
                p.median, p.p99, p.max
            )?;
        }
        writeln!(f, "  tracking error (RMS; revolute rad, prismatic mm):")?;
        for (arm, t) in &self.tracking_error_detail {
            writeln!(
                f,
                "    {arm:<5} {:.5} rad (max {:.5})  prismatic {:.3} mm (max {:.3})",
                t.rms_rad, t.max_rad, t.prismatic_rms_mm, t.prismatic_max_mm
            )?;
        }
        writeln!(f, "  {}", self.errors)?;
        let watchdog = if self.watchdog.period_ms > 0.0 {
            format!(
                "{} ms",
                firelink_wire::human::Number(self.watchdog.period_ms)
            )
        } else {
            "OFF".into()
        };
        write!(
            f,
            "  watchdog: {watchdog}, expired on boards {}",
            board_ids(&self.watchdog.expired_boards)
        )?;
        if !self.watchdog.unknown_boards.is_empty() {
            write!(
                f,
                "; boards {} not answering: unknown",
                board_ids(&self.watchdog.unknown_boards)
            )?;
        }
        writeln!(f)?;
        match &self.fault {
            None => writeln!(f, "  faults: none; final state {}", self.state)?,
            Some(fl) => {
                let answering = if self.boards_not_answering.is_empty() {
                    String::new()
                } else {
                    " on the boards that answer".into()
                };
                writeln!(
                    f,
                    "  FAULT ({} injected): {}\n  safety chain: left active, amplifiers {}{answering}",
                    self.fault_injected,
                    fl.text,
                    if self.amplifiers_on_after_fault == Some(true) {
                        "STILL ON"
                    } else {
                        "off"
                    }
                )?;
                if !self.boards_not_answering.is_empty() {
                    writeln!(
                        f,
                        "  boards {} not answering: amplifier state unknown (their own watchdog {})",
                        board_ids(&self.boards_not_answering),
                        if self.watchdog.period_ms > 0.0 {
                            "turns their amplifiers off if they are powered and running"
                        } else {
                            "is OFF: nothing turns their amplifiers off"
                        }
                    )?;
                }
            }
        }
        let p = &self.power_down;
        write!(f, "  powered down: off on boards {}", board_ids(&p.off))?;
        if !p.unknown.is_empty() {
            write!(
                f,
                "; boards {} did not answer: state unknown",
                board_ids(&p.unknown)
            )?;
        }
        if !p.still_on.is_empty() {
            write!(f, "; boards {} STILL ON", board_ids(&p.still_on))?;
        }
        if p.watchdog_restored {
            write!(f, "; watchdog set back to its default period")?;
        }
        writeln!(f)
    }
}

/// The board whose loss the demo simulates: PSM1's first board in seed
/// 000's dVRK, the ECM's DQLA in the dVRK's numbering of DQLA arms
/// (`configs/dvrk-dqla-rev9.json`).
const LOST_BOARD: u8 = 4;

/// The demo's motions: on every arm, even joints follow a sinusoid (10 %
/// of the joint's range, 0.4 to 0.7 Hz), odd joints move point to point by
/// 5 %, from `here`.
pub fn motion_for(config: &IoConfig, i: usize, here: f64) -> Motion {
    let Some(j) = config.joints().nth(i) else {
        return Motion::Hold(here);
    };
    let a = j.actuator;
    let span = a.encoder.position_limits_soft.span();
    let (v, acc) = a.limits.map_or((0.5, 2.0), |l| {
        (0.3 * l.velocity, l.acceleration.unwrap_or(1.0) * 0.3)
    });
    if i % 2 == 0 {
        let f = 0.4 + 0.1 * (i % 4) as f64;
        Sinusoid::new(0.05 * span, f, 0.0, here, 0.5)
            .map(Motion::Sinusoid)
            .unwrap_or(Motion::Hold(here))
    } else {
        PointToPoint::new(here, here + 0.05 * span, v, acc)
            .map(Motion::PointToPoint)
            .unwrap_or(Motion::Hold(here))
    }
}

/// A demo's duration must be finite and above 0 (its period was checked
/// when it was made, [`ServoPeriod`]).
///
/// # Errors
/// [`TestbedError::Config`] naming the value.
pub(crate) fn check_run(duration_s: f64) -> Result<(), TestbedError> {
    if !(duration_s.is_finite() && duration_s > 0.0) {
        return Err(TestbedError::Config(format!(
            "duration {duration_s} s: must be above 0"
        )));
    }
    Ok(())
}

/// The servo period of a rate, Hz, refused as a configuration error.
///
/// # Errors
/// [`TestbedError::Config`] outside 1 Hz to 100 kHz.
pub(crate) fn servo_period(rate_hz: f64) -> Result<ServoPeriod, TestbedError> {
    ServoPeriod::from_rate_hz(rate_hz).map_err(|e| TestbedError::Config(e.to_string()))
}

/// The real-time settings of a run: `realtime()` with wall-clock pacing,
/// none otherwise.
pub(crate) fn realtime_status(
    pacing: Pacing,
    realtime: Option<&dyn Fn() -> RealtimeStatus>,
) -> RealtimeStatus {
    match (pacing, realtime) {
        (Pacing::WallClock, Some(setup)) => setup(),
        _ => RealtimeStatus::default(),
    }
}

/// What the demo needs of a robot's I/O beyond the abstract robot I/O
/// ([`RobotIo`]): the port, on which its [`FaultTarget`] applies faults,
/// the boards found, and what the report names. QLA boards ([`IoSystem`](firelink_host::qla::io::IoSystem))
/// and seed 001's Snake nodes
/// ([`SnakeSystem`](firelink_host::snake::SnakeSystem)) both run the same
/// demo ([`run_program`]).
pub trait DemoIo: RobotIo {
    /// The port the I/O system talks through.
    type Port: Port + 'static;
    /// The port, to apply faults on.
    fn port_mut(&mut self) -> &mut Self::Port;
    /// Each board found: its board ID and node (for a link filter's
    /// `dest=`).
    fn board_nodes(&self) -> Vec<(u8, u8)>;
    /// Firmware of the first board.
    fn firmware(&self) -> Option<u32>;
    /// The I/O protocol's name.
    fn protocol(&self) -> String;
    /// What ran at which level of detail on the simulated bus (`None`:
    /// not a simulated port).
    fn detail_report(&self) -> Option<DetailReport>;
}

/// The periodic progress event: the median I/O time of the last 2000 cycles.
pub(crate) fn tick<R: RobotIo>(r: &Robot<R>) -> DemoProgress {
    let io = &r.times().io_us;
    let mut last: Vec<f32> = io[io.len().saturating_sub(2000)..].to_vec();
    DemoProgress::Tick {
        t: r.now(),
        cycles: r.cycles(),
        io_median_us: Percentiles::of(&mut last).median,
        errors: r.io_stats().total_errors(),
    }
}

/// What a demo run does, whatever the robot.
#[derive(Debug, Clone, Copy)]
pub struct DemoPlan<'a> {
    /// The robot.
    pub config: &'a IoConfig,
    /// The servo period.
    pub period: ServoPeriod,
    /// Seconds of motion after homing.
    pub duration_s: f64,
    /// The fault to inject half way (a named preset).
    pub fault: DemoFault,
    /// A fault script instead of the preset.
    pub script: Option<&'a FaultScript>,
    /// Board watchdog.
    pub watchdog: WatchdogSetting,
    /// Pacing.
    pub pacing: Pacing,
}

/// What a plan breaks: its name in reports and progress, its script, and
/// whether joint 0's setpoint jumps at the fault moment.
struct PlannedFaults {
    name: String,
    /// Whether `name` is a preset's (else the script's text).
    preset: bool,
    script: FaultScript,
    following_error: bool,
}

impl DemoPlan<'_> {
    /// The script the plan applies, and its name.
    fn faults(&self) -> PlannedFaults {
        match self.script {
            Some(script) if !script.is_empty() => PlannedFaults {
                name: script.to_string(),
                preset: false,
                script: script.clone(),
                following_error: false,
            },
            _ => PlannedFaults {
                name: self.fault.name().into(),
                preset: true,
                script: self.fault.script(self.watchdog.period_or_zero()),
                following_error: self.fault == DemoFault::FollowingError,
            },
        }
    }

    /// Whether the plan's faults can all happen: each entry within the
    /// motion (`cycle=N` before its last cycle, `t=` before its end, half
    /// way plus `t`), and each applicable by `target` on `port`
    /// ([`FaultTarget::check`]; `nodes`: the boards the scan found, `None`
    /// before the scan). Called before the boards are touched, so that a
    /// fault that could never be applied is refused, naming the entry,
    /// rather than reported as not detected.
    ///
    /// # Errors
    /// [`TestbedError::Config`] naming the entry and the motion's length,
    /// or what [`FaultTarget::check`] refuses.
    pub fn check_faults<P: Port + 'static>(
        &self,
        target: &FaultTarget,
        port: &P,
        nodes: Option<&[(u8, u8)]>,
    ) -> Result<(), TestbedError> {
        let faults = self.faults();
        let rate = self.period.rate_hz();
        let total = motion_cycles(self.duration_s, rate);
        // The fault moment is half way; after it, this long is left.
        let left_s = (total - total / 2) as f64 / rate;
        for entry in &faults.script.entries {
            let late = match entry.at {
                FaultMoment::Start => total == 0,
                FaultMoment::Cycle(n) => n >= total,
                FaultMoment::After(t) => t.as_secs_f64() >= left_s,
            };
            if late {
                return Err(TestbedError::Config(format!(
                    "fault {entry} cannot happen within the motion: it is {total} cycles \
                     ({} s) long, `cycle=` counts from its start and `t=` from half way \
                     ({left_s} s before its end)",
                    self.duration_s
                )));
            }
        }
        target.check(&faults.script, port, nodes)
    }

    /// The servo settings of the plan.
    pub fn settings(&self) -> RobotSettings {
        RobotSettings {
            period: self.period,
            watchdog: self.watchdog,
            ..RobotSettings::default()
        }
    }
}

/// A finished demo: the report, the timing record and the cycles before
/// the motion started.
#[derive(Debug, Clone)]
pub struct DemoRun {
    /// The report.
    pub report: DemoReport,
    /// Every cycle's timing.
    pub times: CycleTimes,
    /// Cycles run before the motion (power on, homing).
    pub setup_cycles: u64,
}

/// Run the demo with a servo program on its boards: configure, power on,
/// home, move every joint, apply the plan's faults (`target` applies them
/// on the port) at their moments, power off, report. `wall` is when the
/// run started (for the wall time).
///
/// # Errors
/// The program failed outside a cycle; a fault `target` cannot apply on
/// this port or that cannot happen within the motion (the callers check
/// the plan before they open the port's boards,
/// [`DemoPlan::check_faults`]; here it is checked again with the boards
/// the scan found, so a `dest=` board not found is refused after the
/// scan, before any board is configured or powered on).
pub fn run_program<R: DemoIo>(
    mut robot: Robot<R>,
    plan: &DemoPlan<'_>,
    target: &FaultTarget,
    port_name: String,
    rt: RealtimeStatus,
    wall: Instant,
    progress: &mut dyn FnMut(DemoProgress),
) -> Result<DemoRun, TestbedError> {
    let faults = plan.faults();
    let nodes = robot.io().board_nodes();
    plan.check_faults(target, &*robot.io_mut().port_mut(), Some(&nodes))?;
    if plan.watchdog.is_off() {
        progress(DemoProgress::WatchdogOff);
    }
    let mut setup_cycles = 0;
    let ran = bring_up(&mut robot, plan.config, progress).and_then(|()| {
        setup_cycles = robot.cycles();
        run_motion(&mut robot, plan, &faults, target, progress)
    });
    let fault = match ran {
        Ok(fault) => fault,
        // Whatever ended the program (an error in bring-up or motion, a
        // stop request), the robot is powered down before it returns.
        Err(error) => {
            let power_down = robot.shutdown()?;
            progress(DemoProgress::PoweredOff(wall.elapsed().as_secs_f64()));
            return Err(TestbedError::PoweredDown {
                error: Box::new(error),
                power_down,
            });
        }
    };
    let after = AfterRun::of(&robot);
    let motion_cycles = robot.cycles() - setup_cycles;
    let power_down = robot.shutdown()?;
    let wall_s = wall.elapsed().as_secs_f64();
    progress(DemoProgress::PoweredOff(wall_s));
    let run = FinishedRun {
        port_name,
        rt,
        wall_s,
        motion_cycles,
        fault,
        after,
        power_down,
    };
    Ok(DemoRun {
        report: demo_report(&robot, plan, &faults.name, run),
        times: robot.times().clone(),
        setup_cycles,
    })
}

/// Configure, power on, home and activate the robot, and start every
/// joint's motion.
pub(crate) fn bring_up<R: DemoIo>(
    robot: &mut Robot<R>,
    config: &IoConfig,
    progress: &mut dyn FnMut(DemoProgress),
) -> Result<(), TestbedError> {
    let left = robot.configure()?;
    if !left.is_clean() {
        progress(DemoProgress::TookOver(left.to_string()));
    }
    progress(DemoProgress::Configured);
    robot.power_on()?;
    progress(DemoProgress::Powered(robot.now()));
    robot.home()?;
    robot.activate()?;
    progress(DemoProgress::Homed(robot.now()));
    for i in 0..robot.joint_count() {
        let here = robot.position(i).unwrap_or(0.0);
        robot.set_motion(i, motion_for(config, i, here))?;
    }
    robot.reset_tracking();
    Ok(())
}

/// The plan's motion, its faults applied at their moments (`start`: the
/// motion's first cycle; `cycle=N`: N cycles into the motion; `t=`: from
/// the fault moment, half way); a fault ends the motion and is followed by
/// cycles in Fault (twice the watchdog period) so that the safety chain
/// can act. Returns the fault, if one happened.
fn run_motion<R: DemoIo>(
    robot: &mut Robot<R>,
    plan: &DemoPlan<'_>,
    faults: &PlannedFaults,
    target: &FaultTarget,
    progress: &mut dyn FnMut(DemoProgress),
) -> Result<Option<FaultReport>, TestbedError> {
    let (pacing, rate) = (plan.pacing, plan.period.rate_hz());
    let watchdog = plan.watchdog.period_or_zero();
    let total = motion_cycles(plan.duration_s, rate);
    let every = (rate / 4.0).max(1.0) as u64;
    let stops = fault_stops(faults, total);
    let mut outcome = Ok(());
    let mut done = 0;
    for &(cycle, moment) in &stops {
        if cycle > done {
            outcome = robot.run(cycle - done, pacing, every, |r| progress(tick(r)));
            done = cycle;
        }
        if outcome.is_err() {
            break;
        }
        // Each with its index in the script (its link filter's seed).
        let due: Vec<(usize, &ScriptEntry)> = faults
            .script
            .entries
            .iter()
            .enumerate()
            .filter(|(_, e)| match e.at {
                FaultMoment::Start => cycle == 0 && !moment,
                FaultMoment::Cycle(n) => n == cycle && !moment,
                FaultMoment::After(_) => moment,
            })
            .collect();
        let following_error = moment && faults.following_error;
        if due.is_empty() && !following_error {
            continue;
        }
        progress(DemoProgress::Injecting(if faults.preset {
            faults.name.clone()
        } else {
            due.iter()
                .map(|(_, e)| e.to_string())
                .collect::<Vec<_>>()
                .join(";")
        }));
        let nodes = robot.io().board_nodes();
        for (index, entry) in due {
            target.apply(index, entry, robot.io_mut().port_mut(), &nodes)?;
        }
        if following_error {
            // A setpoint jump the joint cannot follow within the grace time.
            let _ = robot.step_setpoint(0, 0.5);
        }
    }
    if outcome.is_ok() && total > done {
        outcome = robot.run(total - done, pacing, every, |r| progress(tick(r)));
    }
    match outcome {
        Ok(()) => Ok(None),
        Err(RunnerError::Fault(f)) => {
            progress(DemoProgress::Fault(f.to_string()));
            // Cycles in Fault for twice the watchdog period: outputs stay
            // safe, and a board that stopped answering has time to turn
            // its own amplifiers off.
            let n = ((2.0 * watchdog.as_secs_f64() * rate).ceil() as u64).max(3);
            for _ in 0..n {
                let _ = robot.step(Pacing::Virtual);
            }
            progress(DemoProgress::SafetyChain {
                state: robot.state().to_string(),
                amplifiers_on: robot.any_amp_on(),
            });
            Ok(Some(f))
        }
        Err(e) => Err(e.into()),
    }
}

/// The cycles of a motion of `duration_s` seconds at `rate` Hz.
fn motion_cycles(duration_s: f64, rate: f64) -> u64 {
    (duration_s * rate).round() as u64
}

/// The motion cycles at which faults are due, in order: (cycle, whether it
/// is the fault moment, half way). Entries at or after the motion's end
/// never come.
fn fault_stops(faults: &PlannedFaults, total: u64) -> Vec<(u64, bool)> {
    let mut stops: Vec<(u64, bool)> = faults
        .script
        .entries
        .iter()
        .filter_map(|e| match e.at {
            FaultMoment::Start => Some(0),
            FaultMoment::Cycle(n) => (n < total).then_some(n),
            FaultMoment::After(_) => None,
        })
        .map(|c| (c, false))
        .collect();
    let at_moment = faults.following_error
        || faults
            .script
            .entries
            .iter()
            .any(|e| matches!(e.at, FaultMoment::After(_)));
    if at_moment {
        stops.push((total / 2, true));
    }
    stops.sort_unstable();
    stops.dedup();
    stops
}

/// The robot's state right after the motion, before shutdown.
struct AfterRun {
    amplifiers_on: bool,
    boards: usize,
    silent: Vec<u8>,
    expired: Vec<u8>,
    state: String,
}

impl AfterRun {
    fn of<R: RobotIo>(robot: &Robot<R>) -> AfterRun {
        let io = robot.io();
        let found: Vec<u8> = (0..16u8).filter(|id| robot.found().contains(*id)).collect();
        AfterRun {
            amplifiers_on: robot.any_amp_on(),
            boards: found.len(),
            silent: found
                .iter()
                .copied()
                .filter(|id| !io.board_answered(*id))
                .collect(),
            expired: found
                .iter()
                .copied()
                .filter(|id| io.watchdog_expired(*id))
                .collect(),
            state: robot.state().to_string(),
        }
    }
}

/// What a finished run hands the report beside the robot.
struct FinishedRun {
    port_name: String,
    rt: RealtimeStatus,
    wall_s: f64,
    motion_cycles: u64,
    fault: Option<FaultReport>,
    after: AfterRun,
    power_down: PowerDown,
}

/// The demo's report of a finished run.
fn demo_report<R: DemoIo>(
    robot: &Robot<R>,
    plan: &DemoPlan<'_>,
    fault_name: &str,
    run: FinishedRun,
) -> DemoReport {
    let times = robot.times();
    let (mut c, mut io, mut comp) = (
        times.cycle_us.clone(),
        times.io_us.clone(),
        times.compute_us.clone(),
    );
    let mut tracking_error = BTreeMap::new();
    let mut tracking_error_detail = BTreeMap::new();
    for t in robot.tracking() {
        tracking_error.insert(t.name.clone(), t.rms_rad);
        tracking_error_detail.insert(
            t.name.clone(),
            TrackingDetail {
                rms_rad: t.rms_rad,
                max_rad: t.max_rad,
                prismatic_rms_mm: t.rms_mm,
                prismatic_max_mm: t.max_mm,
                samples: t.samples,
            },
        );
    }
    let port_time_s = robot.now();
    let wall_s = run.wall_s;
    let watchdog = plan.watchdog.period_or_zero();
    DemoReport {
        port: run.port_name,
        boards: run.after.boards,
        axes: robot.joint_count(),
        firmware: robot.io().firmware(),
        protocol: robot.io().protocol(),
        rate_hz: plan.period.rate_hz(),
        pacing: match plan.pacing {
            Pacing::Virtual => "virtual",
            Pacing::WallClock => "realtime",
        }
        .to_string(),
        cycles: robot.cycles(),
        motion_cycles: run.motion_cycles,
        port_time_s,
        wall_time_s: wall_s,
        speed_vs_real_time: if wall_s > 0.0 {
            port_time_s / wall_s
        } else {
            0.0
        },
        cycle_time_us: TimeStats::of(&mut c),
        io_time_us: TimeStats::of(&mut io),
        compute_time_us: TimeStats::of(&mut comp),
        overruns: times.overruns,
        realtime: run.rt,
        tracking_error,
        tracking_error_unit: "rad RMS over each arm's revolute joints (prismatic: tracking_error_detail, mm)",
        tracking_error_detail,
        errors: ErrorCounts::from(robot.io_stats()),
        watchdog: WatchdogReport {
            period_ms: watchdog.as_secs_f64() * 1e3,
            expired_boards: run.after.expired,
            unknown_boards: run.after.silent.clone(),
        },
        fault_injected: fault_name.to_string(),
        fault: run.fault.as_ref().map(FaultSummary::from),
        state_after_run: run.after.state,
        amplifiers_on_after_fault: run.fault.map(|_| run.after.amplifiers_on),
        boards_not_answering: run.after.silent,
        power_down: PowerDownReport::from(&run.power_down),
        state: robot.state().to_string(),
        detail: robot.io().detail_report(),
    }
}
