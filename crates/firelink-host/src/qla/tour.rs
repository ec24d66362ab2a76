//! The tour of one broadcast I/O cycle (seed 000's protocol, firmware
//! Rev 8, QLA1 boards): every packet built with the wire layer, checked by
//! decoding it again, and shown as a table with its size, CRCs and its raw
//! time on the wire at S400 (`firelink tour`).

use std::fmt;

use firelink_wire::Error;
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed};

/// One packet of the tour.
#[derive(Debug, Clone)]
pub struct TourPacket {
    /// What it is and who sends it.
    pub label: String,
    /// Its bytes, CRCs included.
    pub bytes: Vec<u8>,
}

/// Every packet of one broadcast I/O cycle, in order; `Display` is the
/// table.
#[derive(Debug, Clone)]
pub struct Tour {
    /// Boards on the bus.
    pub boards: u8,
    /// The packets.
    pub packets: Vec<TourPacket>,
}

/// Quadlets of a QLA1 real-time block at firmware Rev 8 (`fpga-board.md` §4).
const RT_BLOCK_QUADLETS: usize = 32;
/// Quadlets of a QLA1 Rev 8 write block: header, 4 DACs, control (§5).
const WRITE_BLOCK_QUADLETS: usize = 6;

fn quadlets_to_bytes(q: &[u32]) -> Vec<u8> {
    q.iter().flat_map(|v| v.to_be_bytes()).collect()
}

/// One broadcast I/O cycle of `boards` boards (1..=16; other counts are
/// taken as the nearest of these), every packet built and checked.
///
/// # Errors
/// A packet could not be built or does not decode again (a wire-layer
/// bug).
pub fn build(boards: u8) -> Result<Tour, Error> {
    let boards = boards.clamp(1, 16);
    let n = usize::from(boards);
    let pc = NodeId::local(boards);
    let seq: u32 = 1;
    let mask: u32 = (1u32 << n) - 1;
    let mut packets: Vec<TourPacket> = Vec::new();
    let mut emit = |label: String, repr: PacketRepr<'_>| -> Result<(), Error> {
        let mut buf = vec![0u8; repr.buffer_len()];
        repr.emit(&mut buf)?;
        packets.push(TourPacket { label, bytes: buf });
        Ok(())
    };

    emit(
        "query (PC)".into(),
        PacketRepr::WriteQuadletRequest {
            header: AsyncHeader::new(NodeId::BROADCAST, pc, 0),
            offset: 0x1800,
            data: (seq << 16) | mask,
        },
    )?;
    for board in 0..n {
        let mut block = vec![0u32; 1 + RT_BLOCK_QUADLETS];
        block[0] = (seq << 16) | (1 + RT_BLOCK_QUADLETS) as u32;
        block[2] = (4 << 28) | ((board as u32) << 24); // STATUS: 4 axes, board id
        let payload = quadlets_to_bytes(&block);
        emit(
            format!("status broadcast (board {board})"),
            PacketRepr::WriteBlockRequest {
                header: AsyncHeader::new(NodeId::BROADCAST, NodeId::local(board as u8), 0)
                    .with_pri(0xA),
                offset: 0xFFFF_FF00_1000,
                extended_tcode: 0,
                data: &payload,
            },
        )?;
    }
    let hub_quadlets = n * (1 + RT_BLOCK_QUADLETS) + 1;
    emit(
        "hub read request (PC)".into(),
        PacketRepr::ReadBlockRequest {
            header: AsyncHeader::new(NodeId::local(0), pc, 1),
            offset: 0x1000,
            data_length: (hub_quadlets * 4) as u16,
            extended_tcode: 0,
        },
    )?;
    let hub = vec![0u8; hub_quadlets * 4];
    emit(
        "hub read response (board 0)".into(),
        PacketRepr::ReadBlockResponse {
            header: AsyncHeader::new(pc, NodeId::local(0), 1),
            rcode: Rcode::Complete,
            extended_tcode: 0,
            data: &hub,
        },
    )?;
    let mut commands = Vec::with_capacity(n * WRITE_BLOCK_QUADLETS);
    for board in 0..n as u32 {
        commands.push((board << 8) | WRITE_BLOCK_QUADLETS as u32);
        commands.extend([0x8000_8000u32; 4]); // valid, zero current
        commands.push(0);
    }
    let commands = quadlets_to_bytes(&commands);
    emit(
        "command broadcast (PC)".into(),
        PacketRepr::WriteBlockRequest {
            header: AsyncHeader::new(NodeId::BROADCAST, pc, 2),
            offset: 0,
            extended_tcode: 0,
            data: &commands,
        },
    )?;

    for p in &packets {
        let packet = Packet::new_checked(&p.bytes[..])?;
        packet.verify()?;
    }
    Ok(Tour { boards, packets })
}

impl fmt::Display for Tour {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            out,
            "One broadcast I/O cycle, {} QLA1 boards at firmware Rev 8 (seed 000 protocol)\n",
            self.boards
        )?;
        writeln!(
            out,
            "{:<30} {:<22} {:>7} {:>6} {:>10} {:>9} {:>11}",
            "packet", "tcode", "dest", "bytes", "hdr CRC", "data CRC", "S400 us"
        )?;
        let mut total_us = 0.0;
        for TourPacket { label, bytes } in &self.packets {
            // Checked in `build`.
            let Ok(p) = Packet::new_checked(&bytes[..]) else {
                continue;
            };
            let us = bytes.len() as f64 * 8.0 / Speed::S400.bits_per_second() as f64 * 1e6;
            total_us += us;
            writeln!(
                out,
                "{:<30} {:<22} {:>7} {:>6} {:>10} {:>9} {:>11.3}",
                label,
                p.tcode().name(),
                format!("{:#06x}", p.destination_id().0),
                bytes.len(),
                format!("{:08x}", p.header_crc().unwrap_or(0)),
                p.data_crc().map_or("-".to_string(), |c| format!("{c:08x}")),
                us
            )?;
        }
        writeln!(
            out,
            "\n{} packets, {:.2} us of raw S400 bit time (without arbitration, gaps and PC overhead).",
            self.packets.len(),
            total_us
        )?;
        if let Some(first) = self.packets.first() {
            writeln!(
                out,
                "Try: firelink packet decode {}",
                crate::hex::to_hex(&first.bytes)
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_packet_of_eight_boards_is_built_and_shown() {
        let tour = build(8).unwrap();
        // Query, 8 status broadcasts, hub read request and response, command broadcast.
        assert_eq!(tour.packets.len(), 12);
        let table = tour.to_string();
        assert!(table.contains("12 packets"), "{table}");
        assert!(table.contains("status broadcast (board 7)"), "{table}");
    }
}
