//! A minimal FPGA-board responder for bus-only scenarios and tests.
//!
//! Just enough of an FPGA1394/QLA board to exercise the bus with the seed
//! papers' traffic. The real emulated boards (crate `firelink-board`)
//! replace it everywhere but in bus-only tests. It:
//!
//! - answers quadlet and block reads with a concatenated ack_pending and
//!   response, and writes with ack_complete (ack_data_error on a data CRC
//!   error; silence on a header CRC error);
//! - takes the broadcast query (a quadlet write to offset 0x1800, sent to
//!   node 63 or snooped from node 0, data `seq << 16 | mask`) and, if it is
//!   selected, broadcasts its status block (a block write to
//!   0xFFFF_FF00_1000, destination 0xFFFF, pri 0xA) in its slot: the seed
//!   profile's fixed TDMA slot (150 + 256 x physical ID clocks of
//!   49.152 MHz after the query), or the Rev 7+ chain (the lowest selected
//!   board after 150 clocks, each next one as soon as every lower selected
//!   board's block has arrived);
//! - caches every status block (its own too) in hub memory, packed in
//!   arrival order, and answers the hub block read at 0x1000;
//! - takes its slice of the command broadcast;
//! - reports what it detects (CRC errors, a corrupt query, duplicate or late
//!   packets, a stalled chain) with
//!   [`NodeCtx::report_error`](crate::node::NodeCtx::report_error).
//!
//! The status block's content is synthetic: quadlet 0 the time since the
//! query in clocks, quadlet 1 a STATUS word (4 axes, board ID in bits
//! 27:24), then a counter pattern.

use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed, Tcode};

use super::Profile;
use crate::node::{ArbitrationClass, Node, NodeCtx, ResetInfo, RxReply, TransmitRequest};
use crate::time::{SimDuration, SimTime};

/// FPGA system clock: 49.152 MHz.
pub const SYSCLK_HZ: u64 = 49_152_000;

/// `n` system clocks.
pub fn clocks(n: u64) -> SimDuration {
    SimDuration::from_bits(n, SYSCLK_HZ)
}

/// Clocks before the first status broadcast (and before the lowest board of
/// the Rev 7+ chain): 150 (about 3.05 us).
pub const FIRST_SLOT_CLOCKS: u64 = 150;
/// TDMA slot per physical ID in the seed profile: 256 clocks (5.21 us).
pub const TDMA_SLOT_CLOCKS: u64 = 256;

/// Offset of the broadcast query (hub space register).
pub const QUERY_OFFSET: u16 = 0x1800;
/// Offset of hub memory.
pub const HUB_OFFSET: u16 = 0x1000;
/// Full offset of the status broadcasts.
pub const STATUS_BROADCAST_OFFSET: u64 = 0xFFFF_FF00_1000;
/// Full offset of the command broadcast when sent to node 0 (snooped).
pub const COMMAND_SNOOP_OFFSET: u64 = 0xFFFF_FFFF_0000;
/// Hub memory size in quadlets.
pub const HUB_QUADLETS: usize = 512;

const TOKEN_SEND: u64 = 1;
const TOKEN_CHAIN_TIMEOUT: u64 = 2;
const TOKEN_BROADCAST: u64 = 0xB0;

/// What a [`MinimalBoard`] counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BoardStats {
    /// Queries taken (corrupt ones included).
    pub queries: u32,
    /// Status broadcasts sent.
    pub broadcasts_sent: u32,
    /// Status blocks cached in hub memory (its own included).
    pub blocks_cached: u32,
    /// Packets dropped for a CRC error.
    pub crc_errors: u32,
    /// Reads answered.
    pub reads: u32,
    /// Writes accepted (command broadcasts excluded).
    pub writes: u32,
    /// Command broadcasts taken.
    pub commands: u32,
    /// Duplicate requests or status blocks seen.
    pub duplicates: u32,
    /// Status blocks that arrived after their TDMA slot.
    pub late: u32,
    /// Bus resets seen.
    pub resets: u32,
}

#[derive(Clone, Copy, Debug)]
struct CycleState {
    seq: u16,
    mask: u16,
    query_at: SimTime,
    sent: bool,
    got: u16,
    timing_written: bool,
}

/// The minimal board. See the module docs.
#[derive(Debug)]
pub struct MinimalBoard {
    name: String,
    board_id: u8,
    profile: Profile,
    class: ArbitrationClass,
    speed: Speed,
    phy_id: u8,
    hub: Vec<u32>,
    hub_fill: usize,
    cycle: Option<CycleState>,
    last_request: Option<Vec<u8>>,
    command: Vec<u32>,
    /// What it counted.
    pub stats: BoardStats,
}

