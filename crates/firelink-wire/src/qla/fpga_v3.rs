//! Codecs of the FPGA V3 board's Ethernet side (firmware Rev 8/9): the
//! ETH_STATUS word of register 12 as a V3 reads it, the Ethernet control
//! word written there, and the MDIO window at `0x4nA0` through which the
//! host reaches the two RTL8211F PHYs (`rev9-fpga-v3.md`, "Rev 9 changes").
//!
//! Facts, read in jhu-cisst/mechatronics-firmware (`FPGA1394V3.v`: the
//! `Eth_Result` word; `RTL8211F.v`: the per-port status byte, the control
//! bits each port takes, the MDIO request and result words, the PHY ID
//! checks) and jhu-cisst/mechatronics-software (`FpgaIO.h`: `EthStatus`,
//! `EthPortV3Status`, `EthControl`, `EthPortV3Control`, `RTL8211F_Regs`,
//! `PHY_ADDR`; `FpgaIO.cpp`: `ReadRTL8211F_Register`,
//! `WriteRTL8211F_Register`, `WriteEthernetPhyReset`,
//! `WriteEthernetClearErrors`). Raw bits only.
//!
//! ```
//! use firelink_wire::qla::fpga_v3::{EthStatusV3, MdioRequest, PhyPort, mdio_offset};
//! // A Rev 9 V3 with both links up at 1 Gb/s and the PS Ethernet enabled.
//! let s = EthStatusV3(0x40B1_B1B1);
//! assert!(s.is_v3() && s.ps_eth_enabled());
//! assert_eq!(s.port(PhyPort::Eth2).speed(), 2);
//! // FpgaIO::ReadRTL8211F_Register(1, 1, 2): PHY 1, register 2 (PHYID1).
//! assert_eq!(mdio_offset(PhyPort::Eth1), 0x41A0);
//! assert_eq!(MdioRequest::read(1, 2).raw(), 0x6088_0000);
//! ```

use crate::qla::quadlet_register;

/// Bit fields, each defined once.
mod field {
    use crate::field::Field;

    // ETH_STATUS of a V3 (FPGA1394V3.v Eth_Result; FpgaIO.h EthStatus).
    pub const VERSION: Field = Field::new(0, 31, 30);
    pub const HOST_PORT: Field = Field::new(0, 29, 29);
    pub const FRAME_ERR: Field = Field::new(0, 28, 28);
    pub const IPV4_ERR: Field = Field::new(0, 27, 27);
    pub const UDP_ERR: Field = Field::new(0, 26, 26);
    pub const DEST_ERR: Field = Field::new(0, 25, 25);
    pub const ACCESS_ERR: Field = Field::new(0, 24, 24);
    pub const CLK125_OK: Field = Field::new(0, 23, 23);
    pub const ETHST_ERR: Field = Field::new(0, 22, 22);
    pub const CLK200_OK: Field = Field::new(0, 21, 21);
    pub const UDP_MODE: Field = Field::new(0, 20, 20);
    pub const PSETH_EN: Field = Field::new(0, 16, 16);
    pub const PORT2: Field = Field::new(0, 15, 8);
    pub const PORT1: Field = Field::new(0, 7, 0);

    // Ethernet control, register 12 written (FpgaIO.h EthControl).
    pub const CTRL_CLEAR_SWITCH: Field = Field::new(0, 30, 30);
    pub const CTRL_CLEAR_NET: Field = Field::new(0, 29, 29);
    pub const CTRL_IRQ_GEN: Field = Field::new(0, 28, 28);
    pub const CTRL_IRQ_DISABLE: Field = Field::new(0, 27, 27);
    pub const CTRL_RESET_PHY: Field = Field::new(0, 26, 26);
    pub const CTRL_PS_ETH_MASK: Field = Field::new(0, 25, 25);
    pub const CTRL_PS_ETH: Field = Field::new(0, 16, 16);
    pub const CTRL_PORT2: Field = Field::new(0, 15, 8);
    pub const CTRL_PORT1: Field = Field::new(0, 7, 0);

