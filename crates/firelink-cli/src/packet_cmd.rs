//! `firelink packet decode|encode` and `firelink crc`: one packet as hex in,
//! one JSON object out, and back.

use serde::{Deserialize, Deserializer, Serialize};

use firelink_wire::bridge::{ControlWord, split_host_datagram};
use firelink_wire::crc::crc1394;
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Tcode};

use crate::CliError;
use crate::hex::{parse_hex, to_hex};

/// One decoded packet, as printed by `packet decode` and read by `packet encode --json`.
/// Keys that do not apply to a packet's tcode are absent.
#[derive(Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PacketJson {
    /// Transaction code.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tcode: Option<u64>,
    /// Snake-case name of the tcode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tcode_name: Option<String>,
    /// Destination node ID.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub destination_id: Option<u64>,
    /// Source node ID.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_id: Option<u64>,
    /// Transaction label.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tl: Option<u64>,
    /// Retry code.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rt: Option<u64>,
    /// Priority.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pri: Option<u64>,
    /// Whether the header CRC matches (decode only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub header_crc_ok: Option<bool>,
    /// 48-bit destination offset (requests, cycle start).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset: Option<u64>,
    /// Header data quadlet (quadlet writes, quadlet read responses, cycle start).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quadlet_data: Option<u64>,
    /// Response code (responses).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rcode: Option<u64>,
    /// Payload length in bytes (block packets).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data_length: Option<u64>,
    /// Extended tcode (block packets).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extended_tcode: Option<u64>,
    /// Payload as hex (block packets with data).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<String>,
    /// Whether the data CRC matches (decode only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_crc_ok: Option<bool>,
    /// Bridge control word: handle on the Ethernet board itself.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_forward: Option<bool>,
    /// Bridge control word: the host's bus generation.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generation: Option<u64>,
    /// Total packet length in bytes (decode only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub packet_length: Option<usize>,
}

/// Accept JSON numbers or strings like "0xffc0" / "65472".
fn num_or_hex<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum NumOrText {
        Num(u64),
        Text(String),
    }
    match Option::<NumOrText>::deserialize(d)? {
        None => Ok(None),
        Some(NumOrText::Num(n)) => Ok(Some(n)),
        Some(NumOrText::Text(t)) => crate::parse_number(&t)
            .map(Some)
            .map_err(serde::de::Error::custom),
    }
}

/// Decode one complete packet (or, with `bridge`, one host->board datagram).
pub fn decode(hex: &str, bridge: bool) -> Result<PacketJson, CliError> {
    let bytes = parse_hex(hex)?;
    if bridge {
        let (control, packet) = split_host_datagram(&bytes)?;
        let mut json = describe(&packet)?;
        json.no_forward = Some(control.no_forward);
        json.generation = Some(u64::from(control.generation));
        return Ok(json);
    }
    let packet = Packet::new_checked(&bytes[..])?;
    let total = packet.total_len();
    if bytes.len() > total {
        return Err(firelink_wire::Error::TrailingBytes {
            what: packet.tcode().name(),
            extra: bytes.len() - total,
        }
        .into());
    }
    describe(&packet)
}

/// Describe a length-checked packet field by field.
pub fn describe(packet: &Packet<&[u8]>) -> Result<PacketJson, CliError> {
    let tcode = packet.tcode();
    let mut json = PacketJson {
        tcode: Some(u64::from(u8::from(tcode))),
        tcode_name: Some(tcode.name().to_string()),
        packet_length: Some(packet.total_len()),
        header_crc_ok: packet.header_crc_ok(),
        ..PacketJson::default()
    };
    match tcode {
        Tcode::Unknown(code) => return Err(firelink_wire::Error::UnknownTcode(code).into()),
        Tcode::Stream => {
            json.data_length = Some(u64::from(packet.data_length()));
        }
        Tcode::LinkInternal => {
            json.quadlet_data = Some(u64::from(packet.phy_body()));
        }
        _ => {
            json.destination_id = Some(u64::from(packet.destination_id().0));
            json.source_id = Some(u64::from(packet.source_id().0));
            json.tl = Some(u64::from(packet.tl()));
            json.rt = Some(u64::from(packet.rt()));
            json.pri = Some(u64::from(packet.pri()));
        }
    }
    if tcode.is_request() {
        json.offset = Some(packet.offset());
    }
    if tcode.is_response() {
        json.rcode = Some(u64::from(u8::from(packet.rcode())));
    }
    if matches!(
        tcode,
        Tcode::WriteQuadletRequest | Tcode::ReadQuadletResponse | Tcode::CycleStart
    ) {
        json.quadlet_data = Some(u64::from(packet.quadlet_data()));
    }
    if tcode.has_block_length() {
        json.data_length = Some(u64::from(packet.data_length()));
        json.extended_tcode = Some(u64::from(packet.extended_tcode()));
    }
    if tcode.has_data_block() {
        json.data = Some(to_hex(packet.payload()));
        json.data_crc_ok = packet.data_crc_ok();
    }
    Ok(json)
}

