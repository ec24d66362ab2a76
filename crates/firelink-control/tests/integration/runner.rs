//! The runner over emulated boards on the simulated bus (`common::port`),
//! in virtual time: lifecycle, tracking, and every safety path.

use crate::common;

use std::time::Duration;

use firelink_control::config::presets;
use firelink_control::runner::{Pacing, Robot, RobotSettings, RunnerError};
use firelink_control::trajectory::{Motion, Sinusoid};
use firelink_control::{FaultKind, LifecycleError, ServoPeriod, State};
use firelink_host::Port;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::sim::SimPort;

/// Joints start inside their soft limits and away from the encoders'
/// zero, so homing matters.
fn start(i: usize) -> f64 {
    let config = presets::dvrk_seed000();
    let j = config.joints().nth(i).unwrap();
    let l = j.actuator.encoder.position_limits_soft;
    0.5 * (l.lower + l.upper) + 0.1 * l.span() * ((i % 5) as f64 - 2.0) / 2.0
}

fn robot(protocol: Protocol, rate: f64) -> Robot<IoSystem<SimPort>> {
    robot_on(protocol, rate, false)
}

/// `seed_000`: seed 000's own boards (they answer a corrupt query with
/// sequence 0xFFFF); otherwise Rev 8 boards.
fn robot_on(protocol: Protocol, rate: f64, seed_000: bool) -> Robot<IoSystem<SimPort>> {
    let config = presets::dvrk_seed000();
    let port = common::port(&config, seed_000, start);
    let (io, scan) = IoSystem::open(
        port,
        IoOptions {
            protocol: Some(protocol),
            ..IoOptions::default()
        },
    )
    .unwrap();
    assert_eq!(scan.boards.len(), 8);
    Robot::new(
        io,
        &config,
        RobotSettings {
            period: ServoPeriod::from_rate_hz(rate).unwrap(),
            ..RobotSettings::default()
        },
    )
    .unwrap()
}

fn active(protocol: Protocol) -> Robot<IoSystem<SimPort>> {
    active_on(protocol, false)
}

fn active_on(protocol: Protocol, seed_000: bool) -> Robot<IoSystem<SimPort>> {
    let mut r = robot_on(protocol, 2000.0, seed_000);
    r.configure().unwrap();
    r.power_on().unwrap();
    r.home().unwrap();
    r.activate().unwrap();
    assert_eq!(r.state(), State::Active);
    r
}

#[test]
fn motion_is_refused_unless_active() {
    let mut r = robot(Protocol::Broadcast, 1000.0);
    let refused = |r: &mut Robot<IoSystem<SimPort>>| {
        matches!(
            r.set_motion(0, Motion::Hold(0.1)),
            Err(RunnerError::Lifecycle(LifecycleError::NotActive { .. }))
        )
    };
    assert!(refused(&mut r));
    r.configure().unwrap();
    assert!(refused(&mut r));
    // Activation without power is refused too.
    assert!(matches!(
        r.activate(),
        Err(RunnerError::Lifecycle(LifecycleError::NotPowered { .. }))
    ));
    r.power_on().unwrap();
    assert!(refused(&mut r));
    r.home().unwrap();
    r.activate().unwrap();
    assert!(r.set_motion(0, Motion::Hold(0.0)).is_ok());
    r.shutdown().unwrap();
    assert_eq!(r.state(), State::Configured);
    assert!(refused(&mut r));
    assert!(!r.any_amp_on());
}

#[test]
fn homing_finds_the_joint_positions() {
    let r = active(Protocol::Broadcast);
    let config = presets::dvrk_seed000();
    for (i, j) in config.joints().enumerate() {
        let p = r.position(i).unwrap();
        // Where the joint really is: it started at `start(i)`, and a
        // joint its load pulls on may have moved before the amplifiers
        // held it.
        let truth = common::board(r.io().port(), j.actuator.board_id)
            .plant()
            .axis(usize::from(j.actuator.axis_id))
            .unwrap()
            .joint_position();
        // Pots are 16-bit over twice the range: a few mrad (or um).
        assert!((p - truth).abs() < 5e-3, "joint {i}: {p} vs {truth}");
    }
}

