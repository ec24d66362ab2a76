//! The Ethernet side of an FPGA V3 (`rev9-fpga-v3.md`): register 12 as the
//! V3's status and control word, and its two RTL8211F PHYs behind the MDIO
//! windows `0x41A0` / `0x42A0` of space 4.
//!
//! Facts (`firelink_wire::qla::fpga_v3` cites them): the status word's
//! version bits `01`, clock checks, UDP mode, the PS Ethernet enable (bit
//! 16, Rev 9 on; 0 before), ACCESS_ERR 0 at Rev 9, one status byte per
//! port; the control word's clear-errors, per-port PHY reset and PS
//! Ethernet enable; the firmware's PHY reset (RTL8211F.v: reset held 10 ms,
//! then the PHY's IRQ line, "experimentally about 160 ms", then the
//! initialisation programme reads the PHY IDs `0x001C` / `0xC916`).
//!
//! Modelling choices:
//! - The board has been powered for a while: both PHYs start initialised,
//!   FPGA V3.1 (IRQ line wired), and Eth1's link follows
//!   [`EthernetV3::set_link`] (the port the host or the previous board is
//!   on) at 1 Gb/s; Eth2 has no link (the Ethernet-only network's chain,
//!   `firelink_emulate::qla::eth_network`, does not reach these bits yet). The
//!   PS Ethernet starts enabled.
//! - A PHY reset takes the port down (not initialised, no link) for
//!   [`PHY_RESET_TIME`]: the 10 ms reset plus the 160 ms until the PHY
//!   signals; then the firmware's programme runs and the port is back.
//! - No error bit is ever set (no malformed traffic reaches the model), so
//!   the clear-errors bits change nothing that reads back.
//! - MDIO: PHY address 1 (and the broadcast address 0) is the RTL8211F;
//!   its IEEE registers 0-3, the page select (31), INER (18, page 0xA42),
//!   PHYSR (26) and INSR (29, page 0xA43) read as the chip does for the
//!   port's state; other registers hold what was last written on their
//!   page (0 before). Other PHY addresses read `0xFFFF` (MDIO pulled
//!   high: nobody drives it). A request completes at once: the window
//!   reads state 0 (idle) by the time the host reads it.

use std::collections::BTreeMap;

use firelink_wire::qla::fpga_v3::{
    EthControlV3, EthPortStatusV3, EthStatusV3, MdioRequest, MdioResult, PHY_ADDR_BROADCAST,
    PHY_ADDR_RTL8211F, PhyPort, VERSION_V3, rtl8211f, speed,
};

use crate::time::{SimDuration, SimTime};

/// How long a port stays down after the host resets its PHY: the reset is
/// held 10 ms, then the firmware waits for the PHY's interrupt (about
/// 160 ms, RTL8211F.v) before it re-reads the PHY IDs.
pub const PHY_RESET_TIME: SimDuration = SimDuration::from_millis(170);

/// How long the firmware holds a PHY's reset pin low (RTL8211F.v: 491520
/// clocks, 10 ms).
const RESET_HOLD: SimDuration = SimDuration::from_millis(10);

/// BMCR after reset: auto-negotiation on, full duplex, 1000 Mb/s speed
/// bits (bit 6 set, bit 13 clear) as RTL8211F.v copies them to the GMII
/// core.
const BMCR_DEFAULT: u16 = 0x1140;
/// BMSR with the link up and auto-negotiation complete (the IEEE bits of a
/// 10/100/1000 PHY: extended status, 100/10 full and half, MF preamble
/// suppression, autoneg complete, autoneg ability, link, extended
/// capability).
const BMSR_LINK_UP: u16 = 0x796D;
/// BMSR without link: autoneg complete and link bits clear.
const BMSR_LINK_DOWN: u16 = 0x7949;
/// PHYSR bits: link (2), full duplex (3), speed 5:4.
const PHYSR_LINK: u16 = 1 << 2;
const PHYSR_DUPLEX: u16 = 1 << 3;
/// What an MDIO read of an absent PHY returns (the line's pull-up).
const MDIO_NOBODY: u16 = 0xFFFF;

