//! Identity, every register, the link rules and the real-time blocks, all
//! through request packets built as a host builds them.

use crate::common;

use common::*;
use firelink_board::qla::config::{BoardConfig, FpgaVersion, Hardware, Profile};
use firelink_board::qla::{Reply, RxError};
use firelink_board::time::SimDuration;
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, PacketRepr, Rcode};
use firelink_wire::qla::registers::DigitalOutWrite;

fn rig(profile: Profile) -> Rig {
    Rig::new(BoardConfig::new(5, Hardware::Qla1, profile), 2)
}

#[test]
fn identity_reads() {
    let profiles = [
        (Profile::Seed, 7),
        (Profile::Rev7, 7),
        (Profile::Rev8, 8),
        (Profile::Rev9, 9),
    ];
    for (profile, fw) in profiles {
        // A QLA1 on FPGA V1 or V2; a DQLA only on an FPGA V3, whose
        // ETH_STATUS bits 31:30 read 01.
        for (hw, code, axes, fpga, eth) in [
            (Hardware::Qla1, 0x514C_4131, 4, FpgaVersion::V1, 0),
            (Hardware::Qla1, 0x514C_4131, 4, FpgaVersion::V2, 0b10),
            (Hardware::Qla1, 0x514C_4131, 4, FpgaVersion::V3, 0b01),
            (Hardware::Dqla, 0x4451_4C41, 8, FpgaVersion::V3, 0b01),
        ] {
            let cfg = BoardConfig::new(9, hw, profile)
                .with_fpga(fpga)
                .with_git_desc(0x1234_5678);
            let mut r = Rig::new(cfg, 3);
            assert_eq!(r.read(4), code, "HW_VERSION");
            assert_eq!(r.read(7), fw, "FW_VERSION");
            assert_eq!(r.read(12) >> 30, eth, "ETH_STATUS {profile:?} {fpga:?}");
            // GIT_DESC exists from Rev 9 on (BoardRegs.v).
            let git = if fw >= 9 { 0x1234_5678 } else { 0 };
            assert_eq!(r.read(15), git, "GIT_DESC");
            let status = r.read(0);
            assert_eq!(status >> 28, axes, "number of axes");
            assert_eq!((status >> 24) & 0xF, 9, "board ID");
            // Power-up: power and relay off (bits 18, 16); a QLA1's
            // amplifiers off (3:0; a DQLA has its expanders there).
            assert_eq!(status & 0x0005_0000, 0);
            if hw == Hardware::Qla1 {
                assert_eq!(status & 0xF, 0);
            }
        }
    }
}

