//! IEEE 1394 asynchronous packets: codes, a checked zero-copy view and a
//! meaning type that parses and emits.
//!
//! Facts: `ieee1394.md`, "Transaction codes" and "Header layout". Quadlets are
//! big-endian on the wire. The header length is derived from the tcode; block
//! packets carry `data_length` bytes padded to whole quadlets and a data CRC.
//!
//! # Panics
//! After [`Packet::new_checked`] (or a successful [`Packet::check_len`]) no
//! accessor of [`Packet`] panics, whatever the bytes are.
//!
//! Private submodules, re-exported here: `codes` (node IDs, tcode, rcode,
//! ack, speed), `view` (the checked view [`Packet`]) and `repr` (the meaning
//! type [`PacketRepr`]).
//!
//! ```
//! use firelink_wire::packet::{Packet, PacketRepr, NodeId, AsyncHeader};
//! let repr = PacketRepr::ReadQuadletRequest {
//!     header: AsyncHeader::new(NodeId::local(1), NodeId(0xffc2), 5),
//!     offset: 0x7,
//! };
//! let mut buf = [0u8; 64];
//! let len = repr.emit(&mut buf).unwrap();
//! let packet = Packet::new_checked(&buf[..len]).unwrap();
//! assert!(packet.header_crc_ok().unwrap());
//! assert_eq!(PacketRepr::parse(&packet).unwrap(), repr);
//! ```

use core::fmt;

use crate::crc::crc1394;
use crate::error::{Error, Result, check_max};
use crate::field::{Field, pad4, read_quadlet, write_quadlet};
use crate::open_enum::open_enum;

/// Header field positions, each defined once (`ieee1394.md`, "Header layout").
mod field {
    use crate::field::Field;

    pub const DESTINATION_ID: Field = Field::new(0, 31, 16);
    pub const TL: Field = Field::new(0, 15, 10);
    pub const RT: Field = Field::new(0, 9, 8);
    pub const TCODE: Field = Field::new(0, 7, 4);
    pub const PRI: Field = Field::new(0, 3, 0);
    pub const SOURCE_ID: Field = Field::new(1, 31, 16);
    pub const OFFSET_HIGH: Field = Field::new(1, 15, 0);
    pub const RCODE: Field = Field::new(1, 15, 12);
    pub const OFFSET_LOW: Field = Field::quadlet(2);
    pub const QUADLET_DATA: Field = Field::quadlet(3);
    pub const DATA_LENGTH: Field = Field::new(3, 31, 16);
    pub const EXTENDED_TCODE: Field = Field::new(3, 15, 0);
    /// Stream packets keep their length in q0.
    pub const STREAM_DATA_LENGTH: Field = Field::new(0, 31, 16);
    /// Link-internal PHY packet body and its complement.
    pub const PHY_BODY: Field = Field::quadlet(1);
    pub const PHY_CHECK: Field = Field::quadlet(2);
}

mod codes;
mod repr;
mod view;

pub use codes::*;
pub use repr::*;
pub use view::*;
