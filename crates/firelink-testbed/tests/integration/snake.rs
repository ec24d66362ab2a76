//! Seed 001's own system on emulated Snake nodes: the 36-axis demo at
//! 1 kHz, the same servo code on a QLA rig and a Snake rig through the
//! abstract robot I/O, the safety chain, the seed's measurements, and the
//! nodes behind the UDP bridge. Virtual time throughout (except the one
//! UDP test, which asserts behaviour only).

use std::time::Duration;

use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_host::RobotIo;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::snake::SnakeSystem;
use firelink_testbed::demo::{DemoFault, motion_for};
use firelink_testbed::rig;
use firelink_testbed::snake::bench::{Seed001Options, run_seed001_bench};
use firelink_testbed::snake::demo::{SnakeDemoOptions, run_snake_demo};
use firelink_testbed::snake::{emulator, node_configs, prepare, sim_port};

fn short(fault: DemoFault) -> SnakeDemoOptions {
    SnakeDemoOptions {
        duration_s: 0.6,
        fault,
        find_max_rate: false,
        ..SnakeDemoOptions::default()
    }
}

#[test]
fn the_36_axis_system_runs_at_1_khz_without_errors() {
    let r = run_snake_demo(&short(DemoFault::None), None, |_| {}).unwrap();
    r.verdict().unwrap();
    let d = &r.demo;
    assert_eq!((d.boards, d.axes), (6, 36));
    assert_eq!(r.nodes, [0, 1, 2, 3, 4, 5]);
    assert_eq!(d.rate_hz, 1000.0);
    assert_eq!(d.errors.total, 0, "{:?}", d.errors);
    assert!(d.fault.is_none());
    assert!(d.watchdog.expired_boards.is_empty());
    assert!(d.boards_not_answering.is_empty());
    assert_eq!(d.motion_cycles, 600);
    // Six nodes, one block read and one block write each with seed 001's
    // PC: about 6 x 65 us of I/O per cycle (virtual time), inside 1 ms.
    assert!(
        (300.0..600.0).contains(&d.io_time_us.median),
        "{:?}",
        d.io_time_us
    );
    for (arm, t) in &d.tracking_error_detail {
        assert!(t.samples > 0, "{arm}");
        assert!(t.rms_rad < 0.02, "{arm}: {t:?}");
    }
    assert_eq!(d.state, "configured");
}

/// Configure, power, home, move every joint and run `cycles` cycles with
/// the generic servo: the tracking per arm and the I/O errors.
fn exercise<R: RobotIo>(io: R, config: &IoConfig, cycles: u64) -> (Vec<(String, f64)>, u64) {
    let settings = RobotSettings {
        period: firelink_control::ServoPeriod::KHZ_1,
        watchdog: firelink_host::WatchdogSetting::default(),
        ..RobotSettings::default()
    };
    let mut servo = Robot::new(io, config, settings).unwrap();
    servo.configure().unwrap();
    servo.power_on().unwrap();
    servo.home().unwrap();
    servo.activate().unwrap();
    for i in 0..servo.joint_count() {
        let here = servo.position(i).unwrap();
        servo.set_motion(i, motion_for(config, i, here)).unwrap();
    }
    servo.reset_tracking();
    servo.run(cycles, Pacing::Virtual, 0, |_| {}).unwrap();
    servo.shutdown().unwrap();
    assert!(!servo.any_amp_on());
    let tracking = servo
        .tracking()
        .into_iter()
        .map(|t| (t.name, t.rms_rad))
        .collect();
    (tracking, servo.io().stats().total_errors())
}

#[test]
fn the_same_servo_drives_a_qla_rig_and_a_snake_rig() {
    // QLA: one QLA1 board, four generic motors, read and written one by one.
    let qla_config = presets::bench_1board();
    let boards = rig::board_configs(&qla_config, firelink_board::qla::config::Profile::Rev8, 1);
    let (port, _) = rig::sim_port(boards, false).unwrap();
    let (qla, _) = IoSystem::open(
        port,
        IoOptions {
            protocol: Some(Protocol::Sequential),
            ..IoOptions::default()
        },
    )
    .unwrap();
    let (qla_tracking, qla_errors) = exercise(qla, &qla_config, 800);
    // Snake: one master on one node of the seed's own system.
    let mut snake_config = presets::snake_seed001();
    snake_config.robots.retain(|r| r.name == "MASTER1");
    let port = sim_port(node_configs(&snake_config, 2).unwrap(), true, None).unwrap();
    let mut snake = SnakeSystem::open(port).unwrap();
    prepare(&mut snake, &snake_config).unwrap();
    let (snake_tracking, snake_errors) = exercise(snake, &snake_config, 800);
    for (what, tracking, errors) in [
        ("QLA", &qla_tracking, qla_errors),
        ("Snake", &snake_tracking, snake_errors),
    ] {
        assert_eq!(errors, 0, "{what}");
        assert_eq!(tracking.len(), 1, "{what}");
        let (arm, rms) = &tracking[0];
        assert!(*rms > 0.0 && *rms < 0.02, "{what} {arm}: {rms}");
    }
}

#[test]
fn a_silent_host_is_caught_by_every_node_watchdog() {
    let r = run_snake_demo(&short(DemoFault::StopHost), None, |_| {}).unwrap();
    r.verdict().unwrap();
    let f = r.demo.fault.as_ref().expect("fault detected");
    assert_eq!(f.kind, "Watchdog", "{f:?}");
    assert_eq!(r.demo.amplifiers_on_after_fault, Some(false));
    assert!(!r.demo.watchdog.expired_boards.is_empty());
}

