//! The concatenated command block (`fpga-board.md` §6.5): the host writes one
//! real-time write block per board in a single broadcast; each board finds its
//! own slice by ID.

use super::*;

/// Quadlets of the command block of these boards: the sum of their write
/// blocks (`fpga-board.md` §6.5).
pub fn command_block_quadlets<I: IntoIterator<Item = BoardLayout>>(layouts: I) -> usize {
    layouts
        .into_iter()
        .map(BoardLayout::write_block_quadlets)
        .sum()
}

/// Builds the command block: each board's write block concatenated in
/// strictly ascending board order into a caller-provided buffer
/// (`fpga-board.md` §6.5).
#[derive(Debug)]
pub struct CommandBlockWriter<'a> {
    buf: &'a mut [u8],
    len: usize,
    last: Option<u8>,
}

impl<'a> CommandBlockWriter<'a> {
    /// Write into `buf` from its start.
    pub fn new(buf: &'a mut [u8]) -> CommandBlockWriter<'a> {
        CommandBlockWriter {
            buf,
            len: 0,
            last: None,
        }
    }

    /// Bytes written so far.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is written yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Append the next board's write block.
    ///
    /// # Errors
    /// [`Error::BoardOrder`] unless the board ID is above the previous one;
    /// [`Error::BufferTooSmall`]; the errors of [`WriteBlockRepr::emit`].
    #[inline]
    pub fn push(&mut self, block: &WriteBlockRepr) -> Result<()> {
        self.push_with_control(block, block.control)
    }

    /// [`push`](Self::push) with `control` as the block's control quadlet
    /// ([`WriteBlockRepr::emit_with_control`]): the block goes straight
    /// into the buffer, without a copy of it with the control put in.
    /// (Always inlined: the host's cycle calls it for every board, and
    /// `#[inline]` alone left it a call.)
    ///
    /// # Errors
    /// As [`push`](Self::push).
    #[inline(always)]
    pub fn push_with_control(
        &mut self,
        block: &WriteBlockRepr,
        control: StatusWrite,
    ) -> Result<()> {
        if let Some(previous) = self.last {
            if block.board_id <= previous {
                return Err(Error::BoardOrder {
                    previous,
                    next: block.board_id,
                });
            }
        }
        let needed = self.len + block.buffer_len();
        let available = self.buf.len();
        let Some(out) = self.buf.get_mut(self.len..needed) else {
            return Err(Error::BufferTooSmall {
                what: "command block",
                needed,
                available,
            });
        };
        self.len += block.emit_with_control(control, out)?;
        self.last = Some(block.board_id);
        Ok(())
    }
}

/// Emit a whole command block from the boards' write blocks, in ascending
/// board order; returns bytes written.
///
/// # Errors
/// As [`CommandBlockWriter::push`].
pub fn emit_command_block(buf: &mut [u8], blocks: &[WriteBlockRepr]) -> Result<usize> {
    let mut writer = CommandBlockWriter::new(buf);
    for block in blocks {
        writer.push(block)?;
    }
    Ok(writer.len())
}

/// One board's slice of a command block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CommandSlice<'a> {
    /// The board the slice names.
    pub board_id: u8,
    /// Its bytes (a whole write block).
    pub bytes: &'a [u8],
}

/// Iterator over the slices of a command block; yields an error once and
/// then stops when the block is malformed.
#[derive(Debug, Clone)]
pub struct CommandSlices<'a> {
    payload: &'a [u8],
    pos: usize,
    layout: BoardLayout,
    done: bool,
}

/// Walk a command block (`fpga-board.md` §6.5). Rev 8 follows the headers:
/// the low byte counts the slice's quadlets including the header, bits 15:8
/// name the board. Rev 4 and Rev 7 cut fixed slices of `layout`'s write
/// block (5 quadlets for a Rev 7 QLA1, 4 on Rev 4), the board ID in bits
/// 27:24 of the first DAC quadlet. Only `layout`'s format (and, before
/// Rev 8, its size) is used.
pub fn command_slices(payload: &[u8], layout: BoardLayout) -> CommandSlices<'_> {
    CommandSlices {
        payload,
        pos: 0,
        layout,
        done: false,
    }
}

impl<'a> CommandSlices<'a> {
    fn step(&mut self) -> Result<Option<CommandSlice<'a>>> {
        let total = self.payload.len();
        if total % 4 != 0 {
            return Err(Error::NotQuadletAligned {
                what: "command block",
                len: total,
            });
        }
        let Some(rest) = self.payload.get(self.pos..).filter(|r| !r.is_empty()) else {
            return Ok(None);
        };
        let first = read_quadlet(rest, 0);
        let (board_id, quadlets) = match self.layout.format() {
            BlockFormat::Rev8 => {
                let header = WriteHeader::from_word(first);
                if header.quadlets == 0 {
                    return Err(Error::Malformed {
                        what: "command block header with length 0",
                        value: first,
                    });
                }
                (header.board_id, usize::from(header.quadlets))
            }
            BlockFormat::Rev4 | BlockFormat::Rev7 => (
                DacWord(first).board_id(),
                self.layout.write_block_quadlets(),
            ),
        };
        let Some(bytes) = rest.get(..quadlets * 4) else {
            return Err(Error::LengthExceedsBuffer {
                what: "command block slice",
                declared: quadlets * 4,
                available: rest.len(),
            });
        };
        self.pos += bytes.len();
        Ok(Some(CommandSlice { board_id, bytes }))
    }
}

