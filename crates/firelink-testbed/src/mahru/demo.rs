//! The MAHRU demo: seed 002's humanoid on the simulated bus, brought up
//! by the MotionController and walking at its period, then stopped; the
//! report gives the timing of every phase, each module's read time and
//! tracking, the force/torque readings, the errors, and the fastest period
//! that holds.

use std::fmt;
use std::time::Duration;

use serde::Serialize;

use firelink_board::mahru::ModuleNode;
use firelink_bus::{Detail, DetailReport};
use firelink_control::ServoPeriod;
use firelink_control::runner::Percentiles;
use firelink_host::Port;
use firelink_host::mahru::{MotionController, MotionError, RobotLayout};
use firelink_host::sim::SimPort;
use firelink_wire::mahru::{ModuleKind, ModuleState};

use firelink_wire::human::Number;

use super::config::{MahruConfig, bounds};
use super::main_loop::{MainLoop, PeriodTimes};
use super::rig::{PlacedModule, robot_port};
use crate::TestbedError;

/// The most periods whose timings a run keeps per series (about 35 minutes
/// of walking at 2 ms); later periods are run and counted, not recorded.
pub const MAX_SAMPLES: usize = 1 << 20;

/// The most periods the search for the fastest period runs at each
/// candidate.
const FASTEST_PERIODS: u64 = 10_000;

/// The longest walk a demo runs, seconds (one day).
pub const MAX_DURATION_S: f64 = 86_400.0;

/// `period` if it is within [`bounds::PERIOD_US`].
///
/// # Errors
/// [`TestbedError::Config`] with the range.
pub fn check_period(period: Duration) -> Result<Duration, TestbedError> {
    let us = period.as_secs_f64() * 1e6;
    let (lo, hi) = bounds::PERIOD_US;
    if (lo..=hi).contains(&us) {
        Ok(period)
    } else {
        Err(TestbedError::Config(format!(
            "MAHRU: period {} us is out of range: {} to {} us",
            Number(us),
            Number(lo),
            Number(hi)
        )))
    }
}

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct MahruDemoOptions {
    /// The robot.
    pub config: MahruConfig,
    /// Seconds of walking.
    pub duration_s: f64,
    /// The period (default: the configuration's).
    pub period: Option<ServoPeriod>,
    /// Also search for the fastest period that holds.
    pub find_fastest: bool,
    /// The simulated bus's level of detail for the walk (the same answer
    /// either way; the search for the fastest period runs fast).
    pub detail: Detail,
}

impl Default for MahruDemoOptions {
    fn default() -> Self {
        MahruDemoOptions {
            config: MahruConfig::seed002(),
            duration_s: 3.0,
            period: None,
            find_fastest: true,
            detail: Detail::Fast,
        }
    }
}

/// Median, 99th percentile and maximum, us.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Stat {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Maximum.
    pub max: f64,
}

impl Stat {
    /// Of samples (sorted in place).
    pub fn of(samples: &mut [f32]) -> Stat {
        let p = Percentiles::of(samples);
        let r = |x: f64| (x * 100.0).round() / 100.0;
        Stat {
            p50: r(p.median),
            p99: r(p.p99),
            max: r(p.max),
        }
    }
}

impl fmt::Display for Stat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:8.1} {:8.1} {:8.1}", self.p50, self.p99, self.max)
    }
}

/// The phases of a period.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct PhaseStats {
    /// Reading every module, `t(Te)`.
    pub read: Stat,
    /// Computation charged, `t(Tf)`.
    pub compute: Stat,
    /// The QWRITE broadcast, `t(Tg)`.
    pub write: Stat,
    /// The whole period's work.
    pub busy: Stat,
}

/// Collected phase samples.
#[derive(Debug, Default)]
pub(crate) struct PhaseSamples {
    read: Vec<f32>,
    compute: Vec<f32>,
    write: Vec<f32>,
    busy: Vec<f32>,
}

impl PhaseSamples {
    /// Record one period (beyond [`MAX_SAMPLES`] periods, only the first
    /// ones are kept: the statistics are theirs).
    pub(crate) fn push(&mut self, t: &PeriodTimes) {
        if self.read.len() >= MAX_SAMPLES {
            return;
        }
        self.read.push(t.read_us as f32);
        self.compute.push(t.compute_us as f32);
        self.write.push(t.write_us as f32);
        self.busy.push(t.busy_us as f32);
    }

