//! Issue 29 item 5: teleoperation MTMR -> PSM1 through the console-like
//! control. The MTM is driven by a recorded-like hand motion (seeded:
//! `HAND_SEED`) through its inverse kinematics, the PSM follows through
//! the console's teleoperation, 60 s of virtual time on the simulated bus:
//! no fault of either arm (a tracking error would be one), the PSM's tip
//! following the MTM's motion scaled by 0.2, the jaw following the
//! gripper, and a clutch half-way that resumes without a jump.

use firelink_testbed::teleop::{TeleopOptions, run_teleop};

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
