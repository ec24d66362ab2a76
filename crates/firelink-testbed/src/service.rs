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

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crossbeam_queue::ArrayQueue;

use firelink_control::FaultReport;
use firelink_control::config::IoConfig;
use firelink_control::lifecycle::State;
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, PointToPoint, ServoPoint};
use firelink_host::WatchdogSetting;
use firelink_host::io::{IoOptions, IoSystem};
use std::thread::JoinHandle;

use firelink_board::config::Profile;

use crate::demo::{DemoFault, DemoPort, Injector, motion_for};
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
            errors: 0,
            joints: vec![JointSample::default(); joints],
            axes: vec![AxisSample::default(); axes],
            boards: vec![BoardSample::default(); boards],
        }
    }

    /// Fill from the robot after a cycle; no allocation.
    fn fill<P: firelink_host::Port>(&mut self, robot: &Robot<IoSystem<P>>) {
        self.t = robot.now();
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

/// What the browser can ask of the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Unconfigured -> Configured (boards found, watchdogs set).
    Configure,
    /// Power, relay and amplifiers on.
    PowerOn,
    /// Home every joint against its potentiometer.
    Home,
    /// Configured -> Active, then the demo's motions on every joint.
    Enable,
    /// Active -> Configured, then amplifiers, power and relay off.
    Disable,
    /// Acknowledge a fault (-> Unconfigured).
    ClearFault,
    /// Request the safety relay of every board (outside the lifecycle).
    Relay(bool),
    /// Request every amplifier on or off (outside the lifecycle: turning
    /// them off while Active is a fault, as on a real robot).
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
        /// When the sender stamped it, ns since the Unix epoch (0: not
        /// stamped); the loop records stamp-to-applied latency.
        stamp_ns: u64,
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

/// The most joints one servo or move command carries (one arm).
pub const MAX_ARM_JOINTS: usize = 16;

/// How long a servo point is extrapolated at its velocity before the
/// joint holds (a stream that stops leaves the joint still), seconds.
pub const SERVO_HORIZON: f64 = 0.05;

/// What happened to the last command.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CommandOutcome {
    /// The command, as text.
    pub command: String,
    /// `ok` or the error.
    pub result: String,
}

/// The queues and flags shared by the loop and the consumer.
pub struct Shared {
    /// Frames ready for the consumer.
    pub full: ArrayQueue<Box<Frame>>,
    /// Frames the loop may fill.
    pub free: ArrayQueue<Box<Frame>>,
    /// Commands for the loop.
    pub commands: ArrayQueue<Command>,
    /// Outcomes of commands (the consumer reads them).
    pub outcomes: ArrayQueue<CommandOutcome>,
    /// Frames skipped because none was free.
    pub skipped: AtomicU64,
    /// Commands the consumer accepted and queued.
    pub queued: AtomicU64,
    /// Set to stop the loop (it powers off first).
    pub stop: AtomicBool,
    /// Joint labels, in configuration order.
    pub joint_labels: Vec<String>,
    /// Control rate, Hz.
    pub rate_hz: f64,
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
    /// The last applied servo command's stamp-to-applied latency, ns.
    pub servo_latency_ns: AtomicU64,
}

/// Frames in the pool: a second of cycles at 1 kHz lets the consumer be late
/// by that much without a skipped frame.
pub const POOL: usize = 1024;

/// How to run the loop.
#[derive(Debug, Clone)]
pub struct LoopOptions {
    /// The robot.
    pub config: IoConfig,
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Board watchdog.
    pub watchdog: WatchdogSetting,
    /// `Virtual` on the simulated bus (then paced to the wall clock by the
    /// loop so the browser sees real time), `WallClock` over UDP.
    pub pacing: Pacing,
}

