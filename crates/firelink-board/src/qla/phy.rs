//! Access to the board's own PHY registers, which the firmware reaches
//! through PHY_CTRL / PHY_DATA (`fpga-board.md` section 2).
//!
//! On the simulated bus the PHY belongs to the bus model, so the firmware
//! takes a [`PhyAccess`] with each packet. Without a bus, the bus's own
//! register file serves: [`PhyRegisters`] (one definition, in
//! `firelink-bus`), whose read-only registers ignore writes as a PHY's do.

pub use firelink_bus::phy::PhyRegisters;

/// Read and write the local PHY's registers (0..=15).
pub trait PhyAccess {
    /// The value of PHY register `register`.
    fn read_phy_register(&mut self, register: u8) -> u8;
    /// Write PHY register `register`.
    fn write_phy_register(&mut self, register: u8, value: u8);
}

impl PhyAccess for PhyRegisters {
    fn read_phy_register(&mut self, register: u8) -> u8 {
        self.read(register)
    }

    fn write_phy_register(&mut self, register: u8, value: u8) {
        self.write(register, value);
    }
}
