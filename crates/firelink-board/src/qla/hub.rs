//! The broadcast protocol on the board side (`fpga-board.md` section 6):
//! the query registers, the schedule of this board's status broadcast and
//! the hub memory every board fills with every board's broadcast.

use firelink_wire::field::{read_quadlet, write_quadlet};
use firelink_wire::qla::address::HUB_MEMORY_QUADLETS;
use firelink_wire::qla::broadcast::{BroadcastHeader, HubHeader, HubTiming, Query, has_hub_timing};
use firelink_wire::qla::realtime::{BlockFormat, FirmwareRev};
use firelink_wire::qla::registers::StatusRead;

use crate::time::{SimDuration, SimTime};

/// Rev 7+: the lowest selected board waits this many clocks after the
/// query (about 3 us).
pub const FIRST_SLOT_CLOCKS: u64 = 150;

/// Seed profile: fixed slot width per node ID (about 5.2 us) ...
pub const SEED_SLOT: SimDuration = SimDuration::from_nanos(5_200);

/// ... after this offset from the query (about 3 us).
pub const SEED_OFFSET: SimDuration = SimDuration::from_nanos(3_000);

/// Seed 000's own firmware (Rev 4) counts its TDMA slots in FPGA clocks:
/// 256 per node ID (5.21 us), after [`FIRST_SLOT_CLOCKS`].
pub const SEED_SLOT_CLOCKS: u64 = 256;

/// Seed profile: when node `node`'s status broadcast is due after the
/// query. Rev 4 boards count `150 + 256 x node` clocks (3.05 + 5.21 us x
/// node, the figures calibrated against seed 000's Fig. 9); over later
/// firmware's layouts the profile keeps the spec's round figures
/// ([`SEED_OFFSET`] + [`SEED_SLOT`] x node).
pub fn seed_slot(firmware: FirmwareRev, node: u8) -> SimDuration {
    if firmware.block_format() == BlockFormat::Rev4 {
        SimDuration::from_clocks(FIRST_SLOT_CLOCKS + SEED_SLOT_CLOCKS * u64::from(node))
    } else {
        SEED_OFFSET + SimDuration(SEED_SLOT.0 * u64::from(node))
    }
}

/// Rev 7+: a board whose predecessors have not all been heard transmits
/// anyway this long per predecessor after its first possible slot, so one
/// silent board does not silence the chain behind it.
pub const CHAIN_TIMEOUT_PER_BOARD: SimDuration = SimDuration::from_micros(50);

/// This board's status broadcast, waiting for its slot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Pending {
    /// Header and real-time block, wire order.
    pub payload: Vec<u8>,
    /// Not before.
    pub earliest: SimTime,
    /// Board IDs (mask) whose broadcasts must have arrived first.
    pub wait_for: u16,
    /// Transmit at this time even if some have not.
    pub deadline: SimTime,
}

impl Pending {
    /// Whether it may go at `now`, given the boards heard (`seen`).
    pub fn ready(&self, now: SimTime, seen: u16) -> bool {
        now >= self.earliest && (self.wait_for & !seen == 0 || now >= self.deadline)
    }

    /// When it becomes ready if nothing more is heard.
    pub fn due(&self, seen: u16) -> SimTime {
        if self.wait_for & !seen == 0 {
            self.earliest
        } else {
            self.deadline.max(self.earliest)
        }
    }
}

/// The hub's timers (`bcTimer`, `bcReadStart`) count 14 bits at Rev 7
/// and 8 and wrap (HubReg.v; Rev 9 widened them to 16).
const TIMER_MASK: u64 = 0x3FFF;

/// The Ethernet hub of an FPGA V3 at Rev 9 (EthernetIO.v's `hub_eth`,
/// clocked by the 125 MHz Ethernet clock): its timers count 16 bits; the
/// hub header keeps 15 of them as the update time.
const ETH_TIMER_MASK: u64 = 0xFFFF;

/// Which clock the hub's timers count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum HubClock {
    /// The board's 49.152 MHz system clock, 14 bits (the FireWire hub).
    System,
    /// The 125 MHz Ethernet clock, 16 bits (the Ethernet-only network;
    /// the host's `GetBroadcastReadClockPeriod` is 8 ns there).
    Ethernet,
}

