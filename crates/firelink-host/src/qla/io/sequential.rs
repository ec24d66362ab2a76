//! The per-board protocols' halves of a cycle: [`Protocol::Sequential`]
//! reads each board's real-time block and writes its command block, one
//! transaction each; [`Protocol::SequentialReadBroadcastWrite`] reads the
//! same way and writes with the broadcast protocol's command block
//! ([`super::broadcast`]).
//!
//! [`Protocol::Sequential`]: crate::qla::scan::Protocol::Sequential
//! [`Protocol::SequentialReadBroadcastWrite`]: crate::qla::scan::Protocol::SequentialReadBroadcastWrite

use firelink_wire::qla::address::REALTIME_BLOCK_OFFSET;
use firelink_wire::qla::realtime::{ReadBlock, ReadBlockRepr};

use super::{IoSystem, miss_from_wire};
use crate::error::{HostError, MissReason};
use crate::port::{Dest, Port};

impl<P: Port> IoSystem<P> {
    /// Each board's real-time block read, checked and latched, one
    /// transaction per board.
    pub(super) fn read_sequential(&mut self) {
        for i in 0..self.boards.len() {
            let Some(board) = self.boards.get(i) else {
                break;
            };
            let info = *board.info();
            let len = info.layout.read_block_len();
            let Some(buf) = self.buf.get_mut(..len) else {
                self.miss(i, MissReason::Transaction);
                continue;
            };
            if let Err(e) = self
                .port
                .read_block(Dest::node(info.node), REALTIME_BLOCK_OFFSET, buf)
            {
                self.miss(i, MissReason::Transaction);
                self.note_error(e);
                if matches!(e, HostError::BusReset { .. }) {
                    return;
                }
                continue;
            }
            let parsed = ReadBlock::new_checked(&buf[..], info.layout)
                .and_then(|b| ReadBlockRepr::parse(&b));
            match parsed {
                Ok(repr) if repr.status.board_id() != info.board_id => self.miss(
                    i,
                    MissReason::WrongBoardId {
                        found: repr.status.board_id(),
                    },
                ),
                Ok(repr) => {
                    if let Some(b) = self.boards.get_mut(i) {
                        b.latch(repr);
                    }
                }
                Err(e) => self.miss(i, miss_from_wire(e)),
            }
        }
    }

    /// Each board's command block written, one transaction per board.
    pub(super) fn write_sequential(&mut self) {
        for i in 0..self.boards.len() {
            let Some(board) = self.boards.get(i) else {
                break;
            };
            let info = *board.info();
            let out = board.output();
            let len = info.layout.write_block_len();
            let Some(buf) = self.cmd.get_mut(..len) else {
                continue;
            };
            if let Err(e) = out.emit(buf) {
                self.note_error(e.into());
                continue;
            }
            if let Err(e) = self
                .port
                .write_block(Dest::node(info.node), REALTIME_BLOCK_OFFSET, buf)
            {
                self.note_error(e);
                if matches!(e, HostError::BusReset { .. }) {
                    return;
                }
            }
        }
    }
}
