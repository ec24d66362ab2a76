//! The real-time write block (`fpga-board.md` §5): the Rev 8 header, the per-
//! motor DAC commands and the STATUS control word, as a checked view over bytes
//! and a meaning type.

use super::*;

/// The header quadlet of a Rev 8 write block: `(board_id<<8) | (motors+2)`
/// (`fpga-board.md` §5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct WriteHeader {
    /// The board the block is for (bits 15:8).
    pub board_id: u8,
    /// Quadlets of the block including this header (bits 7:0).
    pub quadlets: u8,
}

impl WriteHeader {
    /// Decode a header quadlet (bits 31:16 are ignored).
    pub fn from_word(word: u32) -> WriteHeader {
        WriteHeader {
            board_id: field::HEADER_BOARD_ID.extract(word) as u8,
            quadlets: field::HEADER_QUADLETS.extract(word) as u8,
        }
    }

    /// Encode as the header quadlet.
    pub fn to_word(self) -> u32 {
        let w = field::HEADER_BOARD_ID.insert(0, u32::from(self.board_id));
        field::HEADER_QUADLETS.insert(w, u32::from(self.quadlets))
    }
}

layout_view! {
    /// A checked view of a real-time write block (`fpga-board.md` §5).
    pub struct WriteBlock;
    what: "real-time write block",
    quadlets: write_block_quadlets,
}

impl<T: AsRef<[u8]>> WriteBlock<T> {
    fn dac_quadlet(&self) -> usize {
        match self.layout.format() {
            BlockFormat::Rev4 | BlockFormat::Rev7 => 0,
            BlockFormat::Rev8 => 1,
        }
    }

    /// The Rev 8 header; `None` on Rev 4 and Rev 7 (no header).
    pub fn header(&self) -> Option<WriteHeader> {
        match self.layout.format() {
            BlockFormat::Rev4 | BlockFormat::Rev7 => None,
            BlockFormat::Rev8 => Some(WriteHeader::from_word(read_quadlet(
                self.buffer.as_ref(),
                0,
            ))),
        }
    }

    /// The board the block is for: header bits 15:8 on Rev 8, the first DAC
    /// quadlet's bits 27:24 on Rev 4 and Rev 7.
    pub fn board_id(&self) -> u8 {
        match self.header() {
            Some(h) => h.board_id,
            None => self.dac(0).map_or(0, DacWord::board_id),
        }
    }

    /// The DAC quadlet of 0-based `motor`.
    pub fn dac(&self, motor: usize) -> Option<DacWord> {
        (motor < self.layout.motors()).then(|| {
            DacWord(read_quadlet(
                self.buffer.as_ref(),
                self.dac_quadlet() + motor,
            ))
        })
    }

    /// The control quadlet, written to STATUS (only bits 19:0 take effect:
    /// see [`StatusWrite::block_command`]); Rev 4 blocks have none and read
    /// the zero word, which changes nothing.
    pub fn control(&self) -> StatusWrite {
        match self.layout.format() {
            BlockFormat::Rev4 => StatusWrite::default(),
            BlockFormat::Rev7 | BlockFormat::Rev8 => {
                let q = self.layout.write_block_quadlets().saturating_sub(1);
                StatusWrite(read_quadlet(self.buffer.as_ref(), q))
            }
        }
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> WriteBlock<T> {
    /// Set the Rev 8 header.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] on Rev 4 and Rev 7, whose blocks have no
    /// header.
    pub fn set_header(&mut self, header: WriteHeader) -> Result<()> {
        match self.layout.format() {
            BlockFormat::Rev4 | BlockFormat::Rev7 => Err(Error::InvalidValue {
                what: "firmware revision for a write block header (Rev 4 and 7 blocks have none)",
                value: self.layout.firmware().number(),
            }),
            BlockFormat::Rev8 => {
                write_quadlet(self.buffer.as_mut(), 0, header.to_word());
                Ok(())
            }
        }
    }

    /// Set the DAC quadlet of 0-based `motor`.
    ///
    /// # Errors
    /// [`Error::Index`] for a motor the layout does not have.
    pub fn set_dac(&mut self, motor: usize, dac: DacWord) -> Result<()> {
        let count = self.layout.motors();
        if motor >= count {
            return Err(Error::Index {
                what: "DAC (motor)",
                index: motor,
                count,
            });
        }
        let q = self.dac_quadlet() + motor;
        write_quadlet(self.buffer.as_mut(), q, dac.0);
        Ok(())
    }

    /// Set the control quadlet (Rev 4 blocks have none: nothing is written).
    pub fn set_control(&mut self, control: StatusWrite) {
        if self.layout.format() == BlockFormat::Rev4 {
            return;
        }
        let q = self.layout.write_block_quadlets().saturating_sub(1);
        write_quadlet(self.buffer.as_mut(), q, control.0);
    }
}

/// The meaning of a real-time write block (`fpga-board.md` §5).
///
/// On Rev 4 and Rev 7 the board ID travels in bits 27:24 of every DAC
/// quadlet (and Rev 4 has no control quadlet: `control` is not on the wire):
/// [`emit`](Self::emit) writes it there, [`parse`](Self::parse) keeps the DAC
/// quadlets raw (so they carry it) and checks they agree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct WriteBlockRepr {
    /// The layout.
    pub layout: BoardLayout,
    /// The board the block is for, 0..=15.
    pub board_id: u8,
    /// DAC quadlets, index 0 = motor 1; entries beyond the layout's motors
    /// are not on the wire.
    pub dac: [DacWord; MAX_AXES],
    /// The control quadlet, written to STATUS.
    pub control: StatusWrite,
}

impl WriteBlockRepr {
    /// A block for `board_id` with all DAC quadlets and the control zero.
    pub fn new(layout: BoardLayout, board_id: u8) -> WriteBlockRepr {
        WriteBlockRepr {
            layout,
            board_id,
            dac: [DacWord::default(); MAX_AXES],
            control: StatusWrite::default(),
        }
    }

