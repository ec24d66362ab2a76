//! Robot I/O configuration in the dVRK's `saw-robot-io` version 6 layout.
//!
//! A dVRK user should recognise these files: the top level carries
//! `"$id": "saw-robot-io.schema.json"` and `"$version": "6"`, then `robots`,
//! each with `actuators` that name a `board_id` and `axis_id` and carry the
//! `drive`, `encoder` and `potentiometer` conversions under the same keys as
//! sawRobotIO1394's generated files. Firelink adds optional sections that v6
//! does not have: per actuator `limits` (velocity, following error, current
//! saturation time), `simulation` (the plant preset, its mechanical stops,
//! PID gains and homing defaults, including a stop search) and, on the
//! encoder, `counts_per_turn`; per robot `simulation` (which dVRK arm it is,
//! the PSM's sterile adapter and instrument, the boards' serial numbers).
//! A robot's v6 `potentiometers.coupling` (pots mounted on joints, as on
//! the dVRK MTM) is used: pot positions are turned into actuator space with
//! its `JointToActuatorPosition` matrix, as sawRobotIO1394 does. A file may
//! also carry v6's `digital_inputs` (typed: the emulator puts each switch's
//! level on its line, the dVRK's rule reads it back,
//! [`DigitalInputConfig::is_pressed`]), a robot's `number_of_brakes` and
//! `brakes` and an actuator's `brake` calibration (typed: the emulator
//! models the brakes, the runner releases them as it powers the arm), and
//! `digital_outputs` and `dallas_chips` (kept as JSON).
//!
//! Keys Firelink does not know are read past and reported as warnings
//! ([`IoConfig::load_with_warnings`]), as the dVRK console reads past
//! them; a malformed value of a known key is refused with its path. What
//! the console's own reader would refuse (a required key missing, a wrong
//! type) is a warning too ([`console`]).
//!
//! Older sawRobotIO1394 names are accepted as aliases: `amps_to_bits` for
//! `current_to_bits`, `bits_to_feedback_amps` for `bits_to_current`,
//! `nm_to_amps` for `effort_to_current`, `max_current` for
//! `maximum_current`, `sensor_to_position` for `voltage_to_position`.
//!
//! ```json
//! {
//!   "actuator_id": 0, "board_id": 0, "axis_id": 0, "joint_type": "REVOLUTE",
//!   "drive": {
//!     "current_to_bits":   { "scale": -5242.88, "offset": 32768.0 },
//!     "bits_to_current":   { "scale": -0.000190734863, "offset": 6.25 },
//!     "effort_to_current": { "scale": 0.36006 },
//!     "maximum_current": 0.67
//!   },
//!   "encoder": {
//!     "bits_to_position": { "scale": -2.4773e-05 },
//!     "position_limits_soft": { "lower": -0.698, "upper": 1.134 },
//!     "velocity_source": "FIRMWARE", "counts_per_turn": 4000
//!   },
//!   "potentiometer": {
//!     "bits_to_voltage":     { "scale": 6.866455e-05 },
//!     "voltage_to_position": { "scale": 0.9, "offset": -2.025 }
//!   },
//!   "limits": { "velocity": 3.0, "following_error": 0.2,
//!               "following_error_grace": 0.05, "saturation_time": 1.0 },
//!   "simulation": { "plant": "mtm_j1",
//!                   "pid": { "kp": 8.0, "ki": 4.0, "kd": 0.4 },
//!                   "homing": { "position": 0.0, "velocity": 0.5, "acceleration": 2.0 } }
//! }
//! ```
//!
//! # Units
//!
//! SI everywhere above the configuration: radians or metres, seconds,
//! amperes, newton-metres or newtons. Raw board values (`fpga-board.md`
//! §3): the 16-bit DAC command and current feedback (`0x8000` ~ 0 A), the
//! 16-bit potentiometer ADC and the 24-bit offset-binary encoder count.
//! The conversion methods on [`DriveConfig`], [`EncoderConfig`] and
//! [`PotentiometerConfig`] are the only place in Firelink where one becomes
//! the other.
//!
//! # Loading
//!
//! [`IoConfig::load`] and [`IoConfig::from_json_str`] parse with serde,
//! report type errors with their JSON path (`robots[1].actuators[3].drive`),
//! then [`IoConfig::validate`] checks every rule and reports *all* broken
//! ones, each naming the file, the path and the problem. Every number has
//! an upper bound ([`bounds`]) besides its lower one, so nothing a file
//! holds can overflow a duration, hang a move or a loop, or saturate a
//! conversion; an error echoes the number as it was written (`1e300`, not
//! 301 digits) and names the field the value breaks.

pub mod console;
mod convert;
mod error;
pub mod presets;
mod validate;

#[cfg(test)]
mod props;

pub use error::{ConfigError, ConfigErrors, ConfigWarning, Measured, Problem, Warning};
pub use validate::bounds;

use crate::label::{BoardSet, Label};
use crate::pid::PidGains;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The value `$id` must have.
pub const SCHEMA_ID: &str = "saw-robot-io.schema.json";
/// The value `$version` must have.
pub const SCHEMA_VERSION: &str = "6";
/// Board IDs are set by a 4-bit rotary switch.
pub use firelink_wire::qla::MAX_BOARD_ID;

/// `robots[0].actuators[1].brake`: an ignored key's path as the loader's
/// errors write paths.
fn json_path(path: &serde_ignored::Path<'_>) -> String {
    use serde_ignored::Path;
    match path {
        Path::Root => String::new(),
        Path::Seq { parent, index } => format!("{}[{index}]", json_path(parent)),
        Path::Map { parent, key } => {
            let p = json_path(parent);
            if p.is_empty() {
                key.clone()
            } else {
                format!("{p}.{key}")
            }
        }
        Path::Some { parent }
        | Path::NewtypeStruct { parent }
        | Path::NewtypeVariant { parent } => json_path(parent),
    }
}

