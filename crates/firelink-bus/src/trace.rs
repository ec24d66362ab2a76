//! The record of everything that happened on the bus, in virtual time.
//!
//! Two views of one run:
//! - [`PacketRecord`]s: every packet that went on the wire (requests, acks,
//!   concatenated responses, cycle starts, PHY and self-ID packets, babble),
//!   with its bytes as transmitted (after any injected corruption), its
//!   arbitration start, data-prefix start, last bit and data-end end. This
//!   is what [`pcap`](crate::pcap) exports and what phase measurements read.
//! - [`TraceEntry`]s: a time-ordered log of bus events (arbitration wins,
//!   packet start and end, acks, missing acks, resets, faults, errors that
//!   nodes reported). [`Trace::timeline`] renders it as compact text.
//!
//! Two runs with the same seed give equal traces (`==` compares every byte
//! and every picosecond).

use std::fmt::Write as _;
use std::sync::Arc;

use firelink_wire::packet::{Ack, Packet, Speed, Tcode};

use crate::id::FaultId;
use crate::node::ArbitrationClass;
use crate::time::SimTime;

/// Identifies one packet on the wire (sequential from 0 in one run).
pub use crate::id::PacketId;

/// What role a packet played.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PacketKind {
    /// A node's transmit request (a request, a split response, a broadcast).
    Request,
    /// An ack (one byte).
    Ack,
    /// A response sent right after its ack without releasing the bus.
    ConcatResponse,
    /// A cycle start from the cycle master.
    CycleStart,
    /// A self-ID packet during bus reset.
    SelfId,
    /// A copy sent again by an injected duplicate fault.
    Duplicate,
    /// Garbage from a babbling node (an injected fault).
    Babble,
}

impl PacketKind {
    fn short(self) -> &'static str {
        match self {
            PacketKind::Request => "tx",
            PacketKind::Ack => "ack",
            PacketKind::ConcatResponse => "resp",
            PacketKind::CycleStart => "cyc",
            PacketKind::SelfId => "sid",
            PacketKind::Duplicate => "dup",
            PacketKind::Babble => "bab",
        }
    }
}

/// One packet on the wire.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PacketRecord {
    /// Its identifier.
    pub id: PacketId,
    /// Its role.
    pub kind: PacketKind,
    /// Node index of the transmitter.
    pub sender: usize,
    /// Physical ID of the transmitter.
    pub sender_phy: u8,
    /// When the transmitter started arbitrating (`None`: no arbitration,
    /// e.g. acks and concatenated responses).
    pub arb_start: Option<SimTime>,
    /// Arbitration class used.
    pub class: Option<ArbitrationClass>,
    /// Data prefix begins at the transmitter.
    pub start: SimTime,
    /// Last bit leaves the transmitter.
    pub bits_end: SimTime,
    /// The transmitter stops driving (end of data end; equals `bits_end`
    /// for an ack followed by a concatenated response).
    pub end: SimTime,
    /// Signalling speed.
    pub speed: Speed,
    /// The bytes as transmitted (after injected corruption). An ack is its
    /// one ack byte; a PHY packet its link-internal form.
    pub bytes: Arc<[u8]>,
    /// For acks and concatenated responses: the packet answered.
    pub answers: Option<PacketId>,
    /// Bus generation at transmission.
    pub generation: u32,
    /// Faults injected into this packet.
    pub faults: Vec<FaultId>,
}

impl PacketRecord {
    /// Destination physical ID (63 for broadcast; `None` for acks, self-ID
    /// and PHY packets, or packets too short to have one).
    pub fn destination_phy(&self) -> Option<u8> {
        match self.kind {
            PacketKind::Ack | PacketKind::SelfId => None,
            _ => {
                if self.tcode() == Some(Tcode::LinkInternal) {
                    return None;
                }
                let b = self.bytes.get(..2)?;
                Some(b[1] & 0x3F)
            }
        }
    }

    /// The tcode (`None` for acks and packets shorter than a quadlet).
    pub fn tcode(&self) -> Option<Tcode> {
        if self.kind == PacketKind::Ack {
            return None;
        }
        self.bytes.get(3).map(|b| Tcode::from(b >> 4))
    }

