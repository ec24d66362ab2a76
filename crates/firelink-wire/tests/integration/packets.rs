//! Packet codec tests: published vectors, one known packet per tcode decoded
//! field by field and encoded back, and property tests.

use firelink_wire::Error;
use firelink_wire::bridge::{
    ControlWord, EXTRA_DATA_LEN, ExtraData, split_board_datagram, split_host_datagram,
};
use firelink_wire::crc::{crc1394, crc1394_bitwise, crc1394_quadlets};
use firelink_wire::packet::{
    AsyncHeader, MAX_OFFSET, NodeId, Packet, PacketRepr, Rcode, Speed, Tcode,
};
use firelink_wire::phy::PhyPacket;
use proptest::prelude::*;
use serde_json::Value;

fn hex_quadlet(v: &Value) -> u32 {
    u32::from_str_radix(v.as_str().expect("hex string"), 16).expect("hex quadlet")
}

fn quadlet_bytes(q: &[u32]) -> Vec<u8> {
    q.iter().flat_map(|v| v.to_be_bytes()).collect()
}

fn load(name: &str) -> Value {
    let path = format!("{}/tests/vectors/{name}", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).expect("vector file")).expect("json")
}

#[test]
fn crc_vectors() {
    let v = load("crc1394.json");
    let check = &v["check"];
    let ascii = check["ascii"].as_str().unwrap();
    assert_eq!(crc1394(ascii.as_bytes()), hex_quadlet(&check["crc"]));
    let vectors = v["vectors"].as_array().unwrap();
    assert!(vectors.len() >= 4);
    for vector in vectors {
        let quadlets: Vec<u32> = vector["quadlets"]
            .as_array()
            .unwrap()
            .iter()
            .map(hex_quadlet)
            .collect();
        let expected = hex_quadlet(&vector["crc"]);
        let what = vector["what"].as_str().unwrap();
        assert_eq!(crc1394_quadlets(&quadlets), expected, "{what}");
        assert_eq!(crc1394(&quadlet_bytes(&quadlets)), expected, "{what}");
        assert_eq!(
            crc1394_bitwise(&quadlet_bytes(&quadlets)),
            expected,
            "{what}"
        );
    }
}

/// Derived from the spec (`ieee1394.md`, CRC): the CRC of an empty input is
/// the complement of the initial value, and appending a message's own CRC
/// (big-endian) always leaves the CRC-32/BZIP2 residue 0xC704DD7B in the
/// register, so the final CRC is its complement.
#[test]
fn crc_derived_vectors() {
    assert_eq!(crc1394(&[]), 0);
    for msg in [&b"a"[..], b"123456789", &[0u8; 64], &[0xFF; 7]] {
        let crc = crc1394(msg);
        let mut with = msg.to_vec();
        with.extend_from_slice(&crc.to_be_bytes());
        assert_eq!(!crc1394(&with), 0xC704_DD7B, "{msg:?}");
    }
}

