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
//! The options and the measurement are [`firelink_testbed::dvrk::bench`]'s
//! ([`BenchRequest`]), the figure [`firelink_plot::fig11`]; this file
//! prints.

mod seed001;

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use firelink_testbed::dvrk::bench::{BenchRequest, BenchTransport, run_bench};
use firelink_testbed::fw_run::{library_path, rerun_with_twin, under_twin};

use crate::error::CliError;

/// Options of `firelink bench`.
#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    /// What to measure.
    #[command(flatten)]
    pub request: BenchRequest,
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

/// Run `firelink bench`.
pub fn run(args: &BenchArgs, out: &mut impl Write) -> Result<(), CliError> {
    if args.seed.is_some() {
        return seed001::run(args.iterations, args.plot.as_deref(), args.json, out);
    }
    let options = args.request.options().map_err(CliError::BenchOptions)?;
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
                say!("bench: {} {} at udp:{addr}", t.name(), proto.name());
            }
            _ => say!("bench: {} {} {n} boards", t.name(), proto.name()),
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
