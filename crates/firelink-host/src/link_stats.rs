//! What a link saw, counted by outcome: the one set of counters every
//! host-side link keeps (the transaction engine counts, ports report, the
//! errors that name a link's state carry a snapshot). A leaf: it imports
//! nothing of this crate.

/// What a link saw, by outcome. Every packet received is counted under
/// exactly one of `matched`, `garbage`, `bad_crc`, `late` or `unmatched`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkStats {
    /// Requests sent.
    pub sent: u64,
    /// Responses accepted as the answer to the open request.
    pub matched: u64,
    /// Requests that got no acceptable answer in time.
    pub timeouts: u64,
    /// Received bytes that do not decode as a packet (truncated, too short,
    /// a length field beyond the datagram, an unknown tcode).
    pub garbage: u64,
    /// Packets whose header or data CRC failed.
    pub bad_crc: u64,
    /// Well-formed answers to a request that had already timed out.
    pub late: u64,
    /// Well-formed packets that answer no request of this link (wrong
    /// label, node, tcode or length).
    pub unmatched: u64,
    /// Bus generation changes seen.
    pub bus_resets: u64,
}

impl LinkStats {
    /// Packets received and refused, whatever the reason.
    pub fn refused(&self) -> u64 {
        self.garbage + self.bad_crc + self.late + self.unmatched
    }

    /// Counters since `earlier` (a snapshot taken before).
    pub fn since(&self, earlier: &LinkStats) -> LinkStats {
        LinkStats {
            sent: self.sent.saturating_sub(earlier.sent),
            matched: self.matched.saturating_sub(earlier.matched),
            timeouts: self.timeouts.saturating_sub(earlier.timeouts),
            garbage: self.garbage.saturating_sub(earlier.garbage),
            bad_crc: self.bad_crc.saturating_sub(earlier.bad_crc),
            late: self.late.saturating_sub(earlier.late),
            unmatched: self.unmatched.saturating_sub(earlier.unmatched),
            bus_resets: self.bus_resets.saturating_sub(earlier.bus_resets),
        }
    }
}

/// One line: what was sent and what came back, by outcome.
impl core::fmt::Display for LinkStats {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} requests sent, {} answered, {} timed out; refused: {} garbage, {} bad CRC, \
             {} late, {} answering no request",
            self.sent,
            self.matched,
            self.timeouts,
            self.garbage,
            self.bad_crc,
            self.late,
            self.unmatched
        )
    }
}
