//! The FPGA1394/QLA board protocol end to end: worked examples from
//! `fpga-board.md`, a whole broadcast cycle between emulated boards and a
//! host, command-block slicing for 1..16 boards, and property tests (round
//! trips, and no parser panics on arbitrary bytes).
//!
//! Every vector here comes from the spec text (`fpga-board.md`, section
//! named next to it); none was captured from hardware.

use std::net::Ipv4Addr;
use std::vec::Vec;

use firelink_wire::Error;
use firelink_wire::field::{read_quadlet, write_quadlet};
use firelink_wire::qla::address::{
    Address, AddressSpace, AxisRegister, BoardRegister, COMMAND_SNOOP_OFFSET, HUB_QUERY_OFFSET,
    HubAddress, Register, STATUS_BROADCAST_OFFSET,
};
use firelink_wire::qla::broadcast::{
    BoardSlot, BroadcastHeader, CommandBlockWriter, HubBlock, HubHeader, HubPacker, HubTiming,
    Query, SeqRule, StatusBroadcast, StatusBroadcastRepr, command_block_quadlets, command_slices,
    emit_command_block, find_command_block, hub_block_quadlets, status_broadcast_offset,
};
use firelink_wire::qla::extras::{
    DallasControl, DallasStatus, EthControl, EthStatusV2, ExpanderDebug, ExpanderRead,
    ExpanderWrite, PromCommand, PromStatus, QlaPromCommand,
};
use firelink_wire::qla::realtime::{
    BlockFormat, BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr, WriteBlock, WriteBlockRepr,
};
use firelink_wire::qla::registers::{
    AdcWord, DAC_ZERO, DacWord, DigitalIn, DigitalOutRead, DigitalOutWrite, DoutCtrl, EncPeriod,
    EncPosition, EncPreload, EncQuarter, EncRun, FpgaVersion, GitDesc, HardwareVersion,
    MotorConfig, MotorStatus, PhyData, PhyRequest, STATUS_POWER_OFF, STATUS_POWER_ON,
    STATUS_RELAY_ON, StatusCommand, StatusRead, StatusWrite, Temperature, Watchdog, WaveformEntry,
    counts_from_offset_binary, ip_from_register, ip_to_register, offset_binary_from_counts,
};
use proptest::prelude::*;

const QLA1_REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
const QLA1_REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);
const DQLA_REV8: BoardLayout = BoardLayout::dqla(FirmwareRev::Rev8);

// ------------------------------------------------------- worked examples ---

#[test]
fn spec_block_sizes() {
    // §4: QLA1 Rev 7 = 28, Rev 8 = 32, DQLA Rev 8 = 60 quadlets.
    assert_eq!(QLA1_REV7.read_block_quadlets(), 28);
    assert_eq!(QLA1_REV8.read_block_quadlets(), 32);
    assert_eq!(DQLA_REV8.read_block_quadlets(), 60);
    // §5: QLA1 Rev 8 write block 6 quadlets, Rev 7 5.
    assert_eq!(QLA1_REV8.write_block_quadlets(), 6);
    assert_eq!(QLA1_REV7.write_block_quadlets(), 5);
    // §6.2: the broadcast is 33 quadlets for QLA1 Rev 8 (29 for Rev 7).
    assert_eq!(QLA1_REV8.broadcast_quadlets(), 33);
    assert_eq!(QLA1_REV7.broadcast_quadlets(), 29);
    // §6.4: two QLA1 Rev 8 boards: 67 quadlets = 268 bytes; Rev 7 29 x N + 1.
    assert_eq!(hub_block_quadlets([QLA1_REV8; 2]), 67);
    assert_eq!(hub_block_quadlets([QLA1_REV8; 2]) * 4, 268);
    for n in 1..=8 {
        assert_eq!(
            hub_block_quadlets(std::iter::repeat_n(QLA1_REV7, n)),
            29 * n + 1
        );
    }
}

#[test]
fn spec_status_write_constants() {
    // §2 "STATUS write".
    assert_eq!(StatusCommand::power(true).to_word().raw(), 0x000C_0000);
    assert_eq!(StatusCommand::power(false).to_word().raw(), 0x0008_0000);
    assert_eq!(StatusCommand::relay(true).to_word().raw(), 0x0003_0000);
    assert_eq!(StatusCommand::relay(false).to_word().raw(), 0x0002_0000);
    assert_eq!(StatusCommand::reboot().to_word().raw(), 0x0030_0000);
    for mask in 0..16u8 {
        for state in 0..16u8 {
            let state = state & mask;
            let word = StatusCommand::amplifiers(mask, state).to_word().raw();
            assert_eq!(word, u32::from(mask) << 8 | u32::from(state));
            assert_eq!(
                StatusCommand::parse(word),
                StatusCommand::amplifiers(mask, state)
            );
        }
    }
    assert_eq!(STATUS_POWER_ON, 0x000C_0000);
    assert_eq!(STATUS_POWER_OFF, 0x0008_0000);
    assert_eq!(STATUS_RELAY_ON, 0x0003_0000);
}

