//! PHY packets: self-ID, PHY configuration and link-on.
//!
//! A PHY packet is one quadlet followed on the wire by its bitwise complement.
//! The simulated bus uses self-ID packets during bus reset and PHY
//! configuration packets to set the gap count (`ieee1394.md`, "Gaps").

use crate::error::{Error, Result};
use crate::field::Field;

/// The PHY-link interface clock (SCLK), 49.152 MHz: the 1394 base rate's
/// clock, which every node's link runs on. The boards' logic runs on it
/// too and counts their timestamps and timers in its cycles: the QLA
/// board's system clock (`fpga-board.md` §2, §4), the Snake node's
/// timestamp clock (seed 001 §5.3), and the simulated bus's cycle counter.
pub const SYSTEM_CLOCK_HZ: u32 = 49_152_000;

mod field {
    use crate::field::Field;
    pub const IDENTIFIER: Field = Field::new(0, 31, 30);
    pub const PHY_ID: Field = Field::new(0, 29, 24);
    // Self-ID packet 0.
    pub const SELF_ID_EXTENDED: Field = Field::new(0, 23, 23);
    pub const LINK_ACTIVE: Field = Field::new(0, 22, 22);
    pub const GAP_COUNT: Field = Field::new(0, 21, 16);
    pub const SPEED: Field = Field::new(0, 15, 14);
    pub const CONTENDER: Field = Field::new(0, 11, 11);
    pub const POWER_CLASS: Field = Field::new(0, 10, 8);
    pub const PORT0: Field = Field::new(0, 7, 6);
    pub const PORT1: Field = Field::new(0, 5, 4);
    pub const PORT2: Field = Field::new(0, 3, 2);
    pub const INITIATED_RESET: Field = Field::new(0, 1, 1);
    pub const MORE_PACKETS: Field = Field::new(0, 0, 0);
    // PHY configuration packet.
    pub const FORCE_ROOT: Field = Field::new(0, 23, 23);
    pub const SET_GAP_COUNT: Field = Field::new(0, 22, 22);
}

/// State of one PHY port as reported in a self-ID packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PortStatus {
    /// No such port.
    NotPresent = 0,
    /// Port present, nothing connected.
    NotConnected = 1,
    /// Connected towards the root (to the parent).
    Parent = 2,
    /// Connected away from the root (to a child).
    Child = 3,
}

impl PortStatus {
    fn from_bits(bits: u32) -> PortStatus {
        match bits & 3 {
            0 => PortStatus::NotPresent,
            1 => PortStatus::NotConnected,
            2 => PortStatus::Parent,
            _ => PortStatus::Child,
        }
    }
}

/// Self-ID packet 0, sent by every PHY after a bus reset in ID order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SelfId {
    /// Physical ID assigned during self-identification.
    pub phy_id: u8,
    /// The node's link layer is active.
    pub link_active: bool,
    /// The PHY's current gap count.
    pub gap_count: u8,
    /// Speed capability code (0 = S100, 1 = S200, 2 = S400).
    pub speed: u8,
    /// Bus manager contender.
    pub contender: bool,
    /// Power class (3 bits).
    pub power_class: u8,
    /// Ports 0..2.
    pub ports: [PortStatus; 3],
    /// This node initiated the reset.
    pub initiated_reset: bool,
}

/// The meaning of one PHY packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PhyPacket {
    /// Self-ID packet 0.
    SelfId(SelfId),
    /// PHY configuration: optionally force a root, optionally set the gap count.
    Config {
        /// Node to become root on the next reset.
        force_root: Option<u8>,
        /// New gap count for every PHY.
        gap_count: Option<u8>,
    },
    /// Link-on: wake the link layer of `phy_id`.
    LinkOn {
        /// Target physical ID.
        phy_id: u8,
    },
    /// Any other PHY quadlet (extended PHY packets, self-ID continuation).
    Other(u32),
}

