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
//!   groups ([`crate::qla::scan::broadcast_groups`]): query, wait and hub read
//!   once per group, each query with its own sequence number and the
//!   group's board mask, then the one command write to all boards.
//!
//! Every cycle checks that each expected board answered: its block size,
//! its board ID and (broadcast) the sequence number. A board that misses a
//! cycle is reported by ID with the reason and counted; its inputs are
//! marked invalid, never silently reused.
//!
//! The module's parts: the per-board protocols' reads and writes
//! (`sequential`), the broadcast protocol's queries, hub reads and
//! command block (`broadcast`) and the system as the abstract robot I/O
//! (`robot_io`); what they share (the system, its set-up, registers and
//! the cycle's frame) is here. What every protocol fills in, the cycle's
//! report and the counters, is every robot's: [`crate::cycle_report`].

mod broadcast;
mod robot_io;
mod sequential;

use std::time::Duration;

use firelink_wire::qla::MAX_BOARDS;
use firelink_wire::qla::address::{BoardRegister, Register};
use firelink_wire::qla::broadcast::{BoardSlot, SeqRule};
use firelink_wire::qla::realtime::BlockFormat;
use firelink_wire::qla::registers::{AmpCommand, StatusCommand, WatchdogSetting};

use crate::cycle_report::{CycleReport, IoStats};
use crate::error::{HostError, MissReason, Result};
use crate::port::{Dest, Port};
use crate::qla::board::BoardIo;
use crate::qla::scan::{Protocol, ScanReport, scan};

pub use broadcast::BroadcastRoute;
use broadcast::QueryGroup;

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
    /// Whether a board's write block has no control quadlet (Rev 4): only
    /// such a board takes its power, relay and amplifier changes as STATUS
    /// writes ([`BoardIo::pending_status_write`]); worked out at each scan.
    status_writes: bool,
}

/// Where boards and axes are in an [`IoSystem`]'s board list.
#[derive(Debug, Clone, Default)]
struct AxisLookup {
    /// Per board ID: index in the board list, `u8::MAX` for none.
    by_id: [u8; MAX_BOARDS],
    /// Per axis over all boards: (board index, axis on that board).
    axes: Vec<(u8, u8)>,
    /// The same table board by board, in axis order: (board index, its
    /// axes), so that a walk over every axis finds each board once.
    runs: Vec<(usize, usize)>,
}

impl AxisLookup {
    fn of(boards: &[BoardIo]) -> AxisLookup {
        let mut by_id = [u8::MAX; MAX_BOARDS];
        let mut axes = Vec::new();
        let mut runs = Vec::new();
        for (index, b) in boards.iter().enumerate() {
            let i = u8::try_from(index).unwrap_or(u8::MAX);
            if let Some(slot) = by_id.get_mut(usize::from(b.board_id())) {
                if *slot == u8::MAX {
                    *slot = i;
                }
            }
            axes.extend((0..b.axes()).map(|a| (i, u8::try_from(a).unwrap_or(u8::MAX))));
            runs.push((usize::from(i), b.axes()));
        }
        AxisLookup { by_id, axes, runs }
    }

    #[inline]
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
            status_writes: false,
        };
        system.adopt(scan)?;
        Ok(system)
    }

    fn adopt(&mut self, scan: &ScanReport) -> Result<()> {
        self.boards = scan.boards.iter().map(|b| BoardIo::new(*b)).collect();
        self.lookup = AxisLookup::of(&self.boards);
        self.status_writes = self
            .boards
            .iter()
            .any(|b| b.info().layout.format() == BlockFormat::Rev4);
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
    /// the broadcast protocol runs in groups ([`crate::qla::scan::protocol_label`]).
    pub fn protocol_label(&self) -> String {
        crate::qla::scan::protocol_label(self.protocol, self.groups.len())
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

    /// Every axis's latched encoder count (0 where there is none) and pot
    /// code, in axis order: `counts[i]` and `pots[i]` for every axis `i`
    /// below the shorter slice's length, 0 and `None` past the last axis
    /// (what [`RobotIo::axis_inputs`](crate::RobotIo::axis_inputs) says).
    /// One walk over the boards, each board's axes read from its latched
    /// block in one run ([`BoardIo::axis_inputs`]), no look-up per axis.
    #[inline]
    pub fn axis_inputs(&self, counts: &mut [i32], pots: &mut [Option<u16>]) {
        let n = counts.len().min(pots.len());
        let (mut counts, mut pots) = (
            counts.get_mut(..n).unwrap_or_default(),
            pots.get_mut(..n).unwrap_or_default(),
        );
        for &(b, axes) in &self.lookup.runs {
            let here = axes.min(counts.len());
            let (board_counts, rest_counts) = core::mem::take(&mut counts).split_at_mut(here);
            let (board_pots, rest_pots) = core::mem::take(&mut pots).split_at_mut(here);
            match self.boards.get(b) {
                Some(board) => board.axis_inputs(board_counts, board_pots),
                None => {
                    board_counts.fill(0);
                    board_pots.fill(None);
                }
            }
            (counts, pots) = (rest_counts, rest_pots);
        }
        // (Most often nothing is left: no call to fill nothing.)
        if !counts.is_empty() {
            counts.fill(0);
            pots.fill(None);
        }
    }

    /// Axis `i`'s DAC code into its board's next command block for each
    /// `codes[i]` that is `Some` (what
    /// [`RobotIo::set_motor_commands`](crate::RobotIo::set_motor_commands)
    /// says); codes past the last axis are ignored. One walk over the
    /// boards, each board's codes set in one run ([`BoardIo::set_dacs`]).
    #[inline]
    pub fn set_motor_commands(&mut self, codes: &[Option<u16>]) {
        let mut codes = codes;
        for &(b, axes) in &self.lookup.runs {
            let (board_codes, rest) = codes.split_at(axes.min(codes.len()));
            codes = rest;
            if let Some(board) = self.boards.get_mut(b) {
                board.set_dacs(board_codes);
            }
        }
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
        self.report.restart(cycle);
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
        // (Only a Rev 4 board can have a STATUS write pending.)
        if !self.needs_rescan && self.status_writes {
            self.write_status_registers();
        }
        for b in self.boards.iter_mut() {
            let id = b.board_id();
            if b.outputs_applied() {
                self.energised |= 1 << (id & 0xF);
            }
        }
        self.report.write_time = self.port.now().saturating_sub(started);
        self.port.end_cycle();
        let slot = (self.report.cycle % HISTORY as u64) as usize;
        if let Some(h) = self.history.get_mut(slot) {
            *h = self.report;
        }
        &self.report
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
