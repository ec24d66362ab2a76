//! The codes a 1394 asynchronous packet carries (`ieee1394.md`, "Transaction
//! codes"): node IDs, the transaction code with the header length it implies,
//! the response code, the acknowledge and the speed code. The enums are open:
//! unknown values are data.

use super::*;

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
}
