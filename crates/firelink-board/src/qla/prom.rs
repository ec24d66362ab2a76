//! The two serial memories (`fpga-board-extras.md` §1, §2): the FPGA's
//! M25P16 configuration PROM behind PROM_CMD / PROM_RESULT and space 2,
//! and the QLA's 25AA128 EEPROM behind space 3. They hold the serial
//! numbers the reference host reads (`GetFPGASerialNumber`,
//! `GetQLASerialNumber`) and take the erase and program sequences of
//! `pgm1394`.
//!
//! Timing: the FPGA's SPI interface shifts at half the system clock (so a
//! 256-byte read takes about 85 us, as the spec measures); the chips' own
//! write cycles (the WIP bit) take the data sheets' typical times. The QLA
//! PROM's interface answers at once (the host does not poll it; it only
//! waits, over Ethernet, 1 ms).

use std::collections::BTreeMap;

use firelink_wire::qla::extras::{
    FPGA_PROM_BYTES, FPGA_PROM_ID, FPGA_PROM_PAGE_BYTES, FPGA_PROM_SECTOR_BYTES,
    FPGA_PROM_SIGNATURE, FPGA_SERIAL_ADDRESS, PROM_STATUS_WEL, PROM_STATUS_WIP, PromCommand,
    PromOpcode, PromStatus, QLA_PROM_BUFFER_QUADLETS, QLA_PROM_BYTES, QLA_PROM_PAGE_BYTES,
    QlaPromCommand, QlaPromOpcode, fpga_serial_image, qla_serial_image,
};

use crate::time::{SYSTEM_CLOCK_HZ, SimTime};

/// System clocks per SPI bit of the FPGA PROM interface (SPI clock =
/// 24.576 MHz: a 256-byte read, 2080 bits, takes 84.6 us).
pub const SPI_CLOCKS_PER_BIT: u64 = 2;
/// M25P16 page program time (typical).
pub const PAGE_PROGRAM_MS: f64 = 0.64;
/// M25P16 sector erase time (typical).
pub const SECTOR_ERASE_MS: f64 = 600.0;
/// M25P16 bulk erase time (typical).
pub const BULK_ERASE_MS: f64 = 13_000.0;
/// M25P16 write-status time (typical).
pub const WRITE_STATUS_MS: f64 = 1.5;
/// 25AA128 write cycle (byte, page or status).
pub const QLA_WRITE_MS: f64 = 5.0;

fn clocks_of_ms(ms: f64) -> u64 {
    (ms * SYSTEM_CLOCK_HZ as f64 / 1000.0) as u64
}

/// Block-protect bits of the M25P16 status byte (4:2) and SRWD (7).
const STATUS_WRITABLE: u8 = 0x9C;

/// The M25P16 and the FPGA's interface to it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct FpgaProm {
    /// Programmed sectors (absent = erased, every byte `0xFF`).
    sectors: BTreeMap<usize, Vec<u8>>,
    /// Status byte bits other than WIP (WEL, block protect, SRWD).
    status: u8,
    /// Clock at which the chip's write cycle ends (WIP until then).
    wip_until: u64,
    /// Clock at which the interface is idle again.
    busy_until: u64,
    /// Whether the busy period is a page-program stream.
    streaming: bool,
    deep_power_down: bool,
    result: u32,
    buffer: Vec<u8>,
    error_info: u16,
}

impl FpgaProm {
    /// An erased PROM with `serial` programmed at
    /// [`FPGA_SERIAL_ADDRESS`] (nothing if it is not a valid serial).
    pub fn new(serial: &str) -> FpgaProm {
        let mut prom = FpgaProm {
            sectors: BTreeMap::new(),
            status: 0,
            wip_until: 0,
            busy_until: 0,
            streaming: false,
            deep_power_down: false,
            result: 0,
            buffer: vec![0xFF; FPGA_PROM_PAGE_BYTES],
            error_info: 0,
        };
        if let Ok(image) = fpga_serial_image(serial) {
            for (i, b) in image.iter().enumerate() {
                prom.program_byte(FPGA_SERIAL_ADDRESS as usize + i, *b);
            }
        }
        prom
    }

