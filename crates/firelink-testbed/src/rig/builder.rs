//! The one rig builder: a robot's boards (QLA-family boards or seed 001's
//! Snake nodes), each known by its board ID, daisy-chained behind the PC's
//! link on a seeded simulated bus, with faults named by board ID and the
//! board whose Ethernet port a bridge uses. The simulated port, the
//! in-process emulator and `firelink emulate` (UDP bridge and /dev/fw*
//! twin) are all built here.
//!
//! Rules:
//! - the chain is wired PC - last board - ... - first board: the first
//!   board given gets physical ID 0, the PC (the root) the highest ID
//!   (as [`BoardRig::daisy_chain_nodes`] does, with Linux's gap count for
//!   the chain's hops);
//! - a board is named by its board ID everywhere above the bus (faults,
//!   the bridge board); its node handle is looked up, never computed;
//! - a fault or bridge board naming an ID the rig does not have is an
//!   error ([`TestbedError::NoSuchBoard`]), not ignored;
//! - board faults (and a bus-reset storm) are resolved to bus faults at
//!   build and held, each at its offset from the fault moment, until the
//!   caller schedules them ([`Rig::schedule_pending`]) or takes them
//!   (a twin that starts them after N requests: [`Rig::take_pending`]);
//! - rules that name the PC's link (busy answers to its requests) are
//!   added at build, when the link exists.

use std::fmt;
use std::str::FromStr;

use firelink_board::qla::config::BoardConfig;
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_board::snake::SnakeNodeConfig;
use firelink_bus::trace::PacketKind;
use firelink_bus::{
    Bus, Detail, FaultRule, Node, NodeHandle, PacketFault, PacketMatch, SimDuration, TimedFault,
};
use firelink_control::config::IoConfig;
use firelink_emulate::Bridge;
use firelink_host::sim::SimPort;
use firelink_wire::packet::Tcode;

use crate::TestbedError;
use crate::fault_script::apply_on_bus;
use crate::fault_script::{BoardFault, FaultMoment, FaultScript, FaultTarget, ScriptedFault};

/// Which family of robot a rig carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RobotKind {
    /// The dVRK and other robots on QLA-family boards (FPGA1394 + QLA1 or
    /// DQLA), seed 000.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Seed 000's da Vinci Research Kit on QLA boards")
    )]
    Dvrk,
    /// Seed 001's Snake robot on its own 7-channel nodes.
    #[cfg_attr(
        feature = "clap",
        value(help = "Seed 001's Snake robot system on its 7-channel nodes")
    )]
    Snake,
    /// Seed 002's MAHRU humanoid on its own modules (three chains).
    #[cfg_attr(
        feature = "clap",
        value(help = "Seed 002's MAHRU humanoid: 14 modules on three chains, walking")
    )]
    Mahru,
}

impl RobotKind {
    /// Every kind, in the order of the docs.
    pub const ALL: [RobotKind; 3] = [RobotKind::Dvrk, RobotKind::Snake, RobotKind::Mahru];

    /// Its name (`dvrk`, `snake`, `mahru`).
    pub fn name(self) -> &'static str {
        match self {
            RobotKind::Dvrk => "dvrk",
            RobotKind::Snake => "snake",
            RobotKind::Mahru => "mahru",
        }
    }

    /// The kind a saw-robot-io configuration drives: Snake when every
    /// robot's `hardware_version` is `SNAKE`, else QLA-family boards.
    pub fn of_config(config: &IoConfig) -> RobotKind {
        if !config.robots.is_empty() && config.robots.iter().all(|r| r.hardware_version.is_snake())
        {
            RobotKind::Snake
        } else {
            RobotKind::Dvrk
        }
    }
}

impl fmt::Display for RobotKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for RobotKind {
    type Err = TestbedError;
    fn from_str(s: &str) -> Result<RobotKind, TestbedError> {
        RobotKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                TestbedError::Config(format!(
                    "unknown robot {s:?}: expected dvrk, snake or mahru"
                ))
            })
    }
}

/// What to build: the boards, the bus's seed and the faults.
pub struct RigBuilder {
    kind: RobotKind,
    boards: Vec<(u8, Box<dyn Node>)>,
    configs: Vec<BoardConfig>,
    seed: u64,
    rules: Vec<FaultRule>,
    board_faults: Vec<BoardFault>,
    busy_rate: f64,
    reset_storm: u32,
    script: FaultScript,
    detail: Detail,
}