    /// The DAC quadlets of the layout's motors.
    #[inline]
    pub fn dacs(&self) -> &[DacWord] {
        self.dac.get(..self.layout.motors()).unwrap_or(&[])
    }

    /// Parse a write block.
    ///
    /// # Errors
    /// Length errors of [`WriteBlock::check_len`]; on Rev 8
    /// [`Error::Malformed`] for a header with bits 31:16 set or a board ID
    /// above 15 and [`Error::BlockSize`] when its length is not the
    /// layout's; on Rev 4 and Rev 7 [`Error::Malformed`] when the DAC quadlets
    /// disagree on the board ID.
    pub fn parse<T: AsRef<[u8]>>(block: &WriteBlock<T>) -> Result<WriteBlockRepr> {
        block.check_len()?;
        let layout = block.layout;
        let board_id = block.board_id();
        if layout.format() == BlockFormat::Rev8 {
            let word = read_quadlet(block.as_bytes(), 0);
            if field::HEADER_RESERVED.extract(word) != 0 || check_board_id(board_id).is_err() {
                return Err(Error::Malformed {
                    what: "Rev 8 write block header",
                    value: word,
                });
            }
            let declared = usize::from(WriteHeader::from_word(word).quadlets);
            if declared != layout.write_block_quadlets() {
                return Err(Error::BlockSize {
                    what: "Rev 8 write block (header length)",
                    expected: layout.write_block_quadlets(),
                    found: declared,
                });
            }
        }
        let mut repr = WriteBlockRepr::new(layout, board_id);
        for (i, d) in repr.dac.iter_mut().enumerate() {
            let Some(dac) = block.dac(i) else { break };
            if layout.format() != BlockFormat::Rev8 && dac.board_id() != board_id {
                return Err(Error::Malformed {
                    what: "Rev 4/7 write block DAC quadlet with another board ID",
                    value: dac.0,
                });
            }
            *d = dac;
        }
        repr.control = block.control();
        Ok(repr)
    }

    /// Bytes [`emit`](Self::emit) writes.
    #[inline]
    pub fn buffer_len(&self) -> usize {
        self.layout.write_block_len()
    }

    /// Write the block into the start of `buf`; returns bytes written.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a board ID above 15;
    /// [`Error::BufferTooSmall`].
    #[inline]
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        self.emit_with_control(self.control, buf)
    }

