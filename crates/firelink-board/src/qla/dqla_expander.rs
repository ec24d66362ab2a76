//! The DQLA's two MAX7301 I/O expanders (one per QLA, register-14 IDs 3
//! and 4), which carry each QLA's power enable, amplifier disables,
//! switches, index lines, amplifier fault lines and supply-good line
//! (`firelink_wire::qla::dqla` cites the sources: DQLA.v, Max7301x2.v,
//! fpgatest's `DQLA_IOExp_Check`).
//!
//! What the model keeps: each chip's configuration registers (`0x04`,
//! `0x09-0x0F`) as the firmware programmed them at power-up (the board
//! has been on: both chips found and configured) and as the host writes
//! them; its port output registers; the register-14 read-out with the
//! answer to the host's last read command (`0x80 | register`, data), the
//! error flags (never set: the model's ports always read back as
//! commanded) and the debug read-out (the output error count, 0).
//! A port read returns the board's lines as the firmware maps them
//! (DQLA.v): 27 supply good, 26:23 home, 22:19 negative limits, 18:17
//! positive limits 1-2, 16 power enable, 15:12 amplifier disables, 11:8
//! the amplifier lines (1 = amplifier on), 7:4 index; 31:28 the LEDs as
//! last written. The SPI bus is never busy.

use firelink_wire::qla::dqla::{MAX7301_CONFIG, MAX7301_READ_MARKER, Max7301Read};
use firelink_wire::qla::extras::ExpanderWrite;

/// Registers of a MAX7301 (0x00-0x5F).
const REGISTERS: usize = 0x60;
/// First single-port register (port n at `0x20 + n`, n = 4..=31).
const PORT_SINGLE: u8 = 0x20;
/// First eight-port register (ports n..n+7 at `0x40 + n`).
const PORT_RANGE: u8 = 0x40;

/// The board lines one QLA's MAX7301 sees, as port bits (bit n = port n).
pub(crate) type PortLines = u32;

/// One MAX7301.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Max7301 {
    /// Configuration and other non-port registers.
    registers: [u8; REGISTERS],
    /// Port output latches (bit n = port n).
    outputs: u32,
    debug: bool,
    answer: u16,
}

impl Max7301 {
    fn new() -> Max7301 {
        let mut registers = [0u8; REGISTERS];
        for command in MAX7301_CONFIG {
            let [register, data] = command.to_be_bytes();
            if let Some(r) = registers.get_mut(usize::from(register)) {
                *r = data;
            }
        }
        Max7301 {
            registers,
            outputs: 0,
            debug: false,
            answer: 0,
        }
    }

    /// What the chip returns for a read of `register`, the ports
    /// reading `lines` (outputs as latched in bits 31:28).
    fn read(&self, register: u8, lines: PortLines) -> u8 {
        let ports = (lines & 0x0FFF_FFFF) | (self.outputs & 0xF000_0000);
        match register {
            r if (PORT_SINGLE + 4..PORT_SINGLE + 32).contains(&r) => {
                ((ports >> (r - PORT_SINGLE)) & 1) as u8
            }
            r if (PORT_RANGE + 4..PORT_RANGE + 32).contains(&r) => {
                (ports >> (r - PORT_RANGE)) as u8
            }
            r => self.registers.get(usize::from(r)).copied().unwrap_or(0),
        }
    }

    fn write(&mut self, register: u8, data: u8) {
        match register {
            r if (PORT_SINGLE + 4..PORT_SINGLE + 32).contains(&r) => {
                let bit = 1u32 << (r - PORT_SINGLE);
                self.outputs = (self.outputs & !bit) | if data & 1 != 0 { bit } else { 0 };
            }
            r if (PORT_RANGE + 4..PORT_RANGE + 32).contains(&r) => {
                let shift = r - PORT_RANGE;
                let mask = (0xFFu32 << shift) & 0xFFFF_FFF0;
                self.outputs = (self.outputs & !mask) | ((u32::from(data) << shift) & mask);
            }
            r => {
                if let Some(slot) = self.registers.get_mut(usize::from(r)) {
                    *slot = data;
                }
            }
        }
    }

