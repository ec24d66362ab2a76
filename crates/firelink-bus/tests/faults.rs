//! Every fault kind is injected, recorded, and detected downstream.

mod common;

use common::{Recorder, Reply, bwrite, qwrite, rec, send};
use firelink_bus::fault::{
    EvidenceKind, FaultPlan, FaultRule, PacketFault, PacketMatch, TimedFault,
};
use firelink_bus::host::{HostLink, Outcome};
use firelink_bus::scenario::{CycleConfig, MinimalBoard, Profile, Protocol, run_cycle};
use firelink_bus::trace::PacketKind;
use firelink_bus::{
    ArbitrationClass, Bus, BusConfig, NodeConfig, NodeHandle, SimDuration, SimTime,
};
use firelink_wire::packet::{Speed, Tcode};

/// PC (HostLink) and `n` minimal seed-profile boards in a chain.
fn boards(n: usize, seed: u64) -> (Bus, NodeHandle, Vec<NodeHandle>) {
    let mut bus = Bus::new(BusConfig {
        seed,
        ..BusConfig::default()
    });
    let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
    let mut nodes = Vec::new();
    for id in 0..n {
        nodes.push(bus.add(
            MinimalBoard::new(
                id as u8,
                Profile::Seed,
                ArbitrationClass::Isochronous,
                Speed::S400,
            ),
            NodeConfig::board(),
        ));
    }
    let mut chain = vec![pc];
    chain.extend(&nodes);
    bus.daisy_chain(&chain).unwrap();
    bus.reset();
    (bus, pc, nodes)
}

fn host_send(bus: &mut Bus, pc: NodeHandle, packet: Vec<u8>) -> u64 {
    bus.with_node::<HostLink, _>(pc, |l, ctx| l.submit(ctx, packet, Speed::S400))
        .unwrap()
}

fn outcome(bus: &mut Bus, pc: NodeHandle, token: u64) -> Outcome {
    bus.node_mut::<HostLink>(pc)
        .unwrap()
        .take_completion(token)
        .unwrap()
        .outcome
}

fn only_fault(bus: &Bus) -> firelink_bus::fault::FaultRecord {
    let records = bus.fault_log().records();
    assert_eq!(records.len(), 1, "{records:?}");
    records[0].clone()
}

#[test]
fn drop_unicast_is_detected_by_the_missing_ack() {
    let (mut bus, pc, nodes) = boards(2, 1);
    bus.set_fault_plan(FaultPlan::new().once(PacketMatch::any().from(pc), PacketFault::Drop));
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(nodes[0]).unwrap();
    let t = host_send(&mut bus, pc, qwrite(me, dst, 0, 1));
    bus.run_for(SimDuration::from_micros(50));
    assert_eq!(outcome(&mut bus, pc, t), Outcome::NoAck);
    let f = only_fault(&bus);
    assert_eq!(f.what, "drop");
    assert!(f.evidence.iter().any(|e| e.kind == EvidenceKind::NoAck));
    // The dropped packet still took its wire time, but nobody received it.
    let p = bus.trace().packet(f.packet.unwrap()).unwrap();
    assert_eq!(p.faults, vec![0]);
    assert_eq!(bus.node::<MinimalBoard>(nodes[0]).unwrap().stats.writes, 0);
}

#[test]
fn drop_broadcast_is_detected_by_the_host_hub_check() {
    let mut cfg = CycleConfig::new(4, Profile::Seed, Protocol::Broadcast);
    cfg.faults = FaultPlan::new().once(
        PacketMatch::any()
            .tcode(Tcode::WriteBlockRequest)
            .to_phy(63)
            .skip(1),
        PacketFault::Drop,
    );
    let mut run = run_cycle(&cfg);
    assert_eq!(run.report.boards_ok, 3);
    assert!(
        run.report
            .errors
            .iter()
            .any(|e| e.contains("no fresh data"))
    );
    // Broadcasts have no ack: the host library records what it detected.
    let id = run.report.faults[0].id;
    run.bus
        .record_detection(id, run.pc, "hub data missing a board");
    assert!(run.bus.fault_log().undetected().is_empty());
}