/// Right after activation, before any cycle, every joint's setpoint is
/// where it holds (its homed position), so a move planned from the
/// setpoint starts where the joint is: no step (a stale setpoint from
/// before homing stepped the first move and tripped the velocity or
/// following-error check).
#[test]
fn the_setpoint_after_activation_is_the_held_position() {
    let r = active(Protocol::Broadcast);
    for i in 0..r.joint_count() {
        let (p, sp) = (r.position(i).unwrap(), r.setpoint(i).unwrap());
        assert_eq!(sp, p, "joint {i}");
        // Away from the encoders' zero: the check means something.
        assert!(p != 0.0, "joint {i}");
    }
}

/// Tolerance: RMS tracking error below 0.01 rad (revolute) and 1 mm
/// (prismatic) for 0.1 rad / 10 mm, 0.5 Hz sinusoids at 2 kHz.
#[test]
fn pid_tracks_sinusoids_in_virtual_time() {
    for protocol in [Protocol::Broadcast, Protocol::Sequential] {
        let mut r = active(protocol);
        let n = r.joint_count();
        for i in 0..n {
            let p = r.position(i).unwrap();
            let prismatic = i >= 14 && i % 7 == 2;
            let amp = if prismatic { 0.01 } else { 0.1 };
            let s = Sinusoid::new(amp, 0.5, 0.0, p, 0.5).unwrap();
            r.set_motion(i, Motion::Sinusoid(s)).unwrap();
        }
        r.reset_tracking();
        r.run(4000, Pacing::Virtual, 0, |_| {}).unwrap();
        assert!((r.now() - 2.0).abs() < 0.3, "virtual time {}", r.now());
        for arm in r.tracking() {
            assert!(arm.samples > 0);
            assert!(arm.rms_rad < 0.01, "{protocol:?} {}: {arm:?}", arm.name);
            assert!(arm.rms_mm < 1.0, "{protocol:?} {}: {arm:?}", arm.name);
        }
        assert_eq!(r.io_stats().total_errors(), 0);
        assert!(r.fault().is_none());
    }
}

#[test]
fn stopped_host_trips_the_watchdog() {
    let mut r = active(Protocol::Broadcast);
    r.run(100, Pacing::Virtual, 0, |_| {}).unwrap();
    // The host stops for 50 ms (watchdog 20 ms).
    common::stop_host(r.io_mut().port_mut(), Duration::from_millis(50));
    for id in 0..8 {
        assert!(common::watchdog_expired(r.io().port(), id));
        assert!(!common::any_amp_on(r.io().port(), id));
    }
    let e = r.step(Pacing::Virtual).unwrap_err();
    let RunnerError::Fault(f) = e else {
        panic!("{e:?}")
    };
    assert!(matches!(f.kind, FaultKind::Watchdog { .. }), "{f}");
    assert_eq!(r.state(), State::Fault);
    assert!(!r.any_amp_on());
}

#[test]
fn corrupt_query_is_detected_and_amps_go_off() {
    let mut r = active_on(Protocol::Broadcast, true);
    r.run(50, Pacing::Virtual, 0, |_| {}).unwrap();
    common::corrupt_next_query(r.io_mut().port_mut());
    let RunnerError::Fault(f) = r.step(Pacing::Virtual).unwrap_err() else {
        panic!()
    };
    assert!(
        matches!(
            f.kind,
            FaultKind::Sequence {
                received: 0xFFFF,
                ..
            }
        ),
        "{f}"
    );
    assert!(r.io_stats().corrupt_queries > 0);
    // The faulting cycle already wrote amplifiers off.
    for id in 0..8 {
        assert!(!common::any_amp_on(r.io().port(), id), "board {id}");
    }
    let _ = r.step(Pacing::Virtual);
    assert!(!r.any_amp_on());
}