/// A built rig: the bus, the PC's link at its root, and every board by ID.
pub struct Rig {
    /// What it carries.
    pub kind: RobotKind,
    /// The bus, reset and numbered.
    pub bus: Bus,
    /// The PC's (or the bridge's) link.
    pub host: NodeHandle,
    /// Each board's ID and node, in chain order (physical IDs 0, 1, ...).
    pub boards: Vec<(u8, NodeHandle)>,
    /// The configurations of its QLA-family boards (none for Snake nodes).
    pub configs: Vec<BoardConfig>,
    /// Held faults (board faults resolved to their nodes, a reset storm),
    /// each with its offset from the fault moment; not yet scheduled.
    pending: Vec<(SimDuration, TimedFault)>,
}

impl RigBuilder {
    /// QLA-family boards (emulated FPGA1394 boards), in the order given.
    pub fn qla(boards: Vec<BoardConfig>) -> RigBuilder {
        let nodes = boards
            .iter()
            .map(|b| (b.board_id, super::qla_node(b.clone())))
            .collect();
        RigBuilder::of(RobotKind::Dvrk, nodes, boards)
    }

    /// Seed 001's Snake nodes, in the order given (the first is the
    /// Ethernet-connected one unless [`Rig::bridge`] names another).
    pub fn snake(nodes: Vec<SnakeNodeConfig>) -> RigBuilder {
        let nodes = nodes
            .into_iter()
            .map(|n| {
                (
                    n.board_id,
                    Box::new(firelink_board::snake::SnakeNode::new(n)) as Box<dyn Node>,
                )
            })
            .collect();
        RigBuilder::of(RobotKind::Snake, nodes, Vec::new())
    }

    fn of(
        kind: RobotKind,
        boards: Vec<(u8, Box<dyn Node>)>,
        configs: Vec<BoardConfig>,
    ) -> RigBuilder {
        RigBuilder {
            kind,
            boards,
            configs,
            seed: 0,
            rules: Vec::new(),
            board_faults: Vec::new(),
            busy_rate: 0.0,
            reset_storm: 0,
            script: FaultScript::new(),
            detail: Detail::Fast,
        }
    }

    /// The bus's level of detail ([`Detail::Fast`] by default; the same
    /// answer either way).
    pub fn detail(mut self, detail: Detail) -> RigBuilder {
        self.detail = detail;
        self
    }

    /// The bus's seed (its fault injector's random draws); 0 by default.
    pub fn seed(mut self, seed: u64) -> RigBuilder {
        self.seed = seed;
        self
    }

    /// A packet fault rule on the bus (a seeded drop or corruption rate).
    pub fn fault_rule(mut self, rule: FaultRule) -> RigBuilder {
        self.rules.push(rule);
        self
    }

    /// A fault script's entries, resolved at build to the bus's fault plan
    /// (before the rules and board faults given one by one): packet rules
    /// from the start (`@start`) become the bus's rules, a board's loss at
    /// `t=` after the fault moment is held like [`board_fault`](Self::board_fault)'s,
    /// at that offset, and one from the start is scheduled at build.
    /// Boards are named by ID. Entries from the start are translated to
    /// the bus as the servo loop's fault target does it (one translation).
    /// What the rig cannot hold until its fault moment (a packet rule from
    /// a later moment, anything at a servo cycle, a host pause: the servo
    /// loop's, through [`Rig::fault_target`]) is refused at build.
    pub fn fault_script(mut self, script: &FaultScript) -> RigBuilder {
        self.script.entries.extend(script.entries.iter().copied());
        self
    }

    /// A fault on a board by its ID (held until scheduled).
    pub fn board_fault(mut self, fault: BoardFault) -> RigBuilder {
        self.board_faults.push(fault);
        self
    }

    /// Drop each read response a board sends (quadlet and block) with
    /// this probability: the PC's request is answered by nothing.
    pub fn drop_responses(mut self, probability: f64) -> RigBuilder {
        for tcode in [Tcode::ReadQuadletResponse, Tcode::ReadBlockResponse] {
            self.rules.push(FaultRule::random(
                PacketMatch::any().tcode(tcode),
                PacketFault::Drop,
                probability.clamp(0.0, 1.0),
            ));
        }
        self
    }

    /// The addressed board is busy for each request the PC sends, with
    /// this probability: it takes nothing and acknowledges ack_busy_X.
    pub fn busy_requests(mut self, probability: f64) -> RigBuilder {
        self.busy_rate = probability.clamp(0.0, 1.0);
        self
    }