    pub(crate) fn stats(&mut self) -> PhaseStats {
        PhaseStats {
            read: Stat::of(&mut self.read),
            compute: Stat::of(&mut self.compute),
            write: Stat::of(&mut self.write),
            busy: Stat::of(&mut self.busy),
        }
    }
}

/// One module in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModuleReport {
    /// Module ID.
    pub mod_id: u8,
    /// Name.
    pub name: String,
    /// `motor` or `force_torque`.
    pub kind: &'static str,
    /// Chain (port of the card).
    pub chain: usize,
    /// Hops from the computer.
    pub hops: u32,
    /// Node ID at the end of the run.
    pub node: Option<u8>,
    /// Its QREAD / FTREAD time.
    pub read_us: Stat,
    /// Motors: the servo's tracking error (target - position), RMS, mrad.
    pub tracking_rms_mrad: Option<f64>,
    /// Motors: the largest tracking error, mrad.
    pub tracking_max_mrad: Option<f64>,
}

/// One force/torque sensor's readings over the walk (N, N, N, Nm, Nm, Nm).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FtReport {
    /// Module ID.
    pub mod_id: u8,
    /// Name.
    pub name: String,
    /// Mean per axis.
    pub mean: [f64; 6],
    /// Minimum per axis.
    pub min: [f64; 6],
    /// Maximum per axis.
    pub max: [f64; 6],
    /// The reading of the first period (just after START).
    pub first: [f64; 6],
}

/// The errors of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct MahruErrors {
    /// Periods in which a module was missed (the robot stopped).
    pub missed: u64,
    /// Periods whose work did not fit.
    pub overruns: u64,
    /// What stopped the robot, if anything did.
    pub fault: Option<String>,
    /// Bus resets recovered from (not errors: node IDs moved).
    pub resets_recovered: u64,
    /// Missed, overruns and the fault.
    pub total: u64,
}

/// The fastest period that held.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FastestPeriod {
    /// The period, us.
    pub period_us: f64,
    /// Periods run at it.
    pub periods: u64,
    /// Overruns (0: it holds).
    pub overruns: u64,
    /// The work of a period at it.
    pub busy: Stat,
}

/// The demo's report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MahruDemoReport {
    /// The robot.
    pub robot: String,
    /// The computer's real-time system.
    pub rtos: &'static str,
    /// Control period, us.
    pub period_us: f64,
    /// Walking time, s.
    pub duration_s: f64,
    /// Periods run.
    pub periods: u64,
    /// The bus's diameter in hops and its gap count.
    pub diameter_hops: u32,
    /// The phases of a period.
    pub timing: PhaseStats,
    /// Every module.
    pub modules: Vec<ModuleReport>,
    /// The force/torque sensors.
    pub force_torque: Vec<FtReport>,
    /// Mean of both feet's vertical force while walking, N.
    pub weight_on_feet_n: f64,
    /// The robot's weight, N.
    pub body_weight_n: f64,
    /// Whether STOP left every module stopped with its amplifier off.
    pub stopped_cleanly: bool,
    /// What went wrong.
    pub errors: MahruErrors,
    /// The fastest period that held (when searched).
    pub fastest: Option<FastestPeriod>,
    /// What ran at which level of detail in the walk (from its first
    /// period on).
    pub detail: DetailReport,
}

impl MahruDemoReport {
    /// `Ok` when the run walked without an error and stopped cleanly.
    ///
    /// # Errors
    /// What went wrong, in one line.
    pub fn verdict(&self) -> Result<(), String> {
        if self.errors.total > 0 {
            return Err(format!(
                "{} errors ({} missed, {} overruns{})",
                self.errors.total,
                self.errors.missed,
                self.errors.overruns,
                self.errors
                    .fault
                    .as_deref()
                    .map_or(String::new(), |f| format!(", {f}"))
            ));
        }
        if !self.stopped_cleanly {
            return Err("STOP did not leave every module stopped".into());
        }
        Ok(())
    }
}

/// One sensor's readings, summed up.
#[derive(Debug, Clone, Copy)]
struct FtAccum {
    sum: [f64; 6],
    min: [f64; 6],
    max: [f64; 6],
    first: Option<[f64; 6]>,
    count: u64,
}

impl Default for FtAccum {
    fn default() -> Self {
        FtAccum {
            sum: [0.0; 6],
            min: [f64::INFINITY; 6],
            max: [f64::NEG_INFINITY; 6],
            first: None,
            count: 0,
        }
    }
}

