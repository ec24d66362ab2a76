//! `firelink sim`: one I/O cycle of N boards on the simulated 1394a bus.
//!
//! A thin wrapper over [`firelink_testbed::sim`]: the testbed's
//! [`SimRequest`] makes the [`SimOptions`](firelink_testbed::sim::SimOptions),
//! the cycle runs on emulated boards through the host library, and this
//! file prints the report as one JSON object (`--json`) or a table,
//! optionally writing the bus's packets as a pcap file (`--pcap FILE`, 1394
//! packets as UDP payloads to port 1394) and the bus timeline
//! (`--timeline`).

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use firelink_testbed::sim::SimRequest;

use crate::error::CliError;

/// Arguments of `firelink sim`.
#[derive(Args, Debug)]
pub struct SimArgs {
    /// The cycle to simulate.
    #[command(flatten)]
    request: SimRequest,
    /// Write the bus trace (setup and cycle) as a pcap file.
    #[arg(long)]
    pcap: Option<PathBuf>,
    /// Print the bus timeline after the report.
    #[arg(long)]
    timeline: bool,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// Run `firelink sim`.
///
/// # Errors
/// The protocol cannot run on these boards (e.g. 16 Rev 8 boards overflow
/// the hub memory); writing the output or the pcap file failed.
pub fn run(args: &SimArgs, out: &mut impl Write) -> Result<(), CliError> {
    let run = firelink_testbed::sim::run(&args.request.options())?;
    let bus = run.port().bus();
    if let Some(path) = &args.pcap {
        let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
        bus.write_pcap(&mut file)?;
        file.flush()?;
    }
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&run.report)?)?;
    } else {
        write!(out, "{}", run.report)?;
    }
    if args.timeline {
        write!(out, "{}", bus.timeline())?;
    }
    Ok(())
}
