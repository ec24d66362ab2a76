//! Typed codecs for the register quadlets of the board (`fpga-board.md` §2,
//! §3). Raw bits only: no physical units.
//!
//! Most registers are `u32` newtypes (every bit pattern is a valid raw
//! quadlet) whose bit fields each have a getter, a setter and a builder,
//! defined from one [`Field`](crate::field::Field) in the private `field`
//! module. Write-only command encodings that carry a choice (STATUS write,
//! PHY_CTRL, DIGITAL_OUT) also have a meaning type with `parse`/`to_word`.
//! Each register group lives in a private submodule (`status`, `phy`,
//! `watchdog`, `identity`, `digital_io`, `axis`) re-exported here.
//!
//! ```
//! use firelink_wire::qla::registers::{StatusCommand, StatusRead};
//! // The emulator builds STATUS; the host reads it.
//! let status = StatusRead::default().with_axes(4).with_board_id(3).with_amp_enabled(0b0101);
//! assert_eq!(status.raw(), 0x4300_0005);
//! // Turn motor power on (fpga-board.md §2: 0x000C0000).
//! assert_eq!(StatusCommand::power(true).to_word().raw(), 0x000C_0000);
//! ```

use core::net::Ipv4Addr;
use core::time::Duration;

use crate::error::{Error, Result};
use crate::open_enum::open_enum;
use crate::qla::{check_max, quadlet_register};

/// Bit fields of the register quadlets, each defined once
/// (`fpga-board.md` §2 and §3).
mod field {
    use crate::field::Field;

    // STATUS read (§2 "STATUS read").
    pub const STATUS_AXES: Field = Field::new(0, 31, 28);
    pub const STATUS_BOARD_ID: Field = Field::new(0, 27, 24);
    pub const STATUS_WATCHDOG_TIMEOUT: Field = Field::new(0, 23, 23);
    pub const STATUS_QUAD_DAC: Field = Field::new(0, 22, 22);
    pub const STATUS_DOUT_CHECKED: Field = Field::new(0, 21, 21);
    pub const STATUS_DOUT_BIDIRECTIONAL: Field = Field::new(0, 20, 20);
    pub const STATUS_MOTOR_SUPPLY_GOOD: Field = Field::new(0, 19, 19);
    pub const STATUS_MOTOR_POWER_ENABLED: Field = Field::new(0, 18, 18);
    pub const STATUS_RELAY_STATE: Field = Field::new(0, 17, 17);
    pub const STATUS_RELAY_ON: Field = Field::new(0, 16, 16);
    pub const STATUS_SUPPLY_FAULT: Field = Field::new(0, 15, 15);
    pub const STATUS_SAFETY_FEEDBACK: Field = Field::new(0, 14, 14);
    pub const STATUS_IO_EXPANDER: Field = Field::new(0, 12, 12);
    pub const STATUS_AMP_FAULT: Field = Field::new(0, 11, 8);
    pub const STATUS_SAFETY_AMP_DISABLE: Field = Field::new(0, 7, 4);
    pub const STATUS_AMP_ENABLED: Field = Field::new(0, 3, 0);

    // STATUS write (§2 "STATUS write").
    pub const WRITE_REBOOT: Field = Field::new(0, 21, 20);
    pub const WRITE_POWER_MASK: Field = Field::new(0, 19, 19);
    pub const WRITE_POWER_VALUE: Field = Field::new(0, 18, 18);
    pub const WRITE_RELAY_MASK: Field = Field::new(0, 17, 17);
    pub const WRITE_RELAY_VALUE: Field = Field::new(0, 16, 16);
    pub const WRITE_AMP_MASK: Field = Field::new(0, 11, 8);
    pub const WRITE_AMP_VALUE: Field = Field::new(0, 3, 0);
    /// The bits of a real-time block's control quadlet that take effect (§5).
    pub const WRITE_BLOCK_EFFECTIVE: Field = Field::new(0, 19, 0);

    // PHY_CTRL / PHY_DATA (§2).
    pub const PHY_CTRL_WRITE: Field = Field::new(0, 12, 12);
    pub const PHY_CTRL_REGISTER: Field = Field::new(0, 11, 8);
    pub const PHY_CTRL_DATA: Field = Field::new(0, 7, 0);
    pub const PHY_CTRL_READ_REGISTER: Field = Field::new(0, 3, 0);
    pub const PHY_DATA_REGISTER: Field = Field::new(0, 11, 8);
    pub const PHY_DATA_DATA: Field = Field::new(0, 7, 0);

    // WATCHDOG (§2).
    pub const WATCHDOG_TICKS: Field = Field::new(0, 15, 0);
    pub const WATCHDOG_LED: Field = Field::new(0, 31, 31);

    // TEMPERATURE (§2).
    pub const TEMPERATURE_UPPER: Field = Field::new(0, 15, 8);
    pub const TEMPERATURE_LOWER: Field = Field::new(0, 7, 0);

    // DIGITAL_OUT write and read (extras §3).
    pub const DOUT_PLAY: Field = Field::new(0, 31, 31);
    pub const DOUT_MASK: Field = Field::new(0, 11, 8);
    pub const DOUT_RAW: Field = Field::new(0, 3, 0);
    pub const DOUT_TABLE_ACTIVE: Field = Field::new(0, 31, 31);
    pub const DOUT_TABLE_VALID: Field = Field::new(0, 30, 30);
    pub const DOUT_TABLE_INDEX: Field = Field::new(0, 25, 16);
    pub const DOUT_EXTRA_IO: Field = Field::new(0, 11, 8);

