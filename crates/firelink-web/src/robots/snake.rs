//! The Snake view: seed 001's 36-axis system (two 11-axis Snake robots and
//! two 7-axis masters on six 7-channel nodes) on the simulated bus, servoed
//! by the runner's [`Robot`] over [`SnakeSystem`], as `firelink demo
//! --robot snake` runs it.
//!
//! What the page shows per axis: node and channel, setpoint, position,
//! velocity, commanded and measured current, encoder and pot, amplifier,
//! the channel's fault, its digital pot's wiper with the feedback gain it
//! sets, and its torque/speed switch; per node: answering, watchdog,
//! amplifiers. What it drives: the lifecycle (configure, power on, home,
//! enable, disable, clear fault), the tool's per-channel functions (the
//! torque/speed switch, the wiper, EEPROM words read and written raw or
//! as floats, the EEPROM's write protection), motion of one axis (move
//! to a position, jog by an amount) and the Snake demo's faults.
//!
//! Settings change the drive under the servo: they are refused while the
//! robot is enabled or an amplifier is on (disable first). Motion needs an
//! enabled, homed robot.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use firelink_control::config::IoConfig;
use firelink_control::lifecycle::State;
use firelink_control::runner::{Pacing, Robot, RobotSettings, RunnerError};
use firelink_control::trajectory::{Motion, PointToPoint};
use firelink_control::{FaultReport, ServoPeriod};
use firelink_host::WatchdogSetting;
use firelink_host::robot_io::RobotIo;
use firelink_host::sim::SimPort;
use firelink_host::snake::SnakeSystem;
use firelink_testbed::demo::{DemoFault, DemoIo};
use firelink_testbed::fault_script::FaultTarget;
use firelink_testbed::loop_outcome::LoopExit;
use firelink_testbed::snake::{node_configs, prepare, sim_port_with_faults};
use firelink_wire::snake::WIPER_MAX;
use firelink_wire::snake::registers::{PotOutputs, Wiper};

use super::{Exchange, Hosted, PUBLISH_SECONDS, Pending, Refused, RobotKind, RobotModel};
use super::{failed, pace, parse_json, refused};
use crate::WebError;

/// EEPROM words per channel (the pot's user words, 0..=13).
pub const EEPROM_WORDS: u8 = firelink_wire::snake::EEPROM_WORDS as u8;
/// The largest jog, rad or m (one click should not throw an arm).
pub const MAX_JOG: f64 = 0.5;

/// One axis as the page shows it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SnakeAxis {
    /// Node (board ID).
    pub node: u8,
    /// Channel on the node, 1..=7.
    pub channel: u8,
    /// Setpoint, rad or m.
    pub setpoint: f64,
    /// Position, rad or m.
    pub position: f64,
    /// Velocity.
    pub velocity: f64,
    /// Commanded current, A.
    pub current_cmd: f64,
    /// Measured current, A (0 when the node did not answer).
    pub current: f64,
    /// Encoder counts.
    pub encoder: i32,
    /// Pot ADC (API units, 0..=16383).
    pub pot: u16,
    /// Amplifier on.
    pub amp: bool,
    /// The channel's fault bit.
    pub fault: bool,
    /// The digital pot's wiper.
    pub wiper: u16,
    /// The motor-current feedback gain the wiper sets.
    pub gain: f64,
    /// The torque/speed switch: speed mode.
    pub speed_mode: bool,
    /// The channel's EEPROM is write-protected.
    pub write_protect: bool,
}

/// One node as the page shows it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SnakeNodeSample {
    /// Board ID.
    pub id: u8,
    /// Answered the last cycle.
    pub valid: bool,
    /// Its watchdog expired.
    pub watchdog_expired: bool,
    /// Amplifiers on (bit i: channel i + 1).
    pub amps: u8,
}

/// What the loop hands over.
#[derive(Debug, Clone)]
pub struct SnakeFrame {
    t: f64,
    cycle: u64,
    state: State,
    fault: Option<FaultReport>,
    homed: bool,
    io_us: f64,
    errors: u64,
    axes: Vec<SnakeAxis>,
    nodes: Vec<SnakeNodeSample>,
}

