//! The broadcast protocol with 1..16 boards: query, slots, hub memory,
//! sequence checks and command slicing. The boards sit on a minimal
//! in-test wire: one packet at a time, every board hears it when it ends
//! (S400 transmission time, no arbitration); the host checks the hub
//! block with the `firelink_wire::qla::broadcast` codecs.

use crate::common;

use common::*;
use firelink_board::qla::Reply;
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::time::{SYSTEM_CLOCK_HZ, SimDuration, SimTime};
use firelink_wire::Error;
use firelink_wire::packet::{NodeId, Packet};
use firelink_wire::qla::broadcast::{
    BoardSlot, HubBlock, HubHeader, SeqRule, emit_command_block, has_hub_timing, hub_block_quadlets,
};
use firelink_wire::qla::realtime::{BoardLayout, WriteBlockRepr};
use firelink_wire::qla::registers::{DacWord, StatusRead};

/// Transmission time of `bytes` at S400 (393.216 Mb/s).
fn s400(bytes: usize) -> SimDuration {
    SimDuration((bytes as u64 * 8 * 1_000_000_000_000) / 393_216_000)
}

/// Boards with IDs `ids` on nodes 0.., all with the same profile.
struct Wire {
    boards: Vec<Rig>,
    now: SimTime,
    /// (sender node, time) of each status broadcast, in order.
    log: Vec<(u8, SimTime)>,
}

impl Wire {
    fn new(profile: Profile, hw: Hardware, ids: &[u8]) -> Wire {
        let boards = ids
            .iter()
            .enumerate()
            .map(|(node, &id)| Rig::new(BoardConfig::new(id, hw, profile), node as u8))
            .collect();
        Wire {
            boards,
            now: SimTime::from_micros(100),
            log: Vec::new(),
        }
    }

    /// Put a packet on the wire now; every board (but `except`) hears it
    /// at its end. Returns the replies.
    fn send(&mut self, packet: &[u8], except: Option<usize>) -> Vec<Reply> {
        self.now += s400(packet.len());
        let now = self.now;
        self.boards
            .iter_mut()
            .enumerate()
            .filter(|(k, _)| Some(*k) != except)
            .map(|(_, b)| {
                b.now = now;
                b.deliver(packet)
            })
            .collect()
    }

    /// Let the boards send their status broadcasts until none is waiting.
    fn run(&mut self) {
        while let Some(next) = self.boards.iter().filter_map(|b| b.fw.next_wakeup()).min() {
            self.now = self.now.max(next);
            let now = self.now;
            let mut sent = false;
            for k in 0..self.boards.len() {
                if let Some(packet) = self.boards[k].fw.poll_transmit(now) {
                    let p = Packet::new_checked(&packet[..]).unwrap();
                    assert!(p.destination_id().is_broadcast());
                    assert_eq!(p.pri(), 0xA);
                    assert!(p.crc_status().all_ok());
                    self.log.push((self.boards[k].node, now));
                    let replies = self.send(&packet, Some(k));
                    assert!(replies.iter().all(|r| *r == Reply::Silent));
                    self.boards[k].fw.transmitted(self.now);
                    // Isochronous-style gap before the next arbitration.
                    self.now += SimDuration::from_nanos(40);
                    sent = true;
                    break;
                }
            }
            assert!(sent, "a board woke up but had nothing to send");
        }
    }

    /// The host's query, to `dest` (broadcast or node 0).
    fn query(&mut self, dest: NodeId, seq: u16, mask: u16) {
        let q = quadlet_write(dest, 1, 0x1800, (u32::from(seq) << 16) | u32::from(mask));
        self.send(&q, None);
    }

    fn slots(&self) -> Vec<BoardSlot> {
        let mut slots: Vec<BoardSlot> = self
            .boards
            .iter()
            .map(|b| BoardSlot {
                id: b.fw.board_id(),
                layout: b.fw.config().layout(),
            })
            .collect();
        slots.sort_by_key(|s| s.id);
        slots
    }
}