/// A configuration as loaded, with what its loader accepted but its user
/// should hear about once: keys Firelink does not use (ignored), and what
/// would make the dVRK console refuse the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// The configuration.
    pub config: IoConfig,
    /// The warnings, in file order (ignored keys first).
    pub warnings: Vec<ConfigWarning>,
}

/// A whole configuration file: one or more robots sharing one bus.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IoConfig {
    /// Must be [`SCHEMA_ID`]; empty when the file has none (a warning:
    /// the dVRK console refuses such a file).
    #[serde(rename = "$id", default)]
    pub id: String,
    /// Must be [`SCHEMA_VERSION`]: a string, as in the dVRK files (a
    /// number is read as the console reads it, `6` as `"6"`).
    #[serde(rename = "$version", deserialize_with = "string_or_number")]
    pub version: String,
    /// Free text (Firelink extension): where the numbers came from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// The robots (arms) on this bus (none in a file of inputs only, such
    /// as the foot pedals').
    #[serde(default)]
    pub robots: Vec<RobotConfig>,
    /// v6 digital inputs: buttons, pedals and contacts on the boards'
    /// DIGIN lines.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub digital_inputs: Option<Vec<DigitalInputConfig>>,
    /// v6 digital outputs (accepted, not used yet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub digital_outputs: Option<serde_json::Value>,
    /// v6 Dallas (1-wire) chips (accepted, not used yet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dallas_chips: Option<serde_json::Value>,
}

/// One robot (arm): a named list of actuators.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotConfig {
    /// Robot name, unique in the file (`MTML`, `PSM1`, ...).
    pub name: String,
    /// Controller board type of every board this robot uses; decides how many
    /// axes a board has. Defaults to `QLA1`.
    #[serde(default)]
    pub hardware_version: HardwareVersion,
    /// Serial number of the arm (a string in v6; a number is read as
    /// the console reads it).
    #[serde(deserialize_with = "string_or_number")]
    pub serial_number: String,
    /// Must equal the number of entries in `actuators`.
    pub number_of_actuators: usize,
    /// The actuators, in joint order.
    pub actuators: Vec<ActuatorConfig>,
    /// v6 robot type marker, e.g. `"io-only"` for an MTM gripper file.
    #[serde(default, rename = "type", skip_serializing_if = "Option::is_none")]
    pub robot_type: Option<String>,
    /// v6: the robot only does I/O (no servo loop).
    #[serde(default, rename = "only_IO", skip_serializing_if = "Option::is_none")]
    pub only_io: Option<bool>,
    /// v6: whether encoders are preloaded from the potentiometers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub has_encoder_preload: Option<bool>,
    /// v6 number of brakes: equals the entries of `brakes` (the dVRK
    /// console requires the key, 0 for an arm without brakes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub number_of_brakes: Option<usize>,
    /// v6 brakes: brake `i` holds actuator `i` while its amplifier channel
    /// carries no release current.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brakes: Option<Vec<BrakeConfig>>,
    /// v6 potentiometer settings shared by the robot (tolerances used by
    /// homing and the safety monitor).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potentiometers: Option<PotentiometersConfig>,
    /// What the emulator puts behind this robot (Firelink extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<RobotSimulation>,
}

/// The da Vinci Research Kit arms Firelink knows the mechanics of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum DvrkArm {
    /// Master tool manipulator (MTML, MTMR): 7 actuators and a gripper.
    #[serde(rename = "MTM")]
    Mtm,
    /// Patient side manipulator (PSM1-3): 7 actuators.
    #[serde(rename = "PSM")]
    Psm,
    /// Endoscope camera manipulator: 4 actuators (and 3 brakes).
    #[serde(rename = "ECM")]
    Ecm,
}

impl DvrkArm {
    /// The arm a robot name says, as the dVRK names them (`MTML`, `MTMR`,
    /// `PSM1`, ..., `ECM`); `None` for other names.
    pub fn from_robot_name(name: &str) -> Option<DvrkArm> {
        let upper = name.to_ascii_uppercase();
        if upper.starts_with("MTM") {
            Some(DvrkArm::Mtm)
        } else if upper.starts_with("PSM") {
            Some(DvrkArm::Psm)
        } else if upper.starts_with("ECM") {
            Some(DvrkArm::Ecm)
        } else {
            None
        }
    }

    /// Motorised actuators of the arm.
    pub fn actuators(self) -> usize {
        self.plants().len()
    }

    /// The plants of the arm's actuators, in order.
    pub fn plants(self) -> &'static [PlantPreset] {
        use PlantPreset::*;
        match self {
            DvrkArm::Mtm => &[MtmJ1, MtmJ2, MtmJ3, MtmJ4, MtmJ5, MtmJ6, MtmJ7],
            DvrkArm::Psm => &[PsmJ1, PsmJ2, PsmJ3, PsmJ4, PsmJ5, PsmJ6, PsmJ7],
            DvrkArm::Ecm => &[EcmJ1, EcmJ2, EcmJ3, EcmJ4],
        }
    }

    /// The plant of actuator `index` (0-based); `None` beyond the arm.
    pub fn plant(self, index: usize) -> Option<PlantPreset> {
        self.plants().get(index).copied()
    }
}

/// What the emulator puts behind one robot (Firelink extension).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RobotSimulation {
    /// Which dVRK arm the robot is, for the plants of actuators whose
    /// `simulation` names none; by default the robot's name says
    /// ([`DvrkArm::from_robot_name`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arm: Option<DvrkArm>,
    /// PSM: whether the sterile adapter is on (its contact, the v6 digital
    /// input named `<robot>_adapter`, reads pressed).
    #[serde(default, skip_serializing_if = "is_false")]
    pub adapter: bool,
    /// PSM: the instrument in the adapter, if any (its contact, the v6
    /// digital input `<robot>_tool`, reads pressed, and its 1-wire memory
    /// holds what is here).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<ToolConfig>,
    /// Serial numbers of the robot's boards, as their PROMs hold them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boards: Vec<BoardSimulation>,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// An instrument as its 1-wire memory describes it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ToolConfig {
    /// Name, as the dVRK tool index spells it (`LARGE_NEEDLE_DRIVER`).
    pub name: String,
    /// Model number (`400006`).
    pub model: u32,
    /// Version byte.
    #[serde(default)]
    pub version: u8,
}