/// Hub registers and memory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Hub {
    /// Hub memory, packed in arrival order (512 quadlets, wire order).
    pub memory: Vec<u8>,
    /// Quadlets written since the query (register 0x1802 once a query
    /// came).
    pub count: usize,
    /// The block format (which timers and registers the hub has).
    format: BlockFormat,
    /// The clock of its timers.
    pub clock: HubClock,
    /// Power-up (or reboot): where the timer counts from until the first
    /// query.
    power_up: SimTime,
    /// The system clock's count at the timer's origin (`query_at`, or
    /// `power_up` before any query), kept with them so that the timer of
    /// every store converts only `now` to clocks.
    origin_clocks: u64,
    /// `bcReadStart`: the timer when a read last addressed hub quadlet 0
    /// (HubReg.v), 0 from power-up.
    read_start: u16,
    /// The last query taken.
    pub query: Option<Query>,
    /// When it arrived.
    pub query_at: Option<SimTime>,
    /// Boards heard since (bit = board ID).
    pub seen: u16,
    /// When every selected board had been heard.
    pub complete_at: Option<SimTime>,
    /// This board's broadcast waiting for its slot.
    pub pending: Option<Pending>,
    /// This board's broadcast handed to the bus, stored once sent.
    pub in_flight: Option<Vec<u8>>,
    /// A payload buffer kept for the next broadcast (no allocation per
    /// query).
    spare: Vec<u8>,
}

impl Hub {
    /// The hub of a board of block `format` powered up at `now`.
    pub fn new(now: SimTime, format: BlockFormat) -> Hub {
        Hub {
            memory: vec![0; HUB_MEMORY_QUADLETS * 4],
            count: 0,
            format,
            clock: HubClock::System,
            power_up: now,
            origin_clocks: now.clocks(),
            read_start: 0,
            query: None,
            query_at: None,
            seen: 0,
            complete_at: None,
            pending: None,
            in_flight: None,
            spare: Vec::new(),
        }
    }

    /// A buffer for the next broadcast's payload.
    pub fn spare_payload(&mut self) -> Vec<u8> {
        core::mem::take(&mut self.spare)
    }

    /// Keep a sent broadcast's payload buffer for the next one.
    pub fn keep_payload(&mut self, payload: Vec<u8>) {
        self.spare = payload;
    }

    /// The selected boards of the last query.
    pub fn mask(&self) -> u16 {
        self.query.map_or(0, |q| q.board_mask)
    }

    /// The register at 0x1800.
    pub fn query_word(&self) -> u32 {
        self.query.and_then(|q| q.to_word().ok()).unwrap_or(0)
    }

    /// Start a new cycle at `now`.
    pub fn start_cycle(&mut self, now: SimTime) {
        self.query_at = Some(now);
        self.origin_clocks = now.clocks();
        self.count = 0;
        self.seen = 0;
        self.complete_at = None;
        self.pending = None;
        self.in_flight = None;
    }

    /// Store one status broadcast payload (header + real-time block)
    /// arriving at `now`, its header rewritten as the format says
    /// (`HubHeader::rewrite`). A payload whose header size does not match
    /// its length, or that does not fit, is not stored; nor is a second
    /// block answering this board's query from a board already heard (a
    /// packet the bus delivered twice): that returns `false`.
    ///
    /// The same bytes, count and answer as `HubPacker::store_broadcast`
    /// into the free memory (the test `store_matches_the_hub_packer` holds
    /// the two together), its checks worked out once from the header's
    /// size and the payload copied whole, its first quadlet then
    /// overwritten with the rewritten header. Always inlined: a board
    /// stores another board's broadcast on most deliveries (56 stores per
    /// demo cycle), and a call costs about a tenth of a store.
    #[inline(always)]
    pub fn store(&mut self, now: SimTime, payload: &[u8], format: BlockFormat) -> bool {
        // The block's STATUS quadlet (after header and timestamp) names the
        // board.
        let board = StatusRead(read_quadlet(payload, 2)).board_id();
        let bit = 1u16.checked_shl(u32::from(board)).unwrap_or(0);
        let broadcast = BroadcastHeader::from_word(read_quadlet(payload, 0));
        if self.seen & bit != 0 && self.query.is_some_and(|q| q.seq == broadcast.seq) {
            return false;
        }
        // What the packer refuses: no header, partial quadlets or a header
        // size that is not the payload's (one test: a size of at least one
        // quadlet equal to the length), at Rev 8 a size its 8-bit field
        // cannot hold, no room left in the 512 quadlets.
        let quadlets = usize::from(broadcast.quadlets);
        if quadlets == 0
            || quadlets * 4 != payload.len()
            || (format == BlockFormat::Rev8 && quadlets > 0xFF)
            || self.count + quadlets > HUB_MEMORY_QUADLETS
        {
            return true;
        }
        // The update time is the hub timer's (14 bits, wrapping) at Rev 7
        // and 8; Rev 4 counts 16 bits, held at the top.
        let update = match format {
            BlockFormat::Rev4 => {
                self.query_at.map_or(0, |q| now.clocks_since(q)).min(0xFFFF) as u16
            }
            BlockFormat::Rev7 | BlockFormat::Rev8 => self.timer(now),
        };
        let seq = self.query.map_or(0, |q| q.seq);
        let Ok(word) = HubHeader::rewrite(broadcast, seq, update, format).to_word() else {
            return true;
        };
        let start = self.count * 4;
        let Some(entry) = self.memory.get_mut(start..start + payload.len()) else {
            return true;
        };
        entry.copy_from_slice(payload);
        write_quadlet(entry, 0, word);
        self.count += quadlets;
        self.seen |= bit;
        if self.complete_at.is_none() && self.updated() {
            self.complete_at = Some(now);
        }
        true
    }

