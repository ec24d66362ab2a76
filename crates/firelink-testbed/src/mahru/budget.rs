//! Seed 002's time budget (Table I and inequality (1)) evaluated from
//! transaction times measured on the simulated robot, the seed's example
//! reproduced, and the same budget measured end to end.
//!
//! For each real-time system the robot is built and its modules mapped;
//! then every transaction type of Table I is timed on the computer's port
//! (call to return, the seed's `t1`..`t2`), `samples` times per module:
//! `t(PRQ)` (IDCHECK), `t(PWB)` (PARAMETER to each motor), `t(BWQ)` (a
//! quadlet broadcast selecting no module), `t(BWB)` (a 320-byte QWRITE
//! every module ignores) and `t(PRB)` (QREAD and FTREAD). Table I is
//! evaluated with the worst cases, and inequality (1) twice: as the seed's
//! example adds it up (`t(Te) = (Nm + Ns) x t(PRB)`, `t(Tg) = t(BWB)`)
//! and with Table I's formulas literally (their own slack terms inside
//! `Te` and `Tg`); see [`firelink_control::budget`]. Finally a fresh robot
//! walks for `periods` periods and the phases of each period are measured:
//! the sum of worst cases is a bound on the end-to-end worst case.

use std::fmt;
use std::time::Duration;

use serde::Serialize;

use firelink_control::ServoPeriod;
use firelink_control::budget::{CycleBudget, TableI};
use firelink_host::Port;
use firelink_host::mahru::rtos::Rtos;
use firelink_host::mahru::{MotionController, RobotLayout};
use firelink_host::port::Dest;
use firelink_wire::mahru::{
    Command, FtBlock, JointBlock, ModMask, ModuleKind, ParameterRecord, QWRITE_LEN,
};

use super::can::MAX_PERIODS;
use super::config::{MahruConfig, bounds, duration_us};
use super::demo::{PhaseSamples, PhaseStats, Stat, bring_up, check_period, motion};
use super::main_loop::MainLoop;
use super::rig::robot_port;
use crate::TestbedError;

/// The most timings per transaction type and module (each module's are
/// kept, 14 modules by 6 types).
pub const MAX_TIMINGS: u32 = 100_000;

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct BudgetOptions {
    /// The robot.
    pub config: MahruConfig,
    /// The period (default: the configuration's).
    pub period: Option<ServoPeriod>,
    /// Timings of each transaction type, per module.
    pub samples: u32,
    /// Periods of the end-to-end run.
    pub periods: u64,
    /// The real-time systems.
    pub rtos: Vec<Rtos>,
}

impl Default for BudgetOptions {
    fn default() -> Self {
        BudgetOptions {
            config: MahruConfig::seed002(),
            period: None,
            samples: 200,
            periods: 2000,
            rtos: Rtos::ALL.to_vec(),
        }
    }
}

/// Measured times of each transaction type of Table I, us.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TransactionTimes {
    /// P2P quadlet read (IDCHECK).
    pub prq: Stat,
    /// P2P block write (PARAMETER, 32 bytes).
    pub pwb: Stat,
    /// Broadcast quadlet write.
    pub bwq: Stat,
    /// Broadcast block write (QWRITE, 320 bytes).
    pub bwb: Stat,
    /// P2P block read, every module (QREAD 32 bytes, FTREAD 24 bytes).
    pub prb: Stat,
    /// P2P block read of the motor controllers (32 bytes).
    pub prb_32: Stat,
    /// P2P block read of the sensors (24 bytes).
    pub prb_24: Stat,
}

/// One row of Table I.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskRow {
    /// Task code (`T_a`).
    pub code: &'static str,
    /// Task name (`checkControllers`).
    pub name: &'static str,
    /// The equation.
    pub equation: &'static str,
    /// Its value with the measured worst cases, us.
    pub us: f64,
}

