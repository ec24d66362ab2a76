//! The MAHRU robot's configuration: its modules on the chains of the
//! computer's 3-port card, their parameters and physics, the computer, the
//! period and the walking gait. `configs/mahru-seed002.json` is
//! [`MahruConfig::seed002`] written out.

use std::path::Path;

use serde::{Deserialize, Serialize};

use firelink_board::mahru::{
    BodyParams, DeviceConfig, FtLoad, FtParams, JointParams, ModuleConfig, ResponderTiming,
};
use firelink_bus::SimDuration;
use firelink_host::mahru::rtos::Rtos;
use firelink_host::mahru::{ModuleSpec, RobotLayout};
use firelink_wire::mahru::{ModId, ModuleKind, ParameterRecord, QWRITE_SLOTS};
use firelink_wire::packet::Speed;

use firelink_control::config::{ConfigError, ConfigErrors, Problem};
use firelink_wire::human::Number;

use crate::TestbedError;

/// The whole robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MahruConfig {
    /// A name for reports.
    pub name: String,
    /// Control period, us (the seed: 2000).
    pub period_us: f64,
    /// The computer's real-time system: `xenomai` or `rtlinux`.
    pub rtos: String,
    /// The SBC's computation per cycle, `t(Tf)`, us (the seed: at most
    /// 500). Charged in virtual time; the control code itself also runs.
    pub compute_us: f64,
    /// Slack between two events of the program, `t(Ts)`, us (the seed: 20).
    pub slack_us: f64,
    /// Speed of the host's broadcasts, Mb/s (100, 200 or 400).
    pub broadcast_mbps: u32,
    /// Seed of every random draw (computer jitter, sensor noise).
    pub seed: u64,
    /// The modules' DSP timing.
    pub responder: ResponderJson,
    /// The body the force/torque load model uses.
    pub body: BodyJson,
    /// The walking gait.
    pub gait: GaitJson,
    /// The chains, one per port of the computer's card (at most 3), each
    /// listed from the card outwards.
    pub chains: Vec<ChainJson>,
}

/// The DSP's answer time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResponderJson {
    /// Polling period of the FPGA, us.
    pub poll_us: f64,
    /// Fixed work per answer, us.
    pub fixed_us: f64,
    /// Work per byte of the answer, us.
    pub per_byte_us: f64,
}

/// The body.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyJson {
    /// Whole robot, kg.
    pub mass_kg: f64,
    /// Hip to ankle, m.
    pub leg_length_m: f64,
    /// Hand beyond the wrist sensor, kg.
    pub hand_mass_kg: f64,
    /// Elbow to hand centre of mass, m.
    pub forearm_length_m: f64,
    /// Wrist sensor to hand centre of mass, m.
    pub hand_offset_m: f64,
}

/// The walking gait (see [`super::gait`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaitJson {
    /// Stride period, s.
    pub stride_s: f64,
    /// Time to ramp the motion in from standing still, s.
    pub ramp_s: f64,
    /// Hip pitch swing amplitude, rad.
    pub hip_rad: f64,
    /// Knee bend of the swing leg, rad.
    pub knee_rad: f64,
    /// Shoulder swing amplitude, rad.
    pub shoulder_rad: f64,
    /// Elbow swing amplitude, rad.
    pub elbow_rad: f64,
    /// Hand motion amplitude, rad.
    pub hand_rad: f64,
}

/// One chain from a port of the card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainJson {
    /// A name ("legs").
    pub name: String,
    /// Its modules, from the card outwards.
    pub modules: Vec<ModuleJson>,
}

/// One module.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModuleJson {
    /// Module ID (motor controllers 0..9: their QWRITE slot).
    pub mod_id: u8,
    /// Name.
    pub name: String,
    /// What it is, with its settings.
    pub device: ModuleKindJson,
}

/// A module's kind and its settings: `{"motor": {...}}` or
/// `{"force_torque": {...}}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ModuleKindJson {
    /// A motor controller.
    Motor(MotorJson),
    /// A force/torque sensor.
    ForceTorque(FtJson),
}

