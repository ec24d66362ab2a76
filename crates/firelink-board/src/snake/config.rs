//! What a Snake node is: its rotary-switch ID, the seven channels' plants
//! and digital pots, the amplifier circuit, the version register, the
//! noise seed.

use super::channel::{AmplifierModel, DigitalPot};
use crate::plant::{AxisParams, presets};
use crate::time::SimDuration;
use firelink_wire::snake::CHANNELS;

/// The ADC's conversion time (§6.2: "roughly 2 us"): a new node's plant
/// step, so each conversion samples a plant advanced to that instant.
pub const ADC_CONVERSION_TIME: SimDuration = SimDuration::from_micros(2);

/// The version register of the emulated firmware: "SNK" and revision 2
/// (seed 001's final revision, §5.4).
pub const SNAKE_VERSION: u32 = firelink_wire::snake::registers::VERSION;

/// Everything that makes one emulated Snake node.
#[derive(Debug, Clone, PartialEq)]
pub struct SnakeNodeConfig {
    /// Rotary-switch board ID, 0..=15 (higher values are cut to 4 bits).
    pub board_id: u8,
    /// The plant behind each channel, channel 1 first; missing channels
    /// have no motor, extra entries are ignored.
    pub channels: Vec<AxisParams>,
    /// Each channel's digital pot at power-up (missing: the default, the
    /// nominal wiper, torque mode, write-protected, EEPROM zeros).
    pub pots: Vec<DigitalPot>,
    /// The amplifier circuit of every channel.
    pub amplifier: AmplifierModel,
    /// The version register.
    pub version: u32,
    /// Seed of the measurement noise.
    pub seed: u64,
    /// Plant integration step (default: the ADC's 2 us conversion time,
    /// so that every conversion samples a fresh plant state).
    pub plant_step: SimDuration,
}

impl SnakeNodeConfig {
    /// A node with generic motors on all seven channels, seed 0.
    pub fn new(board_id: u8) -> SnakeNodeConfig {
        SnakeNodeConfig {
            board_id: board_id & 0xF,
            channels: vec![presets::generic_motor(); CHANNELS],
            pots: Vec::new(),
            amplifier: AmplifierModel::default(),
            version: SNAKE_VERSION,
            seed: 0,
            plant_step: ADC_CONVERSION_TIME,
        }
    }

    /// The same node with these channel plants (channel 1 first).
    pub fn with_channels(mut self, channels: Vec<AxisParams>) -> SnakeNodeConfig {
        self.channels = channels;
        self
    }

    /// The same node with this noise seed.
    pub fn with_seed(mut self, seed: u64) -> SnakeNodeConfig {
        self.seed = seed;
        self
    }

    /// Exactly seven plants: the configured ones, then unused channels.
    pub fn plant_axes(&self) -> Vec<AxisParams> {
        let mut axes: Vec<AxisParams> = self.channels.iter().take(CHANNELS).cloned().collect();
        axes.resize(CHANNELS, presets::unused_channel());
        axes
    }
}