#[test]
fn board_registers() {
    let mut r = rig(Profile::Rev8);
    // WATCHDOG: power-up 0x1680, read/write.
    assert_eq!(r.read(3), 0x1680);
    assert_eq!(r.write(3, 0x0100), Some(Ack::Complete));
    assert_eq!(r.read(3), 0x0100);
    // TEMPERATURE: both sensors at ambient (25 C, 0.5 C per bit) at power-up.
    assert_eq!(r.read(5), 0x3232);
    // DIGITAL_OUT stores the raw bits written (extras §3): register 6 and
    // DIGITAL_IN 15:12 read them unmodified. The host means levels and
    // sends their complement (mask<<8 | (~bits & mask)).
    assert_eq!(r.read(6), 0, "power-up raw 0");
    let host = |mask, levels| DigitalOutWrite::levels(mask, levels).to_word();
    assert_eq!(host(0xF, 0b1010), 0x0F05);
    r.write(6, host(0xF, 0b1010));
    assert_eq!(r.read(6) & 0xF, 0b0101);
    assert_eq!((r.read(10) >> 12) & 0xF, 0b0101);
    r.write(6, host(0x1, 0)); // output 1 to level 0 (raw 1), others kept
    assert_eq!((r.read(10) >> 12) & 0xF, 0b0101);
    r.write(6, host(0x2, 0)); // output 2 to level 0 (raw 1)
    assert_eq!((r.read(10) >> 12) & 0xF, 0b0111);
    // Issue 13: writing 0x0F0E reads back 0xE (it used to read 0x1).
    r.write(6, 0x0F0E);
    assert_eq!(r.read(6), 0xE);
    assert_eq!((r.read(10) >> 12) & 0xF, 0xE);
    // DIGITAL_IN at rest: encoder lines at count 0 (A = B = 0, index 1).
    let din = r.read(10);
    assert_eq!((din >> 24) & 0xF, 0, "A lines");
    assert_eq!((din >> 20) & 0xF, 0, "B lines");
    assert_eq!((din >> 16) & 0xF, 0xF, "index lines");
    // IP_ADDR, little-endian, on an Ethernet-capable FPGA.
    r.write(11, 0x6400_FEA9);
    assert_eq!(r.read(11), 0x6400_FEA9);
    // Unmapped addresses (and spaces not modelled) read 0.
    for offset in [0x3000u64, 0x7000, 0x4100] {
        assert_eq!(r.read(offset), 0, "offset {offset:#x}");
    }
    // The main space decodes bits 7:0 only, and at Rev 8 spaces 9-15 read
    // as the main space (FPGA1394V2.v l.187-191).
    let status = r.read(0);
    for offset in [0x0100u64, 0x0F00, 0x9000, 0xC000, 0xF000] {
        assert_eq!(r.read(offset), status, "offset {offset:#x}");
    }
    // Channel 5 on a 4-axis board is unmapped.
    assert_eq!(r.read(0x50), 0);
    assert_eq!(r.read(0x55), 0);
    // A write to an unmapped address is acknowledged and ignored.
    assert_eq!(r.write(0x2000, 1), Some(Ack::Complete));
    // Only the low 16 bits of the offset are decoded.
    assert_eq!(r.read(0xFFFF_0000_0007), 8);
}

#[test]
fn ip_addr_absent_on_fpga_v1() {
    let mut r = Rig::new(
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev7).with_fpga(FpgaVersion::V1),
        0,
    );
    r.write(11, 0x6400_FEA9);
    assert_eq!(r.read(11), 0);
}

#[test]
fn phy_registers_through_phy_ctrl() {
    let mut r = rig(Profile::Rev8);
    // Read register 1 (gap count, power-up 63).
    r.write(1, 1);
    assert_eq!(r.read(1), 1);
    assert_eq!(r.read(2), 0x0100 | 0x3F);
    // Write the gap count, read it back.
    r.write(1, 0x1000 | (1 << 8) | 0x05);
    assert_eq!(r.phy.gap_count(), 5);
    r.write(1, 1);
    assert_eq!(r.read(2), 0x0105);
    // Register 0 holds the physical ID in bits 7:2.
    r.write(1, 0);
    assert_eq!(r.read(2), u32::from(r.node) << 2);
}

