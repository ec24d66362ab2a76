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

/// Item 1: the output register stores the raw bits written. Writing
/// `0x0F0E` to register 6 reads back `0xE` there and in DIGIN bits 15:12
/// (it read `0x1` and DIGIN `0xF1000` when the emulator inverted on
/// write); the host's complemented write of levels reads back their
/// complement, which the host complements again.
#[test]
fn digital_outputs_store_the_raw_bits() {
    let mut host = RefHost::new(bridge(qla1(2)));
    for node in [0u8, 1] {
        assert_eq!(
            host.qread(node, 6),
            0,
            "power-up raw 0 (the host shows 0xF)"
        );
        host.qwrite(node, 6, 0x0F0E);
        assert_eq!(host.qread(node, 6), 0xE);
        let din = host.qread(node, 10);
        assert_eq!((din >> 12) & 0xF, 0xE, "DIGIN {din:#x}");
        assert_eq!(
            din & 0xFFFF_F000,
            0x000F_E000,
            "index lines high, outputs 0xE"
        );
        // WriteDigitalOutput(0x3, 0x1): mask 3, ~bits & mask = 0x2.
        host.qwrite(node, 6, 0x0302);
        assert_eq!(host.qread(node, 6) & 0xF, 0xE);
        assert_eq!(
            !host.qread(node, 6) & 0x3,
            0x1,
            "the host reads its levels back"
        );
    }
    // Only the written board changed.
    host.qwrite(1, 6, 0x0F00);
    assert_eq!(host.qread(0, 6) & 0xF, 0xE);
    assert_eq!(host.qread(1, 6) & 0xF, 0x0);
    // DOUT_CTRL (axis offset 8) reads back as written; WritePWM(1 kHz,
    // 25 %) sends low<<16 | high = 36864<<16 | 12288.
    for output in 1..=4u64 {
        host.qwrite(0, output << 4 | 8, 0x9000_3000);
        assert_eq!(host.qread(0, output << 4 | 8), 0x9000_3000);
    }
}

/// Item 1 (continued), the waveform table: fpgatest `B` (write `len`
/// entries of `(len+i)<<16 | (len-i)`, XOR 0xF on the wire, read them
/// back) for every length an Ethernet host sends, fpgatest `w` (256
/// entries `0x80C0000x`, 1 ms each, a final 0, read back whole ten
/// times), then playback started by `WriteWaveformControl(0x03, 0x03)`.
#[test]
fn waveform_table_written_read_back_and_played() {
    let mut host = RefHost::new(bridge(qla1(1)));
    for len in 2..=360u32 {
        let entries: Vec<u32> = (0..len)
            .map(|i| ((len + i) << 16 | (len - i)) ^ 0xF)
            .collect();
        if len == 2 {
            assert_eq!(entries[0], 0x0002_000D, "the spec's wire value");
        }
        assert_eq!(host.bwrite(0, 0x8000, &entries), Handled::Written);
        let back = host.bread(0, 0x8000, (len * 4) as u16);
        assert_eq!(back, entries, "length {len}");
    }
    let table: Vec<u32> = (0..256u32)
        .map(|i| if i == 255 { 0 } else { 0x80C0_0000 | (i & 0xF) })
        .collect();
    assert_eq!(host.bwrite(0, 0x8000, &table), Handled::Written);
    for _ in 0..10 {
        assert_eq!(host.bread(0, 0x8000, 1024), table);
    }
    // Not playing: register 6 bit 31 clear, DIGIN bit 29 clear.
    assert_eq!(host.qread(0, 6) >> 31, 0);
    assert_eq!(host.qwrite(0, 6, 0x8000_0300), Handled::Written);
    let r6 = host.qread(0, 6);
    assert_eq!(r6 >> 30, 0b11, "playing, current entry valid: {r6:#x}");
    assert_ne!(host.qread(0, 10) & (1 << 29), 0, "DIGIN bit 29");
    // Each entry lasts 0xC000 + 1 clocks (1 ms): 10.5 ms later, entry 10.
    host.sleep_us(10_500);
    let r6 = host.qread(0, 6);
    assert_eq!((r6 >> 16) & 0x3FF, 10, "index: {r6:#x}");
    assert_eq!(r6 & 0x3, 10 & 0x3, "outputs 1-2 follow the table");
    // Reads of space 8 return the current playback entry.
    let now = host.bread(0, 0x8000 + 100, 8);
    assert!(now.iter().all(|e| e & 0xFF00_0000 == 0x8000_0000));
    // Entry 255 is invalid: playback ends after 255 ms and the outputs are
    // released (raw 0, as written with the start).
    host.sleep_us(250_000);
    let r6 = host.qread(0, 6);
    assert_eq!(r6 >> 31, 0, "stopped: {r6:#x}");
    assert_eq!((r6 >> 16) & 0x3FF, 255);
    assert_eq!(r6 & 0xF, 0);
    assert_eq!(host.qread(0, 10) & (1 << 29), 0);
    assert_eq!(host.bread(0, 0x8000, 1024), table, "addressed reads again");
}