/// A motor controller: what PARAMETER sends, and the joint's physics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorJson {
    /// Gear ratio.
    pub gear_ratio: f64,
    /// Proportional gain, Nm/rad.
    pub kp: f64,
    /// Integral gain, Nm/(rad s).
    pub ki: f64,
    /// Derivative gain, Nm s/rad.
    pub kd: f64,
    /// Position limits, rad.
    pub position_limits_rad: [f64; 2],
    /// Torque limit, Nm.
    pub torque_limit_nm: f64,
    /// Inertia at the joint, kg m^2.
    pub inertia: f64,
    /// Viscous friction, Nm s/rad.
    pub damping: f64,
    /// Largest gravity torque, Nm.
    pub gravity_torque_nm: f64,
    /// Motor torque constant, Nm/A.
    pub torque_constant: f64,
    /// Servo rate, Hz.
    pub servo_hz: f64,
    /// Watchdog, ms.
    pub watchdog_ms: f64,
    /// Angle at power-up (and the centre of the gait), rad.
    pub initial_position_rad: f64,
}

/// A force/torque sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FtJson {
    /// Where it sits.
    pub load: FtLoadJson,
    /// Zero error per axis: N, N, N, Nm, Nm, Nm.
    pub offset: [f64; 6],
    /// Noise standard deviation: force (N), torque (Nm).
    pub noise: [f64; 2],
}

/// Where a sensor sits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum FtLoadJson {
    /// Under a foot: the leg's hip and knee, the other knee, the side.
    Foot {
        /// Hip pitch ModID.
        hip: u8,
        /// Knee ModID.
        knee: u8,
        /// The other leg's knee ModID.
        other_knee: u8,
        /// Left foot.
        left: bool,
    },
    /// At a wrist: the arm's shoulder and elbow.
    Wrist {
        /// Shoulder ModID.
        shoulder: u8,
        /// Elbow ModID.
        elbow: u8,
    },
}

/// The bounds of a MAHRU configuration's numbers. Every number that
/// becomes a duration, a rate, a loop count or a parameter the modules
/// take is bounded above as well as below, so a file cannot make the
/// simulation hang (a servo tick of a picosecond, a period of days) or a
/// conversion panic.
pub mod bounds {
    /// Control period, us: 100 us to 1 s (the seed: 2000).
    pub const PERIOD_US: (f64, f64) = (100.0, 1e6);
    /// Computation and slack per period, us: at most 1 s.
    pub const PHASE_US: f64 = 1e6;
    /// The DSP's polling period and fixed work per answer, us.
    pub const RESPONDER_US: f64 = 1e4;
    /// The DSP's work per byte of an answer, us.
    pub const PER_BYTE_US: f64 = 100.0;
    /// A module's servo rate, Hz (the seed: 5000).
    pub const SERVO_HZ: (f64, f64) = (100.0, 20_000.0);
    /// A module's watchdog, ms (the seed: 10).
    pub const WATCHDOG_MS: (f64, f64) = (0.1, 10_000.0);
    /// The robot's mass, kg.
    pub const MASS_KG: f64 = 1e3;
    /// The hand's mass, kg.
    pub const HAND_MASS_KG: f64 = 100.0;
    /// Lengths of the body model, m.
    pub const LENGTH_M: f64 = 10.0;
    /// Gait times (stride, ramp), s.
    pub const GAIT_S: f64 = 60.0;
    /// Joint angles (limits, amplitudes, start), rad.
    pub const ANGLE_RAD: f64 = 100.0;
    /// Gear ratio.
    pub const GEAR_RATIO: f64 = 1e4;
    /// PID gains (as PARAMETER carries them, f32).
    pub const GAIN: f64 = 1e6;
    /// Torques (limit, gravity), N m.
    pub const TORQUE_NM: f64 = 1e5;
    /// Inertia at the joint, kg m².
    pub const INERTIA: f64 = 1e3;
    /// Viscous friction, N m s/rad.
    pub const DAMPING: f64 = 1e4;
    /// Motor torque constant, N m/A.
    pub const TORQUE_CONSTANT: f64 = 100.0;
    /// A force/torque sensor's zero error (N or N m) and noise.
    pub const SENSOR: f64 = 1e4;
}

