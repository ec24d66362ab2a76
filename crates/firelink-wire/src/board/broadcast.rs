//! The broadcast protocol (`fpga-board.md` §6; seed 000; firmware Rev 7+):
//! the query, the per-board status broadcasts, the hub block and the
//! concatenated command block.
//!
//! One cycle: the host writes a [`Query`] to `0x1800`; every selected board
//! broadcasts a [`StatusBroadcast`] (header + real-time read block); every
//! board packs all of them into its hub memory ([`HubPacker`]) with
//! rewritten [`HubHeader`]s and a final [`HubTiming`] quadlet; the host
//! reads the [`HubBlock`] from one board, checks sequences with a
//! [`SeqRule`], then broadcasts one command block
//! ([`CommandBlockWriter`]) from which each board takes its slice
//! ([`find_command_block`]).
//!
//! ```
//! use firelink_wire::board::broadcast::{
//!     BoardSlot, HubBlock, HubHeader, HubPacker, HubTiming, SeqRule, StatusBroadcastRepr,
//! };
//! use firelink_wire::board::realtime::{BoardLayout, FirmwareRev, ReadBlockRepr};
//! let layout = BoardLayout::qla1(FirmwareRev::Rev8);
//! let boards = [BoardSlot { id: 0, layout }, BoardSlot { id: 1, layout }];
//! let mut hub = [0u8; 2048];
//! let mut packer = HubPacker::new(&mut hub);
//! for slot in &boards {
//!     // Each board's broadcast, as it arrives on the bus.
//!     let mut packet = [0u8; 33 * 4];
//!     let status = StatusBroadcastRepr { seq: 7, block: ReadBlockRepr::new(slot.layout) };
//!     status.emit(&mut packet).unwrap();
//!     packer.store_broadcast(&packet, 7, 100, layout.format()).unwrap();
//! }
//! let len = packer.finish(HubTiming { read_start: 1, now: 2 }).unwrap();
//! assert_eq!(len, 268);
//! let block = HubBlock::new_checked(&hub[..len], &boards).unwrap();
//! assert_eq!(block.check_sequences(SeqRule::Rev8LowByte, 7), Ok(()));
//! assert_eq!(block.entries().count(), 2);
//! ```

use crate::board::address::{
    HUB_MEMORY_QUADLETS, STATUS_BROADCAST_BOARD_STRIDE, STATUS_BROADCAST_OFFSET, check_board_id,
};
use crate::board::realtime::{
    BlockFormat, BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr, WriteBlock, WriteBlockRepr,
    WriteHeader,
};
use crate::board::registers::DacWord;
use crate::board::{MAX_BOARDS, check_exact, check_max, layout_view};
use crate::error::{Error, Result};
use crate::field::{read_quadlet, write_quadlet};

/// Bit fields of the broadcast protocol quadlets (`fpga-board.md` §6), each
/// defined once.
mod field {
    use crate::field::Field;

    /// Query: the sequence number, bits 31:16.
    pub const QUERY_SEQ: Field = Field::new(0, 31, 16);
    /// Query: the board mask, bits 15:0.
    pub const QUERY_MASK: Field = Field::new(0, 15, 0);

    /// Status broadcast header: the query's sequence, bits 31:16.
    pub const BCAST_SEQ: Field = Field::new(0, 31, 16);
    /// Status broadcast header: quadlets including the header, bits 15:0.
    pub const BCAST_QUADLETS: Field = Field::new(0, 15, 0);

    /// Rev 8 hub header: quadlets including the header, bits 31:24.
    pub const HUB8_QUADLETS: Field = Field::new(0, 31, 24);
    /// Rev 8 hub header: low byte of the board's sequence, bits 23:16.
    pub const HUB8_SEQ_LOW: Field = Field::new(0, 23, 16);
    /// Rev 8 hub header: the full sequence did not match, bit 15.
    pub const HUB8_SEQ_ERROR: Field = Field::new(0, 15, 15);
    /// Rev 8 hub header: update time, bits 14:0.
    pub const HUB8_UPDATE_TIME: Field = Field::new(0, 14, 0);

    /// Rev 7 hub header: the board's sequence, bits 31:16.
    pub const HUB7_SEQ: Field = Field::new(0, 31, 16);
    /// Rev 7 hub header: time, bits 15:0.
    pub const HUB7_TIME: Field = Field::new(0, 15, 0);

    /// Hub timing quadlet: when the hub read started, bits 31:16.
    pub const TIMING_READ_START: Field = Field::new(0, 31, 16);
    /// Hub timing quadlet: the time now, bits 15:0.
    pub const TIMING_NOW: Field = Field::new(0, 15, 0);
}

/// The sequence number answered by a board that received a corrupt query
/// (seed-000 profile, `fpga-board.md` §6).
pub const CORRUPT_QUERY_SEQ: u16 = 0xFFFF;

// ----------------------------------------------------------------- Query ---

/// The broadcast query written to `0x1800`: `seq<<16 | board_mask`
/// (`fpga-board.md` §6.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Query {
    /// Sequence number, 1..=65535 (never 0).
    pub seq: u16,
    /// Boards in use: bit i = board i.
    pub board_mask: u16,
}

fn check_seq(seq: u16) -> Result<()> {
    if seq == 0 {
        Err(Error::InvalidValue {
            what: "broadcast query sequence (must be 1..=65535)",
            value: 0,
        })
    } else {
        Ok(())
    }
}

impl Query {
    /// Decode a query word.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for sequence 0.
    pub fn parse(word: u32) -> Result<Query> {
        let query = Query {
            seq: field::QUERY_SEQ.extract(word) as u16,
            board_mask: field::QUERY_MASK.extract(word) as u16,
        };
        check_seq(query.seq)?;
        Ok(query)
    }

    /// Encode as the query word.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for sequence 0.
    pub fn to_word(self) -> Result<u32> {
        check_seq(self.seq)?;
        let w = field::QUERY_SEQ.insert(0, u32::from(self.seq));
        Ok(field::QUERY_MASK.insert(w, u32::from(self.board_mask)))
    }

    /// Whether board `board_id` is selected.
    pub fn selects(self, board_id: u8) -> bool {
        1u16.checked_shl(u32::from(board_id))
            .is_some_and(|bit| self.board_mask & bit != 0)
    }

    /// The selected board IDs, ascending.
    pub fn boards(self) -> impl Iterator<Item = u8> {
        (0..MAX_BOARDS as u8).filter(move |&id| self.selects(id))
    }
}

