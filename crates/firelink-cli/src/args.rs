//! Every value the command line accepts, checked at the boundary by clap:
//! the number rules are [`firelink_testbed::limits`] (out of range, not
//! finite or not a number is a usage error, exit status 2, with one line
//! naming the option, the value and the range); the named choices
//! (firmware, FPGA, hardware) are the enums here; the protocol and the UDP
//! wait are the host library's own (`firelink_host::scan::Protocol`,
//! `firelink_host::udp::WaitMode`, clap's `ValueEnum` behind its `clap`
//! feature).

use clap::ValueEnum;
use firelink_testbed::emulated::{FpgaVersion, Hardware, Profile};
pub use firelink_testbed::limits::{
    CpuLatencyRequest as CpuLatencyArg, WatchdogSetting, board_count, board_id, can_cycles,
    cpu_latency, cycles, mahru_period_us, measured, node_id, parse_number, period_us, probability,
    quadlets, rate_hz, rate_hz_or_max, run_seconds, seconds_or_forever, timeout_ms, timings,
    wait_us, watchdog,
};

/// `--firmware` (and `sim --profile`): the emulated boards' firmware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FirmwareArg {
    /// Seed 000's firmware: fixed TDMA slots, 0xFFFF for a corrupt query.
    Seed,
    /// Firmware Rev 7: chained broadcasts.
    #[value(alias = "7")]
    Rev7,
    /// Firmware Rev 8: chained broadcasts, MOTOR_STATUS, write-block header.
    #[value(alias = "8")]
    Rev8,
    /// Firmware Rev 9: Rev 8's blocks, GIT_DESC, the FPGA V3 Ethernet status.
    #[value(alias = "9")]
    Rev9,
}

impl From<FirmwareArg> for Profile {
    fn from(f: FirmwareArg) -> Profile {
        match f {
            FirmwareArg::Seed => Profile::Seed,
            FirmwareArg::Rev7 => Profile::Rev7,
            FirmwareArg::Rev8 => Profile::Rev8,
            FirmwareArg::Rev9 => Profile::Rev9,
        }
    }
}

/// `--fpga`: the FPGA board generation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FpgaArg {
    /// FPGA V2: Spartan-6, one 100 Mb/s Ethernet port (the bridge).
    #[value(name = "V2", alias = "v2", alias = "2")]
    V2,
    /// FPGA V3: Zynq, two 1 Gb/s Ethernet ports (RTL8211F PHYs).
    #[value(name = "V3", alias = "v3", alias = "3")]
    V3,
}

impl From<FpgaArg> for FpgaVersion {
    fn from(f: FpgaArg) -> FpgaVersion {
        match f {
            FpgaArg::V2 => FpgaVersion::V2,
            FpgaArg::V3 => FpgaVersion::V3,
        }
    }
}

/// `--hardware`: the companion board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HardwareArg {
    /// Quad linear amplifier: 4 axes.
    #[value(name = "QLA1", alias = "qla1", alias = "QLA", alias = "qla")]
    Qla1,
    /// Dual QLA: 8 axes.
    #[value(name = "DQLA", alias = "dqla")]
    Dqla,
}

impl From<HardwareArg> for Hardware {
    fn from(h: HardwareArg) -> Hardware {
        match h {
            HardwareArg::Qla1 => Hardware::Qla1,
            HardwareArg::Dqla => Hardware::Dqla,
        }
    }
}

/// Whether the default run should be quiet about progress (tests).
pub fn quiet() -> bool {
    std::env::var_os("FIRELINK_QUIET").is_some()
}