/// One RTL8211F and its port.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Phy {
    /// Link on the wire (the cable and a partner).
    cable: bool,
    /// The PHY's reset pin is held low until this time.
    reset_held_until: SimTime,
    /// The port is back from its last reset at this time.
    ready_at: SimTime,
    page: u16,
    /// Written registers by (page, register).
    written: BTreeMap<(u16, u8), u16>,
    /// The MDIO window: the result of the last request.
    result: MdioResult,
}

impl Phy {
    fn new() -> Phy {
        Phy {
            cable: false,
            reset_held_until: SimTime::ZERO,
            ready_at: SimTime::ZERO,
            page: rtl8211f::PAGE_DEFAULT,
            written: BTreeMap::new(),
            result: MdioResult::default(),
        }
    }

    fn initialised(&self, now: SimTime) -> bool {
        now >= self.ready_at
    }

    fn link(&self, now: SimTime) -> bool {
        self.cable && self.initialised(now)
    }

    fn status(&self, now: SimTime) -> EthPortStatusV3 {
        let up = self.initialised(now);
        EthPortStatusV3::new(up, true, self.link(now), speed::MBPS_1000)
    }

    fn reset(&mut self, now: SimTime) {
        self.reset_held_until = now + RESET_HOLD;
        self.ready_at = now + PHY_RESET_TIME;
        self.page = rtl8211f::PAGE_DEFAULT;
        self.written.clear();
    }

    /// Register `register` of the RTL8211F on the current page.
    fn register(&self, now: SimTime, register: u8) -> u16 {
        let link = self.link(now);
        let stored = |r| self.written.get(&(self.page, r)).copied();
        match register {
            rtl8211f::BMCR => stored(register).unwrap_or(BMCR_DEFAULT),
            rtl8211f::BMSR => {
                if link {
                    BMSR_LINK_UP
                } else {
                    BMSR_LINK_DOWN
                }
            }
            rtl8211f::PHYID1 => rtl8211f::PHYID1_VALUE,
            rtl8211f::PHYID2 => rtl8211f::PHYID2_VALUE,
            rtl8211f::PAGSR => self.page,
            rtl8211f::PHYSR if self.page == rtl8211f::PAGE_STATUS => {
                if link {
                    PHYSR_LINK | PHYSR_DUPLEX | u16::from(speed::MBPS_1000) << 4
                } else {
                    0
                }
            }
            r => stored(r).unwrap_or(0),
        }
    }

    fn mdio(&mut self, now: SimTime, request: MdioRequest) {
        let phy = request.phy();
        let present = phy == PHY_ADDR_RTL8211F || phy == PHY_ADDR_BROADCAST;
        let register = request.register();
        if request.is_read() {
            let data = if present {
                self.register(now, register)
            } else {
                MDIO_NOBODY
            };
            self.result = MdioResult::default()
                .with_register(register)
                .with_data(data);
        } else if present {
            if register == rtl8211f::PAGSR {
                self.page = request.data();
            } else {
                self.written.insert((self.page, register), request.data());
            }
        }
    }
}

/// Register 12 and the MDIO windows of one V3 board.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct EthernetV3 {
    phys: [Phy; 2],
    ps_eth_enabled: bool,
}

impl EthernetV3 {
    /// A V3 powered long enough for both PHYs to be initialised.
    pub fn new() -> EthernetV3 {
        EthernetV3 {
            phys: [Phy::new(), Phy::new()],
            ps_eth_enabled: true,
        }
    }

    fn phy(&self, port: PhyPort) -> &Phy {
        let [eth1, eth2] = &self.phys;
        match port {
            PhyPort::Eth1 => eth1,
            PhyPort::Eth2 => eth2,
        }
    }

    fn phy_mut(&mut self, port: PhyPort) -> &mut Phy {
        let [eth1, eth2] = &mut self.phys;
        match port {
            PhyPort::Eth1 => eth1,
            PhyPort::Eth2 => eth2,
        }
    }

    /// Connect or disconnect the cable of Eth1 (the host's side).
    pub fn set_link(&mut self, up: bool) {
        self.phy_mut(PhyPort::Eth1).cable = up;
    }

    /// Register 12 as read at `now`; `rev9` for the PS Ethernet enable bit
    /// (0 before Rev 9).
    pub fn status(&self, now: SimTime, rev9: bool) -> EthStatusV3 {
        let mut s = EthStatusV3::default()
            .with_version(VERSION_V3)
            .with_clk125_ok(true)
            .with_clk200_ok(true)
            .with_udp_mode(true)
            .with_ps_eth_enabled(rev9 && self.ps_eth_enabled);
        for port in PhyPort::BOTH {
            s = s.with_port(port, self.phy(port).status(now));
        }
        s
    }