/// Destination offset of board `board_id`'s status broadcast: Rev 4-7 add
/// `0x20 * board_id` to `0xFFFF_FF00_1000` (`fpga-board.md` §6.2). The
/// board-specific part does not decide where the hub stores the packet:
/// hub memory is packed in arrival order (§6.3).
///
/// # Errors
/// [`Error::FieldRange`] for a board ID above 15.
pub fn status_broadcast_offset(firmware: FirmwareRev, board_id: u8) -> Result<u64> {
    check_board_id(board_id)?;
    Ok(if (4..=7).contains(&firmware.number()) {
        STATUS_BROADCAST_OFFSET + STATUS_BROADCAST_BOARD_STRIDE * u64::from(board_id)
    } else {
        STATUS_BROADCAST_OFFSET
    })
}

// ------------------------------------------------------ Status broadcast ---

/// What a host that overhears the bus learns from one packet: `Some((header,
/// board ID))` when it is a status broadcast (a block write to broadcast
/// node 63 in the status broadcast range, `fpga-board.md` §6.2, carrying at
/// least the header and the block's first quadlets), `None` for anything
/// else. The board ID is the one in the block's STATUS quadlet; nothing
/// else is checked (the hub read does that).
pub fn status_broadcast_board(
    packet: &crate::packet::Packet<&[u8]>,
) -> Option<(BroadcastHeader, u8)> {
    let range = STATUS_BROADCAST_OFFSET
        ..STATUS_BROADCAST_OFFSET + STATUS_BROADCAST_BOARD_STRIDE * MAX_BOARDS as u64;
    if packet.tcode() != crate::packet::Tcode::WriteBlockRequest
        || !packet.destination_id().is_broadcast()
        || !range.contains(&packet.offset())
    {
        return None;
    }
    let data = packet.data();
    // Header, timestamp, STATUS.
    let (head, status) = (data.get(..4)?, data.get(8..12)?);
    let header = BroadcastHeader::from_word(read_quadlet(head, 0));
    let board = crate::board::registers::StatusRead(read_quadlet(status, 0)).board_id();
    Some((header, board))
}

/// The header of a status broadcast: `seq<<16 | size_in_quadlets`, the size
/// counting the header too (`fpga-board.md` §6.2: 33 for QLA1 Rev 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BroadcastHeader {
    /// The sequence of the query answered.
    pub seq: u16,
    /// Quadlets of the broadcast including this header.
    pub quadlets: u16,
}

impl BroadcastHeader {
    /// Decode the header quadlet.
    pub fn from_word(word: u32) -> BroadcastHeader {
        BroadcastHeader {
            seq: field::BCAST_SEQ.extract(word) as u16,
            quadlets: field::BCAST_QUADLETS.extract(word) as u16,
        }
    }

    /// Encode the header quadlet.
    pub fn to_word(self) -> u32 {
        let w = field::BCAST_SEQ.insert(0, u32::from(self.seq));
        field::BCAST_QUADLETS.insert(w, u32::from(self.quadlets))
    }
}

layout_view! {
    /// A checked view of a status broadcast payload: header, then the board's
    /// real-time read block (`fpga-board.md` §6.2).
    pub struct StatusBroadcast;
    what: "status broadcast",
    quadlets: broadcast_quadlets,
}

impl<T: AsRef<[u8]>> StatusBroadcast<T> {
    /// The header.
    pub fn header(&self) -> BroadcastHeader {
        BroadcastHeader::from_word(read_quadlet(self.buffer.as_ref(), 0))
    }

    /// The real-time read block after the header.
    pub fn block(&self) -> ReadBlock<&[u8]> {
        let bytes = self.buffer.as_ref();
        ReadBlock::new_unchecked(bytes.get(4..).unwrap_or(&[]), self.layout)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> StatusBroadcast<T> {
    /// Set the header.
    pub fn set_header(&mut self, header: BroadcastHeader) {
        write_quadlet(self.buffer.as_mut(), 0, header.to_word());
    }

    /// The real-time read block after the header, mutable.
    pub fn block_mut(&mut self) -> ReadBlock<&mut [u8]> {
        let layout = self.layout;
        let bytes = self.buffer.as_mut();
        ReadBlock::new_unchecked(bytes.get_mut(4..).unwrap_or(&mut []), layout)
    }
}

/// The meaning of a status broadcast (`fpga-board.md` §6.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StatusBroadcastRepr {
    /// The sequence of the query answered.
    pub seq: u16,
    /// The board's real-time read block.
    pub block: ReadBlockRepr,
}

impl StatusBroadcastRepr {
    /// Parse a status broadcast.
    ///
    /// # Errors
    /// Length errors; [`Error::BlockSize`] when the header's size is not
    /// the layout's.
    pub fn parse<T: AsRef<[u8]>>(packet: &StatusBroadcast<T>) -> Result<StatusBroadcastRepr> {
        packet.check_len()?;
        let header = packet.header();
        let expected = packet.layout.broadcast_quadlets();
        if usize::from(header.quadlets) != expected {
            return Err(Error::BlockSize {
                what: "status broadcast (header size)",
                expected,
                found: usize::from(header.quadlets),
            });
        }
        Ok(StatusBroadcastRepr {
            seq: header.seq,
            block: ReadBlockRepr::parse(&packet.block())?,
        })
    }

    /// Bytes [`emit`](Self::emit) writes.
    pub fn buffer_len(&self) -> usize {
        self.block.layout.broadcast_quadlets() * 4
    }

    /// Write the broadcast payload into the start of `buf`; returns bytes
    /// written.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let len = self.buffer_len();
        let available = buf.len();
        let Some(out) = buf.get_mut(..len) else {
            return Err(Error::BufferTooSmall {
                what: "status broadcast",
                needed: len,
                available,
            });
        };
        let mut packet = StatusBroadcast::new_unchecked(out, self.block.layout);
        packet.set_header(BroadcastHeader {
            seq: self.seq,
            quadlets: self.block.layout.broadcast_quadlets() as u16,
        });
        self.block.emit(packet.block_mut().into_inner())?;
        Ok(len)
    }
}

// --------------------------------------------------------------- Hub block ---

/// A board's header quadlet in hub memory (`fpga-board.md` §6.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HubHeader {
    /// Rev 7 keeps `seq<<16 | time`.
    Rev7 {
        /// The full sequence the board answered.
        seq: u16,
        /// Time of the update.
        time: u16,
    },
    /// Rev 8 rewrites it as `size:8 | seq_low:8 | seq_error:1 | update_time:15`.
    Rev8 {
        /// Quadlets of the entry including this header (block + 1).
        quadlets: u8,
        /// Low byte of the sequence the board answered.
        seq_low: u8,
        /// The board's full sequence did not match the query's.
        seq_error: bool,
        /// Time of the update (15 bits).
        update_time: u16,
    },
}