    /// The FPGA's SPI interface after a reboot (the chip keeps its data).
    pub fn reboot(&mut self) {
        self.busy_until = 0;
        self.streaming = false;
        self.result = 0;
        self.error_info = 0;
    }

    fn byte(&self, address: usize) -> u8 {
        let a = address % FPGA_PROM_BYTES;
        self.sectors
            .get(&(a / FPGA_PROM_SECTOR_BYTES))
            .and_then(|s| s.get(a % FPGA_PROM_SECTOR_BYTES))
            .copied()
            .unwrap_or(0xFF)
    }

    /// Programming only clears bits.
    fn program_byte(&mut self, address: usize, value: u8) {
        let a = address % FPGA_PROM_BYTES;
        let sector = self
            .sectors
            .entry(a / FPGA_PROM_SECTOR_BYTES)
            .or_insert_with(|| vec![0xFF; FPGA_PROM_SECTOR_BYTES]);
        if let Some(b) = sector.get_mut(a % FPGA_PROM_SECTOR_BYTES) {
            *b &= value;
        }
    }

    /// Bytes `address..address + len` (for tests and tools).
    pub fn read(&self, address: usize, len: usize) -> Vec<u8> {
        (0..len).map(|i| self.byte(address + i)).collect()
    }

    fn status_byte(&self, now: u64) -> u8 {
        let wip = now < self.wip_until;
        let wel = self.status & PROM_STATUS_WEL != 0;
        let mut s = self.status & STATUS_WRITABLE;
        if wip {
            s |= PROM_STATUS_WIP;
        }
        // The chip clears WEL when a write cycle ends.
        if wel {
            s |= PROM_STATUS_WEL;
        }
        s
    }

    /// Apply the end of a write cycle that finished by `now`.
    fn settle(&mut self, now: u64) {
        if self.wip_until != 0 && now >= self.wip_until {
            self.wip_until = 0;
            self.status &= !PROM_STATUS_WEL;
        }
    }

    /// Whether `address` lies in the area the block-protect bits guard
    /// (BP = 1: the top sector, 2: top 2, 3: 4, 4: 8, 5: 16, 6-7: all).
    fn protected(&self, address: usize) -> bool {
        let bp = (self.status >> 2) & 0x7;
        if bp == 0 {
            return false;
        }
        let sectors = FPGA_PROM_BYTES / FPGA_PROM_SECTOR_BYTES;
        let guarded = (1usize << (bp - 1)).min(sectors);
        address % FPGA_PROM_BYTES / FPGA_PROM_SECTOR_BYTES >= sectors - guarded
    }

    fn writable(&self, now: u64) -> bool {
        self.status & PROM_STATUS_WEL != 0 && now >= self.wip_until && !self.deep_power_down
    }

    /// PROM_CMD as read at `now`.
    pub fn status(&self, now: SimTime) -> PromStatus {
        let now = now.clocks();
        let busy = now < self.busy_until;
        PromStatus::default()
            .with_error_info(self.error_info)
            .with_cs(!busy)
            .with_block_write(busy && self.streaming)
            .with_state(u8::from(busy && !self.streaming))
    }

    /// PROM_RESULT.
    pub fn result(&self) -> u32 {
        self.result
    }

    /// Space 2 quadlet `index` (bits 5:0) of the read buffer.
    pub fn buffer_quadlet(&self, index: u16) -> u32 {
        let i = usize::from(index) % (FPGA_PROM_PAGE_BYTES / 4) * 4;
        let mut q = [0xFF; 4];
        for (k, b) in q.iter_mut().enumerate() {
            *b = self.buffer.get(i + k).copied().unwrap_or(0xFF);
        }
        u32::from_be_bytes(q)
    }

