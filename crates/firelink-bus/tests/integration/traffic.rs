//! Packets, acks, concatenated and split responses, arbitration classes,
//! speeds, the cycle master and robustness against garbage.

use crate::common;

use common::{Recorder, Reply, bwrite, packets_of, qread, qwrite, rec, send, send_fair};
use firelink_bus::host::{HostLink, Outcome};
use firelink_bus::trace::PacketKind;
use firelink_bus::{
    ArbitrationClass, Bus, BusConfig, NodeConfig, NodeHandle, SimDuration, SimTime,
};
use firelink_wire::packet::{Ack, Packet, Speed, Tcode};

/// PC (Recorder, root) - n0 - n1 - ... with the given reply for the nodes.
fn bus_with(n: usize, reply: Reply) -> (Bus, NodeHandle, Vec<NodeHandle>) {
    let mut bus = Bus::new(BusConfig::default());
    let pc = bus.add(Recorder::new("pc", Reply::Complete), NodeConfig::pc());
    let nodes: Vec<NodeHandle> = (0..n)
        .map(|i| {
            bus.add(
                Recorder::new(&format!("n{i}"), reply.clone()),
                NodeConfig::board(),
            )
        })
        .collect();
    let mut chain = vec![pc];
    chain.extend(&nodes);
    bus.daisy_chain(&chain).unwrap();
    bus.reset();
    bus.trace_mut().clear();
    (bus, pc, nodes)
}

fn pc_phy(bus: &Bus, pc: NodeHandle) -> u8 {
    bus.phy_id(pc).unwrap()
}

#[test]
fn broadcast_reaches_every_node_and_is_never_acked() {
    let (mut bus, pc, nodes) = bus_with(5, Reply::Fixed(Ack::Complete));
    let me = pc_phy(&bus, pc);
    send_fair(&mut bus, pc, qwrite(me, 63, 0x1800, 0x0001_00FF), 11);
    bus.run_for(SimDuration::from_micros(30));
    for &n in &nodes {
        assert_eq!(
            rec(&bus, n).received.len(),
            1,
            "every node receives the broadcast"
        );
    }
    assert!(
        rec(&bus, pc).received.is_empty(),
        "the sender does not receive itself"
    );
    // Nodes replied with an ack to a broadcast: the bus ignores it.
    assert!(packets_of(&bus, PacketKind::Ack).is_empty());
    assert_eq!(
        rec(&bus, pc).transmitted,
        vec![(rec(&bus, pc).transmitted[0].0, 11, None)]
    );
    assert!(bus.run_until_idle());
    assert!(bus.is_idle() && !bus.has_pending_traffic());
    // Farther nodes receive later, by the repeat delay per hop.
    let t: Vec<SimTime> = nodes.iter().map(|&n| rec(&bus, n).received[0].0).collect();
    for w in t.windows(2) {
        assert_eq!((w[1] - w[0]).as_nanos(), 144);
    }
}

#[test]
fn unicast_acks_follow_after_the_ack_gap() {
    for ack in [Ack::Complete, Ack::BusyX, Ack::DataError, Ack::TypeError] {
        let (mut bus, pc, nodes) = bus_with(2, Reply::Fixed(ack));
        let me = pc_phy(&bus, pc);
        let dst = bus.phy_id(nodes[0]).unwrap();
        send_fair(&mut bus, pc, qwrite(me, dst, 0, 1), 3);
        bus.run_for(SimDuration::from_micros(30));
        let packets = bus.trace().packets();
        assert_eq!(packets.len(), 2);
        let (req, a) = (&packets[0], &packets[1]);
        assert_eq!(a.kind, PacketKind::Ack);
        assert_eq!(a.ack(), Some(ack));
        assert_eq!(a.answers, Some(req.id));
        // Ack starts one hop plus the ack gap after the request ends.
        assert_eq!((a.start - req.end).as_nanos(), 144 + 40);
        // An ack is 8 bits at the request's speed inside prefix and end.
        assert_eq!(a.duration().as_nanos(), 140 + 20 + 240);
        let (when, token, got) = rec(&bus, pc).transmitted[0];
        assert_eq!((token, got), (3, Some(ack)));
        assert_eq!(when, a.bits_end + SimDuration::from_nanos(144));
    }
}

