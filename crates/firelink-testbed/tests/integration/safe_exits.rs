//! The one power-down rule, driven through every way a robot program can
//! end, with the boards read afterwards by a second client.
//!
//! Each test runs emulated boards behind an in-process `firelink emulate`
//! on loopback UDP (wall-clock paced, as real boards are), drives them with
//! a robot program, ends that program one way (normal return, error
//! return, a stop request, a panic, a crash that powers nothing down), and
//! then opens a *second* UDP client to the same boards and reads what they
//! say. Nothing here depends on timing: waits are bounded polls of board
//! state, and the watchdogs are long (300 ms) so a loaded machine cannot
//! trip them.

use std::time::{Duration, Instant};

use firelink_board::qla::config::Profile;
use firelink_control::config::{IoConfig, presets};
use firelink_control::lifecycle::State;
use firelink_control::runner::{Robot, RobotSettings, RunnerError};
use firelink_host::WatchdogSetting;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::ScanReport;
use firelink_host::stop::{StopReason, StopRequest};
use firelink_host::udp::UdpPort;
use firelink_testbed::TestbedError;
use firelink_testbed::demo::{DemoProgress, PortSpec};
use firelink_testbed::dvrk::demo::{DemoOptions, run_demo_until};
use firelink_testbed::rig::{self, Emulator};

/// The bench robot: one QLA board, four gentle axes.
fn config() -> IoConfig {
    presets::bench_1board()
}

fn emulator(config: &IoConfig) -> Emulator {
    let emu = Emulator::start(rig::board_configs(
        config,
        Profile::Rev8,
        config.board_slots(),
    ))
    .expect("emulator");
    // Scan now, while nothing runs (see `second_client`).
    let _ = scan_of(&emu);
    emu
}

/// A UDP port with a generous time-out: a loaded machine must not turn a
/// slow answer into a fault these tests are not about.
fn port(emu: &Emulator) -> UdpPort {
    let mut p = emu.port().expect("port");
    p.set_timeout(Duration::from_millis(500));
    p
}

fn settings() -> RobotSettings {
    RobotSettings {
        watchdog: WatchdogSetting::from_ms(300.0).expect("300 ms"),
        ..RobotSettings::default()
    }
}

fn robot(emu: &Emulator, config: &IoConfig) -> Robot<IoSystem<UdpPort>> {
    let io = IoSystem::with_scan(port(emu), &scan_of(emu), IoOptions::default()).expect("boards");
    Robot::new(io, config, settings()).expect("robot")
}

/// What a second client reads of every board: (board ID, motor power on,
/// amplifiers on (bit per axis), watchdog timed out, watchdog ticks).
#[derive(Debug)]
struct Seen {
    id: u8,
    powered: bool,
    amplifiers: u32,
    watchdog_timed_out: bool,
}

/// The second client: one read cycle over the boards a scan found before
/// the test began (a scan waits out every absent node ID, longer than a
/// watchdog period: reading later must take one cycle, not a scan).
fn second_client(emu: &Emulator) -> Vec<Seen> {
    let mut io =
        IoSystem::with_scan(port(emu), &scan_of(emu), IoOptions::default()).expect("second client");
    io.read_all();
    let seen = io
        .boards()
        .iter()
        .map(|b| Seen {
            id: b.board_id(),
            powered: b.power_enabled(),
            amplifiers: (0..b.axes())
                .filter(|&a| b.amp_enabled(a))
                .fold(0, |m, a| m | 1 << a),
            watchdog_timed_out: b.watchdog_expired(),
        })
        .collect();
    // This client energised nothing: dropping it writes nothing.
    assert_eq!(io.energised(), 0);
    seen
}

/// The boards behind `emu`, scanned once per emulator.
fn scan_of(emu: &Emulator) -> ScanReport {
    static SCANS: std::sync::Mutex<Vec<(std::net::SocketAddr, ScanReport)>> =
        std::sync::Mutex::new(Vec::new());
    let known = SCANS
        .lock()
        .expect("scans")
        .iter()
        .find(|(a, _)| *a == emu.addr)
        .map(|(_, s)| s.clone());
    known.unwrap_or_else(|| {
        let config = config();
        let boards = rig::board_configs(&config, Profile::Rev8, config.board_slots()).len();
        let scan = crate::rescan::until_all_found(&mut port(emu), boards);
        SCANS.lock().expect("scans").push((emu.addr, scan.clone()));
        scan
    })
}

fn assert_all_off(seen: &[Seen]) {
    assert!(!seen.is_empty());
    for b in seen {
        assert!(
            !b.powered && b.amplifiers == 0,
            "board {} left energised: {b:?}",
            b.id
        );
    }
}

/// Power on, as every program here does first; the second client sees it.
fn power_on(robot: &mut Robot<IoSystem<UdpPort>>, emu: &Emulator) {
    let left = robot.configure().expect("configure");
    assert!(left.is_clean(), "{left}");
    robot.power_on().expect("power on");
    let seen = second_client(emu);
    assert!(
        seen.iter().all(|b| b.powered && b.amplifiers != 0),
        "{seen:?}"
    );
}

#[test]
fn a_normal_end_powers_the_robot_down() {
    let config = config();
    let emu = emulator(&config);
    let mut robot = robot(&emu, &config);
    power_on(&mut robot, &emu);
    robot.home().expect("home");
    robot.activate().expect("activate");
    let done = robot.shutdown().expect("shutdown");
    assert!(done.all_off(), "{done}");
    assert_eq!(done.off, 0b1);
    assert_eq!(robot.state(), State::Configured);
    assert_all_off(&second_client(&emu));
}

