//! `firelink monitor`: a live terminal view of every axis of every board,
//! like the dVRK's qladisp. The I/O loop runs at full rate; the screen is
//! redrawn at a human rate (10 Hz). Keys toggle power, relay, amplifiers and
//! the watchdog.

use std::io::Write;
use std::time::{Duration, Instant};

use clap::Args;

use firelink_host::io::{IoOptions, IoSystem};
use firelink_host::scan::Protocol;
use firelink_host::{Port, WatchdogSetting};

use firelink_wire::board::address::{BoardRegister, Register};
use firelink_wire::board::registers::{StatusRead, Watchdog};
use firelink_wire::human::Number;

use crate::error::CliError;
use crate::ports::{PortArgs, open_port};

/// Options of `firelink monitor`.
#[derive(Args, Debug)]
pub struct MonitorArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// I/O protocol (default: the best the boards support).
    #[arg(long, value_enum)]
    pub protocol: Option<crate::args::ProtocolArg>,
    /// Target I/O rate in Hz (0 = as fast as possible, else 1 to 100000).
    #[arg(long, default_value_t = 1000.0, value_parser = crate::args::rate_hz_or_max)]
    pub rate: f64,
    /// Print one frame after this many cycles and exit (no terminal control).
    #[arg(long, value_parser = crate::args::cycles)]
    pub once: Option<u64>,
    /// Watchdog period set at start, in ms (above 0, at most 341), or
    /// `off`; absent: left as the boards have it.
    #[arg(long = "watchdog-ms", value_parser = crate::args::watchdog)]
    pub watchdog: Option<crate::args::WatchdogSetting>,
}

/// Running figures the monitor shows.
#[derive(Debug, Default, Clone)]
pub struct MonitorFigures {
    /// Cycles run.
    pub cycles: u64,
    /// Achieved cycle rate over the last display period, Hz.
    pub rate_hz: f64,
    /// I/O time of the last cycle, us.
    pub last_io_us: f64,
    /// Largest I/O time over the last display period, us.
    pub max_io_us: f64,
    /// A one-line message from the last key action.
    pub message: String,
    /// Each board's watchdog period as read from its WATCHDOG register,
    /// ms (0: off), by board ID; absent when it could not be read.
    pub watchdog_ms: Vec<(u8, f64)>,
}

/// Every board's watchdog period from its WATCHDOG register, ms (0: off);
/// boards whose register cannot be read are left out.
pub fn watchdog_periods<P: Port>(io: &mut IoSystem<P>) -> Vec<(u8, f64)> {
    let Ok(offset) = Register::board(BoardRegister::Watchdog).offset() else {
        return Vec::new();
    };
    let ids: Vec<u8> = io.boards().iter().map(|b| b.board_id()).collect();
    ids.into_iter()
        .filter_map(|id| {
            let raw = io.read_register(id, offset).ok()?;
            Some((id, Watchdog(raw).period().as_secs_f64() * 1e3))
        })
        .collect()
}

/// What a board's STATUS says about its motor supply and its watchdog,
/// in words, for the lines under the board (none when all is well):
/// why the supply is not good, and what an expired watchdog means.
fn explain(st: StatusRead, watchdog_ms: Option<f64>) -> Vec<String> {
    let mut lines = Vec::new();
    if !st.motor_supply_good() {
        lines.push(if !st.motor_power_enabled() {
            "supply off: motor power is not enabled (normal for idle boards)".to_string()
        } else if st.motor_supply_fault() {
            "supply FAULT: motor power is enabled but no motor supply is present".to_string()
        } else {
            "supply BAD: motor power is enabled but the motor supply is not up (still rising, \
             or too low)"
                .to_string()
        });
    }
    if st.watchdog_timeout() {
        let period = match watchdog_ms {
            Some(ms) if ms > 0.0 => {
                format!("its {} ms period", Number((ms * 1000.0).round() / 1000.0))
            }
            _ => "its period".to_string(),
        };
        lines.push(format!(
            "watchdog expired: at some point the host wrote nothing for longer than {period} \
             (normal for idle boards); it turned the amplifiers off and stays set until power \
             or an amplifier is enabled"
        ));
    }
    lines
}