/// Item 3: fpgatest `8`, a quadlet read of offset 0 to node 63 with the
/// no-forward bit clear (and a generation the host never learnt): one
/// answer, from the bridge's own registers (its STATUS, its board ID in
/// bits 27:24) with the bridge's FireWire node as source; the request also
/// goes onto FireWire, where no board answers it.
#[test]
fn broadcast_quadlet_read_is_answered_by_the_bridge_alone() {
    for bridge_id in [0usize, 2] {
        let boards = qla1(3);
        let rig = firelink_board::rig::BoardRig::daisy_chain(
            boards,
            &firelink_board::rig::RigOptions::default(),
        );
        let phy = rig.bus.phy_id(rig.boards[bridge_id]).unwrap();
        let b = firelink_emulate::Bridge::new(rig.bus, rig.host, rig.boards[bridge_id]);
        let mut host = RefHost::new(b);
        host.generation = host.generation.wrapping_add(7);
        let a = host
            .try_qread(63, false, 0)
            .expect("an answer to a node-63 read");
        assert_eq!(
            (a.quadlets[0] >> 24) & 0xF,
            bridge_id as u32,
            "bridge's STATUS"
        );
        assert_eq!(a.source.0, 0xFFC0 | u16::from(phy));
        assert_eq!(a.destination.0, 0xFFD0);
        let s = host.bridge.stats();
        assert_eq!((s.broadcast_reads, s.local, s.replies), (1, 1, 1));
        assert_eq!(s.dropped(), 0);
        // Nothing else came back: the next read answers normally.
        assert_eq!((host.qread(1, 0) >> 24) & 0xF, 1);
    }
}

/// Item 3 (continued): every reason a datagram is dropped is counted and
/// named in the stop line.
#[test]
fn every_drop_reason_is_counted_and_named() {
    use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};
    let mut host = RefHost::new(bridge(qla1(2)));
    // Malformed.
    assert!(matches!(host.send(&[0, 1, 2]), Handled::Dropped(_)));
    // Bad CRC.
    let repr = PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(NodeId(0xFFC0), NodeId(0xFFD0), 1),
        offset: 0,
    };
    let mut d = host.datagram(false, &repr);
    d[7] ^= 0x40; // a bit of the source ID: the header CRC fails
    assert!(matches!(host.send(&d), Handled::Dropped(_)));
    // Unsupported tcode (a response sent to the bridge).
    let response = PacketRepr::WriteResponse {
        header: AsyncHeader::new(NodeId(0xFFC0), NodeId(0xFFD0), 2),
        rcode: firelink_wire::packet::Rcode::Complete,
    };
    let d = host.datagram(false, &response);
    assert!(matches!(host.send(&d), Handled::Dropped(_)));
    // Stale generation.
    host.generation = host.generation.wrapping_add(1);
    assert!(host.try_qread(0, false, 0).is_none());
    host.generation = host.bridge.generation();
    // Bus failure: a node that is not there.
    assert!(host.try_qread(9, false, 0).is_none());
    let s = host.bridge.stats();
    assert_eq!(
        (
            s.malformed,
            s.bad_crc,
            s.unsupported,
            s.stale_generation,
            s.bus_failures
        ),
        (1, 1, 1, 1, 1)
    );
    assert_eq!(s.dropped(), 5);
    assert_eq!(s.accounted(), s.datagrams);
    let line = s.to_string();
    for words in [
        "5 dropped",
        "1 malformed",
        "1 bad CRC",
        "1 unsupported tcode",
        "1 stale generation",
        "1 bus failures",
    ] {
        assert!(line.contains(words), "{words:?} missing from {line:?}");
    }
}
