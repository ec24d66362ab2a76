//! Issue 13: the reference dVRK host's request sequences, replayed as raw
//! datagrams against the bridge (no sockets, virtual time), checking the
//! Rev 8 firmware behaviour of `fpga-board-extras.md` item by item.

use crate::common;

use common::{RefHost, bridge};
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
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
        let rig = firelink_board::qla::rig::BoardRig::daisy_chain(
            boards,
            &firelink_board::qla::rig::RigOptions::default(),
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
        // With the no-forward bit (discovery) the bridge answers alone.
        let a = host.try_qread(63, true, 4).expect("HW_VERSION");
        assert_eq!(a.quadlets[0], 0x514C_4131);
        assert_eq!(host.bridge.stats().broadcast_reads, 1);
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

/// The reference host's PROM command over Ethernet: write PROM_CMD, sleep
/// `PromDelay` (1 ms), then poll PROM_CMD up to 8 times 10 us apart until
/// bits 2:0 are 0, and read PROM_RESULT.
fn prom_command(host: &mut RefHost, node: u8, word: u32) -> u32 {
    assert_eq!(host.qwrite(node, 8, word), Handled::Written);
    host.sleep_us(1_000);
    let mut idle = false;
    for _ in 0..8 {
        host.sleep_us(10);
        if host.qread(node, 8) & 0x7 == 0 {
            idle = true;
            break;
        }
    }
    assert!(idle, "command {word:#010x} failed to finish");
    host.qread(node, 9)
}

/// `PromReadData(addr, n)`: per 64-byte chunk a read command (result must
/// be 64 quadlets) and a block read of space 2.
fn prom_read(host: &mut RefHost, node: u8, address: u32, bytes: usize) -> Vec<u8> {
    let mut out = Vec::new();
    let mut at = address;
    while out.len() < bytes {
        let n = (bytes - out.len()).min(64);
        assert_eq!(
            prom_command(host, node, 0x0300_0000 | at),
            64,
            "4 x result == 256"
        );
        let q = host.bread(node, 0x2000, n as u16);
        out.extend(q.iter().flat_map(|q| q.to_be_bytes()));
        at += n as u32;
    }
    out
}

/// Repeat "read status" until the whole status byte is 0.
fn prom_wait_status_zero(host: &mut RefHost, node: u8) {
    for _ in 0..5_000 {
        if prom_command(host, node, 0x0500_0000) & 0xFF == 0 {
            return;
        }
        host.sleep_us(1_000);
    }
    panic!("PROM status never cleared");
}

/// Item 4: the FPGA configuration PROM: read ID, read status,
/// `GetFPGASerialNumber` (unique per board by default, the configured one
/// when set), then `pgm1394`: program a new serial (erase sector
/// `0x1F0000`, page program at `0x1FFF00`) and its self-test (erase
/// `0x1E0000`, program 0..255 at `0x1EFF00`, read back).
#[test]
fn fpga_prom_and_serial_number() {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_fpga_serial("5496-12"),
        BoardConfig::new(2, Hardware::Qla1, Profile::Rev8),
    ];
    let mut host = RefHost::new(bridge(boards));
    assert_eq!(
        prom_command(&mut host, 0, 0x9F00_0000),
        0x0020_2015,
        "JEDEC ID"
    );
    assert_eq!(prom_command(&mut host, 0, 0x0500_0000), 0, "status");
    let mut serials = Vec::new();
    for node in 0..3u8 {
        let sn = prom_read(&mut host, node, 0x1F_FF00, 16);
        assert_eq!(&sn[..5], b"FPGA ");
        let end = sn.iter().position(|b| *b == 0xFF).unwrap_or(16);
        serials.push(String::from_utf8(sn[5..end].to_vec()).unwrap());
    }
    assert_eq!(serials[1], "5496-12");
    assert_ne!(serials[0], serials[2], "defaults are unique per board");
    // The same board gives the same default every run.
    let mut again = RefHost::new(bridge(qla1(1)));
    let sn = prom_read(&mut again, 0, 0x1F_FF00, 16);
    assert_eq!(&sn[5..12], serials[0].as_bytes());
    // pgm1394: program "FPGA 1234-56" on board 2.
    prom_command(&mut host, 2, 0x0600_0000);
    prom_command(&mut host, 2, 0xD81F_0000);
    prom_wait_status_zero(&mut host, 2);
    assert_eq!(
        prom_read(&mut host, 2, 0x1F_FF00, 16),
        vec![0xFF; 16],
        "erased"
    );
    prom_command(&mut host, 2, 0x0600_0000);
    let page = [0x021F_FF00, 0x4650_4741, 0x2031_3233, 0x342D_3536];
    assert_eq!(host.bwrite(2, 0x2000, &page), Handled::Written);
    host.sleep_us(1_000);
    let status = host.qread(2, 8);
    assert_eq!(status & 0xF, 0, "stream done: {status:#x}");
    assert_eq!(status >> 24, 0, "no stream error");
    assert_eq!(host.qread(2, 9), 4, "n/4 + 1 quadlets sent");
    prom_wait_status_zero(&mut host, 2);
    let sn = prom_read(&mut host, 2, 0x1F_FF00, 16);
    assert_eq!(&sn, b"FPGA 1234-56\xFF\xFF\xFF\xFF");
    // The self-test: 256 bytes 0..255 at 0x1EFF00 in one stream.
    prom_command(&mut host, 2, 0x0600_0000);
    prom_command(&mut host, 2, 0xD81E_0000);
    prom_wait_status_zero(&mut host, 2);
    let data: Vec<u8> = (0..=255u8).collect();
    let mut stream = vec![0x021E_FF00u32];
    stream.extend(
        data.chunks(4)
            .map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]])),
    );
    prom_command(&mut host, 2, 0x0600_0000);
    assert_eq!(host.bwrite(2, 0x2000, &stream), Handled::Written);
    host.sleep_us(1_000);
    assert_eq!(host.qread(2, 9), 65);
    prom_wait_status_zero(&mut host, 2);
    assert_eq!(prom_read(&mut host, 2, 0x1E_FF00, 256), data);
    // A stream out of order is refused with the error info.
    prom_command(&mut host, 2, 0x0600_0000);
    assert_eq!(host.bwrite(2, 0x2001, &[0x1234_5678]), Handled::Written);
    assert_ne!(
        host.qread(2, 8) >> 24,
        0,
        "error info after an out-of-order quadlet"
    );
}

