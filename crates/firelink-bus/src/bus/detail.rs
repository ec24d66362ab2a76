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
//! level runs instead, for a whole packet (decided when it starts on the
//! wire, kept to its last delivery), when
//! - it was chosen ([`Detail::Packet`], `--detail packet`);
//! - the trace records every event ([`TraceLevel::Verbose`](super::TraceLevel::Verbose));
//! - a fault touched the packet (dropped, corrupted, delayed, a muted
//!   addressee: the evidence each delivery leaves is kept per delivery).
//!
//! What ran is counted ([`DetailReport`]): packets and deliveries by
//! level, and, between the marks a program sets at the start of each
//! servo cycle ([`Bus::begin_cycle`](super::Bus::begin_cycle)), the cycles
//! all of whose packets went the fast way and those that did not, with
//! why (the reasons above, and a bus reset within the cycle; a cycle begun
//! with the packet level chosen or every event traced is a packet-level
//! cycle even when no packet went). Nothing before the first mark is
//! counted.

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
        match why {
            PacketLevelWhy::Chosen => self.chosen,
            PacketLevelWhy::Tracing => self.tracing,
            PacketLevelWhy::Fault => self.fault,
            PacketLevelWhy::Reset => self.bus_reset,
        }
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
    /// Packets whose deliveries went in one batch (an ack belongs to the
    /// packet it answers and is not counted on its own).
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

impl DetailReport {
    /// The one-line summary with the spans between two cycle marks called
    /// `unit` (the Ethernet bridge marks each host datagram:
    /// `detail fast: datagrams 12 fast, ...`); [`Display`](fmt::Display)
    /// calls them `cycles`.
    pub fn counted_in(&self, unit: &'static str) -> CountedIn<'_> {
        CountedIn { report: self, unit }
    }
}

/// [`DetailReport::counted_in`]'s line.
pub struct CountedIn<'a> {
    report: &'a DetailReport,
    unit: &'static str,
}

impl fmt::Display for CountedIn<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.report;
        write!(
            f,
            "detail {}: {} {} fast, {} at the packet level",
            r.detail, self.unit, r.fast_cycles, r.packet_level_cycles
        )?;
        let why: Vec<String> = PacketLevelWhy::ALL
            .iter()
            .filter_map(|&w| {
                let n = r.packet_level_cycles_why.get(w);
                (n > 0).then(|| format!("{} {n}", w.name()))
            })
            .collect();
        if !why.is_empty() {
            write!(f, " ({})", why.join(", "))?;
        }
        write!(
            f,
            "; packets {} fast, {} at the packet level",
            r.fast_packets,
            r.packet_level_packets()
        )
    }
}