impl FtAccum {
    fn add(&mut self, w: [f64; 6]) {
        self.first.get_or_insert(w);
        self.count += 1;
        for (a, x) in w.into_iter().enumerate() {
            self.sum[a] += x;
            self.min[a] = self.min[a].min(x);
            self.max[a] = self.max[a].max(x);
        }
    }
}

/// A robot on the bus, brought up.
pub(crate) struct Running {
    pub controller: MotionController<SimPort>,
    pub modules: Vec<PlacedModule>,
    pub diameter: u32,
}

/// Build the robot of `config` and bring it up (the first SETBIAS while
/// it hangs, START lowers it to the ground).
pub(crate) fn bring_up(config: &MahruConfig) -> Result<Running, TestbedError> {
    bring_up_at(config, Detail::Fast)
}

/// [`bring_up`] on a bus at level of detail `detail`.
pub(crate) fn bring_up_at(config: &MahruConfig, detail: Detail) -> Result<Running, TestbedError> {
    let (mut port, modules, diameter) = robot_port(config)?;
    port.bus_mut().set_detail(detail);
    let mut controller = MotionController::new(port, config.layout()?).map_err(motion)?;
    controller.bring_up().map_err(motion)?;
    Ok(Running {
        controller,
        modules,
        diameter,
    })
}

pub(crate) fn motion(e: MotionError) -> TestbedError {
    TestbedError::Config(format!("MAHRU: {e}"))
}

/// Whether every module is stopped with its amplifier off.
fn all_stopped(controller: &mut MotionController<SimPort>, modules: &[PlacedModule]) -> bool {
    controller.port_mut().wait(Duration::from_millis(1));
    let bus = controller.port().bus();
    modules.iter().all(|m| {
        bus.node::<ModuleNode>(m.handle).is_some_and(|n| {
            n.state() == ModuleState::Stopped && n.motor().is_none_or(|j| !j.amplifier_on())
        })
    })
}

/// Run `periods` periods at `period` on a fresh robot; the work of each.
fn try_period(
    config: &MahruConfig,
    period: Duration,
    periods: u64,
) -> Result<(PhaseStats, u64, u64), TestbedError> {
    let mut r = bring_up(config)?;
    let mut main = MainLoop::new(config, period);
    let mut samples = PhaseSamples::default();
    let mut failed = 0;
    for _ in 0..periods {
        match main.period_once(&mut r.controller, |_| {}) {
            Ok(t) => samples.push(&t),
            Err(_) => {
                failed += 1;
                break;
            }
        }
    }
    let _ = r.controller.stop();
    Ok((samples.stats(), main.overruns, failed))
}

