//! A console-like homing scenario: what the dVRK console does to an arm
//! after power-on, through the host library against emulated boards on the
//! simulated bus, with every cycle watched.
//!
//! 0. Read the arm's digital inputs (buttons, clutches, the PSM's sterile
//!    adapter and instrument contacts) as the console does: each DIGIN bit
//!    through its `pressed_value`. Power on, which releases the brakes.
//! 1. Bias the encoders from the pots ([`Robot::home`]).
//! 2. Home every joint that needs a stop search the way the console homes
//!    the MTM roll ([`Robot::search_stop_observed`]): a constant-velocity
//!    move into the stop until the following error says the joint
//!    stalled; the encoder is set to the stop's position; then a free move
//!    back to the joint's home position.
//! 3. Move every joint, one after the other, to its lower software limit,
//!    home, its upper software limit and home again.
//!
//! Throughout, after every cycle: |encoder - pot| per joint (in actuator
//! space, the way sawRobotIO1394 compares them), and the emulated joint's
//! true position against its mechanical stops (read from the plant behind
//! the bus). The robot's own safety monitor runs too: a pot that disagrees
//! with its encoder longer than the configuration allows faults the run.
//!
//! ```no_run
//! use firelink_control::config::presets;
//! use firelink_testbed::dvrk::console_homing::{run_console_homing, ConsoleHomingOptions};
//! let report = run_console_homing(&presets::stock_mtmr(), &ConsoleHomingOptions::default()).unwrap();
//! println!("{report}");
//! ```

use std::fmt;

use firelink_board::qla::config::Profile;
use firelink_board::qla::node::BoardNode;
use firelink_bus::NodeHandle;
use firelink_control::config::{IoConfig, JointType};
use firelink_control::runner::{Pacing, Robot, RobotSettings, StopFound};
use firelink_control::trajectory::{Motion, PointToPoint};
use firelink_control::{Label, ServoPeriod};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::sim::SimPort;
use serde::Serialize;

use crate::{TestbedError, rig};

/// Settings of the scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConsoleHomingOptions {
    /// The servo period.
    pub period: ServoPeriod,
    /// Fraction of each joint's velocity limit the moves to the software
    /// limits use (0 to 1].
    pub speed: f64,
    /// Firmware of the emulated boards.
    pub firmware: Profile,
}

impl Default for ConsoleHomingOptions {
    /// 1 kHz (the dVRK console's IO rate is 1 to 1.5 kHz), half the
    /// joints' velocity limits, Rev 8.
    fn default() -> Self {
        ConsoleHomingOptions {
            period: ServoPeriod::KHZ_1,
            speed: 0.5,
            firmware: Profile::Rev8,
        }
    }
}

/// One joint over the whole scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointHoming {
    /// `robot[index]`.
    pub joint: String,
    /// Prismatic (metres) or revolute (radians).
    pub prismatic: bool,
    /// Whether the configuration checks pot against encoder for it (v6
    /// tolerance `distance` above 0).
    pub checked: bool,
    /// The configuration's tolerance (0: unchecked).
    pub tolerance: f64,
    /// Largest |encoder - pot| seen while homed, actuator space.
    pub max_pot_error: f64,
    /// Software limits the joint was moved to, and where it got.
    pub soft_limits: (f64, f64),
    /// Where the encoder said the joint was at the end of the move to
    /// each software limit.
    pub reached: (f64, f64),
    /// The emulated joint's mechanical stops.
    pub stops: (f64, f64),
    /// Largest distance the true joint position went past a stop (0 when
    /// it never did).
    pub beyond_stop: f64,
}

