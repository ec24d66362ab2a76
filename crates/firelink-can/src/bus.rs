//! A CAN bus in virtual time: frames wait in their nodes, arbitrate by
//! identifier when the bus is free, occupy it for their exact bit count,
//! and are retransmitted after an error frame.
//!
//! - **Arbitration**: when the bus becomes free (after the intermission),
//!   every node with a frame ready starts it; the bitwise arbitration over
//!   the identifier lets the lowest identifier through (a data frame beats
//!   a remote frame with the same identifier) and the others wait for the
//!   next free bus. It costs no time: the winner's frame simply goes on.
//!   Two nodes sending the same identifier with different data would
//!   collide on a real bus; here the lower node index wins (do not build
//!   such a schedule).
//! - **Errors**: a frame may be hit by a bit error (seeded, with a
//!   probability per transmission, or injected on the next transmission).
//!   At the erroneous bit the detecting node sends an error flag (6 bits),
//!   the others answer with theirs (up to 6 more), then an 8-bit error
//!   delimiter and the 3-bit intermission; the transmitter retries, in a
//!   new arbitration. Fault confinement follows the standard's counters:
//!   transmit error counter +8 per error and -1 per success, receive
//!   counters +1 / -1; above 127 a node is error-passive (it waits an
//!   extra 8-bit suspend time after each of its transmissions), above 255
//!   bus-off (its frames are dropped).
//!
//! Nothing here reads a clock: time is a [`Duration`] since the bus
//! started, advanced only by the frames.

use core::time::Duration;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

use crate::frame::Frame;
use crate::{CanError, Result};

/// Error flag of the node that detects an error.
pub const ERROR_FLAG_BITS: usize = 6;
/// Error delimiter.
pub const ERROR_DELIMITER_BITS: usize = 8;
/// Intermission after every frame.
pub const INTERMISSION_BITS: usize = 3;
/// Suspend transmission of an error-passive transmitter.
pub const SUSPEND_BITS: usize = 8;

/// How the bus behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CanConfig {
    /// Bits per second (1 Mb/s: the fastest CAN 2.0).
    pub bit_rate: u64,
    /// Chance that a transmission is hit by a bit error.
    pub error_probability: f64,
    /// Bits of the other nodes' error flags after the first (0 to 6).
    pub echo_flag_bits: usize,
    /// Seed of the error draws.
    pub seed: u64,
}

impl Default for CanConfig {
    fn default() -> Self {
        CanConfig {
            bit_rate: 1_000_000,
            error_probability: 0.0,
            echo_flag_bits: 6,
            seed: 0,
        }
    }
}

/// A node's place on the bus.
pub type NodeIndex = usize;

/// A node's fault-confinement state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorState {
    /// Normal.
    Active,
    /// Transmit error counter above 127.
    Passive,
    /// Transmit error counter above 255: off the bus.
    BusOff,
}

#[derive(Debug, Clone)]
struct NodeState {
    name: String,
    tec: u32,
    rec: u32,
    suspended_until: Duration,
}

impl NodeState {
    fn state(&self) -> ErrorState {
        if self.tec > 255 {
            ErrorState::BusOff
        } else if self.tec > 127 || self.rec > 127 {
            ErrorState::Passive
        } else {
            ErrorState::Active
        }
    }
}

#[derive(Debug, Clone)]
struct Pending {
    token: u64,
    node: NodeIndex,
    frame: Frame,
    ready_at: Duration,
    submitted_at: Duration,
    attempts: u32,
    lost_arbitration: u32,
}

/// How a frame ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// Every node received it.
    Delivered,
    /// Its node went bus-off before it got through.
    BusOff,
}

/// One frame's journey.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Delivery {
    /// The token [`CanBus::submit`] returned.
    pub token: u64,
    /// The sending node.
    pub node: NodeIndex,
    /// The frame.
    pub frame: Frame,
    /// When it was handed to its node.
    pub submitted_at: Duration,
    /// When its last attempt started.
    pub started_at: Duration,
    /// When receivers had it (end of frame).
    pub delivered_at: Duration,
    /// When the bus was free again (after the intermission).
    pub bus_free_at: Duration,
    /// Attempts (1 without errors).
    pub attempts: u32,
    /// Arbitrations it lost.
    pub lost_arbitration: u32,
    /// How it ended.
    pub outcome: Outcome,
}