fn cycle_checks(profile: Profile, hw: Hardware, n: usize, via_node0: bool) {
    let ids: Vec<u8> = (0..n as u8).collect();
    let mut wire = Wire::new(profile, hw, &ids);
    let mask = ((1u32 << n) - 1) as u16;
    let dest = if via_node0 {
        NodeId::local(0)
    } else {
        NodeId::BROADCAST
    };
    wire.query(dest, 0x1234, mask);
    let t_query = wire.now;
    wire.run();
    assert_eq!(wire.log.len(), n, "every board answered once");
    // Slots in ascending board (= node) order; the first after ~3 us.
    let first = wire.log[0].1 - t_query;
    if profile == Profile::Seed {
        assert!((first.as_micros_f64() - 3.0).abs() < 0.01);
        for (node, at) in &wire.log {
            let slot = (*at - t_query).as_micros_f64();
            assert!(
                slot + 1e-6 >= 3.0 + 5.2 * f64::from(*node),
                "{node}: {slot}"
            );
        }
    } else {
        assert!((first.as_micros_f64() - 150.0 / 49.152).abs() < 0.01);
    }
    for (k, (node, _)) in wire.log.iter().enumerate() {
        assert_eq!(usize::from(*node), k);
    }
    let slots = wire.slots();
    let layout = slots[0].layout;
    let quadlets = hub_block_quadlets(slots.iter().map(|s| s.layout));
    let rule = if profile == Profile::Seed {
        SeqRule::Seed000
    } else {
        SeqRule::for_firmware(layout.firmware())
    };
    let mut entries_seen: Option<Vec<Vec<u8>>> = None;
    for b in &mut wire.boards {
        b.now = wire.now + SimDuration::from_micros(5);
        // 0x1802 counts the blocks, not the extra timing word after them
        // (HubReg.v l.64-65, `is_extra`).
        let extra = usize::from(has_hub_timing(layout.format()));
        assert_eq!(
            b.read(0x1802) as usize,
            quadlets - extra,
            "quadlets written"
        );
        assert_eq!(b.read(0x1800), (0x1234 << 16) | u32::from(mask));
        let hub = bytes(&b.read_block(0x1000, quadlets));
        let block = HubBlock::new_checked(&hub[..], &slots).unwrap();
        block.check_sequences(rule, 0x1234).unwrap();
        let mut blocks = Vec::new();
        for (k, e) in block.entries().enumerate() {
            assert_eq!(e.block.status().board_id(), k as u8);
            assert_eq!(usize::from(e.block.status().axes()), hw.axes());
            match e.header {
                HubHeader::Rev8 {
                    quadlets, seq_low, ..
                } => {
                    assert_eq!(usize::from(quadlets), layout.broadcast_quadlets());
                    assert_eq!(seq_low, 0x34);
                }
                HubHeader::Rev7 { seq, .. } => assert_eq!(seq, 0x1234),
            }
            blocks.push(e.block.as_bytes().to_vec());
        }
        // Every board holds the same blocks.
        match &entries_seen {
            None => entries_seen = Some(blocks),
            Some(first) => assert_eq!(first, &blocks),
        }
        // The timing quadlet: the read started after the last update.
        let timing = block.timing();
        assert!(timing.now >= timing.read_start);
        assert!(timing.read_start > 0);
    }
}

#[test]
fn query_with_1_to_15_boards_rev8() {
    for n in 1..=15 {
        cycle_checks(Profile::Rev8, Hardware::Qla1, n, n % 2 == 0);
    }
}

#[test]
fn sixteen_rev8_boards_overflow_the_hub_memory() {
    // 16 x 33 + 1 = 529 quadlets do not fit the 512 of hub memory: the
    // first 15 entries are stored, the 16th and the timing quadlet are not.
    let ids: Vec<u8> = (0..16).collect();
    let mut wire = Wire::new(Profile::Rev8, Hardware::Qla1, &ids);
    wire.query(NodeId::BROADCAST, 1, 0xFFFF);
    wire.run();
    assert_eq!(wire.log.len(), 16, "every board still answers");
    for b in &mut wire.boards {
        b.now = wire.now;
        assert_eq!(b.read(0x1802), 15 * 33);
    }
}

