//! The I/O system: latch all inputs, apply all outputs, with one of three
//! protocols, and per-cycle statistics without allocation.
//!
//! - [`Protocol::Sequential`]: per board one block read of the real-time
//!   block and one block write of the command block (`T = (Tr + Tw) x N`).
//! - [`Protocol::SequentialReadBroadcastWrite`]: per-board reads, then all
//!   commands in one broadcast block write.
//! - [`Protocol::Broadcast`] (seed 000): a broadcast query, a wait while the
//!   boards broadcast their status, one block read of the hub memory from one
//!   board, one broadcast write of all commands (`T = TQ + wait + TR + TW`).
//!   Boards whose blocks together overflow the hub memory run in broadcast
//!   groups ([`crate::scan::broadcast_groups`]): query, wait and hub read
//!   once per group, each query with its own sequence number and the
//!   group's board mask, then the one command write to all boards.
//!
//! Every cycle checks that each expected board answered: its block size,
//! its board ID and (broadcast) the sequence number. A board that misses a
//! cycle is reported by ID with the reason and counted; its inputs are
//! marked invalid, never silently reused.

use std::time::Duration;

use firelink_wire::board::MAX_BOARDS;
use firelink_wire::board::address::{
    BoardRegister, COMMAND_BLOCK_OFFSET, COMMAND_SNOOP_NODE, COMMAND_SNOOP_OFFSET,
    HUB_MEMORY_OFFSET, HUB_QUERY_OFFSET, REALTIME_BLOCK_OFFSET, Register,
};
use firelink_wire::board::broadcast::{
    BoardSlot, CommandBlockWriter, HubBlock, HubHeader, Query, SeqRule, hub_block_quadlets,
    status_broadcast_board,
};
use firelink_wire::board::realtime::{BlockFormat, BoardLayout, ReadBlock, ReadBlockRepr};
use firelink_wire::board::registers::{AmpCommand, StatusCommand, WatchdogSetting};
use firelink_wire::packet::Packet;

use crate::board::BoardIo;
use crate::error::{HostError, MissReason, Result};
use crate::port::{Dest, Port};
use crate::scan::{Protocol, ScanReport, scan};

/// How to run the I/O system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IoOptions {
    /// Protocol to use; `None` takes the best the boards support.
    pub protocol: Option<Protocol>,
    /// Board to read the hub from; `None`: the bridge board, else the lowest ID.
    pub hub_board: Option<u8>,
    /// Wait between a query and its hub read (with broadcast groups,
    /// after each group's query); `None`: the port's
    /// [`Port::broadcast_wait`] for the boards the query selects (10 + 5 N
    /// us on the bus and the bridge, the Rev 9 host's 3 + 38 (N - 1) us on
    /// the Ethernet-only network).
    pub broadcast_wait: Option<Duration>,
    /// Sequence rule; `None`: the rule of the boards' firmware.
    pub seq_rule: Option<SeqRule>,
    /// Quadlets each hub read asks for (at least the largest group's hub
    /// block); `None`: the group's hub block, or for Rev 4 boards the fixed
    /// 16-board block the hosts of seed 000's era read.
    pub hub_read_quadlets: Option<usize>,
    /// Where the broadcast protocol's query and commands go.
    pub broadcast_route: BroadcastRoute,
    /// Between the query and the hub read, stop waiting as soon as every
    /// board's status broadcast has been overheard (the wait then only
    /// bounds it). Ports that cannot overhear the bus wait the whole time.
    pub listen_for_broadcasts: bool,
}

/// The boards a query selects, counted as the host's broadcast wait
/// counts them ([`Port::broadcast_wait`]; FirewirePort `WaitBroadcastRead`:
/// 10 + 5 us per board): in QLA1 read blocks, so that a board whose read
/// block is longer than a QLA1's (a DQLA's 60 quadlets) counts as the QLA1
/// blocks it spans (rounded up) and the wait still covers the broadcasts
/// it is meant to. A QLA1-only set counts its boards.
fn qla1_read_blocks(layouts: impl IntoIterator<Item = BoardLayout>) -> usize {
    /// A QLA1's read block at Rev 8/9: the block the formula is for.
    const QLA1_READ_QUADLETS: usize = 32;
    layouts
        .into_iter()
        .map(|l| l.read_block_quadlets().div_ceil(QLA1_READ_QUADLETS).max(1))
        .sum()
}

/// Where the broadcast protocol sends its query and its commands
/// (`fpga-board.md` §6.1, §6.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum BroadcastRoute {
    /// To broadcast node 63 (the Ethernet bridge; seed 000's patched
    /// FireWire driver): one unacknowledged packet each.
    #[default]
    Node63,
    /// To node 0, which every board snoops (what stock FireWire stacks
    /// allow, as they reject true broadcast writes): the commands at
    /// `0xFFFF_FFFF_0000`; node 0 acknowledges both.
    SnoopedNode0,
}

impl BroadcastRoute {
    fn query(self) -> Dest {
        match self {
            BroadcastRoute::Node63 => Dest::BROADCAST,
            BroadcastRoute::SnoopedNode0 => Dest::node(COMMAND_SNOOP_NODE),
        }
    }

    fn command(self) -> (Dest, u64) {
        match self {
            BroadcastRoute::Node63 => (Dest::BROADCAST, COMMAND_BLOCK_OFFSET),
            BroadcastRoute::SnoopedNode0 => (Dest::node(COMMAND_SNOOP_NODE), COMMAND_SNOOP_OFFSET),
        }
    }
}

/// The hub's timing quadlet (`read_start:16 | now:16`, timers counting
/// from the query) in us: when the hub read started and when the quadlet
/// itself was read. The timers count the board's 49.152 MHz system clock
/// on the FireWire bus and behind the bridge, the 125 MHz Ethernet clock
/// on the Ethernet-only network (EthBasePort `GetBroadcastReadClockPeriod`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HubReadTimes {
    /// When the hub read started, us after the query.
    pub read_start_us: f32,
    /// When the timing quadlet was read, us after the query.
    pub read_end_us: f32,
}