/// What the page can ask of the Snake system.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum SnakeCommand {
    /// Unconfigured -> Configured.
    Configure,
    /// Every used amplifier on (from Configured).
    PowerOn,
    /// Home against the pots (from Configured).
    Home,
    /// Configured -> Active, every axis holding where it is.
    Enable,
    /// Active -> Configured, amplifiers off.
    Disable,
    /// Acknowledge a fault.
    ClearFault,
    /// The torque/speed switch of an axis's channel.
    Mode {
        /// The axis (0-based, configuration order).
        axis: usize,
        /// Speed mode (`false`: torque mode).
        speed: bool,
    },
    /// The wiper of an axis's digital pot (the feedback gain).
    Wiper {
        /// The axis.
        axis: usize,
        /// 0..=1023.
        wiper: u16,
    },
    /// Read an EEPROM word of an axis's channel (two words as a float).
    EepromRead {
        /// The axis.
        axis: usize,
        /// Word 0..=13 (0..=12 for a float).
        word: u8,
        /// Read words `word` and `word + 1` as a float.
        #[serde(default)]
        float: bool,
    },
    /// Write an EEPROM word of an axis's channel.
    EepromWrite {
        /// The axis.
        axis: usize,
        /// Word 0..=13 (0..=12 for a float).
        word: u8,
        /// The value: 0..=65535, or any finite number with `float`.
        value: f64,
        /// Write `value` as a float in words `word` and `word + 1`.
        #[serde(default)]
        float: bool,
    },
    /// The EEPROM write protection of an axis's channel.
    WriteProtect {
        /// The axis.
        axis: usize,
        /// Protected.
        on: bool,
    },
    /// Move an axis to a position with its configured limits.
    Move {
        /// The axis.
        axis: usize,
        /// The goal, rad or m.
        position: f64,
    },
    /// Inject a fault on the simulated bus, as `firelink demo --robot
    /// snake --fault` does: `board-loss` (node 4 stops answering for
    /// good), `stop-host` (the host goes silent for three watchdog
    /// periods) or `following-error` (axis 0's setpoint jumps).
    Inject {
        /// The fault's name.
        fault: String,
    },
    /// Move an axis by an amount from its setpoint.
    Jog {
        /// The axis.
        axis: usize,
        /// The amount, rad or m (at most [`MAX_JOG`]).
        delta: f64,
    },
}

impl SnakeCommand {
    fn axis(&self) -> Option<usize> {
        match *self {
            SnakeCommand::Mode { axis, .. }
            | SnakeCommand::Wiper { axis, .. }
            | SnakeCommand::EepromRead { axis, .. }
            | SnakeCommand::EepromWrite { axis, .. }
            | SnakeCommand::WriteProtect { axis, .. }
            | SnakeCommand::Move { axis, .. }
            | SnakeCommand::Jog { axis, .. } => Some(axis),
            _ => None,
        }
    }

    /// Range checks that need no robot but its axis count.
    fn check(&self, axes: usize) -> Result<(), String> {
        if let Some(axis) = self.axis() {
            if axis >= axes {
                return Err(format!(
                    "axis {axis} does not exist (axes 0..={})",
                    axes - 1
                ));
            }
        }
        let word_ok = |word: u8, float: bool| {
            let last = if float {
                EEPROM_WORDS - 2
            } else {
                EEPROM_WORDS - 1
            };
            if word > last {
                Err(format!(
                    "EEPROM word {word}: 0..={last}{}",
                    if float {
                        " for a float (two words)"
                    } else {
                        ""
                    }
                ))
            } else {
                Ok(())
            }
        };
        match *self {
            SnakeCommand::Wiper { wiper, .. } if wiper > WIPER_MAX => {
                Err(format!("wiper {wiper}: 0..={WIPER_MAX}"))
            }
            SnakeCommand::EepromRead { word, float, .. } => word_ok(word, float),
            SnakeCommand::EepromWrite {
                word, value, float, ..
            } => {
                word_ok(word, float)?;
                let raw_ok = value.fract() == 0.0 && (0.0..=65535.0).contains(&value);
                if !value.is_finite() || (!float && !raw_ok) {
                    return Err(format!(
                        "EEPROM value {value}: a word is 0..=65535 (or add \"float\": true)"
                    ));
                }
                Ok(())
            }
            SnakeCommand::Move { position, .. } if !position.is_finite() => {
                Err(format!("position {position} is not a number"))
            }
            SnakeCommand::Inject { ref fault } => fault_named(fault).map(|_| ()),
            SnakeCommand::Jog { delta, .. } if !(delta.is_finite() && delta.abs() <= MAX_JOG) => {
                Err(format!("jog {delta}: at most {MAX_JOG} either way"))
            }
            _ => Ok(()),
        }
    }
}

