//! The host library against emulated boards on the simulated bus: scan,
//! every protocol, board loss, bus reset recovery, sequence errors.

use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::{FaultRule, HostModel, PacketFault, PacketMatch, SimDuration, TimedFault};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_host::sim::SimPort;
use firelink_host::{BoardStatus, HostError, MissReason, Port, RobotIo};
use firelink_wire::packet::Tcode;
use firelink_wire::qla::address::HUB_QUERY_OFFSET;

fn rig(n: u8, hardware: Hardware, profile: Profile) -> BoardRig {
    let boards = (0..n)
        .map(|id| BoardConfig::new(id, hardware, profile))
        .collect();
    BoardRig::daisy_chain(boards, &RigOptions::default())
}

fn port(n: u8, profile: Profile) -> SimPort {
    let r = rig(n, Hardware::Qla1, profile);
    SimPort::new(r.bus, r.host)
}

/// Power every board on (one cycle carries the request) and wait 60 ms for
/// the motor supply to come up, amplifiers still off.
/// `n` QLA1 Rev 8 boards run with the sequential protocol; board `victim`
/// stops answering `after_us` into the run, for good.
fn sequential_io_with_a_silent_board(n: u8, victim: usize, after_us: u64) -> IoSystem<SimPort> {
    let mut r = rig(n, Hardware::Qla1, Profile::Rev8);
    let when = r.bus.now() + SimDuration::from_micros(after_us);
    r.bus.schedule_fault(
        when,
        TimedFault::StopAnswering {
            node: r.boards[victim],
            duration: None,
        },
    );
    let config = IoOptions {
        protocol: Some(Protocol::Sequential),
        ..IoOptions::default()
    };
    IoSystem::open(SimPort::new(r.bus, r.host), config)
        .unwrap()
        .0
}

fn power_up(io: &mut IoSystem<SimPort>) {
    for b in io.boards_mut() {
        b.set_power(true);
    }
    io.cycle();
    io.port_mut().wait(Duration::from_millis(60));
}

#[test]
fn scan_finds_1_8_and_16_boards() {
    for (n, profile, protocol) in [
        (1, Profile::Rev8, Protocol::Broadcast),
        (8, Profile::Rev8, Protocol::Broadcast),
        (8, Profile::Rev7, Protocol::Broadcast),
        // 16 QLA1 Rev 8 blocks (529 quadlets) do not fit the 512-quadlet
        // hub together: two broadcast groups (this used to fall back to
        // sequential reads with a broadcast write).
        (16, Profile::Rev8, Protocol::Broadcast),
        (16, Profile::Rev7, Protocol::Broadcast),
    ] {
        let mut p = port(n, profile);
        let report = scan(&mut p).unwrap();
        assert_eq!(
            report.boards.len(),
            usize::from(n),
            "{n} boards {profile:?}"
        );
        for (i, b) in report.boards.iter().enumerate() {
            assert_eq!(b.board_id, i as u8);
            assert_eq!(b.node, i as u8);
            assert_eq!(b.hardware.name(), "QLA1");
            assert_eq!(b.firmware, if profile == Profile::Rev8 { 8 } else { 7 });
        }
        assert_eq!(report.protocol, protocol, "{n} boards {profile:?}");
        let groups = if (n, profile) == (16, Profile::Rev8) {
            vec![0x00FF, 0xFF00]
        } else {
            vec![((1u32 << n) - 1) as u16]
        };
        assert_eq!(report.broadcast_groups, groups, "{n} boards {profile:?}");
        assert!(report.silent_nodes.is_empty());
    }
}

#[test]
fn dqla_boards_use_their_layout() {
    let r = rig(2, Hardware::Dqla, Profile::Rev8);
    let mut p = SimPort::new(r.bus, r.host);
    let report = scan(&mut p).unwrap();
    assert_eq!(report.boards[0].hardware.name(), "DQLA");
    assert_eq!(report.boards[0].layout.read_block_quadlets(), 60);
    let (mut io, _) = IoSystem::open(p, IoOptions::default()).unwrap();
    assert!(io.cycle().all_ok());
    assert_eq!(io.boards()[1].axes(), 8);
}

