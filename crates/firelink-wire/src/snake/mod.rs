//! The Snake robot's 7-channel FPGA/1394 node of seed 001: its quadlet
//! address map (Table 1), its register quadlets (Table 2 and the channel
//! devices) and its fixed-size real-time blocks (Fig. 17).
//!
//! Facts: `seed-systems.md` section B and seed 001 sections 6-7. Where the
//! seed gives no bit layout (Fig. 17 survives only as a caption, the
//! channel devices' quadlets are not drawn), the layouts here are
//! Firelink's own, chosen once and documented on each register; the PHY
//! registers and the watchdog reuse the JHU board's encodings
//! ([`crate::qla::registers`]), the node's direct descendant.
//!
//! - [`address`]: Table 1: bits 7-4 of the offset select the channel
//!   (0 = global), bits 3-0 the device; what each cell allows.
//! - [`registers`]: the quadlets: STATUS (Table 2), power control, ADC,
//!   DAC, digital potentiometer command and result, encoder count,
//!   preload and period; the feedback gain of eq. 1.
//! - [`analog`]: the channels' analog values (DAC, ADC and amplifier
//!   scales) that turn codes into volts and amperes.
//! - [`block`]: the block read (status, timestamp, every channel's
//!   feedback) and the block write (one quadlet per channel with its MSB
//!   valid bit), checked views and meaning types.
//!
//! Channels are numbered 1 to 7 as in Table 1 (channel 0 is the global
//! I/O module); arrays hold channel `c` at index `c - 1`.
//!
//! ```
//! use firelink_wire::snake::address::{ChannelDevice, SnakeRegister};
//! use firelink_wire::snake::registers::Wiper;
//! // Channel 3's encoder count lives at offset 0x35 (Table 1).
//! let r = SnakeRegister::from_offset(0x35).unwrap();
//! assert_eq!(r, SnakeRegister::Channel { channel: 3, device: ChannelDevice::EncoderData });
//! // Eq. 1: the nominal wiper 375 gives a current feedback gain near 2.
//! let g = Wiper::new(375).unwrap().feedback_gain();
//! assert!((g - 2.0).abs() < 0.02);
//! ```

pub mod address;
pub mod analog;
pub mod block;
pub mod registers;

/// Channels (amplifier sections) on one node (seed 001 §5.3).
pub const CHANNELS: usize = 7;
/// 16-bit words of each channel's digital-potentiometer EEPROM (§5.2).
pub const EEPROM_WORDS: usize = 14;
/// Largest digital-potentiometer wiper value (10 bits, §7.2).
pub const WIPER_MAX: u16 = 1023;
/// Offset of both real-time blocks (the block read and the block write).
pub const BLOCK_OFFSET: u64 = 0;
/// Largest block a node serves: 512 quadlets, one S400 payload (§8.3).
pub const MAX_BLOCK_QUADLETS: usize = 512;

/// Check that `channel` is one of the node's channels (1..=7).
///
/// # Errors
/// [`Error::OutOfRange`](crate::Error::OutOfRange) otherwise.
pub fn check_channel(channel: u8) -> crate::Result<u8> {
    if (1..=CHANNELS as u8).contains(&channel) {
        Ok(channel)
    } else {
        Err(crate::Error::OutOfRange {
            what: "Snake node channel",
            value: i64::from(channel),
            min: 1,
            max: CHANNELS as i64,
        })
    }
}
