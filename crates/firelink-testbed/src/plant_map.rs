//! How a configuration's actuator becomes an emulated joint: its plant, its
//! mechanical stops, what its potentiometer measures, how its amplifier's
//! calibration shows, and what is plugged into its boards (a PSM's sterile
//! adapter and instrument). [`plant_for`] gives a joint's plant;
//! [`rig::board_configs`](crate::rig::board_configs) uses it.
//!
//! The emulated robot agrees with its configuration as a calibrated robot
//! agrees with its own: the encoder and the pot measure the same joint
//! through the configuration's conversions, over the whole mechanical
//! range.
//!
//! **Stops.** Each joint stops at the configuration's
//! `simulation.hard_stops`; without them, at the arm's physical range where
//! Firelink knows it (the MTM wrist roll: -480 to +456 degrees, from the
//! dVRK console), else 3 degrees (3 mm) beyond the soft limits. The stops
//! stay where the arm has them whatever the pot can read: past the end of
//! its electrical range (0 to 4.5 V through the configuration's pot
//! conversion) the pot saturates, as a real one does (the MTM roll's pot
//! reads about half a turn of the roll's 2.6). [`notes`] says where a pot
//! the configuration checks saturates before a stop.
//!
//! **Coupled pots.** Where a robot's `potentiometers.coupling` says its
//! pots sit on joints that several actuators move (the dVRK MTM), each pot
//! measures its joint, `inverse(JointToActuatorPosition) x actuators`, as
//! the real arm's do; the host turns them back into actuator space.

use firelink_board::plant::presets;
use firelink_board::plant::{AxisParams, HardStops, POT_FULL_SCALE_VOLTS};
use firelink_board::qla::config::{BrakeLine, BrakeWire, Instrument};
use firelink_control::config::presets::{STOP_MARGIN_M, STOP_MARGIN_RAD};
use firelink_control::config::{
    ActuatorConfig, DigitalInputConfig, DvrkArm, IoConfig, JointRef, JointType, PlantPreset,
    RobotConfig,
};

/// Where a joint starts, inside its soft limits (a little off centre, so
/// homing has something to do).
pub fn start_position(config: &IoConfig, joint: usize) -> f64 {
    config.joints().nth(joint).map_or(0.0, |j| {
        let l = j.actuator.encoder.position_limits_soft;
        0.5 * (l.lower + l.upper) + 0.05 * l.span() * ((joint % 5) as f64 - 2.0) / 2.0
    })
}

/// The plant model a configuration's actuator names, with its
/// transmission, encoder, pot, drive direction, amplifier calibration and
/// mechanical stops made to agree with the configuration, as a calibrated
/// robot's configuration agrees with the robot (see the module doc),
/// starting at [`start_position`]. An actuator without a `simulation`
/// section drives what its robot's dVRK arm has there (by the robot's
/// name: `MTMR`, `PSM1`, `ECM`, ...), else a generic motor.
pub fn plant_for(config: &IoConfig, joint: usize) -> Option<AxisParams> {
    plant_starting_at(config, joint, start_position(config, joint))
}

/// [`plant_for`], the joint starting at `start` (joint units).
pub fn plant_starting_at(config: &IoConfig, joint: usize, start: f64) -> Option<AxisParams> {
    let j = config.joints().nth(joint)?;
    let a = j.actuator;
    let mut p = preset_params(plant_preset(&j));
    let scale = a.encoder.bits_to_position.scale;
    let cpt = a
        .encoder
        .counts_per_turn
        .unwrap_or(p.encoder.counts_per_rev);
    let gear = 2.0 * std::f64::consts::PI / (f64::from(cpt) * scale.abs());
    // A negative transmission ratio turns both the drive and the encoder
    // around, as the configuration's direction -1 says.
    p.load.gear_ratio = gear * scale.signum();
    p.encoder.counts_per_rev = cpt;
    p.encoder.reversed = false;
    // Motor torque constant as the configuration models it.
    let e2c = a.drive.effort_to_current.scale.abs();
    if e2c > 0.0 {
        p.motor.torque_constant = 1.0 / (gear * e2c);
    }
    p.amplifier.current_limit = p.amplifier.current_limit.max(a.drive.maximum_current);
    if let Some(pot) = a.potentiometer {
        let vs = pot.voltage_to_position.scale;
        if vs != 0.0 {
            p.pot.volts_per_unit = 1.0 / vs;
            p.pot.offset_volts = -pot.voltage_to_position.offset / vs;
        }
    }
    p.load.initial_position = start;
    apply(&j, &mut p);
    Some(p)
}

