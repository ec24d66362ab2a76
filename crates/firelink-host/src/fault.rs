//! A port that loses and damages packets: [`FaultyPort`] wraps any port
//! that shows its packets and, with seeded probabilities, drops packets or
//! flips one of their bits, in both directions, counting what it did. The
//! host library then meets what a lossy link gives it: time-outs naming the
//! real transaction label, CRC errors with the CRCs the packet carries,
//! refusals counted by reason ([`Port::link_stats`]).
//!
//! ```
//! # #[cfg(feature = "sim")] {
//! use firelink_host::fault::{FaultyPort, LinkFaults};
//! use firelink_host::{Dest, HostError, Port};
//! # let mut bus = firelink_bus::Bus::new(firelink_bus::BusConfig::default());
//! # let pc = bus.add(firelink_bus::HostLink::new("pc"), firelink_bus::NodeConfig::pc());
//! # bus.reset();
//! # let port = firelink_host::sim::SimPort::new(bus, pc);
//! // Every packet is lost: the read times out, naming its label.
//! let faults = LinkFaults { drop: 1.0, corrupt: 0.0 };
//! let mut port = FaultyPort::new(port, faults, 7).unwrap();
//! assert!(matches!(port.read_quadlet(Dest::node(0), 0), Err(HostError::Timeout { tl: 1, .. })));
//! assert_eq!(port.counts().dropped, 1);
//! # }
//! ```

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

use crate::error::Result;
use crate::port::{Dest, Direction, LinkFilter, Port, Verdict, forward_port};

/// How often packets are hurt, each a probability per packet (0 to 1).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LinkFaults {
    /// The packet is lost.
    pub drop: f64,
    /// One bit of the packet is flipped (the CRCs then disagree).
    pub corrupt: f64,
}

/// What a [`FaultyPort`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultCounts {
    /// Packets seen.
    pub packets: u64,
    /// Packets lost.
    pub dropped: u64,
    /// Packets with a bit flipped.
    pub corrupted: u64,
}

/// The link filter doing it.
struct RandomFaultFilter {
    faults: LinkFaults,
    rng: ChaCha8Rng,
    counts: Arc<Mutex<FaultCounts>>,
}

impl RandomFaultFilter {
    /// A uniform draw in [0, 1).
    fn draw(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

impl LinkFilter for RandomFaultFilter {
    fn packet(&mut self, _at_ps: u64, _direction: Direction, packet: &mut [u8]) -> Verdict {
        let (drop, corrupt) = (self.draw(), self.draw());
        let bit = self.rng.next_u64();
        let mut counts = self.counts.lock().unwrap_or_else(PoisonError::into_inner);
        counts.packets += 1;
        if drop < self.faults.drop {
            counts.dropped += 1;
            return Verdict::Drop;
        }
        if corrupt < self.faults.corrupt && !packet.is_empty() {
            let bit = (bit % (packet.len() as u64 * 8)) as usize;
            if let Some(b) = packet.get_mut(bit / 8) {
                *b ^= 1 << (bit % 8);
                counts.corrupted += 1;
            }
        }
        Verdict::Pass
    }
}

/// A [`Port`] whose packets are lost and damaged at seeded random. See the
/// module docs.
pub struct FaultyPort<P: Port> {
    inner: P,
    counts: Arc<Mutex<FaultCounts>>,
}

impl<P: Port> FaultyPort<P> {
    /// Wrap `inner`, hurting its packets as `faults` says, drawn from a
    /// generator seeded with `seed` (the same seed, the same faults).
    ///
    /// # Errors
    /// `inner` does not show its packets ([`Port::add_link_filter`]).
    pub fn new(mut inner: P, faults: LinkFaults, seed: u64) -> Result<FaultyPort<P>> {
        let counts = Arc::new(Mutex::new(FaultCounts::default()));
        inner.add_link_filter(Box::new(RandomFaultFilter {
            faults,
            rng: ChaCha8Rng::seed_from_u64(seed),
            counts: counts.clone(),
        }))?;
        Ok(FaultyPort { inner, counts })
    }

    /// What it did so far.
    pub fn counts(&self) -> FaultCounts {
        *self.counts.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The wrapped port.
    pub fn inner(&self) -> &P {
        &self.inner
    }

    /// The wrapped port, mutable.
    pub fn inner_mut(&mut self) -> &mut P {
        &mut self.inner
    }
}

impl<P: Port> Port for FaultyPort<P> {
    forward_port!(s => s.inner);
}