/// The host's two broadcast groups for 16 QLA1 Rev 8 boards, as the
/// firmware sees them: a query selecting boards 0-7, then one selecting
/// 8-15. Only the selected boards answer, the lowest selected board of each
/// query goes first (~3 us), and each query restarts every board's hub
/// memory from its start: after each, every board (selected or not) holds
/// exactly that group's hub block (8 x 33 + 1 = 265 quadlets) with the
/// timing quadlet, and nothing of the other group's answers.
#[test]
fn two_masked_queries_in_a_row_each_restart_the_hub() {
    let ids: Vec<u8> = (0..16).collect();
    let mut wire = Wire::new(Profile::Rev8, Hardware::Qla1, &ids);
    let all = wire.slots();
    for (seq, mask) in [(0x0101u16, 0x00FFu16), (0x0102, 0xFF00)] {
        wire.log.clear();
        wire.query(NodeId::BROADCAST, seq, mask);
        let t_query = wire.now;
        wire.run();
        let answered: Vec<u8> = wire.log.iter().map(|(n, _)| *n).collect();
        let selected: Vec<u8> = ids
            .iter()
            .copied()
            .filter(|id| mask & (1 << id) != 0)
            .collect();
        assert_eq!(answered, selected, "query {seq:#x}");
        let first = wire.log[0].1 - t_query;
        assert!((first.as_micros_f64() - 150.0 / 49.152).abs() < 0.01);
        let slots: Vec<BoardSlot> = all
            .iter()
            .copied()
            .filter(|s| mask & (1 << s.id) != 0)
            .collect();
        let quadlets = hub_block_quadlets(slots.iter().map(|s| s.layout));
        assert_eq!(quadlets, 265);
        for b in &mut wire.boards {
            b.now = wire.now + SimDuration::from_micros(5);
            assert_eq!(b.read(0x1800), (u32::from(seq) << 16) | u32::from(mask));
            assert_eq!(b.read(0x1802) as usize, quadlets - 1, "board {}", b.node);
            let hub = bytes(&b.read_block(0x1000, quadlets));
            let block = HubBlock::new_checked(&hub[..], &slots).unwrap();
            block.check_sequences(SeqRule::Rev8LowByte, seq).unwrap();
            let named: Vec<u8> = block
                .entries()
                .map(|e| e.block.status().board_id())
                .collect();
            assert_eq!(named, selected, "board {}", b.node);
            let timing = block.timing();
            assert!(timing.read_start > 0 && timing.now >= timing.read_start);
        }
    }
}

/// A board left out of a query sends nothing but still latches its block
/// (the firmware samples on every query): the timestamp in its next
/// answer counts from the query that left it out, not from its last
/// answer.
#[test]
fn a_query_that_leaves_a_board_out_still_restarts_its_timestamp() {
    let ids: Vec<u8> = (0..16).collect();
    let mut wire = Wire::new(Profile::Rev8, Hardware::Qla1, &ids);
    let group_a = wire
        .slots()
        .into_iter()
        .filter(|s| s.id < 8)
        .collect::<Vec<_>>();
    let mut query_times = Vec::new();
    for (seq, mask) in [(0x0101u16, 0x00FFu16), (0x0102, 0xFF00), (0x0103, 0x00FF)] {
        wire.log.clear();
        wire.query(NodeId::BROADCAST, seq, mask);
        query_times.push(wire.now);
        wire.run();
        // Time between the queries, as a host's cycle would leave.
        wire.now += SimDuration::from_micros(50);
    }
    let b = &mut wire.boards[0];
    b.now = wire.now;
    let quadlets = hub_block_quadlets(group_a.iter().map(|s| s.layout));
    let hub = bytes(&b.read_block(0x1000, quadlets));
    let block = HubBlock::new_checked(&hub[..], &group_a).unwrap();
    let since = |k: usize| (query_times[2] - query_times[k]).as_secs_f64() * SYSTEM_CLOCK_HZ as f64;
    for e in block.entries() {
        let ts = f64::from(e.block.timestamp());
        let id = e.block.status().board_id();
        assert!(
            (ts - since(1)).abs() <= 1.0,
            "board {id}: {ts} clocks, want {}",
            since(1)
        );
        assert!((ts - since(0)).abs() > 100.0, "board {id}");
    }
}

