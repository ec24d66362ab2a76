//! The one transaction engine every host-side link uses.
//!
//! A 1394 request is answered by a response from the node it went to, with
//! the same transaction label and the matching response tcode (Linux's
//! `fw_core_handle_response` matches the same way). Whatever carries the
//! packets (the simulated bus's link, a UDP socket to an Ethernet bridge,
//! the bridge forwarding onto FireWire), the rules are the same and live
//! here, once:
//!
//! - **labels**: a 6-bit counter per link ([`Transactions::next_label`]);
//! - **generation**: a port learns the bus generation from the boards and
//!   fails each request once after it changes, so the caller rescans
//!   ([`Transactions::check_generation`]);
//! - **matching**: a received packet is the answer to the open request only
//!   if it decodes, its CRCs pass, and (node, label, tcode, length) agree;
//!   anything else is counted under the reason it was refused and dropped
//!   ([`Transactions::accept`]): garbage, bad CRC, a late answer to a
//!   request that already timed out, or an answer to no request at all;
//! - **errors**: time-outs carry the real label; a response with an error
//!   rcode or the wrong size is reported as such, never as data.
//!
//! No I/O and no clock: callers wait (on the bus or the socket) and pass in
//! what arrived.

use firelink_wire::packet::{Packet, Rcode, Tcode};

use crate::error::{HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::Dest;

/// The answer one open request waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expect {
    /// Where the request went (a broadcast or no-forward request accepts an
    /// answer from any node, as the reference host does for node 63).
    pub dest: Dest,
    /// Its transaction label.
    pub tl: u8,
    /// The response tcode that answers it.
    pub tcode: Tcode,
    /// Payload bytes expected (4 for a quadlet).
    pub len: usize,
}

impl Expect {
    /// The answer to a quadlet read.
    pub fn quadlet(dest: Dest, tl: u8) -> Expect {
        Expect {
            dest,
            tl,
            tcode: Tcode::ReadQuadletResponse,
            len: 4,
        }
    }

    /// The answer to a block read of `len` bytes.
    pub fn block(dest: Dest, tl: u8, len: usize) -> Expect {
        Expect {
            dest,
            tl,
            tcode: Tcode::ReadBlockResponse,
            len,
        }
    }

    /// The answer to a unicast write.
    pub fn write(dest: Dest, tl: u8) -> Expect {
        Expect {
            dest,
            tl,
            tcode: Tcode::WriteResponse,
            len: 0,
        }
    }

    fn is_answered_by(&self, p: &Packet<&[u8]>) -> bool {
        if p.tcode() != self.tcode || p.tl() != self.tl {
            return false;
        }
        let any_node = self.dest.is_broadcast() || self.dest.no_forward;
        if !any_node && p.source_id().phy() != self.dest.node {
            return false;
        }
        match self.tcode {
            Tcode::ReadQuadletResponse => self.len == 4,
            // An error response answers whatever its size (a refused
            // read carries no data): its rcode says what went wrong.
            Tcode::ReadBlockResponse => {
                usize::from(p.data_length()) == self.len || p.rcode() != Rcode::Complete
            }
            _ => true,
        }
    }
}

/// Why a received packet was not taken as the answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// It does not decode.
    Garbage(firelink_wire::Error),
    /// A CRC failed.
    BadCrc(firelink_wire::Error),
    /// It answers a request that already timed out.
    Late {
        /// Its label.
        tl: u8,
    },
    /// It answers no request of this link.
    Unmatched {
        /// Its label.
        tl: u8,
    },
}

/// How a port treats a CRC field of 0 on an answer the bridge board made
/// itself: the FPGA V2 leaves them 0 on locally generated responses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrcCheck {
    /// Every CRC must be right.
    Always,
    /// A header CRC of 0 means "not computed" (bridge-local answers).
    ZeroMeansUnset,
    /// The link already found every CRC of these very bytes good (the
    /// simulated link, which checks a response as it arrives and hands
    /// over the bytes it checked): they are not worked out again. Only for
    /// bytes nothing changed since; any other packet is checked as
    /// [`Always`](Self::Always).
    KnownGood,
}

/// Labels that timed out recently, so their late answers are told apart.
const LATE_LABELS: usize = 8;

/// Labels, generation and matching of one link. See the module docs.
#[derive(Debug, Clone)]
pub struct Transactions {
    tl: u8,
    generation: u32,
    known: bool,
    pending_generation: Option<u32>,
    timed_out: [Option<u8>; LATE_LABELS],
    timed_out_at: usize,
    stats: LinkStats,
}

impl Default for Transactions {
    fn default() -> Self {
        Transactions::new()
    }
}

