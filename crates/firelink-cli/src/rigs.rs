//! Building emulated hardware for the commands that need it (`emulate`,
//! `demo`, `bench`, `--port sim`): boards from a robot configuration with
//! plants whose encoder, potentiometer and amplifier scaling match the
//! configuration's conversions, on a simulated bus.

use firelink_board::config::{BoardConfig, Hardware, Profile};
use firelink_board::plant::AxisParams;
use firelink_board::plant::presets;
use firelink_board::rig::{BoardRig, RigOptions};
use firelink_bus::HostModel;
use firelink_control::config::{ActuatorConfig, IoConfig, PlantPreset};
use firelink_host::sim::SimPort;

use crate::CliError;

/// Firmware profile from the command line's `--firmware 7|8|seed`.
pub fn parse_profile(text: &str) -> Result<Profile, String> {
    match text {
        "7" | "rev7" => Ok(Profile::Rev7),
        "8" | "rev8" => Ok(Profile::Rev8),
        "seed" => Ok(Profile::Seed),
        _ => Err(format!("unknown firmware {text:?}: 7, 8 or seed")),
    }
}

/// Hardware from `--hardware QLA1|DQLA`.
pub fn parse_hardware(text: &str) -> Result<Hardware, String> {
    match text.to_ascii_uppercase().as_str() {
        "QLA1" | "QLA" => Ok(Hardware::Qla1),
        "DQLA" => Ok(Hardware::Dqla),
        _ => Err(format!("unknown hardware {text:?}: QLA1 or DQLA")),
    }
}

fn preset_params(preset: PlantPreset) -> AxisParams {
    let name = preset.name();
    let joint = name
        .rsplit_once('j')
        .and_then(|(_, n)| n.parse::<u8>().ok())
        .unwrap_or(0);
    let params = if name.starts_with("mtm") {
        presets::mtm_joint(joint)
    } else if name.starts_with("psm") {
        presets::psm_joint(joint)
    } else {
        None
    };
    params.unwrap_or_else(presets::generic_motor)
}

/// The plant of one actuator: the preset's motor and load, with the
/// encoder, potentiometer and amplifier scaled so that the configuration's
/// conversions read it correctly (so homing and the PID gains make sense).
pub fn plant_for(actuator: &ActuatorConfig) -> AxisParams {
    let preset = actuator
        .simulation
        .as_ref()
        .map(|s| s.plant)
        .unwrap_or(PlantPreset::Generic);
    let mut p = preset_params(preset);
    let gear = p.load.gear_ratio.abs().max(1e-9);
    // Encoder: counts per joint radian = 1 / |scale|.
    let es = actuator.encoder.bits_to_position.scale;
    let cs = actuator.drive.current_to_bits.scale;
    if es.is_finite() && es != 0.0 {
        let cpr = (2.0 * std::f64::consts::PI / (es.abs() * gear)).round();
        p.encoder.counts_per_rev = cpr.clamp(1.0, f64::from(u32::MAX)) as u32;
        // The plant's current follows the DAC with a positive sign; with the
        // configuration's signs, positive commanded current must move the
        // joint in the positive direction.
        p.encoder.reversed = (cs < 0.0) != (es < 0.0);
    }
    // Potentiometer: volts = (position - offset) / scale of voltage_to_position.
    if let Some(pot) = &actuator.potentiometer {
        let v2p = pot.voltage_to_position;
        if v2p.scale.is_finite() && v2p.scale != 0.0 {
            p.pot.volts_per_unit = 1.0 / v2p.scale;
            p.pot.offset_volts = -v2p.offset / v2p.scale;
        }
    }
    if cs.is_finite() && cs != 0.0 {
        p.amplifier.amps_per_bit = 1.0 / cs.abs();
    }
    p
}

/// Emulated boards for every board the configuration uses.
pub fn boards_for(config: &IoConfig, profile: Profile, seed: u64) -> Vec<BoardConfig> {
    let mut boards = Vec::new();
    for used in config.boards() {
        let hardware = match used.hardware.axes() {
            8 => Hardware::Dqla,
            _ => Hardware::Qla1,
        };
        let mut axes = vec![presets::unused_channel(); hardware.axes()];
        for joint in config.joints() {
            let a = joint.actuator;
            if a.board_id == used.board_id {
                if let Some(slot) = axes.get_mut(usize::from(a.axis_id)) {
                    *slot = plant_for(a);
                }
            }
        }
        boards.push(
            BoardConfig::new(used.board_id, hardware, profile)
                .with_axes(axes)
                .with_seed(seed.wrapping_add(u64::from(used.board_id))),
        );
    }
    boards
}

/// `n` boards with generic motors, IDs 0..n.
pub fn generic_boards(n: u8, hardware: Hardware, profile: Profile, seed: u64) -> Vec<BoardConfig> {
    (0..n)
        .map(|id| {
            BoardConfig::new(id, hardware, profile).with_seed(seed.wrapping_add(u64::from(id)))
        })
        .collect()
}

/// A simulated port with the PC and these boards on a daisy chain;
/// optionally with seed 000's PC overhead model.
pub fn sim_port(
    boards: Vec<BoardConfig>,
    seed: u64,
    host_overhead: bool,
) -> Result<SimPort, CliError> {
    if boards.is_empty() {
        return Err(CliError::Conflict("no boards to emulate".into()));
    }
    let rig = BoardRig::daisy_chain(
        boards,
        &RigOptions {
            seed,
            ..RigOptions::default()
        },
    );
    let mut port = SimPort::new(rig.bus, rig.host);
    if host_overhead {
        let model = HostModel::seed000(port.bus().timing());
        port = port.with_host_model(model);
    }
    Ok(port)
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_control::config::presets as cfg;

    #[test]
    fn dvrk_config_makes_eight_qla1_boards_with_plants() {
        let config = cfg::dvrk_seed000();
        let boards = boards_for(&config, Profile::Rev8, 1);
        assert_eq!(boards.len(), 8);
        assert!(boards.iter().all(|b| b.hardware == Hardware::Qla1));
        // The plant's encoder reads back the configured scale.
        let joint = config.joints().next().unwrap();
        let p = plant_for(joint.actuator);
        let counts_per_rad =
            f64::from(p.encoder.counts_per_rev) * p.load.gear_ratio / (2.0 * std::f64::consts::PI);
        let scale = joint.actuator.encoder.bits_to_position.scale.abs();
        assert!((counts_per_rad * scale - 1.0).abs() < 1e-3);
    }
}
