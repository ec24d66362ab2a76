//! The MAHRU view: seed 002's humanoid (ten motor controllers and four
//! force/torque sensors on the computer's three chains) on the simulated
//! bus behind its real-time system's port, run by the MainController's
//! period as `firelink demo --robot mahru` runs it: read every module,
//! slack, compute the gait's set-points, slack, QWRITE, wait.
//!
//! What the page shows: each module's position, target, velocity, current
//! and torque (motors) or wrench (sensors) and state; the gait (walking
//! or holding, its time and its phase in the stride); the time budget of
//! the last period (read, compute, write, the whole work) against the
//! period, the largest work seen and the overruns. What it drives:
//! enable (bring-up: map, check, parameters, READY, START), disable (STOP
//! to every module) and the gait's start and stop. A stopped gait holds
//! the pose it had (its clock stops); started again, it goes on from
//! there.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use firelink_board::mahru::ModuleNode;
use firelink_control::ServoPeriod;
use firelink_host::Port;
use firelink_host::PowerDown;
use firelink_host::mahru::{ControllerState, MotionController, MotionError, Setpoints};
use firelink_host::sim::SimPort;
use firelink_testbed::loop_outcome::LoopExit;
use firelink_testbed::mahru::MahruConfig;
use firelink_testbed::mahru::gait::Gait;
use firelink_testbed::mahru::main_loop::{gait_setpoints, motor_models};
use firelink_testbed::mahru::rig::{PlacedModule, robot_port};
use firelink_wire::mahru::{ModId, ModuleKind, ModuleState};

use super::{Exchange, Hosted, PUBLISH_SECONDS, Pending, Refused, RobotKind, RobotModel};
use super::{failed, pace, parse_json, refused};
use crate::WebError;

/// One module as the page shows it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ModuleSample {
    /// Module ID.
    pub mod_id: u8,
    /// Read in the last period.
    pub valid: bool,
    /// Its state, as it reported it.
    pub state: &'static str,
    /// Joint position, rad (motors).
    pub position: f64,
    /// The position its servo tracks, rad.
    pub target: f64,
    /// Velocity, rad/s.
    pub velocity: f64,
    /// Motor current, A.
    pub current: f64,
    /// Torque commanded, Nm.
    pub torque: f64,
    /// Fx, Fy, Fz (N), Tx, Ty, Tz (Nm) (sensors).
    pub wrench: [f64; 6],
    /// How long its read took, us.
    pub read_us: f64,
}

/// The time budget of the last period, us.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Budget {
    /// The period.
    pub period_us: f64,
    /// Reading every module, `t(Te)`.
    pub read_us: f64,
    /// Computation as charged, `t(Tf)`.
    pub compute_us: f64,
    /// QWRITE, `t(Tg)`.
    pub write_us: f64,
    /// The period's whole work (with both slacks).
    pub busy_us: f64,
    /// The largest work seen since the last enable.
    pub busy_max_us: f64,
    /// Periods whose work did not fit.
    pub overruns: u64,
    /// Periods run since the last enable.
    pub periods: u64,
}

/// What the loop hands over.
#[derive(Debug, Clone)]
pub struct MahruFrame {
    t: f64,
    state: ControllerState,
    fault: Option<MotionError>,
    walking: bool,
    gait_time: f64,
    modules: Vec<ModuleSample>,
    budget: Budget,
    missed: u64,
    resets_recovered: u64,
}

/// What the page can ask of MAHRU.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum MahruCommand {
    /// Bring the robot up (map, check, parameters, READY, START).
    Enable,
    /// STOP every module (amplifiers off).
    Disable,
    /// Start (or resume) walking.
    GaitStart,
    /// Stop walking: hold the pose.
    GaitStop,
}

/// MAHRU's model for the server.
pub struct MahruModel {
    modules: Vec<Value>,
    stride_s: f64,
    rtos: &'static str,
}

