//! Bus reset, self-ID numbering, generations and the gap count.

use crate::common;

use common::{Recorder, Reply, packets_of, rec, send, send_fair};
use firelink_bus::phy::phy_config_packet;
use firelink_bus::trace::PacketKind;
use firelink_bus::{
    ArbitrationClass, Bus, BusConfig, BusError, NodeConfig, NodeHandle, SimDuration,
};

fn chain(n: usize) -> (Bus, Vec<NodeHandle>) {
    let mut bus = Bus::new(BusConfig::default());
    let nodes: Vec<NodeHandle> = (0..n)
        .map(|i| {
            bus.add(
                Recorder::new(&format!("n{i}"), Reply::Complete),
                NodeConfig::board(),
            )
        })
        .collect();
    bus.daisy_chain(&nodes).unwrap();
    (bus, nodes)
}

#[test]
fn daisy_chain_root_highest_far_end_zero() {
    let (mut bus, nodes) = chain(4);
    assert_eq!(bus.generation(), 0);
    assert_eq!(bus.phy_id(nodes[0]), None);
    bus.reset();
    assert_eq!(bus.generation(), 1);
    // nodes[0] is the root (first added): highest ID; the far end gets 0.
    let ids: Vec<u8> = nodes.iter().map(|&n| bus.phy_id(n).unwrap()).collect();
    assert_eq!(ids, vec![3, 2, 1, 0]);
    for (&n, &id) in nodes.iter().zip(&ids) {
        let r = rec(&bus, n);
        assert_eq!(r.phy_id, id);
        assert_eq!(r.resets.len(), 1);
        assert_eq!(r.resets[0].node_count, 4);
        assert_eq!(r.resets[0].root_phy_id, 3);
        assert_eq!(r.resets[0].generation, 1);
        // PHY register 0 carries the ID in bits 7:2, and R for the root.
        let reg0 = bus.phy_registers(n).unwrap().read(0);
        assert_eq!(reg0 >> 2, id);
        assert_eq!(reg0 & 2 != 0, id == 3);
    }
    // Self-ID packets are recorded in ID order.
    let sids: Vec<u8> = bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.kind == PacketKind::SelfId)
        .map(|p| p.sender_phy)
        .collect();
    assert_eq!(sids, vec![0, 1, 2, 3]);
    // A long reset takes the 166.7 us signal plus self-ID.
    assert!(bus.now().as_micros_f64() > 166.7 && bus.now().as_micros_f64() < 175.0);
}

#[test]
fn tree_numbering_and_set_root() {
    // A 3-port PC with two chains (seed 002's humanoid wiring).
    let mut bus = Bus::new(BusConfig::default());
    let a: Vec<NodeHandle> = (0..3)
        .map(|i| {
            bus.add(
                Recorder::new(&format!("a{i}"), Reply::Complete),
                NodeConfig::board(),
            )
        })
        .collect();
    let b: Vec<NodeHandle> = (0..2)
        .map(|i| {
            bus.add(
                Recorder::new(&format!("b{i}"), Reply::Complete),
                NodeConfig::board(),
            )
        })
        .collect();
    let pc = bus.add(Recorder::new("pc", Reply::Complete), NodeConfig::pc());
    bus.set_root(pc).unwrap();
    bus.tree_with_chains(pc, &[&a, &b]).unwrap();
    bus.reset();
    // Post-order, children in port order: chain a (far end first), then b.
    let order: Vec<NodeHandle> = vec![a[2], a[1], a[0], b[1], b[0], pc];
    assert_eq!(bus.nodes_by_phy(), order);
    assert_eq!(bus.phy_id(pc), Some(5));
    assert_eq!(bus.hops(a[2], b[1]), 5);
    assert_eq!(bus.root(), Some(pc));
}

