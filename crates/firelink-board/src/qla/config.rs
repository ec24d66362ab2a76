//! What a board is: its identity (board ID, companion board, firmware
//! profile, FPGA version, git description), its plant and its seed.
//!
//! ```
//! use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
//! use firelink_board::plant::presets::{arm_axes, Arm};
//! let cfg = BoardConfig::new(6, Hardware::Qla1, Profile::Rev8)
//!     .with_axes(arm_axes(Arm::Psm, 0, 4))
//!     .with_seed(42);
//! assert_eq!(cfg.hardware.axes(), 4);
//! assert_eq!(cfg.read_block_quadlets(), 32);
//! ```

use firelink_wire::qla::realtime::{BoardLayout, FirmwareRev};
pub use firelink_wire::qla::registers::FpgaVersion;
use firelink_wire::qla::registers::HardwareVersion;

use firelink_wire::qla::extras::{fpga_serial_image, qla_serial_image};

use crate::plant::{AxisParams, DEFAULT_STEP, presets};
pub use crate::qla::{BrakeLine, BrakeWire, Instrument};
use crate::time::SimDuration;

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
    /// Firmware Rev 9 (`rev9-fpga-v3.md`): Rev 8's registers and block
    /// layouts, plus GIT_DESC in register 15, the FPGA V3 Ethernet status
    /// format with the PS Ethernet enable, ACCESS_ERR reading 0, and the
    /// status broadcast asking for the bus with a priority-class request.
    /// On an FPGA V2 the board keeps the FireWire bridge.
    Rev9,
}

impl Profile {
    /// Every profile, oldest first.
    pub const ALL: [Profile; 4] = [Profile::Seed, Profile::Rev7, Profile::Rev8, Profile::Rev9];