#[test]
fn query_with_1_to_16_boards_rev7() {
    for n in 1..=16 {
        cycle_checks(Profile::Rev7, Hardware::Qla1, n, n % 2 == 1);
    }
}

#[test]
fn query_with_1_to_16_boards_seed() {
    for n in 1..=16 {
        cycle_checks(Profile::Seed, Hardware::Qla1, n, false);
    }
}

#[test]
fn query_with_dqla_boards() {
    // 8 DQLA Rev 8 boards: 8 x 61 + 1 = 489 quadlets fit the 512 of hub
    // memory.
    cycle_checks(Profile::Rev8, Hardware::Dqla, 8, false);
}

#[test]
fn hub_sizes_match_the_spec() {
    let qla8 = BoardLayout::qla1(firelink_wire::qla::realtime::FirmwareRev::Rev8);
    let qla7 = BoardLayout::qla1(firelink_wire::qla::realtime::FirmwareRev::Rev7);
    assert_eq!(hub_block_quadlets([qla8; 2]), 67);
    assert_eq!(hub_block_quadlets([qla7; 3]), 29 * 3 + 1);
}

#[test]
fn only_selected_boards_answer() {
    let mut wire = Wire::new(Profile::Rev8, Hardware::Qla1, &[0, 1, 2, 3, 4]);
    // Boards 1 and 3 only.
    wire.query(NodeId::BROADCAST, 9, 0b01010);
    wire.run();
    let nodes: Vec<u8> = wire.log.iter().map(|(n, _)| *n).collect();
    assert_eq!(nodes, vec![1, 3]);
    let slots = [
        BoardSlot {
            id: 1,
            layout: wire.boards[0].fw.config().layout(),
        },
        BoardSlot {
            id: 3,
            layout: wire.boards[0].fw.config().layout(),
        },
    ];
    // Board 0 did not answer but holds the hub block too.
    let b = &mut wire.boards[0];
    b.now = wire.now;
    let hub = bytes(&b.read_block(0x1000, 67));
    let block = HubBlock::new_checked(&hub[..], &slots).unwrap();
    block.check_sequences(SeqRule::Rev8LowByte, 9).unwrap();
    assert_eq!(block.entry(1).unwrap().block.status().board_id(), 3);
}

#[test]
fn a_silent_board_does_not_stall_the_chain() {
    // Board 1 is selected but absent: board 2 goes after its time-out.
    let mut wire = Wire::new(Profile::Rev8, Hardware::Qla1, &[0, 2]);
    wire.query(NodeId::BROADCAST, 3, 0b111);
    let t0 = wire.now;
    wire.run();
    assert_eq!(wire.log.len(), 2);
    let late = wire.log[1].1 - t0;
    assert!(
        late.as_micros_f64() > 50.0 && late.as_micros_f64() < 110.0,
        "{late:?}"
    );
}

