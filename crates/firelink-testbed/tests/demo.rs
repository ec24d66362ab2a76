//! The demo and the bench as library calls: typed reports, the same
//! report for the same inputs, faults detected with the safety chain.

use firelink_host::scan::Protocol;
use firelink_testbed::bench::{BenchOptions, BenchTransport, check_board_counts, run_bench};
use firelink_testbed::demo::{DemoFault, DemoOptions, DemoProgress, PortSpec, run_demo};

fn short(fault: DemoFault) -> DemoOptions {
    DemoOptions {
        duration_s: 0.1,
        fault,
        ..DemoOptions::default()
    }
}

#[test]
fn the_demo_runs_the_dvrk_and_reports_the_same_twice() {
    let mut events = Vec::new();
    let a = run_demo(&short(DemoFault::None), None, |e| events.push(e)).unwrap();
    assert_eq!(a.verdict(), Ok(()));
    assert_eq!((a.boards, a.axes), (8, 28));
    assert_eq!(a.errors.total, 0);
    assert_eq!(a.protocol, "broadcast");
    assert_eq!(a.motion_cycles, 600);
    assert!(a.tracking_error.contains_key("PSM1"));
    assert!(matches!(
        events.first(),
        Some(DemoProgress::Found { boards: 8, .. })
    ));
    assert!(matches!(events.last(), Some(DemoProgress::PoweredOff(_))));
    let mut b = run_demo(&short(DemoFault::None), None, |_| {}).unwrap();
    // Only what the host's own clock measures may differ: wall time and
    // the compute part of the cycle (host CPU time).
    b.wall_time_s = a.wall_time_s;
    b.speed_vs_real_time = a.speed_vs_real_time;
    b.compute_time_us = a.compute_time_us;
    b.cycle_time_us = a.cycle_time_us;
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );
}

#[test]
fn a_lost_board_is_named_and_every_amplifier_ends_off() {
    let r = run_demo(&short(DemoFault::BoardLoss), None, |_| {}).unwrap();
    assert_eq!(r.verdict(), Ok(()), "{r}");
    let fault = r.fault.as_ref().unwrap();
    assert_eq!(fault.board, Some(4), "{fault:?}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false));
    assert!(r.boards_not_answering.contains(&4));
    // What the host cannot see is reported as unknown, not as "off" or
    // "not expired".
    assert_eq!(r.watchdog.unknown_boards, r.boards_not_answering);
    assert!(
        r.watchdog
            .expired_boards
            .iter()
            .all(|b| !r.boards_not_answering.contains(b))
    );
    assert!(r.power_down.unknown.contains(&4), "{:?}", r.power_down);
    assert!(r.power_down.still_on.is_empty());
    let text = r.to_string();
    assert!(
        text.contains("amplifiers off on the boards that answer"),
        "{text}"
    );
    assert!(
        text.contains("not answering: amplifier state unknown"),
        "{text}"
    );
    assert!(text.contains("did not answer: state unknown"), "{text}");
    assert!(!text.contains("expired on boards []"), "{text}");
}

#[test]
fn a_verdict_fails_when_an_injected_fault_goes_unseen() {
    let mut r = run_demo(
        &DemoOptions {
            port: PortSpec::SIM,
            ..short(DemoFault::None)
        },
        None,
        |_| {},
    )
    .unwrap();
    assert_eq!(r.verdict(), Ok(()));
    r.fault_injected = DemoFault::StopHost.name();
    assert!(r.verdict().unwrap_err().contains("not detected"));
}

#[test]
fn bad_demo_options_are_refused_with_the_reason() {
    let e = run_demo(
        &DemoOptions {
            rate_hz: 0.0,
            ..DemoOptions::default()
        },
        None,
        |_| {},
    )
    .unwrap_err();
    assert!(e.to_string().contains("rate"), "{e}");
    assert!("meteor".parse::<DemoFault>().is_err());
    assert!("nowhere".parse::<PortSpec>().is_err());
    assert_eq!(
        "board-loss".parse::<DemoFault>().unwrap(),
        DemoFault::BoardLoss
    );
}

#[test]
fn the_bench_measures_models_and_says_which_is_which() {
    let options = BenchOptions {
        transports: vec![BenchTransport::Sim],
        boards: vec![2, 8, 32],
        protocols: vec![Protocol::Sequential, Protocol::Broadcast],
        cycles: 20,
        ..BenchOptions::default()
    };
    let mut heard = Vec::new();
    let r = run_bench(&options, |t, p, n| heard.push((t, p, n))).unwrap();
    assert_eq!(heard.len(), 4, "32 boards is modelled, not run");
    assert_eq!(r.results.len(), 6);
    let at = |proto: &str, n: usize| {
        r.results
            .iter()
            .find(|p| p.protocol_asked == proto && p.boards == n)
            .unwrap()
    };
    assert!(!at("sequential", 8).model && at("sequential", 32).model);
    assert_eq!(at("sequential", 32).io_time_us.max, None);
    assert!(at("broadcast", 8).io_time_us.median < at("sequential", 8).io_time_us.median);
    assert!(r.results.iter().all(|p| p.errors == 0));
    // The I/O figures are deterministic on the simulated bus (the compute
    // time, and the rate and budget built on it, are the host's own CPU).
    let again = run_bench(&options, |_, _, _| {}).unwrap();
    let io = |r: &firelink_testbed::bench::BenchReport| {
        r.results
            .iter()
            .map(|p| (p.io_time_us, p.read_us, p.write_us, p.errors, p.model))
            .collect::<Vec<_>>()
    };
    assert_eq!(io(&r), io(&again));
    assert!(check_board_counts(&[32, 8]).is_err());
    assert!(check_board_counts(&[]).is_err());
    assert!(check_board_counts(&[0]).is_err());
}
