//! Every fault kind is injected, recorded, and detected downstream, on a
//! bus of recording nodes (`common::Recorder`). Faults across a whole I/O
//! cycle of emulated boards and the host library are tested in
//! `firelink-testbed` (`tests/integration/sim_faults.rs`).

use crate::common;

use common::{Recorder, Reply, bwrite, qwrite, rec, send_fair};
use firelink_bus::fault::{EvidenceKind, FaultPlan, PacketFault, PacketMatch, TimedFault};
use firelink_bus::host::{HostLink, Outcome};
use firelink_bus::trace::PacketKind;
use firelink_bus::{Bus, BusConfig, NodeConfig, NodeHandle, SimDuration};
use firelink_wire::packet::{Ack, Speed, Tcode};

/// PC (HostLink) and `n` responders (writes acked, quadlet reads answered
/// concatenated) in a chain.
fn boards(n: usize, seed: u64) -> (Bus, NodeHandle, Vec<NodeHandle>) {
    let mut bus = Bus::new(BusConfig {
        seed,
        ..BusConfig::default()
    });
    let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
    let mut nodes = Vec::new();
    for id in 0..n {
        let reply = Reply::Board;
        nodes.push(bus.add(
            Recorder::new(&format!("board{id}"), reply),
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
    assert_eq!(rec(&bus, nodes[0]).writes(), 0);
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
    assert_eq!(rec(&bus, nodes[0]).crc_errors, 1);
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
    let board = rec(&bus, nodes[0]);
    assert_eq!((board.writes(), board.duplicates), (2, 1));
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
}

/// A quadlet write of `value` from the PC to `node`, the bus run 50 us:
/// its outcome.
fn write_outcome(bus: &mut Bus, pc: NodeHandle, node: NodeHandle, value: u32) -> Outcome {
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(node).unwrap();
    let t = host_send(bus, pc, qwrite(me, dst, 0, value));
    bus.run_for(SimDuration::from_micros(50));
    outcome(bus, pc, t)
}

#[test]
fn a_busy_addressee_takes_nothing_and_acknowledges_busy() {
    let (mut bus, pc, nodes) = boards(1, 0);
    bus.set_fault_plan(FaultPlan::new().once(PacketMatch::any().from(pc), PacketFault::AckBusy));
    assert_eq!(write_outcome(&mut bus, pc, nodes[0], 1), Outcome::Busy);
    // The board never took the write; the sender heard ack_busy_X.
    assert_eq!(rec(&bus, nodes[0]).writes(), 0);
    let acks: Vec<Option<Ack>> = bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.kind == PacketKind::Ack)
        .map(|p| p.ack())
        .collect();
    assert_eq!(acks, [Some(Ack::BusyX)]);
    assert!(only_fault(&bus).detected());
    // The next write (no fault left) is taken.
    assert_eq!(write_outcome(&mut bus, pc, nodes[0], 2), Outcome::Complete);
    assert_eq!(rec(&bus, nodes[0]).writes(), 1);
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
        assert_eq!(rec(&bus, nodes[0]).writes(), 1);
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
    send_fair(&mut bus, pc, qwrite(me, dst, 0, 1), 1);
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