/// The faults the Snake system can be given (the Snake demo's: a corrupt
/// query needs the broadcast protocol the nodes do not have).
pub const FAULTS: [DemoFault; 3] = [
    DemoFault::BoardLoss,
    DemoFault::StopHost,
    DemoFault::FollowingError,
];

/// One of [`FAULTS`] by its name.
fn fault_named(name: &str) -> Result<DemoFault, String> {
    let names = || FAULTS.map(DemoFault::name).join(", ");
    let fault: DemoFault = name
        .parse()
        .map_err(|_| format!("fault {name:?}: one of {}", names()))?;
    if FAULTS.contains(&fault) {
        Ok(fault)
    } else {
        Err(format!(
            "fault {name} cannot be injected here: one of {}",
            names()
        ))
    }
}

/// The Snake system's model for the server.
pub struct SnakeModel {
    labels: Vec<String>,
    nodes: Vec<u8>,
    period: ServoPeriod,
}

impl RobotModel for SnakeModel {
    type Frame = SnakeFrame;
    type Command = SnakeCommand;

    fn info(&self) -> Value {
        json!({
            "joints": self.labels,
            "nodes": self.nodes,
            "rate_hz": self.period.rate_hz(),
            "period_us": self.period.as_micros_f64(),
            "wiper_max": WIPER_MAX,
            "eeprom_words": EEPROM_WORDS,
            "max_jog": MAX_JOG,
            "faults": FAULTS.map(DemoFault::name),
        })
    }

    fn render(&self, f: &SnakeFrame) -> Value {
        json!({
            "t": f.t,
            "cycle": f.cycle,
            "state": f.state.to_string(),
            "fault": f.fault.map(|x| json!({"text": x.to_string(), "time": x.time, "cycle": x.cycle})),
            "homed": f.homed,
            "io_us": f.io_us,
            "errors": f.errors,
            "axes": f.axes,
            "nodes": f.nodes,
        })
    }

    fn parse(&self, body: &[u8]) -> Result<SnakeCommand, String> {
        let c: SnakeCommand = parse_json(body)?;
        c.check(self.labels.len())?;
        Ok(c)
    }

    fn describe(c: &SnakeCommand) -> String {
        match *c {
            SnakeCommand::Inject { ref fault } => format!("inject {fault}"),
            SnakeCommand::Configure => "configure".into(),
            SnakeCommand::PowerOn => "power on".into(),
            SnakeCommand::Home => "home".into(),
            SnakeCommand::Enable => "enable".into(),
            SnakeCommand::Disable => "disable".into(),
            SnakeCommand::ClearFault => "clear fault".into(),
            SnakeCommand::Mode { axis, speed } => format!(
                "axis {axis} {} mode",
                if speed { "speed" } else { "torque" }
            ),
            SnakeCommand::Wiper { axis, wiper } => format!("axis {axis} wiper {wiper}"),
            SnakeCommand::EepromRead { axis, word, float } => format!(
                "axis {axis} EEPROM read {}word {word}",
                if float { "float at " } else { "" }
            ),
            SnakeCommand::EepromWrite {
                axis,
                word,
                value,
                float,
            } => format!(
                "axis {axis} EEPROM write {}word {word} = {value}",
                if float { "float at " } else { "" }
            ),
            SnakeCommand::WriteProtect { axis, on } => format!(
                "axis {axis} write protection {}",
                if on { "on" } else { "off" }
            ),
            SnakeCommand::Move { axis, position } => format!("axis {axis} move to {position}"),
            SnakeCommand::Jog { axis, delta } => format!("axis {axis} jog {delta:+}"),
        }
    }
}