/// A stop search as the scenario saw it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StopSearchRecord {
    /// `robot[index]`.
    pub joint: String,
    /// Where the encoder (biased from the pot) said the joint stalled.
    pub stalled_at: f64,
    /// Where the true joint was then (the plant).
    pub true_position: f64,
    /// Seconds from the start of the search to the stall.
    pub duration: f64,
    /// Seconds the joint spent against the stop before the stall was
    /// declared.
    pub stalled_for: f64,
    /// Following error when the stall was declared.
    pub following_error: f64,
    /// Whether the following error grew every cycle while the joint was
    /// against the stop.
    pub error_grew: bool,
    /// Current commanded then, and the drive's `maximum_current`, A.
    pub commanded_current: f64,
    /// The configuration's current limit, A.
    pub current_limit: f64,
    /// Current the amplifier measured then, A.
    pub measured_current: f64,
    /// Where the encoder reads from then on.
    pub stop_position: f64,
    /// Where the joint got back to, and its home position.
    pub returned_to: f64,
    /// The joint's home position.
    pub home: f64,
}

/// One arm's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArmHoming {
    /// Robot name.
    pub name: String,
    /// Its serial number.
    pub serial_number: String,
    /// Every joint.
    pub joints: Vec<JointHoming>,
    /// Every stop search.
    pub stop_searches: Vec<StopSearchRecord>,
    /// The arm's digital inputs (those named after it) as the console
    /// reads them once the boards are read: (name, pressed).
    pub inputs: Vec<(String, bool)>,
}

impl ArmHoming {
    /// Largest |encoder - pot| over the checked revolute joints, rad.
    pub fn max_pot_error_rad(&self) -> f64 {
        self.max_pot_error(false)
    }

    /// Largest |encoder - pot| over the checked prismatic joints, m.
    pub fn max_pot_error_m(&self) -> f64 {
        self.max_pot_error(true)
    }

    fn max_pot_error(&self, prismatic: bool) -> f64 {
        self.joints
            .iter()
            .filter(|j| j.checked && j.prismatic == prismatic)
            .map(|j| j.max_pot_error)
            .fold(0.0, f64::max)
    }
}

/// The whole scenario's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConsoleHomingReport {
    /// Per arm, in configuration order.
    pub arms: Vec<ArmHoming>,
    /// Servo cycles run.
    pub cycles: u64,
    /// Virtual seconds run.
    pub seconds: f64,
}

impl fmt::Display for ConsoleHomingReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "console-like homing: {} cycles, {:.1} s of virtual time",
            self.cycles, self.seconds
        )?;
        for arm in &self.arms {
            writeln!(
                f,
                "{} ({}): max |encoder - pot| {:.5} rad, {:.3} mm",
                arm.name,
                arm.serial_number,
                arm.max_pot_error_rad(),
                arm.max_pot_error_m() * 1e3
            )?;
            for j in &arm.joints {
                writeln!(
                    f,
                    "  {:<9} |enc-pot| max {:.5} (tolerance {:.4}{}), limits [{:.4}, {:.4}] \
                     reached [{:.4}, {:.4}], stops [{:.4}, {:.4}], past a stop {:.1e}",
                    j.joint,
                    j.max_pot_error,
                    j.tolerance,
                    if j.checked { "" } else { ", unchecked" },
                    j.soft_limits.0,
                    j.soft_limits.1,
                    j.reached.0,
                    j.reached.1,
                    j.stops.0,
                    j.stops.1,
                    j.beyond_stop
                )?;
            }
            for (name, pressed) in &arm.inputs {
                writeln!(
                    f,
                    "  input {name}: {}",
                    if *pressed { "pressed" } else { "released" }
                )?;
            }
            for s in &arm.stop_searches {
                writeln!(
                    f,
                    "  stop search {}: stalled at {:.4} (true {:.4}) after {:.3} s, {:.3} s against \
                     the stop, following error {:.3} ({}), current {:.3} A commanded / {:.3} A \
                     measured (limit {:.3} A); encoder set to {:.4}, back to {:.4} (home {:.4})",
                    s.joint,
                    s.stalled_at,
                    s.true_position,
                    s.duration,
                    s.stalled_for,
                    s.following_error,
                    if s.error_grew {
                        "growing every cycle"
                    } else {
                        "not always growing"
                    },
                    s.commanded_current,
                    s.measured_current,
                    s.current_limit,
                    s.stop_position,
                    s.returned_to,
                    s.home
                )?;
            }
        }
        Ok(())
    }
}

