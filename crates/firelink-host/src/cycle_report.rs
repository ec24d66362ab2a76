//! What a robot's I/O cycle reports, whichever boards it runs: the
//! cycle's [`CycleReport`] (fixed size, `Copy`), the counters over all
//! cycles ([`IoStats`]) and the hub's timing quadlet in us
//! ([`HubReadTimes`]). Every robot's I/O system fills in the same ones
//! (the QLA family's [`IoSystem`](crate::qla::io::IoSystem) with each of
//! its protocols, the [`SnakeSystem`](crate::snake::SnakeSystem)); the
//! runner reads them through [`RobotIo`](crate::RobotIo), the demo's
//! report and the soak from the runner or the system. The broadcast
//! protocol's fields (update times, the hub's timing) stay zero where
//! there is no hub.

use std::time::Duration;

use firelink_wire::qla::MAX_BOARDS;

use crate::error::{HostError, MissReason};

/// The hub's timing quadlet (`read_start:16 | now:16`, timers counting
/// from the query) in us: when the hub read started and when the quadlet
/// itself was read. The timers count the board's 49.152 MHz system clock
/// on the FireWire bus and behind the bridge, the 125 MHz Ethernet clock
/// on the Ethernet-only network (EthBasePort `GetBroadcastReadClockPeriod`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HubReadTimes {
    /// When the hub read started, us after the query.
    pub read_start_us: f32,
    /// When the timing quadlet was read, us after the query.
    pub read_end_us: f32,
}

impl HubReadTimes {
    /// No hub read yet.
    pub const ZERO: HubReadTimes = HubReadTimes {
        read_start_us: 0.0,
        read_end_us: 0.0,
    };

    /// The timing quadlet `word` of timers counting at `clock_hz`.
    #[inline]
    pub fn from_word(word: u32, clock_hz: u32) -> HubReadTimes {
        let timing = firelink_wire::qla::broadcast::HubTiming::from_word(word);
        HubReadTimes {
            read_start_us: hub_ticks_us(u32::from(timing.read_start), clock_hz),
            read_end_us: hub_ticks_us(u32::from(timing.now), clock_hz),
        }
    }
}

/// `ticks` of a hub timer counting at `clock_hz`, in us (0 Hz reads as
/// 1 Hz rather than dividing by zero). (Inlined into the hub read's loop
/// over its boards.)
#[inline]
pub fn hub_ticks_us(ticks: u32, clock_hz: u32) -> f32 {
    (f64::from(ticks) * 1e6 / f64::from(clock_hz.max(1))) as f32
}

/// What happened in the last cycle. `Copy`, fixed size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleReport {
    /// Cycle number (from 1).
    pub cycle: u64,
    /// Query sequence number (broadcast protocol: the cycle's first query;
    /// each board's own in `query_seq`), 0 otherwise.
    pub seq: u16,
    /// Broadcast protocol: the sequence number of the query that selected
    /// each board this cycle (its group's), by board ID; 0 otherwise.
    pub query_seq: [u16; MAX_BOARDS],
    /// Port time when the read phase started.
    pub started: Duration,
    /// Duration of the read phase (query + wait + hub read, or all reads).
    pub read_time: Duration,
    /// Duration of the write phase.
    pub write_time: Duration,
    /// Bit i set: board ID i missed this cycle: exactly the IDs with a
    /// reason in `reasons` ([`note_miss`](Self::note_miss) sets both; the
    /// runner reads the mask alone).
    pub missed: u16,
    /// Why each missed board missed, by board ID.
    pub reasons: [Option<MissReason>; MAX_BOARDS],
    /// Broadcast protocol: when each board's block reached the hub, in us
    /// after its query (from the hub headers, counted at the port's
    /// [`Port::hub_clock_hz`](crate::port::Port::hub_clock_hz)), by board ID.
    pub update_time_us: [f32; MAX_BOARDS],
    /// Broadcast protocol: the hub's timing quadlet of the cycle's last
    /// hub block, at the same clock.
    pub hub_read: HubReadTimes,
    /// The first port error of the cycle, if any.
    pub error: Option<HostError>,
    /// A bus reset was seen in this cycle (whatever the first error was):
    /// node numbers may have moved.
    pub bus_reset: bool,
}

impl CycleReport {
    /// A report of no cycle yet.
    pub const EMPTY: CycleReport = CycleReport {
        cycle: 0,
        seq: 0,
        query_seq: [0; MAX_BOARDS],
        started: Duration::ZERO,
        read_time: Duration::ZERO,
        write_time: Duration::ZERO,
        missed: 0,
        reasons: [None; MAX_BOARDS],
        update_time_us: [0.0; MAX_BOARDS],
        hub_read: HubReadTimes::ZERO,
        error: None,
        bus_reset: false,
    };

