//! `firelink monitor`: a live terminal view of every axis of every board,
//! like the dVRK's qladisp. The I/O loop runs at full rate; the screen is
//! redrawn at a human rate (10 Hz). Keys toggle power, relay, amplifiers and
//! the watchdog. The loop, the frame and the keys are
//! [`firelink_host::qla::monitor_frame`]; this file owns the terminal.

use std::io::Write;
use std::time::Duration;

use clap::Args;

use firelink_host::Port;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;

use firelink_host::qla::monitor::{MonitorFigures, Switches, watchdog_periods};
use firelink_host::qla::monitor_frame::{LiveView, render, run_cycles, switch_of};

use crate::error::CliError;
use crate::ports::{PortArgs, open_port};

/// Options of `firelink monitor`.
#[derive(Args, Debug)]
pub struct MonitorArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// I/O protocol (default: the best the boards support).
    #[arg(long, value_enum)]
    pub protocol: Option<Protocol>,
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

/// `firelink monitor`.
pub fn run(args: &MonitorArgs, out: &mut impl Write) -> Result<(), CliError> {
    let port = open_port(&args.port, "firelink monitor")?;
    let config = IoOptions {
        protocol: args.protocol,
        ..IoOptions::default()
    };
    let (mut io, _scan) = IoSystem::open(port, config)?;
    if let Some(w) = args.watchdog {
        if let Some(warning) = w.warning() {
            say!("monitor: {warning}");
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
        run_cycles(&mut io, cycles, period, &mut f);
        write!(out, "{}", render(&io, &f))?;
        return Ok(());
    }
    let result = interactive(&mut io, period, watchdog_ms, out);
    // Power the boards down if this session switched anything on (the
    // one rule, RobotIo::power_down; dropping `io` would do it silently).
    if io.energised() != 0 {
        let done = firelink_host::RobotIo::power_down(&mut io);
        say!("monitor: powered down: {done}");
    }
    result
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
        let mut live = LiveView::new(period);
        let mut switches = Switches::default();
        let stop = firelink_host::stop::StopRequest::process();
        while let Some(frame) = live.next_frame(io, &mut f, &stop) {
            execute!(
                out,
                cursor::MoveTo(0, 0),
                terminal::Clear(terminal::ClearType::All)
            )?;
            write!(out, "{}", frame.replace('\n', "\r\n"))?;
            out.flush()?;
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
        Ok(())
    })();
    let _ = execute!(out, cursor::Show, terminal::LeaveAlternateScreen);
    let _ = terminal::disable_raw_mode();
    result
}
