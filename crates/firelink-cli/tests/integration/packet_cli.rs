//! End-to-end tests of `firelink packet`, `firelink crc` and `firelink tour`,
//! run as a user would run them.

use crate::common;

use common::{fails, firelink, json};

/// `firelink ARGS` fails with one line of error naming `needle`.
fn fails_with(args: &[&str], needle: &str) {
    let stderr = fails(args, needle);
    assert_eq!(
        stderr.lines().count(),
        1,
        "one line of error, got {stderr:?}"
    );
}
#[test]
fn decode_quadlet_read_request() {
    // CRC vector "quadlet read request header, dest 0xffc1, tl 5, offset 0x7".
    let v = json(&["packet", "decode", "ffc11540 ffc20000 00000007 b2b02823"]);
    assert_eq!(v["tcode"], 4);
    assert_eq!(v["tcode_name"], "read_request_quadlet");
    assert_eq!(v["destination_id"], 0xffc1);
    assert_eq!(v["source_id"], 0xffc2);
    assert_eq!(v["tl"], 5);
    assert_eq!(v["rt"], 1);
    assert_eq!(v["pri"], 0);
    assert_eq!(v["header_crc_ok"], true);
    assert_eq!(v["offset"], 7);
    assert!(v.get("quadlet_data").is_none());
    assert!(v.get("rcode").is_none());
}

#[test]
fn decode_quadlet_read_response_and_bad_crc() {
    let v = json(&[
        "packet",
        "decode",
        "ffc21460ffc100000000000000000009 50d68132",
    ]);
    assert_eq!(v["tcode_name"], "read_response_quadlet");
    assert_eq!(v["quadlet_data"], 9);
    assert_eq!(v["rcode"], 0);
    assert!(v.get("offset").is_none());
    let v = json(&[
        "packet",
        "decode",
        "ffc21460ffc100000000000000000009 50d68133",
    ]);
    assert_eq!(v["header_crc_ok"], false);
}

#[test]
fn encode_then_decode_block_write_via_flags_and_json() {
    let out = firelink(&[
        "packet",
        "encode",
        "--tcode",
        "write_request_block",
        "--destination-id",
        "0xffff",
        "--source-id",
        "0xffc1",
        "--pri",
        "10",
        "--offset",
        "0xffffff001000",
        "--data",
        "00010021 00000000",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let hex = String::from_utf8(out.stdout).unwrap();
    let v = json(&["packet", "decode", hex.trim()]);
    assert_eq!(v["tcode"], 1);
    assert_eq!(v["destination_id"], 0xffff);
    assert_eq!(v["pri"], 10);
    assert_eq!(v["offset"], 0xffff_ff00_1000u64);
    assert_eq!(v["data_length"], 8);
    assert_eq!(v["data"], "0001002100000000");
    assert_eq!(v["header_crc_ok"], true);
    assert_eq!(v["data_crc_ok"], true);

    // The decoded JSON encodes back to the same bytes.
    let out = firelink(&["packet", "encode", "--json", &v.to_string()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(String::from_utf8(out.stdout).unwrap(), hex);
}

#[test]
fn bridge_decode_adds_control_word() {
    let out = firelink(&[
        "packet",
        "encode",
        "--tcode",
        "4",
        "--destination-id",
        "0xffc3",
        "--offset",
        "4",
        "--bridge",
        "--generation",
        "7",
        "--no-forward",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let hex = String::from_utf8(out.stdout).unwrap();
    assert!(hex.starts_with("0107"), "{hex}");
    let v = json(&["packet", "decode", "--bridge", hex.trim()]);
    assert_eq!(v["no_forward"], true);
    assert_eq!(v["generation"], 7);
    assert_eq!(v["destination_id"], 0xffc3);
    assert_eq!(v["header_crc_ok"], true);
}

#[test]
fn crc_command() {
    let out = firelink(&["crc", "313233343536373839"]);
    assert_eq!(String::from_utf8(out.stdout).unwrap().trim(), "fc891918");
    let out = firelink(&["crc", "ffff001a ffc1ffff ff001000 00840000"]);
    assert_eq!(String::from_utf8(out.stdout).unwrap().trim(), "3774a9b4");
}

#[test]
fn malformed_input_names_the_problem() {
    fails_with(&["packet", "decode", "abc"], "odd number of hex digits");
    fails_with(&["packet", "decode", "ffc115zz"], "invalid hex digit");
    fails_with(
        &["packet", "decode", "ffc11540 ffc2"],
        "truncated read_request_quadlet",
    );
    // Block write header claiming 0x84 bytes with 4 present.
    fails_with(
        &[
            "packet",
            "decode",
            "ffff001a ffc1ffff ff001000 00840000 3774a9b4 00000000",
        ],
        "length field says 132 bytes",
    );
    fails_with(
        &["packet", "decode", "ffc11530 ffc20000 00000007 b2b02823"],
        "unknown tcode 0x3",
    );
    fails_with(
        &["packet", "decode", "ffc11540 ffc20000 00000007 b2b02823 00"],
        "trailing bytes",
    );
    fails_with(
        &["packet", "decode", "--bridge", "01"],
        "truncated bridge control word",
    );
    fails_with(
        &[
            "packet",
            "encode",
            "--tcode",
            "write_request_quadlet",
            "--destination-id",
            "0xffc0",
            "--offset",
            "0",
        ],
        "missing field quadlet_data",
    );
    fails_with(
        &[
            "packet",
            "encode",
            "--tcode",
            "read_request_quadlet",
            "--destination-id",
            "0xffc0",
            "--offset",
            "0",
            "--tl",
            "64",
        ],
        "tl = 0x40 is out of range",
    );
    fails_with(
        &["packet", "encode", "--json", "{\"tcode\":"],
        "invalid JSON",
    );
    fails_with(
        &[
            "packet",
            "encode",
            "--tcode",
            "cycle_start",
            "--destination-id",
            "0xffff",
        ],
        "cannot encode cycle_start",
    );
}

/// `firelink` with no arguments runs the demo (tested in `demo_bench.rs`
/// with a short duration); the packet tour is `firelink tour`.
#[test]
fn tour_shows_one_cycle() {
    let out = firelink(&["tour"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("status broadcast (board 7)"));
    assert!(text.contains("command broadcast (PC)"));
    assert!(text.contains("12 packets"));
}
