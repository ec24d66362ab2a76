//! The query (`fpga-board.md` §6.1): the word the host writes to `0x1800` to
//! start a cycle (sequence number and board mask), the reserved sequence values,
//! and where each board's status broadcast lands.

use super::*;

/// The broadcast query written to `0x1800`: `seq<<16 | board_mask`
/// (`fpga-board.md` §6.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Query {
    /// Sequence number, 1..=65535 (never 0).
    pub seq: u16,
    /// Boards in use: bit i = board i.
    pub board_mask: u16,
}

fn check_seq(seq: u16) -> Result<()> {
    if seq == 0 {
        Err(Error::InvalidValue {
            what: "broadcast query sequence (must be 1..=65535)",
            value: 0,
        })
    } else {
        Ok(())
    }
}

impl Query {
    /// Decode a query word.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for sequence 0.
    pub fn parse(word: u32) -> Result<Query> {
        let query = Query {
            seq: field::QUERY_SEQ.extract(word) as u16,
            board_mask: field::QUERY_MASK.extract(word) as u16,
        };
        check_seq(query.seq)?;
        Ok(query)
    }

    /// Encode as the query word.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for sequence 0.
    pub fn to_word(self) -> Result<u32> {
        check_seq(self.seq)?;
        let w = field::QUERY_SEQ.insert(0, u32::from(self.seq));
        Ok(field::QUERY_MASK.insert(w, u32::from(self.board_mask)))
    }

    /// Whether board `board_id` is selected.
    pub fn selects(self, board_id: u8) -> bool {
        1u16.checked_shl(u32::from(board_id))
            .is_some_and(|bit| self.board_mask & bit != 0)
    }

    /// The selected board IDs, ascending.
    pub fn boards(self) -> impl Iterator<Item = u8> {
        (0..MAX_BOARDS as u8).filter(move |&id| self.selects(id))
    }
}

/// Destination offset of board `board_id`'s status broadcast: Rev 4-7 add
/// `0x20 * board_id` to `0xFFFF_FF00_1000` (`fpga-board.md` §6.2). The
/// board-specific part does not decide where the hub stores the packet:
/// hub memory is packed in arrival order (§6.3).
///
/// # Errors
/// [`Error::FieldRange`] for a board ID above 15.
pub fn status_broadcast_offset(firmware: FirmwareRev, board_id: u8) -> Result<u64> {
    check_board_id(board_id)?;
    Ok(if (4..=7).contains(&firmware.number()) {
        STATUS_BROADCAST_OFFSET + STATUS_BROADCAST_BOARD_STRIDE * u64::from(board_id)
    } else {
        STATUS_BROADCAST_OFFSET
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_words() {
        let q = Query {
            seq: 0x1234,
            board_mask: 0b1001,
        };
        assert_eq!(q.to_word(), Ok(0x1234_0009));
        assert_eq!(Query::parse(0x1234_0009), Ok(q));
        assert!(Query::parse(0x0000_0009).is_err());
        assert!(
            Query {
                seq: 0,
                board_mask: 1
            }
            .to_word()
            .is_err()
        );
        assert!(q.selects(0) && q.selects(3) && !q.selects(1) && !q.selects(200));
        let mut boards = q.boards();
        assert_eq!(
            (boards.next(), boards.next(), boards.next()),
            (Some(0), Some(3), None)
        );
    }

    #[test]
    fn next_sequence_skips_reserved_values() {
        assert_eq!(SeqRule::Rev8LowByte.next_seq(1), 2);
        assert_eq!(SeqRule::Rev8LowByte.next_seq(0xFFFF), 1);
        assert_eq!(SeqRule::Rev7Echo.next_seq(0xFFFE), 0xFFFF);
        assert_eq!(SeqRule::Seed000.next_seq(0xFFFE), 1);
    }

    #[test]
    fn broadcast_offsets() {
        assert_eq!(
            status_broadcast_offset(FirmwareRev::Rev8, 5),
            Ok(0xFFFF_FF00_1000)
        );
        assert_eq!(
            status_broadcast_offset(FirmwareRev::Rev7, 5),
            Ok(0xFFFF_FF00_10A0)
        );
        assert_eq!(
            status_broadcast_offset(FirmwareRev::from(4), 1),
            Ok(0xFFFF_FF00_1020)
        );
        assert!(status_broadcast_offset(FirmwareRev::Rev7, 16).is_err());
    }
}
