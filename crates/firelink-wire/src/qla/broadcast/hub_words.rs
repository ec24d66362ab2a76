//! The hub block's own words (`fpga-board.md` §6.3): the per-board hub header in
//! its Rev 7 and Rev 8 forms, the final timing quadlet, and the rule by which
//! the host checks the sequences the headers carry.

use super::*;

/// A board's header quadlet in hub memory (`fpga-board.md` §6.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HubHeader {
    /// Rev 7 keeps `seq<<16 | time`.
    Rev7 {
        /// The full sequence the board answered.
        seq: u16,
        /// Time of the update.
        time: u16,
    },
    /// Rev 8 rewrites it as `size:8 | seq_low:8 | seq_error:1 | update_time:15`.
    Rev8 {
        /// Quadlets of the entry including this header (block + 1).
        quadlets: u8,
        /// Low byte of the sequence the board answered.
        seq_low: u8,
        /// The board's full sequence did not match the query's.
        seq_error: bool,
        /// Time of the update (15 bits).
        update_time: u16,
    },
}

impl HubHeader {
    /// Decode a hub header quadlet in the given format.
    #[inline]
    pub fn from_word(word: u32, format: BlockFormat) -> HubHeader {
        match format {
            BlockFormat::Rev4 | BlockFormat::Rev7 => HubHeader::Rev7 {
                seq: field::HUB7_SEQ.extract(word) as u16,
                time: field::HUB7_TIME.extract(word) as u16,
            },
            BlockFormat::Rev8 => HubHeader::Rev8 {
                quadlets: field::HUB8_QUADLETS.extract(word) as u8,
                seq_low: field::HUB8_SEQ_LOW.extract(word) as u8,
                seq_error: field::HUB8_SEQ_ERROR.extract(word) == 1,
                update_time: field::HUB8_UPDATE_TIME.extract(word) as u16,
            },
        }
    }

    /// Encode the header quadlet.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a Rev 8 update time above 15 bits.
    pub fn to_word(self) -> Result<u32> {
        match self {
            HubHeader::Rev7 { seq, time } => {
                let w = field::HUB7_SEQ.insert(0, u32::from(seq));
                Ok(field::HUB7_TIME.insert(w, u32::from(time)))
            }
            HubHeader::Rev8 {
                quadlets,
                seq_low,
                seq_error,
                update_time,
            } => {
                let time = field::HUB8_UPDATE_TIME;
                check_max(
                    "hub update time",
                    u64::from(update_time),
                    u64::from(time.max()),
                )?;
                let w = field::HUB8_QUADLETS.insert(0, u32::from(quadlets));
                let w = field::HUB8_SEQ_LOW.insert(w, u32::from(seq_low));
                let w = field::HUB8_SEQ_ERROR.insert(w, u32::from(seq_error));
                Ok(time.insert(w, u32::from(update_time)))
            }
        }
    }

    /// The format of this header.
    pub fn format(self) -> BlockFormat {
        match self {
            HubHeader::Rev7 { .. } => BlockFormat::Rev7,
            HubHeader::Rev8 { .. } => BlockFormat::Rev8,
        }
    }

    /// The hub's rewrite of a received broadcast header (`fpga-board.md`
    /// §6.3): Rev 8 keeps the size and the sequence's low byte, flags a
    /// full-sequence mismatch with `query_seq` and keeps the low 15 bits of
    /// `update_time`; Rev 4 and Rev 7 keep the sequence and store
    /// `update_time`.
    pub fn rewrite(
        broadcast: BroadcastHeader,
        query_seq: u16,
        update_time: u16,
        format: BlockFormat,
    ) -> HubHeader {
        match format {
            BlockFormat::Rev4 | BlockFormat::Rev7 => HubHeader::Rev7 {
                seq: broadcast.seq,
                time: update_time,
            },
            BlockFormat::Rev8 => HubHeader::Rev8 {
                quadlets: broadcast.quadlets as u8,
                seq_low: broadcast.seq as u8,
                seq_error: broadcast.seq != query_seq,
                update_time: update_time & field::HUB8_UPDATE_TIME.max() as u16,
            },
        }
    }
}

