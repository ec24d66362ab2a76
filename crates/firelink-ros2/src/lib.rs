//! # firelink-ros2: the robot as a ROS 2 node with the dVRK's CRTK topics
//!
//! `firelink ros2` runs a robot on the testbed's robot service (simulated
//! bus, in-process emulator or real boards) and is a ROS 2 node over DDS
//! (RustDDS through `ros2-client`: nothing of ROS needs to be installed).
//! Per arm of the configuration, as the dVRK does:
//!
//! | topic | type | direction | QoS |
//! |---|---|---|---|
//! | `/<ARM>/measured_js` | `sensor_msgs/JointState` | published | sensor data (best effort, keep last 5) |
//! | `/<ARM>/setpoint_js` | `sensor_msgs/JointState` | published | sensor data |
//! | `/<ARM>/operating_state` | `crtk_msgs/OperatingState` | published (10 Hz and on change) | reliable |
//! | `/<ARM>/error` | `std_msgs/String` | published (refusals, faults) | reliable |
//! | `/<ARM>/servo_jp` | `sensor_msgs/JointState` | subscribed | reliable, keep last 10 |
//! | `/<ARM>/move_jp` | `sensor_msgs/JointState` | subscribed | reliable |
//! | `/<ARM>/state_command` | `crtk_msgs/StringStamped` | subscribed (`enable`, `disable`, `home`) | reliable |
//!
//! `enable` configures and powers the robot, `home` homes every joint and
//! activates it, `disable` powers off; they act on the whole robot (one
//! bus). `servo_jp` and `move_jp` are refused, with the reason on
//! `/<ARM>/error`, unless the robot is enabled (Active) and homed; the
//! operating state says which is missing.
//!
//! The control loop never waits on DDS: frames and commands cross between
//! the robot thread and this node's thread through the service's lock-free
//! queues; the node publishes at its own rate (default 1 kHz, decimated
//! from the control rate) from the newest frame. `ROS_DOMAIN_ID` is
//! honoured.

pub mod messages;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    QosProfile, Subscription,
    qos::{Durability, History, WhenFull},
};

use firelink_control::config::IoConfig;
use firelink_control::lifecycle::State;
use firelink_testbed::service::{Command, Frame, MAX_ARM_JOINTS, Service, Shared};

use messages::{Header, JointState, OperatingState, StringMsg, StringStamped, Time};

/// Why the node could not run.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// A DDS or ROS 2 entity could not be created.
    #[error("ROS 2: {0}")]
    Ros(String),
    /// The robot service failed.
    #[error(transparent)]
    Testbed(#[from] firelink_testbed::TestbedError),
}

fn ros<E: std::fmt::Debug>(what: &str) -> impl Fn(E) -> Ros2Error + '_ {
    move |e| Ros2Error::Ros(format!("{what}: {e:?}"))
}

/// The domain: `ROS_DOMAIN_ID` if it is a number 0..=232, else 0.
pub fn domain_from_env() -> u16 {
    std::env::var("ROS_DOMAIN_ID")
        .ok()
        .and_then(|v| v.trim().parse::<u16>().ok())
        .filter(|d| *d <= 232)
        .unwrap_or(0)
}

/// Sensor-data QoS for measurements.
fn sensor_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 5 })
}

/// Reliable QoS for commands and states.
fn reliable_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// One arm's topics.
struct Arm {
    first: usize,
    count: usize,
    joint_names: Vec<String>,
    measured: Publisher<JointState>,
    setpoint: Publisher<JointState>,
    operating: Publisher<OperatingState>,
    error: Publisher<StringMsg>,
    servo: Subscription<JointState>,
    move_jp: Subscription<JointState>,
    state_command: Subscription<StringStamped>,
    last_state: Option<(String, bool, bool)>,
    /// The last servo point: stamp (s) and positions, to estimate the
    /// velocity when a servo_jp carries none.
    last_servo: Option<(f64, [f64; MAX_ARM_JOINTS])>,
}

fn topic(
    node: &Node,
    arm: &str,
    base: &str,
    kind: (&str, &str),
    qos: &QosProfile,
) -> Result<ros2_client::dds::rustdds::Topic, Ros2Error> {
    let name = Name::new(&format!("/{arm}"), base).map_err(ros("topic name"))?;
    node.create_topic(&name, MessageTypeName::new(kind.0, kind.1), qos)
        .map_err(ros("topic"))
}