fn field<T: TryFrom<u64>>(value: Option<u64>, name: &'static str, max: u64) -> Result<T, CliError> {
    let v = value.ok_or(CliError::Missing(name))?;
    if v > max {
        return Err(CliError::Range {
            name,
            value: v,
            max,
        });
    }
    T::try_from(v).map_err(|_| CliError::Range {
        name,
        value: v,
        max,
    })
}

fn field_or<T: TryFrom<u64>>(
    value: Option<u64>,
    default: u64,
    name: &'static str,
    max: u64,
) -> Result<T, CliError> {
    field(Some(value.unwrap_or(default)), name, max)
}

/// Build the packet described by `json` and return its bytes (with the
/// bridge control word in front when `generation`/`no_forward` are set and
/// `bridge` is true).
pub fn encode(json: &PacketJson, bridge: bool) -> Result<Vec<u8>, CliError> {
    let tcode = match (&json.tcode, &json.tcode_name) {
        (Some(code), name) => {
            let t = Tcode::from(field::<u8>(Some(*code), "tcode", 0xF)?);
            if let Some(name) = name {
                if Tcode::from_name(name) != Some(t) {
                    return Err(CliError::Conflict(format!(
                        "tcode {code:#x} is {} but tcode_name says {name:?}",
                        t.name()
                    )));
                }
            }
            t
        }
        (None, Some(name)) => {
            Tcode::from_name(name).ok_or_else(|| CliError::UnknownTcodeName(name.clone()))?
        }
        (None, None) => return Err(CliError::Missing("tcode or tcode_name")),
    };
    let header = AsyncHeader {
        destination: NodeId(field(json.destination_id, "destination_id", 0xFFFF)?),
        source: NodeId(field_or(json.source_id, 0xFFD0, "source_id", 0xFFFF)?),
        tl: field_or(json.tl, 0, "tl", 0x3F)?,
        rt: field_or(json.rt, 0, "rt", 0x3)?,
        pri: field_or(json.pri, 0, "pri", 0xF)?,
    };
    let data_bytes = match &json.data {
        Some(hex) if hex.trim().is_empty() => Some(Vec::new()),
        Some(hex) => Some(parse_hex(hex)?),
        None => None,
    };
    if let (Some(len), Some(data)) = (json.data_length, &data_bytes) {
        if tcode.has_data_block() && len != data.len() as u64 {
            return Err(CliError::Conflict(format!(
                "data_length is {len} but data has {} bytes",
                data.len()
            )));
        }
    }
    let offset = || field::<u64>(json.offset, "offset", firelink_wire::packet::MAX_OFFSET);
    let rcode = || field_or::<u8>(json.rcode, 0, "rcode", 0xF).map(Rcode::from);
    let ext = || field_or::<u16>(json.extended_tcode, 0, "extended_tcode", 0xFFFF);
    let data = || data_bytes.as_deref().ok_or(CliError::Missing("data"));
    let repr = match tcode {
        Tcode::WriteQuadletRequest => PacketRepr::WriteQuadletRequest {
            header,
            offset: offset()?,
            data: field(json.quadlet_data, "quadlet_data", 0xFFFF_FFFF)?,
        },
        Tcode::WriteBlockRequest => PacketRepr::WriteBlockRequest {
            header,
            offset: offset()?,
            extended_tcode: ext()?,
            data: data()?,
        },
        Tcode::WriteResponse => PacketRepr::WriteResponse {
            header,
            rcode: rcode()?,
        },
        Tcode::ReadQuadletRequest => PacketRepr::ReadQuadletRequest {
            header,
            offset: offset()?,
        },
        Tcode::ReadBlockRequest => PacketRepr::ReadBlockRequest {
            header,
            offset: offset()?,
            data_length: field(json.data_length, "data_length", 0xFFFF)?,
            extended_tcode: ext()?,
        },
        Tcode::ReadQuadletResponse => PacketRepr::ReadQuadletResponse {
            header,
            rcode: rcode()?,
            data: field(json.quadlet_data, "quadlet_data", 0xFFFF_FFFF)?,
        },
        Tcode::ReadBlockResponse => PacketRepr::ReadBlockResponse {
            header,
            rcode: rcode()?,
            extended_tcode: ext()?,
            data: data()?,
        },
        other => return Err(CliError::CannotEncode(other.name())),
    };
    let mut out = vec![0u8; repr.buffer_len()];
    repr.emit(&mut out)?;
    if bridge {
        let control = ControlWord {
            no_forward: json.no_forward.unwrap_or(false),
            generation: field_or(json.generation, 0, "generation", 0xFF)?,
        };
        let mut framed = control.to_bytes().to_vec();
        framed.extend_from_slice(&out);
        return Ok(framed);
    }
    Ok(out)
}

/// The 1394 CRC of hex bytes.
pub fn crc(hex: &str) -> Result<u32, CliError> {
    Ok(crc1394(&parse_hex(hex)?))
}

#[cfg(test)]
mod tests {
    use super::*;

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