impl HubReadTimes {
    /// No hub read yet.
    pub const ZERO: HubReadTimes = HubReadTimes {
        read_start_us: 0.0,
        read_end_us: 0.0,
    };

    /// The timing quadlet `word` of timers counting at `clock_hz`.
    pub fn from_word(word: u32, clock_hz: u32) -> HubReadTimes {
        let timing = firelink_wire::board::broadcast::HubTiming::from_word(word);
        HubReadTimes {
            read_start_us: hub_ticks_us(u32::from(timing.read_start), clock_hz),
            read_end_us: hub_ticks_us(u32::from(timing.now), clock_hz),
        }
    }
}

/// `ticks` of a hub timer counting at `clock_hz`, in us (0 Hz reads as
/// 1 Hz rather than dividing by zero).
pub fn hub_ticks_us(ticks: u32, clock_hz: u32) -> f32 {
    (f64::from(ticks) * 1e6 / f64::from(clock_hz.max(1))) as f32
}

/// What happened in the last cycle. `Copy`, fixed size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleReport {
    /// Cycle number (from 1).
    pub cycle: u64,
    /// Query sequence number (broadcast protocol: the cycle's first query;
    /// each board's own in `query_seq`), 0 otherwise.
    pub seq: u16,
    /// Broadcast protocol: the sequence number of the query that selected
    /// each board this cycle (its group's), by board ID; 0 otherwise.
    pub query_seq: [u16; MAX_BOARDS],
    /// Port time when the read phase started.
    pub started: Duration,
    /// Duration of the read phase (query + wait + hub read, or all reads).
    pub read_time: Duration,
    /// Duration of the write phase.
    pub write_time: Duration,
    /// Bit i set: board ID i missed this cycle.
    pub missed: u16,
    /// Why each missed board missed, by board ID.
    pub reasons: [Option<MissReason>; MAX_BOARDS],
    /// Broadcast protocol: when each board's block reached the hub, in us
    /// after its query (from the hub headers, counted at the port's
    /// [`Port::hub_clock_hz`]), by board ID.
    pub update_time_us: [f32; MAX_BOARDS],
    /// Broadcast protocol: the hub's timing quadlet of the cycle's last
    /// hub block, at the same clock.
    pub hub_read: HubReadTimes,
    /// The first port error of the cycle, if any.
    pub error: Option<HostError>,
    /// A bus reset was seen in this cycle (whatever the first error was):
    /// node numbers may have moved.
    pub bus_reset: bool,
}

impl CycleReport {
    /// A report of no cycle yet.
    pub const EMPTY: CycleReport = CycleReport {
        cycle: 0,
        seq: 0,
        query_seq: [0; MAX_BOARDS],
        started: Duration::ZERO,
        read_time: Duration::ZERO,
        write_time: Duration::ZERO,
        missed: 0,
        reasons: [None; MAX_BOARDS],
        update_time_us: [0.0; MAX_BOARDS],
        hub_read: HubReadTimes::ZERO,
        error: None,
        bus_reset: false,
    };

    /// Whether every board took part and no error happened.
    pub fn all_ok(&self) -> bool {
        self.missed == 0 && self.error.is_none()
    }

    /// I/O time of the cycle (read + write phases).
    pub fn io_time(&self) -> Duration {
        self.read_time + self.write_time
    }

    /// Board IDs that missed the cycle, with the reason.
    pub fn missed_boards(&self) -> impl Iterator<Item = (u8, MissReason)> + '_ {
        self.reasons
            .iter()
            .enumerate()
            .filter_map(|(id, r)| r.map(|r| (id as u8, r)))
    }

    /// Board `board_id` missed this cycle for `reason`: in this report and
    /// counted in `stats`.
    pub fn note_miss(&mut self, stats: &mut IoStats, board_id: u8, reason: MissReason) {
        let id = usize::from(board_id & 0xF);
        self.missed |= 1 << id;
        if let Some(r) = self.reasons.get_mut(id) {
            *r = Some(reason);
        }
        if let Some(c) = stats.missed_by_board.get_mut(id) {
            *c += 1;
        }
        stats.count_miss(reason);
    }

    /// An error in this cycle: counted in `stats`, the first one kept.
    /// Returns whether it was a bus reset (node numbers may have moved:
    /// the caller finds its boards again between cycles).
    pub fn note_error(&mut self, stats: &mut IoStats, e: HostError) -> bool {
        stats.count_error(&e);
        if self.error.is_none() {
            self.error = Some(e);
        }
        let reset = matches!(e, HostError::BusReset { .. });
        self.bus_reset |= reset;
        reset
    }
}

/// Counters over all cycles, by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct IoStats {
    /// Cycles run (read phases).
    pub cycles: u64,
    /// Cycles in which every board answered.
    pub clean_cycles: u64,
    /// Misses per board ID.
    pub missed_by_board: [u64; MAX_BOARDS],
    /// Time-outs.
    pub timeouts: u64,
    /// Bus resets seen.
    pub bus_resets: u64,
    /// Bad packets (CRC, length) from the port.
    pub bad_packets: u64,
    /// Error acks or rcodes.
    pub nacks: u64,
    /// Sequence mismatches.
    pub sequence_errors: u64,
    /// Corrupt queries reported by boards.
    pub corrupt_queries: u64,
    /// Blocks naming the wrong board.
    pub wrong_board: u64,
    /// Blocks of the wrong size.
    pub block_size: u64,
    /// Other failures (socket errors, invalid requests).
    pub other: u64,
}

impl IoStats {
    /// Total errors of every kind.
    pub fn total_errors(&self) -> u64 {
        self.timeouts
            + self.bus_resets
            + self.bad_packets
            + self.nacks
            + self.sequence_errors
            + self.corrupt_queries
            + self.wrong_board
            + self.block_size
            + self.other
    }