    /// A register-12 write (the Ethernet control word) at `now`.
    pub fn control(&mut self, now: SimTime, word: EthControlV3) {
        for port in PhyPort::BOTH {
            // A reset asked while one runs is ignored (RTL8211F.v: `&RSTn`
            // while the reset is held).
            let phy = self.phy_mut(port);
            if word.resets(port) && now >= phy.reset_held_until {
                phy.reset(now);
            }
        }
        if let Some(enable) = word.ps_eth_enable() {
            self.ps_eth_enabled = enable;
        }
    }

    /// A write to an MDIO window.
    pub fn mdio_write(&mut self, now: SimTime, port: PhyPort, word: u32) {
        self.phy_mut(port).mdio(now, MdioRequest(word));
    }

    /// An MDIO window as read.
    pub fn mdio_read(&self, port: PhyPort) -> u32 {
        self.phy(port).result.raw()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at_ms(ms: u64) -> SimTime {
        SimTime::ZERO + SimDuration::from_millis(ms)
    }

    /// The reference host's reads: `ReadRTL8211F_Register(chan, 1, 2/3)`
    /// see the IDs the firmware checks (`0x001C`, `0xC916`), the window
    /// reads idle (26:24 = 0) with the register in 20:16.
    #[test]
    fn phy_ids_through_the_mdio_window() {
        let mut e = EthernetV3::new();
        for port in PhyPort::BOTH {
            e.mdio_write(at_ms(1), port, MdioRequest::read(1, 2).raw());
            assert_eq!(e.mdio_read(port), 0x0002_001C);
            e.mdio_write(at_ms(1), port, MdioRequest::read(1, 3).raw());
            assert_eq!(e.mdio_read(port), 0x0003_C916);
            e.mdio_write(at_ms(1), port, MdioRequest::read(5, 3).raw());
            assert_eq!(e.mdio_read(port) & 0xFFFF, 0xFFFF, "no PHY at 5");
        }
        // Page select, then PHYSR on page 0xA43: link, full duplex, 1000.
        e.set_link(true);
        e.mdio_write(
            at_ms(2),
            PhyPort::Eth1,
            MdioRequest::write(1, 31, 0x0A43).raw(),
        );
        e.mdio_write(at_ms(2), PhyPort::Eth1, MdioRequest::read(1, 26).raw());
        assert_eq!(e.mdio_read(PhyPort::Eth1), 0x001A_002C);
        e.mdio_write(at_ms(2), PhyPort::Eth2, MdioRequest::read(1, 31).raw());
        assert_eq!(
            e.mdio_read(PhyPort::Eth2) & 0xFFFF,
            0x0A42,
            "Eth2's own page"
        );
    }

    /// Status bytes, the PS Ethernet bit by revision, and a PHY reset that
    /// takes the port down for 170 ms.
    #[test]
    fn status_and_phy_reset() {
        let mut e = EthernetV3::new();
        e.set_link(true);
        assert_eq!(e.status(at_ms(1), true).raw(), 0x40B1_D1F1);
        assert_eq!(
            e.status(at_ms(1), false).raw(),
            0x40B0_D1F1,
            "no PSETH_EN before Rev 9"
        );
        e.control(at_ms(10), EthControlV3::phy_reset(1));
        let down = e.status(at_ms(11), true);
        assert_eq!(down.port(PhyPort::Eth1), EthPortStatusV3(0x51));
        assert!(down.port(PhyPort::Eth2).init_ok(), "Eth2 untouched");
        assert_eq!(e.status(at_ms(180), true).port1(), 0xF1, "back");
        e.control(at_ms(200), EthControlV3(0x0200_0000));
        assert!(!e.status(at_ms(200), true).ps_eth_enabled());
        e.control(at_ms(200), EthControlV3(0x0201_0000));
        assert!(e.status(at_ms(200), true).ps_eth_enabled());
        // Clear errors: nothing reads differently.
        let before = e.status(at_ms(201), true);
        e.control(at_ms(201), EthControlV3(0x6000_0000));
        assert_eq!(e.status(at_ms(201), true), before);
    }
}