/// Every protocol on Rev 7 and Rev 8: all boards answer, inputs are valid,
/// and commands reach the plant (power on, amplifiers on, current -> motion).
#[test]
fn every_protocol_moves_motors() {
    for profile in [Profile::Rev7, Profile::Rev8] {
        for protocol in [
            Protocol::Sequential,
            Protocol::SequentialReadBroadcastWrite,
            Protocol::Broadcast,
        ] {
            let p = port(4, profile);
            let config = IoOptions {
                protocol: Some(protocol),
                ..IoOptions::default()
            };
            let (mut io, _) = IoSystem::open(p, config).unwrap();
            assert_eq!(io.protocol(), protocol);
            for _ in 0..3 {
                let r = *io.cycle();
                assert!(r.all_ok(), "{profile:?} {protocol:?}: {r:?}");
            }
            assert!(io.boards().iter().all(|b| b.is_valid()));
            // Power on, wait for the supply, then amplifiers and current.
            power_up(&mut io);
            for b in io.boards_mut() {
                b.set_all_amps(true);
                b.set_dac(0, 0x8000 + 0x1800).unwrap();
            }
            io.cycle();
            let start = io.board(2).unwrap().encoder_counts(0).unwrap();
            for _ in 0..40 {
                io.cycle();
                io.port_mut().wait(Duration::from_millis(1));
            }
            let board = io.board(2).unwrap();
            assert!(board.power_enabled(), "{profile:?} {protocol:?}");
            assert!(board.amp_enabled(0), "{profile:?} {protocol:?}");
            let moved = board.encoder_counts(0).unwrap() - start;
            assert!(moved.abs() > 10, "{profile:?} {protocol:?}: moved {moved}");
            assert!(board.encoder_velocity(0).unwrap().abs() > 0.0);
            assert_eq!(io.stats().total_errors(), 0, "{profile:?} {protocol:?}");
        }
    }
}

#[test]
fn seed_model_reproduces_pc_side_cycle_times() {
    // With the PC model, the broadcast protocol's I/O time for 8 boards is
    // far below the sequential one (seed 000: 116 us vs 496 us).
    let mut times = Vec::new();
    for protocol in [Protocol::Sequential, Protocol::Broadcast] {
        let r = rig(8, Hardware::Qla1, Profile::Seed);
        let model = HostModel::seed000(r.bus.timing());
        let p = SimPort::new(r.bus, r.host).with_host_model(model);
        // Seed 000's PC sleeps 5 us x boards after the query.
        let config = IoOptions {
            protocol: Some(protocol),
            broadcast_wait: Some(Duration::from_micros(40)),
            seq_rule: Some(firelink_wire::qla::broadcast::SeqRule::Seed000),
            ..IoOptions::default()
        };
        let (mut io, _) = IoSystem::open(p, config).unwrap();
        let mut total = Duration::ZERO;
        for _ in 0..10 {
            total += io.cycle().io_time();
        }
        assert_eq!(io.stats().total_errors(), 0);
        times.push(total.as_secs_f64() * 1e6 / 10.0);
    }
    let (seq, bc) = (times[0], times[1]);
    eprintln!("sequential {seq:.1} us, broadcast {bc:.1} us");
    assert!(seq > 400.0 && seq < 650.0, "sequential {seq} us");
    assert!(bc > 80.0 && bc < 160.0, "broadcast {bc} us");
    assert!(seq / bc >= 4.0, "ratio {}", seq / bc);
}

