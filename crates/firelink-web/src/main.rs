//! `firelink-web` (also run as `firelink web`): the web console.

use firelink_control::ServoPeriod;
use firelink_host::WatchdogSetting;
use std::net::SocketAddr;
use std::path::PathBuf;

use clap::Parser;

use firelink_host::stop::install_signal_handlers;
use firelink_testbed::limits::watchdog;
use firelink_testbed::port_spec::{PortSpec, parse_port};
use firelink_web::{RobotKind, WebOptions, serve, start};

/// Watch and drive the boards and the robot in a browser.
#[derive(Parser, Debug)]
#[command(name = "firelink web", version)]
struct Args {
    /// Which robot: the dVRK (seed 000's QLA boards), snake (seed 001's
    /// 36-axis system on its 7-channel nodes) or mahru (seed 002's
    /// humanoid: 14 modules on three chains). Snake and MAHRU run on the
    /// simulated bus (`--port sim`).
    #[arg(long, value_enum, default_value_t = RobotKind::Dvrk)]
    robot: RobotKind,
    /// Where the boards are: sim (the robot's emulated boards on the
    /// simulated bus, paced to the wall clock; sim:N[:FW]: boards 0..N at
    /// firmware FW), emulate (the same behind an in-process `firelink
    /// emulate`, over UDP), udp:HOST[:PORT], or fw / fw:N (FireWire card
    /// 0 / N).
    #[arg(long, default_value = "sim", value_parser = parse_port)]
    port: PortSpec,
    /// Robot configuration (default: seed 000's dVRK, 28 axes; with
    /// --robot snake configs/snake-seed001.json's, with --robot mahru
    /// configs/mahru-seed002.json's).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Address to listen on. Anything but a loopback address must be asked
    /// for explicitly and prints a warning: the page can enable motor power.
    #[arg(long, default_value = "127.0.0.1:8080")]
    listen: SocketAddr,
    /// Also accept requests from pages of this origin (repeatable), e.g.
    /// http://robot-pc.lab:8080 when the console is opened by a name of
    /// this machine (its own addresses are accepted as they are reached).
    #[arg(long = "allow-origin", value_name = "ORIGIN", value_parser = firelink_web::server::parse_origin)]
    allow_origin: Vec<String>,
    /// The servo period, as a period or a rate: `1ms`, `250us`, `6kHz`
    /// (10 us to 1 s; default: 1 ms; MAHRU: its configuration's period,
    /// 2 ms for seed 002, within 100 us to 1 s).
    #[arg(long, conflicts_with = "rate")]
    period: Option<ServoPeriod>,
    /// The period as a rate in Hz (the older spelling of --period).
    #[arg(long, hide = true, value_parser = firelink_testbed::limits::servo_rate_hz)]
    rate: Option<ServoPeriod>,
    /// Board watchdog period, ms (one 5.208 us tick to 341.32 ms), or
    /// `off` (with a warning).
    #[arg(long = "watchdog-ms", default_value = "20", value_parser = watchdog)]
    watchdog_ms: WatchdogSetting,
    /// The dVRK's read time-out in milliseconds (1..=60000) on `udp:`,
    /// `emulate` and `fw`: a servo cycle whose answer takes longer counts
    /// the board as missed (a fault); the scan waits that long for each
    /// absent node.
    #[arg(long = "timeout-ms", default_value_t = 20, value_parser = firelink_testbed::limits::timeout_ms)]
    timeout_ms: u64,
}

/// MAHRU's period by default: its configuration's.
fn mahru_period(
    config: Option<&std::path::Path>,
) -> Result<ServoPeriod, Box<dyn std::error::Error>> {
    let config = match config {
        Some(path) => firelink_testbed::mahru::MahruConfig::load(path)?,
        None => firelink_testbed::mahru::MahruConfig::seed002(),
    };
    Ok(ServoPeriod::from_duration(config.period())?)
}

/// The console's options from the command line: `--period` or its older
/// spelling `--rate`, else the robot's default period.
fn web_options(args: Args) -> Result<WebOptions, Box<dyn std::error::Error>> {
    let period = match (args.period.or(args.rate), args.robot) {
        (Some(period), _) => period,
        (None, RobotKind::Mahru) => mahru_period(args.config.as_deref())?,
        (None, _) => ServoPeriod::KHZ_1,
    };
    Ok(WebOptions {
        robot: args.robot,
        port: args.port,
        config: args.config,
        period,
        watchdog: args.watchdog_ms,
        timeout: std::time::Duration::from_millis(args.timeout_ms),
        listen: args.listen,
        allow_origins: args.allow_origin,
    })
}

