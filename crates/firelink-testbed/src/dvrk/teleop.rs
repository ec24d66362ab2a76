//! A teleoperation session in the console's terms: an operator's hand
//! moves the MTMR, PSM1 follows through
//! [`firelink_control::dvrk::teleop`], everything through the host library
//! against emulated boards on the simulated bus, every cycle watched.
//!
//! 1. The arms as the console leaves them: MTMR (boards 2-3, its gripper
//!    on board 3 axis 3) and PSM1 with a Large Needle Driver (boards 6-7)
//!    powered, biased from their pots, the MTM roll homed against its
//!    stop; both moved to a working pose.
//! 2. Teleoperation enabled: the MTM's wrist turns to the PSM tip's
//!    orientation (the console's alignment, through the MTM's inverse
//!    kinematics) while the hand pinches the gripper to say it is there.
//! 3. Following: for [`TeleopOptions::seconds`] the hand moves as
//!    [`HandMotion`] says. The hand *is* the MTM's motion: each cycle its
//!    pose goes through the MTM's inverse kinematics to setpoints of the
//!    MTM's joints, and its fingers pinch the gripper's levers (a force on
//!    the emulated gripper, read back through its Hall-effect sensor). The
//!    teleoperation reads the MTM's measured pose (forward kinematics of
//!    its encoders) and gripper, and streams the PSM's joints (its
//!    closed-form inverse kinematics) and jaw (through the instrument's
//!    coupling) as servo points.
//! 4. Half-way the operator presses the clutch for
//!    [`TeleopOptions::clutch`]: the PSM holds while the hand brings the
//!    MTM back 40 mm; on release the teleoperation aligns again and
//!    resumes from where the PSM was held.
//!
//! The report gives the faults (any fault of either arm ends the run with
//! an error), how far the PSM's measured tip was from the scaled MTM
//! motion (p50/p99/max, mm), its orientation error, the jaw's, and the jump
//! at the clutch's release.
//!
//! ```no_run
//! use firelink_testbed::dvrk::teleop::{run_teleop, TeleopOptions};
//! let report = run_teleop(&TeleopOptions::default()).unwrap();
//! println!("{report}");
//! ```

use std::fmt;

use firelink_board::plant::presets::{
    MTM_GRIPPER_DEG_AT_ZERO_VOLTS, MTM_GRIPPER_DEG_PER_VOLT, MTM_GRIPPER_REST, MTM_GRIPPER_SPRING,
};
use firelink_board::qla::config::Profile;
use firelink_board::qla::node::BoardNode;
use firelink_bus::NodeHandle;
use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, RobotSimulation, ToolConfig, presets};
use firelink_control::dvrk::kinematics::frame::{add, norm, sub};
use firelink_control::dvrk::kinematics::mtm::{
    MTM_JOINTS, mtm_actuators, mtm_forward, mtm_inverse, mtm_joints, mtm_orient,
};
use firelink_control::dvrk::kinematics::psm::{
    PSM_ACTUATORS, PSM_JOINTS, psm_actuators, psm_forward, psm_inverse, psm_joints,
};
use firelink_control::dvrk::kinematics::{Frame, Rotation, Vec3};
use firelink_control::dvrk::teleop::{Teleop, TeleopInput, TeleopSettings, TeleopState};
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, PointToPoint, ServoPoint};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::sim::SimPort;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::{TestbedError, rig};

/// The seed of the default hand motion.
pub const HAND_SEED: u64 = 0x7e1e_0b5e;

/// Settings of the session.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TeleopOptions {
    /// The servo period (the console's teleoperation runs at 1 kHz).
    pub period: ServoPeriod,
    /// Seconds of following (the clutch's included).
    pub seconds: f64,
    /// The clutch: pressed at this many seconds into the following, for
    /// this long (`None`: never).
    pub clutch: Option<(f64, f64)>,
    /// The hand motion's seed.
    pub seed: u64,
    /// Firmware of the emulated boards.
    pub firmware: Profile,
}

impl Default for TeleopOptions {
    /// 1 kHz, 60 s with the clutch pressed from 30 to 33 s, the documented
    /// seed, Rev 8.
    fn default() -> Self {
        TeleopOptions {
            period: ServoPeriod::KHZ_1,
            seconds: 60.0,
            clutch: Some((30.0, 3.0)),
            seed: HAND_SEED,
            firmware: Profile::Rev8,
        }
    }
}