/// Item 4: the QLA PROM: `GetQLASerialNumber` (block read of 3 quadlets at
/// 0: `514C4120 31323334 2D353600` for `QLA 1234-56`), byte read and byte
/// write, block write and read, and a DQLA's two QLAs on channels 1 and 2.
#[test]
fn qla_prom_and_serial_number() {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8).with_qla_serial(0, "1234-56"),
        BoardConfig::new(1, Hardware::Dqla, Profile::Rev8)
            .with_qla_serial(0, "4980-07")
            .with_qla_serial(1, "4980-08"),
    ];
    let mut host = RefHost::new(bridge(boards));
    let block_read = |host: &mut RefHost, node: u8, channel: u64, n: u32| {
        host.qwrite(node, 0x3000 | channel << 4, 0xFE00_0000 | (n - 1));
        host.sleep_us(1_000);
        host.bread(node, 0x3100 | channel << 4, (4 * n) as u16)
    };
    assert_eq!(
        block_read(&mut host, 0, 0, 3),
        vec![0x514C_4120, 0x3132_3334, 0x2D35_3600]
    );
    let text = |q: Vec<u32>| -> String {
        let b: Vec<u8> = q.iter().flat_map(|q| q.to_be_bytes()).collect();
        String::from_utf8(b)
            .unwrap()
            .trim_end_matches(['\0', '\u{ff}'])
            .to_string()
    };
    assert_eq!(text(block_read(&mut host, 1, 1, 3)), "QLA 4980-07");
    assert_eq!(text(block_read(&mut host, 1, 2, 3)), "QLA 4980-08");
    // Byte read: command, delay, result bits 7:0.
    host.qwrite(0, 0x3000, 0x0300_0100);
    host.sleep_us(1_000);
    assert_eq!(host.qread(0, 0x3002) & 0xFF, u32::from(b'L'));
    // Byte write as the tools write the serial: enable, 100 us, byte, 5 ms.
    for (i, b) in b"QLA 9999-99\0".iter().enumerate() {
        host.qwrite(0, 0x3000, 0x0600_0000);
        host.sleep_us(100);
        host.qwrite(0, 0x3000, 0x0200_0000 | (i as u32) << 8 | u32::from(*b));
        host.sleep_us(5_000);
    }
    assert_eq!(text(block_read(&mut host, 0, 0, 3)), "QLA 9999-99");
    // Block write: data to the buffer, enable, page write.
    host.bwrite(0, 0x3100, &[0xCAFE_F00D, 0x0123_4567]);
    host.qwrite(0, 0x3000, 0x0600_0000);
    host.qwrite(0, 0x3000, 0xFF00_4001);
    host.sleep_us(5_000);
    host.qwrite(0, 0x3000, 0xFE00_4001);
    host.sleep_us(1_000);
    assert_eq!(host.bread(0, 0x3100, 8), vec![0xCAFE_F00D, 0x0123_4567]);
    // Status reads through 0x3001 (idle) and the status command.
    assert_eq!(host.qread(0, 0x3001) & 0x7, 0);
    host.qwrite(0, 0x3000, 0x0500_0000);
    assert_eq!(host.qread(0, 0x3002) & 0x3, 0, "no write in progress");
}

