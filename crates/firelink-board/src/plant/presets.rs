//! Axis presets: a generic motor and the da Vinci Research Kit arm joints
//! (MTM, PSM, ECM).
//!
//! The values are *plausible*, not calibrated: motor data in the range of
//! the public Maxon catalogue for the motor classes the dVRK arms use
//! (RE 40 for the large PSM joints, RE 25 for the MTM arm joints and the
//! PSM tool actuators, RE 13-class for the MTM wrist), transmission ratios
//! and encoder resolutions of the order given in the public dVRK
//! configuration files (sawIntuitiveResearchKit), and loads estimated from
//! the arms' size. They make an emulated arm move and sound like one on
//! the bus; they do not reproduce a particular arm.
//!
//! Catalogue figures used (approximate, per motor class):
//!
//! | motor | kt (mNm/A) | R (ohm) | rotor inertia (g cm^2) |
//! |---|---|---|---|
//! | RE 40, 48 V winding | 60.3 | 1.16 | 134 |
//! | RE 25, 24 V winding | 23.4 | 2.3 | 10.5 |
//! | RE 13-class, 12 V winding | 9.0 | 10.0 | 0.6 |
//! | large (ECM joints 1-2) | 119 | 0.8 | 300 |
//!
//! The large class takes its torque constant from the public dVRK ECM
//! configuration (0.119 N m/A); its resistance and inertia are plausible
//! values for a motor of that size.
//!
//! Mechanical stops: 5 % of each joint's range beyond both ends, except
//! where the public dVRK software states the physical range: the MTM wrist
//! roll's lower stop is at -480 degrees (the console sets the roll encoder
//! there when its stop search stalls) and the roll turns about 2.6 turns
//! in all ("limited to ~2.6 turns"), so its upper stop is at +456 degrees.

use super::params::*;

/// Which motor class an axis uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MotorClass {
    Re40,
    Re25,
    Re13,
    Large,
}

fn motor(class: MotorClass) -> MotorParams {
    match class {
        MotorClass::Re40 => MotorParams {
            torque_constant: 0.0603,
            resistance: 1.16,
            rotor_inertia: 134e-7,
            viscous_friction: 4e-6,
            coulomb_friction: 4e-3,
        },
        MotorClass::Re25 => MotorParams {
            torque_constant: 0.0234,
            resistance: 2.3,
            rotor_inertia: 10.5e-7,
            viscous_friction: 1e-6,
            coulomb_friction: 1e-3,
        },
        MotorClass::Re13 => MotorParams {
            torque_constant: 0.009,
            resistance: 10.0,
            rotor_inertia: 0.6e-7,
            viscous_friction: 2e-7,
            coulomb_friction: 3e-4,
        },
        MotorClass::Large => MotorParams {
            torque_constant: 0.119,
            resistance: 0.8,
            rotor_inertia: 300e-7,
            viscous_friction: 1e-5,
            coulomb_friction: 8e-3,
        },
    }
}

/// Common shape of a preset joint.
struct Joint {
    name: &'static str,
    class: MotorClass,
    supply: f64,
    current_limit: f64,
    gear_ratio: f64,
    counts_per_rev: u32,
    inertia: f64,
    gravity: f64,
    /// Joint range, used to centre the potentiometer and to place the
    /// mechanical stops (5 % of the range beyond each end).
    range: (f64, f64),
}

/// How far beyond its range a preset joint's mechanical stops are, as a
/// fraction of the range.
const STOP_MARGIN: f64 = 0.05;

