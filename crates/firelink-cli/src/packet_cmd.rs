//! `firelink packet decode|encode` and `firelink crc`: one packet as hex in,
//! one JSON object out, and back. The record and its codec are
//! [`firelink_host::packet_json`]; this file handles the hex text.

use firelink_host::packet_json as codec;
pub use firelink_host::packet_json::PacketJson;
use firelink_wire::crc::crc1394;

use crate::error::CliError;
use crate::hex::parse_hex;

/// Decode one complete packet (or, with `bridge`, one host->board datagram).
pub fn decode(hex: &str, bridge: bool) -> Result<PacketJson, CliError> {
    Ok(codec::decode(&parse_hex(hex)?, bridge)?)
}

/// Build the packet described by `json` and return its bytes.
pub fn encode(json: &PacketJson, bridge: bool) -> Result<Vec<u8>, CliError> {
    Ok(codec::encode(json, bridge)?)
}

/// The 1394 CRC of hex bytes.
pub fn crc(hex: &str) -> Result<u32, CliError> {
    Ok(crc1394(&parse_hex(hex)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex::to_hex;

    #[test]
    fn decode_then_encode_is_identity() {
        let hex = "ffc11540ffc2000000000007b2b02823";
        let json = decode(hex, false).unwrap();
        assert_eq!(json.tcode_name.as_deref(), Some("read_request_quadlet"));
        assert_eq!(json.header_crc_ok, Some(true));
        assert_eq!(to_hex(&encode(&json, false).unwrap()), hex);
    }

    #[test]
    fn encode_names_missing_fields() {
        let json = PacketJson {
            tcode_name: Some("write_request_quadlet".into()),
            destination_id: Some(0xffc0),
            offset: Some(0),
            ..Default::default()
        };
        let err = encode(&json, false).unwrap_err();
        assert_eq!(err.to_string(), "missing field quadlet_data");
    }
}