#[test]
fn no_ack_from_an_absent_or_silent_node() {
    let (mut bus, pc, nodes) = bus_with(2, Reply::Silent);
    let me = pc_phy(&bus, pc);
    // To a silent node.
    let dst = bus.phy_id(nodes[1]).unwrap();
    send_fair(&mut bus, pc, qwrite(me, dst, 0, 1), 1);
    // To an ID nobody has.
    send_fair(&mut bus, pc, qwrite(me, 40, 0, 1), 2);
    bus.run_for(SimDuration::from_micros(200));
    let t = &rec(&bus, pc).transmitted;
    assert_eq!(
        t.iter().map(|x| (x.1, x.2)).collect::<Vec<_>>(),
        vec![(1, None), (2, None)]
    );
    assert!(packets_of(&bus, PacketKind::Ack).is_empty());
    assert_eq!(
        bus.trace()
            .entries()
            .iter()
            .filter(|e| matches!(e.event, firelink_bus::trace::TraceEvent::NoAck { .. }))
            .count(),
        2
    );
}

#[test]
fn concatenated_response_needs_no_arbitration_split_does() {
    let span = |reply: Reply| {
        let (mut bus, pc, nodes) = bus_with(1, reply);
        let me = pc_phy(&bus, pc);
        let dst = bus.phy_id(nodes[0]).unwrap();
        send(&mut bus, pc, qread(me, dst, 4), ArbitrationClass::Fair, 1);
        bus.run_for(SimDuration::from_micros(200));
        let packets = bus.trace().packets().to_vec();
        let kinds: Vec<PacketKind> = packets.iter().map(|p| p.kind).collect();
        let resp = packets
            .iter()
            .find(|p| p.tcode() == Some(Tcode::ReadQuadletResponse))
            .unwrap()
            .clone();
        // The PC acks the response with ack_complete.
        let last = packets.last().unwrap();
        assert_eq!(last.ack(), Some(Ack::Complete));
        assert_eq!(
            rec(&bus, nodes[0]).response_acks.len(),
            usize::from(resp.kind == PacketKind::ConcatResponse)
        );
        (kinds, (last.end - packets[0].start).as_micros_f64(), resp)
    };
    let (kinds, concat_us, resp) = span(Reply::Concatenated);
    assert_eq!(
        kinds,
        vec![
            PacketKind::Request,
            PacketKind::Ack,
            PacketKind::ConcatResponse,
            PacketKind::Ack
        ]
    );
    assert!(resp.arb_start.is_none());
    let (kinds, split_us, resp) = span(Reply::Split { delay_us: 0.0 });
    assert_eq!(
        kinds,
        vec![
            PacketKind::Request,
            PacketKind::Ack,
            PacketKind::Request,
            PacketKind::Ack
        ]
    );
    assert!(resp.arb_start.is_some());
    // The split response waits a subaction gap (10.5 us at gap count 63).
    assert!(split_us - concat_us > 10.0, "{split_us} vs {concat_us}");
    assert!(concat_us < 3.0, "{concat_us}");
}

#[test]
fn isochronous_style_requests_wait_only_the_iso_gap() {
    // Node n1 sends right after n0's broadcast, with each class.
    let wait = |class: ArbitrationClass| {
        let (mut bus, _pc, nodes) = bus_with(2, Reply::Silent);
        let a = bus.phy_id(nodes[0]).unwrap();
        let b = bus.phy_id(nodes[1]).unwrap();
        send(
            &mut bus,
            nodes[0],
            qwrite(a, 63, 0, 1),
            ArbitrationClass::Isochronous,
            1,
        );
        send(&mut bus, nodes[1], qwrite(b, 63, 0, 2), class, 2);
        bus.run_for(SimDuration::from_micros(100));
        let p = bus.trace().packets();
        assert_eq!(p.len(), 2);
        // Idle from the end of the first packet to the second's arbitration.
        (p[1].arb_start.unwrap() - p[0].end).as_micros_f64()
    };
    let iso = wait(ArbitrationClass::Isochronous);
    let pri = wait(ArbitrationClass::Priority);
    let fair = wait(ArbitrationClass::Fair);
    // Propagation to the farthest node (n0 sits in the middle: 1 hop) plus
    // the gap.
    assert!((iso - (0.144 + 0.04)).abs() < 0.01, "{iso}");
    assert!((pri - (0.144 + 10.53)).abs() < 0.02, "{pri}");
    assert!(
        (fair - pri).abs() < 1e-9,
        "first fair request of the interval"
    );
}

