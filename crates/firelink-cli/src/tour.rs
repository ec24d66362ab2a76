//! `firelink tour`: every packet of one broadcast I/O cycle (seed 000's
//! protocol, firmware Rev 8, QLA1 boards), built with the wire layer, then
//! decoded again, with its size, CRCs and its raw time on the wire at S400.

use std::io::Write;

use clap::Args;

use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed};

use crate::error::CliError;

/// Options of `firelink tour`.
#[derive(Args, Clone, Debug)]
pub struct TourArgs {
    /// Number of boards on the bus (1..=16).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=16))]
    pub boards: u8,
}

impl Default for TourArgs {
    fn default() -> Self {
        TourArgs { boards: 8 }
    }
}

/// Quadlets of a QLA1 real-time block at firmware Rev 8 (`fpga-board.md` §4).
const RT_BLOCK_QUADLETS: usize = 32;
/// Quadlets of a QLA1 Rev 8 write block: header, 4 DACs, control (§5).
const WRITE_BLOCK_QUADLETS: usize = 6;

fn quadlets_to_bytes(q: &[u32]) -> Vec<u8> {
    q.iter().flat_map(|v| v.to_be_bytes()).collect()
}

/// Print the cycle's packets as a table.
pub fn run(args: &TourArgs, out: &mut impl Write) -> Result<(), CliError> {
    let n = usize::from(args.boards);
    let pc = NodeId::local(args.boards);
    let seq: u32 = 1;
    let mask: u32 = (1u32 << n) - 1;
    let mut packets: Vec<(String, Vec<u8>)> = Vec::new();
    let mut emit = |label: String, repr: PacketRepr<'_>| -> Result<(), CliError> {
        let mut buf = vec![0u8; repr.buffer_len()];
        repr.emit(&mut buf)?;
        packets.push((label, buf));
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

    writeln!(
        out,
        "One broadcast I/O cycle, {n} QLA1 boards at firmware Rev 8 (seed 000 protocol)\n"
    )?;
    writeln!(
        out,
        "{:<30} {:<22} {:>7} {:>6} {:>10} {:>9} {:>11}",
        "packet", "tcode", "dest", "bytes", "hdr CRC", "data CRC", "S400 us"
    )?;
    let mut total_us = 0.0;
    for (label, bytes) in &packets {
        let p = Packet::new_checked(&bytes[..])?;
        p.verify()?;
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
        packets.len(),
        total_us
    )?;
    writeln!(
        out,
        "Try: firelink packet decode {}",
        crate::hex::to_hex(&packets[0].1)
    )?;
    Ok(())
}