impl MinimalBoard {
    /// Board `board_id` (rotary switch, 0..15) of `profile`, broadcasting at
    /// `speed` with `class` arbitration.
    pub fn new(board_id: u8, profile: Profile, class: ArbitrationClass, speed: Speed) -> Self {
        MinimalBoard {
            name: format!("board{board_id}"),
            board_id: board_id & 0xF,
            profile,
            class,
            speed,
            phy_id: NodeId::BROADCAST_PHY,
            hub: vec![0; HUB_QUADLETS],
            hub_fill: 0,
            cycle: None,
            last_request: None,
            command: Vec::new(),
            stats: BoardStats::default(),
        }
    }

    /// The board ID.
    pub fn board_id(&self) -> u8 {
        self.board_id
    }

    /// Hub memory quadlets written in the current cycle.
    pub fn hub(&self) -> &[u32] {
        self.hub.get(..self.hub_fill).unwrap_or(&[])
    }

    /// This board's slice of the last command broadcast.
    pub fn command(&self) -> &[u32] {
        &self.command
    }

    fn status_word(&self) -> u32 {
        (4 << 28) | (u32::from(self.board_id) << 24)
    }

    fn start_cycle(&mut self, now: SimTime, seq: u16, mask: u16, ctx: &mut NodeCtx<'_>) {
        self.stats.queries += 1;
        self.hub_fill = 0;
        self.cycle = Some(CycleState {
            seq,
            mask,
            query_at: now,
            sent: false,
            got: 0,
            timing_written: false,
        });
        ctx.cancel_timer(TOKEN_SEND);
        ctx.cancel_timer(TOKEN_CHAIN_TIMEOUT);
        if mask & (1 << self.board_id) == 0 {
            return;
        }
        if self.profile.uses_tdma() {
            let at = now + clocks(FIRST_SLOT_CLOCKS + TDMA_SLOT_CLOCKS * u64::from(self.phy_id));
            ctx.set_timer(at, TOKEN_SEND);
        } else {
            let lower = mask & ((1u16 << self.board_id) - 1);
            if lower == 0 {
                ctx.set_timer(now + clocks(FIRST_SLOT_CLOCKS), TOKEN_SEND);
            } else {
                // Fallback if a lower board never shows up.
                let wait = clocks(FIRST_SLOT_CLOCKS + TDMA_SLOT_CLOCKS * u64::from(self.board_id))
                    + SimDuration::from_micros(20);
                ctx.set_timer(now + wait, TOKEN_CHAIN_TIMEOUT);
            }
        }
    }

    fn send_status(&mut self, now: SimTime, ctx: &mut NodeCtx<'_>) {
        let Some(mut cycle) = self.cycle else {
            return;
        };
        if cycle.sent {
            return;
        }
        cycle.sent = true;
        let n = self.profile.status_broadcast_quadlets();
        let mut block = Vec::with_capacity(n);
        block.push((u32::from(cycle.seq) << 16) | n as u32);
        let elapsed = (now - cycle.query_at).0 as u128 * u128::from(SYSCLK_HZ) / 1_000_000_000_000;
        block.push(elapsed as u32);
        block.push(self.status_word());
        for i in 3..n {
            block.push((u32::from(self.board_id) << 16) | i as u32);
        }
        let mut data = Vec::with_capacity(n * 4);
        for q in &block {
            data.extend_from_slice(&q.to_be_bytes());
        }
        let offset = STATUS_BROADCAST_OFFSET
            + if self.profile == Profile::Rev8 {
                0
            } else {
                0x20 * u64::from(self.board_id)
            };
        let repr = PacketRepr::WriteBlockRequest {
            header: AsyncHeader::new(NodeId::BROADCAST, NodeId::local(self.phy_id), 0)
                .with_pri(0xA),
            offset,
            extended_tcode: 0,
            data: &data,
        };
        let mut packet = vec![0u8; repr.buffer_len()];
        if repr.emit(&mut packet).is_err() {
            return;
        }
        ctx.transmit(TransmitRequest {
            packet,
            speed: self.speed,
            class: self.class,
            token: TOKEN_BROADCAST,
        });
        self.stats.broadcasts_sent += 1;
        self.cycle = Some(cycle);
        self.cache(&block, self.board_id, now, ctx);
    }