    /// The hub timer (`bcTimer`) at `now`: clocks since the last query, or
    /// since power-up before any, 14 bits wrapping.
    fn timer(&self, now: SimTime) -> u16 {
        match self.clock {
            // `now.clocks_since(since)`, the origin's count kept.
            HubClock::System => {
                (now.clocks().saturating_sub(self.origin_clocks) & TIMER_MASK) as u16
            }
            HubClock::Ethernet => {
                let since = self.query_at.unwrap_or(self.power_up);
                ((now.saturating_since(since).as_nanos() / 8) & ETH_TIMER_MASK) as u16
            }
        }
    }

    /// Whether every board the last query selected has stored its block
    /// since (false before any query).
    pub fn complete(&self) -> bool {
        self.query_at.is_some() && self.updated()
    }

    /// Every board the query selected has stored its block (before any
    /// query, or after one with an empty mask, that is every board).
    fn updated(&self) -> bool {
        self.mask() & !self.seen == 0
    }

    /// Register `0x1802`: the quadlets written since the query (HubReg.v
    /// l.64-65: the last write address plus one). At Rev 8 that address
    /// powers up at 0, so the register reads 1 until the first query (Rev
    /// 9 reads 0).
    pub fn num_written(&self) -> u32 {
        if self.query_at.is_none() && self.format == BlockFormat::Rev8 {
            1
        } else {
            self.count as u32
        }
    }

    /// Whether quadlet `index` reads the extra timing word: once every
    /// selected board has updated, at the quadlet after the last board's
    /// block (HubReg.v `is_extra`); before any query, quadlet 1 at Rev 8.
    fn is_extra(&self, index: usize) -> bool {
        has_hub_timing(self.format)
            && self.updated()
            && index as u64 == u64::from(self.num_written())
    }

    /// A read addressed hub quadlet 0 at `at`: `bcReadStart` takes the
    /// timer (HubReg.v l.134).
    pub fn latch_read_start(&mut self, at: SimTime) {
        self.read_start = self.timer(at);
    }

    /// Hub memory quadlets from `start` on, as read by a read that started
    /// at `read_start`, into `out` (wire order) as far as the memory goes;
    /// returns how many quadlets that was.
    pub fn read_into(&mut self, start: usize, read_start: SimTime, out: &mut [u8]) -> usize {
        if start == 0 {
            self.latch_read_start(read_start);
        }
        let end = HUB_MEMORY_QUADLETS.min(start.saturating_add(out.len() / 4));
        let n = end.saturating_sub(start);
        if let (Some(src), Some(dst)) = (self.memory.get(start * 4..end * 4), out.get_mut(..n * 4))
        {
            dst.copy_from_slice(src);
        }
        let extra = self.num_written() as usize;
        if (start..end).contains(&extra) && self.is_extra(extra) {
            let k = (extra - start) * 4;
            let word = self.timing_word(extra, read_start);
            if let Some(dst) = out.get_mut(k..k + 4) {
                dst.copy_from_slice(&word.to_be_bytes());
            }
        }
        n
    }

    /// Hub quadlet `index` as a quadlet read at `at` reads it (a read of
    /// quadlet 0 latches `bcReadStart`).
    pub fn read(&mut self, index: usize, at: SimTime) -> u32 {
        if index == 0 {
            self.latch_read_start(at);
        }
        if self.is_extra(index) {
            return self.timing_word(index, at);
        }
        read_quadlet(&self.memory, index)
    }