#[test]
fn flipped_bits_fail_the_crc_downstream() {
    // Unicast: header or data CRC fails at the receiver -> no ack or
    // ack_data_error, whichever bits were hit.
    for seed in 0..20 {
        let (mut bus, pc, nodes) = boards(2, seed);
        bus.set_fault_plan(FaultPlan::new().once(
            PacketMatch::any().from(pc),
            PacketFault::FlipBits { count: 1 },
        ));
        let me = bus.phy_id(pc).unwrap();
        let dst = bus.phy_id(nodes[1]).unwrap();
        let t = host_send(&mut bus, pc, bwrite(me, dst, 0, &[1, 2, 3, 4, 5, 6, 7, 8]));
        bus.run_for(SimDuration::from_micros(100));
        let o = outcome(&mut bus, pc, t);
        assert!(
            matches!(o, Outcome::NoAck | Outcome::AckError),
            "seed {seed}: {o:?}"
        );
        let f = only_fault(&bus);
        assert!(f.what.starts_with("flip bits"));
        assert!(f.detected(), "seed {seed}: {f:?}");
    }
    // Broadcast query: every board notices the corrupt query.
    let mut cfg = CycleConfig::new(4, Profile::Seed, Protocol::Broadcast);
    cfg.faults = FaultPlan::new().once(
        PacketMatch::any().offset(0x1800),
        PacketFault::CorruptQuadlet { index: 3, xor: 1 },
    );
    let report = run_cycle(&cfg).report;
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
fn corrupt_data_quadlet_gets_ack_data_error() {
    let (mut bus, pc, nodes) = boards(1, 0);
    bus.set_fault_plan(FaultPlan::new().once(
        PacketMatch::any().from(pc).tcode(Tcode::WriteBlockRequest),
        PacketFault::CorruptQuadlet {
            index: 5,
            xor: 0x0100_0000,
        },
    ));
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(nodes[0]).unwrap();
    let t = host_send(&mut bus, pc, bwrite(me, dst, 0, &[0; 16]));
    bus.run_for(SimDuration::from_micros(50));
    assert_eq!(outcome(&mut bus, pc, t), Outcome::AckError);
    let f = only_fault(&bus);
    assert!(
        f.evidence
            .iter()
            .any(|e| e.kind == EvidenceKind::ErrorAck(0xD))
    );
    assert_eq!(
        bus.node::<MinimalBoard>(nodes[0]).unwrap().stats.crc_errors,
        1
    );
}

#[test]
fn delayed_status_broadcast_arrives_late_and_boards_notice() {
    let mut cfg = CycleConfig::new(4, Profile::Seed, Protocol::Broadcast);
    cfg.faults = FaultPlan::new().once(
        PacketMatch::any()
            .tcode(Tcode::WriteBlockRequest)
            .to_phy(63)
            .skip(1),
        PacketFault::Delay(SimDuration::from_micros(8)),
    );
    let base = run_cycle(&CycleConfig::new(4, Profile::Seed, Protocol::Broadcast)).report;
    let run = run_cycle(&cfg);
    let f = &run.report.faults[0];
    assert!(f.what.starts_with("delay"));
    assert!(
        f.evidence
            .iter()
            .any(|e| matches!(&e.kind, EvidenceKind::Report(t) if t.contains("after its slot")))
    );
    // The delayed packet really started later.
    let delayed = run
        .bus
        .trace()
        .packets()
        .iter()
        .find(|p| p.faults.contains(&f.id))
        .unwrap();
    assert!(delayed.start - delayed.arb_start.unwrap() < SimDuration::from_micros(3));
    assert!(run.report.phase_us("broadcast").unwrap() >= base.phase_us("broadcast").unwrap());
}

#[test]
fn duplicates_are_noticed() {
    // A duplicated unicast write: the board sees the same request twice.
    let (mut bus, pc, nodes) = boards(1, 0);
    bus.set_fault_plan(FaultPlan::new().once(PacketMatch::any().from(pc), PacketFault::Duplicate));
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(nodes[0]).unwrap();
    let t = host_send(&mut bus, pc, bwrite(me, dst, 0, &[9; 8]));
    bus.run_for(SimDuration::from_micros(100));
    assert_eq!(outcome(&mut bus, pc, t), Outcome::Complete);
    let board = bus.node::<MinimalBoard>(nodes[0]).unwrap();
    assert_eq!((board.stats.writes, board.stats.duplicates), (2, 1));
    let f = only_fault(&bus);
    assert!(
        f.evidence
            .iter()
            .any(|e| matches!(&e.kind, EvidenceKind::Report(t) if t.contains("duplicate")))
    );
    let dups = bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.kind == PacketKind::Duplicate)
        .count();
    assert_eq!(dups, 1);
    // A duplicated status broadcast: every board caches it once.
    let mut cfg = CycleConfig::new(3, Profile::Seed, Protocol::Broadcast);
    cfg.faults = FaultPlan::new().once(
        PacketMatch::any()
            .tcode(Tcode::WriteBlockRequest)
            .to_phy(63),
        PacketFault::Duplicate,
    );
    let report = run_cycle(&cfg).report;
    assert_eq!(report.boards_ok, 3);
    assert!(report.faults[0].detected());
}

