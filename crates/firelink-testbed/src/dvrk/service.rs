//! A robot as a service for programs that are not real-time (the web
//! console, the ROS 2 node): one thread owns the robot (configuration, I/O
//! system, port) and runs its servo cycles; it never waits on them.
//!
//! Hand-off is lock-free and allocation-free once running: a fixed pool of
//! [`Frame`]s travels between two bounded queues. After each cycle the loop
//! takes a free frame (if none is free the consumer is behind and this
//! cycle's frame is skipped, counted), fills it in place and queues it as
//! full; the consumer drains full frames and gives them back. Commands from
//! the browser arrive on a third queue the loop polls once per cycle and
//! carries out between cycles.
//!
//! Between cycles the loop sleeps until the next cycle is due on the wall
//! clock, or until a consumer that queued a command wakes it
//! ([`Shared::nudge`]): then the cycle runs at once (at least a fifth of a
//! period after the last one) and the schedule re-phases from it
//! ([`crate::cycle_schedule`]), so a command waits for the cycle's own I/O,
//! not for the period. On the simulated bus the port's virtual clock moves
//! by the schedule's interval before each cycle (a period, or less for an
//! early cycle), so the control law's period is the real interval there
//! too.
//!
//! Commands go through the robot's lifecycle: what powers anything (motor
//! power, the relay, amplifiers) is refused, with the reason, in a state
//! that does not allow it, and reaches only the boards and axes the
//! robot's joints use; what turns things off is always allowed. Each
//! command's [`CommandOutcome`] says whether it was done, refused or
//! failed, and what it found. A command queued with an id
//! ([`Shared::requests`]) gets an outcome with that id, so a consumer can
//! wait for the outcome of *its* command.
//!
//! The loop powers the robot down on every way out: a stop
//! ([`Service::stop`], or the process's stop request that
//! [`firelink_host::stop::install_signal_handlers`] sets on a signal) and a
//! panic inside the loop, which is caught, powered down after and reported
//! in the [`LoopExit`] that [`Service::stop`] returns.

use std::fmt;
use std::io::Write as _;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use crossbeam_queue::ArrayQueue;

use firelink_control::config::IoConfig;
use firelink_control::lifecycle::State;
use firelink_control::runner::{Pacing, Robot, RobotSettings, RunnerError};
use firelink_control::trajectory::{Motion, PointToPoint, ServoPoint};
use firelink_control::{BoardSet, FaultReport, ServoPeriod};
use firelink_host::RobotIo;
use firelink_host::WatchdogSetting;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::robot_io::board_list;
use std::thread::JoinHandle;

use firelink_board::qla::config::Profile;

use crate::cycle_schedule::{CycleSchedule, Due};
use crate::demo::{DemoFault, DemoIo, motion_for};
use crate::fault_script::FaultTarget;
use crate::loop_outcome::{CommandOutcome, LoopExit, Verdict};
use crate::port_spec::PortSpec;
use crate::rig;

/// One axis of one board, as read this cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct AxisSample {
    /// Board ID.
    pub board: u8,
    /// Axis on the board.
    pub axis: u8,
    /// Encoder counts.
    pub encoder: i32,
    /// Encoder velocity, counts/s.
    pub velocity: f64,
    /// Potentiometer ADC bits.
    pub pot: u16,
    /// Measured motor current, A.
    pub current: f64,
    /// Amplifier on.
    pub amp: bool,
    /// DAC command sent, bits.
    pub dac: u16,
}

/// One board's state, as read this cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct BoardSample {
    /// Board ID.
    pub id: u8,
    /// Answered this cycle.
    pub valid: bool,
    /// Motor power on.
    pub power: bool,
    /// Safety relay closed.
    pub relay: bool,
    /// Watchdog expired.
    pub watchdog_expired: bool,
    /// STATUS as read (raw).
    pub status: u32,
}

/// One joint of the robot this cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct JointSample {
    /// Setpoint, rad or m.
    pub setpoint: f64,
    /// Measured position, rad or m.
    pub position: f64,
    /// Estimated velocity.
    pub velocity: f64,
    /// Commanded current, A.
    pub current: f64,
}

/// Everything the console shows of one cycle. Sized once for the robot;
/// filled in place by the loop.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Port time, s.
    pub t: f64,
    /// Cycle number.
    pub cycle: u64,
    /// Lifecycle state.
    pub state: State,
    /// The latched fault, if any.
    pub fault: Option<FaultReport>,
    /// I/O time of this cycle, us.
    pub io_us: f64,
    /// Compute time of this cycle (the host's CPU), us.
    pub compute_us: f64,
    /// What the robot thread's work on the cycle before this one cost: the
    /// commands it took, the cycle itself (with the simulated boards on
    /// the simulated bus), its frame handed over and the consumer woken;
    /// not the pacing sleep. `None` for cycles run inside a command
    /// (homing, power-on, settling), which are not paced the same way.
    pub busy: Option<LoopCost>,
    /// I/O errors so far.
    pub errors: u64,
    /// Per joint, in configuration order.
    pub joints: Vec<JointSample>,
    /// Per axis of every board, in board order.
    pub axes: Vec<AxisSample>,
    /// Per board.
    pub boards: Vec<BoardSample>,
}

impl Frame {
    fn sized(joints: usize, axes: usize, boards: usize) -> Frame {
        Frame {
            t: 0.0,
            cycle: 0,
            state: State::Unconfigured,
            fault: None,
            io_us: 0.0,
            compute_us: 0.0,
            busy: None,
            errors: 0,
            joints: vec![JointSample::default(); joints],
            axes: vec![AxisSample::default(); axes],
            boards: vec![BoardSample::default(); boards],
        }
    }

