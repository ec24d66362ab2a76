//! Issue 33 behind the bridge: the bus of `firelink emulate --detail
//! packet` answers every datagram as `--detail fast` does, byte for byte
//! (the reference host's broadcast cycles with status and block reads
//! between, in virtual time, no sockets), and the bridge's counters say
//! which level ran, each datagram one span.

use crate::common::{Answer, RefHost, bridge, qla1s};

use firelink_board::qla::config::Profile;
use firelink_bus::{Detail, SimDuration};
use firelink_emulate::BridgeStats;
use firelink_wire::qla::address::{HUB_MEMORY_OFFSET, HUB_QUERY_OFFSET};

const BOARDS: u8 = 8;
const CYCLES: u32 = 150;

/// What the reference host heard in `CYCLES` cycles against a bridge at
/// `detail`: every answer, and the counters.
fn run(detail: Detail) -> (Vec<Option<Answer>>, BridgeStats) {
    let mut b = bridge(qla1s(BOARDS, Profile::Rev8));
    b.bus_mut().set_detail(detail);
    let mut host = RefHost::new(b);
    let mut heard = Vec::new();
    let start = host.bridge.bus().now();
    for cycle in 0..CYCLES {
        host.bridge
            .advance_to(start + SimDuration::from_micros(166) * u64::from(cycle + 1));
        // The broadcast query (sequence, every board), then the hub.
        let query = ((cycle & 0xFFFF) << 16) | 0xFF;
        host.qwrite(63, HUB_QUERY_OFFSET, query);
        host.bridge.finish_pending();
        heard.push(host.try_bread(0, HUB_MEMORY_OFFSET, 4 * 8 * u16::from(BOARDS)));
        // A board's status and its real-time block, a different one each
        // cycle.
        let node = (cycle % u32::from(BOARDS)) as u8;
        heard.push(host.try_qread(node, false, 0));
        heard.push(host.try_bread(node, 0, 4 * 16));
    }
    let stats = host.bridge.stats();
    (heard, stats)
}

#[test]
fn the_bridge_answers_the_same_at_both_levels_and_counts_each_datagram() {
    let (fast, fast_stats) = run(Detail::Fast);
    let (packet, packet_stats) = run(Detail::Packet);
    assert_eq!(fast.len(), packet.len());
    for (i, (a, b)) in fast.iter().zip(&packet).enumerate() {
        assert_eq!(format!("{a:?}"), format!("{b:?}"), "answer {i}");
        assert!(a.is_some(), "answer {i}: every request is answered");
    }
    let same = |s: &BridgeStats| BridgeStats {
        detail: Default::default(),
        ..*s
    };
    assert_eq!(same(&fast_stats), same(&packet_stats));
    let datagrams = fast_stats.datagrams;
    assert_eq!(datagrams, u64::from(CYCLES) * 4);
    let f = fast_stats.detail;
    assert_eq!(f.detail, Detail::Fast);
    assert_eq!(f.fast_cycles + f.packet_level_cycles, datagrams, "{f}");
    assert_eq!(f.packet_level_cycles, 0, "no fault, no reset: {f}");
    assert!(f.fast_packets > datagrams, "{f}");
    let p = packet_stats.detail;
    assert_eq!(p.detail, Detail::Packet);
    assert_eq!(p.fast_cycles, 0, "{p}");
    assert_eq!(p.packet_level_cycles_why.chosen, datagrams, "{p}");
    assert_eq!(p.packet_level_packets(), f.fast_packets, "{p} / {f}");
    let line = fast_stats.to_string();
    assert!(
        line.contains(&format!(
            "detail fast: datagrams {datagrams} fast, 0 at the packet level"
        )),
        "{line}"
    );
}