    // MDIO request (FpgaIO.cpp: 01 OP PPPPP RRRRR TA DATA) and result
    // (RTL8211F.v mdio_result: state 26:24, register 20:16, data 15:0).
    pub const MDIO_START: Field = Field::new(0, 31, 30);
    pub const MDIO_OP: Field = Field::new(0, 29, 28);
    pub const MDIO_PHY: Field = Field::new(0, 27, 23);
    pub const MDIO_REG: Field = Field::new(0, 22, 18);
    pub const MDIO_TA: Field = Field::new(0, 17, 16);
    pub const MDIO_DATA: Field = Field::new(0, 15, 0);
    pub const MDIO_STATE: Field = Field::new(0, 26, 24);
    pub const MDIO_RESULT_REG: Field = Field::new(0, 20, 16);
}

/// One of the two Ethernet ports of an FPGA V3 (each with its RTL8211F).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PhyPort {
    /// Eth1: status and control byte 7:0, MDIO at `0x41A0`.
    Eth1,
    /// Eth2: status and control byte 15:8, MDIO at `0x42A0`.
    Eth2,
}

impl PhyPort {
    /// Both ports, Eth1 first.
    pub const BOTH: [PhyPort; 2] = [PhyPort::Eth1, PhyPort::Eth2];

    /// The port's number as the host names it (1 or 2).
    pub fn number(self) -> u8 {
        match self {
            PhyPort::Eth1 => 1,
            PhyPort::Eth2 => 2,
        }
    }

    /// 0 for Eth1, 1 for Eth2.
    pub fn index(self) -> usize {
        usize::from(self.number() - 1)
    }
}

/// The MDIO window of a port's RTL8211F: `0x40A0 | n << 8` in the Ethernet
/// space (FpgaIO.cpp; FPGA1394V3.v takes writes at `4nA0`).
pub fn mdio_offset(port: PhyPort) -> u16 {
    0x40A0 | u16::from(port.number()) << 8
}

/// Which port an Ethernet-space index (bits 11:0 of the address) reaches
/// through its MDIO window, if it is one (`nA0`, n = 1 or 2).
pub fn mdio_port_of(index: u16) -> Option<PhyPort> {
    match index & 0xFFF {
        0x1A0 => Some(PhyPort::Eth1),
        0x2A0 => Some(PhyPort::Eth2),
        _ => None,
    }
}

/// ETH_STATUS version bits of a V3 (bits 31:30 = 01).
pub const VERSION_V3: u8 = 0b01;

/// The RTL8211F's PHY address on an FPGA V3 (FpgaIO.h `PHY_RTL8211F`,
/// strapped by RxD during reset, FPGA1394V3.v).
pub const PHY_ADDR_RTL8211F: u8 = 1;
/// The MDIO broadcast PHY address (FpgaIO.h `PHY_BROADCAST`).
pub const PHY_ADDR_BROADCAST: u8 = 0;
/// The GMII-to-RGMII core's PHY address (FpgaIO.h `PHY_GMII_CORE`).
pub const PHY_ADDR_GMII_CORE: u8 = 8;

/// RTL8211F registers the host and the firmware use (FpgaIO.h
/// `RTL8211F_Regs`, RTL8211F.v).
pub mod rtl8211f {
    /// Basic mode control (page 0).
    pub const BMCR: u8 = 0;
    /// Basic mode status (page 0).
    pub const BMSR: u8 = 1;
    /// PHY identifier 1 (page 0).
    pub const PHYID1: u8 = 2;
    /// PHY identifier 2 (page 0).
    pub const PHYID2: u8 = 3;
    /// Interrupt enable (page 0xA42).
    pub const INER: u8 = 18;
    /// PHY-specific status (page 0xA43): bit 2 link, bits 5:4 speed.
    pub const PHYSR: u8 = 26;
    /// Interrupt status (page 0xA43), cleared by reading.
    pub const INSR: u8 = 29;
    /// Page select (every page).
    pub const PAGSR: u8 = 31;
    /// What PHYID1 reads: the firmware checks it at initialisation
    /// (RTL8211F.v `ST_INIT_CHECK_CHIPID1`).
    pub const PHYID1_VALUE: u16 = 0x001C;
    /// What PHYID2 reads (RTL8211F.v `ST_INIT_CHECK_CHIPID2`).
    pub const PHYID2_VALUE: u16 = 0xC916;
    /// The page selected after reset and after the firmware's programs
    /// (FpgaIO.h `RTL8211F_PAGE_DEFAULT`).
    pub const PAGE_DEFAULT: u16 = 0x0A42;
    /// The page of PHYSR and INSR.
    pub const PAGE_STATUS: u16 = 0x0A43;
}