/// One error frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorEvent {
    /// When the erroneous bit was sent.
    pub at: Duration,
    /// The transmitter.
    pub node: NodeIndex,
    /// Its frame's token.
    pub token: u64,
    /// Which bit of the frame was hit (0 = start of frame).
    pub bit: usize,
    /// Bus time lost: the bits sent so far, the error frame, the
    /// intermission.
    pub lost: Duration,
}

/// The bus. See the module docs.
#[derive(Debug, Clone)]
pub struct CanBus {
    config: CanConfig,
    bit: Duration,
    now: Duration,
    nodes: Vec<NodeState>,
    pending: Vec<Pending>,
    rng: ChaCha8Rng,
    next_token: u64,
    forced_errors: Vec<usize>,
    errors: Vec<ErrorEvent>,
    busy: Duration,
}

impl CanBus {
    /// An empty bus.
    ///
    /// # Errors
    /// [`CanError::Config`] for a bit rate of 0 or above 1 Gb/s, or an
    /// error probability outside 0..1.
    pub fn new(config: CanConfig) -> Result<CanBus> {
        if config.bit_rate == 0 || config.bit_rate > 1_000_000_000 {
            return Err(CanError::Config("bit rate must be 1 b/s to 1 Gb/s"));
        }
        if !(0.0..1.0).contains(&config.error_probability) {
            return Err(CanError::Config("error probability must be in [0, 1)"));
        }
        Ok(CanBus {
            bit: Duration::from_nanos(1_000_000_000 / config.bit_rate),
            now: Duration::ZERO,
            nodes: Vec::new(),
            pending: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(config.seed ^ 0x0CA4),
            next_token: 0,
            forced_errors: Vec::new(),
            errors: Vec::new(),
            busy: Duration::ZERO,
            config,
        })
    }

    /// Add a node; returns its index.
    pub fn add_node(&mut self, name: impl Into<String>) -> NodeIndex {
        self.nodes.push(NodeState {
            name: name.into(),
            tec: 0,
            rec: 0,
            suspended_until: Duration::ZERO,
        });
        self.nodes.len() - 1
    }

    /// One bit time (rounded to a nanosecond).
    pub fn bit_time(&self) -> Duration {
        self.bit
    }

    /// Time on the bus of `bits` bits.
    pub fn bits(&self, bits: usize) -> Duration {
        self.bit * bits as u32
    }

    /// The time of the last event.
    pub fn now(&self) -> Duration {
        self.now
    }

    /// Time the bus carried frames or error frames.
    pub fn busy_time(&self) -> Duration {
        self.busy
    }

    /// A node's name.
    pub fn name(&self, node: NodeIndex) -> Option<&str> {
        self.nodes.get(node).map(|n| n.name.as_str())
    }

    /// A node's error state.
    pub fn error_state(&self, node: NodeIndex) -> Option<ErrorState> {
        self.nodes.get(node).map(NodeState::state)
    }

    /// A node's transmit error counter.
    pub fn transmit_errors(&self, node: NodeIndex) -> Option<u32> {
        self.nodes.get(node).map(|n| n.tec)
    }

    /// Every error frame so far.
    pub fn errors(&self) -> &[ErrorEvent] {
        &self.errors
    }

    /// Frames waiting.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Hit the next transmission with a bit error at `bit` (0 = start of
    /// frame; past the end of frame means its last bit). Several calls hit
    /// several transmissions, in order.
    pub fn inject_error(&mut self, bit: usize) {
        self.forced_errors.push(bit);
    }

    /// Give `frame` to `node`, to be sent from `ready_at` on; returns its
    /// token.
    ///
    /// # Errors
    /// [`CanError::NoSuchNode`].
    pub fn submit(&mut self, node: NodeIndex, frame: Frame, ready_at: Duration) -> Result<u64> {
        if node >= self.nodes.len() {
            return Err(CanError::NoSuchNode(node));
        }
        self.next_token += 1;
        self.pending.push(Pending {
            token: self.next_token,
            node,
            frame,
            ready_at,
            submitted_at: ready_at,
            attempts: 0,
            lost_arbitration: 0,
        });
        Ok(self.next_token)
    }

    /// When a pending frame may start: ready, and its node not suspended.
    fn eligible_at(&self, p: &Pending) -> Duration {
        let suspended = self
            .nodes
            .get(p.node)
            .map_or(Duration::ZERO, |n| n.suspended_until);
        p.ready_at.max(suspended)
    }

