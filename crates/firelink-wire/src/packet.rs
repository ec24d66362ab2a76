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

/// A 16-bit node ID: bus ID (10 bits) and physical ID (6 bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u16);

impl NodeId {
    /// The local bus ID, `0x3FF`.
    pub const LOCAL_BUS: u16 = 0x3FF;
    /// The broadcast physical ID, 63.
    pub const BROADCAST_PHY: u8 = 0x3F;
    /// Broadcast on the local bus, `0xFFFF`.
    pub const BROADCAST: NodeId = NodeId(0xFFFF);

    /// Physical ID `phy` on the local bus (`0xFFC0 | phy`).
    pub const fn local(phy: u8) -> NodeId {
        NodeId((Self::LOCAL_BUS << 6) | (phy as u16 & 0x3F))
    }

    /// The 10-bit bus ID.
    pub const fn bus(self) -> u16 {
        self.0 >> 6
    }

    /// The 6-bit physical ID.
    pub const fn phy(self) -> u8 {
        (self.0 & 0x3F) as u8
    }

    /// Whether the physical ID is the broadcast ID 63.
    pub const fn is_broadcast(self) -> bool {
        self.phy() == Self::BROADCAST_PHY
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#06x}", self.0)
    }
}

open_enum! {
    /// Transaction code (4 bits), `ieee1394.md` "Transaction codes".
    pub enum Tcode(u8) {
        /// Write request with one data quadlet in the header.
        WriteQuadletRequest = 0x0,
        /// Write request with a data block.
        WriteBlockRequest = 0x1,
        /// Write response.
        WriteResponse = 0x2,
        /// Read request for one quadlet.
        ReadQuadletRequest = 0x4,
        /// Read request for a block.
        ReadBlockRequest = 0x5,
        /// Read response with one data quadlet in the header.
        ReadQuadletResponse = 0x6,
        /// Read response with a data block.
        ReadBlockResponse = 0x7,
        /// Cycle start from the cycle master.
        CycleStart = 0x8,
        /// Lock request.
        LockRequest = 0x9,
        /// Stream (isochronous-format) packet.
        Stream = 0xA,
        /// Lock response.
        LockResponse = 0xB,
        /// Link-internal: a PHY packet carried as q1 with its complement in q2.
        LinkInternal = 0xE,
    }
}

impl Tcode {
    /// Bytes of header before the header CRC (or the whole packet for
    /// link-internal PHY packets); `None` for codes without a defined format.
    pub fn header_len(self) -> Option<usize> {
        match self {
            Tcode::WriteResponse | Tcode::ReadQuadletRequest | Tcode::LinkInternal => Some(12),
            Tcode::WriteQuadletRequest
            | Tcode::WriteBlockRequest
            | Tcode::ReadBlockRequest
            | Tcode::ReadQuadletResponse
            | Tcode::ReadBlockResponse
            | Tcode::CycleStart
            | Tcode::LockRequest
            | Tcode::LockResponse => Some(16),
            Tcode::Stream => Some(4),
            Tcode::Unknown(_) => None,
        }
    }

    /// Whether the header is followed by a header CRC.
    pub fn has_header_crc(self) -> bool {
        !matches!(self, Tcode::LinkInternal | Tcode::Unknown(_))
    }

    /// Whether a data block (when `data_length > 0`) and data CRC follow.
    pub fn has_data_block(self) -> bool {
        matches!(
            self,
            Tcode::WriteBlockRequest
                | Tcode::ReadBlockResponse
                | Tcode::LockRequest
                | Tcode::LockResponse
                | Tcode::Stream
        )
    }

    /// Whether q3 holds `data_length:16 | extended_tcode:16`.
    pub fn has_block_length(self) -> bool {
        matches!(
            self,
            Tcode::WriteBlockRequest
                | Tcode::ReadBlockRequest
                | Tcode::ReadBlockResponse
                | Tcode::LockRequest
                | Tcode::LockResponse
        )
    }

    /// Whether q1/q2 carry a 48-bit destination offset.
    pub fn is_request(self) -> bool {
        matches!(
            self,
            Tcode::WriteQuadletRequest
                | Tcode::WriteBlockRequest
                | Tcode::ReadQuadletRequest
                | Tcode::ReadBlockRequest
                | Tcode::LockRequest
                | Tcode::CycleStart
        )
    }

    /// Whether q1 carries an rcode.
    pub fn is_response(self) -> bool {
        matches!(
            self,
            Tcode::WriteResponse
                | Tcode::ReadQuadletResponse
                | Tcode::ReadBlockResponse
                | Tcode::LockResponse
        )
    }

