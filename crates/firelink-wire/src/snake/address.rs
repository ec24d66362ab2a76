//! Table 1 of seed 001: the device map of the quadlet address field.
//!
//! Bits 7-4 of the destination offset select a channel (0 is the global
//! I/O module, 1-7 the amplifier channels), bits 3-0 a device on it. The
//! node decodes nothing else: an offset with any bit above bit 7 set, a
//! channel above 7 or a device the table does not list is not an address
//! of the node.
//!
//! ```
//! use firelink_wire::snake::address::{Access, GlobalRegister, SnakeRegister};
//! let wd = SnakeRegister::Global(GlobalRegister::WatchdogPeriod);
//! assert_eq!(wd.offset(), 0x03);
//! assert_eq!(wd.access(), Access::ReadWrite);
//! assert!(SnakeRegister::from_offset(0x85).is_err()); // no channel 8
//! assert!(SnakeRegister::from_offset(0x105).is_err()); // bit 8 set
//! ```

use crate::error::{Error, Result};
use crate::snake::CHANNELS;

/// The global I/O module's registers (channel 0, Table 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GlobalRegister {
    /// 0: STATUS (Table 2) when read; power control (enable mask and
    /// amplifier enables) when written.
    Status,
    /// 1: IEEE 1394 physical layer chip control register.
    PhyControl,
    /// 2: IEEE 1394 physical layer chip data register.
    PhyData,
    /// 3: watchdog time-out period (16 bits of 5.2083 us; 0 = off).
    WatchdogPeriod,
    /// 4: version number (read only; deprecated by the seed).
    Version,
}

/// A channel's devices (channels 1-7, Table 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ChannelDevice {
    /// 0: ADC data (potentiometer and motor current).
    Adc,
    /// 1: DAC control (motor voltage or current limit).
    Dac,
    /// 2: digital potentiometer control (a command).
    PotControl,
    /// 3: digital potentiometer data (the command's result).
    PotData,
    /// 4: quadrature encoder preload.
    EncoderPreload,
    /// 5: quadrature encoder data (the count).
    EncoderData,
    /// 6: encoder period data.
    EncoderPeriod,
    /// 7: encoder frequency data: listed by the seed as not implemented.
    EncoderFrequency,
}

/// What a register allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Access {
    /// Quadlet reads only.
    ReadOnly,
    /// Quadlet reads and writes.
    ReadWrite,
    /// In the table but not implemented: neither.
    NotImplemented,
}

impl Access {
    /// Whether a quadlet read is served.
    pub fn readable(self) -> bool {
        !matches!(self, Access::NotImplemented)
    }

    /// Whether a quadlet write is taken.
    pub fn writable(self) -> bool {
        matches!(self, Access::ReadWrite)
    }
}

/// One cell of Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SnakeRegister {
    /// A register of the global I/O module.
    Global(GlobalRegister),
    /// A device of channel `channel` (1..=7).
    Channel {
        /// The channel, 1..=7.
        channel: u8,
        /// The device.
        device: ChannelDevice,
    },
}

impl GlobalRegister {
    /// Every global register, by address.
    pub const ALL: [GlobalRegister; 5] = [
        GlobalRegister::Status,
        GlobalRegister::PhyControl,
        GlobalRegister::PhyData,
        GlobalRegister::WatchdogPeriod,
        GlobalRegister::Version,
    ];

    /// The device address, bits 3-0.
    pub fn index(self) -> u8 {
        self as u8
    }

    /// A short name for tools.
    pub fn name(self) -> &'static str {
        match self {
            GlobalRegister::Status => "status",
            GlobalRegister::PhyControl => "phy_control",
            GlobalRegister::PhyData => "phy_data",
            GlobalRegister::WatchdogPeriod => "watchdog",
            GlobalRegister::Version => "version",
        }
    }
}

impl ChannelDevice {
    /// Every channel device, by address.
    pub const ALL: [ChannelDevice; 8] = [
        ChannelDevice::Adc,
        ChannelDevice::Dac,
        ChannelDevice::PotControl,
        ChannelDevice::PotData,
        ChannelDevice::EncoderPreload,
        ChannelDevice::EncoderData,
        ChannelDevice::EncoderPeriod,
        ChannelDevice::EncoderFrequency,
    ];

    /// The device address, bits 3-0.
    pub fn index(self) -> u8 {
        self as u8
    }

    /// A short name for tools.
    pub fn name(self) -> &'static str {
        match self {
            ChannelDevice::Adc => "adc",
            ChannelDevice::Dac => "dac",
            ChannelDevice::PotControl => "pot_control",
            ChannelDevice::PotData => "pot_data",
            ChannelDevice::EncoderPreload => "encoder_preload",
            ChannelDevice::EncoderData => "encoder",
            ChannelDevice::EncoderPeriod => "encoder_period",
            ChannelDevice::EncoderFrequency => "encoder_frequency",
        }
    }
}