impl Arm {
    fn new(
        node: &mut Node,
        name: &str,
        first: usize,
        joint_names: Vec<String>,
    ) -> Result<Arm, Ros2Error> {
        let js = ("sensor_msgs", "JointState");
        let sensor = sensor_qos();
        let reliable = reliable_qos();
        let t_measured = topic(node, name, "measured_js", js, &sensor)?;
        let t_setpoint = topic(node, name, "setpoint_js", js, &sensor)?;
        let t_operating = topic(
            node,
            name,
            "operating_state",
            ("crtk_msgs", "OperatingState"),
            &reliable,
        )?;
        let t_error = topic(node, name, "error", ("std_msgs", "String"), &reliable)?;
        let t_servo = topic(node, name, "servo_jp", js, &reliable)?;
        let t_move = topic(node, name, "move_jp", js, &reliable)?;
        let t_state = topic(
            node,
            name,
            "state_command",
            ("crtk_msgs", "StringStamped"),
            &reliable,
        )?;
        Ok(Arm {
            first,
            count: joint_names.len(),
            joint_names,
            measured: node
                .create_publisher(&t_measured, None)
                .map_err(ros("publisher"))?,
            setpoint: node
                .create_publisher(&t_setpoint, None)
                .map_err(ros("publisher"))?,
            operating: node
                .create_publisher(&t_operating, None)
                .map_err(ros("publisher"))?,
            error: node
                .create_publisher(&t_error, None)
                .map_err(ros("publisher"))?,
            servo: node
                .create_subscription(&t_servo, None)
                .map_err(ros("subscription"))?,
            move_jp: node
                .create_subscription(&t_move, None)
                .map_err(ros("subscription"))?,
            state_command: node
                .create_subscription(&t_state, None)
                .map_err(ros("subscription"))?,
            last_state: None,
            last_servo: None,
        })
    }

    fn joint_state(&self, frame: &Frame, setpoint: bool, stamp: Time) -> JointState {
        let joints = frame
            .joints
            .get(self.first..self.first + self.count)
            .unwrap_or(&[]);
        JointState {
            header: Header {
                stamp,
                frame_id: String::new(),
            },
            name: self.joint_names.clone(),
            position: joints
                .iter()
                .map(|j| if setpoint { j.setpoint } else { j.position })
                .collect(),
            velocity: joints.iter().map(|j| j.velocity).collect(),
            effort: joints.iter().map(|j| j.current).collect(),
        }
    }

    fn report(&self, text: String) {
        let _ = self.error.publish(StringMsg { data: text });
    }
}

/// CRTK's name for a lifecycle state.
pub fn crtk_state(state: State) -> &'static str {
    match state {
        State::Unconfigured | State::Configured => "DISABLED",
        State::Active => "ENABLED",
        State::Fault => "FAULT",
    }
}

/// Options of the node.
#[derive(Debug, Clone)]
pub struct NodeSettings {
    /// Publications per second (decimated from the control rate).
    pub publish_hz: f64,
    /// DDS domain.
    pub domain_id: u16,
    /// Stop after this long (None: until `stop`).
    pub duration: Option<Duration>,
    /// Stamp messages with the robot's own clock (the simulated bus's
    /// virtual time, as ROS's `use_sim_time`) instead of the wall clock.
    pub sim_time: bool,
}

/// What the node measured, printed as JSON when it stops.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct NodeReport {
    /// Seconds it ran.
    pub seconds: f64,
    /// measured_js messages published per arm and second.
    pub measured_js_hz: f64,
    /// servo_jp messages received.
    pub servo_jp_received: u64,
    /// servo_jp applied by the robot.
    pub servo_jp_applied: u64,
    /// Commands refused (reason published on `/<ARM>/error`).
    pub refused: u64,
    /// servo_jp stamp to application by the robot loop, us: p50, p99, max.
    pub servo_latency_us: [f64; 3],
    /// Control loop compute time per cycle (host CPU), us: median, p99.
    pub control_compute_us: [f64; 2],
    /// Control loop cycle time (I/O on the port's clock + compute), us:
    /// median, p99.
    pub control_cycle_us: [f64; 2],
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// The arms of a configuration: (name, first joint, joint names).
pub fn arms_of(config: &IoConfig, labels: &[String]) -> Vec<(String, usize, Vec<String>)> {
    let mut first = 0;
    config
        .robots
        .iter()
        .map(|r| {
            let n = r.actuators.len();
            let names = labels
                .get(first..first + n)
                .map_or_else(Vec::new, <[String]>::to_vec);
            let arm = (r.name.clone(), first, names);
            first += n;
            arm
        })
        .collect()
}

