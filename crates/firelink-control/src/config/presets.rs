//! The shipped configurations, built in code.
//!
//! `configs/*.json` at the repository root are these values written by
//! `cargo run -p firelink-control --example write_configs`; a test checks
//! that the files and the code agree. Tests and tools can use the functions
//! directly without reading files.
//!
//! Where the numbers come from: the conversion formulas and the per-joint
//! facts (encoder counts per turn, gear ratios, motor torque constants,
//! maximum currents, drive directions, soft limits, pot tolerances) are the
//! public ones of the dVRK's Classic MTM and PSM as used by its
//! configuration generator for QLA1 boards. Calibration-specific values
//! (pot gains and offsets) and the Firelink extensions (velocity and
//! following-error limits, PID gains, homing moves) are plausible choices,
//! not a calibrated robot's.

use super::{
    ActuatorConfig, DriveConfig, EncoderConfig, HardwareVersion, HomingDefaults, IoConfig,
    JointType, Limits, LimitsConfig, LinearFunction, PlantPreset, PotentiometerConfig,
    PotentiometerTolerance, PotentiometersConfig, PotentiometersType, RobotConfig, SCHEMA_ID,
    SCHEMA_VERSION, SimulationConfig, VelocitySource,
};
use crate::pid::PidGains;
use core::f64::consts::PI;
use firelink_wire::snake::analog;
use firelink_wire::snake::registers::Wiper;

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
}

impl Axis {
    fn drive(&self) -> DriveConfig {
        let amps_to_bits = self.direction * 32768.0 / QLA_FULL_SCALE_AMPS;
        DriveConfig {
            current_to_bits: LinearFunction {
                scale: round_to(amps_to_bits, 4),
                offset: 32768.0,
            },
            bits_to_current: LinearFunction {
                scale: round_to(1.0 / amps_to_bits, 9),
                offset: round_to(-self.direction * QLA_FULL_SCALE_AMPS, 4),
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

    /// A pot whose 0..4.5 V spans the soft range widened by half on each
    /// side, centred on it.
    fn potentiometer(&self) -> PotentiometerConfig {
        let span = 2.0 * (self.upper - self.lower);
        let scale = round_to(span / QLA_POT_VOLTS, 8);
        let centre = 0.5 * (self.lower + self.upper);
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
        number_of_brakes: None,
        brakes: None,
        potentiometers: Some(PotentiometersConfig {
            potentiometers_type: Some(PotentiometersType::Analog),
            tolerances,
            coupling: None,
            lookup_table_file: None,
        }),
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
    let plants = [
        PlantPreset::MtmJ1,
        PlantPreset::MtmJ2,
        PlantPreset::MtmJ3,
        PlantPreset::MtmJ4,
        PlantPreset::MtmJ5,
        PlantPreset::MtmJ6,
        PlantPreset::MtmJ7,
    ];
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
    let plants = [
        PlantPreset::PsmJ1,
        PlantPreset::PsmJ2,
        PlantPreset::PsmJ3,
        PlantPreset::PsmJ4,
        PlantPreset::PsmJ5,
        PlantPreset::PsmJ6,
        PlantPreset::PsmJ7,
    ];
    let gains = [
        (60.0, 2.0, 3.0),
        (60.0, 2.0, 3.0),
        (4000.0, 100.0, 100.0),
        (2.0, 0.1, 0.05),
        (2.0, 0.1, 0.05),
        (2.0, 0.1, 0.05),
        (2.0, 0.1, 0.05),
    ];
    let vmax = [1.5, 1.5, 0.2, 6.0, 6.0, 6.0, 6.0];
    (0..7)
        .map(|i| {
            let prismatic = i == 2;
            Axis {
                joint_type: if prismatic {
                    JointType::Prismatic
                } else {
                    JointType::Revolute
                },
                direction: direction[i],
                counts_per_turn: cpt[i],
                gear_ratio: gear[i],
                torque_constant: 0.0438,
                maximum_current: imax[i],
                lower: lower[i],
                upper: upper[i],
                pot_tolerance: if prismatic { 5.0 * MM } else { 5.0 * DEG },
                plant: plants[i],
                effort_gains: gains[i],
                velocity_limit: vmax[i],
                following_error: if prismatic { 0.02 } else { 0.35 },
                home: if prismatic { 50.0 * MM } else { 0.0 },
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
pub fn shipped() -> [(&'static str, IoConfig); 4] {
    [
        ("dvrk-seed000.json", dvrk_seed000()),
        ("bench-1board.json", bench_1board()),
        ("snake-36axes.json", snake_36axes()),
        ("snake-seed001.json", snake_seed001()),
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