/// The timing quadlet after the last board's entry: `read_start:16 | now:16`
/// (`fpga-board.md` §6.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct HubTiming {
    /// When the hub read started.
    pub read_start: u16,
    /// The time now.
    pub now: u16,
}

impl HubTiming {
    /// Decode the timing quadlet.
    pub fn from_word(word: u32) -> HubTiming {
        HubTiming {
            read_start: field::TIMING_READ_START.extract(word) as u16,
            now: field::TIMING_NOW.extract(word) as u16,
        }
    }

    /// Encode the timing quadlet.
    pub fn to_word(self) -> u32 {
        let w = field::TIMING_READ_START.insert(0, u32::from(self.read_start));
        field::TIMING_NOW.insert(w, u32::from(self.now))
    }
}

/// How boards report the query's sequence (`fpga-board.md` §6, last points).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SeqRule {
    /// Rev 7: every board echoes the full 16-bit sequence.
    Rev7Echo,
    /// Rev 8: the hub header keeps the low byte and an error bit set when
    /// the full sequence did not match.
    Rev8LowByte,
    /// Seed 000: the sequence is echoed, and a board that received a
    /// corrupt query answers `0xFFFF` (so the host never queries with it).
    Seed000,
}

impl SeqRule {
    /// The rule of a firmware revision's real boards.
    pub fn for_firmware(firmware: FirmwareRev) -> SeqRule {
        match firmware.block_format() {
            BlockFormat::Rev4 => SeqRule::Seed000,
            BlockFormat::Rev7 => SeqRule::Rev7Echo,
            BlockFormat::Rev8 => SeqRule::Rev8LowByte,
        }
    }

    /// The sequence to query with after `seq`: never 0, and under
    /// [`SeqRule::Seed000`] never [`CORRUPT_QUERY_SEQ`].
    #[inline]
    pub fn next_seq(self, seq: u16) -> u16 {
        let mut next = seq.wrapping_add(1);
        while next == 0 || (self == SeqRule::Seed000 && next == CORRUPT_QUERY_SEQ) {
            next = next.wrapping_add(1);
        }
        next
    }

    /// Check a full 16-bit sequence a board answered (a status broadcast
    /// header or a Rev 7 hub header) against the query's.
    ///
    /// # Errors
    /// [`Error::CorruptQuery`] (seed 000, `0xFFFF`), else
    /// [`Error::Sequence`] on a mismatch.
    #[inline]
    pub fn check_seq(self, query_seq: u16, received: u16, board: u8) -> Result<()> {
        if self == SeqRule::Seed000 && received == CORRUPT_QUERY_SEQ {
            return Err(Error::CorruptQuery { board });
        }
        if received != query_seq {
            return Err(Error::Sequence {
                board,
                expected: query_seq,
                received,
            });
        }
        Ok(())
    }