/// The emulator's parameters of a named plant.
pub fn preset_params(preset: PlantPreset) -> AxisParams {
    use PlantPreset::*;
    let (mtm, psm) = match preset {
        MtmJ1 => (Some(1), None),
        MtmJ2 => (Some(2), None),
        MtmJ3 => (Some(3), None),
        MtmJ4 => (Some(4), None),
        MtmJ5 => (Some(5), None),
        MtmJ6 => (Some(6), None),
        MtmJ7 => (Some(7), None),
        PsmJ1 => (None, Some(1)),
        PsmJ2 => (None, Some(2)),
        PsmJ3 => (None, Some(3)),
        PsmJ4 => (None, Some(4)),
        PsmJ5 => (None, Some(5)),
        PsmJ6 => (None, Some(6)),
        PsmJ7 => (None, Some(7)),
        EcmJ1 => return presets::ecm_joint(1).unwrap_or_else(presets::generic_motor),
        EcmJ2 => return presets::ecm_joint(2).unwrap_or_else(presets::generic_motor),
        EcmJ3 => return presets::ecm_joint(3).unwrap_or_else(presets::generic_motor),
        EcmJ4 => return presets::ecm_joint(4).unwrap_or_else(presets::generic_motor),
        MtmGripper => (Some(8), None),
        Generic => (None, None),
    };
    mtm.and_then(presets::mtm_joint)
        .or_else(|| psm.and_then(presets::psm_joint))
        .unwrap_or_else(presets::generic_motor)
}

/// How far inside the end of its electrical range a pot still reads its
/// joint, V: well above its noise (0.5 mV) and an ADC count (69 uV).
const POT_END_GUARD_VOLTS: f64 = 0.005;

/// The plant an actuator gets: its `simulation.plant`, else what its
/// robot's dVRK arm has at that index, else a generic motor.
pub fn plant_preset(joint: &JointRef<'_>) -> PlantPreset {
    joint
        .actuator
        .simulation
        .map(|s| s.plant)
        .or_else(|| {
            joint
                .robot
                .dvrk_arm()
                .and_then(|arm| arm.plant(joint.actuator_index))
        })
        .unwrap_or(PlantPreset::Generic)
}

/// Where a joint's mechanical stops are, before the pot has its say (see
/// the module docs).
pub fn stated_stops(joint: &JointRef<'_>) -> (f64, f64) {
    let a = joint.actuator;
    let soft = a.encoder.position_limits_soft;
    if let Some(s) = a.simulation.and_then(|s| s.hard_stops) {
        return (s.lower, s.upper);
    }
    if plant_preset(joint) == PlantPreset::MtmJ7 {
        let (lo, hi) = (presets::MTM_ROLL_LOWER_STOP, presets::MTM_ROLL_UPPER_STOP);
        if lo <= soft.lower && soft.upper <= hi {
            return (lo, hi);
        }
    }
    let margin = if a.joint_type == Some(JointType::Prismatic) {
        STOP_MARGIN_M
    } else {
        STOP_MARGIN_RAD
    };
    (soft.lower - margin, soft.upper + margin)
}

/// What one actuator's pot measures: weights of its robot's actuators
/// (actuator index, weight). Without a coupling, the actuator itself.
fn pot_weights(joint: &JointRef<'_>) -> Vec<(usize, f64)> {
    let coupled = joint.robot.pot_coupling().and_then(|j2a| j2a.inverse());
    match coupled {
        Some(a2j) => (0..joint.robot.actuators.len())
            .map(|s| (s, a2j.get(joint.actuator_index, s)))
            .filter(|&(_, w)| w != 0.0)
            .collect(),
        None => vec![(joint.actuator_index, 1.0)],
    }
}

/// Whether an actuator's pot measures only its own actuator.
fn pot_is_own(joint: &JointRef<'_>) -> bool {
    matches!(pot_weights(joint).as_slice(), [(s, w)] if *s == joint.actuator_index && *w == 1.0)
}