    /// [`emit`](Self::emit) with `control` as the control quadlet instead
    /// of the block's own: the host keeps its board's commands in a block
    /// and the control apart, and writes both into the command block
    /// without a copy of the block put together first (always inlined:
    /// the command block writer calls it for every board and cycle, and
    /// `#[inline]` alone left it a call).
    ///
    /// # Errors
    /// As [`emit`](Self::emit).
    #[inline(always)]
    pub fn emit_with_control(&self, control: StatusWrite, buf: &mut [u8]) -> Result<usize> {
        check_board_id(self.board_id)?;
        let len = self.buffer_len();
        let available = buf.len();
        let Some(out) = buf.get_mut(..len) else {
            return Err(Error::BufferTooSmall {
                what: "real-time write block",
                needed: len,
                available,
            });
        };
        // Whole quadlets in wire order (what `WriteBlock`'s setters write,
        // each once): the Rev 8 header, the DACs (Rev 4 and 7: with the
        // board ID), the control quadlet last (none on Rev 4). The QLA1's
        // and the DQLA's Rev 8 blocks each quadlet stored in its place;
        // any other put together in a fixed array first, then stored in
        // one pass (`out` holds exactly the layout's quadlets).
        let format = self.layout.format();
        let stored = match (format, self.layout.motors()) {
            (BlockFormat::Rev8, 4) => self.emit_rev8::<4>(control, out),
            (BlockFormat::Rev8, 8) => self.emit_rev8::<8>(control, out),
            _ => false,
        };
        if stored {
            return Ok(len);
        }
        let mut words = [0u32; MAX_AXES + 2];
        let (dacs, rest) = match format {
            BlockFormat::Rev8 => {
                let (header, rest) = words.split_at_mut(1);
                if let Some(h) = header.first_mut() {
                    *h = WriteHeader {
                        board_id: self.board_id,
                        quadlets: self.layout.write_block_quadlets() as u8,
                    }
                    .to_word();
                }
                rest.split_at_mut(MAX_AXES)
            }
            BlockFormat::Rev4 | BlockFormat::Rev7 => words.split_at_mut(MAX_AXES),
        };
        let motors = self.layout.motors();
        for (w, &dac) in dacs.iter_mut().zip(&self.dac) {
            *w = match format {
                BlockFormat::Rev4 | BlockFormat::Rev7 => dac.with_board_id(self.board_id).0,
                BlockFormat::Rev8 => dac.0,
            };
        }
        // The control quadlet right after the layout's DACs.
        if format != BlockFormat::Rev4 {
            if let Some(c) = dacs.get_mut(motors).or_else(|| rest.first_mut()) {
                *c = control.0;
            }
        }
        for (q, w) in out.chunks_exact_mut(4).zip(words) {
            q.copy_from_slice(&w.to_be_bytes());
        }
        Ok(len)
    }

    /// [`emit_with_control`](Self::emit_with_control)'s Rev 8 block of a
    /// layout with `N` motors into `out`, which holds exactly its `N + 2`
    /// quadlets: the header, the `N` DACs, the control quadlet, each
    /// stored in its place (constants here); false, nothing written, when
    /// `out` is shorter.
    #[inline(always)]
    fn emit_rev8<const N: usize>(&self, control: StatusWrite, out: &mut [u8]) -> bool {
        let Some(out) = out.get_mut(..(N + 2) * 4) else {
            return false;
        };
        let mut put = |q: usize, word: u32| {
            if let Some(b) = out.get_mut(q * 4..q * 4 + 4) {
                b.copy_from_slice(&word.to_be_bytes());
            }
        };
        let header = WriteHeader {
            board_id: self.board_id,
            quadlets: (N + 2) as u8,
        };
        put(0, header.to_word());
        for (i, dac) in self.dac.iter().take(N).enumerate() {
            put(1 + i, dac.0);
        }
        put(N + 1, control.0);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qla::registers::{DAC_ZERO, STATUS_POWER_ON, StatusCommand};

    const REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);

    #[test]
    fn rev8_write_block_worked_example() {
        let mut repr = WriteBlockRepr::new(REV8, 3);
        for (i, d) in repr.dac.iter_mut().take(4).enumerate() {
            *d = DacWord::valid_command(DAC_ZERO + i as u16).with_amp_request(Some(true));
        }
        repr.control = StatusCommand::power(true).to_word();
        let mut buf = [0xA5u8; 32];
        assert_eq!(repr.emit(&mut buf), Ok(24));
        let expect: [u32; 6] = [
            0x0000_0306,
            0xB000_8000,
            0xB000_8001,
            0xB000_8002,
            0xB000_8003,
            STATUS_POWER_ON,
        ];
        for (i, &w) in expect.iter().enumerate() {
            assert_eq!(read_quadlet(&buf, i), w, "quadlet {i}");
        }
        assert!(buf[24..].iter().all(|&b| b == 0xA5));
        let block = WriteBlock::new_checked(&buf[..24], REV8).unwrap();
        assert_eq!(
            block.header(),
            Some(WriteHeader {
                board_id: 3,
                quadlets: 6
            })
        );
        assert_eq!(block.board_id(), 3);
        assert_eq!(WriteBlockRepr::parse(&block), Ok(repr));
    }