/// One smooth component of the hand's motion: `a sin(2 pi f t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Wave {
    amplitude: f64,
    frequency: f64,
    phase: f64,
}

impl Wave {
    fn at(&self, t: f64) -> (f64, f64) {
        let w = 2.0 * std::f64::consts::PI * self.frequency;
        let x = w * t + self.phase;
        (self.amplitude * x.sin(), self.amplitude * w * x.cos())
    }
}

/// A recorded-like hand motion: the hand's translation and rotation from
/// where it took the MTM, and the gripper's opening, each a sum of three
/// seeded sinusoids of 0.05 to 0.35 Hz (smooth, bounded, never repeating
/// within a session): up to about 90 mm per axis at up to 0.1 m/s, 27
/// degrees about each axis, the gripper between about 22 and 58 degrees,
/// and every 4 to 8 s a quick grasp (35 degrees further closed and open
/// again in 0.4 s). The same seed gives the same motion.
#[derive(Debug, Clone, PartialEq)]
pub struct HandMotion {
    translation: [[Wave; 3]; 3],
    rotation: [[Wave; 3]; 3],
    gripper: [Wave; 3],
    /// Quick grasps: (start, s) every 4 to 8 s.
    grasps: Vec<f64>,
}

/// A grasp: the gripper pinched [`GRASP_DEPTH`] further and let go again
/// within [`GRASP_SECONDS`] (a raised cosine), as a hand takes a needle.
const GRASP_SECONDS: f64 = 0.4;
/// How much further a grasp closes the gripper, rad.
const GRASP_DEPTH: f64 = 35.0 * std::f64::consts::PI / 180.0;

/// Where the hand is at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandSample {
    /// Translation from where the hand took the MTM, m.
    pub translation: Vec3,
    /// Its velocity, m/s.
    pub velocity: Vec3,
    /// Rotation from where the hand took the MTM (a rotation vector in
    /// the MTM's base frame), rad.
    pub rotation: Vec3,
    /// The gripper's opening the fingers hold, rad.
    pub gripper: f64,
}

impl HandMotion {
    /// The motion of `seed`.
    pub fn new(seed: u64) -> HandMotion {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut wave = |amplitude: f64| Wave {
            amplitude: amplitude * rng.random_range(0.5..1.0),
            frequency: rng.random_range(0.05..0.35),
            phase: rng.random_range(0.0..2.0 * std::f64::consts::PI),
        };
        let mut three = |a: f64| [wave(a), wave(a), wave(a)];
        let translation = [three(0.015), three(0.015), three(0.015)];
        let rotation = [three(0.08), three(0.08), three(0.08)];
        let gripper = three(6f64.to_radians());
        let mut grasps = Vec::new();
        let mut t = rng.random_range(2.0..6.0);
        while t < 3600.0 {
            grasps.push(t);
            t += rng.random_range(4.0..8.0);
        }
        HandMotion {
            translation,
            rotation,
            gripper,
            grasps,
        }
    }

    /// The hand `t` seconds into the motion. At 0 it is where it took the
    /// MTM (the sines' values then are subtracted).
    pub fn at(&self, t: f64) -> HandSample {
        let sum = |w: &[Wave; 3], t: f64| {
            w.iter().fold((0.0, 0.0), |(p, v), w| {
                let (a, b) = w.at(t);
                (p + a, v + b)
            })
        };
        let mut s = HandSample {
            translation: [0.0; 3],
            velocity: [0.0; 3],
            rotation: [0.0; 3],
            gripper: 0.0,
        };
        for k in 0..3 {
            let (p, v) = sum(&self.translation[k], t);
            let (p0, _) = sum(&self.translation[k], 0.0);
            s.translation[k] = p - p0;
            s.velocity[k] = v;
            let (r, _) = sum(&self.rotation[k], t);
            let (r0, _) = sum(&self.rotation[k], 0.0);
            s.rotation[k] = r - r0;
        }
        let (g, _) = sum(&self.gripper, t);
        // The grasp under way, if any (they are sorted and apart).
        let k = self.grasps.partition_point(|&start| start <= t);
        let grasp = k
            .checked_sub(1)
            .and_then(|k| self.grasps.get(k))
            .map_or(0.0, |&start| {
                let x = (t - start) / GRASP_SECONDS;
                if x < 1.0 {
                    0.5 * GRASP_DEPTH * (1.0 - (2.0 * std::f64::consts::PI * x).cos())
                } else {
                    0.0
                }
            });
        s.gripper = 40f64.to_radians() + g - grasp;
        s
    }
}

