//! A fingerprint of a board's state, for comparing two runs of the same
//! simulation cycle by cycle (two levels of detail of the simulated bus
//! must leave every board in the same state; issue 33).
//!
//! The digest covers what the board holds and what the host or the plant
//! can see: its clock, bus identity, registers (power, watchdog, axes,
//! digital outputs, PHY access), the hub (memory, count, query, boards
//! heard, the waiting and in-flight broadcast), the received-packet memory,
//! the last sample's time and the whole plant (clock, every axis's state,
//! noise streams, encoders). It leaves out what only makes the simulation
//! faster: buffers kept for reuse, the status broadcast's remembered
//! header CRC and the cached time of the next internal event, which two
//! equivalent runs may hold differently. It is computed by
//! hashing the state's `Debug` text: for tests and tools, not the real-time
//! path.

use std::hash::{DefaultHasher, Hasher};

use super::Firmware;

/// Feeds formatted text into a hasher without keeping it.
struct HashWriter(DefaultHasher);

impl core::fmt::Write for HashWriter {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.write(s.as_bytes());
        Ok(())
    }
}

impl Firmware {
    /// A 64-bit digest of the board's state (see the module docs): equal
    /// for two boards in the same state, different (but for a hash
    /// collision) when any register, hub entry or plant variable differs.
    pub fn state_digest(&self) -> u64 {
        use core::fmt::Write as _;
        let mut w = HashWriter(DefaultHasher::new());
        let hub = &self.hub;
        // Writing into a hasher cannot fail.
        let _ = write!(
            w,
            "{:?}|{:?}|{}|{:?}|{:?}|{:?}|{:?}|{:?}|{:?}|{:?}|{:?}",
            self.now,
            self.phy_id,
            self.generation,
            self.phy_ctrl,
            self.dout,
            self.power,
            self.watchdog,
            self.axes,
            self.last_sample,
            self.rx_memory,
            self.plant,
        );
        let _ = write!(
            w,
            "|{:?}|{}|{:?}|{:?}|{}|{:?}|{:?}|{:?}",
            hub.memory,
            hub.count,
            hub.query,
            hub.query_at,
            hub.seen,
            hub.complete_at,
            hub.pending,
            hub.in_flight,
        );
        w.0.finish()
    }
}

#[cfg(test)]
mod tests {
    use crate::qla::Firmware;
    use crate::qla::config::{BoardConfig, Hardware, Profile};
    use crate::time::SimTime;

    #[test]
    fn equal_boards_have_equal_digests_and_a_change_shows() {
        let a = Firmware::new(BoardConfig::new(3, Hardware::Qla1, Profile::Rev8));
        let mut b = a.clone();
        assert_eq!(a.state_digest(), b.state_digest());
        // Time passing moves the clock: a different state.
        b.advance(SimTime::from_micros(100));
        assert_ne!(a.state_digest(), b.state_digest());
        let mut c = a.clone();
        c.set_motor_supply(SimTime::ZERO, false);
        assert_ne!(a.state_digest(), c.state_digest());
    }

    #[test]
    fn a_reused_buffer_does_not_change_the_digest() {
        let a = Firmware::new(BoardConfig::new(3, Hardware::Qla1, Profile::Rev8));
        let mut b = a.clone();
        b.scratch = vec![0xA5; 64];
        b.next_event = Some(SimTime::from_micros(7));
        assert_eq!(a.state_digest(), b.state_digest());
    }
}