    /// Count one error by its kind.
    pub fn count_error(&mut self, e: &HostError) {
        match e {
            HostError::Timeout { .. } | HostError::CycleDeadline { .. } => self.timeouts += 1,
            HostError::BusReset { .. } => self.bus_resets += 1,
            HostError::Wire(_) => self.bad_packets += 1,
            HostError::Ack { .. } | HostError::Rcode { .. } => self.nacks += 1,
            _ => self.other += 1,
        }
    }

    /// Count one missed board by its reason.
    pub fn count_miss(&mut self, reason: MissReason) {
        match reason {
            MissReason::Sequence { .. } | MissReason::NotUpdated => self.sequence_errors += 1,
            MissReason::CorruptQuery => self.corrupt_queries += 1,
            MissReason::WrongBoardId { .. } => self.wrong_board += 1,
            MissReason::BlockSize { .. } => self.block_size += 1,
            MissReason::Transaction => {}
        }
    }
}

fn miss_from_wire(e: firelink_wire::Error) -> MissReason {
    use firelink_wire::Error as W;
    match e {
        W::Sequence {
            expected, received, ..
        } => MissReason::Sequence { expected, received },
        W::SequenceFlagged { .. } | W::CorruptQuery { .. } => MissReason::CorruptQuery,
        W::BlockSize {
            expected, found, ..
        } => MissReason::BlockSize {
            expected: expected as u16,
            found: found as u16,
        },
        _ => MissReason::NotUpdated,
    }
}

/// Boards behind a port, driven with one protocol.
pub struct IoSystem<P: Port> {
    port: P,
    boards: Vec<BoardIo>,
    /// Per board ID: its index in `boards` (`u8::MAX`: none), and per axis
    /// over all boards: (index in `boards`, axis on it), both worked out
    /// once at each scan so that the per-axis calls of a cycle index.
    lookup: AxisLookup,
    slots: Vec<BoardSlot>,
    protocol: Protocol,
    hub: usize,
    seq: u16,
    rule: SeqRule,
    config: IoOptions,
    /// Broadcast protocol: the queries of one cycle, in order (empty for
    /// the other protocols).
    groups: Vec<QueryGroup>,
    buf: Vec<u8>,
    cmd: Vec<u8>,
    report: CycleReport,
    /// The last [`HISTORY`] finished cycles' reports (a ring), for
    /// monitors and fault accounting that look back.
    history: Box<[CycleReport]>,
    stats: IoStats,
    bridge_board: Option<u8>,
    /// A bus reset was seen: node numbers may have moved; the caller
    /// rescans between cycles ([`IoSystem::recover`]).
    needs_rescan: bool,
    /// Board IDs the last rescan no longer found.
    left: Vec<u8>,
    /// Boards this system asked for power or an amplifier since the last
    /// power-down (bit i = board ID i): dropping the system powers them
    /// down.
    energised: u16,
    /// The watchdog this system last programmed.
    watchdog: Option<WatchdogSetting>,
}

/// Where boards and axes are in an [`IoSystem`]'s board list.
#[derive(Debug, Clone, Default)]
struct AxisLookup {
    /// Per board ID: index in the board list, `u8::MAX` for none.
    by_id: [u8; MAX_BOARDS],
    /// Per axis over all boards: (board index, axis on that board).
    axes: Vec<(u8, u8)>,
}

impl AxisLookup {
    fn of(boards: &[BoardIo]) -> AxisLookup {
        let mut by_id = [u8::MAX; MAX_BOARDS];
        let mut axes = Vec::new();
        for (i, b) in boards.iter().enumerate() {
            let i = u8::try_from(i).unwrap_or(u8::MAX);
            if let Some(slot) = by_id.get_mut(usize::from(b.board_id())) {
                if *slot == u8::MAX {
                    *slot = i;
                }
            }
            axes.extend((0..b.axes()).map(|a| (i, u8::try_from(a).unwrap_or(u8::MAX))));
        }
        AxisLookup { by_id, axes }
    }

    fn board(&self, id: u8) -> Option<usize> {
        self.by_id
            .get(usize::from(id))
            .filter(|&&i| i != u8::MAX)
            .map(|&i| usize::from(i))
    }

    fn axis(&self, axis: usize) -> Option<(usize, usize)> {
        self.axes
            .get(axis)
            .map(|&(b, a)| (usize::from(b), usize::from(a)))
    }
}

/// Finished cycles whose reports an [`IoSystem`] keeps.
pub const HISTORY: usize = 1024;

/// One broadcast query of a cycle and the hub block it fills.
#[derive(Debug, Clone, PartialEq, Eq)]
struct QueryGroup {
    /// The query's board mask.
    mask: u16,
    /// The selected boards' indices in the system (ascending board ID).
    members: Vec<usize>,
    /// Their slots, in the same order: the hub block's entries.
    slots: Vec<BoardSlot>,
    /// Quadlets of the hub block these boards fill ...
    hub_quadlets: usize,
    /// ... and of the hub read (more for Rev 4 boards: a fixed 16-board
    /// block).
    hub_read_quadlets: usize,
    /// Between the query and the hub read.
    wait: Duration,
}

/// Per board (index in the system): its block from the hub was latched,
/// or why it has none; `None` when no block came.
type HubOutcomes = [Option<core::result::Result<(), MissReason>>; MAX_BOARDS];

impl<P: Port> IoSystem<P> {
    /// Scan the port and set up every board found.
    ///
    /// # Errors
    /// Errors of [`scan`], or [`HostError::InvalidRequest`] when the asked
    /// protocol cannot be used with these boards.
    pub fn open(mut port: P, config: IoOptions) -> Result<(IoSystem<P>, ScanReport)> {
        let report = scan(&mut port)?;
        let system = IoSystem::with_scan(port, &report, config)?;
        Ok((system, report))
    }

