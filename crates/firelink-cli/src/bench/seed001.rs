//! `firelink bench --seed 001`: seed 001's measurements (quadlet times of
//! Fig. 20, block times against size of Fig. 21, the 453 us and 65 us
//! servo budgets) reproduced on the simulated bus with that paper's PC
//! model; a table, JSON, and the figures as a PNG. The measurement is
//! [`firelink_testbed::snake::bench`], the figure
//! [`firelink_plot::seed001`].

use std::io::Write;
use std::path::Path;

use firelink_testbed::snake::bench::{Seed001Options, run_seed001_bench};

use crate::error::CliError;

/// The papers whose own measurements `--seed` reproduces.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeedPaper {
    /// Seed 001: the Snake robot's node.
    #[value(name = "001")]
    Seed001,
}

/// Run `firelink bench --seed 001` with `iterations` quadlet reads and
/// writes each, the figures drawn to `plot`, JSON or a table on `out`:
/// exits non-zero when a figure is more than 15 % from the paper's.
pub fn run(
    iterations: u64,
    plot: Option<&Path>,
    json: bool,
    out: &mut impl Write,
) -> Result<(), CliError> {
    let options = Seed001Options {
        iterations: usize::try_from(iterations).unwrap_or(usize::MAX),
        ..Seed001Options::default()
    };
    if !crate::args::quiet() {
        say!(
            "bench: seed 001 on the simulated bus: {} quadlet reads and writes, block sizes 1..512",
            options.iterations
        );
    }
    let report = run_seed001_bench(&options)?;
    if let Some(path) = plot {
        firelink_plot::seed001(&report, path)?;
    }
    if json {
        writeln!(out, "{}", serde_json::to_string(&report)?)?;
    } else {
        write!(out, "{report}")?;
    }
    report.verdict().map_err(CliError::Failed)
}
