//! Who applies a [`FaultScript`] on one port: a [`FaultTarget`], made by
//! whoever built the port (the rig for the simulated bus, the in-process
//! emulator, or any other link), handed to the servo loop, which decides
//! when each entry is due (at the start, at a cycle, at the fault moment)
//! and has the target apply it then.
//!
//! Rules:
//! - [`FaultTarget::check`] refuses, before a run, every entry this port
//!   cannot apply, naming the entry and the port: what `apply` would
//!   refuse later (a board the target does not have, a `dest=` board the
//!   host's scan did not find, packet rules on a port that takes no link
//!   filters, the simulated bus's target on another port);
//!   [`FaultTarget::apply`] applies one entry now; its `t=` is then an
//!   offset from now (its moment is the caller's business);
//! - each link filter draws from its own seed, mixed from the target's
//!   seed (the run's) and the entry's index in its script: two `rate=`
//!   rules never draw the same sequence, and the same seed gives the
//!   same run;
//! - on the simulated bus (the rig's target): a board fault is a timed
//!   bus fault on the board's node as the rig built it (by board ID,
//!   never by its place), a packet rule is a bus fault rule from now on,
//!   a host pause is the port's wait (virtual time);
//! - on the in-process emulator: a board fault goes through the
//!   emulator's fault channel and is on its bus before `apply` returns;
//!   packet rules are a link filter on the host's port ([`ScriptFilter`]);
//!   a host pause is the port's wait;
//! - on any other link: packet rules are a link filter (refused by a port
//!   that does not show its packets); a host pause is the port's wait; a
//!   board fault is refused: from the host's side of a link one board
//!   cannot be silenced (with the broadcast protocol one block from the
//!   hub carries every board's state);
//! - a host pause starts at its moment (`t=0us` or a cycle): a later `t=`
//!   is refused;
//! - on the simulated bus a packet rule aimed at a board that is off the
//!   bus (unplugged) is refused, naming the board: the bus's rule without
//!   a destination would hit every board.

use std::any::Any;
use std::fmt;
use std::sync::Arc;

use firelink_bus::{Bus, FaultRule, NodeHandle, PacketFault, PacketMatch, SimDuration};
use firelink_host::Port;
use firelink_host::sim::SimPort;

use super::{
    BoardFault, FaultMoment, FaultScript, Occurrence, PacketEffect, PacketSelector, ScriptEntry,
    ScriptFilter, ScriptedFault,
};
use crate::TestbedError;

/// A way to put a board fault on a bus the host's port does not own: the
/// in-process emulator's fault channel
/// ([`EmulatorFaults`](crate::rig::EmulatorFaults)).
pub trait BoardFaultChannel: Send + Sync {
    /// The board IDs on that bus.
    fn boards(&self) -> &[u8];
    /// `fault` on that bus, `after` from its present time; applied when
    /// this returns.
    ///
    /// # Errors
    /// The board is not there; the bus's owner has stopped.
    fn board_fault(&self, fault: BoardFault, after: SimDuration) -> Result<(), TestbedError>;
}

/// Where a [`FaultTarget`] applies what it is given.
#[derive(Clone, Default)]
enum Place {
    /// The simulated bus the host's port drives: each board's node as the
    /// rig built it.
    Sim { boards: Vec<(u8, NodeHandle)> },
    /// The in-process emulator behind a UDP port.
    Emulator(Arc<dyn BoardFaultChannel>),
    /// Any other link: only what the host's side can do.
    #[default]
    Link,
}

/// Applies a fault script's entries on one port. See the module docs.
#[derive(Clone, Default)]
pub struct FaultTarget {
    place: Place,
    seed: u64,
}

impl fmt::Debug for FaultTarget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let place = match &self.place {
            Place::Sim { boards } => format!("simulated bus, boards {:?}", ids(boards)),
            Place::Emulator(_) => "in-process emulator".into(),
            Place::Link => "link".into(),
        };
        write!(f, "FaultTarget({place})")
    }
}