/// `x` microseconds as simulated time (negative and NaN: zero; beyond
/// the bounds: saturated, never a panic).
fn us(x: f64) -> SimDuration {
    SimDuration::from_micros_f64(x.max(0.0))
}

/// `x` microseconds as a duration, 0 to `max_us` (NaN: zero): the
/// conversions of validated numbers, safe for unvalidated ones too.
pub(crate) fn duration_us(x: f64, max_us: f64) -> std::time::Duration {
    let x = if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, max_us)
    };
    std::time::Duration::from_secs_f64(x / 1e6)
}

fn bad(what: impl Into<String>) -> TestbedError {
    TestbedError::Config(what.into())
}

/// Collects a file's problems, each with its JSON path.
struct Checker {
    errors: Vec<(String, Problem)>,
}

impl Checker {
    fn push(&mut self, path: impl Into<String>, problem: Problem) {
        self.errors.push((path.into(), problem));
    }

    /// A finite `x` in `lo..=hi` (`lo < x` when `open_low`).
    fn range(
        &mut self,
        path: impl Into<String>,
        x: f64,
        lo: f64,
        hi: f64,
        open_low: bool,
        unit: &str,
    ) {
        if !x.is_finite() {
            self.push(path, Problem::NotFinite);
            return;
        }
        let low_ok = if open_low { x > lo } else { x >= lo };
        if !low_ok || x > hi {
            let low = if open_low { "above" } else { "from" };
            self.push(
                path,
                Problem::OutOfRange {
                    value: x,
                    expected: format!("{low} {} to {}{unit}", Number(lo), Number(hi)),
                },
            );
        }
    }

    /// Above 0, at most `hi`.
    fn positive(&mut self, path: impl Into<String>, x: f64, hi: f64, unit: &str) {
        self.range(path, x, 0.0, hi, true, unit);
    }

    /// 0 to `hi`.
    fn not_negative(&mut self, path: impl Into<String>, x: f64, hi: f64, unit: &str) {
        self.range(path, x, 0.0, hi, false, unit);
    }

    /// `-hi` to `hi`.
    fn magnitude(&mut self, path: impl Into<String>, x: f64, hi: f64, unit: &str) {
        self.range(path, x, -hi, hi, false, unit);
    }
}