    /// Fill from the robot after a cycle; no allocation.
    fn fill<P: firelink_host::Port>(&mut self, robot: &Robot<IoSystem<P>>, busy: Option<LoopCost>) {
        self.t = robot.now();
        self.busy = busy;
        self.cycle = robot.cycles();
        self.state = robot.state();
        self.fault = robot.fault().copied();
        self.io_us = robot
            .last_report()
            .map_or(0.0, |r| r.io_time().as_secs_f64() * 1e6);
        self.errors = robot.io_stats().total_errors();
        self.compute_us = f64::from(robot.times().last_compute_us);
        for (i, j) in self.joints.iter_mut().enumerate() {
            *j = JointSample {
                setpoint: robot.setpoint(i).unwrap_or(0.0),
                position: robot.position(i).unwrap_or(0.0),
                velocity: robot.velocity(i).unwrap_or(0.0),
                current: robot.commanded_current(i).unwrap_or(0.0),
            };
        }
        let mut k = 0;
        for (bi, b) in robot.io().boards().iter().enumerate() {
            if let Some(s) = self.boards.get_mut(bi) {
                *s = BoardSample {
                    id: b.board_id(),
                    valid: b.is_valid(),
                    power: b.power_enabled(),
                    relay: b.relay_on(),
                    watchdog_expired: b.watchdog_expired(),
                    status: b.status().raw(),
                };
            }
            for a in 0..b.axes() {
                if let Some(s) = self.axes.get_mut(k) {
                    *s = AxisSample {
                        board: b.board_id(),
                        axis: a as u8,
                        encoder: b.encoder_counts(a).unwrap_or(0),
                        velocity: b.encoder_velocity(a).unwrap_or(0.0),
                        pot: b.pot_bits(a).unwrap_or(0),
                        current: b.current_amps(a).unwrap_or(0.0),
                        amp: b.amp_enabled(a),
                        dac: b.dac(a).unwrap_or(0),
                    };
                }
                k += 1;
            }
        }
    }
}

/// What one turn of the robot loop cost ([`Frame::busy`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopCost {
    /// Wall time, us (with the time the thread waited for a CPU).
    pub wall_us: f64,
    /// The robot thread's own CPU time, us (user and system), when the
    /// platform has a thread CPU clock.
    pub cpu_us: Option<f64>,
}

/// What the browser can ask of the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Unconfigured -> Configured (boards found, watchdogs set).
    Configure,
    /// Motor power and relay on the robot's boards, then the amplifiers
    /// its joints use (from Configured only).
    PowerOn,
    /// Home every joint against its potentiometer (from Configured only:
    /// homing while Active would move every setpoint).
    Home,
    /// Configured -> Active, then the demo's motions on every joint.
    Enable,
    /// Active -> Configured, then amplifiers, power and relay off (always
    /// allowed).
    Disable,
    /// Acknowledge a fault (-> Unconfigured).
    ClearFault,
    /// The safety relay: on only where power-on is allowed (Configured or
    /// Active) and only on the robot's boards; off on every board, always
    /// allowed.
    Relay(bool),
    /// The amplifiers: on only from Configured with motor power on every
    /// robot board, or Active, and only those of the axes the joints use;
    /// off on every axis of every board, always allowed (while Active that
    /// is a fault, as on a real robot).
    Amplifiers(bool),
    /// Set every board's watchdog (off only by name).
    Watchdog(WatchdogSetting),
    /// Configured -> Active, every joint holding where it is.
    Activate,
    /// Inject a fault on the port.
    Inject(DemoFault),
    /// Joint positions to hold from now on (CRTK `servo_jp`) for joints
    /// `first .. first + count`; refused unless Active and homed.
    ServoJoints {
        /// First joint (configuration order).
        first: u16,
        /// How many.
        count: u8,
        /// Positions, rad or m (the first `count` are used).
        positions: [f64; MAX_ARM_JOINTS],
        /// Velocities fed forward until the next point (at most
        /// [`SERVO_HORIZON`]), rad/s or m/s.
        velocities: [f64; MAX_ARM_JOINTS],
        /// Where the point came from and when; the loop reports it back in
        /// [`Shared::servo_log`] once the write block carrying it is sent.
        trace: ServoTrace,
    },
    /// Move joints `first .. first + count` to these positions with the
    /// configuration's velocity and acceleration limits (CRTK `move_jp`);
    /// refused unless Active and homed.
    MoveJoints {
        /// First joint (configuration order).
        first: u16,
        /// How many.
        count: u8,
        /// Goals, rad or m (the first `count` are used).
        positions: [f64; MAX_ARM_JOINTS],
    },
}

/// Where a servo point came from and when, as the consumer that queued it
/// saw it; `Default` (all 0) for a point nobody traces.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServoTrace {
    /// When the sender stamped it (the DDS source timestamp), ns since the
    /// Unix epoch; 0: not stamped.
    pub source_ns: u64,
    /// When the consumer took it and queued it, ns since the Unix epoch;
    /// 0: not recorded.
    pub queued_ns: u64,
    /// [`Shared::cycles_done`] when it was queued: the last cycle whose
    /// write block had been sent.
    pub queued_after_cycle: u64,
}

/// A servo point the loop applied: its trace, and the cycle whose write
/// block carried it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServoApplied {
    /// As queued.
    pub trace: ServoTrace,
    /// The cycle (the robot's cycle counter) whose write block carried the
    /// point: the first run after the loop took it from the queue. That is
    /// `trace.queued_after_cycle + 1`, or `+ 2` when the point was queued
    /// while the loop was already taking that cycle's commands; later only
    /// when it waited behind a command that runs cycles of its own
    /// (power-on, homing, a relay or amplifier change).
    pub cycle: u64,
    /// When the loop's next cycle (the one `applied_ns` closes) started,
    /// before it took its commands, ns since the Unix epoch (as
    /// `applied_ns`, less the time the cycle took on the monotonic clock).
    pub started_ns: u64,
    /// When the write block of the loop's next cycle had been sent, ns
    /// since the Unix epoch (the wall clock, read once after that cycle,
    /// only when a traced point was applied in it): the point's own cycle
    /// unless a command queued behind it ran cycles.
    pub applied_ns: u64,
}

/// Applied servo points kept for the consumer ([`Shared::servo_log`]):
/// more than a second of a 200 Hz stream it does not read.
pub const SERVO_LOG: usize = 256;

/// The most joints one servo or move command carries (one arm).
pub const MAX_ARM_JOINTS: usize = 16;

/// How long a servo point is extrapolated at its velocity before the
/// joint holds (a stream that stops leaves the joint still), seconds.
pub const SERVO_HORIZON: f64 = 0.05;