#[test]
fn board_removed_mid_run_is_reported_and_the_loop_goes_on() {
    let mut r = rig(4, Hardware::Qla1, Profile::Rev8);
    // The board at the far end of the chain (board 0, node 0): the others
    // are renumbered by the reset.
    let victim = r.boards[0];
    let when = r.bus.now() + SimDuration::from_micros(2_000);
    r.bus.schedule_fault(
        when,
        TimedFault::Disconnect {
            node: victim,
            reconnect_after: None,
        },
    );
    let p = SimPort::new(r.bus, r.host);
    let (mut io, _) = IoSystem::open(p, IoOptions::default()).unwrap();
    let mut saw_reset = false;
    for _ in 0..40 {
        let rep = *io.cycle();
        if matches!(rep.error, Some(HostError::BusReset { .. })) {
            saw_reset = true;
        }
        // The loop, not the cycle, rescans after a reset.
        io.recover().unwrap();
        io.port_mut().wait(Duration::from_micros(200));
    }
    assert!(saw_reset, "the disconnect reset the bus");
    assert!(io.stats().bus_resets >= 1);
    // After the rescan the remaining boards run cleanly without board 0,
    // at their new node numbers.
    assert_eq!(io.boards().len(), 3);
    let rep = *io.cycle();
    assert!(rep.all_ok(), "{rep:?}");
    assert!(io.board(0).is_none());
    assert_eq!(io.board(1).unwrap().info().node, 0);
}

#[test]
fn board_that_stops_answering_is_named_every_cycle() {
    let mut io = sequential_io_with_a_silent_board(3, 1, 3_000);
    io.port_mut().wait(Duration::from_millis(4));
    let rep = *io.cycle();
    assert_eq!(rep.missed, 0b010, "{rep:?}");
    assert_eq!(rep.reasons[1], Some(MissReason::Transaction));
    assert!(!io.board(1).unwrap().is_valid());
    assert!(io.board(0).unwrap().is_valid() && io.board(2).unwrap().is_valid());
    assert!(io.stats().timeouts >= 1);
}

#[test]
fn corrupt_query_is_detected_as_a_sequence_error() {
    let mut r = rig(4, Hardware::Qla1, Profile::Rev8);
    // Flip a bit in the third query: no board takes it (CRC), nobody
    // broadcasts, and the hub still holds the previous cycle's blocks.
    r.bus.add_fault_rule(FaultRule::once(
        PacketMatch::any()
            .tcode(Tcode::WriteQuadletRequest)
            .offset(HUB_QUERY_OFFSET as u16)
            .skip(2),
        PacketFault::FlipBits { count: 1 },
    ));
    let p = SimPort::new(r.bus, r.host);
    let (mut io, _) = IoSystem::open(p, IoOptions::default()).unwrap();
    let mut first_bad = None;
    for cycle in 0..5 {
        let rep = *io.cycle();
        if !rep.all_ok() && first_bad.is_none() {
            first_bad = Some((cycle, rep));
        }
    }
    let (cycle, rep) = first_bad.expect("the corrupt query was detected");
    assert_eq!(cycle, 2);
    assert_eq!(rep.missed, 0b1111, "{rep:?}");
    assert!(
        rep.missed_boards()
            .all(|(_, r)| matches!(r, MissReason::Sequence { .. }))
    );
    assert!(io.stats().sequence_errors >= 4);
    // The next cycle is clean again.
    assert!(io.cycle().all_ok());
    let log = io.port().bus().fault_log();
    assert_eq!(log.records().len(), 1);
}

#[test]
fn watchdog_expires_when_the_host_stops() {
    let p = port(2, Profile::Rev8);
    let (mut io, _) = IoSystem::open(p, IoOptions::default()).unwrap();
    io.set_watchdog(firelink_host::WatchdogSetting::from_ms(10.0).unwrap())
        .unwrap();
    power_up(&mut io);
    for b in io.boards_mut() {
        b.set_all_amps(true);
    }
    for _ in 0..5 {
        io.cycle();
        io.port_mut().wait(Duration::from_millis(1));
    }
    assert!(io.board(0).unwrap().amp_enabled(0));
    // The host goes silent for 30 ms; the firmware applies the expiry at
    // its exact time (10 ms after the last write).
    io.port_mut().wait(Duration::from_millis(30));
    let now = firelink_board::time::SimTime(io.port().bus().now().0);
    let node = io.port().bus().node_by_phy(0).unwrap();
    let fw = io
        .port_mut()
        .bus_mut()
        .node_mut::<BoardNode>(node)
        .unwrap()
        .firmware_mut();
    fw.advance(now);
    assert!(fw.watchdog_timed_out());
    assert!(!fw.amplifier_on(0));
    io.read_all();
    let b = io.board(0).unwrap();
    assert!(b.watchdog_expired());
    assert!(!b.amp_enabled(0));
}