#[test]
fn fairness_interval_makes_a_second_fair_request_wait_the_arb_reset_gap() {
    let (mut bus, pc, nodes) = bus_with(1, Reply::Complete);
    let me = pc_phy(&bus, pc);
    let dst = bus.phy_id(nodes[0]).unwrap();
    send_fair(&mut bus, pc, qwrite(me, dst, 0, 1), 1);
    send_fair(&mut bus, pc, qwrite(me, dst, 0, 2), 2);
    send(
        &mut bus,
        pc,
        qwrite(me, dst, 0, 3),
        ArbitrationClass::Priority,
        3,
    );
    bus.run_for(SimDuration::from_micros(200));
    let req: Vec<_> = packets_of(&bus, PacketKind::Request);
    let acks: Vec<_> = packets_of(&bus, PacketKind::Ack);
    let idle = |i: usize| (req[i + 1].arb_start.unwrap() - acks[i].end).as_micros_f64() - 0.144;
    assert!(
        (idle(0) - 21.03).abs() < 0.05,
        "second fair waits the arbitration reset gap: {}",
        idle(0)
    );
    assert!(
        (idle(1) - 10.53).abs() < 0.05,
        "priority waits only a subaction gap: {}",
        idle(1)
    );
}

#[test]
fn transmission_time_follows_length_and_speed() {
    for (speed, bits_per_us) in [
        (Speed::S100, 98.304),
        (Speed::S200, 196.608),
        (Speed::S400, 393.216),
    ] {
        let (mut bus, pc, _nodes) = bus_with(1, Reply::Silent);
        let me = pc_phy(&bus, pc);
        let data = vec![0xA5; 1000];
        bus.with_node::<Recorder, _>(pc, |_, ctx| {
            ctx.transmit(firelink_bus::TransmitRequest {
                packet: bwrite(me, 63, 0, &data),
                speed,
                class: ArbitrationClass::Fair,
                token: 1,
            })
        })
        .unwrap();
        bus.run_for(SimDuration::from_micros(200));
        let p = &bus.trace().packets()[0];
        assert_eq!(p.bytes.len(), 20 + 1000 + 4);
        let expect = 0.14 + 1024.0 * 8.0 / bits_per_us + 0.24;
        assert!((p.duration().as_micros_f64() - expect).abs() < 1e-3);
    }
}

#[test]
fn slow_phy_on_the_path_blocks_faster_packets() {
    let mut bus = Bus::new(BusConfig::default());
    let pc = bus.add(Recorder::new("pc", Reply::Complete), NodeConfig::pc());
    let slow = bus.add(
        Recorder::new("slow", Reply::Complete),
        NodeConfig::board().with_speed(Speed::S200),
    );
    let far = bus.add(Recorder::new("far", Reply::Complete), NodeConfig::board());
    bus.daisy_chain(&[pc, slow, far]).unwrap();
    bus.reset();
    let me = bus.phy_id(pc).unwrap();
    send_fair(&mut bus, pc, qwrite(me, 63, 0, 1), 1);
    bus.run_for(SimDuration::from_micros(50));
    assert!(rec(&bus, slow).received.is_empty());
    assert!(
        rec(&bus, far).received.is_empty(),
        "repeated through an S200 PHY"
    );
}