#[test]
fn sequence_error_on_a_mismatched_query() {
    // Board 1 missed the query of seq 5 and last saw seq 4.
    let mut wire = Wire::new(Profile::Rev8, Hardware::Qla1, &[0, 1]);
    wire.query(NodeId::BROADCAST, 4, 0b11);
    wire.run();
    let q = quadlet_write(NodeId::local(0), 1, 0x1800, (5 << 16) | 0b01);
    // Only board 0 hears it.
    wire.boards[0].now = wire.now;
    wire.boards[0].deliver(&q);
    wire.run();
    let layout = wire.boards[0].fw.config().layout();
    let slots = [BoardSlot { id: 0, layout }];
    // Board 1 (no new cycle: it missed the query) appended board 0's
    // seq-5 answer after the previous cycle's 66 quadlets of blocks (where
    // the extra timing word was read), error bit set.
    let b1 = &mut wire.boards[1];
    b1.now = wire.now;
    assert_eq!(b1.read(0x1802), 66 + 33);
    // A host reading board 1 as the hub sees last cycle's sequence.
    let stale = bytes(&b1.read_block(0x1000, 34));
    assert!(matches!(
        HubBlock::new_checked(&stale[..], &slots)
            .unwrap()
            .check_sequences(SeqRule::Rev8LowByte, 5),
        Err(Error::Sequence { board: 0, .. })
    ));
    let words = b1.read_block(0x1000 + 66, 33);
    let header = HubHeader::from_word(words[0], layout.format());
    assert_eq!(
        header,
        HubHeader::Rev8 {
            quadlets: 33,
            seq_low: 5,
            seq_error: true,
            update_time: match header {
                HubHeader::Rev8 { update_time, .. } => update_time,
                _ => unreachable!(),
            }
        }
    );
    // ... which the host's check flags; board 0's own copy is clean.
    let mut with_timing = words.clone();
    with_timing.push(0);
    let hub = bytes(&with_timing[..34]);
    let block = HubBlock::new_checked(&hub[..], &slots).unwrap();
    assert!(matches!(
        block.check_sequences(SeqRule::Rev8LowByte, 5),
        Err(Error::SequenceFlagged { board: 0, .. })
    ));
    let b0 = &mut wire.boards[0];
    b0.now = wire.now;
    let hub = bytes(&b0.read_block(0x1000, 34));
    HubBlock::new_checked(&hub[..], &slots)
        .unwrap()
        .check_sequences(SeqRule::Rev8LowByte, 5)
        .unwrap();
}

#[test]
fn seed_corrupt_query_answers_ffff() {
    let mut wire = Wire::new(Profile::Seed, Hardware::Qla1, &[0, 1]);
    let mut q = quadlet_write(NodeId::BROADCAST, 1, 0x1800, (7 << 16) | 0b11);
    // Corrupt the data quadlet: the header CRC fails, the offset is intact.
    q[13] ^= 0x40;
    wire.send(&q, None);
    wire.run();
    assert_eq!(wire.log.len(), 2, "both boards answer in their slots");
    let slots = wire.slots();
    let b = &mut wire.boards[1];
    b.now = wire.now;
    let hub = bytes(&b.read_block(0x1000, 29 * 2));
    let mut hub = hub;
    hub.extend([0; 4]);
    let block = HubBlock::new_checked(&hub[..], &slots).unwrap();
    assert!(matches!(
        block.check_sequences(SeqRule::Seed000, 7),
        Err(Error::CorruptQuery { board: 0 })
    ));
    // Rev 7 firmware drops a corrupt query: nobody answers.
    let mut wire = Wire::new(Profile::Rev7, Hardware::Qla1, &[0, 1]);
    wire.send(&q, None);
    wire.run();
    assert!(wire.log.is_empty());
}

fn command_slicing(profile: Profile, n: usize, via_node0: bool) {
    let ids: Vec<u8> = (0..n as u8).rev().collect();
    let mut wire = Wire::new(profile, Hardware::Qla1, &ids);
    let layout = wire.boards[0].fw.config().layout();
    // One write block per board, ascending board order, each axis a
    // distinct command.
    let blocks: Vec<WriteBlockRepr> = (0..n as u8)
        .map(|id| {
            let mut b = WriteBlockRepr::new(layout, id);
            for (axis, d) in b.dac.iter_mut().take(4).enumerate() {
                *d = DacWord::valid_command(0x9000 + (u16::from(id) << 4) + axis as u16);
            }
            b
        })
        .collect();
    let mut buf = vec![0u8; 2048];
    let len = emit_command_block(&mut buf, &blocks).unwrap();
    let (dest, offset) = if via_node0 {
        (NodeId::local(0), 0xFFFF_FFFF_0000)
    } else {
        (NodeId::BROADCAST, 0)
    };
    let p = block_write(dest, 2, offset, &quads(&buf[..len]));
    let replies = wire.send(&p, None);
    for (b, reply) in wire.boards.iter_mut().zip(replies) {
        // Node 0 is addressed when the command goes to node 0.
        if via_node0 && b.node == 0 {
            assert_eq!(reply, Reply::Ack(firelink_wire::packet::Ack::Complete));
        } else {
            assert_eq!(reply, Reply::Silent);
        }
        let id = u32::from(b.fw.board_id());
        for axis in 0..4u64 {
            let dac = b.read(((axis + 1) << 4) | 1);
            assert_eq!(
                dac,
                0x9000 + (id << 4) + axis as u32,
                "board {id} axis {axis}"
            );
        }
    }
}