#[test]
fn header_vectors_decode_every_field_and_encode_back() {
    let v = load("headers.json");
    for vector in v["vectors"].as_array().unwrap() {
        let what = vector["what"].as_str().unwrap();
        let mut quadlets: Vec<u32> = vector["header_quadlets"]
            .as_array()
            .unwrap()
            .iter()
            .map(hex_quadlet)
            .collect();
        let crc = hex_quadlet(&vector["header_crc"]);
        assert_eq!(crc1394_quadlets(&quadlets), crc, "{what}: header CRC");
        quadlets.push(crc);
        let fields = &vector["fields"];
        let tcode = Tcode::from(fields["tcode"].as_u64().unwrap() as u8);
        // Block packets need their data block for a complete packet: append
        // `data_length` bytes of a counting pattern with its data CRC.
        let data_length = fields
            .get("data_length")
            .and_then(Value::as_u64)
            .unwrap_or(0) as usize;
        let mut bytes = quadlet_bytes(&quadlets);
        let data: Vec<u8> = (0..data_length).map(|i| i as u8).collect();
        if tcode.has_data_block() && data_length > 0 {
            bytes.extend_from_slice(&data);
            bytes.extend_from_slice(&crc1394(&data).to_be_bytes());
        }
        let packet = Packet::new_checked(&bytes[..]).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(packet.total_len(), bytes.len(), "{what}");
        assert_eq!(packet.tcode(), tcode, "{what}");
        assert_eq!(
            u64::from(packet.destination_id().0),
            fields["destination_id"].as_u64().unwrap(),
            "{what}"
        );
        assert_eq!(
            u64::from(packet.source_id().0),
            fields["source_id"].as_u64().unwrap(),
            "{what}"
        );
        assert_eq!(
            u64::from(packet.tl()),
            fields["tl"].as_u64().unwrap(),
            "{what}"
        );
        assert_eq!(
            u64::from(packet.rt()),
            fields["rt"].as_u64().unwrap(),
            "{what}"
        );
        assert_eq!(
            u64::from(packet.pri()),
            fields["pri"].as_u64().unwrap(),
            "{what}"
        );
        if let Some(offset) = fields.get("offset") {
            assert_eq!(packet.offset(), offset.as_u64().unwrap(), "{what}");
        }
        if let Some(rcode) = fields.get("rcode") {
            assert_eq!(
                u64::from(u8::from(packet.rcode())),
                rcode.as_u64().unwrap(),
                "{what}"
            );
        }
        if let Some(q) = fields.get("quadlet_data") {
            assert_eq!(
                u64::from(packet.quadlet_data()),
                q.as_u64().unwrap(),
                "{what}"
            );
        }
        if let Some(len) = fields.get("data_length") {
            assert_eq!(
                u64::from(packet.data_length()),
                len.as_u64().unwrap(),
                "{what}"
            );
            assert_eq!(
                u64::from(packet.extended_tcode()),
                fields["extended_tcode"].as_u64().unwrap(),
                "{what}"
            );
        }
        assert_eq!(packet.header_crc_ok(), Some(true), "{what}");
        packet.verify().unwrap_or_else(|e| panic!("{what}: {e}"));

        // Encode back from the meaning type and compare bytes, with the
        // output buffer pre-filled so unset bytes would show.
        let repr = PacketRepr::parse(&packet).unwrap();
        assert_eq!(repr.buffer_len(), bytes.len(), "{what}");
        let mut out = vec![0xA5u8; bytes.len()];
        repr.emit(&mut out).unwrap();
        assert_eq!(out, bytes, "{what}: re-encoded bytes differ");
        if matches!(tcode, Tcode::LockRequest | Tcode::LockResponse) {
            assert!(matches!(repr, PacketRepr::Opaque { .. }), "{what}");
        } else {
            assert!(repr.header().is_some(), "{what}");
        }
    }
}

fn hdr(dest: u8, src: u8, tl: u8) -> AsyncHeader {
    AsyncHeader::new(NodeId::local(dest), NodeId::local(src), tl)
}

