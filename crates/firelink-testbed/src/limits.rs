//! The value rules of every number a front end accepts: rates, periods,
//! run lengths, probabilities, IDs, counts, time-outs and the watchdog.
//!
//! Each rule takes the text as typed and gives the value or one line
//! naming the value and the range: out of range, not finite or not a
//! number is refused before anything runs. Nothing downstream can then
//! panic building a `Duration` from `1e300`, wrap a node ID modulo 64
//! into a broadcast, or turn a watchdog off by accident. The command line
//! hands these functions to clap (`value_parser = fn(&str) -> Result<T,
//! String>`); other front ends may call them on their own text, or, when
//! they are handed numbers rather than text (Python), check them against
//! the same ranges: [`Span`] constants for the real rules (`RATE_HZ`,
//! `RUN_SECONDS`, ...) and `RangeInclusive` constants for the integer ones
//! (`NODE_ID`, `BOARD_ID`, ...).

use firelink_control::ServoPeriod;
pub use firelink_host::WatchdogSetting;
/// A number as decimal or `0x` hex, `_` separators allowed (the packet
/// records' rule).
pub use firelink_host::packet_json::parse_number;
use firelink_wire::human::Number;
use std::ops::RangeInclusive;

/// The range a real value must lie in, and its unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    /// The lowest value.
    pub lo: f64,
    /// Whether `lo` itself is refused (the value must be above it).
    pub above: bool,
    /// The highest value (included).
    pub hi: f64,
    /// The unit, with its leading space (`" s"`), or empty.
    pub unit: &'static str,
}

impl Span {
    /// `lo..=hi`.
    pub const fn closed(lo: f64, hi: f64, unit: &'static str) -> Span {
        Span {
            lo,
            above: false,
            hi,
            unit,
        }
    }

    /// Above `lo`, at most `hi`.
    pub const fn above(lo: f64, hi: f64, unit: &'static str) -> Span {
        Span {
            lo,
            above: true,
            hi,
            unit,
        }
    }

    /// Whether `x` lies in the span (NaN never does).
    pub fn contains(self, x: f64) -> bool {
        let low = if self.above {
            x > self.lo
        } else {
            x >= self.lo
        };
        low && x <= self.hi
    }
}

/// A control or I/O rate: 1 Hz to 100 kHz.
pub const RATE_HZ: Span = Span::closed(1.0, 100_000.0, " Hz");
/// A run length: above 0 and at most one day.
pub const RUN_SECONDS: Span = Span::above(0.0, 86_400.0, " s");
/// A run length where 0 means "until stopped": 0 to one year.
pub const SECONDS_OR_FOREVER: Span = Span::closed(0.0, 31_536_000.0, " s");
/// A wait or idle time: 0 to 1 s.
pub const WAIT_US: Span = Span::closed(0.0, 1e6, " us");
/// A control period: above 0, at most 1 s.
pub const PERIOD_US: Span = Span::above(0.0, 1e6, " us");
/// A probability.
pub const PROBABILITY: Span = Span::closed(0.0, 1.0, "");

/// A physical node ID: 0..=62, and 63 for broadcast.
pub const NODE_ID: RangeInclusive<u64> = 0..=63;
/// A board ID (the rotary switch).
pub const BOARD_ID: RangeInclusive<u64> = 0..=15;
/// Emulated boards on one bus (the board-ID space).
pub const BOARD_COUNT: RangeInclusive<u64> = 1..=16;
/// Cycles to run.
pub const CYCLES: RangeInclusive<u64> = 1..=1_000_000_000;
/// Cycles, periods or reads whose every time is kept.
pub const MEASURED: RangeInclusive<u64> = 1..=10_000_000;
/// Board counts of a benchmark: up to 62 (above 16, the board-ID space,
/// modelled from a measured count).
pub const BENCH_BOARD_COUNT: RangeInclusive<u64> = 1..=62;
/// Quadlets of one register access (a block of 2048 bytes at most).
pub const QUADLETS: RangeInclusive<u64> = 1..=512;
/// A time-out in milliseconds: 1 ms to 60 s.
pub const TIMEOUT_MS: RangeInclusive<u64> = 1..=60_000;

