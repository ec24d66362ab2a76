//! The robot service: frames flow without waiting for anyone, commands run
//! between cycles and go through the lifecycle (what powers anything is
//! refused, with its reason, where the state does not allow it, and reaches
//! only the axes the joints use), each outcome carries its command's id,
//! and the loop powers down on every way out, a panic included.
//!
//! Nothing here is timed: waits are bounded only to end a hung test.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use firelink_board::qla::config::Profile;
use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, presets};
use firelink_control::lifecycle::State;
use firelink_control::runner::Pacing;
use firelink_host::sim::SimPort;
use firelink_host::{Dest, Port};
use firelink_testbed::demo::{DemoFault, PortSpec};
use firelink_testbed::dvrk::service::{
    Command, Frame, LoopOptions, MAX_ARM_JOINTS, Service, ServoApplied, ServoTrace, Shared,
};
use firelink_testbed::fault_script::FaultTarget;
use firelink_testbed::loop_outcome::{CommandOutcome, Verdict};
use firelink_testbed::rig;

/// Bounded only so that a broken build fails instead of hanging.
const HANG: Duration = Duration::from_secs(300);

/// Queue `c` with an id and wait for the outcome with that id (others,
/// and frames, are dropped on the way).
fn run(shared: &Shared, c: Command) -> CommandOutcome {
    let id = shared.submit(c).unwrap();
    let start = Instant::now();
    loop {
        while let Some(f) = shared.full.pop() {
            let _ = shared.free.push(f);
        }
        while let Some(o) = shared.outcomes.pop() {
            if o.id == id {
                assert_eq!(o.command, c.to_string());
                return o;
            }
        }
        assert!(start.elapsed() < HANG, "no outcome for {c}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The next frame the loop publishes from now on (frames queued before are
/// dropped).
fn next_frame(shared: &Shared) -> Box<Frame> {
    while let Some(f) = shared.full.pop() {
        let _ = shared.free.push(f);
    }
    let start = Instant::now();
    loop {
        if let Some(f) = shared.full.pop() {
            return f;
        }
        assert!(start.elapsed() < HANG, "no frame");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn ok(o: &CommandOutcome) {
    assert_eq!(o.result, Verdict::Ok, "{o}");
}

fn refused(o: &CommandOutcome, why: &str) {
    assert_eq!(o.result, Verdict::Refused, "{o}");
    assert!(o.detail.contains(why), "{o}: expected {why:?}");
}

/// A servo point for joints `first..first + count`: all at 0, at rest.
fn servo_at_zero(first: u16, count: u8) -> Command {
    traced_servo_at(first, count, 0.0, ServoTrace::default())
}

/// A servo point holding joints `first..first + count` at `position`, with
/// a trace the loop logs when it applies it.
fn traced_servo_at(first: u16, count: u8, position: f64, trace: ServoTrace) -> Command {
    Command::ServoJoints {
        first,
        count,
        positions: [position; MAX_ARM_JOINTS],
        velocities: [0.0; MAX_ARM_JOINTS],
        trace,
    }
}

#[test]
fn commands_drive_the_lifecycle_and_motion_waits_for_homing() {
    let service = Service::start(
        &PortSpec::SIM,
        presets::bench_1board(),
        "2ms".parse().unwrap(),
        firelink_host::WatchdogSetting::default(),
    )
    .unwrap();
    let shared = &service.shared;
    let servo = servo_at_zero(0, 1);
    refused(&run(shared, servo), "needs an active robot");
    let configured = run(shared, Command::Configure);
    ok(&configured);
    assert_eq!(configured.detail, "boards found powered off");
    ok(&run(shared, Command::PowerOn));
    ok(&run(shared, Command::Activate));
    refused(&run(shared, servo), "home first");
    refused(&run(shared, Command::Home), "disable first");
    let disabled = run(shared, Command::Disable);
    ok(&disabled);
    assert_eq!(
        disabled.detail,
        "amplifiers and motor power off on boards 0"
    );
    refused(
        &run(shared, Command::Configure),
        "cannot configure from state configured",
    );
    ok(&run(shared, Command::PowerOn));
    ok(&run(shared, Command::Home));
    ok(&run(shared, Command::Activate));
    // A successful servo point reports no outcome (its path allocates
    // nothing); it is counted as applied.
    shared.commands.push(servo).unwrap();
    let start = Instant::now();
    while shared.servo_applied.load(Ordering::Relaxed) == 0 {
        assert!(start.elapsed() < HANG);
        std::thread::sleep(Duration::from_millis(2));
    }
    refused(&run(shared, servo_at_zero(3, 4)), "do not exist");
    // Frames keep coming and say Active.
    assert_eq!(next_frame(shared).state, State::Active);
    let exit = service.stop();
    assert!(exit.is_clean(), "{exit}");
    assert_eq!(
        exit.to_string(),
        "amplifiers and motor power off on boards 0"
    );
}

/// The design property of the loop's wake-up, counted in cycles, not
/// timed, with a synthetic source on the simulated bus: a servo point
/// queued between two cycles (after cycle k was done and before the loop
/// began taking cycle k + 1's commands) is carried by the very next write
/// block, cycle k + 1's; one queued while the loop ran is carried at the
/// latest by the first cycle whose commands were taken after it was
/// queued (the loop says which, [`Shared::commands_taken_for`]). The
/// source wakes the loop after each point ([`Shared::nudge`]), as the
/// ROS 2 node does. Each applied point is logged once, with its trace.
#[test]
fn a_servo_point_queued_between_cycles_is_carried_by_the_very_next_write_block() {
    let service = Service::start(
        &PortSpec::SIM,
        presets::bench_1board(),
        ServoPeriod::KHZ_1,
        firelink_host::WatchdogSetting::default(),
    )
    .unwrap();
    let shared = &service.shared;
    for c in [
        Command::Configure,
        Command::PowerOn,
        Command::Home,
        Command::Activate,
    ] {
        ok(&run(shared, c));
    }
    // Held where homing left the joint (a jump would be a following error).
    let here = next_frame(shared).joints[0].setpoint;
    let mut between_cycles = 0;
    for n in 1..=300u64 {
        let done = shared.cycles_done.load(Ordering::SeqCst);
        let trace = ServoTrace {
            source_ns: 0,
            queued_ns: n,
            queued_after_cycle: done,
        };
        shared
            .commands
            .push(traced_servo_at(0, 1, here, trace))
            .unwrap();
        std::sync::atomic::fence(Ordering::SeqCst);
        let taking = shared.commands_taken_for.load(Ordering::SeqCst);
        shared.nudge();
        let applied = applied_point(shared, n);
        assert_eq!(applied.trace, trace, "one entry per point, in order");
        assert!(applied.applied_ns > 0);
        if taking == done {
            // Between cycles `done` and `done + 1`.
            between_cycles += 1;
            assert_eq!(applied.cycle, done + 1, "point {n}");
        } else {
            // Queued while the loop ran: after cycle `done`, by cycle
            // `taking + 1` (whose commands were taken after it was queued).
            assert!(
                (done + 1..=taking + 1).contains(&applied.cycle),
                "point {n}: queued after cycle {done}, while cycle {taking} took its \
                 commands; carried by {}",
                applied.cycle
            );
        }
    }
    assert_eq!(shared.servo_log_dropped.load(Ordering::Relaxed), 0);
    assert_eq!(shared.servo_applied.load(Ordering::Relaxed), 300);
    // (How many fell between cycles depends on the machine's timing; the
    // source mostly finds the loop asleep.)
    eprintln!("{between_cycles} of 300 points queued between cycles");
    assert!(service.stop().is_clean());
}

/// Wait until the loop logs servo point `n` as applied (frames given back
/// meanwhile); a refusal fails the test.
fn applied_point(shared: &Shared, n: u64) -> ServoApplied {
    let start = Instant::now();
    loop {
        while let Some(f) = shared.full.pop() {
            let _ = shared.free.push(f);
        }
        if let Some(a) = shared.servo_log.pop() {
            return a;
        }
        // (An applied servo point reports no outcome; a refused one does.)
        if let Some(o) = shared.outcomes.pop() {
            panic!("servo point {n}: {o}");
        }
        assert!(start.elapsed() < HANG, "servo point {n} never applied");
        std::thread::yield_now();
    }
}

/// Every amplifier of every board, as a frame shows them: (on, of).
fn amps_on(frame: &Frame) -> Vec<(u8, u8)> {
    frame
        .axes
        .iter()
        .filter(|a| a.amp)
        .map(|a| (a.board, a.axis))
        .collect()
}

/// (board ID, axis) of every joint of `config`.
fn used_axes(config: &IoConfig) -> Vec<(u8, u8)> {
    let mut used: Vec<(u8, u8)> = config
        .joints()
        .map(|j| (j.actuator.board_id, j.actuator.axis_id))
        .collect();
    used.sort_unstable();
    used
}

#[test]
fn power_commands_follow_the_lifecycle_and_reach_only_the_used_axes() {
    // Seed 000's dVRK: 8 boards of 4 axes, 28 joints; 4 axes unused.
    let config = presets::dvrk_seed000();
    let used = used_axes(&config);
    assert_eq!(used.len(), 28);
    let service = Service::start(
        &PortSpec::SIM,
        config,
        ServoPeriod::KHZ_1,
        firelink_host::WatchdogSetting::default(),
    )
    .unwrap();
    let shared = &service.shared;

    // Unconfigured: nothing may be switched on; off is always allowed.
    refused(&run(shared, Command::Amplifiers(true)), "unconfigured");
    refused(&run(shared, Command::Relay(true)), "unconfigured");
    refused(&run(shared, Command::PowerOn), "unconfigured");
    ok(&run(shared, Command::Amplifiers(false)));
    ok(&run(shared, Command::Relay(false)));
    let frame = next_frame(shared);
    assert!(amps_on(&frame).is_empty(), "{:?}", amps_on(&frame));
    assert!(frame.boards.iter().all(|b| !b.power && !b.relay));
    let _ = shared.free.push(frame);

    // Configured, no power yet: amplifiers need power; the relay may close.
    ok(&run(shared, Command::Configure));
    refused(&run(shared, Command::Amplifiers(true)), "no motor power");
    ok(&run(shared, Command::Relay(true)));
    assert!(next_frame(shared).boards.iter().all(|b| b.relay));

    // Powered, amplifiers off, then on again: only the joints' axes.
    ok(&run(shared, Command::PowerOn));
    ok(&run(shared, Command::Amplifiers(false)));
    let frame = next_frame(shared);
    assert_eq!(frame.state, State::Configured);
    assert!(frame.boards.iter().all(|b| b.power));
    assert!(amps_on(&frame).is_empty(), "{:?}", amps_on(&frame));
    let on = run(shared, Command::Amplifiers(true));
    ok(&on);
    assert!(on.detail.contains("the 28 axes the joints use"), "{on}");
    let mut shown = amps_on(&next_frame(shared));
    shown.sort_unstable();
    assert_eq!(shown, used);

    // Fault (a host that stops writing: the watchdogs expire): refused,
    // with the fault named; off still allowed.
    ok(&run(shared, Command::Inject(DemoFault::StopHost)));
    let start = Instant::now();
    while next_frame(shared).state != State::Fault {
        assert!(start.elapsed() < HANG);
    }
    refused(&run(shared, Command::Amplifiers(true)), "fault");
    refused(&run(shared, Command::Relay(true)), "fault");
    ok(&run(shared, Command::Amplifiers(false)));
    ok(&run(shared, Command::ClearFault));
    // Configure says what it did with the boards: this program powered
    // them itself, so they are not "taken over" from an earlier one.
    let again = run(shared, Command::Configure);
    ok(&again);
    assert_eq!(
        again.detail,
        "boards 0-7 kept as this program left them (not taken over)"
    );
    let exit = service.stop();
    assert!(exit.is_clean(), "{exit}");
    assert_eq!(exit.panic, None);
    assert_eq!(
        exit.to_string(),
        "amplifiers and motor power off on boards 0-7"
    );
}

/// The simulated port, but injecting a fault panics: a bug inside the
/// robot loop.
struct PanickingPort(SimPort);

impl Port for PanickingPort {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> firelink_host::Result<u32> {
        self.0.read_quadlet(dest, offset)
    }
    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> firelink_host::Result<()> {
        self.0.write_quadlet(dest, offset, value)
    }
    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> firelink_host::Result<()> {
        self.0.read_block(dest, offset, out)
    }
    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> firelink_host::Result<()> {
        self.0.write_block(dest, offset, data)
    }
    fn start_write_quadlet(
        &mut self,
        dest: Dest,
        offset: u64,
        value: u32,
    ) -> firelink_host::Result<()> {
        self.0.start_write_quadlet(dest, offset, value)
    }
    fn start_write_block(
        &mut self,
        dest: Dest,
        offset: u64,
        data: &[u8],
    ) -> firelink_host::Result<()> {
        self.0.start_write_block(dest, offset, data)
    }
    fn wait(&mut self, duration: Duration) {
        self.0.wait(duration);
    }
    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        self.0.wait_until_heard(limit, heard)
    }
    fn now(&self) -> Duration {
        self.0.now()
    }
    fn now_ps(&self) -> u64 {
        self.0.now_ps()
    }
    fn generation(&self) -> u32 {
        self.0.generation()
    }
    fn acknowledges_writes(&self) -> bool {
        self.0.acknowledges_writes()
    }
    fn link_stats(&self) -> firelink_host::link_stats::LinkStats {
        self.0.link_stats()
    }
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.0.candidate_nodes()
    }
    /// The injected corrupt query's link filter is where the loop's bug
    /// is.
    fn add_link_filter(
        &mut self,
        _: Box<dyn firelink_host::port::LinkFilter>,
    ) -> firelink_host::Result<()> {
        panic!("a bug in the robot loop");
    }
    // It says it takes filters, so that the fault target hands it one.
    fn takes_link_filters(&self) -> bool {
        true
    }
}

#[test]
fn a_panic_in_the_loop_powers_down_and_is_reported() {
    let config = presets::bench_1board();
    let boards = rig::board_configs(&config, Profile::Rev8, config.board_slots());
    let (port, _) = rig::sim_port(boards, false).unwrap();
    let service = Service::on_port(
        PanickingPort(port),
        "sim".into(),
        LoopOptions {
            config,
            period: "500Hz".parse().unwrap(),
            watchdog: firelink_host::WatchdogSetting::default(),
            pacing: Pacing::Virtual,
            faults: FaultTarget::link(),
        },
    )
    .unwrap();
    let shared = &service.shared;
    ok(&run(shared, Command::Configure));
    ok(&run(shared, Command::PowerOn));
    assert!(next_frame(shared).boards.iter().all(|b| b.power));
    // The panicking command gets no outcome of its own; the loop ends.
    let id = shared
        .submit(Command::Inject(DemoFault::CorruptQuery))
        .unwrap();
    let start = Instant::now();
    let exit = loop {
        if let Some(exit) = shared.exit.get() {
            break exit.clone();
        }
        assert!(start.elapsed() < HANG);
        std::thread::sleep(Duration::from_millis(2));
    };
    assert_eq!(exit.panic.as_deref(), Some("a bug in the robot loop"));
    assert!(exit.power_down.is_some_and(|p| p.all_off()), "{exit}");
    assert!(
        exit.to_string()
            .starts_with("the robot loop panicked (a bug in the robot loop); amplifiers and motor power off on boards 0"),
        "{exit}"
    );
    // The last frame shows the boards powered down.
    let mut last = None;
    while let Some(f) = shared.full.pop() {
        last = Some(f);
    }
    assert!(last.unwrap().boards.iter().all(|b| !b.power));
    // A command queued after the end is answered, not left waiting: the
    // loop is gone, so nothing takes it (the consumer sees `exit`).
    assert!(
        shared.outcomes.pop().is_none_or(|o| o.id != id),
        "the panicking command has no outcome"
    );
    let stopped = service.stop();
    assert_eq!(stopped, exit);
}