fn ids(boards: &[(u8, NodeHandle)]) -> Vec<u8> {
    boards.iter().map(|(id, _)| *id).collect()
}

impl FaultTarget {
    /// The simulated bus's target: `boards` are each board's ID and node
    /// as the rig built them ([`Rig::fault_target`](crate::rig::Rig::fault_target)).
    pub fn sim(boards: Vec<(u8, NodeHandle)>) -> FaultTarget {
        FaultTarget {
            place: Place::Sim { boards },
            seed: 0,
        }
    }

    /// The in-process emulator's target: board faults through its channel
    /// ([`Emulator::faults`](crate::rig::Emulator::faults)).
    pub fn emulator(faults: impl BoardFaultChannel + 'static) -> FaultTarget {
        FaultTarget {
            place: Place::Emulator(Arc::new(faults)),
            seed: 0,
        }
    }

    /// Any other link (UDP to a remote bridge, the Ethernet-only network,
    /// FireWire): only what the host's side can do.
    pub fn link() -> FaultTarget {
        FaultTarget::default()
    }

    /// The run's seed, from which each link filter's random draws are
    /// seeded (with the entry's index; 0 by default).
    pub fn with_seed(mut self, seed: u64) -> FaultTarget {
        self.seed = seed;
        self
    }

    /// Whether every entry of `script` can be applied on `port`; `nodes`
    /// are the boards the host's scan found (board ID, node), `None`
    /// before the scan (a `dest=` board is then checked once they are
    /// known). The error names the first entry that cannot and the port.
    ///
    /// # Errors
    /// [`TestbedError::Config`] naming the entry, the port and why;
    /// [`TestbedError::NoSuchBoard`] for a board not there.
    pub fn check<P: Port + 'static>(
        &self,
        script: &FaultScript,
        port: &P,
        nodes: Option<&[(u8, u8)]>,
    ) -> Result<(), TestbedError> {
        let on = OnPort::of(port, nodes);
        for entry in &script.entries {
            self.check_entry(entry, &on)?;
        }
        Ok(())
    }

    fn check_entry(&self, entry: &ScriptEntry, on: &OnPort<'_>) -> Result<(), TestbedError> {
        let refused = |why: &str| refusal(entry, on.name, why);
        let filter = |dest: Option<u8>| {
            if !on.takes_filters {
                return Err(refused(
                    "this port does not show its packets to a link filter (packet rules \
                     need the sim port, the in-process emulator or a UDP or FireWire link)",
                ));
            }
            match (dest, on.nodes) {
                (Some(d), Some(nodes)) if !nodes.iter().any(|(id, _)| *id == d) => {
                    Err(TestbedError::NoSuchBoard {
                        role: "packets' destination board",
                        board: d,
                    })
                }
                _ => Ok(()),
            }
        };
        // (A host pause is the port's own wait: any port, wrapped or not.)
        let host_pause = matches!(entry.fault, ScriptedFault::HostPause(_));
        if matches!(self.place, Place::Sim { .. }) && !on.sim_port && !host_pause {
            return Err(refused(
                "the simulated bus's target on another port (it applies faults on a SimPort)",
            ));
        }
        match (entry.fault, &self.place) {
            (ScriptedFault::HostPause(_), _) => match entry.at {
                FaultMoment::After(t) if t > SimDuration::ZERO => Err(refused(
                    "a host pause starts at its moment: give t=0us or cycle=N",
                )),
                _ => Ok(()),
            },
            (ScriptedFault::Board(b), Place::Sim { boards }) => {
                board_node(boards, b.board_id(), b.role()).map(|_| ())
            }
            (ScriptedFault::Packets { select, .. }, Place::Sim { boards }) => match select.dest {
                Some(d) => board_node(boards, d, "packets' destination board").map(|_| ()),
                None => Ok(()),
            },
            (ScriptedFault::Board(b), Place::Emulator(faults)) => {
                if faults.boards().contains(&b.board_id()) {
                    Ok(())
                } else {
                    Err(TestbedError::NoSuchBoard {
                        role: b.role(),
                        board: b.board_id(),
                    })
                }
            }
            (ScriptedFault::Board(_), Place::Link) => Err(refused(
                "a board cannot be silenced from the host's side of a link (behind a hub one \
                 block carries every board's state); use the sim port or the in-process emulator",
            )),
            (ScriptedFault::Packets { select, .. }, Place::Emulator(_) | Place::Link) => {
                filter(select.dest)
            }
        }
    }

    /// Apply `entry` now on `port` (its `t=` counted from now); `nodes` are
    /// the boards the host found (board ID, node), for a link filter's
    /// `dest=`.
    ///
    /// # Errors
    /// What [`check`](Self::check) refuses; a board not found; a port that
    /// does not show its packets to a link filter.
    pub fn apply<P: Port + 'static>(
        &self,
        index: usize,
        entry: &ScriptEntry,
        port: &mut P,
        nodes: &[(u8, u8)],
    ) -> Result<(), TestbedError> {
        self.check_entry(entry, &OnPort::of(port, Some(nodes)))?;
        let offset = match entry.at {
            FaultMoment::After(t) => t,
            FaultMoment::Start | FaultMoment::Cycle(_) => SimDuration::ZERO,
        };
        if let ScriptedFault::HostPause(d) = entry.fault {
            port.wait(d);
            return Ok(());
        }
        match &self.place {
            Place::Sim { boards } => {
                let name = port.name().to_string();
                let bus = (port as &mut dyn Any)
                    .downcast_mut::<SimPort>()
                    .map(SimPort::bus_mut)
                    .ok_or_else(|| {
                        refusal(entry, &name, "the simulated bus's target on another port")
                    })?;
                apply_on_bus(bus, boards, entry.fault, offset)
            }
            Place::Emulator(faults) => match entry.fault {
                ScriptedFault::Board(b) => faults.board_fault(b, offset),
                _ => self.filter(index, entry, offset, port, nodes),
            },
            Place::Link => self.filter(index, entry, offset, port, nodes),
        }
    }

    /// Every entry of `script` now, in order (each moment taken as now,
    /// `t=` counted from now; entry `i` is index `i` for its seed): an
    /// injected fault's script.
    ///
    /// # Errors
    /// As [`apply`](Self::apply), for the first entry that fails.
    pub fn apply_all<P: Port + 'static>(
        &self,
        script: &FaultScript,
        port: &mut P,
        nodes: &[(u8, u8)],
    ) -> Result<(), TestbedError> {
        for (index, entry) in script.entries.iter().enumerate() {
            self.apply(index, entry, port, nodes)?;
        }
        Ok(())
    }

    /// A packet rule (entry `index` of its script) as a link filter on the
    /// host's port, from now + `offset`.
    fn filter<P: Port>(
        &self,
        index: usize,
        entry: &ScriptEntry,
        offset: SimDuration,
        port: &mut P,
        nodes: &[(u8, u8)],
    ) -> Result<(), TestbedError> {
        let script = FaultScript::new().with(FaultMoment::After(offset), entry.fault);
        let seed = entry_seed(self.seed, index);
        let (filter, _) = ScriptFilter::new(&script, nodes, port.now_ps(), seed)?;
        let name = port.name().to_string();
        port.add_link_filter(Box::new(filter))
            .map_err(|e| refusal(entry, &name, &e.to_string()))
    }
}

