//! What a board is: its identity (board ID, companion board, firmware
//! profile, FPGA version, git description), its plant and its seed.
//!
//! ```
//! use firelink_board::config::{BoardConfig, Hardware, Profile};
//! use firelink_board::plant::presets::{arm_axes, Arm};
//! let cfg = BoardConfig::new(6, Hardware::Qla1, Profile::Rev8)
//!     .with_axes(arm_axes(Arm::Psm, 0, 4))
//!     .with_seed(42);
//! assert_eq!(cfg.hardware.axes(), 4);
//! assert_eq!(cfg.read_block_quadlets(), 32);
//! ```

use firelink_wire::board::realtime::{BoardLayout, FirmwareRev};
pub use firelink_wire::board::registers::FpgaVersion;
use firelink_wire::board::registers::HardwareVersion;

use crate::plant::{AxisParams, DEFAULT_STEP, presets};
use crate::time::TimeDelta;

/// Which firmware behaviour a board reproduces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Profile {
    /// The seed-000 era broadcast firmware: fixed TDMA slots of about
    /// 5.2 us x node ID (+ ~3 us) after the query, every board answering;
    /// a corrupt query is answered with sequence `0xFFFF`. Register and
    /// block layouts are those of Rev 7 (FW_VERSION reads 7).
    Seed,
    /// Firmware Rev 7: Rev 7 block layouts, chained broadcasts, the hub
    /// header keeps the full sequence.
    Rev7,
    /// Firmware Rev 8: MOTOR_STATUS block, write-block header, amplifier
    /// enables in the DAC word, hub headers with a sequence-error bit.
    Rev8,
}

impl Profile {
    /// The firmware revision reported in FW_VERSION, which also selects
    /// the block layouts.
    pub fn firmware_rev(self) -> FirmwareRev {
        match self {
            Profile::Seed | Profile::Rev7 => FirmwareRev::Rev7,
            Profile::Rev8 => FirmwareRev::Rev8,
        }
    }

    /// Whether the Rev 8 layouts and registers apply.
    pub fn is_rev8(self) -> bool {
        self == Profile::Rev8
    }
}

/// The companion (amplifier) board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Hardware {
    /// Quad linear amplifier: 4 axes.
    Qla1,
    /// Dual QLA: 8 axes.
    Dqla,
}

impl Hardware {
    /// Number of axes (motors and encoders).
    pub fn axes(self) -> usize {
        match self {
            Hardware::Qla1 => 4,
            Hardware::Dqla => 8,
        }
    }

    /// The HW_VERSION register (`fpga-board.md` section 2).
    pub fn hardware_version(self) -> HardwareVersion {
        match self {
            Hardware::Qla1 => HardwareVersion::Qla1,
            Hardware::Dqla => HardwareVersion::Dqla,
        }
    }
}

/// Everything that makes one emulated board.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardConfig {
    /// Rotary-switch board ID, 0..=15 (higher values are cut to 4 bits).
    pub board_id: u8,
    /// Companion board.
    pub hardware: Hardware,
    /// Firmware profile.
    pub profile: Profile,
    /// FPGA generation.
    pub fpga: FpgaVersion,
    /// GIT_DESC register: short commit id in bits 31:4, dirty in bit 3.
    pub git_desc: u32,
    /// One parameter set per axis; missing ones are generic motors, extra
    /// ones are ignored.
    pub axes: Vec<AxisParams>,
    /// Seed of the measurement noise.
    pub seed: u64,
    /// Plant integration step.
    pub plant_step: TimeDelta,
    /// Whether the motor supply is connected (false: power never becomes
    /// good and STATUS shows a supply fault once power is enabled).
    pub motor_supply_present: bool,
    /// Time from power enable to motor supply good.
    pub supply_rise: TimeDelta,
    /// Digital input lines held high by what is plugged into the board
    /// (DIGIN bits 11:0: home switches 3:0, positive limits 7:4, negative
    /// limits 11:8), on top of the plant's own switches: e.g. the contacts
    /// that tell a dVRK PSM its sterile adapter and instrument are in.
    pub input_lines: u16,
    /// The instrument (tool) whose 1-wire memory this board's Dallas
    /// interface reads, if one is in.
    pub instrument: Option<Instrument>,
}

/// An instrument (a da Vinci tool) as its 1-wire memory (DS2505, 2 KiB)
/// describes it (`fpga-board-extras.md` section 4).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Instrument {
    /// Model number, e.g. 400006 (Classic Large Needle Driver).
    pub model: u32,
    /// Version byte.
    pub version: u8,
    /// Name, e.g. `LARGE_NEEDLE_DRIVER` (at most 27 bytes are stored).
    pub name: String,
}

impl Instrument {
    /// Size of the 1-wire memory, bytes.
    pub const MEMORY_BYTES: usize = 2048;
    /// Where the model number is stored (big-endian 32 bits).
    pub const MODEL_AT: usize = 0xA4;
    /// Where the version byte is stored.
    pub const VERSION_AT: usize = 0xA8;
    /// Where the NUL-terminated name starts.
    pub const NAME_AT: usize = 0x160;
    /// Where the name field ends (exclusive).
    pub const NAME_END: usize = 0x17C;