#[test]
fn lost_or_corrupt_ack_is_a_missing_ack_for_the_sender() {
    for fault in [PacketFault::DropAck, PacketFault::CorruptAck] {
        let (mut bus, pc, nodes) = boards(1, 0);
        bus.set_fault_plan(FaultPlan::new().once(PacketMatch::any().from(pc), fault.clone()));
        let me = bus.phy_id(pc).unwrap();
        let dst = bus.phy_id(nodes[0]).unwrap();
        let t = host_send(&mut bus, pc, qwrite(me, dst, 0, 1));
        bus.run_for(SimDuration::from_micros(50));
        assert_eq!(outcome(&mut bus, pc, t), Outcome::NoAck, "{fault:?}");
        // The board did take the write: only the ack was hit.
        assert_eq!(bus.node::<MinimalBoard>(nodes[0]).unwrap().stats.writes, 1);
        let f = only_fault(&bus);
        assert!(f.evidence.iter().any(|e| e.kind == EvidenceKind::NoAck));
        let ack = bus
            .trace()
            .packets()
            .iter()
            .find(|p| p.kind == PacketKind::Ack)
            .unwrap();
        assert_eq!(ack.ack().is_none(), fault == PacketFault::CorruptAck);
    }
    // A concatenated read whose ack is lost still delivers its response.
    let (mut bus, pc, nodes) = boards(1, 0);
    bus.set_fault_plan(FaultPlan::new().once(PacketMatch::any().from(pc), PacketFault::DropAck));
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(nodes[0]).unwrap();
    let t = host_send(&mut bus, pc, common::qread(me, dst, 4));
    bus.run_for(SimDuration::from_micros(50));
    let c = bus
        .node_mut::<HostLink>(pc)
        .unwrap()
        .take_completion(t)
        .unwrap();
    assert!(c.response.is_some());
    assert_eq!(c.ack, None);
}

#[test]
fn disconnect_and_reconnect_reset_the_bus_mid_cycle() {
    let mut cfg = CycleConfig::new(4, Profile::Seed, Protocol::Broadcast);
    // Unplug board 2 (and board 1 and 0 behind it) 10 us into the cycle,
    // plug it back 300 us later.
    let run0 = run_cycle(&cfg);
    let board2 = run0.boards[2];
    cfg.faults = FaultPlan::new().at(
        SimTime(SimDuration::from_micros(10).0),
        TimedFault::Disconnect {
            node: board2,
            reconnect_after: Some(SimDuration::from_micros(300)),
        },
    );
    let mut run = run_cycle(&cfg);
    assert!(run.report.boards_ok < 4);
    assert!(!run.report.errors.is_empty());
    run.bus.run_for(SimDuration::from_micros(1000));
    let f = &run.bus.fault_log().records()[0];
    let resets: Vec<u32> = f
        .evidence
        .iter()
        .filter_map(|e| match e.kind {
            EvidenceKind::BusReset { generation } => Some(generation),
            _ => None,
        })
        .collect();
    let g = run0.bus.generation();
    assert_eq!(resets, vec![g + 1, g + 2]);
    assert_eq!(run.bus.node_count(), 5);
    assert!(run.bus.node::<HostLink>(run.pc).unwrap().resets() >= 3);
}