/// Percentiles of one error over the session.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Spread {
        if v.is_empty() {
            return Spread {
                p50: f64::NAN,
                p99: f64::NAN,
                max: f64::NAN,
            };
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Spread {
            p50: at(0.5),
            p99: at(0.99),
            max: at(1.0),
        }
    }
}

/// The session's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TeleopReport {
    /// Seconds of following asked for.
    pub seconds: f64,
    /// Servo cycles while teleoperation was enabled or clutched.
    pub cycles: u64,
    /// Servo cycles in all (bring-up included).
    pub total_cycles: u64,
    /// Faults of either arm (a fault ends the run with an error, so a
    /// report always says 0).
    pub faults: u32,
    /// Seconds from "enable" to following, the first time.
    pub alignment_seconds: f64,
    /// The orientation error when following started, degrees.
    pub aligned_within_deg: f64,
    /// |PSM measured tip - (PSM tip at enable + 0.2 x MTM measured motion
    /// since)|, mm, every following cycle.
    pub tip_error_mm: Spread,
    /// Angle between the PSM tip's measured orientation and its goal,
    /// degrees.
    pub orientation_error_deg: Spread,
    /// |PSM jaw measured - jaw goal|, degrees.
    pub jaw_error_deg: Spread,
    /// |jaw goal - the gripper mapped to the jaw|, degrees, once caught up
    /// (the console's rate limit of 720 degrees/s included).
    pub jaw_to_gripper_deg: Spread,
    /// The gripper's reading at rest before the hand took it, degrees.
    pub gripper_at_rest_deg: f64,
    /// The gripper's range over the session, degrees.
    pub gripper_range_deg: (f64, f64),
    /// How far the MTM moved (its gripper frame's path), m.
    pub mtm_path_m: f64,
    /// How far the PSM tip moved, m.
    pub psm_path_m: f64,
    /// How many times following started (1 + returns from the clutch).
    pub times_enabled: u32,
    /// The PSM's largest tip motion while clutched, mm.
    pub clutched_psm_motion_mm: f64,
    /// How far the MTM moved while clutched, mm.
    pub clutched_mtm_motion_mm: f64,
    /// The PSM goal's jump when following resumed after the clutch, mm.
    pub resume_jump_mm: f64,
    /// Cycles whose hand pose the MTM's inverse kinematics could not
    /// reach (the previous setpoint held).
    pub mtm_unreachable: u32,
    /// Cycles whose PSM goal its inverse kinematics refused (the previous
    /// goal held).
    pub psm_unreachable: u32,
}

impl fmt::Display for TeleopReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "teleoperation MTMR -> PSM1: {:.1} s, {} cycles following or clutched ({} in all), {} faults",
            self.seconds, self.cycles, self.total_cycles, self.faults
        )?;
        writeln!(
            f,
            "  aligned in {:.2} s (within {:.2} deg); enabled {} times; gripper at rest {:.1} deg, \
             pinched {:.1}..{:.1} deg",
            self.alignment_seconds,
            self.aligned_within_deg,
            self.times_enabled,
            self.gripper_at_rest_deg,
            self.gripper_range_deg.0,
            self.gripper_range_deg.1
        )?;
        let s = |x: &Spread| format!("p50 {:.3} p99 {:.3} max {:.3}", x.p50, x.p99, x.max);
        writeln!(f, "  tip following error, mm:   {}", s(&self.tip_error_mm))?;
        writeln!(
            f,
            "  tip orientation error, deg: {}",
            s(&self.orientation_error_deg)
        )?;
        writeln!(f, "  jaw following error, deg:  {}", s(&self.jaw_error_deg))?;
        writeln!(
            f,
            "  jaw goal vs gripper, deg:  {}",
            s(&self.jaw_to_gripper_deg)
        )?;
        writeln!(
            f,
            "  MTM path {:.3} m, PSM path {:.3} m; clutch: MTM moved {:.1} mm, PSM {:.3} mm, \
             resumed with a {:.4} mm jump; unreachable poses: MTM {}, PSM {}",
            self.mtm_path_m,
            self.psm_path_m,
            self.clutched_mtm_motion_mm,
            self.clutched_psm_motion_mm,
            self.resume_jump_mm,
            self.mtm_unreachable,
            self.psm_unreachable
        )
    }
}