#[test]
fn cycle_master_sends_cycle_starts_every_125_us_and_delays_async() {
    let cfg = BusConfig {
        cycle_master: true,
        ..BusConfig::default()
    };
    let mut bus = Bus::new(cfg);
    let pc = bus.add(Recorder::new("pc", Reply::Complete), NodeConfig::pc());
    let n = bus.add(Recorder::new("n", Reply::Complete), NodeConfig::board());
    bus.connect(pc, n).unwrap();
    bus.reset();
    bus.run_for(SimDuration::from_micros(1000));
    let starts: Vec<SimTime> = bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.kind == PacketKind::CycleStart)
        .map(|p| p.arb_start.unwrap())
        .collect();
    assert!(starts.len() >= 7);
    for w in starts.windows(2) {
        assert_eq!((w[1] - w[0]).as_micros_f64().round(), 125.0);
    }
    // The cycle start carries the cycle time and is broadcast.
    let cs = bus
        .trace()
        .packets()
        .iter()
        .find(|p| p.kind == PacketKind::CycleStart)
        .unwrap();
    let view = Packet::new_checked(&cs.bytes[..]).unwrap();
    assert_eq!(view.tcode(), Tcode::CycleStart);
    assert!(view.destination_id().is_broadcast());
    assert_eq!(view.header_crc_ok(), Some(true));
    assert_eq!(rec(&bus, n).received.len(), starts.len());
    // A request made just before a cycle tick goes after the cycle start.
    let tick = SimTime(starts.last().unwrap().0 + 125_000_000);
    bus.run_until(tick - SimDuration::from_nanos(5));
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(n).unwrap();
    send_fair(&mut bus, n, qwrite(dst, me, 0, 1), 9);
    bus.run_for(SimDuration::from_micros(50));
    let after: Vec<PacketKind> = bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.start >= tick - SimDuration::from_nanos(5))
        .map(|p| p.kind)
        .collect();
    assert_eq!(&after[..2], &[PacketKind::CycleStart, PacketKind::Request]);
}

#[test]
fn garbage_from_nodes_never_crashes_the_bus() {
    // A node answering with garbage "responses" of every odd shape.
    for garbage in [
        vec![],
        vec![0xFF],
        vec![0; 3],
        vec![0xAB; 5000],
        vec![0x12; 100_000],
    ] {
        let (mut bus, pc, nodes) = bus_with(2, Reply::Garbage(garbage));
        let me = pc_phy(&bus, pc);
        let dst = bus.phy_id(nodes[0]).unwrap();
        send(&mut bus, pc, qread(me, dst, 0), ArbitrationClass::Fair, 1);
        bus.run_for(SimDuration::from_micros(500));
        assert_eq!(rec(&bus, pc).transmitted.len(), 1);
    }
    // Nodes transmitting garbage: empty, short, unknown tcodes, huge.
    let (mut bus, pc, nodes) = bus_with(2, Reply::Complete);
    for (i, junk) in [
        vec![],
        vec![1u8, 2, 3],
        vec![0xFF; 64],
        vec![0x30; 17],
        vec![0; 9000],
    ]
    .into_iter()
    .enumerate()
    {
        send(
            &mut bus,
            nodes[1],
            junk,
            ArbitrationClass::Isochronous,
            i as u64,
        );
    }
    bus.run_for(SimDuration::from_micros(500));
    assert_eq!(rec(&bus, nodes[1]).transmitted.len(), 5);
    assert!(rec(&bus, pc).crc_errors >= 3);
    // Timers in the past fire at once; cancelled timers never fire.
    bus.with_node::<Recorder, _>(nodes[0], |_, ctx| {
        ctx.set_timer(SimTime::ZERO, 1);
        ctx.set_timer(ctx.now() + SimDuration::from_micros(1), 2);
        ctx.cancel_timer(2);
        ctx.set_timer(ctx.now() + SimDuration::from_micros(2), 3);
        ctx.set_timer(ctx.now() + SimDuration::from_micros(3), 3);
    })
    .unwrap();
    let now = bus.now();
    bus.run_for(SimDuration::from_micros(10));
    let fired: Vec<(f64, u64)> = rec(&bus, nodes[0])
        .timers
        .iter()
        .map(|(t, k)| (((*t - now).as_micros_f64()).round(), *k))
        .collect();
    assert_eq!(fired, vec![(0.0, 1), (3.0, 3)]);
}