#[test]
fn a_lost_node_is_named_and_every_amplifier_ends_off() {
    let r = run_snake_demo(&short(DemoFault::BoardLoss), None, |_| {}).unwrap();
    r.verdict().unwrap();
    let f = r.demo.fault.as_ref().expect("fault detected");
    assert_eq!((f.kind.as_str(), f.board), ("MissedBoard", Some(4)));
    assert!(f.text.contains("MASTER1"), "{}", f.text);
    assert_eq!(r.demo.boards_not_answering, [4]);
    assert_eq!(r.demo.amplifiers_on_after_fault, Some(false));
}

#[test]
fn a_following_error_trips_the_safety_monitor() {
    let r = run_snake_demo(&short(DemoFault::FollowingError), None, |_| {}).unwrap();
    r.verdict().unwrap();
    assert_eq!(r.demo.amplifiers_on_after_fault, Some(false));
}

#[test]
fn options_the_nodes_cannot_honour_are_refused() {
    let e = run_snake_demo(&short(DemoFault::CorruptQuery), None, |_| {}).unwrap_err();
    assert!(e.to_string().contains("broadcast"), "{e}");
    let qla = SnakeDemoOptions {
        config: presets::dvrk_seed000(),
        ..short(DemoFault::None)
    };
    let e = run_snake_demo(&qla, None, |_| {}).unwrap_err();
    assert!(e.to_string().contains("SNAKE"), "{e}");
    let endless = SnakeDemoOptions {
        duration_s: f64::NAN,
        ..short(DemoFault::None)
    };
    assert!(run_snake_demo(&endless, None, |_| {}).is_err());
}

#[test]
fn the_rate_search_confirms_a_rate_that_holds() {
    let options = SnakeDemoOptions {
        duration_s: 0.3,
        find_max_rate: true,
        ..SnakeDemoOptions::default()
    };
    let r = run_snake_demo(&options, None, |_| {}).unwrap();
    let m = r.max_rate.as_ref().expect("searched");
    assert!(!m.trials.is_empty());
    // I/O alone (virtual time) allows about 2.4 kHz; whatever the
    // machine's computation, every trial is reported and the one that
    // held is the answer.
    assert!(m.io_bound_hz > 1500.0 && m.io_bound_hz < 3500.0, "{m:?}");
    if m.rate_hz > 0.0 {
        let held = m.trials.iter().find(|t| t.held).unwrap();
        assert_eq!(held.rate_hz, m.rate_hz);
        assert_eq!(held.errors, 0);
        assert!(held.cycle_time_us.p99 <= 1e6 / held.rate_hz);
    }
}

#[test]
fn seed_001_measurements_are_reproduced_within_15_percent() {
    let options = Seed001Options {
        iterations: 3000,
        sweep_step: 4,
        sweep_repeats: 2,
        cycles: 200,
        seed: 7,
    };
    let r = run_seed001_bench(&options).unwrap();
    r.verdict().unwrap();
    assert_eq!(r.rows.len(), 8);
    assert_eq!(r.quadlet_read_us.len(), 3000);
    // Fig. 20: three bands of reads, two of writes, the lowest the most
    // common.
    let near = |xs: &[f32], at: f32| xs.iter().filter(|&&x| (x - at).abs() < 2.0).count();
    let reads = &r.quadlet_read_us;
    assert!(near(reads, 30.0) > near(reads, 42.0));
    assert!(near(reads, 42.0) > near(reads, 49.0));
    assert!(near(reads, 49.0) > 0);
    let writes = &r.quadlet_write_us;
    assert!(near(writes, 27.0) > near(writes, 42.0));
    assert_eq!(near(writes, 49.0), 0);
    // The same seed, the same figures.
    let again = run_seed001_bench(&options).unwrap();
    assert_eq!(again.rows, r.rows);
}

#[test]
fn snake_nodes_behind_the_udp_bridge() {
    let config = presets::snake_seed001();
    let emu = emulator(node_configs(&config, 1).unwrap()).unwrap();
    let mut port = emu.port().unwrap();
    // Behaviour, not speed: a generous time-out for a loaded machine.
    port.set_timeout(Duration::from_secs(2));
    let mut s = SnakeSystem::open(port).unwrap();
    let ids: Vec<u8> = s.nodes().iter().map(|n| n.board_id()).collect();
    assert_eq!(ids, [0, 1, 2, 3, 4, 5]);
    prepare(&mut s, &config).unwrap();
    s.set_digital_pot_wiper(3, 2, 649).unwrap();
    assert_eq!(s.digital_pot_wiper(3, 2).unwrap().value(), 649);
    s.node_mut(5)
        .unwrap()
        .set_amplifier_enable(7, true)
        .unwrap();
    s.node_mut(5).unwrap().set_motor_voltage(7, 0x8100).unwrap();
    s.apply_all_outputs();
    s.latch_all_inputs();
    assert!(s.report().all_ok(), "{:?}", s.report());
    assert!(s.node(5).unwrap().amplifier_enabled(7).unwrap());
    assert!(s.node(5).unwrap().encoder_counts(7).unwrap().abs() < 1000);
    s.set_power_control(5, firelink_wire::snake::registers::PowerControl::all(false))
        .unwrap();
    drop(s);
    emu.stop().unwrap();
}
