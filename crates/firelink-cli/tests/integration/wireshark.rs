//! The Wireshark dissector (`tools/wireshark/firelink.lua`) run by Debian's
//! `tshark` on the committed captures (`tests/data/captures`, made by
//! `scripts/make-captures`): named fields and values of known packets, the
//! broken CRCs flagged, every capture decoded with no malformed entry and
//! no Lua error, garbage decoded without an error either.
//!
//! Needs `tshark` (`scripts/test` installs Debian's when missing); without
//! it these tests fail saying so.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn capture(name: &str) -> PathBuf {
    repo().join("tests/data/captures").join(name)
}

/// The captures of every packet kind Firelink produces (garbage.pcap
/// apart: it is meant to be broken).
const CAPTURES: [&str; 10] = [
    "dvrk-rev8-broadcast.pcap",
    "dvrk-rev7-broadcast.pcap",
    "dvrk-seed-broadcast.pcap",
    "dvrk-sequential.pcap",
    "dvrk-host.pcap",
    "dvrk-bridge.pcap",
    "snake.pcap",
    "snake-bridge.pcap",
    "mahru.pcap",
    "bad-crc.pcap",
];

/// Run tshark with the dissector loaded on `file` (two passes, no name
/// resolution, a private home so that no installed copy of the plugin is
/// loaded beside it); stdout. Fails on a Lua error on stderr.
fn tshark(file: &str, args: &[&str]) -> String {
    let home = std::env::temp_dir().join(format!("firelink-tshark-home-{}", std::process::id()));
    std::fs::create_dir_all(&home).unwrap();
    let script = repo().join("tools/wireshark/firelink.lua");
    let out = Command::new("tshark")
        .env("HOME", &home)
        .env_remove("XDG_CONFIG_HOME")
        .arg("-n")
        .arg("-2")
        .arg("-X")
        .arg(format!("lua_script:{}", script.display()))
        .arg("-r")
        .arg(capture(file))
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run tshark ({e}): install Debian's tshark (scripts/test does)")
        });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "tshark on {file} failed: {stderr}");
    assert!(
        !stderr.contains("Lua"),
        "tshark on {file}: Lua error: {stderr}"
    );
    String::from_utf8(out.stdout).unwrap()
}

/// One row per frame: the values of `fields` (all occurrences joined by
/// commas), `display` as the display filter ("" for every frame).
fn fields(file: &str, display: &str, fields: &[&str]) -> Vec<Vec<String>> {
    fields_with(file, display, fields, &[])
}

fn fields_with(file: &str, display: &str, fields: &[&str], extra: &[&str]) -> Vec<Vec<String>> {
    let mut args = vec!["-T", "fields", "-E", "occurrence=a", "-E", "separator=/t"];
    for f in fields {
        args.push("-e");
        args.push(f);
    }
    if !display.is_empty() {
        args.push("-Y");
        args.push(display);
    }
    args.extend_from_slice(extra);
    tshark(file, &args)
        .lines()
        .map(|l| l.split('\t').map(str::to_owned).collect())
        .collect()
}

fn row(values: &[&str]) -> Vec<String> {
    values.iter().map(|&s| s.to_owned()).collect()
}

#[test]
fn header_fields_of_known_packets() {
    let rows = fields(
        "dvrk-rev8-broadcast.pcap",
        "frame.number >= 8 && frame.number <= 10",
        &[
            "frame.number",
            "firelink.tcode",
            "firelink.src",
            "firelink.dst",
            "firelink.tlabel",
            "firelink.retry",
            "firelink.priority",
            "firelink.offset",
            "firelink.rcode",
            "firelink.quadlet",
            "firelink.register",
            "firelink.board.hw_version",
            "firelink.header_crc.status",
            "firelink.ack",
            "firelink.kind",
        ],
    );
    assert_eq!(
        rows,
        vec![
            // Board 2 (the host's node) reads HW_VERSION of node 0 ...
            row(&[
                "8",
                "0x04",
                "0xffc2",
                "0xffc0",
                "1",
                "0",
                "0x00",
                "0x0000000000000004",
                "",
                "",
                "HW_VERSION",
                "",
                "0",
                "",
                "bus"
            ]),
            // ... which acks pending ...
            row(&[
                "9", "", "", "", "", "", "", "", "", "", "", "", "", "0x02", "bus"
            ]),
            // ... and answers QLA1.
            row(&[
                "10",
                "0x06",
                "0xffc0",
                "0xffc2",
                "1",
                "0",
                "0x00",
                "",
                "0",
                "0x514c4131",
                "HW_VERSION",
                "QLA1",
                "0",
                "",
                "bus"
            ]),
        ]
    );
}

