//! The broadcast protocol's half of the I/O system: per broadcast group
//! a query, the wait while the boards broadcast their status, one hub
//! read whose blocks are checked and parsed straight into the boards'
//! inputs; then all commands in one broadcast block write (also the
//! write of [`Protocol::SequentialReadBroadcastWrite`]). Where the query
//! and the commands go ([`BroadcastRoute`]) and each group's hub block,
//! hub read and wait ([`QueryGroup`]) are worked out at each scan.
//!
//! [`Protocol::SequentialReadBroadcastWrite`]: crate::qla::scan::Protocol::SequentialReadBroadcastWrite

use std::time::Duration;

use firelink_wire::packet::Packet;
use firelink_wire::qla::MAX_BOARDS;
use firelink_wire::qla::address::{
    COMMAND_BLOCK_OFFSET, COMMAND_SNOOP_NODE, COMMAND_SNOOP_OFFSET, HUB_MEMORY_OFFSET,
    HUB_QUERY_OFFSET,
};
use firelink_wire::qla::broadcast::{
    BoardSlot, CommandBlockWriter, HubBlock, HubHeader, Query, hub_block_quadlets,
    status_broadcast_board,
};
use firelink_wire::qla::realtime::{BlockFormat, BoardLayout};

use super::{IoSystem, miss_from_wire};
use crate::cycle_report::{HubReadTimes, hub_ticks_us};
use crate::error::{HostError, MissReason, Result};
use crate::port::{Dest, Port};
use crate::qla::scan::ScanReport;

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

/// One broadcast query of a cycle and the hub block it fills.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct QueryGroup {
    /// The query's board mask.
    pub(super) mask: u16,
    /// The selected boards' indices in the system (ascending board ID).
    pub(super) members: Vec<usize>,
    /// Their slots, in the same order: the hub block's entries.
    pub(super) slots: Vec<BoardSlot>,
    /// Quadlets of the hub block these boards fill ...
    pub(super) hub_quadlets: usize,
    /// ... and of the hub read (more for Rev 4 boards: a fixed 16-board
    /// block).
    pub(super) hub_read_quadlets: usize,
    /// Between the query and the hub read.
    pub(super) wait: Duration,
    /// Where the hub block's timing quadlet is
    /// ([`HubBlock::timing_quadlet`] of `slots`, worked out here once).
    pub(super) timing_quadlet: Option<usize>,
    /// Whether every slot has the same layout (then each hub block is
    /// taken for the board its STATUS names), worked out here once.
    pub(super) uniform: bool,
    /// Per board ID: the first slot with that ID, `u8::MAX` for none.
    pub(super) slot_by_id: [u8; MAX_BOARDS],
}

impl QueryGroup {
    /// The first slot of board `id` (what `slots.iter().position` finds,
    /// from the table made with the group).
    #[inline]
    fn slot_of(&self, id: u8) -> Option<usize> {
        match self.slot_by_id.get(usize::from(id)) {
            Some(&k) if k != u8::MAX => Some(usize::from(k)),
            Some(_) => None,
            // (No board ID is above 15; searched all the same.)
            None => self.slots.iter().position(|s| s.id == id),
        }
    }
}

/// Per board (index in the system): its block from the hub was latched,
/// or why it has none; `None` when no block came.
type HubOutcomes = [Option<core::result::Result<(), MissReason>>; MAX_BOARDS];

impl<P: Port> IoSystem<P> {
    /// The broadcast queries of one cycle for the boards of `scan`
    /// ([`crate::qla::scan::broadcast_groups`]), each with its hub block, hub read and
    /// wait.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] when these boards cannot run the
    /// broadcast protocol, or the asked hub read is shorter than a group's
    /// hub block.
    pub(super) fn query_groups(&self, scan: &ScanReport) -> Result<Vec<QueryGroup>> {
        let masks =
            crate::qla::scan::broadcast_groups(&scan.boards).ok_or(HostError::InvalidRequest {
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
            let timing_quadlet = HubBlock::<&[u8]>::timing_quadlet(&slots);
            let uniform = slots.windows(2).all(|w| w[0].layout == w[1].layout);
            let mut slot_by_id = [u8::MAX; MAX_BOARDS];
            for (k, slot) in slots.iter().enumerate().rev() {
                if let (Some(at), Ok(k)) =
                    (slot_by_id.get_mut(usize::from(slot.id)), u8::try_from(k))
                {
                    *at = k;
                }
            }
            groups.push(QueryGroup {
                mask,
                members,
                slots,
                hub_quadlets,
                hub_read_quadlets,
                wait,
                timing_quadlet,
                uniform,
                slot_by_id,
            });
        }
        Ok(groups)
    }

    /// The broadcast protocol's read: per group, query, wait for the
    /// status broadcasts, one hub read, each hub block taken for its board.
    pub(super) fn read_broadcast(&mut self) {
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
        // (Filled in place: no copy of the table returned.)
        let mut outcomes: HubOutcomes = [None; MAX_BOARDS];
        if let Err(e) = self.hub_outcomes(g, hub_len, seq, &mut outcomes) {
            let reason = miss_from_wire(e);
            self.stats.count_error(&HostError::Wire(e));
            self.miss_group(g, reason);
            return;
        }
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
    /// buffer (`hub_len` bytes) after query `seq`, by index in the system,
    /// into `outcomes` (all `None` when called): its block parsed straight
    /// into the board's inputs and latched, or why it has none (`None`: no
    /// block came, or the board is not in the group); the update times go
    /// into the report.
    ///
    /// # Errors
    /// The hub memory does not decode.
    fn hub_outcomes(
        &mut self,
        g: usize,
        hub_len: usize,
        seq: u16,
        outcomes: &mut HubOutcomes,
    ) -> core::result::Result<(), firelink_wire::Error> {
        let Some(group) = self.groups.get(g) else {
            return Ok(());
        };
        let bytes = self.buf.get(..hub_len).unwrap_or(&[]);
        let hub = HubBlock::new_checked_quadlets(bytes, &group.slots, group.hub_quadlets)?;
        let clock_hz = self.port.hub_clock_hz();
        // The hub packs blocks in arrival order, which is board order for
        // the Rev 7+ chain but not always for TDMA slots (a late slot, fair
        // arbitration, a late answer to an earlier group's query): when
        // every block has the same size, each one is taken for the board
        // its STATUS names.
        // (`uniform` and the slots by ID worked out with the group.)
        for (i, entry) in hub.entries().enumerate() {
            let named = entry.block.status().board_id();
            let k = if group.uniform {
                match group.slot_of(named) {
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
        let timing = hub.timing_at(group.timing_quadlet).to_word();
        self.report.hub_read = HubReadTimes::from_word(timing, clock_hz);
        Ok(())
    }

    /// Every board's commands in one command block, written once on the
    /// broadcast route.
    pub(super) fn write_broadcast(&mut self) {
        let mut writer = CommandBlockWriter::new(&mut self.cmd);
        for board in &self.boards {
            let (block, control) = board.output_parts();
            if let Err(e) = writer.push_with_control(block, control) {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::qla::realtime::FirmwareRev;

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
