//! The DS2505 1-wire interface (`fpga-board-extras.md` §4): register 13
//! and the 256-byte buffer of space 6, with or without an instrument (a
//! da Vinci tool carries a DS2505 add-only memory) on the line.
//!
//! The emulated QLA drives the 1-wire line directly (no DS2480B serial
//! driver answers, so bit 15 stays 0). A first read tries the DS2480B for
//! about 1.6 ms, then resets the line: with an instrument, the ROM (family
//! `0x0B`) and 256 bytes follow (about 250 ms in all); without one, no
//! presence pulse (reset result 3) and the buffer keeps what it had.

use firelink_wire::qla::extras::{
    DALLAS_BUFFER_QUADLETS, DS2505_BYTES, DS2505_FAMILY, DallasControl, DallasMode, DallasReset,
    DallasStatus,
};

use crate::time::{SYSTEM_CLOCK_HZ, SimTime};

/// Time the firmware gives a DS2480B to answer before it uses the direct
/// line.
pub const DS2480B_PROBE_US: u64 = 1_600;
/// Reset and presence detection on the direct line.
pub const RESET_US: u64 = 1_000;
/// ROM read, read-memory command and 256 bytes with an instrument present.
pub const READ_256_US: u64 = 250_000;
/// The rise time the direct line measures with its pull-up, in clocks
/// (inference: about half a microsecond).
pub const RISE_CLOCKS: u8 = 0x18;

/// What an instrument (a tool's DS2505) holds, laid out as the dVRK reads
/// it: `"997"` at `0x80`, the model number at `0xA4..0xA8` (24 bits),
/// the version at `0xA8`, the name from `0x160`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Instrument {
    /// Model number (24 bits).
    pub model: u32,
    /// Version byte.
    pub version: u8,
    /// Name (at most 27 bytes of ASCII are kept).
    pub name: String,
}

impl Instrument {
    /// The 2048 bytes of its DS2505 (unwritten bytes read `0xFF`).
    pub fn memory(&self) -> Vec<u8> {
        let mut m = vec![0xFF; DS2505_BYTES];
        let mut put = |at: usize, bytes: &[u8]| {
            for (i, b) in bytes.iter().enumerate() {
                if let Some(dst) = m.get_mut(at + i) {
                    *dst = *b;
                }
            }
        };
        put(0x80, b"997");
        put(0xA4, &(self.model & 0x00FF_FFFF).to_be_bytes());
        put(0xA8, &[self.version]);
        let name: Vec<u8> = self
            .name
            .bytes()
            .filter(u8::is_ascii)
            .take(0x17B - 0x160)
            .chain([0])
            .collect();
        put(0x160, &name);
        m
    }
}

/// Register 13 and the space-6 buffer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Dallas {
    memory: Option<Vec<u8>>,
    enabled: bool,
    family: u8,
    rise: u8,
    reset: DallasReset,
    busy_until: u64,
    buffer: Vec<u8>,
    next_address: usize,
}

impl Dallas {
    /// Power-up, with `instrument` on the line (or none).
    pub fn new(instrument: Option<&Instrument>) -> Dallas {
        Dallas {
            memory: instrument.map(Instrument::memory),
            enabled: false,
            family: 0,
            rise: 0xFF,
            reset: DallasReset::NotTried,
            busy_until: 0,
            buffer: vec![0; DALLAS_BUFFER_QUADLETS * 4],
            next_address: 0,
        }
    }

    /// Back to power-up (the instrument stays on the line).
    pub fn reboot(&mut self) {
        let memory = self.memory.take();
        *self = Dallas {
            memory,
            ..Dallas::new(None)
        };
    }

    /// Put an instrument on the line, or take it off.
    pub fn set_instrument(&mut self, instrument: Option<&Instrument>) {
        self.memory = instrument.map(Instrument::memory);
    }

