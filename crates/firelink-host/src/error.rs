//! Host-side failures, kept apart from the wire code space.

use firelink_wire::packet::{Ack, Rcode};

/// Why a host operation failed. `Copy` and allocation-free so the servo
/// cycle can pass it around.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum HostError {
    /// No matching response arrived in time.
    #[error("no response from node {node} (tl {tl}) within {waited_us} us")]
    Timeout {
        /// Destination node.
        node: u8,
        /// Transaction label of the request.
        tl: u8,
        /// How long the host waited.
        waited_us: u32,
    },
    /// A servo cycle spent its whole budget for waiting on answers (the
    /// `fw` port's per-cycle deadline) before this request's answer came:
    /// the cycle ends here; the answer, if it comes later, is dropped.
    #[error("no response from node {node} within the cycle's budget of {budget_us} us")]
    CycleDeadline {
        /// Destination node.
        node: u8,
        /// The cycle's budget for waiting.
        budget_us: u32,
    },
    /// The responder acknowledged with something other than complete/pending.
    #[error("node {node} answered with ack {}", ack_words(*.ack))]
    Ack {
        /// Destination node.
        node: u8,
        /// The ack received.
        ack: Ack,
    },
    /// The response carried an error rcode.
    #[error("node {node} answered with rcode {}", rcode_words(*.rcode))]
    Rcode {
        /// Responding node.
        node: u8,
        /// The rcode received.
        rcode: Rcode,
    },
    /// The bus was reset: node numbers may have changed. In-flight requests
    /// fail with this error once; rescan the bus, then go on.
    #[error("bus reset: generation {old} -> {new}; rescan needed")]
    BusReset {
        /// Generation the host was using.
        old: u32,
        /// Generation now on the bus.
        new: u32,
    },
    /// The Linux FireWire driver completed a request without the node's
    /// answer (its pseudo rcodes: no ack, busy, cancelled, send error).
    #[error("node {node}: {}", driver_rcode_words(*.rcode))]
    Driver {
        /// Destination node.
        node: u8,
        /// The driver's rcode (`firelink_wire::fw_cdev::rcode`).
        rcode: u32,
    },
    /// A FireWire device call failed in the operating system (errno).
    #[error("FireWire device: {what}: errno {errno}")]
    Device {
        /// The call.
        what: &'static str,
        /// Its errno.
        errno: i32,
    },
    /// Bytes from the port did not decode.
    #[error("bad packet from the port: {0}")]
    Wire(#[from] firelink_wire::Error),
    /// The operating system refused a socket operation.
    #[error("socket error: {0}")]
    Io(std::io::ErrorKind),
    /// A port address (`udp:HOST[:PORT]`) that is not one.
    #[error("{0}")]
    Address(AddressProblem),
    /// A request that cannot be expressed (size, destination).
    #[error("invalid request: {what} (value {value})")]
    InvalidRequest {
        /// What is wrong.
        what: &'static str,
        /// The offending value.
        value: u32,
    },
    /// A board did not take part in a cycle it was expected in.
    #[error("board {board} missed the cycle: {reason}")]
    BoardMissed {
        /// Board ID (rotary switch).
        board: u8,
        /// What was wrong with its data.
        reason: MissReason,
    },
    /// No board answered a scan; what the port saw says why (silence,
    /// garbage, bad CRCs, late or foreign answers).
    #[error("no boards found: {seen}")]
    NoBoards {
        /// The port's counters over the scan.
        seen: crate::link_stats::LinkStats,
    },
    /// A board ID is not present in the current configuration.
    #[error("board {0} is not on the bus")]
    UnknownBoard(u8),
}

/// What is wrong with a port address (`udp:HOST` or `udp:HOST:PORT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AddressProblem {
    /// Not `udp:HOST` or `udp:HOST:PORT`.
    #[error("expected udp:HOST or udp:HOST:PORT (an IPv6 address in brackets: udp:[::1]:1394)")]
    Syntax,
    /// The text after the last `:` is not a UDP port.
    #[error("the UDP port must be a number from 1 to 65535")]
    Port,
    /// The host name does not resolve to an address.
    #[error("the host name does not resolve to an address")]
    Unresolved,
}

