//! The Ethernet/UDP bridge framing of FPGA V2/V3 boards (firmware Rev 7/8).
//!
//! Host -> board: a 16-bit control word, then a complete 1394 packet with
//! CRCs. Board -> host: the 1394 response packet, then 8 bytes of extra data.
//! Facts: `fpga-board.md` section 8.

use crate::error::{Error, Result};
use crate::packet::Packet;

/// UDP port of the board.
pub const BRIDGE_UDP_PORT: u16 = 1394;
/// Bytes of the host -> board control word.
pub const CONTROL_WORD_LEN: usize = 2;
/// Bytes of the board -> host extra-data trailer.
pub const EXTRA_DATA_LEN: usize = 8;

/// The control word that starts every host -> board datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ControlWord {
    /// Handle on the Ethernet-connected board itself; match the destination
    /// against the board ID instead of the FireWire node ID (bit 8).
    pub no_forward: bool,
    /// The host's copy of the FireWire bus generation (bits 7:0).
    pub generation: u8,
}

impl ControlWord {
    const NO_FORWARD: u16 = 1 << 8;

    /// Decode from the 16-bit word.
    pub fn from_u16(word: u16) -> ControlWord {
        ControlWord {
            no_forward: word & Self::NO_FORWARD != 0,
            generation: word as u8,
        }
    }

    /// Encode as the 16-bit word (other bits zero).
    pub fn to_u16(self) -> u16 {
        (if self.no_forward { Self::NO_FORWARD } else { 0 }) | u16::from(self.generation)
    }

    /// The two wire bytes.
    pub fn to_bytes(self) -> [u8; 2] {
        self.to_u16().to_be_bytes()
    }
}

/// Split a host -> board datagram into its control word and its packet.
/// The packet is checked for length and must fill the rest exactly.
///
/// # Errors
/// [`Error::Truncated`] if there is no control word; any error of
/// [`Packet::new_checked`]; [`Error::TrailingBytes`] after the packet.
pub fn split_host_datagram(datagram: &[u8]) -> Result<(ControlWord, Packet<&[u8]>)> {
    let (Some(word), Some(rest)) = (
        datagram.get(..CONTROL_WORD_LEN),
        datagram.get(CONTROL_WORD_LEN..),
    ) else {
        return Err(Error::Truncated {
            what: "bridge control word",
            needed: CONTROL_WORD_LEN,
            available: datagram.len(),
        });
    };
    let control = ControlWord::from_u16(u16::from_be_bytes([
        word.first().copied().unwrap_or(0),
        word.get(1).copied().unwrap_or(0),
    ]));
    let packet = Packet::new_checked(rest)?;
    let total = packet.total_len();
    if rest.len() > total {
        return Err(Error::TrailingBytes {
            what: "bridged packet",
            extra: rest.len() - total,
        });
    }
    Ok((control, packet))
}

/// Flags byte of the extra-data trailer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ExtraFlags {
    /// A FireWire bus reset is in progress (bit 0).
    pub bus_reset: bool,
    /// A packet was dropped (bit 1).
    pub packet_dropped: bool,
    /// The bridge hit an internal error (bit 2).
    pub internal_error: bool,
    /// Summary of error conditions (bit 3).
    pub summary_error: bool,
    /// The request was handled locally without forwarding (bit 4).
    pub no_forward: bool,
    /// Source port of the request (bits 6:5).
    pub source_port: u8,
}

impl ExtraFlags {
    /// Decode the flags byte.
    pub fn from_byte(b: u8) -> ExtraFlags {
        ExtraFlags {
            bus_reset: b & 0x01 != 0,
            packet_dropped: b & 0x02 != 0,
            internal_error: b & 0x04 != 0,
            summary_error: b & 0x08 != 0,
            no_forward: b & 0x10 != 0,
            source_port: (b >> 5) & 0x3,
        }
    }

