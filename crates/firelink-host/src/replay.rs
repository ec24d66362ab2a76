//! A port that plays back a recorded exchange: [`ReplayPort`] reads a pcap
//! file written by a [`TracingPort`](crate::trace::TracingPort) or
//! `firelink ... --pcap FILE` and answers the host library with the
//! recorded packets, checking that every request it is asked to send is
//! the one recorded, field by field. A test can so run the library (scan,
//! I/O cycles) against real traffic without any board, and notice any
//! change in what the library sends. (How to record a new capture:
//! `crates/firelink-host/tests/data/README.md`.)
//!
//! What the port does with each call:
//! - the next recorded packet the host sent must be this request (same
//!   tcode, destination, offset, length, data); the recording's
//!   transaction label is used;
//! - the packets the host received after it, up to the next one it sent,
//!   are the answers, judged by the [transaction engine](crate::transaction)
//!   as a live port would judge them (a damaged one is a CRC error, a
//!   request with no answer a time-out naming its label);
//! - a request with no recorded packet at all is one the recorded port
//!   refused before sending (a broadcast read on the simulated bus): it is
//!   refused the same way;
//! - anything else is a divergence: the call fails and
//!   [`ReplayPort::divergence`] says where.
//!
//! The clock follows the recording's timestamps.

use std::time::Duration;

use firelink_wire::packet::{Packet, Tcode};
use firelink_wire::pcap::{Direction, Records};

use crate::error::{HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::{Dest, Port};
use crate::transaction::{CrcCheck, Expect, Transactions, copy_answer};

/// One recorded packet.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Entry {
    at_ns: u64,
    sent: bool,
    bytes: Vec<u8>,
}

/// A port answering from a recording. See the module docs.
#[derive(Debug)]
pub struct ReplayPort {
    name: String,
    entries: Vec<Entry>,
    next: usize,
    now_ns: u64,
    host_phy: u8,
    generation: u32,
    transactions: Transactions,
    divergence: Option<String>,
}

/// What the host asked for, to compare with the recording.
#[derive(Debug, Clone, Copy)]
struct Ask<'a> {
    tcode: Tcode,
    dest: Dest,
    offset: u64,
    len: usize,
    data: &'a [u8],
}

impl ReplayPort {
    /// A port replaying the pcap file `file` (its bytes), named `name`.
    ///
    /// # Errors
    /// The file's damage, as [`HostError::Wire`]; a file without the
    /// host's direction marks ([`firelink_wire::pcap`]), or with no packet
    /// sent by the host, as [`HostError::InvalidRequest`].
    pub fn from_pcap(name: &str, file: &[u8]) -> Result<ReplayPort> {
        let mut entries = Vec::new();
        for record in Records::new(file)? {
            let record = record?;
            let sent = match record.direction() {
                Some(Direction::Sent) => true,
                Some(Direction::Received) => false,
                _ => {
                    return Err(HostError::InvalidRequest {
                        what: "pcap record not captured at a host (no direction)",
                        value: entries.len() as u32,
                    });
                }
            };
            entries.push(Entry {
                at_ns: record.ns,
                sent,
                bytes: record.payload.to_vec(),
            });
        }
        let host_phy = entries
            .iter()
            .find(|e| e.sent)
            .and_then(|e| Packet::new_checked(&e.bytes[..]).ok())
            .map(|p| p.source_id().phy())
            .ok_or(HostError::InvalidRequest {
                what: "a recording with no packet sent by the host",
                value: 0,
            })?;
        Ok(ReplayPort {
            name: name.to_string(),
            now_ns: entries.first().map_or(0, |e| e.at_ns),
            entries,
            next: 0,
            host_phy,
            generation: 1,
            transactions: Transactions::with_generation(1),
            divergence: None,
        })
    }

    /// Where the host library first asked for something the recording does
    /// not have, if it did.
    pub fn divergence(&self) -> Option<&str> {
        self.divergence.as_deref()
    }

    /// Recorded packets not played yet.
    pub fn remaining(&self) -> usize {
        self.entries.len() - self.next
    }

    fn diverge(&mut self, what: String) -> HostError {
        if self.divergence.is_none() {
            self.divergence = Some(format!("packet {}: {what}", self.next));
        }
        HostError::InvalidRequest {
            what: "the request differs from the recording (replay)",
            value: self.next as u32,
        }
    }

    /// Play the request `ask`: returns its label, or the error the
    /// recorded port gave (a refusal before sending) or a divergence.
    fn play_request(&mut self, ask: Ask<'_>) -> Result<u8> {
        let recorded = self
            .entries
            .get(self.next)
            .filter(|e| e.sent)
            .map(|e| e.bytes.clone());
        let matches = recorded.as_deref().map(|bytes| Self::same(bytes, &ask));
        match matches {
            Some(Ok(())) => {}
            // Not recorded: the recorded port refused the request before
            // it reached the wire, as reads of node 63 are refused on a
            // bus.
            _ if ask.dest.is_broadcast()
                && matches!(
                    ask.tcode,
                    Tcode::ReadQuadletRequest | Tcode::ReadBlockRequest
                ) =>
            {
                return Err(HostError::InvalidRequest {
                    what: "reads cannot be broadcast on a 1394 bus",
                    value: u32::from(ask.dest.node),
                });
            }
            Some(Err(recorded)) => {
                return Err(self.diverge(format!("asked {ask:?}, recorded {recorded}")));
            }
            None => return Err(self.diverge(format!("no recorded request for {ask:?}"))),
        }
        let Some(entry) = self.entries.get(self.next) else {
            return Err(self.diverge("the recording ended".into()));
        };
        let Ok(p) = Packet::new_checked(&entry.bytes[..]) else {
            return Err(self.diverge("the recorded request does not decode".into()));
        };
        let tl = p.tl();
        self.now_ns = self.now_ns.max(entry.at_ns);
        self.next += 1;
        self.transactions.sent();
        Ok(tl)
    }

