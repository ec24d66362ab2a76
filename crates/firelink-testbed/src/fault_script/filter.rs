//! A [`FaultScript`] on any port that shows its packets: a link filter
//! ([`ScriptFilter`]) that drops and corrupts the packets the script's
//! entries select, and makes a board that "stops answering" silent by
//! dropping every packet to or from its node. It is how a script works
//! over UDP (the bus is in the emulator's process) and on every transport
//! that implements [`Port::add_link_filter`].
//!
//! Rules:
//! - boards are found through a board ID to node map the caller gives
//!   (the host's scan, [`ScriptFilter::for_scan`]); an entry naming a
//!   board not in it is refused, naming the board;
//! - `t=` moments count on the port's clock from the filter's creation;
//!   `cycle=` moments from the cycle reported through
//!   [`ScriptHandle::set_cycle`]: only for a caller that puts a whole
//!   script on its port itself ([`ScriptFilter::for_scan`]) and counts its
//!   own cycles; a [`FaultTarget`](super::FaultTarget)'s filters never
//!   hold a `cycle=` entry (the servo loop applies it at its cycle, as
//!   a `t=0us` filter);
//! - seen from the host, an unplugged board is a muted one (the filter
//!   cannot reset a bus in another process);
//! - host pauses are the servo loop's to do; the filter leaves them
//!   alone;
//! - the filter allocates nothing per packet and takes no lock: counts
//!   and the cycle are atomics shared with the [`ScriptHandle`];
//! - once every rule is a `count=` rule that has fired its count, the
//!   filter is spent ([`LinkFilter::is_spent`]) and the port lets it go
//!   when the next filter comes (faults injected one after another do not
//!   lengthen every packet's path).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use firelink_host::port::{Direction, LinkFilter, Port, Verdict};
use firelink_host::qla::board::BoardInfo;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

use super::{FaultMoment, FaultScript, Occurrence, PacketEffect, ScriptedFault};
use crate::TestbedError;

/// What a [`ScriptFilter`] did so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ScriptCounts {
    /// Packets seen.
    pub packets: u64,
    /// Packets a packet rule dropped.
    pub dropped: u64,
    /// Packets a packet rule corrupted.
    pub corrupted: u64,
    /// Packets lost because they went to or came from a silenced board.
    pub silenced: u64,
}

#[derive(Default)]
struct Shared {
    cycle: AtomicU64,
    packets: AtomicU64,
    dropped: AtomicU64,
    corrupted: AtomicU64,
    silenced: AtomicU64,
}

/// The servo loop's side of a [`ScriptFilter`]: it reports the cycle and
/// reads what the filter did.
#[derive(Clone)]
pub struct ScriptHandle {
    shared: Arc<Shared>,
}

impl ScriptHandle {
    /// The caller's loop is at cycle `cycle` (`cycle=` entries at or
    /// before it are in force). Only a filter made directly from a script
    /// with `cycle=` entries needs it (see the module docs); the servo
    /// loop's [`FaultTarget`](super::FaultTarget) does not use it.
    pub fn set_cycle(&self, cycle: u64) {
        self.shared.cycle.store(cycle, Ordering::Relaxed);
    }

    /// What the filter did so far.
    pub fn counts(&self) -> ScriptCounts {
        let s = &self.shared;
        ScriptCounts {
            packets: s.packets.load(Ordering::Relaxed),
            dropped: s.dropped.load(Ordering::Relaxed),
            corrupted: s.corrupted.load(Ordering::Relaxed),
            silenced: s.silenced.load(Ordering::Relaxed),
        }
    }
}

/// One entry resolved to nodes.
struct Rule {
    at: FaultMoment,
    action: Action,
}

enum Action {
    /// Every packet to or from this node is lost.
    Silence { node: u8 },
    /// Matching packets dropped or corrupted.
    Packets {
        effect: PacketEffect,
        tcode: Option<u8>,
        dest_node: Option<u8>,
        offset: Option<u16>,
        probability: f64,
        /// Firings left (`None`: unlimited).
        left: Option<u32>,
    },
}

/// A [`FaultScript`] as a port's link filter. See the module docs.
pub struct ScriptFilter {
    rules: Vec<Rule>,
    start_ps: u64,
    rng: ChaCha8Rng,
    shared: Arc<Shared>,
}

