//! The hub block as a whole (`fpga-board.md` §6.3, §6.4): the boards expected on
//! the bus, its size, the host's checked walk over its entries, and the packer a
//! board uses to fill its hub memory from the broadcasts it hears.

use super::*;

/// A board expected on the bus: its ID and layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BoardSlot {
    /// Board ID, 0..=15.
    pub id: u8,
    /// Its real-time block layout.
    pub layout: BoardLayout,
}

/// Quadlets of the hub block of these boards: the sum of (read block + 1)
/// plus the timing quadlet (`fpga-board.md` §6.4: two QLA1 Rev 8 boards 67,
/// Rev 7 `29 * boards + 1`). Rev 4 hubs have no timing quadlet: boards
/// that are all Rev 4 give the sum alone (`13 * boards` for QLA1); no
/// boards at all give the timing quadlet alone.
#[inline]
pub fn hub_block_quadlets<I: IntoIterator<Item = BoardLayout>>(layouts: I) -> usize {
    let (mut sum, mut all_rev4) = (0, true);
    for layout in layouts {
        sum += layout.broadcast_quadlets();
        all_rev4 &= !has_hub_timing(layout.format());
    }
    sum + usize::from(sum == 0 || !all_rev4)
}

/// Whether a hub of this format appends the timing quadlet after the last
/// entry (Rev 7 and later).
#[inline]
pub fn has_hub_timing(format: BlockFormat) -> bool {
    format != BlockFormat::Rev4
}

/// A checked view of the hub block read from `0x1000`, walked with the
/// boards expected in arrival order (ascending board ID for the Rev 7+
/// chain), `fpga-board.md` §6.3-6.4. Each entry's header is read in the
/// format of that board's layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HubBlock<'b, T: AsRef<[u8]>> {
    buffer: T,
    boards: &'b [BoardSlot],
}

impl<'b, T: AsRef<[u8]>> HubBlock<'b, T> {
    /// Wrap a buffer without checking it.
    pub const fn new_unchecked(buffer: T, boards: &'b [BoardSlot]) -> HubBlock<'b, T> {
        HubBlock { buffer, boards }
    }

    /// Wrap a buffer after checking its length.
    ///
    /// # Errors
    /// See [`check_len`](Self::check_len).
    pub fn new_checked(buffer: T, boards: &'b [BoardSlot]) -> Result<HubBlock<'b, T>> {
        let b = Self::new_unchecked(buffer, boards);
        b.check_len()?;
        Ok(b)
    }

    /// [`new_checked`](Self::new_checked) for boards whose
    /// [`hub_block_quadlets`] the caller worked out once: `quadlets` must
    /// be that of `boards`' layouts. The same checks in the same order,
    /// without the walk over the layouts (the host's cycle checks a block
    /// of the same boards every cycle).
    ///
    /// # Errors
    /// See [`check_len`](Self::check_len).
    #[inline]
    pub fn new_checked_quadlets(
        buffer: T,
        boards: &'b [BoardSlot],
        quadlets: usize,
    ) -> Result<HubBlock<'b, T>> {
        debug_assert_eq!(
            quadlets,
            hub_block_quadlets(boards.iter().map(|b| b.layout))
        );
        let b = Self::new_unchecked(buffer, boards);
        b.check_len_of(quadlets)?;
        Ok(b)
    }

    /// Check the buffer is exactly the hub block of the expected boards.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for more than 16 boards or a block larger
    /// than the 512-quadlet hub memory; [`Error::NotQuadletAligned`] or
    /// [`Error::BlockSize`] for a buffer of the wrong size.
    pub fn check_len(&self) -> Result<()> {
        self.check_len_of(hub_block_quadlets(self.boards.iter().map(|b| b.layout)))
    }

    /// [`check_len`](Self::check_len) with the boards' hub block size
    /// `quadlets` given.
    #[inline]
    fn check_len_of(&self, quadlets: usize) -> Result<()> {
        check_max("hub boards", self.boards.len() as u64, MAX_BOARDS as u64)?;
        check_max(
            "hub block quadlets",
            quadlets as u64,
            HUB_MEMORY_QUADLETS as u64,
        )?;
        check_exact("hub block", self.buffer.as_ref().len(), quadlets)
    }

    /// The expected boards.
    pub fn boards(&self) -> &'b [BoardSlot] {
        self.boards
    }