/// MTMR (boards 2-3) and PSM1 with a Large Needle Driver (boards 6-7), as
/// the stock configurations have them.
pub fn mtmr_psm1() -> IoConfig {
    let mtm = presets::stock_mtmr();
    let mut c = presets::stock_psm1();
    if let Some(psm) = c.robots.first_mut() {
        let sim = psm.simulation.get_or_insert_with(RobotSimulation::default);
        sim.adapter = true;
        sim.tool = Some(ToolConfig {
            name: "LARGE_NEEDLE_DRIVER".into(),
            model: 400006,
            version: 0,
        });
    }
    let mut robots = mtm.robots;
    robots.append(&mut c.robots);
    c.robots = robots;
    c.description = Some(
        "Stock-style MTMR (boards 2-3) and PSM1 with a Large Needle Driver (boards 6-7) for \
         teleoperation."
            .into(),
    );
    c
}

/// Joints 0-6 are the MTM's, 7-13 the PSM's (configuration order).
const PSM0: usize = MTM_JOINTS;

/// The MTM's working pose at enable (joints, rad): arm forward and down,
/// wrist square.
const MTM_START: [f64; MTM_JOINTS] = [0.0, 0.25, 0.1, 0.0, 0.3, 0.0, 0.0];
/// The PSM's working pose (joints; insertion in m) and jaw.
const PSM_START: ([f64; PSM_JOINTS], f64) = ([0.1, -0.15, 0.14, 0.0, 0.1, -0.1], 0.5);

/// A running session: the robot, the watched plant, the bookkeeping.
struct Session {
    robot: Robot<IoSystem<SimPort>>,
    /// Board 3's node (the MTM gripper is its axis 3).
    gripper_board: Option<NodeHandle>,
    gripper_axis: usize,
    period: f64,
}

impl Session {
    fn actuators<const N: usize>(&self, first: usize, setpoint: bool) -> [f64; N] {
        let mut a = [0.0; N];
        for (k, x) in a.iter_mut().enumerate() {
            let v = if setpoint {
                self.robot.setpoint(first + k)
            } else {
                self.robot.position(first + k)
            };
            *x = v.unwrap_or(f64::NAN);
        }
        a
    }

    fn mtm_measured(&self) -> ([f64; MTM_JOINTS], Frame) {
        let q = mtm_joints(&self.actuators::<MTM_JOINTS>(0, false));
        (q, mtm_forward(&q))
    }

    fn psm(&self, setpoint: bool) -> ([f64; PSM_JOINTS], f64, Frame) {
        let (q, jaw) = psm_joints(&self.actuators::<PSM_ACTUATORS>(PSM0, setpoint));
        (q, jaw, psm_forward(&q))
    }

    /// The gripper as the console reads it: the analog input's ADC bits
    /// through the dVRK's conversion, rad.
    fn gripper(&self) -> f64 {
        let bits = self
            .robot
            .io()
            .boards()
            .iter()
            .find(|b| b.board_id() == 3)
            .and_then(|b| b.pot_bits(self.gripper_axis));
        bits.map_or(f64::NAN, |b| {
            let volts = f64::from(b) * 4.5 / 65536.0;
            (MTM_GRIPPER_DEG_PER_VOLT * volts + MTM_GRIPPER_DEG_AT_ZERO_VOLTS).to_radians()
        })
    }

    /// The fingers: the force that holds the levers at `opening` against
    /// their spring (none: let go).
    fn pinch(&mut self, opening: Option<f64>) {
        let torque = opening.map_or(0.0, |g| MTM_GRIPPER_SPRING * (g - MTM_GRIPPER_REST));
        let axis = self.gripper_axis;
        let Some(handle) = self.gripper_board else {
            return;
        };
        let bus = self.robot.io_mut().port_mut().bus_mut();
        let now = bus.now();
        if let Some(node) = bus.node_mut::<BoardNode>(handle) {
            let plant = node.firmware_mut().plant_mut();
            plant.advance_to(now);
            if let Some(a) = plant.axis_mut(axis) {
                a.set_external_torque(torque);
            }
        }
    }

    fn step(&mut self) -> Result<(), TestbedError> {
        self.robot.step(Pacing::Virtual)?;
        Ok(())
    }

