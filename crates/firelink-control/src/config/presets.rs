//! The shipped configurations, built in code.
//!
//! `configs/*.json` at the repository root are these values written by
//! `cargo run -p firelink-control --example write_configs`; a test checks
//! that the files and the code agree. Tests and tools can use the functions
//! directly without reading files.
//!
//! Where the numbers come from: the conversion formulas and the per-joint
//! facts (encoder counts per turn, gear ratios, motor torque constants,
//! maximum currents, drive directions, soft limits, pot tolerances, the
//! MTM's pot coupling, board IDs, digital inputs, the ECM's brakes) are the
//! public ones of the dVRK's Classic MTM, PSM and ECM as used by its
//! configuration generator for QLA1 boards; arm serial numbers and the
//! boards' serial numbers are the public ones of JHU's own research kit
//! where its hardware status page lists them. Calibration-specific values
//! (pot gains and offsets, current offsets) and the Firelink extensions
//! (velocity and following-error limits, PID gains, homing moves, stops)
//! are plausible choices, not a calibrated robot's.

use super::{
    ActuatorBrakeCalibration, ActuatorConfig, ActuatorJointCoupling, BoardSerial, BoardSimulation,
    BrakeConfig, BrakeDrive, DigitalInputConfig, DriveConfig, DvrkArm, EncoderConfig,
    HardwareVersion, HomingDefaults, IoConfig, JointType, Limits, LimitsConfig, LinearFunction,
    PlantPreset, PotentiometerConfig, PotentiometerTolerance, PotentiometersConfig,
    PotentiometersType, RobotConfig, RobotSimulation, SCHEMA_ID, SCHEMA_VERSION, SimulationConfig,
    StopSearchConfig, StopSide, VelocitySource,
};
use crate::pid::PidGains;
use core::f64::consts::PI;
use firelink_wire::snake::analog;
use firelink_wire::snake::registers::Wiper;
use serde_json::json;

const DEG: f64 = PI / 180.0;
const MM: f64 = 1e-3;

/// QLA: 16-bit DAC and ADC, ±6.25 A full scale (`fpga-board.md` §3).
const QLA_FULL_SCALE_AMPS: f64 = 6.25;
/// QLA pot ADC: 16 bits over 4.5 V.
const QLA_POT_VOLTS: f64 = 4.5;
/// Snake node: DAC and ADC over 0..2.5 V (seed 001 §7.2).
const SNAKE_VOLTS: f64 = 2.5;

fn round_to(x: f64, decimals: i32) -> f64 {
    let p = 10f64.powi(decimals);
    (x * p).round() / p
}

/// Rounds to `digits` significant digits (for readable gains).
fn round_sig(x: f64, digits: i32) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let magnitude = x.abs().log10().floor() as i32;
    round_to(x, digits - 1 - magnitude)
}

/// Physical description of one motor axis, from which every conversion is
/// derived the way the dVRK's generator derives it.
#[derive(Debug, Clone, Copy)]
struct Axis {
    joint_type: JointType,
    /// +1 or -1: motor and encoder direction relative to the joint.
    direction: f64,
    /// Quadrature counts per motor turn.
    counts_per_turn: u32,
    /// Motor turns (in rad) per joint rad, or per joint metre.
    gear_ratio: f64,
    /// Motor torque constant, N m/A.
    torque_constant: f64,
    maximum_current: f64,
    lower: f64,
    upper: f64,
    /// Pot/encoder tolerance distance (0 disables the check).
    pot_tolerance: f64,
    plant: PlantPreset,
    /// Joint-space PID gains (N m/rad, N m/(rad s), N m s/rad, or per metre).
    effort_gains: (f64, f64, f64),
    velocity_limit: f64,
    following_error: f64,
    home: f64,
    /// The positions the pot reads at 0 V and at 4.5 V; `None`: the soft
    /// range widened by half on each side.
    pot_span: Option<(f64, f64)>,
    /// Calibrated DAC code of 0 A minus 32768, and ADC reading of 0 A in
    /// amperes (both 0 for an uncalibrated file).
    current_offsets: (f64, f64),
    /// Mechanical stops of the emulated joint, if stated.
    hard_stops: Option<(f64, f64)>,
    /// Homing by a stop search, if the joint needs one.
    stop_search: Option<StopSearchConfig>,
}

impl Axis {
    fn drive(&self) -> DriveConfig {
        let amps_to_bits = self.direction * 32768.0 / QLA_FULL_SCALE_AMPS;
        let (dac_zero, sense_zero) = self.current_offsets;
        DriveConfig {
            current_to_bits: LinearFunction {
                scale: round_to(amps_to_bits, 4),
                offset: 32768.0 + dac_zero,
            },
            bits_to_current: LinearFunction {
                scale: round_to(1.0 / amps_to_bits, 9),
                offset: round_to(-self.direction * QLA_FULL_SCALE_AMPS + sense_zero, 4),
            },
            effort_to_current: LinearFunction {
                scale: round_to(self.effort_to_current(), 10),
                offset: 0.0,
            },
            maximum_current: self.maximum_current,
        }
    }

    fn effort_to_current(&self) -> f64 {
        1.0 / (self.gear_ratio * self.torque_constant)
    }

    fn encoder(&self) -> EncoderConfig {
        EncoderConfig {
            bits_to_position: LinearFunction {
                scale: round_to(
                    self.direction * 2.0 * PI / f64::from(self.counts_per_turn) / self.gear_ratio,
                    15,
                ),
                offset: 0.0,
            },
            position_limits_soft: Limits {
                lower: round_to(self.lower, 12),
                upper: round_to(self.upper, 12),
            },
            velocity_source: Some(VelocitySource::Firmware),
            counts_per_turn: Some(self.counts_per_turn),
        }
    }