    /// Check a hub header against the query's sequence. A Rev 8 header
    /// carries only the low byte and the error bit, so those are what is
    /// checked whatever the rule (a seed-000 `0xFFFF` shows as the error
    /// bit); a Rev 7 header carries the full sequence: see
    /// [`check_seq`](Self::check_seq).
    ///
    /// # Errors
    /// [`Error::SequenceFlagged`], [`Error::CorruptQuery`] or
    /// [`Error::Sequence`] (with the low bytes for a Rev 8 header).
    #[inline]
    pub fn check(self, query_seq: u16, header: HubHeader, board: u8) -> Result<()> {
        match header {
            HubHeader::Rev7 { seq, .. } => self.check_seq(query_seq, seq, board),
            HubHeader::Rev8 {
                seq_low, seq_error, ..
            } => {
                if seq_error {
                    return Err(Error::SequenceFlagged { board, seq_low });
                }
                let expected = query_seq & 0xFF;
                if u16::from(seq_low) != expected {
                    return Err(Error::Sequence {
                        board,
                        expected,
                        received: u16::from(seq_low),
                    });
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hub_header_words() {
        let h = HubHeader::Rev8 {
            quadlets: 33,
            seq_low: 0x34,
            seq_error: true,
            update_time: 0x1234,
        };
        assert_eq!(h.to_word(), Ok(0x2134_9234));
        assert_eq!(HubHeader::from_word(0x2134_9234, BlockFormat::Rev8), h);
        let h7 = HubHeader::Rev7 {
            seq: 0xBEEF,
            time: 0x1234,
        };
        assert_eq!(h7.to_word(), Ok(0xBEEF_1234));
        assert_eq!(HubHeader::from_word(0xBEEF_1234, BlockFormat::Rev7), h7);
        assert!(
            HubHeader::Rev8 {
                quadlets: 1,
                seq_low: 0,
                seq_error: false,
                update_time: 0x8000
            }
            .to_word()
            .is_err()
        );
        let b = BroadcastHeader {
            seq: 0x1234,
            quadlets: 33,
        };
        assert_eq!(b.to_word(), 0x1234_0021);
        assert_eq!(
            HubHeader::rewrite(b, 0x1234, 0xFFFF, BlockFormat::Rev8),
            HubHeader::Rev8 {
                quadlets: 33,
                seq_low: 0x34,
                seq_error: false,
                update_time: 0x7FFF
            }
        );
        assert_eq!(
            HubHeader::rewrite(b, 0x1334, 5, BlockFormat::Rev8),
            HubHeader::Rev8 {
                quadlets: 33,
                seq_low: 0x34,
                seq_error: true,
                update_time: 5
            }
        );
        assert_eq!(
            HubHeader::rewrite(b, 0x1334, 5, BlockFormat::Rev7),
            HubHeader::Rev7 {
                seq: 0x1234,
                time: 5
            }
        );
    }

    #[test]
    fn sequence_rules() {
        let r7 = |seq| HubHeader::Rev7 { seq, time: 0 };
        let r8 = |seq_low, seq_error| HubHeader::Rev8 {
            quadlets: 33,
            seq_low,
            seq_error,
            update_time: 0,
        };
        assert_eq!(SeqRule::Rev7Echo.check(0x1234, r7(0x1234), 2), Ok(()));
        assert_eq!(
            SeqRule::Rev7Echo.check(0x1234, r7(0x1233), 2),
            Err(Error::Sequence {
                board: 2,
                expected: 0x1234,
                received: 0x1233
            })
        );
        assert_eq!(
            SeqRule::Rev8LowByte.check(0x1234, r8(0x34, false), 1),
            Ok(())
        );
        assert_eq!(
            SeqRule::Rev8LowByte.check(0x1234, r8(0x34, true), 1),
            Err(Error::SequenceFlagged {
                board: 1,
                seq_low: 0x34
            })
        );
        assert_eq!(
            SeqRule::Rev8LowByte.check(0x1234, r8(0x33, false), 1),
            Err(Error::Sequence {
                board: 1,
                expected: 0x34,
                received: 0x33
            })
        );
        assert_eq!(
            SeqRule::Seed000.check(0x1234, r7(0xFFFF), 4),
            Err(Error::CorruptQuery { board: 4 })
        );
        assert_eq!(SeqRule::Seed000.check(0x1234, r7(0x1234), 4), Ok(()));
        assert!(matches!(
            SeqRule::Seed000.check(0x1234, r7(0x1235), 4),
            Err(Error::Sequence { .. })
        ));
        // Rev 7 echo does not treat 0xFFFF specially.
        assert!(matches!(
            SeqRule::Rev7Echo.check(0x1234, r7(0xFFFF), 4),
            Err(Error::Sequence { .. })
        ));
        assert_eq!(
            SeqRule::for_firmware(FirmwareRev::Rev8),
            SeqRule::Rev8LowByte
        );
        assert_eq!(SeqRule::for_firmware(FirmwareRev::Rev7), SeqRule::Rev7Echo);
    }
}