fn build(j: Joint) -> AxisParams {
    let span = (j.range.1 - j.range.0).abs().max(1e-6);
    // The range covers 80 % of the pot's 0..4.5 V, centred.
    let volts_per_unit = 0.8 * POT_FULL_SCALE_VOLTS / span;
    let middle = 0.5 * (j.range.0 + j.range.1);
    AxisParams {
        name: j.name.into(),
        has_motor: true,
        amplifier: AmplifierParams {
            current_limit: j.current_limit,
            supply_voltage: j.supply,
            ..AmplifierParams::default()
        },
        motor: motor(j.class),
        load: LoadParams {
            gear_ratio: j.gear_ratio,
            inertia: j.inertia,
            gravity: (j.gravity != 0.0).then_some(GravityParams {
                amplitude: j.gravity,
                phase: 0.0,
            }),
            spring: None,
            bias: 0.0,
            initial_position: 0.0,
        },
        encoder: EncoderParams {
            counts_per_rev: j.counts_per_rev,
            reversed: false,
        },
        pot: PotParams {
            volts_per_unit,
            offset_volts: POT_FULL_SCALE_VOLTS / 2.0 - volts_per_unit * middle,
            ..PotParams::default()
        },
        current_sense: CurrentSenseParams::default(),
        thermal: ThermalParams::default(),
        switches: SwitchParams::default(),
        stops: HardStops::new(
            j.range.0.min(j.range.1) - STOP_MARGIN * span,
            j.range.0.max(j.range.1) + STOP_MARGIN * span,
        ),
    }
}

/// A generic geared DC motor (RE 25 class, 24 V, 4000 counts per motor
/// revolution, 1:50 to a light load): the default for every axis.
pub fn generic_motor() -> AxisParams {
    build(Joint {
        name: "generic",
        class: MotorClass::Re25,
        supply: 24.0,
        current_limit: QLA_FULL_SCALE_AMPS,
        gear_ratio: 50.0,
        counts_per_rev: 4000,
        inertia: 0.005,
        gravity: 0.0,
        range: (-2.0, 2.0),
    })
}

/// A channel with no motor attached: the amplifier drives no current and
/// nothing moves (unused QLA channels).
pub fn unused_channel() -> AxisParams {
    let mut p = generic_motor();
    p.name = "unused".into();
    p.has_motor = false;
    p
}

/// A brake's coil on an amplifier channel: the amplifier drives current
/// into it (resistance and inductance of a small motor), nothing turns.
/// Which joint the brake holds is the board's wiring
/// ([`BrakeWire`](crate::qla::config::BrakeWire)).
pub fn brake_coil() -> AxisParams {
    let mut p = generic_motor();
    p.name = "brake coil".into();
    // Nothing to turn: a rotor held by friction no current can overcome.
    p.motor.coulomb_friction = 1.0e9;
    p
}

/// A da Vinci Research Kit master tool manipulator (MTM) joint, 1..=7; 8
/// is the gripper (a Hall-effect sensor on the analog input, no motor).
/// `None` for other numbers.
pub fn mtm_joint(joint: u8) -> Option<AxisParams> {
    use MotorClass::*;
    let (name, class, gear, cpr, inertia, gravity, range) = match joint {
        1 => (
            "MTM J1 outer yaw",
            Re25,
            63.41,
            4000,
            0.02,
            0.0,
            (-0.7, 1.2),
        ),
        2 => (
            "MTM J2 shoulder pitch",
            Re25,
            49.88,
            4000,
            0.03,
            0.4,
            (-0.3, 0.9),
        ),
        3 => (
            "MTM J3 elbow pitch",
            Re25,
            59.73,
            4000,
            0.01,
            0.25,
            (-0.25, 0.8),
        ),
        4 => (
            "MTM J4 platform",
            Re13,
            10.53,
            4000,
            0.001,
            0.0,
            (-4.0, 1.7),
        ),
        5 => (
            "MTM J5 wrist pitch",
            Re13,
            33.16,
            256,
            0.0005,
            0.0,
            (-1.6, 3.1),
        ),
        6 => (
            "MTM J6 wrist yaw",
            Re13,
            33.16,
            256,
            0.0003,
            0.0,
            (-0.8, 0.8),
        ),
        7 => (
            "MTM J7 wrist roll",
            Re13,
            16.58,
            256,
            0.0002,
            0.0,
            (-7.7, 7.7),
        ),
        8 => return Some(mtm_gripper()),
        _ => return None,
    };
    let current_limit = if class == Re25 { 0.8 } else { 0.4 };
    let mut p = build(Joint {
        name,
        class,
        supply: 24.0,
        current_limit,
        gear_ratio: gear,
        counts_per_rev: cpr,
        inertia,
        gravity,
        range,
    });
    if joint == 7 {
        p.stops = HardStops::new(MTM_ROLL_LOWER_STOP, MTM_ROLL_UPPER_STOP);
    }
    Some(p)
}

