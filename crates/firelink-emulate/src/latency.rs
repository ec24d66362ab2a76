//! How late the emulator answers: from a datagram's arrival (the kernel's
//! receive stamp) to its reply leaving the server's socket.
//!
//! A host that waits past its time-out (the reference host waits 20 ms
//! for a read's answer) cannot tell from its own side whether the
//! emulator answered late or the machine delivered the answer late. The
//! server therefore records every reply's latency in an
//! [`AnswerLatency`] and reports a [`LatencySummary`] with its counters:
//! the median, the 99th percentile and the maximum, and how many replies
//! left later than 1 ms and later than 20 ms after their datagram arrived.
//!
//! The histogram has a fixed size, allocated once: recording a reply
//! allocates nothing. Durations are passed in; nothing here reads a clock.
//!
//! Buckets are log-linear over nanoseconds: exact below 32 ns, then 32
//! buckets per power of two, so a percentile is reported as the upper
//! end of its bucket, at most 1/32 (3.1 %) above the true value and never
//! below it; the maximum and the two counts are exact.

use std::time::Duration;

/// Sub-buckets per power of two (as a shift).
const SUB_BITS: u32 = 5;
/// Sub-buckets per power of two.
const SUB: u64 = 1 << SUB_BITS;
/// Buckets covering every `u64` nanosecond value.
const BUCKETS: usize = ((64 - SUB_BITS as usize) + 1) * SUB as usize;

/// A reply later than this after its arrival is counted as late.
pub const LATE: Duration = Duration::from_millis(1);
/// A reply later than this after its arrival came after the reference
/// host's time-out (`EthBasePort`'s `ReceiveTimeout`, 20 ms).
pub const PAST_HOST_TIMEOUT: Duration = Duration::from_millis(20);

/// The bucket of `ns` nanoseconds.
fn bucket_of(ns: u64) -> usize {
    if ns < SUB {
        return ns as usize;
    }
    // The highest set bit, at least SUB_BITS here.
    let top = 63 - ns.leading_zeros();
    let mantissa = (ns >> (top - SUB_BITS)) & (SUB - 1);
    ((top - SUB_BITS + 1) as usize) * SUB as usize + mantissa as usize
}

/// The largest nanosecond value that falls in `bucket`.
fn bucket_top(bucket: usize) -> u64 {
    let bucket = bucket as u64;
    if bucket < SUB {
        return bucket;
    }
    let octave = bucket / SUB; // >= 1
    let mantissa = bucket % SUB;
    let shift = (octave - 1) as u32;
    let low = (SUB + mantissa) << shift;
    low.saturating_add((1u64 << shift) - 1)
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// Every reply's latency, in a fixed-size histogram.
#[derive(Clone)]
pub struct AnswerLatency {
    counts: Box<[u64; BUCKETS]>,
    answers: u64,
    max: Duration,
    over_late: u64,
    over_host_timeout: u64,
}

impl Default for AnswerLatency {
    fn default() -> Self {
        AnswerLatency::new()
    }
}

impl core::fmt::Debug for AnswerLatency {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_tuple("AnswerLatency")
            .field(&self.summary())
            .finish()
    }
}

impl AnswerLatency {
    /// Nothing recorded yet.
    pub fn new() -> AnswerLatency {
        AnswerLatency {
            counts: Box::new([0; BUCKETS]),
            answers: 0,
            max: Duration::ZERO,
            over_late: 0,
            over_host_timeout: 0,
        }
    }

    /// One reply sent `latency` after its datagram arrived.
    pub fn record(&mut self, latency: Duration) {
        if let Some(c) = self.counts.get_mut(bucket_of(nanos(latency))) {
            *c += 1;
        }
        self.answers += 1;
        self.max = self.max.max(latency);
        if latency > LATE {
            self.over_late += 1;
        }
        if latency > PAST_HOST_TIMEOUT {
            self.over_host_timeout += 1;
        }
    }

    /// The latency at or below which a fraction `q` (0..=1) of the replies
    /// left: the upper end of its bucket, never more than the maximum.
    /// Zero before any reply.
    pub fn quantile(&self, q: f64) -> Duration {
        if self.answers == 0 {
            return Duration::ZERO;
        }
        // The rank (1-based) of the reply that quantile names.
        let rank = ((q.clamp(0.0, 1.0) * self.answers as f64).ceil() as u64).clamp(1, self.answers);
        let mut seen = 0u64;
        for (bucket, &n) in self.counts.iter().enumerate() {
            seen += n;
            if seen >= rank {
                return Duration::from_nanos(bucket_top(bucket)).min(self.max);
            }
        }
        self.max
    }

    /// The counters as reported.
    pub fn summary(&self) -> LatencySummary {
        LatencySummary {
            answers: self.answers,
            p50: self.quantile(0.50),
            p99: self.quantile(0.99),
            max: self.max,
            later_than_1ms: self.over_late,
            later_than_20ms: self.over_host_timeout,
        }
    }
}