/// Render one frame as text.
pub fn render<P: Port>(io: &IoSystem<P>, f: &MonitorFigures) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let stats = io.stats();
    let groups: Vec<String> = io
        .broadcast_groups()
        .map(|m| format!("boards {}", firelink_host::scan::mask_boards(m)))
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
        let period = f
            .watchdog_ms
            .iter()
            .find(|(id, _)| *id == b.board_id())
            .map(|&(_, ms)| ms);
        for line in explain(st, period) {
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

fn on_off(b: bool) -> &'static str {
    if b { "on " } else { "off" }
}

/// `firelink monitor`.
pub fn run(args: &MonitorArgs, out: &mut impl Write) -> Result<(), CliError> {
    let port = open_port(&args.port, "firelink monitor")?;
    let config = IoOptions {
        protocol: args.protocol.map(Protocol::from),
        ..IoOptions::default()
    };
    let (mut io, _scan) = IoSystem::open(port, config)?;
    if let Some(w) = args.watchdog {
        if let Some(warning) = w.warning() {
            eprintln!("monitor: {warning}");
        }
        io.set_watchdog(w)?;
    }
    let watchdog_ms = watchdog_periods(&mut io);
    let period = if args.rate > 0.0 {
        Duration::from_secs_f64(1.0 / args.rate)
    } else {
        Duration::ZERO
    };
    if let Some(cycles) = args.once {
        let mut f = MonitorFigures {
            watchdog_ms,
            ..MonitorFigures::default()
        };
        let start = Instant::now();
        for _ in 0..cycles.max(1) {
            let r = *io.cycle();
            let _ = io.recover();
            f.cycles += 1;
            f.last_io_us = r.io_time().as_secs_f64() * 1e6;
            f.max_io_us = f.max_io_us.max(f.last_io_us);
            pace(start, f.cycles, period);
        }
        f.rate_hz = f.cycles as f64 / start.elapsed().as_secs_f64().max(1e-9);
        write!(out, "{}", render(&io, &f))?;
        return Ok(());
    }
    let result = interactive(&mut io, period, watchdog_ms, out);
    // Power the boards down if this session switched anything on (the
    // one rule, RobotIo::power_down; dropping `io` would do it silently).
    if io.energised() != 0 {
        let done = firelink_host::RobotIo::power_down(&mut io);
        eprintln!("monitor: powered down: {done}");
    }
    result
}

fn pace(start: Instant, cycles: u64, period: Duration) {
    if period.is_zero() {
        return;
    }
    firelink_host::pacing::sleep_until(start + period.mul_f64(cycles as f64));
}

