//! Packets as field-by-field records ([`PacketJson`]): what `firelink
//! packet decode` prints and `packet encode --json` reads, and what the
//! Python package's `decode_packet`/`encode_packet` use. Decoding checks
//! lengths and CRCs and never panics; encoding names the missing or
//! out-of-range field.

use serde::{Deserialize, Deserializer, Serialize};

use firelink_wire::bridge::{ControlWord, split_host_datagram};
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Tcode};

/// Why a packet record could not be decoded or encoded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PacketJsonError {
    /// The wire layer rejected the bytes or fields.
    #[error(transparent)]
    Wire(#[from] firelink_wire::Error),
    /// A required field is absent.
    #[error("missing field {0}")]
    Missing(&'static str),
    /// A field is too large.
    #[error("{name} = {value:#x} is out of range (maximum {max:#x})")]
    Range {
        /// Field.
        name: &'static str,
        /// Value given.
        value: u64,
        /// Largest allowed.
        max: u64,
    },
    /// No tcode has that name.
    #[error("unknown tcode name {0:?}")]
    UnknownTcodeName(String),
    /// Two fields disagree.
    #[error("{0}")]
    Conflict(String),
    /// The tcode is recognised but not built by `encode`.
    #[error("cannot encode {0} packets: only quadlet/block read/write requests and responses")]
    CannotEncode(&'static str),
    /// The payload's hex text is not hex.
    #[error("data: {0}")]
    Hex(String),
}

type Result<T> = core::result::Result<T, PacketJsonError>;

/// One decoded packet, as printed by `packet decode` and read by `packet encode --json`.
/// Keys that do not apply to a packet's tcode are absent. Behind the `clap`
/// feature, also `packet encode`'s flags for the header fields and the
/// payload (clap's `Args`; the tcode, which takes a number or a name, and
/// the bridge control word are the front end's).
#[derive(Debug, Default, Clone, Serialize, Deserialize, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct PacketJson {
    /// Transaction code.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub tcode: Option<u64>,
    /// Snake-case name of the tcode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub tcode_name: Option<String>,
    /// Destination node ID.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long = "destination-id", value_parser = parse_number, help = "Destination node ID (e.g. 0xffc0)"))]
    pub destination_id: Option<u64>,
    /// Source node ID.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long = "source-id", value_parser = parse_number, help = "Source node ID (default 0xffd0)"))]
    pub source_id: Option<u64>,
    /// Transaction label.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long, value_parser = parse_number, help = "Transaction label 0..63"))]
    pub tl: Option<u64>,
    /// Retry code.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long, value_parser = parse_number, help = "Retry code 0..3"))]
    pub rt: Option<u64>,
    /// Priority.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long, value_parser = parse_number, help = "Priority 0..15"))]
    pub pri: Option<u64>,
    /// Whether the header CRC matches (decode only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub header_crc_ok: Option<bool>,
    /// 48-bit destination offset (requests, cycle start).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long, value_parser = parse_number, help = "48-bit destination offset"))]
    pub offset: Option<u64>,
    /// Header data quadlet (quadlet writes, quadlet read responses, cycle start).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long = "quadlet-data", value_parser = parse_number, help = "Data quadlet of quadlet writes / quadlet read responses"))]
    pub quadlet_data: Option<u64>,
    /// Response code (responses).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long, value_parser = parse_number, help = "Response code"))]
    pub rcode: Option<u64>,
    /// Payload length in bytes (block packets).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long = "data-length", value_parser = parse_number, help = "Bytes requested by a block read"))]
    pub data_length: Option<u64>,
    /// Extended tcode (block packets).
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(long = "extended-tcode", value_parser = parse_number, help = "Extended tcode"))]
    pub extended_tcode: Option<u64>,
    /// Payload as hex (block packets with data).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(
        feature = "clap",
        arg(long, help = "Payload of block writes / block read responses, as hex")
    )]
    pub data: Option<String>,
    /// Whether the data CRC matches (decode only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub data_crc_ok: Option<bool>,
    /// Bridge control word: handle on the Ethernet board itself.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub no_forward: Option<bool>,
    /// Bridge control word: the host's bus generation.
    #[serde(default, deserialize_with = "num_or_hex")]
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub generation: Option<u64>,
    /// Total packet length in bytes (decode only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "clap", arg(skip))]
    pub packet_length: Option<usize>,
}