    /// The ack code of an ack record (`None` if not an ack or corrupt).
    pub fn ack(&self) -> Option<Ack> {
        if self.kind != PacketKind::Ack {
            return None;
        }
        Ack::from_byte(*self.bytes.first()?).ok()
    }

    /// Wire time from data prefix to end of data end.
    pub fn duration(&self) -> crate::time::SimDuration {
        self.end - self.start
    }
}

/// One bus event.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TraceEvent {
    /// A node won arbitration.
    Arbitration {
        /// Node index.
        node: usize,
        /// Class used.
        class: ArbitrationClass,
        /// When it started arbitrating (its gap had elapsed).
        requested: SimTime,
    },
    /// A packet's data prefix began (see the record for details).
    PacketStart(PacketId),
    /// A packet ended (end of data end at the transmitter).
    PacketEnd(PacketId),
    /// A packet reached a node (only at [`TraceLevel::Verbose`]).
    ///
    /// [`TraceLevel::Verbose`]: crate::bus::TraceLevel::Verbose
    Deliver {
        /// The packet.
        packet: PacketId,
        /// Node index.
        node: usize,
    },
    /// A unicast packet got no (valid) ack.
    NoAck {
        /// The packet.
        packet: PacketId,
    },
    /// The bus went idle.
    Idle,
    /// A bus reset began.
    ResetStart {
        /// Why.
        cause: String,
        /// Short (arbitrated) reset.
        short: bool,
    },
    /// Self-ID finished; nodes were told their IDs.
    ResetDone {
        /// New generation.
        generation: u32,
        /// Nodes on the bus.
        node_count: u8,
        /// Physical ID of the root.
        root_phy: u8,
    },
    /// A fault was injected.
    Fault {
        /// Its record in the fault log.
        id: FaultId,
        /// What was done.
        what: String,
    },
    /// A node reported an error it detected.
    Report {
        /// Node index.
        node: usize,
        /// What it said.
        text: String,
        /// The packet it was receiving, if any.
        packet: Option<PacketId>,
    },
    /// Something the bus noticed (ignored replies, refused packets...).
    Note(String),
}

/// A timestamped event.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TraceEntry {
    /// When.
    pub time: SimTime,
    /// What.
    pub event: TraceEvent,
}

/// Everything recorded in one run.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Trace {
    pub(crate) entries: Vec<TraceEntry>,
    pub(crate) packets: Vec<PacketRecord>,
    pub(crate) names: Vec<String>,
}

impl Trace {
    /// All events in time order.
    pub fn entries(&self) -> &[TraceEntry] {
        &self.entries
    }

    /// All packets in start order.
    pub fn packets(&self) -> &[PacketRecord] {
        &self.packets
    }

    /// The record of one packet.
    pub fn packet(&self, id: PacketId) -> Option<&PacketRecord> {
        self.packets
            .binary_search_by_key(&id, |p| p.id)
            .ok()
            .and_then(|i| self.packets.get(i))
    }

    /// Node names by index, as added to the bus.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Forget everything recorded so far (names are kept).
    pub fn clear(&mut self) {
        self.entries.clear();
        self.packets.clear();
    }

    /// Reports nodes made, as (time, node, text).
    pub fn reports(&self) -> impl Iterator<Item = (SimTime, usize, &str)> {
        self.entries.iter().filter_map(|e| match &e.event {
            TraceEvent::Report { node, text, .. } => Some((e.time, *node, text.as_str())),
            _ => None,
        })
    }

    pub(crate) fn name_of(&self, node: usize) -> &str {
        self.name(node)
    }

    fn name(&self, node: usize) -> &str {
        self.names.get(node).map_or("?", String::as_str)
    }

    /// A compact text timeline: one line per event, times in microseconds.
    /// Deliveries, packet ends and idle periods are left out.
    pub fn timeline(&self) -> String {
        self.render(false)
    }

    /// A verbose timeline that also lists deliveries, packet ends and idle
    /// periods.
    pub fn timeline_verbose(&self) -> String {
        self.render(true)
    }