#[test]
fn spec_register_encodings() {
    // §2 IP_ADDR.
    assert_eq!(ip_to_register(Ipv4Addr::new(169, 254, 0, 100)), 0x6400_FEA9);
    // §2 HW_VERSION.
    assert_eq!(HardwareVersion::from(0x514C_4131).name(), "QLA1");
    assert_eq!(HardwareVersion::from(0x4451_4C41).name(), "DQLA");
    assert_eq!(HardwareVersion::from(0x6452_4131).name(), "dRA1");
    assert_eq!(&HardwareVersion::Dra1.fourcc(), b"dRA1");
    // §2 ETH_STATUS.
    assert_eq!(FpgaVersion::from_eth_status(0), Ok(FpgaVersion::V1));
    assert_eq!(
        FpgaVersion::from_eth_status(0x8000_0000),
        Ok(FpgaVersion::V2)
    );
    assert_eq!(
        FpgaVersion::from_eth_status(0x4000_0000),
        Ok(FpgaVersion::V3)
    );
    // §2 WATCHDOG: power-up 0x1680 = 30 ms.
    assert_eq!(
        Watchdog::from_period(std::time::Duration::from_millis(30)),
        Ok(Watchdog(0x1680))
    );
    // §2 PHY_CTRL.
    assert_eq!(
        PhyRequest::Write {
            register: 1,
            data: 0x3F
        }
        .to_word(),
        Ok(0x113F)
    );
    assert_eq!(PhyRequest::Read { register: 1 }.to_word(), Ok(1));
    // §2 DIGITAL_OUT: the host sends mask<<8 | (~bits & mask); the board
    // stores the raw bits (extras §3).
    assert_eq!(DigitalOutWrite::levels(0xF, 0x3).to_word(), 0x0F0C);
    assert_eq!(DigitalOutWrite::parse(0x0F0C).raw, 0xC);
    // §3 DAC zero, ENC neutral.
    assert_eq!(DacWord::valid_command(DAC_ZERO).raw(), 0x8000_8000);
    assert_eq!(counts_from_offset_binary(0x80_0000), 0);
}

#[test]
fn spec_addresses() {
    // §1: main space 0x00CO.
    assert_eq!(
        Register::from_offset(0x0000),
        Some(Register::Board(BoardRegister::Status))
    );
    assert_eq!(
        Register::from_offset(0x0031),
        Some(Register::axis(3, AxisRegister::Dac))
    );
    // §6: the query register, the status broadcast and command offsets.
    assert_eq!(
        Address::from_offset(HUB_QUERY_OFFSET).hub(),
        Some(HubAddress::Query)
    );
    assert_eq!(
        Address::from_offset(STATUS_BROADCAST_OFFSET).space,
        AddressSpace::Hub
    );
    assert_eq!(
        status_broadcast_offset(FirmwareRev::Rev7, 3),
        Ok(0xFFFF_FF00_1060)
    );
    assert_eq!(
        status_broadcast_offset(FirmwareRev::Rev8, 3),
        Ok(0xFFFF_FF00_1000)
    );
    assert_eq!(
        Register::from_offset(COMMAND_SNOOP_OFFSET),
        Some(Register::Board(BoardRegister::Status))
    );
}

/// A read block whose values tell board, axis and register apart.
fn board_state(layout: BoardLayout, id: u8) -> ReadBlockRepr {
    let mut r = ReadBlockRepr::new(layout);
    r.timestamp = 1000 + u32::from(id);
    r.status = StatusRead::default()
        .with_axes(layout.motors() as u8)
        .with_board_id(id)
        .with_motor_power_enabled(true);
    r.digital_in = DigitalIn::default().with_home(id & 0xF);
    r.temperature = Temperature::default().with_upper(30).with_lower(31);
    for (i, m) in r.motor.iter_mut().take(layout.motors()).enumerate() {
        m.adc = AdcWord::default()
            .with_pot(u16::from(id) << 8 | i as u16)
            .with_current(0x8000);
        if layout.format() == BlockFormat::Rev8 {
            m.status = MotorStatus::default()
                .with_amp_on(true)
                .with_current_command(i as u16);
        }
    }
    for (i, e) in r.encoder.iter_mut().take(layout.encoders()).enumerate() {
        e.position = EncPosition::default()
            .with_counts(i32::from(id) * 100 - i as i32)
            .unwrap();
        e.period = EncPeriod::default().with_period(i as u32);
        e.qtr1 = EncQuarter::default().with_edges(0xA);
        e.qtr5 = EncQuarter::default().with_direction(true);
        e.run = EncRun::default().with_clocks(77);
    }
    r
}