quadlet_register! {
    /// ETH_STATUS (register 12) as an FPGA V3 reads it: bits 31:30 = 01,
    /// the EthernetIO error bits, clock checks, the UDP mode, the PS
    /// Ethernet enable (Rev 9+) and one status byte per port.
    pub struct EthStatusV3 {
        /// FPGA version bits, 31:30 (`01` on a V3).
        version, set_version, with_version: u8 = field::VERSION;
        /// The port the host was last heard on (0 = Eth1), bit 29
        /// (FPGA1394V3.v `eth_port`).
        host_port, set_host_port, with_host_port: bool = field::HOST_PORT;
        /// Unsupported Ethernet frame, bit 28.
        frame_error, set_frame_error, with_frame_error: bool = field::FRAME_ERR;
        /// IPv4 header error, bit 27.
        ipv4_error, set_ipv4_error, with_ipv4_error: bool = field::IPV4_ERR;
        /// Unsupported UDP port, bit 26.
        udp_error, set_udp_error, with_udp_error: bool = field::UDP_ERR;
        /// Wrong FireWire destination, bit 25.
        dest_error, set_dest_error, with_dest_error: bool = field::DEST_ERR;
        /// Internal bus access error, bit 24 (reads 0 from Rev 9 on).
        access_error, set_access_error, with_access_error: bool = field::ACCESS_ERR;
        /// The 125 MHz clock runs, bit 23.
        clk125_ok, set_clk125_ok, with_clk125_ok: bool = field::CLK125_OK;
        /// EthernetIO state machine error, bit 22.
        state_error, set_state_error, with_state_error: bool = field::ETHST_ERR;
        /// The 200 MHz clock (from the PS) runs, bit 21.
        clk200_ok, set_clk200_ok, with_clk200_ok: bool = field::CLK200_OK;
        /// UDP mode (0 = raw Ethernet), bit 20.
        udp_mode, set_udp_mode, with_udp_mode: bool = field::UDP_MODE;
        /// The Zynq PS may use the Ethernet ports, bit 16 (Rev 9+; 0
        /// before).
        ps_eth_enabled, set_ps_eth_enabled, with_ps_eth_enabled: bool = field::PSETH_EN;
        /// Eth2's status byte, bits 15:8.
        port2, set_port2, with_port2: u8 = field::PORT2;
        /// Eth1's status byte, bits 7:0.
        port1, set_port1, with_port1: u8 = field::PORT1;
    }
}

impl EthStatusV3 {
    /// Whether the version bits say FPGA V3.
    pub fn is_v3(self) -> bool {
        self.version() == VERSION_V3
    }

    /// The status byte of `port`.
    pub fn port(self, port: PhyPort) -> EthPortStatusV3 {
        EthPortStatusV3(match port {
            PhyPort::Eth1 => self.port1(),
            PhyPort::Eth2 => self.port2(),
        })
    }

    /// The same word with `port`'s status byte set.
    pub fn with_port(self, port: PhyPort, status: EthPortStatusV3) -> EthStatusV3 {
        match port {
            PhyPort::Eth1 => self.with_port1(status.0),
            PhyPort::Eth2 => self.with_port2(status.0),
        }
    }
}

