//! Seed 001's own system on emulated Snake nodes: rigs (the nodes of a
//! configuration, each channel driving the plant its actuator names, on
//! the simulated bus with seed 001's PC model or behind an in-process
//! Ethernet bridge), the node setup a program does before servoing
//! ([`prepare`]), the 36-axis demo ([`demo`]) and the reproduction of the
//! seed's measurements ([`bench`](mod@bench)); the test and configuration
//! program's model ([`tool`]).

pub mod bench;
pub mod demo;
pub mod tool;

use firelink_board::plant::{AxisParams, presets};
use firelink_board::snake::SnakeNodeConfig;
use firelink_bus::HostModel;
use firelink_control::config::IoConfig;
use firelink_host::Port;
use firelink_host::sim::SimPort;
use firelink_host::snake::SnakeSystem;
use firelink_wire::snake::CHANNELS;
use firelink_wire::snake::analog::limit_code;
use firelink_wire::snake::registers::{ENCODER_MIDPOINT, PotOutputs, Wiper};

use crate::TestbedError;
use crate::plant_map::plant_for;
use crate::rig::{Emulator, RigBuilder, RobotKind};

/// The current limit programmed on a channel, relative to the largest
/// current the servo commands (headroom for the PID's transients).
pub const LIMIT_HEADROOM: f64 = 1.25;

/// Whether `config` drives seed 001's Snake nodes (every robot's
/// `hardware_version` is `SNAKE`).
pub fn is_snake_config(config: &IoConfig) -> bool {
    RobotKind::of_config(config) == RobotKind::Snake
}

/// One node per board ID the configuration uses, each channel driving the
/// plant its actuator names (unused channels have no motor), noise
/// seeded by `seed` and the board ID.
///
/// # Errors
/// [`TestbedError::Config`] when a robot is not on Snake nodes.
pub fn node_configs(config: &IoConfig, seed: u64) -> Result<Vec<SnakeNodeConfig>, TestbedError> {
    if !is_snake_config(config) {
        return Err(TestbedError::Config(
            "not a Snake-node configuration: every robot's hardware_version must be SNAKE".into(),
        ));
    }
    let mut out = Vec::new();
    for b in config.boards() {
        let mut channels: Vec<AxisParams> = vec![presets::unused_channel(); CHANNELS];
        for (i, j) in config.joints().enumerate() {
            if j.actuator.board_id != b.board_id {
                continue;
            }
            if let (Some(slot), Some(p)) = (
                channels.get_mut(usize::from(j.actuator.axis_id)),
                plant_for(config, i),
            ) {
                *slot = p;
            }
        }
        out.push(
            SnakeNodeConfig::new(b.board_id)
                .with_channels(channels)
                .with_seed(seed.wrapping_add(u64::from(b.board_id))),
        );
    }
    Ok(out)
}

/// The nodes on a simulated bus behind the PC's link, with seed 001's PC
/// model when `pc_model` (and its spread when `jitter` is `Some(seed)`).
///
/// # Errors
/// [`TestbedError::NoBoards`].
pub fn sim_port(
    configs: Vec<SnakeNodeConfig>,
    pc_model: bool,
    jitter: Option<u64>,
) -> Result<SimPort, TestbedError> {
    sim_port_with_faults(configs, pc_model, jitter).map(|(port, _)| port)
}

/// [`sim_port`] and its fault target (the nodes by ID as the rig built
/// them).
///
/// # Errors
/// [`TestbedError::NoBoards`].
pub fn sim_port_with_faults(
    configs: Vec<SnakeNodeConfig>,
    pc_model: bool,
    jitter: Option<u64>,
) -> Result<(SimPort, crate::fault_script::FaultTarget), TestbedError> {
    let rig = RigBuilder::snake(configs).build()?;
    let target = rig.fault_target();
    let mut model = HostModel::seed001(rig.bus.timing());
    if let Some(seed) = jitter {
        model = model.with_jitter(seed);
    }
    let port = rig.sim_port();
    let port = if pc_model {
        port.with_host_model(model)
    } else {
        port
    };
    Ok((port, target))
}

/// An in-process `firelink emulate` of the nodes (the first is the
/// Ethernet-connected one).
///
/// # Errors
/// As [`Emulator::start_rig`].
pub fn emulator(configs: Vec<SnakeNodeConfig>) -> Result<Emulator, TestbedError> {
    Emulator::start_rig(RigBuilder::snake(configs))
}

/// What a program sets on each node before servoing, as the seed
/// prescribes (§6.2, §7.2): per used channel, the nominal wiper (the
/// gain the configuration's conversions assume), torque mode, a current
/// limit [`LIMIT_HEADROOM`] above the largest current the servo commands,
/// and the encoder preloaded with the midpoint.
///
/// # Errors
/// Port errors; a configuration naming a node or channel not found.
pub fn prepare<P: Port>(
    system: &mut SnakeSystem<P>,
    config: &IoConfig,
) -> Result<(), TestbedError> {
    for j in config.joints() {
        let a = j.actuator;
        let ch = a.axis_id + 1;
        let id = a.board_id;
        system.set_digital_pot_wiper(id, ch, Wiper::NOMINAL.value())?;
        system.set_analog_switches(id, ch, PotOutputs::default())?;
        system.set_motor_current(id, ch, limit_code(a.drive.maximum_current * LIMIT_HEADROOM))?;
        system.set_encoder_preload(id, ch, ENCODER_MIDPOINT)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_control::config::presets;

    #[test]
    fn seed001_config_gives_six_nodes() {
        let c = presets::snake_seed001();
        assert!(is_snake_config(&c));
        let nodes = node_configs(&c, 1).unwrap();
        let ids: Vec<u8> = nodes.iter().map(|n| n.board_id).collect();
        assert_eq!(ids, [0, 1, 2, 3, 4, 5]);
        // Node 1 carries SNAKE1's axes 7-10 on channels 1-4; 5-7 unused.
        assert!(nodes[1].channels[3].has_motor);
        assert!(!nodes[1].channels[4].has_motor);
        assert!(!is_snake_config(&presets::snake_36axes()));
        assert!(node_configs(&presets::dvrk_seed000(), 1).is_err());
    }
}
