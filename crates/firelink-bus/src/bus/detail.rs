//! Two levels of detail, one answer (issue 33).
//!
//! At the **packet** level every delivery of a packet is an event of its
//! own: taken off the queue, looked up in the subaction table, checked,
//! traced when asked, handed to its node. At the **fast** level (the
//! default) a packet's deliveries are handed to their nodes as one
//! batch: the subaction, its CRC status and speed are looked up once, and
//! each next delivery is taken straight from the packet's wave while it
//! is the queue's next event, with no pass through the general event
//! loop in between.
//!
//! The fast level is exact by construction, not an approximation: the
//! batch takes the deliveries in the order and at the times the queue
//! would give them one by one (it stops at the first other event due
//! before the next delivery, at the caller's deadline, when the caller's
//! condition holds, and when a callback started a bus reset), and each
//! node's callback is the same call with the same arguments. The packet
//! level runs instead, for a whole packet, when
//! - it was chosen ([`Detail::Packet`], `--detail packet`);
//! - the trace records every event ([`TraceLevel::Verbose`](super::TraceLevel::Verbose));
//! - a fault touched the packet (dropped, corrupted, delayed, a muted
//!   addressee: the evidence each delivery leaves is kept per delivery).
//!
//! What ran is counted ([`DetailReport`]): packets and deliveries by
//! level, and, between the marks a program sets at the start of each
//! servo cycle ([`Bus::begin_cycle`](super::Bus::begin_cycle)), the cycles
//! all of whose packets went the fast way and those that did not, with
//! why (the reasons above, and a bus reset within the cycle).

use std::fmt;
use std::str::FromStr;

use serde::Serialize;

/// How much of each packet the bus works out event by event. See the
/// module docs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Detail {
    /// Every delivery an event of its own (the reference).
    Packet,
    /// A packet's deliveries in one batch where that is exact (default).
    #[default]
    Fast,
}

impl Detail {
    /// The name used on command lines and in reports.
    pub const fn name(self) -> &'static str {
        match self {
            Detail::Packet => "packet",
            Detail::Fast => "fast",
        }
    }
}

impl fmt::Display for Detail {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A level of detail that is neither `packet` nor `fast`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown level of detail '{0}' (packet or fast)")]
pub struct UnknownDetail(pub String);

impl FromStr for Detail {
    type Err = UnknownDetail;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "packet" => Ok(Detail::Packet),
            "fast" => Ok(Detail::Fast),
            other => Err(UnknownDetail(other.to_string())),
        }
    }
}

/// Why a packet, or a cycle, ran at the packet level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PacketLevelWhy {
    /// The packet level was chosen.
    Chosen,
    /// The trace records every event.
    Tracing,
    /// A fault touched a packet.
    Fault,
    /// A bus reset began (cycles only).
    Reset,
}

impl PacketLevelWhy {
    /// Every reason, in report order.
    pub const ALL: [PacketLevelWhy; 4] = [
        PacketLevelWhy::Chosen,
        PacketLevelWhy::Tracing,
        PacketLevelWhy::Fault,
        PacketLevelWhy::Reset,
    ];

    const fn bit(self) -> u8 {
        1 << self as u8
    }

    /// The name used in reports.
    pub const fn name(self) -> &'static str {
        match self {
            PacketLevelWhy::Chosen => "chosen",
            PacketLevelWhy::Tracing => "tracing",
            PacketLevelWhy::Fault => "fault",
            PacketLevelWhy::Reset => "bus reset",
        }
    }
}

/// Counts by reason (see [`PacketLevelWhy`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WhyCounts {
    /// The packet level was chosen.
    pub chosen: u64,
    /// The trace recorded every event.
    pub tracing: u64,
    /// A fault touched a packet.
    pub fault: u64,
    /// A bus reset began.
    pub bus_reset: u64,
}

impl WhyCounts {
    fn add(&mut self, why: PacketLevelWhy) {
        *self.count_mut(why) += 1;
    }

