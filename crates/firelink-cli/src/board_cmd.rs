//! `firelink scan`, `info`, `read` and `write`: discovery and register
//! access ([`firelink_host::qla::board_access`]).

use std::io::Write;

use clap::Args;

use firelink_host::qla::board_access::{self, ScanSummary, parse_address, scan_text};
use firelink_host::qla::register_address::check_address;
use firelink_host::qla::scan::scan;
use firelink_host::{Dest, Port};

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

/// `firelink scan`.
pub fn run_scan(args: &ScanArgs, out: &mut impl Write) -> Result<(), CliError> {
    let mut port = open_port(&args.port, "firelink scan")?;
    let report = scan(port.as_mut())?;
    if args.json {
        writeln!(
            out,
            "{}",
            serde_json::to_string(&ScanSummary::new(port.name(), &report))?
        )?;
        return Ok(());
    }
    write!(out, "{}", scan_text(port.name(), &report))?;
    Ok(())
}

/// `firelink info`: identity and live state of every board.
pub fn run_info(args: &ScanArgs, out: &mut impl Write) -> Result<(), CliError> {
    let mut port = open_port(&args.port, "firelink info")?;
    let report = scan(port.as_mut())?;
    let mut all = Vec::new();
    for b in &report.boards {
        // As a JSON value (its keys sorted), as `info` has always printed it.
        all.push(serde_json::to_value(board_access::read_state(
            port.as_mut(),
            b,
        )?)?);
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
        let dest = board_access::destination(port.as_mut(), self.board, self.node)?;
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

/// A register address on the command line (clap): a number or a name, in
/// the board's map.
fn address_arg(text: &str) -> Result<u64, String> {
    let address = parse_address(text).map_err(|e| e.to_string())?;
    check_address(address, 1).map_err(|e| e.to_string())?;
    Ok(address)
}

/// `firelink read`.
pub fn run_read(args: &ReadArgs, out: &mut impl Write) -> Result<(), CliError> {
    let address = args.address;
    check_address(address, args.count)?;
    let (mut port, dest) = args.target.open()?;
    let values = board_access::read_registers(port.as_mut(), dest, address, args.count)?;
    for (i, v) in values.iter().enumerate() {
        writeln!(out, "{:#06x}: {v:08x}", address + i as u64)?;
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
    let outcome = board_access::write_registers(port.as_mut(), dest, address, &values)?;
    writeln!(out, "{}", outcome.line(values.len(), address)?)?;
    Ok(())
}