/// Inequality (1): `t(Te) + t(Tf) + t(Tg) + 2 t(Ts) < P`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Inequality {
    /// `t(Te)`, us.
    pub te_us: f64,
    /// `t(Tf)`, us.
    pub tf_us: f64,
    /// `t(Tg)`, us.
    pub tg_us: f64,
    /// `t(Ts)`, us.
    pub ts_us: f64,
    /// The left side, us.
    pub total_us: f64,
    /// `P`, us.
    pub period_us: f64,
    /// `P` minus the left side, us (negative: does not fit).
    pub slack_us: f64,
    /// Whether (1) holds.
    pub fits: bool,
}

fn us(d: Duration) -> f64 {
    (d.as_secs_f64() * 1e8).round() / 100.0
}

/// A budget term of `us` microseconds (validated figures; anything else is
/// clamped to 0..=1 s, never a panic).
fn dur(us: f64) -> Duration {
    duration_us(us, bounds::PHASE_US)
}

impl Inequality {
    fn of(b: &CycleBudget, period: Duration) -> Inequality {
        let r = b.check(period);
        Inequality {
            te_us: us(b.t_e),
            tf_us: us(b.t_f),
            tg_us: us(b.t_g),
            ts_us: us(b.t_s),
            total_us: us(r.total),
            period_us: us(period),
            slack_us: (r.margin_us() * 100.0).round() / 100.0,
            fits: r.fits(),
        }
    }
}

/// The seed's example (section IV.A) and the same from the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SeedExample {
    /// The seed's `t(PRB)` for 32 bytes, us (Table III).
    pub paper_prb_us: f64,
    /// The seed's worst-case `t(Tg)`, us.
    pub paper_tg_us: f64,
    /// The seed's sum, us (1640 Xenomai, 1560 RTLinux).
    pub paper_total_us: f64,
    /// The simulated worst `t(PRB)` of a 32-byte read, us.
    pub sim_prb_us: f64,
    /// The simulated worst `t(BWB)`, us.
    pub sim_tg_us: f64,
    /// The same sum with the simulated figures, us.
    pub sim_total_us: f64,
    /// `(sim - paper) / paper`, per cent.
    pub diff_pct: f64,
}

/// The budget measured end to end.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EndToEnd {
    /// Periods run.
    pub periods: u64,
    /// Phases of a period.
    pub phases: PhaseStats,
    /// Periods whose work did not fit.
    pub overruns: u64,
    /// The budget's bound (the seed's sum of worst cases), us.
    pub bound_us: f64,
    /// Whether the worst period stayed within the bound.
    pub within_bound: bool,
}

/// Everything for one real-time system.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RtosBudget {
    /// The system.
    pub rtos: &'static str,
    /// The transactions.
    pub transactions: TransactionTimes,
    /// Table I with the worst cases.
    pub table: Vec<TaskRow>,
    /// (1) as the seed's example adds it up.
    pub seed_arithmetic: Inequality,
    /// (1) with Table I's formulas literally.
    pub literal: Inequality,
    /// The seed's example.
    pub example: SeedExample,
    /// Measured end to end.
    pub end_to_end: EndToEnd,
}

/// The whole analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetReport {
    /// The robot.
    pub robot: String,
    /// Motor controllers.
    pub nm: u32,
    /// Sensor modules.
    pub ns: u32,
    /// The period, us.
    pub period_us: f64,
    /// `t(Tf)`, us.
    pub compute_us: f64,
    /// `t(Ts)`, us.
    pub slack_us: f64,
    /// Timings per transaction type and module.
    pub samples: u32,
    /// Per real-time system.
    pub per_rtos: Vec<RtosBudget>,
}

/// The seed's figures for `rtos`: `t(PRB)` of 32 bytes and `t(Tg)`.
pub fn paper_figures(rtos: Rtos) -> (f64, f64) {
    match rtos {
        Rtos::Xenomai => (75.0, 50.0),
        Rtos::RtLinux => (70.0, 40.0),
    }
}

/// Time one port call.
fn timed<P: Port, T>(port: &mut P, f: impl FnOnce(&mut P) -> T) -> (T, f32) {
    let t0 = port.now();
    let r = f(port);
    (
        r,
        (port.now().saturating_sub(t0).as_secs_f64() * 1e6) as f32,
    )
}