impl SnakeRegister {
    /// Decode a destination offset (Table 1).
    ///
    /// # Errors
    /// [`Error::InvalidValue`] naming the offset when any bit above bit 7
    /// is set, the channel is above 7 or the device is not in the table.
    pub fn from_offset(offset: u64) -> Result<SnakeRegister> {
        let bad = Error::InvalidValue {
            what: "Snake node address (Table 1)",
            value: offset.min(u64::from(u32::MAX)) as u32,
        };
        if offset > 0xFF {
            return Err(bad);
        }
        let channel = ((offset >> 4) & 0xF) as u8;
        let device = (offset & 0xF) as usize;
        if channel == 0 {
            return GlobalRegister::ALL
                .get(device)
                .map(|&r| SnakeRegister::Global(r))
                .ok_or(bad);
        }
        if usize::from(channel) > CHANNELS {
            return Err(bad);
        }
        ChannelDevice::ALL
            .get(device)
            .map(|&device| SnakeRegister::Channel { channel, device })
            .ok_or(bad)
    }

    /// A channel device's register.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn channel(channel: u8, device: ChannelDevice) -> Result<SnakeRegister> {
        crate::snake::check_channel(channel)?;
        Ok(SnakeRegister::Channel { channel, device })
    }

    /// The destination offset of this register.
    pub fn offset(self) -> u64 {
        match self {
            SnakeRegister::Global(r) => u64::from(r.index()),
            SnakeRegister::Channel { channel, device } => {
                (u64::from(channel & 0xF) << 4) | u64::from(device.index())
            }
        }
    }

    /// What the register allows.
    pub fn access(self) -> Access {
        match self {
            SnakeRegister::Global(GlobalRegister::PhyData | GlobalRegister::Version) => {
                Access::ReadOnly
            }
            SnakeRegister::Global(_) => Access::ReadWrite,
            SnakeRegister::Channel { device, .. } => match device {
                ChannelDevice::Adc
                | ChannelDevice::PotData
                | ChannelDevice::EncoderData
                | ChannelDevice::EncoderPeriod => Access::ReadOnly,
                ChannelDevice::Dac | ChannelDevice::PotControl | ChannelDevice::EncoderPreload => {
                    Access::ReadWrite
                }
                ChannelDevice::EncoderFrequency => Access::NotImplemented,
            },
        }
    }

    /// Every cell of Table 1 (global registers, then channels 1-7).
    pub fn all() -> impl Iterator<Item = SnakeRegister> {
        GlobalRegister::ALL
            .into_iter()
            .map(SnakeRegister::Global)
            .chain((1..=CHANNELS as u8).flat_map(|channel| {
                ChannelDevice::ALL
                    .into_iter()
                    .map(move |device| SnakeRegister::Channel { channel, device })
            }))
    }
}

impl core::fmt::Display for SnakeRegister {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SnakeRegister::Global(r) => write!(f, "{}", r.name()),
            SnakeRegister::Channel { channel, device } => {
                write!(f, "ch{channel}.{}", device.name())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn every_offset_decodes_to_its_cell_or_is_rejected() {
        let mut cells = 0;
        for offset in 0u64..0x200 {
            match SnakeRegister::from_offset(offset) {
                Ok(r) => {
                    cells += 1;
                    assert_eq!(r.offset(), offset);
                }
                Err(e) => assert!(matches!(e, Error::InvalidValue { .. })),
            }
        }
        // 5 global registers and 8 devices on each of 7 channels.
        assert_eq!(cells, 5 + 7 * 8);
        assert_eq!(SnakeRegister::all().count(), cells);
    }

    #[test]
    fn table_1_cells() {
        use ChannelDevice::*;
        let at = |o| SnakeRegister::from_offset(o).unwrap();
        assert_eq!(at(0x00), SnakeRegister::Global(GlobalRegister::Status));
        assert_eq!(at(0x01), SnakeRegister::Global(GlobalRegister::PhyControl));
        assert_eq!(at(0x02), SnakeRegister::Global(GlobalRegister::PhyData));
        assert_eq!(
            at(0x03),
            SnakeRegister::Global(GlobalRegister::WatchdogPeriod)
        );
        assert_eq!(at(0x04), SnakeRegister::Global(GlobalRegister::Version));
        for (d, dev) in [
            Adc,
            Dac,
            PotControl,
            PotData,
            EncoderPreload,
            EncoderData,
            EncoderPeriod,
            EncoderFrequency,
        ]
        .into_iter()
        .enumerate()
        {
            assert_eq!(
                at(0x70 | d as u64),
                SnakeRegister::Channel {
                    channel: 7,
                    device: dev
                }
            );
        }
        assert!(SnakeRegister::from_offset(0x05).is_err());
        assert!(SnakeRegister::from_offset(0x18).is_err());
        assert!(SnakeRegister::from_offset(0xF0).is_err());
        assert!(SnakeRegister::channel(0, Adc).is_err());
        assert!(SnakeRegister::channel(8, Adc).is_err());
        assert_eq!(
            SnakeRegister::from_offset(0x17).unwrap().access(),
            Access::NotImplemented
        );
        assert_eq!(at(0x24).to_string(), "ch2.encoder_preload");
    }
}