    /// The underlying bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// The entries, one per expected board.
    #[inline]
    pub fn entries(&self) -> HubEntries<'_> {
        HubEntries {
            bytes: self.buffer.as_ref(),
            boards: self.boards,
            pos: 0,
        }
    }

    /// The entry of the `index`-th expected board.
    pub fn entry(&self, index: usize) -> Option<HubEntry<'_>> {
        self.entries().nth(index)
    }

    /// The entry of board `board_id`.
    pub fn entry_of(&self, board_id: u8) -> Option<HubEntry<'_>> {
        self.entries().find(|e| e.slot.id == board_id)
    }

    /// The timing quadlet after the last entry (all zero for Rev 4 boards,
    /// whose hub has none).
    pub fn timing(&self) -> HubTiming {
        self.timing_at(Self::timing_quadlet(self.boards))
    }

    /// Where the timing quadlet of a hub block of `boards` is (`None`: Rev
    /// 4 boards, whose hub has none): what [`timing`](Self::timing) reads,
    /// for a caller that works it out once for many blocks of the same
    /// boards ([`timing_at`](Self::timing_at)).
    pub fn timing_quadlet(boards: &[BoardSlot]) -> Option<usize> {
        let layouts = boards.iter().map(|b| b.layout);
        if !boards.is_empty() && !layouts.clone().any(|l| has_hub_timing(l.format())) {
            return None;
        }
        Some(hub_block_quadlets(layouts).saturating_sub(1))
    }

    /// The timing quadlet at `quadlet`, as
    /// [`timing_quadlet`](Self::timing_quadlet) of this block's boards
    /// gives it (all zero for `None`).
    #[inline]
    pub fn timing_at(&self, quadlet: Option<usize>) -> HubTiming {
        match quadlet {
            Some(q) => HubTiming::from_word(read_quadlet(self.buffer.as_ref(), q)),
            None => HubTiming::default(),
        }
    }

    /// Validate every entry ([`HubEntry::validate`]); the first failure is
    /// returned.
    ///
    /// # Errors
    /// As [`HubEntry::validate`].
    pub fn check_sequences(&self, rule: SeqRule, query_seq: u16) -> Result<()> {
        self.entries().try_for_each(|e| e.validate(rule, query_seq))
    }
}

/// One board's entry in the hub block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HubEntry<'a> {
    /// The board expected here.
    pub slot: BoardSlot,
    /// The hub header.
    pub header: HubHeader,
    /// The board's real-time read block.
    pub block: ReadBlock<&'a [u8]>,
}

impl HubEntry<'_> {
    /// Check the entry is this cycle's answer: a Rev 8 header's size must
    /// be the layout's, and the sequence must pass `rule`.
    ///
    /// # Errors
    /// [`Error::BlockSize`] for a Rev 8 size mismatch; the errors of
    /// [`SeqRule::check`].
    #[inline]
    pub fn validate(&self, rule: SeqRule, query_seq: u16) -> Result<()> {
        if let HubHeader::Rev8 { quadlets, .. } = self.header {
            let expected = self.slot.layout.broadcast_quadlets();
            if usize::from(quadlets) != expected {
                return Err(Error::BlockSize {
                    what: "hub entry (header size)",
                    expected,
                    found: usize::from(quadlets),
                });
            }
        }
        rule.check(query_seq, self.header, self.slot.id)
    }
}

