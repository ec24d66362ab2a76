//! The bus tools' work on boards, for any front end: a scan report and
//! a board's identity as records (`scan --json`) and as text
//! ([`scan_text`]), every board's live
//! state (`info`), a destination from a board ID, and register reads and
//! writes checked against the board's map, with a write over the bridge
//! confirmed by reading back.

use std::fmt::Write as _;

use serde::Serialize;

use firelink_wire::qla::address::{AxisRegister, BoardRegister, Register};
use firelink_wire::qla::registers::{StatusRead, Temperature, Watchdog, counts_from_offset_binary};

use crate::qla::board::BoardInfo;
use crate::qla::register_address::{AddressError, check_address, register_offset};
use crate::qla::scan::{ScanReport, mask_boards, scan};
use crate::{Dest, HostError, Port};

/// One board's identity as a record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoardSummary {
    /// Rotary-switch board ID.
    pub board_id: u8,
    /// Physical node ID.
    pub node: u8,
    /// Companion board's name (QLA1, DQLA, ...).
    pub hardware: String,
    /// Firmware revision.
    pub firmware: u32,
    /// FPGA generation (2, 3).
    pub fpga: u8,
    /// Firmware's git commit, 7 hex digits, `-dirty` when built so.
    pub git: String,
}

impl From<&BoardInfo> for BoardSummary {
    fn from(b: &BoardInfo) -> Self {
        BoardSummary {
            board_id: b.board_id,
            node: b.node,
            hardware: b.hardware.name().to_string(),
            firmware: b.firmware,
            fpga: b.fpga.number(),
            git: format!(
                "{:07x}{}",
                b.git.commit(),
                if b.git.dirty() { "-dirty" } else { "" }
            ),
        }
    }
}

/// A scan of one port as a record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanSummary {
    /// The port's name.
    pub port: String,
    /// The boards found.
    pub boards: Vec<BoardSummary>,
    /// The protocol chosen.
    pub protocol: &'static str,
    /// Why.
    pub protocol_reason: &'static str,
    /// Broadcast protocol: the board IDs each query of a cycle selects.
    pub broadcast_groups: Vec<Vec<u8>>,
    /// Nodes that answered nothing.
    pub silent_nodes: Vec<u8>,
    /// Nodes with hardware or firmware the host does not drive.
    pub unsupported_nodes: Vec<u8>,
    /// The Ethernet bridge's board, if any.
    pub bridge_board: Option<u8>,
    /// The bus generation of the scan.
    pub generation: u32,
}

impl ScanSummary {
    /// The record of `report`, a scan of the port named `port`.
    pub fn new(port: &str, report: &ScanReport) -> Self {
        ScanSummary {
            port: port.to_string(),
            boards: report.boards.iter().map(BoardSummary::from).collect(),
            protocol: report.protocol.name(),
            protocol_reason: report.protocol_reason,
            broadcast_groups: report
                .broadcast_groups
                .iter()
                .map(|&mask| (0..16u8).filter(|id| mask & (1 << id) != 0).collect())
                .collect(),
            silent_nodes: report.silent_nodes.clone(),
            unsupported_nodes: report.unsupported.iter().map(|u| u.node).collect(),
            bridge_board: report.bridge_board,
            generation: report.generation,
        }
    }
}

/// `report`, a scan of the port named `port`, as the table `firelink scan`
/// prints: one line per board, the bridge board, the nodes the host does
/// not drive, the protocol and why, and the broadcast groups when there
/// are several.
pub fn scan_text(port: &str, report: &ScanReport) -> String {
    let mut text = format!("{} board(s) on {port}:\n", report.boards.len());
    text.push_str("  board  node  hardware  firmware  fpga  git\n");
    for b in report.boards.iter().map(BoardSummary::from) {
        let _ = writeln!(
            text,
            "  {:>5}  {:>4}  {:<8}  {:>8}  V{}    {}",
            b.board_id, b.node, b.hardware, b.firmware, b.fpga, b.git
        );
    }
    if let Some(bridge) = report.bridge_board {
        let _ = writeln!(text, "Ethernet bridge: board {bridge}");
    }
    for u in &report.unsupported {
        let _ = writeln!(
            text,
            "node {}: unsupported hardware {} firmware {}",
            u.node,
            u.hardware.name(),
            u.firmware
        );
    }
    let _ = writeln!(
        text,
        "protocol: {} ({})",
        report.protocol_label(),
        report.protocol_reason
    );
    if report.broadcast_groups.len() > 1 {
        let groups: Vec<String> = report
            .broadcast_groups
            .iter()
            .map(|&m| format!("boards {}", mask_boards(m)))
            .collect();
        let _ = writeln!(text, "broadcast groups: {}", groups.join(" | "));
    }
    text
}

