//! Fault injection: seeded, scriptable, deterministic, and every fault logged.
//!
//! A [`FaultPlan`] holds two kinds of faults:
//! - packet faults ([`FaultRule`]): when a packet matching a
//!   [`PacketMatch`] is about to go on the wire, drop it, flip bits, corrupt a
//!   quadlet, delay it, send it twice, or lose or corrupt its ack;
//! - timed faults ([`TimedFault`]): at a virtual instant, unplug a node's
//!   cable (bus reset, optionally plugged back later), make a node stop
//!   answering, or make a node babble garbage.
//!
//! The injector sits between the transmitter and the receivers, like
//! smoltcp's `FaultInjector` middleware: nodes never know a fault was
//! injected. Random choices (which bits to flip, whether a rule with a
//! probability fires, babble bytes) come from a ChaCha RNG seeded from the
//! bus seed, so the same seed gives the same faults.
//!
//! Every injected fault gets a [`FaultRecord`] in the [`FaultLog`]. The bus
//! attaches downstream [`Evidence`] to it: a receiver's error ack, a missing
//! ack at the transmitter, a receiver's [`report_error`] while receiving the
//! faulted packet, or the bus reset that an unplugged cable caused. A test
//! asserts `fault_log().undetected()` is empty.
//!
//! [`report_error`]: crate::node::NodeCtx::report_error

use firelink_wire::packet::{Ack, Tcode};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

use crate::id::PacketId;
use crate::node::NodeHandle;
use crate::time::{SimDuration, SimTime};
use crate::trace::PacketKind;

/// Index of a fault record in the [`FaultLog`].
pub use crate::id::FaultId;

/// Which packets a [`FaultRule`] applies to. Every field left `None` matches
/// anything.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PacketMatch {
    /// Transmitting node.
    pub source: Option<NodeHandle>,
    /// Destination physical ID (63 = broadcast).
    pub destination_phy: Option<u8>,
    /// Transaction code.
    pub tcode: Option<Tcode>,
    /// Low 16 bits of the destination offset (what the boards decode).
    pub offset_low16: Option<u16>,
    /// Packet role (requests, concatenated responses, duplicates, ...).
    pub kind: Option<PacketKind>,
    /// Only packets starting at or after this instant.
    pub after: Option<SimTime>,
    /// Only packets starting before this instant.
    pub before: Option<SimTime>,
    /// Let this many matching packets pass before the rule applies.
    pub skip: u64,
}

impl PacketMatch {
    /// Match every packet.
    pub fn any() -> PacketMatch {
        PacketMatch::default()
    }

    /// Only packets from `node`.
    pub fn from(mut self, node: NodeHandle) -> PacketMatch {
        self.source = Some(node);
        self
    }

    /// Only packets to physical ID `phy` (63 = broadcast).
    pub fn to_phy(mut self, phy: u8) -> PacketMatch {
        self.destination_phy = Some(phy);
        self
    }

    /// Only packets with this tcode.
    pub fn tcode(mut self, tcode: Tcode) -> PacketMatch {
        self.tcode = Some(tcode);
        self
    }

    /// Only packets whose offset's low 16 bits are `offset`.
    pub fn offset(mut self, offset: u16) -> PacketMatch {
        self.offset_low16 = Some(offset);
        self
    }

    /// Only packets of this role.
    pub fn kind(mut self, kind: PacketKind) -> PacketMatch {
        self.kind = Some(kind);
        self
    }

    /// Only packets starting in `[after, before)`.
    pub fn between(mut self, after: SimTime, before: SimTime) -> PacketMatch {
        self.after = Some(after);
        self.before = Some(before);
        self
    }

    /// Skip the first `n` matching packets.
    pub fn skip(mut self, n: u64) -> PacketMatch {
        self.skip = n;
        self
    }

