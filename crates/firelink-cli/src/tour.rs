//! `firelink tour`: every packet of one broadcast I/O cycle (seed 000's
//! protocol, firmware Rev 8, QLA1 boards), built with the wire layer, then
//! decoded again, with its size, CRCs and its raw time on the wire at S400
//! ([`firelink_host::qla::tour`]).

use std::io::Write;

use clap::Args;

use crate::error::CliError;

/// Options of `firelink tour`.
#[derive(Args, Clone, Debug)]
pub struct TourArgs {
    /// Number of boards on the bus (1..=16).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=16))]
    pub boards: u8,
}

/// Print the cycle's packets as a table.
pub fn run(args: &TourArgs, out: &mut impl Write) -> Result<(), CliError> {
    write!(out, "{}", firelink_host::qla::tour::build(args.boards)?)?;
    Ok(())
}
