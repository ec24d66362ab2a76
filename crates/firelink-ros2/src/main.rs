//! `firelink-ros2` (also run as `firelink ros2`): the robot as a ROS 2 node.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use clap::Parser;

use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, presets};
use firelink_host::WatchdogSetting;
use firelink_host::stop::install_signal_handlers;
use firelink_ros2::{NodeSettings, ServoStream, domain_from_env, run_node, run_without_dds};
use firelink_testbed::dvrk::service::Service;
use firelink_testbed::limits::watchdog;
use firelink_testbed::port_spec::{PortSpec, parse_port};

/// Run the robot and speak ROS 2 (CRTK topics per arm) over DDS.
#[derive(Parser, Debug)]
#[command(name = "firelink ros2", version)]
struct Args {
    /// Where the boards are: sim (the robot's emulated boards on the
    /// simulated bus; sim:N[:FW]: boards 0..N at firmware FW), emulate,
    /// udp:HOST[:PORT], or fw / fw:N (FireWire card 0 / N).
    #[arg(long, default_value = "sim", value_parser = parse_port)]
    port: PortSpec,
    /// Robot configuration (default: seed 000's dVRK: MTML, MTMR, PSM1, PSM2).
    #[arg(long)]
    config: Option<PathBuf>,
    /// The servo period, as a period or a rate: `1ms`, `250us`, `6kHz`
    /// (10 us to 1 s).
    #[arg(long, default_value = "1ms")]
    period: ServoPeriod,
    /// The period as a rate in Hz (the older spelling of --period).
    #[arg(long, hide = true, conflicts_with = "period", value_parser = firelink_testbed::limits::servo_rate_hz)]
    rate: Option<ServoPeriod>,
    /// Publications per second (measured_js, setpoint_js), decimated from
    /// the control rate (1 / --period).
    #[arg(long = "publish-hz", default_value_t = 1000.0)]
    publish_hz: f64,
    /// DDS domain (default: ROS_DOMAIN_ID, else 0).
    #[arg(long)]
    domain: Option<u16>,
    /// Board watchdog period, ms (one 5.208 us tick to 341.32 ms), or
    /// `off` (with a warning).
    #[arg(long = "watchdog-ms", default_value = "20", value_parser = watchdog)]
    watchdog_ms: WatchdogSetting,
    /// Stop after this many seconds (default: at Ctrl-C, SIGTERM or SIGHUP).
    #[arg(long)]
    seconds: Option<f64>,
    /// Run the robot without DDS (brought up and holding still) for
    /// `--seconds` and report its costs (the comparison for "with ROS 2
    /// attached").
    #[arg(long = "no-dds")]
    no_dds: bool,
    /// With `--no-dds`: instead of holding still, this arm follows the
    /// benchmark client's servo stream made in this process (200 points a
    /// second, its first joint on a 0.05 rad, 0.5 Hz sinusoid), so the
    /// robot loop does the same work as with the client over DDS.
    #[arg(long = "servo-stream", value_name = "ARM", requires = "no_dds")]
    servo_stream: Option<String>,
    /// Real-time scheduling for the robot loop, RustDDS's socket reader and
    /// the node's thread (SCHED_FIFO 80 / 75 / 70, 1 ns timer slack,
    /// mlockall), where the OS permits it (root or CAP_SYS_NICE; otherwise
    /// said on stderr and in the report's `realtime`, and the node runs on
    /// at normal priority). The default.
    #[arg(long = "rt", overrides_with = "no_rt")]
    rt: bool,
    /// Leave every thread at normal priority (no SCHED_FIFO, mlockall or
    /// timer slack).
    #[arg(long = "no-rt", overrides_with = "rt")]
    no_rt: bool,
}

