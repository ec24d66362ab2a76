//! Property test: whatever nodes send and answer, the bus neither panics
//! nor stalls, and the same inputs give the same trace.

use crate::common;

use common::{Recorder, Reply};
use firelink_bus::fault::{FaultPlan, FaultRule, PacketFault, PacketMatch};
use firelink_bus::{
    ArbitrationClass, Bus, BusConfig, NodeConfig, NodeHandle, SimDuration, TransmitRequest,
};
use firelink_wire::packet::{Ack, Speed};
use proptest::prelude::*;

fn reply(kind: u8, bytes: &[u8]) -> Reply {
    match kind % 6 {
        0 => Reply::Complete,
        1 => Reply::Fixed(Ack::from(kind >> 4)),
        2 => Reply::Concatenated,
        3 => Reply::Split {
            delay_us: f64::from(kind) / 10.0,
        },
        4 => Reply::Garbage(bytes.to_vec()),
        _ => Reply::Silent,
    }
}

fn run(
    replies: &[(u8, Vec<u8>)],
    sends: &[(usize, u8, Vec<u8>, bool)],
    seed: u64,
) -> firelink_bus::trace::Trace {
    let mut bus = Bus::new(BusConfig {
        seed,
        cycle_master: seed % 2 == 0,
        ..BusConfig::default()
    });
    let nodes: Vec<NodeHandle> = replies
        .iter()
        .enumerate()
        .map(|(i, (k, b))| {
            bus.add(
                Recorder::new(&format!("n{i}"), reply(*k, b)),
                NodeConfig::board(),
            )
        })
        .collect();
    bus.daisy_chain(&nodes).unwrap();
    bus.set_fault_plan(FaultPlan::new().rule(FaultRule::random(
        PacketMatch::any(),
        PacketFault::FlipBits { count: 3 },
        0.2,
    )));
    bus.reset();
    for (who, class, packet, header_like) in sends {
        let node = nodes[who % nodes.len()];
        let mut packet = packet.clone();
        if *header_like && packet.len() >= 4 {
            // Aim at a real node now and then.
            packet[1] = 0xC0 | (packet[1] % nodes.len() as u8);
        }
        let class = match class % 3 {
            0 => ArbitrationClass::Fair,
            1 => ArbitrationClass::Priority,
            _ => ArbitrationClass::Isochronous,
        };
        bus.with_node::<Recorder, _>(node, |_, ctx| {
            ctx.transmit(TransmitRequest {
                packet,
                speed: Speed::S400,
                class,
                token: 1,
            })
        })
        .unwrap();
        bus.run_for(SimDuration::from_micros(3));
    }
    bus.run_for(SimDuration::from_millis(2));
    assert!(!bus.has_pending_traffic(), "the bus drained");
    bus.trace().clone()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn any_traffic_any_replies(
        replies in prop::collection::vec((any::<u8>(), prop::collection::vec(any::<u8>(), 0..64)), 1..6),
        sends in prop::collection::vec(
            (any::<usize>(), any::<u8>(), prop::collection::vec(any::<u8>(), 0..96), any::<bool>()),
            0..12,
        ),
        seed in any::<u64>(),
    ) {
        let a = run(&replies, &sends, seed);
        let b = run(&replies, &sends, seed);
        prop_assert_eq!(a, b);
    }
}