    // DOUT_CTRL, axis offset 8 (extras §3).
    pub const DOUT_CTRL_HIGH: Field = Field::new(0, 31, 16);
    pub const DOUT_CTRL_LOW: Field = Field::new(0, 15, 0);

    // Waveform table entry (extras §3).
    pub const WAVE_VALID: Field = Field::new(0, 31, 31);
    pub const WAVE_END_COUNT: Field = Field::new(0, 30, 8);
    pub const WAVE_OUTPUTS: Field = Field::new(0, 7, 0);

    // DIGITAL_IN (§2).
    pub const DIN_V_FAULT: Field = Field::new(0, 31, 31);
    pub const DIN_WAVEFORM: Field = Field::new(0, 29, 29);
    pub const DIN_SUPPLY_COMPARATOR: Field = Field::new(0, 28, 28);
    pub const DIN_ENC_A: Field = Field::new(0, 27, 24);
    pub const DIN_ENC_B: Field = Field::new(0, 23, 20);
    pub const DIN_INDEX: Field = Field::new(0, 19, 16);
    pub const DIN_OUTPUTS: Field = Field::new(0, 15, 12);
    pub const DIN_NEG_LIMITS: Field = Field::new(0, 11, 8);
    pub const DIN_POS_LIMITS: Field = Field::new(0, 7, 4);
    pub const DIN_HOME: Field = Field::new(0, 3, 0);

    // ETH_STATUS (§2).
    pub const ETH_V2: Field = Field::new(0, 31, 31);
    pub const ETH_VERSION_BITS: Field = Field::new(0, 31, 30);

    // GIT_DESC (§2).
    pub const GIT_COMMIT: Field = Field::new(0, 31, 4);
    pub const GIT_DIRTY: Field = Field::new(0, 3, 3);

    // ADC (§3).
    pub const ADC_POT: Field = Field::new(0, 31, 16);
    pub const ADC_CURRENT: Field = Field::new(0, 15, 0);

    // DAC (§3).
    pub const DAC_VALID: Field = Field::new(0, 31, 31);
    pub const DAC_AMP_ENABLE_MASK: Field = Field::new(0, 29, 29);
    pub const DAC_AMP_ENABLE: Field = Field::new(0, 28, 28);
    pub const DAC_BOARD_ID: Field = Field::new(0, 27, 24);
    pub const DAC_CONTROL_MODE: Field = Field::new(0, 27, 24);
    pub const DAC_COMMAND: Field = Field::new(0, 15, 0);

    // ENC_PRELOAD / ENC_POSITION (§3).
    pub const ENC_COUNT: Field = Field::new(0, 23, 0);
    pub const ENC_OVERFLOW: Field = Field::new(0, 24, 24);
    pub const ENC_INDEX: Field = Field::new(0, 30, 30);
    pub const ENC_B: Field = Field::new(0, 29, 29);
    pub const ENC_A: Field = Field::new(0, 28, 28);

    // ENC_PERIOD, ENC_QTR1/5, ENC_RUN (§3).
    pub const ENC_TIME: Field = Field::new(0, 25, 0);
    pub const ENC_TIME_OVERFLOW: Field = Field::new(0, 31, 31);
    pub const ENC_DIRECTION: Field = Field::new(0, 30, 30);
    pub const ENC_DIRECTION_CHANGED: Field = Field::new(0, 29, 29);
    pub const ENC_ERROR: Field = Field::new(0, 28, 28);
    pub const ENC_PARTIAL: Field = Field::new(0, 27, 27);
    pub const ENC_EDGES: Field = Field::new(0, 29, 26);

    // MOTOR_CONFIG (§3).
    pub const MCFG_DISABLE_SAFETY: Field = Field::new(0, 31, 31);
    pub const MCFG_FORCE_DISABLE: Field = Field::new(0, 30, 30);
    pub const MCFG_VOLTAGE_MODE: Field = Field::new(0, 25, 25);
    pub const MCFG_CURRENT_MODE: Field = Field::new(0, 24, 24);
    pub const MCFG_ENABLE_DELAY: Field = Field::new(0, 23, 16);
    pub const MCFG_CURRENT_LIMIT: Field = Field::new(0, 15, 0);

    // MOTOR_STATUS (§3).
    pub const MSTAT_AMP_ON: Field = Field::new(0, 29, 29);
    pub const MSTAT_AMP_REQUESTED: Field = Field::new(0, 28, 28);
    pub const MSTAT_CONTROL_MODE: Field = Field::new(0, 27, 24);
    pub const MSTAT_CURRENT_CONTROL: Field = Field::new(0, 20, 20);
    pub const MSTAT_SAFETY_DISABLE: Field = Field::new(0, 17, 17);
    pub const MSTAT_AMP_FAULT: Field = Field::new(0, 16, 16);
    pub const MSTAT_CURRENT_COMMAND: Field = Field::new(0, 15, 0);
}

mod axis;
mod digital_io;
mod identity;
mod phy;
mod status;
mod watchdog;

pub use axis::*;
pub use digital_io::*;
pub use identity::*;
pub use phy::*;
pub use status::*;
pub use watchdog::*;