/// What an entry is checked against: the port's name, whether it takes
/// link filters and is the simulated bus's, and the boards the host's
/// scan found (`None`: not yet scanned).
struct OnPort<'a> {
    name: &'a str,
    takes_filters: bool,
    sim_port: bool,
    nodes: Option<&'a [(u8, u8)]>,
}

impl<'a> OnPort<'a> {
    fn of<P: Port + 'static>(port: &'a P, nodes: Option<&'a [(u8, u8)]>) -> OnPort<'a> {
        OnPort {
            name: port.name(),
            takes_filters: port.takes_link_filters(),
            sim_port: (port as &dyn Any).is::<SimPort>(),
            nodes,
        }
    }
}

/// The seed of entry `index`'s link filter in a run seeded with `seed`
/// (SplitMix64's finaliser over both: nearby seeds and indexes give
/// unrelated streams).
pub(crate) fn entry_seed(seed: u64, index: usize) -> u64 {
    let mut z = seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// "fault ENTRY cannot be applied on PORT: WHY".
fn refusal(entry: &ScriptEntry, port_name: &str, why: &str) -> TestbedError {
    TestbedError::Config(format!(
        "fault {entry} cannot be applied on {port_name}: {why}"
    ))
}

/// The node of board `board`, or the error naming `role` and the ID.
fn board_node(
    boards: &[(u8, NodeHandle)],
    board: u8,
    role: &'static str,
) -> Result<NodeHandle, TestbedError> {
    boards
        .iter()
        .find(|(id, _)| *id == board)
        .map(|(_, n)| *n)
        .ok_or(TestbedError::NoSuchBoard { role, board })
}

/// The bus's fault rule for a script's packet rule: packets to
/// `destination_phy` (when the rule names a board), from `after` on.
pub(crate) fn bus_rule(
    effect: PacketEffect,
    select: PacketSelector,
    occurrence: Occurrence,
    destination_phy: Option<u8>,
    after: Option<firelink_bus::SimTime>,
) -> FaultRule {
    let mut matcher = PacketMatch::any();
    matcher.tcode = select.tcode;
    matcher.offset_low16 = select.offset;
    matcher.destination_phy = destination_phy;
    matcher.after = after;
    let fault = match effect {
        PacketEffect::Drop => PacketFault::Drop,
        PacketEffect::Corrupt => PacketFault::FlipBits { count: 1 },
    };
    match occurrence {
        Occurrence::Rate(p) => FaultRule::random(matcher, fault, p.clamp(0.0, 1.0)),
        Occurrence::Count(n) => FaultRule {
            count: Some(n),
            ..FaultRule::once(matcher, fault)
        },
    }
}

/// `fault` on the simulated bus, `offset` from its present time.
pub(crate) fn apply_on_bus(
    bus: &mut Bus,
    boards: &[(u8, NodeHandle)],
    fault: ScriptedFault,
    offset: SimDuration,
) -> Result<(), TestbedError> {
    let at = bus.now() + offset;
    match fault {
        ScriptedFault::Board(b) => {
            let node = board_node(boards, b.board_id(), b.role())?;
            bus.schedule_fault(at, b.on_node(node));
        }
        ScriptedFault::Packets {
            effect,
            select,
            occurrence,
        } => {
            let phy = match select.dest {
                Some(d) => {
                    let node = board_node(boards, d, "packets' destination board")?;
                    // No physical ID: the board is off the bus, and a rule
                    // without a destination would hit every board.
                    Some(bus.phy_id(node).ok_or_else(|| {
                        TestbedError::Config(format!(
                            "packets to board {d} cannot be {}: board {d} is off the bus \
                             (unplugged)",
                            match effect {
                                PacketEffect::Drop => "dropped",
                                PacketEffect::Corrupt => "corrupted",
                            }
                        ))
                    })?)
                }
                None => None,
            };
            let after = (offset > SimDuration::ZERO).then_some(at);
            bus.add_fault_rule(bus_rule(effect, select, occurrence, phy, after));
        }
        // The servo loop's: the caller waits.
        ScriptedFault::HostPause(_) => {}
    }
    Ok(())
}