/// One packet per asynchronous tcode, built from the spec's header layout
/// (`ieee1394.md`, "Header layout"), checked field by field and round-tripped.
#[test]
fn one_known_packet_per_tcode() {
    // Quadlet write of the broadcast query word (fpga-board.md §6) to node 63.
    let bytes = quadlet_bytes(&[
        0xFFFF_0000 | (3 << 10),
        0xFFD0_0000,
        0x0000_1800,
        0x0007_0003,
    ]);
    let mut packet_bytes = bytes.clone();
    packet_bytes.extend_from_slice(&crc1394(&bytes).to_be_bytes());
    let p = Packet::new_checked(&packet_bytes[..]).unwrap();
    assert_eq!(p.tcode(), Tcode::WriteQuadletRequest);
    assert_eq!(p.destination_id(), NodeId::BROADCAST);
    assert_eq!(p.tl(), 3);
    assert_eq!(p.source_id(), NodeId(0xFFD0));
    assert_eq!(p.offset(), 0x1800);
    assert_eq!(p.quadlet_data(), 0x0007_0003);
    assert_eq!(p.total_len(), 20);
    let repr = PacketRepr::parse_verified(&packet_bytes).unwrap();
    assert_eq!(
        repr,
        PacketRepr::WriteQuadletRequest {
            header: AsyncHeader::new(NodeId::BROADCAST, NodeId(0xFFD0), 3),
            offset: 0x1800,
            data: 0x0007_0003
        }
    );

    let payload: Vec<u8> = (0u8..48).collect();
    let cases: Vec<(PacketRepr<'_>, usize)> = vec![
        (
            PacketRepr::WriteBlockRequest {
                header: hdr(0, 8, 1),
                offset: 0,
                extended_tcode: 0,
                data: &payload[..16],
            },
            20 + 16 + 4,
        ),
        (
            PacketRepr::WriteResponse {
                header: hdr(8, 0, 1),
                rcode: Rcode::Complete,
            },
            16,
        ),
        (
            PacketRepr::ReadQuadletRequest {
                header: hdr(0, 8, 2),
                offset: 0x4,
            },
            16,
        ),
        (
            PacketRepr::ReadBlockRequest {
                header: hdr(0, 8, 3),
                offset: 0,
                data_length: 48,
                extended_tcode: 0,
            },
            20,
        ),
        (
            PacketRepr::ReadQuadletResponse {
                header: hdr(8, 0, 2),
                rcode: Rcode::AddressError,
                data: 0x514C_4131,
            },
            20,
        ),
        (
            PacketRepr::ReadBlockResponse {
                header: hdr(8, 0, 3),
                rcode: Rcode::Complete,
                extended_tcode: 0,
                data: &payload,
            },
            20 + 48 + 4,
        ),
    ];
    for (repr, len) in cases {
        assert_eq!(repr.buffer_len(), len, "{repr:?}");
        let mut buf = vec![0xA5u8; len];
        repr.emit(&mut buf).unwrap();
        let p = Packet::new_checked(&buf[..]).unwrap();
        assert_eq!(p.tcode(), repr.tcode());
        assert!(p.crc_status().all_ok());
        let h = repr.header().unwrap();
        assert_eq!(p.destination_id(), h.destination);
        assert_eq!(p.source_id(), h.source);
        assert_eq!(p.tl(), h.tl);
        assert_eq!(p.payload(), repr.data());
        assert_eq!(PacketRepr::parse_verified(&buf).unwrap(), repr);
    }
}

#[test]
fn opaque_packets_are_carried_verbatim() {
    // Cycle start: destination 0xFFFF, source the cycle master, offset
    // 0xFFFF_F000_0200 (CYCLE_TIME register), q3 the cycle time.
    let header = quadlet_bytes(&[0xFFFF_0080, 0xFFC8_FFFF, 0xF000_0200, 0x1234_5678]);
    let mut cycle_start = header.clone();
    cycle_start.extend_from_slice(&crc1394(&header).to_be_bytes());
    let repr = PacketRepr::parse_verified(&cycle_start).unwrap();
    assert_eq!(
        repr,
        PacketRepr::Opaque {
            tcode: Tcode::CycleStart,
            bytes: &cycle_start
        }
    );
    let p = Packet::new_checked(&cycle_start[..]).unwrap();
    assert_eq!(p.quadlet_data(), 0x1234_5678);
    assert_eq!(p.offset(), 0xFFFF_F000_0200);

    // Stream packet: 8 data bytes, channel 5.
    let q0 = (8u32 << 16) | (5 << 8) | (0xA << 4);
    let mut stream = q0.to_be_bytes().to_vec();
    stream.extend_from_slice(&crc1394(&q0.to_be_bytes()).to_be_bytes());
    let data = [1u8, 2, 3, 4, 5, 6, 7, 8];
    stream.extend_from_slice(&data);
    stream.extend_from_slice(&crc1394(&data).to_be_bytes());
    let p = Packet::new_checked(&stream[..]).unwrap();
    assert_eq!(p.total_len(), 4 + 4 + 8 + 4);
    assert_eq!(p.payload(), &data);
    assert!(p.crc_status().all_ok());
    let mut out = vec![0u8; stream.len()];
    PacketRepr::parse_verified(&stream)
        .unwrap()
        .emit(&mut out)
        .unwrap();
    assert_eq!(out, stream);

    // Link-internal PHY config packet setting gap count 5.
    let body = PhyPacket::Config {
        force_root: None,
        gap_count: Some(5),
    }
    .to_quadlet();
    let link = quadlet_bytes(&[0xE0, body, !body]);
    let p = Packet::new_checked(&link[..]).unwrap();
    assert_eq!(p.tcode(), Tcode::LinkInternal);
    p.verify().unwrap();
    assert_eq!(
        PhyPacket::from_quadlet(p.phy_body()),
        PhyPacket::Config {
            force_root: None,
            gap_count: Some(5)
        }
    );
    let bad = quadlet_bytes(&[0xE0, body, body]);
    assert!(matches!(
        PacketRepr::parse_verified(&bad),
        Err(Error::Malformed { .. })
    ));
}