impl fmt::Display for Command {
    /// A short name for reports: `configure`, `amplifiers on`, ...
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let on_off = |on: bool| if on { "on" } else { "off" };
        match self {
            Command::Configure => f.write_str("configure"),
            Command::PowerOn => f.write_str("power on"),
            Command::Home => f.write_str("home"),
            Command::Enable => f.write_str("enable"),
            Command::Disable => f.write_str("disable"),
            Command::ClearFault => f.write_str("clear fault"),
            Command::Relay(on) => write!(f, "relay {}", on_off(*on)),
            Command::Amplifiers(on) => write!(f, "amplifiers {}", on_off(*on)),
            Command::Watchdog(w) => match w.period() {
                Some(p) => write!(f, "watchdog {:.3} ms", p.as_secs_f64() * 1e3),
                None => f.write_str("watchdog off"),
            },
            Command::Activate => f.write_str("activate"),
            Command::Inject(fault) => write!(f, "inject {fault}"),
            Command::ServoJoints { .. } => f.write_str("servo_jp"),
            Command::MoveJoints { .. } => f.write_str("move_jp"),
        }
    }
}

/// A command queued with the id its outcome will carry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// From [`Shared::new_id`]; never 0.
    pub id: u64,
    /// What to do.
    pub command: Command,
}

/// The queues and flags shared by the loop and the consumer.
pub struct Shared {
    /// Frames ready for the consumer.
    pub full: ArrayQueue<Box<Frame>>,
    /// Frames the loop may fill.
    pub free: ArrayQueue<Box<Frame>>,
    /// Commands for the loop, without an id (a servo stream; their
    /// outcomes carry id 0, and a servo point that is applied reports
    /// none).
    pub commands: ArrayQueue<Command>,
    /// Commands for the loop whose outcome someone waits for: each carries
    /// an id from [`new_id`](Self::new_id) and its outcome the same id.
    /// Taken after [`commands`](Self::commands) in each cycle.
    pub requests: ArrayQueue<Request>,
    /// Outcomes of commands (the consumer reads them; when it does not,
    /// the oldest are dropped).
    pub outcomes: ArrayQueue<CommandOutcome>,
    /// The last id handed out.
    pub last_id: AtomicU64,
    /// How the loop ended, once it has (set once, after the power-down).
    pub exit: OnceLock<LoopExit>,
    /// Frames skipped because none was free.
    pub skipped: AtomicU64,
    /// Commands the consumer accepted and queued.
    pub queued: AtomicU64,
    /// Set to stop the loop (it powers off first).
    pub stop: AtomicBool,
    /// Joint labels, in configuration order.
    pub joint_labels: Vec<String>,
    /// The servo period (its rate: `period.rate_hz()`).
    pub period: ServoPeriod,
    /// The port's name.
    pub port_name: String,
    /// Boards found: (board ID, firmware, hardware name).
    pub board_infos: Vec<(u8, u32, &'static str)>,
    /// Every joint homed since the last configure.
    pub homed: AtomicBool,
    /// Port time (s, as f64 bits) at which the last move ends.
    pub move_ends: AtomicU64,
    /// Servo commands applied so far.
    pub servo_applied: AtomicU64,
    /// Every traced servo point applied ([`ServoTrace::source_ns`] or
    /// `queued_ns` not 0), with the cycle that carried it; when the
    /// consumer does not read them, the newest are dropped (counted in
    /// [`servo_log_dropped`](Self::servo_log_dropped)).
    pub servo_log: ArrayQueue<ServoApplied>,
    /// Applied servo points not logged because the log was full.
    pub servo_log_dropped: AtomicU64,
    /// The last cycle whose write block has been sent (the robot's cycle
    /// counter; 0 before the first): a consumer reads it when it queues a
    /// command, to count in cycles how long the command waited.
    pub cycles_done: AtomicU64,
    /// Called with the cycle's number and port time (s) after every frame
    /// is handed over (from the robot thread: it must not block, lock or
    /// allocate), so a consumer can sleep until a frame it wants is there;
    /// set at most once.
    pub frame_waker: OnceLock<FrameWaker>,
    /// The cycle whose commands the loop takes now or took last (stored
    /// before it takes them): a consumer that reads it after queueing a
    /// command (with a `SeqCst` fence between) knows the command is
    /// carried at the latest by the cycle after that one; exactly by it
    /// when [`cycles_done`](Self::cycles_done), read before queueing, was
    /// the same number (the command was queued between cycles).
    pub commands_taken_for: AtomicU64,
    /// Cycles of the loop by how they started against the schedule:
    /// early for a command, on schedule, overrun
    /// ([`CycleStart`](crate::cycle_schedule::CycleStart)).
    pub cycle_starts: [AtomicU64; 3],
    /// The robot loop's thread, for [`nudge`](Self::nudge) (set when the
    /// loop starts).
    pub robot_thread: OnceLock<std::thread::Thread>,
}

/// What the loop calls after handing over the frame of a cycle
/// ([`Shared::frame_waker`]), with the cycle's number and port time (s):
/// e.g. a `mio::Waker`'s `wake` (one `eventfd` write) for the cycles the
/// consumer publishes.
pub type FrameWaker = Box<dyn Fn(u64, f64) + Send + Sync>;

impl Shared {
    /// Wake the robot loop if it sleeps between cycles: a consumer calls it
    /// after queueing a command, and the command's cycle starts at once
    /// (at least a fifth of a period after the last one) instead of at the
    /// next deadline. Allocation-free; harmless when the loop is busy (it
    /// looks at the queues before it sleeps again).
    pub fn nudge(&self) {
        if let Some(t) = self.robot_thread.get() {
            t.unpark();
        }
    }

    /// A fresh id for a [`Request`] (never 0).
    pub fn new_id(&self) -> u64 {
        self.last_id.fetch_add(1, Ordering::Relaxed) + 1
    }