#[test]
fn host_link_matches_responses_and_reports_outcomes() {
    let mut bus = Bus::new(BusConfig::default());
    let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
    let good = bus.add(
        Recorder::new("good", Reply::Concatenated),
        NodeConfig::board(),
    );
    let split = bus.add(
        Recorder::new("split", Reply::Split { delay_us: 3.0 }),
        NodeConfig::board(),
    );
    let busy = bus.add(
        Recorder::new("busy", Reply::Fixed(Ack::BusyX)),
        NodeConfig::board(),
    );
    bus.daisy_chain(&[pc, good, split, busy]).unwrap();
    bus.reset();
    let me = bus.phy_id(pc).unwrap();
    let mut tokens = Vec::new();
    for (dst, tl_packet) in [
        (
            bus.phy_id(good).unwrap(),
            qread(me, bus.phy_id(good).unwrap(), 0),
        ),
        (
            bus.phy_id(split).unwrap(),
            qread(me, bus.phy_id(split).unwrap(), 0),
        ),
        (
            bus.phy_id(busy).unwrap(),
            qwrite(me, bus.phy_id(busy).unwrap(), 0, 5),
        ),
        (63, qwrite(me, 63, 0, 5)),
        (50, qwrite(me, 50, 0, 5)),
    ] {
        let _ = dst;
        let t = bus
            .with_node::<HostLink, _>(pc, |l, ctx| l.submit(ctx, tl_packet, Speed::S400))
            .unwrap();
        tokens.push(t);
    }
    bus.run_for(SimDuration::from_micros(300));
    let link = bus.node_mut::<HostLink>(pc).unwrap();
    let outcomes: Vec<(Outcome, bool)> = tokens
        .iter()
        .map(|&t| {
            let c = link.take_completion(t).unwrap();
            (c.outcome, c.response.is_some())
        })
        .collect();
    assert_eq!(
        outcomes,
        vec![
            (Outcome::Complete, true),
            (Outcome::Complete, true),
            (Outcome::Busy, false),
            (Outcome::Complete, false),
            (Outcome::NoAck, false),
        ]
    );
    assert_eq!(link.pending_count(), 0);
}

#[test]
fn host_link_split_timeout_and_bus_reset_flush() {
    let mut bus = Bus::new(BusConfig::default());
    let pc = bus.add(
        HostLink::new("pc").with_split_timeout(SimDuration::from_micros(50)),
        NodeConfig::pc(),
    );
    let n = bus.add(
        Recorder::new("pending", Reply::Fixed(Ack::Pending)),
        NodeConfig::board(),
    );
    bus.connect(pc, n).unwrap();
    bus.reset();
    let me = bus.phy_id(pc).unwrap();
    let dst = bus.phy_id(n).unwrap();
    let t1 = bus
        .with_node::<HostLink, _>(pc, |l, ctx| l.submit(ctx, qread(me, dst, 0), Speed::S400))
        .unwrap();
    bus.run_for(SimDuration::from_micros(100));
    let c = bus
        .node_mut::<HostLink>(pc)
        .unwrap()
        .take_completion(t1)
        .unwrap();
    assert_eq!(c.outcome, Outcome::ResponseTimeout);
    // A request still queued when the bus resets is flushed.
    let t2 = bus
        .with_node::<HostLink, _>(pc, |l, ctx| l.submit(ctx, qread(me, dst, 0), Speed::S400))
        .unwrap();
    bus.initiate_reset(false);
    bus.run_for(SimDuration::from_micros(300));
    let c = bus
        .node_mut::<HostLink>(pc)
        .unwrap()
        .take_completion(t2)
        .unwrap();
    assert!(matches!(c.outcome, Outcome::NoAck | Outcome::BusReset));
    assert_eq!(bus.node::<HostLink>(pc).unwrap().resets(), 2);
}