/// Open the I/O system and the robot on `port`, size the frame pool and
/// the shared state. The robot is returned to be moved into [`run`]'s thread.
///
/// # Errors
/// The scan or the configuration failed.
pub fn prepare<P: Injector>(
    port: P,
    port_name: String,
    options: &LoopOptions,
) -> Result<(Robot<IoSystem<P>>, Arc<Shared>), crate::TestbedError> {
    let (io, _) = IoSystem::open(port, IoOptions::default())?;
    let settings = RobotSettings {
        rate_hz: options.rate_hz,
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
        outcomes: ArrayQueue::new(64),
        skipped: AtomicU64::new(0),
        queued: AtomicU64::new(0),
        stop: AtomicBool::new(false),
        joint_labels,
        rate_hz: options.rate_hz,
        port_name,
        board_infos,
        homed: AtomicBool::new(false),
        move_ends: AtomicU64::new(0f64.to_bits()),
        servo_applied: AtomicU64::new(0),
        servo_latency_ns: AtomicU64::new(0),
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

fn publish<P: firelink_host::Port>(shared: &Shared, robot: &Robot<IoSystem<P>>) {
    match shared.free.pop() {
        Some(mut frame) => {
            frame.fill(robot);
            if let Err(frame) = shared.full.push(frame) {
                let _ = shared.free.push(frame);
                shared.skipped.fetch_add(1, Ordering::Relaxed);
            }
        }
        None => {
            shared.skipped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

fn outcome(shared: &Shared, command: Command, result: Result<(), String>) {
    // A full outcome queue drops the oldest: the browser only shows the last.
    let entry = CommandOutcome {
        command: format!("{command:?}"),
        result: result.err().unwrap_or_else(|| "ok".into()),
    };
    if let Err(entry) = shared.outcomes.push(entry) {
        let _ = shared.outcomes.pop();
        let _ = shared.outcomes.push(entry);
    }
}

fn execute<P: Injector>(
    robot: &mut Robot<IoSystem<P>>,
    shared: &Shared,
    command: Command,
    options: &LoopOptions,
) -> Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    match command {
        Command::Configure => {
            shared.homed.store(false, Ordering::Relaxed);
            robot.configure().map(|_| ()).map_err(|e| text(&e))
        }
        Command::PowerOn => robot
            .power_on_observed(&mut |r| publish(shared, r))
            .map_err(|e| text(&e)),
        Command::Home => {
            robot.home().map_err(|e| text(&e))?;
            shared.homed.store(true, Ordering::Relaxed);
            Ok(())
        }
        Command::Enable => {
            robot.activate().map_err(|e| text(&e))?;
            for i in 0..robot.joint_count() {
                let here = robot.position(i).unwrap_or(0.0);
                robot
                    .set_motion(i, motion_for(&options.config, i, here))
                    .map_err(|e| text(&e))?;
            }
            Ok(())
        }
        Command::Activate => robot.activate().map_err(|e| text(&e)),
        Command::Disable => robot.shutdown().map(|_| ()).map_err(|e| text(&e)),
        Command::ClearFault => robot.clear_fault().map(|_| ()).map_err(|e| text(&e)),
        Command::Relay(on) => {
            for b in robot.io_mut().boards_mut() {
                b.set_relay(on);
            }
            Ok(())
        }
        Command::Amplifiers(on) => {
            for b in robot.io_mut().boards_mut() {
                b.set_all_amps(on);
            }
            Ok(())
        }
        Command::Watchdog(period) => robot.io_mut().set_watchdog(period).map_err(|e| text(&e)),
        Command::ServoJoints {
            first,
            count,
            positions,
            velocities,
            stamp_ns,
        } => {
            ready_for_motion(robot, shared)?;
            for (n, (k, &p)) in joints(robot, first, count, &positions)?.enumerate() {
                let v = velocities
                    .get(n)
                    .copied()
                    .filter(|v| v.is_finite())
                    .unwrap_or(0.0);
                let point = ServoPoint::new(p, v, SERVO_HORIZON).map_err(|e| text(&e))?;
                robot
                    .set_motion(k, Motion::Servo(point))
                    .map_err(|e| text(&e))?;
            }
            // Applied: the next write block carries it.
            if stamp_ns > 0 {
                let now = std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos() as u64);
                shared
                    .servo_latency_ns
                    .store(now.saturating_sub(stamp_ns), Ordering::Relaxed);
            }
            shared.servo_applied.fetch_add(1, Ordering::Relaxed);
            Ok(())
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
                let p2p = PointToPoint::new(here, goal, v, a).map_err(|e| text(&e))?;
                ends = ends.max(robot.now() + p2p.duration());
                robot
                    .set_motion(k, Motion::PointToPoint(p2p))
                    .map_err(|e| text(&e))?;
            }
            shared.move_ends.store(ends.to_bits(), Ordering::Relaxed);
            Ok(())
        }
        Command::Inject(fault) => {
            let watchdog = options.watchdog.period_or_zero();
            robot
                .io_mut()
                .port_mut()
                .inject(fault, watchdog)
                .map_err(|e| text(&e))?;
            if fault == DemoFault::FollowingError {
                robot.step_setpoint(0, 0.5).map_err(|e| text(&e))?;
            }
            Ok(())
        }
    }
}

/// Motion commands need an Active robot whose joints are homed.
fn ready_for_motion<P: Injector>(
    robot: &Robot<IoSystem<P>>,
    shared: &Shared,
) -> Result<(), String> {
    if robot.state() != State::Active {
        return Err(format!(
            "refused: the robot is {}, not active",
            robot.state()
        ));
    }
    if !shared.homed.load(Ordering::Relaxed) {
        return Err("refused: not homed".into());
    }
    Ok(())
}

/// Joint indices and positions of a servo or move command, checked.
fn joints<'a, P: Injector>(
    robot: &Robot<IoSystem<P>>,
    first: u16,
    count: u8,
    positions: &'a [f64; MAX_ARM_JOINTS],
) -> Result<impl Iterator<Item = (usize, &'a f64)> + 'a, String> {
    let first = usize::from(first);
    let count = usize::from(count);
    if count > MAX_ARM_JOINTS || first + count > robot.joint_count() {
        return Err(format!(
            "joints {first}..{} do not exist ({} joints)",
            first + count,
            robot.joint_count()
        ));
    }
    if let Some(p) = positions[..count].iter().find(|p| !p.is_finite()) {
        return Err(format!("position {p} is not a number"));
    }
    Ok(positions[..count]
        .iter()
        .enumerate()
        .map(move |(i, p)| (first + i, p)))
}

/// Run the robot until `shared.stop`; then power off. Call on the thread
/// that owns the robot.
pub fn run<P: Injector>(mut robot: Robot<IoSystem<P>>, shared: Arc<Shared>, options: LoopOptions) {
    let period = Duration::from_secs_f64(1.0 / options.rate_hz);
    let wall_start = Instant::now();
    let port_start = robot.now();
    while !shared.stop.load(Ordering::Relaxed) {
        // Every command waiting is taken before the cycle (at most what the
        // queue holds, so a cycle's work stays bounded): a servo stream
        // faster than this loop (a slow machine, a debug build) then never
        // fills the queue; the newest servo point of an arm wins.
        for _ in 0..shared.commands.capacity() {
            let Some(command) = shared.commands.pop() else {
                break;
            };
            let r = execute(&mut robot, &shared, command, &options);
            // Servo commands stream at the publisher's rate: only their
            // refusals are reported (the success path allocates nothing).
            if r.is_err() || !matches!(command, Command::ServoJoints { .. }) {
                outcome(&shared, command, r);
            }
        }
        // A fault is latched in the robot and shown in the frames; the
        // loop keeps cycling (outputs safe) until it is cleared.
        let _ = robot.step(options.pacing);
        publish(&shared, &robot);
        if options.pacing == Pacing::Virtual {
            // Keep virtual time in step with the wall clock so the browser
            // sees the robot move at its real speed.
            let ahead = (robot.now() - port_start) - wall_start.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(Duration::from_secs_f64(ahead).min(period * 4));
            }
        }
    }
    let _ = robot.shutdown();
    publish(&shared, &robot);
}

/// A robot service running in its own thread.
pub struct Service {
    /// What the loop and its consumers share.
    pub shared: Arc<Shared>,
    /// The faults this port can inject.
    pub faults: Vec<DemoFault>,
    thread: Option<JoinHandle<()>>,
    emulator: Option<rig::Emulator>,
}

impl Service {
    /// Start the robot of `config` on `port` (emulated boards at firmware
    /// Rev 8 for `sim` and `emulate`) at `rate_hz`; the loop runs until
    /// [`stop`](Self::stop).
    ///
    /// # Errors
    /// A bad rate, a failed scan or configuration, sockets, the thread.
    pub fn start(
        port: &DemoPort,
        config: IoConfig,
        rate_hz: f64,
        watchdog: WatchdogSetting,
    ) -> Result<Service, crate::TestbedError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 20_000.0) {
            return Err(crate::TestbedError::Config(format!(
                "rate {rate_hz} Hz: must be 0 < rate <= 20000"
            )));
        }
        let boards = config.board_slots();
        let options = |pacing| LoopOptions {
            config: config.clone(),
            rate_hz,
            watchdog,
            pacing,
        };
        let all: Vec<DemoFault> = DemoFault::ALL
            .iter()
            .copied()
            .filter(|f| *f != DemoFault::None)
            .collect();
        let remote = vec![DemoFault::StopHost, DemoFault::FollowingError];
        let configs = || rig::board_configs(&config, Profile::Rev8, boards);
        let (shared, thread, emulator, faults) = match port {
            DemoPort::Sim => {
                let (port, _) = rig::sim_port(configs(), false)?;
                let (s, h) = spawn(port, "sim".into(), options(Pacing::Virtual))?;
                (s, h, None, all)
            }
            DemoPort::Emulate => {
                let emu = rig::Emulator::start(configs())?;
                let name = format!("udp:{} (in-process emulator)", emu.addr);
                let port = emu.port()?;
                let (s, h) = spawn(port, name, options(Pacing::WallClock))?;
                (s, h, Some(emu), remote)
            }
            DemoPort::Udp(addr) => {
                let port = rig::udp_port(*addr)?;
                let (s, h) = spawn(port, format!("udp:{addr}"), options(Pacing::WallClock))?;
                (s, h, None, remote)
            }
        };
        Ok(Service {
            shared,
            faults,
            thread: Some(thread),
            emulator,
        })
    }

    /// Stop the loop (it powers the robot off first) and the emulator.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        if let Some(e) = self.emulator.take() {
            let _ = e.stop();
        }
    }
}

impl Drop for Service {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn spawn<P: Injector + Send + 'static>(
    port: P,
    name: String,
    options: LoopOptions,
) -> Result<(Arc<Shared>, JoinHandle<()>), crate::TestbedError> {
    let (robot, shared) = prepare(port, name, &options)?;
    let loop_shared = Arc::clone(&shared);
    let handle = std::thread::Builder::new()
        .name("firelink-robot".into())
        .spawn(move || run(robot, loop_shared, options))?;
    Ok((shared, handle))
}