    /// A stable snake-case name, used in JSON output.
    pub fn name(self) -> &'static str {
        match self {
            Tcode::WriteQuadletRequest => "write_request_quadlet",
            Tcode::WriteBlockRequest => "write_request_block",
            Tcode::WriteResponse => "write_response",
            Tcode::ReadQuadletRequest => "read_request_quadlet",
            Tcode::ReadBlockRequest => "read_request_block",
            Tcode::ReadQuadletResponse => "read_response_quadlet",
            Tcode::ReadBlockResponse => "read_response_block",
            Tcode::CycleStart => "cycle_start",
            Tcode::LockRequest => "lock_request",
            Tcode::Stream => "stream",
            Tcode::LockResponse => "lock_response",
            Tcode::LinkInternal => "link_internal",
            Tcode::Unknown(_) => "unknown",
        }
    }

    /// The tcode with the given [`name`](Self::name).
    pub fn from_name(name: &str) -> Option<Tcode> {
        (0u8..16)
            .map(Tcode::from)
            .find(|t| t.is_known() && t.name() == name)
    }
}

open_enum! {
    /// Response code (4 bits), `ieee1394.md` "Response codes".
    pub enum Rcode(u8) {
        /// The transaction completed.
        Complete = 0,
        /// A resource conflict; the request may be retried.
        ConflictError = 4,
        /// Data not available or corrupt.
        DataError = 5,
        /// The operation is not supported at that address.
        TypeError = 6,
        /// The address is not accessible.
        AddressError = 7,
    }
}

impl Rcode {
    /// A stable snake-case name (`unknown` for undefined codes).
    pub fn name(self) -> &'static str {
        match self {
            Rcode::Complete => "complete",
            Rcode::ConflictError => "conflict_error",
            Rcode::DataError => "data_error",
            Rcode::TypeError => "type_error",
            Rcode::AddressError => "address_error",
            Rcode::Unknown(_) => "unknown",
        }
    }
}

open_enum! {
    /// Acknowledge code (4 bits), `ieee1394.md` "Response codes and acknowledge codes".
    pub enum Ack(u8) {
        /// Unified transaction complete.
        Complete = 0x1,
        /// Request received; a response subaction follows.
        Pending = 0x2,
        /// Busy (single-phase retry).
        BusyX = 0x4,
        /// Busy, phase A.
        BusyA = 0x5,
        /// Busy, phase B.
        BusyB = 0x6,
        /// CRC or length error in the data block.
        DataError = 0xD,
        /// Unsupported transaction or bad header field.
        TypeError = 0xE,
    }
}

impl Ack {
    /// The 8-bit ack packet: code in the high nibble, its complement low.
    pub fn to_byte(self) -> u8 {
        let code = u8::from(self) & 0xF;
        (code << 4) | (!code & 0xF)
    }

    /// Decode an 8-bit ack packet, checking the complement nibble.
    ///
    /// # Errors
    /// [`Error::Malformed`] when the low nibble is not the complement.
    pub fn from_byte(byte: u8) -> Result<Ack> {
        let code = byte >> 4;
        if byte & 0xF != !code & 0xF {
            return Err(Error::Malformed {
                what: "ack packet",
                value: u32::from(byte),
            });
        }
        Ok(Ack::from(code))
    }
}

/// Signalling speed of a packet on a 1394a bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Speed {
    /// 98.304 Mb/s.
    S100,
    /// 196.608 Mb/s.
    S200,
    /// 393.216 Mb/s.
    S400,
}

impl Speed {
    /// Bits per second.
    pub const fn bits_per_second(self) -> u64 {
        match self {
            Speed::S100 => 98_304_000,
            Speed::S200 => 196_608_000,
            Speed::S400 => 393_216_000,
        }
    }

    /// Largest asynchronous payload in bytes at this speed.
    pub const fn max_async_payload(self) -> usize {
        match self {
            Speed::S100 => 512,
            Speed::S200 => 1024,
            Speed::S400 => 2048,
        }
    }

    /// The 2-bit speed code (0 = S100, 1 = S200, 2 = S400).
    pub const fn code(self) -> u8 {
        match self {
            Speed::S100 => 0,
            Speed::S200 => 1,
            Speed::S400 => 2,
        }
    }

    /// Speed from megabits (100, 200 or 400).
    pub fn from_mbps(mbps: u32) -> Option<Speed> {
        match mbps {
            100 => Some(Speed::S100),
            200 => Some(Speed::S200),
            400 => Some(Speed::S400),
            _ => None,
        }
    }
}

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

/// Largest 48-bit destination offset.
pub const MAX_OFFSET: u64 = (1 << 48) - 1;

/// Result of checking a packet's CRCs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CrcStatus {
    /// Header CRC matches; `None` for packets without one.
    pub header_ok: Option<bool>,
    /// Data CRC matches; `None` for packets without a data block.
    pub data_ok: Option<bool>,
}

impl CrcStatus {
    /// Whether every CRC present matches.
    pub fn all_ok(&self) -> bool {
        self.header_ok != Some(false) && self.data_ok != Some(false)
    }
}

