//! The checked, zero-copy view of one packet (`ieee1394.md`, "Header layout"):
//! length checks, a getter and setter per header field, the header and data
//! CRCs, and the one-line human form. After `Packet::check_len` succeeds no
//! accessor panics.

use super::*;

/// Largest 48-bit destination offset.
pub const MAX_OFFSET: u64 = (1 << 48) - 1;

/// A packet's carried header CRC and data CRC, each with the bytes it
/// covers (`None`: the packet has no such CRC).
type CrcSpans<'a> = (Option<(u32, &'a [u8])>, Option<(u32, &'a [u8])>);

/// Result of checking a packet's CRCs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CrcStatus {
    /// Header CRC matches; `None` for packets without one.
    pub header_ok: Option<bool>,
    /// Data CRC matches; `None` for packets without a data block.
    pub data_ok: Option<bool>,
}

/// Bytes after the header CRC of a packet with `tcode` and `data_length`:
/// the padded data block and its CRC, or none.
fn data_block_len(tcode: Tcode, data_length: u16) -> usize {
    if tcode.has_data_block() && data_length > 0 {
        pad4(usize::from(data_length)) + 4
    } else {
        0
    }
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
    pub(super) buffer: T,
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
    #[inline]
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
    #[inline]
    pub fn check_len(&self) -> Result<()> {
        let buf = self.buffer.as_ref();
        if buf.len() < 4 {
            return Err(Error::Truncated {
                what: "packet header",
                needed: 4,
                available: buf.len(),
            });
        }
        // The tcode decoded once for every check (each accessor would
        // decode it again).
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
        let data_length = self.data_length_of(tcode);
        let total = with_crc + data_block_len(tcode, data_length);
        if buf.len() < total {
            return Err(Error::LengthExceedsBuffer {
                what: tcode.name(),
                declared: data_length as usize,
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
        header_len + crc + data_block_len(tcode, self.data_length_of(tcode))
    }

    /// Bytes of the whole packet (header, CRCs, padded data).
    pub fn total_len(&self) -> usize {
        self.total_len_unchecked()
    }

    /// The transaction code.
    #[inline]
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
        self.data_length_of(self.tcode())
    }

    /// [`data_length`](Self::data_length) with the tcode decoded.
    fn data_length_of(&self, tcode: Tcode) -> u16 {
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
    #[inline]
    pub fn data(&self) -> &[u8] {
        // As `has_data` and `data_start` say, the tcode decoded once.
        let tcode = self.tcode();
        let data_length = self.data_length_of(tcode);
        if !(tcode.has_data_block() && data_length > 0) {
            return &[];
        }
        let start = tcode.header_len().unwrap_or(0) + 4;
        let end = start + data_length as usize;
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

    /// The CRCs the packet carries, each with the bytes it covers, the
    /// tcode decoded once: the header CRC and [`header_bytes`](Self::header_bytes)
    /// when the tcode has one, the data CRC and
    /// [`padded_data`](Self::padded_data) when there is a data block (what
    /// [`header_crc`](Self::header_crc) and [`data_crc`](Self::data_crc)
    /// read).
    #[inline]
    fn crc_spans(&self) -> CrcSpans<'_> {
        let buf = self.buffer.as_ref();
        let tcode = self.tcode();
        let header_len = tcode.header_len().unwrap_or(0);
        let header = tcode.has_header_crc().then(|| {
            (
                read_quadlet(buf, header_len / 4),
                buf.get(..header_len).unwrap_or(buf),
            )
        });
        let data_length = self.data_length_of(tcode);
        let data = (tcode.has_data_block() && data_length > 0).then(|| {
            let start = header_len + 4;
            let end = start + pad4(data_length as usize);
            (
                read_quadlet(buf, end / 4),
                buf.get(start..end).unwrap_or(&[]),
            )
        });
        (header, data)
    }

    /// Both CRC checks at once.
    pub fn crc_status(&self) -> CrcStatus {
        let (header, data) = self.crc_spans();
        CrcStatus {
            header_ok: header.map(|(carried, bytes)| carried == crc1394(bytes)),
            data_ok: data.map(|(carried, bytes)| carried == crc1394(bytes)),
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
        let (header, data) = self.crc_spans();
        if let Some((carried, bytes)) = header {
            let computed = crc1394(bytes);
            if carried != computed {
                return Err(Error::HeaderCrc { carried, computed });
            }
        }
        if let Some((carried, bytes)) = data {
            let computed = crc1394(bytes);
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

#[cfg(test)]
mod tests {
    use super::*;

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
    fn crc_status_and_verify_read_what_the_single_accessors_read() {
        // Every tcode, data lengths around the padding, whole and cut
        // buffers, CRCs filled then one byte flipped in turn: the one-pass
        // status is the two accessors' answers, and verify fails exactly
        // where one says false (its first failure, header before data).
        let mut x = 0x9E37_79B9u32;
        for tcode in 0..16u8 {
            for data_length in [0u16, 1, 3, 4, 5, 68] {
                let mut whole = [0u8; 100];
                for b in whole.iter_mut() {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    *b = x as u8;
                }
                let mut p = Packet::new_unchecked(&mut whole[..]);
                p.set_tcode(Tcode::from(tcode));
                p.set_data_length(data_length);
                p.fill_header_crc();
                p.fill_data_crc();
                for flip in [None, Some(2usize), Some(13), Some(21), Some(40)] {
                    let mut buf = whole;
                    if let Some(i) = flip {
                        buf[i] ^= 0x10;
                    }
                    for cut in [100usize, 90, 40, 24, 17, 12, 4] {
                        let view = Packet::new_unchecked(&buf[..cut]);
                        let status = view.crc_status();
                        let what = (tcode, data_length, flip, cut);
                        assert_eq!(status.header_ok, view.header_crc_ok(), "{what:?}");
                        assert_eq!(status.data_ok, view.data_crc_ok(), "{what:?}");
                        let verdict = view.verify();
                        if view.tcode() != Tcode::LinkInternal {
                            assert_eq!(verdict.is_ok(), status.all_ok(), "{what:?}");
                        }
                        match verdict {
                            Err(Error::HeaderCrc { carried, computed }) => {
                                assert_eq!(Some(carried), view.header_crc(), "{what:?}");
                                assert_eq!(computed, crc1394(view.header_bytes()), "{what:?}");
                            }
                            Err(Error::DataCrc { carried, computed }) => {
                                assert_eq!(
                                    status.header_ok,
                                    view.header_crc().map(|_| true),
                                    "{what:?}"
                                );
                                assert_eq!(Some(carried), view.data_crc(), "{what:?}");
                                assert_eq!(computed, crc1394(view.padded_data()), "{what:?}");
                            }
                            _ => {}
                        }
                    }
                }
            }
        }
    }
}