/// Per axis: where it is (node, channel, the I/O's flat axis) and its
/// channel's settings as last read back.
#[derive(Debug, Clone, Copy)]
struct Channel {
    node: u8,
    channel: u8,
    flat: usize,
    wiper: u16,
    speed_mode: bool,
    write_protect: bool,
}

/// The loop's own state besides the robot.
struct Rig {
    robot: Robot<SnakeSystem<SimPort>>,
    config: IoConfig,
    channels: Vec<Channel>,
    homed: bool,
    watchdog: WatchdogSetting,
    /// Who applies an injected fault's script on the simulated bus.
    faults: FaultTarget,
}

/// Start the Snake system of `config` on the simulated bus with a servo
/// period of `period`.
///
/// # Errors
/// A configuration not on Snake nodes, the rig, the node setup.
pub fn start(
    config: IoConfig,
    period: ServoPeriod,
    watchdog: WatchdogSetting,
) -> Result<Hosted<SnakeModel>, WebError> {
    let (port, faults) = sim_port_with_faults(node_configs(&config, 1)?, false, None)?;
    let mut system = SnakeSystem::open(port).map_err(firelink_testbed::TestbedError::from)?;
    prepare(&mut system, &config)?;
    let nodes: Vec<u8> = system.nodes().iter().map(|n| n.board_id()).collect();
    let mut channels = Vec::new();
    for j in config.joints() {
        let (node, axis) = (j.actuator.board_id, j.actuator.axis_id);
        let channel = axis + 1;
        let flat = system.axis_index(node, axis).ok_or_else(|| {
            WebError::Options(format!("node {node} channel {channel}: not found"))
        })?;
        let io = |e: firelink_host::HostError| WebError::Options(format!("node {node}: {e}"));
        let wiper = system.digital_pot_wiper(node, channel).map_err(io)?.value();
        let speed_mode = system
            .analog_switches(node, channel)
            .map_err(io)?
            .speed_mode;
        let write_protect = system.write_protect(node, channel).map_err(io)?;
        channels.push(Channel {
            node,
            channel,
            flat,
            wiper,
            speed_mode,
            write_protect,
        });
    }
    let settings = RobotSettings {
        period,
        watchdog,
        ..RobotSettings::default()
    };
    let robot = Robot::new(system, &config, settings)
        .map_err(|e| WebError::Options(format!("the Snake robot: {e}")))?;
    let labels = (0..robot.joint_count())
        .map(|i| {
            robot
                .joint_label(i)
                .map_or_else(|| format!("axis {i}"), |l| l.as_str().to_string())
        })
        .collect();
    let axes = channels.len();
    let node_count = nodes.len();
    let exchange = Arc::new(Exchange::new(|| SnakeFrame {
        t: 0.0,
        cycle: 0,
        state: State::Unconfigured,
        fault: None,
        homed: false,
        io_us: 0.0,
        errors: 0,
        axes: vec![SnakeAxis::default(); axes],
        nodes: vec![SnakeNodeSample::default(); node_count],
    }));
    let rig = Rig {
        robot,
        config,
        channels,
        homed: false,
        watchdog,
        faults,
    };
    let loop_exchange = Arc::clone(&exchange);
    let thread = std::thread::Builder::new()
        .name("firelink-snake".into())
        .spawn(move || run(rig, &loop_exchange, period))?;
    let model = SnakeModel {
        labels,
        nodes,
        period,
    };
    Ok(Hosted::new(
        RobotKind::Snake,
        "sim (Snake nodes on the simulated bus)".into(),
        model,
        exchange,
        thread,
    ))
}