/// Link speed codes of a port status byte (RTL8211F.v `linkSpeed`).
pub mod speed {
    /// 10 Mb/s.
    pub const MBPS_10: u8 = 0;
    /// 100 Mb/s.
    pub const MBPS_100: u8 = 1;
    /// 1000 Mb/s.
    pub const MBPS_1000: u8 = 2;
}

/// One port's status byte in a V3 ETH_STATUS (RTL8211F.v `eth_status`;
/// FpgaIO.h `EthPortV3Status`): 7 initialised OK (the PHY IDs checked),
/// 6 the PHY's IRQ line is wired (FPGA V3.1+), 5 link up, 4:3 speed, 2:0
/// the firmware's low bits (Rev 8: receive error, send overflow, PS
/// Ethernet; the Rev 9-era RTL8211F.v drives `001`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct EthPortStatusV3(pub u8);

impl EthPortStatusV3 {
    const INIT_OK: u8 = 0x80;
    const HAS_IRQ: u8 = 0x40;
    const LINK: u8 = 0x20;
    const SPEED_SHIFT: u8 = 3;
    const SPEED_MASK: u8 = 0x18;
    /// The low bits the firmware drives after the speed (RTL8211F.v).
    pub const LOW_BITS: u8 = 0x01;

    /// A status byte from its parts (the low bits as the firmware drives
    /// them).
    pub fn new(init_ok: bool, has_irq: bool, link: bool, speed: u8) -> EthPortStatusV3 {
        let mut b = Self::LOW_BITS | ((speed << Self::SPEED_SHIFT) & Self::SPEED_MASK);
        if init_ok {
            b |= Self::INIT_OK;
        }
        if has_irq {
            b |= Self::HAS_IRQ;
        }
        if link {
            b |= Self::LINK;
        }
        EthPortStatusV3(b)
    }

    /// Initialised OK (both PHY IDs read as expected).
    pub fn init_ok(self) -> bool {
        self.0 & Self::INIT_OK != 0
    }

    /// The PHY's interrupt line is connected (FPGA V3.1+).
    pub fn has_irq(self) -> bool {
        self.0 & Self::HAS_IRQ != 0
    }

    /// Link up.
    pub fn link(self) -> bool {
        self.0 & Self::LINK != 0
    }

    /// Speed code ([`speed`]).
    pub fn speed(self) -> u8 {
        (self.0 & Self::SPEED_MASK) >> Self::SPEED_SHIFT
    }
}

quadlet_register! {
    /// The Ethernet control word an FPGA V3 takes at register 12 (FpgaIO.h
    /// `EthControl`, `EthPortV3Control`; RTL8211F.v). Per-port actions
    /// need both the global mask bit and the port's bit.
    pub struct EthControlV3 {
        /// Clear the switch errors, bit 30 (Rev 9 host: with bit 29).
        clear_switch_errors, set_clear_switch_errors, with_clear_switch_errors: bool =
            field::CTRL_CLEAR_SWITCH;
        /// Clear the network-layer (EthernetIO) errors, bit 29.
        clear_net_errors, set_clear_net_errors, with_clear_net_errors: bool =
            field::CTRL_CLEAR_NET;
        /// Mask for the ports' software IRQ and clear-error bits, bit 28.
        irq_gen, set_irq_gen, with_irq_gen: bool = field::CTRL_IRQ_GEN;
        /// Mask for the ports' IRQ-disable bits, bit 27.
        irq_disable, set_irq_disable, with_irq_disable: bool = field::CTRL_IRQ_DISABLE;
        /// Mask for the ports' PHY-reset bits, bit 26.
        reset_phy, set_reset_phy, with_reset_phy: bool = field::CTRL_RESET_PHY;
        /// Mask for bit 16 (write the PS Ethernet enable), bit 25.
        ps_eth_mask, set_ps_eth_mask, with_ps_eth_mask: bool = field::CTRL_PS_ETH_MASK;
        /// The PS Ethernet enable, bit 16 (taken with bit 25).
        ps_eth, set_ps_eth, with_ps_eth: bool = field::CTRL_PS_ETH;
        /// Eth2's control byte, bits 15:8.
        port2, set_port2, with_port2: u8 = field::CTRL_PORT2;
        /// Eth1's control byte, bits 7:0.
        port1, set_port1, with_port1: u8 = field::CTRL_PORT1;
    }
}