    /// `resets` bus resets in a row, 1 ms apart, from the fault moment
    /// (held with the board faults).
    pub fn reset_storm(mut self, resets: u32) -> RigBuilder {
        self.reset_storm = resets;
        self
    }

    /// Build the bus: chain, reset, gap count, fault rules; board faults
    /// resolved to their nodes.
    ///
    /// # Errors
    /// [`TestbedError::NoBoards`]; [`TestbedError::NoSuchBoard`] for a
    /// fault naming an ID the rig does not have.
    pub fn build(self) -> Result<Rig, TestbedError> {
        if self.boards.is_empty() {
            return Err(TestbedError::NoBoards);
        }
        let (ids, nodes): (Vec<u8>, Vec<Box<dyn Node>>) = self.boards.into_iter().unzip();
        let mut built = BoardRig::daisy_chain_nodes(
            nodes,
            &RigOptions {
                seed: self.seed,
                ..RigOptions::default()
            },
        );
        built.bus.set_detail(self.detail);
        let script = self.script;
        // Each board's node by ID, as the fault target knows them.
        let by_id: Vec<(u8, NodeHandle)> = ids.iter().copied().zip(built.boards.clone()).collect();
        let mut scripted_faults = Vec::new();
        for entry in &script.entries {
            let refused = |why: &str| TestbedError::Config(format!("fault {entry}: {why}"));
            match (entry.at, entry.fault) {
                // From the start: on the bus now, translated as the servo
                // loop's fault target does it (one place).
                (FaultMoment::Start, ScriptedFault::Packets { .. } | ScriptedFault::Board(_)) => {
                    apply_on_bus(&mut built.bus, &by_id, entry.fault, SimDuration::ZERO)?;
                }
                (FaultMoment::After(offset), ScriptedFault::Board(b)) => {
                    let node = by_id
                        .iter()
                        .find(|(id, _)| *id == b.board_id())
                        .map(|(_, n)| *n)
                        .ok_or(TestbedError::NoSuchBoard {
                            role: b.role(),
                            board: b.board_id(),
                        })?;
                    scripted_faults.push((offset, b.on_node(node)));
                }
                (_, ScriptedFault::HostPause(_)) => {
                    return Err(refused(
                        "the host pauses itself: the servo loop's to do, not the bus's",
                    ));
                }
                (FaultMoment::Cycle(_), _) => {
                    return Err(refused(
                        "the simulated bus does not count servo cycles: give it to the servo loop's fault target (Rig::fault_target)",
                    ));
                }
                (FaultMoment::After(_), ScriptedFault::Packets { .. }) => {
                    return Err(refused(
                        "the rig holds only board faults until its fault moment; a packet rule \
                         from a later moment is the servo loop's: give it to the rig's fault \
                         target (Rig::fault_target), which applies it when due",
                    ));
                }
            }
        }
        for rule in self.rules {
            built.bus.add_fault_rule(rule);
        }
        if self.busy_rate > 0.0 {
            built.bus.add_fault_rule(FaultRule::random(
                PacketMatch::any()
                    .from(built.host)
                    .kind(PacketKind::Request),
                PacketFault::AckBusy,
                self.busy_rate,
            ));
        }
        let mut rig = Rig {
            kind: self.kind,
            bus: built.bus,
            host: built.host,
            boards: ids.into_iter().zip(built.boards).collect(),
            configs: self.configs,
            pending: scripted_faults,
        };
        for fault in self.board_faults {
            let node = rig.node_of(fault.board_id(), fault.role())?;
            rig.pending.push((SimDuration::ZERO, fault.on_node(node)));
        }
        // Each reset is over, and its generation counted, before the next.
        for k in 0..self.reset_storm {
            rig.pending
                .push((SimDuration::from_millis(u64::from(k)), TimedFault::BusReset));
        }
        Ok(rig)
    }
}

impl Rig {
    /// The board IDs, in chain order.
    pub fn ids(&self) -> Vec<u8> {
        self.boards.iter().map(|(id, _)| *id).collect()
    }

    /// The node of board `board_id`.
    pub fn node(&self, board_id: u8) -> Option<NodeHandle> {
        self.boards
            .iter()
            .find(|(id, _)| *id == board_id)
            .map(|(_, h)| *h)
    }

    /// [`node`](Self::node), or the error naming `role` and the ID.
    fn node_of(&self, board_id: u8, role: &'static str) -> Result<NodeHandle, TestbedError> {
        self.node(board_id).ok_or(TestbedError::NoSuchBoard {
            role,
            board: board_id,
        })
    }