    /// Queue `command` with a fresh id; returns the id.
    ///
    /// # Errors
    /// [`QueueFull`]: the loop is that far behind (or has ended).
    pub fn submit(&self, command: Command) -> Result<u64, QueueFull> {
        let id = self.new_id();
        self.requests
            .push(Request { id, command })
            .map(|()| id)
            .map_err(|_| QueueFull)
    }
}

/// The command queue is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the command queue is full")]
pub struct QueueFull;

/// Frames in the pool: a second of cycles at 1 kHz lets the consumer be late
/// by that much without a skipped frame.
pub const POOL: usize = 1024;

/// How to run the loop.
#[derive(Debug, Clone)]
pub struct LoopOptions {
    /// The robot.
    pub config: IoConfig,
    /// The servo period.
    pub period: ServoPeriod,
    /// Board watchdog.
    pub watchdog: WatchdogSetting,
    /// `Virtual` on the simulated bus (then paced to the wall clock by the
    /// loop so the browser sees real time), `WallClock` over UDP.
    pub pacing: Pacing,
    /// Who applies an injected fault's script on the port (the rig's on
    /// `sim`, the emulator's on `emulate`; [`FaultTarget::link`] for any
    /// other port).
    pub faults: FaultTarget,
}

/// Open the I/O system and the robot on `port`, size the frame pool and
/// the shared state. The robot is returned to be moved into [`run`]'s thread.
///
/// # Errors
/// The scan or the configuration failed.
pub fn prepare<P: firelink_host::Port + 'static>(
    port: P,
    port_name: String,
    options: &LoopOptions,
) -> Result<(Robot<IoSystem<P>>, Arc<Shared>), crate::TestbedError> {
    let (io, _) = IoSystem::open(port, IoOptions::default())?;
    let settings = RobotSettings {
        period: options.period,
        watchdog: options.watchdog,
        ..RobotSettings::default()
    };
    let robot = Robot::new(io, &options.config, settings)?;
    let joint_labels = (0..robot.joint_count())
        .map(|i| {
            robot
                .joint_label(i)
                .map_or_else(|| format!("joint {i}"), |l| l.as_str().to_string())
        })
        .collect();
    let axes: usize = robot.io().boards().iter().map(|b| b.axes()).sum();
    let board_infos = robot
        .io()
        .boards()
        .iter()
        .map(|b| (b.board_id(), b.info().firmware, b.info().hardware.name()))
        .collect();
    let shared = Shared {
        full: ArrayQueue::new(POOL),
        free: ArrayQueue::new(POOL),
        commands: ArrayQueue::new(64),
        requests: ArrayQueue::new(64),
        outcomes: ArrayQueue::new(64),
        last_id: AtomicU64::new(0),
        exit: OnceLock::new(),
        skipped: AtomicU64::new(0),
        queued: AtomicU64::new(0),
        stop: AtomicBool::new(false),
        joint_labels,
        period: options.period,
        port_name,
        board_infos,
        homed: AtomicBool::new(false),
        move_ends: AtomicU64::new(0f64.to_bits()),
        servo_applied: AtomicU64::new(0),
        servo_log: ArrayQueue::new(SERVO_LOG),
        servo_log_dropped: AtomicU64::new(0),
        cycles_done: AtomicU64::new(0),
        frame_waker: OnceLock::new(),
        commands_taken_for: AtomicU64::new(0),
        cycle_starts: Default::default(),
        robot_thread: OnceLock::new(),
    };
    for _ in 0..POOL {
        let _ = shared.free.push(Box::new(Frame::sized(
            robot.joint_count(),
            axes,
            robot.io().boards().len(),
        )));
    }
    Ok((robot, Arc::new(shared)))
}

/// After a cycle: say it is done ([`Shared::cycles_done`]), hand its frame
/// over and wake the consumer. `busy`: see [`Frame::busy`].
fn publish<P: firelink_host::Port>(
    shared: &Shared,
    robot: &Robot<IoSystem<P>>,
    busy: Option<LoopCost>,
) {
    shared.cycles_done.store(robot.cycles(), Ordering::SeqCst);
    match shared.free.pop() {
        Some(mut frame) => {
            frame.fill(robot, busy);
            if let Err(frame) = shared.full.push(frame) {
                let _ = shared.free.push(frame);
                shared.skipped.fetch_add(1, Ordering::Relaxed);
            }
        }
        None => {
            shared.skipped.fetch_add(1, Ordering::Relaxed);
        }
    }
    if let Some(wake) = shared.frame_waker.get() {
        wake(robot.cycles(), robot.now());
    }
}

fn outcome(shared: &Shared, id: u64, command: Command, result: Result<String, Refusal>) {
    let (result, detail) = match result {
        Ok(found) => (Verdict::Ok, found),
        Err(Refusal(verdict, why)) => (verdict, why),
    };
    let entry = CommandOutcome {
        id,
        command: command.to_string(),
        result,
        detail,
    };
    // A full outcome queue drops the oldest: the consumer is not reading.
    if let Err(entry) = shared.outcomes.push(entry) {
        let _ = shared.outcomes.pop();
        let _ = shared.outcomes.push(entry);
    }
}

/// Why a command was not done: [`Verdict::Refused`] or
/// [`Verdict::Failed`], and the reason.
#[derive(Debug)]
struct Refusal(Verdict, String);

fn refused(why: impl Into<String>) -> Refusal {
    Refusal(Verdict::Refused, why.into())
}

fn failed(why: impl Into<String>) -> Refusal {
    Refusal(Verdict::Failed, why.into())
}

/// A lifecycle refusal is a refusal; the rest (time-outs, faults, port
/// errors) are failures.
fn runner(e: RunnerError) -> Refusal {
    match e {
        RunnerError::Lifecycle(l) => refused(l.to_string()),
        RunnerError::Stopped(reason) => refused(format!("stopping: {reason}")),
        other => failed(other.to_string()),
    }
}

/// Why powering anything is refused in `robot`'s state, if it is:
/// `needs` says what the command needs ("power on needs ...").
fn power_refusal<P: firelink_host::Port + 'static>(
    robot: &Robot<IoSystem<P>>,
    what: &str,
) -> Option<Refusal> {
    match robot.state() {
        State::Configured | State::Active => None,
        State::Unconfigured => Some(refused(format!(
            "{what} needs a configured robot: it is unconfigured (configure first)"
        ))),
        State::Fault => Some(refused(format!(
            "{what} is refused in fault{}: clear the fault, configure and power on again",
            robot.fault().map(|f| format!(" ({f})")).unwrap_or_default()
        ))),
    }
}

/// The boards found, as a set.
fn all_boards<P: firelink_host::Port + 'static>(robot: &Robot<IoSystem<P>>) -> BoardSet {
    robot.io().boards().iter().map(|b| b.board_id()).collect()
}

/// Cycle (publishing every frame) until `done` says so, at most half a
/// second of the robot's cycles; a fault on the way is latched and shown
/// in the frames like any other.
fn settle<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    options: &LoopOptions,
    done: impl Fn(&Robot<IoSystem<P>>) -> bool,
) -> bool {
    let cycles = (options.period.rate_hz() * SETTLE_SECONDS).ceil().max(10.0) as u64;
    for _ in 0..cycles {
        let _ = robot.step(options.pacing);
        publish(shared, robot, None);
        if done(robot) {
            return true;
        }
    }
    false
}

