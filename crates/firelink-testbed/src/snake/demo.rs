//! The Snake demo: seed 001's 36-axis system (two 11-axis Snake robots
//! and two 7-axis masters on six 7-channel nodes) servoed by the runner's
//! [`Robot`] over the abstract robot I/O: configure, prepare the nodes
//! (wiper, torque mode, current limit, encoder preload), power on, home,
//! follow trajectories on every arm, optionally inject a fault half way,
//! power off; then, on the simulated bus, find the highest rate that
//! holds. The report is the dVRK demo's ([`DemoReport`]) plus the rate
//! search.

use std::fmt;
use std::time::Instant;

use serde::Serialize;

use firelink_bus::{Detail, DetailReport};
use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::{Pacing, Robot};
use firelink_host::snake::SnakeSystem;
use firelink_host::udp::WaitMode;
use firelink_host::{Port, WatchdogSetting};

use crate::TestbedError;
use crate::demo::{
    DemoFault, DemoIo, DemoPlan, DemoProgress, DemoReport, PortSpec, RealtimeStatus, TimeStats,
    check_run, realtime_status, run_program,
};
use crate::fault_script::{FaultScript, FaultTarget};
use crate::rig;
use crate::snake::{emulator, node_configs, prepare, sim_port_with_faults};

/// Options of a Snake demo run.
#[derive(Debug, Clone)]
pub struct SnakeDemoOptions {
    /// The robot (default: `configs/snake-seed001.json`).
    pub config: IoConfig,
    /// The servo period (the seed's target: 1 kHz).
    pub period: ServoPeriod,
    /// Seconds of motion after homing.
    pub duration_s: f64,
    /// Where the nodes are (plain `sim`: the nodes come from the
    /// configuration).
    pub port: PortSpec,
    /// The fault to inject half way (a corrupt query needs the broadcast
    /// protocol, which the Snake nodes do not have: refused).
    pub fault: DemoFault,
    /// A fault script instead of the preset (`fault` must then be
    /// [`DemoFault::None`]).
    pub faults: Option<FaultScript>,
    /// Pacing; `None`: the port's default.
    pub pacing: Option<Pacing>,
    /// Node watchdog.
    pub watchdog: WatchdogSetting,
    /// After the run, search for the highest rate that holds (simulated
    /// bus only).
    pub find_max_rate: bool,
    /// Seed of the plants' noise.
    pub seed: u64,
    /// How the UDP port's reads wait for their answer (emulate, udp).
    pub udp_wait: WaitMode,
    /// The read time-out of a UDP or FireWire port (emulate, udp, fw): a
    /// servo cycle whose answer takes longer counts the board as missed (a
    /// fault); the scan waits that long for each absent node.
    pub timeout: std::time::Duration,
    /// The simulated bus's level of detail (sim; the same answer either
    /// way).
    pub detail: Detail,
}

impl Default for SnakeDemoOptions {
    fn default() -> Self {
        SnakeDemoOptions {
            config: presets::snake_seed001(),
            period: ServoPeriod::KHZ_1,
            duration_s: 3.0,
            port: PortSpec::SIM,
            fault: DemoFault::None,
            faults: None,
            pacing: None,
            watchdog: WatchdogSetting::default(),
            find_max_rate: true,
            seed: 1,
            udp_wait: WaitMode::Blocking,
            timeout: rig::UDP_TIMEOUT,
            detail: Detail::Fast,
        }
    }
}

/// One trial of the rate search.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RateTrial {
    /// The rate tried, Hz.
    pub rate_hz: f64,
    /// Whether it held: no fault, no I/O error, and the 99th percentile of
    /// I/O plus computation within the period.
    pub held: bool,
    /// I/O + computation per cycle with motion, us.
    pub cycle_time_us: TimeStats,
    /// Cycles whose I/O + computation exceeded the period.
    pub late_cycles: u64,
    /// I/O errors.
    pub errors: u64,
    /// The fault, if one happened.
    pub fault: Option<String>,
}

/// The highest rate that holds, and how it was found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MaxRate {
    /// The highest rate tried that held, Hz (0 if none did).
    pub rate_hz: f64,
    /// The bound from the I/O time alone: 1 / (largest I/O time), Hz.
    pub io_bound_hz: f64,
    /// The trials, in order (the first from the main run's 99th
    /// percentiles, rounded down to 50 Hz; each failure 10 % lower).
    pub trials: Vec<RateTrial>,
}