/// Run the demo. `progress` hears what is happening.
///
/// # Errors
/// A configuration that cannot be built or brought up.
pub fn run_mahru_demo(
    options: &MahruDemoOptions,
    mut progress: impl FnMut(&str),
) -> Result<MahruDemoReport, TestbedError> {
    let config = &options.config;
    config.validate()?;
    let period = options.period.map(ServoPeriod::as_duration);
    let period = check_period(period.unwrap_or_else(|| config.period()))?;
    if !(options.duration_s.is_finite()
        && options.duration_s > 0.0
        && options.duration_s <= MAX_DURATION_S)
    {
        return Err(TestbedError::Config(format!(
            "MAHRU demo: duration {} s is out of range: above 0 to {} s",
            Number(options.duration_s),
            Number(MAX_DURATION_S)
        )));
    }
    let mut r = bring_up_at(config, options.detail)?;
    progress(&format!(
        "brought up {} modules on 3 chains ({} hops across); walking at {:.0} us for {} s",
        r.modules.len(),
        r.diameter,
        period.as_secs_f64() * 1e6,
        Number(options.duration_s)
    ));
    let n = r.controller.layout().modules.len();
    let periods = (options.duration_s.max(0.0) / period.as_secs_f64()).round() as u64;
    let mut main = MainLoop::new(config, period);
    let mut phases = PhaseSamples::default();
    let room = usize::try_from(periods).map_or(MAX_SAMPLES, |p| p.min(MAX_SAMPLES));
    let mut reads: Vec<Vec<f32>> = vec![Vec::with_capacity(room); n];
    let mut tracking: Vec<(f64, f64, u64)> = vec![(0.0, 0.0, 0); n];
    let mut ft: Vec<FtAccum> = vec![FtAccum::default(); n];
    let mut samples = 0u64;
    let mut feet_fz = 0.0;
    let feet: Vec<usize> = r
        .controller
        .layout()
        .modules
        .iter()
        .enumerate()
        .filter(|(_, m)| m.name.contains("foot"))
        .map(|(i, _)| i)
        .collect();
    let mut fault = None;
    for _ in 0..periods {
        let result = main.period_once(&mut r.controller, |fb| {
            samples += 1;
            for i in 0..n {
                if reads[i].len() < MAX_SAMPLES {
                    reads[i].push((fb.read_times[i].as_secs_f64() * 1e6) as f32);
                }
                if let Some(j) = fb.joints[i] {
                    let e = f64::from(j.target_urad) - f64::from(j.position_urad);
                    let t = &mut tracking[i];
                    t.0 += e * e;
                    t.1 = t.1.max(e.abs());
                    t.2 += 1;
                }
                if let Some(w) = fb.wrenches[i] {
                    ft[i].add(w.wrench());
                }
            }
            feet_fz += feet
                .iter()
                .filter_map(|&i| fb.wrenches[i])
                .map(|w| w.wrench()[2])
                .sum::<f64>();
        });
        match result {
            Ok(t) => phases.push(&t),
            Err(e) => {
                progress(&format!("FAULT: {e}"));
                fault = Some(e.to_string());
                break;
            }
        }
    }
    let _ = r.controller.stop();
    let detail = r.controller.port().bus().detail_report();
    let stopped_cleanly = all_stopped(&mut r.controller, &r.modules);
    let stats = r.controller.stats();
    let layout = r.controller.layout().clone();
    let modules = module_reports(
        &layout,
        &r.modules,
        r.controller.nodes(),
        &mut reads,
        &tracking,
    );
    let round = |x: f64| (x * 1000.0).round() / 1000.0;
    let force_torque = force_torque_reports(&layout, &ft);
    let missed = stats.missed;
    let errors = MahruErrors {
        missed,
        overruns: main.overruns,
        total: missed + main.overruns + u64::from(fault.is_some() && missed == 0),
        fault,
        resets_recovered: stats.resets_recovered,
    };
    let timing = phases.stats();
    let fastest = if options.find_fastest && errors.total == 0 {
        progress("searching the fastest period that holds");
        Some(fastest_period(
            config,
            timing.busy.max,
            periods.clamp(500, FASTEST_PERIODS),
        )?)
    } else {
        None
    };
    Ok(MahruDemoReport {
        robot: config.name.clone(),
        rtos: config.rtos()?.name(),
        period_us: period.as_secs_f64() * 1e6,
        duration_s: main.periods as f64 * period.as_secs_f64(),
        periods: main.periods,
        diameter_hops: r.diameter,
        timing,
        modules,
        force_torque,
        weight_on_feet_n: round(feet_fz / samples.max(1) as f64),
        body_weight_n: round(config.body.mass_kg * 9.81),
        stopped_cleanly,
        errors,
        fastest,
        detail,
    })
}

/// Each module's line of the report: where it sits, its read times and
/// how closely it tracked (`tracking[i]`: squared-error sum, largest
/// error, samples, in urad).
fn module_reports(
    layout: &RobotLayout,
    placed: &[PlacedModule],
    nodes: &[Option<u8>],
    reads: &mut [Vec<f32>],
    tracking: &[(f64, f64, u64)],
) -> Vec<ModuleReport> {
    let milli = |x: f64| (x * 1000.0).round() / 1000.0;
    layout
        .modules
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            let placed = placed.iter().find(|m| m.mod_id == spec.mod_id);
            let (rms, max) = match tracking[i] {
                (sq, max, k) if k > 0 => (Some((sq / k as f64).sqrt() * 1e-3), Some(max * 1e-3)),
                _ => (None, None),
            };
            ModuleReport {
                mod_id: spec.mod_id.0,
                name: spec.name.clone(),
                kind: if spec.kind == ModuleKind::ForceTorque {
                    "force_torque"
                } else {
                    "motor"
                },
                chain: placed.map_or(0, |m| m.chain),
                hops: placed.map_or(0, |m| m.hops),
                node: nodes.get(i).copied().flatten(),
                read_us: Stat::of(&mut reads[i]),
                tracking_rms_mrad: rms.map(milli),
                tracking_max_mrad: max.map(milli),
            }
        })
        .collect()
}