impl fmt::Display for DetailReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.counted_in("cycles").fmt(f)
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

    /// A packet's level, decided when it starts (`None`: fast). Counted
    /// from the first cycle mark on.
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

    /// The level chosen and the trace level in force as a cycle begins: a
    /// cycle begun with the packet level chosen, or every event traced, is
    /// a packet-level cycle even if no packet went.
    pub fn level_in_force(&mut self, detail: Detail, trace: super::TraceLevel) {
        if !self.in_cycle {
            return;
        }
        if detail == Detail::Packet {
            self.cycle_why |= PacketLevelWhy::Chosen.bit();
        }
        if trace >= super::TraceLevel::Verbose {
            self.cycle_why |= PacketLevelWhy::Tracing.bit();
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
        // The packet level chosen (as a cycle begins).
        bus.set_detail(Detail::Packet);
        bus.begin_cycle();
        broadcast(&mut bus);
        // Every event traced.
        bus.set_detail(Detail::Fast);
        bus.set_trace_level(TraceLevel::Verbose);
        bus.begin_cycle();
        broadcast(&mut bus);
        // A dropped packet (it reaches no one, and counts).
        bus.set_trace_level(TraceLevel::Normal);
        bus.begin_cycle();
        bus.add_fault_rule(FaultRule::once(PacketMatch::any(), PacketFault::Drop));
        broadcast(&mut bus);
        // A corrupted packet.
        bus.begin_cycle();
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
        assert_eq!((r.fast_cycles, r.packet_level_cycles), (1, 5), "{r:?}");
        let one_each = WhyCounts {
            chosen: 1,
            tracing: 1,
            fault: 2,
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
            text.starts_with("detail fast: cycles 1 fast, 5 at the packet level (chosen 1, tracing 1, fault 2, bus reset 1)"),
            "{text}"
        );
        // The same line with the spans named otherwise (the bridge's
        // datagrams), nothing else changed.
        assert_eq!(
            r.counted_in("datagrams").to_string(),
            text.replacen("cycles", "datagrams", 1)
        );
    }

    /// A node that does in its callbacks what can end a batch, and logs
    /// what it is called with: on every packet it sets a timer for the
    /// same instant (a tie with the next arrival) and one for a picosecond
    /// later (between arrivals); on its `transmit_on`-th packet it sends a
    /// broadcast, on its `reset_on`-th it sets IBR (a bus reset inside a
    /// batch).
    #[derive(Default)]
    struct Echo {
        log: Vec<String>,
        received: u64,
        transmit_on: Option<u64>,
        reset_on: Option<u64>,
    }

    impl crate::node::Node for Echo {
        fn name(&self) -> &str {
            "echo"
        }

        fn on_bus_reset(
            &mut self,
            now: SimTime,
            info: &crate::node::ResetInfo,
            _ctx: &mut crate::node::NodeCtx<'_>,
        ) {
            self.log.push(format!("{now:?} reset {}", info.phy_id));
        }

        fn on_receive(
            &mut self,
            now: SimTime,
            packet: &[u8],
            speed: firelink_wire::packet::Speed,
            ctx: &mut crate::node::NodeCtx<'_>,
        ) -> crate::node::RxReply {
            self.received += 1;
            let n = self.received;
            self.log.push(format!(
                "{now:?} rx {:02x?} {speed:?} gen {} crc {:?} idle {}",
                &packet[..packet.len().min(8)],
                ctx.generation(),
                ctx.received_crc_status(),
                ctx.bus_is_idle()
            ));
            ctx.set_timer(now, 2 * n);
            ctx.set_timer(now + SimDuration(1), 2 * n + 1);
            if self.transmit_on == Some(n) {
                ctx.transmit(crate::node::TransmitRequest {
                    packet: qwrite(ctx.phy_id(), 63),
                    speed: firelink_wire::packet::Speed::S400,
                    class: ArbitrationClass::Fair,
                    token: n,
                });
            }
            if self.reset_on == Some(n) {
                ctx.write_phy_register(1, 0x40 | ctx.read_phy_register(1));
            }
            crate::node::RxReply::Silent
        }

        fn on_transmitted(
            &mut self,
            now: SimTime,
            token: u64,
            ack: Option<Ack>,
            _ctx: &mut crate::node::NodeCtx<'_>,
        ) {
            self.log.push(format!("{now:?} sent {token} {ack:?}"));
        }

        fn on_timer(&mut self, now: SimTime, token: u64, _ctx: &mut crate::node::NodeCtx<'_>) {
            self.log.push(format!("{now:?} timer {token}"));
        }
    }

    /// Seven echoes, the root in the middle of the chain, node `first`
    /// sending a broadcast; run as `how` says at `detail`. Each node's log
    /// and the bus's clock and packet count.
    fn echoes(detail: Detail, how: u8, reset_on: Option<u64>) -> (Vec<Vec<String>>, SimTime, u64) {
        let mut bus = Bus::new(BusConfig {
            detail,
            ..BusConfig::default()
        });
        let nodes: Vec<NodeHandle> = (0..7u64)
            .map(|i| {
                let echo = Echo {
                    transmit_on: (i % 3 == 0).then_some(1 + i % 2),
                    reset_on: reset_on.filter(|_| i == 5),
                    ..Echo::default()
                };
                bus.add(echo, crate::bus::NodeConfig::board())
            })
            .collect();
        bus.daisy_chain(&nodes).expect("a chain");
        bus.set_root(nodes[3]).expect("a root");
        bus.reset();
        bus.run_until_idle();
        let p0 = bus.phy_id(nodes[0]).expect("numbered");
        bus.with_node::<Echo, _>(nodes[0], |_, ctx| {
            ctx.transmit(crate::node::TransmitRequest {
                packet: qwrite(p0, 63),
                speed: firelink_wire::packet::Speed::S400,
                class: ArbitrationClass::Fair,
                token: 99,
            });
        })
        .expect("an echo");
        let deadline = bus.now() + SimDuration::from_micros(400);
        match how {
            // Until the deadline.
            0 => bus.run_until(deadline),
            // One event at a time.
            1 => while bus.next_event_time().is_some_and(|t| t <= deadline) && bus.step() {},
            // Until a condition with a memory holds, again and again.
            _ => {
                let mut calls = 0u64;
                let watched = nodes[6];
                let mut seen = None;
                while bus.now() < deadline {
                    let held = bus.run_until_with(deadline, |b| {
                        calls += 1;
                        b.called_since(watched, &mut seen) && calls % 5 == 0
                    });
                    if !held {
                        break;
                    }
                    bus.with_node::<Echo, _>(watched, |e, _| {
                        e.log.push(format!("condition held, call {calls}"));
                    })
                    .expect("an echo");
                }
            }
        }
        let logs = nodes
            .iter()
            .map(|&n| bus.node::<Echo>(n).expect("an echo").log.clone())
            .collect();
        (logs, bus.now(), bus.packets_sent())
    }

    #[test]
    fn callbacks_that_set_timers_send_and_reset_in_a_batch_change_nothing() {
        for how in 0..3 {
            for reset_on in [None, Some(1), Some(2)] {
                let fast = echoes(Detail::Fast, how, reset_on);
                let packet = echoes(Detail::Packet, how, reset_on);
                assert_eq!(fast, packet, "run {how}, reset on {reset_on:?}");
                let lines: usize = fast.0.iter().map(Vec::len).sum();
                assert!(lines > 20, "run {how}: only {lines} lines");
                if reset_on.is_some() {
                    assert!(
                        fast.0.iter().flatten().any(|l| l.contains(" reset ")),
                        "a reset happened"
                    );
                }
            }
        }
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
