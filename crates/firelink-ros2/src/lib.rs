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
//! the robot thread and this node's thread through the service's lock-free,
//! allocation-free queues. The node's thread sleeps in one `poll` until a
//! subscription has a sample (DDS readiness) or the robot loop hands over
//! a frame to publish (it wakes the poll after such a cycle): a `servo_jp` is queued
//! for the robot loop as soon as it arrives, and the next cycle's write
//! block carries it: the node wakes the robot loop
//! ([`Shared::nudge`]), which runs that cycle at once (at least a fifth of
//! a period after the last one) and re-phases its schedule from it
//! ([`firelink_testbed::cycle_schedule`]), so the point waits for the
//! cycle's own I/O, not for the next period. It publishes `measured_js`
//! and `setpoint_js` from the frames due at `--publish-hz` (default 1 kHz;
//! the first frame of each `1 / publish-hz` slot of the robot's clock, so
//! early cycles do not raise the rate), each stamped with its own cycle's
//! time. `ROS_DOMAIN_ID` is honoured. The threads a point passes through
//! (RustDDS's socket reader, this node's, the robot loop's) run with
//! real-time scheduling where the OS permits ([`realtime`], on unless
//! [`NodeSettings::realtime`] is off), so that other work on the machine
//! does not delay their wake-ups.

pub mod messages;
pub mod realtime;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token, Waker};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    QosProfile, Subscription,
    qos::{Durability, History, WhenFull},
};

use firelink_control::config::IoConfig;
use firelink_control::lifecycle::State;
use firelink_testbed::dvrk::service::{
    Command, Frame, MAX_ARM_JOINTS, POOL, Service, ServoApplied, ServoTrace, Shared,
};
use firelink_testbed::loop_outcome::Verdict;

use messages::{Header, JointState, OperatingState, StringMsg, StringStamped, Time};

/// Why the node could not run.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// A DDS or ROS 2 entity could not be created.
    #[error("ROS 2: {0}")]
    Ros(String),
    /// Bringing the robot up without DDS failed.
    #[error("bring-up: {0}")]
    BringUp(String),
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
    /// Publications per second, decimated from the control rate by the
    /// frames' time (at 1 kHz control, 500 Hz publishes one frame in every
    /// 2 ms of the robot's clock).
    pub publish_hz: f64,
    /// DDS domain.
    pub domain_id: u16,
    /// Stop after this long (None: until `stop`).
    pub duration: Option<Duration>,
    /// Stamp messages with the robot's own clock (the simulated bus's
    /// virtual time, as ROS's `use_sim_time`) instead of the wall clock.
    pub sim_time: bool,
    /// Give the threads on a servo point's path real-time scheduling
    /// ([`realtime`]) where the OS permits it.
    pub realtime: bool,
}

/// What the node measured, printed as JSON when it stops.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct NodeReport {
    /// Seconds it ran.
    pub seconds: f64,
    /// measured_js messages published per arm and second.
    pub measured_js_hz: f64,
    /// The publication rate asked for (`--publish-hz`, at most the control
    /// rate).
    pub measured_js_asked_hz: f64,
    /// servo_jp messages received (without DDS: the points of the
    /// in-process [`ServoStream`] queued).
    pub servo_jp_received: u64,
    /// servo_jp applied by the robot.
    pub servo_jp_applied: u64,
    /// Commands refused (reason published on `/<ARM>/error`).
    pub refused: u64,
    /// servo_jp from its DDS source timestamp (the sender's wall clock) to
    /// applied, us: p50, p99, max. Applied: the write block of the control
    /// cycle that carried it has been sent.
    pub servo_latency_us: [f64; 3],
    /// The first part of that: DDS source timestamp to queued for the
    /// robot loop by this node (DDS delivery and this node's wake-up), us:
    /// p50, p99, max.
    pub servo_transit_us: [f64; 3],
    /// Of the transit: DDS source timestamp to RustDDS's reception stamp
    /// (the sender's write, the socket, RustDDS's event loop's wake-up),
    /// us: p50, p99, max.
    pub servo_delivery_us: [f64; 3],
    /// Of the transit: RustDDS's reception to queued for the robot loop
    /// (this node's wake-up and its take), us: p50, p99, max.
    pub servo_take_us: [f64; 3],
    /// The second part: queued to applied (the wait for the next control
    /// cycle, and the cycle up to its write block), us: p50, p99, max.
    pub servo_wait_us: [f64; 3],
    /// Of the wait: queued to the start of the cycle that carried the
    /// point (the robot loop's wake-up, the minimum gap, a cycle already
    /// in flight for a point carried by k + 2), us: p50, p99, max.
    pub servo_to_cycle_us: [f64; 3],
    /// Of the wait: the carrying cycle's start to applied (its work up to
    /// the write block sent), us: p50, p99, max.
    pub servo_cycle_us: [f64; 3],
    /// Applied servo_jp by the cycle that carried them, counted from the
    /// last cycle done when this node queued them: k + 1, k + 2, later.
    pub servo_applied_by_cycle: [u64; 3],
    /// Wake-ups with a subscription ready (servo_jp, move_jp or
    /// state_command), and wake-ups at the time-out (nothing ready and no
    /// frame: every subscription is read then too).
    pub wakes_ready_timeout: [u64; 2],
    /// Control loop compute time per cycle (host CPU), us: median, p99.
    pub control_compute_us: [f64; 2],
    /// Control loop cycle time (I/O on the port's clock + compute), us:
    /// median, p99.
    pub control_cycle_us: [f64; 2],
    /// Wall time the robot thread works per cycle while the robot is Active
    /// (commands, the cycle, the frame and the wake-up; not its sleep
    /// between cycles), us: median, p99.
    /// It includes the time the thread waited for a CPU (this node's
    /// threads, other processes).
    pub control_busy_us: [f64; 2],
    /// The robot thread's own CPU time for the same work, us: median, p99
    /// (0 where the platform has no thread CPU clock).
    pub control_busy_cpu_us: [f64; 2],
    /// Frames the robot loop skipped because this node had none free.
    pub frames_skipped: u64,
    /// Control cycles per second while the node ran (early cycles for
    /// commands included).
    pub control_hz: f64,
    /// The control rate asked for (`--period`, as a rate): the schedule's.
    pub control_asked_hz: f64,
    /// The servo period asked for (`--period`), us.
    pub control_asked_period_us: f64,
    /// The robot loop's cycles while the node ran by how they started:
    /// early for a command, on schedule, overrun (more than half a period
    /// late).
    pub cycle_starts: [u64; 3],
    /// This node's thread's time publishing one frame (every arm's
    /// measured_js and setpoint_js), us: median, p99: while it publishes,
    /// a servo_jp waits.
    pub publish_frame_us: [f64; 2],
    /// The real-time settings (`--rt`) and what took.
    pub realtime: realtime::RealtimeReport,
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// p50, p99 and max of `samples` (sorted in place).
fn p50_p99_max(samples: &mut [f64]) -> [f64; 3] {
    samples.sort_by(f64::total_cmp);
    [
        percentile(samples, 0.5),
        percentile(samples, 0.99),
        samples.last().copied().unwrap_or(0.0),
    ]
}