    /// A pot whose 0..4.5 V spans [`Axis::pot_span`], by default the soft
    /// range widened by half on each side, centred on it.
    fn potentiometer(&self) -> PotentiometerConfig {
        let (at_zero, at_full) = self.pot_span.unwrap_or_else(|| {
            let half = self.upper - self.lower;
            (self.lower - 0.5 * half, self.upper + 0.5 * half)
        });
        let span = at_full - at_zero;
        let scale = round_to(span / QLA_POT_VOLTS, 8);
        let centre = 0.5 * (at_zero + at_full);
        PotentiometerConfig {
            bits_to_voltage: LinearFunction {
                scale: QLA_POT_VOLTS / 65536.0,
                offset: 0.0,
            },
            voltage_to_position: LinearFunction {
                scale,
                offset: round_to(centre - scale * QLA_POT_VOLTS / 2.0, 8),
            },
        }
    }

    /// Seed 001's Snake node instead of a QLA: the motor DAC in torque
    /// mode at the nominal wiper (amperes through the feedback gain and the
    /// sense resistor), the 14-bit current monitor and potentiometer in the
    /// API's 0..=16383 (ADC + 8192) over 0..2.5 V
    /// (`firelink_wire::snake::analog`).
    fn snake_conversions(&self, actuator: &mut ActuatorConfig) {
        let gain = Wiper::NOMINAL.feedback_gain();
        let amps_to_bits = self.direction * gain * analog::SENSE_OHMS * 65536.0 / SNAKE_VOLTS;
        let amps_per_count = SNAKE_VOLTS / 16384.0 / analog::MONITOR_VOLTS_PER_AMP;
        actuator.drive.current_to_bits = LinearFunction {
            scale: round_to(amps_to_bits, 4),
            offset: 32768.0,
        };
        actuator.drive.bits_to_current = LinearFunction {
            scale: round_to(self.direction * amps_per_count, 14),
            offset: round_to(-self.direction * 8192.0 * amps_per_count, 9),
        };
        let span = 2.0 * (self.upper - self.lower);
        let scale = round_to(span / SNAKE_VOLTS, 8);
        actuator.potentiometer = Some(PotentiometerConfig {
            bits_to_voltage: LinearFunction {
                scale: SNAKE_VOLTS / 16384.0,
                offset: 0.0,
            },
            voltage_to_position: LinearFunction {
                scale,
                offset: round_to(
                    0.5 * (self.lower + self.upper) - scale * SNAKE_VOLTS / 2.0,
                    8,
                ),
            },
        });
    }

    fn actuator(&self, index: usize, board_id: u8, axis_id: u8) -> ActuatorConfig {
        let e2c = self.effort_to_current();
        let (kp, ki, kd) = self.effort_gains;
        ActuatorConfig {
            actuator_id: Some(index),
            board_id,
            axis_id,
            joint_type: Some(self.joint_type),
            drive: self.drive(),
            encoder: self.encoder(),
            potentiometer: Some(self.potentiometer()),
            brake: None,
            limits: Some(LimitsConfig {
                velocity: self.velocity_limit,
                acceleration: Some(round_sig(4.0 * self.velocity_limit, 3)),
                following_error: self.following_error,
                following_error_grace: 0.05,
                saturation_time: 1.0,
                position_margin: Some(round_sig(0.1 * (self.upper - self.lower), 3)),
            }),
            simulation: Some(SimulationConfig {
                plant: self.plant,
                hard_stops: self.hard_stops.map(|(lower, upper)| Limits {
                    lower: round_to(lower, 12),
                    upper: round_to(upper, 12),
                }),
                pid: Some(PidGains {
                    integral_limit: Some(round_sig(0.5 * self.maximum_current, 3)),
                    ..PidGains::pid(
                        round_sig(kp * e2c, 4),
                        round_sig(ki * e2c, 4),
                        round_sig(kd * e2c, 4),
                    )
                }),
                homing: Some(HomingDefaults {
                    position: self.home,
                    velocity: round_sig(0.25 * self.velocity_limit, 3),
                    acceleration: round_sig(self.velocity_limit, 3),
                    stop_search: self.stop_search,
                }),
            }),
        }
    }
}

/// A robot on consecutive boards: actuator *i* on board
/// `boards[i / axes]`, axis `i % axes`.
fn robot(
    name: &str,
    serial: &str,
    hardware: HardwareVersion,
    boards: &[u8],
    axes: &[Axis],
) -> RobotConfig {
    let per_board = usize::from(hardware.axes());
    let actuators: Vec<ActuatorConfig> = axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let board = boards.get(i / per_board).copied().unwrap_or(u8::MAX);
            let mut actuator = a.actuator(i, board, (i % per_board) as u8);
            if hardware.is_snake() {
                a.snake_conversions(&mut actuator);
            }
            actuator
        })
        .collect();
    let tolerances = axes
        .iter()
        .enumerate()
        .map(|(i, a)| PotentiometerTolerance {
            axis_id: i,
            distance: round_to(a.pot_tolerance, 12),
            latency: if a.pot_tolerance > 0.0 { 0.01 } else { 0.0 },
        })
        .collect();
    RobotConfig {
        name: name.to_string(),
        hardware_version: hardware,
        serial_number: serial.to_string(),
        number_of_actuators: actuators.len(),
        actuators,
        robot_type: None,
        only_io: None,
        has_encoder_preload: Some(true),
        // The dVRK console requires the count, 0 without brakes.
        number_of_brakes: Some(0),
        brakes: Some(Vec::new()),
        potentiometers: Some(PotentiometersConfig {
            potentiometers_type: Some(PotentiometersType::Analog),
            tolerances,
            coupling: None,
            lookup_table_file: None,
        }),
        simulation: None,
    }
}