/// Sets the plant's stops, pot coupling and amplifier calibration from the
/// configuration (the transmission, encoder and pot conversion are already
/// set by the caller).
pub fn apply(joint: &JointRef<'_>, p: &mut AxisParams) {
    let a = joint.actuator;
    // Stops where the arm has them; the pot saturates where it must.
    let (lo, hi) = stated_stops(joint);
    if lo < hi {
        p.stops = HardStops::new(lo, hi);
    }
    p.load.initial_position = p.stops.clamp(p.load.initial_position);
    // A pot on a joint several actuators move.
    if !pot_is_own(joint) {
        p.pot.measures = pot_weights(joint)
            .into_iter()
            .filter_map(|(s, w)| {
                let other = joint.robot.actuators.get(s)?;
                (other.board_id == a.board_id).then_some((usize::from(other.axis_id), w))
            })
            .collect();
    }
    calibrate_amplifier(a, p);
}

/// The positions the pot reads between the ends of its electrical range,
/// [`POT_END_GUARD_VOLTS`] inside them (where it still reads the joint
/// through its noise).
fn pot_visible_range(p: &AxisParams) -> Option<(f64, f64)> {
    let k = p.pot.volts_per_unit.abs();
    let (lo, hi) = p.pot_position_range()?;
    let guard = POT_END_GUARD_VOLTS / k;
    (lo + guard < hi - guard).then_some((lo + guard, hi - guard))
}

/// The amplifier delivers no current at the configuration's calibrated DAC
/// code, and its current sense reads so that the configuration's feedback
/// conversion gives the true current.
fn calibrate_amplifier(a: &ActuatorConfig, p: &mut AxisParams) {
    let c2b = a.drive.current_to_bits;
    let b2c = a.drive.bits_to_current;
    if (0.0..=65535.0).contains(&c2b.offset) {
        p.amplifier.zero_code = c2b.offset.round() as u16;
    }
    // Plant amperes per configured ampere (+-1 for the QLA's own scale).
    let k = c2b.scale * p.amplifier.amps_per_bit;
    let zero_reading = b2c.scale * f64::from(firelink_board::plant::DAC_ZERO) + b2c.offset;
    // Below 0.1 mA (half an ADC count) it is the rounding of the file's
    // numbers, not a calibration.
    let offset = -k * zero_reading;
    if offset.is_finite() && (1e-4..1.0).contains(&offset.abs()) {
        p.current_sense.offset_amps = offset;
    }
}

/// Where a robot's MTM gripper is wired: the axis after its last actuator
/// (board ID, axis), if that axis exists on a QLA1 or DQLA board.
pub fn gripper_slot(robot: &RobotConfig) -> Option<(u8, u8)> {
    if robot.dvrk_arm() != Some(DvrkArm::Mtm) {
        return None;
    }
    let last = robot.actuators.get(DvrkArm::Mtm.actuators() - 1)?;
    let axis = last.axis_id.checked_add(1)?;
    (axis < robot.hardware_version.axes()).then_some((last.board_id, axis))
}

/// The MTM gripper's plant: a Hall-effect sensor on the analog input, no
/// motor.
pub fn gripper_params() -> AxisParams {
    presets::mtm_joint(8).unwrap_or_else(presets::unused_channel)
}

/// Whether the switch behind a v6 digital input is pressed: the PSM's
/// sterile adapter and instrument contacts (`<robot>_adapter`,
/// `<robot>_tool`) as the robot's simulation section puts them in; every
/// other input as its own `simulation.pressed` says, released unless told.
pub fn input_pressed(config: &IoConfig, input: &DigitalInputConfig) -> bool {
    let name = input.name.as_str();
    let contact = config.robots.iter().find_map(|r| {
        let sim = r.simulation.as_ref();
        let tool = sim.is_some_and(|s| s.tool.is_some());
        let adapter = tool || sim.is_some_and(|s| s.adapter);
        if name == format!("{}_adapter", r.name) {
            Some(adapter)
        } else if name == format!("{}_tool", r.name) {
            Some(tool)
        } else {
            None
        }
    });
    contact.unwrap_or_else(|| input.simulation.is_some_and(|s| s.pressed))
}

