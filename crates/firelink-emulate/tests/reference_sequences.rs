//! Issue 13: the reference dVRK host's request sequences, replayed as raw
//! datagrams against the bridge (no sockets, virtual time), checking the
//! Rev 8 firmware behaviour of `fpga-board-extras.md` item by item.

mod common;

use common::{RefHost, bridge};
use firelink_board::config::{BoardConfig, Hardware, Profile};
use firelink_emulate::Handled;

fn qla1(n: u8) -> Vec<BoardConfig> {
    (0..n)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
        .collect()
}

/// Item 2: a hub read sent straight after the query (the two datagrams
/// queued back to back: no virtual time passes between them) sees the
/// cycle of that query, at every board count the hub holds.
#[test]
fn hub_read_right_after_the_query_sees_its_cycle() {
    for boards in [1u8, 2, 4, 8, 15] {
        let mut host = RefHost::new(bridge(qla1(boards)));
        let mask = (1u32 << boards) - 1;
        // Rev 8 QLA1: hub header + 32-quadlet block per board, + timing
        // (2 boards: 67 quadlets).
        let hub_bytes = (33 * u16::from(boards) + 1) * 4;
        for seq in 1..=50u32 {
            assert_eq!(host.qwrite(63, 0x1800, seq << 16 | mask), Handled::Written);
            let hub = host.bread(0, 0x1000, hub_bytes);
            for b in 0..usize::from(boards) {
                let header = hub[b * 33];
                // size:8 | seq_low:8 | seq_error:1 | update_time:15
                assert_eq!(header >> 24, 33, "{boards} boards: block size");
                assert_eq!(
                    (header >> 16) & 0xFF,
                    seq & 0xFF,
                    "{boards} boards, cycle {seq}: board {b} still holds an older cycle"
                );
                assert_eq!(header & 0x8000, 0, "sequence error bit");
                // STATUS of the block names the board, in arrival order.
                assert_eq!((hub[b * 33 + 2] >> 24) & 0xF, b as u32);
            }
            // The timing quadlet is there: every board has updated.
            assert_ne!(hub[usize::from(boards) * 33], 0, "{hub:08x?}");
        }
    }
}
