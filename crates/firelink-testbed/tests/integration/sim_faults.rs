//! Faults injected into one I/O cycle of emulated boards driven by the host
//! library ([`firelink_testbed::sim`]): each is recorded by the bus and
//! detected by a board or the host. (Faults on single transactions are
//! tested on the bus alone, in `firelink-bus`'s `tests/integration/faults.rs`.)

use firelink_board::qla::config::Profile;
use firelink_bus::fault::{
    EvidenceKind, FaultPlan, FaultRule, PacketFault, PacketMatch, TimedFault,
};
use firelink_bus::host::HostLink;
use firelink_bus::{SimDuration, SimTime};
use firelink_host::qla::scan::Protocol;
use firelink_testbed::sim::{SimOptions, SimRun};
use firelink_wire::packet::Tcode;

fn run(options: &SimOptions) -> SimRun {
    firelink_testbed::sim::run(options).expect("the cycle runs")
}

fn seed(boards: usize) -> SimOptions {
    SimOptions::new(boards, Profile::Seed, Protocol::Broadcast)
}

/// The boards' status broadcasts (block writes to node 63), but the first
/// `skip`.
fn status_broadcasts(skip: u64) -> PacketMatch {
    PacketMatch::any()
        .tcode(Tcode::WriteBlockRequest)
        .to_phy(63)
        .skip(skip)
}

#[test]
fn drop_broadcast_is_detected_by_the_host_hub_check() {
    let mut cfg = seed(4);
    cfg.faults = FaultPlan::new().once(status_broadcasts(1), PacketFault::Drop);
    let mut run = run(&cfg);
    assert_eq!(run.report.boards_ok, 3);
    assert!(
        run.report
            .errors
            .iter()
            .any(|e| e.contains("no fresh data"))
    );
    // Broadcasts have no ack: the host library records what it detected.
    let id = run.report.faults[0].id;
    let pc = run.pc;
    run.port_mut()
        .bus_mut()
        .record_detection(id, pc, "hub data missing a board");
    assert!(run.port().bus().fault_log().undetected().is_empty());
}

#[test]
fn corrupt_query_is_noticed_by_every_board() {
    let mut cfg = seed(4);
    cfg.faults = FaultPlan::new().once(
        PacketMatch::any().offset(0x1800),
        PacketFault::CorruptQuadlet { index: 3, xor: 1 },
    );
    let report = run(&cfg).report;
    assert_eq!(report.boards_ok, 0);
    assert!(report.errors.iter().any(|e| e.contains("corrupt query")));
    let f = &report.faults[0];
    let reporters = f
        .evidence
        .iter()
        .filter(|e| matches!(&e.kind, EvidenceKind::Report(t) if t.contains("corrupt query")))
        .count();
    assert_eq!(reporters, 4);
}

#[test]
fn delayed_status_broadcast_arrives_late_and_boards_notice() {
    let mut cfg = seed(4);
    cfg.faults = FaultPlan::new().once(
        status_broadcasts(1),
        PacketFault::Delay(SimDuration::from_micros(8)),
    );
    let base = run(&seed(4)).report;
    let run = run(&cfg);
    let f = &run.report.faults[0];
    assert!(f.what.starts_with("delay"));
    assert!(
        f.evidence
            .iter()
            .any(|e| matches!(&e.kind, EvidenceKind::Report(t) if t.contains("after its slot")))
    );
    // The delayed packet really started later.
    let delayed = run
        .port()
        .bus()
        .trace()
        .packets()
        .iter()
        .find(|p| p.faults.contains(&f.id))
        .unwrap();
    assert!(delayed.start - delayed.arb_start.unwrap() < SimDuration::from_micros(3));
    assert!(run.report.phase_us("broadcast").unwrap() >= base.phase_us("broadcast").unwrap());
}

#[test]
fn duplicated_status_broadcast_is_stored_once() {
    // A duplicated status broadcast: every board caches it once.
    let mut cfg = seed(3);
    cfg.faults = FaultPlan::new().once(status_broadcasts(0), PacketFault::Duplicate);
    let report = run(&cfg).report;
    assert_eq!(report.boards_ok, 3);
    assert!(report.faults[0].detected());
}

#[test]
fn disconnect_and_reconnect_reset_the_bus_mid_cycle() {
    let mut cfg = seed(4);
    // Unplug board 2 (and board 1 and 0 behind it) 10 us into the cycle,
    // plug it back 300 us later.
    let run0 = run(&cfg);
    let board2 = run0.boards[2];
    cfg.faults = FaultPlan::new().at(
        SimTime(SimDuration::from_micros(10).0),
        TimedFault::Disconnect {
            node: board2,
            reconnect_after: Some(SimDuration::from_micros(300)),
        },
    );
    let mut run = run(&cfg);
    assert!(run.report.boards_ok < 4);
    assert!(!run.report.errors.is_empty());
    run.port_mut()
        .bus_mut()
        .run_for(SimDuration::from_micros(1000));
    let bus = run.port().bus();
    let f = &bus.fault_log().records()[0];
    let resets: Vec<u32> = f
        .evidence
        .iter()
        .filter_map(|e| match e.kind {
            EvidenceKind::BusReset { generation } => Some(generation),
            _ => None,
        })
        .collect();
    let g = run0.port().bus().generation();
    assert_eq!(resets, vec![g + 1, g + 2]);
    assert_eq!(bus.node_count(), 5);
    assert!(bus.node::<HostLink>(run.pc).unwrap().resets() >= 3);
}

#[test]
fn random_faults_are_deterministic_per_seed() {
    let run = |seed: u64| {
        let mut cfg = SimOptions::new(8, Profile::Rev8, Protocol::Broadcast);
        cfg.seed = seed;
        cfg.faults = FaultPlan::new().rule(FaultRule::random(
            PacketMatch::any(),
            PacketFault::FlipBits { count: 2 },
            0.3,
        ));
        let r = run(&cfg);
        (r.port().bus().trace().clone(), r.report.faults.clone())
    };
    let (a, fa) = run(11);
    let (b, fb) = run(11);
    assert_eq!(a, b);
    assert_eq!(fa, fb);
    let (c, fc) = run(12);
    assert!(a != c || fa != fc);
    assert!(!fa.is_empty());
}