fn state_name(s: ControllerState) -> &'static str {
    match s {
        ControllerState::Unmapped => "disabled",
        ControllerState::Running => "enabled",
        ControllerState::Stopped => "stopped",
    }
}

fn module_state(s: ModuleState) -> &'static str {
    match s {
        ModuleState::Idle => "idle",
        ModuleState::Parameterized => "parameterized",
        ModuleState::Ready => "ready",
        ModuleState::Running => "running",
        ModuleState::Stopped => "stopped",
        _ => "unknown",
    }
}

impl RobotModel for MahruModel {
    type Frame = MahruFrame;
    type Command = MahruCommand;

    fn info(&self) -> Value {
        json!({
            "modules": self.modules,
            "stride_s": self.stride_s,
            "rtos": self.rtos,
        })
    }

    fn render(&self, f: &MahruFrame) -> Value {
        let phase = if self.stride_s > 0.0 {
            (f.gait_time / self.stride_s).fract()
        } else {
            0.0
        };
        json!({
            "t": f.t,
            "state": state_name(f.state),
            "fault": f.fault.map(|e| json!({"text": e.to_string()})),
            "gait": {"walking": f.walking, "time_s": f.gait_time, "phase": phase},
            "modules": f.modules,
            "budget": f.budget,
            "missed": f.missed,
            "resets_recovered": f.resets_recovered,
        })
    }

    fn parse(&self, body: &[u8]) -> Result<MahruCommand, String> {
        parse_json(body)
    }

    fn describe(c: &MahruCommand) -> String {
        match c {
            MahruCommand::Enable => "enable",
            MahruCommand::Disable => "disable",
            MahruCommand::GaitStart => "gait start",
            MahruCommand::GaitStop => "gait stop",
        }
        .into()
    }
}

/// The loop's own state besides the controller.
struct Rig {
    controller: MotionController<SimPort>,
    placed: Vec<PlacedModule>,
    gait: Gait,
    /// (ModID, gravity torque, inertia) of every motor.
    motors: Vec<(ModId, f64, f64)>,
    setpoints: Setpoints,
    period: Duration,
    compute: Duration,
    slack: Duration,
    walking: bool,
    gait_time: f64,
    budget: Budget,
}