/// A finite number in `span`.
fn bounded(s: &str, span: Span) -> Result<f64, String> {
    let x: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if !x.is_finite() || !span.contains(x) {
        let low = if span.above { "above" } else { "from" };
        return Err(format!(
            "{} is out of range: {low} {} to {}{}",
            s.trim(),
            Number(span.lo),
            Number(span.hi),
            span.unit
        ));
    }
    Ok(x)
}

/// A control or I/O rate: [`RATE_HZ`], 1 Hz to 100 kHz.
pub fn rate_hz(s: &str) -> Result<f64, String> {
    bounded(s, RATE_HZ)
}

/// A servo rate in Hz as a servo period (the older `--rate` spelling of
/// `--period`, the one parser of every program's `--rate`): a number, then
/// [`ServoPeriod`]'s one range rule, 1 Hz to 100 kHz, named in its error.
pub fn servo_rate_hz(s: &str) -> Result<firelink_control::ServoPeriod, String> {
    let hz: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number (a rate in Hz)"))?;
    firelink_control::ServoPeriod::from_rate_hz(hz).map_err(|e| e.to_string())
}

/// An I/O rate where 0 means "as fast as possible": 0, or 1 Hz to 100 kHz.
pub fn rate_hz_or_max(s: &str) -> Result<f64, String> {
    if s.trim().parse::<f64>().is_ok_and(|x| x == 0.0) {
        return Ok(0.0);
    }
    rate_hz(s)
}

/// A run length in seconds: [`RUN_SECONDS`], above 0 and at most one day.
pub fn run_seconds(s: &str) -> Result<f64, String> {
    bounded(s, RUN_SECONDS)
}

/// A run length in seconds where 0 means "until stopped":
/// [`SECONDS_OR_FOREVER`], 0 to one year.
pub fn seconds_or_forever(s: &str) -> Result<f64, String> {
    bounded(s, SECONDS_OR_FOREVER)
}

/// A wait or idle time in microseconds: [`WAIT_US`], 0 to 1 s.
pub fn wait_us(s: &str) -> Result<f64, String> {
    bounded(s, WAIT_US)
}

/// A control period in microseconds: [`PERIOD_US`], above 0, at most 1 s.
pub fn period_us(s: &str) -> Result<f64, String> {
    bounded(s, PERIOD_US)
}

/// A servo period given in microseconds, MAHRU's bounds
/// ([`mahru_period_us`]: 100 us to 1 s).
pub fn servo_period_us(s: &str) -> Result<ServoPeriod, String> {
    ServoPeriod::from_micros_f64(mahru_period_us(s)?).map_err(|e| e.to_string())
}

/// A servo period as [`ServoPeriod`] reads it (`2ms`, `500Hz`, `250us`),
/// within MAHRU's bounds (100 us to 1 s; the period's own rule allows
/// 10 us): `budget --period`.
pub fn mahru_servo_period(s: &str) -> Result<ServoPeriod, String> {
    let period = s.parse::<ServoPeriod>().map_err(|e| e.to_string())?;
    crate::mahru::demo::check_period(period.as_duration()).map_err(|e| e.to_string())?;
    Ok(period)
}

/// A soak's servo period as [`ServoPeriod`] reads it, shorter than the
/// boards' watchdog ([`crate::dvrk::soak::watchdog_allows`]): `soak
/// --period`, refused as a usage error.
pub fn soak_servo_period(s: &str) -> Result<ServoPeriod, String> {
    let period = s.parse::<ServoPeriod>().map_err(|e| e.to_string())?;
    crate::dvrk::soak::watchdog_allows(period).map_err(|e| e.to_string())?;
    Ok(period)
}

/// A probability: [`PROBABILITY`], 0 to 1.
pub fn probability(s: &str) -> Result<f64, String> {
    bounded(s, PROBABILITY)
}

/// `--cpu-latency`: hold the CPUs' wake-up latency at some microseconds,
/// or do not hold it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CpuLatencyRequest {
    /// No request.
    Off,
    /// Hold this many microseconds.
    Microseconds(u32),
}

impl CpuLatencyRequest {
    /// The latency to hold, in microseconds; `None`: no request.
    pub fn microseconds(self) -> Option<u32> {
        match self {
            CpuLatencyRequest::Off => None,
            CpuLatencyRequest::Microseconds(us) => Some(us),
        }
    }
}