    fn count_mut(&mut self, why: PacketLevelWhy) -> &mut u64 {
        match why {
            PacketLevelWhy::Chosen => &mut self.chosen,
            PacketLevelWhy::Tracing => &mut self.tracing,
            PacketLevelWhy::Fault => &mut self.fault,
            PacketLevelWhy::Reset => &mut self.bus_reset,
        }
    }

    /// The count for `why`.
    pub fn get(&self, why: PacketLevelWhy) -> u64 {
        let mut copy = *self;
        *copy.count_mut(why)
    }
}

/// What ran at which level of detail from the first servo cycle on (the
/// set-up before it, a scan, is not counted; see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DetailReport {
    /// The level chosen.
    pub detail: Detail,
    /// Servo cycles (between two [`Bus::begin_cycle`](super::Bus::begin_cycle)
    /// marks) whose every packet went the fast way.
    pub fast_cycles: u64,
    /// Servo cycles with at least one packet at the packet level, or a
    /// bus reset.
    pub packet_level_cycles: u64,
    /// Of those, how many had each reason (a cycle may have several).
    pub packet_level_cycles_why: WhyCounts,
    /// Packets whose deliveries went in one batch.
    pub fast_packets: u64,
    /// Packets delivered event by event, by why.
    pub packet_level_packets_why: WhyCounts,
    /// Deliveries made in batches.
    pub batched_deliveries: u64,
    /// Batches (a packet's deliveries split by other events due between
    /// them make more than one).
    pub batches: u64,
}

impl DetailReport {
    /// Packets delivered event by event, every reason.
    pub fn packet_level_packets(&self) -> u64 {
        let w = &self.packet_level_packets_why;
        w.chosen + w.tracing + w.fault + w.bus_reset
    }
}

impl fmt::Display for DetailReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "detail {}: {} cycles fast, {} at the packet level",
            self.detail, self.fast_cycles, self.packet_level_cycles
        )?;
        let why: Vec<String> = PacketLevelWhy::ALL
            .iter()
            .filter_map(|&w| {
                let n = self.packet_level_cycles_why.get(w);
                (n > 0).then(|| format!("{} {n}", w.name()))
            })
            .collect();
        if !why.is_empty() {
            write!(f, " ({})", why.join(", "))?;
        }
        write!(
            f,
            "; packets {} fast, {} at the packet level",
            self.fast_packets,
            self.packet_level_packets()
        )
    }
}

/// The counts as the bus keeps them, with the reasons seen in the cycle
/// under way.
#[derive(Clone, Debug, Default)]
pub(super) struct DetailTally {
    pub report: DetailReport,
    /// Reasons seen since the last cycle mark (bits of [`PacketLevelWhy`]).
    cycle_why: u8,
    /// A cycle mark was set (the counts of cycles start with it).
    in_cycle: bool,
}

impl DetailTally {
    /// No counts yet, at level `detail`.
    pub fn new(detail: Detail) -> DetailTally {
        DetailTally {
            report: DetailReport {
                detail,
                ..DetailReport::default()
            },
            ..DetailTally::default()
        }
    }

    /// A packet's path, decided at its first delivery (`None`: fast).
    /// Counted from the first cycle mark on.
    pub fn packet(&mut self, why: Option<PacketLevelWhy>) {
        if !self.in_cycle {
            return;
        }
        match why {
            None => self.report.fast_packets += 1,
            Some(w) => {
                self.report.packet_level_packets_why.add(w);
                self.cycle_why |= w.bit();
            }
        }
    }

    /// A batch of deliveries begins (counted from the first cycle mark on).
    pub fn batch(&mut self) {
        if self.in_cycle {
            self.report.batches += 1;
        }
    }

    /// A delivery in a batch (counted from the first cycle mark on).
    pub fn batched_delivery(&mut self) {
        if self.in_cycle {
            self.report.batched_deliveries += 1;
        }
    }

    /// A bus reset began.
    pub fn reset(&mut self) {
        self.cycle_why |= PacketLevelWhy::Reset.bit();
    }