    /// Move joints `first..first + target.len()` to `target` (actuator
    /// space) with trapezoidal profiles, and let them settle.
    fn move_actuators(
        &mut self,
        first: usize,
        target: &[f64],
        speed: f64,
    ) -> Result<(), TestbedError> {
        let mut longest: f64 = 0.0;
        for (k, &goal) in target.iter().enumerate() {
            let i = first + k;
            let here = self.robot.setpoint(i).unwrap_or(goal);
            let m = PointToPoint::new(here, goal, speed, 4.0 * speed)
                .map_err(|e| TestbedError::Config(format!("joint {i}: {e}")))?;
            longest = longest.max(m.duration());
            self.robot.set_motion(i, Motion::PointToPoint(m))?;
        }
        let cycles = ((longest + 0.3) / self.period).ceil() as u64;
        for _ in 0..cycles {
            self.step()?;
        }
        Ok(())
    }

    /// Stream `target` (actuator space) with `velocity` to joints
    /// `first..`.
    fn servo(
        &mut self,
        first: usize,
        target: &[f64],
        velocity: &[f64],
    ) -> Result<(), TestbedError> {
        let horizon = 2.0 * self.period;
        for (k, (&p, &v)) in target.iter().zip(velocity).enumerate() {
            let point = ServoPoint::new(p, v, horizon)
                .map_err(|e| TestbedError::Config(format!("servo point: {e}")))?;
            self.robot.servo_point(first + k, point)?;
        }
        Ok(())
    }
}

/// Run the session.
///
/// # Errors
/// A fault of either arm (a tracking error included), an alignment that
/// does not finish within 10 s, a configuration the rig cannot build.
pub fn run_teleop(options: &TeleopOptions) -> Result<TeleopReport, TestbedError> {
    let config = mtmr_psm1();
    let (port, boards) = rig::sim_port_of_used(&config, options.firmware)?;
    let gripper_board = boards.iter().find(|(id, _)| *id == 3).map(|(_, h)| *h);
    let gripper_axis = config
        .robots
        .first()
        .and_then(crate::plant_map::gripper_slot)
        .map_or(3, |(_, axis)| usize::from(axis));
    let (io, _) = IoSystem::open(port, IoOptions::default())?;
    let settings = RobotSettings {
        period: options.period,
        ..RobotSettings::default()
    };
    let robot = Robot::new(io, &config, settings)?;
    let period = robot.period();
    let mut s = Session {
        robot,
        gripper_board,
        gripper_axis,
        period,
    };
    match session(&mut s, options) {
        Ok(r) => {
            s.robot.shutdown()?;
            Ok(r)
        }
        Err(e) => {
            let power_down = s.robot.shutdown()?;
            Err(TestbedError::PoweredDown {
                error: Box::new(e),
                power_down,
            })
        }
    }
}

/// The console's bring-up: power, bias from the pots, the MTM roll against
/// its stop, both arms to a working pose. The gripper's reading at rest.
fn bring_up(s: &mut Session) -> Result<f64, TestbedError> {
    s.robot.configure()?;
    s.robot.power_on()?;
    s.robot.home()?;
    s.robot.activate()?;
    let searches: Vec<usize> = s.robot.stop_search_joints().collect();
    for i in searches {
        s.robot.search_stop_observed(i, &mut |_| {})?;
    }
    let gripper_at_rest = s.gripper();
    s.move_actuators(0, &mtm_actuators(&MTM_START), 0.5)?;
    let (q, jaw) = PSM_START;
    s.move_actuators(PSM0, &psm_actuators(&q, jaw), 0.5)?;
    Ok(gripper_at_rest)
}