impl<'a> Iterator for CommandSlices<'a> {
    type Item = Result<CommandSlice<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = self.step().transpose();
        if !matches!(item, Some(Ok(_))) {
            self.done = true;
        }
        item
    }
}

/// Find board `board_id`'s write block in a command block; `Ok(None)` when
/// no slice names it (the board got no command this cycle).
///
/// # Errors
/// A malformed walk before the board's slice is reached (see
/// [`command_slices`]); [`Error::BlockSize`] when the slice naming the board
/// is not the size of `layout`'s write block.
pub fn find_command_block(
    payload: &[u8],
    board_id: u8,
    layout: BoardLayout,
) -> Result<Option<WriteBlock<&[u8]>>> {
    for slice in command_slices(payload, layout) {
        let slice = slice?;
        if slice.board_id == board_id {
            return WriteBlock::new_checked(slice.bytes, layout).map(Some);
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qla::registers::DAC_ZERO;

    const REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);

    fn write_blocks(layout: BoardLayout, ids: &[u8]) -> ([u8; 1024], usize) {
        let mut buf = [0xA5u8; 1024];
        let mut writer = CommandBlockWriter::new(&mut buf);
        for &id in ids {
            let mut w = WriteBlockRepr::new(layout, id);
            w.dac[0] = DacWord::valid_command(DAC_ZERO + u16::from(id));
            writer.push(&w).unwrap();
        }
        let len = writer.len();
        (buf, len)
    }

    #[test]
    fn command_block_slicing() {
        for layout in [REV8, REV7] {
            let (buf, len) = write_blocks(layout, &[0, 2, 3, 7]);
            assert_eq!(len, 4 * layout.write_block_len());
            let payload = &buf[..len];
            for id in [0u8, 2, 3, 7] {
                let block = find_command_block(payload, id, layout).unwrap().unwrap();
                assert_eq!(block.board_id(), id);
                assert_eq!(block.dac(0).unwrap().command(), DAC_ZERO + u16::from(id));
            }
            assert_eq!(find_command_block(payload, 1, layout), Ok(None));
            assert_eq!(command_slices(payload, layout).count(), 4);
        }
    }

    #[test]
    fn command_block_order_and_space() {
        let mut buf = [0u8; 64];
        let mut writer = CommandBlockWriter::new(&mut buf);
        assert!(writer.is_empty());
        writer.push(&WriteBlockRepr::new(REV8, 3)).unwrap();
        assert_eq!(
            writer.push(&WriteBlockRepr::new(REV8, 3)),
            Err(Error::BoardOrder {
                previous: 3,
                next: 3
            })
        );
        assert!(writer.push(&WriteBlockRepr::new(REV8, 1)).is_err());
        writer.push(&WriteBlockRepr::new(REV8, 4)).unwrap();
        assert!(matches!(
            writer.push(&WriteBlockRepr::new(REV8, 5)),
            Err(Error::BufferTooSmall { needed: 72, .. })
        ));
        assert_eq!(writer.len(), 48);
        assert_eq!(command_block_quadlets([REV8, REV7]), 11);
    }

    #[test]
    fn malformed_command_blocks_terminate() {
        // A zero-length header.
        let zero = [0u8; 24];
        let mut walk = command_slices(&zero, REV8);
        assert!(matches!(walk.next(), Some(Err(Error::Malformed { .. }))));
        assert!(walk.next().is_none());
        assert!(find_command_block(&zero, 0, REV8).is_err());
        // A header running past the end.
        let mut long = [0u8; 24];
        write_quadlet(&mut long, 0, 0x0000_0107);
        assert!(matches!(
            find_command_block(&long, 1, REV8),
            Err(Error::LengthExceedsBuffer { declared: 28, .. })
        ));
        // The board's slice of the wrong size.
        write_quadlet(&mut long, 0, 0x0000_0105);
        assert!(matches!(
            find_command_block(&long, 1, REV8),
            Err(Error::BlockSize { .. })
        ));
        // Not whole quadlets.
        assert!(matches!(
            find_command_block(&long[..23], 1, REV8),
            Err(Error::NotQuadletAligned { .. })
        ));
        // Rev 7: a partial trailing slice.
        let (buf, len) = write_blocks(REV7, &[1, 2]);
        assert!(matches!(
            find_command_block(&buf[..len - 4], 2, REV7),
            Err(Error::LengthExceedsBuffer { .. })
        ));
        assert_eq!(find_command_block(&[], 0, REV8), Ok(None));
    }
}