/// One axis's raw readouts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisReadout {
    /// Axis, from 1.
    pub axis: u8,
    /// Encoder position, counts.
    pub encoder_counts: i32,
    /// Potentiometer ADC bits.
    pub pot_bits: u32,
    /// Motor current ADC bits.
    pub current_bits: u32,
}

/// One board's identity and live state, read register by register.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoardState {
    /// Who it is.
    pub board: BoardSummary,
    /// The STATUS register, `0x`-prefixed hex.
    pub status: String,
    /// Motor power enabled.
    pub power: bool,
    /// Safety relay on.
    pub relay: bool,
    /// Motor supply good.
    pub supply_good: bool,
    /// Watchdog expired.
    pub watchdog_expired: bool,
    /// Amplifiers enabled, one bit per axis.
    pub amp_enabled_mask: u8,
    /// Watchdog period, ms (0: off).
    pub watchdog_period_ms: f64,
    /// The two temperature sensors, degrees C (`None`: out of range).
    pub temperature_c: [Option<f64>; 2],
    /// Every axis.
    pub axes: Vec<AxisReadout>,
}

/// Read the live state of board `b` (found by a scan) through `port`.
///
/// # Errors
/// A read failed.
pub fn read_state(port: &mut dyn Port, b: &BoardInfo) -> Result<BoardState, HostError> {
    let dest = Dest::node(b.node);
    let mut read = |r: Register| -> Result<u32, HostError> { port.read_quadlet(dest, r.offset()?) };
    let status = StatusRead(read(Register::board(BoardRegister::Status))?);
    let watchdog = Watchdog(read(Register::board(BoardRegister::Watchdog))?);
    let temperature = Temperature(read(Register::board(BoardRegister::Temperature))?);
    let mut axes = Vec::new();
    for axis in 1..=b.layout.motors() as u8 {
        let enc = read(Register::axis(axis, AxisRegister::EncPosition))?;
        let adc = read(Register::axis(axis, AxisRegister::Adc))?;
        axes.push(AxisReadout {
            axis,
            encoder_counts: counts_from_offset_binary(enc),
            pot_bits: adc >> 16,
            current_bits: adc & 0xFFFF,
        });
    }
    // The QLA's sensors read 0.5 degree C per bit (0xFF: out of range).
    let temperature_c = [temperature.upper(), temperature.lower()]
        .map(|b| (b != 0xFF).then_some(f64::from(b) / 2.0));
    Ok(BoardState {
        board: BoardSummary::from(b),
        status: format!("{:#010x}", status.raw()),
        power: status.motor_power_enabled(),
        relay: status.relay_on(),
        supply_good: status.motor_supply_good(),
        watchdog_expired: status.watchdog_timeout(),
        amp_enabled_mask: status.amp_enabled(),
        watchdog_period_ms: watchdog.period().as_secs_f64() * 1e3,
        temperature_c,
        axes,
    })
}

/// The destination of a register access: `node` as given, else the node
/// of board `board` found by a scan.
///
/// # Errors
/// The scan failed; [`HostError::UnknownBoard`].
pub fn destination(port: &mut dyn Port, board: u8, node: Option<u8>) -> Result<Dest, HostError> {
    if let Some(node) = node {
        return Ok(Dest::node(node));
    }
    scan(port)?
        .boards
        .iter()
        .find(|b| b.board_id == board)
        .map(|b| Dest::node(b.node))
        .ok_or(HostError::UnknownBoard(board))
}

/// A register address as written: a number (decimal or `0x` hex) or a
/// name such as `status` or `axis2.enc_position`.
///
/// # Errors
/// [`AddressError::Register`] for a name that is not a register.
pub fn parse_address(text: &str) -> Result<u64, AddressError> {
    match crate::packet_json::parse_number(text) {
        Ok(n) => Ok(n),
        Err(_) => register_offset(text),
    }
}