/// What a Snake demo run did; serialises to `firelink demo --robot snake
/// --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SnakeDemoReport {
    /// The run, reported as the dVRK demo reports it.
    #[serde(flatten)]
    pub demo: DemoReport,
    /// Board IDs of the nodes found.
    pub nodes: Vec<u8>,
    /// Cycles with motion whose I/O plus computation exceeded the period.
    pub late_cycles: u64,
    /// The rate search (simulated bus, when asked).
    pub max_rate: Option<MaxRate>,
}

impl SnakeDemoReport {
    /// Whether the run did what it was asked (as
    /// [`DemoReport::verdict`]; and a rate search found a rate that holds
    /// at least at the demo's own rate).
    ///
    /// # Errors
    /// What went wrong, in one line.
    pub fn verdict(&self) -> Result<(), String> {
        self.demo.verdict()?;
        if let Some(m) = &self.max_rate {
            if m.rate_hz < self.demo.rate_hz && self.demo.fault.is_none() {
                return Err(format!(
                    "no rate at or above {} Hz held in the rate search",
                    self.demo.rate_hz
                ));
            }
        }
        Ok(())
    }
}

impl fmt::Display for SnakeDemoReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.demo)?;
        writeln!(f, "  Snake nodes (board IDs): {:?}", self.nodes)?;
        writeln!(
            f,
            "  cycles whose I/O + computation exceeded the period: {}",
            self.late_cycles
        )?;
        if let Some(m) = &self.max_rate {
            writeln!(
                f,
                "  highest rate that holds: {:.0} Hz (I/O alone allows {:.0} Hz)",
                m.rate_hz, m.io_bound_hz
            )?;
            for t in &m.trials {
                writeln!(
                    f,
                    "    {:6.0} Hz: {}  cycle p99 {:7.1} us  max {:7.1} us  late {}  errors {}{}",
                    t.rate_hz,
                    if t.held { "held  " } else { "failed" },
                    t.cycle_time_us.p99,
                    t.cycle_time_us.max,
                    t.late_cycles,
                    t.errors,
                    t.fault
                        .as_ref()
                        .map_or(String::new(), |s| format!("  fault: {s}"))
                )?;
            }
        }
        Ok(())
    }
}

/// Run the Snake demo. `realtime` is called once the port is open, when
/// the pacing is wall-clock.
///
/// # Errors
/// Options the Snake nodes cannot honour; assembling the rig; the servo
/// failing outside a cycle (configuration, homing, time-outs).
pub fn run_snake_demo(
    options: &SnakeDemoOptions,
    realtime: Option<&dyn Fn() -> RealtimeStatus>,
    mut progress: impl FnMut(DemoProgress),
) -> Result<SnakeDemoReport, TestbedError> {
    check_run(options.duration_s)?;
    if options.fault == DemoFault::CorruptQuery {
        return Err(TestbedError::Config(
            "fault corrupt-query needs the broadcast protocol; Snake nodes are read and \
             written one by one (stop-host, board-loss or following-error)"
                .into(),
        ));
    }
    if options.fault != DemoFault::None && options.faults.is_some() {
        return Err(TestbedError::Config(format!(
            "fault {} and a fault script: give one of the two",
            options.fault
        )));
    }
    options.port.refuse_board_count(
        "the Snake demo",
        "Snake nodes come from the configuration and have no QLA firmware",
    )?;
    let nodes = node_configs(&options.config, options.seed)?;
    // Any other link: only what the host's side can do. Link filters draw
    // from the run's seed.
    let link = FaultTarget::link().with_seed(options.seed);
    let out = match &options.port {
        PortSpec::Sim(_) => {
            let (mut port, target) = sim_port_with_faults(nodes, true, None)?;
            port.bus_mut().set_detail(options.detail);
            run_on(
                port,
                &target.with_seed(options.seed),
                options,
                SIM_NAME.into(),
                realtime,
                &mut progress,
            )?
        }
        PortSpec::Emulate => {
            let emu = emulator(nodes)?;
            let name = format!("udp:{} (in-process firelink emulate)", emu.addr);
            let mut port = emu.port_with(options.udp_wait)?;
            port.set_timeout(options.timeout);
            let target = emu.fault_target().with_seed(options.seed);
            let r = run_on(port, &target, options, name, realtime, &mut progress);
            emu.stop()?;
            r?
        }
        PortSpec::Udp(addr) | PortSpec::UdpFw(addr) => {
            let force_bridge = matches!(options.port, PortSpec::UdpFw(_));
            let port = firelink_host::eth::UdpNetPort::open(
                *addr,
                force_bridge,
                options.timeout,
                options.udp_wait,
            )?;
            let name = port.name().to_string();
            run_on(port, &link, options, name, realtime, &mut progress)?
        }
        PortSpec::Fw(card) => {
            let port = crate::ports::fw_port(
                *card,
                &crate::ports::PortOptions {
                    timeout: options.timeout,
                    ..crate::ports::PortOptions::default()
                },
            )?;
            let name = options.port.to_string();
            run_on(port, &link, options, name, realtime, &mut progress)?
        }
    };
    let max_rate = (options.find_max_rate && options.port.is_sim() && out.report.fault.is_none())
        .then(|| search_max_rate(options, &out))
        .transpose()?;
    Ok(SnakeDemoReport {
        demo: out.report,
        nodes: out.ids,
        late_cycles: out.late_cycles,
        max_rate,
    })
}

