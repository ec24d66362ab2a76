//! Brakes wired across boards: a spring-applied brake on one board's joint,
//! released by the current of an amplifier channel (often on another
//! board), as the dVRK ECM's three brakes hang on its second QLA.
//!
//! The wire between them is a [`BrakeLine`]: the driving board says, from
//! its channel's current command, whether the brake is open; the braked
//! board's joint does not move while it is not. The coil's electrical time
//! constant (milliseconds) is not modelled: the brake opens when the
//! channel's amplifier is on with a command of at least the pull-in current
//! and stays open until the command falls below the drop-out current (a
//! real brake's hysteresis; the console holds the larger release current
//! for seconds, then the smaller holding current).
//!
//! **Time.** The driving board updates the line when its amplifier inputs
//! change (a write, the enable delay, the watchdog, a fault), at that
//! instant of virtual time; the braked board takes the line's state when
//! it next looks at its plant. A brake therefore acts at most one bus
//! exchange of the braked board late (one servo cycle), the same in every
//! run: the boards handle the bus's events in its deterministic order.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// The wire from a brake's amplifier channel to its brake: `true` while
/// the brake is open (released). Clones are the same wire.
#[derive(Debug, Clone, Default)]
pub struct BrakeLine(Arc<AtomicBool>);

impl BrakeLine {
    /// A new wire, the brake engaged.
    pub fn new() -> BrakeLine {
        BrakeLine::default()
    }

    /// Whether the brake is released.
    pub fn released(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }

    fn set(&self, released: bool) {
        self.0.store(released, Ordering::Release);
    }
}

impl PartialEq for BrakeLine {
    /// The same wire.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// What one board does with a brake.
#[derive(Debug, Clone, PartialEq)]
pub enum BrakeWire {
    /// Axis `axis`'s amplifier drives the brake's coil.
    Drives {
        /// The channel.
        axis: usize,
        /// The wire.
        line: BrakeLine,
        /// Command that opens the brake, A.
        pull_in_amps: f64,
        /// Command below which an open brake closes, A.
        drop_out_amps: f64,
    },
    /// The brake holds axis `axis`'s joint.
    Holds {
        /// The braked axis.
        axis: usize,
        /// The wire.
        line: BrakeLine,
    },
}

impl BrakeWire {
    /// The driving end, with its thresholds from the configuration's
    /// currents: the brake opens at the middle of the holding and release
    /// currents, and stays open down to half the holding current.
    pub fn drives(axis: usize, line: BrakeLine, release_amps: f64, hold_amps: f64) -> BrakeWire {
        let hold = hold_amps.abs().min(release_amps.abs());
        BrakeWire::Drives {
            axis,
            line,
            pull_in_amps: 0.5 * (hold + release_amps.abs()),
            drop_out_amps: 0.5 * hold,
        }
    }

    /// The driving end's new state from its channel: amplifier `on` with
    /// current command `amps`. Returns whether the line changed.
    pub(crate) fn drive(&self, on: bool, amps: f64) -> bool {
        let BrakeWire::Drives {
            line,
            pull_in_amps,
            drop_out_amps,
            ..
        } = self
        else {
            return false;
        };
        let was = line.released();
        let now = on
            && if was {
                amps.abs() >= *drop_out_amps
            } else {
                amps.abs() >= *pull_in_amps
            };
        line.set(now);
        now != was
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_brake_opens_at_pull_in_and_closes_at_drop_out() {
        let line = BrakeLine::new();
        // The stock ECM's first brake: 0.25 A to release, 0.09 A to hold.
        let w = BrakeWire::drives(0, line.clone(), 0.25, 0.09);
        assert!(!line.released());
        assert!(!w.drive(true, 0.09), "the holding current does not open it");
        assert!(!line.released());
        assert!(w.drive(true, 0.25));
        assert!(line.released());
        assert!(!w.drive(true, 0.09), "but keeps it open");
        assert!(w.drive(true, 0.02), "below drop-out it closes");
        assert!(w.drive(true, -0.25), "either direction");
        assert!(w.drive(false, 0.25), "amplifier off: closed");
        assert_eq!(w, w.clone());
        assert_ne!(BrakeLine::new(), line);
    }
}