/// Median and p99 of `samples` (sorted in place).
fn median_p99(samples: &mut [f64]) -> [f64; 2] {
    samples.sort_by(f64::total_cmp);
    [percentile(samples, 0.5), percentile(samples, 0.99)]
}

/// The robot loop's costs, per frame, for the report (at most 2^20 frames
/// of each: about 17 minutes at 1 kHz).
#[derive(Default)]
struct LoopCosts {
    compute: Vec<f64>,
    cycle: Vec<f64>,
    busy: Vec<f64>,
    busy_cpu: Vec<f64>,
}

impl LoopCosts {
    const MAX: usize = 1 << 20;

    /// Record `frame`'s costs if the robot was Active in it (with and
    /// without ROS 2 the robot is compared in the same state).
    fn record(&mut self, frame: &Frame) {
        if frame.state != State::Active {
            return;
        }
        if self.compute.len() < Self::MAX {
            self.compute.push(frame.compute_us);
            self.cycle.push(frame.io_us + frame.compute_us);
        }
        if let Some(b) = frame.busy
            && self.busy.len() < Self::MAX
        {
            self.busy.push(b.wall_us);
            self.busy_cpu.extend(b.cpu_us);
        }
    }

    fn into_report(mut self, report: &mut NodeReport) {
        report.control_compute_us = median_p99(&mut self.compute);
        report.control_cycle_us = median_p99(&mut self.cycle);
        report.control_busy_us = median_p99(&mut self.busy);
        report.control_busy_cpu_us = median_p99(&mut self.busy_cpu);
    }
}

/// Microseconds from `from` to `to` (ns stamps of one clock; 0 if `to`
/// is earlier).
fn us_between(from: u64, to: u64) -> f64 {
    to.saturating_sub(from) as f64 / 1e3
}

/// The servo points: their transit as this node queued them, and their
/// wait as the robot loop logged them applied.
#[derive(Default)]
struct ServoLatencies {
    total: Vec<f64>,
    transit: Vec<f64>,
    delivery: Vec<f64>,
    take: Vec<f64>,
    wait: Vec<f64>,
    to_cycle: Vec<f64>,
    cycle: Vec<f64>,
    by_cycle: [u64; 3],
}

impl ServoLatencies {
    /// A point queued at `queued_ns` that RustDDS stamped received at
    /// `received_ns` and its sender at `source_ns` (0: not stamped).
    fn queued(&mut self, source_ns: u64, received_ns: u64, queued_ns: u64) {
        if source_ns == 0 || received_ns == 0 || self.delivery.len() >= LoopCosts::MAX {
            return;
        }
        self.delivery.push(us_between(source_ns, received_ns));
        self.take.push(us_between(received_ns, queued_ns));
    }

    fn record(&mut self, a: &ServoApplied) {
        let us = us_between;
        let lag = a.cycle.saturating_sub(a.trace.queued_after_cycle);
        let slot = usize::try_from(lag.clamp(1, 3) - 1).unwrap_or(2);
        self.by_cycle[slot] += 1;
        if self.total.len() >= LoopCosts::MAX {
            return;
        }
        if a.trace.source_ns != 0 {
            self.total.push(us(a.trace.source_ns, a.applied_ns));
            self.transit.push(us(a.trace.source_ns, a.trace.queued_ns));
        }
        self.wait.push(us(a.trace.queued_ns, a.applied_ns));
        self.to_cycle.push(us(a.trace.queued_ns, a.started_ns));
        self.cycle.push(us(a.started_ns, a.applied_ns));
    }