impl Args {
    /// `--period`, or its older spelling `--rate` when that was given.
    fn servo_period(&self) -> ServoPeriod {
        self.rate.unwrap_or(self.period)
    }
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("firelink ros2: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Box<dyn std::error::Error>> {
    if let Some(w) = args.watchdog_ms.warning() {
        eprintln!("firelink ros2: {w}");
    }
    if !(args.publish_hz.is_finite() && args.publish_hz >= 1.0 && args.publish_hz <= 10_000.0) {
        return Err(format!("--publish-hz {}: must be 1..=10000", args.publish_hz).into());
    }
    let duration = match args.seconds {
        Some(s) if s.is_finite() && s > 0.0 && s <= 86_400.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => return Err(format!("--seconds {s}: must be 0 < s <= 86400").into()),
        None => None,
    };
    let config = match &args.config {
        Some(p) => {
            let loaded = IoConfig::load_with_warnings(p)?;
            for w in &loaded.warnings {
                eprintln!("warning: {w}");
            }
            loaded.config
        }
        None => presets::dvrk_seed000(),
    };
    let port = args.port;
    // SIGINT, SIGTERM and SIGHUP: the robot loop powers down and ends (it
    // watches the process's stop request), and so does the node (its own
    // flag, set by the same signals); a second signal ends the process at
    // once (the boards' watchdogs then turn the amplifiers off).
    let stop_request = install_signal_handlers()?;
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
    ] {
        signal_hook::flag::register(signal, Arc::clone(&stop))?;
    }
    if let Some(arm) = &args.servo_stream
        && !config.robots.iter().any(|r| r.name == *arm)
    {
        let arms: Vec<&str> = config.robots.iter().map(|r| r.name.as_str()).collect();
        return Err(format!(
            "servo stream: no arm named {arm} (the configuration has {})",
            arms.join(", ")
        )
        .into());
    }
    let service = Service::start(&port, config.clone(), args.servo_period(), args.watchdog_ms)?;
    let report = if args.no_dds {
        let d = duration.ok_or("--no-dds needs --seconds")?;
        let stream = args.servo_stream.map(|arm| ServoStream { arm });
        run_without_dds(&service, &config, d, !args.no_rt, stream.as_ref(), &stop)?
    } else {
        let domain = args.domain.unwrap_or_else(domain_from_env);
        let base = 7400 + 250 * u32::from(domain);
        eprintln!(
            "firelink ros2: WARNING: DDS is not restricted to loopback: RustDDS listens on \
             UDP 0.0.0.0 (every interface) and joins multicast 239.255.0.1, and does not read \
             ROS_LOCALHOST_ONLY: anyone who can reach this machine in DDS domain {domain} can \
             switch motor power on and move the robot (DDS has no token); to keep it on this \
             machine, run it in a network namespace that has only loopback, or firewall UDP \
             ports {base}-{}",
            base + 249
        );
        eprintln!(
            "firelink ros2: node /firelink on domain {domain}, arms {}",
            config
                .robots
                .iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
        println!("firelink ros2: ready");
        run_node(
            &service,
            &config,
            &NodeSettings {
                publish_hz: args.publish_hz,
                domain_id: domain,
                duration,
                sim_time: port.is_sim(),
                realtime: !args.no_rt,
            },
            &stop,
        )?
    };
    stop.store(true, Ordering::Relaxed);
    // (Real-time refusals were said on stderr as they happened.)
    if let Some(reason) = stop_request.reason() {
        eprintln!("firelink ros2: stopping: {reason}");
    }
    let exit = service.stop();
    eprintln!("firelink ros2: stopped: {exit}");
    println!("{}", serde_json::to_string(&report)?);
    if exit.panic.is_some() {
        return Err("the robot loop panicked".into());
    }
    Ok(())
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
        Args::try_parse_from([&["firelink"], args].concat())
            .map(|a| a.servo_period())
            .map_err(|e| e.to_string())
    }

    #[test]
    fn the_period_and_the_older_rate_give_the_same_servo_period() {
        let one_ms = period_of(&["--period", "1ms"]).unwrap();
        assert_eq!(one_ms, ServoPeriod::KHZ_1);
        assert_eq!(period_of(&["--rate", "1000"]).unwrap(), one_ms);
        assert_eq!(period_of(&[]).unwrap(), one_ms);
        assert_eq!(
            period_of(&["--period", "250us"]).unwrap(),
            period_of(&["--rate", "4000"]).unwrap()
        );
        let both = period_of(&["--period", "1ms", "--rate", "1000"]).unwrap_err();
        assert!(both.contains("cannot be used with"), "{both}");
    }

    #[test]
    fn a_period_out_of_range_is_refused_with_the_one_rule() {
        for args in [
            ["--period", "5us"],
            ["--period", "0.1Hz"],
            ["--rate", "0"],
            ["--rate", "1e6"],
        ] {
            let e = period_of(&args).unwrap_err();
            assert!(
                e.contains("out of range, 10 us to 1 s (100 kHz to 1 Hz)"),
                "{args:?}: {e}"
            );
        }
    }
}
