//! Faults as a plan ([`firelink_testbed::fault_script`]): one script, read
//! from its text, turned by the rig into the simulated bus's fault plan,
//! and into a link filter on the host's UDP port to an in-process
//! `firelink emulate` on loopback.
//!
//! Nothing here depends on timing: the UDP tests use a long watchdog
//! (300 ms) and port time-out (500 ms), so a loaded machine cannot turn a
//! slow answer into a fault these tests are not about, and they wait for
//! board state by bounded polls; the demo's runs over UDP keep the host's
//! virtual time on both sides ([`HostClock`]), so no delay of either
//! thread reaches the boards' plants.

use std::time::{Duration, Instant};

use firelink_board::qla::config::Profile;
use firelink_board::qla::node::BoardNode;
use firelink_bus::SimDuration;
use firelink_control::config::{IoConfig, presets};
use firelink_control::fault::FaultKind;
use firelink_control::runner::{Pacing, Robot, RobotSettings, RunnerError};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::UdpPort;
use firelink_host::{Dest, Port, WatchdogSetting};
use firelink_testbed::fault_script::{FaultScript, ScriptFilter};
use firelink_testbed::rig::{self, Emulator, HostClock, HostClockedPort, RigBuilder};

/// The stock MTMR: two QLA1 boards.
fn config() -> IoConfig {
    presets::stock_mtmr()
}

/// The boards `config` uses (no empty slots), in board-ID order.
fn used_boards(config: &IoConfig) -> Vec<firelink_board::qla::config::BoardConfig> {
    let used: Vec<u8> = config.boards().iter().map(|b| b.board_id).collect();
    rig::board_configs(config, Profile::Rev8, config.board_slots())
        .into_iter()
        .filter(|b| used.contains(&b.board_id))
        .collect()
}

/// The board the tests lose: the MTMR's second, the last in the chain.
fn lost_board(config: &IoConfig) -> u8 {
    let ids: Vec<u8> = used_boards(config).iter().map(|b| b.board_id).collect();
    assert_eq!(ids.len(), 2, "{ids:?}");
    ids[1]
}

fn settings() -> RobotSettings {
    RobotSettings {
        watchdog: WatchdogSetting::from_ms(300.0).expect("300 ms"),
        ..RobotSettings::default()
    }
}

/// Configure, power on, home and activate.
fn bring_up<P: Port>(robot: &mut Robot<IoSystem<P>>) {
    let left = robot.configure().expect("configure");
    assert!(left.is_clean(), "{left}");
    robot.power_on().expect("power on");
    robot.home().expect("home");
    robot.activate().expect("activate");
}

/// Run until the first fault (at most `cycles`): the board it names.
fn missed_board<P: Port>(robot: &mut Robot<IoSystem<P>>, cycles: u64, pacing: Pacing) -> u8 {
    match robot.run(cycles, pacing, 0, |_| {}) {
        Err(RunnerError::Fault(f)) => match f.kind {
            FaultKind::MissedBoard { board_id, .. } => board_id,
            other => panic!("another fault: {other:?}"),
        },
        other => panic!("no fault in {cycles} cycles: {other:?}"),
    }
}

#[test]
fn a_board_lost_by_id_on_sim_ends_with_every_amplifier_off_and_the_board_named() {
    let config = config();
    let lost = lost_board(&config);
    // Named by ID, found by the rig.
    let script: FaultScript = format!("mute@t=0us:id={lost}").parse().unwrap();
    let mut built = RigBuilder::qla(used_boards(&config))
        .fault_script(&script)
        .build()
        .unwrap();
    let fault_at = SimDuration::from_millis(20_000);
    built.schedule_pending(fault_at);
    let nodes = built.boards.clone();
    let io = IoSystem::open(built.sim_port(), IoOptions::default())
        .unwrap()
        .0;
    let mut robot = Robot::new(io, &config, settings()).unwrap();
    bring_up(&mut robot);
    assert!(
        robot.io().port().now() < Duration::from_secs(20),
        "the fault moment must come after the bring-up"
    );
    assert_eq!(missed_board(&mut robot, 40_000, Pacing::Virtual), lost);
    // Twice the watchdog: the answering board is switched off by the
    // host, the lost one by its own watchdog.
    for _ in 0..600 {
        let _ = robot.step(Pacing::Virtual);
    }
    assert!(!robot.any_amp_on());
    // A board's firmware catches up with time when it hears a packet;
    // the lost one hears nothing: bring it to now, as a real one is.
    let bus = robot.io_mut().port_mut().bus_mut();
    let now = bus.now();
    for (id, node) in nodes {
        let board = bus.node_mut::<BoardNode>(node).expect("a QLA board");
        board.firmware_mut().advance(now);
        let on: Vec<usize> = (0..4)
            .filter(|&a| board.firmware().amplifier_on(a))
            .collect();
        assert!(on.is_empty(), "board {id}: amplifiers {on:?} still on");
    }
}

