//! Per-node PHY state: the 1394a base register map and PHY-packet helpers.
//!
//! Register map (1394a base registers, the ones a link reads and writes):
//!
//! | reg | bits | field |
//! |---|---|---|
//! | 0 | 7:2 physical_ID, 1 R (root), 0 CPS | read only |
//! | 1 | 7 RHB (root holdoff), 6 IBR (initiate bus reset), 5:0 gap_count | read/write |
//! | 2 | 7:5 extended (7), 4:0 total ports | read only |
//! | 3 | 7:5 max speed (0 S100, 1 S200, 2 S400), 3:0 delay | read only |
//! | 4 | 7 LCtrl, 6 contender, 5:3 jitter, 2:0 power class | read/write |
//! | 5 | 6 ISBR (initiate short bus reset), others interrupt enables | read/write |
//! | 7 | 7:5 page select, 3:0 port select | read/write |
//!
//! Register 3's delay field gives the PHY's worst-case repeater delay as
//! `144 + 20 x delay` ns; the PHYs here repeat in 144 ns (the bus timing's
//! figure), so it reads 0, as the FPGA1394's PHY does: a board reads
//! `0x40` (S400, delay 0) and `0xE2` in register 2 (`fpga-board-extras.md`
//! §8, fpgatest `f`).
//!
//! Gap-count rule (1394a): a PHY configuration packet with the gap-count bit
//! set changes every PHY's gap count; a bus reset keeps that value, but the
//! gap count returns to 63 after a bus reset that was not preceded by such a
//! packet since the previous reset.

use firelink_wire::packet::{Speed, Tcode};
use firelink_wire::phy::PhyPacket;

use crate::timing::DEFAULT_GAP_COUNT;

/// The sixteen base PHY registers of one node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhyRegisters {
    regs: [u8; 16],
}

impl Default for PhyRegisters {
    /// [`PhyRegisters::new`]`(0)`.
    fn default() -> Self {
        PhyRegisters::new(0)
    }
}

impl PhyRegisters {
    /// A PHY off any bus with physical ID `phy_id` as the FPGA1394 has it:
    /// 2 ports, S400, gap count 63 (what a board's firmware reaches through
    /// PHY_CTRL when it runs without a bus).
    pub fn new(phy_id: u8) -> PhyRegisters {
        let mut r = PhyRegisters::with_ports(2, Speed::S400);
        r.set_identity(phy_id, false);
        r
    }

    /// Registers of a PHY with `ports` ports and maximum speed `speed`, gap
    /// count 63, not yet on a bus.
    pub fn with_ports(ports: u8, speed: Speed) -> PhyRegisters {
        let mut regs = [0u8; 16];
        regs[0] = 0x3F << 2;
        regs[1] = DEFAULT_GAP_COUNT;
        regs[2] = (7 << 5) | (ports & 0x1F);
        regs[3] = speed.code() << 5;
        regs[4] = 0x80 | 0x04; // link active, power class 4
        PhyRegisters { regs }
    }

    /// Read a register (0 past the map).
    pub fn read(&self, reg: u8) -> u8 {
        self.regs.get(usize::from(reg)).copied().unwrap_or(0)
    }

    /// A write from the link: read-only registers ignore it.
    pub fn write(&mut self, reg: u8, value: u8) {
        match reg {
            1 | 4 | 5 | 7 => {
                if let Some(r) = self.regs.get_mut(usize::from(reg)) {
                    *r = value;
                }
            }
            _ => {}
        }
    }

    /// Physical ID field of register 0.
    pub fn phy_id(&self) -> u8 {
        self.regs[0] >> 2
    }

    /// Whether register 0 says this PHY is the root.
    pub fn is_root(&self) -> bool {
        self.regs[0] & 0x02 != 0
    }

    /// Gap count (register 1 bits 5:0).
    pub fn gap_count(&self) -> u8 {
        self.regs[1] & 0x3F
    }

    /// Root holdoff bit.
    pub fn root_holdoff(&self) -> bool {
        self.regs[1] & 0x80 != 0
    }

    /// Set register 0 after self-ID.
    pub(crate) fn set_identity(&mut self, phy_id: u8, root: bool) {
        self.regs[0] = ((phy_id & 0x3F) << 2) | (u8::from(root) << 1) | (self.regs[0] & 1);
    }

