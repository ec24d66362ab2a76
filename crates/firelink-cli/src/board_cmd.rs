//! `firelink scan`, `info`, `read` and `write`: discovery and register access.

use std::io::Write;

use clap::Args;
use serde::Serialize;

use firelink_host::board::BoardInfo;
use firelink_host::register_address::{self, register_offset};
use firelink_host::scan::{ScanReport, mask_boards, scan};
use firelink_host::{Dest, Port};
use firelink_wire::qla::address::{AxisRegister, BoardRegister, Register};
use firelink_wire::qla::registers::{StatusRead, Temperature, Watchdog};

use crate::error::CliError;
use crate::ports::{PortArgs, open_port};

/// Options of `firelink scan` and `firelink info`.
#[derive(Args, Debug)]
pub struct ScanArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct BoardJson {
    board_id: u8,
    node: u8,
    hardware: String,
    firmware: u32,
    fpga: u8,
    git: String,
}

#[derive(Serialize)]
struct ScanJson {
    port: String,
    boards: Vec<BoardJson>,
    protocol: &'static str,
    protocol_reason: &'static str,
    /// Broadcast protocol: the board IDs each query of a cycle selects.
    broadcast_groups: Vec<Vec<u8>>,
    silent_nodes: Vec<u8>,
    unsupported_nodes: Vec<u8>,
    bridge_board: Option<u8>,
    generation: u32,
}