    /// A PROM_CMD write at `now` (ignored unless the interface is idle).
    pub fn command(&mut self, now: SimTime, cmd: PromCommand) {
        let now = now.clocks();
        self.settle(now);
        if now < self.busy_until {
            return;
        }
        let address = cmd.address() as usize;
        let opcode = cmd.opcode();
        // Bits shifted: opcode, then address and data as the command has.
        let bits: u64 = match opcode {
            PromOpcode::Read | PromOpcode::FastRead => 8 + 24 + 8 * FPGA_PROM_PAGE_BYTES as u64,
            PromOpcode::ReadId => 32,
            PromOpcode::SectorErase => 32,
            PromOpcode::ReadStatus | PromOpcode::WriteStatus => 16,
            PromOpcode::Wake => 40,
            _ => 8,
        };
        if self.deep_power_down && opcode != PromOpcode::Wake {
            // The chip ignores all but the wake command.
            self.busy_until = now + bits * SPI_CLOCKS_PER_BIT;
            self.streaming = false;
            return;
        }
        match opcode {
            PromOpcode::ReadId => self.result = FPGA_PROM_ID,
            PromOpcode::ReadStatus => self.result = u32::from(self.status_byte(now)),
            PromOpcode::WriteEnable if now >= self.wip_until => {
                self.status |= PROM_STATUS_WEL;
                self.result = 0;
            }
            PromOpcode::WriteDisable if now >= self.wip_until => {
                self.status &= !PROM_STATUS_WEL;
                self.result = 0;
            }
            PromOpcode::Read | PromOpcode::FastRead => {
                self.buffer = (0..FPGA_PROM_PAGE_BYTES)
                    .map(|i| self.byte(address + i))
                    .collect();
                self.result = (FPGA_PROM_PAGE_BYTES / 4) as u32;
            }
            PromOpcode::SectorErase => {
                self.result = 0;
                if self.writable(now) && !self.protected(address) {
                    self.sectors
                        .remove(&(address % FPGA_PROM_BYTES / FPGA_PROM_SECTOR_BYTES));
                    self.wip_until = now + clocks_of_ms(SECTOR_ERASE_MS);
                }
            }
            PromOpcode::BulkErase if self.writable(now) && (self.status >> 2) & 0x7 == 0 => {
                self.sectors.clear();
                self.wip_until = now + clocks_of_ms(BULK_ERASE_MS);
            }
            PromOpcode::WriteStatus if self.writable(now) => {
                let value = (cmd.address() >> 16) as u8;
                self.status = (self.status & !STATUS_WRITABLE) | (value & STATUS_WRITABLE);
                self.wip_until = now + clocks_of_ms(WRITE_STATUS_MS);
            }
            PromOpcode::DeepPowerDown => self.deep_power_down = true,
            PromOpcode::Wake => {
                self.deep_power_down = false;
                self.result = FPGA_PROM_SIGNATURE;
            }
            // Bit-banging the pins (debug) is not modelled; page program
            // comes by block write.
            _ => {}
        }
        self.busy_until = now + bits * SPI_CLOCKS_PER_BIT;
        self.streaming = false;
    }

    /// A write of `quadlets` to space 2 starting at quadlet `first` (bits
    /// 5:0): a page-program stream, quadlet 0 `0x02000000 | address` and
    /// the data bytes in order. The firmware shifts as the quadlets come
    /// and needs quadlet i at offset i: a stream that starts elsewhere is
    /// refused with the error info `{00, addr[5:0], 0, expected[6:0]}`.
    pub fn stream(&mut self, now: SimTime, first: u16, quadlets: &[u32]) {
        let now = now.clocks();
        self.settle(now);
        if now < self.busy_until {
            return;
        }
        if first & 0x3F != 0 {
            self.error_info = ((first & 0x3F) << 8) & 0x3F00;
            return;
        }
        self.error_info = 0;
        let Some((&head, data)) = quadlets.split_first() else {
            return;
        };
        let cmd = PromCommand(head);
        self.result = quadlets.len() as u32;
        let bytes: Vec<u8> = data.iter().flat_map(|q| q.to_be_bytes()).collect();
        self.busy_until = now + (32 + 8 * bytes.len() as u64) * SPI_CLOCKS_PER_BIT;
        self.streaming = true;
        let address = cmd.address() as usize;
        if cmd.opcode() != PromOpcode::PageProgram || !self.writable(now) || self.protected(address)
        {
            return;
        }
        // The address wraps inside its 256-byte page; only the last 256
        // bytes of a longer stream are kept.
        let page = address & !(FPGA_PROM_PAGE_BYTES - 1);
        let skip = bytes.len().saturating_sub(FPGA_PROM_PAGE_BYTES);
        for (i, b) in bytes.iter().enumerate().skip(skip) {
            let offset = (address + i) % FPGA_PROM_PAGE_BYTES;
            self.program_byte(page + offset, *b);
        }
        self.wip_until = self.busy_until + clocks_of_ms(PAGE_PROGRAM_MS);
    }
}