/// One board of a robot, as the emulator presents it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoardSimulation {
    /// Board ID (rotary switch).
    pub board_id: u8,
    /// Serial numbers in the board's PROMs.
    pub serial: BoardSerial,
    /// The FPGA board generation (default: V2 under a QLA1, V3 under a
    /// DQLA, the only FPGA a DQLA exists on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fpga_version: Option<FpgaGeneration>,
    /// The firmware revision the board runs (7, 8 or 9; default: what the
    /// emulator is asked for).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub firmware: Option<u32>,
}

/// An FPGA board generation, as a configuration names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FpgaGeneration {
    /// FPGA V2 (Spartan-6, one Ethernet port: the bridge).
    #[serde(rename = "V2")]
    V2,
    /// FPGA V3 (Zynq, two Ethernet ports).
    #[serde(rename = "V3")]
    V3,
}

/// The serial numbers of an FPGA board and its companion QLA, as printed
/// on their labels (`1234-56` or `1234-567`; the PROMs add the `FPGA ` and
/// `QLA ` prefixes).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoardSerial {
    /// The FPGA board's serial number.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fpga: Option<String>,
    /// The QLA's serial number.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub qla: Option<String>,
}

/// Controller board types, as v6 names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum HardwareVersion {
    /// Quad Linear Amplifier: 4 axes per FPGA board.
    #[default]
    #[serde(rename = "QLA1")]
    Qla1,
    /// Dual QLA: 8 axes per FPGA board.
    #[serde(rename = "DQLA")]
    Dqla,
    /// dVRK-Si controller: 10 axes per board.
    #[serde(rename = "dRA1")]
    Dra1,
    /// Seed 001's 7-channel Snake robot node (its own FPGA/1394 board,
    /// not a JHU one): 7 axes per board.
    #[serde(rename = "SNAKE")]
    Snake,
}

impl HardwareVersion {
    /// Motor axes per board.
    pub fn axes(self) -> u8 {
        match self {
            HardwareVersion::Qla1 => 4,
            HardwareVersion::Dqla => 8,
            HardwareVersion::Dra1 => 10,
            HardwareVersion::Snake => 7,
        }
    }

    /// The name used in the files.
    pub fn name(self) -> &'static str {
        match self {
            HardwareVersion::Qla1 => "QLA1",
            HardwareVersion::Dqla => "DQLA",
            HardwareVersion::Dra1 => "dRA1",
            HardwareVersion::Snake => "SNAKE",
        }
    }

    /// The board's HW_VERSION register value (`fpga-board.md` §2); for
    /// a Snake node, its version register (seed 001 Table 1, address 4).
    pub fn hw_version_register(self) -> u32 {
        match self {
            HardwareVersion::Qla1 => 0x514C_4131,
            HardwareVersion::Dqla => 0x4451_4C41,
            HardwareVersion::Dra1 => 0x6452_4131,
            HardwareVersion::Snake => firelink_wire::snake::registers::VERSION,
        }
    }

    /// Whether the board is seed 001's Snake node (driven through
    /// `firelink_host::snake`, not the QLA protocols).
    pub fn is_snake(self) -> bool {
        self == HardwareVersion::Snake
    }
}

/// One actuator: where it is wired and how its raw values convert.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ActuatorConfig {
    /// Index of the actuator in its robot; if present it must equal its
    /// position in the list.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuator_id: Option<usize>,
    /// Board ID (rotary switch, 0..=15).
    pub board_id: u8,
    /// Axis on the board, 0-based, below the board's axis count.
    pub axis_id: u8,
    /// Kind of joint (v6).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_type: Option<JointType>,
    /// Current command and feedback conversions.
    pub drive: DriveConfig,
    /// Encoder conversion and soft limits.
    pub encoder: EncoderConfig,
    /// Analog potentiometer conversion, if the joint has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potentiometer: Option<PotentiometerConfig>,
    /// The current calibration of this actuator's brake channel, as the
    /// dVRK's calibration tools write it beside the drive (the stock ECM);
    /// the brake itself is the robot's `brakes` entry of the same index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brake: Option<ActuatorBrakeCalibration>,
    /// Safety limits (Firelink extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits: Option<LimitsConfig>,
    /// Simulation plant and control defaults (Firelink extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<SimulationConfig>,
}

/// Joint kinds of v6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum JointType {
    /// Rotation with limits (radians).
    Revolute,
    /// Translation (metres).
    Prismatic,
    /// Rotation without limits.
    Continuous,
    /// Does not move.
    Fixed,
    /// Not said.
    Undefined,
}

/// `y = scale * x + offset`, the v6 `linear_function`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinearFunction {
    /// Slope; must be finite and non-zero.
    pub scale: f64,
    /// Intercept; 0 when omitted.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub offset: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// A string the console reads with jsoncpp's `asString`: a JSON string,
/// or a number or boolean written as text (`6` reads `"6"`).
fn string_or_number<'de, D: serde::Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    match serde_json::Value::deserialize(d)? {
        serde_json::Value::String(s) => Ok(s),
        serde_json::Value::Number(n) => Ok(n.to_string()),
        serde_json::Value::Bool(b) => Ok(b.to_string()),
        other => Err(serde::de::Error::invalid_type(
            match &other {
                serde_json::Value::Null => serde::de::Unexpected::Unit,
                serde_json::Value::Array(_) => serde::de::Unexpected::Seq,
                _ => serde::de::Unexpected::Map,
            },
            &"a string (or a number)",
        )),
    }
}