impl PhyPacket {
    /// Decode a PHY packet body quadlet.
    pub fn from_quadlet(q: u32) -> PhyPacket {
        let f = |field: Field| field.extract(q);
        match f(field::IDENTIFIER) {
            0b10 if f(field::SELF_ID_EXTENDED) == 0 => PhyPacket::SelfId(SelfId {
                phy_id: f(field::PHY_ID) as u8,
                link_active: f(field::LINK_ACTIVE) == 1,
                gap_count: f(field::GAP_COUNT) as u8,
                speed: f(field::SPEED) as u8,
                contender: f(field::CONTENDER) == 1,
                power_class: f(field::POWER_CLASS) as u8,
                ports: [
                    PortStatus::from_bits(f(field::PORT0)),
                    PortStatus::from_bits(f(field::PORT1)),
                    PortStatus::from_bits(f(field::PORT2)),
                ],
                initiated_reset: f(field::INITIATED_RESET) == 1,
            }),
            0b00 if f(field::FORCE_ROOT) == 1 || f(field::SET_GAP_COUNT) == 1 => {
                PhyPacket::Config {
                    force_root: (f(field::FORCE_ROOT) == 1).then(|| f(field::PHY_ID) as u8),
                    gap_count: (f(field::SET_GAP_COUNT) == 1).then(|| f(field::GAP_COUNT) as u8),
                }
            }
            0b01 => PhyPacket::LinkOn {
                phy_id: f(field::PHY_ID) as u8,
            },
            _ => PhyPacket::Other(q),
        }
    }

    /// Decode a PHY packet and its complement quadlet.
    ///
    /// # Errors
    /// [`Error::Malformed`] if the second quadlet is not the complement.
    pub fn from_pair(body: u32, check: u32) -> Result<PhyPacket> {
        if check != !body {
            return Err(Error::Malformed {
                what: "PHY packet complement",
                value: body,
            });
        }
        Ok(Self::from_quadlet(body))
    }

    /// Encode as the body quadlet.
    pub fn to_quadlet(&self) -> u32 {
        let mut q = 0;
        let mut put = |field: Field, v: u32| q = field.insert(q, v);
        match *self {
            PhyPacket::SelfId(s) => {
                put(field::IDENTIFIER, 0b10);
                put(field::PHY_ID, u32::from(s.phy_id));
                put(field::LINK_ACTIVE, u32::from(s.link_active));
                put(field::GAP_COUNT, u32::from(s.gap_count));
                put(field::SPEED, u32::from(s.speed));
                put(field::CONTENDER, u32::from(s.contender));
                put(field::POWER_CLASS, u32::from(s.power_class));
                put(field::PORT0, s.ports[0] as u32);
                put(field::PORT1, s.ports[1] as u32);
                put(field::PORT2, s.ports[2] as u32);
                put(field::INITIATED_RESET, u32::from(s.initiated_reset));
                put(field::MORE_PACKETS, 0);
            }
            PhyPacket::Config {
                force_root,
                gap_count,
            } => {
                if let Some(root) = force_root {
                    put(field::PHY_ID, u32::from(root));
                    put(field::FORCE_ROOT, 1);
                }
                if let Some(gap) = gap_count {
                    put(field::GAP_COUNT, u32::from(gap));
                    put(field::SET_GAP_COUNT, 1);
                }
            }
            PhyPacket::LinkOn { phy_id } => {
                put(field::IDENTIFIER, 0b01);
                put(field::PHY_ID, u32::from(phy_id));
            }
            PhyPacket::Other(raw) => q = raw,
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn self_id_round_trip() {
        let s = SelfId {
            phy_id: 7,
            link_active: true,
            gap_count: 63,
            speed: 2,
            contender: false,
            power_class: 4,
            ports: [
                PortStatus::Parent,
                PortStatus::Child,
                PortStatus::NotPresent,
            ],
            initiated_reset: true,
        };
        let q = PhyPacket::SelfId(s).to_quadlet();
        assert_eq!(q >> 30, 0b10);
        assert_eq!(PhyPacket::from_pair(q, !q), Ok(PhyPacket::SelfId(s)));
        assert!(PhyPacket::from_pair(q, q).is_err());
    }

    #[test]
    fn config_sets_gap_count() {
        let p = PhyPacket::Config {
            force_root: Some(8),
            gap_count: Some(5),
        };
        let q = p.to_quadlet();
        assert_eq!(q, 0x08C5_0000);
        assert_eq!(PhyPacket::from_quadlet(q), p);
    }
}