    fn into_report(mut self, report: &mut NodeReport) {
        report.servo_latency_us = p50_p99_max(&mut self.total);
        report.servo_transit_us = p50_p99_max(&mut self.transit);
        report.servo_delivery_us = p50_p99_max(&mut self.delivery);
        report.servo_take_us = p50_p99_max(&mut self.take);
        report.servo_wait_us = p50_p99_max(&mut self.wait);
        report.servo_to_cycle_us = p50_p99_max(&mut self.to_cycle);
        report.servo_cycle_us = p50_p99_max(&mut self.cycle);
        report.servo_applied_by_cycle = self.by_cycle;
    }
}

/// Which frames are published: at `publish_hz`, by the frames' own time
/// on the robot's clock (the first frame in each slot of `1 / publish_hz`
/// seconds), so the rate holds however late this node reads them and
/// however many cycles the robot loop runs early for commands; every
/// frame when `publish_hz` is at least the control rate.
#[derive(Debug, Clone, Copy)]
struct Decimation {
    /// Publications per second.
    hz: f64,
    /// Every frame is published.
    every_frame: bool,
}

impl Decimation {
    fn new(publish_hz: f64, rate_hz: f64) -> Decimation {
        Decimation {
            hz: publish_hz.max(1e-9),
            every_frame: publish_hz >= rate_hz,
        }
    }

