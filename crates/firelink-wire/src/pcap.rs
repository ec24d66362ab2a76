//! 1394 packets in pcap files, both ways.
//!
//! There is no standard link type for raw 1394 asynchronous packets, so each
//! packet travels as the payload of an IPv4/UDP datagram (link type
//! `LINKTYPE_RAW`, 101) in a nanosecond-resolution pcap file, which
//! Wireshark opens:
//!
//! - addresses `127.13.94.<source>` and `127.13.94.<destination>`: the
//!   physical IDs of the sender and the addressee (63 for broadcast, 255
//!   when there is none, e.g. a PHY packet);
//! - ports: [`BUS_PORT`] (1394) on both sides for packets seen on the bus;
//!   a host's captures mark its own side with [`HOST_PORT`], so packets it
//!   sent go from port 1395 to 1394 and packets it received from 1394 to
//!   1395 ([`Record::direction`]);
//! - the timestamp: when the packet started, in nanoseconds.
//!
//! These are addresses in a file, not traffic: nothing is ever sent.
//!
//! [`write_file_header`] and [`write_record`] encode into caller buffers;
//! [`Records`] walks a file's bytes, checking every length before it reads
//! (a damaged file gives an error naming what was wrong, never a panic).
//!
//! ```
//! use firelink_wire::pcap::{self, Direction, Records};
//! let mut file = [0u8; 128];
//! let mut len = pcap::write_file_header(&mut file).unwrap();
//! len += pcap::write_record(&mut file[len..], 1_500, Direction::Sent, 2, 0, &[1, 2, 3, 4]).unwrap();
//! let record = Records::new(&file[..len]).unwrap().next().unwrap().unwrap();
//! assert_eq!((record.ns, record.direction(), record.payload), (1_500, Some(Direction::Sent), &[1u8, 2, 3, 4][..]));
//! ```

use crate::error::{Error, Result};

/// pcap magic for nanosecond timestamps, as written (little-endian).
pub const MAGIC_NS: u32 = 0xA1B2_3C4D;
/// `LINKTYPE_RAW`: packets begin with an IPv4 or IPv6 header.
pub const LINKTYPE_RAW: u32 = 101;
/// UDP port of the bus side.
pub const BUS_PORT: u16 = 1394;
/// UDP port of a capturing host's side.
pub const HOST_PORT: u16 = 1395;
/// Bytes of the file header.
pub const FILE_HEADER_LEN: usize = 24;
/// Bytes a record adds to its payload: record header, IPv4 and UDP headers.
pub const RECORD_OVERHEAD: usize = 16 + IP_UDP_LEN;
/// Largest payload a record may carry (the IPv4 length field).
pub const MAX_PAYLOAD: usize = 65_535 - IP_UDP_LEN;

const IP_UDP_LEN: usize = 28;
const SNAPLEN: u32 = 65_535;

/// Which way a packet went, seen from a capturing host.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// The host sent it.
    Sent,
    /// The host received it.
    Received,
    /// Seen on the bus (no host side).
    OnBus,
}

/// Write the file header into the start of `out`; returns its length.
///
/// # Errors
/// [`Error::BufferTooSmall`].
pub fn write_file_header(out: &mut [u8]) -> Result<usize> {
    let available = out.len();
    let Some(h) = out.get_mut(..FILE_HEADER_LEN) else {
        return Err(Error::BufferTooSmall {
            what: "pcap file header",
            needed: FILE_HEADER_LEN,
            available,
        });
    };
    h.fill(0);
    put(h, 0, &MAGIC_NS.to_le_bytes());
    put(h, 4, &2u16.to_le_bytes());
    put(h, 6, &4u16.to_le_bytes());
    put(h, 16, &SNAPLEN.to_le_bytes());
    put(h, 20, &LINKTYPE_RAW.to_le_bytes());
    Ok(FILE_HEADER_LEN)
}