/// One 25AA128 and its interface.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct QlaProm {
    memory: Vec<u8>,
    /// Status byte bits other than WIP.
    status: u8,
    wip_until: u64,
    result: u32,
    buffer: [u32; QLA_PROM_BUFFER_QUADLETS],
}

impl QlaProm {
    /// An erased EEPROM with `serial` written from address 0 (nothing if it
    /// is not a valid serial).
    pub fn new(serial: &str) -> QlaProm {
        let mut memory = vec![0xFF; QLA_PROM_BYTES];
        if let Ok(image) = qla_serial_image(serial) {
            for (dst, b) in memory.iter_mut().zip(image) {
                *dst = b;
            }
        }
        QlaProm {
            memory,
            status: 0,
            wip_until: 0,
            result: 0,
            buffer: [0; QLA_PROM_BUFFER_QUADLETS],
        }
    }

    /// The interface after a reboot (the chip keeps its data).
    pub fn reboot(&mut self) {
        self.result = 0;
        self.buffer = [0; QLA_PROM_BUFFER_QUADLETS];
    }

    fn settle(&mut self, now: u64) {
        if self.wip_until != 0 && now >= self.wip_until {
            self.wip_until = 0;
            self.status &= !PROM_STATUS_WEL;
        }
    }

    fn writable(&self, now: u64) -> bool {
        self.status & PROM_STATUS_WEL != 0 && now >= self.wip_until
    }

    /// Bytes `address..address + len` (14-bit address, wrapping).
    pub fn read(&self, address: usize, len: usize) -> Vec<u8> {
        (0..len)
            .map(|i| {
                self.memory
                    .get((address + i) % QLA_PROM_BYTES)
                    .copied()
                    .unwrap_or(0xFF)
            })
            .collect()
    }

    /// A page write: the address wraps inside its 64-byte page.
    fn write_page(&mut self, address: usize, bytes: &[u8]) {
        let a = address % QLA_PROM_BYTES;
        let page = a & !(QLA_PROM_PAGE_BYTES - 1);
        for (i, b) in bytes.iter().enumerate() {
            let offset = (a + i) % QLA_PROM_PAGE_BYTES;
            if let Some(dst) = self.memory.get_mut(page + offset) {
                *dst = *b;
            }
        }
    }

    /// The status register (`0x3001`): the interface is never busy.
    pub fn status(&self) -> PromStatus {
        PromStatus::default().with_cs(true)
    }

    /// The result register (`0x3002`).
    pub fn result(&self) -> u32 {
        self.result
    }

    /// Buffer quadlet `index` (0..16).
    pub fn buffer_quadlet(&self, index: usize) -> u32 {
        self.buffer.get(index).copied().unwrap_or(0)
    }

    /// Write buffer quadlet `index` (0..16).
    pub fn set_buffer_quadlet(&mut self, index: usize, value: u32) {
        if let Some(q) = self.buffer.get_mut(index) {
            *q = value;
        }
    }

