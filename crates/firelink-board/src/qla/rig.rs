//! Ready-made buses of emulated boards: the PC's link at the root and the
//! boards on a daisy chain, as in the dVRK.
//!
//! The chain is wired PC - board N-1 - ... - board 0, so after the bus
//! reset the board given first gets physical ID 0, the next 1, and so on,
//! and the PC (the root) gets the highest ID.

use firelink_bus::phy::phy_config_packet;
use firelink_bus::{
    ArbitrationClass, Bus, BusConfig, HostLink, Node, NodeConfig, NodeHandle, SimDuration,
    TraceLevel,
};
use firelink_wire::packet::Speed;

use crate::qla::config::BoardConfig;
use crate::qla::node::BoardNode;

/// A bus with the PC's link and emulated boards, reset and numbered.
pub struct BoardRig {
    /// The bus.
    pub bus: Bus,
    /// The PC's link node (a [`HostLink`]).
    pub host: NodeHandle,
    /// The board nodes, in the order their configurations were given.
    pub boards: Vec<NodeHandle>,
}

/// Options of a rig.
#[derive(Debug, Clone)]
pub struct RigOptions {
    /// Seed of the bus (fault injector).
    pub seed: u64,
    /// What the bus records (long runs want [`TraceLevel::Off`]).
    pub trace: TraceLevel,
    /// Cycle master on (off, as in seed 000).
    pub cycle_master: bool,
    /// Gap count the PC sets after the first reset with a PHY configuration
    /// packet (and a second reset), as the Linux FireWire stack does when it
    /// is bus manager: `Some(GapCount::ForHops)` picks the value of Linux's
    /// table for the chain's hop count, `None` leaves the power-up 63.
    pub gap_count: Option<GapCount>,
    /// Speed of the boards' status broadcasts.
    pub broadcast_speed: Speed,
    /// How the boards arbitrate for their status broadcasts
    /// (isochronous-style: seed 000's bus arbitration acceleration).
    pub broadcast_class: ArbitrationClass,
}

/// How the rig sets the gap count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GapCount {
    /// The Linux firewire-core table for the bus's hop count.
    ForHops,
    /// This value (0..=63).
    Fixed(u8),
}

/// Gap count the Linux FireWire stack uses for a bus with `hops` hops
/// (`ieee1394.md`, "Gaps").
pub fn linux_gap_count(hops: usize) -> u8 {
    const TABLE: [u8; 16] = [63, 5, 7, 8, 10, 13, 16, 18, 21, 24, 26, 29, 32, 35, 37, 40];
    TABLE.get(hops).copied().unwrap_or(63)
}

/// Set every PHY's gap count to `gap` as the Linux stack does when it is
/// bus manager: the PC's link `host` sends a PHY configuration packet,
/// then a bus reset makes it take effect. Nothing is sent if the gap
/// count is already `gap`.
pub fn set_gap_count(bus: &mut Bus, host: NodeHandle, gap: u8) {
    let gap = gap.min(63);
    if bus.gap_count(host) == Some(gap) {
        return;
    }
    let packet = phy_config_packet(Some(gap), None);
    if let Ok(token) = HostLink::submit_on(bus, host, &packet, Speed::S100) {
        let deadline = bus.now() + SimDuration::from_micros(1_000);
        let _ = HostLink::wait_on(bus, host, token, deadline);
        // The PHYs take the configuration when the subaction ends.
        bus.run_until_with(deadline, |b| !b.has_pending_traffic());
    }
    bus.reset();
}

impl Default for RigOptions {
    fn default() -> Self {
        RigOptions {
            seed: 0,
            trace: TraceLevel::Off,
            cycle_master: false,
            gap_count: Some(GapCount::ForHops),
            broadcast_speed: Speed::S400,
            broadcast_class: ArbitrationClass::Isochronous,
        }
    }
}

impl BoardRig {
    /// Build the bus, add the PC link and the boards, wire the chain and
    /// run the first bus reset.
    pub fn daisy_chain(boards: Vec<BoardConfig>, options: &RigOptions) -> BoardRig {
        let nodes = boards
            .into_iter()
            .map(|cfg| {
                let name = format!("board{}", cfg.board_id);
                let node = BoardNode::new(cfg)
                    .with_name(name)
                    .with_broadcast(options.broadcast_speed, options.broadcast_class);
                Box::new(node) as Box<dyn Node>
            })
            .collect();
        BoardRig::daisy_chain_nodes(nodes, options)
    }

    /// The same with any nodes as the boards (Snake nodes, a mix of
    /// kinds): the first given gets physical ID 0.
    pub fn daisy_chain_nodes(nodes: Vec<Box<dyn Node>>, options: &RigOptions) -> BoardRig {
        let mut bus = Bus::new(BusConfig {
            seed: options.seed,
            trace: options.trace,
            cycle_master: options.cycle_master,
            ..BusConfig::default()
        });
        let host = bus.add(HostLink::new("pc"), NodeConfig::pc());
        let handles: Vec<NodeHandle> = nodes
            .into_iter()
            .map(|node| bus.add_node(node, NodeConfig::board()))
            .collect();
        let mut chain = vec![host];
        chain.extend(handles.iter().rev().copied());
        // Fresh nodes in a simple chain: connecting cannot fail.
        let _ = bus.daisy_chain(&chain);
        bus.reset();
        let hops = handles.len();
        let gap = match options.gap_count {
            Some(GapCount::ForHops) => Some(linux_gap_count(hops)),
            Some(GapCount::Fixed(g)) => Some(g.min(63)),
            None => None,
        };
        if let Some(g) = gap {
            set_gap_count(&mut bus, host, g);
        }
        BoardRig {
            bus,
            host,
            boards: handles,
        }
    }

    /// The board node behind `handle`.
    pub fn board(&self, index: usize) -> Option<&BoardNode> {
        self.boards
            .get(index)
            .and_then(|h| self.bus.node::<BoardNode>(*h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qla::config::{Hardware, Profile};

    #[test]
    fn boards_are_numbered_in_order_and_pc_is_root() {
        let boards = (0..4)
            .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
            .collect();
        let rig = BoardRig::daisy_chain(boards, &RigOptions::default());
        for (i, h) in rig.boards.iter().enumerate() {
            assert_eq!(rig.bus.phy_id(*h), Some(i as u8));
        }
        assert_eq!(rig.bus.phy_id(rig.host), Some(4));
        assert_eq!(rig.board(2).map(|b| b.firmware().board_id()), Some(2));
        // 4 hops: Linux's gap count 10 on every PHY.
        assert_eq!(rig.bus.gap_count(rig.host), Some(10));
        assert_eq!(rig.bus.gap_count(rig.boards[0]), Some(10));
    }
}