impl HubHeader {
    /// Decode a hub header quadlet in the given format.
    #[inline]
    pub fn from_word(word: u32, format: BlockFormat) -> HubHeader {
        match format {
            BlockFormat::Rev4 | BlockFormat::Rev7 => HubHeader::Rev7 {
                seq: field::HUB7_SEQ.extract(word) as u16,
                time: field::HUB7_TIME.extract(word) as u16,
            },
            BlockFormat::Rev8 => HubHeader::Rev8 {
                quadlets: field::HUB8_QUADLETS.extract(word) as u8,
                seq_low: field::HUB8_SEQ_LOW.extract(word) as u8,
                seq_error: field::HUB8_SEQ_ERROR.extract(word) == 1,
                update_time: field::HUB8_UPDATE_TIME.extract(word) as u16,
            },
        }
    }

    /// Encode the header quadlet.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a Rev 8 update time above 15 bits.
    pub fn to_word(self) -> Result<u32> {
        match self {
            HubHeader::Rev7 { seq, time } => {
                let w = field::HUB7_SEQ.insert(0, u32::from(seq));
                Ok(field::HUB7_TIME.insert(w, u32::from(time)))
            }
            HubHeader::Rev8 {
                quadlets,
                seq_low,
                seq_error,
                update_time,
            } => {
                let time = field::HUB8_UPDATE_TIME;
                check_max(
                    "hub update time",
                    u64::from(update_time),
                    u64::from(time.max()),
                )?;
                let w = field::HUB8_QUADLETS.insert(0, u32::from(quadlets));
                let w = field::HUB8_SEQ_LOW.insert(w, u32::from(seq_low));
                let w = field::HUB8_SEQ_ERROR.insert(w, u32::from(seq_error));
                Ok(time.insert(w, u32::from(update_time)))
            }
        }
    }

    /// The format of this header.
    pub fn format(self) -> BlockFormat {
        match self {
            HubHeader::Rev7 { .. } => BlockFormat::Rev7,
            HubHeader::Rev8 { .. } => BlockFormat::Rev8,
        }
    }

    /// The hub's rewrite of a received broadcast header (`fpga-board.md`
    /// §6.3): Rev 8 keeps the size and the sequence's low byte, flags a
    /// full-sequence mismatch with `query_seq` and keeps the low 15 bits of
    /// `update_time`; Rev 4 and Rev 7 keep the sequence and store
    /// `update_time`.
    pub fn rewrite(
        broadcast: BroadcastHeader,
        query_seq: u16,
        update_time: u16,
        format: BlockFormat,
    ) -> HubHeader {
        match format {
            BlockFormat::Rev4 | BlockFormat::Rev7 => HubHeader::Rev7 {
                seq: broadcast.seq,
                time: update_time,
            },
            BlockFormat::Rev8 => HubHeader::Rev8 {
                quadlets: broadcast.quadlets as u8,
                seq_low: broadcast.seq as u8,
                seq_error: broadcast.seq != query_seq,
                update_time: update_time & field::HUB8_UPDATE_TIME.max() as u16,
            },
        }
    }
}

/// The timing quadlet after the last board's entry: `read_start:16 | now:16`
/// (`fpga-board.md` §6.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct HubTiming {
    /// When the hub read started.
    pub read_start: u16,
    /// The time now.
    pub now: u16,
}

impl HubTiming {
    /// Decode the timing quadlet.
    pub fn from_word(word: u32) -> HubTiming {
        HubTiming {
            read_start: field::TIMING_READ_START.extract(word) as u16,
            now: field::TIMING_NOW.extract(word) as u16,
        }
    }

    /// Encode the timing quadlet.
    pub fn to_word(self) -> u32 {
        let w = field::TIMING_READ_START.insert(0, u32::from(self.read_start));
        field::TIMING_NOW.insert(w, u32::from(self.now))
    }
}

/// How boards report the query's sequence (`fpga-board.md` §6, last points).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SeqRule {
    /// Rev 7: every board echoes the full 16-bit sequence.
    Rev7Echo,
    /// Rev 8: the hub header keeps the low byte and an error bit set when
    /// the full sequence did not match.
    Rev8LowByte,
    /// Seed 000: the sequence is echoed, and a board that received a
    /// corrupt query answers `0xFFFF` (so the host never queries with it).
    Seed000,
}

impl SeqRule {
    /// The rule of a firmware revision's real boards.
    pub fn for_firmware(firmware: FirmwareRev) -> SeqRule {
        match firmware.block_format() {
            BlockFormat::Rev4 => SeqRule::Seed000,
            BlockFormat::Rev7 => SeqRule::Rev7Echo,
            BlockFormat::Rev8 => SeqRule::Rev8LowByte,
        }
    }

    /// The sequence to query with after `seq`: never 0, and under
    /// [`SeqRule::Seed000`] never [`CORRUPT_QUERY_SEQ`].
    #[inline]
    pub fn next_seq(self, seq: u16) -> u16 {
        let mut next = seq.wrapping_add(1);
        while next == 0 || (self == SeqRule::Seed000 && next == CORRUPT_QUERY_SEQ) {
            next = next.wrapping_add(1);
        }
        next
    }

    /// Check a full 16-bit sequence a board answered (a status broadcast
    /// header or a Rev 7 hub header) against the query's.
    ///
    /// # Errors
    /// [`Error::CorruptQuery`] (seed 000, `0xFFFF`), else
    /// [`Error::Sequence`] on a mismatch.
    #[inline]
    pub fn check_seq(self, query_seq: u16, received: u16, board: u8) -> Result<()> {
        if self == SeqRule::Seed000 && received == CORRUPT_QUERY_SEQ {
            return Err(Error::CorruptQuery { board });
        }
        if received != query_seq {
            return Err(Error::Sequence {
                board,
                expected: query_seq,
                received,
            });
        }
        Ok(())
    }

    /// Check a hub header against the query's sequence. A Rev 8 header
    /// carries only the low byte and the error bit, so those are what is
    /// checked whatever the rule (a seed-000 `0xFFFF` shows as the error
    /// bit); a Rev 7 header carries the full sequence: see
    /// [`check_seq`](Self::check_seq).
    ///
    /// # Errors
    /// [`Error::SequenceFlagged`], [`Error::CorruptQuery`] or
    /// [`Error::Sequence`] (with the low bytes for a Rev 8 header).
    #[inline]
    pub fn check(self, query_seq: u16, header: HubHeader, board: u8) -> Result<()> {
        match header {
            HubHeader::Rev7 { seq, .. } => self.check_seq(query_seq, seq, board),
            HubHeader::Rev8 {
                seq_low, seq_error, ..
            } => {
                if seq_error {
                    return Err(Error::SequenceFlagged { board, seq_low });
                }
                let expected = query_seq & 0xFF;
                if u16::from(seq_low) != expected {
                    return Err(Error::Sequence {
                        board,
                        expected,
                        received: u16::from(seq_low),
                    });
                }
                Ok(())
            }
        }
    }
}