    /// Whether the frame of time `t` (s) is published, the frame before
    /// it being of time `previous` (`-inf`: none).
    fn due(self, previous: f64, t: f64) -> bool {
        self.every_frame || (t * self.hz).floor() > (previous * self.hz).floor()
    }
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
fn motion_refusal(state: State, homed: bool) -> Option<String> {
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

/// The poll token of the robot loop's frame waker.
const FRAME: Token = Token(usize::MAX);

/// The subscriptions of an arm, in the order of their poll tokens.
const SUBSCRIPTIONS: usize = 3;

/// The poll token of subscription `which` (0 servo_jp, 1 move_jp,
/// 2 state_command) of arm `arm`.
fn subscription_token(arm: usize, which: usize) -> Token {
    Token(arm * SUBSCRIPTIONS + which)
}

/// The wall clock, ns since the Unix epoch (0 before it).
fn wall_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// What the node knows of the newest frame.
#[derive(Debug, Clone, Copy)]
struct Newest {
    /// Port time, s.
    t: f64,
    state: State,
}

/// Publish `measured_js` and `setpoint_js` of every arm from each frame of
/// `to_publish` (each stamped with its own cycle's time, or the wall clock
/// off the simulated bus), giving the frames back; the time each took goes
/// to `publish_us` (bounded). Returns how many frames were published.
// The frames stay boxed: they move between the pool's queues by pointer.
#[allow(clippy::vec_box)]
fn publish_frames(
    arms: &[Arm],
    to_publish: &mut Vec<Box<Frame>>,
    shared: &Shared,
    sim_time: bool,
    publish_us: &mut Vec<f64>,
) -> u64 {
    let mut published = 0;
    for frame in to_publish.drain(..) {
        let publishing = Instant::now();
        let stamp = if sim_time {
            Time::from_secs_f64(frame.t)
        } else {
            Time::now()
        };
        for arm in arms {
            let _ = arm.measured.publish(arm.joint_state(&frame, false, stamp));
            let _ = arm.setpoint.publish(arm.joint_state(&frame, true, stamp));
        }
        published += 1;
        let _ = shared.free.push(frame);
        if publish_us.len() < LoopCosts::MAX {
            publish_us.push(publishing.elapsed().as_secs_f64() * 1e6);
        }
    }
    published
}

/// The robot loop's figures over the node's run (`report.seconds` set):
/// its rate against the asked one, and how its cycles started since
/// `starts_at_start`.
fn loop_figures(
    shared: &Shared,
    cycles_at_start: u64,
    starts_at_start: [u64; 3],
    report: &mut NodeReport,
) {
    let cycles = shared
        .cycles_done
        .load(Ordering::Relaxed)
        .saturating_sub(cycles_at_start);
    report.control_hz = cycles as f64 / report.seconds.max(1e-9);
    report.control_asked_hz = shared.period.rate_hz();
    report.control_asked_period_us = shared.period.as_micros_f64();
    let starts = cycle_starts(shared);
    for (r, (now, then)) in report
        .cycle_starts
        .iter_mut()
        .zip(starts.iter().zip(starts_at_start))
    {
        *r = now.saturating_sub(then);
    }
}

/// The operating state's stamp (the newest frame's time on the simulated
/// bus, else the wall clock) and whether the robot is busy (a move not yet
/// ended, or commands waiting).
fn state_stamp_and_busy(shared: &Shared, sim_time: bool, newest: Option<Newest>) -> (Time, bool) {
    let now = match (sim_time, newest) {
        (true, Some(n)) => Time::from_secs_f64(n.t),
        (true, None) => Time::default(),
        (false, _) => Time::now(),
    };
    let ends = f64::from_bits(shared.move_ends.load(Ordering::Relaxed));
    let busy = newest.is_some_and(|n| n.t < ends) || !shared.commands.is_empty();
    (now, busy)
}

/// Run the node on a started service until `stop` (or the duration).
///
/// One thread (the caller's) does all of the node's DDS work and sleeps in
/// one `poll` until something is there: a sample on a subscription (their
/// readiness, registered with the poll), or a frame to publish from the
/// robot loop (the loop wakes the poll after each cycle due for
/// publication, through [`Shared::frame_waker`]); at the latest every
/// 100 ms, to see `stop`.
/// A command taken on a wake-up is queued for the robot loop before
/// anything is published, so it is applied by the next cycle's write block
/// (the one after, if the loop was already taking that cycle's commands).
/// The robot loop never waits for this thread.
///
/// # Errors
/// DDS entities or the poll could not be created, or another consumer
/// already waits for this service's frames.
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
    let mut poll = Poll::new().map_err(ros("poll"))?;
    register_readiness(&poll, &mut arms)?;
    let waker = Waker::new(poll.registry(), FRAME).map_err(ros("frame waker"))?;
    let decimation = Decimation::new(settings.publish_hz, shared.period.rate_hz());
    let last_frame_t = AtomicU64::new(f64::NEG_INFINITY.to_bits());
    shared
        .frame_waker
        .set(Box::new(move |_cycle, t| {
            // Woken for the frames it publishes (commands wake it by their
            // own readiness). A failed wake leaves the 100 ms time-out.
            let previous = f64::from_bits(last_frame_t.swap(t.to_bits(), Ordering::Relaxed));
            if decimation.due(previous, t) {
                let _ = waker.wake();
            }
        }))
        .map_err(|_| Ros2Error::Ros("another consumer already waits for these frames".into()))?;
    // The frames of the cycles run while DDS started are not published.
    while let Some(frame) = shared.full.pop() {
        let _ = shared.free.push(frame);
    }
    let mut events = Events::with_capacity(64);
    let start = Instant::now();
    let mut newest: Option<Newest> = None;
    let mut last_frame_t = f64::NEG_INFINITY;
    let cycles_at_start = shared.cycles_done.load(Ordering::Relaxed);
    let starts_at_start = cycle_starts(shared);
    let mut to_publish: Vec<Box<Frame>> = Vec::with_capacity(POOL);
    let mut ready = vec![false; arms.len() * SUBSCRIPTIONS];
    let mut report = NodeReport::default();
    let mut published = 0u64;
    let mut costs = LoopCosts::default();
    let mut servo = ServoLatencies::default();
    let mut last_state_publish = start;
    let mut publish_us = Vec::new();
    // Now that the DDS threads are there: real-time scheduling for the
    // ones a servo point passes through (and the robot loop's).
    if settings.realtime {
        report.realtime = realtime::apply(&mut realtime::OsScheduler, true);
        say_refusals(&report.realtime);
    }
    while !stop.load(Ordering::Relaxed) {
        let left = settings
            .duration
            .map_or(Duration::MAX, |d| d.saturating_sub(start.elapsed()));
        if left.is_zero() {
            break;
        }
        match poll.poll(&mut events, Some(left.min(Duration::from_millis(100)))) {
            Ok(()) => {}
            // A signal: the loop's condition sees the stop flag.
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(ros("poll")(e)),
        }
        // Which subscriptions are ready (edge-triggered: each is read until
        // empty); at the time-out, all of them.
        ready.fill(events.is_empty());
        let mut any_ready = false;
        for event in &events {
            if let Some(r) = ready.get_mut(event.token().0) {
                *r = true;
                any_ready = true;
            }
        }
        report.wakes_ready_timeout[0] += u64::from(any_ready);
        report.wakes_ready_timeout[1] += u64::from(events.is_empty());
        // Frames: the due ones kept for publication, the rest given back.
        let frames = Frames {
            decimation,
            last_t: &mut last_frame_t,
            costs: &mut costs,
            newest: &mut newest,
            to_publish: &mut to_publish,
        };
        take_frames(shared, frames);
        let state = newest.map_or(State::Unconfigured, |n| n.state);
        let homed = shared.homed.load(Ordering::Relaxed);
        // Commands first: they are what waits.
        for (i, arm) in arms.iter_mut().enumerate() {
            let ready_of = |which| ready.get(i * SUBSCRIPTIONS + which).copied() == Some(true);
            if ready_of(2) {
                take_state_commands(arm, shared, state, &mut report);
            }
            let mut taking = Taking {
                shared,
                state,
                homed,
                report: &mut report,
                servo: &mut servo,
            };
            if ready_of(0) {
                take_motion(arm, true, &mut taking);
            }
            if ready_of(1) {
                take_motion(arm, false, &mut taking);
            }
        }
        // Publications, each from its own cycle's frame.
        published += publish_frames(
            &arms,
            &mut to_publish,
            shared,
            settings.sim_time,
            &mut publish_us,
        );
        // Operating state: at 10 Hz and whenever it changes.
        let (now, busy) = state_stamp_and_busy(shared, settings.sim_time, newest);
        let periodic = last_state_publish.elapsed() >= Duration::from_millis(100);
        publish_operating_state(&mut arms, now, state, homed, busy, periodic);
        if periodic {
            last_state_publish = Instant::now();
        }
        // Servo points the robot applied, and when.
        while let Some(applied) = shared.servo_log.pop() {
            servo.record(&applied);
        }
    }
    report.seconds = start.elapsed().as_secs_f64();
    loop_figures(shared, cycles_at_start, starts_at_start, &mut report);
    report.measured_js_hz = published as f64 / report.seconds.max(1e-9);
    report.measured_js_asked_hz = settings.publish_hz.min(shared.period.rate_hz());
    report.servo_jp_applied = shared.servo_applied.load(Ordering::Relaxed);
    report.frames_skipped = shared.skipped.load(Ordering::Relaxed);
    report.publish_frame_us = median_p99(&mut publish_us);
    costs.into_report(&mut report);
    servo.into_report(&mut report);
    drop(arms);
    drop(node);
    drop(context);
    Ok(report)
}

/// Register each arm's subscriptions with the poll, each under its own
/// token, so that a sample waiting wakes the node.
fn register_readiness(poll: &Poll, arms: &mut [Arm]) -> Result<(), Ros2Error> {
    for (i, arm) in arms.iter_mut().enumerate() {
        let registry = poll.registry();
        registry
            .register(&mut arm.servo, subscription_token(i, 0), Interest::READABLE)
            .map_err(ros("servo_jp readiness"))?;
        registry
            .register(
                &mut arm.move_jp,
                subscription_token(i, 1),
                Interest::READABLE,
            )
            .map_err(ros("move_jp readiness"))?;
        registry
            .register(
                &mut arm.state_command,
                subscription_token(i, 2),
                Interest::READABLE,
            )
            .map_err(ros("state_command readiness"))?;
    }
    Ok(())
}

/// The robot loop's cycles so far by how they started: early for a
/// command, on schedule, overrun.
fn cycle_starts(shared: &Shared) -> [u64; 3] {
    let mut counts = [0; 3];
    for (c, a) in counts.iter_mut().zip(&shared.cycle_starts) {
        *c = a.load(Ordering::Relaxed);
    }
    counts
}

/// Where [`take_frames`] puts what it takes.
struct Frames<'a> {
    decimation: Decimation,
    /// The time of the last frame taken (`-inf`: none yet).
    last_t: &'a mut f64,
    costs: &'a mut LoopCosts,
    newest: &'a mut Option<Newest>,
    // The frames stay boxed: they move between the pool's queues by pointer.
    #[allow(clippy::vec_box)]
    to_publish: &'a mut Vec<Box<Frame>>,
}