/// Measure every transaction type on a freshly mapped robot.
fn measure_transactions(
    config: &MahruConfig,
    samples: u32,
) -> Result<TransactionTimes, TestbedError> {
    let (port, _, _) = robot_port(config)?;
    let layout: RobotLayout = config.layout()?;
    let mut c = MotionController::new(port, layout.clone()).map_err(motion)?;
    c.map_modules().map_err(motion)?;
    let nodes: Vec<u8> = c.nodes().iter().map(|n| n.unwrap_or(0)).collect();
    let (mut prq, mut pwb, mut bwq, mut bwb, mut prb32, mut prb24) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut record = [0u8; ParameterRecord::LEN];
    let mut block = [0u8; JointBlock::LEN];
    let qwrite = [0u8; QWRITE_LEN];
    let port = c.port_mut();
    for _ in 0..samples {
        for (spec, &node) in layout.modules.iter().zip(&nodes) {
            let dest = Dest::node(node);
            let (r, t) = timed(port, |p| p.read_quadlet(dest, Command::IdCheck.offset()));
            r?;
            prq.push(t);
            if let Some(params) = spec.parameters {
                params
                    .emit(&mut record)
                    .map_err(firelink_host::HostError::Wire)?;
                let (r, t) = timed(port, |p| {
                    p.write_block(dest, Command::Parameter.offset(), &record)
                });
                r?;
                pwb.push(t);
            }
            let (command, len, out) = match spec.kind {
                ModuleKind::ForceTorque => (Command::FtRead, FtBlock::LEN, &mut prb24),
                _ => (Command::QRead, JointBlock::LEN, &mut prb32),
            };
            let buf = &mut block[..len];
            let (r, t) = timed(port, |p| p.read_block(dest, command.offset(), buf));
            r?;
            out.push(t);
        }
        let (r, t) = timed(port, |p| {
            p.write_quadlet(Dest::BROADCAST, Command::Ready.offset(), ModMask(0).0)
        });
        r?;
        bwq.push(t);
        let (r, t) = timed(port, |p| {
            p.write_block(Dest::BROADCAST, Command::QWrite.offset(), &qwrite)
        });
        r?;
        bwb.push(t);
    }
    let mut all: Vec<f32> = prb32.iter().chain(&prb24).copied().collect();
    Ok(TransactionTimes {
        prq: Stat::of(&mut prq),
        pwb: Stat::of(&mut pwb),
        bwq: Stat::of(&mut bwq),
        bwb: Stat::of(&mut bwb),
        prb: Stat::of(&mut all),
        prb_32: Stat::of(&mut prb32),
        prb_24: Stat::of(&mut prb24),
    })
}

/// Table I evaluated with worst cases `t`, `n` modules of which `nm`
/// motors.
fn table_i(t: &TransactionTimes, nm: u32, n: u32, tf: f64, ts: f64) -> Vec<TaskRow> {
    let row = |code, name, equation, us: f64| TaskRow {
        code,
        name,
        equation,
        us: (us * 100.0).round() / 100.0,
    };
    let n = f64::from(n);
    vec![
        row(
            "T_a",
            "checkControllers",
            "(Nm + Ns) x t(PRQ) + 2 t(Ts)",
            n * t.prq.max + 2.0 * ts,
        ),
        row(
            "T_b",
            "transmitParam",
            "Nm x t(PWB) + 2 t(Ts)",
            f64::from(nm) * t.pwb.max + 2.0 * ts,
        ),
        row("T_c", "setReadyOrBias", "t(BWQ) + t(Ts)", t.bwq.max + ts),
        row("T_d", "startControl", "t(BWQ) + t(Ts)", t.bwq.max + ts),
        row(
            "T_e",
            "readCurrentData",
            "(Nm + Ns) x t(PRB) + 2 t(Ts)",
            n * t.prb.max + 2.0 * ts,
        ),
        row("T_f", "computeNewParam", "t(Tf)", tf),
        row("T_g", "transmitNewParam", "t(BWB) + t(Ts)", t.bwb.max + ts),
        row("T_h", "stopControl", "t(BWQ) + t(Ts)", t.bwq.max + ts),
    ]
}