    /// Set up the boards of an earlier scan.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] when the asked protocol is better than
    /// what the boards support, or the hub board is unknown.
    pub fn with_scan(port: P, scan: &ScanReport, config: IoOptions) -> Result<IoSystem<P>> {
        let mut config = config;
        if port.refuses_broadcast_registers() {
            // The query at 0x1800 cannot go to node 63 on this port.
            config.broadcast_route = BroadcastRoute::SnoopedNode0;
        }
        let protocol = config.protocol.unwrap_or(scan.protocol);
        if protocol > scan.protocol {
            return Err(HostError::InvalidRequest {
                what: "protocol not supported by every board (see the scan's reason)",
                value: protocol as u32,
            });
        }
        let mut system = IoSystem {
            port,
            boards: Vec::new(),
            lookup: AxisLookup::default(),
            slots: Vec::new(),
            protocol,
            hub: 0,
            seq: 0,
            rule: SeqRule::Rev8LowByte,
            config,
            groups: Vec::new(),
            buf: Vec::new(),
            cmd: Vec::new(),
            report: CycleReport::EMPTY,
            history: vec![CycleReport::EMPTY; HISTORY].into_boxed_slice(),
            stats: IoStats::default(),
            bridge_board: scan.bridge_board,
            needs_rescan: false,
            left: Vec::new(),
            energised: 0,
            watchdog: None,
        };
        system.adopt(scan)?;
        Ok(system)
    }

    fn adopt(&mut self, scan: &ScanReport) -> Result<()> {
        self.boards = scan.boards.iter().map(|b| BoardIo::new(*b)).collect();
        self.lookup = AxisLookup::of(&self.boards);
        self.slots = scan
            .boards
            .iter()
            .map(|b| BoardSlot {
                id: b.board_id,
                layout: b.layout,
            })
            .collect();
        // One hub board for every group: every board stores every status
        // broadcast, selected or not, and the bridge board's own hub is one
        // FireWire hop nearer.
        let hub_id = self
            .config
            .hub_board
            .or(self.bridge_board)
            .filter(|id| scan.boards.iter().any(|b| b.board_id == *id))
            .or_else(|| scan.boards.first().map(|b| b.board_id));
        self.hub = self
            .boards
            .iter()
            .position(|b| Some(b.board_id()) == hub_id)
            .ok_or(HostError::NoBoards {
                seen: self.port.link_stats(),
            })?;
        self.rule = self.config.seq_rule.unwrap_or_else(|| {
            self.boards
                .first()
                .map(|b| SeqRule::for_firmware(b.info().layout.firmware()))
                .unwrap_or(SeqRule::Rev8LowByte)
        });
        let read_max = self
            .boards
            .iter()
            .map(|b| b.info().layout.read_block_len())
            .max()
            .unwrap_or(0);
        self.groups = match self.protocol {
            Protocol::Broadcast => self.query_groups(scan)?,
            Protocol::Sequential | Protocol::SequentialReadBroadcastWrite => Vec::new(),
        };
        let hub_read_max = self
            .groups
            .iter()
            .map(|g| g.hub_read_quadlets)
            .max()
            .unwrap_or(0);
        self.buf = vec![0; read_max.max(hub_read_max * 4)];
        let cmd: usize = self
            .boards
            .iter()
            .map(|b| b.info().layout.write_block_len())
            .sum();
        self.cmd = vec![0; cmd];
        Ok(())
    }

    /// The broadcast queries of one cycle for the boards of `scan`
    /// ([`crate::scan::broadcast_groups`]), each with its hub block, hub read and
    /// wait.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] when these boards cannot run the
    /// broadcast protocol, or the asked hub read is shorter than a group's
    /// hub block.
    fn query_groups(&self, scan: &ScanReport) -> Result<Vec<QueryGroup>> {
        let masks =
            crate::scan::broadcast_groups(&scan.boards).ok_or(HostError::InvalidRequest {
                what: "the boards' hub blocks do not fit the hub memory",
                value: scan.boards.len() as u32,
            })?;
        // Hosts of seed 000's era read a fixed 16-board hub block.
        let rev4 = !self.slots.is_empty()
            && self
                .slots
                .iter()
                .all(|s| s.layout.format() == BlockFormat::Rev4);
        let per_board = self
            .slots
            .iter()
            .map(|s| s.layout.broadcast_quadlets())
            .max()
            .unwrap_or(0);
        let mut groups = Vec::with_capacity(masks.len());
        for mask in masks {
            let members: Vec<usize> = self
                .slots
                .iter()
                .enumerate()
                .filter(|(_, s)| {
                    1u16.checked_shl(u32::from(s.id))
                        .is_some_and(|bit| mask & bit != 0)
                })
                .map(|(i, _)| i)
                .collect();
            let slots: Vec<BoardSlot> = members
                .iter()
                .filter_map(|&i| self.slots.get(i).copied())
                .collect();
            let hub_quadlets = hub_block_quadlets(slots.iter().map(|s| s.layout));
            let hub_read_quadlets = match self.config.hub_read_quadlets {
                Some(q) if q < hub_quadlets => {
                    return Err(HostError::InvalidRequest {
                        what: "hub read shorter than the hub block",
                        value: q as u32,
                    });
                }
                Some(q) => q,
                None if rev4 => hub_quadlets.max(MAX_BOARDS * per_board),
                None => hub_quadlets,
            };
            let wait = self.config.broadcast_wait.unwrap_or_else(|| {
                self.port
                    .broadcast_wait(qla1_read_blocks(slots.iter().map(|s| s.layout)))
            });
            groups.push(QueryGroup {
                mask,
                members,
                slots,
                hub_quadlets,
                hub_read_quadlets,
                wait,
            });
        }
        Ok(groups)
    }

    /// Scan again (after a bus reset) keeping the protocol; boards that
    /// vanished are dropped, new ones added.
    ///
    /// # Errors
    /// Errors of [`scan`].
    pub fn rescan(&mut self) -> Result<ScanReport> {
        let report = scan(&mut self.port)?;
        self.protocol = self.protocol.min(report.protocol);
        self.bridge_board = report.bridge_board;
        let before: Vec<u8> = self.boards.iter().map(BoardIo::board_id).collect();
        self.adopt(&report)?;
        self.left = before
            .into_iter()
            .filter(|id| !report.boards.iter().any(|b| b.board_id == *id))
            .collect();
        self.needs_rescan = false;
        Ok(report)
    }

