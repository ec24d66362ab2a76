//! Export a trace as a pcap file that Wireshark opens.
//!
//! There is no standard link type for raw 1394 asynchronous packets, so each
//! packet is carried as the payload of an IPv4/UDP datagram to port 1394
//! (link type `LINKTYPE_RAW`, 101), in a nanosecond-resolution pcap file:
//!
//! - source address `127.13.94.<sender physical ID>`, destination
//!   `127.13.94.<destination physical ID>` (63 for broadcast; for acks, the
//!   node acknowledged; 255 for PHY and self-ID packets);
//! - source and destination port 1394;
//! - payload: the packet bytes as they went on the wire (after injected
//!   faults), an ack as its one byte, a PHY packet in its link-internal
//!   12-byte form;
//! - timestamp: the start of the packet's data prefix in virtual time.
//!
//! These are addresses in a file, not traffic: nothing is ever sent.

use std::io::{self, Write};

use crate::trace::{PacketKind, Trace};

/// pcap magic for nanosecond timestamps.
const MAGIC_NS: u32 = 0xA1B2_3C4D;
/// `LINKTYPE_RAW`: packets begin with an IPv4 or IPv6 header.
pub const LINKTYPE_RAW: u32 = 101;
/// UDP port the packets are addressed to.
pub const UDP_PORT: u16 = 1394;

/// Write `trace` as a pcap file.
///
/// # Errors
/// I/O errors of `out`.
pub fn write_pcap(trace: &Trace, out: &mut impl Write) -> io::Result<()> {
    out.write_all(&pcap_bytes(trace))
}

/// The pcap file of `trace`, in memory.
pub fn pcap_bytes(trace: &Trace) -> Vec<u8> {
    let mut out = Vec::with_capacity(24 + trace.packets().len() * 64);
    out.extend_from_slice(&MAGIC_NS.to_le_bytes());
    out.extend_from_slice(&2u16.to_le_bytes());
    out.extend_from_slice(&4u16.to_le_bytes());
    out.extend_from_slice(&0i32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&65_535u32.to_le_bytes());
    out.extend_from_slice(&LINKTYPE_RAW.to_le_bytes());
    for p in trace.packets() {
        let dst = match p.kind {
            PacketKind::Ack => p
                .answers
                .and_then(|a| trace.packet(a))
                .map_or(255, |q| q.sender_phy),
            PacketKind::SelfId => 255,
            _ => p.destination_phy().unwrap_or(255),
        };
        let datagram = ipv4_udp(p.sender_phy, dst, &p.bytes);
        let ns = p.start.as_nanos();
        out.extend_from_slice(&((ns / 1_000_000_000) as u32).to_le_bytes());
        out.extend_from_slice(&((ns % 1_000_000_000) as u32).to_le_bytes());
        out.extend_from_slice(&(datagram.len() as u32).to_le_bytes());
        out.extend_from_slice(&(datagram.len() as u32).to_le_bytes());
        out.extend_from_slice(&datagram);
    }
    out
}

/// An IPv4 + UDP datagram carrying `payload` from 127.13.94.`src` to
/// 127.13.94.`dst`, port 1394 to 1394, with a correct IPv4 header checksum
/// (the UDP checksum is 0, "none", which IPv4 allows).
fn ipv4_udp(src: u8, dst: u8, payload: &[u8]) -> Vec<u8> {
    let udp_len = 8 + payload.len();
    let total = 20 + udp_len;
    let mut d = Vec::with_capacity(total);
    d.extend_from_slice(&[0x45, 0x00]);
    d.extend_from_slice(&(total.min(65_535) as u16).to_be_bytes());
    d.extend_from_slice(&[0, 0, 0x40, 0x00, 64, 17, 0, 0]);
    d.extend_from_slice(&[127, 13, 94, src]);
    d.extend_from_slice(&[127, 13, 94, dst]);
    let mut sum: u32 = 0;
    for pair in d.chunks(2) {
        sum += u32::from(u16::from_be_bytes([pair[0], pair[1]]));
    }
    while sum > 0xFFFF {
        sum = (sum & 0xFFFF) + (sum >> 16);
    }
    let checksum = !(sum as u16);
    d[10..12].copy_from_slice(&checksum.to_be_bytes());
    d.extend_from_slice(&UDP_PORT.to_be_bytes());
    d.extend_from_slice(&UDP_PORT.to_be_bytes());
    d.extend_from_slice(&(udp_len.min(65_535) as u16).to_be_bytes());
    d.extend_from_slice(&[0, 0]);
    d.extend_from_slice(payload);
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ipv4_header_checksum_verifies() {
        let d = ipv4_udp(1, 63, &[1, 2, 3, 4]);
        assert_eq!(d.len(), 32);
        let mut sum: u32 = 0;
        for pair in d[..20].chunks(2) {
            sum += u32::from(u16::from_be_bytes([pair[0], pair[1]]));
        }
        while sum > 0xFFFF {
            sum = (sum & 0xFFFF) + (sum >> 16);
        }
        assert_eq!(sum, 0xFFFF);
        assert_eq!(&d[20..22], &1394u16.to_be_bytes());
    }

    #[test]
    fn empty_trace_is_a_bare_header() {
        let bytes = pcap_bytes(&Trace::default());
        assert_eq!(bytes.len(), 24);
        assert_eq!(&bytes[..4], &MAGIC_NS.to_le_bytes());
    }
}