#[test]
fn board_loss_stops_safely_naming_the_board() {
    for protocol in [Protocol::Broadcast, Protocol::Sequential] {
        let mut r = active(protocol);
        r.run(50, Pacing::Virtual, 0, |_| {}).unwrap();
        common::lose_board(r.io_mut().port_mut(), 5);
        let RunnerError::Fault(f) = r.step(Pacing::Virtual).unwrap_err() else {
            panic!()
        };
        match f.kind {
            FaultKind::MissedBoard { board_id, robot } => {
                assert_eq!(board_id, 5);
                assert_eq!(robot.as_str(), "PSM1");
            }
            k => panic!("{protocol:?}: {k:?}"),
        }
        for id in [0, 1, 2, 3, 4, 6, 7] {
            assert!(!common::any_amp_on(r.io().port(), id), "board {id}");
        }
    }
}

#[test]
fn following_error_excess_trips() {
    let mut r = active(Protocol::Broadcast);
    r.run(20, Pacing::Virtual, 0, |_| {}).unwrap();
    // MTML joint 1 is blocked, then asked to move by 0.5 rad (limit
    // 0.35 rad, 50 ms grace).
    common::block_axis(r.io_mut().port_mut(), 0, 0);
    r.step_setpoint(0, 0.5).unwrap();
    let e = r.run(2000, Pacing::Virtual, 0, |_| {}).unwrap_err();
    let RunnerError::Fault(f) = e else { panic!() };
    assert!(matches!(f.kind, FaultKind::FollowingError { .. }), "{f}");
    assert!(!r.any_amp_on() || r.step(Pacing::Virtual).is_err());
    let _ = r.step(Pacing::Virtual);
    assert!(!r.any_amp_on());
}

#[test]
fn configuration_errors() {
    // The dVRK configuration against a single bench board.
    let bench = presets::bench_1board();
    let port = common::port(&bench, false, |_| 0.0);
    let (io, _) = IoSystem::open(port, IoOptions::default()).unwrap();
    let e = Robot::new(io, &presets::dvrk_seed000(), RobotSettings::default())
        .err()
        .unwrap();
    assert!(
        matches!(e, RunnerError::Config(ref m) if m.contains("not on the bus")),
        "{e}"
    );
    // A zero rate cannot even be said.
    assert!(ServoPeriod::from_rate_hz(0.0).is_err());
}

/// A late cycle (the host stalled for several periods, in virtual time)
/// does not distort the velocity estimate: the runner divides by the
/// measured span of its window, not by a nominal period. The estimate is a
/// filtered average of window averages, so it can never exceed the fastest
/// step the joint actually made; dividing by the last period times the
/// window (what the runner did) broke that bound by 11/8 after a 4-period
/// stall.
#[test]
fn late_cycles_do_not_inflate_the_velocity_estimate() {
    let mut robot = active(Protocol::Broadcast);
    let period = robot.period();
    let n = robot.joint_count();
    for i in 0..n {
        let p = robot.position(i).unwrap();
        let s = Sinusoid::new(0.01, 1.0, 0.0, p, 0.0).unwrap();
        robot.set_motion(i, Motion::Sinusoid(s)).unwrap();
    }
    let mut fastest = vec![0.0f64; n];
    let mut last: Vec<(f64, f64)> = (0..n)
        .map(|i| (robot.now(), robot.position(i).unwrap()))
        .collect();
    for k in 0..1500 {
        // After warm-up, every fifth cycle starts 4 periods late.
        if k >= 1200 && k % 5 == 0 {
            let stall = Duration::from_secs_f64(4.0 * period);
            robot.io_mut().port_mut().wait(stall);
        }
        robot.step(Pacing::Virtual).unwrap();
        let now = robot.now();
        for i in 0..n {
            let p = robot.position(i).unwrap();
            let (t0, p0) = last[i];
            if now > t0 {
                fastest[i] = fastest[i].max(((p - p0) / (now - t0)).abs());
            }
            last[i] = (now, p);
            let v = robot.velocity(i).unwrap();
            assert!(
                v.abs() <= 1.02 * fastest[i] + 1e-9,
                "cycle {k} joint {i}: estimate {v} beyond the fastest step {}",
                fastest[i]
            );
        }
    }
}