/// `off`, or microseconds from 0 to 1 s (a request above that would ask
/// for nothing the idle governor does not do anyway).
pub fn cpu_latency(s: &str) -> Result<CpuLatencyRequest, String> {
    if s.eq_ignore_ascii_case("off") {
        return Ok(CpuLatencyRequest::Off);
    }
    let n = parse_number(s)
        .map_err(|_| format!("a CPU latency is microseconds (0 to 1000000) or off, not {s:?}"))?;
    if n > 1_000_000 {
        return Err(format!("CPU latency {n} us is out of range: 0 to 1000000"));
    }
    Ok(CpuLatencyRequest::Microseconds(n as u32))
}

/// An unsigned integer in `range` (decimal or 0x hex).
fn integer(s: &str, range: RangeInclusive<u64>, what: &str) -> Result<u64, String> {
    let n = parse_number(s)?;
    if !range.contains(&n) {
        return Err(format!(
            "{what} {n} is out of range: {} to {}",
            range.start(),
            range.end()
        ));
    }
    Ok(n)
}

/// A physical node ID: 0..=62, or 63 for broadcast. Larger values are
/// rejected (they used to wrap modulo 64, so 127 became a broadcast).
pub fn node_id(s: &str) -> Result<u8, String> {
    integer(s, NODE_ID, "node ID (0..=62, 63 = broadcast)").map(|n| n as u8)
}

/// A board ID (rotary switch): 0..=15.
pub fn board_id(s: &str) -> Result<u8, String> {
    integer(s, BOARD_ID, "board ID").map(|n| n as u8)
}

/// A number of emulated boards on one bus: 1..=16 (the board-ID space).
pub fn board_count(s: &str) -> Result<u8, String> {
    let n = parse_number(s)?;
    if !BOARD_COUNT.contains(&n) {
        return Err(format!("{n} is out of range: between 1 and 16 boards"));
    }
    Ok(n as u8)
}

/// Cycles to run: 1 to 10^9.
pub fn cycles(s: &str) -> Result<u64, String> {
    integer(s, CYCLES, "number of cycles")
}

/// Cycles, periods or reads whose every time is kept (a benchmark's
/// measured cycles, `budget --periods` and `--reads`): 1 to 10^7, tens of
/// megabytes of samples at most.
pub fn measured(s: &str) -> Result<u64, String> {
    integer(s, MEASURED, "number of measured cycles")
}

/// `budget --samples`: timings per transaction type and module, 1 to
/// [`MAX_TIMINGS`](crate::mahru::budget::MAX_TIMINGS).
pub fn timings(s: &str) -> Result<u64, String> {
    let hi = u64::from(crate::mahru::budget::MAX_TIMINGS);
    integer(s, 1..=hi, "number of timings")
}

/// `budget --can-cycles`: 1 to
/// [`MAX_CAN_CYCLES`](crate::mahru::can::MAX_CAN_CYCLES).
pub fn can_cycles(s: &str) -> Result<u64, String> {
    let hi = u64::from(crate::mahru::can::MAX_CAN_CYCLES);
    integer(s, 1..=hi, "number of CAN cycles")
}

/// MAHRU's control period in microseconds: the configuration's bounds,
/// 100 us to 1 s.
pub fn mahru_period_us(s: &str) -> Result<f64, String> {
    let (lo, hi) = crate::mahru::config::bounds::PERIOD_US;
    bounded(s, Span::closed(lo, hi, " us"))
}

/// Quadlets of one register access: 1..=512 (a block of 2048 bytes).
pub fn quadlets(s: &str) -> Result<usize, String> {
    integer(s, QUADLETS, "number of quadlets").map(|n| n as usize)
}

/// A time-out in milliseconds: 1 ms to 60 s.
pub fn timeout_ms(s: &str) -> Result<u64, String> {
    integer(s, TIMEOUT_MS, "time-out (ms)")
}

