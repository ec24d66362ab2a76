//! The broadcast protocol on the board side (`fpga-board.md` section 6):
//! the query registers, the schedule of this board's status broadcast and
//! the hub memory every board fills with every board's broadcast.

use super::bits;
use crate::config::Profile;
use crate::time::{Time, TimeDelta};

/// Quadlets of hub memory.
pub const HUB_QUADLETS: usize = 512;

/// Rev 7+: the lowest selected board waits this many clocks after the
/// query (about 3 us).
pub const FIRST_SLOT_CLOCKS: u64 = 150;

/// Seed profile: fixed slot width per node ID (about 5.2 us) ...
pub const SEED_SLOT: TimeDelta = TimeDelta::from_nanos(5_200);

/// ... after this offset from the query (about 3 us).
pub const SEED_OFFSET: TimeDelta = TimeDelta::from_nanos(3_000);

/// Rev 7+: a board whose predecessors have not all been heard transmits
/// anyway this long per predecessor after its first possible slot, so one
/// silent board does not silence the chain behind it.
pub const CHAIN_TIMEOUT_PER_BOARD: TimeDelta = TimeDelta::from_micros(50);

/// This board's status broadcast, waiting for its slot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Pending {
    /// Header and real-time block.
    pub payload: Vec<u32>,
    /// Not before.
    pub earliest: Time,
    /// Board IDs (mask) whose broadcasts must have arrived first.
    pub wait_for: u16,
    /// Transmit at this time even if some have not.
    pub deadline: Time,
}

impl Pending {
    /// Whether it may go at `now`, given the boards heard (`seen`).
    pub fn ready(&self, now: Time, seen: u16) -> bool {
        now >= self.earliest && (self.wait_for & !seen == 0 || now >= self.deadline)
    }

    /// When it becomes ready if nothing more is heard.
    pub fn due(&self, seen: u16) -> Time {
        if self.wait_for & !seen == 0 {
            self.earliest
        } else {
            self.deadline.max(self.earliest)
        }
    }
}

/// Hub registers and memory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Hub {
    /// Hub memory, packed in arrival order.
    pub memory: Vec<u32>,
    /// Quadlets written since the query (register 0x1802).
    pub count: usize,
    /// Sequence of the last query taken.
    pub seq: u16,
    /// Board mask of the last query taken.
    pub mask: u16,
    /// When it arrived.
    pub query_at: Option<Time>,
    /// Boards heard since (bit = board ID).
    pub seen: u16,
    /// When every selected board had been heard.
    pub complete_at: Option<Time>,
    /// Where the timing trailer sits.
    pub trailer_index: Option<usize>,
    /// This board's broadcast waiting for its slot.
    pub pending: Option<Pending>,
    /// This board's broadcast handed to the bus, stored once sent.
    pub in_flight: Option<Vec<u32>>,
}

impl Hub {
    pub fn new() -> Hub {
        Hub {
            memory: vec![0; HUB_QUADLETS],
            count: 0,
            seq: 0,
            mask: 0,
            query_at: None,
            seen: 0,
            complete_at: None,
            trailer_index: None,
            pending: None,
            in_flight: None,
        }
    }

    /// Start a new cycle at `now`.
    pub fn start_cycle(&mut self, now: Time) {
        self.query_at = Some(now);
        self.count = 0;
        self.seen = 0;
        self.complete_at = None;
        self.trailer_index = None;
        self.pending = None;
        self.in_flight = None;
    }

    /// Store one status broadcast (header + real-time block) arriving at
    /// `now`, rewriting its header as the profile does.
    pub fn store(&mut self, now: Time, quads: &[u32], profile: Profile) {
        let Some(&first) = quads.first() else {
            return;
        };
        let (seq, _size) = bits::broadcast_header_parse(first);
        let update = self.query_at.map_or(0, |q| now.clocks_since(q));
        let header = if profile.is_rev8() {
            bits::hub_header_rev8(
                u16::try_from(quads.len()).unwrap_or(u16::MAX),
                seq,
                seq != self.seq,
                update,
            )
        } else {
            bits::hub_header_rev7(seq, update)
        };
        let words = core::iter::once(header).chain(quads.iter().skip(1).copied());
        for (slot, word) in self.memory.iter_mut().skip(self.count).zip(words) {
            *slot = word;
        }
        self.count = (self.count + quads.len()).min(HUB_QUADLETS);
        // The block's STATUS quadlet names the board.
        if let Some(status) = quads.get(2) {
            self.seen |= 1 << ((status >> 24) & 0xF);
        }
        if self.complete_at.is_none() && self.mask != 0 && self.mask & !self.seen == 0 {
            self.complete_at = Some(now);
            if self.count < HUB_QUADLETS {
                self.trailer_index = Some(self.count);
                self.count += 1;
            }
        }
    }

    /// Hub memory quadlet `index` as read at `now` (the trailer is
    /// computed: clocks from the query to the start of this read, and to
    /// the moment every selected board had been heard).
    pub fn read(&self, index: usize, read_start: Time) -> u32 {
        if Some(index) == self.trailer_index {
            if let (Some(q), Some(done)) = (self.query_at, self.complete_at) {
                return bits::hub_trailer(read_start.clocks_since(q), done.clocks_since(q));
            }
        }
        self.memory.get(index).copied().unwrap_or(0)
    }
}