#[test]
fn broadcast_reads_are_refused_on_the_bus() {
    let mut p = port(1, Profile::Rev8);
    let err = p
        .read_quadlet(firelink_host::Dest::BROADCAST, 0)
        .unwrap_err();
    assert!(matches!(err, HostError::InvalidRequest { .. }));
}

/// Thousands of broadcast cycles leave nothing behind in the PC's link:
/// the non-blocking broadcast writes (query, commands) are not waited for,
/// so nothing of them may be kept (they used to pile up, one completion per
/// write, for the whole run).
#[test]
fn broadcast_cycles_leave_nothing_in_the_link() {
    let p = port(8, Profile::Rev8);
    let (mut io, _) = IoSystem::open(
        p,
        IoOptions {
            protocol: Some(Protocol::Broadcast),
            ..IoOptions::default()
        },
    )
    .unwrap();
    for _ in 0..2_000 {
        io.read_all();
        io.write_all();
        io.port_mut().wait(Duration::from_micros(100));
    }
    let link = io.port().host_link().unwrap();
    assert_eq!(link.pending_count(), 0);
    assert_eq!(link.completions().count(), 0);
}

/// What the trait's default `board_status` composes from the per-call
/// methods.
fn composed<R: RobotIo>(io: &R, id: u8) -> BoardStatus {
    let amplifiers = (0..8u8)
        .filter_map(|a| Some((a, io.axis_index(id, a)?)))
        .filter(|&(_, axis)| io.amplifier_enabled(axis).unwrap_or(false))
        .fold(0, |m, (a, _)| m | 1u64 << a);
    BoardStatus {
        answered: io.board_answered(id),
        powered: io.powered(id),
        watchdog_expired: io.watchdog_expired(id),
        timestamp: io.timestamp(id),
        amplifiers,
    }
}

/// `board_status` (one look-up per board) says what the per-call methods
/// say: boards powered with some amplifiers on, one absent, one that
/// stopped answering.
#[test]
fn board_status_is_the_per_call_methods() {
    let mut io = sequential_io_with_a_silent_board(3, 2, 200_000);
    power_up(&mut io);
    for (axis, on) in [(0, true), (2, true), (5, true), (9, true)] {
        RobotIo::set_amplifier_enable(&mut io, axis, on).unwrap();
    }
    for _ in 0..3 {
        io.cycle();
        io.port_mut().wait(Duration::from_millis(2));
    }
    let check = |io: &IoSystem<SimPort>| {
        for id in 0..16 {
            assert_eq!(io.board_status(id), composed(io, id), "board {id}");
        }
    };
    check(&io);
    assert_eq!(io.board_status(0).amplifiers, 0b0101);
    assert_eq!(io.board_status(1).amplifiers, 0b0010);
    assert!(io.board_status(2).answered && io.board_status(2).powered);
    assert_eq!(io.board_status(7), BoardStatus::default());
    // A board that stops answering: not answered, no timestamp, no
    // amplifiers, its old watchdog bit as the per-call method reads it.
    io.port_mut().wait(Duration::from_millis(200));
    io.cycle();
    check(&io);
    assert!(!io.board_status(2).answered);
    assert!(io.board_status(0).answered);
}