/// An ack code in words.
fn ack_words(ack: Ack) -> String {
    match ack {
        Ack::Complete => "complete".into(),
        Ack::Pending => "pending".into(),
        Ack::BusyX | Ack::BusyA | Ack::BusyB => "busy (the node could not take the request)".into(),
        Ack::DataError => "data error (CRC or length error in the data block)".into(),
        Ack::TypeError => "type error (unsupported transaction or bad header field)".into(),
        Ack::Unknown(code) => format!("{code:#x} (not a defined ack code)"),
    }
}

/// A response code in words.
fn rcode_words(rcode: Rcode) -> String {
    match rcode {
        Rcode::Complete => "complete".into(),
        Rcode::ConflictError => "conflict error (a resource conflict; it may be retried)".into(),
        Rcode::DataError => "data error (data not available or corrupt)".into(),
        Rcode::TypeError => "type error (the operation is not supported at that address)".into(),
        Rcode::AddressError => "address error (the address is not accessible)".into(),
        Rcode::Unknown(code) => format!("{code:#x} (not a defined response code)"),
    }
}

impl From<std::io::Error> for HostError {
    fn from(e: std::io::Error) -> Self {
        HostError::Io(e.kind())
    }
}

/// Why a board's data for a cycle was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MissReason {
    /// The board's block was absent or not updated this cycle.
    NotUpdated,
    /// The sequence number did not match the query.
    Sequence {
        /// Sequence (or its low byte) the host sent.
        expected: u16,
        /// Sequence the board reported.
        received: u16,
    },
    /// The board flagged a corrupt query (seed-000 0xFFFF rule, Rev 8 error bit).
    CorruptQuery,
    /// The block's STATUS names another board.
    WrongBoardId {
        /// Board found in the data.
        found: u8,
    },
    /// The block size does not match the board's layout.
    BlockSize {
        /// Quadlets expected.
        expected: u16,
        /// Quadlets found.
        found: u16,
    },
    /// The board's own read or write transaction failed.
    Transaction,
}

impl core::fmt::Display for MissReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            MissReason::NotUpdated => write!(f, "no data this cycle"),
            MissReason::Sequence { expected, received } => {
                write!(f, "sequence {received:#x}, expected {expected:#x}")
            }
            MissReason::CorruptQuery => write!(f, "board reported a corrupt query"),
            MissReason::WrongBoardId { found } => write!(f, "data is from board {found}"),
            MissReason::BlockSize { expected, found } => {
                write!(f, "block of {found} quadlets, expected {expected}")
            }
            MissReason::Transaction => write!(f, "transaction failed"),
        }
    }
}

/// The Linux FireWire driver's pseudo rcode in words.
fn driver_rcode_words(rcode: u32) -> &'static str {
    use firelink_wire::fw_cdev::rcode as r;
    match rcode {
        r::NO_ACK => "no acknowledgement (no such node, or it is not answering)",
        r::BUSY => "busy (the node stayed busy through the retries)",
        r::CANCELLED => "cancelled (no response within the split time-out)",
        r::SEND_ERROR => "send error (the request could not be sent)",
        r::GENERATION => "stale bus generation (a bus reset came first)",
        _ => "an rcode the driver does not document",
    }
}

/// Result alias of the host layer.
pub type Result<T> = core::result::Result<T, HostError>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_read_as_sentences() {
        let e = HostError::Ack {
            node: 3,
            ack: Ack::BusyA,
        };
        assert_eq!(
            e.to_string(),
            "node 3 answered with ack busy (the node could not take the request)"
        );
        let e = HostError::Rcode {
            node: 1,
            rcode: Rcode::AddressError,
        };
        assert!(
            e.to_string()
                .ends_with("address error (the address is not accessible)")
        );
        let e = HostError::Io(std::io::ErrorKind::ConnectionRefused);
        assert_eq!(e.to_string(), "socket error: connection refused");
        for e in [
            HostError::Ack {
                node: 0,
                ack: Ack::Unknown(9),
            },
            HostError::Address(AddressProblem::Port),
        ] {
            let shown = e.to_string();
            assert!(
                !shown.contains('{') && !shown.contains("Unknown("),
                "{shown}"
            );
        }
    }
}