/// Read `count` quadlets from `address` (one block read when more than
/// one), checked against the board's map first.
///
/// # Errors
/// [`RegisterError::Address`]; the read failed.
pub fn read_registers(
    port: &mut dyn Port,
    dest: Dest,
    address: u64,
    count: usize,
) -> Result<Vec<u32>, RegisterError> {
    check_address(address, count)?;
    if count <= 1 {
        return Ok(vec![port.read_quadlet(dest, address)?]);
    }
    let mut buf = vec![0u8; count * 4];
    port.read_block(dest, address, &mut buf)?;
    Ok(buf
        .chunks_exact(4)
        .map(|q| u32::from_be_bytes([q[0], q[1], q[2], q[3]]))
        .collect())
}

/// What became of a write.
#[derive(Debug)]
pub enum WriteOutcome {
    /// The port acknowledges writes, and this one was.
    Acknowledged,
    /// A broadcast: never acknowledged.
    Broadcast,
    /// The bridge answers no write: the same address read back (what a
    /// register reads back is shown, not judged: many do not read back
    /// what is written), or why that read failed.
    ReadBack(Result<u32, HostError>),
}

/// Write `values` at `address` (one block write when more than one),
/// checked against the board's map first. Over a port that acknowledges
/// no write, a read of the same address proves the node is there and
/// takes requests of this bus generation (the bridge drops stale ones
/// silently).
///
/// # Errors
/// [`RegisterError::Address`]; the write failed.
pub fn write_registers(
    port: &mut dyn Port,
    dest: Dest,
    address: u64,
    values: &[u32],
) -> Result<WriteOutcome, RegisterError> {
    check_address(address, values.len())?;
    match values {
        [one] => port.write_quadlet(dest, address, *one)?,
        many => {
            let bytes: Vec<u8> = many.iter().flat_map(|v| v.to_be_bytes()).collect();
            port.write_block(dest, address, &bytes)?;
        }
    }
    Ok(if port.acknowledges_writes() {
        WriteOutcome::Acknowledged
    } else if dest.is_broadcast() {
        WriteOutcome::Broadcast
    } else {
        WriteOutcome::ReadBack(port.read_quadlet(dest, address))
    })
}

impl WriteOutcome {
    /// What `firelink write` says of `count` quadlets written at
    /// `address` this way; `Err`: the read-back that was to confirm the
    /// write failed.
    ///
    /// # Errors
    /// [`WriteOutcome::ReadBack`] of an error: [`RegisterError::NotConfirmed`]
    /// with that error.
    pub fn line(self, count: usize, address: u64) -> Result<String, RegisterError> {
        Ok(match self {
            WriteOutcome::Acknowledged => {
                format!("wrote {count} quadlet(s) at {address:#06x} (acknowledged)")
            }
            WriteOutcome::Broadcast => format!(
                "sent {count} quadlet(s) to every board at {address:#06x} (broadcast writes \
                 are never acknowledged)"
            ),
            WriteOutcome::ReadBack(back) => format!(
                "sent {count} quadlet(s) at {address:#06x} (not acknowledged over UDP; the node \
                 answers, reading back {:08x})",
                back.map_err(|error| RegisterError::NotConfirmed { address, error })?
            ),
        })
    }
}

/// Why a register access was not made or failed.
#[derive(Debug, thiserror::Error)]
pub enum RegisterError {
    /// The address is outside the board's map.
    #[error(transparent)]
    Address(#[from] AddressError),
    /// The port failed.
    #[error(transparent)]
    Host(#[from] HostError),
    /// A write over the bridge could not be confirmed by reading back.
    #[error(
        "write to {address:#06x} not confirmed: the bridge acknowledges no write, and a read-back failed: {error}"
    )]
    NotConfirmed {
        /// The register.
        address: u64,
        /// Why the read-back failed.
        error: HostError,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_by_number_or_name() {
        assert_eq!(parse_address("status").unwrap(), 0);
        assert_eq!(parse_address("hw_version").unwrap(), 4);
        assert_eq!(parse_address("axis2.enc_position").unwrap(), 0x25);
        assert_eq!(parse_address("0x1000").unwrap(), 0x1000);
        assert!(parse_address("bogus").is_err());
        assert!(parse_address("axis2.bogus").is_err());
    }
}