/// What the scenario watches each cycle.
struct Watch {
    /// Per joint: board handle and axis of its plant.
    plant: Vec<(Option<NodeHandle>, usize)>,
    /// Per joint: largest |encoder - pot| since homing.
    max_pot_error: Vec<f64>,
    /// Per joint: largest distance the true position went past a stop.
    beyond_stop: Vec<f64>,
    /// Whether the encoders are homed (pot errors mean something).
    homed: bool,
    /// During a stop search: (joint, cycles against the stop, following
    /// error last cycle, whether it grew every cycle).
    stall: Option<(usize, u64, f64, bool)>,
}

impl Watch {
    /// The plant axis behind joint `i`.
    fn axis<'a>(
        &self,
        robot: &'a Robot<IoSystem<SimPort>>,
        i: usize,
    ) -> Option<&'a firelink_board::plant::Axis> {
        let (handle, axis) = self.plant.get(i)?;
        robot
            .io()
            .port()
            .bus()
            .node::<BoardNode>((*handle)?)?
            .firmware()
            .plant()
            .axis(*axis)
    }

    fn observe(&mut self, robot: &Robot<IoSystem<SimPort>>) {
        for i in 0..self.plant.len() {
            if self.homed {
                if let (Some(p), Some(e)) = (robot.potentiometer(i), robot.position(i)) {
                    if p.is_finite() {
                        let slot = &mut self.max_pot_error[i];
                        *slot = slot.max((p - e).abs());
                    }
                }
            }
            if let Some(a) = self.axis(robot, i) {
                let q = a.joint_position();
                let s = a.params().stops;
                let past = s
                    .lower
                    .map_or(0.0, |l| l - q)
                    .max(s.upper.map_or(0.0, |u| q - u));
                let slot = &mut self.beyond_stop[i];
                *slot = slot.max(past);
            }
        }
        if let Some((i, cycles, last, grew)) = self.stall {
            let against = self.axis(robot, i).is_some_and(|a| a.at_stop().is_some());
            if against {
                let error = match (robot.setpoint(i), robot.position(i)) {
                    (Some(s), Some(p)) => (s - p).abs(),
                    _ => f64::NAN,
                };
                let grew = grew && (cycles == 0 || error > last);
                self.stall = Some((i, cycles + 1, error, grew));
            }
        }
    }
}

/// Run the scenario on `config`'s arms.
///
/// # Errors
/// A fault (the safety monitor's, e.g. a pot that disagrees with its
/// encoder), a failed stop search, a configuration the rig cannot build.
pub fn run_console_homing(
    config: &IoConfig,
    options: &ConsoleHomingOptions,
) -> Result<ConsoleHomingReport, TestbedError> {
    let (port, boards) = rig::sim_port_of_used(config, options.firmware)?;
    let plant = config
        .joints()
        .map(|j| {
            let handle = boards
                .iter()
                .find(|(id, _)| *id == j.actuator.board_id)
                .map(|(_, h)| *h);
            (handle, usize::from(j.actuator.axis_id))
        })
        .collect::<Vec<_>>();
    let (io, _) = IoSystem::open(port, IoOptions::default())?;
    let settings = RobotSettings {
        period: options.period,
        ..RobotSettings::default()
    };
    let mut robot = Robot::new(io, config, settings)?;
    let n = robot.joint_count();
    let mut watch = Watch {
        plant,
        max_pot_error: vec![0.0; n],
        beyond_stop: vec![0.0; n],
        homed: false,
        stall: None,
    };
    robot.configure()?;
    let inputs = console_inputs(config, &robot);
    robot.power_on()?;
    robot.home()?;
    watch.homed = true;
    robot.activate()?;
    let speed = options.speed.clamp(0.01, 1.0);

    // Stop searches first, as the console calibrates the MTM roll before
    // the arm's homing move.
    let searches = search_stops(&mut robot, &mut watch, config, options, speed)?;

    // Every joint to both software limits and back.
    let reached = sweep_soft_limits(&mut robot, &mut watch, config, speed)?;

    let cycles = robot.cycles();
    let seconds = robot.now();
    let arms = arm_reports(config, &robot, &watch, inputs, searches, &reached);
    robot.shutdown()?;
    Ok(ConsoleHomingReport {
        arms,
        cycles,
        seconds,
    })
}