    fn read_out(&self) -> u32 {
        let w = Max7301Read::default()
            .with_marker(MAX7301_READ_MARKER)
            .with_answer(self.answer);
        // Found and configured: bits 23/22 (their complements) are 0; no
        // output mismatch, no error count.
        if self.debug {
            w.with_error_count(0).raw()
        } else {
            w.raw()
        }
    }
}

/// The pair on a DQLA, IDs 3 (QLA 1) and 4 (QLA 2).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct DqlaExpanders {
    chips: [Max7301; 2],
}

impl DqlaExpanders {
    /// Both chips found and configured, as after the firmware's power-up.
    pub fn new() -> DqlaExpanders {
        DqlaExpanders {
            chips: [Max7301::new(), Max7301::new()],
        }
    }

    /// Which chip an expander ID names (3 -> 0, 4 -> 1).
    pub fn chip_of(id: u8) -> Option<usize> {
        match id {
            3 => Some(0),
            4 => Some(1),
            _ => None,
        }
    }

    /// A register-14 write naming chip `chip`, its ports reading `lines`.
    pub fn write(&mut self, chip: usize, w: ExpanderWrite, lines: PortLines) {
        let Some(c) = self.chips.get_mut(chip) else {
            return;
        };
        c.debug = w.debug();
        if !w.sends_command() {
            return;
        }
        let [upper, data] = w.command().to_be_bytes();
        let register = upper & 0x7F;
        if upper & 0x80 != 0 {
            c.answer = u16::from(upper) << 8 | u16::from(c.read(register, lines));
        } else {
            c.write(register, data);
            // Max7301x2.v clears the saved answer when a command starts.
            c.answer = 0;
        }
    }

    /// Register 14 as chip `chip` answers it.
    pub fn read(&self, chip: usize) -> u32 {
        self.chips.get(chip).map_or(0, Max7301::read_out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// fpgatest's DQLA_IOExp_Check on chip 3: the NOP (`0x08000000`)
    /// shows it found and configured, each configuration register reads
    /// back its command's data, the debug read-out counts no error.
    #[test]
    fn fpgatest_dqla_check_reads_back_the_configuration() {
        let mut x = DqlaExpanders::new();
        x.write(0, ExpanderWrite(0x0003_0000 | 0x0800_0000), 0);
        let r = Max7301Read(x.read(0));
        assert_eq!(r.raw() & 0x00C0_0000, 0, "configured and found");
        assert_eq!(r.marker(), 0b010);
        for command in MAX7301_CONFIG {
            let read = (command & 0xFF00) | 0x8000;
            x.write(0, ExpanderWrite(0x0003_0000 | u32::from(read)), 0);
            let r = x.read(0);
            assert_eq!(r & 0xFF00, u32::from(read), "command echo {read:#x}");
            assert_eq!(r & 0xFF, u32::from(command & 0xFF), "{command:#x}");
        }
        x.write(0, ExpanderWrite(0x4003_0000), 0);
        assert_eq!((x.read(0) >> 16) & 0xFF, 0, "no output errors");
    }

    /// Port reads return the lines; LED outputs read back as written.
    #[test]
    fn ports_read_the_lines() {
        let mut x = DqlaExpanders::new();
        let lines: PortLines = 1 << 27 | 0b1010 << 23;
        x.write(1, ExpanderWrite(0x0000_D400), lines); // ports 20-27
        assert_eq!(x.read(1) & 0xFFFF, 0xD400 | (lines >> 20) & 0xFF);
        x.write(1, ExpanderWrite(0x0000_3F01), lines); // port 31 = 1
        x.write(1, ExpanderWrite(0x0000_BF00), lines);
        assert_eq!(x.read(1) & 0xFFFF, 0xBF01);
        assert_eq!(DqlaExpanders::chip_of(3), Some(0));
        assert_eq!(DqlaExpanders::chip_of(1), None);
    }
}
