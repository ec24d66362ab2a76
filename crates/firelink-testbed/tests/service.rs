//! The robot service: frames flow without waiting for anyone, commands run
//! between cycles, motion is refused until the robot is active and homed.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use firelink_control::config::presets;
use firelink_control::lifecycle::State;
use firelink_testbed::demo::DemoPort;
use firelink_testbed::service::{Command, CommandOutcome, MAX_ARM_JOINTS, Service, Shared};

/// Wait (bounded, generously) for the outcome of the next command.
fn outcome(shared: &Shared) -> CommandOutcome {
    let start = Instant::now();
    loop {
        while let Some(f) = shared.full.pop() {
            let _ = shared.free.push(f);
        }
        if let Some(o) = shared.outcomes.pop() {
            return o;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "no outcome");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn run(shared: &Shared, c: Command) -> CommandOutcome {
    shared.commands.push(c).unwrap();
    outcome(shared)
}

/// A servo point for joints `first..first + count`: all at 0, at rest.
fn servo_at_zero(first: u16, count: u8) -> Command {
    Command::ServoJoints {
        first,
        count,
        positions: [0.0; MAX_ARM_JOINTS],
        velocities: [0.0; MAX_ARM_JOINTS],
        stamp_ns: 0,
    }
}

#[test]
fn commands_drive_the_lifecycle_and_motion_waits_for_homing() {
    let service = Service::start(
        &DemoPort::Sim,
        presets::bench_1board(),
        500.0,
        firelink_host::WatchdogSetting::default(),
    )
    .unwrap();
    let shared = &service.shared;
    let servo = servo_at_zero(0, 1);
    assert!(run(shared, servo).result.contains("not active"));
    assert_eq!(run(shared, Command::Configure).result, "ok");
    assert_eq!(run(shared, Command::PowerOn).result, "ok");
    assert_eq!(run(shared, Command::Activate).result, "ok");
    assert!(run(shared, servo).result.contains("not homed"));
    assert_eq!(run(shared, Command::Disable).result, "ok");
    assert!(
        run(shared, Command::Configure)
            .result
            .contains("lifecycle: cannot configure from state")
    );
    assert_eq!(run(shared, Command::PowerOn).result, "ok");
    assert_eq!(run(shared, Command::Home).result, "ok");
    assert_eq!(run(shared, Command::Activate).result, "ok");
    // A successful servo point reports no outcome (its path allocates
    // nothing); it is counted as applied.
    shared.commands.push(servo).unwrap();
    let start = Instant::now();
    while shared.servo_applied.load(Ordering::Relaxed) == 0 {
        assert!(start.elapsed() < Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(2));
    }
    let bad = servo_at_zero(3, 4);
    assert!(run(shared, bad).result.contains("do not exist"));
    // Frames keep coming and say Active.
    let start = Instant::now();
    let state = loop {
        if let Some(f) = shared.full.pop() {
            let s = f.state;
            let _ = shared.free.push(f);
            break s;
        }
        assert!(start.elapsed() < Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(2));
    };
    assert_eq!(state, State::Active);
    service.stop();
}