    /// Set the gap count field.
    pub(crate) fn set_gap_count(&mut self, gap: u8) {
        self.regs[1] = (self.regs[1] & 0xC0) | (gap & 0x3F);
    }

    /// Set or clear root holdoff.
    pub(crate) fn set_root_holdoff(&mut self, on: bool) {
        self.regs[1] = (self.regs[1] & 0x7F) | (u8::from(on) << 7);
    }

    /// Take (and clear) the IBR bit: a long reset was asked for.
    pub(crate) fn take_ibr(&mut self) -> bool {
        let set = self.regs[1] & 0x40 != 0;
        self.regs[1] &= !0x40;
        set
    }

    /// Take (and clear) the ISBR bit: a short reset was asked for.
    pub(crate) fn take_isbr(&mut self) -> bool {
        let set = self.regs[5] & 0x40 != 0;
        self.regs[5] &= !0x40;
        set
    }

    /// Whether the link is active (register 4 bit 7).
    pub fn link_active(&self) -> bool {
        self.regs[4] & 0x80 != 0
    }

    /// Contender bit (register 4 bit 6).
    pub fn contender(&self) -> bool {
        self.regs[4] & 0x40 != 0
    }
}

/// Build the link-internal form (tcode 0xE, 12 bytes: header quadlet, PHY
/// quadlet, complement) of a PHY packet, the form [`TransmitRequest`]
/// carries.
///
/// [`TransmitRequest`]: crate::node::TransmitRequest
pub fn phy_packet_bytes(packet: &PhyPacket) -> Vec<u8> {
    let body = packet.to_quadlet();
    let mut out = Vec::with_capacity(12);
    out.extend_from_slice(&(u32::from(u8::from(Tcode::LinkInternal)) << 4).to_be_bytes());
    out.extend_from_slice(&body.to_be_bytes());
    out.extend_from_slice(&(!body).to_be_bytes());
    out
}

/// A PHY configuration packet setting every PHY's gap count (and optionally
/// the root for the next reset), in link-internal form.
pub fn phy_config_packet(gap_count: Option<u8>, force_root: Option<u8>) -> Vec<u8> {
    phy_packet_bytes(&PhyPacket::Config {
        force_root,
        gap_count: gap_count.map(|g| g & 0x3F),
    })
}

/// Decode a link-internal PHY packet (tcode 0xE, body and complement);
/// `None` if the bytes are not one or the complement check fails.
pub fn parse_phy_packet(bytes: &[u8]) -> Option<PhyPacket> {
    let word = |i: usize| -> Option<u32> {
        let b = bytes.get(i * 4..i * 4 + 4)?;
        Some(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    };
    let q0 = word(0)?;
    if (q0 >> 4) & 0xF != u32::from(u8::from(Tcode::LinkInternal)) {
        return None;
    }
    PhyPacket::from_pair(word(1)?, word(2)?).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn register_map() {
        let mut r = PhyRegisters::with_ports(3, Speed::S400);
        assert_eq!(r.phy_id(), 63);
        assert_eq!(r.gap_count(), 63);
        assert_eq!(r.read(2), 0xE3);
        assert_eq!(r.read(3), 0x40, "S400, repeater delay 0 (144 ns)");
        assert_eq!(PhyRegisters::with_ports(2, Speed::S400).read(2), 0xE2);
        assert_eq!(PhyRegisters::new(4).read(2), 0xE2, "the FPGA1394's PHY");
        assert_eq!(r.read(200), 0);
        r.set_identity(5, true);
        assert_eq!(r.read(0), (5 << 2) | 2);
        r.write(0, 0xFF); // read only
        assert_eq!(r.phy_id(), 5);
        r.write(1, 0x40 | 26);
        assert_eq!(r.gap_count(), 26);
        assert!(r.take_ibr());
        assert!(!r.take_ibr());
        assert_eq!(r.gap_count(), 26);
    }

    #[test]
    fn phy_config_round_trip() {
        let bytes = phy_config_packet(Some(5), None);
        assert_eq!(bytes.len(), 12);
        assert_eq!(
            parse_phy_packet(&bytes),
            Some(PhyPacket::Config {
                force_root: None,
                gap_count: Some(5)
            })
        );
        let mut bad = bytes.clone();
        bad[11] ^= 1;
        assert_eq!(parse_phy_packet(&bad), None);
        assert_eq!(parse_phy_packet(&bytes[..7]), None);
    }
}