/// The in-process emulator serving `config`'s boards, and its scan.
fn emulator(config: &IoConfig) -> (Emulator, firelink_host::qla::scan::ScanReport) {
    let boards = used_boards(config).len();
    let emu = Emulator::start(used_boards(config)).expect("emulator");
    let scan = crate::rescan::until_all_found(&mut port(&emu), boards);
    (emu, scan)
}

fn port(emu: &Emulator) -> UdpPort {
    let mut p = emu.port().expect("port");
    p.set_timeout(Duration::from_millis(500));
    p
}

#[test]
fn a_board_lost_by_id_over_udp_ends_with_every_amplifier_off_and_the_board_named() {
    let config = config();
    let (emu, scan) = emulator(&config);
    // Board by board: with the broadcast protocol every board's state
    // reaches the host inside the bridge board's block, where no link
    // filter on the host's port can tell one board from another.
    let options = IoOptions {
        protocol: Some(Protocol::Sequential),
        ..IoOptions::default()
    };
    let io = IoSystem::with_scan(port(&emu), &scan, options).unwrap();
    let mut robot = Robot::new(io, &config, settings()).unwrap();
    bring_up(&mut robot);
    let lost = lost_board(&config);
    let script: FaultScript = format!("mute@start:id={lost}").parse().unwrap();
    let handle =
        ScriptFilter::for_scan(robot.io_mut().port_mut(), &script, &scan.boards, 0).unwrap();
    assert_eq!(missed_board(&mut robot, 1000, Pacing::WallClock), lost);
    for _ in 0..3 {
        let _ = robot.step(Pacing::Virtual);
    }
    assert!(!robot.any_amp_on());
    assert!(handle.counts().silenced > 0);
    drop(robot);
    // A second client, without the filter: the lost board heard nothing
    // more from the host, so its own watchdog switched its amplifiers off;
    // the other was switched off by the first client.
    let lost_node = scan
        .boards
        .iter()
        .find(|b| b.board_id == lost)
        .expect("the lost board")
        .node;
    let mut p = port(&emu);
    let deadline = Instant::now() + Duration::from_secs(30);
    while p.read_quadlet(Dest::node(lost_node), 0).expect("status") & (1 << 23) == 0 {
        assert!(
            Instant::now() < deadline,
            "the lost board's watchdog never fired"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut io = IoSystem::with_scan(p, &scan, IoOptions::default()).unwrap();
    io.read_all();
    for b in io.boards() {
        let on: Vec<usize> = (0..b.axes()).filter(|&a| b.amp_enabled(a)).collect();
        assert!(
            on.is_empty(),
            "board {}: amplifiers {on:?} on",
            b.board_id()
        );
    }
    emu.stop().unwrap();
}

/// Corrupted answers are refused by the host (their CRCs disagree) and
/// counted by both sides; dropped requests time out. The script's counts
/// are exact.
#[test]
fn corruption_and_drops_over_udp_are_counted_and_refused() {
    let (emu, scan) = emulator(&config());
    let mut p = port(&emu);
    // Read-quadlet responses (tcode 6) corrupted, read-quadlet requests
    // (tcode 4) to board 0 dropped: three and two of them.
    let first = &scan.boards[0];
    let script: FaultScript = format!(
        "corrupt@start:tcode=0x6,count=3;drop@start:tcode=0x4,dest={},count=2",
        first.board_id
    )
    .parse()
    .unwrap();
    let handle = ScriptFilter::for_scan(&mut p, &script, &scan.boards, 5).unwrap();
    let node = first.node;
    let before = p.link_stats();
    let results: Vec<bool> = (0..7)
        .map(|_| p.read_quadlet(Dest::node(node), 0).is_ok())
        .collect();
    // Two requests lost, then three answers corrupted, then clean reads.
    assert_eq!(results, [false, false, false, false, false, true, true]);
    let c = handle.counts();
    assert_eq!((c.dropped, c.corrupted), (2, 3));
    let after = p.link_stats();
    assert_eq!(after.bad_crc - before.bad_crc, 3);
    // The lost requests time out; the corrupted answers are refused as
    // such.
    assert_eq!(after.timeouts - before.timeouts, 2);
    emu.stop().unwrap();
}

/// The demo's program over loopback UDP to an in-process emulator of
/// `config()`'s boards (broadcast protocol, 0.2 s at 1 kHz), `script`
/// applied by the emulator's fault target: the report, the bridge's
/// counters and what the run said it injected.
///
/// The host runs in virtual time on a [`HostClock`] (its port's clock moves
/// only when it waits, one period a cycle) and the emulator keeps that
/// time ([`Emulator::start_following`]): a host or server thread kept off
/// the CPU changes nothing the boards' plants or watchdogs see, so no
/// delay on a loaded machine can trip a limit the test is not about.
fn demo_over_udp(
    script: &FaultScript,
) -> (
    firelink_testbed::demo::DemoReport,
    firelink_emulate::BridgeStats,
    Vec<String>,
) {
    use firelink_testbed::demo::{DemoFault, DemoPlan, DemoProgress, RealtimeStatus, run_program};
    let config = config();
    let clock = HostClock::new();
    let emu = Emulator::start_following(used_boards(&config), clock.clone()).expect("emulator");
    let options = IoOptions {
        protocol: Some(Protocol::Broadcast),
        ..IoOptions::default()
    };
    let (io, _) = IoSystem::open(HostClockedPort::new(port(&emu), clock), options).unwrap();
    let plan = DemoPlan {
        config: &config,
        period: firelink_control::ServoPeriod::from_rate_hz(1000.0).unwrap(),
        duration_s: 0.2,
        fault: DemoFault::None,
        script: Some(script),
        watchdog: settings().watchdog,
        pacing: Pacing::Virtual,
    };
    let robot = Robot::new(io, &config, plan.settings()).unwrap();
    let mut injected = Vec::new();
    let run = run_program(
        robot,
        &plan,
        &emu.fault_target(),
        "emulate".into(),
        RealtimeStatus::default(),
        Instant::now(),
        &mut |e| {
            if let DemoProgress::Injecting(what) = e {
                injected.push(what);
            }
        },
    )
    .unwrap();
    let stats = emu.stop().unwrap();
    (run.report, stats, injected)
}

/// The demo's corrupt-query preset as a script over loopback UDP to the
/// in-process emulator: the emulator's fault target puts it in a link
/// filter on the host's port, one query goes out corrupted, the bridge
/// refuses it by its CRC (counted once), and the run recovers.
#[test]
fn a_corrupt_query_over_udp_is_counted_by_the_bridge_and_the_run_recovers() {
    // The preset itself, at the fault moment (t=0us: half way through the
    // motion); the 300 ms is the boards' watchdog, which only the
    // stop-host preset uses.
    let script = firelink_testbed::demo::DemoFault::CorruptQuery.script(Duration::from_millis(300));
    assert_eq!(
        script.to_string(),
        "corrupt@t=0us:tcode=0x0,offset=0x1800,count=1"
    );
    let (r, stats, injected) = demo_over_udp(&script);
    assert_eq!(injected, [script.to_string()], "{r}");
    assert_eq!(stats.bad_crc, 1, "{stats}");
    // The lost query is a cycle whose boards did not answer: the fault
    // is detected, the safety chain acts, and the link has recovered:
    // every board answers afterwards and is powered down.
    assert_eq!(r.verdict(), Ok(()), "{r}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false), "{r}");
    assert!(r.boards_not_answering.is_empty(), "{r}");
    assert!(r.power_down.unknown.is_empty(), "{:?}", r.power_down);
    assert!(r.power_down.still_on.is_empty(), "{:?}", r.power_down);
    assert_eq!(r.power_down.off.len(), 2, "{:?}", r.power_down);
}

/// What a port cannot apply is refused, naming the entry and the port:
/// a board silenced from the host's side of a link, a host pause after
/// its moment; a board the rig does not have, by its ID.
#[test]
fn a_fault_target_refuses_what_its_port_cannot_do() {
    use firelink_testbed::fault_script::FaultTarget;
    let emu = Emulator::start(used_boards(&config())).expect("emulator");
    let udp = port(&emu);
    let name = udp.name().to_string();
    let mute: FaultScript = "mute@t=0us:id=4".parse().unwrap();
    let e = FaultTarget::link().check(&mute, &udp, None).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "configuration: fault mute@t=0us:id=4 cannot be applied on {name}: a board \
             cannot be silenced from the host's side of a link (behind a hub one block \
             carries every board's state); use the sim port or the in-process emulator"
        )
    );
    let pause: FaultScript = "host-pause@t=10us:for=100us".parse().unwrap();
    let e = FaultTarget::link().check(&pause, &udp, None).unwrap_err();
    assert!(
        e.to_string().contains(&format!(
            "fault host-pause@t=10us:for=100us cannot be applied on {name}"
        )),
        "{e}"
    );
    // Packets and host pauses are the host's side's to do.
    let link_ok: FaultScript = "drop@cycle=5:dest=2,rate=0.5;host-pause@cycle=9:for=100us"
        .parse()
        .unwrap();
    assert!(FaultTarget::link().check(&link_ok, &udp, None).is_ok());
    // The rig's target knows its boards by ID; the emulator's mutes them
    // on its own bus.
    let rig = RigBuilder::qla(used_boards(&config())).build().unwrap();
    let target = rig.fault_target();
    let sim = rig.sim_port();
    let e = target
        .check(&"unplug@cycle=3:id=9".parse().unwrap(), &sim, None)
        .unwrap_err();
    assert_eq!(e.to_string(), "unplugged board 9: no such board on the rig");
    let lost: FaultScript = format!("mute@t=0us:id={}", lost_board(&config()))
        .parse()
        .unwrap();
    assert!(emu.fault_target().check(&lost, &udp, None).is_ok());
    let e = emu.fault_target().check(&mute, &udp, None).unwrap_err();
    assert_eq!(e.to_string(), "muted board 4: no such board on the rig");
    drop(udp);
    emu.stop().unwrap();
}

/// A board muted behind the broadcast hub, which no filter on the host's
/// port could do: the in-process emulator's fault target mutes it on the
/// emulator's own bus at the fault moment; the host names it and every
/// amplifier that answers ends off.
#[test]
fn a_board_muted_on_the_emulators_bus_is_named_over_udp() {
    let lost = lost_board(&config());
    // Half way, as the board-loss preset does.
    let script: FaultScript = format!("mute@t=0us:id={lost}").parse().unwrap();
    let (r, stats, injected) = demo_over_udp(&script);
    assert_eq!(injected, [script.to_string()], "{r}");
    assert_eq!(stats.bad_crc, 0, "{stats}");
    assert_eq!(r.verdict(), Ok(()), "{r}");
    let fault = r.fault.as_ref().unwrap();
    assert_eq!(fault.board, Some(lost), "{fault:?}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false), "{r}");
    assert!(r.boards_not_answering.contains(&lost), "{r}");
}

/// The simulated bus's target on a wrapped sim port (a tracer over it):
/// a host pause is the port's own wait and is applied (the port's clock
/// moves by it); a board fault needs the bus and is still refused.
#[test]
fn the_sim_target_pauses_the_host_on_a_wrapped_sim_port() {
    use firelink_host::trace::TracingPort;
    let rig = RigBuilder::qla(used_boards(&config())).build().unwrap();
    let target = rig.fault_target();
    let mut port = TracingPort::new(rig.sim_port());
    let name = port.name().to_string();
    let pause: FaultScript = "host-pause@cycle=3:for=100us".parse().unwrap();
    target.check(&pause, &port, None).unwrap();
    let before = port.now();
    target.apply(0, &pause.entries[0], &mut port, &[]).unwrap();
    assert_eq!(port.now() - before, Duration::from_micros(100));
    let mute: FaultScript = format!("mute@t=0us:id={}", lost_board(&config()))
        .parse()
        .unwrap();
    let e = target.check(&mute, &port, None).unwrap_err();
    assert!(
        e.to_string().contains(&format!(
            "cannot be applied on {name}: the simulated bus's target on another port"
        )),
        "{e}"
    );
}