    /// A command at `0x3000`.
    pub fn command(&mut self, now: SimTime, cmd: QlaPromCommand) {
        let now = now.clocks();
        self.settle(now);
        let address = usize::from(cmd.address());
        let write_cycle = now + clocks_of_ms(QLA_WRITE_MS);
        match cmd.opcode() {
            QlaPromOpcode::ReadByte => {
                self.result = u32::from(self.read(address, 1).first().copied().unwrap_or(0xFF));
            }
            QlaPromOpcode::ReadStatus => {
                let wip = if now < self.wip_until {
                    PROM_STATUS_WIP
                } else {
                    0
                };
                self.result = u32::from(self.status | wip);
            }
            QlaPromOpcode::WriteEnable if now >= self.wip_until => {
                self.status |= PROM_STATUS_WEL;
            }
            QlaPromOpcode::WriteDisable if now >= self.wip_until => {
                self.status &= !PROM_STATUS_WEL;
            }
            QlaPromOpcode::WriteByte if self.writable(now) => {
                self.write_page(address, &[cmd.data()]);
                self.wip_until = write_cycle;
            }
            QlaPromOpcode::WriteStatus if self.writable(now) => {
                // Block protect bits 3:2 and WPEN (7).
                self.status = (self.status & !0x8C) | (cmd.data() & 0x8C);
                self.wip_until = write_cycle;
            }
            QlaPromOpcode::ReadBlock => {
                let n = usize::from(cmd.data() & 0xF) + 1;
                let bytes = self.read(address, 4 * n);
                for (q, v) in self
                    .buffer
                    .iter_mut()
                    .zip(firelink_wire::field::quadlets(&bytes))
                {
                    *q = v;
                }
            }
            QlaPromOpcode::WriteBlock if self.writable(now) => {
                let n = usize::from(cmd.data() & 0xF) + 1;
                let bytes: Vec<u8> = self
                    .buffer
                    .iter()
                    .take(n)
                    .flat_map(|q| q.to_be_bytes())
                    .collect();
                self.write_page(address, &bytes);
                self.wip_until = write_cycle;
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::SimDuration;
    use firelink_wire::qla::extras::{parse_fpga_serial, parse_qla_serial};

    fn cmd(op: PromOpcode, a: u32) -> PromCommand {
        PromCommand::new(op, a)
    }

    #[test]
    fn fpga_prom_reads_the_serial_number() {
        let mut p = FpgaProm::new("1234-56");
        let t = SimTime::from_micros(10);
        p.command(t, cmd(PromOpcode::Read, FPGA_SERIAL_ADDRESS));
        // Busy for about 85 us, then idle with 64 quadlets read.
        assert_eq!(p.status(t + SimDuration::from_micros(80)).state(), 1);
        assert_eq!(p.status(t + SimDuration::from_micros(90)).state(), 0);
        assert_eq!(p.result(), 64);
        let bytes: Vec<u8> = (0..4)
            .flat_map(|i| p.buffer_quadlet(i).to_be_bytes())
            .collect();
        assert_eq!(parse_fpga_serial(&bytes), Ok("1234-56"));
        // Commands are refused while busy.
        p.command(
            t + SimDuration::from_micros(100),
            cmd(PromOpcode::ReadId, 0),
        );
        p.command(
            t + SimDuration::from_micros(101),
            cmd(PromOpcode::ReadStatus, 0),
        );
        assert_eq!(p.result(), FPGA_PROM_ID);
    }

    #[test]
    fn erase_and_program_follow_the_chip() {
        let mut p = FpgaProm::new("1234-56");
        let mut t = SimTime::from_micros(1);
        let step = |t: &mut SimTime, us: u64| *t += SimDuration::from_micros(us);
        // Without write enable nothing is erased.
        p.command(t, cmd(PromOpcode::SectorErase, 0x1F_0000));
        step(&mut t, 10);
        assert_eq!(p.read(0x1F_FF00, 4), b"FPGA");
        p.command(t, cmd(PromOpcode::WriteEnable, 0));
        step(&mut t, 10);
        p.command(t, cmd(PromOpcode::ReadStatus, 0));
        assert_eq!(p.result(), u32::from(PROM_STATUS_WEL));
        step(&mut t, 10);
        p.command(t, cmd(PromOpcode::SectorErase, 0x1F_0000));
        step(&mut t, 10);
        p.command(t, cmd(PromOpcode::ReadStatus, 0));
        assert_eq!(p.result(), u32::from(PROM_STATUS_WIP | PROM_STATUS_WEL));
        assert_eq!(p.read(0x1F_FF00, 4), [0xFF; 4]);
        step(&mut t, 700_000);
        p.command(t, cmd(PromOpcode::ReadStatus, 0));
        assert_eq!(p.result(), 0, "WIP and WEL clear when the erase ends");
        // Page program: 8 bytes at 0x1EFFFC wrap inside the page.
        step(&mut t, 10);
        p.command(t, cmd(PromOpcode::WriteEnable, 0));
        step(&mut t, 10);
        p.stream(t, 0, &[0x021E_FFFC, 0x0001_0203, 0x0405_0607]);
        assert_eq!(p.result(), 3);
        assert!(p.status(t).block_write());
        assert_eq!(p.read(0x1E_FFFC, 4), [0, 1, 2, 3]);
        assert_eq!(p.read(0x1E_FF00, 4), [4, 5, 6, 7]);
        // A stream that does not start at offset 0 is refused.
        step(&mut t, 2_000);
        p.stream(t, 5, &[0x1234_5678]);
        assert_eq!(p.status(t).error_info(), 0x0500);
    }

    #[test]
    fn qla_prom_serial_bytes_and_blocks() {
        let mut q = QlaProm::new("1234-56");
        let t = SimTime::from_micros(1);
        assert_eq!(parse_qla_serial(&q.read(0, 12)), Ok("1234-56"));
        q.command(t, QlaPromCommand::new(QlaPromOpcode::ReadBlock, 0, 2));
        assert_eq!(
            [
                q.buffer_quadlet(0),
                q.buffer_quadlet(1),
                q.buffer_quadlet(2)
            ],
            [0x514C_4120, 0x3132_3334, 0x2D35_3600]
        );
        q.command(t, QlaPromCommand::new(QlaPromOpcode::ReadByte, 1, 0));
        assert_eq!(q.result(), u32::from(b'L'));
        // Byte write needs write enable and takes 5 ms.
        q.command(
            t,
            QlaPromCommand::new(QlaPromOpcode::WriteByte, 0x100, 0x42),
        );
        assert_eq!(q.read(0x100, 1), [0xFF]);
        q.command(t, QlaPromCommand::new(QlaPromOpcode::WriteEnable, 0, 0));
        q.command(
            t,
            QlaPromCommand::new(QlaPromOpcode::WriteByte, 0x100, 0x42),
        );
        assert_eq!(q.read(0x100, 1), [0x42]);
        q.command(t, QlaPromCommand::new(QlaPromOpcode::ReadStatus, 0, 0));
        assert_eq!(q.result(), u32::from(PROM_STATUS_WIP | PROM_STATUS_WEL));
        let later = t + SimDuration::from_millis(6);
        q.command(later, QlaPromCommand::new(QlaPromOpcode::ReadStatus, 0, 0));
        assert_eq!(q.result(), 0);
        // Block write of the buffer, wrapping in the 64-byte page.
        q.set_buffer_quadlet(0, 0xA1A2_A3A4);
        q.set_buffer_quadlet(1, 0xB1B2_B3B4);
        q.command(later, QlaPromCommand::new(QlaPromOpcode::WriteEnable, 0, 0));
        q.command(
            later,
            QlaPromCommand::new(QlaPromOpcode::WriteBlock, 0x13C, 1),
        );
        assert_eq!(q.read(0x13C, 4), [0xA1, 0xA2, 0xA3, 0xA4]);
        assert_eq!(q.read(0x100, 4), [0xB1, 0xB2, 0xB3, 0xB4]);
    }
}