/// A v6 brake (`robots[].brakes[]`): an amplifier channel whose current
/// releases a spring-applied brake. The console releases the brakes as it
/// powers the arm (`release_current` for `release_time`, then
/// `released_current` to hold them open) and engages them
/// (`engaged_current`) as it powers it down.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BrakeConfig {
    /// Board ID of the brake's amplifier channel.
    pub board_id: u8,
    /// Axis (amplifier channel) on that board.
    pub axis_id: u8,
    /// The channel's current command and feedback conversions.
    pub drive: BrakeDrive,
    /// Current that releases the brake, A.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub release_current: Option<f64>,
    /// How long the console holds `release_current`, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub release_time: Option<f64>,
    /// Current that keeps a released brake open, A.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub released_current: Option<f64>,
    /// Current while the brake is engaged, A (0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub engaged_current: Option<f64>,
}

/// A brake channel's conversions (a drive without an effort).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BrakeDrive {
    /// Amperes to the 16-bit DAC command.
    pub current_to_bits: LinearFunction,
    /// 16-bit ADC current feedback to amperes.
    pub bits_to_current: LinearFunction,
    /// Largest current ever commanded, A.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub maximum_current: Option<f64>,
}

/// `actuators[].brake`: offsets of the actuator's brake channel from a
/// current calibration (the scales are the brake's drive's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ActuatorBrakeCalibration {
    /// Offset of the current command.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_to_bits: Option<OffsetOnly>,
    /// Offset of the current feedback.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bits_to_current: Option<OffsetOnly>,
}

/// A linear function's offset alone (its scale, if given, is kept).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffsetOnly {
    /// Intercept.
    #[serde(default)]
    pub offset: f64,
    /// Slope, if the file gives one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
}

impl BrakeConfig {
    /// The current that opens the brake, A: `release_current`, else
    /// `released_current`, else the drive's `maximum_current`.
    pub fn opening_current(&self) -> Option<f64> {
        self.release_current
            .or(self.released_current)
            .or(self.drive.maximum_current)
    }

    /// The current that keeps it open, A: `released_current`, else the
    /// opening current.
    pub fn holding_current(&self) -> Option<f64> {
        self.released_current.or_else(|| self.opening_current())
    }
}

/// A v6 digital input: a switch on one of a board's DIGIN lines.
///
/// The dVRK reads it (sawRobotIO1394 `mtsDigitalInput1394::PollState`) as
/// pressed when its line is *low* if `pressed_value` is true, when it is
/// high if `pressed_value` is false: [`DigitalInputConfig::is_pressed`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DigitalInputConfig {
    /// Name (`PSM1_adapter`, `Clutch`, ...).
    pub name: String,
    /// Board ID.
    pub board_id: u8,
    /// Bit of DIGIN (0..=31; the switch lines are 11:0).
    pub bit_id: u8,
    /// Which reading means pressed (see the type's docs).
    #[serde(default, deserialize_with = "bool_or_number")]
    pub pressed_value: bool,
    /// v6: emit an event when pressed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trigger_when_pressed: Option<bool>,
    /// v6: emit an event when released.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trigger_when_released: Option<bool>,
    /// v6: skip the first reading's event.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skip_first_run: Option<bool>,
    /// v6 debounce time, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub debounce_time: Option<f64>,
    /// v6 debounce time of a click, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub debounce_time_click: Option<f64>,
    /// What the emulated switch does (Firelink extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<InputSimulation>,
}

/// The emulated switch behind a digital input (Firelink extension).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct InputSimulation {
    /// Whether it rests pressed (a pedal held down, a contact closed);
    /// released when absent.
    #[serde(default)]
    pub pressed: bool,
}

impl DigitalInputConfig {
    /// DIGIN's mask of this input.
    pub fn mask(&self) -> u32 {
        1u32.checked_shl(u32::from(self.bit_id)).unwrap_or(0)
    }

    /// Whether the input reads pressed in DIGIN word `digin`, by the
    /// dVRK's rule: a set bit reads `!pressed_value`, a clear bit
    /// `pressed_value`.
    pub fn is_pressed(&self, digin: u32) -> bool {
        if digin & self.mask() != 0 {
            !self.pressed_value
        } else {
            self.pressed_value
        }
    }

    /// The level (true: high) a switch puts on the line to read `pressed`.
    pub fn line_level(&self, pressed: bool) -> bool {
        pressed != self.pressed_value
    }
}

/// A boolean the console reads with jsoncpp's `asBool` (a number: not 0).
fn bool_or_number<'de, D: serde::Deserializer<'de>>(d: D) -> Result<bool, D::Error> {
    match serde_json::Value::deserialize(d)? {
        serde_json::Value::Bool(b) => Ok(b),
        serde_json::Value::Number(n) => Ok(n.as_f64().is_some_and(|x| x != 0.0)),
        _ => Err(serde::de::Error::custom("expected a boolean")),
    }
}

/// The amplifier: current command and feedback conversions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DriveConfig {
    /// Amperes to the 16-bit DAC command (`offset` ~ 0 A, e.g. 32768).
    #[serde(alias = "amps_to_bits")]
    pub current_to_bits: LinearFunction,
    /// 16-bit ADC current feedback to amperes.
    #[serde(alias = "bits_to_feedback_amps")]
    pub bits_to_current: LinearFunction,
    /// Joint effort (N m or N) to motor current (A): 1 / (gear ratio x torque
    /// constant).
    #[serde(alias = "nm_to_amps")]
    pub effort_to_current: LinearFunction,
    /// Largest current ever commanded, amperes (> 0).
    #[serde(alias = "max_current")]
    pub maximum_current: f64,
}

/// Where joint velocity comes from (v6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum VelocitySource {
    /// From the FPGA's encoder period measurement.
    Firmware,
    /// From position differences on the host.
    Software,
}

/// The quadrature encoder.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EncoderConfig {
    /// Signed counts (around the `0x800000` midpoint) to position (rad or m).
    pub bits_to_position: LinearFunction,
    /// Soft position limits (`lower < upper`); commands are kept inside them.
    pub position_limits_soft: Limits,
    /// v6 velocity source.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_source: Option<VelocitySource>,
    /// Encoder counts per motor turn (quadrature, x4), for documentation and
    /// checks (Firelink extension, from the older XML `CountsPerTurn`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counts_per_turn: Option<u32>,
}

