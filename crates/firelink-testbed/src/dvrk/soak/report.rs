//! What a soak is asked to do and what it reports: the settings (cycles, fault
//! rate, seed, target), the kinds of fault it injects with their names, the per-
//! kind outcome counts (detected, harmless, undetected) and the report with the
//! safety invariants' tallies.

use super::*;

/// What to run.
#[derive(Debug, Clone)]
pub struct SoakSettings {
    /// Servo cycles to run (re-arming included).
    pub cycles: u64,
    /// Seed of every random choice (faults, bus, plants).
    pub seed: u64,
    /// Share of all packets on the bus to fault. Faults go to the packets
    /// of the I/O cycle (12 a cycle with 8 boards: query, status
    /// broadcasts, hub read and response, command), each with the chance
    /// that makes this share of everything on the bus (acks included).
    pub packet_fault_rate: f64,
    /// On average one bus-level fault (reset, babble, unplug) per this
    /// many cycles.
    pub bus_fault_every: u64,
    /// The servo period (virtual time).
    pub period: ServoPeriod,
    /// The simulated bus's level of detail (the same answer either way).
    pub detail: Detail,
}

impl Default for SoakSettings {
    fn default() -> Self {
        SoakSettings {
            cycles: 1_000_000,
            seed: 1,
            packet_fault_rate: 0.01,
            bus_fault_every: 2_000,
            period: ServoPeriod::from_rate_hz(6_000.0).expect("6 kHz is a servo period"),
            detail: Detail::Fast,
        }
    }
}

/// Which packets a fault hits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    /// The host's broadcast query.
    Query,
    /// A board's status broadcast.
    Status,
    /// The host's hub read request.
    HubRequest,
    /// The hub board's response.
    HubResponse,
    /// The host's command broadcast.
    Command,
    /// The bus as a whole (resets, babble, cables).
    Bus,
}

/// What a fault does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// The packet is lost.
    Drop,
    /// Two bits flipped (CRCs left as they were).
    BitFlip,
    /// Held back 3 us.
    ShortDelay,
    /// Held back 60 us.
    LongDelay,
    /// Sent twice.
    Duplicate,
    /// Cut to its first two quadlets.
    Truncate,
    /// A bus reset.
    BusReset,
    /// A board sends garbage back to back for up to 300 us.
    Babble,
    /// A board's cable is unplugged and plugged back 1 to 5 ms later.
    Unplug,
}

impl Kind {
    pub(super) const PACKET: [Kind; 6] = [
        Kind::Drop,
        Kind::BitFlip,
        Kind::ShortDelay,
        Kind::LongDelay,
        Kind::Duplicate,
        Kind::Truncate,
    ];

    pub(super) fn name(self) -> &'static str {
        match self {
            Kind::Drop => "drop",
            Kind::BitFlip => "bit_flip",
            Kind::ShortDelay => "short_delay",
            Kind::LongDelay => "long_delay",
            Kind::Duplicate => "duplicate",
            Kind::Truncate => "truncate",
            Kind::BusReset => "bus_reset",
            Kind::Babble => "babble",
            Kind::Unplug => "unplug",
        }
    }

    pub(super) fn fault(self) -> Option<PacketFault> {
        Some(match self {
            Kind::Drop => PacketFault::Drop,
            Kind::BitFlip => PacketFault::FlipBits { count: 2 },
            Kind::ShortDelay => PacketFault::Delay(SimDuration::from_micros(3)),
            Kind::LongDelay => PacketFault::Delay(SimDuration::from_micros(60)),
            Kind::Duplicate => PacketFault::Duplicate,
            Kind::Truncate => PacketFault::Truncate { quadlets: 2 },
            _ => return None,
        })
    }
}

/// How the faults of one kind ended.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Outcomes {
    /// Injected (the bus logged them).
    pub injected: u64,
    /// Reported by the host with the right reason.
    pub detected: u64,
    /// Shown to have done no harm.
    pub harmless: u64,
    /// Neither.
    pub undetected: u64,
}

impl Outcomes {
    pub(super) fn add(&mut self, verdict: Verdict) {
        self.injected += 1;
        match verdict {
            Verdict::Detected => self.detected += 1,
            Verdict::Harmless(_) => self.harmless += 1,
            Verdict::Undetected => self.undetected += 1,
        }
    }
}

/// The soak's result (`firelink soak --json`).
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    /// Servo cycles run.
    pub cycles: u64,
    /// The seed.
    pub seed: u64,
    /// The servo period, us (`1e6 / rate`).
    pub period_us: f64,
    /// Virtual time run, seconds.
    pub virtual_s: f64,
    /// Packets on the bus.
    pub packets: u64,
    /// Faults injected.
    pub injected: u64,
    /// Share of packets faulted (packet faults over packets).
    pub packet_fault_share: f64,
    /// Faults the host reported with the right reason.
    pub detected: u64,
    /// Faults shown harmless.
    pub harmless: u64,
    /// Of those: the data the host used was proven fresh.
    pub harmless_fresh: u64,
    /// Of those: the host rejected the whole cycle for another fault.
    pub harmless_masked: u64,
    /// Of those: a lost or late command, held by every board a period
    /// later.
    pub harmless_command_held: u64,
    /// Of those: a spare hub response (answering a duplicated request)
    /// while the host's own hub read completed.
    pub harmless_spare: u64,
    /// Faults neither detected nor harmless (must be 0).
    pub undetected: u64,
    /// Commands a board applied that the host never sent (must be 0).
    pub bad_commands_applied: u64,
    /// Cycles in which a board that had acknowledged "amplifiers off" had
    /// one on while the robot was in Fault (must be 0).
    pub amplifier_on_after_off: u64,
    /// Cycles in Fault before every board acknowledged "amplifiers off"
    /// (the broadcast command and the watchdog cover them; for the record).
    pub disable_pending_cycles: u64,
    /// Faults the robot raised (each one re-armed).
    pub robot_faults: u64,
    /// Times the robot was re-armed (clear, configure, power, enable).
    pub rearms: u64,
    /// Faults by kind.
    pub by_kind: BTreeMap<String, Outcomes>,
    /// Faults by kind and target (`kind/target`).
    pub by_fault: BTreeMap<String, Outcomes>,
    /// The first few undetected faults, described.
    pub undetected_examples: Vec<String>,
    /// What ran at which level of detail: the cycles a fault touched ran
    /// at the packet level, the fault-free stretches fast.
    pub detail: DetailReport,
}

impl SoakReport {
    /// Whether every fault was accounted for and both safety invariants
    /// held.
    pub fn passed(&self) -> bool {
        self.undetected == 0 && self.bad_commands_applied == 0 && self.amplifier_on_after_off == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_packet_kind_has_a_fault_and_a_name() {
        for k in Kind::PACKET {
            assert!(k.fault().is_some(), "{k:?}");
            assert!(!k.name().is_empty());
        }
        assert!(Kind::BusReset.fault().is_none());
    }
}