/// The MTM gripper's Hall-effect sensor, degrees per volt and degrees at
/// 0 V: the conversion the dVRK's configuration generator writes for every
/// MTM gripper (`VoltsToPosSI`, scale -23.1788, offset 91.4238), so the
/// sensor reads 3.94 V closed and 1.36 V at 60 degrees.
pub const MTM_GRIPPER_DEG_PER_VOLT: f64 = -23.1788;
/// See [`MTM_GRIPPER_DEG_PER_VOLT`].
pub const MTM_GRIPPER_DEG_AT_ZERO_VOLTS: f64 = 91.4238;
/// Where the MTM gripper's spring holds it when nobody squeezes it, rad:
/// fully open, the top of the 0 to 60 degrees the dVRK console maps onto
/// the PSM's jaw (`mtsTeleOperationPSM`'s `gripper.max`).
pub const MTM_GRIPPER_REST: f64 = 60.0 * core::f64::consts::PI / 180.0;
/// The stiffness of the MTM gripper's opening spring, N m/rad.
pub const MTM_GRIPPER_SPRING: f64 = 0.02;

/// The MTM gripper: two spring-loaded levers the operator pinches, the
/// angle between them read by a Hall-effect sensor on the QLA channel's
/// analog input (no motor, no encoder). Joint units are radians of
/// opening: 0 is closed (a closed PSM jaw), the spring holds it open at
/// [`MTM_GRIPPER_REST`]; the levers stop 10 degrees past closed (squeezed
/// hard) and at 65 degrees. A hand pinches it with an external torque
/// ([`Axis::set_external_torque`](super::Axis::set_external_torque));
/// viscous friction makes the levers settle in about 50 ms.
pub fn mtm_gripper() -> AxisParams {
    let mut p = unused_channel();
    p.name = "MTM gripper".into();
    let rad_per_deg = core::f64::consts::PI / 180.0;
    let volts_per_rad = 1.0 / (MTM_GRIPPER_DEG_PER_VOLT * rad_per_deg);
    p.pot.volts_per_unit = volts_per_rad;
    p.pot.offset_volts = -MTM_GRIPPER_DEG_AT_ZERO_VOLTS / MTM_GRIPPER_DEG_PER_VOLT;
    p.motor.rotor_inertia = 1.0e-6;
    p.motor.viscous_friction = 1.0e-3;
    p.motor.coulomb_friction = 2.0e-4;
    p.load = LoadParams {
        gear_ratio: 1.0,
        inertia: 2.0e-5,
        gravity: None,
        spring: Some(SpringParams {
            stiffness: MTM_GRIPPER_SPRING,
            rest: MTM_GRIPPER_REST,
        }),
        bias: 0.0,
        initial_position: MTM_GRIPPER_REST,
    };
    p.stops = HardStops::new(-10.0 * rad_per_deg, 65.0 * rad_per_deg);
    p
}

/// The MTM wrist roll's lower mechanical stop, rad: -480 degrees, where
/// the dVRK console sets the roll encoder when its stop search stalls.
pub const MTM_ROLL_LOWER_STOP: f64 = -480.0 * core::f64::consts::PI / 180.0;

/// The MTM wrist roll's upper mechanical stop, rad: about 2.6 turns above
/// the lower one (+456 degrees).
pub const MTM_ROLL_UPPER_STOP: f64 = MTM_ROLL_LOWER_STOP + 2.6 * 2.0 * core::f64::consts::PI;