/// A board expected on the bus: its ID and layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BoardSlot {
    /// Board ID, 0..=15.
    pub id: u8,
    /// Its real-time block layout.
    pub layout: BoardLayout,
}

/// Quadlets of the hub block of these boards: the sum of (read block + 1)
/// plus the timing quadlet (`fpga-board.md` §6.4: two QLA1 Rev 8 boards 67,
/// Rev 7 `29 * boards + 1`). Rev 4 hubs have no timing quadlet: boards
/// that are all Rev 4 give the sum alone (`13 * boards` for QLA1); no
/// boards at all give the timing quadlet alone.
#[inline]
pub fn hub_block_quadlets<I: IntoIterator<Item = BoardLayout>>(layouts: I) -> usize {
    let (mut sum, mut all_rev4) = (0, true);
    for layout in layouts {
        sum += layout.broadcast_quadlets();
        all_rev4 &= !has_hub_timing(layout.format());
    }
    sum + usize::from(sum == 0 || !all_rev4)
}

/// Whether a hub of this format appends the timing quadlet after the last
/// entry (Rev 7 and later).
#[inline]
pub fn has_hub_timing(format: BlockFormat) -> bool {
    format != BlockFormat::Rev4
}

/// A checked view of the hub block read from `0x1000`, walked with the
/// boards expected in arrival order (ascending board ID for the Rev 7+
/// chain), `fpga-board.md` §6.3-6.4. Each entry's header is read in the
/// format of that board's layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HubBlock<'b, T: AsRef<[u8]>> {
    buffer: T,
    boards: &'b [BoardSlot],
}

impl<'b, T: AsRef<[u8]>> HubBlock<'b, T> {
    /// Wrap a buffer without checking it.
    pub const fn new_unchecked(buffer: T, boards: &'b [BoardSlot]) -> HubBlock<'b, T> {
        HubBlock { buffer, boards }
    }

    /// Wrap a buffer after checking its length.
    ///
    /// # Errors
    /// See [`check_len`](Self::check_len).
    pub fn new_checked(buffer: T, boards: &'b [BoardSlot]) -> Result<HubBlock<'b, T>> {
        let b = Self::new_unchecked(buffer, boards);
        b.check_len()?;
        Ok(b)
    }

    /// Check the buffer is exactly the hub block of the expected boards.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for more than 16 boards or a block larger
    /// than the 512-quadlet hub memory; [`Error::NotQuadletAligned`] or
    /// [`Error::BlockSize`] for a buffer of the wrong size.
    pub fn check_len(&self) -> Result<()> {
        check_max("hub boards", self.boards.len() as u64, MAX_BOARDS as u64)?;
        let quadlets = hub_block_quadlets(self.boards.iter().map(|b| b.layout));
        check_max(
            "hub block quadlets",
            quadlets as u64,
            HUB_MEMORY_QUADLETS as u64,
        )?;
        check_exact("hub block", self.buffer.as_ref().len(), quadlets)
    }

    /// The expected boards.
    pub fn boards(&self) -> &'b [BoardSlot] {
        self.boards
    }

    /// The underlying bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// The entries, one per expected board.
    #[inline]
    pub fn entries(&self) -> HubEntries<'_> {
        HubEntries {
            bytes: self.buffer.as_ref(),
            boards: self.boards,
            pos: 0,
        }
    }

    /// The entry of the `index`-th expected board.
    pub fn entry(&self, index: usize) -> Option<HubEntry<'_>> {
        self.entries().nth(index)
    }

    /// The entry of board `board_id`.
    pub fn entry_of(&self, board_id: u8) -> Option<HubEntry<'_>> {
        self.entries().find(|e| e.slot.id == board_id)
    }

    /// The timing quadlet after the last entry (all zero for Rev 4 boards,
    /// whose hub has none).
    pub fn timing(&self) -> HubTiming {
        let layouts = self.boards.iter().map(|b| b.layout);
        if !self.boards.is_empty() && !layouts.clone().any(|l| has_hub_timing(l.format())) {
            return HubTiming::default();
        }
        let q = hub_block_quadlets(layouts).saturating_sub(1);
        HubTiming::from_word(read_quadlet(self.buffer.as_ref(), q))
    }

    /// Validate every entry ([`HubEntry::validate`]); the first failure is
    /// returned.
    ///
    /// # Errors
    /// As [`HubEntry::validate`].
    pub fn check_sequences(&self, rule: SeqRule, query_seq: u16) -> Result<()> {
        self.entries().try_for_each(|e| e.validate(rule, query_seq))
    }
}

/// One board's entry in the hub block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HubEntry<'a> {
    /// The board expected here.
    pub slot: BoardSlot,
    /// The hub header.
    pub header: HubHeader,
    /// The board's real-time read block.
    pub block: ReadBlock<&'a [u8]>,
}

impl HubEntry<'_> {
    /// Check the entry is this cycle's answer: a Rev 8 header's size must
    /// be the layout's, and the sequence must pass `rule`.
    ///
    /// # Errors
    /// [`Error::BlockSize`] for a Rev 8 size mismatch; the errors of
    /// [`SeqRule::check`].
    #[inline]
    pub fn validate(&self, rule: SeqRule, query_seq: u16) -> Result<()> {
        if let HubHeader::Rev8 { quadlets, .. } = self.header {
            let expected = self.slot.layout.broadcast_quadlets();
            if usize::from(quadlets) != expected {
                return Err(Error::BlockSize {
                    what: "hub entry (header size)",
                    expected,
                    found: usize::from(quadlets),
                });
            }
        }
        rule.check(query_seq, self.header, self.slot.id)
    }
}

/// Iterator over the entries of a [`HubBlock`].
#[derive(Debug, Clone)]
pub struct HubEntries<'a> {
    bytes: &'a [u8],
    boards: &'a [BoardSlot],
    pos: usize,
}

impl<'a> Iterator for HubEntries<'a> {
    type Item = HubEntry<'a>;