/// A number as text: decimal, or hexadecimal with `0x`; `_` separators allowed.
pub fn parse_number(s: &str) -> core::result::Result<u64, String> {
    let t = s.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => u64::from_str_radix(&h.replace('_', ""), 16),
        None => t.replace('_', "").parse(),
    };
    parsed.map_err(|_| format!("not a number: {s:?}"))
}

/// Accept JSON numbers or strings like "0xffc0" / "65472".
fn num_or_hex<'de, D: Deserializer<'de>>(d: D) -> core::result::Result<Option<u64>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum NumOrText {
        Num(u64),
        Text(String),
    }
    match Option::<NumOrText>::deserialize(d)? {
        None => Ok(None),
        Some(NumOrText::Num(n)) => Ok(Some(n)),
        Some(NumOrText::Text(t)) => parse_number(&t).map(Some).map_err(serde::de::Error::custom),
    }
}

/// Decode one complete packet (or, with `bridge`, one host->board datagram:
/// the bridge control word, then the packet). Trailing bytes are an error.
pub fn decode(bytes: &[u8], bridge: bool) -> Result<PacketJson> {
    if bridge {
        let (control, packet) = split_host_datagram(bytes)?;
        let mut json = describe(&packet)?;
        json.no_forward = Some(control.no_forward);
        json.generation = Some(u64::from(control.generation));
        return Ok(json);
    }
    let packet = Packet::new_checked(bytes)?;
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
pub fn describe(packet: &Packet<&[u8]>) -> Result<PacketJson> {
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
        json.data = Some(crate::hex::to_hex(packet.payload()));
        json.data_crc_ok = packet.data_crc_ok();
    }
    Ok(json)
}

fn field<T: TryFrom<u64>>(value: Option<u64>, name: &'static str, max: u64) -> Result<T> {
    let v = value.ok_or(PacketJsonError::Missing(name))?;
    if v > max {
        return Err(PacketJsonError::Range {
            name,
            value: v,
            max,
        });
    }
    T::try_from(v).map_err(|_| PacketJsonError::Range {
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
) -> Result<T> {
    field(Some(value.unwrap_or(default)), name, max)
}

/// Build the packet described by `json` and return its bytes (with the
/// bridge control word in front when `generation`/`no_forward` are set and
/// `bridge` is true).
pub fn encode(json: &PacketJson, bridge: bool) -> Result<Vec<u8>> {
    let tcode = match (&json.tcode, &json.tcode_name) {
        (Some(code), name) => {
            let t = Tcode::from(field::<u8>(Some(*code), "tcode", 0xF)?);
            if let Some(name) = name {
                if Tcode::from_name(name) != Some(t) {
                    return Err(PacketJsonError::Conflict(format!(
                        "tcode {code:#x} is {} but tcode_name says {name:?}",
                        t.name()
                    )));
                }
            }
            t
        }
        (None, Some(name)) => {
            Tcode::from_name(name).ok_or_else(|| PacketJsonError::UnknownTcodeName(name.clone()))?
        }
        (None, None) => return Err(PacketJsonError::Missing("tcode or tcode_name")),
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
        // The tree's one hex reader, as `packet decode` reads its argument.
        Some(hex) => {
            Some(crate::hex::parse_hex(hex).map_err(|e| PacketJsonError::Hex(e.to_string()))?)
        }
        None => None,
    };
    if let (Some(len), Some(data)) = (json.data_length, &data_bytes) {
        if tcode.has_data_block() && len != data.len() as u64 {
            return Err(PacketJsonError::Conflict(format!(
                "data_length is {len} but data has {} bytes",
                data.len()
            )));
        }
    }
    let offset = || field::<u64>(json.offset, "offset", firelink_wire::packet::MAX_OFFSET);
    let rcode = || field_or::<u8>(json.rcode, 0, "rcode", 0xF).map(Rcode::from);
    let ext = || field_or::<u16>(json.extended_tcode, 0, "extended_tcode", 0xFFFF);
    let data = || {
        data_bytes
            .as_deref()
            .ok_or(PacketJsonError::Missing("data"))
    };
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
        other => return Err(PacketJsonError::CannotEncode(other.name())),
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