    /// `seed`, `rev7`, `rev8` or `rev9`: the name on command lines and in
    /// reports.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Seed => "seed",
            Profile::Rev7 => "rev7",
            Profile::Rev8 => "rev8",
            Profile::Rev9 => "rev9",
        }
    }

    /// The firmware revision reported in FW_VERSION, which also selects
    /// the block layouts.
    pub fn firmware_rev(self) -> FirmwareRev {
        match self {
            Profile::Seed | Profile::Rev7 => FirmwareRev::Rev7,
            Profile::Rev8 => FirmwareRev::Rev8,
            Profile::Rev9 => FirmwareRev::Rev9,
        }
    }

    /// Whether the Rev 8 layouts and registers apply (Rev 8 and Rev 9).
    pub fn is_rev8(self) -> bool {
        matches!(self, Profile::Rev8 | Profile::Rev9)
    }

    /// Whether what Rev 9 added applies.
    pub fn is_rev9(self) -> bool {
        self == Profile::Rev9
    }

    /// The profile of a firmware revision number: 7, 8 or 9 (the seed
    /// profile has no number of its own).
    pub fn from_number(n: u32) -> Option<Profile> {
        match n {
            7 => Some(Profile::Rev7),
            8 => Some(Profile::Rev8),
            9 => Some(Profile::Rev9),
            _ => None,
        }
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

    /// From its name: `QLA1` (or `QLA`) or `DQLA`, any case.
    pub fn from_name(name: &str) -> Option<Hardware> {
        match name.to_ascii_uppercase().as_str() {
            "QLA1" | "QLA" => Some(Hardware::Qla1),
            "DQLA" => Some(Hardware::Dqla),
            _ => None,
        }
    }

    /// The FPGA a board with this companion has unless told otherwise: V2
    /// for a QLA1, V3 for a DQLA.
    pub fn default_fpga(self) -> FpgaVersion {
        match self {
            Hardware::Qla1 => FpgaVersion::V2,
            Hardware::Dqla => FpgaVersion::V3,
        }
    }

    /// Whether the firmware is built for this companion on `fpga`: a DQLA
    /// only on FPGA V3 (`FPGA1394V3-DQLA.v`; there is no V2 DQLA image).
    pub fn fits(self, fpga: FpgaVersion) -> bool {
        self != Hardware::Dqla || fpga == FpgaVersion::V3
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
    /// The register exists from firmware Rev 9 on (BoardRegs.v): Rev 4,
    /// 7 and 8 boards read 0 at register 15 whatever this says.
    pub git_desc: u32,
    /// One parameter set per axis; missing ones are generic motors, extra
    /// ones are ignored.
    pub axes: Vec<AxisParams>,
    /// Seed of the measurement noise.
    pub seed: u64,
    /// Plant integration step.
    pub plant_step: SimDuration,
    /// Whether the motor supply is connected (false: power never becomes
    /// good and STATUS shows a supply fault once power is enabled).
    pub motor_supply_present: bool,
    /// Time from power enable to motor supply good.
    pub supply_rise: SimDuration,
    /// Digital input lines held high by what is plugged into the board
    /// (DIGIN bits 11:0: home switches 3:0, positive limits 7:4, negative
    /// limits 11:8), on top of the plant's own switches: e.g. the contacts
    /// that tell a dVRK PSM its sterile adapter and instrument are in.
    pub input_lines: u16,
    /// Motor supply voltage, V (what `MeasureMotorSupplyVoltage` finds
    /// through the comparator, `fpga-board-extras.md` §7); a DQLA's first
    /// QLA.
    pub motor_supply_volts: f64,
    /// A DQLA's second QLA's motor supply, V (dvrktest expects the nominal
    /// of board ID + 1: the DQLA stands for two QLA1 boards).
    pub qla2_supply_volts: f64,
    /// FPGA serial number in the configuration PROM (`1234-56`, at most 11
    /// characters; `fpga-board-extras.md` §1).
    pub fpga_serial: String,
    /// QLA serial number per QLA (one; two on a DQLA), in the QLA PROMs
    /// (at most 8 characters; `fpga-board-extras.md` §2). Missing ones get
    /// the default; an invalid one leaves its PROM erased.
    pub qla_serials: Vec<String>,
    /// The instrument on the 1-wire line (a tool's DS2505), if any.
    pub instrument: Option<Instrument>,
    /// A MAX7317 I/O expander on the QLA (QLA 1.5+, the default): STATUS
    /// bit 12, voltage control available (MOTOR_CONFIG bit 25, control
    /// mode 1), the amplifier enable delay. Without one (older QLAs) a
    /// mode-1 DAC write is refused and amplifiers enable at once
    /// (MotorChannelQLA.v).
    pub io_expander: bool,
    /// Commit writes that arrive damaged, as the Rev 8 firmware does: a
    /// quadlet write whose header CRC fails (acknowledged `ack_data_error`
    /// and written all the same, FireWire.v) and a real-time block write
    /// whose data CRC fails (written quadlet by quadlet as it arrives).
    /// Off by default: Firelink's boards acknowledge such packets as the
    /// firmware does but commit nothing. Turn it on only to test a host's
    /// robustness against what real boards do.
    pub commit_corrupt_writes: bool,
    /// Brakes this board drives or whose joints it carries (see
    /// [`BrakeWire`]).
    pub brakes: Vec<BrakeWire>,
}

/// The FPGA generation of a name: `V1`, `V2`, `V3` (or the bare number),
/// any case.
pub fn fpga_from_name(name: &str) -> Option<FpgaVersion> {
    match name.trim().trim_start_matches(['v', 'V']) {
        "1" => Some(FpgaVersion::V1),
        "2" => Some(FpgaVersion::V2),
        "3" => Some(FpgaVersion::V3),
        _ => None,
    }
}

/// The default FPGA serial number of board `board_id`: unique per board ID
/// and the same every run (build `8801`, board number `ID + 1`).
pub fn default_fpga_serial(board_id: u8) -> String {
    format!("8801-{:02}", u16::from(board_id & 0xF) + 1)
}

/// The default serial number of QLA `qla` (0, or 1 for a DQLA's second)
/// of board `board_id` (build `8802`; a DQLA's second QLA counts from 17).
pub fn default_qla_serial(board_id: u8, qla: usize) -> String {
    let n = u16::from(board_id & 0xF) + 1 + 16 * (qla as u16 & 1);
    format!("8802-{n:02}")
}

/// The nominal motor supply of board `board_id` in a dVRK controller, as
/// `dvrktest` expects it (`fpga-board-extras.md` §7): 12 V for the MTMs'
/// second boards (1, 3), 36 V for the ECM (4, 5), 48 V for board 12, 24 V
/// elsewhere.
pub fn nominal_motor_supply_volts(board_id: u8) -> f64 {
    match board_id & 0xF {
        1 | 3 => 12.0,
        4 | 5 => 36.0,
        12 => 48.0,
        _ => 24.0,
    }
}

/// A configuration value the board cannot hold.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A serial number that does not fit its PROM format.
    #[error(
        "board {board}: {what} serial number {serial:?} must be 1 to {max} printable characters without spaces"
    )]
    Serial {
        /// Board ID.
        board: u8,
        /// "FPGA" or "QLA".
        what: &'static str,
        /// The serial given.
        serial: String,
        /// Its longest length.
        max: usize,
    },
    /// A board setting that does not parse.
    #[error("board setting {setting:?}: {why}")]
    Setting {
        /// The text given.
        setting: String,
        /// What is wrong with it.
        why: &'static str,
    },
    /// A companion board on an FPGA the firmware is not built for (a DQLA
    /// on anything but an FPGA V3).
    #[error(
        "board {board}: a DQLA exists only on an FPGA V3 (the firmware builds no FPGA V{fpga} \
         DQLA image); give it --fpga V3 or hardware QLA1"
    )]
    DqlaNeedsV3 {
        /// Board ID.
        board: u8,
        /// The FPGA version given.
        fpga: u8,
    },
    /// A motor supply voltage outside what the comparator can measure.
    #[error("board {board}: motor supply {volts} V is outside 0..=80 V")]
    SupplyVolts {
        /// Board ID.
        board: u8,
        /// The voltage given.
        volts: f64,
    },
}