impl Transactions {
    /// A link that does not know the bus generation yet.
    pub const fn new() -> Transactions {
        Transactions {
            tl: 0,
            generation: 0,
            known: false,
            pending_generation: None,
            timed_out: [None; LATE_LABELS],
            timed_out_at: 0,
            stats: LinkStats {
                sent: 0,
                matched: 0,
                timeouts: 0,
                garbage: 0,
                bad_crc: 0,
                late: 0,
                unmatched: 0,
                bus_resets: 0,
            },
        }
    }

    /// A link on a bus whose generation is known (the simulated bus).
    pub fn with_generation(generation: u32) -> Transactions {
        let mut t = Transactions::new();
        t.generation = generation;
        t.known = true;
        t
    }

    /// The next transaction label (1, 2, ... 63, 0, 1, ...).
    pub fn next_label(&mut self) -> u8 {
        self.tl = (self.tl + 1) & 0x3F;
        self.tl
    }

    /// A request went out.
    pub fn sent(&mut self) {
        self.stats.sent += 1;
    }

    /// The generation requests carry.
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// Whether the generation came from the bus or a board yet.
    pub fn generation_known(&self) -> bool {
        self.known
    }

    /// The bus (or a board's reply) shows generation `g`. The first one is
    /// adopted at once; a change is remembered and reported by the next
    /// [`check_generation`](Self::check_generation).
    pub fn observe_generation(&mut self, g: u32) {
        if !self.known {
            self.generation = g;
            self.known = true;
        } else if g != self.generation && self.pending_generation != Some(g) {
            self.pending_generation = Some(g);
            self.stats.bus_resets += 1;
        }
    }

    /// Before a request to `dest`: adopt a changed generation, failing a
    /// unicast request once with [`HostError::BusReset`] so the caller
    /// knows node numbers may have moved (broadcasts just go on).
    ///
    /// # Errors
    /// [`HostError::BusReset`] once per change.
    pub fn check_generation(&mut self, dest: Dest) -> Result<()> {
        if dest.is_broadcast() {
            // A broadcast reaches every node whatever their numbers (and
            // a bridge does not check its generation): it goes on, and the
            // reset stays to be reported by the next unicast request. A
            // cycle that starts with its broadcast query must still learn
            // that node numbers may have moved.
            return Ok(());
        }
        if let Some(new) = self.pending_generation.take() {
            let old = self.generation;
            self.generation = new;
            return Err(HostError::BusReset { old, new });
        }
        Ok(())
    }

    /// Decide whether `bytes` is the answer to `expect`. Refused packets
    /// are counted by reason; the accepted one is checked for its rcode.
    ///
    /// # Errors
    /// `Ok(Err(refusal))` for a packet that is not the answer (the caller
    /// keeps waiting); `Err` for the answer itself arriving damaged (its
    /// header names the request but a CRC fails) or carrying an error
    /// rcode.
    pub fn accept<'a>(
        &mut self,
        bytes: &'a [u8],
        expect: &Expect,
        crc: CrcCheck,
    ) -> Result<core::result::Result<Packet<&'a [u8]>, Refusal>> {
        let packet = match Packet::new_checked(bytes) {
            Ok(p) => p,
            Err(e) => {
                self.stats.garbage += 1;
                return Ok(Err(Refusal::Garbage(e)));
            }
        };
        let unset_crc = crc == CrcCheck::ZeroMeansUnset && packet.header_crc() == Some(0);
        // What `verify` says of them: a link-internal packet's complement
        // (which no link checks as a CRC) is looked at all the same.
        let known_good = crc == CrcCheck::KnownGood && packet.tcode() != Tcode::LinkInternal;
        debug_assert!(!known_good || packet.verify().is_ok(), "CRCs said good");
        let crc_error = if unset_crc || known_good {
            None
        } else {
            packet.verify().err()
        };
        let answers = expect.is_answered_by(&packet);
        if let Some(e) = crc_error {
            self.stats.bad_crc += 1;
            if answers {
                // The answer came, damaged: fail now, naming the CRC,
                // rather than wait for an answer that will not come.
                return Err(HostError::Wire(e));
            }
            return Ok(Err(Refusal::BadCrc(e)));
        }
        if !answers {
            let tl = packet.tl();
            if packet.tcode().is_response() && self.timed_out.contains(&Some(tl)) {
                self.stats.late += 1;
                return Ok(Err(Refusal::Late { tl }));
            }
            self.stats.unmatched += 1;
            return Ok(Err(Refusal::Unmatched { tl }));
        }
        self.stats.matched += 1;
        let rcode = packet.rcode();
        if rcode != Rcode::Complete {
            return Err(HostError::Rcode {
                node: packet.source_id().phy(),
                rcode,
            });
        }
        Ok(Ok(packet))
    }

    /// The request `expect` got no answer within `waited_us`: remember its
    /// label (a late answer is then told apart) and say so.
    pub fn timed_out(&mut self, expect: &Expect, waited_us: u32) -> HostError {
        self.stats.timeouts += 1;
        if let Some(slot) = self.timed_out.get_mut(self.timed_out_at) {
            *slot = Some(expect.tl);
        }
        self.timed_out_at = (self.timed_out_at + 1) % LATE_LABELS;
        HostError::Timeout {
            node: expect.dest.node,
            tl: expect.tl,
            waited_us,
        }
    }

    /// A packet was received and refused outside [`accept`](Self::accept)
    /// (e.g. from a stranger's address).
    pub fn refused_unmatched(&mut self) {
        self.stats.unmatched += 1;
    }

    /// A packet arrived while no request was open (drained before the next
    /// one): count it as late if it answers a request that timed out,
    /// otherwise under the reason it cannot be an answer.
    pub fn refuse_unsolicited(&mut self, bytes: &[u8]) {
        let packet = match Packet::new_checked(bytes) {
            Ok(p) => p,
            Err(_) => {
                self.stats.garbage += 1;
                return;
            }
        };
        if packet.verify().is_err() {
            self.stats.bad_crc += 1;
        } else if packet.tcode().is_response() && self.timed_out.contains(&Some(packet.tl())) {
            self.stats.late += 1;
        } else {
            self.stats.unmatched += 1;
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }
}