/// Item 4: the DS2505 interface: power-up status, `DallasReadTool` without
/// an instrument (enabled, idle, no presence pulse: "997" missing) and with
/// one (family 0x0B, the tool's record).
#[test]
fn dallas_interface_with_and_without_a_tool() {
    use firelink_board::qla::Instrument;
    let tool = Instrument {
        model: 420_006,
        version: 12,
        name: "PROGRASP FORCEPS".into(),
    };
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_instrument(tool),
    ];
    let mut host = RefHost::new(bridge(boards));
    assert_eq!(
        host.qread(0, 13),
        0x00FF_0008,
        "power-up (bidirectional DOUT)"
    );
    let read_tool = |host: &mut RefHost, node: u8| -> (u32, Vec<u8>) {
        host.qwrite(node, 13, 0x0080_0002);
        let mut status = 0;
        for _ in 0..10_000 {
            status = host.qread(node, 13);
            if status & 0x20F0 == 0 {
                break;
            }
            host.sleep_us(1_000);
        }
        assert_eq!(status & 0x20F0, 0, "interface idle within 10 s");
        let data = host.bread(node, 0x6000, 256);
        (status, data.iter().flat_map(|q| q.to_be_bytes()).collect())
    };
    let (status, data) = read_tool(&mut host, 0);
    assert_eq!(
        status & 0xFF00_FFFF,
        0x0000_000F,
        "enabled, no presence: {status:#x}"
    );
    assert_eq!((status >> 1) & 3, 3);
    assert_ne!(&data[..3], b"997", "no tool: DALLAS_DATA_ERROR");
    let (status, data) = read_tool(&mut host, 1);
    assert_eq!(
        status & 0xFF00_FFFF,
        0x0B00_000B,
        "tool present: {status:#x}"
    );
    assert_eq!(&data[..3], b"997");
    let model = u32::from_be_bytes([data[0x24], data[0x25], data[0x26], data[0x27]]);
    assert_eq!(model, 420_006);
    assert_eq!(data[0x28], 12);
    assert!(data[0xE0..].starts_with(b"PROGRASP FORCEPS\0"));
    // DallasReadMemory(0, 2048): first read, then 7 next reads.
    host.qwrite(1, 13, 0x0000_0002);
    let mut all = Vec::new();
    for k in 0..8 {
        if k > 0 {
            host.qwrite(1, 13, 0x0000_0003);
        }
        host.sleep_us(300_000);
        assert_eq!(host.qread(1, 13) & 0x20F0, 0);
        all.extend(host.bread(1, 0x6000, 256));
    }
    let bytes: Vec<u8> = all.iter().flat_map(|q| q.to_be_bytes()).collect();
    assert_eq!(&bytes[0x80..0x83], b"997");
    assert_eq!(bytes.len(), 2048);
}

/// Item 4: the I/O expander, fpgatest `m` (STATUS bit 12 first; register
/// 14 read after each write), which prints rather than judges: the reads
/// carry the `010` marker and the answer to the last read command.
#[test]
fn io_expander_fpgatest_m() {
    let mut host = RefHost::new(bridge(qla1(1)));
    assert_ne!(
        host.qread(0, 0) & (1 << 12),
        0,
        "STATUS bit 12: expander present"
    );
    assert_eq!(host.qread(0, 14), 0, "0 until the first write with ID 0");
    let mut after = |word: u32| {
        host.qwrite(0, 14, word);
        host.qread(0, 14)
    };
    assert_eq!(after(0x1345) >> 29, 0b010);
    // Register 0x13 is not a port register: it reads 0.
    assert_eq!(after(0x9300), 0x4000_9300);
    for i in 0..10u32 {
        let r = after(0x8000 | i << 8);
        assert_eq!(r, 0x4000_8001 | i << 8, "port {i}");
    }
    assert_eq!(after(0x8E00), 0x4000_8EFF, "ports 7:0");
    // Port 8 = safety feedback inverted (relay off: 1), port 9 = the supply
    // comparator (power off: 0).
    assert_eq!(after(0x8F00), 0x4000_8F01);
    assert_eq!(after(0x4000_0000), 0x0000_FFFF, "debug read-out");
    assert_eq!(after(0xC000_0000), 0x0000_FFFF);
}