/// Take the robot loop's finished frames: each one's costs recorded and
/// the newest remembered; the due ones kept for publication, the rest
/// given back.
fn take_frames(shared: &Shared, into: Frames<'_>) {
    while let Some(frame) = shared.full.pop() {
        into.costs.record(&frame);
        *into.newest = Some(Newest {
            t: frame.t,
            state: frame.state,
        });
        let due = into.decimation.due(*into.last_t, frame.t);
        *into.last_t = frame.t;
        if due && into.to_publish.len() < into.to_publish.capacity() {
            into.to_publish.push(frame);
        } else {
            let _ = shared.free.push(frame);
        }
    }
}

/// Publish each arm's operating state at 10 Hz (`periodic`) and whenever
/// it changes.
fn publish_operating_state(
    arms: &mut [Arm],
    now: Time,
    state: State,
    homed: bool,
    busy: bool,
    periodic: bool,
) {
    for arm in arms.iter_mut() {
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
}

/// Take every `state_command` waiting on `arm` and queue what it means.
fn take_state_commands(arm: &Arm, shared: &Shared, state: State, report: &mut NodeReport) {
    while let Ok(Some((msg, _))) = arm.state_command.take() {
        match lifecycle(&msg.string, state) {
            Ok(commands) => {
                for c in commands {
                    if shared.commands.push(c).is_err() {
                        arm.report("refused: command queue full".into());
                    }
                }
                shared.nudge();
            }
            Err(e) => {
                report.refused += 1;
                arm.report(e);
            }
        }
    }
}

/// What [`take_motion`] needs: the service, the robot's state, and where
/// it counts.
struct Taking<'a> {
    shared: &'a Shared,
    state: State,
    homed: bool,
    report: &'a mut NodeReport,
    servo: &'a mut ServoLatencies,
}

/// Take every `servo_jp` (`servo`) or `move_jp` waiting on `arm`, check it
/// and queue it for the robot loop with its trace.
fn take_motion(arm: &mut Arm, servo: bool, taking: &mut Taking<'_>) {
    let Taking {
        shared,
        state,
        homed,
        ..
    } = *taking;
    let report = &mut *taking.report;
    loop {
        let taken = if servo {
            arm.servo.take()
        } else {
            arm.move_jp.take()
        };
        let Ok(Some((msg, info))) = taken else {
            break;
        };
        if servo {
            report.servo_jp_received += 1;
        }
        let checked = match motion_refusal(state, homed) {
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
        let mut command = if servo {
            let t = msg.header.stamp.as_secs_f64();
            let velocities = servo_velocities(arm, &msg, t, &positions);
            arm.last_servo = Some((t, positions));
            // Latency from the DDS source timestamp (the sender's wall
            // clock), whatever clock the header uses.
            let ns = |t: Option<ros2_client::ROSTime>| {
                t.map_or(0, |t| u64::try_from(t.to_nanos()).unwrap_or(0))
            };
            let trace = ServoTrace {
                source_ns: ns(info.source_timestamp()),
                queued_ns: wall_ns(),
                // Read just before the push, below.
                queued_after_cycle: 0,
            };
            taking.servo.queued(
                trace.source_ns,
                ns(info.received_timestamp()),
                trace.queued_ns,
            );
            Command::ServoJoints {
                first,
                count,
                positions,
                velocities,
                trace,
            }
        } else {
            Command::MoveJoints {
                first,
                count,
                positions,
            }
        };
        if let Command::ServoJoints { trace, .. } = &mut command {
            // The last cycle done as the point is queued: read with
            // nothing between it and the push (the stamps and the
            // statistics above came first), so that a thread pre-empted
            // on the way does not make the point look later than it was.
            trace.queued_after_cycle = shared.cycles_done.load(Ordering::SeqCst);
        }
        if shared.commands.push(command).is_err() {
            report.refused += 1;
            arm.report("refused: command queue full".into());
        }
        // The robot loop runs the command's cycle now, not at its next
        // deadline.
        shared.nudge();
    }
}

/// Each real-time setting the OS refused, on stderr as soon as it was
/// refused (at start-up: an operator sees it while the node runs, not only
/// in the report when it stops).
fn say_refusals(report: &realtime::RealtimeReport) {
    for e in &report.errors {
        eprintln!("firelink ros2: real-time: {e} (running on without it)");
    }
}

/// A servo stream made in this process, for [`run_without_dds`]: what the
/// benchmark's ROS 2 client (`tests/dds/crtk_client.py`) sends, without
/// DDS, so that the robot loop does the same work with ROS 2 and without
/// (an arm that follows a stream costs more per cycle than one holding
/// still: its plants move, its joints are not quiet). The arm's first joint
/// follows a sinusoid of [`AMPLITUDE_RAD`](Self::AMPLITUDE_RAD) at
/// [`FREQUENCY_HZ`](Self::FREQUENCY_HZ) about where it was when the stream
/// began, on the robot's clock; a point is sent every [`1 / RATE_HZ`](Self::RATE_HZ)
/// of the wall clock, aimed [`LEAD_S`](Self::LEAD_S) ahead of the newest
/// frame; each is queued with its velocity and trace as the node queues a
/// `servo_jp`, and the loop is nudged.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServoStream {
    /// The arm (a robot's name in the configuration), e.g. `PSM1`.
    pub arm: String,
}

