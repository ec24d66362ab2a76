//! 16 QLA1 Rev 8 boards on the simulated bus: their status blocks
//! (16 x 33 + 1 = 529 quadlets) overflow one 512-quadlet hub memory, so the
//! broadcast protocol runs in two groups per cycle (boards 0-7, then 8-15):
//! query, wait and hub read per group, each query with its own sequence
//! number and board mask, then one command block to all boards. Virtual
//! time: every figure here is deterministic.

use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_board::qla::{CHAIN_TIMEOUT_PER_BOARD, FIRST_SLOT_CLOCKS};
use firelink_bus::trace::PacketKind;
use firelink_bus::{SimDuration, TimedFault, TraceLevel};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_host::sim::SimPort;
use firelink_host::{MissReason, Port};
use firelink_wire::packet::{Packet, Tcode};
use firelink_wire::qla::address::HUB_QUERY_OFFSET;
use firelink_wire::qla::broadcast::{Query, SeqRule, status_broadcast_board};
use firelink_wire::qla::realtime::{BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr};

const GROUP_1: u16 = 0x00FF;
const GROUP_2: u16 = 0xFF00;

fn rig(trace: TraceLevel) -> BoardRig {
    let boards = (0..16)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
        .collect();
    BoardRig::daisy_chain(
        boards,
        &RigOptions {
            trace,
            ..RigOptions::default()
        },
    )
}

fn port() -> SimPort {
    let r = rig(TraceLevel::Off);
    SimPort::new(r.bus, r.host)
}

#[test]
fn scan_picks_the_broadcast_protocol_in_two_groups() {
    let mut p = port();
    let report = scan(&mut p).unwrap();
    assert_eq!(report.boards.len(), 16);
    assert_eq!(report.protocol, Protocol::Broadcast);
    assert_eq!(report.broadcast_groups, vec![GROUP_1, GROUP_2]);
    assert!(
        report.protocol_reason.contains("512-quadlet hub memory"),
        "{}",
        report.protocol_reason
    );
    assert_eq!(report.protocol_label(), "broadcast, 2 groups");
    let (io, _) = IoSystem::open(p, IoOptions::default()).unwrap();
    assert_eq!(io.protocol(), Protocol::Broadcast);
    assert_eq!(io.protocol_label(), "broadcast, 2 groups");
    assert_eq!(
        io.broadcast_groups().collect::<Vec<_>>(),
        vec![GROUP_1, GROUP_2]
    );
    // One hub board for both groups: every board stores every broadcast.
    assert_eq!(io.hub_board(), 0);
    // The explicit protocols still run on these boards.
    for protocol in [Protocol::Sequential, Protocol::SequentialReadBroadcastWrite] {
        let (mut io, _) = IoSystem::open(
            port(),
            IoOptions {
                protocol: Some(protocol),
                ..IoOptions::default()
            },
        )
        .unwrap();
        assert_eq!(io.broadcast_groups().len(), 0);
        assert_eq!(io.protocol_label(), protocol.name());
        for _ in 0..3 {
            let r = *io.cycle();
            assert!(r.all_ok(), "{protocol:?}: {r:?}");
        }
    }
}

/// What the boards put on the bus in one cycle, from the bus trace: the
/// PC's queries (word), and each status broadcast as (board, its header's
/// sequence, its real-time block).
struct CycleOnTheBus {
    queries: Vec<Query>,
    answers: Vec<(u8, u16, ReadBlockRepr)>,
    hub_reads: usize,
    command_writes: usize,
}

fn on_the_bus(io: &IoSystem<SimPort>, pc: usize) -> CycleOnTheBus {
    let layout = BoardLayout::qla1(FirmwareRev::Rev8);
    let mut cycle = CycleOnTheBus {
        queries: Vec::new(),
        answers: Vec::new(),
        hub_reads: 0,
        command_writes: 0,
    };
    for record in io.port().bus().trace().packets() {
        if record.kind != PacketKind::Request {
            continue;
        }
        let Ok(packet) = Packet::new_checked(&record.bytes[..]) else {
            continue;
        };
        if record.sender == pc {
            match packet.tcode() {
                Tcode::WriteQuadletRequest if packet.offset() & 0xFFFF == HUB_QUERY_OFFSET => {
                    cycle
                        .queries
                        .push(Query::parse(packet.quadlet_data()).unwrap());
                }
                Tcode::ReadBlockRequest => cycle.hub_reads += 1,
                Tcode::WriteBlockRequest => cycle.command_writes += 1,
                _ => {}
            }
        } else if let Some((header, board)) = status_broadcast_board(&packet) {
            let data = packet.data();
            let block = ReadBlock::new_checked(&data[4..], layout).unwrap();
            cycle
                .answers
                .push((board, header.seq, ReadBlockRepr::parse(&block).unwrap()));
        }
    }
    cycle
}