/// How long a relay or amplifier change may take to show, seconds of the
/// robot's clock (the firmware's enable delay is 2.5 ms).
const SETTLE_SECONDS: f64 = 0.5;

/// Boards of `set` that answered the last latch with `state` wrong, as a
/// mask (the ones that did not answer included).
fn boards_not<P: firelink_host::Port + 'static>(
    robot: &Robot<IoSystem<P>>,
    set: BoardSet,
    ok: impl Fn(&firelink_host::qla::board::BoardIo) -> bool,
) -> u16 {
    robot
        .io()
        .boards()
        .iter()
        .filter(|b| set.contains(b.board_id()))
        .filter(|b| !(b.is_valid() && ok(b)))
        .fold(0, |m, b| m | 1 << (b.board_id() & 0xF))
}

fn execute<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    command: Command,
    options: &LoopOptions,
) -> Result<String, Refusal> {
    let robot_boards = options.config.board_set();
    match command {
        Command::Configure => {
            let left = robot.configure().map_err(runner)?;
            shared.homed.store(false, Ordering::Relaxed);
            Ok(left.to_string())
        }
        Command::PowerOn => {
            if robot.state() != State::Configured {
                return Err(refused(format!(
                    "power on needs a configured robot: it is {}",
                    robot.state()
                )));
            }
            robot
                .power_on_observed(&mut |r| publish(shared, r, None))
                .map_err(runner)?;
            Ok(format!(
                "motor power, relay and the joints' amplifiers on at boards {}",
                board_list(robot_boards.0)
            ))
        }
        Command::Home => {
            match robot.state() {
                State::Configured => {}
                State::Active => {
                    return Err(refused(
                        "home while active would move every setpoint: disable first",
                    ));
                }
                state => {
                    return Err(refused(format!(
                        "home needs a configured robot: it is {state}"
                    )));
                }
            }
            robot.home().map_err(runner)?;
            shared.homed.store(true, Ordering::Relaxed);
            Ok(String::new())
        }
        Command::Enable => {
            robot.activate().map_err(runner)?;
            for i in 0..robot.joint_count() {
                let here = robot.position(i).unwrap_or(0.0);
                robot
                    .set_motion(i, motion_for(&options.config, i, here))
                    .map_err(runner)?;
            }
            Ok(String::new())
        }
        Command::Activate => robot.activate().map(|()| String::new()).map_err(runner),
        Command::Disable => robot.shutdown().map(|p| p.to_string()).map_err(runner),
        Command::ClearFault => robot
            .clear_fault()
            .map(|r| format!("cleared: {r}"))
            .map_err(runner),
        Command::Relay(true) => relay_on(robot, shared, options, robot_boards),
        Command::Relay(false) => relay_off(robot, shared, options),
        Command::Amplifiers(true) => amplifiers_on(robot, shared, robot_boards),
        Command::Amplifiers(false) => amplifiers_off(robot, shared, options),
        Command::Watchdog(period) => robot
            .io_mut()
            .set_watchdog(period)
            .map(|()| String::new())
            .map_err(|e| failed(e.to_string())),
        Command::ServoJoints {
            first,
            count,
            positions,
            velocities,
            trace: _,
        } => {
            ready_for_motion(robot, shared)?;
            for (n, (k, &p)) in joints(robot, first, count, &positions)?.enumerate() {
                let v = velocities
                    .get(n)
                    .copied()
                    .filter(|v| v.is_finite())
                    .unwrap_or(0.0);
                let point =
                    ServoPoint::new(p, v, SERVO_HORIZON).map_err(|e| refused(e.to_string()))?;
                robot.set_motion(k, Motion::Servo(point)).map_err(runner)?;
            }
            // Applied: the next write block carries it (the loop logs
            // its trace once that block is sent).
            shared.servo_applied.fetch_add(1, Ordering::Relaxed);
            // (An empty String does not allocate.)
            Ok(String::new())
        }
        Command::MoveJoints {
            first,
            count,
            positions,
        } => {
            ready_for_motion(robot, shared)?;
            let mut ends = robot.now();
            let targets = joints(robot, first, count, &positions)?;
            for (k, &goal) in targets {
                let here = robot.setpoint(k).unwrap_or(goal);
                let (v, a) = options
                    .config
                    .joints()
                    .nth(k)
                    .and_then(|j| j.actuator.limits)
                    .map_or((0.5, 2.0), |l| (l.velocity, l.acceleration.unwrap_or(2.0)));
                let p2p =
                    PointToPoint::new(here, goal, v, a).map_err(|e| refused(e.to_string()))?;
                ends = ends.max(robot.now() + p2p.duration());
                robot
                    .set_motion(k, Motion::PointToPoint(p2p))
                    .map_err(runner)?;
            }
            shared.move_ends.store(ends.to_bits(), Ordering::Relaxed);
            Ok(String::new())
        }
        Command::Inject(fault) => {
            let script = fault.script(options.watchdog.period_or_zero());
            let nodes = robot.io().board_nodes();
            options
                .faults
                .apply_all(&script, robot.io_mut().port_mut(), &nodes)
                .map_err(|e| refused(e.to_string()))?;
            if fault == DemoFault::FollowingError {
                robot.step_setpoint(0, 0.5).map_err(runner)?;
            }
            Ok(String::new())
        }
    }
}

/// Close the relay of the robot's boards and wait until they report it closed.
fn relay_on<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    options: &LoopOptions,
    robot_boards: BoardSet,
) -> Result<String, Refusal> {
    if let Some(r) = power_refusal(robot, "relay on") {
        return Err(r);
    }
    for b in robot.io_mut().boards_mut() {
        if robot_boards.contains(b.board_id()) {
            b.set_relay(true);
        }
    }
    let closed = |r: &Robot<IoSystem<P>>| {
        boards_not(
            r,
            robot_boards,
            firelink_host::qla::board::BoardIo::relay_on,
        ) == 0
    };
    if !settle(robot, shared, options, closed) {
        let open = boards_not(
            robot,
            robot_boards,
            firelink_host::qla::board::BoardIo::relay_on,
        );
        return Err(failed(format!(
            "the relay of boards {} did not report closed",
            board_list(open)
        )));
    }
    Ok(format!(
        "relay closed at boards {}",
        board_list(robot_boards.0)
    ))
}