/// The loop: commands between cycles, a frame every [`PUBLISH_SECONDS`];
/// on the way out (a stop, the process's stop request, a panic) the
/// robot is powered down.
fn run(mut rig: Rig, ex: &Exchange<SnakeFrame, SnakeCommand>, servo: ServoPeriod) -> LoopExit {
    let every = ((servo.rate_hz() * PUBLISH_SECONDS).round() as u64).max(1);
    let period = servo.as_duration();
    let looped = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let wall = Instant::now();
        let start = rig.robot.now();
        while !ex.stop.load(Ordering::Relaxed) && !rig.robot.stop_request().is_requested() {
            ex.take_requests(|p| take(&mut rig, ex, p));
            let _ = rig.robot.step(Pacing::Virtual);
            if rig.robot.cycles() % every == 0 {
                ex.publish(|f| fill(f, &rig));
            }
            pace(rig.robot.now() - start, wall, period * 4);
        }
    }));
    let panic = looped
        .err()
        .map(|p| super::panic_text(p.as_ref()).to_string());
    let stopped_by = rig.robot.stop_request().reason();
    let power_down = rig.robot.shutdown().ok();
    ex.publish(|f| fill(f, &rig));
    let exit = LoopExit {
        power_down,
        panic,
        stopped_by,
    };
    ex.finish(exit.clone(), SnakeModel::describe);
    exit
}

fn take(rig: &mut Rig, ex: &Exchange<SnakeFrame, SnakeCommand>, p: Pending<SnakeCommand>) {
    let what = SnakeModel::describe(&p.command);
    let result = execute(rig, p.command.clone());
    // The state that shows it first, then the outcome.
    ex.publish(|f| fill(f, rig));
    ex.answer(p, what, result);
}

/// Fill a frame from the robot; no allocation.
fn fill(f: &mut SnakeFrame, rig: &Rig) {
    let robot = &rig.robot;
    let io = robot.io();
    f.t = robot.now();
    f.cycle = robot.cycles();
    f.state = robot.state();
    f.fault = robot.fault().copied();
    f.homed = rig.homed;
    f.io_us = robot
        .last_report()
        .map_or(0.0, |r| r.io_time().as_secs_f64() * 1e6);
    f.errors = robot.io_stats().total_errors();
    for (i, (a, c)) in f.axes.iter_mut().zip(&rig.channels).enumerate() {
        let status = io.node(c.node).map(|n| n.status());
        *a = SnakeAxis {
            node: c.node,
            channel: c.channel,
            setpoint: robot.setpoint(i).unwrap_or(0.0),
            position: robot.position(i).unwrap_or(0.0),
            velocity: robot.velocity(i).unwrap_or(0.0),
            current_cmd: robot.commanded_current(i).unwrap_or(0.0),
            current: robot.measured_current(i).unwrap_or(0.0),
            encoder: io.encoder_position(c.flat).unwrap_or(0),
            pot: io.analog_position(c.flat).unwrap_or(0),
            amp: io.amplifier_enabled(c.flat).unwrap_or(false),
            fault: status.is_some_and(|s| s.fault(c.channel)),
            wiper: c.wiper,
            gain: Wiper::new(c.wiper).map_or(0.0, Wiper::feedback_gain),
            speed_mode: c.speed_mode,
            write_protect: c.write_protect,
        };
    }
    for (s, n) in f.nodes.iter_mut().zip(io.nodes()) {
        let status = n.status();
        *s = SnakeNodeSample {
            id: n.board_id(),
            valid: n.is_valid(),
            watchdog_expired: status.watchdog_timeout(),
            amps: (1..=7u8)
                .filter(|&ch| n.is_valid() && status.amp_enabled(ch))
                .fold(0, |m, ch| m | 1 << (ch - 1)),
        };
    }
}

/// A lifecycle refusal is a refusal; the rest are failures.
fn runner(e: RunnerError) -> Refused {
    match e {
        RunnerError::Lifecycle(l) => refused(l.to_string()),
        RunnerError::Stopped(reason) => refused(format!("stopping: {reason}")),
        other => failed(other.to_string()),
    }
}

