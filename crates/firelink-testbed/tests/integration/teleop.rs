//! Issue 29 item 5: teleoperation MTMR -> PSM1 through the console-like
//! control. The MTM is driven by a recorded-like hand motion (seeded:
//! `HAND_SEED`) through its inverse kinematics, the PSM follows through
//! the console's teleoperation, 60 s of virtual time on the simulated bus:
//! no fault of either arm (a tracking error would be one), the PSM's tip
//! following the MTM's motion scaled by 0.2, the jaw following the
//! gripper, and a clutch half-way that resumes without a jump.

use firelink_testbed::dvrk::teleop::{TeleopOptions, run_teleop};

#[test]
fn psm1_follows_mtmr_for_60_seconds_without_a_fault() {
    let options = TeleopOptions::default();
    let r = run_teleop(&options).unwrap_or_else(|e| panic!("{e}"));
    println!("{r}");
    assert_eq!(r.faults, 0);
    assert_eq!(r.cycles, 60_000);
    // The gripper at rest reads open (60 degrees), as a real MTM's does.
    assert!((r.gripper_at_rest_deg - 60.0).abs() < 1.0, "{r:?}");
    // Aligned as the console requires: within 5 degrees.
    assert!(r.aligned_within_deg <= 5.0);
    // Every hand pose and every PSM goal reachable.
    assert_eq!((r.mtm_unreachable, r.psm_unreachable), (0, 0));
    // The tip follows the scaled MTM motion within 3 mm (p99 2 mm), its
    // orientation within 3 degrees.
    assert!(
        r.tip_error_mm.p99 < 2.0 && r.tip_error_mm.max < 3.0,
        "{r:?}"
    );
    assert!(r.orientation_error_deg.max < 3.0, "{r:?}");
    // The PSM really moved: the MTM's path scaled by 0.2, within 15 %
    // (the clutch's 40 mm of MTM travel does not count).
    let scaled = 0.2 * (r.mtm_path_m - r.clutched_mtm_motion_mm * 1e-3);
    assert!(r.mtm_path_m > 0.5, "{r:?}");
    assert!((r.psm_path_m / scaled - 1.0).abs() < 0.15, "{r:?}");
    // The jaw follows its goal within 5 degrees through the grasps, and
    // the goal follows the gripper (0..60 -> 0..80 degrees) within the
    // console's rate limit.
    assert!(
        r.gripper_range_deg.0 < 15.0 && r.gripper_range_deg.1 > 50.0,
        "{r:?}"
    );
    assert!(r.jaw_error_deg.max < 5.0, "{r:?}");
    assert!(r.jaw_to_gripper_deg.p99 < 2.0, "{r:?}");
    // The clutch: the MTM went back about 40 mm while the PSM held still;
    // following resumed once, from where the PSM was held.
    assert_eq!(r.times_enabled, 2);
    assert!(r.clutched_mtm_motion_mm > 30.0, "{r:?}");
    assert!(r.clutched_psm_motion_mm < 0.5, "{r:?}");
    assert!(r.resume_jump_mm < 0.01, "{r:?}");
}