/// Classic MTM axes (`left` picks the MTML directions and limits).
fn mtm_axes(left: bool) -> Vec<Axis> {
    let direction: [f64; 7] = if left {
        [-1.0, 1.0, 1.0, 1.0, -1.0, 1.0, -1.0]
    } else {
        [-1.0, 1.0, 1.0, 1.0, 1.0, 1.0, -1.0]
    };
    let (lower, upper): ([f64; 7], [f64; 7]) = if left {
        (
            [-40.0, -18.0, -15.0, -240.0, -95.0, -45.0, -475.0],
            [65.0, 65.0, 42.0, 120.0, 185.0, 45.0, 445.0],
        )
    } else {
        (
            [-65.0, -18.0, -15.0, -120.0, -95.0, -45.0, -475.0],
            [40.0, 65.0, 42.0, 240.0, 185.0, 45.0, 445.0],
        )
    };
    let cpt = [4000, 4000, 4000, 4000, 64, 64, 64];
    let gear = [63.41, 49.88, 59.73, 10.53, 33.16, 33.16, 16.58];
    let kt = [0.0438, 0.0438, 0.0438, 0.0438, 0.00495, 0.00495, 0.00339];
    let imax = [0.67, 0.67, 0.67, 0.67, 0.59, 0.59, 0.407];
    let plants = DvrkArm::Mtm.plants();
    // Joint-space gains (N m/rad, N m/(rad s), N m s/rad).
    let gains = [
        (30.0, 1.0, 1.5),
        (30.0, 1.0, 1.5),
        (30.0, 1.0, 1.5),
        (10.0, 0.5, 0.3),
        (4.0, 0.2, 0.1),
        (3.0, 0.2, 0.05),
        (1.0, 0.05, 0.02),
    ];
    let vmax = [2.0, 2.0, 2.0, 4.0, 6.0, 6.0, 8.0];
    (0..7)
        .map(|i| Axis {
            joint_type: JointType::Revolute,
            direction: direction[i],
            counts_per_turn: cpt[i],
            gear_ratio: gear[i],
            torque_constant: kt[i],
            maximum_current: imax[i],
            lower: lower[i] * DEG,
            upper: upper[i] * DEG,
            pot_tolerance: if i < 6 { 5.0 * DEG } else { 0.0 },
            plant: plants[i],
            effort_gains: gains[i],
            velocity_limit: vmax[i],
            following_error: if i < 3 { 0.35 } else { 0.5 },
            home: 0.0,
            pot_span: None,
            current_offsets: (0.0, 0.0),
            hard_stops: None,
            stop_search: None,
        })
        .collect()
}

/// Classic PSM axes.
fn psm_axes() -> Vec<Axis> {
    let direction = [-1.0, -1.0, 1.0, -1.0, -1.0, 1.0, 1.0];
    let cpt = [14400, 14400, 14400, 4000, 4000, 4000, 4000];
    let gear = [56.50, 56.50, 336.6, 11.71, 11.71, 11.71, 11.71];
    let imax = [1.34, 1.34, 0.67, 0.67, 0.67, 0.67, 0.67];
    let lower = [
        -91.0 * DEG,
        -53.0 * DEG,
        0.0 * MM,
        -174.0 * DEG,
        -174.0 * DEG,
        -174.0 * DEG,
        -174.0 * DEG,
    ];
    let upper = [
        91.0 * DEG,
        53.0 * DEG,
        240.0 * MM,
        174.0 * DEG,
        174.0 * DEG,
        174.0 * DEG,
        174.0 * DEG,
    ];
    let plants = DvrkArm::Psm.plants();
    let gains = [
        (60.0, 2.0, 3.0),
        (60.0, 2.0, 3.0),
        (4000.0, 100.0, 100.0),
        (2.0, 0.1, 0.05),
        (2.0, 0.1, 0.05),
        (2.0, 0.1, 0.05),
        (2.0, 0.1, 0.05),
    ];
    // The instrument's disks: 12 rad/s. The console's teleoperation moves
    // a Large Needle Driver's jaw at up to 720 degrees/s
    // (`TeleOperationPSM::JawRate`), 5.2 rad/s on each of the last two
    // disks (jaw = 1.2177 x their difference), and a hand-speed wrist yaw
    // and pitch add 2 to 3 rad/s; the disks' motors (11.71:1, 24 V) turn
    // them at up to about 45 rad/s.
    let vmax = [1.5, 1.5, 0.2, 12.0, 12.0, 12.0, 12.0];
    patient_side_axes(PatientSideArm {
        direction: &direction,
        counts_per_turn: &cpt,
        gear_ratio: &gear,
        torque_constant: &[0.0438; 7],
        maximum_current: &imax,
        lower: &lower,
        upper: &upper,
        plants,
        gains: &gains,
        velocity_limit: &vmax,
        insertion_home: 50.0 * MM,
    })
}