/// Write one record (`payload` from physical ID `src` to `dst`, at `ns`
/// nanoseconds) into the start of `out`; returns its length
/// (`RECORD_OVERHEAD + payload.len()`).
///
/// # Errors
/// [`Error::OutOfRange`] for a payload above [`MAX_PAYLOAD`];
/// [`Error::BufferTooSmall`].
pub fn write_record(
    out: &mut [u8],
    ns: u64,
    direction: Direction,
    src: u8,
    dst: u8,
    payload: &[u8],
) -> Result<usize> {
    if payload.len() > MAX_PAYLOAD {
        return Err(Error::OutOfRange {
            what: "pcap record payload",
            value: payload.len() as i64,
            min: 0,
            max: MAX_PAYLOAD as i64,
        });
    }
    let len = RECORD_OVERHEAD + payload.len();
    let available = out.len();
    let Some(r) = out.get_mut(..len) else {
        return Err(Error::BufferTooSmall {
            what: "pcap record",
            needed: len,
            available,
        });
    };
    let datagram = (IP_UDP_LEN + payload.len()) as u32;
    r.fill(0);
    put(r, 0, &((ns / 1_000_000_000) as u32).to_le_bytes());
    put(r, 4, &((ns % 1_000_000_000) as u32).to_le_bytes());
    put(r, 8, &datagram.to_le_bytes());
    put(r, 12, &datagram.to_le_bytes());
    let mut ip = [0u8; 20];
    ip[0] = 0x45;
    ip[2..4].copy_from_slice(&(datagram as u16).to_be_bytes());
    ip[6] = 0x40;
    ip[8] = 64;
    ip[9] = 17;
    ip[12..16].copy_from_slice(&[127, 13, 94, src]);
    ip[16..20].copy_from_slice(&[127, 13, 94, dst]);
    let checksum = ipv4_checksum(&ip);
    ip[10..12].copy_from_slice(&checksum.to_be_bytes());
    put(r, 16, &ip);
    let (from, to) = match direction {
        Direction::Sent => (HOST_PORT, BUS_PORT),
        Direction::Received => (BUS_PORT, HOST_PORT),
        Direction::OnBus => (BUS_PORT, BUS_PORT),
    };
    put(r, 36, &from.to_be_bytes());
    put(r, 38, &to.to_be_bytes());
    put(r, 40, &((8 + payload.len()) as u16).to_be_bytes());
    put(r, 44, payload);
    Ok(len)
}

/// Copy `bytes` into `buf` at `at` (the caller sized `buf`).
fn put(buf: &mut [u8], at: usize, bytes: &[u8]) {
    if let Some(dst) = buf.get_mut(at..at + bytes.len()) {
        dst.copy_from_slice(bytes);
    }
}

/// The little-endian `u32` at `at` (0 where bytes are missing).
fn le32(buf: &[u8], at: usize) -> u32 {
    let mut b = [0u8; 4];
    if let Some(src) = buf.get(at..at + 4) {
        b.copy_from_slice(src);
    }
    u32::from_le_bytes(b)
}

/// The big-endian `u16` at `at` (0 where bytes are missing).
fn be16(buf: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([
        buf.get(at).copied().unwrap_or(0),
        buf.get(at + 1).copied().unwrap_or(0),
    ])
}

/// The byte at `at` (0 where missing).
fn byte(buf: &[u8], at: usize) -> u8 {
    buf.get(at).copied().unwrap_or(0)
}

/// The IPv4 header checksum of `header` (its checksum field taken as read).
fn ipv4_checksum(header: &[u8]) -> u16 {
    let mut sum: u32 = 0;
    for at in (0..header.len()).step_by(2) {
        sum += u32::from(be16(header, at));
    }
    while sum > 0xFFFF {
        sum = (sum & 0xFFFF) + (sum >> 16);
    }
    !(sum as u16)
}

/// One record of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record<'a> {
    /// Timestamp, nanoseconds.
    pub ns: u64,
    /// Last byte of the source address: the sender's physical ID.
    pub src: u8,
    /// Last byte of the destination address: the addressee's physical ID.
    pub dst: u8,
    /// UDP source port.
    pub src_port: u16,
    /// UDP destination port.
    pub dst_port: u16,
    /// The 1394 packet.
    pub payload: &'a [u8],
}

impl Record<'_> {
    /// Which way the packet went, from the ports; `None` for ports this
    /// format does not use.
    pub fn direction(&self) -> Option<Direction> {
        match (self.src_port, self.dst_port) {
            (HOST_PORT, BUS_PORT) => Some(Direction::Sent),
            (BUS_PORT, HOST_PORT) => Some(Direction::Received),
            (BUS_PORT, BUS_PORT) => Some(Direction::OnBus),
            _ => None,
        }
    }
}

/// The records of a pcap file in this format; yields an error once and
/// then stops when the file is damaged.
#[derive(Debug, Clone)]
pub struct Records<'a> {
    rest: &'a [u8],
    done: bool,
}

