//! Access to the board's own PHY registers, which the firmware reaches
//! through PHY_CTRL / PHY_DATA (`fpga-board.md` section 2).
//!
//! On the simulated bus the PHY belongs to the bus model, so the firmware
//! takes a [`PhyAccess`] with each packet; [`PhyRegisters`] is a plain
//! register file for use without a bus.

/// Read and write the local PHY's registers (0..=15).
pub trait PhyAccess {
    /// The value of PHY register `register`.
    fn read_phy_register(&mut self, register: u8) -> u8;
    /// Write PHY register `register`.
    fn write_phy_register(&mut self, register: u8, value: u8);
}

/// A stand-alone 1394a PHY register file as the FPGA1394's PHY has it:
/// register 0 holds the physical ID in bits 7:2, register 1 the gap count
/// in bits 5:0 (power-up 63), register 2 `0xE2` (extended map, 2 ports),
/// register 3 `0x40` (S400, repeater delay 0).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PhyRegisters {
    /// The sixteen registers.
    pub registers: [u8; 16],
}

impl PhyRegisters {
    /// A PHY with physical ID `phy_id` and the power-up gap count 63.
    pub fn new(phy_id: u8) -> PhyRegisters {
        let mut registers = [0u8; 16];
        registers[0] = (phy_id & 0x3F) << 2;
        registers[1] = 0x3F;
        registers[2] = 0xE2;
        registers[3] = 0x40;
        PhyRegisters { registers }
    }

    /// The gap count (register 1, bits 5:0).
    pub fn gap_count(&self) -> u8 {
        self.registers[1] & 0x3F
    }
}

impl Default for PhyRegisters {
    fn default() -> Self {
        PhyRegisters::new(0)
    }
}

impl PhyAccess for PhyRegisters {
    fn read_phy_register(&mut self, register: u8) -> u8 {
        self.registers
            .get(usize::from(register))
            .copied()
            .unwrap_or(0)
    }

    fn write_phy_register(&mut self, register: u8, value: u8) {
        if let Some(r) = self.registers.get_mut(usize::from(register)) {
            *r = value;
        }
    }
}