#[test]
fn axis_registers_at_rest() {
    let mut r = rig(Profile::Rev8);
    for axis in 1..=4u64 {
        let ch = axis << 4;
        let adc = r.read(ch);
        let current = adc_to_amps(adc);
        assert!(current.abs() < 0.01, "axis {axis} current {current}");
        let pot = adc >> 16;
        assert!((pot as i64 - 32768).abs() < 200, "pot {pot:#x}");
        assert_eq!(r.read(ch | 1), 0x8000, "DAC at zero current");
        assert_eq!(r.read(ch | 4), 0x80_0000, "preload neutral");
        let pos = r.read(ch | 5);
        assert_eq!(pos & 0x00FF_FFFF, 0x80_0000, "position neutral");
        assert_eq!(pos & 0x0100_0000, 0, "no overflow");
        // Rev 8: lines in bits 30:28 (index high at count 0).
        assert_eq!(pos >> 28, 0b100);
        // No edge yet: the firmware's power-up words (EncPeriod.v).
        assert_eq!(r.read(ch | 6), 0xCBFF_FFFF);
        assert_eq!(r.read(ch | 7), 0x43FF_FFFF);
        assert_eq!(r.read(ch | 9), 0x43FF_FFFF);
        assert_eq!(r.read(ch | 10), 0x83FF_FFFF);
        // MOTOR_CONFIG: current mode and voltage mode available, 2.5 ms
        // delay, 200 mA limit (MotorChannelQLA.v l.61).
        assert_eq!(r.read(ch | 11), 0x0378_0418);
        // MOTOR_STATUS: off, current control, command 0x8000.
        assert_eq!(r.read(ch | 12), 0x0010_8000);
        // Unmapped axis offsets.
        for off in [2u64, 3, 8, 13, 14, 15] {
            assert_eq!(r.read(ch | off), 0);
        }
    }
    // Writable axis registers.
    r.write(0x11, 0x8000_9000);
    assert_eq!(r.read(0x11), 0x9000);
    assert_eq!(r.read(0x1C) & 0xFFFF, 0x9000, "MOTOR_STATUS command");
    r.write(0x11, 0x0000_A000); // not valid: ignored
    assert_eq!(r.read(0x11), 0x9000);
    r.write(0x14, 0x12_3456);
    assert_eq!(r.read(0x14), 0x12_3456);
    assert_eq!(r.read(0x15) & 0x00FF_FFFF, 0x12_3456);
    // MOTOR_CONFIG: bits 25/24 load the delay and the limit.
    r.write(0x1B, (60 << 16) | 0x1000);
    assert_eq!(r.read(0x1B), 0x0378_0418, "nothing loaded");
    r.write(0x1B, 0x0300_0000 | (60 << 16) | 0x1000);
    assert_eq!(r.read(0x1B), 0x0300_0000 | (60 << 16) | 0x1000);
}

#[test]
fn rev7_has_no_motor_registers() {
    let mut r = rig(Profile::Rev7);
    assert_eq!(r.read(0x1B), 0);
    assert_eq!(r.read(0x1C), 0);
    // Rev 7 positions carry no line bits.
    assert_eq!(r.read(0x15), 0x80_0000);
}

#[test]
fn realtime_block_layouts() {
    for (profile, hw, size) in [
        (Profile::Rev7, Hardware::Qla1, 28),
        (Profile::Seed, Hardware::Qla1, 28),
        (Profile::Rev8, Hardware::Qla1, 32),
        (Profile::Rev8, Hardware::Dqla, 60),
        (Profile::Rev7, Hardware::Dqla, 52),
    ] {
        let mut r = Rig::new(BoardConfig::new(2, hw, profile), 1);
        let m = hw.axes();
        r.write((1 << 4) | 1, 0x8000_8123);
        r.write(0x14, 0x80_0010);
        r.wait(SimDuration::from_micros(100));
        let block = r.read_block(0, size);
        // Timestamp: clocks since power-up (the previous sample).
        let ts = block[0];
        assert!((f64::from(ts) - 100e-6 * 49.152e6).abs() < 2.0, "{ts}");
        assert_eq!(block[1], r.read(0), "STATUS");
        assert_eq!(block[2], r.read(10), "DIGITAL_IN");
        // Rev 8 QLA1: the data buffer's status in bits 31:16 (QLA.v).
        let databuf = if profile.is_rev8() && m == 4 {
            0x0400_0000
        } else {
            0
        };
        assert_eq!(block[3], r.read(5) | databuf, "TEMPERATURE");
        assert_eq!(block[4 + m] & 0x00FF_FFFF, 0x80_0010, "first ENC_POSITION");
        for k in 0..m {
            if profile.is_rev8() {
                assert_eq!(block[4 + 5 * m + k], 0x83FF_FFFF, "RUN before any edge");
                assert_eq!(block[4 + 4 * m + k], 0x43FF_FFFF, "QTR5 before any edge");
            } else {
                assert_eq!(block[4 + 5 * m + k] & 0x8000_0000, 0, "RUN no overflow");
                assert_ne!(
                    block[4 + 4 * m + k] & 0x8000_0000,
                    0,
                    "QTR5 overflow at rest"
                );
            }
        }
        if profile.is_rev8() {
            assert_eq!(block[4 + 6 * m] & 0xFFFF, 0x8123, "MOTOR_STATUS command");
        }
        // The timestamp restarts at every real-time read.
        r.wait(SimDuration::from_micros(10));
        let again = r.read_block(0, size);
        assert!((f64::from(again[0]) - 10e-6 * 49.152e6).abs() < 2.0);
    }
}