/// Enable teleoperation and align the MTM to the PSM, the hand pinching to
/// say it is there: the alignment error when enabled (degrees), the
/// seconds it took and the MTM's joint goal it leaves.
fn enable_and_align(
    s: &mut Session,
    teleop: &mut Teleop,
) -> Result<(f64, f64, [f64; MTM_JOINTS]), TestbedError> {
    teleop.enable();
    let enable_at = s.robot.now();
    let mut mtm_goal_q = mtm_joints(&s.actuators::<MTM_JOINTS>(0, true));
    let mut aligning_move = false;
    let aligned_within = loop {
        let t = s.robot.now() - enable_at;
        if t > 10.0 {
            return Err(TestbedError::Config(format!(
                "teleoperation did not align within 10 s (state {:?})",
                teleop.state()
            )));
        }
        // A pinch of 15 degrees after half a second, let go at one.
        let pinch = (0.5..1.0).contains(&t).then_some(45f64.to_radians());
        s.pinch(pinch);
        let input = teleop_input(s, t, false);
        let c = teleop.update(&input);
        if c.state == TeleopState::Enabled {
            break c.alignment_error.to_degrees();
        }
        if let (Some(goal), false) = (c.mtm_orientation, aligning_move) {
            // The console's move_cp of the MTM's orientation.
            let q = mtm_orient(&mtm_goal_q, &goal)
                .map_err(|e| TestbedError::Config(format!("aligning the MTM: {e}")))?;
            mtm_goal_q = q;
            let a = mtm_actuators(&q);
            for (k, &goal) in a.iter().enumerate() {
                let here = s.robot.setpoint(k).unwrap_or(goal);
                let m = PointToPoint::new(here, goal, 1.0, 4.0)
                    .map_err(|e| TestbedError::Config(format!("MTM joint {k}: {e}")))?;
                s.robot.set_motion(k, Motion::PointToPoint(m))?;
            }
            aligning_move = true;
        }
        s.step()?;
    };
    let alignment_seconds = s.robot.now() - enable_at;
    Ok((aligned_within, alignment_seconds, mtm_goal_q))
}

/// Servo the MTM towards `goal` through its inverse kinematics (the goal
/// kept when unreachable), velocities from the last actuator positions.
/// Whether the goal was reachable.
fn servo_mtm(
    s: &mut Session,
    goal: &Frame,
    mtm_goal_q: &mut [f64; MTM_JOINTS],
    last_mtm_a: &mut [f64; MTM_JOINTS],
) -> Result<bool, TestbedError> {
    let reachable = match mtm_inverse(goal, mtm_goal_q) {
        Ok(q) => {
            *mtm_goal_q = q;
            true
        }
        Err(_) => false,
    };
    let a = mtm_actuators(mtm_goal_q);
    let v: [f64; MTM_JOINTS] = std::array::from_fn(|i| (a[i] - last_mtm_a[i]) / s.period);
    *last_mtm_a = a;
    s.servo(0, &a, &v)?;
    Ok(reachable)
}

/// Hold the PSM where its setpoint is: the pose held and the actuator
/// positions.
fn hold_psm(s: &mut Session) -> Result<(Frame, [f64; PSM_ACTUATORS]), TestbedError> {
    let (_, _, f) = s.psm(true);
    let hold = s.actuators::<PSM_ACTUATORS>(PSM0, true);
    for (i, p) in hold.iter().enumerate() {
        s.robot.set_motion(PSM0 + i, Motion::Hold(*p))?;
    }
    Ok((f, hold))
}

/// Servo the PSM towards `goal` with `jaw` through its inverse kinematics
/// (the goal kept when unreachable). Whether the goal was reachable.
fn servo_psm(
    s: &mut Session,
    goal: &Frame,
    jaw: f64,
    psm_goal_q: &mut [f64; PSM_JOINTS],
    last_psm_a: &mut [f64; PSM_ACTUATORS],
) -> Result<bool, TestbedError> {
    let reachable = match psm_inverse(goal, psm_goal_q) {
        Ok(q) => {
            *psm_goal_q = q;
            true
        }
        Err(_) => false,
    };
    let a = psm_actuators(psm_goal_q, jaw);
    let v: [f64; PSM_ACTUATORS] = std::array::from_fn(|i| (a[i] - last_psm_a[i]) / s.period);
    *last_psm_a = a;
    s.servo(PSM0, &a, &v)?;
    Ok(reachable)
}

/// Where the hand has carried the MTM `progress` (0 to 1) of the way
/// through the clutch's `travel`, on a smooth-step.
fn clutch_offset_at(progress: f64, travel: [f64; 3]) -> [f64; 3] {
    let x = progress.clamp(0.0, 1.0);
    let smooth = x * x * (3.0 - 2.0 * x);
    let mut offset = [0.0; 3];
    for (o, d) in offset.iter_mut().zip(travel) {
        *o = smooth * d;
    }
    offset
}