#[test]
fn phy_packets_of_the_bus_capture() {
    let rows = fields(
        "dvrk-rev8-broadcast.pcap",
        "firelink.phy",
        &[
            "firelink.phy.kind",
            "firelink.phy.id",
            "firelink.phy.gap_count",
        ],
    );
    // Self-IDs of nodes 0-2, the PHY configuration setting gap count 5,
    // then the self-IDs of the bus reset it causes (gap count 5 in them).
    let kinds: Vec<&str> = rows.iter().map(|r| r[0].as_str()).collect();
    assert_eq!(kinds, ["2", "2", "2", "0", "2", "2", "2"]);
    assert_eq!(rows[3], row(&["0", "0", "5"]));
    assert_eq!(rows[6][1..], row(&["2", "5"])[..]);
}

#[test]
fn the_rev8_cycle_query_broadcasts_hub_block_and_command_block() {
    let f = "dvrk-rev8-broadcast.pcap";
    let query = fields(
        f,
        "firelink.register == \"hub query\"",
        &["firelink.bcast.seq", "firelink.bcast.board_mask"],
    );
    assert_eq!(query, vec![row(&["1", "0x00000003"])]);
    let broadcasts = fields(
        f,
        "firelink.register == \"status broadcast\"",
        &[
            "firelink.bcast.status_seq",
            "firelink.bcast.status_quadlets",
            "firelink.board.id",
        ],
    );
    assert_eq!(
        broadcasts,
        vec![row(&["1", "33", "0"]), row(&["1", "33", "1"])]
    );
    // The hub block: board 0 and board 1, each with its STATUS, four axes
    // and Rev 8 header, then the timing quadlet.
    let hub = fields(
        f,
        "firelink.hub.board",
        &[
            "firelink.board.id",
            "firelink.board.status",
            "firelink.board.status.board_id",
            "firelink.hub.size",
            "firelink.hub.seq_low",
            "firelink.hub.seq_error",
            "firelink.axis",
            "firelink.axis.encoder",
            "firelink.axis.current",
        ],
    );
    assert_eq!(hub.len(), 1, "{hub:?}");
    let h = &hub[0];
    assert_eq!(h[0], "0,1");
    assert_eq!(h[1], "0x40701000,0x41701000");
    assert_eq!(h[2], "0,1");
    assert_eq!(h[3], "33,33");
    assert_eq!(h[4], "1,1");
    assert_eq!(h[5], "0,0");
    assert_eq!(h[6], "1,2,3,4,1,2,3,4");
    assert_eq!(h[7], ["0x00800000"; 8].join(","));
    assert_eq!(h[8].split(',').count(), 8);
    // The command block, snooped by node 0: one slice per board by its
    // header, each with four DAC quadlets.
    let command = fields(
        f,
        "firelink.wblock.header",
        &[
            "firelink.offset",
            "firelink.register",
            "firelink.wblock.board_id",
            "firelink.wblock.quadlets",
            "firelink.axis.dac.valid",
        ],
    );
    assert_eq!(
        command,
        vec![row(&[
            "0x0000ffffffff0000",
            "command block (snooped by node 0)",
            "0,1",
            "6,6",
            "1,1,1,1,1,1,1,1"
        ])]
    );
}