impl ServoStream {
    /// Points per second (wall clock).
    pub const RATE_HZ: f64 = 200.0;
    /// The sinusoid's amplitude, rad.
    pub const AMPLITUDE_RAD: f64 = 0.05;
    /// The sinusoid's frequency, Hz.
    pub const FREQUENCY_HZ: f64 = 0.5;
    /// How far ahead of the newest frame a point aims, s.
    pub const LEAD_S: f64 = 0.01;
}

/// A [`ServoStream`] under way: the arm's joints and where the sinusoid
/// started.
struct StreamState {
    first: usize,
    count: usize,
    /// The robot's time and the arm's positions at the stream's first frame.
    origin: Option<(f64, [f64; MAX_ARM_JOINTS])>,
    /// The last point sent: its time and positions (for the velocities).
    last: Option<(f64, [f64; MAX_ARM_JOINTS])>,
    /// The newest frame's time (the robot's clock).
    newest_t: f64,
    next_send: Instant,
    sent: u64,
}

impl StreamState {
    fn new(stream: &ServoStream, shared: &Shared, config: &IoConfig) -> Result<Self, Ros2Error> {
        let (_, first, joints) = arms_of(config, &shared.joint_labels)
            .into_iter()
            .find(|(name, _, _)| *name == stream.arm)
            .ok_or_else(|| {
                Ros2Error::BringUp(format!("servo stream: no arm named {}", stream.arm))
            })?;
        Ok(StreamState {
            first,
            count: joints.len().min(MAX_ARM_JOINTS),
            origin: None,
            last: None,
            newest_t: 0.0,
            next_send: Instant::now(),
            sent: 0,
        })
    }

    /// Note the frame's time, and where the arm is in the stream's first
    /// (Active) frame.
    fn see(&mut self, frame: &Frame) {
        self.newest_t = frame.t;
        if self.origin.is_some() || frame.state != State::Active {
            return;
        }
        let mut at = [0.0; MAX_ARM_JOINTS];
        for (p, j) in at
            .iter_mut()
            .zip(frame.joints.iter().skip(self.first).take(self.count))
        {
            *p = j.position;
        }
        self.origin = Some((frame.t, at));
    }

    /// Queue the next point if it is due (once the stream's first frame
    /// was seen), aimed ahead of the newest frame's time.
    fn send_if_due(&mut self, shared: &Shared) {
        let now = Instant::now();
        let Some((t0, origin)) = self.origin else {
            return;
        };
        if now < self.next_send {
            return;
        }
        let period = Duration::from_secs_f64(1.0 / ServoStream::RATE_HZ);
        // Late by more than a period (the first point, or a stall): the
        // next one a period from now, not at once (no point twice).
        self.next_send = if now >= self.next_send + period {
            now + period
        } else {
            self.next_send + period
        };
        let t = self.newest_t + ServoStream::LEAD_S;
        let mut positions = origin;
        positions[0] = origin[0]
            + ServoStream::AMPLITUDE_RAD
                * (2.0 * std::f64::consts::PI * ServoStream::FREQUENCY_HZ * (t - t0)).sin();
        let mut velocities = [0.0; MAX_ARM_JOINTS];
        if let Some((tl, pl)) = self.last {
            let dt = t - tl;
            if dt > 1e-4 && dt < 0.5 {
                for i in 0..self.count {
                    velocities[i] = (positions[i] - pl[i]) / dt;
                }
            }
        }
        self.last = Some((t, positions));
        let stamp = wall_ns();
        let command = Command::ServoJoints {
            first: self.first as u16,
            count: self.count as u8,
            positions,
            velocities,
            trace: ServoTrace {
                source_ns: stamp,
                queued_ns: stamp,
                queued_after_cycle: shared.cycles_done.load(Ordering::SeqCst),
            },
        };
        if shared.commands.push(command).is_ok() {
            self.sent += 1;
        }
        shared.nudge();
    }

    /// How long to sleep at most before the next point is due (before
    /// the stream's first frame: a point is not due).
    fn until_due(&self) -> Duration {
        if self.origin.is_none() {
            return Duration::MAX;
        }
        self.next_send.saturating_duration_since(Instant::now())
    }
}