#[test]
fn link_rules() {
    let mut r = rig(Profile::Rev8);
    // Addressed to another node: silent, not applied.
    let p = quadlet_write(NodeId::local(7), 1, 0x11, 0x8000_9999);
    assert_eq!(r.deliver(&p), Reply::Silent);
    assert_eq!(r.read(0x11), 0x8000);
    // To another bus: only the physical ID counts (FireWire.v l.891).
    let p = quadlet_write(
        NodeId((0x123 << 6) | u16::from(r.node)),
        1,
        0x11,
        0x8000_9998,
    );
    assert_eq!(r.deliver(&p), Reply::Ack(Ack::Complete));
    assert_eq!(r.read(0x11), 0x9998);
    // Broadcast write: taken, never acknowledged.
    let p = quadlet_write(NodeId::BROADCAST, 2, 0x11, 0x8000_9999);
    assert_eq!(r.deliver(&p), Reply::Silent);
    assert_eq!(r.read(0x11), 0x9999);
    // A write to node 0 (not us) outside the snooped addresses: ignored.
    let p = quadlet_write(NodeId::local(0), 3, 0x11, 0x8000_7777);
    assert_eq!(r.deliver(&p), Reply::Silent);
    assert_eq!(r.read(0x11), 0x9999);
    // Reads to broadcast get nothing.
    let p = quadlet_read(NodeId::BROADCAST, 4, 0);
    assert_eq!(r.deliver(&p), Reply::Silent);
    // Lock requests get no acknowledge at all (FireWire.v l.893-919).
    let lock = {
        let mut p = block_write(r.dest(), 5, 0x11, &[1, 2]);
        p[3] = (p[3] & 0x0F) | 0x90;
        let mut pk = firelink_wire::packet::Packet::new_unchecked(&mut p[..]);
        pk.fill_header_crc();
        p
    };
    assert_eq!(r.deliver(&lock), Reply::Silent);
    // A response addressed to the board is taken and ignored.
    let resp = emit(&PacketRepr::WriteResponse {
        header: AsyncHeader::new(r.dest(), NodeId::local(HOST_PHY), 6),
        rcode: Rcode::Complete,
    });
    assert_eq!(r.deliver(&resp), Reply::Ack(Ack::Complete));
    // Truncated or garbage bytes: silent.
    assert_eq!(r.deliver(&[]), Reply::Silent);
    assert_eq!(r.deliver(&[0xFF, 0xC2]), Reply::Silent);
}

#[test]
fn block_read_lengths() {
    let mut r = rig(Profile::Rev8);
    let (rcode, data) = r.read_block_rcode(0, 0);
    assert_eq!((rcode, data.len()), (Rcode::Complete, 0));
    assert_eq!(r.read_block_rcode(0, 513).0, Rcode::AddressError);
    // A block read of the main space elsewhere reads the real-time block
    // from there (FireWire.v l.1306, l.1407): quadlet 4 on, the ADCs.
    let rt = r.read_block(0, 32);
    let regs = r.read_block(4, 4);
    assert_eq!(regs[0] & 0xFFFF_0000, rt[4] & 0xFFFF_0000, "axis 1 pot");
    // Other spaces read register by register.
    r.write(0x8000, 0x1234_5678);
    assert_eq!(r.read_block(0x8000, 2), vec![0x1234_5678, 0]);
    // A length that is not whole quadlets is answered with that many
    // bytes (FireWire.v l.1162).
    let tl = 9;
    let p = emit(&PacketRepr::ReadBlockRequest {
        header: AsyncHeader::new(r.dest(), NodeId::local(HOST_PHY), tl),
        offset: 0,
        data_length: 6,
        extended_tcode: 0,
    });
    let Reply::AckThenResponse { response, .. } = r.deliver(&p) else {
        panic!()
    };
    let repr = PacketRepr::parse_verified(&response).unwrap();
    let PacketRepr::ReadBlockResponse { rcode, data, .. } = repr else {
        panic!("{repr:?}")
    };
    assert_eq!((rcode, data.len()), (Rcode::Complete, 6));
}