#[test]
fn a_stop_search_without_a_stop_fails_and_leaves_the_checks_on() {
    // No mechanical stop within the search's travel (the MTM roll's stops
    // are more than a turn away): a stop search runs its whole travel and
    // says so; the joint's checks are back on after.
    let mut config = presets::dvrk_seed000();
    let roll = &mut config.robots[1].actuators[6];
    let soft = roll.encoder.position_limits_soft;
    let mut sim = roll.simulation.unwrap();
    let mut homing = sim.homing.unwrap();
    homing.stop_search = Some(firelink_control::config::StopSearchConfig {
        side: firelink_control::config::StopSide::Lower,
        velocity: 2.0,
        acceleration: 8.0,
        stall_error: 0.5,
        stop_position: soft.lower - 0.1,
        max_travel: 1.0,
    });
    sim.homing = Some(homing);
    roll.simulation = Some(sim);
    let port = common::port(&config, false, start);
    let (io, _) = IoSystem::open(port, IoOptions::default()).unwrap();
    let mut r = Robot::new(io, &config, RobotSettings::default()).unwrap();
    let roll = 13;
    assert_eq!(r.stop_search_joints().collect::<Vec<_>>(), [roll]);
    // Not before Active.
    assert!(matches!(
        r.search_stop(roll),
        Err(RunnerError::Lifecycle(LifecycleError::NotActive { .. }))
    ));
    r.configure().unwrap();
    r.power_on().unwrap();
    r.home().unwrap();
    r.activate().unwrap();
    assert!(matches!(
        r.search_stop(0),
        Err(RunnerError::StopSearch {
            problem: firelink_control::runner::StopSearchProblem::NotConfigured,
            ..
        })
    ));
    let before = r.position(roll).unwrap();
    let e = r.search_stop(roll).unwrap_err();
    assert!(
        matches!(
            e,
            RunnerError::StopSearch {
                problem: firelink_control::runner::StopSearchProblem::NoStop { .. },
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string().contains("MTMR[6]: stop search: no stop"),
        "{e}"
    );
    // It travelled the whole way and is still Active, holding.
    assert!((r.position(roll).unwrap() - (before - 1.0)).abs() < 0.05);
    assert_eq!(r.state(), State::Active);
    // The following-error check is back: a setpoint jump faults.
    r.step_setpoint(roll, 1.0).unwrap();
    let faulted = (0..2000).any(|_| r.step(Pacing::Virtual).is_err());
    assert!(faulted);
    assert!(matches!(
        r.fault().map(|f| f.kind),
        Some(FaultKind::FollowingError { .. })
    ));
}

/// Before homing the encoders count from wherever the boards started, so
/// the safety monitor does not compare them with the pots: a robot
/// activated unhomed (the joints away from the encoders' zero) holds for
/// a whole second without a pot mismatch. Before, it faulted once its
/// latency had passed, so whether the service's lifecycle test faulted
/// depended on how long its thread took between two commands.
#[test]
fn an_unhomed_robot_is_not_faulted_for_pots_its_encoders_were_never_biased_from() {
    let mut r = robot(Protocol::Broadcast, 2000.0);
    r.configure().unwrap();
    r.power_on().unwrap();
    r.activate().unwrap();
    for _ in 0..2000 {
        r.step(Pacing::Virtual).unwrap();
    }
    assert_eq!(r.state(), State::Active);
    // Encoder and pot do disagree: the check would have fired.
    let disagree = (0..r.joint_count()).any(|i| {
        let (p, pot) = (
            r.position(i).unwrap(),
            r.potentiometer(i).unwrap_or(f64::NAN),
        );
        (p - pot).abs() > 0.1
    });
    assert!(
        disagree,
        "no joint's encoder and pot disagree: the test shows nothing"
    );
}