/// Open the relay of every board and wait until they report it open.
fn relay_off<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    options: &LoopOptions,
) -> Result<String, Refusal> {
    for b in robot.io_mut().boards_mut() {
        b.set_relay(false);
    }
    let all = all_boards(robot);
    let open = |r: &Robot<IoSystem<P>>| boards_not(r, all, |b| !b.relay_on()) == 0;
    if !settle(robot, shared, options, open) {
        let closed = boards_not(robot, all, |b| !b.relay_on());
        return Err(failed(format!(
            "boards {} did not report their relay open (or did not answer)",
            board_list(closed)
        )));
    }
    Ok(format!("relay open at boards {}", board_list(all.0)))
}

/// Turn on the amplifiers of the axes the joints use, watched cycle by cycle.
fn amplifiers_on<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    robot_boards: BoardSet,
) -> Result<String, Refusal> {
    if let Some(r) = power_refusal(robot, "amplifiers on") {
        return Err(r);
    }
    robot
        .enable_amplifiers_observed(&mut |r| publish(shared, r, None))
        .map_err(|e| match runner(e) {
            Refusal(Verdict::Refused, why) => refused(format!(
                "amplifiers on needs motor power (power on first): {why}"
            )),
            other => other,
        })?;
    Ok(format!(
        "amplifiers on for the {} axes the joints use, at boards {}; the other axes stay off",
        robot.joint_count(),
        board_list(robot_boards.0)
    ))
}

/// Turn every amplifier off and wait until every board reports them off.
fn amplifiers_off<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    options: &LoopOptions,
) -> Result<String, Refusal> {
    for b in robot.io_mut().boards_mut() {
        b.set_all_amps(false);
    }
    let all = all_boards(robot);
    let any_on = |b: &firelink_host::qla::board::BoardIo| (0..b.axes()).any(|a| b.amp_enabled(a));
    let off = |r: &Robot<IoSystem<P>>| boards_not(r, all, |b| !any_on(b)) == 0;
    if !settle(robot, shared, options, off) {
        let on = boards_not(robot, all, |b| !any_on(b));
        return Err(failed(format!(
            "boards {} still report an amplifier on (or did not answer)",
            board_list(on)
        )));
    }
    Ok(format!(
        "every amplifier off at boards {}",
        board_list(all.0)
    ))
}

/// Motion commands need an Active robot whose joints are homed.
fn ready_for_motion<P: firelink_host::Port + 'static>(
    robot: &Robot<IoSystem<P>>,
    shared: &Shared,
) -> Result<(), Refusal> {
    if robot.state() != State::Active {
        return Err(refused(format!(
            "motion needs an active robot: it is {}",
            robot.state()
        )));
    }
    if !shared.homed.load(Ordering::Relaxed) {
        return Err(refused("motion needs homed joints: home first"));
    }
    Ok(())
}

/// Joint indices and positions of a servo or move command, checked.
fn joints<'a, P: firelink_host::Port + 'static>(
    robot: &Robot<IoSystem<P>>,
    first: u16,
    count: u8,
    positions: &'a [f64; MAX_ARM_JOINTS],
) -> Result<impl Iterator<Item = (usize, &'a f64)> + 'a, Refusal> {
    let first = usize::from(first);
    let count = usize::from(count);
    if count > MAX_ARM_JOINTS || first + count > robot.joint_count() {
        return Err(refused(format!(
            "joints {first}..{} do not exist ({} joints)",
            first + count,
            robot.joint_count()
        )));
    }
    if let Some(p) = positions[..count].iter().find(|p| !p.is_finite()) {
        return Err(refused(format!("position {p} is not a number")));
    }
    Ok(positions[..count]
        .iter()
        .enumerate()
        .map(move |(i, p)| (first + i, p)))
}

/// Run the robot until `shared.stop` or the robot's stop request (by
/// default the process's: a signal); then power down, whatever ended the
/// loop, a panic inside it included, and record how in [`Shared::exit`].
/// Call on the thread that owns the robot.
pub fn run<P: firelink_host::Port + 'static>(
    mut robot: Robot<IoSystem<P>>,
    shared: Arc<Shared>,
    options: LoopOptions,
) -> LoopExit {
    let looped = std::panic::catch_unwind(AssertUnwindSafe(|| {
        cycle_until_stopped(&mut robot, &shared, &options);
    }));
    let panic = looped.err().map(|p| panic_text(p.as_ref()));
    let stopped_by = robot.stop_request().reason();
    // The power-down rule needs only the I/O system, so it runs after a
    // panic too. (Should it panic itself, this thread unwinds, the I/O
    // system's drop runs the rule once more, and `Service::stop` reports
    // the panic.)
    let power_down = robot.shutdown().ok();
    publish(&shared, &robot, None);
    let exit = LoopExit {
        power_down,
        panic,
        stopped_by,
    };
    let _ = shared.exit.set(exit.clone());
    // Whoever waits for a command still queued is told it never ran.
    let why = format!("not run: the robot loop has ended ({exit})");
    while let Some(command) = shared.commands.pop() {
        outcome(&shared, 0, command, Err(refused(why.clone())));
    }
    while let Some(Request { id, command }) = shared.requests.pop() {
        outcome(&shared, id, command, Err(refused(why.clone())));
    }
    exit
}