/// Run the robot service alone (no DDS), draining its frames (and its log
/// of applied servo points) as the node would: the control loop's costs
/// without ROS 2. The robot is brought up as a ROS 2 client does it
/// (configured, powered, homed, active); then for `duration` it holds
/// still, or follows `stream` (the benchmark client's stream made in this
/// process: the same work for the robot loop as with the client over
/// DDS). The costs are those of its Active cycles, as with the node, and so
/// are the real-time settings (`realtime`: the robot loop's and the calling
/// thread's). A stop request (`stop`, set by the signals) ends it early.
///
/// # Errors
/// A bring-up command was refused or failed, or `stream` names no arm of
/// `config`.
pub fn run_without_dds(
    service: &Service,
    config: &IoConfig,
    duration: Duration,
    realtime: bool,
    stream: Option<&ServoStream>,
    stop: &AtomicBool,
) -> Result<NodeReport, Ros2Error> {
    let mut stream = stream
        .map(|s| StreamState::new(s, &service.shared, config))
        .transpose()?;
    let realtime = if realtime {
        let applied = realtime::apply(&mut realtime::OsScheduler, false);
        say_refusals(&applied);
        applied
    } else {
        realtime::RealtimeReport::default()
    };
    for command in [
        Command::Configure,
        Command::PowerOn,
        Command::Home,
        Command::Activate,
    ] {
        bring_up_step(&service.shared, command, stop)?;
    }
    eprintln!(
        "firelink ros2: active without DDS for {:.1} s{}",
        duration.as_secs_f64(),
        stream
            .as_ref()
            .map_or("", |_| ", following the servo stream")
    );
    let start = Instant::now();
    let shared = &service.shared;
    let cycles_at_start = shared.cycles_done.load(Ordering::Relaxed);
    let starts_at_start = cycle_starts(shared);
    let mut costs = LoopCosts::default();
    while start.elapsed() < duration && !stop.load(Ordering::Relaxed) {
        while let Some(frame) = shared.full.pop() {
            costs.record(&frame);
            if let Some(s) = stream.as_mut() {
                s.see(&frame);
            }
            let _ = shared.free.push(frame);
        }
        while shared.servo_log.pop().is_some() {}
        let mut nap = Duration::from_millis(1);
        if let Some(s) = stream.as_mut() {
            s.send_if_due(shared);
            nap = nap.min(s.until_due());
        }
        std::thread::sleep(nap);
    }
    let mut report = NodeReport {
        seconds: start.elapsed().as_secs_f64(),
        frames_skipped: shared.skipped.load(Ordering::Relaxed),
        realtime,
        servo_jp_received: stream.as_ref().map_or(0, |s| s.sent),
        servo_jp_applied: shared.servo_applied.load(Ordering::Relaxed),
        ..NodeReport::default()
    };
    loop_figures(shared, cycles_at_start, starts_at_start, &mut report);
    costs.into_report(&mut report);
    Ok(report)
}

