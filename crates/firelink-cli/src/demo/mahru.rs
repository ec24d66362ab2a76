//! Seed 002's MAHRU humanoid on the command line: `firelink demo --robot
//! mahru` (the robot walking) and `firelink budget` (Tables I, III and IV).
//! The runs are [`firelink_testbed::mahru`]; this file parses options and
//! prints.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::{Args, ValueEnum};

use firelink_host::mahru::rtos::Rtos;
use firelink_testbed::mahru::budget::{BudgetOptions, run_budget};
use firelink_testbed::mahru::can::{Table4Options, run_table4};
use firelink_testbed::mahru::table3::{Table3Options, run_table3};
use firelink_testbed::mahru::{MahruConfig, MahruDemoOptions, run_mahru_demo};

use super::DemoArgs;
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
    /// The control period, us (default: the configuration's, 2000).
    #[arg(long = "period-us", value_parser = crate::args::mahru_period_us)]
    pub period_us: Option<f64>,
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

fn config(path: Option<&Path>) -> Result<MahruConfig, CliError> {
    match path {
        Some(p) => MahruConfig::load(p).map_err(CliError::from),
        None => Ok(MahruConfig::seed002()),
    }
}

fn period(us: Option<f64>) -> Option<Duration> {
    us.map(|us| Duration::from_secs_f64(us / 1e6))
}

/// `firelink demo --robot mahru`.
pub fn run_demo(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    const COMMAND: &str = "firelink demo --robot mahru";
    args.port
        .refuse_unless(COMMAND, &[firelink_testbed::port_spec::PortKind::Sim])?;
    args.port.refuse_board_count(
        COMMAND,
        "the MAHRU modules come from its configuration (seed 002's own protocol)",
    )?;
    let quiet = args.quiet || crate::args::quiet();
    let options = MahruDemoOptions {
        config: config(args.config.as_deref())?,
        duration_s: args.duration,
        period: period(args.period_us),
        find_fastest: true,
    };
    let report = run_mahru_demo(&options, |line| {
        if !quiet {
            eprintln!("demo: {line}");
        }
    })?;
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&report)?)?;
    } else {
        write!(out, "{report}")?;
    }
    report.verdict().map_err(CliError::Failed)
}

/// `firelink budget`.
pub fn run_budget_cmd(args: &BudgetArgs, out: &mut impl Write) -> Result<(), CliError> {
    let quiet = crate::args::quiet();
    let say = |line: &str| {
        if !quiet {
            eprintln!("budget: {line}");
        }
    };
    let config = config(args.config.as_deref())?;
    let systems = args.rtos.systems();
    let mut json = serde_json::Map::new();
    let mut does_not_fit = Vec::new();
    if args.tables.contains(&Table::Budget) {
        let report = run_budget(
            &BudgetOptions {
                config: config.clone(),
                period: period(args.period_us),
                samples: args.samples.min(u64::from(u32::MAX)) as u32,
                periods: args.periods,
                rtos: systems.clone(),
            },
            say,
        )?;
        does_not_fit = report.misfits();
        if args.json {
            json.insert("table_i".into(), serde_json::to_value(&report)?);
        } else {
            writeln!(out, "{report}")?;
        }
    }
    if args.tables.contains(&Table::ReadTimes) {
        say(&format!(
            "Table III: {} reads per payload and system",
            args.reads
        ));
        let report = run_table3(
            &Table3Options {
                reads: args.reads,
                rtos: systems,
                responder: config.responder_timing(),
                seed: config.seed,
                ..Table3Options::default()
            },
            |p| say(&format!("{} {} B done", p.rtos, p.payload)),
        )?;
        if let Some(path) = &args.plot {
            firelink_plot::mahru::table3(&report, path)?;
        }
        if args.json {
            json.insert("table_iii".into(), serde_json::to_value(&report)?);
        } else {
            writeln!(out, "{report}")?;
        }
    }
    if args.tables.contains(&Table::Can) {
        let report = run_table4(
            &Table4Options {
                config,
                cycles: args.can_cycles.min(u64::from(u32::MAX)) as u32,
                error_probability: args.can_errors,
                reads: args.reads.min(200_000),
                periods: args.periods.min(2000),
            },
            say,
        )?;
        if args.json {
            json.insert("table_iv".into(), serde_json::to_value(&report)?);
        } else {
            writeln!(out, "{report}")?;
        }
    }
    if args.json {
        writeln!(out, "{}", serde_json::Value::Object(json))?;
    }
    if does_not_fit.is_empty() {
        Ok(())
    } else {
        Err(CliError::DoesNotFit(format!(
            "the budget does not fit: {}",
            does_not_fit.join("; ")
        )))
    }
}