/// Per board ID, the digital input lines held high (DIGIN bits 11:0).
///
/// Each v6 digital input is a switch on its line: pressed or released
/// ([`input_pressed`]), it puts the level on the line that the dVRK reads
/// as that state: low for pressed when `pressed_value` is true (every
/// stock button, pedal and contact), high for pressed when it is false
/// ([`DigitalInputConfig::line_level`]). A line no input names stays low.
pub fn input_lines(config: &IoConfig) -> [u16; 16] {
    let mut lines = [0u16; 16];
    for input in config.digital_inputs.iter().flatten() {
        let high = input.line_level(input_pressed(config, input));
        if let Some(l) = lines.get_mut(usize::from(input.board_id)) {
            if high && input.bit_id < 12 {
                *l |= 1 << input.bit_id;
            }
        }
    }
    lines
}

/// The brakes of every robot, as (board ID, wire) pairs: brake `i` of a
/// robot's `brakes` holds its actuator `i` (the dVRK's order: the ECM's
/// three brakes hold its first three joints) and is driven by the channel
/// the entry names. The brake opens at the middle of its holding
/// (`released_current`) and release (`release_current`) currents and
/// closes below half the holding current.
pub fn brake_wires(config: &IoConfig) -> Vec<(u8, BrakeWire)> {
    let mut out = Vec::new();
    for robot in &config.robots {
        for (brake, actuator) in robot.brakes.iter().flatten().zip(&robot.actuators) {
            let (Some(open), Some(hold)) = (brake.opening_current(), brake.holding_current())
            else {
                continue;
            };
            let line = BrakeLine::new();
            out.push((
                brake.board_id,
                BrakeWire::drives(usize::from(brake.axis_id), line.clone(), open, hold),
            ));
            out.push((
                actuator.board_id,
                BrakeWire::Holds {
                    axis: usize::from(actuator.axis_id),
                    line,
                },
            ));
        }
    }
    out
}

/// Per board ID, the instrument whose 1-wire memory it reads: a robot's
/// `simulation.tool`, on the board of its Dallas chip (`<robot>_dallas`
/// in the v6 `dallas_chips`), else on its last board.
pub fn instruments(config: &IoConfig) -> Vec<(u8, Instrument)> {
    config
        .robots
        .iter()
        .filter_map(|r| {
            let tool = r.simulation.as_ref()?.tool.as_ref()?;
            let dallas = config
                .dallas_chips
                .as_ref()
                .and_then(serde_json::Value::as_array)
                .and_then(|chips| {
                    chips.iter().find(|c| {
                        c.get("name").and_then(serde_json::Value::as_str)
                            == Some(&format!("{}_dallas", r.name))
                    })
                })
                .and_then(|c| c.get("board_id")?.as_u64())
                .and_then(|b| u8::try_from(b).ok());
            let board = dallas.or_else(|| r.actuators.iter().map(|a| a.board_id).max())?;
            Some((
                board,
                Instrument {
                    model: tool.model,
                    version: tool.version,
                    name: tool.name.clone(),
                },
            ))
        })
        .collect()
}