#[test]
fn generation_increments_and_renumbers_on_connect_and_disconnect() {
    let (mut bus, nodes) = chain(3);
    bus.reset();
    let late = bus.add(Recorder::new("late", Reply::Complete), NodeConfig::board());
    assert_eq!(bus.phy_id(late), None);
    // Connecting after the bus started resets it.
    bus.connect(nodes[2], late).unwrap();
    bus.run_for(SimDuration::from_micros(400));
    assert_eq!(bus.generation(), 2);
    assert_eq!(bus.phy_id(late), Some(0));
    assert_eq!(bus.phy_id(nodes[2]), Some(1));
    assert_eq!(bus.phy_id(nodes[0]), Some(3));
    assert_eq!(rec(&bus, late).resets.len(), 1);
    // Disconnecting detaches the far part and renumbers the rest.
    bus.disconnect(nodes[1], nodes[2]).unwrap();
    bus.run_for(SimDuration::from_micros(400));
    assert_eq!(bus.generation(), 3);
    assert_eq!(bus.node_count(), 2);
    assert_eq!(bus.phy_id(nodes[2]), None);
    assert_eq!(bus.phy_id(late), None);
    assert_eq!(bus.phy_id(nodes[1]), Some(0));
    assert_eq!(rec(&bus, nodes[0]).resets.last().unwrap().node_count, 2);
    // A detached node cannot transmit: it is told at once.
    send_fair(&mut bus, late, common::qwrite(0, 1, 0, 0), 5);
    bus.run_for(SimDuration::from_micros(1));
    assert_eq!(rec(&bus, late).transmitted.last().unwrap().1, 5);
    assert_eq!(rec(&bus, late).transmitted.last().unwrap().2, None);
}

#[test]
fn topology_errors() {
    let (mut bus, nodes) = chain(3);
    assert!(matches!(
        bus.connect(nodes[0], nodes[2]),
        Err(BusError::Loop { .. }) | Err(BusError::NoFreePort(_))
    ));
    assert!(matches!(
        bus.connect(nodes[0], NodeHandle(99)),
        Err(BusError::NoSuchNode(99))
    ));
    assert!(matches!(
        bus.disconnect(nodes[0], nodes[2]),
        Err(BusError::NotConnected { .. })
    ));
    assert!(bus.node::<firelink_bus::HostLink>(nodes[0]).is_none());
    assert!(matches!(
        bus.with_node::<firelink_bus::HostLink, _>(nodes[0], |_, _| ()),
        Err(BusError::WrongNodeType(_))
    ));
    // 63 nodes fit on one bus, the 64th does not.
    let mut bus = Bus::new(BusConfig::default());
    let many: Vec<NodeHandle> = (0..64)
        .map(|i| {
            bus.add(
                Recorder::new(&format!("m{i}"), Reply::Silent),
                NodeConfig::board(),
            )
        })
        .collect();
    bus.daisy_chain(&many[..63]).unwrap();
    assert!(matches!(
        bus.connect(many[62], many[63]),
        Err(BusError::TooManyNodes(64))
    ));
    bus.reset();
    assert_eq!(bus.node_count(), 63);
    assert_eq!(bus.phy_id(many[0]), Some(62));
    assert_eq!(bus.phy_id(many[62]), Some(0));
}

#[test]
fn gap_count_by_phy_config_packet_survives_one_reset() {
    let (mut bus, nodes) = chain(4);
    bus.reset();
    for &n in &nodes {
        assert_eq!(bus.gap_count(n), Some(63));
    }
    let root = nodes[0];
    send_fair(&mut bus, root, phy_config_packet(Some(5), None), 1);
    bus.run_for(SimDuration::from_micros(20));
    for &n in &nodes {
        assert_eq!(
            bus.gap_count(n),
            Some(5),
            "every PHY takes the new gap count"
        );
        assert_eq!(bus.phy_registers(n).unwrap().read(1) & 0x3F, 5);
    }
    // PHY packets are never acked; the sender hears `None`.
    assert_eq!(rec(&bus, root).transmitted.last().unwrap().2, None);
    bus.reset();
    for &n in &nodes {
        assert_eq!(bus.gap_count(n), Some(5), "kept over the next reset");
    }
    bus.reset();
    for &n in &nodes {
        assert_eq!(
            bus.gap_count(n),
            Some(63),
            "back to 63 after a reset without a PHY config packet"
        );
    }
}