/// Run the analysis.
///
/// # Errors
/// A configuration that cannot be built, or a transaction that fails.
pub fn run_budget(
    options: &BudgetOptions,
    mut progress: impl FnMut(&str),
) -> Result<BudgetReport, TestbedError> {
    let base = &options.config;
    base.validate()?;
    if !(1..=MAX_PERIODS).contains(&options.periods) {
        return Err(TestbedError::Config(format!(
            "Table I: {} periods is out of range: 1 to {MAX_PERIODS}",
            options.periods
        )));
    }
    if !(1..=MAX_TIMINGS).contains(&options.samples) {
        return Err(TestbedError::Config(format!(
            "Table I: {} timings per transaction type and module is out of range: 1 to {MAX_TIMINGS}",
            options.samples
        )));
    }
    let period = options.period.map(ServoPeriod::as_duration);
    let period = check_period(period.unwrap_or_else(|| base.period()))?;
    let layout = base.layout()?;
    let nm = layout
        .modules
        .iter()
        .filter(|m| m.kind == ModuleKind::MotorController)
        .count() as u32;
    let n = layout.modules.len() as u32;
    let (tf, ts) = (base.compute_us, base.slack_us);
    let mut per_rtos = Vec::new();
    for &rtos in &options.rtos {
        let config = MahruConfig {
            rtos: rtos.name().into(),
            ..base.clone()
        };
        progress(&format!("{rtos}: timing every transaction type"));
        let t = measure_transactions(&config, options.samples.max(1))?;
        let seed = CycleBudget {
            t_e: dur(f64::from(n) * t.prb.max),
            t_f: dur(tf),
            t_g: dur(t.bwb.max),
            t_s: dur(ts),
        };
        let literal = TableI {
            motor_controllers: nm,
            sensor_modules: n - nm,
            t_prb: dur(t.prb.max),
            t_f: dur(tf),
            t_bwb: dur(t.bwb.max),
            t_s: dur(ts),
        }
        .budget();
        let (paper_prb, paper_tg) = paper_figures(rtos);
        let paper_total = 14.0 * paper_prb + 500.0 + paper_tg + 2.0 * 20.0;
        let sim_total = 14.0 * t.prb_32.max + 500.0 + t.bwb.max + 2.0 * 20.0;
        progress(&format!(
            "{rtos}: walking {} periods at {:.0} us",
            options.periods,
            us(period)
        ));
        let mut r = bring_up(&config)?;
        let mut main = MainLoop::new(&config, period);
        let mut phases = PhaseSamples::default();
        for _ in 0..options.periods {
            let p = main
                .period_once(&mut r.controller, |_| {})
                .map_err(motion)?;
            phases.push(&p);
        }
        let _ = r.controller.stop();
        let phases = phases.stats();
        let seed_arithmetic = Inequality::of(&seed, period);
        per_rtos.push(RtosBudget {
            rtos: rtos.name(),
            table: table_i(&t, nm, n, tf, ts),
            literal: Inequality::of(&literal, period),
            example: SeedExample {
                paper_prb_us: paper_prb,
                paper_tg_us: paper_tg,
                paper_total_us: paper_total,
                sim_prb_us: t.prb_32.max,
                sim_tg_us: t.bwb.max,
                sim_total_us: (sim_total * 100.0).round() / 100.0,
                diff_pct: ((sim_total - paper_total) / paper_total * 1000.0).round() / 10.0,
            },
            end_to_end: EndToEnd {
                periods: main.periods,
                overruns: main.overruns,
                bound_us: seed_arithmetic.total_us,
                within_bound: phases.busy.max <= seed_arithmetic.total_us,
                phases,
            },
            seed_arithmetic,
            transactions: t,
        });
    }
    Ok(BudgetReport {
        robot: base.name.clone(),
        nm,
        ns: n - nm,
        period_us: us(period),
        compute_us: tf,
        slack_us: ts,
        samples: options.samples,
        per_rtos,
    })
}