/// A da Vinci Research Kit patient side manipulator (PSM) joint, 1..=7:
/// outer yaw, outer pitch, insertion (prismatic: metres, gear ratio in
/// motor radians per metre), and the four tool actuators. `None` for other
/// numbers.
pub fn psm_joint(joint: u8) -> Option<AxisParams> {
    use MotorClass::*;
    let (name, class, gear, cpr, inertia, gravity, range, limit) = match joint {
        1 => (
            "PSM J1 outer yaw",
            Re40,
            56.50,
            4000,
            0.15,
            0.0,
            (-1.6, 1.6),
            2.2,
        ),
        2 => (
            "PSM J2 outer pitch",
            Re40,
            56.50,
            4000,
            0.15,
            2.0,
            (-0.8, 0.8),
            2.2,
        ),
        3 => (
            "PSM J3 insertion",
            Re40,
            336.6,
            4000,
            0.8,
            0.0,
            (0.0, 0.24),
            2.2,
        ),
        4 => (
            "PSM J4 tool roll",
            Re25,
            11.71,
            4000,
            0.0002,
            0.0,
            (-4.5, 4.5),
            1.0,
        ),
        5 => (
            "PSM J5 tool pitch",
            Re25,
            11.71,
            4000,
            0.0002,
            0.0,
            (-1.5, 1.5),
            1.0,
        ),
        6 => (
            "PSM J6 tool yaw 1",
            Re25,
            11.71,
            4000,
            0.0001,
            0.0,
            (-1.5, 1.5),
            1.0,
        ),
        7 => (
            "PSM J7 tool yaw 2",
            Re25,
            11.71,
            4000,
            0.0001,
            0.0,
            (-1.5, 1.5),
            1.0,
        ),
        _ => return None,
    };
    Some(build(Joint {
        name,
        class,
        supply: if class == Re40 { 48.0 } else { 24.0 },
        current_limit: limit,
        gear_ratio: gear,
        counts_per_rev: cpr,
        inertia,
        gravity,
        range,
    }))
}

/// A da Vinci Research Kit endoscope camera manipulator (ECM) joint,
/// 1..=4: outer yaw, outer pitch, insertion (prismatic: metres, gear
/// ratio in motor radians per metre) and the camera roll. Ranges are the
/// public Classic ECM soft limits; gear ratios and encoder resolutions
/// those of its public configuration. The ECM's brakes are not modelled,
/// so neither is gravity (a braked arm does not fall; an emulated one
/// without brakes would). `None` for other numbers.
pub fn ecm_joint(joint: u8) -> Option<AxisParams> {
    use MotorClass::*;
    const DEG: f64 = core::f64::consts::PI / 180.0;
    let (name, class, gear, cpr, inertia, range, limit) = match joint {
        1 => (
            "ECM J1 outer yaw",
            Large,
            240.0,
            4000,
            0.6,
            (-90.0 * DEG, 90.0 * DEG),
            1.0,
        ),
        2 => (
            "ECM J2 outer pitch",
            Large,
            240.0,
            4000,
            0.6,
            (-45.0 * DEG, 64.0 * DEG),
            1.0,
        ),
        3 => (
            "ECM J3 insertion",
            Re25,
            2748.55,
            640,
            1.5,
            (0.0, 0.255),
            0.8,
        ),
        4 => (
            "ECM J4 camera roll",
            Re13,
            300.15,
            64,
            0.002,
            (-89.0 * DEG, 89.0 * DEG),
            0.7,
        ),
        _ => return None,
    };
    Some(build(Joint {
        name,
        class,
        supply: if class == Large { 48.0 } else { 24.0 },
        current_limit: limit,
        gear_ratio: gear,
        counts_per_rev: cpr,
        inertia,
        gravity: 0.0,
        range,
    }))
}

/// A dVRK arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arm {
    /// Master tool manipulator: joints 1..=7 and the gripper (8).
    Mtm,
    /// Patient side manipulator: joints 1..=7.
    Psm,
    /// Endoscope camera manipulator: joints 1..=4.
    Ecm,
}

