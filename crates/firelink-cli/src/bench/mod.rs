//! `firelink bench`: I/O time per cycle against the number of boards, for
//! the sequential and broadcast protocols, on the simulated bus with the
//! seed-000 PC model (seed 000, Fig. 11) and measured for real over
//! loopback UDP against an in-process `firelink emulate` (or any bridge:
//! `--port udp:HOST[:PORT]`), side by side. Plus the maximum sustainable
//! control rate and seed 002's time budget; for UDP, each wait mode
//! (`--udp-wait block,spin`), the floor of the same exchange and the CPU
//! time per cycle; for `fw` (FirewirePort through the /dev/fw* twin, the
//! command re-runs itself with the twin preloaded), the floor of bare
//! request/event round trips and the host CPU against `sim`'s; for `eth`
//! (the Ethernet-only network of FPGA V3 boards at Rev 9, in process or
//! `--port udp:HOST`), its broadcast cycle beside the bridge at Rev 8 and
//! Rev 9 and the firmware's stated timing.

//!
//! The measurement is [`firelink_testbed::dvrk::bench`], the figure
//! [`firelink_plot::fig11`]; this file parses the options and prints.

mod seed001;

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use firelink_host::qla::scan::Protocol;
use firelink_host::udp::WaitMode;
use firelink_testbed::dvrk::bench::{BenchOptions, BenchTransport, parse_board_counts, run_bench};
use firelink_testbed::emulated::Profile;
use firelink_testbed::fw_run::{library_path, rerun_with_twin, under_twin};

use crate::error::CliError;

/// `--port`: the port grammar, of which the benchmark takes `udp:HOST`
/// (port 1394) or `udp:HOST:PORT`.
fn bridge_address(text: &str) -> Result<crate::ports::PortSpec, CliError> {
    match crate::ports::parse_port_for(
        text,
        "firelink bench --port",
        &[firelink_testbed::port_spec::PortKind::Udp],
    )? {
        // The bench measures the bridge: `udp` and `udpfw` alike.
        spec @ (crate::ports::PortSpec::Udp(_) | crate::ports::PortSpec::UdpFw(_)) => Ok(spec),
        other => Err(other
            .refused("firelink bench --port", "it takes udp".into())
            .into()),
    }
}

/// Options of `firelink bench`.
#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    /// Transports (comma-separated; default `sim,udp`, with `--port` only
    /// `udp`).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub transport: Vec<BenchTransport>,
    /// UDP points: measure the boards behind this bridge (`udp:HOST` on
    /// port 1394, or `udp:HOST:PORT`: a running `firelink emulate` or real
    /// boards) instead of an in-process emulator: one point per protocol
    /// with the boards the scan finds; no emulator CPU. With `--transport
    /// eth`: the Ethernet-only network answering there (`firelink emulate
    /// --network eth` or FPGA V3 boards at Rev 9).
    #[arg(long, value_parser = bridge_address)]
    pub port: Option<crate::ports::PortSpec>,
    /// UDP points: how the host's reads wait (comma-separated, each
    /// measured side by side): `block` (sleep in the kernel) or `spin`
    /// (poll the socket).
    #[arg(long = "udp-wait", value_enum, value_delimiter = ',', default_values_t = [WaitMode::Blocking])]
    pub udp_wait: Vec<WaitMode>,
    /// UDP points: the host's time-out for each answer, ms (a cycle that
    /// waits longer counts an error; real hosts use about 20).
    #[arg(long = "udp-timeout-ms", default_value_t = 20, value_parser = crate::args::timeout_ms)]
    pub udp_timeout_ms: u64,
    /// Board counts (comma-separated, 1..=62); above 16 (the board-ID
    /// space) the figures come from the cost model fitted to the 16-board
    /// run.
    #[arg(long, default_value = "2,4,8,16,32,62")]
    pub boards: String,
    /// Protocols (comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Protocol::Sequential, Protocol::Broadcast])]
    pub protocol: Vec<Protocol>,
    /// Measured cycles per point (after 20 warm-up cycles), 1 to 10^7.
    #[arg(long, default_value_t = 1000, value_parser = crate::args::measured)]
    pub cycles: u64,
    /// Firmware of the emulated boards.
    #[arg(long, default_value = "rev8", value_parser = crate::args::firmware())]
    pub firmware: Profile,
    /// Control period for the seed-002 budget check, us (default: 6 kHz).
    #[arg(long = "period-us", default_value_t = 166.67, value_parser = crate::args::period_us)]
    pub period_us: f64,
    /// Broadcast protocol: the host's wait between the query and the hub
    /// read, us per board (seed 000's PC sleeps 5 us x N).
    #[arg(long = "wait-us", default_value_t = 5.0, value_parser = crate::args::wait_us)]
    pub wait_us: f64,
    /// Idle time between cycles, us: a paced control loop leaves the bus
    /// idle between cycles (longer than the 21 us arbitration reset gap, so
    /// the PC's fairness interval restarts), as at seed 000's 6 kHz.
    #[arg(long = "idle-us", default_value_t = 50.0, value_parser = crate::args::wait_us)]
    pub idle_us: f64,
    /// Write a PNG plot of I/O time against boards here (with `--seed
    /// 001`: that paper's Fig. 20 and 21).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Reproduce a seed paper's own measurements instead: `001`, seed
    /// 001's quadlet and block transaction times and servo budgets on one
    /// Snake node with its PC's model (the other options do not apply).
    #[arg(long, value_enum)]
    pub seed: Option<seed001::SeedPaper>,
    /// With `--seed 001`: quadlet reads and writes each (the paper: 9000;
    /// 1 to 10^7).
    #[arg(long, default_value_t = 9000, value_parser = crate::args::measured)]
    pub iterations: u64,
    /// Print JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The benchmark's options from the command line.
