//! `firelink monitor`: a live terminal view of every axis of every board,
//! like the dVRK's qladisp. The I/O loop runs at full rate; the screen is
//! redrawn at a human rate (10 Hz). Keys toggle power, relay, amplifiers and
//! the watchdog.

use std::io::Write;
use std::time::{Duration, Instant};

use clap::Args;

use firelink_host::Port;
use firelink_host::io::{IoOptions, IoSystem};
use firelink_host::scan::Protocol;

use firelink_host::monitor::{
    MonitorFigures, Switch, Switches, explain_status, on_off, watchdog_periods,
};

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
            f.record_cycle(r.io_time().as_secs_f64() * 1e6);
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

/// The switch a key flips.
fn switch_of(key: char) -> Option<Switch> {
    Some(match key {
        'p' => Switch::Power,
        'r' => Switch::Relay,
        'a' => Switch::Amplifiers,
        'z' => Switch::ZeroDacs,
        'w' => Switch::Watchdog,
        _ => return None,
    })
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
        let mut switches = Switches::default();
        let stop = firelink_host::stop::StopRequest::process();
        loop {
            if stop.is_requested() {
                return Ok(());
            }
            let r = *io.cycle();
            let _ = io.recover();
            f.record_cycle(r.io_time().as_secs_f64() * 1e6);
            window_cycles += 1;
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
                        KeyCode::Char(c) => {
                            if let Some(switch) = switch_of(c) {
                                f.message = switches.flip(switch, io, &mut f);
                            }
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