#[test]
fn many_cycles_in_two_groups_with_every_block_from_its_own_board() {
    let r = rig(TraceLevel::Packets);
    let pc = r.host.0;
    let (mut io, _) = IoSystem::open(SimPort::new(r.bus, r.host), IoOptions::default()).unwrap();
    let rule = io.seq_rule();
    assert_eq!(rule, SeqRule::Rev8LowByte);
    const CYCLES: u64 = 400;
    let mut last_seq = 0u16;
    for _ in 0..CYCLES {
        io.port_mut().bus_mut().trace_mut().clear();
        let report = *io.cycle();
        assert!(report.all_ok(), "{report:?}");
        // The command write is not waited for: let it onto the bus.
        io.port_mut().wait(Duration::from_micros(100));
        // Two queries, each with its own sequence number, the first group
        // first.
        let (s1, s2) = (report.seq, rule.next_seq(report.seq));
        assert_eq!(s1, rule.next_seq(last_seq));
        last_seq = s2;
        for id in 0..16 {
            let expected = if id < 8 { s1 } else { s2 };
            assert_eq!(report.query_seq[id], expected, "board {id}");
        }
        let bus = on_the_bus(&io, pc);
        assert_eq!(
            bus.queries,
            vec![
                Query {
                    seq: s1,
                    board_mask: GROUP_1
                },
                Query {
                    seq: s2,
                    board_mask: GROUP_2
                }
            ]
        );
        assert_eq!((bus.hub_reads, bus.command_writes), (2, 1));
        // Each board answered its own group's query exactly once, and the
        // host took exactly that block for it.
        let mut answered = 0u16;
        for (board, seq, block) in &bus.answers {
            assert_eq!(answered & (1 << board), 0, "board {board} answered twice");
            answered |= 1 << board;
            let expected = if *board < 8 { s1 } else { s2 };
            assert_eq!(*seq, expected, "board {board}");
            let io_board = io.board(*board).unwrap();
            assert!(io_board.is_valid());
            assert_eq!(io_board.status().board_id(), *board);
            assert_eq!(io_board.input(), block, "board {board}");
        }
        assert_eq!(answered, 0xFFFF);
    }
    let stats = *io.stats();
    assert_eq!(stats.cycles, CYCLES);
    assert_eq!(stats.clean_cycles, CYCLES);
    assert_eq!(stats.total_errors(), 0, "{stats:?}");
    assert!(stats.missed_by_board.iter().all(|&m| m == 0));
}

#[test]
fn commands_reach_every_board_of_both_groups() {
    let (mut io, _) = IoSystem::open(port(), IoOptions::default()).unwrap();
    for b in io.boards_mut() {
        b.set_power(true);
    }
    io.cycle();
    io.port_mut().wait(Duration::from_millis(60));
    // A different current command on every axis of every board.
    let dac = |id: u8, axis: usize| 0x8000 + 0x100 * u16::from(id) + 0x10 * axis as u16 + 1;
    for b in io.boards_mut() {
        let id = b.board_id();
        b.set_all_amps(true);
        for axis in 0..4 {
            b.set_dac(axis, dac(id, axis)).unwrap();
        }
    }
    for _ in 0..20 {
        assert!(io.cycle().all_ok());
        io.port_mut().wait(Duration::from_millis(1));
    }
    let now = firelink_board::time::SimTime(io.port().bus().now().0);
    for id in 0..16u8 {
        let node = io.port().bus().node_by_phy(id).unwrap();
        let board = io.port().bus().node::<BoardNode>(node).unwrap();
        let fw = board.firmware();
        assert_eq!(fw.board_id(), id);
        for axis in 0..4 {
            assert_eq!(fw.axis_command(axis), Some(dac(id, axis)), "board {id}");
            assert!(fw.amplifier_on(axis), "board {id} axis {axis} at {now:?}");
        }
        // And the board says so in its next block.
        let b = io.board(id).unwrap();
        assert!(b.power_enabled() && b.amp_enabled(0), "board {id}");
    }
    assert_eq!(io.stats().total_errors(), 0);
}

/// Board `victim` stops answering after the scan; `cycles` cycles run.
fn run_without(victim: u8, options: IoOptions, cycles: usize) -> IoSystem<SimPort> {
    let mut r = rig(TraceLevel::Off);
    let node = r.boards[usize::from(victim)];
    let when = r.bus.now() + SimDuration::from_millis(20);
    r.bus.schedule_fault(
        when,
        TimedFault::StopAnswering {
            node,
            duration: None,
        },
    );
    let (mut io, _) = IoSystem::open(SimPort::new(r.bus, r.host), options).unwrap();
    io.port_mut().wait(Duration::from_millis(25));
    for _ in 0..cycles {
        io.cycle();
        io.port_mut().wait(Duration::from_micros(200));
    }
    io
}

#[test]
fn a_missing_board_of_the_second_group_is_named() {
    // The last board of group 2: nobody waits for it.
    let io = run_without(15, IoOptions::default(), 20);
    let report = *io.report();
    assert_eq!(report.missed, 1 << 15, "{report:?}");
    assert_eq!(report.reasons[15], Some(MissReason::NotUpdated));
    assert_eq!(report.missed_boards().count(), 1);
    assert!((0..15).all(|id| io.board(id).unwrap().is_valid()));
    assert!(!io.board(15).unwrap().is_valid());
    let stats = io.stats();
    assert_eq!(stats.missed_by_board[15], 20);
    assert!(stats.missed_by_board[..15].iter().all(|&m| m == 0));
    assert_eq!(stats.timeouts, 0);

    // A board in the middle of group 2: the boards after it in the chain
    // wait for it (the emulated firmware gives up after its time-out per
    // board before it), so a host that waits long enough hears them and
    // names the silent one alone.
    let chain_wait = SimDuration::from_clocks(FIRST_SLOT_CLOCKS)
        + SimDuration(CHAIN_TIMEOUT_PER_BOARD.0 * 8)
        + SimDuration::from_micros(20);
    let io = run_without(
        12,
        IoOptions {
            broadcast_wait: Some(Duration::from_nanos(chain_wait.0 / 1000)),
            ..IoOptions::default()
        },
        10,
    );
    let report = *io.report();
    assert_eq!(report.missed, 1 << 12, "{report:?}");
    assert_eq!(report.reasons[12], Some(MissReason::NotUpdated));
    assert!(io.board(13).unwrap().is_valid() && io.board(11).unwrap().is_valid());
    // Group 1 never noticed.
    assert!(io.stats().missed_by_board[..8].iter().all(|&m| m == 0));
}