    /// Register 13 as read at `now`; `bidirectional` is the QLA's DOUT
    /// hardware (bit 3).
    pub fn status(&self, now: SimTime, bidirectional: bool) -> DallasStatus {
        let busy = now.clocks() < self.busy_until;
        DallasStatus::default()
            .with_family(self.family)
            .with_rise_time(self.rise)
            .with_busy(busy)
            .with_state(if busy { 1 } else { 0 })
            .with_bidirectional(bidirectional)
            .with_reset_bits(self.reset.into())
            .with_enabled(self.enabled)
    }

    /// A register-13 write at `now`.
    pub fn write(&mut self, now: SimTime, c: DallasControl) {
        let now = now.clocks();
        let us = |us: u64| us * u64::from(SYSTEM_CLOCK_HZ) / 1_000_000;
        match c.mode() {
            DallasMode::Release => self.enabled = false,
            DallasMode::Take => self.enabled = true,
            DallasMode::ReadFirst => {
                self.enabled = true;
                self.rise = RISE_CLOCKS;
                self.next_address = usize::from(c.address()) % DS2505_BYTES;
                match self.memory.is_some() {
                    true => {
                        self.reset = DallasReset::Answered;
                        self.family = DS2505_FAMILY;
                        self.fill();
                        self.busy_until = now + us(DS2480B_PROBE_US + RESET_US + READ_256_US);
                    }
                    false => {
                        self.reset = DallasReset::NoPresence;
                        self.busy_until = now + us(DS2480B_PROBE_US + RESET_US);
                    }
                }
            }
            DallasMode::ReadNext => {
                if self.memory.is_some() && self.reset == DallasReset::Answered {
                    self.fill();
                    self.busy_until = now + us(READ_256_US);
                }
            }
            DallasMode::Unknown(_) => {}
        }
    }

    /// Read 256 bytes from the instrument at the next address.
    fn fill(&mut self) {
        let Some(memory) = &self.memory else {
            return;
        };
        let start = self.next_address;
        for (i, b) in self.buffer.iter_mut().enumerate() {
            *b = memory
                .get((start + i) % DS2505_BYTES)
                .copied()
                .unwrap_or(0xFF);
        }
        self.next_address = (start + self.buffer.len()) % DS2505_BYTES;
    }

    /// Space 6 quadlet `index` (bits 5:0).
    pub fn buffer_quadlet(&self, index: u16) -> u32 {
        let i = usize::from(index) % DALLAS_BUFFER_QUADLETS * 4;
        let mut q = [0; 4];
        for (k, b) in q.iter_mut().enumerate() {
            *b = self.buffer.get(i + k).copied().unwrap_or(0);
        }
        u32::from_be_bytes(q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::SimDuration;

    #[test]
    fn power_up_absent_and_present() {
        let t = SimTime::from_micros(5);
        let mut d = Dallas::new(None);
        assert_eq!(d.status(t, true).raw(), 0x00FF_0008, "power-up read");
        d.write(t, DallasControl(0x0080_0002));
        assert!(d.status(t, true).busy());
        let idle = t + SimDuration::from_millis(5);
        assert_eq!(d.status(idle, true).raw(), 0x0018_000F, "no tool");
        let tool = Instrument {
            model: 400_006,
            version: 3,
            name: "LARGE NEEDLE DRIVER".into(),
        };
        let mut d = Dallas::new(Some(&tool));
        d.write(t, DallasControl(0x0080_0002));
        let s = d.status(t + SimDuration::from_millis(100), true);
        assert_eq!(s.raw() & 0x20F0, 0x2010, "busy while reading");
        let s = d.status(t + SimDuration::from_millis(300), true);
        assert_eq!(s.raw(), 0x0B18_000B);
        // The buffer holds tool bytes 0x80..0x180: "997" first.
        assert_eq!(d.buffer_quadlet(0) >> 8, 0x39_3937);
        assert_eq!(d.buffer_quadlet((0xA4 - 0x80) / 4), 400_006);
        assert_eq!(
            d.buffer_quadlet((0x160 - 0x80) / 4),
            u32::from_be_bytes(*b"LARG")
        );
    }
}