fn micros(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

/// Start MAHRU of `config` on its simulated bus with a control period of
/// `period` (within the configuration's bounds); the robot waits,
/// disabled, for "enable".
///
/// # Errors
/// A configuration that does not validate, a period out of range, the
/// bus.
pub fn start(config: MahruConfig, period: ServoPeriod) -> Result<Hosted<MahruModel>, WebError> {
    config.validate()?;
    let period_us = period.as_micros_f64();
    let period = firelink_testbed::mahru::demo::check_period(period.as_duration())?;
    let phase = |us: f64| Duration::from_secs_f64(us.clamp(0.0, 1e6) / 1e6);
    let (port, placed, _) = robot_port(&config)?;
    let layout = config.layout()?;
    let controller = MotionController::new(port, layout)
        .map_err(|e| WebError::Options(format!("MAHRU: {e}")))?;
    let modules = controller
        .layout()
        .modules
        .iter()
        .map(|m| {
            let chain = placed.iter().find(|p| p.mod_id == m.mod_id);
            json!({
                "mod_id": m.mod_id.0,
                "name": m.name,
                "kind": if m.kind == ModuleKind::ForceTorque { "force_torque" } else { "motor" },
                "chain": chain.map(|p| p.chain),
                "hops": chain.map(|p| p.hops),
            })
        })
        .collect();
    let motors = motor_models(&config);
    let count = controller.layout().modules.len();
    let exchange = Arc::new(Exchange::new(|| MahruFrame {
        t: 0.0,
        state: ControllerState::Unmapped,
        fault: None,
        walking: false,
        gait_time: 0.0,
        modules: vec![ModuleSample::default(); count],
        budget: Budget::default(),
        missed: 0,
        resets_recovered: 0,
    }));
    let rig = Rig {
        controller,
        placed,
        gait: Gait::new(&config),
        motors,
        setpoints: Setpoints::default(),
        period,
        compute: phase(config.compute_us),
        slack: phase(config.slack_us),
        walking: false,
        gait_time: 0.0,
        budget: Budget {
            period_us,
            ..Budget::default()
        },
    };
    let model = MahruModel {
        modules,
        stride_s: config.gait.stride_s,
        rtos: config.rtos()?.name(),
    };
    let loop_exchange = Arc::clone(&exchange);
    let thread = std::thread::Builder::new()
        .name("firelink-mahru".into())
        .spawn(move || run(rig, &loop_exchange))?;
    Ok(Hosted::new(
        RobotKind::Mahru,
        "sim (MAHRU's modules on the simulated bus)".into(),
        model,
        exchange,
        thread,
    ))
}

/// The loop: commands between periods, a frame every [`PUBLISH_SECONDS`];
/// on the way out every module is told to STOP and checked.
fn run(mut rig: Rig, ex: &Exchange<MahruFrame, MahruCommand>) -> LoopExit {
    let every = ((PUBLISH_SECONDS / rig.period.as_secs_f64()).round() as u64).max(1);
    let stop = firelink_host::stop::StopRequest::process();
    let looped = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let wall = Instant::now();
        let start = rig.controller.port().now();
        let mut n = 0u64;
        while !ex.stop.load(Ordering::Relaxed) && !stop.is_requested() {
            ex.take_requests(|p| take(&mut rig, ex, p));
            if rig.controller.state() == ControllerState::Running {
                let _ = period_once(&mut rig);
            } else {
                rig.controller.port_mut().wait(rig.period);
            }
            n += 1;
            if n % every == 0 {
                ex.publish(|f| fill(f, &rig));
            }
            let t = rig.controller.port().now().saturating_sub(start);
            pace(t.as_secs_f64(), wall, rig.period * 4);
        }
    }));
    let panic = looped
        .err()
        .map(|p| super::panic_text(p.as_ref()).to_string());
    let power_down = Some(stop_all(&mut rig));
    ex.publish(|f| fill(f, &rig));
    let exit = LoopExit {
        power_down,
        panic,
        stopped_by: stop.reason(),
    };
    ex.finish(exit.clone(), MahruModel::describe);
    exit
}

/// STOP every module, then look at each: stopped with its amplifier off
/// (bit = ModID) or still on.
fn stop_all(rig: &mut Rig) -> PowerDown {
    let _ = rig.controller.stop();
    rig.walking = false;
    rig.controller.port_mut().wait(Duration::from_millis(1));
    let bus = rig.controller.port().bus();
    let mut p = PowerDown::default();
    for m in &rig.placed {
        let bit = 1u16 << (m.mod_id.0 & 0xF);
        match bus.node::<ModuleNode>(m.handle) {
            Some(n)
                if n.state() == ModuleState::Stopped
                    && n.motor().is_none_or(|j| !j.amplifier_on()) =>
            {
                p.off |= bit;
            }
            Some(_) => p.still_on |= bit,
            None => p.unknown |= bit,
        }
    }
    p
}

fn take(rig: &mut Rig, ex: &Exchange<MahruFrame, MahruCommand>, p: Pending<MahruCommand>) {
    let what = MahruModel::describe(&p.command);
    let result = execute(rig, p.command);
    // The state that shows it first, then the outcome.
    ex.publish(|f| fill(f, rig));
    ex.answer(p, what, result);
}