///
/// # Errors
/// [`CliError::BoardCounts`]: a count outside 1..=62, or counts above 16
/// with no measured count before them.
pub fn options(args: &BenchArgs) -> Result<BenchOptions, CliError> {
    let transports = match (args.transport.is_empty(), args.port) {
        (false, _) => args.transport.clone(),
        (true, Some(_)) => vec![BenchTransport::Udp],
        (true, None) => vec![BenchTransport::Sim, BenchTransport::Udp],
    };
    let mut udp_waits = Vec::new();
    for w in args.udp_wait.iter().copied() {
        if !udp_waits.contains(&w) {
            udp_waits.push(w);
        }
    }
    Ok(BenchOptions {
        transports,
        boards: parse_board_counts(&args.boards).map_err(CliError::BoardCounts)?,
        protocols: args.protocol.clone(),
        cycles: args.cycles,
        firmware: args.firmware,
        period_us: args.period_us,
        wait_us_per_board: args.wait_us,
        idle_us: args.idle_us,
        udp_waits,
        udp_timeout: std::time::Duration::from_millis(args.udp_timeout_ms),
        udp_target: match args.port {
            Some(crate::ports::PortSpec::Udp(addr) | crate::ports::PortSpec::UdpFw(addr)) => {
                Some(addr)
            }
            _ => None,
        },
    })
}

/// Run `firelink bench`.
pub fn run(args: &BenchArgs, out: &mut impl Write) -> Result<(), CliError> {
    if args.seed.is_some() {
        return seed001::run(args.iterations, args.plot.as_deref(), args.json, out);
    }
    let options = options(args)?;
    if options.transports.contains(&BenchTransport::Fw) && !under_twin() {
        // The `fw` points need the twin library in this process: the same
        // command again with it preloaded, its table passed on.
        let output = rerun_with_twin(&library_path()?, std::env::args_os().skip(1))?;
        out.write_all(&output.stdout)?;
        if !output.status.success() {
            return Err(CliError::Failed(format!(
                "bench: the run with the /dev/fw* twin preloaded failed ({})",
                output.status
            )));
        }
        return Ok(());
    }
    let quiet = crate::args::quiet();
    let report = run_bench(&options, |t, proto, n| {
        if quiet {
            return;
        }
        match (t, options.udp_target) {
            (BenchTransport::Udp | BenchTransport::Eth, Some(addr)) => {
                eprintln!("bench: {} {} at udp:{addr}", t.name(), proto.name());
            }
            _ => eprintln!("bench: {} {} {n} boards", t.name(), proto.name()),
        }
    })?;
    if let Some(path) = &args.plot {
        firelink_plot::fig11(&report, path)?;
    }
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&report)?)?;
    } else {
        write!(out, "{report}")?;
    }
    Ok(())
}
