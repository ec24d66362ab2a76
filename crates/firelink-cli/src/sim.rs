//! `firelink sim`: one I/O cycle of N boards on the simulated 1394a bus.
//!
//! A thin wrapper over [`firelink_bus::scenario`]: it turns the flags into a
//! [`CycleConfig`], runs [`run_cycle`], and prints the report as one JSON
//! object (`--json`) or a table, optionally writing the cycle's packets as a
//! pcap file (`--pcap FILE`, 1394 packets as UDP payloads to port 1394) and
//! the bus timeline (`--timeline`).

use std::io::Write;
use std::path::PathBuf;

use clap::{Args, ValueEnum};
use firelink_bus::ArbitrationClass;
use firelink_bus::scenario::{CycleConfig, Profile, Protocol, prepare_cycle_with, run_cycle};
use firelink_wire::packet::Speed;

use crate::CliError;

/// Firmware profile.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProfileArg {
    /// Seed 000's firmware: fixed TDMA slots.
    Seed,
    /// Firmware Rev 7: chained broadcasts.
    Rev7,
    /// Firmware Rev 8: chained broadcasts.
    Rev8,
}

/// I/O protocol.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProtocolArg {
    /// Query, status broadcasts, hub read, command broadcast.
    Broadcast,
    /// One block read and one block write per board.
    Sequential,
}

/// Arbitration class of the boards' status broadcasts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ArbitrationArg {
    /// Isochronous-style requests (0.04 us gap).
    Iso,
    /// Priority requests (subaction gap).
    Priority,
    /// Fair requests (subaction gap, fairness interval).
    Fair,
}

/// Arguments of `firelink sim`.
#[derive(Args, Debug)]
pub struct SimArgs {
    /// Number of boards (1 to 16).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=16))]
    boards: u8,
    /// Firmware profile.
    #[arg(long, value_enum, default_value_t = ProfileArg::Seed)]
    profile: ProfileArg,
    /// I/O protocol.
    #[arg(long, value_enum, default_value_t = ProtocolArg::Broadcast)]
    protocol: ProtocolArg,
    /// Gap count to set (PHY configuration packet and bus reset) before the
    /// cycle; default the power-up 63.
    #[arg(long = "gap-count", value_parser = clap::value_parser!(u8).range(0..=63))]
    gap_count: Option<u8>,
    /// Arbitration of the boards' status broadcasts.
    #[arg(long, value_enum, default_value_t = ArbitrationArg::Iso)]
    arbitration: ArbitrationArg,
    /// Speed of every packet in Mb/s: 100, 200 or 400.
    #[arg(long, default_value_t = 400, value_parser = parse_speed)]
    speed: u32,
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
    /// Which boards answer: `emulated` (the full FPGA1394/QLA emulation) or
    /// `minimal` (a small responder with seed-000-era payload sizes).
    /// Default: minimal for the seed profile (its payloads are those of
    /// the paper's era, not Rev 7's), emulated for rev7 and rev8.
    #[arg(long = "board-model", value_parser = ["emulated", "minimal"])]
    board_model: Option<String>,
}

fn parse_speed(s: &str) -> Result<u32, String> {
    match s.trim() {
        "100" => Ok(100),
        "200" => Ok(200),
        "400" => Ok(400),
        other => Err(format!("speed must be 100, 200 or 400, not {other:?}")),
    }
}

impl SimArgs {
    fn config(&self) -> CycleConfig {
        let profile = match self.profile {
            ProfileArg::Seed => Profile::Seed,
            ProfileArg::Rev7 => Profile::Rev7,
            ProfileArg::Rev8 => Profile::Rev8,
        };
        let protocol = match self.protocol {
            ProtocolArg::Broadcast => Protocol::Broadcast,
            ProtocolArg::Sequential => Protocol::Sequential,
        };
        let mut cfg = CycleConfig::new(usize::from(self.boards), profile, protocol);
        cfg.gap_count = self.gap_count;
        cfg.arbitration = match self.arbitration {
            ArbitrationArg::Iso => ArbitrationClass::Isochronous,
            ArbitrationArg::Priority => ArbitrationClass::Priority,
            ArbitrationArg::Fair => ArbitrationClass::Fair,
        };
        cfg.speed = match self.speed {
            100 => Speed::S100,
            200 => Speed::S200,
            _ => Speed::S400,
        };
        cfg.seed = self.seed;
        cfg.host_overhead = self.host_overhead;
        cfg.host_jitter = self.jitter;
        cfg.cycle_master = self.cycle_master;
        cfg
    }
}

/// Run `firelink sim`.
///
/// # Errors
/// Writing the output or the pcap file failed.
pub fn run(args: &SimArgs, out: &mut impl Write) -> Result<(), CliError> {
    let cfg = args.config();
    let emulated = match args.board_model.as_deref() {
        Some(m) => m == "emulated",
        None => cfg.profile != Profile::Seed,
    };
    let run = if emulated {
        let board_profile = match cfg.profile {
            Profile::Seed => firelink_board::config::Profile::Seed,
            Profile::Rev7 => firelink_board::config::Profile::Rev7,
            Profile::Rev8 => firelink_board::config::Profile::Rev8,
        };
        prepare_cycle_with(&cfg, &mut |id, cfg| {
            let board = firelink_board::config::BoardConfig::new(
                id,
                firelink_board::config::Hardware::Qla1,
                board_profile,
            )
            .with_seed(cfg.seed);
            Box::new(
                firelink_board::node::BoardNode::new(board)
                    .with_name(format!("board{id}"))
                    .with_broadcast(cfg.speed, cfg.arbitration),
            )
        })
        .run()
    } else {
        run_cycle(&cfg)
    };
    if let Some(path) = &args.pcap {
        let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
        run.bus.write_pcap(&mut file)?;
        file.flush()?;
    }
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&run.report)?)?;
    } else {
        write!(out, "{}", run.report.table())?;
    }
    if args.timeline {
        write!(out, "{}", run.bus.timeline())?;
    }
    Ok(())
}