#[test]
fn crc_errors_are_reported_with_both_values() {
    let repr = PacketRepr::ReadBlockResponse {
        header: hdr(8, 0, 3),
        rcode: Rcode::Complete,
        extended_tcode: 0,
        data: &[9, 8, 7, 6],
    };
    let mut buf = vec![0u8; repr.buffer_len()];
    repr.emit(&mut buf).unwrap();
    let mut bad_header = buf.clone();
    bad_header[0] ^= 0x01;
    let p = Packet::new_checked(&bad_header[..]).unwrap();
    assert_eq!(p.header_crc_ok(), Some(false));
    assert!(matches!(p.verify(), Err(Error::HeaderCrc { .. })));
    let mut bad_data = buf.clone();
    bad_data[21] ^= 0x80;
    let p = Packet::new_checked(&bad_data[..]).unwrap();
    assert_eq!(p.header_crc_ok(), Some(true));
    assert_eq!(p.data_crc_ok(), Some(false));
    let err = p.verify().unwrap_err();
    assert!(matches!(err, Error::DataCrc { .. }));
    assert!(err.to_string().starts_with("data CRC mismatch"));
    // Trailing bytes after a complete packet are named.
    let mut long = buf.clone();
    long.extend_from_slice(&[0, 0]);
    assert_eq!(
        PacketRepr::parse_verified(&long),
        Err(Error::TrailingBytes {
            what: "read_response_block",
            extra: 2
        })
    );
}

#[test]
fn bridge_datagrams() {
    let repr = PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(NodeId::local(2), NodeId(0xFFD0), 7),
        offset: 4,
    };
    let mut datagram = ControlWord {
        no_forward: true,
        generation: 9,
    }
    .to_bytes()
    .to_vec();
    let mut pkt = vec![0u8; repr.buffer_len()];
    repr.emit(&mut pkt).unwrap();
    datagram.extend_from_slice(&pkt);
    let (cw, p) = split_host_datagram(&datagram).unwrap();
    assert_eq!(
        cw,
        ControlWord {
            no_forward: true,
            generation: 9
        }
    );
    assert_eq!(PacketRepr::parse(&p).unwrap(), repr);
    assert!(matches!(
        split_host_datagram(&datagram[..1]),
        Err(Error::Truncated { .. })
    ));
    let mut extra = datagram.clone();
    extra.push(0);
    assert!(matches!(
        split_host_datagram(&extra),
        Err(Error::TrailingBytes { .. })
    ));

    let response = PacketRepr::ReadQuadletResponse {
        header: repr.header().unwrap().response(),
        rcode: Rcode::Complete,
        data: 8,
    };
    let mut reply = vec![0u8; response.buffer_len()];
    response.emit(&mut reply).unwrap();
    let trailer = ExtraData {
        generation: 9,
        receive_time: 100,
        total_time: 300,
        ..Default::default()
    };
    reply.extend_from_slice(&trailer.to_bytes());
    let (p, e) = split_board_datagram(&reply).unwrap();
    assert_eq!(e, trailer);
    assert_eq!(PacketRepr::parse(&p).unwrap(), response);
    assert!(matches!(
        split_board_datagram(&reply[..reply.len() - 1]),
        Err(Error::Truncated {
            what: "bridge extra data",
            ..
        })
    ));
    assert_eq!(EXTRA_DATA_LEN, 8);
}

fn arb_header() -> impl Strategy<Value = AsyncHeader> {
    (any::<u16>(), any::<u16>(), 0u8..64, 0u8..4, 0u8..16).prop_map(|(d, s, tl, rt, pri)| {
        AsyncHeader {
            destination: NodeId(d),
            source: NodeId(s),
            tl,
            rt,
            pri,
        }
    })
}