/// Item 4: the Ethernet status and debug window of the FPGA V2 bridge
/// board: fpgatest `6`/`z` KSZ8851 reads through register 12, the healthy
/// UDP link `0xA01C0000 | data`, the port status, `"DBG0"` (a Rev 8 V2 has
/// no debug data) and the last packet received; a board behind it has no
/// link.
#[test]
fn ethernet_status_and_debug_window() {
    let mut host = RefHost::new(bridge(qla1(2)));
    let ksz = |host: &mut RefHost, node: u8, reg: u32| {
        host.qwrite(node, 12, 0x0100_0000 | reg << 16);
        let s = host.qread(node, 12);
        assert_eq!(s >> 30, 0b10, "present, no request error: {s:#x}");
        s
    };
    let s = ksz(&mut host, 0, 0xC0);
    assert_eq!(s & 0xFFFF_0000, 0xA01C_0000, "healthy UDP link: {s:#x}");
    assert_eq!(s & 0xFFF0, 0x8870);
    for (reg, mask, value) in [
        (0x10u32, 0xFFFF, 0x9400),
        (0x12, 0xFFFF, 0x0E13),
        (0x14, 0xFFFF, 0xFA61),
        (0x84, 0x4000, 0x4000),
        (0x70, 0x1FF, 0x1EF),
        (0x86, 0x4000, 0x4000),
        (0x9C, 0xFF, 1),
        (0x74, 0xFFFF, 0x7CE1),
        (0xA2, 0xFFFF, 0x0008),
        (0x82, 0x3F7, 0x020),
        (0x90, 0xFFFF, 0xA000),
        (0xF8, 0x2660, 0x0660),
    ] {
        assert_eq!(
            ksz(&mut host, 0, reg) & mask,
            value,
            "KSZ register {reg:#x}"
        );
    }
    // MAC low word names the board; board 1 has no link.
    assert_eq!(ksz(&mut host, 1, 0x10) & 0xFFFF, 0x9401);
    let s = ksz(&mut host, 1, 0xF8);
    assert_eq!(s & (1 << 19), 0, "no link on board 1");
    assert_eq!(s & 0xFFFF, 0);
    // The window: 0x80-0x9F read "DBG0" ("No debug data available").
    let dbg = host.bread(0, 0x4080, 32 * 4);
    assert!(dbg.iter().all(|q| *q == 0x3047_4244));
    // 0x00-0x7F: the last FireWire packet received over Ethernet, which
    // is this very block read request.
    let w = host.bread(0, 0x4000, 5 * 4);
    assert_eq!(w[0] >> 16, 0xFFC0, "destination of the request");
    assert_eq!((w[0] >> 4) & 0xF, 5, "tcode 5: block read request");
    assert_eq!(w[1], 0xFFD0_0000, "source 0xFFD0, offset high 0");
    assert_eq!(w[2], 0x4000, "offset low");
    assert_eq!(w[3] >> 16, 20, "data length");
}

/// Item 4: the motor supply voltage (`MeasureMotorSupplyVoltage`): relay
/// and power on, amplifiers off, 1 s, STATUS bit 19; then DAC steps on
/// axis 4 with the comparator in DIGIN bit 28; power off at the end. Each
/// board's supply is within 10 % of what dvrktest expects for its ID.
#[test]
fn motor_supply_comparator() {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(4, Hardware::Qla1, Profile::Rev8),
    ];
    let mut host = RefHost::new(bridge(boards));
    for (node, nominal) in [(0u8, 24.0), (1, 12.0), (2, 36.0)] {
        assert_eq!(host.qread(node, 7), 8, "Rev 8");
        assert_ne!(host.qread(node, 0) & (1 << 12), 0);
        // Power off: no supply, comparator 0 whatever the DAC.
        host.qwrite(node, 0x41, 0x8000_0000);
        host.sleep_us(1_000);
        assert_eq!(host.qread(node, 10) & (1 << 28), 0);
        host.qwrite(node, 0, 0x0003_0000);
        host.qwrite(node, 0, 0x000C_0000);
        host.qwrite(node, 0, 0x0000_0F00);
        host.sleep_us(1_000_000);
        assert_ne!(host.qread(node, 0) & (1 << 19), 0, "supply good");
        let below = |host: &mut RefHost, v: u32| {
            host.qwrite(node, 0x41, 0x8000_0000 | v);
            host.sleep_us(1_000);
            host.qread(node, 10) & (1 << 28) != 0
        };
        // The host's search: up by 0x1000 while below, then halve.
        let (mut v, mut step) = (0u32, 0x1000u32);
        loop {
            if below(&mut host, v) {
                v += step;
            } else if step == 1 || v == 0 {
                break;
            } else {
                v -= step;
                step /= 2;
                v += step;
            }
        }
        let volts = f64::from(v) * 2.5 / 65535.0 * 21.0;
        assert!(
            (volts - nominal).abs() < 0.1 * nominal,
            "board at node {node}: {volts:.2} V, nominal {nominal} V"
        );
        host.qwrite(node, 0x41, 0x8000_8000);
        host.qwrite(node, 0, 0x0008_0000);
        assert_eq!(host.qread(node, 10) & (1 << 28), 0, "power off");
    }
}

