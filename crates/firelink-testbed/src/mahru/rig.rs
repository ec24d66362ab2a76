//! MAHRU on the simulated bus: the computer's 3-port card at the root, one
//! chain of modules on each port, the gap count Linux would set for the
//! bus's diameter, and the computer's real-time system as the port's
//! overhead model.

use firelink_board::mahru::{ModuleConfig, ModuleNode};
use firelink_board::qla::rig::{linux_gap_count, set_gap_count};
use firelink_bus::{Bus, BusConfig, HostLink, NodeConfig, NodeHandle, TraceLevel};
use firelink_host::mahru::rtos::{Rtos, RtosModel};
use firelink_host::sim::SimPort;
use firelink_wire::mahru::ModId;
use firelink_wire::packet::Speed;

use super::config::MahruConfig;
use crate::TestbedError;

/// One module on the bus.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlacedModule {
    /// Its module ID.
    pub mod_id: ModId,
    /// Its name.
    pub name: String,
    /// Which chain (port of the card) it is on.
    pub chain: usize,
    /// Cable hops from the computer.
    pub hops: u32,
    /// Its node on the bus.
    pub handle: NodeHandle,
}

/// The bus with the computer and the modules, reset and numbered.
pub struct MahruBus {
    /// The bus.
    pub bus: Bus,
    /// The computer's link.
    pub pc: NodeHandle,
    /// Every module, chain by chain.
    pub modules: Vec<PlacedModule>,
    /// The largest number of hops between two nodes.
    pub diameter: u32,
}

/// Build the bus: the computer (3 ports) at the root, `chains[i]` on its
/// port `i`, listed from the card outwards; reset, then the gap count for
/// the diameter and another reset.
///
/// # Errors
/// [`TestbedError::Config`] without modules or with more than 3 chains.
pub fn build_bus(chains: &[Vec<ModuleConfig>], seed: u64) -> Result<MahruBus, TestbedError> {
    if chains.is_empty() || chains.len() > 3 || chains.iter().all(Vec::is_empty) {
        return Err(TestbedError::Config(
            "MAHRU bus: 1 to 3 chains of modules on the computer's 3-port card".into(),
        ));
    }
    let mut bus = Bus::new(BusConfig {
        seed,
        trace: TraceLevel::Off,
        ..BusConfig::default()
    });
    let pc = bus.add(HostLink::new("sbc"), NodeConfig::pc());
    let mut handles: Vec<Vec<NodeHandle>> = Vec::new();
    let mut placed = Vec::new();
    for (c, chain) in chains.iter().enumerate() {
        let mut hs = Vec::new();
        for m in chain {
            let h = bus.add(ModuleNode::new(m.clone()), NodeConfig::board());
            hs.push(h);
            placed.push(PlacedModule {
                mod_id: m.mod_id,
                name: m.name.clone(),
                chain: c,
                hops: 0,
                handle: h,
            });
        }
        handles.push(hs);
    }
    let refs: Vec<&[NodeHandle]> = handles.iter().map(Vec::as_slice).collect();
    bus.tree_with_chains(pc, &refs)
        .map_err(|e| TestbedError::Config(format!("MAHRU bus: {e}")))?;
    bus.set_root(pc)
        .map_err(|e| TestbedError::Config(format!("MAHRU bus: {e}")))?;
    bus.reset();
    let all: Vec<NodeHandle> = std::iter::once(pc)
        .chain(placed.iter().map(|m| m.handle))
        .collect();
    let diameter = all
        .iter()
        .flat_map(|a| all.iter().map(|b| (*a, *b)))
        .map(|(a, b)| bus.hops(a, b))
        .max()
        .unwrap_or(0);
    set_gap_count(&mut bus, pc, linux_gap_count(diameter as usize));
    for m in &mut placed {
        m.hops = bus.hops(pc, m.handle);
    }
    Ok(MahruBus {
        bus,
        pc,
        modules: placed,
        diameter,
    })
}

/// How long the computer waits for a module's answer: a read takes well
/// under 0.3 ms, and a module that does not answer must be noticed (and
/// the robot stopped) long before the other modules' 10 ms watchdogs
/// would stop them on their own.
pub const MODULE_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(1);

/// The computer's port on `bus`: `rtos`'s overhead model seeded with
/// `seed`, broadcasts at `broadcast` speed, returning once sent, and
/// [`MODULE_TIMEOUT`].
pub fn sbc_port(bus: Bus, pc: NodeHandle, rtos: Rtos, seed: u64, broadcast: Speed) -> SimPort {
    SimPort::new(bus, pc)
        .with_overhead(RtosModel::new(rtos, seed))
        .with_broadcast_speed(broadcast)
        .with_blocking_broadcasts()
        .with_timeout(MODULE_TIMEOUT)
}

/// The robot of `config` on its bus, behind the computer's port (its
/// real-time system, seed and broadcast speed), not yet brought up; with
/// its modules and the bus's diameter.
///
/// # Errors
/// What [`build_bus`] and the configuration's checks find.
pub fn robot_port(config: &MahruConfig) -> Result<(SimPort, Vec<PlacedModule>, u32), TestbedError> {
    let b = build_bus(&config.module_configs(), config.seed)?;
    let port = sbc_port(
        b.bus,
        b.pc,
        config.rtos()?,
        config.seed,
        config.broadcast_speed()?,
    );
    Ok((port, b.modules, b.diameter))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_chains_with_their_hops() {
        let c = MahruConfig::seed002();
        let b = build_bus(&c.module_configs(), 1).unwrap();
        assert_eq!(b.modules.len(), 14);
        // Legs: 4 deep, arms: 6, sensors: 4; the farthest pair is 6 + 4 apart.
        assert_eq!(b.diameter, 10);
        assert_eq!(b.bus.gap_count(b.pc), Some(linux_gap_count(10)));
        let hops: Vec<u32> = b.modules.iter().map(|m| m.hops).collect();
        assert_eq!(hops, [1, 2, 3, 4, 1, 2, 3, 4, 5, 6, 1, 2, 3, 4]);
        // The computer is the root: the highest node ID.
        assert_eq!(b.bus.phy_id(b.pc), Some(14));
        assert!(build_bus(&[], 0).is_err());
    }
}