fn arb_rcode() -> impl Strategy<Value = Rcode> {
    (0u8..16).prop_map(Rcode::from)
}

#[derive(Debug, Clone)]
enum Case {
    Wq(AsyncHeader, u64, u32),
    Wb(AsyncHeader, u64, u16, Vec<u8>),
    Wr(AsyncHeader, Rcode),
    Rq(AsyncHeader, u64),
    Rb(AsyncHeader, u64, u16, u16),
    Rqr(AsyncHeader, Rcode, u32),
    Rbr(AsyncHeader, Rcode, u16, Vec<u8>),
}

impl Case {
    fn repr(&self) -> PacketRepr<'_> {
        match self {
            Case::Wq(h, o, d) => PacketRepr::WriteQuadletRequest {
                header: *h,
                offset: *o,
                data: *d,
            },
            Case::Wb(h, o, e, d) => PacketRepr::WriteBlockRequest {
                header: *h,
                offset: *o,
                extended_tcode: *e,
                data: d,
            },
            Case::Wr(h, r) => PacketRepr::WriteResponse {
                header: *h,
                rcode: *r,
            },
            Case::Rq(h, o) => PacketRepr::ReadQuadletRequest {
                header: *h,
                offset: *o,
            },
            Case::Rb(h, o, l, e) => PacketRepr::ReadBlockRequest {
                header: *h,
                offset: *o,
                data_length: *l,
                extended_tcode: *e,
            },
            Case::Rqr(h, r, d) => PacketRepr::ReadQuadletResponse {
                header: *h,
                rcode: *r,
                data: *d,
            },
            Case::Rbr(h, r, e, d) => PacketRepr::ReadBlockResponse {
                header: *h,
                rcode: *r,
                extended_tcode: *e,
                data: d,
            },
        }
    }
}

fn arb_case() -> impl Strategy<Value = Case> {
    let offset = 0..=MAX_OFFSET;
    let data = proptest::collection::vec(any::<u8>(), 0..300);
    prop_oneof![
        (arb_header(), offset.clone(), any::<u32>()).prop_map(|(h, o, d)| Case::Wq(h, o, d)),
        (arb_header(), offset.clone(), any::<u16>(), data.clone())
            .prop_map(|(h, o, e, d)| Case::Wb(h, o, e, d)),
        (arb_header(), arb_rcode()).prop_map(|(h, r)| Case::Wr(h, r)),
        (arb_header(), offset.clone()).prop_map(|(h, o)| Case::Rq(h, o)),
        (arb_header(), offset, any::<u16>(), any::<u16>())
            .prop_map(|(h, o, l, e)| Case::Rb(h, o, l, e)),
        (arb_header(), arb_rcode(), any::<u32>()).prop_map(|(h, r, d)| Case::Rqr(h, r, d)),
        (arb_header(), arb_rcode(), any::<u16>(), data)
            .prop_map(|(h, r, e, d)| Case::Rbr(h, r, e, d)),
    ]
}