impl<P: Port + 'static> DemoIo for SnakeSystem<P> {
    type Port = P;
    fn port_mut(&mut self) -> &mut P {
        SnakeSystem::port_mut(self)
    }
    fn board_nodes(&self) -> Vec<(u8, u8)> {
        self.nodes()
            .iter()
            .map(|n| (n.info().board_id, n.info().node))
            .collect()
    }
    fn firmware(&self) -> Option<u32> {
        // The version register's low byte is the firmware revision.
        self.nodes().first().map(|n| n.info().version & 0xFF)
    }
    fn protocol(&self) -> String {
        "snake per-node block read/write".into()
    }
    fn detail_report(&self) -> Option<DetailReport> {
        crate::dvrk::demo::sim_detail_report(SnakeSystem::port(self))
    }
}

/// What one run gives: the report, the board IDs found, and the cycles
/// with motion: their I/O plus computation, how many exceeded the period,
/// their largest I/O time.
struct RunOutcome {
    report: DemoReport,
    ids: Vec<u8>,
    motion_cycle_us: TimeStats,
    late_cycles: u64,
    motion_io_max_us: f64,
}

/// Run the demo over one port (paced as `options` say, else as the
/// port's default), its faults applied by `target`.
fn run_on<P: Port + 'static>(
    port: P,
    target: &FaultTarget,
    options: &SnakeDemoOptions,
    port_name: String,
    realtime: Option<&dyn Fn() -> RealtimeStatus>,
    progress: &mut dyn FnMut(DemoProgress),
) -> Result<RunOutcome, TestbedError> {
    let pacing = options
        .pacing
        .unwrap_or_else(|| options.port.default_pacing());
    let rt = realtime_status(pacing, realtime);
    let wall = Instant::now();
    let plan = DemoPlan {
        config: &options.config,
        period: options.period,
        duration_s: options.duration_s,
        fault: options.fault,
        script: options.faults.as_ref(),
        watchdog: options.watchdog,
        pacing,
    };
    // The faults are checked before the nodes are touched (and again with
    // the nodes found).
    plan.check_faults(target, &port, None)?;
    let mut system = SnakeSystem::open(port)?;
    let ids: Vec<u8> = system.nodes().iter().map(|n| n.board_id()).collect();
    progress(DemoProgress::Found {
        boards: ids.len(),
        port: port_name.clone(),
        reason: "Snake nodes found by their version register".into(),
        protocol: "per-node block read and block write",
    });
    prepare(&mut system, &options.config)?;
    let robot = Robot::new(system, &options.config, plan.settings())?;
    let run = run_program(robot, &plan, target, port_name, rt, wall, progress)?;
    let period_us = options.period.as_micros_f64();
    let times = &run.times;
    let setup = (run.setup_cycles as usize).min(times.cycle_us.len());
    let end = (setup + run.report.motion_cycles as usize).min(times.cycle_us.len());
    let mut motion: Vec<f32> = times.cycle_us[setup..end].to_vec();
    let late_cycles = motion.iter().filter(|&&c| f64::from(c) > period_us).count() as u64;
    let motion_io_max_us = times.io_us[setup..end]
        .iter()
        .fold(0.0f64, |m, &x| m.max(f64::from(x)));
    Ok(RunOutcome {
        report: run.report,
        ids,
        motion_cycle_us: TimeStats::of(&mut motion),
        late_cycles,
        motion_io_max_us,
    })
}