/// The whole-cycle calls say and do what the per-axis methods do:
/// `axis_inputs` reads every axis's encoder count and pot code (0 and none
/// past the last axis), `set_motor_commands` sets the DAC code of each axis
/// given one and ignores codes past the last axis.
#[test]
fn whole_cycle_axis_calls_are_the_per_axis_methods() {
    let mut io = sequential_io_with_a_silent_board(3, 2, 200_000);
    power_up(&mut io);
    for _ in 0..3 {
        io.cycle();
        io.port_mut().wait(Duration::from_millis(2));
    }
    let axes = RobotIo::axis_count(&io);
    assert_eq!(axes, 12);
    let mut counts = vec![-1; axes + 2];
    let mut pots = vec![Some(1); axes + 2];
    RobotIo::axis_inputs(&io, &mut counts, &mut pots);
    for axis in 0..axes + 2 {
        let count = io.encoder_position(axis).unwrap_or(0);
        assert_eq!(counts[axis], count, "axis {axis}");
        assert_eq!(pots[axis], io.analog_position(axis).ok(), "axis {axis}");
    }
    assert_eq!((counts[axes], pots[axes]), (0, None));
    assert!(pots.iter().take(axes).any(|p| p.is_some_and(|p| p != 0)));
    let before: Vec<Option<u16>> = (0..3u8)
        .flat_map(|id| {
            let b = io.board(id).unwrap();
            (0..4).map(|a| b.dac(a)).collect::<Vec<_>>()
        })
        .collect();
    // Axes 1 and 5 set, the others left alone; a code past the last
    // axis is ignored.
    let mut codes = vec![None; axes + 2];
    codes[1] = Some(0x9000);
    codes[5] = Some(0x7100);
    codes[axes + 1] = Some(1);
    RobotIo::set_motor_commands(&mut io, &codes);
    assert_eq!(before.len(), axes);
    for (axis, &was) in before.iter().enumerate() {
        let (id, a) = io.axis_location(axis).unwrap();
        let expected = match axis {
            1 => Some(0x9000),
            5 => Some(0x7100),
            _ => was,
        };
        assert_eq!(
            io.board(id).unwrap().dac(usize::from(a)),
            expected,
            "axis {axis}"
        );
    }
}

/// A port on the simulated bus whose first read of node `slow` times out,
/// its answer then counted late during the next transaction, as
/// `UdpPort` counts the answer of a board whose server thread waited for
/// a CPU. (`SimPort` itself drops a late answer uncounted.)
struct FirstAnswerLate {
    inner: SimPort,
    slow: u8,
    timed_out: bool,
    late: u64,
}

impl Port for FirstAnswerLate {
    fn name(&self) -> &str {
        "first-answer-late"
    }
    fn read_quadlet(
        &mut self,
        dest: firelink_host::Dest,
        offset: u64,
    ) -> firelink_host::Result<u32> {
        if self.timed_out && self.late == 0 {
            self.late = 1;
        }
        if dest == firelink_host::Dest::node(self.slow) && !self.timed_out {
            self.timed_out = true;
            return Err(HostError::Timeout {
                node: self.slow,
                tl: 0,
                waited_us: 1000,
            });
        }
        self.inner.read_quadlet(dest, offset)
    }
    fn write_quadlet(
        &mut self,
        dest: firelink_host::Dest,
        offset: u64,
        value: u32,
    ) -> firelink_host::Result<()> {
        self.inner.write_quadlet(dest, offset, value)
    }
    fn read_block(
        &mut self,
        dest: firelink_host::Dest,
        offset: u64,
        out: &mut [u8],
    ) -> firelink_host::Result<()> {
        self.inner.read_block(dest, offset, out)
    }
    fn write_block(
        &mut self,
        dest: firelink_host::Dest,
        offset: u64,
        data: &[u8],
    ) -> firelink_host::Result<()> {
        self.inner.write_block(dest, offset, data)
    }
    fn wait(&mut self, duration: Duration) {
        self.inner.wait(duration);
    }
    fn now(&self) -> Duration {
        self.inner.now()
    }
    fn generation(&self) -> u32 {
        self.inner.generation()
    }
    fn link_stats(&self) -> firelink_host::link_stats::LinkStats {
        let mut stats = self.inner.link_stats();
        stats.late += self.late;
        stats
    }
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.inner.candidate_nodes()
    }
}