#[test]
fn a_node_that_stops_answering_is_detected_by_missing_acks() {
    let (mut bus, pc, nodes) = boards(2, 0);
    let start = bus.now();
    bus.schedule_fault(
        start,
        TimedFault::StopAnswering {
            node: nodes[1],
            duration: Some(SimDuration::from_micros(100)),
        },
    );
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(nodes[1]).unwrap();
    bus.run_for(SimDuration::from_nanos(1));
    let t = host_send(&mut bus, pc, qwrite(me, dst, 0, 1));
    bus.run_for(SimDuration::from_micros(50));
    assert_eq!(outcome(&mut bus, pc, t), Outcome::NoAck);
    let f = only_fault(&bus);
    assert!(f.evidence.iter().any(|e| e.kind == EvidenceKind::NoAck));
    // After the outage it answers again.
    bus.run_for(SimDuration::from_micros(100));
    let t = host_send(&mut bus, pc, qwrite(me, dst, 0, 1));
    bus.run_for(SimDuration::from_micros(50));
    assert_eq!(outcome(&mut bus, pc, t), Outcome::Complete);
}

#[test]
fn a_babbling_node_starves_the_bus_and_receivers_reject_its_garbage() {
    let mut bus = Bus::new(BusConfig {
        seed: 5,
        ..BusConfig::default()
    });
    let pc = bus.add(Recorder::new("pc", Reply::Complete), NodeConfig::pc());
    let a = bus.add(Recorder::new("a", Reply::Complete), NodeConfig::board());
    let babbler = bus.add(
        Recorder::new("babbler", Reply::Complete),
        NodeConfig::board(),
    );
    bus.daisy_chain(&[pc, a, babbler]).unwrap();
    bus.reset();
    let t0 = bus.now();
    bus.schedule_fault(
        t0,
        TimedFault::Babble {
            node: babbler,
            duration: SimDuration::from_micros(40),
            packet_len: 64,
        },
    );
    bus.run_for(SimDuration::from_nanos(1));
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(a).unwrap();
    send(
        &mut bus,
        pc,
        qwrite(me, dst, 0, 1),
        ArbitrationClass::Fair,
        1,
    );
    bus.run_for(SimDuration::from_micros(100));
    let babble = bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.kind == PacketKind::Babble)
        .count();
    assert!(babble >= 12, "{babble}");
    let req = bus
        .trace()
        .packets()
        .iter()
        .find(|p| p.kind == PacketKind::Request && p.sender == pc.0)
        .unwrap();
    assert!(
        req.start >= t0 + SimDuration::from_micros(40),
        "the PC waited for the babble to end"
    );
    assert!(rec(&bus, a).crc_errors >= 12);
    let f = only_fault(&bus);
    assert!(f.detected());
    assert_eq!(
        rec(&bus, pc).transmitted[0].2,
        Some(firelink_wire::packet::Ack::Complete)
    );
}

#[test]
fn random_faults_are_deterministic_per_seed() {
    let run = |seed: u64| {
        let mut cfg = CycleConfig::new(8, Profile::Rev8, Protocol::Broadcast);
        cfg.seed = seed;
        cfg.faults = FaultPlan::new().rule(FaultRule::random(
            PacketMatch::any(),
            PacketFault::FlipBits { count: 2 },
            0.3,
        ));
        let r = run_cycle(&cfg);
        (r.bus.trace().clone(), r.report.faults.clone())
    };
    let (a, fa) = run(11);
    let (b, fb) = run(11);
    assert_eq!(a, b);
    assert_eq!(fa, fb);
    let (c, fc) = run(12);
    assert!(a != c || fa != fc);
    assert!(!fa.is_empty());
}
