//! The MAX7317 I/O expander of a QLA 1.5+ (`fpga-board-extras.md` §5):
//! register 14.
//!
//! The model keeps the chip's ten port output registers and answers the
//! host's SPI commands through register 14. Ports 0-7 read back what they
//! are commanded (no output mismatch ever arises), port 8 is the safety
//! line feedback (inverted STATUS bit 14) and port 9 the motor-supply
//! comparator (DIGIN bit 28). The SPI bus is never busy: a command is
//! answered by the time the next request arrives. A QLA1's expander has
//! register-14 ID 0; a DQLA's two have IDs 1 and 2 (DQLA.v), and each
//! takes only the writes that name its ID.

use firelink_wire::qla::extras::{
    EXPANDER_READ_MARKER, ExpanderDebug, ExpanderRead, ExpanderWrite,
};

/// MAX7317 ports.
pub const PORTS: usize = 10;
/// Register that reads the input levels of ports 7:0.
pub const READ_PORTS_LOW: u8 = 0x0E;
/// Register that reads the input levels of ports 9:8.
pub const READ_PORTS_HIGH: u8 = 0x0F;

/// Register 14 and the chip behind it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Expander {
    /// Register-14 ID (bits 19:16 of a write).
    id: u8,
    /// Port output registers (power-up 1: high impedance).
    outputs: [u8; PORTS],
    /// Register 14 reads 0 until the first write with expander ID 0.
    spoken_to: bool,
    debug: bool,
    /// The answer to the last read command: `0x80 | register`, data.
    answer: u16,
}

/// The inputs the expander sees from the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ExpanderInputs {
    /// STATUS bit 14 (port 8 reads its complement).
    pub safety_feedback: bool,
    /// DIGIN bit 28 (port 9).
    pub supply_comparator: bool,
}

impl Expander {
    /// A QLA1's expander (ID 0).
    pub fn new() -> Expander {
        Expander::with_id(0)
    }

    /// An expander answering to register-14 ID `id`.
    pub fn with_id(id: u8) -> Expander {
        Expander {
            id,
            outputs: [1; PORTS],
            spoken_to: false,
            debug: false,
            answer: 0,
        }
    }

    fn ports_low(&self) -> u8 {
        self.outputs
            .iter()
            .take(8)
            .enumerate()
            .fold(0, |acc, (i, v)| acc | (u8::from(*v != 0) << i))
    }

    /// A register-14 write.
    pub fn write(&mut self, w: ExpanderWrite, inputs: ExpanderInputs) {
        if w.id() != self.id {
            return;
        }
        self.spoken_to = true;
        self.debug = w.debug();
        if !w.sends_command() {
            return;
        }
        let command = w.command();
        let register = ((command >> 8) & 0x7F) as u8;
        let data = (command & 0xFF) as u8;
        if command & 0x8000 == 0 {
            if let Some(o) = self.outputs.get_mut(usize::from(register)) {
                *o = data;
            }
            return;
        }
        let value = match register {
            READ_PORTS_LOW => self.ports_low(),
            READ_PORTS_HIGH => {
                u8::from(!inputs.safety_feedback) | (u8::from(inputs.supply_comparator) << 1)
            }
            r => self.outputs.get(usize::from(r)).copied().unwrap_or(0),
        };
        self.answer = u16::from(0x80 | register) << 8 | u16::from(value);
    }

    /// Register 14 as read.
    pub fn read(&self) -> u32 {
        if !self.spoken_to {
            return 0;
        }
        if self.debug {
            let ports = self.ports_low();
            return ExpanderDebug::default()
                .with_ports_read(ports)
                .with_ports_commanded(ports)
                .raw();
        }
        ExpanderRead::default()
            .with_marker(EXPANDER_READ_MARKER)
            .with_answer(self.answer)
            .raw()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fpgatest_m_sequence() {
        let inputs = ExpanderInputs {
            safety_feedback: true,
            supply_comparator: true,
        };
        let mut e = Expander::new();
        assert_eq!(e.read(), 0, "0 until the first write with ID 0");
        e.write(ExpanderWrite(0x1345), inputs); // port 0x13: no such port
        assert_eq!(e.read(), 0x4000_0000);
        e.write(ExpanderWrite(0x0301), inputs); // port 3 output register = 1
        e.write(ExpanderWrite(0x0300), inputs); // port 3 = 0
        e.write(ExpanderWrite(0x8300), inputs);
        assert_eq!(e.read(), 0x4000_8300);
        e.write(ExpanderWrite(0x8E00), inputs);
        assert_eq!(e.read(), 0x4000_8EF7, "ports 7:0, port 3 low");
        e.write(ExpanderWrite(0x8F00), inputs);
        assert_eq!(
            e.read(),
            0x4000_8F02,
            "safety feedback inverted, comparator"
        );
        e.write(ExpanderWrite(0x4000_0000), inputs);
        assert_eq!(e.read(), 0x0000_F7F7, "debug read-out");
        e.write(ExpanderWrite(0xC000_0000), inputs);
        assert_eq!(e.read(), 0x0000_F7F7);
        e.write(ExpanderWrite(0x8000), inputs);
        assert_eq!(e.read(), 0x4000_8001);
        // A write naming another expander is not this one's.
        e.write(ExpanderWrite(0x0003_8300), inputs);
        assert_eq!(e.read(), 0x4000_8001);
        // A DQLA's QLA 2 expander (ID 2) ignores ID 0 and answers to 2.
        let mut q2 = Expander::with_id(2);
        q2.write(ExpanderWrite(0x8E00), inputs);
        assert_eq!(q2.read(), 0, "not named");
        q2.write(ExpanderWrite(0x0002_8E00), inputs);
        assert_eq!(q2.read(), 0x4000_8EFF);
    }
}