/// `--watchdog-ms`: `off`, or a period in milliseconds the WATCHDOG
/// register can hold (one 5.208 us tick to 65535 ticks). 0, negative values
/// and periods under one tick are refused: they used to turn the watchdog
/// off silently. The one rule is `WatchdogSetting::parse`.
pub fn watchdog(s: &str) -> Result<WatchdogSetting, String> {
    WatchdogSetting::parse(s).map_err(|e| format!("{s:?}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_older_rate_spelling_is_a_servo_period_under_its_one_rule() {
        let p = servo_rate_hz(" 1000 ").unwrap();
        assert_eq!(p, "1ms".parse::<firelink_control::ServoPeriod>().unwrap());
        for bad in ["0", "-5", "1e6", "NaN", "inf"] {
            let e = servo_rate_hz(bad).unwrap_err();
            assert!(
                e.contains("servo period") && e.contains("out of range"),
                "{bad}: {e}"
            );
        }
        assert!(servo_rate_hz("1kHz").unwrap_err().contains("not a number"));
    }

    #[test]
    fn numbers_out_of_range_are_rejected_with_the_range() {
        for bad in ["-5", "0", "NaN", "inf", "1e300", "1e-300", "x", ""] {
            assert!(rate_hz(bad).is_err(), "{bad}");
        }
        assert_eq!(rate_hz("6000").unwrap(), 6000.0);
        assert_eq!(rate_hz_or_max("0").unwrap(), 0.0);
        assert!(rate_hz_or_max("1e-300").is_err());
        assert!(run_seconds("NaN").is_err());
        assert!(run_seconds("-1").is_err());
        assert!(seconds_or_forever("0").is_ok());
        assert!(seconds_or_forever("-1").is_err());
        assert!(seconds_or_forever("1e300").is_err());
        assert!(wait_us("-5").unwrap_err().contains("out of range"));
        assert!(wait_us("NaN").is_err());
        assert!(period_us("1e300").is_err());
        assert!(probability("2").is_err());
        assert!(probability("0.01").is_ok());
        assert!(cycles("0").is_err());
        assert!(quadlets("513").is_err());
        assert!(timeout_ms("0").is_err());
    }

    #[test]
    fn ids_do_not_wrap() {
        assert_eq!(node_id("63").unwrap(), 63);
        assert!(node_id("64").is_err());
        assert!(node_id("127").is_err());
        assert!(node_id("0x40").is_err());
        assert_eq!(board_id("15").unwrap(), 15);
        assert!(board_id("16").is_err());
        assert!(board_count("0").is_err());
        assert!(board_count("17").is_err());
    }

    #[test]
    fn watchdog_off_is_explicit() {
        assert_eq!(watchdog("off").unwrap(), WatchdogSetting::Off);
        assert!(WatchdogSetting::Off.warning().is_some());
        for bad in ["0", "-5", "NaN", "1e300", "342", "zero"] {
            assert!(watchdog(bad).is_err(), "{bad}");
        }
        let w = watchdog("20").unwrap();
        assert_eq!(w.period(), Some(Duration::from_millis(20)));
        assert!(w.warning().is_none());
        assert!(watchdog("341").is_ok());
        for sub_tick in ["1e-7", "1e-9", "0.005"] {
            let e = watchdog(sub_tick).unwrap_err();
            assert!(e.contains("one firmware tick"), "{e}");
        }
    }

    mod props {
        use super::*;
        use proptest::prelude::*;

        /// Every float parser: (parser, lowest accepted, highest, whether
        /// the low end is open, whether 0 is accepted besides the range).
        type FloatParser = fn(&str) -> Result<f64, String>;
        const FLOATS: &[(FloatParser, f64, f64, bool, bool)] = &[
            (rate_hz, 1.0, 1e5, false, false),
            (rate_hz_or_max, 1.0, 1e5, false, true),
            (run_seconds, 0.0, 86_400.0, true, false),
            (seconds_or_forever, 0.0, 31_536_000.0, false, false),
            (wait_us, 0.0, 1e6, false, false),
            (period_us, 0.0, 1e6, true, false),
            (mahru_period_us, 100.0, 1e6, false, false),
            (probability, 0.0, 1.0, false, false),
        ];

        /// Every integer parser with its range.
        type IntParser = fn(&str) -> Result<u64, String>;
        const INTEGERS: &[(IntParser, u64, u64)] = &[
            (cycles, 1, 1_000_000_000),
            (measured, 1, 10_000_000),
            (timings, 1, 100_000),
            (can_cycles, 1, 1_000_000),
            (timeout_ms, 1, 60_000),
        ];

        fn float_text() -> impl Strategy<Value = String> {
            prop_oneof![
                any::<f64>().prop_map(|x| x.to_string()),
                any::<f64>().prop_map(|x| format!("{x:e}")),
                (-400i32..400).prop_map(|e| format!("1e{e}")),
                (-400i32..400).prop_map(|e| format!("-2.5e{e}")),
                Just("NaN".to_string()),
                Just("inf".to_string()),
                Just("-inf".to_string()),
                "[ 0-9eE.+-]{0,12}",
                ".{0,8}",
            ]
        }

        fn integer_text() -> impl Strategy<Value = String> {
            prop_oneof![
                any::<u64>().prop_map(|x| x.to_string()),
                any::<u64>().prop_map(|x| format!("{x:#x}")),
                any::<i64>().prop_map(|x| x.to_string()),
                (0u64..2_000_000_000).prop_map(|x| x.to_string()),
                "[0-9xa-f_]{0,24}",
                ".{0,8}",
            ]
        }

        proptest! {
            /// A float parser accepts only finite numbers in its range,
            /// refuses the rest with one line that echoes the text as
            /// given (never 300 digits), and never panics.
            #[test]
            fn float_parsers_accept_only_their_range(text in float_text()) {
                for &(parse, lo, hi, open_low, zero) in FLOATS {
                    match parse(&text) {
                        Ok(x) => {
                            prop_assert!(x.is_finite(), "{} -> {}", text, x);
                            let low_ok = if open_low { x > lo } else { x >= lo };
                            prop_assert!((low_ok && x <= hi) || (zero && x == 0.0), "{} -> {}", text, x);
                            // What the value becomes downstream cannot panic.
                            if x > 0.0 {
                                let _ = Duration::from_secs_f64(x / 1e6);
                                let _ = Duration::from_secs_f64(x);
                                let _ = Duration::from_secs_f64(1.0 / x.max(1e-9));
                            }
                        }
                        Err(e) => {
                            // The text is echoed as typed; nothing else
                            // in the line is a number written out in full.
                            let rest = e.replace(text.trim(), "");
                            prop_assert!(!e.contains('\n'), "{}", e);
                            prop_assert!(rest.len() < 200, "{}", e);
                            prop_assert!(!rest.contains("0000000000000"), "{}", e);
                        }
                    }
                }
            }

            /// An integer parser accepts only its range (no wrapping), and
            /// says the range when it refuses.
            #[test]
            fn integer_parsers_accept_only_their_range(text in integer_text()) {
                for &(parse, lo, hi) in INTEGERS {
                    match parse(&text) {
                        Ok(n) => prop_assert!((lo..=hi).contains(&n), "{} -> {}", text, n),
                        Err(e) => prop_assert!(
                            e.contains("out of range") || e.contains("not a number"),
                            "{}",
                            e
                        ),
                    }
                }
                match node_id(&text) {
                    Ok(n) => prop_assert!(n <= 63),
                    Err(e) => prop_assert!(!e.is_empty()),
                }
                match board_id(&text) {
                    Ok(n) => prop_assert!(n <= 15),
                    Err(e) => prop_assert!(!e.is_empty()),
                }
                match board_count(&text) {
                    Ok(n) => prop_assert!((1..=16).contains(&n)),
                    Err(e) => prop_assert!(!e.is_empty()),
                }
                match quadlets(&text) {
                    Ok(n) => prop_assert!((1..=512).contains(&n)),
                    Err(e) => prop_assert!(!e.is_empty()),
                }
            }

            /// The watchdog parser gives `off` only for the word, and a
            /// period the register holds otherwise.
            #[test]
            fn watchdog_is_off_only_by_name(text in float_text()) {
                if let Ok(w) = watchdog(&text) {
                    match w.period() {
                        None => prop_assert_eq!(text.trim(), "off"),
                        Some(p) => prop_assert!(p > Duration::ZERO && p <= Duration::from_millis(342)),
                    }
                }
            }
        }
    }
}