/// A checked, zero-copy view of one 1394 packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packet<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Wrap a buffer without checking it. Accessors then read 0 where bytes
    /// are missing; call [`check_len`](Self::check_len) before trusting them.
    pub const fn new_unchecked(buffer: T) -> Packet<T> {
        Packet { buffer }
    }

    /// Wrap a buffer after checking it holds a complete packet.
    ///
    /// # Errors
    /// See [`check_len`](Self::check_len).
    pub fn new_checked(buffer: T) -> Result<Packet<T>> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Check that the buffer holds the whole packet its header describes.
    /// The buffer may be longer (use [`total_len`](Self::total_len)).
    ///
    /// # Errors
    /// [`Error::Truncated`] if the header is incomplete,
    /// [`Error::UnknownTcode`] if the tcode has no defined format,
    /// [`Error::LengthExceedsBuffer`] if `data_length` runs past the end.
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        if buf.len() < 4 {
            return Err(Error::Truncated {
                what: "packet header",
                needed: 4,
                available: buf.len(),
            });
        }
        let tcode = self.tcode();
        let header_len = tcode
            .header_len()
            .ok_or(Error::UnknownTcode(u8::from(tcode)))?;
        let with_crc = header_len + if tcode.has_header_crc() { 4 } else { 0 };
        if buf.len() < with_crc {
            return Err(Error::Truncated {
                what: tcode.name(),
                needed: with_crc,
                available: buf.len(),
            });
        }
        let total = self.total_len_unchecked();
        if buf.len() < total {
            return Err(Error::LengthExceedsBuffer {
                what: tcode.name(),
                declared: self.data_length() as usize,
                available: buf.len() - with_crc,
            });
        }
        Ok(())
    }

    /// Consume the view, returning the buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The underlying bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    fn total_len_unchecked(&self) -> usize {
        let tcode = self.tcode();
        let Some(header_len) = tcode.header_len() else {
            return 0;
        };
        let crc = if tcode.has_header_crc() { 4 } else { 0 };
        let data_length = self.data_length() as usize;
        let data = if tcode.has_data_block() && data_length > 0 {
            pad4(data_length) + 4
        } else {
            0
        };
        header_len + crc + data
    }

    /// Bytes of the whole packet (header, CRCs, padded data).
    pub fn total_len(&self) -> usize {
        self.total_len_unchecked()
    }

    /// The transaction code.
    pub fn tcode(&self) -> Tcode {
        Tcode::from(field::TCODE.get(self.buffer.as_ref()) as u8)
    }

    /// Destination node ID.
    pub fn destination_id(&self) -> NodeId {
        NodeId(field::DESTINATION_ID.get(self.buffer.as_ref()) as u16)
    }

    /// Transaction label (6 bits).
    pub fn tl(&self) -> u8 {
        field::TL.get(self.buffer.as_ref()) as u8
    }

    /// Retry code (2 bits).
    pub fn rt(&self) -> u8 {
        field::RT.get(self.buffer.as_ref()) as u8
    }

    /// Priority (4 bits).
    pub fn pri(&self) -> u8 {
        field::PRI.get(self.buffer.as_ref()) as u8
    }

    /// Source node ID.
    pub fn source_id(&self) -> NodeId {
        NodeId(field::SOURCE_ID.get(self.buffer.as_ref()) as u16)
    }

    /// 48-bit destination offset (meaningful for requests and cycle start).
    pub fn offset(&self) -> u64 {
        let buf = self.buffer.as_ref();
        (u64::from(field::OFFSET_HIGH.get(buf)) << 32) | u64::from(field::OFFSET_LOW.get(buf))
    }

    /// Response code (meaningful for responses).
    pub fn rcode(&self) -> Rcode {
        Rcode::from(field::RCODE.get(self.buffer.as_ref()) as u8)
    }

    /// The data quadlet of quadlet writes, quadlet read responses and the
    /// cycle time of cycle start packets.
    pub fn quadlet_data(&self) -> u32 {
        field::QUADLET_DATA.get(self.buffer.as_ref())
    }

    /// Data length in bytes of block packets (0 for others).
    pub fn data_length(&self) -> u16 {
        let tcode = self.tcode();
        let buf = self.buffer.as_ref();
        if tcode == Tcode::Stream {
            field::STREAM_DATA_LENGTH.get(buf) as u16
        } else if tcode.has_block_length() {
            field::DATA_LENGTH.get(buf) as u16
        } else {
            0
        }
    }

    /// Extended tcode of block packets (0 for others).
    pub fn extended_tcode(&self) -> u16 {
        if self.tcode().has_block_length() {
            field::EXTENDED_TCODE.get(self.buffer.as_ref()) as u16
        } else {
            0
        }
    }

    /// Bytes of header covered by the header CRC.
    pub fn header_len(&self) -> usize {
        self.tcode().header_len().unwrap_or(0)
    }

    /// The header bytes (before the header CRC).
    pub fn header_bytes(&self) -> &[u8] {
        let buf = self.buffer.as_ref();
        buf.get(..self.header_len()).unwrap_or(buf)
    }

    /// The header CRC carried in the packet.
    pub fn header_crc(&self) -> Option<u32> {
        let tcode = self.tcode();
        tcode
            .has_header_crc()
            .then(|| read_quadlet(self.buffer.as_ref(), self.header_len() / 4))
    }

    /// Whether the carried header CRC matches the header.
    pub fn header_crc_ok(&self) -> Option<bool> {
        self.header_crc()
            .map(|carried| carried == crc1394(self.header_bytes()))
    }

    fn data_start(&self) -> usize {
        self.header_len() + 4
    }

    /// Whether the packet has a data block (block packet with length > 0).
    pub fn has_data(&self) -> bool {
        self.tcode().has_data_block() && self.data_length() > 0
    }

    /// The payload: exactly `data_length` bytes (empty if none).
    pub fn data(&self) -> &[u8] {
        if !self.has_data() {
            return &[];
        }
        let start = self.data_start();
        let end = start + self.data_length() as usize;
        self.buffer.as_ref().get(start..end).unwrap_or(&[])
    }

    /// The payload padded to whole quadlets (what the data CRC covers).
    pub fn padded_data(&self) -> &[u8] {
        if !self.has_data() {
            return &[];
        }
        let start = self.data_start();
        let end = start + pad4(self.data_length() as usize);
        self.buffer.as_ref().get(start..end).unwrap_or(&[])
    }

    /// The data CRC carried in the packet.
    pub fn data_crc(&self) -> Option<u32> {
        if !self.has_data() {
            return None;
        }
        let at = self.data_start() + pad4(self.data_length() as usize);
        Some(read_quadlet(self.buffer.as_ref(), at / 4))
    }

    /// Whether the carried data CRC matches the padded data.
    pub fn data_crc_ok(&self) -> Option<bool> {
        self.data_crc()
            .map(|carried| carried == crc1394(self.padded_data()))
    }

    /// The PHY packet body of a link-internal packet (q1).
    pub fn phy_body(&self) -> u32 {
        field::PHY_BODY.get(self.buffer.as_ref())
    }

    /// Both CRC checks at once.
    pub fn crc_status(&self) -> CrcStatus {
        CrcStatus {
            header_ok: self.header_crc_ok(),
            data_ok: self.data_crc_ok(),
        }
    }

    /// Verify every CRC present (and a link-internal packet's complement).
    ///
    /// Under `cfg(fuzzing)` CRCs always pass, so a fuzzer reaches the parser.
    ///
    /// # Errors
    /// [`Error::HeaderCrc`], [`Error::DataCrc`] or [`Error::Malformed`].
    pub fn verify(&self) -> Result<()> {
        if cfg!(fuzzing) {
            return Ok(());
        }
        let buf = self.buffer.as_ref();
        if self.tcode() == Tcode::LinkInternal {
            let body = field::PHY_BODY.get(buf);
            if field::PHY_CHECK.get(buf) != !body {
                return Err(Error::Malformed {
                    what: "PHY packet complement",
                    value: body,
                });
            }
        }
        if let Some(carried) = self.header_crc() {
            let computed = crc1394(self.header_bytes());
            if carried != computed {
                return Err(Error::HeaderCrc { carried, computed });
            }
        }
        if let Some(carried) = self.data_crc() {
            let computed = crc1394(self.padded_data());
            if carried != computed {
                return Err(Error::DataCrc { carried, computed });
            }
        }
        Ok(())
    }
}

