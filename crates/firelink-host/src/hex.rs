//! Hex text <-> bytes, as people type packets and payloads: whitespace,
//! `_` and `:` separators and `0x` prefixes allowed; every refusal names
//! what was wrong. (Here rather than in `firelink-wire`, which allocates
//! nothing.)

/// Why a hex argument could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HexError {
    /// No digits at all.
    #[error("no hex digits given")]
    Empty,
    /// An odd number of digits cannot form whole bytes.
    #[error("odd number of hex digits ({0}): bytes need two digits each")]
    OddLength(usize),
    /// A character that is not a hex digit.
    #[error("invalid hex digit {ch:?} at position {position}")]
    InvalidDigit {
        /// The character.
        ch: char,
        /// Its 0-based index among the non-whitespace characters.
        position: usize,
    },
}

/// Parse hex digits, ignoring whitespace, `_`, `:` separators and `0x`
/// prefixes on each whitespace-separated word.
pub fn parse_hex(text: &str) -> Result<Vec<u8>, HexError> {
    let mut digits = Vec::new();
    for word in text.split_whitespace() {
        let word = word
            .strip_prefix("0x")
            .or_else(|| word.strip_prefix("0X"))
            .unwrap_or(word);
        digits.extend(word.chars().filter(|c| *c != '_' && *c != ':'));
    }
    if digits.is_empty() {
        return Err(HexError::Empty);
    }
    let mut values = Vec::with_capacity(digits.len());
    for (position, ch) in digits.iter().enumerate() {
        let v = ch
            .to_digit(16)
            .ok_or(HexError::InvalidDigit { ch: *ch, position })?;
        values.push(v as u8);
    }
    if values.len() % 2 != 0 {
        return Err(HexError::OddLength(values.len()));
    }
    Ok(values.chunks(2).map(|p| (p[0] << 4) | p[1]).collect())
}

/// Lower-case hex without separators.
pub fn to_hex(bytes: &[u8]) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_separators_and_prefixes() {
        assert_eq!(
            parse_hex("0xffc1 1540").unwrap(),
            vec![0xff, 0xc1, 0x15, 0x40]
        );
        assert_eq!(
            parse_hex("ff:c1_15 40\n").unwrap(),
            vec![0xff, 0xc1, 0x15, 0x40]
        );
        assert_eq!(to_hex(&[0, 0xab]), "00ab");
    }

    #[test]
    fn names_the_problem() {
        assert_eq!(parse_hex("abc"), Err(HexError::OddLength(3)));
        assert_eq!(
            parse_hex("ab zz"),
            Err(HexError::InvalidDigit {
                ch: 'z',
                position: 2
            })
        );
        assert_eq!(parse_hex("  "), Err(HexError::Empty));
    }

    #[test]
    fn packets_typed_as_hex_decode_and_encode_back() {
        use crate::packet_json::{PacketJson, decode, encode};
        let hex = "ffc11540ffc2000000000007b2b02823";
        let json = decode(&parse_hex(hex).unwrap(), false).unwrap();
        assert_eq!(json.tcode_name.as_deref(), Some("read_request_quadlet"));
        assert_eq!(json.header_crc_ok, Some(true));
        assert_eq!(to_hex(&encode(&json, false).unwrap()), hex);
        let json = PacketJson {
            tcode_name: Some("write_request_quadlet".into()),
            destination_id: Some(0xffc0),
            offset: Some(0),
            ..Default::default()
        };
        let err = encode(&json, false).unwrap_err();
        assert_eq!(err.to_string(), "missing field quadlet_data");
    }

    #[test]
    fn a_packets_data_is_read_by_the_same_hex_rules() {
        use crate::packet_json::{PacketJson, encode};
        let block = |data: &str| PacketJson {
            tcode_name: Some("write_request_block".into()),
            destination_id: Some(0xffc0),
            offset: Some(0),
            data: Some(data.into()),
            ..Default::default()
        };
        // A sign is not a hex digit (a byte parser of its own took `+f`).
        let err = encode(&block("+f00"), false).unwrap_err();
        assert_eq!(err.to_string(), "data: invalid hex digit '+' at position 0");
        let err = encode(&block("0f 0"), false).unwrap_err();
        assert!(err.to_string().contains("odd number"), "{err}");
        let with_separators = encode(&block("0x0f:00_01 02"), false).unwrap();
        assert_eq!(with_separators, encode(&block("0f000102"), false).unwrap());
    }
}