impl BoardConfig {
    /// A board with generic motors on every axis, seed 0, on the FPGA its
    /// companion board needs: V2 for a QLA1, V3 for a DQLA (the firmware
    /// builds the DQLA only for FPGA V3, `rev9-fpga-v3.md`).
    pub fn new(board_id: u8, hardware: Hardware, profile: Profile) -> BoardConfig {
        BoardConfig {
            board_id: board_id & 0xF,
            hardware,
            profile,
            firmware: profile.firmware_rev(),
            fpga: hardware.default_fpga(),
            git_desc: 0x0F1E_1140,
            axes: vec![presets::generic_motor(); hardware.axes()],
            seed: 0,
            plant_step: DEFAULT_STEP,
            motor_supply_present: true,
            supply_rise: SimDuration::from_millis(5),
            input_lines: 0,
            motor_supply_volts: nominal_motor_supply_volts(board_id),
            qla2_supply_volts: nominal_motor_supply_volts(board_id.wrapping_add(1)),
            fpga_serial: default_fpga_serial(board_id),
            qla_serials: Vec::new(),
            instrument: None,
            io_expander: true,
            commit_corrupt_writes: false,
            brakes: Vec::new(),
        }
    }

    /// The same board with or without an I/O expander on its QLA (see
    /// [`BoardConfig::io_expander`]).
    pub fn with_io_expander(mut self, present: bool) -> BoardConfig {
        self.io_expander = present;
        self
    }

    /// The same board committing damaged writes as the firmware does, or
    /// not (see [`BoardConfig::commit_corrupt_writes`]).
    pub fn with_commit_corrupt_writes(mut self, commit: bool) -> BoardConfig {
        self.commit_corrupt_writes = commit;
        self
    }

    /// The same board with this brake wire added.
    pub fn with_brake(mut self, wire: BrakeWire) -> BoardConfig {
        self.brakes.push(wire);
        self
    }

    /// The same board with this FPGA serial number.
    pub fn with_fpga_serial(mut self, serial: impl Into<String>) -> BoardConfig {
        self.fpga_serial = serial.into();
        self
    }

    /// The same board with QLA `qla`'s serial number set (0; 0 or 1 on a
    /// DQLA); ignored for a QLA the board does not have.
    pub fn with_qla_serial(mut self, qla: usize, serial: impl Into<String>) -> BoardConfig {
        if qla < self.qla_count() {
            let mut serials = self.qla_serials();
            if let Some(s) = serials.get_mut(qla) {
                *s = serial.into();
            }
            self.qla_serials = serials;
        }
        self
    }

    /// The same board with another motor supply voltage.
    pub fn with_motor_supply_volts(mut self, volts: f64) -> BoardConfig {
        self.motor_supply_volts = volts;
        self
    }