/// A port control byte's PHY-reset bit (`0x80`; `0x8000` for Eth2 in the
/// whole word).
pub const PORT_CTRL_RESET_PHY: u8 = 0x80;

impl EthControlV3 {
    /// `WriteEthernetPhyReset(chan)` of the reference host: the reset mask
    /// and port 1 (`chan & 1`) and/or port 2 (`chan & 2`).
    pub fn phy_reset(chan: u8) -> EthControlV3 {
        let mut w = EthControlV3::default().with_reset_phy(true);
        if chan & 1 != 0 {
            w = w.with_port1(PORT_CTRL_RESET_PHY);
        }
        if chan & 2 != 0 {
            w = w.with_port2(PORT_CTRL_RESET_PHY);
        }
        w
    }

    /// Whether the word resets `port`'s PHY (mask bit 26 and the port's
    /// bit 7).
    pub fn resets(self, port: PhyPort) -> bool {
        let byte = match port {
            PhyPort::Eth1 => self.port1(),
            PhyPort::Eth2 => self.port2(),
        };
        self.reset_phy() && byte & PORT_CTRL_RESET_PHY != 0
    }

    /// The PS Ethernet enable the word sets, if it sets one (bit 25 the
    /// mask, bit 16 the value).
    pub fn ps_eth_enable(self) -> Option<bool> {
        self.ps_eth_mask().then_some(self.ps_eth())
    }
}

/// MDIO operation codes (IEEE 802.3 clause 22; RTL8211F.v `isRead`).
const OP_WRITE: u8 = 0b01;
const OP_READ: u8 = 0b10;

quadlet_register! {
    /// A word written to a port's MDIO window (`0x4nA0`): a clause-22 frame
    /// after the preamble (FpgaIO.cpp: `0110 PPPP PRRR RRXX ...` to read,
    /// `0101 PPPP PRRR RR10 DATA` to write).
    pub struct MdioRequest {
        /// Start bits, 31:30 (`01`).
        start, set_start, with_start: u8 = field::MDIO_START;
        /// Operation, 29:28: `10` read, `01` write.
        op, set_op, with_op: u8 = field::MDIO_OP;
        /// PHY address, 27:23.
        phy, set_phy, with_phy: u8 = field::MDIO_PHY;
        /// Register, 22:18.
        register, set_register, with_register: u8 = field::MDIO_REG;
        /// Turnaround, 17:16 (`10` on a write).
        turnaround, set_turnaround, with_turnaround: u8 = field::MDIO_TA;
        /// Data to write, 15:0.
        data, set_data, with_data: u16 = field::MDIO_DATA;
    }
}

impl MdioRequest {
    /// The reference host's read of `register` of PHY `phy`.
    pub fn read(phy: u8, register: u8) -> MdioRequest {
        MdioRequest::default()
            .with_start(0b01)
            .with_op(OP_READ)
            .with_phy(phy)
            .with_register(register)
    }

    /// The reference host's write of `data` to `register` of PHY `phy`.
    pub fn write(phy: u8, register: u8, data: u16) -> MdioRequest {
        MdioRequest::default()
            .with_start(0b01)
            .with_op(OP_WRITE)
            .with_phy(phy)
            .with_register(register)
            .with_turnaround(0b10)
            .with_data(data)
    }

    /// Whether the frame reads (`op` = 10; anything else writes, as the
    /// firmware's state machine treats it).
    pub fn is_read(self) -> bool {
        self.op() == OP_READ
    }
}