#[test]
fn command_block_slicing() {
    for n in [1, 2, 5, 16] {
        command_slicing(Profile::Rev8, n, false);
        command_slicing(Profile::Rev8, n, true);
        command_slicing(Profile::Rev7, n, false);
        command_slicing(Profile::Rev7, n, true);
    }
}

#[test]
fn status_broadcast_offsets() {
    for (profile, expect) in [
        (Profile::Rev7, 0xFFFF_FF00_1000u64 + 0x20 * 6),
        (Profile::Seed, 0xFFFF_FF00_1000 + 0x20 * 6),
        (Profile::Rev8, 0xFFFF_FF00_1000),
    ] {
        let mut r = Rig::new(BoardConfig::new(6, Hardware::Qla1, profile), 6);
        r.deliver(&quadlet_write(
            NodeId::BROADCAST,
            1,
            0x1800,
            (1 << 16) | 0x40,
        ));
        r.wait(SimDuration::from_micros(50));
        let p = r.fw.poll_transmit(r.now).expect("status broadcast");
        let packet = Packet::new_checked(&p[..]).unwrap();
        assert_eq!(packet.offset(), expect);
        assert_eq!(packet.source_id(), NodeId::local(6));
        let status = StatusRead(u32::from_be_bytes(packet.data()[8..12].try_into().unwrap()));
        assert_eq!(status.board_id(), 6);
        // The broadcast header: sequence and size (header included).
        let header = u32::from_be_bytes(packet.data()[..4].try_into().unwrap());
        let size = r.fw.config().layout().broadcast_quadlets() as u32;
        assert_eq!(header, (1 << 16) | size);
    }
}

/// Seed 000's own firmware (seed profile, Rev 4): FW_VERSION 4, 13-quadlet
/// status broadcasts in slots of 150 + 256 x node FPGA clocks, hub entries
/// with the full sequence and no timing quadlet after them.
#[test]
fn rev4_boards_use_seed_000_sizes_and_clock_exact_slots() {
    use firelink_wire::qla::realtime::FirmwareRev;
    let n = 5;
    let boards = (0..n)
        .map(|id| {
            Rig::new(
                BoardConfig::new(id, Hardware::Qla1, Profile::Seed)
                    .with_firmware(FirmwareRev::Rev4),
                id,
            )
        })
        .collect();
    let mut wire = Wire {
        boards,
        now: SimTime::from_micros(100),
        log: Vec::new(),
    };
    wire.query(NodeId::BROADCAST, 0x0042, 0x001F);
    let t_query = wire.now;
    wire.run();
    assert_eq!(wire.log.len(), usize::from(n));
    for (node, at) in &wire.log {
        let clocks = 150 + 256 * u64::from(*node);
        assert_eq!(
            *at - t_query,
            SimDuration::from_clocks(clocks),
            "node {node}"
        );
    }
    let slots = wire.slots();
    assert_eq!(slots[0].layout.read_block_quadlets(), 12);
    assert_eq!(hub_block_quadlets(slots.iter().map(|s| s.layout)), 13 * 5);
    for b in &mut wire.boards {
        b.now = wire.now + SimDuration::from_micros(5);
        assert_eq!(b.read(7), 4, "FW_VERSION");
        assert_eq!(b.read(0x1802), 13 * 5, "no timing quadlet");
        let hub = bytes(&b.read_block(0x1000, 13 * 5));
        let block = HubBlock::new_checked(&hub[..], &slots).unwrap();
        block.check_sequences(SeqRule::Seed000, 0x0042).unwrap();
        for (k, e) in block.entries().enumerate() {
            assert_eq!(e.block.status().board_id(), k as u8);
            assert!(matches!(e.header, HubHeader::Rev7 { seq: 0x0042, .. }));
        }
    }
}