    /// The same board with another motor supply on a DQLA's second QLA.
    pub fn with_qla2_supply_volts(mut self, volts: f64) -> BoardConfig {
        self.qla2_supply_volts = volts;
        self
    }

    /// The same board with an instrument on its 1-wire line.
    pub fn with_instrument(mut self, instrument: Instrument) -> BoardConfig {
        self.instrument = Some(instrument);
        self
    }

    /// QLAs on the companion board: 1, or 2 on a DQLA.
    pub fn qla_count(&self) -> usize {
        match self.hardware {
            Hardware::Qla1 => 1,
            Hardware::Dqla => 2,
        }
    }

    /// The QLA serial numbers, one per QLA, defaults filled in.
    pub fn qla_serials(&self) -> Vec<String> {
        (0..self.qla_count())
            .map(|i| {
                self.qla_serials
                    .get(i)
                    .cloned()
                    .unwrap_or_else(|| default_qla_serial(self.board_id, i))
            })
            .collect()
    }

    /// Check what the board's memories and comparator can hold.
    ///
    /// # Errors
    /// The first [`ConfigError`] found.
    pub fn check(&self) -> Result<(), ConfigError> {
        let serial = |what, serial: &str, max, ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(ConfigError::Serial {
                    board: self.board_id,
                    what,
                    serial: serial.to_string(),
                    max,
                })
            }
        };
        use firelink_wire::qla::extras::{FPGA_SERIAL_MAX, QLA_SERIAL_MAX};
        serial(
            "FPGA",
            &self.fpga_serial,
            FPGA_SERIAL_MAX,
            fpga_serial_image(&self.fpga_serial).is_ok(),
        )?;
        for s in self.qla_serials() {
            serial("QLA", &s, QLA_SERIAL_MAX, qla_serial_image(&s).is_ok())?;
        }
        if !self.hardware.fits(self.fpga) {
            return Err(ConfigError::DqlaNeedsV3 {
                board: self.board_id,
                fpga: self.fpga.number(),
            });
        }
        for volts in [self.motor_supply_volts, self.qla2_supply_volts] {
            if !(0.0..=80.0).contains(&volts) {
                return Err(ConfigError::SupplyVolts {
                    board: self.board_id,
                    volts,
                });
            }
        }
        Ok(())
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

    /// The same board running another firmware profile (and reporting its
    /// revision).
    pub fn with_profile(mut self, profile: Profile) -> BoardConfig {
        self.profile = profile;
        self.firmware = profile.firmware_rev();
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

/// Settings of one board, as a command line gives them:
/// `ID:key=value,key=value...` with the keys `hardware` (`QLA1`, `DQLA`),
/// `fpga` (`V2`, `V3`), `firmware` (`7`, `8`, `9`), `fpga-serial`,
/// `qla-serial` (every QLA of the board), `qla2-serial` (a DQLA's
/// second), `supply-volts`, `qla2-supply-volts` (a DQLA's second QLA) and
/// `instrument` (`MODEL/VERSION/NAME`). A DQLA without an `fpga` setting
/// goes on an FPGA V3.
///
/// ```
/// use firelink_board::qla::config::{BoardConfig, BoardSettings, Hardware, Profile};
/// let s: BoardSettings = "2:hardware=DQLA,qla-serial=22723,fpga-serial=5496-03".parse().unwrap();
/// let b = s.apply(BoardConfig::new(2, Hardware::Qla1, Profile::Rev8));
/// assert_eq!(b.hardware, Hardware::Dqla);
/// assert_eq!(b.qla_serials(), ["22723", "22723"]);
/// assert_eq!(b.fpga_serial, "5496-03");
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BoardSettings {
    /// The board these settings are for.
    pub board_id: u8,
    /// Companion board.
    pub hardware: Option<Hardware>,
    /// FPGA generation.
    pub fpga: Option<FpgaVersion>,
    /// Firmware profile (Rev 7, 8 or 9).
    pub firmware: Option<Profile>,
    /// FPGA serial number.
    pub fpga_serial: Option<String>,
    /// Serial number of every QLA of the board.
    pub qla_serial: Option<String>,
    /// Serial number of a DQLA's second QLA.
    pub qla2_serial: Option<String>,
    /// Motor supply, V.
    pub supply_volts: Option<f64>,
    /// A DQLA's second QLA's motor supply, V.
    pub qla2_supply_volts: Option<f64>,
    /// Instrument on the 1-wire line.
    pub instrument: Option<Instrument>,
}

impl core::str::FromStr for BoardSettings {
    type Err = ConfigError;

    fn from_str(text: &str) -> Result<BoardSettings, ConfigError> {
        let bad = |why| ConfigError::Setting {
            setting: text.to_string(),
            why,
        };
        let (id, rest) = text
            .split_once(':')
            .ok_or_else(|| bad("expected ID:key=value,..."))?;
        let board_id: u8 = id
            .trim()
            .parse()
            .ok()
            .filter(|id| *id <= 15)
            .ok_or_else(|| bad("the board ID must be 0..=15"))?;
        let mut s = BoardSettings {
            board_id,
            ..BoardSettings::default()
        };
        for pair in rest.split(',').filter(|p| !p.trim().is_empty()) {
            let (key, value) = pair
                .split_once('=')
                .ok_or_else(|| bad("each setting is key=value"))?;
            let value = value.trim();
            match key.trim() {
                "hardware" => {
                    s.hardware = Some(
                        Hardware::from_name(value)
                            .ok_or_else(|| bad("hardware is QLA1 or DQLA"))?,
                    );
                }
                "fpga" => {
                    s.fpga = Some(fpga_from_name(value).ok_or_else(|| bad("fpga is V2 or V3"))?);
                }
                "firmware" => {
                    s.firmware = Some(
                        value
                            .trim_start_matches(['r', 'R', 'e', 'E', 'v', 'V'])
                            .parse::<u32>()
                            .ok()
                            .and_then(Profile::from_number)
                            .ok_or_else(|| bad("firmware is 7, 8 or 9"))?,
                    );
                }
                "fpga-serial" => s.fpga_serial = Some(value.to_string()),
                "qla-serial" => s.qla_serial = Some(value.to_string()),
                "qla2-serial" => s.qla2_serial = Some(value.to_string()),
                "supply-volts" | "qla2-supply-volts" => {
                    let volts = value
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| bad("supply-volts is a number of volts"))?;
                    if key.trim() == "supply-volts" {
                        s.supply_volts = Some(volts);
                    } else {
                        s.qla2_supply_volts = Some(volts);
                    }
                }
                "instrument" => {
                    let mut parts = value.splitn(3, '/');
                    let model = parts.next().and_then(|m| m.trim().parse::<u32>().ok());
                    let version = parts.next().and_then(|v| v.trim().parse::<u8>().ok());
                    let name = parts.next().unwrap_or("").trim().to_string();
                    match (model, version) {
                        (Some(model), Some(version)) if model <= 0x00FF_FFFF => {
                            s.instrument = Some(Instrument {
                                model,
                                version,
                                name,
                            });
                        }
                        _ => return Err(bad("instrument is MODEL/VERSION/NAME (24-bit model)")),
                    }
                }
                _ => {
                    return Err(bad(
                        "unknown key: hardware, fpga, firmware, fpga-serial, qla-serial, \
                         qla2-serial, supply-volts, qla2-supply-volts or instrument",
                    ));
                }
            }
        }
        Ok(s)
    }
}