#[test]
fn an_error_return_without_a_shutdown_powers_the_robot_down() {
    let config = config();
    let emu = emulator(&config);
    {
        let mut robot = robot(&emu, &config);
        power_on(&mut robot, &emu);
        // The program gives up with `?` (as `bring_up` used to): no
        // shutdown call. Dropping the I/O system is the backstop.
        let stop = StopRequest::new();
        robot.set_stop_request(stop.clone());
        stop.request();
        let err = robot.home().expect_err("stopped");
        assert!(
            matches!(err, RunnerError::Stopped(StopReason::Caller)),
            "{err}"
        );
    }
    assert_all_off(&second_client(&emu));
}

#[test]
fn a_panic_after_power_on_powers_the_robot_down() {
    let config = config();
    let emu = emulator(&config);
    let addr = emu.addr;
    let scan = scan_of(&emu);
    let thread_config = config.clone();
    let panicked = std::thread::spawn(move || {
        let mut p = UdpPort::open(addr).expect("port");
        p.set_timeout(Duration::from_millis(500));
        let io = IoSystem::with_scan(p, &scan, IoOptions::default()).expect("boards");
        let mut robot = Robot::new(io, &thread_config, settings()).expect("robot");
        robot.configure().expect("configure");
        robot.power_on().expect("power on");
        panic!("a bug in the robot program, with the robot powered");
    })
    .join();
    assert!(panicked.is_err(), "the thread panicked");
    assert_all_off(&second_client(&emu));
}

#[test]
fn a_stop_request_during_bring_up_ends_the_demo_powered_down() {
    let config = config();
    let emu = emulator(&config);
    let stop = StopRequest::new();
    let asks = stop.clone();
    let options = DemoOptions {
        config: config.clone(),
        period: firelink_control::ServoPeriod::KHZ_1,
        duration_s: 60.0,
        port: PortSpec::Udp(emu.addr),
        watchdog: WatchdogSetting::from_ms(300.0).expect("300 ms"),
        ..DemoOptions::default()
    };
    // As SIGTERM would, the moment power is on (homing comes next).
    let err = run_demo_until(&options, &stop, None, |event| {
        if matches!(event, DemoProgress::Powered(_)) {
            asks.request();
        }
    })
    .expect_err("stopped");
    assert_eq!(err.stopped_by(), Some(StopReason::Caller), "{err}");
    let TestbedError::PoweredDown { power_down, .. } = &err else {
        panic!("not powered down: {err}");
    };
    assert!(power_down.all_off(), "{power_down}");
    assert!(
        err.to_string()
            .contains("then powered down: amplifiers and motor power off on boards 0"),
        "{err}"
    );
    assert_all_off(&second_client(&emu));
}

#[test]
fn a_watchdog_turned_off_is_set_running_again_by_the_power_down() {
    let config = config();
    let emu = emulator(&config);
    let mut robot = robot(&emu, &config);
    power_on(&mut robot, &emu);
    robot
        .io_mut()
        .set_watchdog(WatchdogSetting::Off)
        .expect("watchdog off");
    let done = robot.shutdown().expect("shutdown");
    assert!(done.watchdog_restored, "{done}");
    assert!(done.to_string().contains("watchdog set back"), "{done}");
    let mut p = port(&emu);
    let ticks = firelink_host::Port::read_quadlet(&mut p, firelink_host::Dest::node(0), 3)
        .expect("watchdog register");
    assert_eq!(ticks & 0xFFFF, 3840, "20 ms, the default period");
}

/// Wait (bounded) until the second client sees every board's watchdog
/// timed out: the boards' own clock, not a sleep of a guessed length.
fn wait_for_watchdog(emu: &Emulator) -> Vec<Seen> {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        // Reading writes the broadcast query, which refreshes the
        // watchdog: look at the status registers alone.
        let mut p = port(emu);
        let status = firelink_host::Port::read_quadlet(&mut p, firelink_host::Dest::node(0), 0)
            .expect("status");
        if status & (1 << 23) != 0 {
            return second_client(emu);
        }
        assert!(Instant::now() < deadline, "the watchdog never fired");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_new_session_takes_over_boards_a_crashed_one_left_powered() {
    let config = config();
    let emu = emulator(&config);
    {
        let mut crashed = robot(&emu, &config);
        power_on(&mut crashed, &emu);
        // A crash (kill -9): nothing runs on the way out.
        crashed.io_mut().clear_energised();
    }
    // The boards' watchdog turns the amplifiers off and latches its flag;
    // motor power stays on, as on real boards.
    let seen = wait_for_watchdog(&emu);
    assert!(
        seen.iter()
            .all(|b| b.powered && b.amplifiers == 0 && b.watchdog_timed_out),
        "{seen:?}"
    );
    let mut next = robot(&emu, &config);
    let left = next.configure().expect("the next session configures");
    assert_eq!(left.powered, 0b1, "{left}");
    assert_eq!(left.watchdog_timed_out, 0b1, "{left}");
    let done = left.powered_down.expect("it powered the boards down");
    assert!(done.all_off(), "{done}");
    let text = left.to_string();
    assert!(
        text.contains("motor power on at boards 0")
            && text.contains("watchdog timed out at boards 0")
            && text.contains("left by an earlier program"),
        "{text}"
    );
    assert_eq!(next.found_at_configure(), Some(&left));
    // From power off, power-on clears the flag (the firmware's way) and the
    // robot runs: before, the latched flag was a fault on the first cycle.
    next.power_on().expect("power on after a crashed session");
    next.home().expect("home");
    next.activate().expect("activate");
    assert_eq!(next.state(), State::Active);
    next.run(50, firelink_control::runner::Pacing::Virtual, 0, |_| {})
        .expect("runs");
    assert!(next.shutdown().expect("shutdown").all_off());
    assert_all_off(&second_client(&emu));
}