#[test]
fn a_board_whose_answer_came_late_is_asked_again_and_found() {
    let inner = port(3, Profile::Rev8);
    let mut p = FirstAnswerLate {
        inner,
        slow: 1,
        timed_out: false,
        late: 0,
    };
    let report = scan(&mut p).unwrap();
    assert_eq!(p.link_stats().late, 1);
    let ids: Vec<u8> = report.boards.iter().map(|b| b.board_id).collect();
    assert_eq!(ids, [0, 1, 2], "silent: {:?}", report.silent_nodes);
    assert!(report.silent_nodes.is_empty());
}

#[test]
fn a_silent_board_with_no_late_answer_is_not_asked_again() {
    // The same time-out with no late answer afterwards (node 1 stays
    // silent): one round, node 1 silent and asked once.
    let mut r = rig(3, Hardware::Qla1, Profile::Rev8);
    let when = r.bus.now();
    r.bus.schedule_fault(
        when,
        TimedFault::StopAnswering {
            node: r.boards[1],
            duration: None,
        },
    );
    let mut p = SimPort::new(r.bus, r.host).with_timeout(Duration::from_millis(1));
    let report = scan(&mut p).unwrap();
    assert_eq!(report.silent_nodes, [1]);
    // Five identity reads each of boards 0 and 2, one of node 1 (its
    // first read timed out and ended its identification).
    let stats = p.link_stats();
    assert_eq!((stats.sent, stats.timeouts), (11, 1), "{stats:?}");
}

/// A board's read responses go for the bus to seal and the host takes a
/// clean one without checking its CRCs again: one damaged on the wire is
/// still seen and counted, a data CRC failure as the CRC error it is, a
/// header CRC failure as a response that never came.
#[test]
fn a_damaged_sealed_read_response_is_still_seen() {
    let mut p = port(1, Profile::Rev8);
    let node = scan(&mut p).unwrap().boards[0].node;
    let dest = firelink_host::Dest::node(node);
    let mut block = [0u8; 64];
    p.read_block(dest, 0, &mut block).unwrap();
    p.read_quadlet(dest, 0).unwrap();
    let before = p.link_stats();
    assert_eq!(before.bad_crc, 0);
    // A data quadlet of the next block response (quadlet 6: past the
    // header and its CRC).
    p.bus_mut().add_fault_rule(FaultRule::once(
        PacketMatch::any().tcode(Tcode::ReadBlockResponse),
        PacketFault::CorruptQuadlet { index: 6, xor: 1 },
    ));
    let err = p.read_block(dest, 0, &mut block).unwrap_err();
    assert!(
        matches!(err, HostError::Wire(firelink_wire::Error::DataCrc { .. })),
        "{err:?}"
    );
    assert_eq!(p.link_stats().since(&before).bad_crc, 1);
    // The header of the next quadlet response: the host drops it.
    p.bus_mut().add_fault_rule(FaultRule::once(
        PacketMatch::any().tcode(Tcode::ReadQuadletResponse),
        PacketFault::CorruptQuadlet { index: 1, xor: 1 },
    ));
    let err = p.read_quadlet(dest, 0).unwrap_err();
    assert!(matches!(err, HostError::Timeout { .. }), "{err:?}");
    // Clean again: answered, no more CRC errors.
    p.read_block(dest, 0, &mut block).unwrap();
    p.read_quadlet(dest, 0).unwrap();
    let after = p.link_stats().since(&before);
    assert_eq!((after.bad_crc, after.timeouts), (1, 1), "{after:?}");
    assert_eq!(p.bus().fault_log().records().len(), 2);
}