impl<'a> Packet<&'a [u8]> {
    /// The payload with the lifetime of the underlying buffer (exactly
    /// `data_length` bytes, empty if none).
    pub fn payload(&self) -> &'a [u8] {
        if !self.has_data() {
            return &[];
        }
        let start = self.data_start();
        let end = start + self.data_length() as usize;
        self.buffer.get(start..end).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    fn buf_mut(&mut self) -> &mut [u8] {
        self.buffer.as_mut()
    }

    /// Set the transaction code.
    pub fn set_tcode(&mut self, tcode: Tcode) {
        field::TCODE.set(self.buf_mut(), u32::from(u8::from(tcode)));
    }

    /// Set the destination node ID.
    pub fn set_destination_id(&mut self, id: NodeId) {
        field::DESTINATION_ID.set(self.buf_mut(), u32::from(id.0));
    }

    /// Set the transaction label (truncated to 6 bits).
    pub fn set_tl(&mut self, tl: u8) {
        field::TL.set(self.buf_mut(), u32::from(tl));
    }

    /// Set the retry code (truncated to 2 bits).
    pub fn set_rt(&mut self, rt: u8) {
        field::RT.set(self.buf_mut(), u32::from(rt));
    }

    /// Set the priority (truncated to 4 bits).
    pub fn set_pri(&mut self, pri: u8) {
        field::PRI.set(self.buf_mut(), u32::from(pri));
    }

    /// Set the source node ID.
    pub fn set_source_id(&mut self, id: NodeId) {
        field::SOURCE_ID.set(self.buf_mut(), u32::from(id.0));
    }

    /// Set the 48-bit destination offset (high bits beyond 48 are dropped).
    pub fn set_offset(&mut self, offset: u64) {
        field::OFFSET_HIGH.set(self.buf_mut(), ((offset >> 32) & 0xFFFF) as u32);
        field::OFFSET_LOW.set(self.buf_mut(), offset as u32);
    }

    /// Set the response code.
    pub fn set_rcode(&mut self, rcode: Rcode) {
        field::RCODE.set(self.buf_mut(), u32::from(u8::from(rcode)));
        // The 12 reserved bits after the rcode are zero.
        Field::new(1, 11, 0).set(self.buf_mut(), 0);
    }