/// The answer latency of one run, as the stop line reports it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LatencySummary {
    /// Replies sent.
    pub answers: u64,
    /// Median from arrival to reply sent.
    pub p50: Duration,
    /// 99th percentile.
    pub p99: Duration,
    /// The longest.
    pub max: Duration,
    /// Replies sent later than 1 ms after their datagram arrived.
    pub later_than_1ms: u64,
    /// Replies sent later than 20 ms after their datagram arrived (after
    /// the reference host's time-out).
    pub later_than_20ms: u64,
}

/// A duration for people: microseconds below 1 ms, else milliseconds.
fn show(d: Duration) -> String {
    let us = d.as_secs_f64() * 1e6;
    if us < 1000.0 {
        format!("{us:.1} us")
    } else {
        format!("{:.2} ms", us / 1000.0)
    }
}

/// One line: `answer latency (arrival to reply sent) p50 .., p99 .., max
/// .., N later than 1 ms, M later than 20 ms`.
impl core::fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "answer latency (arrival to reply sent) p50 {}, p99 {}, max {}, \
             {} later than 1 ms, {} later than 20 ms",
            show(self.p50),
            show(self.p99),
            show(self.max),
            self.later_than_1ms,
            self.later_than_20ms
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    #[test]
    fn nothing_recorded_reports_zeros() {
        let h = AnswerLatency::new();
        assert_eq!(h.summary(), LatencySummary::default());
    }

    /// Every bucket holds the values that map to it: its top maps to it,
    /// one more maps to the next; tops increase and cover `u64`.
    #[test]
    fn buckets_tile_the_nanoseconds() {
        let mut last = None;
        for b in 0..BUCKETS {
            let top = bucket_top(b);
            assert_eq!(bucket_of(top), b, "bucket {b} top {top}");
            if let Some(prev) = last {
                assert!(top > prev);
                assert_eq!(bucket_of(prev + 1), b, "bucket {b} starts after {prev}");
            }
            last = Some(top);
        }
        assert_eq!(last, Some(u64::MAX));
    }

    /// A bucket's top is at most 1/32 above any value in it.
    #[test]
    fn relative_error_is_bounded() {
        for ns in [33u64, 1_000, 12_345, 999_999, 20_000_001, 3_000_000_000] {
            let top = bucket_top(bucket_of(ns));
            assert!(top >= ns);
            assert!((top - ns) as f64 <= ns as f64 / 32.0, "{ns} -> {top}");
        }
    }

    #[test]
    fn percentiles_max_and_late_counts_from_given_times() {
        let mut h = AnswerLatency::new();
        // 1000 replies: 980 at 10 us, 15 at 500 us, 3 at 2 ms, 2 at 25 ms.
        for _ in 0..980 {
            h.record(us(10));
        }
        for _ in 0..15 {
            h.record(us(500));
        }
        for _ in 0..3 {
            h.record(us(2_000));
        }
        for _ in 0..2 {
            h.record(us(25_000));
        }
        let s = h.summary();
        assert_eq!(s.answers, 1000);
        // The median and p99 within their bucket (<= 1/32 above).
        assert!(s.p50 >= us(10) && s.p50 <= us(10) + us(10) / 32, "{s:?}");
        assert!(s.p99 >= us(500) && s.p99 <= us(500) + us(500) / 32, "{s:?}");
        assert_eq!(s.max, us(25_000));
        assert_eq!(s.later_than_1ms, 5);
        assert_eq!(s.later_than_20ms, 2);
    }

    /// "Later than" is strict: exactly 1 ms and exactly 20 ms are not late.
    #[test]
    fn thresholds_are_strict() {
        let mut h = AnswerLatency::new();
        h.record(LATE);
        h.record(PAST_HOST_TIMEOUT);
        h.record(LATE + Duration::from_nanos(1));
        h.record(PAST_HOST_TIMEOUT + Duration::from_nanos(1));
        let s = h.summary();
        assert_eq!(s.later_than_1ms, 3);
        assert_eq!(s.later_than_20ms, 1);
        assert_eq!(s.max, PAST_HOST_TIMEOUT + Duration::from_nanos(1));
    }

    /// A percentile never exceeds the maximum, even when the maximum sits
    /// low in a wide bucket; one reply is its own p50, p99 and max.
    #[test]
    fn a_single_reply_is_every_percentile() {
        let mut h = AnswerLatency::new();
        h.record(Duration::from_nanos(1_000_001));
        let s = h.summary();
        assert_eq!(s.p50, s.max);
        assert_eq!(s.p99, s.max);
        assert_eq!(s.later_than_1ms, 1);
    }

    #[test]
    fn huge_latencies_saturate_without_panic() {
        let mut h = AnswerLatency::new();
        h.record(Duration::MAX);
        h.record(Duration::ZERO);
        let s = h.summary();
        assert_eq!(s.max, Duration::MAX);
        assert_eq!(s.p50, Duration::ZERO);
        assert_eq!(s.later_than_20ms, 1);
    }

    #[test]
    fn the_line_names_every_counter() {
        let mut h = AnswerLatency::new();
        h.record(us(12));
        h.record(us(21_000));
        let line = h.summary().to_string();
        assert!(line.contains("p50 12.0 us"), "{line}");
        assert!(line.contains("max 21.00 ms"), "{line}");
        assert!(line.contains("1 later than 1 ms"), "{line}");
        assert!(line.contains("1 later than 20 ms"), "{line}");
    }
}