    /// Encode the flags byte.
    pub fn to_byte(self) -> u8 {
        u8::from(self.bus_reset)
            | u8::from(self.packet_dropped) << 1
            | u8::from(self.internal_error) << 2
            | u8::from(self.summary_error) << 3
            | u8::from(self.no_forward) << 4
            | (self.source_port & 0x3) << 5
    }
}

/// The 8-byte trailer after every board -> host response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ExtraData {
    /// Flags (byte 0).
    pub flags: ExtraFlags,
    /// The board's FireWire bus generation (byte 1).
    pub generation: u8,
    /// Count of invalid bridge states (byte 2).
    pub invalid_states: u8,
    /// Count of packet errors (byte 3).
    pub packet_errors: u8,
    /// Time to receive the request, 49.152 MHz ticks (bytes 4-5).
    pub receive_time: u16,
    /// Total time to answer, 49.152 MHz ticks (bytes 6-7).
    pub total_time: u16,
}

impl ExtraData {
    /// Decode the 8-byte trailer.
    ///
    /// # Errors
    /// [`Error::Truncated`] if fewer than 8 bytes are given.
    pub fn parse(bytes: &[u8]) -> Result<ExtraData> {
        let Some(&[f, g, inv, err, r0, r1, t0, t1]) = bytes.get(..EXTRA_DATA_LEN) else {
            return Err(Error::Truncated {
                what: "bridge extra data",
                needed: EXTRA_DATA_LEN,
                available: bytes.len(),
            });
        };
        Ok(ExtraData {
            flags: ExtraFlags::from_byte(f),
            generation: g,
            invalid_states: inv,
            packet_errors: err,
            receive_time: u16::from_be_bytes([r0, r1]),
            total_time: u16::from_be_bytes([t0, t1]),
        })
    }

    /// Encode the 8-byte trailer.
    pub fn to_bytes(&self) -> [u8; EXTRA_DATA_LEN] {
        let r = self.receive_time.to_be_bytes();
        let t = self.total_time.to_be_bytes();
        [
            self.flags.to_byte(),
            self.generation,
            self.invalid_states,
            self.packet_errors,
            r[0],
            r[1],
            t[0],
            t[1],
        ]
    }
}

/// Split a board -> host datagram into the response packet and the trailer.
/// The packet must be followed by exactly the 8-byte trailer.
///
/// # Errors
/// Length errors of the packet or trailer; [`Error::TrailingBytes`] when more
/// than the trailer follows.
pub fn split_board_datagram(datagram: &[u8]) -> Result<(Packet<&[u8]>, ExtraData)> {
    let packet = Packet::new_checked(datagram)?;
    let total = packet.total_len();
    let rest = datagram.get(total..).unwrap_or(&[]);
    let extra = ExtraData::parse(rest)?;
    if rest.len() > EXTRA_DATA_LEN {
        return Err(Error::TrailingBytes {
            what: "bridge extra data",
            extra: rest.len() - EXTRA_DATA_LEN,
        });
    }
    let packet = Packet::new_unchecked(datagram.get(..total).unwrap_or(datagram));
    Ok((packet, extra))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_word_bits() {
        let c = ControlWord {
            no_forward: true,
            generation: 0x2A,
        };
        assert_eq!(c.to_u16(), 0x012A);
        assert_eq!(c.to_bytes(), [0x01, 0x2A]);
        assert_eq!(ControlWord::from_u16(0x012A), c);
        assert!(!ControlWord::from_u16(0x0005).no_forward);
    }

    #[test]
    fn extra_data_round_trip() {
        let e = ExtraData {
            flags: ExtraFlags {
                bus_reset: true,
                no_forward: true,
                source_port: 2,
                ..Default::default()
            },
            generation: 3,
            invalid_states: 1,
            packet_errors: 9,
            receive_time: 0x1234,
            total_time: 0xBEEF,
        };
        let b = e.to_bytes();
        assert_eq!(b, [0x51, 3, 1, 9, 0x12, 0x34, 0xBE, 0xEF]);
        assert_eq!(ExtraData::parse(&b), Ok(e));
        assert!(ExtraData::parse(&b[..7]).is_err());
    }
}