/// The instrument's wrist yaw and jaw (the last two disks, coupled) follow
/// the fastest motion the console's teleoperation asks of them: the jaw
/// goal across its whole range (-40 to 80 degrees) twice a second at up to
/// the console's 720 degrees/s, while the wrist yaw swings 30 degrees
/// either way at 0.5 Hz and the wrist pitch 0.3 rad at 0.3 Hz. No fault
/// (tracking error, velocity), and the joints stay within 5 degrees of
/// their goals.
#[test]
fn the_instrument_wrist_and_jaw_follow_teleoperation_speeds() {
    use firelink_control::dvrk::kinematics::psm::{PSM_JOINTS, psm_actuators, psm_joints};
    use firelink_control::runner::{Pacing, Robot, RobotSettings};
    use firelink_control::trajectory::{PointToPoint, ServoPoint};
    use firelink_host::qla::io::{IoOptions, IoSystem};
    use firelink_testbed::rig;

    let mut config = firelink_testbed::dvrk::teleop::mtmr_psm1();
    config.robots.remove(0);
    let (port, _) =
        rig::sim_port_of_used(&config, firelink_board::qla::config::Profile::Rev8).unwrap();
    let (io, _) = IoSystem::open(port, IoOptions::default()).unwrap();
    let mut robot = Robot::new(io, &config, RobotSettings::default()).unwrap();
    robot.configure().unwrap();
    robot.power_on().unwrap();
    robot.home().unwrap();
    robot.activate().unwrap();
    let period = robot.period();
    let start = [0.0, 0.0, 0.12, 0.0, 0.0, 0.0];
    let a0 = psm_actuators(&start, 0.0);
    for (i, &a) in a0.iter().enumerate() {
        let here = robot.setpoint(i).unwrap();
        let m = PointToPoint::new(here, a, 0.5, 2.0).unwrap();
        robot
            .set_motion(i, firelink_control::trajectory::Motion::PointToPoint(m))
            .unwrap();
    }
    for _ in 0..3000 {
        robot.step(Pacing::Virtual).unwrap();
    }
    // The jaw's goal as the console moves it: towards a gripper opening
    // and closing across the whole jaw range twice a second, at most 720
    // degrees/s.
    let rate = 720f64.to_radians();
    let mut jaw = 0.0f64;
    let mut last = a0;
    let (mut worst_yaw, mut worst_jaw, mut worst_pitch) = (0.0f64, 0.0f64, 0.0f64);
    let mut worst_speed = 0.0f64;
    for k in 0..8000 {
        let t = f64::from(k) * period;
        let target = (20.0 + 60.0 * (2.0 * std::f64::consts::PI * 2.0 * t).sin()).to_radians();
        jaw += (target - jaw).clamp(-rate * period, rate * period);
        let mut q: [f64; PSM_JOINTS] = start;
        q[4] = 0.3 * (2.0 * std::f64::consts::PI * 0.3 * t).sin();
        q[5] = 30f64.to_radians() * (2.0 * std::f64::consts::PI * 0.5 * t).sin();
        let a = psm_actuators(&q, jaw);
        for (i, (&p, &before)) in a.iter().zip(&last).enumerate() {
            let point = ServoPoint::new(p, (p - before) / period, 2.0 * period).unwrap();
            robot.servo_point(i, point).unwrap();
        }
        last = a;
        robot
            .step(Pacing::Virtual)
            .unwrap_or_else(|e| panic!("at {t:.3} s: {e}"));
        for i in 3..7 {
            worst_speed = worst_speed.max(robot.velocity(i).unwrap().abs());
        }
        let at = |setpoint: bool| {
            let v: [f64; 7] = std::array::from_fn(|i| {
                if setpoint {
                    robot.setpoint(i).unwrap()
                } else {
                    robot.position(i).unwrap()
                }
            });
            psm_joints(&v)
        };
        let ((goal, goal_jaw), (measured, measured_jaw)) = (at(true), at(false));
        worst_pitch = worst_pitch.max((goal[4] - measured[4]).abs());
        worst_yaw = worst_yaw.max((goal[5] - measured[5]).abs());
        worst_jaw = worst_jaw.max((goal_jaw - measured_jaw).abs());
    }
    println!(
        "largest tracking errors: wrist pitch {:.2} deg, wrist yaw {:.2} deg, jaw {:.2} deg; \
         fastest disk {worst_speed:.2} rad/s",
        worst_pitch.to_degrees(),
        worst_yaw.to_degrees(),
        worst_jaw.to_degrees()
    );
    assert!(robot.fault().is_none());
    assert!(worst_yaw < 5f64.to_radians() && worst_jaw < 5f64.to_radians());
    assert!(worst_pitch < 5f64.to_radians());
    robot.shutdown().unwrap();
}