/// The per-joint facts of a patient-side arm (PSM, ECM), joint by joint;
/// the third joint is the prismatic insertion.
struct PatientSideArm<'a> {
    direction: &'a [f64],
    counts_per_turn: &'a [u32],
    gear_ratio: &'a [f64],
    torque_constant: &'a [f64],
    maximum_current: &'a [f64],
    lower: &'a [f64],
    upper: &'a [f64],
    plants: &'a [PlantPreset],
    /// Joint-space PID gains.
    gains: &'a [(f64, f64, f64)],
    velocity_limit: &'a [f64],
    /// Where the insertion joint homes, m (the others home at 0).
    insertion_home: f64,
}

/// A patient-side arm's axes from its table (as many as its shortest
/// column).
fn patient_side_axes(t: PatientSideArm<'_>) -> Vec<Axis> {
    let n = [
        t.direction.len(),
        t.counts_per_turn.len(),
        t.gear_ratio.len(),
        t.torque_constant.len(),
        t.maximum_current.len(),
        t.lower.len(),
        t.upper.len(),
        t.plants.len(),
        t.gains.len(),
        t.velocity_limit.len(),
    ]
    .into_iter()
    .min()
    .unwrap_or(0);
    (0..n)
        .map(|i| {
            let prismatic = i == 2;
            Axis {
                joint_type: if prismatic {
                    JointType::Prismatic
                } else {
                    JointType::Revolute
                },
                direction: t.direction[i],
                counts_per_turn: t.counts_per_turn[i],
                gear_ratio: t.gear_ratio[i],
                torque_constant: t.torque_constant[i],
                maximum_current: t.maximum_current[i],
                lower: t.lower[i],
                upper: t.upper[i],
                pot_tolerance: if prismatic { 5.0 * MM } else { 5.0 * DEG },
                plant: t.plants[i],
                effort_gains: t.gains[i],
                velocity_limit: t.velocity_limit[i],
                following_error: if prismatic { 0.02 } else { 0.35 },
                home: if prismatic { t.insertion_home } else { 0.0 },
                pot_span: None,
                current_offsets: (0.0, 0.0),
                hard_stops: None,
                stop_search: None,
            }
        })
        .collect()
}

/// A generic geared DC motor on a revolute joint with ±`range` rad.
fn generic_axis(range: f64, direction: f64) -> Axis {
    Axis {
        joint_type: JointType::Revolute,
        direction,
        counts_per_turn: 4000,
        gear_ratio: 19.0,
        torque_constant: 0.0232,
        maximum_current: 1.0,
        lower: -range,
        upper: range,
        pot_tolerance: 5.0 * DEG,
        plant: PlantPreset::Generic,
        effort_gains: (10.0, 0.5, 0.3),
        velocity_limit: 3.0,
        following_error: 0.3,
        home: 0.0,
        pot_span: None,
        current_offsets: (0.0, 0.0),
        hard_stops: None,
        stop_search: None,
    }
}

fn io_config(description: &str, robots: Vec<RobotConfig>) -> IoConfig {
    IoConfig {
        id: SCHEMA_ID.to_string(),
        version: SCHEMA_VERSION.to_string(),
        description: Some(description.to_string()),
        robots,
        digital_inputs: None,
        digital_outputs: None,
        dallas_chips: None,
    }
}

/// Seed 000's da Vinci Research Kit: MTML, MTMR, PSM1 and PSM2, 7 actuators
/// each, 28 axes on 8 QLA1 boards (4 axes each): MTML on boards 0-1, MTMR
/// 2-3, PSM1 4-5, PSM2 6-7; each arm's actuators 0-3 on its first board and
/// 4-6 on axes 0-2 of its second.
pub fn dvrk_seed000() -> IoConfig {
    let qla = HardwareVersion::Qla1;
    io_config(
        "Seed 000 dVRK: two Classic MTMs and two Classic PSMs, 28 axes on 8 QLA1 boards \
         (4 axes each; boards 0-1 MTML, 2-3 MTMR, 4-5 PSM1, 6-7 PSM2, contiguous so one \
         8-board bus; the dVRK's own convention puts ECM on 4-5 and PSM1/PSM2 on 6-7/8-9). \
         Conversions follow the public dVRK formulas for QLA1 (+-6.25 A, 16-bit DAC/ADC, \
         pot 4.5 V over 16 bits) and the public Classic MTM/PSM gear ratios, encoder counts, \
         torque constants, maximum currents and soft limits; pot calibration and the Firelink \
         sections (limits, simulation) are plausible values, not a calibrated robot's.",
        vec![
            robot("MTML", "22723", qla, &[0, 1], &mtm_axes(true)),
            robot("MTMR", "28247", qla, &[2, 3], &mtm_axes(false)),
            robot("PSM1", "28007", qla, &[4, 5], &psm_axes()),
            robot("PSM2", "27374", qla, &[6, 7], &psm_axes()),
        ],
    )
}

/// A single QLA1 board with four generic motors (a bench setup).
pub fn bench_1board() -> IoConfig {
    let axes: Vec<Axis> = (0..4)
        .map(|i| generic_axis(PI, if i % 2 == 0 { 1.0 } else { -1.0 }))
        .collect();
    io_config(
        "Bench: one QLA1 board (ID 0) driving four generic geared DC motors \
         (4000 counts/turn, 19:1, 23.2 mN m/A, 1 A max), each with a pot.",
        vec![robot("BENCH", "0001", HardwareVersion::Qla1, &[0], &axes)],
    )
}