    /// The boards (by ID) the last rescan no longer found: unplugged, or
    /// silent since; the others go on being served. Empty before any
    /// rescan.
    pub fn boards_left(&self) -> &[u8] {
        &self.left
    }

    /// Whether a bus reset was seen since the last scan (node numbers may
    /// have moved: cycles go on failing until [`recover`](Self::recover)).
    pub fn needs_rescan(&self) -> bool {
        self.needs_rescan
    }

    /// Between cycles, never inside one: after a bus reset, scan again.
    /// Returns the new scan when one ran.
    ///
    /// # Errors
    /// Errors of [`scan`] (the next call tries again).
    pub fn recover(&mut self) -> Result<Option<ScanReport>> {
        if !self.needs_rescan {
            return Ok(None);
        }
        self.rescan().map(Some)
    }

    /// The port.
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The port, mutable. Prefer [`read_register`](Self::read_register)
    /// and [`write_register`](Self::write_register): a bus reset reported
    /// to a call made directly on the port is not seen by the system.
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// The protocol in use.
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// Broadcast protocol: the board mask of each query of a cycle, in
    /// order (one when every board's block fits one hub block); empty for
    /// the other protocols.
    pub fn broadcast_groups(&self) -> impl ExactSizeIterator<Item = u16> + '_ {
        self.groups.iter().map(|g| g.mask)
    }

    /// The protocol in use as reports name it: `broadcast, 2 groups` when
    /// the broadcast protocol runs in groups ([`crate::scan::protocol_label`]).
    pub fn protocol_label(&self) -> String {
        crate::scan::protocol_label(self.protocol, self.groups.len())
    }

    /// The sequence rule in use.
    pub fn seq_rule(&self) -> SeqRule {
        self.rule
    }

    /// Board ID of the hub board (every group's hub block is read from it).
    pub fn hub_board(&self) -> u8 {
        self.boards.get(self.hub).map_or(0, |b| b.board_id())
    }

    /// All boards, by ascending board ID.
    pub fn boards(&self) -> &[BoardIo] {
        &self.boards
    }

    /// All boards, mutable (to set outputs).
    pub fn boards_mut(&mut self) -> &mut [BoardIo] {
        &mut self.boards
    }

    /// One board by ID.
    pub fn board(&self, id: u8) -> Option<&BoardIo> {
        match self.lookup.board(id).and_then(|i| self.boards.get(i)) {
            Some(b) if b.board_id() == id => Some(b),
            // (Boards reordered through `boards_mut`.)
            _ => self.boards.iter().find(|b| b.board_id() == id),
        }
    }

    /// One board by ID, mutable.
    pub fn board_mut(&mut self, id: u8) -> Option<&mut BoardIo> {
        let at = self
            .lookup
            .board(id)
            .filter(|&i| self.boards.get(i).is_some_and(|b| b.board_id() == id))
            .or_else(|| self.boards.iter().position(|b| b.board_id() == id))?;
        self.boards.get_mut(at)
    }

    /// Axis `axis` over all boards (numbered in the order of
    /// [`boards`](Self::boards) at the last scan, when the table was made):
    /// (index in `boards`, axis on that board).
    pub(crate) fn axis_slot(&self, axis: usize) -> Option<(usize, usize)> {
        self.lookup.axis(axis)
    }

    /// The last cycle's report.
    pub fn report(&self) -> &CycleReport {
        &self.report
    }

    /// Reports of the finished cycles numbered after `cycle` that are still
    /// kept (the last [`HISTORY`]), oldest first.
    pub fn reports_since(&self, cycle: u64) -> impl Iterator<Item = &CycleReport> {
        let last = self.report.cycle;
        let first = cycle
            .saturating_add(1)
            .max(last.saturating_sub(HISTORY as u64 - 1))
            .max(1);
        (first..=last).filter_map(move |c| {
            self.history
                .get((c % HISTORY as u64) as usize)
                .filter(|r| r.cycle == c)
        })
    }

    /// Counters over all cycles.
    pub fn stats(&self) -> &IoStats {
        &self.stats
    }

    fn dest_of(&self, id: u8) -> Result<Dest> {
        if self.needs_rescan {
            // The node this board had may now be another board's.
            return Err(HostError::BusReset {
                old: self.port.generation(),
                new: self.port.generation(),
            });
        }
        self.board(id)
            .map(|b| Dest::node(b.info().node))
            .ok_or(HostError::UnknownBoard(id))
    }

    /// Read a quadlet register of one board.
    ///
    /// # Errors
    /// Port errors; [`HostError::UnknownBoard`].
    pub fn read_register(&mut self, id: u8, offset: u64) -> Result<u32> {
        let dest = self.dest_of(id)?;
        let r = self.port.read_quadlet(dest, offset);
        self.outside_cycle(r)
    }

    /// A port result outside the cycle: a bus reset reported here must not
    /// be lost (the port reports each reset once), so the system learns
    /// that nodes may have moved and rescans before the next cycle.
    fn outside_cycle<T>(&mut self, r: Result<T>) -> Result<T> {
        if let Err(e @ HostError::BusReset { .. }) = r {
            self.needs_rescan = true;
            self.stats.count_error(&e);
        }
        r
    }

    /// Write a quadlet register of one board.
    ///
    /// # Errors
    /// Port errors; [`HostError::UnknownBoard`].
    pub fn write_register(&mut self, id: u8, offset: u64, value: u32) -> Result<()> {
        let dest = self.dest_of(id)?;
        let r = self.port.write_quadlet(dest, offset, value);
        self.outside_cycle(r)
    }

    /// Program every board's watchdog (off only as
    /// [`WatchdogSetting::Off`]: no period turns it off).
    ///
    /// # Errors
    /// Port errors.
    pub fn set_watchdog(&mut self, setting: WatchdogSetting) -> Result<()> {
        let word = setting.register();
        self.watchdog = Some(setting);
        let offset = Register::board(BoardRegister::Watchdog).offset()?;
        if self.needs_rescan {
            return Err(HostError::BusReset {
                old: self.port.generation(),
                new: self.port.generation(),
            });
        }
        for i in 0..self.boards.len() {
            let node = self.boards.get(i).map_or(0, |b| b.info().node);
            let r = self
                .port
                .write_quadlet(Dest::node(node), offset, word.raw());
            self.outside_cycle(r)?;
        }
        Ok(())
    }

    /// The fault path's backstop: tell each board in `boards` (bit i =
    /// board ID i) directly, with one STATUS write per board, to turn every
    /// amplifier off, and return the boards that acknowledged it (none over
    /// a port whose writes are not acknowledged: the next cycle's command
    /// and the boards' watchdogs are then the backstop). The cycle's
    /// broadcast command says the same; this makes it certain on a bus that
    /// loses packets. Allocation-free.
    pub fn disable_amplifiers_acknowledged(&mut self, boards: u16) -> u16 {
        let Ok(offset) = Register::board(BoardRegister::Status).offset() else {
            return 0;
        };
        let word = StatusCommand {
            amps: AmpCommand::new(0xF, 0),
            ..StatusCommand::NONE
        }
        .to_word()
        .raw();
        let acknowledged = self.port.acknowledges_writes();
        let mut confirmed = 0u16;
        for i in 0..self.boards.len() {
            let Some(info) = self.boards.get(i).map(|b| *b.info()) else {
                break;
            };
            if boards & (1 << info.board_id) == 0 || self.needs_rescan {
                continue;
            }
            match self.port.write_quadlet(Dest::node(info.node), offset, word) {
                Ok(()) if acknowledged => confirmed |= 1 << info.board_id,
                Ok(()) => {}
                Err(e) => self.note_error(e),
            }
        }
        confirmed
    }

    fn note_error(&mut self, e: HostError) {
        // Node numbers may have changed after a bus reset: the caller
        // rescans between cycles (`recover`), not inside this one.
        if self.report.note_error(&mut self.stats, e) {
            self.needs_rescan = true;
        }
    }

    fn miss(&mut self, index: usize, reason: MissReason) {
        let Some(board) = self.boards.get_mut(index) else {
            return;
        };
        board.invalidate();
        let id = board.board_id();
        self.report.note_miss(&mut self.stats, id, reason);
    }

    fn miss_all(&mut self, reason: MissReason) {
        for i in 0..self.boards.len() {
            self.miss(i, reason);
        }
    }

    /// Latch every board's inputs with the protocol in use; returns the
    /// cycle's report. Never fails as a whole: misses and errors are in the
    /// report (and the stats).
    pub fn read_all(&mut self) -> &CycleReport {
        let cycle = self.report.cycle + 1;
        self.report = CycleReport::EMPTY;
        self.report.cycle = cycle;
        self.stats.cycles += 1;
        self.port.begin_cycle();
        let started = self.port.now();
        self.report.started = started;
        if self.needs_rescan {
            // Node numbers may have moved since the bus reset: no request
            // goes to a node that may now be another board.
            self.report.error = Some(HostError::BusReset {
                old: self.port.generation(),
                new: self.port.generation(),
            });
            self.miss_all(MissReason::Transaction);
        } else {
            match self.protocol {
                Protocol::Broadcast => self.read_broadcast(),
                Protocol::Sequential | Protocol::SequentialReadBroadcastWrite => {
                    self.read_sequential()
                }
            }
        }
        self.report.read_time = self.port.now().saturating_sub(started);
        if self.report.all_ok() {
            self.stats.clean_cycles += 1;
        }
        &self.report
    }

    fn read_sequential(&mut self) {
        for i in 0..self.boards.len() {
            let Some(board) = self.boards.get(i) else {
                break;
            };
            let info = *board.info();
            let len = info.layout.read_block_len();
            let Some(buf) = self.buf.get_mut(..len) else {
                self.miss(i, MissReason::Transaction);
                continue;
            };
            if let Err(e) = self
                .port
                .read_block(Dest::node(info.node), REALTIME_BLOCK_OFFSET, buf)
            {
                self.miss(i, MissReason::Transaction);
                self.note_error(e);
                if matches!(e, HostError::BusReset { .. }) {
                    return;
                }
                continue;
            }
            let parsed = ReadBlock::new_checked(&buf[..], info.layout)
                .and_then(|b| ReadBlockRepr::parse(&b));
            match parsed {
                Ok(repr) if repr.status.board_id() != info.board_id => self.miss(
                    i,
                    MissReason::WrongBoardId {
                        found: repr.status.board_id(),
                    },
                ),
                Ok(repr) => {
                    if let Some(b) = self.boards.get_mut(i) {
                        b.latch(repr);
                    }
                }
                Err(e) => self.miss(i, miss_from_wire(e)),
            }
        }
    }

    /// The broadcast protocol's read: per group, query, wait for the
    /// status broadcasts, one hub read, each hub block taken for its board.
    fn read_broadcast(&mut self) {
        for g in 0..self.groups.len() {
            self.read_group(g);
        }
    }

    /// Group `g`'s query, wait and hub read. After a bus reset (in this
    /// group or an earlier one) no request goes out: node numbers may
    /// have moved.
    fn read_group(&mut self, g: usize) {
        if self.needs_rescan {
            self.miss_group(g, MissReason::Transaction);
            return;
        }
        let Some((mask, wait)) = self.groups.get(g).map(|q| (q.mask, q.wait)) else {
            return;
        };
        let seq = match self.send_query(mask) {
            Ok(seq) => seq,
            Err(e) => {
                self.note_error(e);
                self.miss_group(g, MissReason::Transaction);
                return;
            }
        };
        if let Some(group) = self.groups.get(g) {
            for slot in &group.slots {
                if let Some(s) = self.report.query_seq.get_mut(usize::from(slot.id)) {
                    *s = seq;
                }
            }
        }
        self.await_broadcasts(seq, mask, wait);
        let (hub_len, read_len) = self
            .groups
            .get(g)
            .map_or((0, 0), |q| (q.hub_quadlets * 4, q.hub_read_quadlets * 4));
        let hub_node = self.boards.get(self.hub).map_or(0, |b| b.info().node);
        let Some(buf) = self.buf.get_mut(..read_len) else {
            self.miss_group(g, MissReason::Transaction);
            return;
        };
        // The Ethernet-only network's hub sends the hub memory unasked;
        // when it does not come, the hub is read (the Rev 9 host's
        // fallback; the port counts each).
        let answered = matches!(self.port.receive_broadcast_response(buf), Some(Ok(())));
        let read = if answered {
            Ok(())
        } else {
            self.port
                .read_block(Dest::node(hub_node), HUB_MEMORY_OFFSET, buf)
        };
        if let Err(e) = read {
            self.note_error(e);
            self.miss_group(g, MissReason::Transaction);
            return;
        }
        let outcomes = match self.hub_outcomes(g, hub_len, seq) {
            Ok(o) => o,
            Err(e) => {
                let reason = miss_from_wire(e);
                self.stats.count_error(&HostError::Wire(e));
                self.miss_group(g, reason);
                return;
            }
        };
        let members = self.groups.get(g).map_or(0, |q| q.members.len());
        for k in 0..members {
            let Some(i) = self.groups.get(g).and_then(|q| q.members.get(k)).copied() else {
                break;
            };
            match outcomes.get(i).copied().flatten() {
                // Latched as it was parsed.
                Some(Ok(())) => {}
                Some(Err(reason)) => self.miss(i, reason),
                None => self.miss(i, MissReason::NotUpdated),
            }
        }
    }

    /// Every board of group `g` missed the cycle for `reason`.
    fn miss_group(&mut self, g: usize, reason: MissReason) {
        let members = self.groups.get(g).map_or(0, |q| q.members.len());
        for k in 0..members {
            if let Some(i) = self.groups.get(g).and_then(|q| q.members.get(k)).copied() {
                self.miss(i, reason);
            }
        }
    }

    /// The next query, selecting the boards of `mask`, on its broadcast
    /// route (without waiting); returns its sequence number.
    fn send_query(&mut self, mask: u16) -> Result<u16> {
        self.seq = self.rule.next_seq(self.seq);
        if self.report.seq == 0 {
            self.report.seq = self.seq;
        }
        let query = Query {
            seq: self.seq,
            board_mask: mask,
        };
        let word = query.to_word()?;
        let route = self.config.broadcast_route;
        self.port
            .start_write_quadlet(route.query(), HUB_QUERY_OFFSET, word)?;
        Ok(self.seq)
    }

    /// Wait for the status broadcasts answering query `seq` of the boards
    /// of `expected`: until every one was overheard (at most `wait`), or
    /// the whole `wait`.
    fn await_broadcasts(&mut self, seq: u16, expected: u16, wait: Duration) {
        if !self.config.listen_for_broadcasts {
            self.port.wait(wait);
            return;
        }
        let mut heard = 0u16;
        self.port.wait_until_heard(wait, &mut |bytes| {
            if let Ok(packet) = Packet::new_checked(bytes)
                && let Some((header, board)) = status_broadcast_board(&packet)
                && header.seq == seq
            {
                heard |= 1u16.checked_shl(u32::from(board)).unwrap_or(0);
            }
            heard & expected == expected
        });
    }

    /// Each board's outcome from group `g`'s hub memory read into the
    /// buffer (`hub_len` bytes) after query `seq`, by index in the system:
    /// its block parsed straight into the board's inputs and latched, or
    /// why it has none (`None`: no block came, or the board is not in the
    /// group); the update times go into the report.
    ///
    /// # Errors
    /// The hub memory does not decode.
    fn hub_outcomes(
        &mut self,
        g: usize,
        hub_len: usize,
        seq: u16,
    ) -> core::result::Result<HubOutcomes, firelink_wire::Error> {
        let mut outcomes: HubOutcomes = [None; MAX_BOARDS];
        let Some(group) = self.groups.get(g) else {
            return Ok(outcomes);
        };
        let bytes = self.buf.get(..hub_len).unwrap_or(&[]);
        let hub = HubBlock::new_checked(bytes, &group.slots)?;
        let clock_hz = self.port.hub_clock_hz();
        // The hub packs blocks in arrival order, which is board order for
        // the Rev 7+ chain but not always for TDMA slots (a late slot, fair
        // arbitration, a late answer to an earlier group's query): when
        // every block has the same size, each one is taken for the board
        // its STATUS names.
        let uniform = group.slots.windows(2).all(|w| w[0].layout == w[1].layout);
        for (i, entry) in hub.entries().enumerate() {
            let named = entry.block.status().board_id();
            let k = if uniform {
                match group.slots.iter().position(|s| s.id == named) {
                    Some(k) => k,
                    // A block of a board not in this query: no one's data.
                    None => continue,
                }
            } else {
                i
            };
            let (Some(slot), Some(&index)) = (group.slots.get(k), group.members.get(k)) else {
                continue;
            };
            // A board's first block counts; a repeat does not replace it
            // (nor is it parsed).
            let first = outcomes.get(index).is_some_and(Option::is_none);
            let outcome = if !first {
                None
            } else if let Err(e) = entry.validate(self.rule, seq) {
                Some(Err(miss_from_wire(e)))
            } else if let Err(e) = entry.block.check_len() {
                Some(Err(miss_from_wire(e)))
            } else if named != slot.id {
                // (The STATUS a parse reads is the one named above.)
                Some(Err(MissReason::WrongBoardId { found: named }))
            } else {
                let latched = match self.boards.get_mut(index) {
                    Some(b) => b.latch_block(&entry.block),
                    None => Ok(()),
                };
                Some(latched.map_err(miss_from_wire))
            };
            let time = match entry.header {
                HubHeader::Rev7 { time, .. } => u32::from(time & 0x7FFF),
                HubHeader::Rev8 { update_time, .. } => u32::from(update_time),
            };
            if let Some(t) = self.report.update_time_us.get_mut(usize::from(slot.id)) {
                *t = hub_ticks_us(time, clock_hz);
            }
            if let (Some(o), Some(outcome)) = (outcomes.get_mut(index), outcome) {
                *o = Some(outcome);
            }
        }
        let timing = hub.timing().to_word();
        self.report.hub_read = HubReadTimes::from_word(timing, clock_hz);
        Ok(outcomes)
    }

    /// Apply every board's outputs with the protocol in use.
    pub fn write_all(&mut self) -> &CycleReport {
        let started = self.port.now();
        match self.protocol {
            // Until the rescan, no command goes to a node that may now be
            // another board; the boards' watchdogs are the backstop.
            _ if self.needs_rescan => {}
            Protocol::Sequential => self.write_sequential(),
            Protocol::SequentialReadBroadcastWrite | Protocol::Broadcast => self.write_broadcast(),
        }
        if !self.needs_rescan {
            self.write_status_registers();
        }
        for b in self.boards.iter_mut() {
            if b.asks_for_energy() {
                self.energised |= 1 << (b.board_id() & 0xF);
            }
            b.outputs_applied();
        }
        self.report.write_time = self.port.now().saturating_sub(started);
        self.port.end_cycle();
        let slot = (self.report.cycle % HISTORY as u64) as usize;
        if let Some(h) = self.history.get_mut(slot) {
            *h = self.report;
        }
        &self.report
    }

    fn write_sequential(&mut self) {
        for i in 0..self.boards.len() {
            let Some(board) = self.boards.get(i) else {
                break;
            };
            let info = *board.info();
            let out = board.output();
            let len = info.layout.write_block_len();
            let Some(buf) = self.cmd.get_mut(..len) else {
                continue;
            };
            if let Err(e) = out.emit(buf) {
                self.note_error(e.into());
                continue;
            }
            if let Err(e) = self
                .port
                .write_block(Dest::node(info.node), REALTIME_BLOCK_OFFSET, buf)
            {
                self.note_error(e);
                if matches!(e, HostError::BusReset { .. }) {
                    return;
                }
            }
        }
    }

    fn write_broadcast(&mut self) {
        let mut writer = CommandBlockWriter::new(&mut self.cmd);
        for board in &self.boards {
            if let Err(e) = writer.push(&board.output()) {
                self.stats.count_error(&HostError::Wire(e));
                if self.report.error.is_none() {
                    self.report.error = Some(HostError::Wire(e));
                }
                return;
            }
        }
        let len = writer.len();
        let Some(block) = self.cmd.get(..len) else {
            return;
        };
        let (dest, offset) = self.config.broadcast_route.command();
        if let Err(e) = self.port.start_write_block(dest, offset, block) {
            self.note_error(e);
        }
    }

    /// Power, relay and amplifier changes of boards whose write block has
    /// no control quadlet (Rev 4): one STATUS write each, when asked.
    fn write_status_registers(&mut self) {
        let Ok(offset) = Register::board(BoardRegister::Status).offset() else {
            return;
        };
        for i in 0..self.boards.len() {
            let Some((node, word)) = self
                .boards
                .get(i)
                .and_then(|b| Some((b.info().node, b.pending_status_write()?)))
            else {
                continue;
            };
            if let Err(e) = self.port.write_quadlet(Dest::node(node), offset, word) {
                self.note_error(e);
                if matches!(e, HostError::BusReset { .. }) {
                    return;
                }
            }
        }
    }

    /// Boards this system asked for motor power or an amplifier since the
    /// last power-down (bit i = board ID i).
    pub fn energised(&self) -> u16 {
        self.energised
    }

    /// Forget what was energised (after a power-down, or to leave the
    /// boards as they are on purpose: a test of a crashed host).
    pub fn clear_energised(&mut self) {
        self.energised = 0;
    }

    /// The watchdog this system last programmed, if it did.
    pub fn watchdog_programmed(&self) -> Option<WatchdogSetting> {
        self.watchdog
    }

    /// One full cycle: read all, then write all.
    pub fn cycle(&mut self) -> &CycleReport {
        self.read_all();
        self.write_all()
    }
}