/// A panic's message.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// The loop proper: commands between cycles, a frame after each; between
/// cycles it sleeps until the next is due or a command is queued
/// ([`crate::cycle_schedule`]).
fn cycle_until_stopped<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    options: &LoopOptions,
) {
    let _ = shared.robot_thread.set(std::thread::current());
    let period = options.period.as_duration();
    // A machine's clock: as the runner's pacing, a cycle more than half a
    // period late restarts the schedule. Virtual time: the missed cycles
    // are caught up (for up to a second), as virtual time is kept in step
    // with the wall clock.
    let catch_up = match options.pacing {
        Pacing::WallClock => period / 2,
        Pacing::Virtual => Duration::from_secs(1),
    };
    let mut schedule = CycleSchedule::new(period, catch_up);
    let wall_start = Instant::now();
    // The port's clock at the last cycle's start (to move a virtual clock
    // by the schedule's interval).
    let mut last_port_start: Option<f64> = None;
    // The traces of the servo points taken for this cycle, with the cycle
    // that carries each (the next one run: this loop's, or the first of a
    // command queued behind it that runs cycles of its own), logged once
    // this loop's cycle is done (sized here, once: the cycle does not
    // allocate).
    let mut traced: Vec<(ServoTrace, u64)> = Vec::with_capacity(shared.commands.capacity());
    let mut busy = None;
    let cpu_clock = crate::cpu::ThreadCpuClock::current();
    // (The stop request is the process's unless the robot was given
    // another: a signal stops the loop at once, whatever its consumer
    // does.)
    while !shared.stop.load(Ordering::Relaxed) && !robot.stop_request().is_requested() {
        let now = wall_start.elapsed();
        let waiting = !shared.commands.is_empty() || !shared.requests.is_empty();
        if let Due::At(t) = schedule.due(now, waiting) {
            // Until the cycle is due, or a consumer's nudge; then look again.
            std::thread::park_timeout(t.saturating_sub(now));
            continue;
        }
        let kind = schedule.start(now);
        if let Some(count) = shared.cycle_starts.get(kind.index()) {
            count.fetch_add(1, Ordering::Relaxed);
        }
        let work_start = Instant::now();
        let cpu_start = cpu_clock.and_then(|c| c.now());
        if options.pacing == Pacing::Virtual {
            // The port's clock moves by the schedule's interval (not less):
            // a period for a cycle on schedule, the time since the last
            // cycle's slot for an early one, so the control law's period
            // is the real interval; never more than a period, as before: the
            // simulated boards do not see this thread wait for a CPU (a
            // busy machine would trip their watchdogs).
            if let (Some(port), Some(interval)) = (last_port_start, schedule.slot_interval()) {
                let behind = port + interval.as_secs_f64() - robot.now();
                if behind > 0.0 {
                    robot.io_mut().wait(Duration::from_secs_f64(behind));
                }
            }
        }
        last_port_start = Some(robot.now());
        take_commands(robot, shared, options, &mut traced);
        // A fault is latched in the robot and shown in the frames; the
        // loop keeps cycling (outputs safe) until it is cleared.
        let _ = robot.cycle();
        // A bus reset renumbers nodes: the boards are found again between
        // cycles (a failed attempt is retried after the next cycle).
        let _ = robot.io_mut().recover();
        log_applied(shared, &mut traced, work_start);
        publish(shared, robot, busy);
        let cpu_end = cpu_clock.and_then(|c| c.now());
        busy = Some(LoopCost {
            wall_us: work_start.elapsed().as_secs_f64() * 1e6,
            cpu_us: cpu_start
                .zip(cpu_end)
                .map(|(a, b)| b.saturating_sub(a).as_secs_f64() * 1e6),
        });
    }
}

/// Every command waiting, taken before a cycle (at most what the queues
/// hold, so a cycle's work stays bounded): a servo stream faster than the
/// loop (a slow machine, a debug build) then never fills the queue; the
/// newest servo point of an arm wins. The traced servo points go to
/// `traced`, with the cycle that carries them.
fn take_commands<P: firelink_host::Port + 'static>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    options: &LoopOptions,
    traced: &mut Vec<(ServoTrace, u64)>,
) {
    // Said before the queue is read (and fenced): a consumer that reads it
    // after queueing knows which cycle at the latest carries its command.
    shared
        .commands_taken_for
        .store(robot.cycles() + 1, Ordering::SeqCst);
    std::sync::atomic::fence(Ordering::SeqCst);
    for _ in 0..shared.commands.capacity() {
        let Some(command) = shared.commands.pop() else {
            break;
        };
        let r = execute(robot, shared, command, options);
        // Servo commands stream at the publisher's rate: only their
        // refusals are reported (the success path allocates nothing).
        match (command, &r) {
            (Command::ServoJoints { trace, .. }, Ok(_)) => {
                if (trace.source_ns != 0 || trace.queued_ns != 0)
                    && traced.len() < traced.capacity()
                {
                    traced.push((trace, robot.cycles() + 1));
                }
            }
            _ => outcome(shared, 0, command, r),
        }
    }
    for _ in 0..shared.requests.capacity() {
        let Some(Request { id, command }) = shared.requests.pop() else {
            break;
        };
        let r = execute(robot, shared, command, options);
        outcome(shared, id, command, r);
    }
}