    /// A servo cycle begins: the one before it, if marked, is counted.
    pub fn begin_cycle(&mut self) {
        if self.in_cycle {
            let r = &mut self.report;
            if self.cycle_why == 0 {
                r.fast_cycles += 1;
            } else {
                r.packet_level_cycles += 1;
                for w in PacketLevelWhy::ALL {
                    if self.cycle_why & w.bit() != 0 {
                        r.packet_level_cycles_why.add(w);
                    }
                }
            }
        }
        self.in_cycle = true;
        self.cycle_why = 0;
    }

    /// The counts so far, the cycle under way counted as if it ended now.
    pub fn snapshot(&self) -> DetailReport {
        let mut copy = self.clone();
        copy.begin_cycle();
        copy.report
    }
}

#[cfg(test)]
mod tests {
    use firelink_wire::packet::Ack;

    use super::super::probe::{Probe, chain, probe, qread, qwrite, send};
    use super::*;
    use crate::bus::{Bus, BusConfig, TraceLevel};
    use crate::fault::{FaultRule, PacketFault, PacketMatch};
    use crate::node::{ArbitrationClass, NodeHandle};
    use crate::time::{SimDuration, SimTime};

    /// What one probe saw: packets received (when, bytes), its transmit
    /// outcomes and its timers.
    type Seen = (
        Vec<(SimTime, Vec<u8>)>,
        Vec<(SimTime, u64, Option<Ack>)>,
        Vec<(SimTime, u64)>,
    );

    fn seen(bus: &Bus, nodes: &[NodeHandle]) -> Vec<Seen> {
        nodes
            .iter()
            .map(|&n| {
                let p = probe(bus, n);
                (p.received.clone(), p.transmitted.clone(), p.timers.clone())
            })
            .collect()
    }

    /// Six probes in a chain: broadcasts from both ends and a read across,
    /// while the middle probe's timers fire every 53 ns (so that they
    /// fall between the arrivals of one packet and split its batch).
    fn traffic(detail: Detail) -> (Bus, Vec<NodeHandle>) {
        let (mut bus, nodes) = chain(
            6,
            BusConfig {
                detail,
                ..BusConfig::default()
            },
        );
        bus.begin_cycle();
        let phy = |bus: &Bus, i: usize| bus.phy_id(nodes[i]).expect("numbered");
        let start = bus.now();
        bus.with_node::<Probe, _>(nodes[3], |_, ctx| {
            for k in 0..600u64 {
                ctx.set_timer(start + SimDuration(k * 53_000), 100 + k);
            }
        })
        .expect("a probe");
        let (p0, p2, p4, p5) = (phy(&bus, 0), phy(&bus, 2), phy(&bus, 4), phy(&bus, 5));
        send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
        send(&mut bus, nodes[5], qwrite(p5, 63), ArbitrationClass::Fair);
        send(&mut bus, nodes[2], qread(p2, p4), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(100));
        (bus, nodes)
    }

    #[test]
    fn both_levels_give_every_node_the_same_packets_at_the_same_times() {
        let (fast, nodes) = traffic(Detail::Fast);
        let (packet, _) = traffic(Detail::Packet);
        assert_eq!(fast.now(), packet.now());
        assert_eq!(fast.packets_sent(), packet.packets_sent());
        assert_eq!(
            format!("{:?}", fast.trace().packets()),
            format!("{:?}", packet.trace().packets())
        );
        assert_eq!(seen(&fast, &nodes), seen(&packet, &nodes));
        // Everything was heard, and the timers did split batches.
        let heard: usize = nodes.iter().map(|&n| probe(&fast, n).received.len()).sum();
        assert!(heard >= 12, "{heard} packets heard");
        let r = fast.detail_report();
        assert_eq!(r.packet_level_packets(), 0, "{r:?}");
        assert!(r.fast_packets >= 3, "{r:?}");
        assert_eq!(r.batched_deliveries, heard as u64, "{r:?}");
        assert!(r.batches > r.fast_packets, "no batch was split: {r:?}");
        assert_eq!(packet.detail_report().batched_deliveries, 0);
    }

