//! The meaning of one packet: the header fields every asynchronous packet starts
//! with and `PacketRepr`, one variant per tcode, which parses from a checked
//! view and emits into a buffer.

use super::*;

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
        let len = self.emit_unsealed(buf)?;
        let opaque = matches!(self, PacketRepr::Opaque { .. });
        if let (false, Some(out)) = (opaque, buf.get_mut(..len)) {
            let mut packet = Packet::new_unchecked(out);
            packet.fill_header_crc();
            packet.fill_data_crc();
        }
        Ok(len)
    }

    /// [`emit`](Self::emit) with the header CRC and data CRC fields left
    /// zero, for a sender whose link writes them as the packet goes out
    /// (the simulated bus's sealing): the same bytes once both are filled.
    /// An [`Opaque`](PacketRepr::Opaque) packet's bytes are copied as they
    /// are, CRCs included.
    ///
    /// # Errors
    /// As [`emit`](Self::emit).
    pub fn emit_unsealed(&self, buf: &mut [u8]) -> Result<usize> {
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
        Ok(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

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

    /// Every kind of packet emitted unsealed is, once its CRCs are
    /// filled, byte for byte what `emit` writes (over stale bytes, data
    /// lengths not whole quadlets included), with both CRC fields zero
    /// before; a field out of range is refused alike.
    #[test]
    fn an_unsealed_packet_sealed_is_the_emitted_one() {
        let header = AsyncHeader::new(NodeId::local(3), NodeId::local(0), 17).with_pri(2);
        let data: Vec<u8> = (0..41u8).map(|i| i.wrapping_mul(37)).collect();
        let mut packets = vec![
            PacketRepr::WriteQuadletRequest {
                header,
                offset: 0xFFFF_F000_0100,
                data: 0xDEAD_BEEF,
            },
            PacketRepr::ReadQuadletRequest { header, offset: 4 },
            PacketRepr::ReadBlockRequest {
                header,
                offset: 0x1000,
                data_length: 24,
                extended_tcode: 0,
            },
            PacketRepr::WriteResponse {
                header,
                rcode: Rcode::Complete,
            },
            PacketRepr::ReadQuadletResponse {
                header,
                rcode: Rcode::Complete,
                data: 0x1234_5678,
            },
        ];
        for len in [0, 1, 4, 7, 41] {
            packets.push(PacketRepr::WriteBlockRequest {
                header,
                offset: 0x2000,
                extended_tcode: 0,
                data: &data[..len],
            });
            packets.push(PacketRepr::ReadBlockResponse {
                header,
                rcode: Rcode::Complete,
                extended_tcode: 0,
                data: &data[..len],
            });
        }
        for repr in &packets {
            let mut emitted = vec![0; repr.buffer_len()];
            repr.emit(&mut emitted).unwrap();
            let mut unsealed = vec![0xA5; repr.buffer_len()];
            assert_eq!(repr.emit_unsealed(&mut unsealed).unwrap(), emitted.len());
            let mut packet = Packet::new_checked(&mut unsealed[..]).unwrap();
            assert_eq!(packet.header_crc(), Some(0), "{repr:?}: left to the sender");
            assert!(matches!(packet.data_crc(), None | Some(0)), "{repr:?}");
            packet.fill_header_crc();
            packet.fill_data_crc();
            assert_eq!(unsealed, emitted, "{repr:?}");
        }
        let out_of_range = PacketRepr::ReadQuadletRequest {
            header,
            offset: MAX_OFFSET + 1,
        };
        let mut buf = [0u8; 16];
        assert!(matches!(
            out_of_range.emit_unsealed(&mut buf),
            Err(Error::FieldRange {
                field: "offset",
                ..
            })
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