    /// Set the header data quadlet.
    pub fn set_quadlet_data(&mut self, data: u32) {
        field::QUADLET_DATA.set(self.buf_mut(), data);
    }

    /// Set `data_length` (and zero the extended tcode).
    pub fn set_data_length(&mut self, length: u16) {
        if self.tcode() == Tcode::Stream {
            field::STREAM_DATA_LENGTH.set(self.buf_mut(), u32::from(length));
        } else {
            field::DATA_LENGTH.set(self.buf_mut(), u32::from(length));
        }
    }

    /// Set the extended tcode.
    pub fn set_extended_tcode(&mut self, extended_tcode: u16) {
        field::EXTENDED_TCODE.set(self.buf_mut(), u32::from(extended_tcode));
    }

    /// The payload, mutable (exactly `data_length` bytes).
    pub fn data_mut(&mut self) -> &mut [u8] {
        if !self.has_data() {
            return &mut [];
        }
        let start = self.data_start();
        let end = start + self.data_length() as usize;
        self.buffer.as_mut().get_mut(start..end).unwrap_or(&mut [])
    }

    /// Compute and store the header CRC.
    pub fn fill_header_crc(&mut self) {
        if self.tcode().has_header_crc() {
            let crc = crc1394(self.header_bytes());
            let q = self.header_len() / 4;
            write_quadlet(self.buf_mut(), q, crc);
        }
    }

    /// Zero the padding, then compute and store the data CRC.
    pub fn fill_data_crc(&mut self) {
        if !self.has_data() {
            return;
        }
        let start = self.data_start();
        let len = self.data_length() as usize;
        let padded = pad4(len);
        if let Some(pad) = self.buffer.as_mut().get_mut(start + len..start + padded) {
            pad.fill(0);
        }
        let crc = crc1394(self.padded_data());
        write_quadlet(self.buf_mut(), (start + padded) / 4, crc);
    }
}

/// The fields every asynchronous packet header starts with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AsyncHeader {
    /// Destination node ID.
    pub destination: NodeId,
    /// Source node ID.
    pub source: NodeId,
    /// Transaction label, 0..=63.
    pub tl: u8,
    /// Retry code, 0..=3.
    pub rt: u8,
    /// Priority, 0..=15.
    pub pri: u8,
}

impl AsyncHeader {
    /// A header with retry code 0 (`retry_1`: a first attempt) and
    /// priority 0.
    pub const fn new(destination: NodeId, source: NodeId, tl: u8) -> AsyncHeader {
        AsyncHeader {
            destination,
            source,
            tl,
            rt: 0,
            pri: 0,
        }
    }

    /// The same header with a different priority.
    pub const fn with_pri(mut self, pri: u8) -> AsyncHeader {
        self.pri = pri;
        self
    }

    /// The response header answering a request with this header: source and
    /// destination swapped, same label.
    pub const fn response(&self) -> AsyncHeader {
        AsyncHeader {
            destination: self.source,
            source: self.destination,
            tl: self.tl,
            rt: self.rt,
            pri: 0,
        }
    }

    fn check(&self) -> Result<()> {
        check_max("tl", u64::from(self.tl), 0x3F)?;
        check_max("rt", u64::from(self.rt), 0x3)?;
        check_max("pri", u64::from(self.pri), 0xF)
    }
}

/// One line for people: the tcode, destination and source, label, then
/// what the tcode carries (offset, data quadlet, data length, rcode) and
/// any failed CRC, e.g. `read_request_block 0xffc0 <- 0xffc2 tl 5
/// @0x1000 len 268`. Bytes that do not form a whole packet read
/// `malformed (N bytes: ...)`; nothing here panics.
impl<T: AsRef<[u8]>> fmt::Display for Packet<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Err(e) = self.check_len() {
            return write!(f, "malformed ({} bytes: {e})", self.buffer.as_ref().len());
        }
        let tcode = self.tcode();
        write!(f, "{}", tcode.name())?;
        if tcode.has_header_crc() {
            write!(
                f,
                " {} <- {} tl {}",
                self.destination_id(),
                self.source_id(),
                self.tl()
            )?;
        }
        match tcode {
            Tcode::WriteQuadletRequest => write!(
                f,
                " @{:#x} data {:#010x}",
                self.offset(),
                self.quadlet_data()
            )?,
            Tcode::ReadQuadletRequest => write!(f, " @{:#x}", self.offset())?,
            Tcode::ReadBlockRequest => {
                write!(f, " @{:#x} len {}", self.offset(), self.data_length())?
            }
            Tcode::WriteBlockRequest | Tcode::LockRequest => {
                write!(f, " @{:#x} {} bytes", self.offset(), self.data_length())?
            }
            Tcode::WriteResponse => write!(f, " {}", self.rcode().name())?,
            Tcode::ReadQuadletResponse => write!(
                f,
                " {} data {:#010x}",
                self.rcode().name(),
                self.quadlet_data()
            )?,
            Tcode::ReadBlockResponse | Tcode::LockResponse => {
                write!(f, " {} {} bytes", self.rcode().name(), self.data_length())?
            }
            _ => {}
        }
        let crc = self.crc_status();
        if crc.header_ok == Some(false) {
            f.write_str(" (header CRC bad)")?;
        }
        if crc.data_ok == Some(false) {
            f.write_str(" (data CRC bad)")?;
        }
        Ok(())
    }
}

