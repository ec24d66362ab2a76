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
    /// block layouts are those of Rev 7 (FW_VERSION reads 7), or with
    /// [`BoardConfig::with_firmware`]`(FirmwareRev::Rev4)` those of seed
    /// 000's own firmware (48-byte blocks, slots counted in FPGA clocks).
    Seed,
    /// Firmware Rev 7: Rev 7 block layouts, chained broadcasts, the hub
    /// header keeps the full sequence.
    Rev7,
    /// Firmware Rev 8: MOTOR_STATUS block, write-block header, amplifier
    /// enables in the DAC word, hub headers with a sequence-error bit.
    Rev8,
}

impl Profile {
    /// Every profile, oldest first.
    pub const ALL: [Profile; 3] = [Profile::Seed, Profile::Rev7, Profile::Rev8];

    /// `seed`, `rev7` or `rev8`: the name on command lines and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Seed => "seed",
            Profile::Rev7 => "rev7",
            Profile::Rev8 => "rev8",
        }
    }

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
    /// Firmware profile: the behaviour (slot timing, sequence rule,
    /// Rev 8 registers).
    pub profile: Profile,
    /// The firmware revision FW_VERSION reports, which selects the block
    /// layouts: the profile's ([`Profile::firmware_rev`]) unless changed
    /// with [`with_firmware`](Self::with_firmware).
    pub firmware: FirmwareRev,
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
}

impl BoardConfig {
    /// A board with generic motors on every axis, FPGA V2, seed 0.
    pub fn new(board_id: u8, hardware: Hardware, profile: Profile) -> BoardConfig {
        BoardConfig {
            board_id: board_id & 0xF,
            hardware,
            profile,
            firmware: profile.firmware_rev(),
            fpga: FpgaVersion::V2,
            git_desc: 0x0F1E_1140,
            axes: vec![presets::generic_motor(); hardware.axes()],
            seed: 0,
            plant_step: DEFAULT_STEP,
            motor_supply_present: true,
            supply_rise: TimeDelta::from_millis(5),
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

    /// The same board reporting firmware `firmware` and using its block
    /// layouts, e.g. the seed profile with [`FirmwareRev::Rev4`]: seed
    /// 000's own firmware, fixed TDMA slots and its 48-byte blocks.
    pub fn with_firmware(mut self, firmware: FirmwareRev) -> BoardConfig {
        self.firmware = firmware;
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
        let rev = self.firmware;
        match self.hardware {
            Hardware::Qla1 => BoardLayout::qla1(rev),
            Hardware::Dqla => BoardLayout::dqla(rev),
        }
    }

    /// Quadlets of the real-time read block (`fpga-board.md` section 4):
    /// Rev 7 `4 + M + 5E`, Rev 8 `4 + 2M + 5E`, Rev 4 `4 + M + E`.
    pub fn read_block_quadlets(&self) -> usize {
        self.layout().read_block_quadlets()
    }

    /// Quadlets of the real-time write block (`fpga-board.md` section 5):
    /// Rev 8 header + M DACs + control, Rev 7 M DACs + control, Rev 4 M
    /// DACs.
    pub fn write_block_quadlets(&self) -> usize {
        self.layout().write_block_quadlets()
    }
}