    #[inline]
    fn next(&mut self) -> Option<HubEntry<'a>> {
        let (&slot, rest) = self.boards.split_first()?;
        let len = slot.layout.broadcast_quadlets() * 4;
        let bytes = self.bytes.get(self.pos..self.pos.checked_add(len)?)?;
        self.boards = rest;
        self.pos += len;
        let header = HubHeader::from_word(read_quadlet(bytes, 0), slot.layout.format());
        Some(HubEntry {
            slot,
            header,
            block: ReadBlock::new_unchecked(bytes.get(4..).unwrap_or(&[]), slot.layout),
        })
    }
}

/// Packs the hub memory as broadcasts arrive (the emulated boards' side of
/// `fpga-board.md` §6.3): entries in arrival order, then the timing quadlet.
#[derive(Debug)]
pub struct HubPacker<'a> {
    buf: &'a mut [u8],
    quadlets: usize,
}

impl<'a> HubPacker<'a> {
    /// Pack into `buf` from its start (normally 2048 bytes of hub memory).
    pub fn new(buf: &'a mut [u8]) -> HubPacker<'a> {
        HubPacker { buf, quadlets: 0 }
    }

    /// Quadlets written so far (what the `0x1802` register reports).
    pub fn quadlets(&self) -> usize {
        self.quadlets
    }

    /// Start a new cycle: the next entry goes to the start of the memory.
    pub fn reset(&mut self) {
        self.quadlets = 0;
    }

    fn reserve(&mut self, what: &'static str, quadlets: usize) -> Result<&mut [u8]> {
        let end = self.quadlets + quadlets;
        check_max("hub block quadlets", end as u64, HUB_MEMORY_QUADLETS as u64)?;
        let available = self.buf.len();
        let start = self.quadlets * 4;
        let Some(out) = self.buf.get_mut(start..end * 4) else {
            return Err(Error::BufferTooSmall {
                what,
                needed: end * 4,
                available,
            });
        };
        Ok(out)
    }

    /// Append one entry: `header` then the read block bytes.
    ///
    /// # Errors
    /// [`Error::NotQuadletAligned`] for a block of partial quadlets;
    /// [`Error::BlockSize`] when a Rev 8 header's size is not block + 1;
    /// [`Error::FieldRange`] beyond 512 quadlets or for a bad header field;
    /// [`Error::BufferTooSmall`].
    pub fn push(&mut self, header: HubHeader, block: &[u8]) -> Result<()> {
        if block.len() % 4 != 0 {
            return Err(Error::NotQuadletAligned {
                what: "hub entry block",
                len: block.len(),
            });
        }
        let quadlets = block.len() / 4 + 1;
        if let HubHeader::Rev8 { quadlets: size, .. } = header {
            if usize::from(size) != quadlets {
                return Err(Error::BlockSize {
                    what: "hub entry (header size)",
                    expected: quadlets,
                    found: usize::from(size),
                });
            }
        }
        let word = header.to_word()?;
        let out = self.reserve("hub entry", quadlets)?;
        write_quadlet(out, 0, word);
        if let Some(dst) = out.get_mut(4..) {
            dst.copy_from_slice(block);
        }
        self.quadlets += quadlets;
        Ok(())
    }

    /// Store a received status broadcast payload with its header rewritten
    /// by [`HubHeader::rewrite`]; returns the header stored.
    ///
    /// # Errors
    /// [`Error::Truncated`] without a header; [`Error::NotQuadletAligned`];
    /// [`Error::BlockSize`] when the header's size is not the payload's
    /// (the packet is then not stored); the errors of
    /// [`push`](Self::push).
    pub fn store_broadcast(
        &mut self,
        payload: &[u8],
        query_seq: u16,
        update_time: u16,
        format: BlockFormat,
    ) -> Result<HubHeader> {
        let (Some(head), Some(block)) = (payload.get(..4), payload.get(4..)) else {
            return Err(Error::Truncated {
                what: "status broadcast header",
                needed: 4,
                available: payload.len(),
            });
        };
        if payload.len() % 4 != 0 {
            return Err(Error::NotQuadletAligned {
                what: "status broadcast",
                len: payload.len(),
            });
        }
        let broadcast = BroadcastHeader::from_word(read_quadlet(head, 0));
        if usize::from(broadcast.quadlets) * 4 != payload.len() {
            return Err(Error::BlockSize {
                what: "status broadcast (header size)",
                expected: payload.len() / 4,
                found: usize::from(broadcast.quadlets),
            });
        }
        let header = HubHeader::rewrite(broadcast, query_seq, update_time, format);
        self.push(header, block)?;
        Ok(header)
    }

    /// Append the timing quadlet; returns the bytes of the whole hub block.
    ///
    /// # Errors
    /// [`Error::FieldRange`] beyond 512 quadlets; [`Error::BufferTooSmall`].
    pub fn finish(&mut self, timing: HubTiming) -> Result<usize> {
        let out = self.reserve("hub timing quadlet", 1)?;
        write_quadlet(out, 0, timing.to_word());
        self.quadlets += 1;
        Ok(self.quadlets * 4)
    }
}

// ----------------------------------------------------------- Command block ---

/// Quadlets of the command block of these boards: the sum of their write
/// blocks (`fpga-board.md` §6.5).
pub fn command_block_quadlets<I: IntoIterator<Item = BoardLayout>>(layouts: I) -> usize {
    layouts
        .into_iter()
        .map(BoardLayout::write_block_quadlets)
        .sum()
}

/// Builds the command block: each board's write block concatenated in
/// strictly ascending board order into a caller-provided buffer
/// (`fpga-board.md` §6.5).
#[derive(Debug)]
pub struct CommandBlockWriter<'a> {
    buf: &'a mut [u8],
    len: usize,
    last: Option<u8>,
}

impl<'a> CommandBlockWriter<'a> {
    /// Write into `buf` from its start.
    pub fn new(buf: &'a mut [u8]) -> CommandBlockWriter<'a> {
        CommandBlockWriter {
            buf,
            len: 0,
            last: None,
        }
    }

    /// Bytes written so far.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is written yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Append the next board's write block.
    ///
    /// # Errors
    /// [`Error::BoardOrder`] unless the board ID is above the previous one;
    /// [`Error::BufferTooSmall`]; the errors of [`WriteBlockRepr::emit`].
    #[inline]
    pub fn push(&mut self, block: &WriteBlockRepr) -> Result<()> {
        if let Some(previous) = self.last {
            if block.board_id <= previous {
                return Err(Error::BoardOrder {
                    previous,
                    next: block.board_id,
                });
            }
        }
        let needed = self.len + block.buffer_len();
        let available = self.buf.len();
        let Some(out) = self.buf.get_mut(self.len..needed) else {
            return Err(Error::BufferTooSmall {
                what: "command block",
                needed,
                available,
            });
        };
        self.len += block.emit(out)?;
        self.last = Some(block.board_id);
        Ok(())
    }
}

/// Emit a whole command block from the boards' write blocks, in ascending
/// board order; returns bytes written.
///
/// # Errors
/// As [`CommandBlockWriter::push`].
pub fn emit_command_block(buf: &mut [u8], blocks: &[WriteBlockRepr]) -> Result<usize> {
    let mut writer = CommandBlockWriter::new(buf);
    for block in blocks {
        writer.push(block)?;
    }
    Ok(writer.len())
}

/// One board's slice of a command block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CommandSlice<'a> {
    /// The board the slice names.
    pub board_id: u8,
    /// Its bytes (a whole write block).
    pub bytes: &'a [u8],
}