fn board_json(b: &BoardInfo) -> BoardJson {
    BoardJson {
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

fn scan_json(port: &str, r: &ScanReport) -> ScanJson {
    ScanJson {
        port: port.to_string(),
        boards: r.boards.iter().map(board_json).collect(),
        protocol: r.protocol.name(),
        protocol_reason: r.protocol_reason,
        broadcast_groups: r
            .broadcast_groups
            .iter()
            .map(|&mask| (0..16u8).filter(|id| mask & (1 << id) != 0).collect())
            .collect(),
        silent_nodes: r.silent_nodes.clone(),
        unsupported_nodes: r.unsupported.iter().map(|u| u.node).collect(),
        bridge_board: r.bridge_board,
        generation: r.generation,
    }
}

/// `firelink scan`.
pub fn run_scan(args: &ScanArgs, out: &mut impl Write) -> Result<(), CliError> {
    let mut port = open_port(&args.port, "firelink scan")?;
    let report = scan(port.as_mut())?;
    if args.json {
        writeln!(
            out,
            "{}",
            serde_json::to_string(&scan_json(port.name(), &report))?
        )?;
        return Ok(());
    }
    writeln!(out, "{} board(s) on {}:", report.boards.len(), port.name())?;
    writeln!(out, "  board  node  hardware  firmware  fpga  git")?;
    for b in &report.boards {
        let j = board_json(b);
        writeln!(
            out,
            "  {:>5}  {:>4}  {:<8}  {:>8}  V{}    {}",
            j.board_id, j.node, j.hardware, j.firmware, j.fpga, j.git
        )?;
    }
    if let Some(bridge) = report.bridge_board {
        writeln!(out, "Ethernet bridge: board {bridge}")?;
    }
    if !report.unsupported.is_empty() {
        for u in &report.unsupported {
            writeln!(
                out,
                "node {}: unsupported hardware {} firmware {}",
                u.node,
                u.hardware.name(),
                u.firmware
            )?;
        }
    }
    writeln!(
        out,
        "protocol: {} ({})",
        report.protocol_label(),
        report.protocol_reason
    )?;
    if report.broadcast_groups.len() > 1 {
        let groups: Vec<String> = report
            .broadcast_groups
            .iter()
            .map(|&m| format!("boards {}", mask_boards(m)))
            .collect();
        writeln!(out, "broadcast groups: {}", groups.join(" | "))?;
    }
    Ok(())
}

/// `firelink info`: identity and live state of every board.
pub fn run_info(args: &ScanArgs, out: &mut impl Write) -> Result<(), CliError> {
    let mut port = open_port(&args.port, "firelink info")?;
    let report = scan(port.as_mut())?;
    let mut all = Vec::new();
    for b in &report.boards {
        let dest = Dest::node(b.node);
        let read = |port: &mut dyn Port, r: BoardRegister| -> Result<u32, CliError> {
            Ok(port.read_quadlet(dest, Register::board(r).offset()?)?)
        };
        let status = StatusRead(read(port.as_mut(), BoardRegister::Status)?);
        let watchdog = Watchdog(read(port.as_mut(), BoardRegister::Watchdog)?);
        let temperature = Temperature(read(port.as_mut(), BoardRegister::Temperature)?);
        let mut axes = Vec::new();
        for axis in 1..=b.layout.motors() as u8 {
            let enc = port.read_quadlet(
                dest,
                Register::axis(axis, AxisRegister::EncPosition).offset()?,
            )?;
            let adc = port.read_quadlet(dest, Register::axis(axis, AxisRegister::Adc).offset()?)?;
            axes.push(serde_json::json!({
                "axis": axis,
                "encoder_counts": firelink_wire::qla::registers::counts_from_offset_binary(enc),
                "pot_bits": adc >> 16,
                "current_bits": adc & 0xFFFF,
            }));
        }
        // The QLA's sensors read 0.5 degree C per bit (0xFF: out of range).
        let celsius = [temperature.upper(), temperature.lower()]
            .map(|b| (b != 0xFF).then_some(f64::from(b) / 2.0));
        let entry = serde_json::json!({
            "board": board_json(b),
            "status": format!("{:#010x}", status.raw()),
            "power": status.motor_power_enabled(),
            "relay": status.relay_on(),
            "supply_good": status.motor_supply_good(),
            "watchdog_expired": status.watchdog_timeout(),
            "amp_enabled_mask": status.amp_enabled(),
            "watchdog_period_ms": watchdog.period().as_secs_f64() * 1e3,
            "temperature_c": celsius,
            "axes": axes,
        });
        all.push(entry);
    }
    if args.json {
        writeln!(
            out,
            "{}",
            serde_json::json!({"port": port.name(), "boards": all})
        )?;
    } else {
        for e in &all {
            writeln!(out, "{}", serde_json::to_string_pretty(e)?)?;
        }
    }
    Ok(())
}

/// Which board a register access goes to, and through which port.
#[derive(Args, Debug)]
pub struct TargetArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Board ID (rotary switch, 0..=15); mapped to its node by a scan.
    #[arg(long, default_value_t = 0, conflicts_with = "node", value_parser = crate::args::board_id)]
    pub board: u8,
    /// Physical node ID (0..=62, 63 = broadcast), without a scan.
    #[arg(long, value_parser = crate::args::node_id)]
    pub node: Option<u8>,
}

impl TargetArgs {
    /// The port, opened, and the destination on it.
    fn open(&self) -> Result<(Box<dyn Port>, Dest), CliError> {
        let mut port = open_port(&self.port, "firelink read/write")?;
        let dest = resolve(port.as_mut(), self.board, self.node)?;
        Ok((port, dest))
    }
}

/// Options of `firelink read`.
#[derive(Args, Debug)]
pub struct ReadArgs {
    #[command(flatten)]
    pub target: TargetArgs,
    /// Register address: a number (0x10 = axis 1 ADC; the board's map is
    /// 0x0000..=0xffff) or a name such as status, hw_version,
    /// axis2.enc_position.
    #[arg(value_parser = address_arg)]
    pub address: u64,
    /// Quadlets to read, 1..=512 (more than 1 uses one block read).
    #[arg(long, default_value_t = 1, value_parser = crate::args::quadlets)]
    pub count: usize,
}

/// Options of `firelink write`.
#[derive(Args, Debug)]
pub struct WriteArgs {
    #[command(flatten)]
    pub target: TargetArgs,
    /// Register address (number or name, as for `read`).
    #[arg(value_parser = address_arg)]
    pub address: u64,
    /// Quadlets to write (more than one uses one block write).
    #[arg(required = true, num_args = 1.., value_parser = crate::args::parse_number)]
    pub values: Vec<u64>,
}

/// Parse a register address: a number or `name` / `axisN.name`.
pub fn parse_address(text: &str) -> Result<u64, CliError> {
    if let Ok(n) = crate::args::parse_number(text) {
        return Ok(n);
    }
    Ok(register_offset(text)?)
}

/// A register address on the command line (clap): a number or a name, in
/// the board's map.
fn address_arg(text: &str) -> Result<u64, String> {
    let address = parse_address(text).map_err(|e| e.to_string())?;
    check_address(address, 1).map_err(|e| e.to_string())?;
    Ok(address)
}

/// `quadlets` quadlets from `address` must lie in the board's map.
///
/// # Errors
/// [`CliError::Address`] saying which limit and what it would have read.
pub fn check_address(address: u64, quadlets: usize) -> Result<(), CliError> {
    Ok(register_address::check_address(address, quadlets)?)
}

fn resolve(port: &mut dyn Port, board: u8, node: Option<u8>) -> Result<Dest, CliError> {
    if let Some(node) = node {
        return Ok(Dest::node(node));
    }
    let report = scan(port)?;
    report
        .boards
        .iter()
        .find(|b| b.board_id == board)
        .map(|b| Dest::node(b.node))
        .ok_or(CliError::Host(firelink_host::HostError::UnknownBoard(
            board,
        )))
}

/// `firelink read`.
pub fn run_read(args: &ReadArgs, out: &mut impl Write) -> Result<(), CliError> {
    let address = args.address;
    check_address(address, args.count)?;
    let (mut port, dest) = args.target.open()?;
    if args.count <= 1 {
        let v = port.read_quadlet(dest, address)?;
        writeln!(out, "{address:#06x}: {v:08x}")?;
    } else {
        let mut buf = vec![0u8; args.count * 4];
        port.read_block(dest, address, &mut buf)?;
        for (i, q) in buf.chunks_exact(4).enumerate() {
            let v = u32::from_be_bytes([q[0], q[1], q[2], q[3]]);
            writeln!(out, "{:#06x}: {v:08x}", address + i as u64)?;
        }
    }
    Ok(())
}

/// `firelink write`.
pub fn run_write(args: &WriteArgs, out: &mut impl Write) -> Result<(), CliError> {
    let address = args.address;
    check_address(address, args.values.len())?;
    let mut values = Vec::with_capacity(args.values.len());
    for v in &args.values {
        values.push(u32::try_from(*v).map_err(|_| CliError::Range {
            name: "value",
            value: *v,
            max: u64::from(u32::MAX),
        })?);
    }
    let (mut port, dest) = args.target.open()?;
    match values.as_slice() {
        [one] => port.write_quadlet(dest, address, *one)?,
        many => {
            let bytes: Vec<u8> = many.iter().flat_map(|v| v.to_be_bytes()).collect();
            port.write_block(dest, address, &bytes)?;
        }
    }
    let n = values.len();
    if port.acknowledges_writes() {
        writeln!(out, "wrote {n} quadlet(s) at {address:#06x} (acknowledged)")?;
        return Ok(());
    }
    if dest.is_broadcast() {
        writeln!(
            out,
            "sent {n} quadlet(s) to every board at {address:#06x} (broadcast writes are never acknowledged)"
        )?;
        return Ok(());
    }
    // The bridge answers no write. A read of the same address proves the
    // node is there and takes requests of this bus generation (the bridge
    // drops stale ones silently); what it reads back is shown, not judged:
    // many registers do not read back what is written.
    let back = port
        .read_quadlet(dest, address)
        .map_err(|error| CliError::WriteNotConfirmed { address, error })?;
    writeln!(
        out,
        "sent {n} quadlet(s) at {address:#06x} (not acknowledged over UDP; the node answers, \
         reading back {back:08x})"
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn register_names() {
        assert_eq!(parse_address("status").unwrap(), 0);
        assert_eq!(parse_address("hw_version").unwrap(), 4);
        assert_eq!(parse_address("axis2.enc_position").unwrap(), 0x25);
        assert_eq!(parse_address("0x1000").unwrap(), 0x1000);
        assert!(parse_address("bogus").is_err());
        assert!(parse_address("axis2.bogus").is_err());
    }
}