fn session(s: &mut Session, options: &TeleopOptions) -> Result<TeleopReport, TestbedError> {
    // 1. The console's bring-up: power, bias from the pots, the MTM roll
    //    against its stop, both arms to a working pose.
    let gripper_at_rest = bring_up(s)?;

    // 2. Enable: align the MTM to the PSM; the hand pinches to say it is
    //    there.
    let mut teleop = Teleop::new(TeleopSettings::default());
    let (aligned_within, alignment_seconds, mut mtm_goal_q) = enable_and_align(s, &mut teleop)?;

    // 3. Following, with the clutch half-way.
    let hand = HandMotion::new(options.seed);
    let (_, took) = s.mtm_measured();
    let mut grip_base = took;
    let cycles = (options.seconds / s.period).round() as u64;
    let mut tip_err = Vec::with_capacity(cycles as usize);
    let mut rot_err = Vec::with_capacity(cycles as usize);
    let mut jaw_err = Vec::with_capacity(cycles as usize);
    let mut jaw_map_err = Vec::with_capacity(cycles as usize);
    let mut psm_goal_q = PSM_START.0;
    let mut last_psm_goal: Option<Frame> = None;
    let mut last_mtm_a = mtm_actuators(&mtm_goal_q);
    let mut last_psm_a = psm_actuators(&PSM_START.0, PSM_START.1);
    let (mut mtm_path, mut psm_path) = (0.0, 0.0);
    let mut psm_last = s.psm(false).2.translation;
    let mut mtm_last = took.translation;
    let mut gripper_range = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut mtm_unreachable, mut psm_unreachable) = (0u32, 0u32);
    let mut clutch_psm_from: Option<Vec3> = None;
    let mut clutch_mtm_from: Option<Vec3> = None;
    let (mut clutched_psm, mut clutched_mtm) = (0.0f64, 0.0f64);
    let mut held: Option<Frame> = None;
    let mut resume_jump = 0.0f64;
    let (clutch_at, clutch_for) = options.clutch.unwrap_or((f64::INFINITY, 0.0));
    // The hand's time stands still while clutched (the MTM's orientation
    // is locked then; the hand only brings it back).
    let mut hand_t = 0.0;
    let clutch_travel = [0.0, -0.04, 0.0];
    let mut clutch_offset = [0.0; 3];
    let mut caught_up = false;
    for k in 0..cycles {
        let t = k as f64 * s.period;
        let clutched = (clutch_at..clutch_at + clutch_for).contains(&t);
        if clutched {
            clutch_offset = clutch_offset_at((t - clutch_at) / clutch_for, clutch_travel);
        } else {
            hand_t += s.period;
        }
        let h = hand.at(hand_t);
        // The hand moves the MTM: its pose through the MTM's inverse
        // kinematics to the MTM's joints.
        let goal = Frame::new(
            Rotation::from_rotation_vector(h.rotation) * grip_base.rotation,
            add(add(grip_base.translation, h.translation), clutch_offset),
        );
        mtm_unreachable += u32::from(!servo_mtm(s, &goal, &mut mtm_goal_q, &mut last_mtm_a)?);
        s.pinch(Some(h.gripper));

        // The console's teleoperation.
        let input = teleop_input(s, t, clutched);
        let c = teleop.update(&input);
        if c.psm_hold {
            let (f, hold) = hold_psm(s)?;
            held = Some(f);
            last_psm_a = hold;
        }
        if let Some(goal) = c.psm {
            if let (Some(h), true) = (held.take(), teleop.times_enabled() > 1) {
                resume_jump = norm(sub(goal.translation, h.translation)) * 1e3;
            }
            let jaw = c.jaw.unwrap_or(input.psm_jaw);
            let reached = servo_psm(s, &goal, jaw, &mut psm_goal_q, &mut last_psm_a)?;
            psm_unreachable += u32::from(!reached);
            last_psm_goal = Some(goal);
        }
        if c.state == TeleopState::Aligning {
            // Back from the clutch: the hand holds the MTM where it is.
            grip_base = Frame::new(
                Rotation::from_rotation_vector(h.rotation).transpose() * input.mtm.rotation,
                sub(sub(input.mtm.translation, h.translation), clutch_offset),
            );
        }
        s.step()?;

        // What happened this cycle.
        let (_, mtm_now) = s.mtm_measured();
        let (_, jaw_now, psm_now) = s.psm(false);
        mtm_path += norm(sub(mtm_now.translation, mtm_last));
        psm_path += norm(sub(psm_now.translation, psm_last));
        mtm_last = mtm_now.translation;
        psm_last = psm_now.translation;
        let g = input.gripper;
        gripper_range = (gripper_range.0.min(g), gripper_range.1.max(g));
        match c.state {
            TeleopState::Enabled => {
                clutch_psm_from = None;
                clutch_mtm_from = None;
                if let Some(goal) = last_psm_goal {
                    tip_err.push(norm(sub(psm_now.translation, goal.translation)) * 1e3);
                    rot_err.push(psm_now.rotation.angle_to(&goal.rotation).to_degrees());
                }
                if let Some(j) = c.jaw {
                    jaw_err.push((jaw_now - j).abs().to_degrees());
                    let mapped = teleop
                        .gripper_to_jaw(g)
                        .clamp(teleop.settings().jaw_limits.0, f64::INFINITY);
                    let gap = (j - mapped).abs().to_degrees();
                    caught_up |= gap < 2.0;
                    if caught_up {
                        jaw_map_err.push(gap);
                    }
                }
            }
            TeleopState::Clutched => {
                caught_up = false;
                let p0 = *clutch_psm_from.get_or_insert(psm_now.translation);
                let m0 = *clutch_mtm_from.get_or_insert(mtm_now.translation);
                clutched_psm = clutched_psm.max(norm(sub(psm_now.translation, p0)) * 1e3);
                clutched_mtm = clutched_mtm.max(norm(sub(mtm_now.translation, m0)) * 1e3);
            }
            _ => {}
        }
    }
    s.pinch(None);
    Ok(TeleopReport {
        seconds: options.seconds,
        cycles,
        total_cycles: s.robot.cycles(),
        faults: u32::from(s.robot.fault().is_some()),
        alignment_seconds,
        aligned_within_deg: aligned_within,
        tip_error_mm: Spread::of(tip_err),
        orientation_error_deg: Spread::of(rot_err),
        jaw_error_deg: Spread::of(jaw_err),
        jaw_to_gripper_deg: Spread::of(jaw_map_err),
        gripper_at_rest_deg: gripper_at_rest.to_degrees(),
        gripper_range_deg: (gripper_range.0.to_degrees(), gripper_range.1.to_degrees()),
        mtm_path_m: mtm_path,
        psm_path_m: psm_path,
        times_enabled: teleop.times_enabled(),
        clutched_psm_motion_mm: clutched_psm,
        clutched_mtm_motion_mm: clutched_mtm,
        resume_jump_mm: resume_jump,
        mtm_unreachable,
        psm_unreachable,
    })
}