    /// Run until the next frame is delivered (or dropped at bus-off);
    /// `None` when nothing is left to send.
    pub fn step(&mut self) -> Option<Delivery> {
        loop {
            if let Some(d) = self.drop_bus_off() {
                return Some(d);
            }
            // The bus is free at `now`; the next arbitration is at the first
            // instant a frame is eligible.
            let start = self
                .pending
                .iter()
                .map(|p| self.eligible_at(p))
                .min()?
                .max(self.now);
            // Arbitration among every eligible frame: lowest identifier,
            // data before remote, then lowest node.
            let winner = self
                .pending
                .iter()
                .enumerate()
                .filter(|(_, p)| self.eligible_at(p) <= start)
                .min_by_key(|(_, p)| (p.frame.id(), p.frame.is_remote(), p.node))
                .map(|(i, _)| i)?;
            for (i, p) in self.pending.iter_mut().enumerate() {
                if i != winner && p.ready_at <= start {
                    p.lost_arbitration += 1;
                }
            }
            let p = self.pending.get_mut(winner)?;
            p.attempts += 1;
            let frame = p.frame;
            let node = p.node;
            let token = p.token;
            let hit = if self.forced_errors.is_empty() {
                let draw = (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                (draw < self.config.error_probability)
                    .then(|| (self.rng.next_u64() % frame.bits_to_end_of_frame() as u64) as usize)
            } else {
                Some(self.forced_errors.remove(0))
            };
            let passive = self
                .nodes
                .get(node)
                .is_some_and(|n| n.state() == ErrorState::Passive);
            let suspend = if passive {
                self.bits(SUSPEND_BITS)
            } else {
                Duration::ZERO
            };
            if let Some(bit) = hit {
                let bit = bit.min(frame.bits_to_end_of_frame() - 1);
                let lost_bits = bit
                    + 1
                    + ERROR_FLAG_BITS
                    + self.config.echo_flag_bits.min(6)
                    + ERROR_DELIMITER_BITS
                    + INTERMISSION_BITS;
                let lost = self.bits(lost_bits);
                self.errors.push(ErrorEvent {
                    at: start + self.bits(bit),
                    node,
                    token,
                    bit,
                    lost,
                });
                for (i, n) in self.nodes.iter_mut().enumerate() {
                    if i == node {
                        n.tec += 8;
                        n.suspended_until = start + lost + suspend;
                    } else if n.state() != ErrorState::BusOff {
                        n.rec += 1;
                    }
                }
                self.busy += lost;
                self.now = start + lost;
                continue;
            }
            let p = self.pending.swap_remove(winner);
            let end = start + self.bits(frame.bits_to_end_of_frame());
            let free = start + self.bits(frame.bits());
            for (i, n) in self.nodes.iter_mut().enumerate() {
                if i == node {
                    n.tec = n.tec.saturating_sub(1);
                    n.suspended_until = free + suspend;
                } else {
                    n.rec = n.rec.saturating_sub(1);
                }
            }
            self.busy += free - start;
            self.now = free;
            return Some(Delivery {
                token,
                node,
                frame,
                submitted_at: p.submitted_at,
                started_at: start,
                delivered_at: end,
                bus_free_at: free,
                attempts: p.attempts,
                lost_arbitration: p.lost_arbitration,
                outcome: Outcome::Delivered,
            });
        }
    }

    /// Drop one frame of a bus-off node, if there is one.
    fn drop_bus_off(&mut self) -> Option<Delivery> {
        let i = self.pending.iter().position(|p| {
            self.nodes
                .get(p.node)
                .is_none_or(|n| n.state() == ErrorState::BusOff)
        })?;
        let p = self.pending.swap_remove(i);
        Some(Delivery {
            token: p.token,
            node: p.node,
            frame: p.frame,
            submitted_at: p.submitted_at,
            started_at: self.now,
            delivered_at: self.now,
            bus_free_at: self.now,
            attempts: p.attempts,
            lost_arbitration: p.lost_arbitration,
            outcome: Outcome::BusOff,
        })
    }

    /// Run until nothing is left to send; every frame's delivery, in order.
    pub fn run_until_idle(&mut self) -> Vec<Delivery> {
        let mut out = Vec::new();
        while let Some(d) = self.step() {
            out.push(d);
        }
        out
    }
}
