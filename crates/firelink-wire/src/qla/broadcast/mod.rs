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
//! Each part lives in a private submodule (`query`, `status`, `hub_words`,
//! `hub_block`, `command`) re-exported here.
//!
//! ```
//! use firelink_wire::qla::broadcast::{
//!     BoardSlot, HubBlock, HubHeader, HubPacker, HubTiming, SeqRule, StatusBroadcastRepr,
//! };
//! use firelink_wire::qla::realtime::{BoardLayout, FirmwareRev, ReadBlockRepr};
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

use crate::error::{Error, Result};
use crate::field::{read_quadlet, write_quadlet};
use crate::qla::address::{
    HUB_MEMORY_QUADLETS, STATUS_BROADCAST_BOARD_STRIDE, STATUS_BROADCAST_OFFSET, check_board_id,
};
use crate::qla::realtime::{
    BlockFormat, BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr, WriteBlock, WriteBlockRepr,
    WriteHeader,
};
use crate::qla::registers::{DacWord, StatusWrite};
use crate::qla::{MAX_BOARDS, check_exact, check_max, layout_view};

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

mod command;
mod hub_block;
mod hub_words;
mod query;
mod status;

pub use command::*;
pub use hub_block::*;
pub use hub_words::*;
pub use query::*;
pub use status::*;