#[test]
fn corrupted_packets_are_not_committed() {
    let mut r = rig(Profile::Rev8);
    // Rev 8 write block: header, 4 DACs, control.
    let block = [
        (5 << 8) | 6,
        0x8000_9000,
        0x8000_9001,
        0x8000_9002,
        0x8000_9003,
        0,
    ];
    let mut p = block_write(r.dest(), 1, 0, &block);
    // Flip one data bit: the data CRC fails.
    p[20 + 6] ^= 0x01;
    assert_eq!(r.deliver(&p), Reply::Ack(Ack::DataError));
    assert_eq!(r.fw.take_rx_error(), Some(RxError::DataCrc));
    assert_eq!(r.fw.take_rx_error(), None);
    assert_eq!(r.read(0x11), 0x8000, "nothing committed");
    // Flip a header bit of a quadlet write: acknowledged ack_data_error
    // as the firmware does (FireWire.v l.1090), not written (the firmware
    // writes it, l.1097; Firelink does only when told to).
    let mut p = quadlet_write(r.dest(), 2, 0x11, 0x8000_9000);
    p[15] ^= 0x10;
    assert_eq!(r.deliver(&p), Reply::Ack(Ack::DataError));
    assert_eq!(r.fw.take_rx_error(), Some(RxError::HeaderCrc));
    assert_eq!(r.read(0x11), 0x8000);
    // Corrupt the CRC itself.
    let mut p = quadlet_write(r.dest(), 3, 0x11, 0x8000_9000);
    p[16] ^= 0x80;
    assert_eq!(r.deliver(&p), Reply::Ack(Ack::DataError));
    assert_eq!(r.read(0x11), 0x8000);
    // The intact packet is applied.
    let p = block_write(r.dest(), 4, 0, &block);
    assert_eq!(r.deliver(&p), Reply::Ack(Ack::Complete));
    for k in 0..4 {
        assert_eq!(r.read(0x11 + (k << 4)), 0x9000 + k as u32);
    }
}

#[test]
fn write_blocks_rev7_and_rev8() {
    // Rev 7: 4 DACs (board ID in 27:24) + control, no header.
    let mut r = rig(Profile::Rev7);
    let id = 5u32 << 24;
    let block = [
        0x8000_8100 | id,
        0x8000_8200 | id,
        id, // not valid
        0x8000_8400 | id,
        0x000C_0000, // power on
    ];
    assert_eq!(r.write_block(0, &block), Some(Ack::Complete));
    assert_eq!(r.read(0x11), 0x8100);
    assert_eq!(r.read(0x21), 0x8200);
    assert_eq!(r.read(0x31), 0x8000);
    assert_eq!(r.read(0x41), 0x8400);
    assert_ne!(
        r.read(0) & (1 << 18),
        0,
        "power enabled by the control quadlet"
    );
    // The control quadlet cannot reboot (only bits 19:0 count).
    r.write_block(0, &[id, id, id, id, 0x0030_0000]);
    assert_ne!(r.read(0) & (1 << 18), 0);

    // Rev 8: a block naming another board is ignored.
    let mut r = rig(Profile::Rev8);
    let block = [(4 << 8) | 6, 0x8000_9000, 0, 0, 0, 0];
    r.write_block(0, &block);
    assert_eq!(r.read(0x11), 0x8000);
    let block = [(5 << 8) | 6, 0x8000_9000, 0, 0, 0, 0];
    r.write_block(0, &block);
    assert_eq!(r.read(0x11), 0x9000);
}