    /// The recorded answers to `expect` (those received before the next
    /// request): the payload of the accepted one copied into `out`.
    fn play_answer(&mut self, expect: &Expect, out: &mut [u8]) -> Result<()> {
        let crc = if expect.dest.no_forward {
            CrcCheck::ZeroMeansUnset
        } else {
            CrcCheck::Always
        };
        let asked_at = self.now_ns;
        while let Some(entry) = self.entries.get(self.next).filter(|e| !e.sent) {
            self.now_ns = self.now_ns.max(entry.at_ns);
            self.next += 1;
            let bytes = entry.bytes.clone();
            if let Ok(packet) = self.transactions.accept(&bytes, expect, crc)? {
                return copy_answer(&packet, expect, out);
            }
        }
        // No answer came in the recording: the recorded port timed out
        // when its next request went out.
        let until = self.entries.get(self.next).map_or(self.now_ns, |e| e.at_ns);
        self.now_ns = self.now_ns.max(until);
        let waited = (until.saturating_sub(asked_at) / 1000).min(u64::from(u32::MAX)) as u32;
        Err(self.transactions.timed_out(expect, waited))
    }

    /// Whether the recorded request `bytes` is `ask`; otherwise what it is.
    fn same(bytes: &[u8], ask: &Ask<'_>) -> core::result::Result<(), String> {
        let Ok(p) = Packet::new_checked(bytes) else {
            return Err("a request that does not decode".into());
        };
        let same = p.tcode() == ask.tcode
            && p.destination_id().phy() == ask.dest.node
            && p.offset() == ask.offset
            && match ask.tcode {
                Tcode::ReadBlockRequest => usize::from(p.data_length()) == ask.len,
                Tcode::WriteQuadletRequest => {
                    ask.data.get(..4) == Some(&p.quadlet_data().to_be_bytes()[..])
                }
                Tcode::WriteBlockRequest => p.data() == ask.data,
                _ => true,
            };
        if same {
            Ok(())
        } else {
            Err(format!(
                "{:?} to node {} at {:#x}",
                p.tcode(),
                p.destination_id().phy(),
                p.offset()
            ))
        }
    }

    fn read(&mut self, ask: Ask<'_>, out: &mut [u8]) -> Result<()> {
        let tl = self.play_request(ask)?;
        let expect = if ask.tcode == Tcode::ReadQuadletRequest {
            Expect::quadlet(ask.dest, tl)
        } else {
            Expect::block(ask.dest, tl, out.len())
        };
        self.play_answer(&expect, out)
    }

    fn write(&mut self, ask: Ask<'_>) -> Result<()> {
        self.play_request(ask)?;
        // Writes get no answer packet (an ack on the bus, nothing over
        // UDP); skip whatever was received before the next request.
        Ok(())
    }
}

impl Port for ReplayPort {
    fn name(&self) -> &str {
        &self.name
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        let ask = Ask {
            tcode: Tcode::ReadQuadletRequest,
            dest,
            offset,
            len: 4,
            data: &[],
        };
        let mut out = [0u8; 4];
        self.read(ask, &mut out)?;
        Ok(u32::from_be_bytes(out))
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        let data = value.to_be_bytes();
        self.write(Ask {
            tcode: Tcode::WriteQuadletRequest,
            dest,
            offset,
            len: 4,
            data: &data,
        })
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        let ask = Ask {
            tcode: Tcode::ReadBlockRequest,
            dest,
            offset,
            len: out.len(),
            data: &[],
        };
        self.read(ask, out)
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.write(Ask {
            tcode: Tcode::WriteBlockRequest,
            dest,
            offset,
            len: data.len(),
            data,
        })
    }

    fn wait(&mut self, duration: Duration) {
        self.now_ns = self
            .now_ns
            .saturating_add(u64::try_from(duration.as_nanos()).unwrap_or(u64::MAX));
    }

    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        // The packets overheard in the recording before the next request.
        let start = self.now_ns;
        while let Some(entry) = self.entries.get(self.next).filter(|e| !e.sent) {
            self.now_ns = self.now_ns.max(entry.at_ns);
            self.next += 1;
            let bytes = entry.bytes.clone();
            if heard(&bytes) {
                return true;
            }
        }
        let limit_ns = u64::try_from(limit.as_nanos()).unwrap_or(u64::MAX);
        self.now_ns = self.now_ns.max(start.saturating_add(limit_ns));
        false
    }

    fn now(&self) -> Duration {
        Duration::from_nanos(self.now_ns)
    }

    fn generation(&self) -> u32 {
        self.generation
    }

    fn link_stats(&self) -> LinkStats {
        self.transactions.stats()
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        // As the recorded port: the bridge's host is node 16 (0xFFD0), so
        // 0..16; on the bus the PC is the root above every board.
        0..self.host_phy
    }
}