    fn cache(&mut self, block: &[u32], from_board: u8, now: SimTime, ctx: &mut NodeCtx<'_>) {
        let Some(mut cycle) = self.cycle else {
            return;
        };
        let bit = 1u16 << (from_board & 0xF);
        if cycle.got & bit != 0 {
            self.stats.duplicates += 1;
            ctx.report_error(format!(
                "{}: duplicate status block from board {from_board}",
                self.name
            ));
            return;
        }
        cycle.got |= bit;
        for &q in block {
            if let Some(slot) = self.hub.get_mut(self.hub_fill) {
                *slot = q;
                self.hub_fill += 1;
            }
        }
        self.stats.blocks_cached += 1;
        if cycle.got & cycle.mask == cycle.mask && !cycle.timing_written {
            cycle.timing_written = true;
            let t = ((now - cycle.query_at).0 as u128 * u128::from(SYSCLK_HZ) / 1_000_000_000_000)
                as u32;
            if let Some(slot) = self.hub.get_mut(self.hub_fill) {
                *slot = t & 0xFFFF;
                self.hub_fill += 1;
            }
        }
        self.cycle = Some(cycle);
        // Rev 7+ chain: go as soon as every lower selected board is in.
        if !self.profile.uses_tdma() && !cycle.sent && cycle.mask & (1 << self.board_id) != 0 {
            let lower = cycle.mask & ((1u16 << self.board_id) - 1);
            if lower != 0 && cycle.got & lower == lower {
                ctx.cancel_timer(TOKEN_CHAIN_TIMEOUT);
                self.send_status(now, ctx);
            }
        }
    }

    fn on_status(&mut self, now: SimTime, view: &Packet<&[u8]>, ctx: &mut NodeCtx<'_>) {
        let data = view.data();
        let quadlets: Vec<u32> = data
            .chunks_exact(4)
            .map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let Some(&status) = quadlets.get(2) else {
            ctx.report_error(format!("{}: short status block", self.name));
            return;
        };
        let from_board = ((status >> 24) & 0xF) as u8;
        if let Some(cycle) = self.cycle {
            let seq = quadlets.first().map_or(0, |h| (h >> 16) as u16);
            if seq != cycle.seq && seq != 0xFFFF {
                ctx.report_error(format!(
                    "{}: status block from board {from_board} has sequence {seq}, expected {}",
                    self.name, cycle.seq
                ));
            }
            if self.profile.uses_tdma() {
                let sender = u64::from(view.source_id().phy());
                let slot_end = cycle.query_at
                    + clocks(FIRST_SLOT_CLOCKS + TDMA_SLOT_CLOCKS * (sender + 1))
                    + SimDuration::from_micros(2);
                if now > slot_end {
                    self.stats.late += 1;
                    ctx.report_error(format!(
                        "{}: status block from board {from_board} arrived after its slot",
                        self.name
                    ));
                }
            }
        }
        self.cache(&quadlets, from_board, now, ctx);
    }

    fn read_register(&self, offset: u16) -> u32 {
        match offset {
            0 => self.status_word(),
            4 => 0x514C_4131,
            7 => self.profile.firmware_version(),
            QUERY_OFFSET => self
                .cycle
                .map_or(0, |c| (u32::from(c.seq) << 16) | u32::from(c.mask)),
            _ => 0,
        }
    }

    fn block_data(&self, offset: u16, len: usize) -> Vec<u8> {
        let mut out = vec![0u8; len];
        if offset == HUB_OFFSET {
            for (chunk, q) in out.chunks_mut(4).zip(self.hub()) {
                let bytes = q.to_be_bytes();
                chunk.copy_from_slice(&bytes[..chunk.len()]);
            }
        } else {
            for (i, chunk) in out.chunks_mut(4).enumerate() {
                let q = if i == 1 {
                    self.status_word()
                } else {
                    (u32::from(self.board_id) << 16) | i as u32
                };
                chunk.copy_from_slice(&q.to_be_bytes()[..chunk.len()]);
            }
        }
        out
    }

    fn respond(&self, repr: &PacketRepr<'_>) -> Option<Vec<u8>> {
        let mut buf = vec![0u8; repr.buffer_len()];
        repr.emit(&mut buf).ok()?;
        Some(buf)
    }
}

impl Node for MinimalBoard {
    fn name(&self) -> &str {
        &self.name
    }

    fn on_bus_reset(&mut self, _now: SimTime, info: &ResetInfo, ctx: &mut NodeCtx<'_>) {
        self.phy_id = info.phy_id;
        self.stats.resets += 1;
        self.cycle = None;
        ctx.cancel_timer(TOKEN_SEND);
        ctx.cancel_timer(TOKEN_CHAIN_TIMEOUT);
    }