/// What the emulated robot cannot make agree with the configuration, one
/// sentence each: a pot the configuration checks (pot tolerance above 0)
/// that saturates before the joint's stops, pots coupled to actuators on
/// another board.
pub fn notes(config: &IoConfig) -> Vec<String> {
    let mut out = Vec::new();
    for j in config.joints() {
        let Some(p) = plant_for(config, j.index) else {
            continue;
        };
        let soft = j.actuator.encoder.position_limits_soft;
        let (lo, hi) = stated_stops(&j);
        let checked = j
            .potentiometer_tolerance()
            .is_some_and(|t| t.distance > 0.0);
        if checked && pot_is_own(&j) && j.actuator.potentiometer.is_some() {
            if let Some((pot_lo, pot_hi)) = pot_visible_range(&p) {
                if pot_lo > lo || pot_hi < hi {
                    out.push(format!(
                        "{}: the pot conversion reads only [{pot_lo:.4}, {pot_hi:.4}] within \
                         0..{POT_FULL_SCALE_VOLTS} V, the stops are at [{lo:.4}, {hi:.4}]: past \
                         it the pot saturates and disagrees with the encoder{}",
                        j.label,
                        if pot_lo > soft.lower || pot_hi < soft.upper {
                            ", inside the soft limits (the pot check faults there)"
                        } else {
                            ""
                        }
                    ));
                }
            }
        }
        let across = pot_weights(&j)
            .iter()
            .filter_map(|&(s, _)| j.robot.actuators.get(s))
            .any(|o| o.board_id != j.actuator.board_id);
        if across {
            out.push(format!(
                "{}: its pot is coupled to actuators on another board; only those on board {} \
                 are emulated",
                j.label, j.actuator.board_id
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_board::qla::config::Profile;
    use firelink_control::config::{ToolConfig, presets};

    /// How sawRobotIO1394 reads a digital input (`mtsDigitalInput1394::
    /// PollState`), written here from its source, apart from Firelink's
    /// own reader: the masked DIGIN bit set reads `!pressed_value`, clear
    /// reads `pressed_value`.
    fn dvrk_reads_pressed(digin: u32, bit_id: u8, pressed_value: bool) -> bool {
        if digin & (1u32 << bit_id) != 0 {
            !pressed_value
        } else {
            pressed_value
        }
    }

    /// What the console reads for input `name` from the emulated boards.
    fn console_reads(config: &IoConfig, name: &str) -> bool {
        let input = config.digital_input(name).unwrap();
        let boards = crate::rig::board_configs(config, Profile::Rev8, 16);
        let digin = u32::from(boards[usize::from(input.board_id)].input_lines);
        let pressed = dvrk_reads_pressed(digin, input.bit_id, input.pressed_value);
        // Firelink's own host side reads it by the same rule.
        assert_eq!(config.input_pressed(name, digin), Some(pressed), "{name}");
        pressed
    }

    #[test]
    fn the_console_reads_the_psm_contacts_and_clutches_as_plugged_in() {
        let mut config = presets::stock_psm1();
        // As shipped: the sterile adapter on, no instrument, clutches
        // released. Every input has pressed_value true: pressed is low.
        assert!(console_reads(&config, "PSM1_adapter"));
        assert!(!console_reads(&config, "PSM1_tool"));
        assert!(!console_reads(&config, "PSM1_arm_clutch"));
        assert!(!console_reads(&config, "PSM1_SUJ_clutch"));
        assert_eq!(input_lines(&config)[7], 1 << 7, "adapter low, tool high");
        assert_eq!(input_lines(&config)[6], (1 << 0) | (1 << 2));
        assert!(instruments(&config).is_empty());
        if let Some(sim) = config.robots[0].simulation.as_mut() {
            sim.tool = Some(ToolConfig {
                name: "LARGE_NEEDLE_DRIVER".into(),
                model: 400_006,
                version: 12,
            });
        }
        assert!(console_reads(&config, "PSM1_adapter"));
        assert!(console_reads(&config, "PSM1_tool"));
        let boards = crate::rig::board_configs(&config, Profile::Rev8, 8);
        let b7 = &boards[7];
        assert_eq!(b7.input_lines, 0, "both contacts closed: both lines low");
        let tool = b7.instrument.as_ref().unwrap();
        assert_eq!((tool.model, tool.version), (400_006, 12));
        assert_eq!(&tool.memory()[0x80..0x83], b"997");
        assert!(boards[6].instrument.is_none());
        // Nothing plugged in: neither contact reads pressed.
        if let Some(sim) = config.robots[0].simulation.as_mut() {
            sim.tool = None;
            sim.adapter = false;
        }
        assert!(!console_reads(&config, "PSM1_adapter"));
        assert!(!console_reads(&config, "PSM1_tool"));
        // The other polarity: pressed is high.
        for d in config.digital_inputs.iter_mut().flatten() {
            d.pressed_value = false;
        }
        assert_eq!(input_lines(&config)[7], 0, "released contacts low");
        if let Some(sim) = config.robots[0].simulation.as_mut() {
            sim.adapter = true;
        }
        assert!(console_reads(&config, "PSM1_adapter"));
        assert!(!console_reads(&config, "PSM1_tool"));
        assert_eq!(input_lines(&config)[7], 1 << 10);
    }

    #[test]
    fn pedals_and_buttons_rest_as_the_configuration_says() {
        // A foot-pedal file as the dVRK lays them out (its own values):
        // every pedal released unless its simulation section says pressed.
        let text = serde_json::json!({
            "$id": "saw-robot-io.schema.json", "$version": "6",
            "robots": [],
            "digital_inputs": [
                { "name": "Clutch", "board_id": 1, "bit_id": 3, "pressed_value": true,
                  "trigger_when_pressed": true, "trigger_when_released": true },
                { "name": "Camera", "board_id": 1, "bit_id": 2, "pressed_value": true,
                  "trigger_when_pressed": true, "trigger_when_released": true },
                { "name": "Coag", "board_id": 1, "bit_id": 0, "pressed_value": true,
                  "trigger_when_pressed": true, "trigger_when_released": true,
                  "simulation": { "pressed": true } },
                { "name": "HeadSensor", "board_id": 1, "bit_id": 5, "pressed_value": false,
                  "trigger_when_pressed": true, "trigger_when_released": true },
                { "name": "Door", "board_id": 1, "bit_id": 6, "pressed_value": false,
                  "trigger_when_pressed": true, "trigger_when_released": true,
                  "simulation": { "pressed": true } }
            ]
        });
        let mut config = presets::stock_psm1();
        let pedals: IoConfig = serde_json::from_value(text).unwrap();
        config.digital_inputs = pedals.digital_inputs;
        for (name, pressed) in [
            ("Clutch", false),
            ("Camera", false),
            ("Coag", true),
            ("HeadSensor", false),
            ("Door", true),
        ] {
            assert_eq!(console_reads(&config, name), pressed, "{name}");
        }
        // Released pressed-low pedals hold their lines high; a pressed
        // pressed-high input too; the rest low.
        assert_eq!(input_lines(&config)[1], (1 << 3) | (1 << 2) | (1 << 6));
    }

    #[test]
    fn the_mtm_gripper_sits_after_the_last_actuator() {
        let config = presets::stock_mtmr();
        assert_eq!(gripper_slot(&config.robots[0]), Some((3, 3)));
        let boards = crate::rig::board_configs(&config, Profile::Rev8, 4);
        let gripper = &boards[3].axes[3];
        assert_eq!(gripper.name, "MTM gripper");
        assert!(!gripper.has_motor);
        assert_eq!(gripper_slot(&presets::stock_psm1().robots[0]), None);
    }

    #[test]
    fn stops_stay_where_the_arm_has_them_and_the_pot_saturates() {
        // A pot calibration that reads only to 1.5 degrees past the PSM
        // tool actuators' soft limits (as in the report that asked for
        // stops: -3.049 rad against -3.037).
        let mut config = presets::stock_psm1();
        let a = &mut config.robots[0].actuators[4];
        let soft = a.encoder.position_limits_soft;
        let pot = a.potentiometer.as_mut().unwrap();
        let reach = soft.upper + 1.5f64.to_radians();
        pot.voltage_to_position.scale = 2.0 * reach / 4.5;
        pot.voltage_to_position.offset = -reach;
        let p = plant_for(&config, 4).unwrap();
        let (lo, hi) = (p.stops.lower.unwrap(), p.stops.upper.unwrap());
        let margin = 3f64.to_radians();
        assert!((lo - (soft.lower - margin)).abs() < 1e-12, "{lo}");
        assert!((hi - (soft.upper + margin)).abs() < 1e-12, "{hi}");
        // At the stops the pot reads the end of its range, not the joint.
        let volts = |q: f64| p.pot_volts_at(q);
        assert_eq!(volts(hi), volts(reach + 0.01));
        assert!(volts(soft.upper) < volts(hi));
        let notes = notes(&config);
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].starts_with("PSM1[4]: the pot conversion reads only"));
        assert!(notes[0].contains("saturates"));
        assert!(!notes[0].contains("inside the soft limits"));
        // The MTM roll: a pot of about half a turn, unchecked, stops at
        // -480 and +456 degrees: nothing to note.
        let mtmr = presets::stock_mtmr();
        let roll = plant_for(&mtmr, 6).unwrap();
        assert!((roll.stops.lower.unwrap() - (-480f64).to_radians()).abs() < 1e-9);
        assert!((roll.stops.upper.unwrap() - 456f64.to_radians()).abs() < 1e-9);
        assert_eq!(super::notes(&mtmr), Vec::<String>::new());
    }
}
