//! `firelink budget`: seed 002's MAHRU humanoid's Tables I, III and IV
//! ([`firelink_testbed::mahru::tables`], whose [`TablesRequest`] is the
//! options); this file prints. (`firelink demo --robot mahru` is the
//! demo's request.)

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use firelink_testbed::mahru::tables::{TablesRequest, run_tables};

use crate::error::CliError;

/// Options of `firelink budget`.
#[derive(Args, Debug, Clone)]
pub struct BudgetArgs {
    /// The tables to run.
    #[command(flatten)]
    pub request: TablesRequest,
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
    let tables = run_tables(&args.request.options()?, |line| {
        if !quiet {
            say!("budget: {line}");
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