    /// The extra timing word `{bcReadStart, bcTimer}` as quadlet `index`
    /// of a read that started at `read_start` sends it: the timer when
    /// that quadlet goes out (4 clocks per quadlet at S400 after a
    /// 5-quadlet response header), both 14 bits.
    fn timing_word(&self, index: usize, read_start: SimTime) -> u32 {
        // A quadlet takes 4 clocks at S400 and 4 at 125 MHz on 1 Gb/s.
        let now = u64::from(self.timer(read_start)) + 4 * (5 + index as u64);
        let mask = match self.clock {
            HubClock::System => TIMER_MASK,
            HubClock::Ethernet => ETH_TIMER_MASK,
        };
        HubTiming {
            read_start: self.read_start,
            now: (now & mask) as u16,
        }
        .to_word()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::qla::broadcast::HubPacker;

    /// `Hub::store` as it was written over the packer: the reference the
    /// store must match byte for byte.
    fn store_with_packer(hub: &mut Hub, now: SimTime, payload: &[u8], format: BlockFormat) -> bool {
        let board = StatusRead(read_quadlet(payload, 2)).board_id();
        let bit = 1u16.checked_shl(u32::from(board)).unwrap_or(0);
        let seq = BroadcastHeader::from_word(read_quadlet(payload, 0)).seq;
        if hub.seen & bit != 0 && hub.query.is_some_and(|q| q.seq == seq) {
            return false;
        }
        let update = match format {
            BlockFormat::Rev4 => hub.query_at.map_or(0, |q| now.clocks_since(q)).min(0xFFFF) as u16,
            BlockFormat::Rev7 | BlockFormat::Rev8 => hub.timer(now),
        };
        let seq = hub.query.map_or(0, |q| q.seq);
        let Some(free) = hub.memory.get_mut(hub.count * 4..) else {
            return true;
        };
        let mut packer = HubPacker::new(free);
        if packer
            .store_broadcast(payload, seq, update, format)
            .is_err()
        {
            return true;
        }
        hub.count += packer.quadlets();
        hub.seen |= bit;
        if hub.complete_at.is_none() && hub.updated() {
            hub.complete_at = Some(now);
        }
        true
    }

    /// A payload of `len` bytes whose header claims `quadlets` and
    /// sequence `seq`, from board `board`, its other bytes from `salt`.
    fn payload(len: usize, quadlets: u16, seq: u16, board: u8, salt: u8) -> Vec<u8> {
        let mut bytes: Vec<u8> = (0..len)
            .map(|i| (i as u8).wrapping_mul(31) ^ salt)
            .collect();
        write_quadlet(&mut bytes, 0, (u32::from(seq) << 16) | u32::from(quadlets));
        let status = StatusRead::default().with_board_id(board).raw();
        write_quadlet(&mut bytes, 2, status);
        bytes
    }

    /// The store and the packer leave the same memory, count, boards heard
    /// and completion time and give the same answer, for good blocks,
    /// wrong sizes, partial quadlets, headers only, sizes beyond 8 bits,
    /// duplicates, a full memory, all three formats and both clocks.
    #[test]
    fn store_matches_the_hub_packer() {
        for format in [BlockFormat::Rev4, BlockFormat::Rev7, BlockFormat::Rev8] {
            for clock in [HubClock::System, HubClock::Ethernet] {
                let mut hub = Hub::new(SimTime::from_micros(3), format);
                hub.clock = clock;
                let mut reference = hub.clone();
                let (mut stored, mut refused) = (0, 0);
                for round in 0u16..6 {
                    let at = SimTime::from_micros(1_000 * u64::from(round) + 7);
                    if round > 0 {
                        let query = Query::parse(0x0000_00FF | (u32::from(round + 1) << 16)).ok();
                        for h in [&mut hub, &mut reference] {
                            h.query = query;
                            h.start_cycle(at);
                        }
                    }
                    // A size beyond 8 bits first, while it would fit.
                    let cases: [(usize, u16); 15] = [
                        (1024, 256),
                        (116, 29),
                        (116, 28),
                        (114, 29),
                        (4, 1),
                        (0, 0),
                        (2, 0),
                        (8, 3),
                        (1020, 255),
                        (1200, 300),
                        (116, 29),
                        (72, 18),
                        (2048, 512),
                        (16, 4),
                        (116, 29),
                    ];
                    for (k, &(len, quadlets)) in cases.iter().enumerate() {
                        let board = (k % 9) as u8;
                        let seq = if k % 4 == 3 { round + 9 } else { round + 1 };
                        let bytes = payload(len, quadlets, seq, board, (k as u8) ^ (round as u8));
                        let now = at + SimDuration::from_nanos(1_300 * k as u64 + 11);
                        let before = hub.count;
                        let a = hub.store(now, &bytes, format);
                        let b = store_with_packer(&mut reference, now, &bytes, format);
                        assert_eq!(a, b, "{format:?} round {round} case {k}");
                        assert_eq!(hub, reference, "{format:?} round {round} case {k}");
                        if hub.count > before {
                            stored += 1;
                        } else {
                            refused += 1;
                        }
                    }
                }
                assert!(stored > 10 && refused > 10, "{stored} {refused}");
            }
        }
    }
}
