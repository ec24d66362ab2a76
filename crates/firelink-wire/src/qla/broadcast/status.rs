//! The per-board status broadcast (`fpga-board.md` §6.2): its header quadlet
//! (the query's sequence and the length) followed by the board's real-time read
//! block, as a checked view and a meaning type.

use super::*;

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
    let board = crate::qla::registers::StatusRead(read_quadlet(status, 0)).board_id();
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qla::registers::StatusRead;

    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);

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
}