    #[test]
    fn a_run_until_a_condition_stops_inside_a_packets_deliveries_at_both_levels() {
        let run = |detail: Detail| {
            let (mut bus, nodes) = chain(
                5,
                BusConfig {
                    detail,
                    ..BusConfig::default()
                },
            );
            let p0 = bus.phy_id(nodes[0]).expect("numbered");
            send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
            let watched = nodes[2];
            let deadline = bus.now() + SimDuration::from_micros(100);
            // Looked at again only when the bus called into the node, as
            // the host's link waits (a condition with a memory).
            let mut looked_at = None;
            let held = bus.run_until_with(deadline, |b| {
                b.called_since(watched, &mut looked_at)
                    && b.node::<Probe>(watched)
                        .is_some_and(|p| !p.received.is_empty())
            });
            let counts: Vec<usize> = nodes
                .iter()
                .map(|&n| probe(&bus, n).received.len())
                .collect();
            (held, bus.now(), counts)
        };
        let fast = run(Detail::Fast);
        assert_eq!(fast, run(Detail::Packet));
        let (held, _, counts) = fast;
        assert!(held);
        // Nearest first from the root: 1 and 2 have it, 3 and 4 not yet.
        assert_eq!(counts, vec![0, 1, 1, 0, 0]);
    }

    #[test]
    fn cycles_and_packets_are_counted_by_level_and_why() {
        let (mut bus, nodes) = chain(3, BusConfig::default());
        let p0 = bus.phy_id(nodes[0]).expect("numbered");
        let broadcast = |bus: &mut Bus| {
            send(bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
            bus.run_for(SimDuration::from_micros(50));
        };
        // Before the first cycle mark: not counted.
        broadcast(&mut bus);
        assert_eq!(bus.detail_report(), DetailReport::default());
        // A fast cycle.
        bus.begin_cycle();
        broadcast(&mut bus);
        // The packet level chosen.
        bus.begin_cycle();
        bus.set_detail(Detail::Packet);
        broadcast(&mut bus);
        // Every event traced.
        bus.begin_cycle();
        bus.set_detail(Detail::Fast);
        bus.set_trace_level(TraceLevel::Verbose);
        broadcast(&mut bus);
        // A corrupted packet.
        bus.begin_cycle();
        bus.set_trace_level(TraceLevel::Normal);
        bus.add_fault_rule(FaultRule::once(
            PacketMatch::any(),
            PacketFault::CorruptQuadlet { index: 3, xor: 1 },
        ));
        broadcast(&mut bus);
        // A bus reset (the cycle under way is counted as it stands).
        bus.begin_cycle();
        bus.initiate_reset(false);
        bus.run_for(SimDuration::from_millis(1));
        let r = bus.detail_report();
        assert_eq!(r.detail, Detail::Fast);
        assert_eq!((r.fast_cycles, r.packet_level_cycles), (1, 4), "{r:?}");
        let one_each = WhyCounts {
            chosen: 1,
            tracing: 1,
            fault: 1,
            bus_reset: 1,
        };
        assert_eq!(r.packet_level_cycles_why, one_each);
        assert_eq!(
            r.packet_level_packets_why,
            WhyCounts {
                bus_reset: 0,
                ..one_each
            }
        );
        assert_eq!(r.fast_packets, 1);
        assert_eq!(r.batched_deliveries, 2);
        let text = r.to_string();
        assert!(
            text.starts_with("detail fast: 1 cycles fast, 4 at the packet level (chosen 1, tracing 1, fault 1, bus reset 1)"),
            "{text}"
        );
    }

    #[test]
    fn a_level_is_named_packet_or_fast() {
        assert_eq!("packet".parse::<Detail>(), Ok(Detail::Packet));
        assert_eq!("fast".parse::<Detail>(), Ok(Detail::Fast));
        let e = "exact".parse::<Detail>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown level of detail 'exact' (packet or fast)"
        );
        assert_eq!(Detail::default(), Detail::Fast);
        assert_eq!(Detail::Packet.to_string(), "packet");
    }
}
