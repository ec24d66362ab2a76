//! `firelink budget`: the seed's Tables I, III and IV in one run, on one
//! configuration and one servo period, each table when asked for, with
//! their JSON (`table_i`, `table_iii`, `table_iv`) and their text.

use std::fmt;

use firelink_control::ServoPeriod;
use firelink_host::mahru::rtos::Rtos;

use super::budget::{BudgetOptions, BudgetReport, run_budget};
use super::can::{Table4Options, Table4Report, run_table4};
use super::config::MahruConfig;
use super::table3::{Table3Options, Table3Report, run_table3};
use crate::TestbedError;

/// What a run of the tables is asked for.
#[derive(Debug, Clone)]
pub struct TablesOptions {
    /// The robot.
    pub config: MahruConfig,
    /// The servo period (default: the configuration's).
    pub period: Option<ServoPeriod>,
    /// The real-time systems.
    pub rtos: Vec<Rtos>,
    /// Table I: its time budget.
    pub budget: bool,
    /// Table III: read times by payload.
    pub read_times: bool,
    /// Table IV: CAN against 1394.
    pub can: bool,
    /// Table I: timings per transaction type and module.
    pub samples: u32,
    /// Table I: periods end to end (Table IV: at most 2000 of them).
    pub periods: u64,
    /// Table III: reads per payload and system (Table IV: at most 200 000).
    pub reads: u64,
    /// Table IV: CAN cycles.
    pub can_cycles: u32,
    /// Table IV: chance of a bit error per CAN frame.
    pub can_errors: f64,
}

/// The tables produced.
#[derive(Debug, Clone, Default)]
pub struct Tables {
    /// Table I.
    pub table_i: Option<BudgetReport>,
    /// Table III.
    pub table_iii: Option<Table3Report>,
    /// Table IV.
    pub table_iv: Option<Table4Report>,
}

/// Run the tables asked for, in order, `say` getting each step (from
/// Table III's threads too).
///
/// # Errors
/// The first table's error.
pub fn run_tables(
    options: &TablesOptions,
    say: impl Fn(&str) + Sync,
) -> Result<Tables, TestbedError> {
    let mut tables = Tables::default();
    let config = &options.config;
    if options.budget {
        let budget = BudgetOptions {
            config: config.clone(),
            period: options.period,
            samples: options.samples,
            periods: options.periods,
            rtos: options.rtos.clone(),
        };
        tables.table_i = Some(run_budget(&budget, &say)?);
    }
    if options.read_times {
        say(&format!(
            "Table III: {} reads per payload and system",
            options.reads
        ));
        let table3 = Table3Options {
            reads: options.reads,
            rtos: options.rtos.clone(),
            responder: config.responder_timing(),
            seed: config.seed,
            ..Table3Options::default()
        };
        tables.table_iii = Some(run_table3(&table3, |p| {
            say(&format!("{} {} B done", p.rtos, p.payload));
        })?);
    }
    if options.can {
        let table4 = Table4Options {
            config: config.clone(),
            cycles: options.can_cycles,
            error_probability: options.can_errors,
            reads: options.reads.min(200_000),
            periods: options.periods.min(2000),
        };
        tables.table_iv = Some(run_table4(&table4, &say)?);
    }
    Ok(tables)
}

impl Tables {
    /// The tables as one JSON object: `table_i`, `table_iii`, `table_iv`
    /// (those produced).
    ///
    /// # Errors
    /// Serialisation (not expected: the reports are plain data).
    pub fn json(&self) -> Result<serde_json::Value, serde_json::Error> {
        let mut json = serde_json::Map::new();
        if let Some(t) = &self.table_i {
            json.insert("table_i".into(), serde_json::to_value(t)?);
        }
        if let Some(t) = &self.table_iii {
            json.insert("table_iii".into(), serde_json::to_value(t)?);
        }
        if let Some(t) = &self.table_iv {
            json.insert("table_iv".into(), serde_json::to_value(t)?);
        }
        Ok(serde_json::Value::Object(json))
    }

    /// The real-time systems whose Table I budget does not fit, each with
    /// why (empty: it fits, or Table I was not asked for).
    pub fn misfits(&self) -> Vec<String> {
        self.table_i
            .as_ref()
            .map(BudgetReport::misfits)
            .unwrap_or_default()
    }

    /// The verdict: `Err` says what does not fit ([`Self::misfits`]), as
    /// one line.
    ///
    /// # Errors
    /// A Table I budget that does not fit.
    pub fn verdict(&self) -> Result<(), String> {
        let misfits = self.misfits();
        if misfits.is_empty() {
            return Ok(());
        }
        Err(format!("the budget does not fit: {}", misfits.join("; ")))
    }
}

/// Each table produced, followed by an empty line.
impl fmt::Display for Tables {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(t) = &self.table_i {
            writeln!(f, "{t}")?;
        }
        if let Some(t) = &self.table_iii {
            writeln!(f, "{t}")?;
        }
        if let Some(t) = &self.table_iv {
            writeln!(f, "{t}")?;
        }
        Ok(())
    }
}