/// Seed 001's Snake robot system: two 11-axis Snake robots and two 7-axis
/// masters, 36 axes. Seed 001 used 7-channel nodes; this configuration
/// puts each Snake on two DQLA boards (8 axes each: 8 + 3 used) and each
/// master on two QLA1 boards (4 + 3), 8 boards in all.
pub fn snake_36axes() -> IoConfig {
    let snake_axes = snake_robot_axes();
    io_config(
        "Seed 001 Snake robot system: two 11-axis Snake robots and two 7-axis masters, \
         36 axes. Seed 001 used 7-channel nodes (14-bit ADC, 16-bit DAC); Firelink emits \
         the system on JHU boards instead: each Snake on two DQLA boards (8 axes each, \
         IDs 0-1 and 2-3), each master on two QLA1 boards (IDs 4-5 and 6-7). Snake axes \
         are generic geared motors; masters reuse the Classic MTM factors.",
        vec![
            robot(
                "SNAKE1",
                "S001",
                HardwareVersion::Dqla,
                &[0, 1],
                &snake_axes,
            ),
            robot(
                "SNAKE2",
                "S002",
                HardwareVersion::Dqla,
                &[2, 3],
                &snake_axes,
            ),
            robot(
                "MASTER1",
                "M001",
                HardwareVersion::Qla1,
                &[4, 5],
                &mtm_axes(true),
            ),
            robot(
                "MASTER2",
                "M002",
                HardwareVersion::Qla1,
                &[6, 7],
                &mtm_axes(false),
            ),
        ],
    )
}

/// Classic ECM axes.
fn ecm_axes() -> Vec<Axis> {
    let direction = [1.0, 1.0, -1.0, 1.0];
    let cpt = [4000, 4000, 640, 64];
    let gear = [240.0, 240.0, 2748.55, 300.15];
    let kt = [0.1190, 0.1190, 0.0438, 0.00495];
    let imax = [0.943, 0.943, 0.67, 0.59];
    let lower = [-90.0 * DEG, -45.0 * DEG, 0.0 * MM, -89.0 * DEG];
    let upper = [90.0 * DEG, 64.0 * DEG, 255.0 * MM, 89.0 * DEG];
    let plants = DvrkArm::Ecm.plants();
    let gains = [
        (100.0, 3.0, 8.0),
        (100.0, 3.0, 8.0),
        (3000.0, 100.0, 150.0),
        (2.0, 0.1, 0.05),
    ];
    let vmax = [1.0, 1.0, 0.1, 2.0];
    patient_side_axes(PatientSideArm {
        direction: &direction,
        counts_per_turn: &cpt,
        gear_ratio: &gear,
        torque_constant: &kt,
        maximum_current: &imax,
        lower: &lower,
        upper: &upper,
        plants,
        gains: &gains,
        velocity_limit: &vmax,
        insertion_home: 20.0 * MM,
    })
}

/// How far beyond the soft limits the stock configurations put the
/// emulated arms' mechanical stops: 3 degrees for a revolute joint.
pub const STOP_MARGIN_RAD: f64 = 3.0 * DEG;
/// The same for a prismatic joint: 3 mm.
pub const STOP_MARGIN_M: f64 = 3.0 * MM;

/// Calibrated-looking current offsets (DAC code of 0 A minus 32768, and
/// the ADC reading of 0 A in amperes): a calibrated arm's are all
/// different, and the dVRK console refuses a file whose DAC offsets are
/// all equal ("please calibrate the current offsets").
const CURRENT_OFFSETS: [(f64, f64); 7] = [
    (37.0, 0.0031),
    (-22.0, -0.0044),
    (14.0, 0.0012),
    (-41.0, 0.0057),
    (29.0, -0.0026),
    (-8.0, 0.0009),
    (51.0, -0.0038),
];

/// A stock arm's axes: calibrated current offsets, stops 3 degrees (3 mm)
/// beyond the soft limits unless stated, and a pot that spans the stops
/// widened by 15 % of its range on each side unless stated.
fn stock(axes: Vec<Axis>) -> Vec<Axis> {
    axes.into_iter()
        .enumerate()
        .map(|(i, mut a)| {
            a.current_offsets = CURRENT_OFFSETS[i % CURRENT_OFFSETS.len()];
            let margin = if a.joint_type == JointType::Prismatic {
                STOP_MARGIN_M
            } else {
                STOP_MARGIN_RAD
            };
            let (lo, hi) = *a
                .hard_stops
                .get_or_insert((a.lower - margin, a.upper + margin));
            if a.pot_span.is_none() {
                let widen = 0.15 * (hi - lo);
                a.pot_span = Some((lo - widen, hi + widen));
            }
            a
        })
        .collect()
}

/// The Classic MTM's pot coupling (the pots of actuators 2-4 are mounted
/// on joints the actuators move together): actuator positions from joint
/// positions, as the dVRK's configuration generator writes it.
fn mtm_coupling() -> Vec<Vec<f64>> {
    let mut m = vec![vec![0.0; 7]; 7];
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    m[2][1] = 1.0;
    m[3][2] = 0.6697;
    m
}