/// What the teleoperation reads: the MTM's measured pose and gripper, the
/// PSM's setpoint pose and jaw, the clutch.
fn teleop_input(s: &Session, now: f64, clutch: bool) -> TeleopInput {
    let (_, mtm) = s.mtm_measured();
    let (_, psm_jaw, psm) = s.psm(true);
    TeleopInput {
        now,
        mtm,
        gripper: s.gripper(),
        psm,
        psm_jaw,
        clutch,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hand_motion_is_smooth_seeded_and_starts_where_the_hand_took_the_mtm() {
        let a = HandMotion::new(HAND_SEED);
        assert_eq!(a, HandMotion::new(HAND_SEED));
        assert_ne!(a, HandMotion::new(HAND_SEED + 1));
        let h0 = a.at(0.0);
        assert_eq!(h0.translation, [0.0; 3]);
        assert_eq!(h0.rotation, [0.0; 3]);
        // Bounded, and no step between two samples 1 ms apart.
        for k in 0..60_000 {
            let t = f64::from(k) * 1e-3;
            let (h, next) = (a.at(t), a.at(t + 1e-3));
            assert!(h.translation.iter().all(|x| x.abs() < 0.1));
            assert!(h.rotation.iter().all(|x| x.abs() < 0.7));
            assert!((-14f64.to_radians()..59f64.to_radians()).contains(&h.gripper));
            assert!(norm(sub(next.translation, h.translation)) < 0.2e-3);
            assert!((next.gripper - h.gripper).abs() < 4f64.to_radians() * 1e-3 * 100.0);
        }
        // Grasps every 4 to 8 s: the gripper closes well below its mean.
        let closed = (0..60_000)
            .filter(|k| a.at(f64::from(*k) * 1e-3).gripper < 20f64.to_radians())
            .count();
        assert!(closed > 500, "{closed}");
    }
}
