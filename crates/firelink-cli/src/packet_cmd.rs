//! `firelink packet decode|encode` and `firelink crc`: one packet as hex in,
//! one JSON object out, and back. The record and its codec are
//! [`firelink_host::packet_json`]; this file handles the flags and the hex
//! text.

use std::io::Write;

use clap::{Args, Subcommand};

use firelink_host::hex::{parse_hex, to_hex};
use firelink_host::packet_json::{self as codec, PacketJson};
use firelink_wire::crc::crc1394;

use crate::args::parse_number;
use crate::error::CliError;

/// `firelink packet`'s two commands.
#[derive(Subcommand)]
pub enum PacketCommand {
    /// Decode one complete packet given as hex; print one JSON object.
    Decode {
        /// The input is a host->board UDP payload: control word, then the packet.
        #[arg(long)]
        bridge: bool,
        /// Packet bytes as hex (whitespace allowed).
        #[arg(required = true, num_args = 1..)]
        hex: Vec<String>,
    },
    /// Build a packet from flags or JSON; print its hex with correct CRCs.
    Encode(Box<EncodeArgs>),
}

/// Options of `firelink packet encode`.
#[derive(Args)]
pub struct EncodeArgs {
    /// The packet as a JSON object with the keys `packet decode` prints.
    #[arg(long, conflicts_with_all = ["tcode", "destination_id"])]
    json: Option<String>,
    /// Transaction code: a number or a name such as read_request_block.
    #[arg(long)]
    tcode: Option<String>,
    /// The header fields and the payload.
    #[command(flatten)]
    fields: PacketJson,
    /// Prepend the Ethernet bridge control word.
    #[arg(long)]
    bridge: bool,
    /// Bus generation for the bridge control word.
    #[arg(long, value_parser = parse_number, requires = "bridge")]
    generation: Option<u64>,
    /// Set the bridge no-forward bit.
    #[arg(long = "no-forward", requires = "bridge")]
    no_forward: bool,
}

/// `firelink packet decode|encode`: one JSON object, or the packet's hex.
pub fn run(command: &PacketCommand, out: &mut impl Write) -> Result<(), CliError> {
    match command {
        PacketCommand::Decode { bridge, hex } => {
            let json = codec::decode(&parse_hex(&hex.join(" "))?, *bridge)?;
            writeln!(out, "{}", serde_json::to_string(&json)?)?;
        }
        PacketCommand::Encode(args) => {
            let json = match &args.json {
                Some(text) => serde_json::from_str(text)?,
                None => args.record()?,
            };
            writeln!(out, "{}", to_hex(&codec::encode(&json, args.bridge)?))?;
        }
    }
    Ok(())
}

impl EncodeArgs {
    /// The packet record the flags describe.
    fn record(&self) -> Result<PacketJson, CliError> {
        let tcode = self.tcode.as_deref().ok_or(CliError::Missing("--tcode"))?;
        let (tcode, tcode_name) = match parse_number(tcode) {
            Ok(n) => (Some(n), None),
            Err(_) => (None, Some(tcode.to_string())),
        };
        Ok(PacketJson {
            tcode,
            tcode_name,
            no_forward: Some(self.no_forward),
            generation: self.generation,
            ..self.fields.clone()
        })
    }
}

/// The 1394 CRC of hex bytes.
pub fn crc(hex: &str) -> Result<u32, CliError> {
    Ok(crc1394(&parse_hex(hex)?))
}