    pub(crate) fn matches(
        &self,
        source: NodeHandle,
        kind: PacketKind,
        bytes: &[u8],
        now: SimTime,
    ) -> bool {
        let q0 = bytes
            .get(..4)
            .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
        let q2 = bytes
            .get(8..12)
            .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
        self.source.is_none_or(|s| s == source)
            && self.kind.is_none_or(|k| k == kind)
            && self
                .destination_phy
                .is_none_or(|d| q0.is_some_and(|q| (q >> 16) as u8 & 0x3F == d))
            && self
                .tcode
                .is_none_or(|t| q0.is_some_and(|q| Tcode::from((q >> 4) as u8 & 0xF) == t))
            && self
                .offset_low16
                .is_none_or(|o| q2.is_some_and(|q| q as u16 == o))
            && self.after.is_none_or(|a| now >= a)
            && self.before.is_none_or(|b| now < b)
    }
}

/// What to do to a matching packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PacketFault {
    /// The packet occupies the wire but no node receives it.
    Drop,
    /// Flip `count` random bits (CRCs are not fixed: receivers must notice).
    FlipBits {
        /// Bits to flip.
        count: u32,
    },
    /// XOR quadlet `index` with `xor` (ignored past the end of the packet).
    CorruptQuadlet {
        /// Quadlet index from the start of the packet.
        index: usize,
        /// Bits to flip.
        xor: u32,
    },
    /// Hold the packet back this long before it may arbitrate (for a
    /// concatenated response: the responder holds the bus this long).
    Delay(SimDuration),
    /// Send the packet a second time right after its subaction.
    Duplicate,
    /// The packet arrives but its ack is lost.
    DropAck,
    /// The packet arrives but its ack is corrupted (fails its check).
    CorruptAck,
    /// The addressee is busy: it does not take the packet (no write, no
    /// response) and acknowledges `ack_busy_X`, as a link whose receive
    /// FIFO is full does. Other nodes still hear the packet.
    AckBusy,
    /// The packet ends early: only its first `quadlets` quadlets reach the
    /// receivers (a PHY that stopped mid-packet).
    Truncate {
        /// Quadlets kept.
        quadlets: usize,
    },
}

/// A packet fault and when it applies.
#[derive(Clone, Debug, PartialEq)]
pub struct FaultRule {
    /// Which packets.
    pub matcher: PacketMatch,
    /// What to do.
    pub fault: PacketFault,
    /// How many times it may fire (`None`: unlimited).
    pub count: Option<u32>,
    /// Chance that a matching packet is hit (1.0 = always).
    pub probability: f64,
}

impl FaultRule {
    /// Apply `fault` once, to the first matching packet.
    pub fn once(matcher: PacketMatch, fault: PacketFault) -> FaultRule {
        FaultRule {
            matcher,
            fault,
            count: Some(1),
            probability: 1.0,
        }
    }

    /// Apply `fault` to every matching packet with `probability`.
    pub fn random(matcher: PacketMatch, fault: PacketFault, probability: f64) -> FaultRule {
        FaultRule {
            matcher,
            fault,
            count: None,
            probability,
        }
    }
}

/// A fault that happens at an instant rather than to a packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TimedFault {
    /// Unplug the cable between `node` and its parent (the root: all its
    /// cables). The node and everything behind it leave the bus; a bus reset
    /// follows. With `reconnect_after`, the cable is plugged back then
    /// (another reset).
    Disconnect {
        /// The node.
        node: NodeHandle,
        /// Plug back after this long.
        reconnect_after: Option<SimDuration>,
    },
    /// The node stops answering: it receives nothing (so acks nothing) and
    /// its transmit requests are discarded, for `duration` or for ever.
    StopAnswering {
        /// The node.
        node: NodeHandle,
        /// For how long (`None`: for ever).
        duration: Option<SimDuration>,
    },
    /// A bus reset with no change of topology (a PHY initiated it): every
    /// node learns a new generation, open transactions are flushed.
    BusReset,
    /// The node babbles: for `duration` it sends random garbage packets of
    /// `packet_len` bytes back to back with isochronous-style arbitration,
    /// starving everybody else.
    Babble {
        /// The node.
        node: NodeHandle,
        /// For how long.
        duration: SimDuration,
        /// Bytes per garbage packet.
        packet_len: usize,
    },
}