/// A closed interval `[lower, upper]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Smallest allowed value.
    pub lower: f64,
    /// Largest allowed value.
    pub upper: f64,
}

/// The analog potentiometer of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PotentiometerConfig {
    /// 16-bit ADC bits to volts (QLA: 4.5 V / 65536).
    pub bits_to_voltage: LinearFunction,
    /// Volts to joint position.
    #[serde(alias = "sensor_to_position")]
    pub voltage_to_position: LinearFunction,
}

/// v6 robot-level potentiometer settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PotentiometersConfig {
    /// `ANALOG`, `DIGITAL`, ...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potentiometers_type: Option<PotentiometersType>,
    /// Allowed pot/encoder disagreement per actuator.
    #[serde(default)]
    pub tolerances: Vec<PotentiometerTolerance>,
    /// v6 coupling: where the pots are mounted on joints that several
    /// actuators move, `JointToActuatorPosition` turns their positions
    /// into actuator space.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coupling: Option<ActuatorJointCoupling>,
    /// v6 lookup table file for digital pots (accepted, not used yet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lookup_table_file: Option<String>,
}

/// The cisst actuator/joint coupling matrices (`prmActuatorJointCoupling`),
/// square, one row and column per actuator. Firelink uses
/// `JointToActuatorPosition` (or the inverse of `ActuatorToJointPosition`
/// when only that is given); the effort matrices are kept.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ActuatorJointCoupling {
    /// Actuator positions from joint positions.
    #[serde(
        rename = "JointToActuatorPosition",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub joint_to_actuator_position: Option<Vec<Vec<f64>>>,
    /// Joint positions from actuator positions.
    #[serde(
        rename = "ActuatorToJointPosition",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub actuator_to_joint_position: Option<Vec<Vec<f64>>>,
    /// Actuator efforts from joint efforts (kept, not used).
    #[serde(
        rename = "JointToActuatorEffort",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub joint_to_actuator_effort: Option<Vec<Vec<f64>>>,
    /// Joint efforts from actuator efforts (kept, not used).
    #[serde(
        rename = "ActuatorToJointEffort",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub actuator_to_joint_effort: Option<Vec<Vec<f64>>>,
}

impl ActuatorJointCoupling {
    /// Actuator positions from joint positions: `JointToActuatorPosition`,
    /// or the inverse of `ActuatorToJointPosition`. `None` if neither is
    /// given, or the one given is not square or cannot be inverted.
    pub fn joint_to_actuator(&self) -> Option<Matrix> {
        if let Some(m) = &self.joint_to_actuator_position {
            return Matrix::from_rows(m);
        }
        Matrix::from_rows(self.actuator_to_joint_position.as_ref()?)?.inverse()
    }

    /// Joint positions from actuator positions (the other direction).
    pub fn actuator_to_joint(&self) -> Option<Matrix> {
        if let Some(m) = &self.actuator_to_joint_position {
            return Matrix::from_rows(m);
        }
        Matrix::from_rows(self.joint_to_actuator_position.as_ref()?)?.inverse()
    }
}

/// A small dense square matrix (row-major), for couplings.
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    n: usize,
    values: Vec<f64>,
}

impl Matrix {
    /// The matrix with these rows; `None` unless square, non-empty and
    /// finite.
    pub fn from_rows(rows: &[Vec<f64>]) -> Option<Matrix> {
        let n = rows.len();
        if n == 0
            || rows
                .iter()
                .any(|r| r.len() != n || r.iter().any(|v| !v.is_finite()))
        {
            return None;
        }
        Some(Matrix {
            n,
            values: rows.iter().flatten().copied().collect(),
        })
    }

    /// Rows and columns.
    pub fn size(&self) -> usize {
        self.n
    }

    /// Element (row, column); 0 outside.
    pub fn get(&self, row: usize, col: usize) -> f64 {
        if row < self.n && col < self.n {
            self.values.get(row * self.n + col).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    }

    /// The inverse (Gauss-Jordan with partial pivoting); `None` if singular.
    pub fn inverse(&self) -> Option<Matrix> {
        let n = self.n;
        let mut a = self.values.clone();
        let mut inv: Vec<f64> = (0..n * n)
            .map(|k| if k / n == k % n { 1.0 } else { 0.0 })
            .collect();
        for col in 0..n {
            let pivot =
                (col..n).max_by(|&x, &y| a[x * n + col].abs().total_cmp(&a[y * n + col].abs()))?;
            let p = a[pivot * n + col];
            if p.abs() < 1e-12 {
                return None;
            }
            for k in 0..n {
                a.swap(col * n + k, pivot * n + k);
                inv.swap(col * n + k, pivot * n + k);
            }
            for k in 0..n {
                a[col * n + k] /= p;
                inv[col * n + k] /= p;
            }
            for row in (0..n).filter(|&r| r != col) {
                let f = a[row * n + col];
                if f != 0.0 {
                    for k in 0..n {
                        a[row * n + k] -= f * a[col * n + k];
                        inv[row * n + k] -= f * inv[col * n + k];
                    }
                }
            }
        }
        Some(Matrix { n, values: inv })
    }
}

/// v6 potentiometer kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum PotentiometersType {
    /// No potentiometers.
    None,
    /// Analog pots read by the QLA ADC.
    Analog,
    /// Digital (Si) pots.
    Digital,
    /// Not said.
    Undefined,
}

/// How far pot and encoder may disagree, and for how long (v6).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PotentiometerTolerance {
    /// Actuator index in the robot (v6 calls it `axis_id`).
    pub axis_id: usize,
    /// Allowed difference (rad or m); 0 disables the check.
    pub distance: f64,
    /// How long the difference may last, seconds.
    pub latency: f64,
}

