//! Firelink's own FireWire port (`--port fw`, `FirewirePort`) against the
//! emulated boards through the /dev/fw* twin (`firelink fw-run`): the
//! program under test is this test executable run again as a child, with
//! the twin preloaded, driving the boards through glibc as it would a real
//! card. Nothing here depends on timing: faults are started by the twin
//! after a number of requests, waits are bounded, no duration is asserted.

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use firelink_host::firewire::{FirewirePort, FwOptions};
use firelink_host::qla::io::{BroadcastRoute, IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::{HostError, Port, RobotIo, WatchdogSetting};
use firelink_wire::fw_cdev::rcode as fw_rcode;

const CHILD_ENV: &str = "FW_PORT_TEST_CHILD";

/// Run `scenario` of this file as a child of `firelink fw-run` with
/// `emulate` options; it must exit 0 having run that one test.
fn run_under_twin(scenario: &str, emulate: &[&str]) {
    if std::env::var_os(CHILD_ENV).is_some() {
        return;
    }
    let lib = PathBuf::from(env!("CARGO_BIN_EXE_firelink")).with_file_name("libfirelink_fwcdev.so");
    assert!(
        lib.exists(),
        "{} is missing: run `cargo build -p firelink-fwcdev` (cargo test --workspace builds it)",
        lib.display()
    );
    let me = std::env::current_exe().unwrap();
    let exact = crate::common::libtest_name(module_path!(), scenario);
    let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .arg("fw-run")
        .args(emulate)
        .arg("--")
        .arg(&me)
        .args([&exact, "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, scenario)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{scenario} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("test result: ok. 1 passed"),
        "{exact} did not run in the child:\n{stdout}"
    );
}

fn in_child(name: &str) -> bool {
    std::env::var(CHILD_ENV).is_ok_and(|c| c == name)
}

fn open_io() -> IoSystem<FirewirePort> {
    let port = FirewirePort::open(FwOptions {
        timeout: Duration::from_millis(200),
        cycle_budget: Duration::from_millis(200),
        ..FwOptions::default()
    })
    .expect("open fw");
    // The default options: the system takes the snooped-node-0 route by
    // itself, as the port refuses broadcast register writes.
    let (io, scan) = IoSystem::open(port, IoOptions::default()).expect("scan over fw");
    assert_eq!(scan.protocol, Protocol::Broadcast);
    io
}

/// Open the port (each call's deadline and each cycle's budget `timeout`)
/// and scan, again (at most 20 times) until the scan sees all `boards`:
/// under a fault plan a scan can lose a packet too.
fn open_all(boards: usize, timeout: Duration, options: IoOptions) -> IoSystem<FirewirePort> {
    for _ in 0..20 {
        let port = FirewirePort::open(FwOptions {
            timeout,
            cycle_budget: timeout,
            ..FwOptions::default()
        })
        .expect("open fw");
        if let Ok((sys, scan)) = IoSystem::open(port, options)
            && scan.boards.len() == boards
        {
            return sys;
        }
    }
    panic!("no scan of all {boards} boards in 20 tries");
}

/// `n` more cycles, every one clean.
fn assert_clean_cycles(io: &mut IoSystem<FirewirePort>, n: u64) {
    let start = *io.stats();
    for _ in 0..n {
        let report = io.cycle();
        assert!(report.all_ok(), "{:?}", report.error);
    }
    let end = *io.stats();
    assert_eq!(end.clean_cycles - start.clean_cycles, n, "{end:?}");
}

#[test]
fn ten_thousand_broadcast_cycles_of_28_axes_without_an_error() {
    run_under_twin(
        "ten_thousand_broadcast_cycles_of_28_axes_without_an_error",
        &["--boards", "7"],
    );
    if !in_child("ten_thousand_broadcast_cycles_of_28_axes_without_an_error") {
        return;
    }
    let mut io = open_io();
    assert_eq!(io.boards().len(), 7);
    assert_eq!(RobotIo::axis_count(&io), 28);
    for _ in 0..10_000 {
        io.cycle();
    }
    let stats = *io.stats();
    assert_eq!(stats.cycles, 10_000);
    assert_eq!(stats.total_errors(), 0, "{stats:?}");
    assert_eq!(stats.clean_cycles, 10_000, "{stats:?}");
}

#[test]
fn a_bus_reset_mid_run_is_reported_once_and_recovered() {
    run_under_twin(
        "a_bus_reset_mid_run_is_reported_once_and_recovered",
        &["--boards", "4"],
    );
    if !in_child("a_bus_reset_mid_run_is_reported_once_and_recovered") {
        return;
    }
    let mut io = open_io();
    for _ in 0..200 {
        io.cycle();
    }
    assert_eq!(io.stats().total_errors(), 0);
    let generation = io.port().generation();
    io.port_mut().initiate_bus_reset(false).unwrap();
    // Cycles go on failing (a reset seen) until the program recovers.
    let mut seen = false;
    for _ in 0..1000 {
        io.cycle();
        if io.needs_rescan() {
            seen = true;
            break;
        }
    }
    assert!(seen, "no cycle met the bus reset");
    let scan = io.recover().unwrap().expect("a rescan");
    assert_eq!(scan.boards.len(), 4);
    assert!(io.port().generation() > generation);
    let before = *io.stats();
    for _ in 0..200 {
        io.cycle();
    }
    let after = *io.stats();
    assert_eq!(after.total_errors(), before.total_errors(), "{after:?}");
    assert_eq!(after.clean_cycles - before.clean_cycles, 200);
}

#[test]
fn an_unplugged_board_is_named_and_the_others_still_served() {
    // Board 0 is the far end of the daisy chain: unplugged, only it leaves.
    run_under_twin(
        "an_unplugged_board_is_named_and_the_others_still_served",
        &[
            "--boards",
            "5",
            "--unplug-board",
            "0",
            "--fault-after-requests",
            "2000",
        ],
    );
    if !in_child("an_unplugged_board_is_named_and_the_others_still_served") {
        return;
    }
    let mut io = open_io();
    let before: Vec<u8> = io.boards().iter().map(|b| b.board_id()).collect();
    assert_eq!(before, [0, 1, 2, 3, 4]);
    let mut cycles = 0;
    while !io.needs_rescan() {
        let report = io.cycle();
        let error = report.error;
        cycles += 1;
        assert!(cycles < 100_000, "the unplug never showed: {error:?}");
    }
    let scan = io.recover().unwrap().expect("a rescan");
    let after: Vec<u8> = scan.boards.iter().map(|b| b.board_id).collect();
    let gone: Vec<u8> = before
        .iter()
        .copied()
        .filter(|b| !after.contains(b))
        .collect();
    println!("boards gone from the bus: {gone:?}");
    assert_eq!(gone, [0]);
    // The system names it too.
    assert_eq!(io.boards_left(), [0]);
    assert_clean_cycles(&mut io, 200);
}

#[test]
fn the_watchdog_turns_the_amplifiers_off_when_the_host_stops() {
    run_under_twin(
        "the_watchdog_turns_the_amplifiers_off_when_the_host_stops",
        &["--boards", "2"],
    );
    if !in_child("the_watchdog_turns_the_amplifiers_off_when_the_host_stops") {
        return;
    }
    let mut io = open_io();
    // The boards behind the twin keep the wall clock: a watchdog long
    // enough that a loaded machine's stall between two of the host's
    // writes (seen: 20 ms expired while the amplifiers came on) does not
    // end the test's own bring-up.
    io.set_watchdog(WatchdogSetting::from_ms(150.0).unwrap())
        .unwrap();
    let axes = RobotIo::axis_count(&io);
    // Power on and enable every amplifier; cycle until the boards show it
    // (bounded).
    RobotIo::set_power(&mut io, 0b11, true);
    io.cycle();
    // The supply is good some milliseconds after power is enabled; cycle
    // (feeding the watchdog) until the boards say they are powered.
    for _ in 0..20_000 {
        io.cycle();
        if [0, 1].iter().all(|b| io.powered(*b)) {
            break;
        }
    }
    for axis in 0..axes {
        io.set_amplifier_enable(axis, true).unwrap();
    }
    let mut on = false;
    for _ in 0..20_000 {
        io.latch_all_inputs();
        io.apply_all_outputs();
        if (0..axes).all(|a| io.amplifier_enabled(a).unwrap_or(false)) {
            on = true;
            break;
        }
    }
    assert!(
        on,
        "the amplifiers never came on: {:?} {:?} {:?}",
        io.board_status(0),
        io.report().error,
        io.stats()
    );
    // The host stops (no writes) for well over the watchdog period.
    std::thread::sleep(Duration::from_millis(1000));
    let mut off = false;
    for _ in 0..100 {
        io.latch_all_inputs();
        if (0..axes).all(|a| !io.amplifier_enabled(a).unwrap_or(true))
            && [0, 1].iter().all(|b| io.watchdog_expired(*b))
        {
            off = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(off, "amplifiers still on after the host stopped");
}

#[test]
fn packets_lost_on_the_bus_are_counted_and_nothing_hangs() {
    // One packet in 200 lost on the bus, from the start (seeded): lost
    // requests end in no-ack, lost responses in the port's own deadline
    // (the twin cancels them 2 s later; those late completions are dropped
    // by closure). Every cycle ends, every failure is counted.
    run_under_twin(
        "packets_lost_on_the_bus_are_counted_and_nothing_hangs",
        &["--boards", "4", "--drop-rate", "0.005", "--seed", "7"],
    );
    if !in_child("packets_lost_on_the_bus_are_counted_and_nothing_hangs") {
        return;
    }
    // A scan can lose a packet too.
    let options = IoOptions {
        broadcast_route: BroadcastRoute::SnoopedNode0,
        ..IoOptions::default()
    };
    let mut io = open_all(4, Duration::from_millis(50), options);
    for _ in 0..3000 {
        io.cycle();
        if io.needs_rescan() {
            let _ = io.recover();
        }
    }
    let stats = *io.stats();
    assert_eq!(stats.cycles, 3000);
    assert!(stats.total_errors() > 0, "no loss seen: {stats:?}");
    assert!(stats.clean_cycles > 2000, "{stats:?}");
    // Each cycle either ran clean or counted what went wrong.
    let missed: u64 = stats.missed_by_board.iter().sum();
    assert!(stats.cycles - stats.clean_cycles <= missed + stats.total_errors());
    let link = io.port().link_stats();
    assert!(link.timeouts > 0 || link.late > 0 || stats.nacks + stats.other > 0);
}

#[test]
fn dropped_responses_and_busy_acks_end_every_cycle_in_a_named_outcome() {
    // A seeded plan on the twin's bus: one read response in 300 lost (the
    // twin cancels it after a 5 ms split time-out of its virtual time) and
    // one request in 300 met by a busy board (ack_busy_X). The port's own
    // deadline (2 s here) is far longer than the split time-out, so a lost
    // response comes back as the twin's one CANCELLED completion (or, on a
    // machine too loaded to serve it within 2 s, as the port's time-out:
    // named all the same).
    run_under_twin(
        "dropped_responses_and_busy_acks_end_every_cycle_in_a_named_outcome",
        &[
            "--boards",
            "4",
            "--drop-response-rate",
            "0.0033",
            "--busy-rate",
            "0.0033",
            "--split-timeout-ms",
            "5",
            "--seed",
            "11",
        ],
    );
    if !in_child("dropped_responses_and_busy_acks_end_every_cycle_in_a_named_outcome") {
        return;
    }
    // The scan meets the plan too.
    let mut io = open_all(4, Duration::from_secs(2), IoOptions::default());
    let (mut clean, mut cancelled, mut busy, mut timeouts) = (0u64, 0u64, 0u64, 0u64);
    for _ in 0..2000 {
        let report = *io.cycle();
        match report.error {
            None if report.missed == 0 => clean += 1,
            // A board whose block the hub did not hold (its status write
            // lost to a busy hub) is counted as missed, not an error.
            None => {}
            Some(HostError::Driver { rcode, .. }) if rcode == fw_rcode::CANCELLED => cancelled += 1,
            Some(HostError::Driver { rcode, .. }) if rcode == fw_rcode::BUSY => busy += 1,
            Some(HostError::Timeout { .. } | HostError::CycleDeadline { .. }) => timeouts += 1,
            // Anything else is a named error too, but not one this plan
            // makes.
            Some(e) => panic!("unexpected error: {e}"),
        }
        if io.needs_rescan() {
            let _ = io.recover();
        }
    }
    println!("clean {clean}, cancelled {cancelled}, busy {busy}, timed out {timeouts}");
    let stats = *io.stats();
    assert_eq!(stats.cycles, 2000);
    assert!(cancelled + timeouts > 0, "no lost response seen");
    assert!(busy > 0, "no busy ack seen");
    assert!(clean > 1800, "clean {clean}");
}

#[test]
fn a_storm_of_bus_resets_is_recovered() {
    // Five bus resets 1 ms apart once the twin has taken 1500 requests.
    run_under_twin(
        "a_storm_of_bus_resets_is_recovered",
        &[
            "--boards",
            "4",
            "--reset-storm",
            "5",
            "--fault-after-requests",
            "1500",
        ],
    );
    if !in_child("a_storm_of_bus_resets_is_recovered") {
        return;
    }
    let mut io = open_io();
    let generation = io.port().generation();
    let mut resets_reported = 0;
    let mut cycles = 0;
    // Run until the storm is over and the system has recovered from its
    // last reset: the generation has risen by five. Bounded by cycles,
    // not by time.
    while io.port().generation() < generation + 5 || io.needs_rescan() {
        cycles += 1;
        assert!(
            cycles < 200_000,
            "the storm never ended: generation {}",
            io.port().generation()
        );
        let report = io.cycle();
        if matches!(report.error, Some(HostError::BusReset { .. })) {
            resets_reported += 1;
        }
        if io.needs_rescan() {
            // Recovery can itself meet the next reset of the storm: it is
            // tried again on the next turn.
            let _ = io.recover();
        }
    }
    println!(
        "generation {generation} -> {}, resets reported {resets_reported}",
        io.port().generation()
    );
    assert!(resets_reported >= 1);
    assert_eq!(io.boards().len(), 4);
    assert_clean_cycles(&mut io, 200);
}

#[test]
fn a_lost_response_ends_its_cycle_at_the_cycle_budget_and_its_late_completion_is_dropped() {
    // One read response in 100 lost on the twin's bus; the twin cancels
    // each after a 1 s split time-out of its virtual time (paced to the
    // wall clock). Each call may wait 5 s, a cycle only 30 ms in all: a
    // cycle whose hub read lost its response ends with the cycle's named
    // deadline, not with the twin's CANCELLED a second later, and that
    // completion, when it comes, is dropped by its closure and counted.
    run_under_twin(
        "a_lost_response_ends_its_cycle_at_the_cycle_budget_and_its_late_completion_is_dropped",
        &[
            "--boards",
            "4",
            "--drop-response-rate",
            "0.01",
            "--split-timeout-ms",
            "1000",
            "--seed",
            "5",
        ],
    );
    if !in_child(
        "a_lost_response_ends_its_cycle_at_the_cycle_budget_and_its_late_completion_is_dropped",
    ) {
        return;
    }
    let mut io = open_all(4, Duration::from_secs(5), IoOptions::default());
    io.port_mut().set_cycle_budget(Duration::from_millis(30));
    let (mut clean, mut deadlines, mut cancelled) = (0u64, 0u64, 0u64);
    let mut cycles = 0u64;
    // Until a cycle met its deadline and a late completion was dropped;
    // bounded by cycles, not by time.
    while deadlines == 0 || io.port().link_stats().late == 0 {
        cycles += 1;
        assert!(
            cycles < 200_000,
            "deadlines {deadlines}, late {}",
            io.port().link_stats().late
        );
        let report = *io.cycle();
        match report.error {
            None => clean += 1,
            Some(HostError::CycleDeadline { budget_us, .. }) => {
                assert_eq!(budget_us, 30_000);
                deadlines += 1;
            }
            // Only a host thread kept off the CPU for the whole second
            // could still be waiting when the twin cancels.
            Some(HostError::Driver { rcode, .. }) if rcode == fw_rcode::CANCELLED => {
                cancelled += 1;
            }
            // The call's own 5 s deadline never comes first.
            Some(e) => panic!("unexpected error: {e}"),
        }
        if io.needs_rescan() {
            let _ = io.recover();
        }
    }
    let link = io.port().link_stats();
    println!(
        "{cycles} cycles: clean {clean}, cycle deadlines {deadlines}, cancelled {cancelled}, \
         late completions dropped {}",
        link.late
    );
    assert_eq!(io.stats().cycles, cycles);
    assert!(io.stats().timeouts >= deadlines);
}

#[test]
fn started_writes_return_at_once_and_a_failed_one_is_reported_by_the_next_call() {
    run_under_twin(
        "started_writes_return_at_once_and_a_failed_one_is_reported_by_the_next_call",
        &["--boards", "1"],
    );
    if !in_child("started_writes_return_at_once_and_a_failed_one_is_reported_by_the_next_call") {
        return;
    }
    let mut port = FirewirePort::open(FwOptions {
        timeout: Duration::from_secs(2),
        ..FwOptions::default()
    })
    .expect("open fw");
    let card = firelink_host::Dest::node(port.local_phy());
    const STATE_CLEAR: u64 = 0xFFFF_F000_0000;
    let before = port.link_stats();
    // Twenty writes the card takes, started one after the other: at most
    // eight stay open, each completes exactly once, none is late.
    for _ in 0..20 {
        port.start_write_quadlet(card, STATE_CLEAR, 0x100).unwrap();
    }
    assert_eq!(port.read_quadlet(card, STATE_CLEAR).unwrap() & 0x100, 0);
    let after = port.link_stats();
    assert_eq!(after.sent - before.sent, 21);
    assert_eq!(after.matched - before.matched, 21, "{after:?}");
    assert_eq!(after.late, before.late);
    // A write the card refuses (no register there): the start succeeds,
    // the call that reads its completion keeps its own result, and the
    // next call reports the failure, once.
    port.start_write_quadlet(card, STATE_CLEAR + 0xF00, 0)
        .unwrap();
    port.read_quadlet(card, STATE_CLEAR).unwrap();
    let failed = port.read_quadlet(card, STATE_CLEAR);
    assert!(
        matches!(
            failed,
            Err(HostError::Rcode {
                rcode: firelink_wire::packet::Rcode::AddressError,
                ..
            })
        ),
        "{failed:?}"
    );
    port.read_quadlet(card, STATE_CLEAR).unwrap();
}