/// A stock Classic MTMR: JHU's research kit MTMR (serial 28247) on boards
/// 2-3 as the dVRK numbers them, its pots on the joints (coupling), the
/// wrist roll's pot reading only about half a turn (unchecked, as in the
/// dVRK's files), the roll homed by a stop search against its lower stop at -480
/// degrees, as the dVRK console does (360 degrees/s reached at 360
/// degrees/s², stall declared at half a turn of following error, at most
/// 3.25 turns of travel).
pub fn stock_mtmr() -> IoConfig {
    let mut axes = mtm_axes(false);
    if let Some(roll) = axes.get_mut(6) {
        roll.hard_stops = Some((-480.0 * DEG, -480.0 * DEG + 2.6 * 2.0 * PI));
        roll.stop_search = Some(StopSearchConfig {
            side: StopSide::Lower,
            velocity: round_to(2.0 * PI, 6),
            acceleration: round_to(2.0 * PI, 6),
            stall_error: round_to(PI, 6),
            stop_position: round_to(-480.0 * DEG, 12),
            max_travel: round_to(6.5 * PI, 6),
        });
    }
    let mut axes = stock(axes);
    // The coupled pots read joints: span what the joints can reach with
    // every actuator inside its stops.
    let coupling = mtm_coupling();
    if let Some(a2j) = super::Matrix::from_rows(&coupling).and_then(|m| m.inverse()) {
        let stops: Vec<(f64, f64)> = axes
            .iter()
            .map(|a| a.hard_stops.unwrap_or((a.lower, a.upper)))
            .collect();
        for (i, a) in axes.iter_mut().enumerate() {
            let (lo, hi) = stops
                .iter()
                .enumerate()
                .fold((0.0, 0.0), |(lo, hi), (j, s)| {
                    let w = a2j.get(i, j);
                    let (x, y) = (w * s.0, w * s.1);
                    (lo + x.min(y), hi + x.max(y))
                });
            let widen = 0.15 * (hi - lo);
            a.pot_span = Some((lo - widen, hi + widen));
        }
    }
    // The wrist roll's pot reads about half a turn, as the arm's does:
    // from +1.4 rad at 0 V to -1.8 rad at 4.5 V, saturating beyond (the
    // console homes the roll by its stop and does not check its pot).
    if let Some(roll) = axes.get_mut(6) {
        roll.pot_span = Some((1.40, -1.80));
    }
    let mut mtmr = robot("MTMR", "28247", HardwareVersion::Qla1, &[2, 3], &axes);
    if let Some(p) = mtmr.potentiometers.as_mut() {
        p.coupling = Some(ActuatorJointCoupling {
            joint_to_actuator_position: Some(coupling),
            ..ActuatorJointCoupling::default()
        });
    }
    mtmr.simulation = Some(RobotSimulation {
        arm: Some(DvrkArm::Mtm),
        boards: serials(&[(2, "3792-22", "3791-14"), (3, "3792-43", "3791-41")]),
        ..RobotSimulation::default()
    });
    io_config(
        "Stock-style Classic MTMR (serial 28247, JHU's research kit) on two QLA1 boards with \
         the dVRK's board IDs 2-3, as the dVRK's configuration generator lays out \
         sawRobotIO1394-MTMR-28247.json: public gear ratios, encoder counts, torque constants, \
         maximum currents, directions, soft limits, pot tolerances and pot coupling (pots on \
         the joints); board serial numbers from JHU's public hardware status page. Pot and \
         current calibrations are plausible values; the wrist roll's pot reads about half a \
         turn (-1.8 to 1.4 rad) and saturates beyond, its check off. Firelink sections: stops \
         3 degrees beyond the soft limits (roll: -480 and +456 degrees), the roll homed by a \
         stop search as the console does (stall at a following error of half a turn, encoder \
         set to -480 degrees).",
        vec![mtmr],
    )
}

/// A stock Classic PSM1: JHU's research kit PSM1 (serial 28007) on boards
/// 6-7 as the dVRK numbers them, with its digital inputs (the sterile
/// adapter and instrument contacts) and Dallas chip, the sterile adapter
/// on and no instrument.
pub fn stock_psm1() -> IoConfig {
    let mut psm1 = robot(
        "PSM1",
        "28007",
        HardwareVersion::Qla1,
        &[6, 7],
        &stock(psm_axes()),
    );
    psm1.simulation = Some(RobotSimulation {
        arm: Some(DvrkArm::Psm),
        adapter: true,
        tool: None,
        boards: serials(&[(6, "3116-01", "3791-15"), (7, "3116-03", "3791-19")]),
    });
    let mut c = io_config(
        "Stock-style Classic PSM1 (serial 28007, JHU's research kit) on two QLA1 boards with \
         the dVRK's board IDs 6-7, as the dVRK's configuration generator lays out \
         sawRobotIO1394-PSM1-28007.json: public gear ratios, encoder counts, torque constants, \
         maximum currents, directions, soft limits, pot tolerances, digital inputs (SUJ and \
         arm clutch, instrument, sterile adapter) and Dallas chip; board serial numbers from \
         JHU's public hardware status page. Pot and current calibrations are plausible values. \
         Firelink sections: stops 3 degrees (3 mm) beyond the soft limits, the sterile adapter \
         on, no instrument (set simulation.tool to put one in).",
        vec![psm1],
    );
    c.digital_inputs = Some(digital_inputs(&[
        ("PSM1_SUJ_clutch", 6, 0),
        ("PSM1_arm_clutch", 6, 2),
        ("PSM1_tool", 7, 7),
        ("PSM1_adapter", 7, 10),
    ]));
    c.dallas_chips = Some(json!([{ "board_id": 7, "name": "PSM1_dallas" }]));
    c
}