impl ScriptFilter {
    /// The filter for `script`, boards found in `nodes` (board ID, node),
    /// `t=` counted from `start_ps` on the port's clock, random draws
    /// seeded with `seed`; and its handle.
    ///
    /// # Errors
    /// [`TestbedError::NoSuchBoard`] for an entry naming a board not in
    /// `nodes`.
    pub fn new(
        script: &FaultScript,
        nodes: &[(u8, u8)],
        start_ps: u64,
        seed: u64,
    ) -> Result<(ScriptFilter, ScriptHandle), TestbedError> {
        let node_of = |board: u8, role: &'static str| {
            nodes
                .iter()
                .find(|(id, _)| *id == board)
                .map(|(_, n)| *n)
                .ok_or(TestbedError::NoSuchBoard { role, board })
        };
        let mut rules = Vec::new();
        for entry in &script.entries {
            let action = match entry.fault {
                ScriptedFault::Board(b) => Action::Silence {
                    node: node_of(b.board_id(), b.role())?,
                },
                ScriptedFault::Packets {
                    effect,
                    select,
                    occurrence,
                } => Action::Packets {
                    effect,
                    tcode: select.tcode.map(u8::from),
                    dest_node: select
                        .dest
                        .map(|d| node_of(d, "packets' destination board"))
                        .transpose()?,
                    offset: select.offset,
                    probability: match occurrence {
                        Occurrence::Rate(r) => r,
                        Occurrence::Count(_) => 1.0,
                    },
                    left: match occurrence {
                        Occurrence::Rate(_) => None,
                        Occurrence::Count(n) => Some(n),
                    },
                },
                ScriptedFault::HostPause(_) => continue,
            };
            rules.push(Rule {
                at: entry.at,
                action,
            });
        }
        let shared = Arc::new(Shared::default());
        let filter = ScriptFilter {
            rules,
            start_ps,
            rng: ChaCha8Rng::seed_from_u64(seed),
            shared: shared.clone(),
        };
        Ok((filter, ScriptHandle { shared }))
    }

    /// The filter for `script` on `port`, boards found in the host's scan
    /// (`boards`), `t=` counted from now on the port's clock; added to the
    /// port, its handle returned.
    ///
    /// # Errors
    /// As [`new`](Self::new); the port does not show its packets.
    pub fn for_scan<P: Port + ?Sized>(
        port: &mut P,
        script: &FaultScript,
        boards: &[BoardInfo],
        seed: u64,
    ) -> Result<ScriptHandle, TestbedError> {
        let nodes: Vec<(u8, u8)> = boards.iter().map(|b| (b.board_id, b.node)).collect();
        let (filter, handle) = ScriptFilter::new(script, &nodes, port.now_ps(), seed)?;
        port.add_link_filter(Box::new(filter))?;
        Ok(handle)
    }

    /// A uniform draw in [0, 1).
    fn draw(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Big-endian quadlet `q` of `packet`, if the packet is that long.
fn quadlet(packet: &[u8], q: usize) -> Option<u32> {
    (packet.len() >= 4 * (q + 1)).then(|| firelink_wire::field::read_quadlet(packet, q))
}

impl LinkFilter for ScriptFilter {
    /// Every rule is a `count=` rule that has fired its count (a silenced
    /// board and a `rate=` rule go on for good).
    fn is_spent(&self) -> bool {
        self.rules
            .iter()
            .all(|r| matches!(r.action, Action::Packets { left: Some(0), .. }))
    }

    fn packet(&mut self, at_ps: u64, _direction: Direction, packet: &mut [u8]) -> Verdict {
        self.shared.packets.fetch_add(1, Ordering::Relaxed);
        let cycle = self.shared.cycle.load(Ordering::Relaxed);
        let (q0, q1, q2) = (quadlet(packet, 0), quadlet(packet, 1), quadlet(packet, 2));
        let dest = q0.map(|q| (q >> 16) as u8 & 0x3F);
        let source = q1.map(|q| (q >> 16) as u8 & 0x3F);
        let tcode = q0.map(|q| (q >> 4) as u8 & 0xF);
        let offset = q2.map(|q| q as u16);
        let since = at_ps.saturating_sub(self.start_ps);
        for i in 0..self.rules.len() {
            let in_force = match self.rules[i].at {
                FaultMoment::Start => true,
                FaultMoment::After(d) => since >= d.as_nanos().saturating_mul(1000),
                FaultMoment::Cycle(n) => cycle >= n,
            };
            if !in_force {
                continue;
            }
            match self.rules[i].action {
                Action::Silence { node } => {
                    if dest == Some(node) || source == Some(node) {
                        self.shared.silenced.fetch_add(1, Ordering::Relaxed);
                        return Verdict::Drop;
                    }
                }
                Action::Packets {
                    effect,
                    tcode: t,
                    dest_node,
                    offset: o,
                    probability,
                    left,
                } => {
                    let matches = t.is_none_or(|t| tcode == Some(t))
                        && dest_node.is_none_or(|d| dest == Some(d))
                        && o.is_none_or(|o| offset == Some(o))
                        && left != Some(0);
                    if !matches || self.draw() >= probability {
                        continue;
                    }
                    if let Action::Packets { left: Some(n), .. } = &mut self.rules[i].action {
                        *n -= 1;
                    }
                    match effect {
                        PacketEffect::Drop => {
                            self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                            return Verdict::Drop;
                        }
                        PacketEffect::Corrupt => {
                            let bit = self.rng.next_u64() % (packet.len() as u64 * 8).max(1);
                            if let Some(b) = packet.get_mut((bit / 8) as usize) {
                                *b ^= 1 << (bit % 8);
                                self.shared.corrupted.fetch_add(1, Ordering::Relaxed);
                            }
                        }
                    }
                }
            }
        }
        Verdict::Pass
    }
}