/// Per-actuator safety limits (Firelink extension). The position limits are
/// `encoder.position_limits_soft` and the current limit is
/// `drive.maximum_current`; this section adds what v6 lacks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LimitsConfig {
    /// Largest allowed speed (rad/s or m/s); also the default trajectory
    /// velocity limit.
    pub velocity: f64,
    /// Largest allowed acceleration for trajectories (rad/s² or m/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// Largest allowed |setpoint - position|.
    pub following_error: f64,
    /// How long the following error may exceed its limit, seconds.
    #[serde(default = "default_following_error_grace")]
    pub following_error_grace: f64,
    /// How long the current command may sit at `maximum_current`, seconds.
    #[serde(default = "default_saturation_time")]
    pub saturation_time: f64,
    /// How far past the soft limits the joint may be before a fault; absent
    /// means no position fault (soft limits still clamp commands).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_margin: Option<f64>,
}

fn default_following_error_grace() -> f64 {
    0.05
}

fn default_saturation_time() -> f64 {
    0.5
}

/// Simulation and control defaults for one actuator (Firelink extension).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimulationConfig {
    /// Which emulated plant drives this axis.
    pub plant: PlantPreset,
    /// The mechanical stops of the emulated joint (rad or m), at or beyond
    /// `encoder.position_limits_soft`. Absent: the arm's physical range
    /// where Firelink knows it (the MTM roll), else the soft limits widened
    /// by 3 degrees (3 mm for a prismatic joint); see
    /// `firelink_testbed::rig`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hard_stops: Option<Limits>,
    /// Default PID gains (current out, SI in).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pid: Option<PidGains>,
    /// Homing defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub homing: Option<HomingDefaults>,
}

/// After the encoders agree with the pots, move here.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HomingDefaults {
    /// Home position (rad or m), inside the soft limits.
    #[serde(default)]
    pub position: f64,
    /// Speed of the homing move (> 0).
    pub velocity: f64,
    /// Acceleration of the homing move (> 0).
    pub acceleration: f64,
    /// For a joint its pot cannot home (the MTM wrist roll turns more than
    /// its pot can tell): find a mechanical stop instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_search: Option<StopSearchConfig>,
}

/// Which way a stop search goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopSide {
    /// Towards decreasing positions.
    Lower,
    /// Towards increasing positions.
    Upper,
}

/// Homing by a stop search, as the dVRK console homes the MTM roll: move
/// at constant velocity (reached with a bounded acceleration) towards a
/// mechanical stop until the joint stalls (the following error passes
/// `stall_error`), declare the encoder to read `stop_position` there, then
/// move freely back.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StopSearchConfig {
    /// Which stop.
    pub side: StopSide,
    /// Search speed (> 0, rad/s or m/s).
    pub velocity: f64,
    /// Acceleration to that speed (> 0, rad/s² or m/s²).
    pub acceleration: f64,
    /// Following error that means the joint stalled against the stop (> 0).
    pub stall_error: f64,
    /// Where the stop is (rad or m): the encoder reads this once found.
    pub stop_position: f64,
    /// Longest travel before giving up: a stop that is not there (> 0).
    pub max_travel: f64,
}

/// Named plant models for the board emulator. The parameters live with the
/// emulator; the configuration only names one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[allow(missing_docs)]
pub enum PlantPreset {
    MtmJ1,
    MtmJ2,
    MtmJ3,
    MtmJ4,
    MtmJ5,
    MtmJ6,
    MtmJ7,
    PsmJ1,
    PsmJ2,
    PsmJ3,
    PsmJ4,
    PsmJ5,
    PsmJ6,
    PsmJ7,
    EcmJ1,
    EcmJ2,
    EcmJ3,
    EcmJ4,
    /// The MTM gripper: a Hall-effect sensor on the analog input, no
    /// motor.
    MtmGripper,
    /// A generic motor + load (benches, the Snake robot).
    Generic,
}

impl PlantPreset {
    /// Every preset, in file order.
    pub const ALL: [PlantPreset; 20] = [
        PlantPreset::MtmJ1,
        PlantPreset::MtmJ2,
        PlantPreset::MtmJ3,
        PlantPreset::MtmJ4,
        PlantPreset::MtmJ5,
        PlantPreset::MtmJ6,
        PlantPreset::MtmJ7,
        PlantPreset::PsmJ1,
        PlantPreset::PsmJ2,
        PlantPreset::PsmJ3,
        PlantPreset::PsmJ4,
        PlantPreset::PsmJ5,
        PlantPreset::PsmJ6,
        PlantPreset::PsmJ7,
        PlantPreset::EcmJ1,
        PlantPreset::EcmJ2,
        PlantPreset::EcmJ3,
        PlantPreset::EcmJ4,
        PlantPreset::MtmGripper,
        PlantPreset::Generic,
    ];

    /// The name used in the files (`"mtm_j1"`, ..., `"generic"`).
    pub fn name(self) -> &'static str {
        const NAMES: [&str; 20] = [
            "mtm_j1",
            "mtm_j2",
            "mtm_j3",
            "mtm_j4",
            "mtm_j5",
            "mtm_j6",
            "mtm_j7",
            "psm_j1",
            "psm_j2",
            "psm_j3",
            "psm_j4",
            "psm_j5",
            "psm_j6",
            "psm_j7",
            "ecm_j1",
            "ecm_j2",
            "ecm_j3",
            "ecm_j4",
            "mtm_gripper",
            "generic",
        ];
        NAMES[self as usize]
    }

    /// The preset named `name`, if any.
    pub fn from_name(name: &str) -> Option<PlantPreset> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
}

/// One actuator seen from the whole file: where it is and what it is called.
#[derive(Debug, Clone, Copy)]
pub struct JointRef<'a> {
    /// Position in the flat joint list (robots in order, actuators in order).
    pub index: usize,
    /// Index of the robot in `robots`.
    pub robot_index: usize,
    /// Index of the actuator in its robot.
    pub actuator_index: usize,
    /// The robot.
    pub robot: &'a RobotConfig,
    /// The actuator.
    pub actuator: &'a ActuatorConfig,
    /// `robot[actuator_index]`, e.g. `MTML[3]`.
    pub label: Label,
}