fn main() {
    let args = Args::parse();
    if let Err(e) = run(args) {
        eprintln!("firelink web: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Box<dyn std::error::Error>> {
    if let Some(w) = args.watchdog_ms.warning() {
        eprintln!("firelink web: {w}");
    }
    if !args.listen.ip().is_loopback() {
        eprintln!(
            "firelink web: WARNING: listening on {}, not loopback: anyone who can reach it \
             and has the token can switch motor power on and move the robot",
            args.listen
        );
        eprintln!(
            "firelink web: from another machine, open the printed URL with this machine's \
             address in it; to open it by a name, add --allow-origin http://NAME:{}",
            args.listen.port()
        );
    }
    // SIGINT, SIGTERM and SIGHUP ask the robot loop to power down and end
    // (it watches the process's stop request); a second one ends the
    // process at once (the boards' watchdogs then turn the amplifiers off).
    let stop = install_signal_handlers()?;
    let options = web_options(args)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let (running, listener) = start(&options).await?;
        println!("firelink web: {}", running.url);
        eprintln!(
            "firelink web: open the URL above (once: it sets this console's cookie); \
             Ctrl-C stops the robot (power off) and the server"
        );
        // The same signals, to end the server (the robot loop ends by itself).
        let signalled = async {
            use tokio::signal::unix::{SignalKind, signal};
            let wait = |kind| async move {
                match signal(kind) {
                    Ok(mut s) => {
                        s.recv().await;
                    }
                    // (The robot loop still obeys the process's stop
                    // request, and its end ends the server.)
                    Err(_) => std::future::pending::<()>().await,
                }
            };
            tokio::select! {
                () = wait(SignalKind::interrupt()) => {}
                () = wait(SignalKind::terminate()) => {}
                () = wait(SignalKind::hangup()) => {}
            }
        };
        let served = serve(&running, listener, signalled).await;
        if let Some(reason) = stop.reason() {
            eprintln!("firelink web: stopping: {reason}");
        }
        let exit = running.stop();
        eprintln!("firelink web: stopped: {exit}");
        served?;
        if exit.panic.is_some() {
            return Err("the robot loop panicked".into());
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_testbed::port_spec::disagreements_with_table;

    /// The shared table of port strings through this program's `--port`:
    /// the same meaning as every other front end, or the same refusal.
    #[test]
    fn port_strings_mean_what_the_table_says() {
        let parse = |text: &str| {
            Args::try_parse_from(["firelink", "--port", text])
                .map(|a| a.port)
                .map_err(|e| e.to_string())
        };
        let wrong = disagreements_with_table(parse, |_| true);
        assert!(wrong.is_empty(), "{wrong:#?}");
    }

    fn period_of(args: &[&str]) -> Result<ServoPeriod, String> {
        let args =
            Args::try_parse_from([&["firelink"], args].concat()).map_err(|e| e.to_string())?;
        web_options(args)
            .map(|o| o.period)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn the_period_and_the_older_rate_give_the_same_servo_period() {
        let one_ms = period_of(&["--period", "1ms"]).unwrap();
        assert_eq!(one_ms, ServoPeriod::KHZ_1);
        assert_eq!(period_of(&["--rate", "1000"]).unwrap(), one_ms);
        assert_eq!(period_of(&["--period", "1kHz"]).unwrap(), one_ms);
        assert_eq!(period_of(&[]).unwrap(), one_ms);
        for robot in ["snake", "mahru"] {
            assert_eq!(
                period_of(&["--robot", robot, "--period", "2ms"]).unwrap(),
                period_of(&["--robot", robot, "--rate", "500"]).unwrap(),
            );
        }
        // MAHRU's default: seed 002's 2 ms.
        assert_eq!(
            period_of(&["--robot", "mahru"]).unwrap(),
            "2ms".parse().unwrap()
        );
        let both = period_of(&["--period", "1ms", "--rate", "1000"]).unwrap_err();
        assert!(both.contains("cannot be used with"), "{both}");
    }

    #[test]
    fn a_period_out_of_range_is_refused_with_the_one_rule() {
        for args in [
            ["--period", "5us"],
            ["--period", "2s"],
            ["--rate", "0"],
            ["--rate", "200000"],
        ] {
            let e = period_of(&args).unwrap_err();
            assert!(
                e.contains("out of range, 10 us to 1 s (100 kHz to 1 Hz)"),
                "{args:?}: {e}"
            );
        }
        let e = period_of(&["--period", "1000"]).unwrap_err();
        assert!(e.contains("no unit"), "{e}");
    }
}