/// Each force/torque sensor's readings over the run (to 1/1000).
fn force_torque_reports(layout: &RobotLayout, ft: &[FtAccum]) -> Vec<FtReport> {
    let round = |x: f64| (x * 1000.0).round() / 1000.0;
    layout
        .modules
        .iter()
        .enumerate()
        .filter(|(_, m)| m.kind == ModuleKind::ForceTorque)
        .map(|(i, m)| {
            let s = &ft[i];
            FtReport {
                mod_id: m.mod_id.0,
                name: m.name.clone(),
                mean: s.sum.map(|x| round(x / s.count.max(1) as f64)),
                min: s.min.map(round),
                max: s.max.map(round),
                first: s.first.unwrap_or_default().map(round),
            }
        })
        .collect()
}

/// From the largest work seen, in 10 us steps: the first period at which
/// `periods` periods run without an overrun or an error.
fn fastest_period(
    config: &MahruConfig,
    busy_max_us: f64,
    periods: u64,
) -> Result<FastestPeriod, TestbedError> {
    let mut candidate = (busy_max_us / 10.0).ceil() * 10.0;
    for _ in 0..50 {
        let period = Duration::from_secs_f64(candidate / 1e6);
        let (stats, overruns, failed) = try_period(config, period, periods)?;
        if overruns == 0 && failed == 0 {
            return Ok(FastestPeriod {
                period_us: candidate,
                periods,
                overruns,
                busy: stats.busy,
            });
        }
        candidate += 10.0;
    }
    Err(TestbedError::Config(
        "MAHRU demo: no period within 500 us of the largest work holds".into(),
    ))
}

impl fmt::Display for MahruDemoReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: {} modules, {} hops across, {} at {:.0} us: {} periods ({:.2} s of walking)",
            self.robot,
            self.modules.len(),
            self.diameter_hops,
            self.rtos,
            self.period_us,
            self.periods,
            self.duration_s
        )?;
        writeln!(f, "period phases (us)          p50      p99      max")?;
        let t = &self.timing;
        writeln!(f, "  read all, t(Te)      {}", t.read)?;
        writeln!(f, "  compute, t(Tf)       {}", t.compute)?;
        writeln!(f, "  QWRITE, t(Tg)        {}", t.write)?;
        writeln!(f, "  whole period's work  {}", t.busy)?;
        writeln!(f, "{}", self.detail)?;
        writeln!(
            f,
            "modules: ModID name              chain hops node  read p50/max (us)  tracking rms/max (mrad)"
        )?;
        for m in &self.modules {
            let track = match (m.tracking_rms_mrad, m.tracking_max_mrad) {
                (Some(r), Some(x)) => format!("{r:8.3} {x:8.3}"),
                _ => "       -        -".into(),
            };
            writeln!(
                f,
                "  {:5} {:18} {:5} {:4} {:4}  {:7.1} {:7.1}       {}",
                m.mod_id,
                m.name,
                m.chain,
                m.hops,
                m.node.map_or("-".into(), |n| n.to_string()),
                m.read_us.p50,
                m.read_us.max,
                track
            )?;
        }
        writeln!(
            f,
            "force/torque (mean [min, max]): Fx, Fy, Fz in N; Tx, Ty, Tz in Nm"
        )?;
        for s in &self.force_torque {
            write!(f, "  {:11}", s.name)?;
            for a in 0..6 {
                write!(f, " {:7.2} [{:7.2},{:7.2}]", s.mean[a], s.min[a], s.max[a])?;
                if a == 2 {
                    write!(f, "\n  {:11}", "")?;
                }
            }
            writeln!(f)?;
        }
        writeln!(
            f,
            "weight on the feet: {:.1} N (body weight {:.1} N)",
            self.weight_on_feet_n, self.body_weight_n
        )?;
        if let Some(p) = &self.fastest {
            writeln!(
                f,
                "fastest period that holds: {:.0} us ({} periods, {} overruns, work p50/p99/max {})",
                p.period_us, p.periods, p.overruns, p.busy
            )?;
        }
        writeln!(
            f,
            "errors: {} ({} missed, {} overruns); bus resets recovered: {}; stopped cleanly: {}",
            self.errors.total,
            self.errors.missed,
            self.errors.overruns,
            self.errors.resets_recovered,
            self.stopped_cleanly
        )?;
        if let Some(fault) = &self.errors.fault {
            writeln!(f, "fault: {fault}")?;
        }
        Ok(())
    }
}