impl MahruConfig {
    /// Read and check a configuration file.
    ///
    /// # Errors
    /// [`TestbedError::Config`] naming the file, the JSON path and the
    /// problem (every problem, one per line).
    pub fn load(path: impl AsRef<Path>) -> Result<MahruConfig, TestbedError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| bad(format!("{file}: {e}")))?;
        Self::from_json_str(&text, &file)
    }

    /// Parse and check JSON text; `file` names it in errors.
    ///
    /// # Errors
    /// As [`MahruConfig::load`].
    pub fn from_json_str(text: &str, file: &str) -> Result<MahruConfig, TestbedError> {
        let mut de = serde_json::Deserializer::from_str(text);
        let config: MahruConfig = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let path = e.path().to_string();
            bad(format!("{file}: {path}: {}", e.into_inner()))
        })?;
        de.end().map_err(|e| bad(format!("{file}: {e}")))?;
        config.check(file).map_err(|e| bad(e.to_string()))?;
        Ok(config)
    }

    /// Check the rules the types cannot: every number finite and within
    /// its [`bounds`], at most three chains, module IDs, parameters
    /// PARAMETER can carry, sensors naming joints that exist.
    ///
    /// # Errors
    /// [`TestbedError::Config`] naming every problem.
    pub fn validate(&self) -> Result<(), TestbedError> {
        self.check("the MAHRU configuration")
            .map_err(|e| bad(e.to_string()))
    }

    /// [`validate`](Self::validate), the errors naming `file` and each
    /// problem's JSON path.
    ///
    /// # Errors
    /// Every problem found, in file order.
    pub fn check(&self, file: &str) -> Result<(), ConfigErrors> {
        let mut c = Checker { errors: Vec::new() };
        self.check_numbers(&mut c);
        match self.rtos() {
            Ok(_) => {}
            Err(_) => c.push(
                "rtos",
                Problem::Mismatch(format!("{:?}: xenomai or rtlinux", self.rtos)),
            ),
        }
        if self.broadcast_speed().is_err() {
            c.push(
                "broadcast_mbps",
                Problem::OutOfRange {
                    value: f64::from(self.broadcast_mbps),
                    expected: "100, 200 or 400 (Mb/s)".into(),
                },
            );
        }
        if self.chains.is_empty() || self.chains.len() > 3 {
            c.push(
                "chains",
                Problem::Mismatch(format!(
                    "{} chains: the computer's card has 3 ports (1 to 3 chains)",
                    self.chains.len()
                )),
            );
        }
        for (ci, chain) in self.chains.iter().enumerate() {
            if chain.modules.is_empty() {
                c.push(format!("chains[{ci}].modules"), Problem::Empty);
            }
        }
        let all_ok = c.errors.is_empty();
        if all_ok {
            match self.layout().map(|l| l.validate()) {
                Ok(Ok(())) => {}
                Ok(Err(e)) => c.push("chains", Problem::Mismatch(e.to_string())),
                Err(e) => c.push("chains", Problem::Mismatch(e.to_string())),
            }
            self.check_loads(&mut c);
        }
        let errors = c
            .errors
            .into_iter()
            .map(|(path, problem)| ConfigError::new(file, path, problem))
            .collect();
        match ConfigErrors::from_vec(errors) {
            None => Ok(()),
            Some(e) => Err(e),
        }
    }

    /// Every number within its bounds.
    fn check_numbers(&self, c: &mut Checker) {
        let (lo, hi) = bounds::PERIOD_US;
        c.range("period_us", self.period_us, lo, hi, false, " us");
        c.not_negative("compute_us", self.compute_us, bounds::PHASE_US, " us");
        c.not_negative("slack_us", self.slack_us, bounds::PHASE_US, " us");
        let r = &self.responder;
        c.not_negative("responder.poll_us", r.poll_us, bounds::RESPONDER_US, " us");
        c.not_negative(
            "responder.fixed_us",
            r.fixed_us,
            bounds::RESPONDER_US,
            " us",
        );
        c.not_negative(
            "responder.per_byte_us",
            r.per_byte_us,
            bounds::PER_BYTE_US,
            " us",
        );
        let b = &self.body;
        c.positive("body.mass_kg", b.mass_kg, bounds::MASS_KG, " kg");
        c.positive(
            "body.hand_mass_kg",
            b.hand_mass_kg,
            bounds::HAND_MASS_KG,
            " kg",
        );
        for (path, x) in [
            ("body.leg_length_m", b.leg_length_m),
            ("body.forearm_length_m", b.forearm_length_m),
            ("body.hand_offset_m", b.hand_offset_m),
        ] {
            c.positive(path, x, bounds::LENGTH_M, " m");
        }
        let g = &self.gait;
        c.positive("gait.stride_s", g.stride_s, bounds::GAIT_S, " s");
        c.not_negative("gait.ramp_s", g.ramp_s, bounds::GAIT_S, " s");
        for (path, x) in [
            ("gait.hip_rad", g.hip_rad),
            ("gait.knee_rad", g.knee_rad),
            ("gait.shoulder_rad", g.shoulder_rad),
            ("gait.elbow_rad", g.elbow_rad),
            ("gait.hand_rad", g.hand_rad),
        ] {
            c.not_negative(path, x, bounds::ANGLE_RAD, " rad");
        }
        for (ci, chain) in self.chains.iter().enumerate() {
            for (mi, m) in chain.modules.iter().enumerate() {
                let at = format!("chains[{ci}].modules[{mi}].device");
                match &m.device {
                    ModuleKindJson::Motor(j) => check_motor(c, &format!("{at}.motor"), j),
                    ModuleKindJson::ForceTorque(f) => {
                        let fp = format!("{at}.force_torque");
                        for (i, x) in f.offset.iter().enumerate() {
                            c.magnitude(format!("{fp}.offset[{i}]"), *x, bounds::SENSOR, "");
                        }
                        for (i, x) in f.noise.iter().enumerate() {
                            c.not_negative(format!("{fp}.noise[{i}]"), *x, bounds::SENSOR, "");
                        }
                    }
                }
            }
        }
    }

    /// Each sensor's load model names motor controllers that exist.
    fn check_loads(&self, c: &mut Checker) {
        for (ci, chain) in self.chains.iter().enumerate() {
            for (mi, m) in chain.modules.iter().enumerate() {
                let ModuleKindJson::ForceTorque(f) = &m.device else {
                    continue;
                };
                let joints: Vec<(&str, u8)> = match f.load {
                    FtLoadJson::Foot {
                        hip,
                        knee,
                        other_knee,
                        ..
                    } => vec![
                        ("foot.hip", hip),
                        ("foot.knee", knee),
                        ("foot.other_knee", other_knee),
                    ],
                    FtLoadJson::Wrist { shoulder, elbow } => {
                        vec![("wrist.shoulder", shoulder), ("wrist.elbow", elbow)]
                    }
                };
                for (name, j) in joints {
                    let is_motor = self
                        .modules()
                        .any(|o| o.mod_id == j && matches!(o.device, ModuleKindJson::Motor(_)));
                    if !is_motor {
                        c.push(
                            format!("chains[{ci}].modules[{mi}].device.force_torque.load.{name}"),
                            Problem::Mismatch(format!(
                                "module {} ({}): its load model names joint {j}, not a motor controller",
                                m.mod_id, m.name
                            )),
                        );
                    }
                }
            }
        }
    }

    /// Every module, chain by chain.
    pub fn modules(&self) -> impl Iterator<Item = &ModuleJson> {
        self.chains.iter().flat_map(|c| c.modules.iter())
    }

    /// The real-time system.
    ///
    /// # Errors
    /// An unknown name.
    pub fn rtos(&self) -> Result<Rtos, TestbedError> {
        Rtos::from_name(&self.rtos)
            .ok_or_else(|| bad(format!("rtos {:?}: xenomai or rtlinux", self.rtos)))
    }

    /// The broadcast speed.
    ///
    /// # Errors
    /// Not 100, 200 or 400.
    pub fn broadcast_speed(&self) -> Result<Speed, TestbedError> {
        match self.broadcast_mbps {
            100 => Ok(Speed::S100),
            200 => Ok(Speed::S200),
            400 => Ok(Speed::S400),
            x => Err(bad(format!("broadcast_mbps {x}: 100, 200 or 400"))),
        }
    }

    /// The period.
    pub fn period(&self) -> std::time::Duration {
        duration_us(self.period_us, bounds::PERIOD_US.1)
    }

    /// The modules' DSP timing.
    pub fn responder_timing(&self) -> ResponderTiming {
        ResponderTiming {
            poll: us(self.responder.poll_us),
            fixed: us(self.responder.fixed_us),
            per_byte: us(self.responder.per_byte_us),
        }
    }

    fn body_params(&self) -> BodyParams {
        let b = &self.body;
        BodyParams {
            mass: b.mass_kg,
            leg_length: b.leg_length_m,
            hand_mass: b.hand_mass_kg,
            forearm_length: b.forearm_length_m,
            hand_offset: b.hand_offset_m,
        }
    }

    /// The parameter record PARAMETER sends to a motor.
    fn record(mod_id: u8, j: &MotorJson) -> ParameterRecord {
        ParameterRecord {
            mod_id: ModId(mod_id),
            gear_ratio: j.gear_ratio as f32,
            kp: j.kp as f32,
            ki: j.ki as f32,
            kd: j.kd as f32,
            position_min: j.position_limits_rad[0] as f32,
            position_max: j.position_limits_rad[1] as f32,
            torque_max: j.torque_limit_nm as f32,
        }
    }

    /// What the MotionController expects, in reading order (chain by
    /// chain).
    ///
    /// # Errors
    /// A module ID past 31.
    pub fn layout(&self) -> Result<RobotLayout, TestbedError> {
        let modules = self
            .modules()
            .map(|m| {
                let (kind, parameters) = match &m.device {
                    ModuleKindJson::Motor(j) => {
                        (ModuleKind::MotorController, Some(Self::record(m.mod_id, j)))
                    }
                    ModuleKindJson::ForceTorque(_) => (ModuleKind::ForceTorque, None),
                };
                ModuleSpec {
                    mod_id: ModId(m.mod_id),
                    kind,
                    name: m.name.clone(),
                    parameters,
                }
            })
            .collect();
        Ok(RobotLayout { modules })
    }

    /// The emulated modules, chain by chain.
    pub fn module_configs(&self) -> Vec<Vec<ModuleConfig>> {
        let timing = self.responder_timing();
        self.chains
            .iter()
            .map(|chain| {
                chain
                    .modules
                    .iter()
                    .map(|m| ModuleConfig {
                        mod_id: ModId(m.mod_id),
                        name: m.name.clone(),
                        firmware: 2,
                        timing,
                        speed: Speed::S400,
                        device: match &m.device {
                            ModuleKindJson::Motor(j) => DeviceConfig::Motor(JointParams {
                                inertia: j.inertia,
                                damping: j.damping,
                                gravity_torque: j.gravity_torque_nm,
                                gravity_offset: 0.0,
                                torque_constant: j.torque_constant,
                                servo_hz: j.servo_hz,
                                watchdog: us(j.watchdog_ms * 1e3),
                                initial_position: j.initial_position_rad,
                            }),
                            ModuleKindJson::ForceTorque(f) => DeviceConfig::ForceTorque(FtParams {
                                load: match f.load {
                                    FtLoadJson::Foot {
                                        hip,
                                        knee,
                                        other_knee,
                                        left,
                                    } => FtLoad::Foot {
                                        hip: ModId(hip),
                                        knee: ModId(knee),
                                        other_knee: ModId(other_knee),
                                        left,
                                    },
                                    FtLoadJson::Wrist { shoulder, elbow } => FtLoad::Wrist {
                                        shoulder: ModId(shoulder),
                                        elbow: ModId(elbow),
                                    },
                                },
                                body: self.body_params(),
                                offset: f.offset,
                                noise: f.noise,
                                seed: self.seed.wrapping_add(u64::from(m.mod_id)),
                                initial_pose: self.initial_pose(),
                            }),
                        },
                    })
                    .collect()
            })
            .collect()
    }

    /// Every joint's power-up angle, by ModID.
    pub fn initial_pose(&self) -> [f64; QWRITE_SLOTS] {
        let mut pose = [0.0; QWRITE_SLOTS];
        for (i, q) in pose.iter_mut().enumerate() {
            if let Some(j) = self.motor(ModId(i as u8)) {
                *q = j.initial_position_rad;
            }
        }
        pose
    }

    /// The motor controller `id`'s settings.
    pub fn motor(&self, id: ModId) -> Option<&MotorJson> {
        self.modules().find_map(|m| match &m.device {
            ModuleKindJson::Motor(j) if m.mod_id == id.0 => Some(j),
            _ => None,
        })
    }

    /// Seed 002's MAHRU: 10 motor controllers (2 per leg, 2 per arm, 1 per
    /// hand) and 4 force/torque sensors (1 per foot, 1 per wrist), on three
    /// chains from the computer's card: legs, arms and hands, sensors. The
    /// computer runs Xenomai at the seed's 2 ms period with its 500 us
    /// computation and 20 us slack.
    pub fn seed002() -> MahruConfig {
        let motor = |gear, kp, ki, kd, lim: [f64; 2], tmax, inertia, gravity, init| MotorJson {
            gear_ratio: gear,
            kp,
            ki,
            kd,
            position_limits_rad: lim,
            torque_limit_nm: tmax,
            inertia,
            damping: 0.05 * kd,
            gravity_torque_nm: gravity,
            torque_constant: 0.05,
            servo_hz: 5000.0,
            watchdog_ms: 10.0,
            initial_position_rad: init,
        };
        let hip = motor(
            160.0,
            2000.0,
            1500.0,
            60.0,
            [-1.0, 1.0],
            200.0,
            1.2,
            27.0,
            0.0,
        );
        let knee = motor(160.0, 1200.0, 800.0, 35.0, [0.0, 2.2], 150.0, 0.5, 7.0, 0.2);
        let shoulder = motor(120.0, 800.0, 400.0, 30.0, [-1.5, 1.5], 80.0, 0.6, 10.0, 0.0);
        let elbow = motor(100.0, 300.0, 150.0, 9.0, [0.0, 2.4], 40.0, 0.15, 3.0, 0.4);
        let hand = motor(50.0, 20.0, 10.0, 0.6, [-0.5, 1.0], 5.0, 0.01, 0.3, 0.2);
        let m = |mod_id, name: &str, j: MotorJson| ModuleJson {
            mod_id,
            name: name.into(),
            device: ModuleKindJson::Motor(j),
        };
        let ft = |mod_id, name: &str, load, offset| ModuleJson {
            mod_id,
            name: name.into(),
            device: ModuleKindJson::ForceTorque(FtJson {
                load,
                offset,
                noise: [0.4, 0.03],
            }),
        };
        let foot = |hip, knee, other_knee, left| FtLoadJson::Foot {
            hip,
            knee,
            other_knee,
            left,
        };
        MahruConfig {
            name: "MAHRU humanoid (seed 002)".into(),
            period_us: 2000.0,
            rtos: "xenomai".into(),
            compute_us: 500.0,
            slack_us: 20.0,
            broadcast_mbps: 400,
            seed: 2,
            responder: ResponderJson {
                poll_us: 5.0,
                fixed_us: 8.0,
                per_byte_us: 0.406,
            },
            body: BodyJson {
                mass_kg: 67.0,
                leg_length_m: 0.75,
                hand_mass_kg: 1.2,
                forearm_length_m: 0.28,
                hand_offset_m: 0.08,
            },
            gait: GaitJson {
                stride_s: 1.2,
                ramp_s: 1.0,
                hip_rad: 0.25,
                knee_rad: 0.5,
                shoulder_rad: 0.2,
                elbow_rad: 0.1,
                hand_rad: 0.1,
            },
            chains: vec![
                ChainJson {
                    name: "legs".into(),
                    modules: vec![
                        m(0, "l_hip_pitch", hip),
                        m(1, "l_knee", knee),
                        m(2, "r_hip_pitch", hip),
                        m(3, "r_knee", knee),
                    ],
                },
                ChainJson {
                    name: "arms and hands".into(),
                    modules: vec![
                        m(4, "l_shoulder_pitch", shoulder),
                        m(5, "l_elbow", elbow),
                        m(8, "l_hand", hand),
                        m(6, "r_shoulder_pitch", shoulder),
                        m(7, "r_elbow", elbow),
                        m(9, "r_hand", hand),
                    ],
                },
                ChainJson {
                    name: "force/torque sensors".into(),
                    modules: vec![
                        ft(
                            10,
                            "l_foot_ft",
                            foot(0, 1, 3, true),
                            [4.0, -3.0, 12.0, 0.3, -0.2, 0.05],
                        ),
                        ft(
                            11,
                            "r_foot_ft",
                            foot(2, 3, 1, false),
                            [-2.5, 1.5, -9.0, -0.1, 0.25, -0.04],
                        ),
                        ft(
                            12,
                            "l_wrist_ft",
                            FtLoadJson::Wrist {
                                shoulder: 4,
                                elbow: 5,
                            },
                            [0.8, -0.6, 1.5, 0.02, -0.03, 0.01],
                        ),
                        ft(
                            13,
                            "r_wrist_ft",
                            FtLoadJson::Wrist {
                                shoulder: 6,
                                elbow: 7,
                            },
                            [-0.5, 0.9, -1.2, -0.02, 0.04, -0.01],
                        ),
                    ],
                },
            ],
        }
    }
}

