//! The real-time side: one thread owns the robot (configuration, I/O
//! system, port) and runs its servo cycles; it never waits on the server.
//!
//! Hand-off is lock-free and allocation-free once running: a fixed pool of
//! [`Frame`]s travels between two bounded queues. After each cycle the loop
//! takes a free frame (if none is free the server is behind and this
//! cycle's frame is skipped, counted), fills it in place and queues it as
//! full; the server drains full frames and gives them back. Commands from
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
use firelink_host::io::{IoConfig as HostIoConfig, IoSystem};
use firelink_testbed::demo::{DemoFault, Injector, motion_for};

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
            errors: 0,
            joints: vec![JointSample::default(); joints],
            axes: vec![AxisSample::default(); axes],
            boards: vec![BoardSample::default(); boards],
        }
    }

    /// Fill from the robot after a cycle; no allocation.
    fn fill<P: firelink_host::Port>(&mut self, robot: &Robot<P>) {
        self.t = robot.now();
        self.cycle = robot.cycles();
        self.state = robot.state();
        self.fault = robot.fault().copied();
        self.io_us = robot
            .last_report()
            .map_or(0.0, |r| r.io_time().as_secs_f64() * 1e6);
        self.errors = robot.io_stats().total_errors();
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
    /// Set every board's watchdog period.
    Watchdog(Duration),
    /// Inject a fault on the port.
    Inject(DemoFault),
}

/// What happened to the last command.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CommandOutcome {
    /// The command, as text.
    pub command: String,
    /// `ok` or the error.
    pub result: String,
}

/// The queues and flags shared by the loop and the server.
pub struct Shared {
    /// Frames ready for the server.
    pub full: ArrayQueue<Box<Frame>>,
    /// Frames the loop may fill.
    pub free: ArrayQueue<Box<Frame>>,
    /// Commands for the loop.
    pub commands: ArrayQueue<Command>,
    /// Outcomes of commands (the server reads them).
    pub outcomes: ArrayQueue<CommandOutcome>,
    /// Frames skipped because none was free.
    pub skipped: AtomicU64,
    /// Commands the server accepted and queued.
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
}

/// Frames in the pool: a second of cycles at 1 kHz lets the server be late
/// by that much without a skipped frame.
pub const POOL: usize = 1024;

/// How to run the loop.
#[derive(Debug, Clone)]
pub struct LoopOptions {
    /// The robot.
    pub config: IoConfig,
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Board watchdog period.
    pub watchdog: Duration,
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
) -> Result<(Robot<P>, Arc<Shared>), firelink_testbed::TestbedError> {
    let (io, _) = IoSystem::open(port, HostIoConfig::default())?;
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

fn publish<P: firelink_host::Port>(shared: &Shared, robot: &Robot<P>) {
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
    robot: &mut Robot<P>,
    shared: &Shared,
    command: Command,
    options: &LoopOptions,
) -> Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    match command {
        Command::Configure => robot.configure().map_err(|e| text(&e)),
        Command::PowerOn => robot
            .power_on_observed(&mut |r| publish(shared, r))
            .map_err(|e| text(&e)),
        Command::Home => robot.home().map_err(|e| text(&e)),
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
        Command::Disable => robot.shutdown().map_err(|e| text(&e)),
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
        Command::Inject(fault) => {
            let watchdog = options.watchdog;
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

/// Run the robot until `shared.stop`; then power off. Call on the thread
/// that owns the robot.
pub fn run<P: Injector>(mut robot: Robot<P>, shared: Arc<Shared>, options: LoopOptions) {
    let period = Duration::from_secs_f64(1.0 / options.rate_hz);
    let wall_start = Instant::now();
    let port_start = robot.now();
    while !shared.stop.load(Ordering::Relaxed) {
        if let Some(command) = shared.commands.pop() {
            let r = execute(&mut robot, &shared, command, &options);
            outcome(&shared, command, r);
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