/// One broadcast cycle between emulated boards and a host, for a firmware.
fn broadcast_cycle(layout: BoardLayout, ids: &[u8]) {
    let rule = SeqRule::for_firmware(layout.firmware());
    let seq = rule.next_seq(0x01FF);
    // 1. Query.
    let mask = ids.iter().fold(0u16, |m, &id| m | 1 << id);
    let query_word = Query {
        seq,
        board_mask: mask,
    }
    .to_word()
    .unwrap();
    let query = Query::parse(query_word).unwrap();
    let selected: Vec<u8> = query.boards().collect();
    assert_eq!(selected, ids);
    // 2. Each selected board broadcasts; 3. the hub board packs them.
    let mut hub_memory = [0xA5u8; 2048];
    let mut packer = HubPacker::new(&mut hub_memory);
    for (t, &id) in selected.iter().enumerate() {
        let mut packet = [0xA5u8; 256];
        let repr = StatusBroadcastRepr {
            seq: query.seq,
            block: board_state(layout, id),
        };
        let n = repr.emit(&mut packet).unwrap();
        assert_eq!(n, layout.broadcast_quadlets() * 4);
        let view = StatusBroadcast::new_checked(&packet[..n], layout).unwrap();
        assert_eq!(view.header().seq, seq);
        packer
            .store_broadcast(&packet[..n], query.seq, 40 * t as u16, layout.format())
            .unwrap();
    }
    let len = packer
        .finish(HubTiming {
            read_start: 5,
            now: 500,
        })
        .unwrap();
    // 4. The host reads the hub block and checks it.
    let boards: Vec<BoardSlot> = selected
        .iter()
        .map(|&id| BoardSlot { id, layout })
        .collect();
    assert_eq!(len, hub_block_quadlets(boards.iter().map(|b| b.layout)) * 4);
    let hub = HubBlock::new_checked(&hub_memory[..len], &boards).unwrap();
    hub.check_sequences(rule, seq).unwrap();
    if !ids.is_empty() {
        // A stale answer (last cycle's sequence) is caught.
        assert!(hub.check_sequences(rule, rule.next_seq(seq)).is_err());
    }
    for entry in hub.entries() {
        let parsed = ReadBlockRepr::parse(&entry.block).unwrap();
        assert_eq!(parsed, board_state(layout, entry.slot.id));
    }
    assert_eq!(hub.timing().now, 500);
    // 5. The host broadcasts the commands; each board takes its slice.
    let mut commands = Vec::new();
    for &id in &selected {
        let mut w = WriteBlockRepr::new(layout, id);
        for (i, d) in w.dac.iter_mut().take(layout.motors()).enumerate() {
            *d = DacWord::valid_command(DAC_ZERO + u16::from(id) * 16 + i as u16);
            if layout.format() == BlockFormat::Rev7 {
                *d = d.with_board_id(id);
            }
        }
        w.control = StatusCommand::amplifiers(0xF, 0xF).to_word();
        commands.push(w);
    }
    let mut payload = [0xA5u8; 1024];
    let n = emit_command_block(&mut payload, &commands).unwrap();
    assert_eq!(
        n,
        command_block_quadlets(commands.iter().map(|c| c.layout)) * 4
    );
    for w in &commands {
        let block = find_command_block(&payload[..n], w.board_id, layout)
            .unwrap()
            .unwrap();
        assert_eq!(WriteBlockRepr::parse(&block).unwrap(), *w);
        let cmd = block.control().block_command();
        assert_eq!(cmd.amps.axis(0), Some(true));
    }
}

#[test]
fn broadcast_cycle_rev8() {
    broadcast_cycle(QLA1_REV8, &[0, 1]);
    broadcast_cycle(QLA1_REV8, &[2, 5, 6, 9, 15]);
    broadcast_cycle(DQLA_REV8, &[0, 1, 2, 3, 4, 5, 6, 7]);
}

#[test]
fn broadcast_cycle_rev7() {
    broadcast_cycle(QLA1_REV7, &[0, 1]);
    broadcast_cycle(QLA1_REV7, &[1, 3, 4, 8, 10, 11, 12, 13, 14, 15]);
}

#[test]
fn two_board_rev8_hub_block_bytes() {
    // §6.3-6.4 worked layout: header at quadlet 0 and 33, timing at 66.
    let boards = [
        BoardSlot {
            id: 0,
            layout: QLA1_REV8,
        },
        BoardSlot {
            id: 1,
            layout: QLA1_REV8,
        },
    ];
    let mut mem = [0xA5u8; 268];
    let mut packer = HubPacker::new(&mut mem);
    for b in &boards {
        let mut pkt = [0u8; 132];
        StatusBroadcastRepr {
            seq: 0x0A0B,
            block: board_state(b.layout, b.id),
        }
        .emit(&mut pkt)
        .unwrap();
        packer
            .store_broadcast(&pkt, 0x0A0B, 0x1234, BlockFormat::Rev8)
            .unwrap();
    }
    assert_eq!(
        packer
            .finish(HubTiming {
                read_start: 0xAAAA,
                now: 0xBBBB
            })
            .unwrap(),
        268
    );
    assert_eq!(read_quadlet(&mem, 0), 0x210B_1234);
    assert_eq!(read_quadlet(&mem, 33), 0x210B_1234);
    assert_eq!(read_quadlet(&mem, 66), 0xAAAA_BBBB);
    assert_eq!(read_quadlet(&mem, 2), 0x4000_0000 | 0x0004_0000); // board 0 STATUS
    let hub = HubBlock::new_checked(&mem[..], &boards).unwrap();
    assert_eq!(hub.entry(1).unwrap().block.status().board_id(), 1);
}

// ------------------------------------------------- command block slicing ---

fn command_block_for(layout: BoardLayout, ids: &[u8], buf: &mut [u8]) -> usize {
    let mut writer = CommandBlockWriter::new(buf);
    for &id in ids {
        let mut w = WriteBlockRepr::new(layout, id);
        w.dac[0] = DacWord::valid_command(0x1000 + u16::from(id));
        w.control = StatusWrite(u32::from(id));
        writer.push(&w).unwrap();
    }
    writer.len()
}