impl BoardSettings {
    /// `board` with these settings applied (the companion board first, so
    /// the serials land on every QLA it has).
    pub fn apply(&self, mut board: BoardConfig) -> BoardConfig {
        if let Some(h) = self.hardware {
            board.hardware = h;
            // A DQLA implies an FPGA V3 unless the settings name one.
            if self.fpga.is_none() && !h.fits(board.fpga) {
                board.fpga = h.default_fpga();
            }
        }
        if let Some(f) = self.fpga {
            board.fpga = f;
        }
        if let Some(p) = self.firmware {
            board = board.with_profile(p);
        }
        if let Some(s) = &self.fpga_serial {
            board.fpga_serial = s.clone();
        }
        if let Some(s) = &self.qla_serial {
            for q in 0..board.qla_count() {
                board = board.with_qla_serial(q, s.clone());
            }
        }
        if let Some(s) = &self.qla2_serial {
            board = board.with_qla_serial(1, s.clone());
        }
        if let Some(v) = self.supply_volts {
            board.motor_supply_volts = v;
        }
        if let Some(v) = self.qla2_supply_volts {
            board.qla2_supply_volts = v;
        }
        if let Some(i) = &self.instrument {
            board.instrument = Some(i.clone());
        }
        board
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_unique_stable_and_valid() {
        let mut seen = std::collections::HashSet::new();
        for id in 0..16u8 {
            for hw in [Hardware::Qla1, Hardware::Dqla] {
                let b = BoardConfig::new(id, hw, Profile::Rev8);
                assert_eq!(b.check(), Ok(()));
                assert_eq!(b.fpga, hw.default_fpga(), "a DQLA goes on a V3");
                assert_eq!(b, BoardConfig::new(id, hw, Profile::Rev8));
                if hw == Hardware::Dqla {
                    for s in b.qla_serials() {
                        assert!(seen.insert(s));
                    }
                    assert!(seen.insert(b.fpga_serial.clone()));
                }
            }
        }
    }

    /// Arbitrary text never panics the settings parser.
    #[test]
    fn settings_parser_takes_any_text() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
        let alphabet = b"0123456789:=,/.-abcdeqlsrtuvwhyDQLA \xff";
        for _ in 0..20_000 {
            let len = rng.random_range(0..40);
            let text: String = (0..len)
                .map(|_| char::from(alphabet[rng.random_range(0..alphabet.len())]))
                .collect();
            if let Ok(s) = text.parse::<BoardSettings>() {
                let _ = s
                    .apply(BoardConfig::new(s.board_id, Hardware::Qla1, Profile::Rev8))
                    .check();
            }
        }
    }