/// Turn a state command into service commands.
fn lifecycle(text: &str, state: State) -> Result<Vec<Command>, String> {
    match text.trim().to_ascii_lowercase().as_str() {
        "enable" => Ok(match state {
            State::Unconfigured => vec![Command::Configure, Command::PowerOn],
            State::Configured => vec![Command::PowerOn],
            State::Active => vec![],
            State::Fault => return Err("refused: in FAULT (disable, then enable)".into()),
        }),
        "home" => Ok(vec![Command::Home, Command::Activate]),
        "disable" => Ok(match state {
            State::Fault => vec![Command::Disable, Command::ClearFault],
            _ => vec![Command::Disable],
        }),
        other => Err(format!(
            "unknown state command {other:?}: enable, disable or home"
        )),
    }
}

/// Why a motion command is refused now, if it is.
fn motion_refusal(frame: Option<&Frame>, homed: bool) -> Option<String> {
    let state = frame.map_or(State::Unconfigured, |f| f.state);
    if state != State::Active {
        return Some(format!(
            "refused: the arm is {} (not ENABLED)",
            crtk_state(state)
        ));
    }
    (!homed).then(|| "refused: not homed".to_string())
}

/// Positions of a JointState for an arm, checked.
fn positions(arm: &Arm, msg: &JointState) -> Result<[f64; MAX_ARM_JOINTS], String> {
    if msg.position.len() != arm.count {
        return Err(format!(
            "refused: {} positions for {} joints",
            msg.position.len(),
            arm.count
        ));
    }
    if let Some(p) = msg.position.iter().find(|p| !p.is_finite()) {
        return Err(format!("refused: position {p} is not a number"));
    }
    let mut out = [0.0; MAX_ARM_JOINTS];
    for (o, p) in out.iter_mut().zip(&msg.position) {
        *o = *p;
    }
    Ok(out)
}

/// The velocities of a servo point: the message's own when it has one per
/// joint, else the change since the arm's last point over the stamps'
/// interval (0 for the first point, or when the stamps do not advance).
fn servo_velocities(
    arm: &Arm,
    msg: &JointState,
    t: f64,
    positions: &[f64; MAX_ARM_JOINTS],
) -> [f64; MAX_ARM_JOINTS] {
    let mut v = [0.0; MAX_ARM_JOINTS];
    if msg.velocity.len() == arm.count && msg.velocity.iter().all(|x| x.is_finite()) {
        for (o, x) in v.iter_mut().zip(&msg.velocity) {
            *o = *x;
        }
    } else if let Some((t0, p0)) = arm.last_servo {
        let dt = t - t0;
        if dt > 1e-4 && dt < 0.5 {
            for i in 0..arm.count.min(MAX_ARM_JOINTS) {
                v[i] = (positions[i] - p0[i]) / dt;
            }
        }
    }
    v
}