    /// Schedule the held faults: the fault moment is `after` the bus's
    /// present time.
    pub fn schedule_pending(&mut self, after: SimDuration) {
        let at = self.bus.now() + after;
        for (offset, fault) in std::mem::take(&mut self.pending) {
            self.bus.schedule_fault(at + offset, fault);
        }
    }

    /// The held faults with their offsets from the fault moment,
    /// unscheduled (for a caller that starts them itself).
    pub fn take_pending(&mut self) -> Vec<(SimDuration, TimedFault)> {
        std::mem::take(&mut self.pending)
    }

    /// The fault target of its simulated port: a script's entries applied
    /// on this bus by the servo loop when they are due (cycle-timed ones
    /// too), boards found by ID as built here.
    pub fn fault_target(&self) -> FaultTarget {
        FaultTarget::sim(self.boards.clone())
    }

    /// The PC's port on the bus (no PC model).
    pub fn sim_port(self) -> SimPort {
        SimPort::new(self.bus, self.host)
    }

    /// An Ethernet bridge whose connected board is `bridge_board` (`None`:
    /// the first in the chain), with the board IDs.
    ///
    /// # Errors
    /// [`TestbedError::NoSuchBoard`] for a bridge board not on the rig.
    pub fn bridge(self, bridge_board: Option<u8>) -> Result<Bridge, TestbedError> {
        let node = match bridge_board {
            Some(id) => self.node_of(id, "bridge board")?,
            None => self
                .boards
                .first()
                .map(|(_, h)| *h)
                .ok_or(TestbedError::NoBoards)?,
        };
        Ok(Bridge::new(self.bus, self.host, node))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_board::qla::config::{Hardware, Profile};

    fn boards(ids: &[u8]) -> Vec<BoardConfig> {
        ids.iter()
            .map(|&id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
            .collect()
    }

    /// Boards are found by ID whatever their place in the chain; the
    /// first given gets physical ID 0 and the PC is the root.
    #[test]
    fn boards_are_known_by_id() {
        let rig = RigBuilder::qla(boards(&[4, 5, 6])).build().unwrap();
        assert_eq!(rig.ids(), [4, 5, 6]);
        let five = rig.node(5).unwrap();
        assert_eq!(rig.bus.phy_id(five), Some(1));
        assert_eq!(rig.bus.phy_id(rig.host), Some(3));
        assert_eq!(rig.node(0), None);
        assert_eq!(rig.configs.len(), 3);
    }

    /// A fault or a bridge board naming an ID the rig does not have is
    /// refused with that ID; faults are held until scheduled.
    #[test]
    fn faults_and_bridge_boards_name_existing_boards() {
        let e = RigBuilder::qla(boards(&[0, 1]))
            .board_fault(BoardFault::Mute(7))
            .build()
            .err()
            .unwrap();
        assert_eq!(e.to_string(), "muted board 7: no such board on the rig");
        let mut rig = RigBuilder::qla(boards(&[0, 1]))
            .board_fault(BoardFault::Unplug(1))
            .build()
            .unwrap();
        let one = rig.node(1).unwrap();
        assert_eq!(
            rig.take_pending(),
            [(
                SimDuration::ZERO,
                TimedFault::Disconnect {
                    node: one,
                    reconnect_after: None
                }
            )]
        );
        assert!(rig.take_pending().is_empty());
        // A reset storm is held with them, its resets 1 ms apart.
        let mut rig = RigBuilder::qla(boards(&[0]))
            .reset_storm(3)
            .build()
            .unwrap();
        assert_eq!(
            rig.take_pending(),
            [0, 1, 2].map(|ms| (SimDuration::from_millis(ms), TimedFault::BusReset))
        );
        let rig = RigBuilder::qla(boards(&[0, 1])).build().unwrap();
        let e = rig.bridge(Some(3)).err().unwrap();
        assert_eq!(e.to_string(), "bridge board 3: no such board on the rig");
        assert!(matches!(
            RigBuilder::qla(Vec::new()).build(),
            Err(TestbedError::NoBoards)
        ));
    }

    #[test]
    fn robot_kinds_by_name_and_configuration() {
        for k in RobotKind::ALL {
            assert_eq!(k.name().parse::<RobotKind>().unwrap(), k);
        }
        assert!("qla".parse::<RobotKind>().is_err());
        use firelink_control::config::presets;
        assert_eq!(
            RobotKind::of_config(&presets::snake_seed001()),
            RobotKind::Snake
        );
        assert_eq!(
            RobotKind::of_config(&presets::dvrk_seed000()),
            RobotKind::Dvrk
        );
    }
}
