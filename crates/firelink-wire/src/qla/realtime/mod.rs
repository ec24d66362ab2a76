//! Firmware revisions, board layouts and the real-time blocks: the block
//! read and block write of address 0 (`fpga-board.md` §4, §5).
//!
//! Two tiers per block, as for packets: a checked view over bytes
//! ([`ReadBlock`], [`WriteBlock`]) and a meaning type with fixed arrays of
//! [`MAX_AXES`] entries ([`ReadBlockRepr`], [`WriteBlockRepr`]).
//!
//! Private submodules, re-exported here: `layout` (firmware revisions and
//! board layouts), `read` (the read block) and `write` (the write block).
//!
//! # Panics
//! After [`ReadBlock::new_checked`] / [`WriteBlock::new_checked`] (or a
//! successful `check_len`) no accessor panics; per-axis accessors return
//! `None` (getters) or [`Error::Index`] (setters) for an axis the layout
//! does not have. Unchecked views read 0 where bytes are missing.
//!
//! ```
//! use firelink_wire::qla::realtime::{BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr};
//! use firelink_wire::qla::registers::EncPosition;
//! let layout = BoardLayout::qla1(FirmwareRev::Rev8);
//! let mut repr = ReadBlockRepr::new(layout);
//! repr.encoder[2].position = EncPosition::default().with_counts(-5).unwrap();
//! let mut buf = [0u8; 128];
//! let len = repr.emit(&mut buf).unwrap();
//! assert_eq!(len, 32 * 4);
//! let view = ReadBlock::new_checked(&buf[..len], layout).unwrap();
//! assert_eq!(view.enc_position(2).unwrap().counts(), -5);
//! assert_eq!(ReadBlockRepr::parse(&view).unwrap(), repr);
//! ```

use crate::error::{Error, Result};
use crate::field::{read_quadlet, write_quadlet};
use crate::open_enum::open_enum;
use crate::qla::address::check_board_id;
use crate::qla::registers::{
    AdcWord, DacWord, DigitalIn, EncPeriod, EncPosition, EncQuarter, EncRun, HardwareVersion,
    MotorStatus, StatusRead, StatusWrite, Temperature,
};
use crate::qla::{MAX_AXES, layout_view};

/// Fixed quadlets of the blocks (`fpga-board.md` §4, §5), each defined once.
mod field {
    use crate::field::Field;

    /// Read block: 49.152 MHz clocks since the previous read.
    pub const TIMESTAMP: Field = Field::quadlet(0);
    /// Read block: STATUS.
    pub const STATUS: Field = Field::quadlet(1);
    /// Read block: DIGITAL_IN.
    pub const DIGITAL_IN: Field = Field::quadlet(2);
    /// Read block: TEMPERATURE.
    pub const TEMPERATURE: Field = Field::quadlet(3);
    /// Read block: quadlets before the per-axis sections.
    pub const READ_FIXED_QUADLETS: usize = 4;

    /// Rev 8 write block header: everything above the board ID must be 0.
    pub const HEADER_RESERVED: Field = Field::new(0, 31, 16);
    /// Rev 8 write block header: the board ID, bits 15:8.
    pub const HEADER_BOARD_ID: Field = Field::new(0, 15, 8);
    /// Rev 8 write block header: quadlets of the block including the
    /// header (`motors + 2`), bits 7:0.
    pub const HEADER_QUADLETS: Field = Field::new(0, 7, 0);
}

mod layout;
mod read;
mod write;

pub use layout::*;
pub use read::*;
pub use write::*;