    /// The memory image: `997` at the start (the tag a dVRK host checks),
    /// the model, version and name at their offsets, erased (`0xFF`)
    /// elsewhere.
    pub fn memory_image(&self) -> Vec<u8> {
        fn put(m: &mut [u8], at: usize, bytes: &[u8]) {
            for (slot, b) in m.iter_mut().skip(at).zip(bytes) {
                *slot = *b;
            }
        }
        let mut m = vec![0xFF; Self::MEMORY_BYTES];
        put(&mut m, 0, b"997");
        put(&mut m, Self::MODEL_AT, &self.model.to_be_bytes());
        put(&mut m, Self::VERSION_AT, &[self.version]);
        // The name and its terminator stay inside the name field.
        let room = Self::NAME_END - Self::NAME_AT - 1;
        let name: Vec<u8> = self
            .name
            .bytes()
            .take(room)
            .chain(core::iter::once(0))
            .collect();
        put(&mut m, Self::NAME_AT, &name);
        m
    }
}

impl BoardConfig {
    /// A board with generic motors on every axis, FPGA V2, seed 0.
    pub fn new(board_id: u8, hardware: Hardware, profile: Profile) -> BoardConfig {
        BoardConfig {
            board_id: board_id & 0xF,
            hardware,
            profile,
            fpga: FpgaVersion::V2,
            git_desc: 0x0F1E_1140,
            axes: vec![presets::generic_motor(); hardware.axes()],
            seed: 0,
            plant_step: DEFAULT_STEP,
            motor_supply_present: true,
            supply_rise: TimeDelta::from_millis(5),
            input_lines: 0,
            instrument: None,
        }
    }

    /// The same board with these axes.
    pub fn with_axes(mut self, axes: Vec<AxisParams>) -> BoardConfig {
        self.axes = axes;
        self
    }

    /// The same board with axis `index` replaced (ignored out of range).
    pub fn with_axis(mut self, index: usize, params: AxisParams) -> BoardConfig {
        if let Some(slot) = self.axes.get_mut(index) {
            *slot = params;
        }
        self
    }

    /// The same board with another FPGA generation.
    pub fn with_fpga(mut self, fpga: FpgaVersion) -> BoardConfig {
        self.fpga = fpga;
        self
    }

    /// The same board with another noise seed.
    pub fn with_seed(mut self, seed: u64) -> BoardConfig {
        self.seed = seed;
        self
    }

    /// The same board with these digital input lines held high (DIGIN
    /// bits 11:0, see [`BoardConfig::input_lines`]).
    pub fn with_input_lines(mut self, lines: u16) -> BoardConfig {
        self.input_lines = lines & 0x0FFF;
        self
    }

    /// The same board with an instrument in.
    pub fn with_instrument(mut self, instrument: Option<Instrument>) -> BoardConfig {
        self.instrument = instrument;
        self
    }

    /// The same board with another GIT_DESC.
    pub fn with_git_desc(mut self, git_desc: u32) -> BoardConfig {
        self.git_desc = git_desc;
        self
    }

    /// The axes the plant gets: exactly `hardware.axes()` of them.
    pub(crate) fn plant_axes(&self) -> Vec<AxisParams> {
        (0..self.hardware.axes())
            .map(|i| {
                self.axes
                    .get(i)
                    .cloned()
                    .unwrap_or_else(presets::generic_motor)
            })
            .collect()
    }

    /// The real-time block layout: firmware revision, motors, encoders.
    pub fn layout(&self) -> BoardLayout {
        let rev = self.profile.firmware_rev();
        match self.hardware {
            Hardware::Qla1 => BoardLayout::qla1(rev),
            Hardware::Dqla => BoardLayout::dqla(rev),
        }
    }

    /// Quadlets of the real-time read block (`fpga-board.md` section 4):
    /// Rev 7 `4 + M + 5E`, Rev 8 `4 + 2M + 5E`.
    pub fn read_block_quadlets(&self) -> usize {
        self.layout().read_block_quadlets()
    }

    /// Quadlets of the real-time write block (`fpga-board.md` section 5):
    /// Rev 8 header + M DACs + control, Rev 7 M DACs + control.
    pub fn write_block_quadlets(&self) -> usize {
        self.layout().write_block_quadlets()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instrument_memory_image() {
        let tool = Instrument {
            model: 400_006,
            version: 12,
            name: "LARGE_NEEDLE_DRIVER".into(),
        };
        let m = tool.memory_image();
        assert_eq!(m.len(), Instrument::MEMORY_BYTES);
        assert_eq!(&m[..3], b"997");
        assert_eq!(&m[0xA4..0xA8], &400_006u32.to_be_bytes());
        assert_eq!(m[0xA8], 12);
        assert_eq!(&m[0x160..0x160 + 19], b"LARGE_NEEDLE_DRIVER");
        assert_eq!(m[0x160 + 19], 0);
        assert_eq!(m[3], 0xFF);
        // A long name is cut so its terminator stays in the field.
        let long = Instrument {
            name: "X".repeat(100),
            ..tool
        };
        let m = long.memory_image();
        assert_eq!(m[Instrument::NAME_END - 1], 0);
        assert_eq!(m[Instrument::NAME_END], 0xFF);
    }
}
