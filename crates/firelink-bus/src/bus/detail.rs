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