/// The console's digital inputs as it reads them: each input's arm, name
/// and whether it is pressed.
fn console_inputs(
    config: &IoConfig,
    robot: &Robot<IoSystem<SimPort>>,
) -> Vec<(usize, String, bool)> {
    // The inputs as the console reads them: DIGIN through the
    // configuration's rule (`pressed_value`), as sawRobotIO1394 does.
    config
        .digital_inputs
        .iter()
        .flatten()
        .filter_map(|d| {
            let arm = config
                .robots
                .iter()
                .position(|r| d.name.starts_with(r.name.as_str()))?;
            let board = robot
                .io()
                .boards()
                .iter()
                .find(|b| b.board_id() == d.board_id)?;
            Some((arm, d.name.clone(), d.is_pressed(board.digital_in().raw())))
        })
        .collect()
}

/// Search every stop-search joint's hard stop and return it home, keeping
/// each search's record with its arm's index.
fn search_stops(
    robot: &mut Robot<IoSystem<SimPort>>,
    watch: &mut Watch,
    config: &IoConfig,
    options: &ConsoleHomingOptions,
    speed: f64,
) -> Result<Vec<(usize, StopSearchRecord)>, TestbedError> {
    let mut searches: Vec<(usize, StopSearchRecord)> = Vec::new();
    let search_joints: Vec<usize> = robot.stop_search_joints().collect();
    for i in search_joints {
        let Some(j) = config.joints().nth(i) else {
            continue;
        };
        watch.stall = Some((i, 0, 0.0, true));
        let found: StopFound = robot.search_stop_observed(i, &mut |r| watch.observe(r))?;
        let (against, grew) = match watch.stall.take() {
            Some((_, cycles, _, grew)) => (cycles, grew),
            None => (0, false),
        };
        let true_position = watch
            .axis(robot, i)
            .map_or(f64::NAN, firelink_board::plant::Axis::joint_position);
        let home = j
            .actuator
            .simulation
            .and_then(|s| s.homing)
            .map_or(0.0, |h| h.position);
        move_to(robot, watch, config, i, home, speed)?;
        searches.push((
            j.robot_index,
            StopSearchRecord {
                joint: j.label.to_string(),
                stalled_at: found.stalled_at,
                true_position,
                duration: found.duration,
                stalled_for: against as f64 / options.period.rate_hz(),
                following_error: found.following_error,
                error_grew: grew && against > 1,
                commanded_current: found.commanded_current,
                current_limit: j.actuator.drive.maximum_current,
                measured_current: found.measured_current,
                stop_position: found.stop_position,
                returned_to: robot.position(i).unwrap_or(f64::NAN),
                home,
            },
        ));
    }

    Ok(searches)
}

/// Move every joint to both software limits and back home; the positions
/// reached at (lower, upper), per joint.
fn sweep_soft_limits(
    robot: &mut Robot<IoSystem<SimPort>>,
    watch: &mut Watch,
    config: &IoConfig,
    speed: f64,
) -> Result<Vec<(f64, f64)>, TestbedError> {
    let mut reached = vec![(f64::NAN, f64::NAN); robot.joint_count()];
    for j in config.joints() {
        let i = j.index;
        let soft = j.actuator.encoder.position_limits_soft;
        let home = j
            .actuator
            .simulation
            .and_then(|s| s.homing)
            .map_or(robot.position(i).unwrap_or(0.0), |h| h.position);
        move_to(robot, watch, config, i, soft.lower, speed)?;
        let lower = robot.position(i).unwrap_or(f64::NAN);
        move_to(robot, watch, config, i, home, speed)?;
        move_to(robot, watch, config, i, soft.upper, speed)?;
        let upper = robot.position(i).unwrap_or(f64::NAN);
        move_to(robot, watch, config, i, home, speed)?;
        reached[i] = (lower, upper);
    }

    Ok(reached)
}