impl RobotConfig {
    /// The dVRK arm this robot is: its `simulation.arm`, else what its name
    /// says.
    pub fn dvrk_arm(&self) -> Option<DvrkArm> {
        self.simulation
            .as_ref()
            .and_then(|s| s.arm)
            .or_else(|| DvrkArm::from_robot_name(&self.name))
    }

    /// Actuator positions from joint positions for the pots
    /// (`potentiometers.coupling`), if the robot has a usable coupling.
    pub fn pot_coupling(&self) -> Option<Matrix> {
        let m = self
            .potentiometers
            .as_ref()?
            .coupling
            .as_ref()?
            .joint_to_actuator()?;
        (m.size() == self.actuators.len()).then_some(m)
    }
}

impl<'a> JointRef<'a> {
    /// The v6 pot tolerance of this actuator, if the robot lists one.
    pub fn potentiometer_tolerance(&self) -> Option<&'a PotentiometerTolerance> {
        self.robot
            .potentiometers
            .as_ref()?
            .tolerances
            .iter()
            .find(|t| t.axis_id == self.actuator_index)
    }
}

/// One board used by the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardUse {
    /// Board ID.
    pub board_id: u8,
    /// Board type.
    pub hardware: HardwareVersion,
    /// Bit *i* set: axis *i* drives an actuator.
    pub axes_used: u16,
    /// Name of the (first) robot using it.
    pub robot: Label,
}

impl IoConfig {
    /// Reads, parses and validates the file at `path`.
    ///
    /// # Errors
    /// Every problem found, each naming the file, the JSON path and what is
    /// wrong: the file cannot be read, bad JSON syntax, a wrong type or
    /// missing field (only the first such error: parsing stops there), or
    /// any number of validation failures.
    pub fn load(path: impl AsRef<Path>) -> Result<IoConfig, ConfigErrors> {
        Self::load_with_warnings(path).map(|l| l.config)
    }