/// Iterator over the slices of a command block; yields an error once and
/// then stops when the block is malformed.
#[derive(Debug, Clone)]
pub struct CommandSlices<'a> {
    payload: &'a [u8],
    pos: usize,
    layout: BoardLayout,
    done: bool,
}

/// Walk a command block (`fpga-board.md` §6.5). Rev 8 follows the headers:
/// the low byte counts the slice's quadlets including the header, bits 15:8
/// name the board. Rev 4 and Rev 7 cut fixed slices of `layout`'s write
/// block (5 quadlets for a Rev 7 QLA1, 4 on Rev 4), the board ID in bits
/// 27:24 of the first DAC quadlet. Only `layout`'s format (and, before
/// Rev 8, its size) is used.
pub fn command_slices(payload: &[u8], layout: BoardLayout) -> CommandSlices<'_> {
    CommandSlices {
        payload,
        pos: 0,
        layout,
        done: false,
    }
}

impl<'a> CommandSlices<'a> {
    fn step(&mut self) -> Result<Option<CommandSlice<'a>>> {
        let total = self.payload.len();
        if total % 4 != 0 {
            return Err(Error::NotQuadletAligned {
                what: "command block",
                len: total,
            });
        }
        let Some(rest) = self.payload.get(self.pos..).filter(|r| !r.is_empty()) else {
            return Ok(None);
        };
        let first = read_quadlet(rest, 0);
        let (board_id, quadlets) = match self.layout.format() {
            BlockFormat::Rev8 => {
                let header = WriteHeader::from_word(first);
                if header.quadlets == 0 {
                    return Err(Error::Malformed {
                        what: "command block header with length 0",
                        value: first,
                    });
                }
                (header.board_id, usize::from(header.quadlets))
            }
            BlockFormat::Rev4 | BlockFormat::Rev7 => (
                DacWord(first).board_id(),
                self.layout.write_block_quadlets(),
            ),
        };
        let Some(bytes) = rest.get(..quadlets * 4) else {
            return Err(Error::LengthExceedsBuffer {
                what: "command block slice",
                declared: quadlets * 4,
                available: rest.len(),
            });
        };
        self.pos += bytes.len();
        Ok(Some(CommandSlice { board_id, bytes }))
    }
}

impl<'a> Iterator for CommandSlices<'a> {
    type Item = Result<CommandSlice<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = self.step().transpose();
        if !matches!(item, Some(Ok(_))) {
            self.done = true;
        }
        item
    }
}