    fn render(&self, verbose: bool) -> String {
        let mut out = String::new();
        for e in &self.entries {
            let t = e.time.as_micros_f64();
            let _ = match &e.event {
                TraceEvent::Arbitration {
                    node,
                    class,
                    requested,
                } => writeln!(
                    out,
                    "{t:12.4} arb   {} {} (from {:.4})",
                    self.name(*node),
                    class.name(),
                    requested.as_micros_f64()
                ),
                TraceEvent::PacketStart(id) => match self.packet(*id) {
                    Some(p) => writeln!(out, "{t:12.4} {}", self.describe(p)),
                    None => writeln!(out, "{t:12.4} pkt   #{id}"),
                },
                TraceEvent::PacketEnd(id) if verbose => writeln!(out, "{t:12.4} end   #{id}"),
                TraceEvent::Deliver { packet, node } if verbose => {
                    writeln!(out, "{t:12.4} rx    #{packet} at {}", self.name(*node))
                }
                TraceEvent::Idle if verbose => writeln!(out, "{t:12.4} idle"),
                TraceEvent::PacketEnd(_) | TraceEvent::Deliver { .. } | TraceEvent::Idle => {
                    continue;
                }
                TraceEvent::NoAck { packet } => writeln!(out, "{t:12.4} noack #{packet}"),
                TraceEvent::ResetStart { cause, short } => writeln!(
                    out,
                    "{t:12.4} reset {} ({cause})",
                    if *short { "short" } else { "long" }
                ),
                TraceEvent::ResetDone {
                    generation,
                    node_count,
                    root_phy,
                } => writeln!(
                    out,
                    "{t:12.4} selfid gen {generation}: {node_count} nodes, root {root_phy}"
                ),
                TraceEvent::Fault { id, what } => writeln!(out, "{t:12.4} FAULT {id}: {what}"),
                TraceEvent::Report { node, text, packet } => writeln!(
                    out,
                    "{t:12.4} error {}: {text}{}",
                    self.name(*node),
                    packet.map(|p| format!(" (#{p})")).unwrap_or_default()
                ),
                TraceEvent::Note(text) => writeln!(out, "{t:12.4} note  {text}"),
            };
        }
        out
    }

    fn describe(&self, p: &PacketRecord) -> String {
        let dur = p.duration().as_micros_f64();
        let speed = match p.speed {
            Speed::S100 => "S100",
            Speed::S200 => "S200",
            Speed::S400 => "S400",
        };
        let from = self.name(p.sender);
        match p.kind {
            PacketKind::Ack => {
                let code = p
                    .ack()
                    .map_or_else(|| "corrupt".to_string(), |a| format!("{a:?}"));
                format!(
                    "{:<5} #{} {from} {code} for #{} [{dur:.3}]",
                    p.kind.short(),
                    p.id,
                    p.answers.unwrap_or(0)
                )
            }
            _ => {
                let view = Packet::new_unchecked(&p.bytes[..]);
                let what = p.tcode().map_or("short", |t| t.name());
                let dest = match p.destination_phy() {
                    Some(63) => "bcast".to_string(),
                    Some(d) => format!("{d}"),
                    None => "-".to_string(),
                };
                let offset = if p.tcode().is_some_and(Tcode::is_request) {
                    format!(" @{:#x}", view.offset())
                } else {
                    String::new()
                };
                let faults = if p.faults.is_empty() {
                    String::new()
                } else {
                    format!(" faults {:?}", p.faults)
                };
                format!(
                    "{:<5} #{} {from}(phy {}) -> {dest} {what}{offset} {}B {speed} [{dur:.3}]{faults}",
                    p.kind.short(),
                    p.id,
                    p.sender_phy,
                    p.bytes.len(),
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ack_record_accessors() {
        let rec = PacketRecord {
            id: 3,
            kind: PacketKind::Ack,
            sender: 0,
            sender_phy: 1,
            arb_start: None,
            class: None,
            start: SimTime(0),
            bits_end: SimTime(10),
            end: SimTime(20),
            speed: Speed::S400,
            bytes: Arc::from(&[Ack::Pending.to_byte()][..]),
            answers: Some(2),
            generation: 1,
            faults: vec![],
        };
        assert_eq!(rec.ack(), Some(Ack::Pending));
        assert_eq!(rec.tcode(), None);
        assert_eq!(rec.destination_phy(), None);
        assert_eq!(rec.duration().0, 20);
    }
}
