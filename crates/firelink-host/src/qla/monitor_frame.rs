//! `firelink monitor`'s screen, for any front end: one frame of every
//! axis of every board as text (like the dVRK's qladisp), the key that
//! flips each switch, and the pacing of the I/O loop ([`LiveView`]: the
//! cycles of a live view and a frame every [`FRAME_INTERVAL`]).

use std::time::{Duration, Instant};

use crate::Port;
use crate::qla::io::IoSystem;
use crate::qla::monitor::{MonitorFigures, Switch, explain_status, on_off};
use crate::stop::StopRequest;

/// Render one frame as text.
pub fn render<P: Port>(io: &IoSystem<P>, f: &MonitorFigures) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let stats = io.stats();
    let groups: Vec<String> = io
        .broadcast_groups()
        .map(|m| format!("boards {}", crate::qla::scan::mask_boards(m)))
        .collect();
    let _ = writeln!(
        s,
        "firelink monitor  port {}  protocol {}{}  hub board {}",
        io.port().name(),
        io.protocol_label(),
        if groups.len() > 1 {
            format!(" ({})", groups.join(" | "))
        } else {
            String::new()
        },
        io.hub_board()
    );
    let _ = writeln!(
        s,
        "cycles {}  rate {:.0} Hz  I/O last {:.1} us  max {:.1} us  errors {} (timeouts {}, sequence {}, bad packets {}, bus resets {})",
        f.cycles,
        f.rate_hz,
        f.last_io_us,
        f.max_io_us,
        stats.total_errors(),
        stats.timeouts,
        stats.sequence_errors,
        stats.bad_packets,
        stats.bus_resets
    );
    let link = io.port().link_stats();
    let _ = writeln!(
        s,
        "link: {} requests, {} answered, {} timed out; refused {} garbage, {} bad CRC, {} late, {} answering no request",
        link.sent,
        link.matched,
        link.timeouts,
        link.garbage,
        link.bad_crc,
        link.late,
        link.unmatched
    );
    let report = io.report();
    for (id, reason) in report.missed_boards() {
        let _ = writeln!(s, "  board {id} missed the last cycle: {reason}");
    }
    for b in io.boards() {
        let st = b.status();
        let _ = writeln!(
            s,
            "\nboard {} (node {}, {} fw {})  {}  power {}  relay {}  supply {}  watchdog {}  status {:08x}",
            b.board_id(),
            b.info().node,
            b.info().hardware.name(),
            b.info().firmware,
            if b.is_valid() { "ok   " } else { "STALE" },
            on_off(st.motor_power_enabled()),
            on_off(st.relay_on()),
            if st.motor_supply_good() {
                "good"
            } else if !st.motor_power_enabled() {
                "off "
            } else {
                "BAD "
            },
            if st.watchdog_timeout() {
                "EXPIRED"
            } else {
                "ok"
            },
            st.raw()
        );
        for line in explain_status(st, f.watchdog_of(b.board_id())) {
            let _ = writeln!(s, "  {line}");
        }
        let _ = writeln!(
            s,
            "  axis  encoder      vel c/s   pot    current A   amp  dac"
        );
        for axis in 0..b.axes() {
            let _ = writeln!(
                s,
                "  {:>4}  {:>9}  {:>10.0}  {:>5}  {:>10.3}   {}  {:04x}",
                axis + 1,
                b.encoder_counts(axis).unwrap_or(0),
                b.encoder_velocity(axis).unwrap_or(0.0),
                b.pot_bits(axis).unwrap_or(0),
                b.current_amps(axis).unwrap_or(0.0),
                if b.amp_enabled(axis) { "on " } else { "off" },
                b.dac(axis).unwrap_or(0)
            );
        }
    }
    let _ = writeln!(
        s,
        "\nkeys: p power  r relay  a amplifiers  z zero DACs  w watchdog 50 ms/off  q quit   {}",
        f.message
    );
    s
}

/// Sleep until cycle `cycles` of a loop paced at `period` from `start`
/// is due (a zero period: at once).
pub fn pace(start: Instant, cycles: u64, period: Duration) {
    if period.is_zero() {
        return;
    }
    crate::pacing::sleep_until(start + period.mul_f64(cycles as f64));
}

/// Run `cycles` I/O cycles (at least one) paced at `period`, each
/// recovered from and recorded in `f`, then the rate they achieved.
pub fn run_cycles<P: Port>(
    io: &mut IoSystem<P>,
    cycles: u64,
    period: Duration,
    f: &mut MonitorFigures,
) {
    let start = Instant::now();
    for _ in 0..cycles.max(1) {
        let r = *io.cycle();
        let _ = io.recover();
        f.record_cycle(r.io_time().as_secs_f64() * 1e6);
        pace(start, f.cycles, period);
    }
    f.rate_hz = f.cycles as f64 / start.elapsed().as_secs_f64().max(1e-9);
}

/// How often a live view shows a new frame: a human rate.
pub const FRAME_INTERVAL: Duration = Duration::from_millis(100);

/// A live view's I/O loop: cycles paced at one period from its start,
/// and a frame every [`FRAME_INTERVAL`] with the rate since the last.
#[derive(Debug, Clone)]
pub struct LiveView {
    start: Instant,
    period: Duration,
    last_frame: Instant,
    window_cycles: u64,
}

impl LiveView {
    /// A view whose cycles are paced at `period` (zero: as fast as they
    /// go) from now.
    pub fn new(period: Duration) -> LiveView {
        let now = Instant::now();
        LiveView {
            start: now,
            period,
            last_frame: now,
            window_cycles: 0,
        }
    }

    /// Run I/O cycles, each recovered from, recorded in `f` and paced,
    /// until a frame is due: then the frame (the window's rate and largest
    /// I/O time, which starts again). `None`: `stop` was requested.
    pub fn next_frame<P: Port>(
        &mut self,
        io: &mut IoSystem<P>,
        f: &mut MonitorFigures,
        stop: &StopRequest,
    ) -> Option<String> {
        loop {
            if stop.is_requested() {
                return None;
            }
            let r = *io.cycle();
            let _ = io.recover();
            f.record_cycle(r.io_time().as_secs_f64() * 1e6);
            self.window_cycles += 1;
            pace(self.start, f.cycles, self.period);
            let since = self.last_frame.elapsed();
            if since >= FRAME_INTERVAL {
                f.rate_hz = self.window_cycles as f64 / since.as_secs_f64();
                self.window_cycles = 0;
                self.last_frame = Instant::now();
                let frame = render(io, f);
                f.max_io_us = 0.0;
                return Some(frame);
            }
        }
    }
}

/// The switch a key flips.
pub fn switch_of(key: char) -> Option<Switch> {
    Some(match key {
        'p' => Switch::Power,
        'r' => Switch::Relay,
        'a' => Switch::Amplifiers,
        'z' => Switch::ZeroDacs,
        'w' => Switch::Watchdog,
        _ => return None,
    })
}