#[test]
fn gap_count_changes_subaction_gap_and_register_write_is_immediate() {
    // Two fair writes back to back from different nodes: the second waits a
    // subaction gap after the first subaction.
    let gap_between = |gap: Option<u8>| {
        let (mut bus, nodes) = chain(3);
        bus.reset();
        if let Some(g) = gap {
            send(
                &mut bus,
                nodes[0],
                phy_config_packet(Some(g), None),
                ArbitrationClass::Fair,
                1,
            );
            bus.run_for(SimDuration::from_micros(30));
        }
        bus.trace_mut().clear();
        let a = bus.phy_id(nodes[1]).unwrap();
        let b = bus.phy_id(nodes[2]).unwrap();
        send(
            &mut bus,
            nodes[2],
            common::qwrite(b, a, 0, 1),
            ArbitrationClass::Priority,
            1,
        );
        send(
            &mut bus,
            nodes[1],
            common::qwrite(a, b, 0, 2),
            ArbitrationClass::Priority,
            2,
        );
        bus.run_for(SimDuration::from_micros(100));
        let reqs: Vec<_> = packets_of(&bus, PacketKind::Request);
        let acks: Vec<_> = packets_of(&bus, PacketKind::Ack);
        assert_eq!(reqs.len(), 2);
        // From the end of the first ack to the second node's arbitration start.
        (reqs[1].arb_start.unwrap() - acks[0].end).as_micros_f64()
    };
    let g63 = gap_between(None);
    let g26 = gap_between(Some(26));
    let g5 = gap_between(Some(5));
    assert!((g63 - 10.53).abs() < 0.5, "{g63}");
    assert!((g26 - 4.51).abs() < 0.5, "{g26}");
    assert!((g5 - 1.09).abs() < 0.5, "{g5}");
    // A register write changes only that PHY, at once.
    let (mut bus, nodes) = chain(2);
    bus.reset();
    bus.with_node::<Recorder, _>(nodes[1], |_, ctx| {
        ctx.write_phy_register(1, 10);
        assert_eq!(ctx.read_phy_register(1) & 0x3F, 10);
    })
    .unwrap();
    assert_eq!(bus.gap_count(nodes[1]), Some(10));
    assert_eq!(bus.gap_count(nodes[0]), Some(63));
}

#[test]
fn ibr_register_write_resets_the_bus() {
    let (mut bus, nodes) = chain(2);
    bus.reset();
    bus.with_node::<Recorder, _>(nodes[1], |_, ctx| ctx.write_phy_register(1, 0x40 | 63))
        .unwrap();
    bus.run_for(SimDuration::from_micros(200));
    assert_eq!(bus.generation(), 2);
    // A short reset (ISBR) is much faster.
    bus.with_node::<Recorder, _>(nodes[1], |_, ctx| ctx.write_phy_register(5, 0x40))
        .unwrap();
    bus.run_for(SimDuration::from_micros(10));
    assert_eq!(bus.generation(), 3);
}

#[test]
fn force_root_by_phy_config_packet() {
    let (mut bus, nodes) = chain(3);
    bus.reset();
    // Make the far end (phy 0) root at the next reset.
    send(
        &mut bus,
        nodes[0],
        phy_config_packet(None, Some(0)),
        ArbitrationClass::Fair,
        1,
    );
    bus.run_for(SimDuration::from_micros(20));
    bus.reset();
    assert_eq!(bus.root(), Some(nodes[2]));
    assert_eq!(bus.phy_id(nodes[2]), Some(2));
    assert_eq!(bus.phy_id(nodes[0]), Some(0));
}