fn interactive<P: Port>(
    io: &mut IoSystem<P>,
    period: Duration,
    watchdog_ms: Vec<(u8, f64)>,
    out: &mut impl Write,
) -> Result<(), CliError> {
    use crossterm::event::{self, Event, KeyCode};
    use crossterm::{cursor, execute, terminal};

    terminal::enable_raw_mode()?;
    execute!(out, terminal::EnterAlternateScreen, cursor::Hide)?;
    let result = (|| -> Result<(), CliError> {
        let mut f = MonitorFigures {
            watchdog_ms,
            ..MonitorFigures::default()
        };
        let start = Instant::now();
        let mut last_draw = Instant::now();
        let mut window_cycles = 0u64;
        let mut power = false;
        let mut relay = false;
        let mut amps = false;
        let mut watchdog = false;
        let stop = firelink_host::stop::StopRequest::process();
        loop {
            if stop.is_requested() {
                return Ok(());
            }
            let r = *io.cycle();
            let _ = io.recover();
            f.cycles += 1;
            window_cycles += 1;
            f.last_io_us = r.io_time().as_secs_f64() * 1e6;
            f.max_io_us = f.max_io_us.max(f.last_io_us);
            pace(start, f.cycles, period);
            if last_draw.elapsed() < Duration::from_millis(100) {
                continue;
            }
            f.rate_hz = window_cycles as f64 / last_draw.elapsed().as_secs_f64();
            window_cycles = 0;
            last_draw = Instant::now();
            let frame = render(io, &f).replace('\n', "\r\n");
            execute!(
                out,
                cursor::MoveTo(0, 0),
                terminal::Clear(terminal::ClearType::All)
            )?;
            write!(out, "{frame}")?;
            out.flush()?;
            f.max_io_us = 0.0;
            while event::poll(Duration::ZERO)? {
                if let Event::Key(key) = event::read()? {
                    // In raw mode Ctrl-C is a key, not a signal.
                    let ctrl = key.modifiers.contains(event::KeyModifiers::CONTROL);
                    match key.code {
                        KeyCode::Char('q') | KeyCode::Esc => return Ok(()),
                        KeyCode::Char('c') if ctrl => return Ok(()),
                        KeyCode::Char('p') => {
                            power = !power;
                            io.boards_mut().iter_mut().for_each(|b| b.set_power(power));
                            f.message = format!("power {}", on_off(power));
                        }
                        KeyCode::Char('r') => {
                            relay = !relay;
                            io.boards_mut().iter_mut().for_each(|b| b.set_relay(relay));
                            f.message = format!("relay {}", on_off(relay));
                        }
                        KeyCode::Char('a') => {
                            amps = !amps;
                            io.boards_mut()
                                .iter_mut()
                                .for_each(|b| b.set_all_amps(amps));
                            f.message = format!("amplifiers {}", on_off(amps));
                        }
                        KeyCode::Char('z') => {
                            io.boards_mut().iter_mut().for_each(|b| b.safe_outputs());
                            amps = false;
                            f.message = "DACs zeroed, amplifiers off".into();
                        }
                        KeyCode::Char('w') => {
                            watchdog = !watchdog;
                            let p = if watchdog {
                                WatchdogSetting::from_ms(50.0).unwrap_or_default()
                            } else {
                                WatchdogSetting::Off
                            };
                            f.message = match io.set_watchdog(p) {
                                Ok(()) => {
                                    f.watchdog_ms = watchdog_periods(io);
                                    let warn =
                                        p.warning().map_or(String::new(), |w| format!(" ({w})"));
                                    format!("watchdog {p}{warn}")
                                }
                                Err(e) => format!("watchdog: {e}"),
                            };
                        }
                        _ => {}
                    }
                }
            }
        }
    })();
    let _ = execute!(out, cursor::Show, terminal::LeaveAlternateScreen);
    let _ = terminal::disable_raw_mode();
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_boards_are_explained() {
        // Power off, watchdog expired: what an idle board reports.
        let idle = StatusRead::default().with_watchdog_timeout(true);
        let lines = explain(idle, Some(20.0));
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].starts_with("supply off: motor power is not enabled"));
        assert!(
            lines[1].contains("longer than its 20 ms period"),
            "{lines:?}"
        );
        assert!(lines[1].contains("turned the amplifiers off"), "{lines:?}");
        // Power on without a supply, and a supply still rising.
        let no_supply = StatusRead::default()
            .with_motor_power_enabled(true)
            .with_motor_supply_fault(true);
        assert!(explain(no_supply, None)[0].starts_with("supply FAULT"));
        let rising = StatusRead::default().with_motor_power_enabled(true);
        assert!(explain(rising, None)[0].starts_with("supply BAD"));
        // All well: nothing to explain.
        let good = StatusRead::default()
            .with_motor_power_enabled(true)
            .with_motor_supply_good(true);
        assert!(explain(good, Some(20.0)).is_empty());
    }
}