/// Settings change the drive under the servo: not while enabled or with
/// an amplifier on.
fn settings_allowed(rig: &Rig, what: &str) -> Result<(), Refused> {
    if rig.robot.state() == State::Active {
        return Err(refused(format!(
            "{what} changes the drive under the servo: disable first"
        )));
    }
    if rig.robot.any_amp_on() {
        return Err(refused(format!(
            "{what} changes the drive under the servo: an amplifier is on (disable first)"
        )));
    }
    Ok(())
}

fn execute(rig: &mut Rig, command: SnakeCommand) -> Result<String, Refused> {
    let robot = &mut rig.robot;
    match command {
        SnakeCommand::Configure => robot
            .configure()
            .map(|left| {
                rig.homed = false;
                left.to_string()
            })
            .map_err(runner),
        SnakeCommand::PowerOn => robot
            .power_on()
            .map(|()| "every used amplifier on".into())
            .map_err(runner),
        SnakeCommand::Home => {
            if robot.state() != State::Configured {
                return Err(refused(format!(
                    "home needs a configured robot (not enabled): it is {}",
                    robot.state()
                )));
            }
            robot.home().map_err(runner)?;
            rig.homed = true;
            Ok("every axis homed against its potentiometer".into())
        }
        SnakeCommand::Enable => robot
            .activate()
            .map(|()| "every axis holds where it is".into())
            .map_err(runner),
        SnakeCommand::Disable => robot.shutdown().map(|p| p.to_string()).map_err(runner),
        SnakeCommand::ClearFault => robot
            .clear_fault()
            .map(|r| format!("cleared: {r}"))
            .map_err(runner),
        SnakeCommand::Move { axis, position } => move_axis(rig, axis, |_| position),
        SnakeCommand::Jog { axis, delta } => move_axis(rig, axis, |here| here + delta),
        SnakeCommand::Inject { fault } => {
            let fault = fault_named(&fault).map_err(refused)?;
            let script = fault.script(rig.watchdog.period_or_zero());
            let nodes = robot.io().board_nodes();
            rig.faults
                .apply_all(&script, robot.io_mut().port_mut(), &nodes)
                .map_err(|e| refused(e.to_string()))?;
            if fault == DemoFault::FollowingError {
                robot.step_setpoint(0, 0.5).map_err(runner)?;
            }
            Ok(String::new())
        }
        other => channel_command(rig, other),
    }
}

/// The tool's per-channel functions.
fn channel_command(rig: &mut Rig, command: SnakeCommand) -> Result<String, Refused> {
    let Some(axis) = command.axis() else {
        return Err(refused("not a channel command"));
    };
    let Some(&c) = rig.channels.get(axis) else {
        return Err(refused(format!("axis {axis} does not exist")));
    };
    let (node, ch) = (c.node, c.channel);
    let io_err = |e: firelink_host::HostError| failed(format!("node {node} channel {ch}: {e}"));
    let what = SnakeModel::describe(&command);
    match command {
        SnakeCommand::Mode { speed, .. } => {
            settings_allowed(rig, &what)?;
            let system = rig.robot.io_mut();
            let mut outputs = system.analog_switches(node, ch).map_err(io_err)?;
            outputs.speed_mode = speed;
            system
                .set_analog_switches(node, ch, outputs)
                .map_err(io_err)?;
            let back: PotOutputs = system.analog_switches(node, ch).map_err(io_err)?;
            set_channel(rig, axis, |c| c.speed_mode = back.speed_mode);
            Ok(format!(
                "node {node} channel {ch}: {} mode (read back)",
                if back.speed_mode { "speed" } else { "torque" }
            ))
        }
        SnakeCommand::Wiper { wiper, .. } => {
            settings_allowed(rig, &what)?;
            let system = rig.robot.io_mut();
            system
                .set_digital_pot_wiper(node, ch, wiper)
                .map_err(io_err)?;
            let back = system.digital_pot_wiper(node, ch).map_err(io_err)?;
            set_channel(rig, axis, |c| c.wiper = back.value());
            Ok(format!(
                "node {node} channel {ch}: wiper {} (read back), gain {:.3}",
                back.value(),
                back.feedback_gain()
            ))
        }
        SnakeCommand::EepromRead { word, float, .. } => {
            read_eeprom(rig.robot.io_mut(), node, ch, word, float).map_err(io_err)
        }
        SnakeCommand::EepromWrite {
            word, value, float, ..
        } => {
            settings_allowed(rig, &what)?;
            let index = eeprom_index(ch, word);
            let system = rig.robot.io_mut();
            if float {
                system.set_eeprom_float(node, index, value as f32)
            } else {
                system.set_eeprom_raw(node, index, value as u16)
            }
            .map_err(io_err)?;
            let back = read_eeprom(system, node, ch, word, float).map_err(io_err)?;
            Ok(format!("{back} (read back)"))
        }
        SnakeCommand::WriteProtect { on, .. } => {
            settings_allowed(rig, &what)?;
            let system = rig.robot.io_mut();
            system.set_write_protect(node, ch, on).map_err(io_err)?;
            let back = system.write_protect(node, ch).map_err(io_err)?;
            set_channel(rig, axis, |c| c.write_protect = back);
            Ok(format!(
                "node {node} channel {ch}: EEPROM write protection {} (read back)",
                if back { "on" } else { "off" }
            ))
        }
        _ => Err(refused("not a channel command")),
    }
}