/// A stock Classic ECM: JHU's ECM (serial 29738) on boards 4-5 as the
/// dVRK numbers them, its three brakes on the second board's channels 0-2
/// (each holds the actuator of its index until released).
pub fn stock_ecm() -> IoConfig {
    let mut ecm = robot(
        "ECM",
        "29738",
        HardwareVersion::Qla1,
        &[4, 5],
        &stock(ecm_axes()),
    );
    let brakes: Vec<BrakeConfig> = [(0.25, 0.25, 0.08), (0.22, 0.22, 0.07), (0.90, 0.90, 0.20)]
        .iter()
        .enumerate()
        .map(|(axis, &(max, release, released))| BrakeConfig {
            board_id: 5,
            axis_id: axis as u8,
            drive: BrakeDrive {
                current_to_bits: LinearFunction {
                    scale: 5242.88,
                    offset: 32768.0 + BRAKE_DAC_OFFSETS[axis],
                },
                bits_to_current: LinearFunction {
                    scale: round_to(1.0 / 5242.88, 9),
                    offset: -6.25,
                },
                maximum_current: Some(max),
            },
            release_current: Some(release),
            release_time: Some(2.0),
            released_current: Some(released),
            engaged_current: Some(0.0),
        })
        .collect();
    // The calibration tool's brake offsets beside each braked actuator's
    // drive, as in the dVRK's ECM files.
    for (a, offset) in ecm.actuators.iter_mut().zip(BRAKE_SENSE_OFFSETS) {
        a.brake = Some(ActuatorBrakeCalibration {
            current_to_bits: Some(super::OffsetOnly {
                offset: 0.0,
                scale: None,
            }),
            bits_to_current: Some(super::OffsetOnly {
                offset,
                scale: None,
            }),
        });
    }
    ecm.number_of_brakes = Some(brakes.len());
    ecm.brakes = Some(brakes);
    ecm.simulation = Some(RobotSimulation {
        arm: Some(DvrkArm::Ecm),
        boards: serials(&[(4, "3985-01", "3984-01"), (5, "3985-02", "3984-02")]),
        ..RobotSimulation::default()
    });
    let mut c = io_config(
        "Stock-style Classic ECM (serial 29738) on two QLA1 boards with the dVRK's board IDs \
         4-5, as the dVRK's configuration generator lays out sawRobotIO1394-ECM-29738.json: \
         public gear ratios, encoder counts, torque constants, maximum currents, directions, \
         soft limits, pot tolerances, brakes (board 5, axes 0-2) and digital inputs (arm and \
         SUJ clutch). Pot, current and brake calibrations are plausible values; the board \
         serial numbers have the public format but are not a documented ECM's. Firelink \
         sections: stops 3 degrees (3 mm) beyond the soft limits. The brakes hold joints 1-3 \
         until their channels carry the release current.",
        vec![ecm],
    );
    c.digital_inputs = Some(digital_inputs(&[
        ("ECM_arm_clutch", 4, 0),
        ("ECM_SUJ_clutch", 4, 2),
    ]));
    c
}

/// A stock arm moved onto one DQLA, as the dVRK's configuration generator
/// lays out a DQLA arm (`getActuatorsPerBoard("DQLA") == 8`): every
/// actuator on the arm's first board ID, axis = actuator index; brake `i`
/// on axis `i + 4` of the same board (the ECM's brakes on axes 4-6).
fn on_dqla(mut robot: RobotConfig, board: u8) -> RobotConfig {
    robot.hardware_version = HardwareVersion::Dqla;
    for (axis, a) in robot.actuators.iter_mut().enumerate() {
        a.board_id = board;
        a.axis_id = axis as u8;
    }
    for (i, b) in robot.brakes.iter_mut().flatten().enumerate() {
        b.board_id = board;
        b.axis_id = (i + 4) as u8;
    }
    if let Some(sim) = robot.simulation.as_mut() {
        sim.boards = vec![BoardSimulation {
            board_id: board,
            serial: BoardSerial {
                fpga: None,
                qla: None,
            },
            fpga_version: Some(super::FpgaGeneration::V3),
            firmware: Some(9),
        }];
    }
    robot
}

/// Today's dVRK controllers: the stock Classic MTMR, ECM and PSM1, each on
/// one DQLA (two QLAs on an FPGA V3, 8 axes) at firmware Rev 9, with the
/// board ID the dVRK gives a DQLA arm (the first of its QLA pair: MTMR 2,
/// ECM 4, PSM1 6). The MTMR's gripper is on its board's axis 7; the
/// PSM's instrument and sterile-adapter contacts on its second QLA's lines
/// (DIGIN bits 23 and 26, the generator's "add 16 for the second board").
pub fn dqla_rev9() -> IoConfig {
    let robots = vec![
        on_dqla(stock_mtmr().robots.remove(0), 2),
        on_dqla(stock_ecm().robots.remove(0), 4),
        on_dqla(stock_psm1().robots.remove(0), 6),
    ];
    let mut c = io_config(
        "Today's dVRK controllers: the stock-style Classic MTMR (28247), ECM (29738) and PSM1 \
         (28007) of this directory, each arm on one DQLA (two QLAs on an FPGA V3, 8 axes) at \
         firmware Rev 9 where the Classic controllers use two QLA1 boards, laid out as the \
         dVRK's configuration generator lays out a DQLA arm: every actuator on the arm's first \
         board ID (MTMR 2, ECM 4, PSM1 6), axis = actuator index, the MTMR's gripper on axis 7, \
         the ECM's brakes on axes 4-6, the PSM's digital inputs on its board (instrument and \
         sterile adapter on the second QLA: bits 23 and 26) and its Dallas chip on its board. \
         Each board's simulation section names FPGA V3 and firmware 9, so `firelink demo` and \
         `firelink emulate` run it on V3/DQLA boards at Rev 9 (`firelink emulate --network eth \
         --fpga V3 --firmware 9` on the Ethernet-only network).",
        robots,
    );
    c.digital_inputs = Some(digital_inputs(&[
        ("ECM_arm_clutch", 4, 0),
        ("ECM_SUJ_clutch", 4, 2),
        ("PSM1_SUJ_clutch", 6, 0),
        ("PSM1_arm_clutch", 6, 2),
        ("PSM1_tool", 6, 23),
        ("PSM1_adapter", 6, 26),
    ]));
    c.dallas_chips = Some(json!([{ "board_id": 6, "name": "PSM1_dallas" }]));
    c
}