/// The axes of board `index` (0-based) of an arm, `per_board` axes each,
/// as the dVRK wires them: joints in order, unused channels after the
/// last joint. For QLA1 boards (4 axes) an arm takes two boards; for a
/// DQLA (8 axes), one.
pub fn arm_axes(arm: Arm, index: usize, per_board: usize) -> Vec<AxisParams> {
    (0..per_board)
        .map(|k| {
            let joint = index * per_board + k + 1;
            let joint = u8::try_from(joint).unwrap_or(u8::MAX);
            match arm {
                Arm::Mtm => mtm_joint(joint),
                Arm::Psm => psm_joint(joint),
                Arm::Ecm => ecm_joint(joint),
            }
            .unwrap_or_else(unused_channel)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_complete_and_sane() {
        for j in 1..=8 {
            let p = mtm_joint(j).unwrap();
            assert_eq!(p.sanitized(), p, "{}", p.name);
        }
        for j in 1..=7 {
            let p = psm_joint(j).unwrap();
            assert_eq!(p.sanitized(), p, "{}", p.name);
            // The joint range stays inside the pot range.
            assert!(p.pot.offset_volts > 0.0 && p.pot.offset_volts < POT_FULL_SCALE_VOLTS);
        }
        for j in 1..=4 {
            let p = ecm_joint(j).unwrap();
            assert_eq!(p.sanitized(), p, "{}", p.name);
        }
        assert!(mtm_joint(0).is_none() && mtm_joint(9).is_none() && psm_joint(8).is_none());
        assert!(ecm_joint(5).is_none());
        // Every motorised preset joint has stops that its pot can see.
        for p in (1..=7)
            .filter_map(mtm_joint)
            .chain((1..=7).filter_map(psm_joint))
            .chain((1..=4).filter_map(ecm_joint))
        {
            let (lo, hi) = (p.stops.lower.unwrap(), p.stops.upper.unwrap());
            let (pot_lo, pot_hi) = p.pot_position_range().unwrap();
            assert!(pot_lo < lo && hi < pot_hi, "{}", p.name);
        }
        let roll = mtm_joint(7).unwrap().stops;
        assert!((roll.lower.unwrap().to_degrees() + 480.0).abs() < 1e-9);
        assert!((roll.upper.unwrap().to_degrees() - 456.0).abs() < 1e-9);
        let board2 = arm_axes(Arm::Psm, 1, 4);
        assert_eq!(board2.len(), 4);
        assert_eq!(board2[0].name, "PSM J5 tool pitch");
        assert!(!board2[3].has_motor);
        assert_eq!(arm_axes(Arm::Mtm, 0, 8)[7].name, "MTM gripper");
    }

    #[test]
    fn the_mtm_gripper_rests_open_and_closes_when_pinched() {
        use crate::plant::{DEFAULT_STEP, Plant};
        use firelink_bus::time::{SimDuration, SimTime};
        // The dVRK's conversion of the sensor's voltage, degrees.
        let read = |volts: f64| MTM_GRIPPER_DEG_PER_VOLT * volts + MTM_GRIPPER_DEG_AT_ZERO_VOLTS;
        let mut plant = Plant::new(vec![mtm_gripper()], 7, DEFAULT_STEP);
        plant.advance_to(SimTime::ZERO + SimDuration::from_millis(500));
        // At rest, open: 60 degrees, 1.36 V (not 0 V, not a rail).
        let v = plant.pot_voltage(0);
        assert!((v - 1.3557).abs() < 1e-3, "{v}");
        assert!((read(v) - 60.0).abs() < 1e-6);
        // Pinched to 20 degrees: the force that holds the levers there
        // against the spring; they settle within 0.5 s (to within the
        // levers' dry friction, 0.6 degrees).
        let target = 20f64.to_radians();
        let force = MTM_GRIPPER_SPRING * (target - MTM_GRIPPER_REST);
        if let Some(a) = plant.axis_mut(0) {
            a.set_external_torque(force);
        }
        plant.advance_to(SimTime::ZERO + SimDuration::from_millis(1000));
        let pinched = read(plant.pot_voltage(0));
        assert!((pinched - 20.0).abs() < 1.0, "{pinched}");
        // Squeezed hard: it stops 10 degrees past closed.
        if let Some(a) = plant.axis_mut(0) {
            a.set_external_torque(-1.0);
        }
        plant.advance_to(SimTime::ZERO + SimDuration::from_millis(1500));
        assert!((read(plant.pot_voltage(0)) + 10.0).abs() < 1e-6);
        // Let go: back open.
        if let Some(a) = plant.axis_mut(0) {
            a.set_external_torque(0.0);
        }
        plant.advance_to(SimTime::ZERO + SimDuration::from_millis(3000));
        let open = read(plant.pot_voltage(0));
        assert!((open - 60.0).abs() < 1.0, "{open}");
    }
}