/// Item 5: fpgatest `f`: PHY registers 0-3 through PHY_CTRL / PHY_DATA,
/// each answer naming its register: node ID, gap count, `0xE2` (2 ports,
/// extended map) and `0x40` (S400, repeater delay 0).
#[test]
fn phy_registers_as_fpgatest_f_reads_them() {
    let mut host = RefHost::new(bridge(qla1(3)));
    for node in 0..3u8 {
        let mut regs = [0u32; 4];
        for (r, slot) in regs.iter_mut().enumerate() {
            host.qwrite(node, 1, r as u32);
            let data = host.qread(node, 2);
            assert_eq!((data >> 8) & 0xF, r as u32, "register number");
            *slot = data & 0xFF;
        }
        assert_eq!(regs[0] >> 2, u32::from(node), "node ID in 7:2");
        assert_eq!(regs[1] & 0x3F, 8, "gap count (Linux's, 3 hops)");
        assert_eq!(regs[2], 0xE2);
        assert_eq!(regs[3], 0x40);
    }
}

/// Item 6: block reads are answered as the firmware answers them, whole,
/// in one response, up to 2048 bytes (512 quadlets; the reference host's
/// loopback abort at 368 quadlets is its own buffer overrun); the first
/// size beyond, 2052 bytes, gets an error response and no data. Block
/// writes: up to 2024 bytes; 2028 is refused.
#[test]
fn largest_block_read_and_the_first_too_large() {
    let mut host = RefHost::new(bridge(qla1(1)));
    let table: Vec<u32> = (0..512u32).map(|i| 0x8000_0000 | i << 8).collect();
    for half in table.chunks(256).enumerate() {
        let at = 0x8000 + 256 * half.0 as u64;
        assert_eq!(host.bwrite(0, at, half.1), Handled::Written);
    }
    for quadlets in [360u16, 361, 367, 368, 506, 512] {
        let a = host.try_bread(0, 0x8000, quadlets * 4).expect("an answer");
        assert_eq!(a.rcode, firelink_wire::packet::Rcode::Complete);
        assert_eq!(a.quadlets.len(), usize::from(quadlets));
        assert_eq!(a.quadlets[..], table[..usize::from(quadlets)]);
        // One datagram: the response packet (20-byte header, data, data
        // CRC) and the 8 bytes of extra data.
        assert_eq!(a.len, 20 + 4 * usize::from(quadlets) + 4 + 8);
    }
    let a = host.try_bread(0, 0x8000, 2052).expect("an error answer");
    assert_ne!(a.rcode, firelink_wire::packet::Rcode::Complete);
    assert!(a.quadlets.is_empty());
    // Hub memory, 512 quadlets, in one read too.
    assert_eq!(host.bread(0, 0x1000, 2048).len(), 512);
    // Writes: the request memory (512 quadlets with header and CRCs) takes
    // 2024 bytes of data; a longer write is refused whole (the bridge
    // counts the refused transaction) and nothing of it is committed.
    let write: Vec<u32> = (0..507u32).map(|i| 0x8000_0000 | i).collect();
    assert_eq!(host.bwrite(0, 0x8000, &write[..506]), Handled::Written);
    assert_eq!(host.bread(0, 0x8000, 506 * 4), write[..506]);
    let failures = host.bridge.stats().bus_failures;
    assert!(matches!(
        host.bwrite(0, 0x8000 + 600, &write),
        Handled::Dropped(_)
    ));
    assert_eq!(host.bridge.stats().bus_failures, failures + 1);
    assert_eq!(host.bread(0, 0x8000 + 600, 4), vec![0], "not committed");
}