/// Find board `board_id`'s write block in a command block; `Ok(None)` when
/// no slice names it (the board got no command this cycle).
///
/// # Errors
/// A malformed walk before the board's slice is reached (see
/// [`command_slices`]); [`Error::BlockSize`] when the slice naming the board
/// is not the size of `layout`'s write block.
pub fn find_command_block(
    payload: &[u8],
    board_id: u8,
    layout: BoardLayout,
) -> Result<Option<WriteBlock<&[u8]>>> {
    for slice in command_slices(payload, layout) {
        let slice = slice?;
        if slice.board_id == board_id {
            return WriteBlock::new_checked(slice.bytes, layout).map(Some);
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::registers::{DAC_ZERO, StatusRead};

    const REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);

    #[test]
    fn query_words() {
        let q = Query {
            seq: 0x1234,
            board_mask: 0b1001,
        };
        assert_eq!(q.to_word(), Ok(0x1234_0009));
        assert_eq!(Query::parse(0x1234_0009), Ok(q));
        assert!(Query::parse(0x0000_0009).is_err());
        assert!(
            Query {
                seq: 0,
                board_mask: 1
            }
            .to_word()
            .is_err()
        );
        assert!(q.selects(0) && q.selects(3) && !q.selects(1) && !q.selects(200));
        let mut boards = q.boards();
        assert_eq!(
            (boards.next(), boards.next(), boards.next()),
            (Some(0), Some(3), None)
        );
    }

    #[test]
    fn next_sequence_skips_reserved_values() {
        assert_eq!(SeqRule::Rev8LowByte.next_seq(1), 2);
        assert_eq!(SeqRule::Rev8LowByte.next_seq(0xFFFF), 1);
        assert_eq!(SeqRule::Rev7Echo.next_seq(0xFFFE), 0xFFFF);
        assert_eq!(SeqRule::Seed000.next_seq(0xFFFE), 1);
    }

    #[test]
    fn broadcast_offsets() {
        assert_eq!(
            status_broadcast_offset(FirmwareRev::Rev8, 5),
            Ok(0xFFFF_FF00_1000)
        );
        assert_eq!(
            status_broadcast_offset(FirmwareRev::Rev7, 5),
            Ok(0xFFFF_FF00_10A0)
        );
        assert_eq!(
            status_broadcast_offset(FirmwareRev::from(4), 1),
            Ok(0xFFFF_FF00_1020)
        );
        assert!(status_broadcast_offset(FirmwareRev::Rev7, 16).is_err());
    }

    #[test]
    fn hub_header_words() {
        let h = HubHeader::Rev8 {
            quadlets: 33,
            seq_low: 0x34,
            seq_error: true,
            update_time: 0x1234,
        };
        assert_eq!(h.to_word(), Ok(0x2134_9234));
        assert_eq!(HubHeader::from_word(0x2134_9234, BlockFormat::Rev8), h);
        let h7 = HubHeader::Rev7 {
            seq: 0xBEEF,
            time: 0x1234,
        };
        assert_eq!(h7.to_word(), Ok(0xBEEF_1234));
        assert_eq!(HubHeader::from_word(0xBEEF_1234, BlockFormat::Rev7), h7);
        assert!(
            HubHeader::Rev8 {
                quadlets: 1,
                seq_low: 0,
                seq_error: false,
                update_time: 0x8000
            }
            .to_word()
            .is_err()
        );
        let b = BroadcastHeader {
            seq: 0x1234,
            quadlets: 33,
        };
        assert_eq!(b.to_word(), 0x1234_0021);
        assert_eq!(
            HubHeader::rewrite(b, 0x1234, 0xFFFF, BlockFormat::Rev8),
            HubHeader::Rev8 {
                quadlets: 33,
                seq_low: 0x34,
                seq_error: false,
                update_time: 0x7FFF
            }
        );
        assert_eq!(
            HubHeader::rewrite(b, 0x1334, 5, BlockFormat::Rev8),
            HubHeader::Rev8 {
                quadlets: 33,
                seq_low: 0x34,
                seq_error: true,
                update_time: 5
            }
        );
        assert_eq!(
            HubHeader::rewrite(b, 0x1334, 5, BlockFormat::Rev7),
            HubHeader::Rev7 {
                seq: 0x1234,
                time: 5
            }
        );
    }

    #[test]
    fn sequence_rules() {
        let r7 = |seq| HubHeader::Rev7 { seq, time: 0 };
        let r8 = |seq_low, seq_error| HubHeader::Rev8 {
            quadlets: 33,
            seq_low,
            seq_error,
            update_time: 0,
        };
        assert_eq!(SeqRule::Rev7Echo.check(0x1234, r7(0x1234), 2), Ok(()));
        assert_eq!(
            SeqRule::Rev7Echo.check(0x1234, r7(0x1233), 2),
            Err(Error::Sequence {
                board: 2,
                expected: 0x1234,
                received: 0x1233
            })
        );
        assert_eq!(
            SeqRule::Rev8LowByte.check(0x1234, r8(0x34, false), 1),
            Ok(())
        );
        assert_eq!(
            SeqRule::Rev8LowByte.check(0x1234, r8(0x34, true), 1),
            Err(Error::SequenceFlagged {
                board: 1,
                seq_low: 0x34
            })
        );
        assert_eq!(
            SeqRule::Rev8LowByte.check(0x1234, r8(0x33, false), 1),
            Err(Error::Sequence {
                board: 1,
                expected: 0x34,
                received: 0x33
            })
        );
        assert_eq!(
            SeqRule::Seed000.check(0x1234, r7(0xFFFF), 4),
            Err(Error::CorruptQuery { board: 4 })
        );
        assert_eq!(SeqRule::Seed000.check(0x1234, r7(0x1234), 4), Ok(()));
        assert!(matches!(
            SeqRule::Seed000.check(0x1234, r7(0x1235), 4),
            Err(Error::Sequence { .. })
        ));
        // Rev 7 echo does not treat 0xFFFF specially.
        assert!(matches!(
            SeqRule::Rev7Echo.check(0x1234, r7(0xFFFF), 4),
            Err(Error::Sequence { .. })
        ));
        assert_eq!(
            SeqRule::for_firmware(FirmwareRev::Rev8),
            SeqRule::Rev8LowByte
        );
        assert_eq!(SeqRule::for_firmware(FirmwareRev::Rev7), SeqRule::Rev7Echo);
    }

    #[test]
    fn status_broadcast_round_trip() {
        let mut block = ReadBlockRepr::new(REV8);
        block.status = StatusRead::default().with_axes(4).with_board_id(2);
        block.timestamp = 0xDEAD_BEEF;
        let repr = StatusBroadcastRepr { seq: 0x55AA, block };
        let mut buf = [0xA5u8; 140];
        assert_eq!(repr.emit(&mut buf), Ok(132));
        assert_eq!(read_quadlet(&buf, 0), 0x55AA_0021);
        assert_eq!(read_quadlet(&buf, 1), 0xDEAD_BEEF);
        assert!(buf[132..].iter().all(|&b| b == 0xA5));
        let view = StatusBroadcast::new_checked(&buf[..132], REV8).unwrap();
        assert_eq!(view.block().status().board_id(), 2);
        assert_eq!(StatusBroadcastRepr::parse(&view), Ok(repr));
        // A header with the wrong size.
        write_quadlet(&mut buf, 0, 0x55AA_0020);
        let view = StatusBroadcast::new_checked(&buf[..132], REV8).unwrap();
        assert!(matches!(
            StatusBroadcastRepr::parse(&view),
            Err(Error::BlockSize {
                expected: 33,
                found: 32,
                ..
            })
        ));
        assert!(StatusBroadcast::new_checked(&buf[..128], REV8).is_err());
        assert!(repr.emit(&mut buf[..100]).is_err());
    }

    #[test]
    fn hub_sizes() {
        assert_eq!(hub_block_quadlets([REV8; 2]), 67);
        assert_eq!(hub_block_quadlets([REV7; 3]), 29 * 3 + 1);
        assert_eq!(hub_block_quadlets([]), 1);
        // Rev 4 (seed 000's era): no timing quadlet after the entries.
        let rev4 = BoardLayout::qla1(FirmwareRev::Rev4);
        assert_eq!(hub_block_quadlets([rev4; 8]), 13 * 8);
        assert_eq!(SeqRule::for_firmware(FirmwareRev::Rev4), SeqRule::Seed000);
        assert_eq!(
            hub_block_quadlets([BoardLayout::dqla(FirmwareRev::Rev8)]),
            62
        );
    }

    #[test]
    fn hub_packer_limits() {
        let mut mem = [0u8; 2048];
        let mut packer = HubPacker::new(&mut mem);
        let block = [0u8; 128];
        for _ in 0..15 {
            packer
                .push(HubHeader::Rev7 { seq: 1, time: 0 }, &block)
                .unwrap();
        }
        assert_eq!(packer.quadlets(), 15 * 33);
        // The 16th QLA1 Rev 8 board no longer fits in 512 quadlets.
        assert!(matches!(
            packer.push(HubHeader::Rev7 { seq: 1, time: 0 }, &block),
            Err(Error::FieldRange { max: 512, .. })
        ));
        assert!(matches!(
            packer.push(HubHeader::Rev7 { seq: 1, time: 0 }, &block[..3]),
            Err(Error::NotQuadletAligned { .. })
        ));
        assert_eq!(packer.finish(HubTiming::default()), Ok(496 * 4));
        packer.reset();
        assert_eq!(packer.quadlets(), 0);
        let bad = HubHeader::Rev8 {
            quadlets: 32,
            seq_low: 1,
            seq_error: false,
            update_time: 0,
        };
        assert!(matches!(
            packer.push(bad, &block),
            Err(Error::BlockSize { .. })
        ));
        let mut small = [0u8; 64];
        let mut packer = HubPacker::new(&mut small);
        assert!(matches!(
            packer.push(HubHeader::Rev7 { seq: 1, time: 0 }, &block),
            Err(Error::BufferTooSmall { .. })
        ));
        assert!(matches!(
            packer.store_broadcast(&[0, 0], 1, 0, BlockFormat::Rev8),
            Err(Error::Truncated { .. })
        ));
        // Header says 2 quadlets, payload has 3.
        let payload = [0, 1, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0];
        assert!(matches!(
            packer.store_broadcast(&payload, 1, 0, BlockFormat::Rev8),
            Err(Error::BlockSize { .. })
        ));
    }

    #[test]
    fn hub_block_walk_and_validate() {
        let boards = [
            BoardSlot {
                id: 1,
                layout: REV8,
            },
            BoardSlot {
                id: 4,
                layout: BoardLayout::dqla(FirmwareRev::Rev8),
            },
        ];
        let mut mem = [0xA5u8; 2048];
        let mut packer = HubPacker::new(&mut mem);
        for (i, slot) in boards.iter().enumerate() {
            let mut block = ReadBlockRepr::new(slot.layout);
            block.status = StatusRead::default().with_board_id(slot.id);
            let seq = if i == 0 { 0x0102 } else { 0x0202 };
            let mut pkt = [0u8; 256];
            let n = StatusBroadcastRepr { seq, block }.emit(&mut pkt).unwrap();
            packer
                .store_broadcast(&pkt[..n], 0x0102, 10 + i as u16, BlockFormat::Rev8)
                .unwrap();
        }
        let len = packer
            .finish(HubTiming {
                read_start: 7,
                now: 9,
            })
            .unwrap();
        assert_eq!(len, (33 + 61 + 1) * 4);
        let hub = HubBlock::new_checked(&mem[..len], &boards).unwrap();
        assert_eq!(
            hub.timing(),
            HubTiming {
                read_start: 7,
                now: 9
            }
        );
        let e = hub.entry_of(4).unwrap();
        assert_eq!(e.block.status().board_id(), 4);
        assert_eq!(
            e.header,
            HubHeader::Rev8 {
                quadlets: 61,
                seq_low: 0x02,
                seq_error: true,
                update_time: 11
            }
        );
        assert_eq!(
            hub.entry(0).unwrap().validate(SeqRule::Rev8LowByte, 0x0102),
            Ok(())
        );
        assert_eq!(
            hub.check_sequences(SeqRule::Rev8LowByte, 0x0102),
            Err(Error::SequenceFlagged {
                board: 4,
                seq_low: 2
            })
        );
        assert!(hub.entry(2).is_none());
        assert!(HubBlock::new_checked(&mem[..len - 4], &boards).is_err());
        let too_many = [BoardSlot {
            id: 0,
            layout: REV8,
        }; 17];
        assert!(matches!(
            HubBlock::new_checked(&mem[..], &too_many),
            Err(Error::FieldRange { .. })
        ));
        // An unchecked view over too few bytes walks only what is there.
        let short = HubBlock::new_unchecked(&mem[..40], &boards);
        assert_eq!(short.entries().count(), 0);
    }

    fn write_blocks(layout: BoardLayout, ids: &[u8]) -> ([u8; 1024], usize) {
        let mut buf = [0xA5u8; 1024];
        let mut writer = CommandBlockWriter::new(&mut buf);
        for &id in ids {
            let mut w = WriteBlockRepr::new(layout, id);
            w.dac[0] = DacWord::valid_command(DAC_ZERO + u16::from(id));
            writer.push(&w).unwrap();
        }
        let len = writer.len();
        (buf, len)
    }

    #[test]
    fn command_block_slicing() {
        for layout in [REV8, REV7] {
            let (buf, len) = write_blocks(layout, &[0, 2, 3, 7]);
            assert_eq!(len, 4 * layout.write_block_len());
            let payload = &buf[..len];
            for id in [0u8, 2, 3, 7] {
                let block = find_command_block(payload, id, layout).unwrap().unwrap();
                assert_eq!(block.board_id(), id);
                assert_eq!(block.dac(0).unwrap().command(), DAC_ZERO + u16::from(id));
            }
            assert_eq!(find_command_block(payload, 1, layout), Ok(None));
            assert_eq!(command_slices(payload, layout).count(), 4);
        }
    }

    #[test]
    fn command_block_order_and_space() {
        let mut buf = [0u8; 64];
        let mut writer = CommandBlockWriter::new(&mut buf);
        assert!(writer.is_empty());
        writer.push(&WriteBlockRepr::new(REV8, 3)).unwrap();
        assert_eq!(
            writer.push(&WriteBlockRepr::new(REV8, 3)),
            Err(Error::BoardOrder {
                previous: 3,
                next: 3
            })
        );
        assert!(writer.push(&WriteBlockRepr::new(REV8, 1)).is_err());
        writer.push(&WriteBlockRepr::new(REV8, 4)).unwrap();
        assert!(matches!(
            writer.push(&WriteBlockRepr::new(REV8, 5)),
            Err(Error::BufferTooSmall { needed: 72, .. })
        ));
        assert_eq!(writer.len(), 48);
        assert_eq!(command_block_quadlets([REV8, REV7]), 11);
    }

    #[test]
    fn malformed_command_blocks_terminate() {
        // A zero-length header.
        let zero = [0u8; 24];
        let mut walk = command_slices(&zero, REV8);
        assert!(matches!(walk.next(), Some(Err(Error::Malformed { .. }))));
        assert!(walk.next().is_none());
        assert!(find_command_block(&zero, 0, REV8).is_err());
        // A header running past the end.
        let mut long = [0u8; 24];
        write_quadlet(&mut long, 0, 0x0000_0107);
        assert!(matches!(
            find_command_block(&long, 1, REV8),
            Err(Error::LengthExceedsBuffer { declared: 28, .. })
        ));
        // The board's slice of the wrong size.
        write_quadlet(&mut long, 0, 0x0000_0105);
        assert!(matches!(
            find_command_block(&long, 1, REV8),
            Err(Error::BlockSize { .. })
        ));
        // Not whole quadlets.
        assert!(matches!(
            find_command_block(&long[..23], 1, REV8),
            Err(Error::NotQuadletAligned { .. })
        ));
        // Rev 7: a partial trailing slice.
        let (buf, len) = write_blocks(REV7, &[1, 2]);
        assert!(matches!(
            find_command_block(&buf[..len - 4], 2, REV7),
            Err(Error::LengthExceedsBuffer { .. })
        ));
        assert_eq!(find_command_block(&[], 0, REV8), Ok(None));
    }
}