impl<'a> Records<'a> {
    /// Check the file header of `file` and walk its records.
    ///
    /// # Errors
    /// [`Error::Truncated`] for a file shorter than its header;
    /// [`Error::Malformed`] for another magic number or link type.
    pub fn new(file: &'a [u8]) -> Result<Records<'a>> {
        let Some((header, rest)) = file.split_at_checked(FILE_HEADER_LEN) else {
            return Err(Error::Truncated {
                what: "pcap file header",
                needed: FILE_HEADER_LEN,
                available: file.len(),
            });
        };
        let word = |at: usize| le32(header, at);
        if word(0) != MAGIC_NS {
            return Err(Error::Malformed {
                what: "pcap magic (nanosecond, little-endian expected)",
                value: word(0),
            });
        }
        if word(20) != LINKTYPE_RAW {
            return Err(Error::Malformed {
                what: "pcap link type (101, raw IP, expected)",
                value: word(20),
            });
        }
        Ok(Records { rest, done: false })
    }

    fn step(&mut self) -> Result<Option<Record<'a>>> {
        if self.rest.is_empty() {
            return Ok(None);
        }
        let Some((head, rest)) = self.rest.split_at_checked(16) else {
            return Err(Error::Truncated {
                what: "pcap record header",
                needed: 16,
                available: self.rest.len(),
            });
        };
        let (secs, nanos, incl) = (le32(head, 0), le32(head, 4), le32(head, 8) as usize);
        let Some((datagram, rest)) = rest.split_at_checked(incl) else {
            return Err(Error::LengthExceedsBuffer {
                what: "pcap record",
                declared: incl,
                available: rest.len(),
            });
        };
        self.rest = rest;
        let Some((ip, udp_and_payload)) = datagram.split_at_checked(20) else {
            return Err(Error::Truncated {
                what: "IPv4 header",
                needed: 20,
                available: datagram.len(),
            });
        };
        if byte(ip, 0) != 0x45 || byte(ip, 9) != 17 {
            return Err(Error::Malformed {
                what: "record (IPv4/UDP without options expected)",
                value: (u32::from(byte(ip, 0)) << 8) | u32::from(byte(ip, 9)),
            });
        }
        let Some((udp, payload)) = udp_and_payload.split_at_checked(8) else {
            return Err(Error::Truncated {
                what: "UDP header",
                needed: 8,
                available: udp_and_payload.len(),
            });
        };
        let udp_len = usize::from(be16(udp, 4));
        if udp_len != 8 + payload.len() {
            return Err(Error::LengthExceedsBuffer {
                what: "UDP length",
                declared: udp_len,
                available: 8 + payload.len(),
            });
        }
        Ok(Some(Record {
            ns: u64::from(secs) * 1_000_000_000 + u64::from(nanos),
            src: byte(ip, 15),
            dst: byte(ip, 19),
            src_port: be16(udp, 0),
            dst_port: be16(udp, 2),
            payload,
        }))
    }
}

impl<'a> Iterator for Records<'a> {
    type Item = Result<Record<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = self.step().transpose();
        if !matches!(item, Some(Ok(_))) {
            self.done = true;
        }
        item
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    #[test]
    fn records_round_trip_with_a_valid_ip_checksum() {
        let mut file = [0xA5u8; 256];
        let mut len = write_file_header(&mut file).unwrap();
        for (i, dir) in [Direction::Sent, Direction::Received, Direction::OnBus]
            .into_iter()
            .enumerate()
        {
            len += write_record(
                &mut file[len..],
                1_000_000_007 * i as u64,
                dir,
                1,
                63,
                &[i as u8; 8],
            )
            .unwrap();
        }
        let ip = &file[FILE_HEADER_LEN + 16..FILE_HEADER_LEN + 36];
        assert_eq!(
            ipv4_checksum(ip),
            0,
            "a header with its checksum sums to 0xFFFF"
        );
        let records: Vec<Record<'_>> = Records::new(&file[..len])
            .unwrap()
            .map(|r| r.unwrap())
            .collect();
        assert_eq!(records.len(), 3);
        assert_eq!(records[1].ns, 1_000_000_007);
        assert_eq!(records[1].direction(), Some(Direction::Received));
        assert_eq!(records[2].direction(), Some(Direction::OnBus));
        assert_eq!((records[0].src, records[0].dst), (1, 63));
        assert_eq!(records[2].payload, &[2u8; 8]);
        assert!(file[len..].iter().all(|&b| b == 0xA5));
    }

    #[test]
    fn damaged_files_are_errors_not_panics() {
        let mut file = [0u8; 128];
        let mut len = write_file_header(&mut file).unwrap();
        len += write_record(&mut file[len..], 5, Direction::Sent, 0, 1, &[9; 12]).unwrap();
        assert!(Records::new(&file[..10]).is_err());
        let mut wrong = file;
        wrong[0] ^= 1;
        assert!(Records::new(&wrong[..len]).is_err());
        for cut in FILE_HEADER_LEN + 1..len {
            let mut it = Records::new(&file[..cut]).unwrap();
            assert!(matches!(it.next(), Some(Err(_))), "cut at {cut}");
            assert!(it.next().is_none());
        }
        assert!(write_record(&mut [0u8; 40], 0, Direction::Sent, 0, 0, &[0; 4]).is_err());
    }
}