/// Copy what the accepted answer `packet` to `expect` carries into `out`:
/// the quadlet of a quadlet read, the payload of a block read.
///
/// # Errors
/// [`HostError::Wire`] with [`firelink_wire::Error::BlockSize`] when that is
/// not `out.len()` bytes.
pub fn copy_answer(packet: &Packet<&[u8]>, expect: &Expect, out: &mut [u8]) -> Result<()> {
    let quadlet = packet.quadlet_data().to_be_bytes();
    let data: &[u8] = if expect.tcode == Tcode::ReadQuadletResponse {
        &quadlet
    } else {
        packet.payload()
    };
    if data.len() != out.len() {
        return Err(HostError::Wire(firelink_wire::Error::BlockSize {
            what: "response payload",
            expected: out.len() / 4,
            found: data.len() / 4,
        }));
    }
    out.copy_from_slice(data);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};

    fn response(source: u8, tl: u8, data: u32) -> Vec<u8> {
        let repr = PacketRepr::ReadQuadletResponse {
            header: AsyncHeader::new(NodeId(0xFFD0), NodeId::local(source), tl),
            rcode: Rcode::Complete,
            data,
        };
        let mut b = vec![0u8; repr.buffer_len()];
        repr.emit(&mut b).unwrap();
        b
    }

    /// A block read refused with an error rcode and no data is the
    /// answer (its rcode is the error), not a stranger's packet.
    #[test]
    fn an_error_response_answers_a_block_read_of_any_size() {
        let mut t = Transactions::with_generation(1);
        let tl = t.next_label();
        let want = Expect::block(Dest::node(3), tl, 2052);
        let header = AsyncHeader::new(NodeId(0xFFD0), NodeId::local(3), tl);
        let refused = PacketRepr::ReadBlockResponse {
            header,
            rcode: Rcode::AddressError,
            extended_tcode: 0,
            data: &[],
        };
        let mut b = vec![0u8; refused.buffer_len()];
        refused.emit(&mut b).unwrap();
        assert!(matches!(
            t.accept(&b, &want, CrcCheck::Always),
            Err(HostError::Rcode {
                node: 3,
                rcode: Rcode::AddressError
            })
        ));
        // Complete but the wrong size: not the answer.
        let short = PacketRepr::ReadBlockResponse {
            header,
            rcode: Rcode::Complete,
            extended_tcode: 0,
            data: &[0; 8],
        };
        let mut b = vec![0u8; short.buffer_len()];
        short.emit(&mut b).unwrap();
        assert!(matches!(
            t.accept(&b, &want, CrcCheck::Always),
            Ok(Err(Refusal::Unmatched { .. }))
        ));
    }

    #[test]
    fn accepts_only_the_answer_and_counts_the_rest_by_reason() {
        let mut t = Transactions::with_generation(1);
        let tl = t.next_label();
        let want = Expect::quadlet(Dest::node(3), tl);
        let ok = response(3, tl, 0x1234);
        let p = t.accept(&ok, &want, CrcCheck::Always).unwrap().unwrap();
        assert_eq!(p.quadlet_data(), 0x1234);
        // Wrong node, wrong label: unmatched.
        assert!(matches!(
            t.accept(&response(4, tl, 0), &want, CrcCheck::Always),
            Ok(Err(Refusal::Unmatched { .. }))
        ));
        assert!(matches!(
            t.accept(&response(3, tl ^ 1, 0), &want, CrcCheck::Always),
            Ok(Err(Refusal::Unmatched { .. }))
        ));
        // Truncated: garbage. Flipped bit: bad CRC.
        assert!(matches!(
            t.accept(&ok[..10], &want, CrcCheck::Always),
            Ok(Err(Refusal::Garbage(_)))
        ));
        // A damaged packet from another node: refused. The answer itself
        // damaged: an error naming the CRC.
        let mut other = response(5, tl, 0);
        other[13] ^= 1;
        assert!(matches!(
            t.accept(&other, &want, CrcCheck::Always),
            Ok(Err(Refusal::BadCrc(_)))
        ));
        let mut bad = ok.clone();
        bad[13] ^= 1;
        assert!(matches!(
            t.accept(&bad, &want, CrcCheck::Always),
            Err(HostError::Wire(firelink_wire::Error::HeaderCrc { .. }))
        ));
        // A request that timed out, answered later: late.
        let old = t.timed_out(&want, 20_000);
        assert!(matches!(old, HostError::Timeout { tl: l, .. } if l == tl));
        let next = Expect::quadlet(Dest::node(3), t.next_label());
        assert!(matches!(
            t.accept(&ok, &next, CrcCheck::Always),
            Ok(Err(Refusal::Late { .. }))
        ));
        let s = t.stats();
        assert_eq!(
            (
                s.matched,
                s.unmatched,
                s.garbage,
                s.bad_crc,
                s.late,
                s.timeouts
            ),
            (1, 2, 1, 2, 1, 1)
        );
        assert_eq!(s.refused(), 6);
    }

    #[test]
    fn error_rcode_is_an_error_not_data() {
        let mut t = Transactions::with_generation(1);
        let tl = t.next_label();
        let repr = PacketRepr::ReadQuadletResponse {
            header: AsyncHeader::new(NodeId(0xFFD0), NodeId::local(2), tl),
            rcode: Rcode::AddressError,
            data: 0,
        };
        let mut b = vec![0u8; repr.buffer_len()];
        repr.emit(&mut b).unwrap();
        let e = t
            .accept(&b, &Expect::quadlet(Dest::node(2), tl), CrcCheck::Always)
            .unwrap_err();
        assert!(matches!(e, HostError::Rcode { node: 2, .. }));
    }

    #[test]
    fn a_new_generation_fails_one_unicast_request() {
        let mut t = Transactions::new();
        assert!(!t.generation_known());
        t.observe_generation(5);
        assert_eq!(t.generation(), 5);
        assert!(t.check_generation(Dest::node(1)).is_ok());
        t.observe_generation(6);
        t.observe_generation(6);
        assert_eq!(t.stats().bus_resets, 1);
        assert_eq!(
            t.check_generation(Dest::node(1)),
            Err(HostError::BusReset { old: 5, new: 6 })
        );
        assert!(t.check_generation(Dest::node(1)).is_ok());
        // A broadcast first does not swallow the reset: the next unicast
        // request still reports it.
        t.observe_generation(7);
        assert!(t.check_generation(Dest::BROADCAST).is_ok());
        assert_eq!(
            t.check_generation(Dest::node(1)),
            Err(HostError::BusReset { old: 6, new: 7 })
        );
        assert_eq!(t.generation(), 7);
    }

    #[test]
    fn broadcast_and_no_forward_reads_take_any_node() {
        let mut t = Transactions::with_generation(1);
        let tl = t.next_label();
        let any = Expect::quadlet(Dest::BROADCAST, tl);
        assert!(
            t.accept(&response(9, tl, 1), &any, CrcCheck::Always)
                .unwrap()
                .is_ok()
        );
        let local = Expect::quadlet(
            Dest {
                node: 0,
                no_forward: true,
            },
            tl,
        );
        assert!(
            t.accept(&response(9, tl, 1), &local, CrcCheck::Always)
                .unwrap()
                .is_ok()
        );
    }

    #[test]
    fn labels_wrap_at_six_bits() {
        let mut t = Transactions::new();
        let labels: Vec<u8> = (0..65).map(|_| t.next_label()).collect();
        assert_eq!(labels[0], 1);
        assert_eq!(labels[62], 63);
        assert_eq!(labels[63], 0);
        assert!(labels.iter().all(|&l| l < 64));
    }
}