/// The ECM brake channels' calibrated DAC offsets (code of 0 A minus
/// 32768).
const BRAKE_DAC_OFFSETS: [f64; 3] = [19.0, -27.0, 33.0];
/// The ECM brakes' feedback offsets the calibration tool writes beside the
/// actuators' drives, A.
const BRAKE_SENSE_OFFSETS: [f64; 3] = [-0.0612, -0.0284, -0.0935];

/// Board serial numbers: (board ID, FPGA, QLA).
fn serials(boards: &[(u8, &str, &str)]) -> Vec<BoardSimulation> {
    boards
        .iter()
        .map(|&(board_id, fpga, qla)| BoardSimulation {
            board_id,
            serial: BoardSerial {
                fpga: Some(fpga.to_string()),
                qla: Some(qla.to_string()),
            },
            fpga_version: None,
            firmware: None,
        })
        .collect()
}

/// v6 digital inputs: (name, board ID, bit), `pressed_value` true (the
/// dVRK reads them pressed when their line is low), 0.2 s debounce, events
/// both ways (the Classic arms' settings).
fn digital_inputs(inputs: &[(&str, u8, u8)]) -> Vec<DigitalInputConfig> {
    inputs
        .iter()
        .map(|&(name, board_id, bit_id)| DigitalInputConfig {
            name: name.to_string(),
            board_id,
            bit_id,
            pressed_value: true,
            trigger_when_pressed: Some(true),
            trigger_when_released: Some(true),
            skip_first_run: None,
            debounce_time: Some(0.2),
            debounce_time_click: None,
            simulation: None,
        })
        .collect()
}

/// The Snake robot's own axes (two three-axis SLUs, a gripper, a
/// two-axis Z-Theta stage and a two-axis five bar): small geared motors.
fn snake_robot_axes() -> Vec<Axis> {
    (0..11)
        .map(|i| {
            let mut a = generic_axis(90.0 * DEG, 1.0);
            // Small cable-drive motors for the continuum segments.
            a.gear_ratio = 64.0;
            a.torque_constant = 0.0107;
            a.maximum_current = 0.5;
            a.counts_per_turn = 2048;
            // About 30 rad/s closed-loop, damping near 0.7 on the
            // joint-side inertia of these axes.
            a.effort_gains = (10.0, 0.5, 0.4);
            a.velocity_limit = 2.5;
            if i >= 8 {
                // Gripper / wrist roll.
                a.lower = -PI;
                a.upper = PI;
            }
            a
        })
        .collect()
}

/// Seed 001's own system: two 11-axis Snake robots and two 7-axis
/// masters, 36 axes on six of the seed's 7-channel nodes, in the seed's
/// arrangement (§5.3): each Snake on two nodes, one for its actuation
/// unit (7 axes, board IDs 0 and 2) and one for its Z-Theta and five-bar
/// stages (4 axes, IDs 1 and 3); each master on one node (IDs 4 and 5).
pub fn snake_seed001() -> IoConfig {
    let snake = HardwareVersion::Snake;
    io_config(
        "Seed 001 Snake robot system on the seed's own 7-channel FPGA/1394 nodes: \
         SNAKE1 and SNAKE2 (11 axes each: actuation unit on one node, Z-Theta and \
         five bar on a second), MASTER1 and MASTER2 (7 axes each, one node each): \
         36 axes on 6 nodes (board IDs 0-5). Conversions are the node's: the motor \
         DAC in torque mode at the nominal wiper 375 (feedback gain 2.01, 0.5 ohm \
         sense), the 14-bit current monitor and pot reported as ADC + 8192 over \
         0..2.5 V. Snake axes are small geared motors; masters reuse the Classic \
         MTM factors. The DQLA mapping of the same robots is snake-36axes.json.",
        vec![
            robot("SNAKE1", "S001", snake, &[0, 1], &snake_robot_axes()),
            robot("SNAKE2", "S002", snake, &[2, 3], &snake_robot_axes()),
            robot("MASTER1", "M001", snake, &[4], &mtm_axes(true)),
            robot("MASTER2", "M002", snake, &[5], &mtm_axes(false)),
        ],
    )
}

/// Every shipped configuration with its file name under `configs/`.
pub fn shipped() -> [(&'static str, IoConfig); 8] {
    [
        ("dvrk-seed000.json", dvrk_seed000()),
        ("bench-1board.json", bench_1board()),
        ("snake-36axes.json", snake_36axes()),
        ("dvrk-psm1-28007.json", stock_psm1()),
        ("dvrk-mtmr-28247.json", stock_mtmr()),
        ("dvrk-ecm-29738.json", stock_ecm()),
        ("snake-seed001.json", snake_seed001()),
        ("dvrk-dqla-rev9.json", dqla_rev9()),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate() {
        for (name, c) in shipped() {
            c.validate(name).unwrap_or_else(|e| panic!("{e}"));
        }
    }

    #[test]
    fn rounding_helpers() {
        assert_eq!(round_sig(10.80163, 4), 10.8);
        assert_eq!(round_sig(-0.0123456, 3), -0.0123);
        assert_eq!(round_sig(0.0, 3), 0.0);
        assert_eq!(round_to(1.0 / 5242.88, 9), 0.000190735);
    }
}