/// The simulated port's name in reports: the nodes on the simulated bus,
/// the PC's overhead that of seed 001's machine.
const SIM_NAME: &str = "sim (seed 001 PC model)";

/// Motion after homing in a rate trial, seconds.
const TRIAL_SECONDS: f64 = 0.5;
/// Trials at most.
const MAX_TRIALS: usize = 5;

/// One short run at `rate_hz` on a fresh simulated rig.
fn trial(options: &SnakeDemoOptions, rate_hz: f64) -> Result<RateTrial, TestbedError> {
    let run = SnakeDemoOptions {
        period: crate::demo::servo_period(rate_hz)?,
        duration_s: TRIAL_SECONDS,
        port: PortSpec::SIM,
        fault: DemoFault::None,
        faults: None,
        pacing: Some(Pacing::Virtual),
        find_max_rate: false,
        ..options.clone()
    };
    let (mut port, target) =
        sim_port_with_faults(node_configs(&run.config, run.seed)?, true, None)?;
    port.bus_mut().set_detail(run.detail);
    let out = match run_on(port, &target, &run, SIM_NAME.into(), None, &mut |_| {}) {
        Ok(out) => out,
        // A rate at which the robot cannot even home (the gains leave a
        // joint under-damped at a low rate) did not hold: say why and let
        // the search go on. Any other error (the rig, the scan) is one.
        Err(e) if matches!(e.cause(), TestbedError::Runner(_)) => {
            return Ok(RateTrial {
                rate_hz,
                held: false,
                cycle_time_us: TimeStats::default(),
                late_cycles: 0,
                errors: 0,
                fault: Some(e.to_string()),
            });
        }
        Err(e) => return Err(e),
    };
    let report = out.report;
    let late = out.motion_cycle_us.p99 > 1e6 / rate_hz;
    let held = report.fault.is_none() && report.errors.total == 0 && !late;
    Ok(RateTrial {
        rate_hz,
        held,
        cycle_time_us: out.motion_cycle_us,
        late_cycles: out.late_cycles,
        errors: report.errors.total,
        fault: report.fault.map(|f| f.text),
    })
}

/// From the main run's cycles with motion (99th percentile of I/O plus
/// computation), the rate that should hold (rounded down to 50 Hz),
/// confirmed by a trial; each failure tries 10 % lower.
fn search_max_rate(options: &SnakeDemoOptions, main: &RunOutcome) -> Result<MaxRate, TestbedError> {
    let cycle_us = main.motion_cycle_us.p99;
    let io_bound_hz = if main.motion_io_max_us > 0.0 {
        1e6 / main.motion_io_max_us
    } else {
        0.0
    };
    // At least one trial, at 50 Hz at the lowest (a stalled machine can
    // make the main run's 99th percentile longer than 20 ms).
    let mut rate = ((1e6 / cycle_us.max(1.0) / 50.0).floor() * 50.0).max(50.0);
    let mut trials = Vec::new();
    let mut best = 0.0;
    while trials.len() < MAX_TRIALS && rate >= 50.0 {
        let t = trial(options, rate)?;
        let held = t.held;
        trials.push(t);
        if held {
            best = rate;
            break;
        }
        rate = (rate * 0.9 / 50.0).floor() * 50.0;
    }
    Ok(MaxRate {
        rate_hz: best,
        io_bound_hz,
        trials,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At 100 Hz the default configuration's gains cannot hold the masters
    /// still enough to home (virtual time: the same on every machine); the
    /// trial says so instead of ending the search with an error.
    #[test]
    fn a_rate_that_cannot_home_is_a_trial_that_did_not_hold() {
        let t = trial(&SnakeDemoOptions::default(), 100.0).unwrap();
        assert!(!t.held);
        assert_eq!(t.rate_hz, 100.0);
        let fault = t.fault.unwrap_or_default();
        assert!(fault.contains("the potentiometer moved"), "{fault}");
        // The trial powered the nodes down before it gave up.
        assert!(fault.contains("then powered down"), "{fault}");
    }
}