#[test]
fn command_slicing_one_to_sixteen_boards_with_one_missing() {
    for layout in [QLA1_REV8, QLA1_REV7, DQLA_REV8] {
        for n in 1..=16u8 {
            let missing = n / 2;
            let ids: Vec<u8> = (0..n).filter(|&id| id != missing || n == 1).collect();
            let mut buf = [0xA5u8; 1024];
            let len = command_block_for(layout, &ids, &mut buf);
            assert_eq!(len, ids.len() * layout.write_block_len());
            let payload = &buf[..len];
            assert_eq!(command_slices(payload, layout).count(), ids.len());
            for id in 0..16u8 {
                let found = find_command_block(payload, id, layout).unwrap();
                if ids.contains(&id) {
                    let block = found.unwrap();
                    assert_eq!(block.board_id(), id);
                    assert_eq!(block.dac(0).unwrap().command(), 0x1000 + u16::from(id));
                    assert_eq!(block.control().raw(), u32::from(id));
                } else {
                    assert!(found.is_none(), "board {id} of {n} should be absent");
                }
            }
        }
    }
}

#[test]
fn command_slicing_rejects_malformed_walks() {
    let mut buf = [0u8; 64];
    let len = command_block_for(QLA1_REV8, &[1, 2], &mut buf);
    // Corrupt the first header's length to 0: the walk stops with an error.
    let mut bad = buf;
    write_quadlet(&mut bad, 0, 0x0000_0100);
    assert!(matches!(
        find_command_block(&bad[..len], 2, QLA1_REV8),
        Err(Error::Malformed { .. })
    ));
    // A length running past the end.
    write_quadlet(&mut bad, 0, 0x0000_01FF);
    assert!(matches!(
        find_command_block(&bad[..len], 2, QLA1_REV8),
        Err(Error::LengthExceedsBuffer { .. })
    ));
    // The board's own slice found before a later malformed header is still used.
    let mut tail = buf;
    write_quadlet(&mut tail, 6, 0);
    assert!(
        find_command_block(&tail[..len], 1, QLA1_REV8)
            .unwrap()
            .is_some()
    );
    assert!(find_command_block(&tail[..len], 2, QLA1_REV8).is_err());
}

// ------------------------------------------------------------- properties ---

fn firmware() -> impl Strategy<Value = FirmwareRev> {
    prop_oneof![
        Just(FirmwareRev::Rev7),
        Just(FirmwareRev::Rev8),
        any::<u32>().prop_map(FirmwareRev::from),
    ]
}

fn layout() -> impl Strategy<Value = BoardLayout> {
    (firmware(), 1u8..=8, 1u8..=8).prop_map(|(f, m, e)| BoardLayout::new(f, m, e).unwrap())
}

/// A read block repr with only the layout's entries set.
fn read_repr() -> impl Strategy<Value = ReadBlockRepr> {
    (layout(), proptest::collection::vec(any::<u32>(), 60)).prop_map(|(layout, w)| {
        let mut r = ReadBlockRepr::new(layout);
        let mut words = w.into_iter();
        let mut next = move || words.next().unwrap_or(0);
        r.timestamp = next();
        r.status = StatusRead(next());
        r.digital_in = DigitalIn(next());
        r.temperature = Temperature(next());
        for m in r.motor.iter_mut().take(layout.motors()) {
            m.adc = AdcWord(next());
            if layout.format() == BlockFormat::Rev8 {
                m.status = MotorStatus(next());
            }
        }
        for e in r.encoder.iter_mut().take(layout.encoders()) {
            e.position = EncPosition(next());
            e.period = EncPeriod(next());
            e.qtr1 = EncQuarter(next());
            e.qtr5 = EncQuarter(next());
            e.run = EncRun(next());
        }
        r
    })
}

fn write_repr() -> impl Strategy<Value = WriteBlockRepr> {
    (
        layout(),
        0u8..=15,
        proptest::collection::vec(any::<u32>(), 8),
        any::<u32>(),
    )
        .prop_map(|(layout, id, dacs, control)| {
            let mut w = WriteBlockRepr::new(layout, id);
            for (d, raw) in w.dac.iter_mut().zip(dacs).take(layout.motors()) {
                *d = DacWord(raw);
                if layout.format() == BlockFormat::Rev7 {
                    *d = d.with_board_id(id);
                }
            }
            w.control = StatusWrite(control);
            w
        })
}

/// The bits of a STATUS write that carry meaning, as `parse` reads them.
fn meaningful_status_bits(w: u32) -> u32 {
    let mut out = 0;
    if w & (1 << 19) != 0 {
        out |= w & (3 << 18);
    }
    if w & (1 << 17) != 0 {
        out |= w & (3 << 16);
    }
    let mask = (w >> 8) & 0xF;
    out |= mask << 8 | (w & mask);
    if w & (3 << 20) == 3 << 20 {
        out |= 3 << 20;
    }
    out
}

/// For every field of every register quadlet: the getter ignores the other
/// bits, setting a field and restoring it gives back the quadlet (the setter
/// touches only its bits), and setting a field to its own value is identity.
macro_rules! register_field_properties {
    ($raw:expr, $other:expr, $( $ty:ident { $( $get:ident / $with:ident ),+ $(,)? } )+) => {
        $( $(
            let original = $ty($raw);
            let value = $ty($other).$get();
            prop_assert_eq!(original.$with(original.$get()), original);
            let changed = original.$with(value);
            prop_assert_eq!(changed.$get(), value);
            prop_assert_eq!($ty(0).$with(value).$get(), value);
            prop_assert_eq!(changed.$with(original.$get()), original);
        )+ )+
    };
}