impl BudgetReport {
    /// What does not fit the period, one phrase per real-time system
    /// (none when everything fits): each inequality (1) that fails, and
    /// the periods that overran end to end.
    pub fn misfits(&self) -> Vec<String> {
        self.per_rtos
            .iter()
            .filter_map(|r| {
                let mut what = Vec::new();
                for (name, q) in [
                    ("as the seed adds it", r.seed_arithmetic),
                    ("with Table I literally", r.literal),
                ] {
                    if !q.fits {
                        what.push(format!(
                            "(1) {name} needs {:.1} us of the {} us period",
                            q.total_us,
                            firelink_wire::human::Number(q.period_us)
                        ));
                    }
                }
                if r.end_to_end.overruns > 0 {
                    what.push(format!(
                        "{} of {} periods overran end to end",
                        r.end_to_end.overruns, r.end_to_end.periods
                    ));
                }
                (!what.is_empty()).then(|| format!("{}: {}", r.rtos, what.join(", ")))
            })
            .collect()
    }
}

impl fmt::Display for BudgetReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Table I for {}: Nm = {}, Ns = {}, P = {:.0} us, t(Tf) = {:.0} us, t(Ts) = {:.0} us ({} timings per transaction type and module)",
            self.robot,
            self.nm,
            self.ns,
            self.period_us,
            self.compute_us,
            self.slack_us,
            self.samples
        )?;
        for r in &self.per_rtos {
            let t = &r.transactions;
            writeln!(
                f,
                "\n{}: transaction times (us)     p50      p99      max",
                r.rtos
            )?;
            for (name, s) in [
                ("t(PRQ) IDCHECK", t.prq),
                ("t(PWB) PARAMETER", t.pwb),
                ("t(BWQ) quadlet broadcast", t.bwq),
                ("t(BWB) QWRITE 320 B", t.bwb),
                ("t(PRB) QREAD 32 B", t.prb_32),
                ("t(PRB) FTREAD 24 B", t.prb_24),
            ] {
                writeln!(f, "  {name:26} {s}")?;
            }
            writeln!(f, "  Table I with the worst cases:")?;
            for row in &r.table {
                writeln!(
                    f,
                    "    {:4} {:17} {:30} {:8.1} us",
                    row.code, row.name, row.equation, row.us
                )?;
            }
            for (name, q) in [
                ("(1) as the seed adds it", r.seed_arithmetic),
                ("(1) with Table I literally", r.literal),
            ] {
                writeln!(
                    f,
                    "  {name:27}: {:.1} + {:.1} + {:.1} + 2 x {:.1} = {:.1} us of {:.0}: {} ({:+.1} us)",
                    q.te_us,
                    q.tf_us,
                    q.tg_us,
                    q.ts_us,
                    q.total_us,
                    q.period_us,
                    if q.fits { "fits" } else { "does NOT fit" },
                    q.slack_us
                )?;
            }
            let e = &r.example;
            writeln!(
                f,
                "  seed's example: 14 x {:.0} + 500 + {:.0} + 40 = {:.0} us; simulated 14 x {:.1} + 500 + {:.1} + 40 = {:.1} us ({:+.1} %)",
                e.paper_prb_us,
                e.paper_tg_us,
                e.paper_total_us,
                e.sim_prb_us,
                e.sim_tg_us,
                e.sim_total_us,
                e.diff_pct
            )?;
            let m = &r.end_to_end;
            writeln!(
                f,
                "  end to end, {} periods (us)  p50      p99      max",
                m.periods
            )?;
            writeln!(f, "    t(Te) read all        {}", m.phases.read)?;
            writeln!(f, "    t(Tf) compute         {}", m.phases.compute)?;
            writeln!(f, "    t(Tg) QWRITE          {}", m.phases.write)?;
            writeln!(f, "    whole period's work   {}", m.phases.busy)?;
            writeln!(
                f,
                "    worst period {:.1} us {} the budget's {:.1} us; {} overruns",
                m.phases.busy.max,
                if m.within_bound { "within" } else { "ABOVE" },
                m.bound_us,
                m.overruns
            )?;
        }
        Ok(())
    }
}