/// A script of faults for one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultPlan {
    /// Packet faults, tried in order on every packet.
    pub rules: Vec<FaultRule>,
    /// Timed faults.
    pub timed: Vec<(SimTime, TimedFault)>,
}

impl FaultPlan {
    /// An empty plan.
    pub fn new() -> FaultPlan {
        FaultPlan::default()
    }

    /// Add a packet fault rule.
    pub fn rule(mut self, rule: FaultRule) -> FaultPlan {
        self.rules.push(rule);
        self
    }

    /// Apply `fault` once to the first packet matching `matcher`.
    pub fn once(self, matcher: PacketMatch, fault: PacketFault) -> FaultPlan {
        self.rule(FaultRule::once(matcher, fault))
    }

    /// Add a timed fault.
    pub fn at(mut self, time: SimTime, fault: TimedFault) -> FaultPlan {
        self.timed.push((time, fault));
        self
    }
}

/// Downstream evidence that a fault was noticed.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EvidenceKind {
    /// The receiver answered with an error or busy ack.
    ErrorAck(u8),
    /// The transmitter got no valid ack.
    NoAck,
    /// A node reported an error while receiving the packet.
    Report(String),
    /// A bus reset told every node about the change.
    BusReset {
        /// The new generation.
        generation: u32,
    },
}

/// One piece of evidence.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Evidence {
    /// When.
    pub time: SimTime,
    /// Node index that noticed.
    pub node: usize,
    /// How.
    pub kind: EvidenceKind,
}

/// One injected fault.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct FaultRecord {
    /// Its id.
    pub id: FaultId,
    /// When it was injected.
    pub time: SimTime,
    /// What was done, in words.
    pub what: String,
    /// The packet hit (packet faults).
    pub packet: Option<PacketId>,
    /// The node concerned (sender for packet faults).
    pub node: Option<usize>,
    /// Which entry of the plan fired: the index in
    /// [`FaultPlan::rules`] for a packet fault, in [`FaultPlan::timed`]
    /// for a timed one (as added, in order).
    pub source: Option<FaultSource>,
    /// What noticed it downstream.
    pub evidence: Vec<Evidence>,
}

impl FaultRecord {
    /// Whether anything downstream noticed the fault.
    pub fn detected(&self) -> bool {
        !self.evidence.is_empty()
    }
}

/// The plan entry behind a fault record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultSource {
    /// A packet rule, by index (rules added later count on from the plan's).
    Rule(usize),
    /// A timed fault, by index in the order scheduled.
    Timed(usize),
}

/// Every fault injected in a run.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FaultLog {
    pub(crate) records: Vec<FaultRecord>,
}

impl FaultLog {
    /// All records, in injection order.
    pub fn records(&self) -> &[FaultRecord] {
        &self.records
    }

    /// Records with no downstream evidence.
    pub fn undetected(&self) -> Vec<&FaultRecord> {
        self.records.iter().filter(|r| !r.detected()).collect()
    }

    /// The record with this id.
    pub fn get(&self, id: FaultId) -> Option<&FaultRecord> {
        self.records.get(id as usize)
    }

    pub(crate) fn add(
        &mut self,
        time: SimTime,
        what: String,
        packet: Option<PacketId>,
        node: Option<usize>,
        source: Option<FaultSource>,
    ) -> FaultId {
        let id = self.records.len() as FaultId;
        self.records.push(FaultRecord {
            id,
            time,
            what,
            packet,
            node,
            source,
            evidence: Vec::new(),
        });
        id
    }

    pub(crate) fn add_evidence(&mut self, id: FaultId, evidence: Evidence) {
        if let Some(r) = self.records.get_mut(id as usize) {
            if !r.evidence.contains(&evidence) {
                r.evidence.push(evidence);
            }
        }
    }
}

/// What the injector decided for one packet.
#[derive(Clone, Debug, Default)]
pub(crate) struct Decision {
    pub drop: bool,
    pub delay: Option<SimDuration>,
    pub duplicate: bool,
    pub drop_ack: bool,
    pub corrupt_ack: bool,
    pub busy: bool,
    /// Keep only this many bytes (the smallest truncation wins).
    pub truncate: Option<usize>,
    /// (fault description, mutation) pairs, applied in order.
    pub mutations: Vec<Mutation>,
    /// What fired: description, fault, index of the rule.
    pub fired: Vec<(String, PacketFault, usize)>,
}

