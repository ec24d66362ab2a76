//! Export a trace as a pcap file that Wireshark opens, in the format of
//! [`firelink_wire::pcap`]: each packet an IPv4/UDP datagram from
//! `127.13.94.<sender physical ID>` to `127.13.94.<addressee>` (for acks,
//! the node acknowledged; 255 for PHY and self-ID packets), port 1394 on
//! both sides (seen on the bus); the payload is the packet as it went on
//! the wire (after injected faults), an ack as its one byte, a PHY packet in
//! its link-internal 12-byte form; the timestamp is the start of the
//! packet's data prefix in virtual time.

use std::io::{self, Write};

pub use firelink_wire::pcap::{BUS_PORT as UDP_PORT, LINKTYPE_RAW};
use firelink_wire::pcap::{
    Direction, FILE_HEADER_LEN, RECORD_OVERHEAD, write_file_header, write_record,
};

use crate::trace::{PacketKind, Trace};

/// Write `trace` as a pcap file.
///
/// # Errors
/// I/O errors of `out`.
pub fn write_pcap(trace: &Trace, out: &mut impl Write) -> io::Result<()> {
    out.write_all(&pcap_bytes(trace))
}

/// The pcap file of `trace`, in memory.
pub fn pcap_bytes(trace: &Trace) -> Vec<u8> {
    let size = FILE_HEADER_LEN
        + trace
            .packets()
            .iter()
            .map(|p| RECORD_OVERHEAD + p.bytes.len())
            .sum::<usize>();
    let mut out = vec![0u8; size];
    let mut at = write_file_header(&mut out).unwrap_or(0);
    for p in trace.packets() {
        let dst = match p.kind {
            PacketKind::Ack => p
                .answers
                .and_then(|a| trace.packet(a))
                .map_or(255, |q| q.sender_phy),
            PacketKind::SelfId => 255,
            _ => p.destination_phy().unwrap_or(255),
        };
        let Some(rest) = out.get_mut(at..) else {
            break;
        };
        // A packet too large for a record (the bus caps packets far below
        // that) is left out.
        if let Ok(n) = write_record(
            rest,
            p.start.as_nanos(),
            Direction::OnBus,
            p.sender_phy,
            dst,
            &p.bytes,
        ) {
            at += n;
        }
    }
    out.truncate(at);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::pcap::Records;

    #[test]
    fn empty_trace_is_a_bare_header() {
        let bytes = pcap_bytes(&Trace::default());
        assert_eq!(bytes.len(), 24);
        assert_eq!(Records::new(&bytes).unwrap().count(), 0);
    }
}
