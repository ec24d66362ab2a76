//! The console-like homing scenario on every shipped stock arm: encoders
//! biased from the pots, the MTM roll's lower stop found by a stop search,
//! every joint to both software limits and back. Throughout, |encoder -
//! pot| stays within the configuration's tolerance and no joint passes its
//! stop; a stall is seen as the current at its limit and a following error
//! that grows every cycle.

use firelink_control::config::{IoConfig, presets};
use firelink_testbed::dvrk::console_homing::{
    ArmHoming, ConsoleHomingOptions, ConsoleHomingReport, run_console_homing,
};

fn run(config: &IoConfig) -> ConsoleHomingReport {
    let report = run_console_homing(config, &ConsoleHomingOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    println!("{report}");
    report
}

/// What holds for every arm.
fn check_arm(arm: &ArmHoming) {
    assert!(!arm.joints.is_empty());
    for j in &arm.joints {
        if j.checked {
            assert!(
                j.max_pot_error <= j.tolerance,
                "{}: |encoder - pot| reached {} (tolerance {})",
                j.joint,
                j.max_pot_error,
                j.tolerance
            );
            // Not just within tolerance: the pot reads the joint (a few
            // ADC counts of noise and quantisation, a little lag).
            assert!(j.max_pot_error < 0.2 * j.tolerance, "{}", j.joint);
        }
        assert_eq!(j.beyond_stop, 0.0, "{} went past a stop", j.joint);
        // The stops are beyond the software limits, and the joint got to
        // both limits (within the dVRK console's goal tolerance of 3
        // degrees; a gravity-loaded joint settles slowly).
        assert!(
            j.stops.0 < j.soft_limits.0 && j.soft_limits.1 < j.stops.1,
            "{j:?}"
        );
        let slack = if j.prismatic {
            0.003
        } else {
            3f64.to_radians()
        };
        assert!((j.reached.0 - j.soft_limits.0).abs() < slack, "{j:?}");
        assert!((j.reached.1 - j.soft_limits.1).abs() < slack, "{j:?}");
    }
}

#[test]
fn stock_psm1_homes_with_pots_and_encoders_agreeing() {
    let r = run(&presets::stock_psm1());
    assert_eq!(r.arms.len(), 1);
    let psm = &r.arms[0];
    assert_eq!(
        (psm.name.as_str(), psm.serial_number.as_str()),
        ("PSM1", "28007")
    );
    check_arm(psm);
    assert_eq!(psm.joints.len(), 7);
    assert!(psm.joints.iter().all(|j| j.checked));
    assert!(psm.stop_searches.is_empty());
    // The console reads the contacts as plugged in: the sterile adapter
    // on, no instrument, clutches released.
    let read = |name: &str| psm.inputs.iter().find(|(n, _)| n == name).unwrap().1;
    assert!(read("PSM1_adapter"));
    assert!(!read("PSM1_tool"));
    assert!(!read("PSM1_arm_clutch") && !read("PSM1_SUJ_clutch"));
}

#[test]
fn stock_ecm_homes_with_pots_and_encoders_agreeing() {
    let r = run(&presets::stock_ecm());
    let ecm = &r.arms[0];
    assert_eq!((ecm.name.as_str(), ecm.joints.len()), ("ECM", 4));
    check_arm(ecm);
}

#[test]
fn stock_mtmr_homes_its_roll_by_a_stop_search() {
    let r = run(&presets::stock_mtmr());
    let mtm = &r.arms[0];
    assert_eq!((mtm.name.as_str(), mtm.joints.len()), ("MTMR", 7));
    check_arm(mtm);
    // The coupled joints' pots (on the joints, not the actuators: the
    // emulated pot of actuator 3 reads a3 - 0.6697 a2 + 0.6697 a1) agree
    // in actuator space.
    assert!(mtm.joints[2].checked && mtm.joints[3].checked);
    let config = presets::stock_mtmr();
    let pot3 = firelink_testbed::plant_map::plant_for(&config, 3)
        .unwrap()
        .pot
        .measures;
    assert_eq!(pot3.len(), 3, "{pot3:?}");
    // The roll's pot reads about half a turn and saturates beyond (as the
    // arm's): the stops are far outside what it can read.
    let roll = firelink_testbed::plant_map::plant_for(&config, 6).unwrap();
    let (pot_lo, pot_hi) = roll.pot_position_range().unwrap();
    assert!(pot_lo > -2.0 && pot_hi < 2.0, "{pot_lo} {pot_hi}");
    assert!(mtm.joints[6].stops.0 < pot_lo - 6.0 && mtm.joints[6].stops.1 > pot_hi + 6.0);
    // The roll: found its lower stop (-480 degrees) by stalling against it.
    assert_eq!(mtm.stop_searches.len(), 1);
    let s = &mtm.stop_searches[0];
    assert_eq!(s.joint, "MTMR[6]");
    let lower_stop = mtm.joints[6].stops.0;
    assert!((s.true_position - lower_stop).abs() < 1e-9, "{s:?}");
    assert!((s.stop_position - lower_stop).abs() < 1e-9, "{s:?}");
    // Stall: the current at the limit, the following error growing every
    // cycle until it passed half a turn.
    assert!(s.error_grew, "{s:?}");
    assert!(s.stalled_for > 0.2, "{s:?}");
    assert!(s.following_error > std::f64::consts::PI, "{s:?}");
    assert!(
        (s.commanded_current.abs() - s.current_limit).abs() < 1e-9,
        "{s:?}"
    );
    assert!(
        (s.measured_current.abs() - s.current_limit).abs() < 0.02,
        "{s:?}"
    );
    // Then free motion back home.
    assert!((s.returned_to - s.home).abs() < 0.02, "{s:?}");
}

#[test]
fn shipped_stock_files_are_the_presets() {
    for name in [
        "dvrk-psm1-28007.json",
        "dvrk-mtmr-28247.json",
        "dvrk-ecm-29738.json",
    ] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs")
            .join(name);
        let c = IoConfig::load(&path).unwrap_or_else(|e| panic!("{e}"));
        // Nothing the emulator cannot make agree with the file.
        assert_eq!(
            firelink_testbed::plant_map::notes(&c),
            Vec::<String>::new(),
            "{name}"
        );
    }
}