    #[test]
    fn rev7_write_block_carries_the_board_id_in_each_dac() {
        let mut repr = WriteBlockRepr::new(REV7, 9);
        repr.dac[0] = DacWord::valid_command(0x1234);
        repr.dac[3] = DacWord::valid_command(DAC_ZERO);
        repr.control = StatusWrite(0x0000_0F0F);
        let mut buf = [0xA5u8; 20];
        assert_eq!(repr.emit(&mut buf), Ok(20));
        assert_eq!(read_quadlet(&buf, 0), 0x8900_1234);
        assert_eq!(read_quadlet(&buf, 1), 0x0900_0000);
        assert_eq!(read_quadlet(&buf, 3), 0x8900_8000);
        assert_eq!(read_quadlet(&buf, 4), 0x0000_0F0F);
        let block = WriteBlock::new_checked(&buf[..], REV7).unwrap();
        assert_eq!(block.header(), None);
        assert_eq!(block.board_id(), 9);
        let parsed = WriteBlockRepr::parse(&block).unwrap();
        assert_eq!(parsed.board_id, 9);
        assert_eq!(parsed.dac[0].command(), 0x1234);
        let mut again = [0xA5u8; 20];
        parsed.emit(&mut again).unwrap();
        assert_eq!(again, buf);
        // A DAC naming another board.
        write_quadlet(&mut buf, 2, 0x8A00_0000);
        let block = WriteBlock::new_checked(&buf[..], REV7).unwrap();
        assert!(matches!(
            WriteBlockRepr::parse(&block),
            Err(Error::Malformed { .. })
        ));
    }

    /// Every format and motor count: the block `emit_with_control`
    /// writes is header (Rev 8), the layout's DACs (Rev 4 and 7 with the
    /// board ID) and the given control (not on Rev 4), quadlet by quadlet,
    /// nothing past it; `emit` is the same with the block's own control.
    #[test]
    fn emit_with_control_writes_each_quadlet_in_wire_order() {
        for rev in [FirmwareRev::Rev4, FirmwareRev::Rev7, FirmwareRev::Rev8] {
            for motors in 1..=MAX_AXES as u8 {
                let layout = BoardLayout::new(rev, motors, motors).unwrap();
                let mut repr = WriteBlockRepr::new(layout, 0xB);
                for (i, d) in repr.dac.iter_mut().enumerate() {
                    *d = DacWord::valid_command(0x100 * i as u16 + 7);
                }
                repr.control = StatusWrite(0x0000_0303);
                let control = StatusWrite(0x0000_0F0A);
                // (The quadlets expected and how many.)
                let mut words = [0u32; MAX_AXES + 2];
                let mut n = 0;
                if layout.format() == BlockFormat::Rev8 {
                    words[n] = 0x0B00 | (u32::from(motors) + 2);
                    n += 1;
                }
                for d in repr.dacs() {
                    words[n] = match layout.format() {
                        BlockFormat::Rev8 => d.0,
                        _ => d.with_board_id(0xB).0,
                    };
                    n += 1;
                }
                let own_len = n;
                if layout.format() != BlockFormat::Rev4 {
                    words[n] = control.0;
                    n += 1;
                }
                let own = &words[..own_len];
                let expected = &words[..n];
                let mut buf = [0xA5u8; (MAX_AXES + 3) * 4];
                let len = expected.len() * 4;
                assert_eq!(repr.emit_with_control(control, &mut buf), Ok(len));
                for (q, &w) in expected.iter().enumerate() {
                    assert_eq!(read_quadlet(&buf, q), w, "{rev:?} {motors}: quadlet {q}");
                }
                assert!(buf[len..].iter().all(|&b| b == 0xA5), "{rev:?} {motors}");
                let mut own_buf = [0xA5u8; (MAX_AXES + 3) * 4];
                assert_eq!(repr.emit(&mut own_buf), Ok(len));
                for (q, &w) in own.iter().enumerate() {
                    assert_eq!(
                        read_quadlet(&own_buf, q),
                        w,
                        "{rev:?} {motors}: quadlet {q}"
                    );
                }
                if layout.format() != BlockFormat::Rev4 {
                    assert_eq!(read_quadlet(&own_buf, own.len()), 0x0000_0303);
                }
            }
        }
    }

    #[test]
    fn write_block_errors() {
        let mut buf = [0u8; 24];
        write_quadlet(&mut buf, 0, 0x0000_0305);
        let block = WriteBlock::new_checked(&buf[..], REV8).unwrap();
        assert!(matches!(
            WriteBlockRepr::parse(&block),
            Err(Error::BlockSize {
                expected: 6,
                found: 5,
                ..
            })
        ));
        write_quadlet(&mut buf, 0, 0x0001_0306);
        let block = WriteBlock::new_checked(&buf[..], REV8).unwrap();
        assert!(matches!(
            WriteBlockRepr::parse(&block),
            Err(Error::Malformed { .. })
        ));
        assert!(WriteBlock::new_checked(&buf[..20], REV8).is_err());
        assert!(WriteBlockRepr::new(REV8, 16).emit(&mut buf).is_err());
        assert!(WriteBlockRepr::new(REV8, 1).emit(&mut buf[..20]).is_err());
        let mut rev7 = [0u8; 20];
        let mut view = WriteBlock::new_unchecked(&mut rev7[..], REV7);
        assert!(view.set_header(WriteHeader::from_word(0)).is_err());
        assert!(view.set_dac(4, DacWord(0)).is_err());
    }
}