/// Run the node on a started service until `stop` (or the duration).
///
/// # Errors
/// DDS entities could not be created.
pub fn run_node(
    service: &Service,
    config: &IoConfig,
    settings: &NodeSettings,
    stop: &AtomicBool,
) -> Result<NodeReport, Ros2Error> {
    let shared: &Arc<Shared> = &service.shared;
    let context = Context::with_options(ContextOptions::new().domain_id(settings.domain_id))
        .map_err(ros("DDS participant"))?;
    let mut node = context
        .new_node(
            NodeName::new("/", "firelink").map_err(ros("node name"))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(ros("node"))?;
    let mut arms = Vec::new();
    for (name, first, joints) in arms_of(config, &shared.joint_labels) {
        arms.push(Arm::new(&mut node, &name, first, joints)?);
    }
    let period = Duration::from_secs_f64(1.0 / settings.publish_hz.clamp(1.0, 10_000.0));
    let start = Instant::now();
    let mut next = start;
    let mut newest: Option<Box<Frame>> = None;
    let mut report = NodeReport::default();
    let mut published = 0u64;
    let mut latencies: Vec<f64> = Vec::new();
    let mut compute: Vec<f64> = Vec::new();
    let mut cycle: Vec<f64> = Vec::new();
    let mut last_state_publish = start;
    let mut applied_seen = 0u64;
    while !stop.load(Ordering::Relaxed) && settings.duration.is_none_or(|d| start.elapsed() < d) {
        // Frames: keep the newest, give the rest back.
        let mut fresh = false;
        while let Some(frame) = shared.full.pop() {
            if compute.len() < 1 << 20 {
                compute.push(frame.compute_us);
                cycle.push(frame.io_us + frame.compute_us);
            }
            if let Some(old) = newest.replace(frame) {
                let _ = shared.free.push(old);
            }
            fresh = true;
        }
        let homed = shared.homed.load(Ordering::Relaxed);
        let now = match (settings.sim_time, newest.as_deref()) {
            (true, Some(f)) => Time::from_secs_f64(f.t),
            (true, None) => Time::default(),
            (false, _) => Time::now(),
        };
        if let (true, Some(frame)) = (fresh, newest.as_deref()) {
            for arm in &arms {
                let _ = arm.measured.publish(arm.joint_state(frame, false, now));
                let _ = arm.setpoint.publish(arm.joint_state(frame, true, now));
            }
            published += 1;
        }
        // Operating state: at 10 Hz and whenever it changes.
        let state = newest.as_ref().map_or(State::Unconfigured, |f| f.state);
        let ends = f64::from_bits(shared.move_ends.load(Ordering::Relaxed));
        let busy = newest.as_ref().is_some_and(|f| f.t < ends) || !shared.commands.is_empty();
        let periodic = last_state_publish.elapsed() >= Duration::from_millis(100);
        for arm in &mut arms {
            let current = (crtk_state(state).to_string(), homed, busy);
            if periodic || arm.last_state.as_ref() != Some(&current) {
                let _ = arm.operating.publish(OperatingState {
                    header: Header {
                        stamp: now,
                        frame_id: String::new(),
                    },
                    state: current.0.clone(),
                    is_homed: homed,
                    is_busy: busy,
                });
                arm.last_state = Some(current);
            }
        }
        if periodic {
            last_state_publish = Instant::now();
        }
        // Commands.
        for arm in &mut arms {
            while let Ok(Some((msg, _))) = arm.state_command.take() {
                match lifecycle(&msg.string, state) {
                    Ok(commands) => {
                        for c in commands {
                            if shared.commands.push(c).is_err() {
                                arm.report("refused: command queue full".into());
                            }
                        }
                    }
                    Err(e) => {
                        report.refused += 1;
                        arm.report(e);
                    }
                }
            }
            for (servo, sub) in [(true, &arm.servo), (false, &arm.move_jp)] {
                while let Ok(Some((msg, info))) = sub.take() {
                    if servo {
                        report.servo_jp_received += 1;
                    }
                    let checked = match motion_refusal(newest.as_deref(), homed) {
                        Some(why) => Err(why),
                        None => positions(arm, &msg),
                    };
                    let positions = match checked {
                        Ok(p) => p,
                        Err(why) => {
                            report.refused += 1;
                            arm.report(why);
                            continue;
                        }
                    };
                    let (first, count) = (arm.first as u16, arm.count as u8);
                    // Latency from the DDS source timestamp (the sender's
                    // wall clock), whatever clock the header uses.
                    let stamp_ns = info
                        .source_timestamp()
                        .map_or(0, |t| u64::try_from(t.to_nanos()).unwrap_or(0));
                    let command = if servo {
                        let t = msg.header.stamp.as_secs_f64();
                        let velocities = servo_velocities(arm, &msg, t, &positions);
                        arm.last_servo = Some((t, positions));
                        Command::ServoJoints {
                            first,
                            count,
                            positions,
                            velocities,
                            stamp_ns,
                        }
                    } else {
                        Command::MoveJoints {
                            first,
                            count,
                            positions,
                        }
                    };
                    if shared.commands.push(command).is_err() {
                        report.refused += 1;
                        arm.report("refused: command queue full".into());
                    }
                }
            }
        }
        // Servo commands the robot applied, and when.
        let applied = shared.servo_applied.load(Ordering::Relaxed);
        if applied != applied_seen {
            applied_seen = applied;
            let lat = shared.servo_latency_ns.load(Ordering::Relaxed) as f64 / 1e3;
            if latencies.len() < 1 << 20 {
                latencies.push(lat);
            }
        }
        next += period;
        let now_i = Instant::now();
        if next > now_i {
            std::thread::sleep(next - now_i);
        } else {
            next = now_i;
        }
    }
    if let Some(f) = newest {
        let _ = shared.free.push(f);
    }
    let seconds = start.elapsed().as_secs_f64();
    latencies.sort_by(f64::total_cmp);
    compute.sort_by(f64::total_cmp);
    cycle.sort_by(f64::total_cmp);
    report.control_cycle_us = [percentile(&cycle, 0.5), percentile(&cycle, 0.99)];
    report.seconds = seconds;
    report.measured_js_hz = published as f64 / seconds.max(1e-9);
    report.servo_jp_applied = shared.servo_applied.load(Ordering::Relaxed);
    report.servo_latency_us = [
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.99),
        latencies.last().copied().unwrap_or(0.0),
    ];
    report.control_compute_us = [percentile(&compute, 0.5), percentile(&compute, 0.99)];
    drop(arms);
    drop(node);
    drop(context);
    Ok(report)
}