#[derive(Clone, Debug)]
pub(crate) enum Mutation {
    Flip(u32),
    Quadlet(usize, u32),
}

/// Applies a plan's packet rules with a seeded RNG.
#[derive(Debug)]
pub(crate) struct FaultInjector {
    rules: Vec<(FaultRule, u64, u32)>, // rule, matches seen, times fired
    pub rng: ChaCha8Rng,
}

impl FaultInjector {
    pub fn new(seed: u64) -> FaultInjector {
        FaultInjector {
            rules: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x1394_FA17_0000_0000),
        }
    }

    pub fn add_rule(&mut self, rule: FaultRule) {
        self.rules.push((rule, 0, 0));
    }

    pub fn scale_probabilities(&mut self, factor: f64) {
        if !factor.is_finite() || factor < 0.0 {
            return;
        }
        for (rule, _, _) in &mut self.rules {
            rule.probability = (rule.probability * factor).clamp(0.0, 1.0);
        }
    }

    pub fn is_empty(&self) -> bool {
        self.rules.is_empty()
    }

    /// A uniform float in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Decide whether a packet about to win arbitration is delayed instead:
    /// the sum of the delays of every matching delay rule, and a description.
    pub fn decide_delay(
        &mut self,
        source: NodeHandle,
        kind: PacketKind,
        bytes: &[u8],
        now: SimTime,
    ) -> Option<(SimDuration, String, Option<usize>)> {
        let d = self.decide_inner(source, kind, bytes, now, true);
        d.delay.map(|delay| {
            let what = d
                .fired
                .iter()
                .map(|(w, _, _)| w.as_str())
                .collect::<Vec<_>>()
                .join(", ");
            let rule = d.fired.first().map(|(_, _, r)| *r);
            (delay, what, rule)
        })
    }

    /// Decide the faults (other than delays) for a packet about to start.
    pub fn decide(
        &mut self,
        source: NodeHandle,
        kind: PacketKind,
        bytes: &[u8],
        now: SimTime,
    ) -> Decision {
        self.decide_inner(source, kind, bytes, now, false)
    }

    fn decide_inner(
        &mut self,
        source: NodeHandle,
        kind: PacketKind,
        bytes: &[u8],
        now: SimTime,
        delays: bool,
    ) -> Decision {
        let mut d = Decision::default();
        if self.rules.is_empty() {
            return d;
        }
        let mut rules = std::mem::take(&mut self.rules);
        for (index, (rule, seen, fired)) in rules.iter_mut().enumerate() {
            if rule.count.is_some_and(|c| *fired >= c) {
                continue;
            }
            if delays != matches!(rule.fault, PacketFault::Delay(_)) {
                continue;
            }
            if !rule.matcher.matches(source, kind, bytes, now) {
                continue;
            }
            *seen += 1;
            if *seen <= rule.matcher.skip {
                continue;
            }
            if rule.probability < 1.0 && self.unit() >= rule.probability {
                continue;
            }
            *fired += 1;
            let what = match &rule.fault {
                PacketFault::Drop => {
                    d.drop = true;
                    "drop".to_string()
                }
                PacketFault::FlipBits { count } => {
                    // Distinct bits: flipping one bit twice would leave
                    // the packet as it was and log a fault that is none.
                    let bits = bytes.len() as u64 * 8;
                    let mut flipped: Vec<u32> = Vec::new();
                    let wanted = u64::from(*count).min(bits) as usize;
                    while flipped.len() < wanted {
                        let bit = (self.rng.next_u64() % bits) as u32;
                        if !flipped.contains(&bit) {
                            flipped.push(bit);
                            d.mutations.push(Mutation::Flip(bit));
                        }
                    }
                    format!("flip bits {flipped:?}")
                }
                PacketFault::CorruptQuadlet { index, xor } => {
                    d.mutations.push(Mutation::Quadlet(*index, *xor));
                    format!("corrupt quadlet {index} ^ {xor:#010x}")
                }
                PacketFault::Delay(by) => {
                    d.delay = Some(d.delay.unwrap_or_default() + *by);
                    format!("delay {by}")
                }
                PacketFault::Duplicate => {
                    d.duplicate = true;
                    "duplicate".to_string()
                }
                PacketFault::DropAck => {
                    d.drop_ack = true;
                    "drop ack".to_string()
                }
                PacketFault::CorruptAck => {
                    d.corrupt_ack = true;
                    "corrupt ack".to_string()
                }
                PacketFault::AckBusy => {
                    d.busy = true;
                    "ack busy".to_string()
                }
                PacketFault::Truncate { quadlets } => {
                    let keep = quadlets.saturating_mul(4);
                    d.truncate = Some(d.truncate.map_or(keep, |k| k.min(keep)));
                    format!("truncate to {quadlets} quadlets")
                }
            };
            d.fired.push((what, rule.fault.clone(), index));
        }
        self.rules = rules;
        d
    }
}

