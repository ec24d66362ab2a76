//! The Ethernet side of an FPGA V2 (`fpga-board-extras.md` §6): register
//! 12 (status, and access to the KSZ8851 MAC/PHY's registers) and the
//! debug window of space 4.
//!
//! The KSZ8851 holds the values the reference host checks after its
//! initialisation (MAC `FA:61:0E:13:94:0n`, receive and interrupt setup);
//! other registers read 0 until written. Only the board whose Ethernet
//! port is connected (the bridge board) has a link; the others read "link
//! down" and an idle port status. The window's first 128 quadlets hold the
//! last FireWire packet received over Ethernet; a Rev 8 V2 is built
//! without debug data, so `0x80-0x9F` read `"DBG0"`. The KSZ programme,
//! the last frame's first 64 bytes and the reply header/index areas are
//! not modelled (they read 0).

use std::collections::BTreeMap;

use firelink_wire::qla::extras::{ETH_DEBUG_ABSENT, EthControl, EthStatusV2, ksz8851};

/// Quadlets of the last-packet area of the window (`0x00-0x7F`).
pub const PACKET_QUADLETS: usize = 0x80;

/// Register 12 and the window of one V2 board.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Ethernet {
    board_id: u8,
    link: bool,
    /// KSZ8851 16-bit registers by (even) address.
    ksz: BTreeMap<u8, u16>,
    last_read: u16,
    last_packet: Vec<u32>,
}

impl Ethernet {
    /// The KSZ8851 after the firmware's initialisation, for board `board_id`.
    pub fn new(board_id: u8) -> Ethernet {
        let mut e = Ethernet {
            board_id,
            link: false,
            ksz: BTreeMap::new(),
            last_read: 0,
            last_packet: Vec::new(),
        };
        e.initialise();
        e
    }

    fn initialise(&mut self) {
        use ksz8851::*;
        self.ksz = [
            (CIDER, 0x8872),
            (MARL, 0x9400 | u16::from(self.board_id & 0xF)),
            (MARM, 0x0E13),
            (MARH, 0xFA61),
            (RXCR1, 0x7DEF),
            (RXCR2, 0x7CE1),
            (RXQCR, 0x0020),
            (TXFDPR, 0x4000),
            (RXFDPR, 0x4000),
            (IER, 0xA000),
            (RXFCTR, 0x0001),
            (MAHTR1, 0x0008),
        ]
        .into_iter()
        .collect();
        self.last_read = 0;
    }

    /// Connect or disconnect the Ethernet port.
    pub fn set_link(&mut self, up: bool) {
        self.link = up;
    }

    /// Whether the Ethernet port is connected.
    pub fn link(&self) -> bool {
        self.link
    }

    /// A FireWire packet (header and data, wire order) arrived over
    /// Ethernet: it fills the window's first 128 quadlets.
    pub fn received(&mut self, packet: &[u8]) {
        let mut bytes = packet.to_vec();
        bytes.resize(packet.len().div_ceil(4) * 4, 0);
        self.last_packet = firelink_wire::field::quadlets(&bytes).collect();
        self.last_packet.truncate(PACKET_QUADLETS);
    }

    fn ksz_register(&self, register: u8) -> u16 {
        if register & !1 == ksz8851::P1SR {
            return if self.link {
                ksz8851::P1SR_LINK_GOOD
                    | ksz8851::P1SR_AUTONEG_DONE
                    | ksz8851::P1SR_FULL_DUPLEX
                    | ksz8851::P1SR_100MBPS
            } else {
                0
            };
        }
        self.ksz.get(&(register & !1)).copied().unwrap_or(0)
    }

    /// Register 12 as read.
    pub fn status(&self) -> EthStatusV2 {
        EthStatusV2::default()
            .with_present(true)
            .with_ksz_init_ok(true)
            .with_udp_mode(true)
            .with_link_up(self.link)
            .with_ksz_idle(true)
            .with_data(self.last_read)
    }

    /// A register-12 write.
    pub fn write(&mut self, c: EthControl) {
        if c.reset_ksz() {
            self.initialise();
            return;
        }
        if !c.is_access() {
            return;
        }
        let register = c.register();
        let word = self.ksz_register(register);
        let high_byte = register & 1 != 0;
        if c.write() {
            let value = if c.word() {
                c.data()
            } else if high_byte {
                (word & 0x00FF) | (c.data() & 0xFF) << 8
            } else {
                (word & 0xFF00) | (c.data() & 0xFF)
            };
            self.ksz.insert(register & !1, value);
        } else {
            self.last_read = if c.word() {
                word
            } else if high_byte {
                word >> 8
            } else {
                word & 0xFF
            };
        }
    }

    /// Space 4 quadlet at `index` (bits 7:0 of the address).
    pub fn window(&self, index: u16) -> u32 {
        match usize::from(index & 0xFF) {
            i @ 0x00..=0x7F => self.last_packet.get(i).copied().unwrap_or(0),
            0x80..=0x9F => ETH_DEBUG_ABSENT,
            _ => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ksz8851::*;

    fn read(e: &mut Ethernet, register: u8) -> u16 {
        e.write(EthControl::read_word(register));
        let s = e.status();
        assert!(s.present() && !s.ksz_request_error());
        s.data()
    }

    #[test]
    fn the_values_fpgatest_checks() {
        let mut e = Ethernet::new(5);
        e.set_link(true);
        assert_eq!(read(&mut e, CIDER) & 0xFFF0, 0x8870);
        assert_eq!(read(&mut e, MARL), 0x9405);
        assert_eq!(read(&mut e, MARM), 0x0E13);
        assert_eq!(read(&mut e, MARH), 0xFA61);
        assert_ne!(read(&mut e, TXFDPR) & 0x4000, 0);
        assert_eq!(read(&mut e, RXCR1) & 0x1FF, 0x1EF);
        assert_ne!(read(&mut e, RXFDPR) & 0x4000, 0);
        assert_eq!(read(&mut e, RXFCTR) & 0xFF, 1);
        assert_eq!(read(&mut e, RXCR2), 0x7CE1);
        assert_eq!(read(&mut e, MAHTR1), 0x0008);
        assert_eq!(read(&mut e, RXQCR) & 0x3F7, 0x020);
        assert_eq!(read(&mut e, IER), 0xA000);
        assert_eq!(read(&mut e, P1SR) & 0x2660, 0x0660);
        assert_eq!(e.status().raw() & 0xFFFF_0000, 0xA01C_0000);
        // A byte read of the high byte; a write then read back.
        e.write(EthControl::default().with_register(MARH + 1));
        assert_eq!(e.status().data(), 0xFA);
        e.write(
            EthControl::read_word(0x20)
                .with_write(true)
                .with_data(0x1234),
        );
        assert_eq!(read(&mut e, 0x20), 0x1234);
        // No link: status and P1SR say so.
        let mut off = Ethernet::new(1);
        assert!(!off.status().link_up());
        assert_eq!(read(&mut off, P1SR), 0);
        // The window: last packet, then DBG0.
        e.received(&[1, 2, 3, 4, 5, 6]);
        assert_eq!(e.window(0), 0x0102_0304);
        assert_eq!(e.window(1), 0x0506_0000);
        assert_eq!(e.window(2), 0);
        assert_eq!(e.window(0x85), 0x3047_4244);
        assert_eq!(e.window(0xC0), 0);
    }
}
