//! The one error type of the wire layer.
//!
//! Every variant carries the structured facts of what was wrong, so callers can
//! match on it and `Display` can name the problem in one line. The type is
//! `Copy` and allocation-free, so it can travel through a servo cycle.

/// What went wrong while checking, parsing or emitting wire bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Error {
    /// The buffer ends before the structure does.
    #[error("truncated {what}: need {needed} bytes, have {available}")]
    Truncated {
        /// The structure being read.
        what: &'static str,
        /// Bytes the structure needs.
        needed: usize,
        /// Bytes present.
        available: usize,
    },
    /// A length field claims more bytes than the buffer holds.
    #[error("{what} length field says {declared} bytes but only {available} follow")]
    LengthExceedsBuffer {
        /// The structure whose length field is wrong.
        what: &'static str,
        /// Bytes the length field declares.
        declared: usize,
        /// Bytes actually present.
        available: usize,
    },
    /// Bytes remain after a complete structure where none may.
    #[error("{extra} unexpected trailing bytes after the {what}")]
    TrailingBytes {
        /// The structure that ended.
        what: &'static str,
        /// How many bytes are left over.
        extra: usize,
    },
    /// A transaction code this layer cannot give meaning to.
    #[error("unknown tcode {0:#x}")]
    UnknownTcode(u8),
    /// A tcode that is valid but not allowed where it was found.
    #[error("tcode {tcode:#x} is not allowed here: expected {expected}")]
    UnexpectedTcode {
        /// The tcode found.
        tcode: u8,
        /// What was expected instead.
        expected: &'static str,
    },
    /// A value does not fit in its wire field.
    #[error("{field} = {value:#x} does not fit (maximum {max:#x})")]
    FieldRange {
        /// The field name.
        field: &'static str,
        /// The offending value.
        value: u64,
        /// The largest value the field holds.
        max: u64,
    },
    /// An output buffer is too small for what must be written into it.
    #[error("output buffer too small for {what}: need {needed} bytes, have {available}")]
    BufferTooSmall {
        /// What was being emitted.
        what: &'static str,
        /// Bytes needed.
        needed: usize,
        /// Bytes available.
        available: usize,
    },
    /// A header CRC did not match the header.
    #[error("header CRC mismatch: packet carries {carried:#010x}, computed {computed:#010x}")]
    HeaderCrc {
        /// CRC carried in the packet.
        carried: u32,
        /// CRC computed over the header.
        computed: u32,
    },
    /// A data CRC did not match the data block.
    #[error("data CRC mismatch: packet carries {carried:#010x}, computed {computed:#010x}")]
    DataCrc {
        /// CRC carried in the packet.
        carried: u32,
        /// CRC computed over the data block.
        computed: u32,
    },
    /// A self-checking encoding (ack byte, PHY packet) failed its check.
    #[error("{what} fails its check: {value:#x}")]
    Malformed {
        /// The structure that failed.
        what: &'static str,
        /// The raw value found.
        value: u32,
    },
    /// A block's size does not match the layout it should have.
    #[error("{what} has {found} quadlets, expected {expected}")]
    BlockSize {
        /// The block.
        what: &'static str,
        /// Quadlets expected.
        expected: usize,
        /// Quadlets found.
        found: usize,
    },
    /// A byte count that must be a whole number of quadlets is not.
    #[error("{what} is {len} bytes, not a whole number of quadlets")]
    NotQuadletAligned {
        /// The structure.
        what: &'static str,
        /// Its length in bytes.
        len: usize,
    },
    /// A board protocol field holds a value with no meaning.
    #[error("invalid {what}: {value:#x}")]
    InvalidValue {
        /// The field.
        what: &'static str,
        /// The value found.
        value: u32,
    },
    /// A signed value lies outside the range its field can represent.
    #[error("{what} = {value} is outside {min}..={max}")]
    OutOfRange {
        /// The quantity.
        what: &'static str,
        /// The offending value.
        value: i64,
        /// The smallest value allowed.
        min: i64,
        /// The largest value allowed.
        max: i64,
    },
    /// An index (axis, motor, encoder, board) beyond the items present.
    #[error("{what} index {index} out of range: {count} present")]
    Index {
        /// What is indexed.
        what: &'static str,
        /// The index asked for.
        index: usize,
        /// How many items there are.
        count: usize,
    },
    /// A board answered a broadcast query with the wrong sequence number
    /// (a stale or foreign answer): `fpga-board.md` section 6.
    #[error("board {board} answered sequence {received:#06x}, expected {expected:#06x}")]
    Sequence {
        /// The board ID.
        board: u8,
        /// The sequence expected (the low byte only for Rev 8 hub headers).
        expected: u16,
        /// The sequence received.
        received: u16,
    },
    /// A Rev 8 hub header carries the sequence-error bit: the board's full
    /// 16-bit sequence did not match the query's.
    #[error("board {board} flagged a sequence mismatch (low byte {seq_low:#04x})")]
    SequenceFlagged {
        /// The board ID.
        board: u8,
        /// The sequence low byte the board reported.
        seq_low: u8,
    },
    /// A board answered with sequence `0xFFFF`: it received a corrupt query
    /// (seed 000 profile).
    #[error("board {board} received a corrupt query (answered sequence 0xffff)")]
    CorruptQuery {
        /// The board ID.
        board: u8,
    },
    /// Board blocks are not in strictly ascending board-ID order.
    #[error("board {next} follows board {previous}: boards must be in strictly ascending ID order")]
    BoardOrder {
        /// The board ID before.
        previous: u8,
        /// The board ID that does not ascend.
        next: u8,
    },
}

/// Result alias of the wire layer.
pub type Result<T> = core::result::Result<T, Error>;

/// Check a value against the largest one its field holds.
///
/// # Errors
/// [`Error::FieldRange`] above `max`.
pub(crate) fn check_max(field: &'static str, value: u64, max: u64) -> Result<()> {
    if value > max {
        Err(Error::FieldRange { field, value, max })
    } else {
        Ok(())
    }
}
