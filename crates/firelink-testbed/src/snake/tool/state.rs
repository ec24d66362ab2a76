//! What the tool commands on a channel, how its readouts convert to
//! units, and the state file that keeps both.

use serde::{Deserialize, Serialize};

use firelink_control::config::{IoConfig, JointType};
use firelink_wire::snake::analog;
use firelink_wire::snake::registers::{DAC_MIDPOINT, Wiper};

/// Format version of the state files.
pub const STATE_VERSION: u32 = 1;

/// How a channel's readouts convert to units (Fig. 19's "Conversion
/// Factors" tab).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Factors {
    /// Encoder: units per count.
    pub encoder_per_count: f64,
    /// Encoder unit ("deg", "mm").
    pub encoder_unit: String,
    /// Potentiometer: units per volt.
    pub pot_per_volt: f64,
    /// Potentiometer: units at 0 V.
    pub pot_offset: f64,
    /// Potentiometer unit.
    pub pot_unit: String,
}

impl Default for Factors {
    /// Motor-side degrees of a 2048-count encoder; the pot in volts.
    fn default() -> Self {
        Factors {
            encoder_per_count: 360.0 / 2048.0,
            encoder_unit: "deg".into(),
            pot_per_volt: 1.0,
            pot_offset: 0.0,
            pot_unit: "V".into(),
        }
    }
}

impl Factors {
    /// The factors a configuration gives the actuator on `(board, axis)`:
    /// joint degrees (or millimetres) per count and per volt.
    pub fn from_config(config: &IoConfig, board: u8, axis: u8) -> Option<Factors> {
        let j = config
            .joints()
            .find(|j| j.actuator.board_id == board && j.actuator.axis_id == axis)?;
        let a = j.actuator;
        let (scale, unit) = if a.joint_type == Some(JointType::Prismatic) {
            (1e3, "mm")
        } else {
            (180.0 / std::f64::consts::PI, "deg")
        };
        let pot = a.potentiometer?.voltage_to_position;
        Some(Factors {
            encoder_per_count: scale * a.encoder.bits_to_position.scale,
            encoder_unit: unit.into(),
            pot_per_volt: scale * pot.scale,
            pot_offset: scale * pot.offset,
            pot_unit: unit.into(),
        })
    }
}

/// One channel as the tool sets it and as a state file keeps it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelState {
    /// Board ID of the node.
    pub board: u8,
    /// Channel 1..=7.
    pub channel: u8,
    /// Amplifier enabled.
    pub enabled: bool,
    /// Motor DAC code.
    pub motor_code: u16,
    /// Current-limit DAC code.
    pub current_limit_code: u16,
    /// Digital pot wiper.
    pub wiper: u16,
    /// Torque (false) or speed (true) mode: pot output O1.
    pub speed_mode: bool,
    /// Pot output O2.
    pub o2: bool,
    /// EEPROM write protection.
    pub write_protect: bool,
    /// The 14 EEPROM words.
    pub eeprom: Vec<u16>,
    /// Conversion factors.
    pub factors: Factors,
}

impl ChannelState {
    /// "Send Defaults": disabled, motor at the midpoint, a 100 mA limit,
    /// the nominal wiper, torque mode, write-protected, EEPROM untouched.
    pub(super) fn defaults(board: u8, channel: u8, factors: Factors) -> ChannelState {
        ChannelState {
            board,
            channel,
            enabled: false,
            motor_code: DAC_MIDPOINT,
            current_limit_code: analog::limit_code(0.1),
            wiper: Wiper::NOMINAL.value(),
            speed_mode: false,
            o2: false,
            write_protect: true,
            eeprom: Vec::new(),
            factors,
        }
    }
}

/// A state file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateFile {
    /// [`STATE_VERSION`].
    pub version: u32,
    /// Every channel of every node.
    pub channels: Vec<ChannelState>,
}