/// The meaning of one packet: what it asks or answers.
///
/// Cycle start, lock, stream and link-internal packets are recognised but
/// carried as [`PacketRepr::Opaque`], verbatim.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketRepr<'a> {
    /// Quadlet write request (tcode 0).
    WriteQuadletRequest {
        /// Common header fields.
        header: AsyncHeader,
        /// 48-bit destination offset.
        offset: u64,
        /// The quadlet written.
        data: u32,
    },
    /// Block write request (tcode 1).
    WriteBlockRequest {
        /// Common header fields.
        header: AsyncHeader,
        /// 48-bit destination offset.
        offset: u64,
        /// Extended tcode (0 for plain writes).
        extended_tcode: u16,
        /// The payload (`data_length` bytes).
        data: &'a [u8],
    },
    /// Write response (tcode 2).
    WriteResponse {
        /// Common header fields.
        header: AsyncHeader,
        /// Response code.
        rcode: Rcode,
    },
    /// Quadlet read request (tcode 4).
    ReadQuadletRequest {
        /// Common header fields.
        header: AsyncHeader,
        /// 48-bit destination offset.
        offset: u64,
    },
    /// Block read request (tcode 5).
    ReadBlockRequest {
        /// Common header fields.
        header: AsyncHeader,
        /// 48-bit destination offset.
        offset: u64,
        /// Bytes requested.
        data_length: u16,
        /// Extended tcode (0 for plain reads).
        extended_tcode: u16,
    },
    /// Quadlet read response (tcode 6).
    ReadQuadletResponse {
        /// Common header fields.
        header: AsyncHeader,
        /// Response code.
        rcode: Rcode,
        /// The quadlet read.
        data: u32,
    },
    /// Block read response (tcode 7).
    ReadBlockResponse {
        /// Common header fields.
        header: AsyncHeader,
        /// Response code.
        rcode: Rcode,
        /// Extended tcode.
        extended_tcode: u16,
        /// The payload (`data_length` bytes).
        data: &'a [u8],
    },
    /// A recognised packet carried verbatim: cycle start, lock, stream or
    /// link-internal (PHY).
    Opaque {
        /// Its transaction code.
        tcode: Tcode,
        /// The whole packet, CRCs included.
        bytes: &'a [u8],
    },
}