/// The servo points of `traced` have been carried by the write blocks of
/// their cycles, the last of them just sent (that cycle started at
/// `cycle_start`): log them for the consumer (the clocks are read once,
/// and only when there is one), and empty `traced`.
fn log_applied(shared: &Shared, traced: &mut Vec<(ServoTrace, u64)>, cycle_start: Instant) {
    if traced.is_empty() {
        return;
    }
    // The sender's stamps are on the wall clock; so is "applied".
    let applied_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let took_ns = u64::try_from(cycle_start.elapsed().as_nanos()).unwrap_or(u64::MAX);
    let started_ns = applied_ns.saturating_sub(took_ns);
    for &(trace, cycle) in traced.iter() {
        let entry = ServoApplied {
            trace,
            cycle,
            started_ns,
            applied_ns,
        };
        if shared.servo_log.push(entry).is_err() {
            shared.servo_log_dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
    traced.clear();
}

/// The name of the robot loop's thread (as the OS shows it, e.g. in
/// `/proc/<pid>/task/<tid>/comm`): how a front end finds the thread to give
/// it a real-time priority.
pub const ROBOT_THREAD_NAME: &str = "firelink-robot";

/// A robot service running in its own thread.
pub struct Service {
    /// What the loop and its consumers share.
    pub shared: Arc<Shared>,
    /// The faults this port can inject.
    pub faults: Vec<DemoFault>,
    thread: Option<JoinHandle<LoopExit>>,
    emulator: Option<rig::Emulator>,
}

impl Service {
    /// Start the robot of `config` on `port` (emulated boards at firmware
    /// Rev 8 for `sim` and `emulate`, unless `sim:N:FW` names one) at
    /// a servo period of `period`; the loop runs until [`stop`](Self::stop).
    ///
    /// # Errors
    /// A failed scan or configuration, sockets, the thread.
    pub fn start(
        port: &PortSpec,
        config: IoConfig,
        period: ServoPeriod,
        watchdog: WatchdogSetting,
    ) -> Result<Service, crate::TestbedError> {
        Service::start_with_timeout(port, config, period, watchdog, rig::UDP_TIMEOUT)
    }

    /// [`start`](Self::start) with `timeout` as the read time-out of a
    /// UDP or FireWire port (the scan waits that long for each absent
    /// node, a servo cycle that long for an answer before the board
    /// counts as missed) instead of [`rig::UDP_TIMEOUT`]; `sim` has none.
    ///
    /// # Errors
    /// As [`start`](Self::start).
    pub fn start_with_timeout(
        port: &PortSpec,
        config: IoConfig,
        period: ServoPeriod,
        watchdog: WatchdogSetting,
        timeout: Duration,
    ) -> Result<Service, crate::TestbedError> {
        let boards = config.board_slots();
        let options = |pacing, faults| LoopOptions {
            config: config.clone(),
            period,
            watchdog,
            pacing,
            faults,
        };
        // The presets whose script the port's fault target can apply on
        // that port (so that the console offers none that cannot work).
        fn offered<P: firelink_host::Port + 'static>(
            target: &FaultTarget,
            port: &P,
            watchdog: WatchdogSetting,
        ) -> Vec<DemoFault> {
            DemoFault::ALL
                .into_iter()
                .filter(|f| *f != DemoFault::None)
                .filter(|f| {
                    target
                        .check(&f.script(watchdog.period_or_zero()), port, None)
                        .is_ok()
                })
                .collect()
        }
        let configs = || rig::board_configs(&config, Profile::Rev8, boards);
        let (shared, thread, emulator, faults) = match port {
            PortSpec::Sim(_) => {
                let boards = crate::ports::sim_boards(port, &config, Profile::Rev8);
                let rig = rig::RigBuilder::qla(boards).build()?;
                let target = rig.fault_target();
                let port = rig.sim_port();
                let faults = offered(&target, &port, watchdog);
                let (s, h) = spawn(port, "sim".into(), options(Pacing::Virtual, target))?;
                (s, h, None, faults)
            }
            PortSpec::Emulate => {
                let emu = rig::Emulator::start(configs())?;
                let name = format!("udp:{} (in-process emulator)", emu.addr);
                let mut port = emu.port()?;
                port.set_timeout(timeout);
                let target = emu.fault_target();
                let faults = offered(&target, &port, watchdog);
                let (s, h) = spawn(port, name, options(Pacing::WallClock, target))?;
                (s, h, Some(emu), faults)
            }
            PortSpec::Udp(addr) | PortSpec::UdpFw(addr) => {
                let force_bridge = matches!(port, PortSpec::UdpFw(_));
                let net = firelink_host::eth::UdpNetPort::open(
                    *addr,
                    force_bridge,
                    timeout,
                    Default::default(),
                )?;
                let name = firelink_host::port::Port::name(&net).to_string();
                let faults = offered(&FaultTarget::link(), &net, watchdog);
                let (s, h) = spawn(net, name, options(Pacing::WallClock, FaultTarget::link()))?;
                (s, h, None, faults)
            }
            PortSpec::Fw(card) => {
                let fw = crate::ports::fw_port(
                    *card,
                    &crate::ports::PortOptions {
                        timeout,
                        ..crate::ports::PortOptions::default()
                    },
                )?;
                let faults = offered(&FaultTarget::link(), &fw, watchdog);
                let options = options(Pacing::WallClock, FaultTarget::link());
                let (s, h) = spawn(fw, port.to_string(), options)?;
                (s, h, None, faults)
            }
        };
        Ok(Service {
            shared,
            faults,
            thread: Some(thread),
            emulator,
        })
    }

    /// The robot of `options` on a port of the caller's (a test's port
    /// that misbehaves on purpose, say): the same loop as
    /// [`start`](Self::start); no fault is offered for injection
    /// ([`faults`](Self::faults) is empty).
    ///
    /// # Errors
    /// A failed scan or configuration, the thread.
    pub fn on_port<P: firelink_host::Port + Send + 'static>(
        port: P,
        name: String,
        options: LoopOptions,
    ) -> Result<Service, crate::TestbedError> {
        let (shared, thread) = spawn(port, name, options)?;
        Ok(Service {
            shared,
            faults: Vec::new(),
            thread: Some(thread),
            emulator: None,
        })
    }

    /// Stop the loop (it powers the robot down first) and the emulator;
    /// returns how the loop ended and what the power-down found.
    pub fn stop(mut self) -> LoopExit {
        self.shutdown()
    }

    fn shutdown(&mut self) -> LoopExit {
        self.shared.stop.store(true, Ordering::Relaxed);
        self.shared.nudge();
        let exit = match self.thread.take() {
            Some(t) => match t.join() {
                Ok(exit) => exit,
                // The power-down itself panicked (the loop's own panics are
                // caught and powered down after).
                Err(p) => LoopExit {
                    power_down: None,
                    panic: Some(panic_text(p.as_ref())),
                    stopped_by: None,
                },
            },
            None => self.shared.exit.get().cloned().unwrap_or(LoopExit {
                power_down: None,
                panic: None,
                stopped_by: None,
            }),
        };
        if let Some(e) = self.emulator.take() {
            let _ = e.stop();
        }
        exit
    }
}

impl Drop for Service {
    /// A service dropped without [`stop`](Service::stop) still powers the
    /// robot down; a panic of its loop is reported on stderr, since no one
    /// else can.
    fn drop(&mut self) {
        if self.thread.is_some() {
            let exit = self.shutdown();
            if exit.panic.is_some() {
                // Never a panic here (a closed stderr): this may run while
                // unwinding, where a second panic aborts.
                let _ = writeln!(std::io::stderr(), "firelink: robot service: {exit}");
            }
        }
    }
}

fn spawn<P: firelink_host::Port + Send + 'static>(
    port: P,
    name: String,
    options: LoopOptions,
) -> Result<(Arc<Shared>, JoinHandle<LoopExit>), crate::TestbedError> {
    let (robot, shared) = prepare(port, name, &options)?;
    let loop_shared = Arc::clone(&shared);
    let handle = std::thread::Builder::new()
        .name(ROBOT_THREAD_NAME.into())
        .spawn(move || run(robot, loop_shared, options))?;
    Ok((shared, handle))
}