proptest! {
    #[test]
    fn register_fields(raw in any::<u32>(), other in any::<u32>()) {
        register_field_properties!(raw, other,
            StatusRead {
                axes / with_axes, board_id / with_board_id,
                watchdog_timeout / with_watchdog_timeout, quad_dac / with_quad_dac,
                dout_checked / with_dout_checked, dout_bidirectional / with_dout_bidirectional,
                motor_supply_good / with_motor_supply_good,
                motor_power_enabled / with_motor_power_enabled,
                relay_state / with_relay_state, relay_on / with_relay_on,
                motor_supply_fault / with_motor_supply_fault,
                safety_feedback / with_safety_feedback, io_expander / with_io_expander,
                amp_fault / with_amp_fault, safety_amp_disable / with_safety_amp_disable,
                amp_enabled / with_amp_enabled,
            }
            StatusWrite {
                reboot_bits / with_reboot_bits, power_mask / with_power_mask,
                power_value / with_power_value, relay_mask / with_relay_mask,
                relay_value / with_relay_value, amp_mask / with_amp_mask,
                amp_values / with_amp_values,
            }
            PhyData { register / with_register, data / with_data }
            Watchdog { ticks / with_ticks }
            Temperature { upper / with_upper, lower / with_lower }
            GitDesc { commit / with_commit, dirty / with_dirty }
            DigitalIn {
                v_fault / with_v_fault, waveform_active / with_waveform_active,
                supply_comparator / with_supply_comparator, enc_a / with_enc_a, enc_b / with_enc_b,
                index / with_index, outputs / with_outputs, neg_limits / with_neg_limits,
                pos_limits / with_pos_limits, home / with_home,
            }
            DigitalOutRead {
                table_active / with_table_active, table_valid / with_table_valid,
                table_index / with_table_index, extra_io / with_extra_io, outputs / with_outputs,
            }
            DoutCtrl { high_time / with_high_time, low_time / with_low_time }
            WaveformEntry {
                valid / with_valid, end_count / with_end_count, outputs / with_outputs,
            }
            AdcWord { pot / with_pot, current / with_current }
            DacWord {
                valid / with_valid, amp_enable_mask / with_amp_enable_mask,
                amp_enable / with_amp_enable, board_id / with_board_id, command / with_command,
            }
            EncPreload { value / with_value }
            EncPosition {
                count / with_count, overflow / with_overflow, index / with_index,
                b / with_b, a / with_a,
            }
            EncPeriod {
                period / with_period, overflow / with_overflow, direction / with_direction,
                direction_changed / with_direction_changed, error / with_error,
                partial / with_partial,
            }
            EncQuarter {
                period / with_period, overflow / with_overflow, direction / with_direction,
                edges / with_edges,
            }
            EncRun { clocks / with_clocks, overflow / with_overflow }
            MotorConfig {
                voltage_mode / with_voltage_mode, current_mode / with_current_mode,
                enable_delay / with_enable_delay, current_limit / with_current_limit,
            }
            MotorStatus {
                amp_on / with_amp_on, amp_requested / with_amp_requested,
                safety_disable / with_safety_disable, amp_fault / with_amp_fault,
                current_command / with_current_command,
            }
            PromCommand { opcode_bits / with_opcode_bits, address / with_address }
            PromStatus {
                error_info / with_error_info, released / with_released, cs / with_cs,
                sclk / with_sclk, miso / with_miso, mosi / with_mosi,
                block_write / with_block_write, state / with_state,
            }
            QlaPromCommand {
                opcode_bits / with_opcode_bits, address / with_address, data / with_data,
            }
            DallasStatus {
                family / with_family, rise_time / with_rise_time, ds2480b / with_ds2480b,
                busy / with_busy, state / with_state, bidirectional / with_bidirectional,
                reset_bits / with_reset_bits, enabled / with_enabled,
            }
            DallasControl {
                address / with_address, end_session / with_end_session,
                mode_bits / with_mode_bits,
            }
            ExpanderWrite {
                clear / with_clear, debug / with_debug, id / with_id, command / with_command,
            }
            ExpanderRead {
                marker / with_marker, prom_busy / with_prom_busy,
                read_waiting / with_read_waiting, pending / with_pending,
                poll_error / with_poll_error, mismatch / with_mismatch,
                mismatch_mask / with_mismatch_mask, answer / with_answer,
            }
            ExpanderDebug {
                mismatch_mask / with_mismatch_mask, mismatch_count / with_mismatch_count,
                ports_read / with_ports_read, ports_commanded / with_ports_commanded,
            }
            EthStatusV2 {
                present / with_present, ksz_request_error / with_ksz_request_error,
                ksz_init_ok / with_ksz_init_ok, frame_error / with_frame_error,
                ipv4_error / with_ipv4_error, udp_port_error / with_udp_port_error,
                destination_error / with_destination_error,
                bus_access_error / with_bus_access_error,
                ksz_state_error / with_ksz_state_error,
                send_state_error / with_send_state_error, udp_mode / with_udp_mode,
                link_up / with_link_up, ksz_idle / with_ksz_idle,
                wait_point / with_wait_point, data / with_data,
            }
            EthControl {
                clear_eth_errors / with_clear_eth_errors,
                clear_ksz_errors / with_clear_ksz_errors, dma / with_dma,
                reset_ksz / with_reset_ksz, write / with_write, word / with_word,
                register / with_register, data / with_data,
            }
        );
    }

    #[test]
    fn read_block_emit_then_parse(repr in read_repr()) {
        let mut buf = [0xA5u8; 256];
        let len = repr.emit(&mut buf).unwrap();
        prop_assert_eq!(len, repr.layout.read_block_len());
        prop_assert!(buf[len..].iter().all(|&b| b == 0xA5));
        let view = ReadBlock::new_checked(&buf[..len], repr.layout).unwrap();
        prop_assert_eq!(ReadBlockRepr::parse(&view).unwrap(), repr);
    }

    #[test]
    fn read_block_parse_then_emit(layout in layout(), bytes in proptest::collection::vec(any::<u8>(), 240)) {
        let len = layout.read_block_len();
        let view = ReadBlock::new_checked(&bytes[..len], layout).unwrap();
        let repr = ReadBlockRepr::parse(&view).unwrap();
        let mut out = [0xA5u8; 240];
        repr.emit(&mut out).unwrap();
        prop_assert_eq!(&out[..len], &bytes[..len]);
    }

    /// Every layout's parse, the QLA1's and DQLA's fast ones included,
    /// reads what the checked view's accessors read, and 0 past the
    /// layout.
    #[test]
    fn read_block_parse_matches_the_view(
        layout in prop_oneof![
            Just(BoardLayout::qla1(FirmwareRev::Rev8)),
            Just(BoardLayout::qla1(FirmwareRev::Rev7)),
            Just(BoardLayout::qla1(FirmwareRev::Rev4)),
            Just(BoardLayout::dqla(FirmwareRev::Rev8)),
            Just(BoardLayout::dqla(FirmwareRev::Rev7)),
            layout(),
        ],
        bytes in proptest::collection::vec(any::<u8>(), 240),
    ) {
        let view = ReadBlock::new_checked(&bytes[..layout.read_block_len()], layout).unwrap();
        let repr = ReadBlockRepr::parse(&view).unwrap();
        prop_assert_eq!(repr.timestamp, view.timestamp());
        prop_assert_eq!(repr.status, view.status());
        for i in 0..8 {
            let m = repr.motor[i];
            prop_assert_eq!(m.adc, view.adc(i).unwrap_or_default());
            prop_assert_eq!(m.status, view.motor_status(i).unwrap_or_default());
            let e = repr.encoder[i];
            prop_assert_eq!(e.position, view.enc_position(i).unwrap_or_default());
            prop_assert_eq!(e.period, view.enc_period(i).unwrap_or_default());
            prop_assert_eq!(e.qtr1, view.enc_qtr1(i).unwrap_or_default());
            prop_assert_eq!(e.qtr5, view.enc_qtr5(i).unwrap_or_default());
            prop_assert_eq!(e.run, view.enc_run(i).unwrap_or_default());
        }
    }

    /// Parsing in place over whatever block was there before (another
    /// layout included) gives what a fresh parse gives; a block of the
    /// wrong length leaves the old one untouched.
    #[test]
    fn read_block_parse_into_equals_parse(
        before in read_repr(),
        layout in layout(),
        bytes in proptest::collection::vec(any::<u8>(), 240),
    ) {
        let len = layout.read_block_len();
        let view = ReadBlock::new_checked(&bytes[..len], layout).unwrap();
        let mut repr = before;
        repr.parse_into(&view).unwrap();
        prop_assert_eq!(repr, ReadBlockRepr::parse(&view).unwrap());
        let mut kept = before;
        let short = ReadBlock::new_unchecked(&bytes[..len - 4], layout);
        prop_assert!(kept.parse_into(&short).is_err());
        prop_assert_eq!(kept, before);
    }

    #[test]
    fn write_block_emit_then_parse(repr in write_repr()) {
        let mut buf = [0xA5u8; 64];
        let len = repr.emit(&mut buf).unwrap();
        prop_assert_eq!(len, repr.layout.write_block_len());
        prop_assert!(buf[len..].iter().all(|&b| b == 0xA5));
        let view = WriteBlock::new_checked(&buf[..len], repr.layout).unwrap();
        prop_assert_eq!(view.board_id(), repr.board_id);
        prop_assert_eq!(WriteBlockRepr::parse(&view).unwrap(), repr);
    }

    #[test]
    fn write_block_parse_then_emit(layout in layout(), bytes in proptest::collection::vec(any::<u8>(), 40)) {
        let len = layout.write_block_len();
        let view = WriteBlock::new_checked(&bytes[..len], layout).unwrap();
        if let Ok(repr) = WriteBlockRepr::parse(&view) {
            let mut out = [0xA5u8; 40];
            repr.emit(&mut out).unwrap();
            prop_assert_eq!(&out[..len], &bytes[..len]);
        }
    }

    #[test]
    fn status_broadcast_round_trip(seq in any::<u16>(), block in read_repr()) {
        let repr = StatusBroadcastRepr { seq, block };
        let mut buf = [0xA5u8; 260];
        let len = repr.emit(&mut buf).unwrap();
        prop_assert!(buf[len..].iter().all(|&b| b == 0xA5));
        let view = StatusBroadcast::new_checked(&buf[..len], block.layout).unwrap();
        prop_assert_eq!(StatusBroadcastRepr::parse(&view).unwrap(), repr);
    }

    #[test]
    fn hub_block_round_trip(
        blocks in proptest::collection::vec(read_repr(), 0..8),
        seq in 1u16..,
        times in proptest::collection::vec(any::<u16>(), 8),
        timing in any::<u32>(),
    ) {
        // Every board on one bus runs the same firmware: use the first's.
        let fw = blocks.first().map_or(FirmwareRev::Rev8, |b| b.layout.firmware());
        let blocks: Vec<ReadBlockRepr> = blocks
            .into_iter()
            .map(|mut b| {
                let l = BoardLayout::new(fw, b.layout.motors() as u8, b.layout.encoders() as u8).unwrap();
                if l.format() == BlockFormat::Rev7 {
                    for m in &mut b.motor { m.status = MotorStatus::default(); }
                }
                b.layout = l;
                b
            })
            .collect();
        let boards: Vec<BoardSlot> = blocks
            .iter()
            .enumerate()
            .map(|(i, b)| BoardSlot { id: i as u8, layout: b.layout })
            .collect();
        let mut mem = [0xA5u8; 2048];
        let mut packer = HubPacker::new(&mut mem);
        for (b, &t) in blocks.iter().zip(&times) {
            let mut pkt = [0u8; 260];
            let n = StatusBroadcastRepr { seq, block: *b }.emit(&mut pkt).unwrap();
            packer.store_broadcast(&pkt[..n], seq, t, b.layout.format()).unwrap();
        }
        let len = packer.finish(HubTiming::from_word(timing)).unwrap();
        let hub = HubBlock::new_checked(&mem[..len], &boards).unwrap();
        prop_assert_eq!(hub.timing().to_word(), timing);
        prop_assert_eq!(hub.check_sequences(SeqRule::for_firmware(fw), seq), Ok(()));
        prop_assert_eq!(hub.entries().count(), blocks.len());
        for (entry, b) in hub.entries().zip(&blocks) {
            prop_assert_eq!(ReadBlockRepr::parse(&entry.block).unwrap(), *b);
        }
    }

    #[test]
    fn command_block_round_trip(
        layout in layout(),
        mask in any::<u16>(),
        dacs in proptest::collection::vec(any::<u32>(), 8),
        control in any::<u32>(),
    ) {
        let ids: Vec<u8> = (0..16u8).filter(|i| mask & (1 << i) != 0).collect();
        let blocks: Vec<WriteBlockRepr> = ids
            .iter()
            .map(|&id| {
                let mut w = WriteBlockRepr::new(layout, id);
                for (d, &raw) in w.dac.iter_mut().zip(&dacs).take(layout.motors()) {
                    *d = DacWord(raw).with_board_id(id);
                }
                w.control = StatusWrite(control);
                w
            })
            .collect();
        let mut buf = [0xA5u8; 16 * 40 + 8];
        let len = emit_command_block(&mut buf, &blocks).unwrap();
        prop_assert!(buf[len..].iter().all(|&b| b == 0xA5));
        for id in 0..16u8 {
            let found = find_command_block(&buf[..len], id, layout).unwrap();
            match blocks.iter().find(|b| b.board_id == id) {
                Some(expected) => {
                    let view = found.unwrap();
                    prop_assert_eq!(WriteBlockRepr::parse(&view).unwrap(), *expected);
                }
                None => prop_assert!(found.is_none()),
            }
        }
    }

    #[test]
    fn status_command_round_trips(word in any::<u32>()) {
        let cmd = StatusCommand::parse(word);
        prop_assert_eq!(cmd.to_word().raw(), meaningful_status_bits(word));
        prop_assert_eq!(StatusCommand::parse(cmd.to_word().raw()), cmd);
        let block = StatusWrite(word).block_command();
        prop_assert!(!block.reboot);
        prop_assert_eq!(block.to_word().raw(), meaningful_status_bits(word & 0xF_FFFF));
    }

    #[test]
    fn small_codecs_round_trip(word in any::<u32>(), seq in 1u16.., mask in any::<u16>(), reg in 0u8..16, data in any::<u8>()) {
        let q = Query { seq, board_mask: mask };
        prop_assert_eq!(Query::parse(q.to_word().unwrap()), Ok(q));
        prop_assert_eq!(BroadcastHeader::from_word(word).to_word(), word);
        prop_assert_eq!(HubTiming::from_word(word).to_word(), word);
        for format in [BlockFormat::Rev7, BlockFormat::Rev8] {
            prop_assert_eq!(HubHeader::from_word(word, format).to_word(), Ok(word));
        }
        for r in [PhyRequest::Read { register: reg }, PhyRequest::Write { register: reg, data }] {
            prop_assert_eq!(PhyRequest::parse(r.to_word().unwrap()), Ok(r));
        }
        let ip = ip_from_register(word);
        prop_assert_eq!(ip_to_register(ip), word);
        let d = DigitalOutWrite { mask: data & 0xF, raw: (word as u8) & 0xF, play_waveform: word >> 31 != 0 };
        prop_assert_eq!(DigitalOutWrite::parse(d.to_word()), d);
        let w = Watchdog(word & 0xFFFF);
        prop_assert_eq!(Watchdog::from_period(w.period()), Ok(w));
    }

    #[test]
    fn encoder_counts_round_trip(counts in -(1i32 << 23)..(1 << 23), high in any::<u32>()) {
        let raw = offset_binary_from_counts(counts).unwrap();
        prop_assert_eq!(counts_from_offset_binary(raw | (high & 0xFF00_0000)), counts);
        let p = EncPosition(high).with_counts(counts).unwrap();
        prop_assert_eq!(p.counts(), counts);
        prop_assert_eq!(p.raw() & 0xFF00_0000, high & 0xFF00_0000);
    }

    #[test]
    fn field_setters_touch_only_their_bits(raw in any::<u32>(), v in any::<u8>(), b in any::<bool>()) {
        let s = StatusRead(raw).with_board_id(v);
        prop_assert_eq!(s.board_id(), v & 0xF);
        prop_assert_eq!(s.raw() & !0x0F00_0000, raw & !0x0F00_0000);
        let d = DacWord(raw).with_valid(b);
        prop_assert_eq!(d.valid(), b);
        prop_assert_eq!(d.raw() & 0x7FFF_FFFF, raw & 0x7FFF_FFFF);
    }

    #[test]
    fn addresses_round_trip(offset in any::<u64>()) {
        let a = Address::from_offset(offset);
        prop_assert_eq!(a.offset(), Ok(offset & 0xFFFF));
        if let Some(reg) = a.register() {
            prop_assert_eq!(reg.offset(), Ok(offset & 0xFFFF));
        }
        if let Some(hub) = a.hub() {
            prop_assert_eq!(hub.offset(), Ok(offset & 0xFFFF));
        }
    }

    #[test]
    fn parsers_never_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..700),
        layout in layout(),
        word in any::<u32>(),
        offset in any::<u64>(),
        id in any::<u8>(),
        n_boards in 0usize..20,
        seq in any::<u16>(),
    ) {
        // Quadlet codecs.
        let _ = Query::parse(word);
        let _ = PhyRequest::parse(word);
        let _ = FpgaVersion::from_eth_status(word);
        let _ = StatusCommand::parse(word);
        let _ = HubHeader::from_word(word, layout.format()).to_word();
        let _ = Address::from_offset(offset).register();
        let _ = Address::from_offset(offset).hub();
        for rule in [SeqRule::Rev7Echo, SeqRule::Rev8LowByte, SeqRule::Seed000] {
            let _ = rule.check(seq, HubHeader::from_word(word, layout.format()), id);
            let _ = rule.next_seq(seq);
        }
        // Block views: checked and unchecked.
        let read = ReadBlock::new_unchecked(&bytes[..], layout);
        let _ = ReadBlockRepr::parse(&read);
        for i in 0..10 {
            let _ = (read.adc(i), read.enc_position(i), read.enc_period(i), read.enc_qtr1(i));
            let _ = (read.enc_qtr5(i), read.enc_run(i), read.motor_status(i));
        }
        let write = WriteBlock::new_unchecked(&bytes[..], layout);
        let _ = WriteBlockRepr::parse(&write);
        let _ = (write.header(), write.board_id(), write.control(), write.dac(0), write.dac(9));
        let bcast = StatusBroadcast::new_unchecked(&bytes[..], layout);
        let _ = StatusBroadcastRepr::parse(&bcast);
        let _ = bcast.block().timestamp();
        // Hub block walked with any number of boards.
        let boards: Vec<BoardSlot> = (0..n_boards).map(|i| BoardSlot { id: i as u8, layout }).collect();
        let hub = HubBlock::new_unchecked(&bytes[..], &boards);
        let _ = hub.check_len();
        let _ = hub.timing();
        for entry in hub.entries() {
            let _ = entry.validate(SeqRule::Seed000, seq);
            let _ = ReadBlockRepr::parse(&entry.block);
        }
        let _ = hub.check_sequences(SeqRule::Rev8LowByte, seq);
        // Command block walk terminates (each step consumes >= 1 quadlet).
        let steps = command_slices(&bytes, layout).count();
        prop_assert!(steps <= bytes.len() / 4 + 1);
        let _ = find_command_block(&bytes, id, layout);
        // The hub board storing an arbitrary broadcast payload.
        let mut mem = [0u8; 2048];
        let mut packer = HubPacker::new(&mut mem);
        let _ = packer.store_broadcast(&bytes, seq, seq, layout.format());
        let _ = packer.finish(HubTiming::default());
    }
}

proptest! {
    /// The serial-number readers never panic on arbitrary PROM bytes, and
    /// every serial the images accept reads back unchanged.
    #[test]
    fn serial_numbers(bytes in proptest::collection::vec(any::<u8>(), 0..24),
                      serial in "[!-~]{1,11}") {
        let _ = firelink_wire::qla::extras::parse_fpga_serial(&bytes);
        let _ = firelink_wire::qla::extras::parse_qla_serial(&bytes);
        use firelink_wire::qla::extras::*;
        let image = fpga_serial_image(&serial).unwrap();
        prop_assert_eq!(parse_fpga_serial(&image), Ok(serial.as_str()));
        match qla_serial_image(&serial) {
            Ok(image) => prop_assert_eq!(parse_qla_serial(&image), Ok(serial.as_str())),
            Err(_) => prop_assert!(serial.len() > QLA_SERIAL_MAX),
        }
    }
}