#[test]
fn rev7_and_seed_firmware_hub_blocks_split_per_board() {
    let rev7 = fields(
        "dvrk-rev7-broadcast.pcap",
        "firelink.hub.board",
        &[
            "firelink.board.id",
            "firelink.hub.seq",
            "firelink.axis.run",
            "firelink.axis.motor_status",
        ],
    );
    assert_eq!(rev7.len(), 1);
    assert_eq!(rev7[0][0], "0,1");
    assert_eq!(rev7[0][1], "1,1");
    // Rev 7 blocks have the encoder sections, no MOTOR_STATUS.
    assert_eq!(rev7[0][2].split(',').count(), 8);
    assert_eq!(rev7[0][3], "");
    // Seed 000's firmware (Rev 4): ADC and encoder position only.
    let seed = fields(
        "dvrk-seed-broadcast.pcap",
        "firelink.hub.board",
        &[
            "firelink.board.id",
            "firelink.axis.encoder",
            "firelink.axis.period",
        ],
    );
    assert_eq!(seed.len(), 1);
    assert_eq!(seed[0][0], "0,1");
    assert_eq!(seed[0][1].split(',').count(), 8);
    assert_eq!(seed[0][2], "");
}

#[test]
fn sequential_protocol_blocks_per_board() {
    let reads = fields(
        "dvrk-sequential.pcap",
        "firelink.register == \"real-time read block\" && firelink.tcode == 7",
        &["firelink.board.status.board_id", "firelink.axis"],
    );
    assert_eq!(reads, vec![row(&["0", "1,2,3,4"]), row(&["1", "1,2,3,4"])]);
    let writes = fields(
        "dvrk-sequential.pcap",
        "firelink.register == \"real-time write block\"",
        &[
            "firelink.dst",
            "firelink.wblock.board_id",
            "firelink.axis.dac.command",
        ],
    );
    assert_eq!(writes.len(), 2, "{writes:?}");
    assert_eq!(writes[0][1], "0");
    assert_eq!(writes[1][1], "1");
}

#[test]
fn host_capture_marks_its_own_side() {
    let rows = fields("dvrk-host.pcap", "", &["firelink.kind", "firelink.tcode"]);
    assert!(rows.len() > 10, "{rows:?}");
    for r in &rows {
        let expected = if ["0x04", "0x05", "0x00", "0x01"].contains(&r[1].as_str()) {
            "host sent"
        } else {
            "host received"
        };
        assert_eq!(r[0], expected, "{r:?}");
    }
}

#[test]
fn bridge_datagrams_control_word_extra_data_and_cycle() {
    let f = "dvrk-bridge.pcap";
    // Discovery's first request: broadcast, no forward, generation 0.
    let first = fields(
        f,
        "frame.number == 1",
        &[
            "firelink.kind",
            "firelink.bridge.no_forward",
            "firelink.bridge.generation",
            "firelink.dst",
            "firelink.src",
            "firelink.register",
        ],
    );
    assert_eq!(
        first,
        vec![row(&[
            "bridge request",
            "1",
            "0",
            "0xffff",
            "0xffd0",
            "HW_VERSION"
        ])]
    );
    let answer = fields(
        f,
        "frame.number == 2",
        &[
            "firelink.kind",
            "firelink.board.hw_version",
            "firelink.bridge.board_generation",
            "firelink.bridge.flag_no_forward",
            "firelink.request_in",
        ],
    );
    assert_eq!(
        answer,
        vec![row(&["bridge response", "QLA1", "2", "1", "1"])]
    );
    // The broadcast cycle driven by hand: query seq 5 for boards 0 and 1,
    // the hub block with both boards, the command block split per board.
    let hub = fields(
        f,
        "firelink.hub.board",
        &[
            "firelink.board.id",
            "firelink.hub.seq_low",
            "firelink.board.status.axes",
        ],
    );
    assert_eq!(hub, vec![row(&["0,1", "5,5", "4,4"])]);
    let command = fields(
        f,
        "firelink.register == \"command block\"",
        &[
            "firelink.dst",
            "firelink.wblock.board_id",
            "firelink.axis.dac.command",
        ],
    );
    assert_eq!(
        command,
        vec![row(&["0xffff", "0,1", &["0x00008000"; 8].join(",")])]
    );
}