/// A motor controller's numbers: PARAMETER's (f32 on the wire) and the
/// joint's physics.
fn check_motor(c: &mut Checker, mp: &str, j: &MotorJson) {
    c.positive(
        format!("{mp}.gear_ratio"),
        j.gear_ratio,
        bounds::GEAR_RATIO,
        "",
    );
    for (name, x) in [("kp", j.kp), ("ki", j.ki), ("kd", j.kd)] {
        c.not_negative(format!("{mp}.{name}"), x, bounds::GAIN, "");
    }
    let [lo, hi] = j.position_limits_rad;
    for (i, x) in [lo, hi].into_iter().enumerate() {
        c.magnitude(
            format!("{mp}.position_limits_rad[{i}]"),
            x,
            bounds::ANGLE_RAD,
            " rad",
        );
    }
    if lo.is_finite() && hi.is_finite() && lo >= hi {
        c.push(
            format!("{mp}.position_limits_rad"),
            Problem::EmptyRange {
                lower: lo,
                upper: hi,
            },
        );
    }
    c.positive(
        format!("{mp}.torque_limit_nm"),
        j.torque_limit_nm,
        bounds::TORQUE_NM,
        " N m",
    );
    c.positive(
        format!("{mp}.inertia"),
        j.inertia,
        bounds::INERTIA,
        " kg m²",
    );
    c.not_negative(
        format!("{mp}.damping"),
        j.damping,
        bounds::DAMPING,
        " N m s/rad",
    );
    c.not_negative(
        format!("{mp}.gravity_torque_nm"),
        j.gravity_torque_nm,
        bounds::TORQUE_NM,
        " N m",
    );
    c.positive(
        format!("{mp}.torque_constant"),
        j.torque_constant,
        bounds::TORQUE_CONSTANT,
        " N m/A",
    );
    let (lo_hz, hi_hz) = bounds::SERVO_HZ;
    c.range(
        format!("{mp}.servo_hz"),
        j.servo_hz,
        lo_hz,
        hi_hz,
        false,
        " Hz",
    );
    let (lo_ms, hi_ms) = bounds::WATCHDOG_MS;
    c.range(
        format!("{mp}.watchdog_ms"),
        j.watchdog_ms,
        lo_ms,
        hi_ms,
        false,
        " ms",
    );
    let ip = format!("{mp}.initial_position_rad");
    if !j.initial_position_rad.is_finite() {
        c.push(ip, Problem::NotFinite);
    } else if !(lo..=hi).contains(&j.initial_position_rad) {
        c.push(
            ip,
            Problem::OutOfRange {
                value: j.initial_position_rad,
                expected: format!(
                    "inside position_limits_rad [{}, {}]",
                    Number(lo),
                    Number(hi)
                ),
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_preset_is_valid_and_matches_the_seed() {
        let c = MahruConfig::seed002();
        c.validate().unwrap();
        let layout = c.layout().unwrap();
        let motors = layout
            .modules
            .iter()
            .filter(|m| m.kind == ModuleKind::MotorController)
            .count();
        assert_eq!((motors, layout.modules.len() - motors), (10, 4));
        assert_eq!(c.chains.len(), 3);
    }

    #[test]
    fn the_shipped_file_is_the_preset() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/mahru-seed002.json"
        );
        let loaded = MahruConfig::load(path).unwrap();
        assert_eq!(loaded, MahruConfig::seed002());
    }

    #[test]
    fn errors_name_the_problem() {
        let text = serde_json::to_string(&MahruConfig::seed002()).unwrap();
        let broken = text.replace("\"period_us\":2000.0", "\"period_us\":-1.0");
        let e = MahruConfig::from_json_str(&broken, "x.json")
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.json") && e.contains("period_us"), "{e}");
        let broken = text.replace("\"kp\":2000.0", "\"kp\":\"high\"");
        let e = MahruConfig::from_json_str(&broken, "x.json")
            .unwrap_err()
            .to_string();
        assert!(e.contains("chains[0].modules[0]"), "{e}");
        let mut c = MahruConfig::seed002();
        c.chains[2].modules[0].mod_id = 3;
        assert!(c.validate().unwrap_err().to_string().contains("twice"));
        let mut c = MahruConfig::seed002();
        c.chains.push(c.chains[2].clone());
        assert!(c.validate().is_err());
        let mut c = MahruConfig::seed002();
        c.rtos = "qnx".into();
        assert!(c.validate().is_err());
    }
}