/// An EEPROM index: the channel in bits 7-4, the word in bits 3-0.
fn eeprom_index(ch: u8, word: u8) -> u32 {
    (u32::from(ch) << 4) | u32::from(word)
}

/// Read an EEPROM word (or two as a float) and say what it holds.
fn read_eeprom(
    system: &mut SnakeSystem<SimPort>,
    node: u8,
    ch: u8,
    word: u8,
    float: bool,
) -> Result<String, firelink_host::HostError> {
    let index = eeprom_index(ch, word);
    Ok(if float {
        let v = system.eeprom_float(node, index)?;
        format!("node {node} channel {ch} EEPROM float at word {word}: {v}")
    } else {
        let v = system.eeprom_raw(node, index)?;
        format!("node {node} channel {ch} EEPROM word {word}: {v} (0x{v:04x})")
    })
}

fn set_channel(rig: &mut Rig, axis: usize, change: impl FnOnce(&mut Channel)) {
    if let Some(c) = rig.channels.get_mut(axis) {
        change(c);
    }
}

/// Move one axis to `goal(its setpoint)` with its configured limits.
fn move_axis(rig: &mut Rig, axis: usize, goal: impl FnOnce(f64) -> f64) -> Result<String, Refused> {
    let robot = &mut rig.robot;
    if robot.state() != State::Active {
        return Err(refused(format!(
            "motion needs an enabled robot: it is {}",
            robot.state()
        )));
    }
    if !rig.homed {
        return Err(refused("motion needs homed axes: home first"));
    }
    let here = robot.setpoint(axis).unwrap_or(0.0);
    let to = goal(here);
    let joint = rig.config.joints().nth(axis);
    if let Some(soft) = joint.map(|j| j.actuator.encoder.position_limits_soft) {
        if !(soft.lower..=soft.upper).contains(&to) {
            return Err(refused(format!(
                "axis {axis}: {to} is outside its soft limits {} ..= {}",
                soft.lower, soft.upper
            )));
        }
    }
    let (v, a) = joint
        .and_then(|j| j.actuator.limits)
        .map_or((0.5, 2.0), |l| (l.velocity, l.acceleration.unwrap_or(2.0)));
    let p2p = PointToPoint::new(here, to, v, a).map_err(|e| refused(e.to_string()))?;
    let seconds = p2p.duration();
    robot
        .set_motion(axis, Motion::PointToPoint(p2p))
        .map_err(runner)?;
    Ok(format!(
        "axis {axis}: {here:.4} -> {to:.4} in {seconds:.2} s"
    ))
}