impl<'a> PacketRepr<'a> {
    /// Parse a checked packet. CRCs are not verified here: use
    /// [`Packet::verify`] or [`PacketRepr::parse_verified`].
    ///
    /// # Errors
    /// [`Error::UnknownTcode`] for tcodes without a defined format.
    pub fn parse(packet: &Packet<&'a [u8]>) -> Result<PacketRepr<'a>> {
        Self::parse_bytes_unverified(packet.buffer)
    }

    fn parse_bytes_unverified(bytes: &'a [u8]) -> Result<PacketRepr<'a>> {
        let packet = Packet::new_checked(bytes)?;
        let header = AsyncHeader {
            destination: packet.destination_id(),
            source: packet.source_id(),
            tl: packet.tl(),
            rt: packet.rt(),
            pri: packet.pri(),
        };
        let total = packet.total_len();
        let data = packet.payload();
        Ok(match packet.tcode() {
            Tcode::WriteQuadletRequest => PacketRepr::WriteQuadletRequest {
                header,
                offset: packet.offset(),
                data: packet.quadlet_data(),
            },
            Tcode::WriteBlockRequest => PacketRepr::WriteBlockRequest {
                header,
                offset: packet.offset(),
                extended_tcode: packet.extended_tcode(),
                data,
            },
            Tcode::WriteResponse => PacketRepr::WriteResponse {
                header,
                rcode: packet.rcode(),
            },
            Tcode::ReadQuadletRequest => PacketRepr::ReadQuadletRequest {
                header,
                offset: packet.offset(),
            },
            Tcode::ReadBlockRequest => PacketRepr::ReadBlockRequest {
                header,
                offset: packet.offset(),
                data_length: packet.data_length(),
                extended_tcode: packet.extended_tcode(),
            },
            Tcode::ReadQuadletResponse => PacketRepr::ReadQuadletResponse {
                header,
                rcode: packet.rcode(),
                data: packet.quadlet_data(),
            },
            Tcode::ReadBlockResponse => PacketRepr::ReadBlockResponse {
                header,
                rcode: packet.rcode(),
                extended_tcode: packet.extended_tcode(),
                data,
            },
            tcode @ (Tcode::CycleStart
            | Tcode::LockRequest
            | Tcode::LockResponse
            | Tcode::Stream
            | Tcode::LinkInternal) => PacketRepr::Opaque {
                tcode,
                bytes: bytes.get(..total).unwrap_or(bytes),
            },
            Tcode::Unknown(code) => return Err(Error::UnknownTcode(code)),
        })
    }

    /// Parse exactly one packet from `bytes`, verifying its CRCs.
    ///
    /// # Errors
    /// Length errors, [`Error::TrailingBytes`] if bytes follow the packet,
    /// CRC errors from [`Packet::verify`], [`Error::UnknownTcode`].
    pub fn parse_verified(bytes: &'a [u8]) -> Result<PacketRepr<'a>> {
        let packet = Packet::new_checked(bytes)?;
        let total = packet.total_len();
        if bytes.len() > total {
            return Err(Error::TrailingBytes {
                what: packet.tcode().name(),
                extra: bytes.len() - total,
            });
        }
        packet.verify()?;
        Self::parse_bytes_unverified(bytes)
    }

    /// The transaction code.
    pub fn tcode(&self) -> Tcode {
        match self {
            PacketRepr::WriteQuadletRequest { .. } => Tcode::WriteQuadletRequest,
            PacketRepr::WriteBlockRequest { .. } => Tcode::WriteBlockRequest,
            PacketRepr::WriteResponse { .. } => Tcode::WriteResponse,
            PacketRepr::ReadQuadletRequest { .. } => Tcode::ReadQuadletRequest,
            PacketRepr::ReadBlockRequest { .. } => Tcode::ReadBlockRequest,
            PacketRepr::ReadQuadletResponse { .. } => Tcode::ReadQuadletResponse,
            PacketRepr::ReadBlockResponse { .. } => Tcode::ReadBlockResponse,
            PacketRepr::Opaque { tcode, .. } => *tcode,
        }
    }

    /// The common header fields; `None` for opaque packets.
    pub fn header(&self) -> Option<AsyncHeader> {
        match self {
            PacketRepr::WriteQuadletRequest { header, .. }
            | PacketRepr::WriteBlockRequest { header, .. }
            | PacketRepr::WriteResponse { header, .. }
            | PacketRepr::ReadQuadletRequest { header, .. }
            | PacketRepr::ReadBlockRequest { header, .. }
            | PacketRepr::ReadQuadletResponse { header, .. }
            | PacketRepr::ReadBlockResponse { header, .. } => Some(*header),
            PacketRepr::Opaque { .. } => None,
        }
    }

    /// The payload of block packets (empty otherwise).
    pub fn data(&self) -> &'a [u8] {
        match self {
            PacketRepr::WriteBlockRequest { data, .. }
            | PacketRepr::ReadBlockResponse { data, .. } => data,
            _ => &[],
        }
    }

    /// Bytes [`emit`](Self::emit) writes.
    pub fn buffer_len(&self) -> usize {
        match self {
            PacketRepr::Opaque { bytes, .. } => bytes.len(),
            _ => {
                let tcode = self.tcode();
                let header = tcode.header_len().unwrap_or(0) + 4;
                let data = self.data();
                if tcode.has_data_block() && !data.is_empty() {
                    header + pad4(data.len()) + 4
                } else {
                    header
                }
            }
        }
    }

    /// Write the packet into `buf` with correct CRCs; returns bytes written.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`], or [`Error::FieldRange`] when a field does
    /// not fit (tl > 63, offset beyond 48 bits, payload over 65535 bytes).
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let len = self.buffer_len();
        let Some(out) = buf.get_mut(..len) else {
            return Err(Error::BufferTooSmall {
                what: self.tcode().name(),
                needed: len,
                available: buf.len(),
            });
        };
        if let PacketRepr::Opaque { bytes, .. } = self {
            out.copy_from_slice(bytes);
            return Ok(len);
        }
        out.fill(0);
        if let Some(header) = self.header() {
            header.check()?;
        }
        let data = self.data();
        check_max("data_length", data.len() as u64, 0xFFFF)?;
        let mut packet = Packet::new_unchecked(out);
        packet.set_tcode(self.tcode());
        if let Some(h) = self.header() {
            packet.set_destination_id(h.destination);
            packet.set_source_id(h.source);
            packet.set_tl(h.tl);
            packet.set_rt(h.rt);
            packet.set_pri(h.pri);
        }
        match *self {
            PacketRepr::WriteQuadletRequest { offset, data, .. } => {
                check_max("offset", offset, MAX_OFFSET)?;
                packet.set_offset(offset);
                packet.set_quadlet_data(data);
            }
            PacketRepr::WriteBlockRequest {
                offset,
                extended_tcode,
                data,
                ..
            } => {
                check_max("offset", offset, MAX_OFFSET)?;
                packet.set_offset(offset);
                packet.set_data_length(data.len() as u16);
                packet.set_extended_tcode(extended_tcode);
                packet.data_mut().copy_from_slice(data);
            }
            PacketRepr::WriteResponse { rcode, .. } => packet.set_rcode(rcode),
            PacketRepr::ReadQuadletRequest { offset, .. } => {
                check_max("offset", offset, MAX_OFFSET)?;
                packet.set_offset(offset);
            }
            PacketRepr::ReadBlockRequest {
                offset,
                data_length,
                extended_tcode,
                ..
            } => {
                check_max("offset", offset, MAX_OFFSET)?;
                packet.set_offset(offset);
                packet.set_data_length(data_length);
                packet.set_extended_tcode(extended_tcode);
            }
            PacketRepr::ReadQuadletResponse { rcode, data, .. } => {
                packet.set_rcode(rcode);
                packet.set_quadlet_data(data);
            }
            PacketRepr::ReadBlockResponse {
                rcode,
                extended_tcode,
                data,
                ..
            } => {
                packet.set_rcode(rcode);
                packet.set_data_length(data.len() as u16);
                packet.set_extended_tcode(extended_tcode);
                packet.data_mut().copy_from_slice(data);
            }
            PacketRepr::Opaque { .. } => {}
        }
        packet.fill_header_crc();
        packet.fill_data_crc();
        Ok(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;

    #[test]
    fn node_id_parts() {
        let n = NodeId::local(5);
        assert_eq!(n.0, 0xFFC5);
        assert_eq!(n.bus(), 0x3FF);
        assert_eq!(n.phy(), 5);
        assert!(NodeId::BROADCAST.is_broadcast());
        assert_eq!(format!("{n}"), "0xffc5");
    }

    #[test]
    fn ack_bytes() {
        assert_eq!(Ack::Complete.to_byte(), 0x1E);
        assert_eq!(Ack::Pending.to_byte(), 0x2D);
        assert_eq!(Ack::from_byte(0x1E), Ok(Ack::Complete));
        assert_eq!(Ack::from_byte(0xD2), Ok(Ack::DataError));
        assert!(Ack::from_byte(0x1F).is_err());
        assert_eq!(Ack::from_byte(0x3C), Ok(Ack::Unknown(3)));
    }

    #[test]
    fn tcode_names_round_trip() {
        for code in 0u8..16 {
            let t = Tcode::from(code);
            if t.is_known() {
                assert_eq!(Tcode::from_name(t.name()), Some(t));
            }
        }
        assert_eq!(Tcode::from_name("nonsense"), None);
    }

    #[test]
    fn truncated_and_overlong_length() {
        // A block write header claiming 0x84 bytes with none present.
        let mut buf = [0u8; 20];
        let mut p = Packet::new_unchecked(&mut buf[..]);
        p.set_tcode(Tcode::WriteBlockRequest);
        p.set_data_length(0x84);
        assert!(matches!(
            Packet::new_checked(&buf[..]),
            Err(Error::LengthExceedsBuffer { declared: 0x84, .. })
        ));
        assert!(matches!(
            Packet::new_checked(&buf[..3]),
            Err(Error::Truncated { needed: 4, .. })
        ));
        assert!(matches!(
            Packet::new_checked(&buf[..10]),
            Err(Error::Truncated { needed: 20, .. })
        ));
        let mut unknown = [0u8; 32];
        unknown[3] = 0x30;
        assert_eq!(
            Packet::new_checked(&unknown[..]),
            Err(Error::UnknownTcode(3))
        );
    }

    #[test]
    fn emit_rejects_out_of_range_fields() {
        let repr = PacketRepr::ReadQuadletRequest {
            header: AsyncHeader::new(NodeId::local(0), NodeId::local(1), 64),
            offset: 0,
        };
        let mut buf = [0u8; 16];
        assert!(matches!(
            repr.emit(&mut buf),
            Err(Error::FieldRange { field: "tl", .. })
        ));
        let repr = PacketRepr::ReadQuadletRequest {
            header: AsyncHeader::new(NodeId::local(0), NodeId::local(1), 1),
            offset: 1 << 48,
        };
        assert!(matches!(
            repr.emit(&mut buf),
            Err(Error::FieldRange {
                field: "offset",
                ..
            })
        ));
        assert!(matches!(
            repr.emit(&mut buf[..8]),
            Err(Error::BufferTooSmall { needed: 16, .. })
        ));
    }

    #[test]
    fn zero_length_block_has_no_data_crc() {
        let repr = PacketRepr::WriteBlockRequest {
            header: AsyncHeader::new(NodeId::local(0), NodeId::local(1), 1),
            offset: 0,
            extended_tcode: 0,
            data: &[],
        };
        assert_eq!(repr.buffer_len(), 20);
        let mut buf = [0xA5u8; 20];
        repr.emit(&mut buf).unwrap();
        let p = Packet::new_checked(&buf[..]).unwrap();
        assert_eq!(p.data_crc(), None);
        assert_eq!(PacketRepr::parse_verified(&buf).unwrap(), repr);
    }

    #[test]
    fn unaligned_payload_is_padded_with_zeros() {
        let repr = PacketRepr::WriteBlockRequest {
            header: AsyncHeader::new(NodeId::local(2), NodeId::local(1), 9),
            offset: 0x1000,
            extended_tcode: 0,
            data: &[1, 2, 3, 4, 5],
        };
        let mut buf = [0xA5u8; 64];
        let len = repr.emit(&mut buf).unwrap();
        assert_eq!(len, 20 + 8 + 4);
        assert_eq!(&buf[20..28], &[1, 2, 3, 4, 5, 0, 0, 0]);
        assert_eq!(PacketRepr::parse_verified(&buf[..len]).unwrap(), repr);
    }
}