#[test]
fn snake_session_auto_detected_with_its_blocks() {
    let f = "snake.pcap";
    let robots = fields(f, "firelink.robot", &["firelink.robot"]);
    assert!(robots.iter().all(|r| r[0] == "snake"), "{robots:?}");
    let read = fields(
        f,
        "firelink.register == \"block read\" && firelink.tcode == 7",
        &[
            "firelink.snake.status.board_id",
            "firelink.snake.channel",
            "firelink.snake.encoder",
        ],
    );
    // Two cycles of six nodes.
    assert_eq!(read.len(), 12, "{read:?}");
    assert_eq!(read[0][0], "0");
    assert_eq!(read[5][0], "5");
    assert_eq!(read[0][1], "1,2,3,4,5,6,7");
    assert_eq!(read[0][2].split(',').count(), 7);
    let write = fields(
        f,
        "firelink.register == \"block write\"",
        &[
            "firelink.dst.phy",
            "firelink.snake.channel",
            "firelink.snake.valid",
        ],
    );
    assert_eq!(write.len(), 12, "{write:?}");
    assert_eq!(write[0][1], "1,2,3,4,5,6,7");
    // Table 1 registers by name.
    let regs = fields(
        f,
        "firelink.tcode == 0",
        &["firelink.register", "firelink.quadlet"],
    );
    assert!(
        regs.contains(&row(&["channel 1 encoder_preload", "0x00800000"])),
        "{regs:?}"
    );
    let bridge = fields(
        "snake-bridge.pcap",
        "firelink.register == \"channel 2 dac\"",
        &["firelink.robot", "firelink.kind"],
    );
    assert!(!bridge.is_empty());
    assert!(bridge.iter().all(|r| r[0] == "snake"), "{bridge:?}");
}

#[test]
fn mahru_session_commands_and_qwrite_slots() {
    let f = "mahru.pcap";
    let commands = fields(f, "firelink.mahru.command", &["firelink.register"]);
    let names: std::collections::BTreeSet<&str> = commands.iter().map(|r| r[0].as_str()).collect();
    for c in [
        "IDREQUEST",
        "IDCHECK",
        "PARAMETER",
        "SETBIAS",
        "READY",
        "START",
        "QREAD",
        "FTREAD",
        "QWRITE",
        "STOP",
    ] {
        assert!(names.contains(c), "no {c} in {names:?}");
    }
    // The first QWRITE: ten slots, ModIDs 0..9, each valid, sequence 1.
    let qwrite = fields(
        f,
        "firelink.register == \"QWRITE\"",
        &[
            "firelink.mahru.slot",
            "firelink.mahru.mod_id",
            "firelink.mahru.sequence",
        ],
    );
    assert_eq!(qwrite.len(), 2, "{qwrite:?}");
    assert_eq!(qwrite[0][0], "0,1,2,3,4,5,6,7,8,9");
    assert_eq!(qwrite[0][1], "0,1,2,3,4,5,6,7,8,9");
    assert_eq!(qwrite[0][2], ["1"; 10].join(","));
    // IDREQUEST answers: motor controllers and force/torque sensors.
    let ids = fields(
        f,
        "firelink.mahru.magic",
        &["firelink.mahru.kind", "firelink.mahru.mod_id"],
    );
    assert_eq!(ids.len(), 14);
    assert_eq!(ids[0], row(&["1", "3"]));
    assert!(ids.contains(&row(&["2", "13"])), "{ids:?}");
    // Answers decoded by the request they answer: QREAD's joint block,
    // FTREAD's wrench; PARAMETER's records.
    let joints = fields(
        f,
        "firelink.register == \"QREAD\" && firelink.tcode == 7",
        &[
            "firelink.mahru.mod_id",
            "firelink.mahru.state",
            "firelink.mahru.servo_ticks",
        ],
    );
    assert_eq!(joints.len(), 20, "{joints:?}");
    assert!(joints.iter().all(|r| r[1] == "3"), "{joints:?}");
    let wrenches = fields(
        f,
        "firelink.register == \"FTREAD\" && firelink.tcode == 7",
        &["firelink.mahru.force", "firelink.mahru.ft_torque"],
    );
    assert_eq!(wrenches.len(), 8, "{wrenches:?}");
    assert!(
        wrenches
            .iter()
            .all(|r| r[0].split(',').count() == 3 && r[1].split(',').count() == 3)
    );
    let gears = fields(
        f,
        "firelink.register == \"PARAMETER\"",
        &[
            "firelink.mahru.mod_id",
            "firelink.mahru.gear",
            "firelink.mahru.torque_max",
        ],
    );
    assert_eq!(gears.len(), 10, "{gears:?}");
    assert_eq!(gears[0], row(&["0", "160", "200"]));
    // The preference overrides the detection: as a dVRK, offset 18 is no
    // command; as MAHRU in one pass, the first request is IDREQUEST.
    let as_dvrk = fields_with(
        f,
        "frame.number == 1",
        &["firelink.robot", "firelink.register"],
        &["-o", "firelink.robot:dvrk"],
    );
    assert_eq!(as_dvrk, vec![row(&["dvrk", "IP_ADDR"])]);
    let as_mahru = fields_with(
        f,
        "frame.number == 1",
        &["firelink.robot", "firelink.register"],
        &["-o", "firelink.robot:mahru"],
    );
    assert_eq!(as_mahru, vec![row(&["mahru", "IDREQUEST"])]);
}