proptest! {
    #[test]
    fn emit_then_parse_round_trips(case in arb_case()) {
        let repr = case.repr();
        let mut buf = vec![0xA5u8; repr.buffer_len() + 3];
        let len = repr.emit(&mut buf).unwrap();
        prop_assert_eq!(len, repr.buffer_len());
        let parsed = PacketRepr::parse_verified(&buf[..len]).unwrap();
        prop_assert_eq!(parsed, repr);
        // Parse then emit reproduces the bytes.
        let mut again = vec![0u8; len];
        parsed.emit(&mut again).unwrap();
        prop_assert_eq!(&again[..], &buf[..len]);
    }

    #[test]
    fn any_bytes_display_without_panicking(bytes in prop::collection::vec(any::<u8>(), 0..64)) {
        let text = Packet::new_unchecked(&bytes[..]).to_string();
        prop_assert!(!text.is_empty());
    }

    #[test]
    fn any_single_bit_flip_is_caught(case in arb_case(), bit in any::<prop::sample::Index>()) {
        let repr = case.repr();
        let mut buf = vec![0u8; repr.buffer_len()];
        repr.emit(&mut buf).unwrap();
        let bit = bit.index(buf.len() * 8);
        buf[bit / 8] ^= 0x80 >> (bit % 8);
        // Either the structure no longer parses (length/tcode bits hit), or
        // a CRC check fails: a flipped bit is never silently accepted.
        if let Ok(p) = Packet::new_checked(&buf[..]) {
            if p.total_len() == buf.len() {
                prop_assert!(p.verify().is_err());
            }
        }
    }

    #[test]
    fn parsing_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        if let Ok(p) = Packet::new_checked(&bytes[..]) {
            let _ = (p.tcode(), p.destination_id(), p.source_id(), p.tl(), p.rt(), p.pri());
            let _ = (p.offset(), p.rcode(), p.quadlet_data(), p.data_length(), p.extended_tcode());
            let _ = (p.header_crc_ok(), p.data_crc_ok(), p.payload(), p.padded_data(), p.verify());
            prop_assert!(p.total_len() <= bytes.len());
            let _ = PacketRepr::parse(&p);
        }
        let _ = PacketRepr::parse_verified(&bytes);
        let _ = split_host_datagram(&bytes);
        let _ = split_board_datagram(&bytes);
        let _ = ExtraData::parse(&bytes);
        if bytes.len() >= 8 {
            let q = |i: usize| u32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
            let _ = PhyPacket::from_pair(q(0), q(4));
        }
    }

    #[test]
    fn table_crc_equals_bitwise_crc(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        prop_assert_eq!(crc1394(&bytes), crc1394_bitwise(&bytes));
    }

    #[test]
    fn phy_packets_round_trip(q in any::<u32>()) {
        let p = PhyPacket::from_quadlet(q);
        prop_assert_eq!(PhyPacket::from_quadlet(p.to_quadlet()), p);
    }
}

#[test]
fn speeds() {
    assert_eq!(Speed::S400.bits_per_second(), 393_216_000);
    assert_eq!(Speed::from_mbps(200), Some(Speed::S200));
    assert_eq!(Speed::S100.max_async_payload(), 512);
    // One quadlet at S400 takes 81.4 ns (ieee1394.md, "Timing on the wire").
    let ns = 32.0 / Speed::S400.bits_per_second() as f64 * 1e9;
    assert!((ns - 81.38).abs() < 0.01);
}

#[test]
fn packets_display_as_one_line_naming_every_field() {
    let show = |repr: PacketRepr<'_>| {
        let mut buf = vec![0u8; repr.buffer_len()];
        repr.emit(&mut buf).unwrap();
        Packet::new_checked(&buf[..]).unwrap().to_string()
    };
    let h = AsyncHeader::new(NodeId(0xFFC0), NodeId(0xFFC2), 5);
    assert_eq!(
        show(PacketRepr::ReadBlockRequest {
            header: h,
            offset: 0x1000,
            data_length: 268,
            extended_tcode: 0,
        }),
        "read_request_block 0xffc0 <- 0xffc2 tl 5 @0x1000 len 268"
    );
    assert_eq!(
        show(PacketRepr::WriteQuadletRequest {
            header: h,
            offset: 0x1800,
            data: 0x0001_00FF,
        }),
        "write_request_quadlet 0xffc0 <- 0xffc2 tl 5 @0x1800 data 0x000100ff"
    );
    assert_eq!(
        show(PacketRepr::ReadQuadletResponse {
            header: h.response(),
            rcode: Rcode::AddressError,
            data: 0,
        }),
        "read_response_quadlet 0xffc2 <- 0xffc0 tl 5 address_error data 0x00000000"
    );
    // A damaged packet says so; bytes that are not a packet say what is
    // wrong.
    let mut buf = vec![0u8; 16];
    PacketRepr::ReadQuadletRequest {
        header: h,
        offset: 7,
    }
    .emit(&mut buf)
    .unwrap();
    buf[13] ^= 1;
    assert!(
        Packet::new_checked(&buf[..])
            .unwrap()
            .to_string()
            .ends_with("(header CRC bad)")
    );
    assert!(
        Packet::new_unchecked(&buf[..3])
            .to_string()
            .starts_with("malformed (3 bytes")
    );
}