#[test]
fn garbage_never_panics() {
    // Deterministic xorshift: random packets and mutations of valid ones.
    let mut state = 0x1234_5678_9ABC_DEF0u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for profile in [Profile::Seed, Profile::Rev7, Profile::Rev8] {
        let mut r = rig(profile);
        let valid = [
            quadlet_write(r.dest(), 1, 0, 0x000C_0F0F),
            block_write(NodeId::BROADCAST, 2, 0x1000, &[0x0001_0021; 33]),
            block_write(r.dest(), 3, 0, &[0x0506, 1, 2, 3, 4, 5]),
            quadlet_write(NodeId::local(0), 4, 0x1800, 0x0001_FFFF),
            block_read(r.dest(), 5, 0x1000, 100),
        ];
        for i in 0..3000 {
            let mut p = if i % 2 == 0 {
                valid[(next() % valid.len() as u64) as usize].clone()
            } else {
                let len = (next() % 80) as usize;
                (0..len).map(|_| next() as u8).collect()
            };
            if !p.is_empty() {
                for _ in 0..(next() % 4) {
                    let at = (next() % p.len() as u64) as usize;
                    p[at] ^= 1 << (next() % 8);
                }
            }
            let _ = r.deliver(&p);
            let _ = r.fw.poll_transmit(r.now);
            r.fw.transmitted(r.now);
            r.wait(SimDuration::from_micros(next() % 50));
        }
    }
}

#[test]
fn reboot_restores_power_up_state() {
    let mut r = rig(Profile::Rev8);
    r.write(0, 0x000C_0000 | 0x0003_0000);
    r.write(3, 0x0200);
    r.write(0x11, 0x8000_9000);
    r.write(0x14, 0x12_3456);
    assert_ne!(r.read(0) & 0x0007_0000, 0);
    assert_eq!(r.write(0, 0x0030_0000), Some(Ack::Complete));
    assert_eq!(
        r.read(0) & 0x008F_CFFF,
        0,
        "power, relay, amps, flags cleared"
    );
    assert_eq!(r.read(3), 0x1680);
    assert_eq!(r.read(0x11), 0x8000);
    assert_eq!(r.read(0x14), 0x80_0000);
    assert_eq!(r.read(0x15) & 0x00FF_FFFF, 0x80_0000);
}

#[test]
fn switches_and_pot_follow_the_joint() {
    use firelink_board::plant::{SwitchParams, presets};
    let mut axis = presets::generic_motor();
    axis.load.initial_position = 0.5;
    axis.switches = SwitchParams {
        negative_limit: Some(-1.0),
        positive_limit: Some(0.4),
        home: Some(0.0),
    };
    let cfg = BoardConfig::new(1, Hardware::Qla1, Profile::Rev7).with_axis(2, axis.clone());
    let mut r = Rig::new(cfg, 0);
    let din = r.read(10);
    assert_eq!((din >> 4) & 0xF, 0b0100, "positive limit on axis 3");
    assert_eq!(din & 0xF, 0b0100, "home on axis 3");
    assert_eq!((din >> 8) & 0xF, 0, "no negative limit");
    // Pot: offset + gain * q, 16 bits over 4.5 V.
    let volts = axis.pot.offset_volts + axis.pot.volts_per_unit * 0.5;
    let pot = f64::from(r.read(0x30) >> 16) * 4.5 / 65535.0;
    assert!((pot - volts).abs() < 0.005, "{pot} vs {volts}");
}

#[test]
fn plugged_in_lines_read_in_digin() {
    // A dVRK PSM's second QLA1: instrument contact on bit 7 (positive
    // limit of axis 4), sterile adapter contact on bit 10 (negative limit
    // of axis 3).
    let cfg = BoardConfig::new(7, Hardware::Qla1, Profile::Rev8).with_input_lines(0x0480);
    let mut r = Rig::new(cfg, 2);
    assert_eq!(r.read(10) & 0x0FFF, 0x0480, "DIGIN");
    let mut r = rig(Profile::Rev8);
    assert_eq!(r.read(10) & 0x0FFF, 0, "nothing plugged in");
}