/// A program that powered boards and ends without powering them down (an
/// error return, a panic unwinding, a stop request) powers them down here:
/// [`RobotIo::power_down`](crate::RobotIo::power_down), the one rule.
impl<P: Port> Drop for IoSystem<P> {
    fn drop(&mut self) {
        if self.energised != 0 {
            let _ = crate::RobotIo::power_down(self);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::board::realtime::FirmwareRev;

    /// QLA1 sets count their boards at every revision (the wait is then
    /// the reference host's 10 + 5 N us); a DQLA (60-quadlet block) counts
    /// as two QLA1 blocks.
    #[test]
    fn the_broadcast_wait_counts_qla1_blocks() {
        let qla1 = |rev| BoardLayout::new(rev, 4, 4).unwrap();
        let dqla = BoardLayout::new(FirmwareRev::Rev9, 8, 8).unwrap();
        for rev in [FirmwareRev::Rev7, FirmwareRev::Rev8, FirmwareRev::Rev9] {
            for n in [1usize, 4, 8, 16] {
                assert_eq!(qla1_read_blocks((0..n).map(|_| qla1(rev))), n, "{rev:?}");
            }
        }
        assert_eq!(dqla.read_block_quadlets(), 60);
        assert_eq!(qla1_read_blocks([dqla; 3]), 6);
        assert_eq!(qla1_read_blocks([dqla, qla1(FirmwareRev::Rev9)]), 3);
    }
}