    /// [`IoConfig::load`], with what the loader accepted but the program
    /// should tell its user once (see [`Loaded`]).
    ///
    /// # Errors
    /// As [`IoConfig::load`].
    pub fn load_with_warnings(path: impl AsRef<Path>) -> Result<Loaded, ConfigErrors> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            ConfigErrors::one(ConfigError::new(&file, "", Problem::Io(e.to_string())))
        })?;
        Self::from_json_str_with_warnings(&text, &file)
    }

    /// Parses and validates `text`; `file` names it in errors.
    ///
    /// # Errors
    /// As [`IoConfig::load`], without the read error.
    pub fn from_json_str(text: &str, file: &str) -> Result<IoConfig, ConfigErrors> {
        Self::from_json_str_with_warnings(text, file).map(|l| l.config)
    }

    /// [`IoConfig::from_json_str`] with its warnings.
    ///
    /// # Errors
    /// As [`IoConfig::from_json_str`].
    pub fn from_json_str_with_warnings(text: &str, file: &str) -> Result<Loaded, ConfigErrors> {
        let loaded = Self::parse_with_warnings(text, file)?;
        loaded.config.validate(file)?;
        Ok(loaded)
    }

    /// Parses `text` without the validation rules (for tools that want to
    /// repair a file).
    ///
    /// # Errors
    /// The first syntax or type error, with its JSON path.
    pub fn parse_unvalidated(text: &str, file: &str) -> Result<IoConfig, ConfigErrors> {
        Self::parse_with_warnings(text, file).map(|l| l.config)
    }

    /// Parses `text`: the keys Firelink knows into the configuration
    /// (a malformed value is an error naming its path), every other key
    /// into a warning, and whatever the dVRK console's reader would refuse
    /// ([`console::check`]) into warnings too.
    fn parse_with_warnings(text: &str, file: &str) -> Result<Loaded, ConfigErrors> {
        let syntax = |e: serde_json::Error| {
            ConfigErrors::one(ConfigError::new(file, "", Problem::Syntax(e.to_string())))
        };
        // The document as JSON first: a syntax error is reported as one,
        // and the console's schema is checked on what the file says.
        let value: serde_json::Value = serde_json::from_str(text).map_err(syntax)?;
        let mut ignored: Vec<String> = Vec::new();
        let mut de = serde_json::Deserializer::from_str(text);
        let config: IoConfig = {
            let mut note = |path: serde_ignored::Path<'_>| ignored.push(json_path(&path));
            let tracked = serde_ignored::Deserializer::new(&mut de, &mut note);
            serde_path_to_error::deserialize(tracked)
                .map_err(|e| ConfigErrors::one(ConfigError::from_serde(file, e)))?
        };
        de.end().map_err(syntax)?;
        let mut warnings: Vec<ConfigWarning> = ignored
            .into_iter()
            .map(|path| ConfigWarning::new(file, path, Warning::Ignored))
            .collect();
        if value.get("$id").is_none() {
            warnings.push(ConfigWarning::new(file, "$id", Warning::NoSchemaId));
        }
        warnings.extend(console::check(&value).into_iter().map(|issue| {
            ConfigWarning::new(file, issue.path.clone(), Warning::Console(issue.problem))
        }));
        Ok(Loaded { config, warnings })
    }

    /// Checks every rule; see [`Problem`] for the list.
    ///
    /// # Errors
    /// All broken rules, in file order.
    pub fn validate(&self, file: &str) -> Result<(), ConfigErrors> {
        validate::validate(self, file)
    }

    /// This configuration as pretty-printed JSON (4-space indent, a final
    /// newline), the format of the shipped files.
    pub fn to_json_pretty(&self) -> String {
        let mut out = Vec::new();
        let fmt = serde_json::ser::PrettyFormatter::with_indent(b"    ");
        let mut ser = serde_json::Serializer::with_formatter(&mut out, fmt);
        // Serialising plain data into memory cannot fail.
        let _ = self.serialize(&mut ser);
        let mut s = String::from_utf8(out).unwrap_or_default();
        s.push('\n');
        s
    }

    /// Every actuator in joint order (robots in order, actuators in order).
    pub fn joints(&self) -> impl Iterator<Item = JointRef<'_>> {
        self.robots
            .iter()
            .enumerate()
            .flat_map(|(ri, robot)| {
                robot
                    .actuators
                    .iter()
                    .enumerate()
                    .map(move |(ai, actuator)| (ri, robot, ai, actuator))
            })
            .enumerate()
            .map(
                |(index, (robot_index, robot, actuator_index, actuator))| JointRef {
                    index,
                    robot_index,
                    actuator_index,
                    robot,
                    actuator,
                    label: Label::joint(&robot.name, actuator_index),
                },
            )
    }

    /// Number of actuators over all robots.
    pub fn actuator_count(&self) -> usize {
        self.robots.iter().map(|r| r.actuators.len()).sum()
    }

    /// How many boards a rig must emulate for this configuration: board
    /// IDs 0 up to the highest one used by an actuator, a brake, a digital
    /// input or output or a Dallas chip.
    pub fn board_slots(&self) -> usize {
        self.boards()
            .iter()
            .map(|b| b.board_id)
            .chain(self.other_boards())
            .map(|id| usize::from(id) + 1)
            .max()
            .unwrap_or(0)
    }

    /// Board IDs the v6 sections kept as JSON name (brakes, digital inputs
    /// and outputs, Dallas chips), in file order, repeats included.
    fn other_boards(&self) -> impl Iterator<Item = u8> + '_ {
        let brakes = self
            .robots
            .iter()
            .filter_map(|r| r.brakes.as_ref())
            .flatten()
            .map(|b| b.board_id);
        let inputs = self.digital_inputs.iter().flatten().map(|d| d.board_id);
        let lists = self
            .digital_outputs
            .iter()
            .chain(self.dallas_chips.as_ref());
        let others = lists
            .filter_map(serde_json::Value::as_array)
            .flatten()
            .filter_map(|item| item.get("board_id")?.as_u64())
            .filter_map(|id| u8::try_from(id).ok());
        brakes
            .chain(inputs)
            .chain(others)
            .filter(|&id| id <= MAX_BOARD_ID)
    }

    /// The serial numbers a robot's `simulation.boards` gives board
    /// `board_id`, if any robot gives them.
    pub fn board_serial(&self, board_id: u8) -> Option<&BoardSerial> {
        self.robots
            .iter()
            .filter_map(|r| r.simulation.as_ref())
            .flat_map(|s| &s.boards)
            .find(|b| b.board_id == board_id)
            .map(|b| &b.serial)
    }

    /// The simulation settings of board `board_id`, if a robot gives any.
    pub fn board_simulation(&self, board_id: u8) -> Option<&BoardSimulation> {
        self.robots
            .iter()
            .filter_map(|r| r.simulation.as_ref())
            .flat_map(|s| &s.boards)
            .find(|b| b.board_id == board_id)
    }

    /// The v6 digital input named `name`.
    pub fn digital_input(&self, name: &str) -> Option<&DigitalInputConfig> {
        self.digital_inputs
            .iter()
            .flatten()
            .find(|d| d.name == name)
    }

    /// Whether the digital input named `name` reads pressed in its
    /// board's DIGIN word `digin` (the dVRK's rule,
    /// [`DigitalInputConfig::is_pressed`]); `None` for no such input.
    pub fn input_pressed(&self, name: &str, digin: u32) -> Option<bool> {
        self.digital_input(name).map(|d| d.is_pressed(digin))
    }

    /// The boards in use, by ascending ID.
    pub fn boards(&self) -> Vec<BoardUse> {
        let mut boards: Vec<BoardUse> = Vec::new();
        for robot in &self.robots {
            for a in &robot.actuators {
                let bit = if a.axis_id < 16 { 1u16 << a.axis_id } else { 0 };
                match boards.iter_mut().find(|b| b.board_id == a.board_id) {
                    Some(b) => b.axes_used |= bit,
                    None => boards.push(BoardUse {
                        board_id: a.board_id,
                        hardware: robot.hardware_version,
                        axes_used: bit,
                        robot: Label::new(&robot.name),
                    }),
                }
            }
        }
        boards.sort_by_key(|b| b.board_id);
        boards
    }

    /// The boards the robots drive as a mask (the broadcast query's board
    /// mask): their actuators' and their brakes' boards.
    pub fn board_set(&self) -> BoardSet {
        let brakes = self
            .robots
            .iter()
            .flat_map(|r| r.brakes.iter().flatten())
            .map(|b| b.board_id);
        self.joints()
            .map(|j| j.actuator.board_id)
            .chain(brakes)
            .filter(|&id| id <= MAX_BOARD_ID)
            .collect()
    }

    /// The robot named `name`.
    pub fn robot(&self, name: &str) -> Option<&RobotConfig> {
        self.robots.iter().find(|r| r.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plant_names_match_serde() {
        for p in PlantPreset::ALL {
            assert_eq!(PlantPreset::from_name(p.name()), Some(p));
            let json = serde_json::to_string(&p).unwrap();
            assert_eq!(json, format!("\"{}\"", p.name()));
        }
        assert_eq!(PlantPreset::from_name("mtm_j8"), None);
    }

    #[test]
    fn hardware_versions() {
        assert_eq!(HardwareVersion::default(), HardwareVersion::Qla1);
        assert_eq!(HardwareVersion::Dqla.axes(), 8);
        assert_eq!(HardwareVersion::Dra1.name(), "dRA1");
        assert_eq!(HardwareVersion::Qla1.hw_version_register(), 0x514C_4131);
        let v: HardwareVersion = serde_json::from_str("\"DQLA\"").unwrap();
        assert_eq!(v, HardwareVersion::Dqla);
    }
}