#[test]
fn corrupted_crcs_are_flagged() {
    let f = "bad-crc.pcap";
    let bad = fields(
        f,
        "firelink.crc.bad",
        &[
            "frame.number",
            "firelink.header_crc.status",
            "firelink.data_crc.status",
        ],
    );
    // The hub read request's header CRC and the hub block's data CRC.
    assert_eq!(bad, vec![row(&["52", "1", ""]), row(&["54", "0", "1"])]);
    let text = tshark(f, &["-V", "-Y", "firelink.crc.bad"]);
    assert!(
        text.contains("Expert Info (Error/Checksum): Bad header CRC"),
        "{text}"
    );
    assert!(
        text.contains("Expert Info (Error/Checksum): Bad data CRC"),
        "{text}"
    );
    // The same capture unbroken has none.
    let good = fields(
        "dvrk-rev8-broadcast.pcap",
        "firelink.crc.bad",
        &["frame.number"],
    );
    assert!(good.is_empty(), "{good:?}");
}

#[test]
fn every_capture_decodes_without_malformed_entries() {
    for f in CAPTURES {
        let text = tshark(f, &["-V"]);
        let frames = text.matches("\nFrame ").count() + usize::from(text.starts_with("Frame "));
        let decoded = text.matches("\nFirelink IEEE 1394\n").count();
        assert!(frames > 40, "{f}: {frames} frames");
        assert_eq!(
            decoded, frames,
            "{f}: not every frame reached the dissector"
        );
        for bad in [
            "Malformed",
            "Lua Error",
            "Truncated",
            "Unknown tcode",
            "Unexpected block size",
        ] {
            assert!(!text.contains(bad), "{f}: {bad} in:\n{text}");
        }
        // Every CRC checks, except the two broken on purpose.
        let errors = text.matches("Expert Info (Error/").count();
        let expected = if f == "bad-crc.pcap" { 2 } else { 0 };
        assert_eq!(errors, expected, "{f}: {errors} expert errors");
    }
}

#[test]
fn garbage_gets_expert_info_never_a_lua_error() {
    let text = tshark("garbage.pcap", &["-V"]);
    let frames = text.matches("\nFrame ").count() + 1;
    assert!(frames > 300, "{frames} frames");
    assert!(!text.contains("Lua Error"));
    assert!(text.contains("Expert Info (Error/Malformed): Truncated"));
    assert!(text.contains("Expert Info (Warning/Protocol): Unknown tcode"));
    // Every frame with a payload reached the dissector (empty ones do not).
    assert!(text.matches("\nFirelink IEEE 1394\n").count() > 300);
}