/// Run the robot service alone (no DDS) for `duration`, draining its frames
/// as the node would: the control loop's compute time without ROS 2;
/// a stop request (`stop`, set by the signals) ends it early.
pub fn run_without_dds(service: &Service, duration: Duration, stop: &AtomicBool) -> NodeReport {
    let start = Instant::now();
    let mut compute = Vec::new();
    let mut cycle = Vec::new();
    while start.elapsed() < duration && !stop.load(Ordering::Relaxed) {
        while let Some(frame) = service.shared.full.pop() {
            compute.push(frame.compute_us);
            cycle.push(frame.io_us + frame.compute_us);
            let _ = service.shared.free.push(frame);
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    compute.sort_by(f64::total_cmp);
    cycle.sort_by(f64::total_cmp);
    NodeReport {
        seconds: start.elapsed().as_secs_f64(),
        control_compute_us: [percentile(&compute, 0.5), percentile(&compute, 0.99)],
        control_cycle_us: [percentile(&cycle, 0.5), percentile(&cycle, 0.99)],
        ..NodeReport::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_control::config::presets;

    #[test]
    fn state_commands_map_onto_the_lifecycle() {
        assert_eq!(
            lifecycle("enable", State::Unconfigured).unwrap(),
            vec![Command::Configure, Command::PowerOn]
        );
        assert_eq!(
            lifecycle(" HOME ", State::Configured).unwrap(),
            vec![Command::Home, Command::Activate]
        );
        assert_eq!(
            lifecycle("disable", State::Fault).unwrap(),
            vec![Command::Disable, Command::ClearFault]
        );
        assert!(lifecycle("enable", State::Fault).is_err());
        assert!(
            lifecycle("fly", State::Active)
                .unwrap_err()
                .contains("unknown")
        );
    }

    #[test]
    fn motion_is_refused_with_the_reason() {
        assert!(motion_refusal(None, true).unwrap().contains("DISABLED"));
        assert_eq!(crtk_state(State::Active), "ENABLED");
        assert_eq!(crtk_state(State::Fault), "FAULT");
    }

    #[test]
    fn the_arms_of_the_dvrk() {
        let config = presets::dvrk_seed000();
        let labels: Vec<String> = (0..28).map(|i| format!("j{i}")).collect();
        let arms = arms_of(&config, &labels);
        let names: Vec<&str> = arms.iter().map(|a| a.0.as_str()).collect();
        assert_eq!(names, ["MTML", "MTMR", "PSM1", "PSM2"]);
        assert_eq!(arms[2].1, 14);
        assert_eq!(arms[2].2.len(), 7);
        assert_eq!(arms[3].2[0], "j21");
    }

    #[test]
    fn stamps_round_trip() {
        let t = Time::from_secs_f64(12.25);
        assert_eq!((t.sec, t.nanosec), (12, 250_000_000));
        assert!((t.as_secs_f64() - 12.25).abs() < 1e-9);
        assert_eq!(Time::from_secs_f64(-3.0), Time::default());
    }
}
