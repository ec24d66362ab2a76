//! `firelink budget`: seed 002's MAHRU humanoid's Tables I, III and IV
//! ([`firelink_testbed::mahru::tables`]); this file parses the options and
//! prints. (`firelink demo --robot mahru` is the demo's request.)

use std::io::Write;
use std::path::PathBuf;

use clap::{Args, ValueEnum};

use firelink_control::ServoPeriod;
use firelink_host::mahru::rtos::Rtos;
use firelink_testbed::mahru::MahruConfig;
use firelink_testbed::mahru::tables::{TablesOptions, run_tables};

use crate::error::CliError;

/// The real-time systems `firelink budget` covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum RtosChoice {
    /// Xenomai and RTLinux.
    #[default]
    Both,
    /// Xenomai only.
    Xenomai,
    /// RTLinux only.
    Rtlinux,
}

impl RtosChoice {
    fn systems(self) -> Vec<Rtos> {
        match self {
            RtosChoice::Both => Rtos::ALL.to_vec(),
            RtosChoice::Xenomai => vec![Rtos::Xenomai],
            RtosChoice::Rtlinux => vec![Rtos::RtLinux],
        }
    }
}

/// One of the seed's tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Table {
    /// Table I: the time budget.
    #[value(name = "1")]
    Budget,
    /// Table III: read time by payload.
    #[value(name = "3")]
    ReadTimes,
    /// Table IV: CAN against 1394.
    #[value(name = "4")]
    Can,
}

/// Options of `firelink budget`.
#[derive(Args, Debug, Clone)]
pub struct BudgetArgs {
    /// The MAHRU configuration (default: `configs/mahru-seed002.json`'s
    /// robot, built in).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The servo period, `2ms`, `500Hz` (default: the configuration's 2
    /// ms; MAHRU's bounds: 100 us to 1 s).
    #[arg(long, conflicts_with = "period_us", value_parser = crate::args::mahru_servo_period)]
    pub period: Option<ServoPeriod>,
    /// The period in us (the older spelling of --period).
    #[arg(long = "period-us", hide = true, value_parser = crate::args::servo_period_us)]
    pub period_us: Option<ServoPeriod>,
    /// Real-time systems.
    #[arg(long, value_enum, default_value_t = RtosChoice::Both)]
    pub rtos: RtosChoice,
    /// Tables to produce (comma-separated): 1, 3, 4.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "1,3,4")]
    pub tables: Vec<Table>,
    /// Table I: timings per transaction type and module (1 to 100000).
    #[arg(long, default_value_t = 200, value_parser = crate::args::timings)]
    pub samples: u64,
    /// Table I: periods walked end to end (1 to 10^7).
    #[arg(long, default_value_t = 5000, value_parser = crate::args::measured)]
    pub periods: u64,
    /// Table III: simulated reads per payload and system (the seed: more
    /// than a million; 1 to 10^7).
    #[arg(long, default_value_t = 1_000_000, value_parser = crate::args::measured)]
    pub reads: u64,
    /// Table IV: CAN cycles (1 to 10^6).
    #[arg(long = "can-cycles", default_value_t = 2000, value_parser = crate::args::can_cycles)]
    pub can_cycles: u64,
    /// Table IV: chance of a bit error per CAN frame (0 to 1).
    #[arg(long = "can-errors", default_value_t = 0.0, value_parser = crate::args::probability)]
    pub can_errors: f64,
    /// Write Table III as a PNG figure here.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `firelink budget`.
pub fn run_budget_cmd(args: &BudgetArgs, out: &mut impl Write) -> Result<(), CliError> {
    let quiet = crate::args::quiet();
    let config = match &args.config {
        Some(path) => MahruConfig::load(path)?,
        None => MahruConfig::seed002(),
    };
    let options = TablesOptions {
        config,
        period: args.period.or(args.period_us),
        rtos: args.rtos.systems(),
        budget: args.tables.contains(&Table::Budget),
        read_times: args.tables.contains(&Table::ReadTimes),
        can: args.tables.contains(&Table::Can),
        samples: args.samples.min(u64::from(u32::MAX)) as u32,
        periods: args.periods,
        reads: args.reads,
        can_cycles: args.can_cycles.min(u64::from(u32::MAX)) as u32,
        can_errors: args.can_errors,
    };
    let tables = run_tables(&options, |line| {
        if !quiet {
            eprintln!("budget: {line}");
        }
    })?;
    if let (Some(path), Some(table3)) = (&args.plot, &tables.table_iii) {
        firelink_plot::mahru::table3(table3, path)?;
    }
    if args.json {
        writeln!(out, "{}", tables.json()?)?;
    } else {
        write!(out, "{tables}")?;
    }
    tables.verdict().map_err(CliError::DoesNotFit)
}
