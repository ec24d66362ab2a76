//! `firelink sim`: one I/O cycle of N boards on the simulated 1394a bus.
//!
//! A thin wrapper over [`firelink_testbed::sim`]: it turns the flags into
//! [`SimOptions`], runs the cycle on emulated boards through the host
//! library, and prints the report as one JSON object (`--json`) or a table,
//! optionally writing the bus's packets as a pcap file (`--pcap FILE`, 1394
//! packets as UDP payloads to port 1394) and the bus timeline
//! (`--timeline`).

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use firelink_host::qla::scan::Protocol;
use firelink_testbed::emulated::{ArbitrationClass, Profile};
use firelink_testbed::sim::SimOptions;
use firelink_wire::packet::Speed;

use crate::error::CliError;

/// Arguments of `firelink sim`.
#[derive(Args, Debug)]
pub struct SimArgs {
    /// Number of boards (1 to 16).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=16))]
    boards: u8,
    /// The boards' firmware (`--firmware` too).
    #[arg(long, alias = "firmware", default_value = "seed", value_parser = crate::args::firmware())]
    profile: Profile,
    /// I/O protocol: broadcast or sequential (the phase tables' two).
    #[arg(long, value_enum, default_value_t = Protocol::Broadcast)]
    protocol: Protocol,
    /// Gap count to set (PHY configuration packet and bus reset) before the
    /// cycle; default the power-up 63.
    #[arg(long = "gap-count", value_parser = clap::value_parser!(u8).range(0..=63))]
    gap_count: Option<u8>,
    /// Arbitration of the boards' status broadcasts.
    #[arg(long, default_value = "iso", value_parser = crate::args::arbitration())]
    arbitration: ArbitrationClass,
    /// Speed of every packet in Mb/s.
    #[arg(long, default_value = "400", value_parser = crate::args::speed())]
    speed: Speed,
    /// Seed of the fault injector and the host jitter.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Add the PC's software overhead (seed 000's PC: read 32 us, write
    /// 34 us, broadcast write call 2.51 us).
    #[arg(long = "host-overhead")]
    host_overhead: bool,
    /// With --host-overhead: draw the overheads from a seeded distribution.
    #[arg(long, requires = "host_overhead")]
    jitter: bool,
    /// Run the cycle master (cycle start every 125 us; off in seed 000).
    #[arg(long = "cycle-master")]
    cycle_master: bool,
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

impl SimArgs {
    fn options(&self) -> SimOptions {
        let mut options = SimOptions::new(usize::from(self.boards), self.profile, self.protocol);
        options.gap_count = self.gap_count;
        options.arbitration = self.arbitration;
        options.speed = self.speed;
        options.seed = self.seed;
        options.host_overhead = self.host_overhead;
        options.host_jitter = self.jitter;
        options.cycle_master = self.cycle_master;
        options
    }
}

/// Run `firelink sim`.
///
/// # Errors
/// The protocol cannot run on these boards (e.g. 16 Rev 8 boards overflow
/// the hub memory); writing the output or the pcap file failed.
pub fn run(args: &SimArgs, out: &mut impl Write) -> Result<(), CliError> {
    let run = firelink_testbed::sim::run(&args.options())?;
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