impl Mutation {
    pub fn apply(&self, bytes: &mut [u8]) {
        match *self {
            Mutation::Flip(bit) => {
                if let Some(b) = bytes.get_mut((bit / 8) as usize) {
                    *b ^= 0x80 >> (bit % 8);
                }
            }
            Mutation::Quadlet(index, xor) => {
                let start = index.saturating_mul(4);
                if let Some(q) = bytes.get_mut(start..start.saturating_add(4)) {
                    for (b, x) in q.iter_mut().zip(xor.to_be_bytes()) {
                        *b ^= x;
                    }
                }
            }
        }
    }
}

/// Corrupt an ack byte so its complement check fails.
pub(crate) fn corrupt_ack_byte(ack: Ack) -> u8 {
    ack.to_byte() ^ 0x01
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_stay_in_bounds() {
        let mut b = vec![0u8; 6];
        Mutation::Flip(0).apply(&mut b);
        assert_eq!(b[0], 0x80);
        Mutation::Flip(1000).apply(&mut b);
        Mutation::Quadlet(1, 0xFFFF_FFFF).apply(&mut b); // only 2 bytes left: ignored
        assert_eq!(b, vec![0x80, 0, 0, 0, 0, 0]);
        Mutation::Quadlet(0, 0x0000_00FF).apply(&mut b);
        assert_eq!(b[3], 0xFF);
        assert!(Ack::from_byte(corrupt_ack_byte(Ack::Complete)).is_err());
    }

    #[test]
    fn rules_count_skip_and_match() {
        let mut inj = FaultInjector::new(1);
        inj.add_rule(FaultRule::once(
            PacketMatch::any().to_phy(63).skip(1),
            PacketFault::Drop,
        ));
        let bcast = [0xFF, 0xFF, 0x00, 0x00];
        let uni = [0xFF, 0xC1, 0x00, 0x00];
        let h = NodeHandle(0);
        let t = SimTime(0);
        assert!(!inj.decide(h, PacketKind::Request, &uni, t).drop);
        assert!(!inj.decide(h, PacketKind::Request, &bcast, t).drop);
        assert!(inj.decide(h, PacketKind::Request, &bcast, t).drop);
        assert!(!inj.decide(h, PacketKind::Request, &bcast, t).drop);
        assert!(!inj.decide(h, PacketKind::Request, &[], t).drop);
        let mut inj = FaultInjector::new(1);
        inj.add_rule(FaultRule::once(
            PacketMatch::any(),
            PacketFault::Delay(SimDuration::from_micros(2)),
        ));
        assert!(inj.decide(h, PacketKind::Request, &uni, t).fired.is_empty());
        let (d, _, rule) = inj.decide_delay(h, PacketKind::Request, &uni, t).unwrap();
        assert_eq!(rule, Some(0));
        assert_eq!(d, SimDuration::from_micros(2));
        assert!(inj.decide_delay(h, PacketKind::Request, &uni, t).is_none());
    }
}