    /// This report made [`EMPTY`](Self::EMPTY) but for its cycle number,
    /// `cycle`: each field stored in place (the start of every cycle; a
    /// copy of the whole constant cost more).
    #[inline]
    pub fn restart(&mut self, cycle: u64) {
        let CycleReport {
            cycle: number,
            seq,
            query_seq,
            started,
            read_time,
            write_time,
            missed,
            reasons,
            update_time_us,
            hub_read,
            error,
            bus_reset,
        } = self;
        *number = cycle;
        *seq = 0;
        *query_seq = [0; MAX_BOARDS];
        *started = Duration::ZERO;
        *read_time = Duration::ZERO;
        *write_time = Duration::ZERO;
        *missed = 0;
        *reasons = [None; MAX_BOARDS];
        *update_time_us = [0.0; MAX_BOARDS];
        *hub_read = HubReadTimes::ZERO;
        *error = None;
        *bus_reset = false;
    }

    /// Whether every board took part and no error happened.
    pub fn all_ok(&self) -> bool {
        self.missed == 0 && self.error.is_none()
    }

    /// I/O time of the cycle (read + write phases).
    pub fn io_time(&self) -> Duration {
        self.read_time + self.write_time
    }

    /// Board IDs that missed the cycle, with the reason.
    pub fn missed_boards(&self) -> impl Iterator<Item = (u8, MissReason)> + '_ {
        self.reasons
            .iter()
            .enumerate()
            .filter_map(|(id, r)| r.map(|r| (id as u8, r)))
    }

    /// Board `board_id` missed this cycle for `reason`: in this report and
    /// counted in `stats`.
    pub fn note_miss(&mut self, stats: &mut IoStats, board_id: u8, reason: MissReason) {
        let id = usize::from(board_id & 0xF);
        self.missed |= 1 << id;
        if let Some(r) = self.reasons.get_mut(id) {
            *r = Some(reason);
        }
        if let Some(c) = stats.missed_by_board.get_mut(id) {
            *c += 1;
        }
        stats.count_miss(reason);
    }

    /// An error in this cycle: counted in `stats`, the first one kept.
    /// Returns whether it was a bus reset (node numbers may have moved:
    /// the caller finds its boards again between cycles).
    pub fn note_error(&mut self, stats: &mut IoStats, e: HostError) -> bool {
        stats.count_error(&e);
        if self.error.is_none() {
            self.error = Some(e);
        }
        let reset = matches!(e, HostError::BusReset { .. });
        self.bus_reset |= reset;
        reset
    }
}

/// Counters over all cycles, by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct IoStats {
    /// Cycles run (read phases).
    pub cycles: u64,
    /// Cycles in which every board answered.
    pub clean_cycles: u64,
    /// Misses per board ID.
    pub missed_by_board: [u64; MAX_BOARDS],
    /// Time-outs.
    pub timeouts: u64,
    /// Bus resets seen.
    pub bus_resets: u64,
    /// Bad packets (CRC, length) from the port.
    pub bad_packets: u64,
    /// Error acks or rcodes.
    pub nacks: u64,
    /// Sequence mismatches.
    pub sequence_errors: u64,
    /// Corrupt queries reported by boards.
    pub corrupt_queries: u64,
    /// Blocks naming the wrong board.
    pub wrong_board: u64,
    /// Blocks of the wrong size.
    pub block_size: u64,
    /// Other failures (socket errors, invalid requests).
    pub other: u64,
}

impl IoStats {
    /// Total errors of every kind.
    pub fn total_errors(&self) -> u64 {
        self.timeouts
            + self.bus_resets
            + self.bad_packets
            + self.nacks
            + self.sequence_errors
            + self.corrupt_queries
            + self.wrong_board
            + self.block_size
            + self.other
    }

    /// Count one error by its kind.
    pub fn count_error(&mut self, e: &HostError) {
        match e {
            HostError::Timeout { .. } | HostError::CycleDeadline { .. } => self.timeouts += 1,
            HostError::BusReset { .. } => self.bus_resets += 1,
            HostError::Wire(_) => self.bad_packets += 1,
            HostError::Ack { .. } | HostError::Rcode { .. } => self.nacks += 1,
            _ => self.other += 1,
        }
    }

    /// Count one missed board by its reason.
    pub fn count_miss(&mut self, reason: MissReason) {
        match reason {
            MissReason::Sequence { .. } | MissReason::NotUpdated => self.sequence_errors += 1,
            MissReason::CorruptQuery => self.corrupt_queries += 1,
            MissReason::WrongBoardId { .. } => self.wrong_board += 1,
            MissReason::BlockSize { .. } => self.block_size += 1,
            MissReason::Transaction => {}
        }
    }
}