/// Iterator over the entries of a [`HubBlock`].
#[derive(Debug, Clone)]
pub struct HubEntries<'a> {
    bytes: &'a [u8],
    boards: &'a [BoardSlot],
    pos: usize,
}

impl<'a> Iterator for HubEntries<'a> {
    type Item = HubEntry<'a>;

    #[inline]
    fn next(&mut self) -> Option<HubEntry<'a>> {
        let (&slot, rest) = self.boards.split_first()?;
        let len = slot.layout.broadcast_quadlets() * 4;
        let bytes = self.bytes.get(self.pos..self.pos.checked_add(len)?)?;
        self.boards = rest;
        self.pos += len;
        let header = HubHeader::from_word(read_quadlet(bytes, 0), slot.layout.format());
        Some(HubEntry {
            slot,
            header,
            block: ReadBlock::new_unchecked(bytes.get(4..).unwrap_or(&[]), slot.layout),
        })
    }
}

/// Packs the hub memory as broadcasts arrive (the emulated boards' side of
/// `fpga-board.md` §6.3): entries in arrival order, then the timing quadlet.
#[derive(Debug)]
pub struct HubPacker<'a> {
    buf: &'a mut [u8],
    quadlets: usize,
}

impl<'a> HubPacker<'a> {
    /// Pack into `buf` from its start (normally 2048 bytes of hub memory).
    pub fn new(buf: &'a mut [u8]) -> HubPacker<'a> {
        HubPacker { buf, quadlets: 0 }
    }

    /// Quadlets written so far (what the `0x1802` register reports).
    pub fn quadlets(&self) -> usize {
        self.quadlets
    }

    /// Start a new cycle: the next entry goes to the start of the memory.
    pub fn reset(&mut self) {
        self.quadlets = 0;
    }

    #[inline]
    fn reserve(&mut self, what: &'static str, quadlets: usize) -> Result<&mut [u8]> {
        let end = self.quadlets + quadlets;
        check_max("hub block quadlets", end as u64, HUB_MEMORY_QUADLETS as u64)?;
        let available = self.buf.len();
        let start = self.quadlets * 4;
        let Some(out) = self.buf.get_mut(start..end * 4) else {
            return Err(Error::BufferTooSmall {
                what,
                needed: end * 4,
                available,
            });
        };
        Ok(out)
    }

    /// Append one entry: `header` then the read block bytes.
    ///
    /// # Errors
    /// [`Error::NotQuadletAligned`] for a block of partial quadlets;
    /// [`Error::BlockSize`] when a Rev 8 header's size is not block + 1;
    /// [`Error::FieldRange`] beyond 512 quadlets or for a bad header field;
    /// [`Error::BufferTooSmall`].
    #[inline]
    pub fn push(&mut self, header: HubHeader, block: &[u8]) -> Result<()> {
        if block.len() % 4 != 0 {
            return Err(Error::NotQuadletAligned {
                what: "hub entry block",
                len: block.len(),
            });
        }
        let quadlets = block.len() / 4 + 1;
        if let HubHeader::Rev8 { quadlets: size, .. } = header {
            if usize::from(size) != quadlets {
                return Err(Error::BlockSize {
                    what: "hub entry (header size)",
                    expected: quadlets,
                    found: usize::from(size),
                });
            }
        }
        let word = header.to_word()?;
        let out = self.reserve("hub entry", quadlets)?;
        write_quadlet(out, 0, word);
        if let Some(dst) = out.get_mut(4..) {
            dst.copy_from_slice(block);
        }
        self.quadlets += quadlets;
        Ok(())
    }

    /// Store a received status broadcast payload with its header rewritten
    /// by [`HubHeader::rewrite`]; returns the header stored.
    ///
    /// # Errors
    /// [`Error::Truncated`] without a header; [`Error::NotQuadletAligned`];
    /// [`Error::BlockSize`] when the header's size is not the payload's
    /// (the packet is then not stored); the errors of
    /// [`push`](Self::push).
    ///
    /// The emulated board's hub keeps its own copy of this store, always
    /// inlined into its delivery path, and is tested against this one
    /// (`firelink_board::qla::hub`).
    #[inline]
    pub fn store_broadcast(
        &mut self,
        payload: &[u8],
        query_seq: u16,
        update_time: u16,
        format: BlockFormat,
    ) -> Result<HubHeader> {
        let (Some(head), Some(block)) = (payload.get(..4), payload.get(4..)) else {
            return Err(Error::Truncated {
                what: "status broadcast header",
                needed: 4,
                available: payload.len(),
            });
        };
        if payload.len() % 4 != 0 {
            return Err(Error::NotQuadletAligned {
                what: "status broadcast",
                len: payload.len(),
            });
        }
        let broadcast = BroadcastHeader::from_word(read_quadlet(head, 0));
        if usize::from(broadcast.quadlets) * 4 != payload.len() {
            return Err(Error::BlockSize {
                what: "status broadcast (header size)",
                expected: payload.len() / 4,
                found: usize::from(broadcast.quadlets),
            });
        }
        let header = HubHeader::rewrite(broadcast, query_seq, update_time, format);
        self.push(header, block)?;
        Ok(header)
    }

    /// Append the timing quadlet; returns the bytes of the whole hub block.
    ///
    /// # Errors
    /// [`Error::FieldRange`] beyond 512 quadlets; [`Error::BufferTooSmall`].
    pub fn finish(&mut self, timing: HubTiming) -> Result<usize> {
        let out = self.reserve("hub timing quadlet", 1)?;
        write_quadlet(out, 0, timing.to_word());
        self.quadlets += 1;
        Ok(self.quadlets * 4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qla::registers::StatusRead;

    const REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);

    #[test]
    fn hub_sizes() {
        assert_eq!(hub_block_quadlets([REV8; 2]), 67);
        assert_eq!(hub_block_quadlets([REV7; 3]), 29 * 3 + 1);
        assert_eq!(hub_block_quadlets([]), 1);
        // Rev 4 (seed 000's era): no timing quadlet after the entries.
        let rev4 = BoardLayout::qla1(FirmwareRev::Rev4);
        assert_eq!(hub_block_quadlets([rev4; 8]), 13 * 8);
        assert_eq!(SeqRule::for_firmware(FirmwareRev::Rev4), SeqRule::Seed000);
        assert_eq!(
            hub_block_quadlets([BoardLayout::dqla(FirmwareRev::Rev8)]),
            62
        );
    }

    #[test]
    fn hub_packer_limits() {
        let mut mem = [0u8; 2048];
        let mut packer = HubPacker::new(&mut mem);
        let block = [0u8; 128];
        for _ in 0..15 {
            packer
                .push(HubHeader::Rev7 { seq: 1, time: 0 }, &block)
                .unwrap();
        }
        assert_eq!(packer.quadlets(), 15 * 33);
        // The 16th QLA1 Rev 8 board no longer fits in 512 quadlets.
        assert!(matches!(
            packer.push(HubHeader::Rev7 { seq: 1, time: 0 }, &block),
            Err(Error::FieldRange { max: 512, .. })
        ));
        assert!(matches!(
            packer.push(HubHeader::Rev7 { seq: 1, time: 0 }, &block[..3]),
            Err(Error::NotQuadletAligned { .. })
        ));
        assert_eq!(packer.finish(HubTiming::default()), Ok(496 * 4));
        packer.reset();
        assert_eq!(packer.quadlets(), 0);
        let bad = HubHeader::Rev8 {
            quadlets: 32,
            seq_low: 1,
            seq_error: false,
            update_time: 0,
        };
        assert!(matches!(
            packer.push(bad, &block),
            Err(Error::BlockSize { .. })
        ));
        let mut small = [0u8; 64];
        let mut packer = HubPacker::new(&mut small);
        assert!(matches!(
            packer.push(HubHeader::Rev7 { seq: 1, time: 0 }, &block),
            Err(Error::BufferTooSmall { .. })
        ));
        assert!(matches!(
            packer.store_broadcast(&[0, 0], 1, 0, BlockFormat::Rev8),
            Err(Error::Truncated { .. })
        ));
        // Header says 2 quadlets, payload has 3.
        let payload = [0, 1, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0];
        assert!(matches!(
            packer.store_broadcast(&payload, 1, 0, BlockFormat::Rev8),
            Err(Error::BlockSize { .. })
        ));
    }

    #[test]
    fn hub_block_walk_and_validate() {
        let boards = [
            BoardSlot {
                id: 1,
                layout: REV8,
            },
            BoardSlot {
                id: 4,
                layout: BoardLayout::dqla(FirmwareRev::Rev8),
            },
        ];
        let mut mem = [0xA5u8; 2048];
        let mut packer = HubPacker::new(&mut mem);
        for (i, slot) in boards.iter().enumerate() {
            let mut block = ReadBlockRepr::new(slot.layout);
            block.status = StatusRead::default().with_board_id(slot.id);
            let seq = if i == 0 { 0x0102 } else { 0x0202 };
            let mut pkt = [0u8; 256];
            let n = StatusBroadcastRepr { seq, block }.emit(&mut pkt).unwrap();
            packer
                .store_broadcast(&pkt[..n], 0x0102, 10 + i as u16, BlockFormat::Rev8)
                .unwrap();
        }
        let len = packer
            .finish(HubTiming {
                read_start: 7,
                now: 9,
            })
            .unwrap();
        assert_eq!(len, (33 + 61 + 1) * 4);
        let hub = HubBlock::new_checked(&mem[..len], &boards).unwrap();
        assert_eq!(
            hub.timing(),
            HubTiming {
                read_start: 7,
                now: 9
            }
        );
        let e = hub.entry_of(4).unwrap();
        assert_eq!(e.block.status().board_id(), 4);
        assert_eq!(
            e.header,
            HubHeader::Rev8 {
                quadlets: 61,
                seq_low: 0x02,
                seq_error: true,
                update_time: 11
            }
        );
        assert_eq!(
            hub.entry(0).unwrap().validate(SeqRule::Rev8LowByte, 0x0102),
            Ok(())
        );
        assert_eq!(
            hub.check_sequences(SeqRule::Rev8LowByte, 0x0102),
            Err(Error::SequenceFlagged {
                board: 4,
                seq_low: 2
            })
        );
        assert!(hub.entry(2).is_none());
        assert!(HubBlock::new_checked(&mem[..len - 4], &boards).is_err());
        // With the size worked out once: the same answer for every length
        // and board list, errors included.
        let of = |b: &[BoardSlot]| hub_block_quadlets(b.iter().map(|s| s.layout));
        let seventeen = [BoardSlot {
            id: 0,
            layout: REV8,
        }; 17];
        let lists: [&[BoardSlot]; 4] = [&boards, &boards[..1], &[], &seventeen];
        for list in lists {
            for n in 0..mem.len().min(len + 9) {
                assert_eq!(
                    HubBlock::new_checked_quadlets(&mem[..n], list, of(list)),
                    HubBlock::new_checked(&mem[..n], list),
                    "{} boards, {n} bytes",
                    list.len()
                );
            }
        }
        let too_many = [BoardSlot {
            id: 0,
            layout: REV8,
        }; 17];
        assert!(matches!(
            HubBlock::new_checked(&mem[..], &too_many),
            Err(Error::FieldRange { .. })
        ));
        // An unchecked view over too few bytes walks only what is there.
        let short = HubBlock::new_unchecked(&mem[..40], &boards);
        assert_eq!(short.entries().count(), 0);
    }
}