    #[test]
    fn settings_parse_apply_and_refuse() {
        let s: BoardSettings =
            "4:qla-serial=334455,supply-volts=36.5,instrument=400006/3/LARGE NEEDLE DRIVER"
                .parse()
                .unwrap();
        let b = s.apply(BoardConfig::new(4, Hardware::Qla1, Profile::Rev8));
        assert_eq!(b.qla_serials(), ["334455"]);
        assert_eq!(b.motor_supply_volts, 36.5);
        assert_eq!(b.instrument.as_ref().map(|i| i.model), Some(400_006));
        let s: BoardSettings = "1:hardware=dqla,qla2-serial=X-2".parse().unwrap();
        let b = s.apply(BoardConfig::new(1, Hardware::Qla1, Profile::Rev8));
        assert_eq!(
            b.qla_serials(),
            [default_qla_serial(1, 0), "X-2".to_string()]
        );
        for bad in [
            "4",
            "16:hardware=QLA1",
            "4:colour=red",
            "4:hardware=QLA9",
            "4:supply-volts=lots",
            "4:instrument=1",
            "4:instrument=x/2/NAME",
            "4:qla-serial",
        ] {
            assert!(bad.parse::<BoardSettings>().is_err(), "{bad}");
        }
        // FPGA and firmware per board; a DQLA implies V3 unless told.
        let s: BoardSettings = "3:hardware=DQLA,firmware=9".parse().unwrap();
        let b = s.apply(BoardConfig::new(3, Hardware::Qla1, Profile::Rev8));
        assert_eq!((b.fpga, b.profile), (FpgaVersion::V3, Profile::Rev9));
        assert_eq!(b.firmware.number(), 9);
        assert_eq!(b.check(), Ok(()));
        let s: BoardSettings = "3:hardware=DQLA,fpga=v2".parse().unwrap();
        let b = s.apply(BoardConfig::new(3, Hardware::Qla1, Profile::Rev8));
        let e = b.check().unwrap_err();
        assert_eq!(e, ConfigError::DqlaNeedsV3 { board: 3, fpga: 2 });
        assert!(e.to_string().contains("only on an FPGA V3"), "{e}");
        for bad in [
            "3:fpga=V4",
            "3:firmware=10",
            "3:firmware=x",
            "3:qla2-supply-volts=no",
        ] {
            assert!(bad.parse::<BoardSettings>().is_err(), "{bad}");
        }
        // A serial the PROM cannot hold is reported by check().
        let b = BoardConfig::new(2, Hardware::Qla1, Profile::Rev8).with_qla_serial(0, "123456789");
        let e = b.check().unwrap_err().to_string();
        assert!(e.contains("board 2") && e.contains("QLA"), "{e}");
    }
}
