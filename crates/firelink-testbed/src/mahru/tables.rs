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

/// The real-time systems a run of the tables covers (`--rtos`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
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
    /// The systems chosen, in the tables' order.
    pub fn systems(self) -> Vec<Rtos> {
        match self {
            RtosChoice::Both => Rtos::ALL.to_vec(),
            RtosChoice::Xenomai => vec![Rtos::Xenomai],
            RtosChoice::Rtlinux => vec![Rtos::RtLinux],
        }
    }
}

/// One of the seed's tables (`--tables`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Table {
    /// Table I: the time budget.
    #[cfg_attr(feature = "clap", value(name = "1"))]
    Budget,
    /// Table III: read time by payload.
    #[cfg_attr(feature = "clap", value(name = "3"))]
    ReadTimes,
    /// Table IV: CAN against 1394.
    #[cfg_attr(feature = "clap", value(name = "4"))]
    Can,
}

/// What `firelink budget` asks for (clap's `Args` behind the `clap`
/// feature): the configuration as a file, the tables as a list, the
/// counts as typed; [`TablesRequest::options`] makes the run's
/// [`TablesOptions`].
#[derive(Debug, Clone)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct TablesRequest {
    /// The MAHRU configuration (default: `configs/mahru-seed002.json`'s
    /// robot, built in).
    #[cfg_attr(feature = "clap", arg(long))]
    pub config: Option<std::path::PathBuf>,
    /// The servo period, `2ms`, `500Hz` (default: the configuration's 2
    /// ms; MAHRU's bounds: 100 us to 1 s).
    #[cfg_attr(
        feature = "clap",
        arg(long, conflicts_with = "period_us", value_parser = crate::limits::mahru_servo_period)
    )]
    pub period: Option<ServoPeriod>,
    /// The period in us (the older spelling of --period).
    #[cfg_attr(
        feature = "clap",
        arg(long = "period-us", hide = true, value_parser = crate::limits::servo_period_us)
    )]
    pub period_us: Option<ServoPeriod>,
    /// Real-time systems.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = RtosChoice::Both))]
    pub rtos: RtosChoice,
    /// Tables to produce (comma-separated): 1, 3, 4.
    #[cfg_attr(
        feature = "clap",
        arg(long, value_enum, value_delimiter = ',', default_value = "1,3,4")
    )]
    pub tables: Vec<Table>,
    /// Table I: timings per transaction type and module (1 to 100000).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 200, value_parser = crate::limits::timings)
    )]
    pub samples: u64,
    /// Table I: periods walked end to end (1 to 10^7).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 5000, value_parser = crate::limits::measured)
    )]
    pub periods: u64,
    /// Table III: simulated reads per payload and system (the seed: more
    /// than a million; 1 to 10^7).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 1_000_000, value_parser = crate::limits::measured)
    )]
    pub reads: u64,
    /// Table IV: CAN cycles (1 to 10^6).
    #[cfg_attr(
        feature = "clap",
        arg(long = "can-cycles", default_value_t = 2000, value_parser = crate::limits::can_cycles)
    )]
    pub can_cycles: u64,
    /// Table IV: chance of a bit error per CAN frame (0 to 1).
    #[cfg_attr(
        feature = "clap",
        arg(long = "can-errors", default_value_t = 0.0, value_parser = crate::limits::probability)
    )]
    pub can_errors: f64,
}

impl Default for TablesRequest {
    /// Every table for both systems on seed 002's robot at its own period,
    /// with `firelink budget`'s counts.
    fn default() -> Self {
        TablesRequest {
            config: None,
            period: None,
            period_us: None,
            rtos: RtosChoice::Both,
            tables: vec![Table::Budget, Table::ReadTimes, Table::Can],
            samples: 200,
            periods: 5000,
            reads: 1_000_000,
            can_cycles: 2000,
            can_errors: 0.0,
        }
    }
}

impl TablesRequest {
    /// The run's options: the configuration loaded (or seed 002's), the
    /// period (`period`, else the older `period_us`), the systems and
    /// tables chosen, the counts clamped to what the runs count in.
    ///
    /// # Errors
    /// The configuration cannot be loaded.
    pub fn options(&self) -> Result<TablesOptions, TestbedError> {
        let config = match &self.config {
            Some(path) => MahruConfig::load(path)?,
            None => MahruConfig::seed002(),
        };
        Ok(TablesOptions {
            config,
            period: self.period.or(self.period_us),
            rtos: self.rtos.systems(),
            budget: self.tables.contains(&Table::Budget),
            read_times: self.tables.contains(&Table::ReadTimes),
            can: self.tables.contains(&Table::Can),
            samples: self.samples.min(u64::from(u32::MAX)) as u32,
            periods: self.periods,
            reads: self.reads,
            can_cycles: self.can_cycles.min(u64::from(u32::MAX)) as u32,
            can_errors: self.can_errors,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_picks_tables_systems_and_period() {
        let options = TablesRequest::default().options().unwrap();
        assert!(options.budget && options.read_times && options.can);
        assert_eq!(options.rtos, Rtos::ALL.to_vec());
        assert_eq!((options.samples, options.can_cycles), (200, 2000));
        assert_eq!(options.period, None);
        let period: ServoPeriod = "1ms".parse().unwrap();
        let older: ServoPeriod = "3ms".parse().unwrap();
        let options = TablesRequest {
            tables: vec![Table::Can],
            rtos: RtosChoice::Xenomai,
            period_us: Some(older),
            samples: u64::MAX,
            ..TablesRequest::default()
        }
        .options()
        .unwrap();
        assert!(!options.budget && !options.read_times && options.can);
        assert_eq!(options.rtos, vec![Rtos::Xenomai]);
        assert_eq!(options.period, Some(older));
        assert_eq!(options.samples, u32::MAX);
        let options = TablesRequest {
            period: Some(period),
            period_us: Some(older),
            ..TablesRequest::default()
        }
        .options()
        .unwrap();
        assert_eq!(options.period, Some(period));
        assert!(
            TablesRequest {
                config: Some("/nonexistent/mahru.json".into()),
                ..TablesRequest::default()
            }
            .options()
            .is_err()
        );
    }

    /// The request's `Default` is the command line's defaults.
    #[cfg(feature = "clap")]
    #[test]
    fn the_default_is_what_the_command_line_gives_with_no_options() {
        use clap::{Args, FromArgMatches};
        let command = TablesRequest::augment_args(clap::Command::new("budget"));
        let parsed =
            TablesRequest::from_arg_matches(&command.get_matches_from(["budget"])).unwrap();
        assert_eq!(
            format!("{parsed:?}"),
            format!("{:?}", TablesRequest::default())
        );
    }
}