/// The per-arm report: the inputs, each joint's pot and limit figures, the
/// stop searches.
fn arm_reports(
    config: &IoConfig,
    robot: &Robot<IoSystem<SimPort>>,
    watch: &Watch,
    inputs: Vec<(usize, String, bool)>,
    searches: Vec<(usize, StopSearchRecord)>,
    reached: &[(f64, f64)],
) -> Vec<ArmHoming> {
    let mut arms: Vec<ArmHoming> = config
        .robots
        .iter()
        .map(|r| ArmHoming {
            name: r.name.clone(),
            serial_number: r.serial_number.clone(),
            joints: Vec::new(),
            stop_searches: Vec::new(),
            inputs: Vec::new(),
        })
        .collect();
    for (arm, name, pressed) in inputs {
        if let Some(a) = arms.get_mut(arm) {
            a.inputs.push((name, pressed));
        }
    }
    for j in config.joints() {
        let i = j.index;
        let tolerance = j.potentiometer_tolerance().map_or(0.0, |t| t.distance);
        let stops =
            watch
                .axis(robot, i)
                .map(|a| a.params().stops)
                .map_or((f64::NAN, f64::NAN), |s| {
                    (
                        s.lower.unwrap_or(f64::NEG_INFINITY),
                        s.upper.unwrap_or(f64::INFINITY),
                    )
                });
        let soft = j.actuator.encoder.position_limits_soft;
        if let Some(arm) = arms.get_mut(j.robot_index) {
            arm.joints.push(JointHoming {
                joint: j.label.to_string(),
                prismatic: j.actuator.joint_type == Some(JointType::Prismatic),
                checked: j.actuator.potentiometer.is_some() && tolerance > 0.0,
                tolerance,
                max_pot_error: watch.max_pot_error[i],
                soft_limits: (soft.lower, soft.upper),
                reached: reached[i],
                stops,
                beyond_stop: watch.beyond_stop[i],
            });
        }
    }
    for (arm, record) in searches {
        if let Some(a) = arms.get_mut(arm) {
            a.stop_searches.push(record);
        }
    }
    arms
}

/// Move joint `i` to `target` with a trapezoidal profile at `speed` times
/// its configured velocity and acceleration limits, and let it settle.
fn move_to(
    robot: &mut Robot<IoSystem<SimPort>>,
    watch: &mut Watch,
    config: &IoConfig,
    i: usize,
    target: f64,
    speed: f64,
) -> Result<(), TestbedError> {
    let label = robot.joint_label(i).unwrap_or(Label::new("?"));
    let (v, a) = config
        .joints()
        .nth(i)
        .and_then(|j| j.actuator.limits)
        .map_or((0.5, 1.0), |l| {
            (l.velocity, l.acceleration.unwrap_or(4.0 * l.velocity))
        });
    let here = robot.setpoint(i).unwrap_or(0.0);
    let motion = PointToPoint::new(here, target, speed * v, speed * a)
        .map_err(|e| TestbedError::Config(format!("{label}: move to {target}: {e}")))?;
    let cycles = ((motion.duration() + SETTLE_S) / robot.period()).ceil() as u64;
    robot.set_motion(i, Motion::PointToPoint(motion))?;
    for _ in 0..cycles {
        let r = robot.step(Pacing::Virtual);
        watch.observe(robot);
        r?;
    }
    Ok(())
}

/// How long a joint is given to settle after a move, s.
const SETTLE_S: f64 = 0.2;