quadlet_register! {
    /// What a port's MDIO window reads (RTL8211F.v `mdio_result`): the MDIO
    /// state (0 = idle), the register of the last read and its data.
    pub struct MdioResult {
        /// MDIO state, 26:24 (0 idle; the host waits for 0).
        state, set_state, with_state: u8 = field::MDIO_STATE;
        /// Register of the last read, 20:16 (the host compares it).
        register, set_register, with_register: u8 = field::MDIO_RESULT_REG;
        /// The data read, 15:0.
        data, set_data, with_data: u16 = field::MDIO_DATA;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FpgaIO.cpp's words: read `0x60000000 | phy<<23 | reg<<18`, write
    /// `0x50020000 | phy<<23 | reg<<18 | data`; FpgaIO.h's masks.
    #[test]
    fn host_words_as_the_reference_library_builds_them() {
        assert_eq!(
            MdioRequest::read(1, 3).raw(),
            0x6000_0000 | 1 << 23 | 3 << 18
        );
        let w = MdioRequest::write(1, 31, 0x0A43);
        assert_eq!(w.raw(), 0x5002_0000 | 1 << 23 | 31 << 18 | 0x0A43);
        assert!(!w.is_read() && MdioRequest::read(8, 16).is_read());
        assert_eq!(MdioRequest(0x6088_0000).register(), 2);
        assert_eq!(mdio_offset(PhyPort::Eth2), 0x42A0);
        assert_eq!(mdio_port_of(0x1A0), Some(PhyPort::Eth1));
        assert_eq!(mdio_port_of(0x2A0), Some(PhyPort::Eth2));
        assert_eq!(mdio_port_of(0x3A0), None);
        // WriteEthernetPhyReset(3): ETH_CTRL_RESET_PHY | 0x80 | 0x8000.
        assert_eq!(EthControlV3::phy_reset(3).raw(), 0x0400_8080);
        assert_eq!(EthControlV3::phy_reset(1).raw(), 0x0400_0080);
        assert!(EthControlV3::phy_reset(2).resets(PhyPort::Eth2));
        assert!(!EthControlV3::phy_reset(2).resets(PhyPort::Eth1));
        assert!(!EthControlV3(0x0000_8080).resets(PhyPort::Eth1), "no mask");
        // WriteEthernetClearErrors on a V3 at Rev 9: CLR_ERR_NET | CLR_ERR_SW.
        let c = EthControlV3(0x6000_0000);
        assert!(c.clear_net_errors() && c.clear_switch_errors());
        assert_eq!(EthControlV3(0x0201_0000).ps_eth_enable(), Some(true));
        assert_eq!(EthControlV3(0x0200_0000).ps_eth_enable(), Some(false));
        assert_eq!(EthControlV3(0x0001_0000).ps_eth_enable(), None);
    }

    /// FpgaIO.h EthStatus: 0x01000000 access error, 0x00800000 clk125,
    /// 0x00200000 clk200, 0x00100000 UDP, 0x00010000 PSETH_EN, port masks
    /// 0xff00 / 0xff; EthPortV3Status 0x80 init, 0x40 IRQ, 0x20 link, 0x18
    /// speed.
    #[test]
    fn status_bits_where_the_host_looks() {
        let p = EthPortStatusV3::new(true, true, true, speed::MBPS_1000);
        assert_eq!(p.0, 0xF1);
        assert!(p.init_ok() && p.has_irq() && p.link() && p.speed() == 2);
        let s = EthStatusV3::default()
            .with_version(VERSION_V3)
            .with_clk125_ok(true)
            .with_clk200_ok(true)
            .with_udp_mode(true)
            .with_ps_eth_enabled(true)
            .with_port(PhyPort::Eth1, p)
            .with_port(PhyPort::Eth2, EthPortStatusV3::new(true, true, false, 0));
        assert_eq!(s.raw(), 0x40B1_C1F1);
        assert!(s.is_v3() && !s.access_error());
        assert_eq!(s.port(PhyPort::Eth1), p);
        assert!(!s.port(PhyPort::Eth2).link());
        assert_eq!(EthStatusV3(0x0100_0000).raw() & 0x0100_0000, 0x0100_0000);
        assert!(EthStatusV3(0x0100_0000).access_error());
    }
}