    fn on_receive(
        &mut self,
        now: SimTime,
        packet: &[u8],
        speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply {
        let Ok(view) = Packet::new_checked(packet) else {
            self.stats.crc_errors += 1;
            ctx.report_error(format!("{}: malformed packet", self.name));
            return RxReply::Silent;
        };
        let tcode = view.tcode();
        if tcode == Tcode::CycleStart || tcode == Tcode::LinkInternal {
            return RxReply::Silent;
        }
        let offset = view.offset();
        let lo = offset as u16;
        let dest = view.destination_id();
        let bcast = dest.is_broadcast();
        let to_me = dest.phy() == self.phy_id && !bcast;
        let is_query =
            tcode == Tcode::WriteQuadletRequest && lo == QUERY_OFFSET && (bcast || dest.phy() == 0);
        let header_ok = view.header_crc_ok() != Some(false);
        let relevant = to_me
            || bcast
            || is_query
            || (tcode == Tcode::WriteBlockRequest
                && dest.phy() == 0
                && offset == COMMAND_SNOOP_OFFSET);
        if header_ok && !relevant {
            // Another node's unicast traffic: the link ignores it.
            return RxReply::Silent;
        }
        if !header_ok {
            self.stats.crc_errors += 1;
            if is_query {
                // Seed 000: answer a corrupt query with sequence 0xFFFF.
                ctx.report_error(format!("{}: corrupt query (header CRC)", self.name));
                let mask = self.cycle.map_or(0xFFFF, |c| c.mask);
                self.start_cycle(now, 0xFFFF, mask, ctx);
            } else {
                ctx.report_error(format!("{}: header CRC error", self.name));
            }
            return RxReply::Silent;
        }
        if view.data_crc_ok() == Some(false) {
            self.stats.crc_errors += 1;
            ctx.report_error(format!("{}: data CRC error", self.name));
            return if to_me {
                RxReply::Ack(Ack::DataError)
            } else {
                RxReply::Silent
            };
        }
        let ack_if_mine = |ack| {
            if to_me {
                RxReply::Ack(ack)
            } else {
                RxReply::Silent
            }
        };
        if is_query {
            let data = view.quadlet_data();
            self.start_cycle(now, (data >> 16) as u16, data as u16, ctx);
            return ack_if_mine(Ack::Complete);
        }
        if tcode == Tcode::WriteBlockRequest
            && bcast
            && (HUB_OFFSET..HUB_OFFSET + HUB_QUADLETS as u16).contains(&lo)
        {
            self.on_status(now, &view, ctx);
            return RxReply::Silent;
        }
        let is_command = tcode == Tcode::WriteBlockRequest
            && lo == 0
            && (bcast || (dest.phy() == 0 && offset == COMMAND_SNOOP_OFFSET));
        if is_command {
            self.stats.commands += 1;
            let per = self.profile.command_quadlets_per_board();
            let start = usize::from(self.board_id) * per * 4;
            self.command = view
                .data()
                .get(start..start + per * 4)
                .unwrap_or(&[])
                .chunks_exact(4)
                .map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            return ack_if_mine(Ack::Complete);
        }
        if !to_me {
            return RxReply::Silent;
        }
        if self.last_request.as_deref() == Some(packet) {
            self.stats.duplicates += 1;
            ctx.report_error(format!("{}: duplicate request (same label)", self.name));
        }
        self.last_request = Some(packet.to_vec());
        let header =
            AsyncHeader::new(view.destination_id(), view.source_id(), view.tl()).response();
        match tcode {
            Tcode::ReadQuadletRequest => {
                self.stats.reads += 1;
                let repr = PacketRepr::ReadQuadletResponse {
                    header,
                    rcode: Rcode::Complete,
                    data: self.read_register(lo),
                };
                match self.respond(&repr) {
                    Some(response) => RxReply::AckThenResponse {
                        ack: Ack::Pending,
                        response,
                        speed,
                    },
                    None => RxReply::Ack(Ack::TypeError),
                }
            }
            Tcode::ReadBlockRequest => {
                let len = usize::from(view.data_length());
                if len > speed.max_async_payload() {
                    return RxReply::Ack(Ack::TypeError);
                }
                self.stats.reads += 1;
                let data = self.block_data(lo, len);
                let repr = PacketRepr::ReadBlockResponse {
                    header,
                    rcode: Rcode::Complete,
                    extended_tcode: 0,
                    data: &data,
                };
                match self.respond(&repr) {
                    Some(response) => RxReply::AckThenResponse {
                        ack: Ack::Pending,
                        response,
                        speed,
                    },
                    None => RxReply::Ack(Ack::TypeError),
                }
            }
            Tcode::WriteQuadletRequest | Tcode::WriteBlockRequest => {
                self.stats.writes += 1;
                RxReply::Ack(Ack::Complete)
            }
            _ => RxReply::Ack(Ack::TypeError),
        }
    }

    fn on_timer(&mut self, now: SimTime, token: u64, ctx: &mut NodeCtx<'_>) {
        match token {
            TOKEN_SEND => self.send_status(now, ctx),
            TOKEN_CHAIN_TIMEOUT if self.cycle.is_some_and(|c| !c.sent) => {
                ctx.report_error(format!(
                    "{}: chain stalled, a lower board never broadcast",
                    self.name
                ));
                self.send_status(now, ctx);
            }
            _ => {}
        }
    }
}