/// Queue `command` and wait for its outcome, giving the frames back
/// meanwhile.
fn bring_up_step(shared: &Shared, command: Command, stop: &AtomicBool) -> Result<(), Ros2Error> {
    let id = shared
        .submit(command)
        .map_err(|e| Ros2Error::BringUp(format!("{command}: {e}")))?;
    shared.nudge();
    while !stop.load(Ordering::Relaxed) {
        while let Some(frame) = shared.full.pop() {
            let _ = shared.free.push(frame);
        }
        while let Some(o) = shared.outcomes.pop() {
            if o.id == id {
                return match o.result {
                    Verdict::Ok => Ok(()),
                    _ => Err(Ros2Error::BringUp(o.to_string())),
                };
            }
        }
        if let Some(exit) = shared.exit.get() {
            return Err(Ros2Error::BringUp(format!(
                "{command}: the robot loop ended: {exit}"
            )));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    Err(Ros2Error::BringUp(format!("{command}: stopped")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_control::config::presets;

    /// The robot's shared state for the dVRK on the simulated bus, with no
    /// loop running (nothing takes the queued commands but the test).
    fn idle_shared(config: &IoConfig) -> Arc<Shared> {
        use firelink_testbed::{dvrk::service, emulated::Profile, rig};
        let boards = rig::board_configs(config, Profile::Rev8, config.board_slots());
        let rig = rig::RigBuilder::qla(boards).build().expect("rig");
        let options = service::LoopOptions {
            config: config.clone(),
            period: firelink_control::ServoPeriod::from_rate_hz(1000.0).expect("1 kHz"),
            watchdog: firelink_host::WatchdogSetting::Off,
            pacing: firelink_control::runner::Pacing::Virtual,
            faults: rig.fault_target(),
        };
        let (_robot, shared) =
            service::prepare(rig.sim_port(), "sim".into(), &options).expect("prepare");
        shared
    }

    #[test]
    fn the_in_process_stream_queues_the_benchmark_clients_points() {
        let config = presets::dvrk_seed000();
        let shared = idle_shared(&config);
        let stream = ServoStream { arm: "PSM1".into() };
        let mut state = StreamState::new(&stream, &shared, &config).expect("PSM1");
        let (_, first, joints) = arms_of(&config, &shared.joint_labels)
            .into_iter()
            .find(|(name, _, _)| name == "PSM1")
            .expect("PSM1");
        let mut frame = shared.free.pop().expect("a frame");
        frame.t = 2.0;
        for (k, j) in frame.joints.iter_mut().enumerate() {
            j.position = 0.1 * k as f64;
        }
        // Nothing is sent before an Active frame says where the arm is.
        frame.state = State::Configured;
        state.see(&frame);
        state.send_if_due(&shared);
        assert!(shared.commands.is_empty());
        assert_eq!(state.until_due(), Duration::MAX);
        frame.state = State::Active;
        state.see(&frame);
        // A point three periods late (a stall): the next is a period after
        // it, not at once (no point twice).
        let period = Duration::from_secs_f64(1.0 / ServoStream::RATE_HZ);
        let before = Instant::now();
        if let Some(late) = before.checked_sub(3 * period) {
            state.next_send = late;
        }
        state.send_if_due(&shared);
        assert!(state.next_send >= before + period);
        let Some(Command::ServoJoints {
            first: f,
            count,
            positions,
            velocities,
            trace,
        }) = shared.commands.pop()
        else {
            panic!("no servo point queued");
        };
        assert_eq!((f as usize, count as usize), (first, joints.len()));
        let origin = 0.1 * first as f64;
        let expected = origin
            + ServoStream::AMPLITUDE_RAD
                * (2.0 * std::f64::consts::PI * ServoStream::FREQUENCY_HZ * ServoStream::LEAD_S)
                    .sin();
        assert_eq!(positions[0], expected);
        for (i, p) in positions.iter().enumerate().take(joints.len()).skip(1) {
            assert_eq!(*p, 0.1 * (first + i) as f64, "joint {i} holds");
        }
        assert!(
            velocities.iter().all(|v| *v == 0.0),
            "no velocity without a previous point"
        );
        assert!(trace.source_ns != 0 && trace.queued_ns == trace.source_ns);
        // The next point (made due now) carries the velocity between the two.
        state.next_send = Instant::now();
        frame.t = 2.1;
        state.see(&frame);
        state.send_if_due(&shared);
        let Some(Command::ServoJoints {
            positions: p2,
            velocities: v2,
            ..
        }) = shared.commands.pop()
        else {
            panic!("no second point");
        };
        assert_eq!(
            v2[0],
            (p2[0] - positions[0]) / ((2.1 + ServoStream::LEAD_S) - (2.0 + ServoStream::LEAD_S))
        );
        assert_eq!(state.sent, 2);
        assert!(StreamState::new(&ServoStream { arm: "PSM9".into() }, &shared, &config).is_err());
    }

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
        assert!(
            motion_refusal(State::Unconfigured, true)
                .unwrap()
                .contains("DISABLED")
        );
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

    /// Publications are due by the frames' time: a second of 1 kHz
    /// cycles gives the asked rate exactly, whatever the ratio, and so does
    /// the same second with a cycle run early for a command in every five;
    /// never more than one per frame.
    #[test]
    fn publications_are_decimated_by_time() {
        // Cycles at 1 kHz (a tenth of a period past each millisecond).
        let regular: Vec<f64> = (1..=1000).map(|k| k as f64 * 1e-3 + 1e-4).collect();
        let mut with_early = regular.clone();
        with_early.extend((1..=1000).step_by(5).map(|k| k as f64 * 1e-3 + 4e-4));
        with_early.sort_by(f64::total_cmp);
        let count = |times: &[f64], publish_hz| {
            let d = Decimation::new(publish_hz, 1000.0);
            let mut previous = 1e-4;
            let mut n = 0;
            for &t in times {
                n += usize::from(d.due(previous, t));
                previous = t;
            }
            n
        };
        for times in [&regular, &with_early] {
            assert_eq!(count(times, 500.0), 500);
            assert_eq!(count(times, 300.0), 300);
            assert_eq!(count(times, 100.0), 100);
        }
        assert_eq!(count(&regular, 1000.0), 1000);
        assert_eq!(count(&regular, 5000.0), 1000);
        let d = Decimation::new(500.0, 1000.0);
        assert!(d.due(f64::NEG_INFINITY, 0.0));
        assert!(!d.due(0.0021, 0.0029));
        assert!(d.due(0.0039, 0.0041));
    }

    /// Each applied point lands in the bucket of the cycle that carried it,
    /// counted from the last cycle done when it was queued; the latency is
    /// split at the queueing.
    #[test]
    fn applied_points_are_counted_by_cycle_and_split_at_the_queue() {
        let mut servo = ServoLatencies::default();
        let applied = |queued_after_cycle, cycle| ServoApplied {
            trace: ServoTrace {
                source_ns: 1_000_000,
                queued_ns: 1_200_000,
                queued_after_cycle,
            },
            cycle,
            started_ns: 1_800_000,
            applied_ns: 1_900_000,
        };
        for (k, c) in [(10, 11), (10, 12), (10, 12), (10, 40)] {
            servo.record(&applied(k, c));
        }
        let mut report = NodeReport::default();
        servo.into_report(&mut report);
        assert_eq!(report.servo_applied_by_cycle, [1, 2, 1]);
        assert_eq!(report.servo_latency_us, [900.0, 900.0, 900.0]);
        assert_eq!(report.servo_transit_us, [200.0, 200.0, 200.0]);
        assert_eq!(report.servo_wait_us, [700.0, 700.0, 700.0]);
        assert_eq!(report.servo_to_cycle_us, [600.0, 600.0, 600.0]);
        assert_eq!(report.servo_cycle_us, [100.0, 100.0, 100.0]);
    }

    #[test]
    fn stamps_round_trip() {
        let t = Time::from_secs_f64(12.25);
        assert_eq!((t.sec, t.nanosec), (12, 250_000_000));
        assert!((t.as_secs_f64() - 12.25).abs() < 1e-9);
        assert_eq!(Time::from_secs_f64(-3.0), Time::default());
    }
}