fn execute(rig: &mut Rig, command: MahruCommand) -> Result<String, Refused> {
    match command {
        MahruCommand::Enable => {
            if rig.controller.state() == ControllerState::Running {
                return Ok("already enabled".into());
            }
            rig.controller
                .bring_up()
                .map_err(|e| failed(format!("bring-up: {e}")))?;
            rig.budget = Budget {
                period_us: rig.budget.period_us,
                ..Budget::default()
            };
            Ok(format!(
                "{} modules brought up: READY, START",
                rig.placed.len()
            ))
        }
        MahruCommand::Disable => {
            rig.walking = false;
            let p = stop_all(rig);
            if p.all_off() {
                Ok("STOP: every module stopped, amplifiers off".into())
            } else {
                Err(failed(format!("STOP sent; modules {p}")))
            }
        }
        MahruCommand::GaitStart => {
            if rig.controller.state() != ControllerState::Running {
                return Err(refused(format!(
                    "the gait needs an enabled robot: it is {} (enable first)",
                    state_name(rig.controller.state())
                )));
            }
            rig.walking = true;
            Ok(format!("walking from {:.2} s of the gait", rig.gait_time))
        }
        MahruCommand::GaitStop => {
            rig.walking = false;
            Ok(format!(
                "holding the pose at {:.2} s of the gait",
                rig.gait_time
            ))
        }
    }
}

/// One MainController period (see the module docs).
fn period_once(rig: &mut Rig) -> Result<(), MotionError> {
    let c = &mut rig.controller;
    let start = c.port().now();
    c.read_all()?;
    let read_end = c.port().now();
    c.port_mut().wait(rig.slack);
    let compute_start = c.port().now();
    gait_setpoints(
        &rig.gait,
        &rig.motors,
        rig.gait_time,
        rig.walking,
        &mut rig.setpoints,
    );
    c.port_mut().wait(rig.compute);
    let compute_end = c.port().now();
    c.port_mut().wait(rig.slack);
    let write_start = c.port().now();
    c.write_setpoints(&rig.setpoints)?;
    let end = c.port().now();
    let busy = end.saturating_sub(start);
    let b = &mut rig.budget;
    b.periods += 1;
    b.read_us = micros(read_end.saturating_sub(start));
    b.compute_us = micros(compute_end.saturating_sub(compute_start));
    b.write_us = micros(end.saturating_sub(write_start));
    b.busy_us = micros(busy);
    b.busy_max_us = b.busy_max_us.max(b.busy_us);
    if busy > rig.period {
        b.overruns += 1;
    } else {
        c.port_mut().wait(rig.period - busy);
    }
    if rig.walking {
        rig.gait_time += rig.period.max(busy).as_secs_f64();
    }
    Ok(())
}

/// Fill a frame from the controller; no allocation.
fn fill(f: &mut MahruFrame, rig: &Rig) {
    let c = &rig.controller;
    f.t = c.port().now().as_secs_f64();
    f.state = c.state();
    f.fault = c.fault();
    f.walking = rig.walking;
    f.gait_time = rig.gait_time;
    f.budget = rig.budget;
    let stats = c.stats();
    f.missed = stats.missed;
    f.resets_recovered = stats.resets_recovered;
    let fb = c.feedback();
    let running = c.state() == ControllerState::Running;
    for (i, (s, spec)) in f.modules.iter_mut().zip(&c.layout().modules).enumerate() {
        let mut m = ModuleSample {
            mod_id: spec.mod_id.0,
            valid: running,
            read_us: fb.read_times.get(i).map_or(0.0, |d| micros(*d)),
            ..ModuleSample::default()
        };
        if let Some(Some(j)) = fb.joints.get(i) {
            m.state = module_state(j.state);
            m.position = f64::from(j.position_urad) * 1e-6;
            m.target = f64::from(j.target_urad) * 1e-6;
            m.velocity = f64::from(j.velocity_urad_s) * 1e-6;
            m.current = f64::from(j.current_ma) * 1e-3;
            m.torque = f64::from(j.torque_mnm) * 1e-3;
        } else if let Some(Some(w)) = fb.wrenches.get(i) {
            m.state = if running { "running" } else { "-" };
            m.wrench = w.wrench();
        } else {
            m.state = "-";
        }
        *s = m;
    }
}
