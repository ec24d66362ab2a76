//! Mixed board sets: an FPGA V2 board at Rev 8 among FPGA V3 boards at Rev
//! 9, as the Rev 9 host meets them (EthUdpPort `InitNodes`): the board
//! answering the host's first broadcast reads (the hub, the one on the
//! host's Ethernet) decides alone; V3 at Rev >= 9 means the Ethernet-only
//! network, anything else the bridge; the other boards are then whatever
//! that path reaches (behind the bridge: every board on the FireWire
//! chain, V2 and V3 alike, V3 boards keeping their FireWire ports).
//!
//! A V2 board has no Ethernet-only firmware (one 100 Mb/s port, no
//! switch): the Ethernet-only network refuses it by name, and a mixed set
//! is the bridge emulator's FireWire chain. Through it, `udp:` keeps the
//! bridge when the hub is the V2 board and the I/O runs with 0 errors;
//! when the hub is a V3 board at Rev 9, `udp:` would take the
//! Ethernet-only network (which never reaches a board on FireWire only),
//! so such a set is driven with `udpfw:`, as on real hardware. No test
//! measures time.

use crate::common;

use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, FpgaVersion, Hardware, Profile};
use firelink_emulate::qla::eth_network::{EthNetwork, NetworkError};
use firelink_host::eth::{EthPort, UdpNetPort};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_host::udp::WaitMode;

/// Long enough never to fire on a loaded machine.
const TIMEOUT: Duration = Duration::from_secs(5);

/// The scan's time-out (absent nodes are waited out once each).
const SCAN_TIMEOUT: Duration = Duration::from_secs(1);

/// Cycles of I/O each set runs.
const CYCLES: u64 = 300;

/// QLA1 boards 0..4: board `v2` an FPGA V2 at Rev 8, the others FPGA V3 at
/// Rev 9; board 0 is the one on the host's Ethernet.
fn mixed(v2: u8) -> Vec<BoardConfig> {
    (0..4)
        .map(|id| {
            if id == v2 {
                BoardConfig::new(id, Hardware::Qla1, Profile::Rev8).with_fpga(FpgaVersion::V2)
            } else {
                BoardConfig::new(id, Hardware::Qla1, Profile::Rev9).with_fpga(FpgaVersion::V3)
            }
        })
        .collect()
}

/// Scan through `port`, check every board with its FPGA, run [`CYCLES`]
/// broadcast cycles (with the scan's read time-out); every cycle must be
/// clean.
fn scan_and_run(mut port: UdpNetPort, v2: u8) {
    let report = scan(&mut port).unwrap();
    let found: Vec<(u8, FpgaVersion)> =
        report.boards.iter().map(|b| (b.board_id, b.fpga)).collect();
    let expected: Vec<(u8, FpgaVersion)> = (0..4)
        .map(|id| {
            let fpga = if id == v2 {
                FpgaVersion::V2
            } else {
                FpgaVersion::V3
            };
            (id, fpga)
        })
        .collect();
    assert_eq!(found, expected);
    assert_eq!(report.bridge_board, Some(0), "board 0 is the bridge");
    assert_eq!(
        report.protocol,
        Protocol::Broadcast,
        "{}",
        report.protocol_reason
    );
    let mut io = IoSystem::with_scan(port, &report, IoOptions::default()).unwrap();
    for _ in 0..CYCLES {
        let r = io.read_all();
        assert!(r.all_ok(), "{:?}", r.missed_boards().collect::<Vec<_>>());
        io.write_all();
    }
    let stats = io.stats();
    assert_eq!(stats.cycles, CYCLES);
    assert_eq!(stats.clean_cycles, CYCLES);
    assert_eq!(stats.total_errors(), 0, "{stats:?}");
}

/// The bridge emulator over [`mixed`]`(v2)`: the hub's probe shows
/// `hub_firmware` and whether the Rev 9 host would take the Ethernet-only
/// network; the port `udp:` (`force_bridge` false) or `udpfw:` opens must
/// be the bridge, scan every board and run [`CYCLES`] clean cycles.
fn drive_through_the_bridge(v2: u8, hub_firmware: u32, ethernet_only: bool, force_bridge: bool) {
    let server = common::Server::start(mixed(v2));
    let probe = EthPort::probe(server.addr, TIMEOUT).unwrap();
    assert_eq!(
        (probe.board, probe.firmware),
        (0, hub_firmware),
        "{probe:?}"
    );
    assert_eq!(probe.is_ethernet_only(), ethernet_only, "{probe:?}");
    let port =
        UdpNetPort::open(server.addr, force_bridge, SCAN_TIMEOUT, WaitMode::Blocking).unwrap();
    assert!(!port.is_ethernet_only(), "the bridge");
    scan_and_run(port, v2);
    let stats = server.stop();
    // The bus failed only the scan's reads of the 12 absent nodes.
    assert_eq!(
        (stats.malformed, stats.bad_crc, stats.bus_failures),
        (0, 0, 12),
        "{stats:?}"
    );
}

/// The hub is the V2 board at Rev 8: `udp:` asks it who it is and keeps
/// the bridge, which reaches the V3 boards over FireWire; 300 broadcast
/// cycles, 0 errors.
#[test]
fn udp_keeps_the_bridge_when_the_hub_is_a_v2_board() {
    drive_through_the_bridge(0, 8, false, false);
}

/// The hub is a V3 board at Rev 9 with a V2 board behind it on FireWire:
/// the Rev 9 host's choice (`udp:`) is the Ethernet-only network, which
/// cannot reach the V2 board; `udpfw:` forces the bridge and drives all
/// four, 300 broadcast cycles with 0 errors.
#[test]
fn udpfw_drives_a_v2_board_behind_a_v3_rev9_hub() {
    drive_through_the_bridge(1, 9, true, true);
}

/// The Ethernet-only network refuses a V2 board by its ID, saying where
/// such a set runs.
#[test]
fn the_ethernet_only_network_refuses_a_v2_board() {
    let refused = EthNetwork::new(mixed(2), Default::default());
    let Err(e) = refused else {
        panic!("a V2 board was taken onto the Ethernet-only network");
    };
    assert_eq!(
        e,
        NetworkError::NotV3Rev9 {
            board: 2,
            fpga: FpgaVersion::V2,
            profile: Profile::Rev8,
        }
    );
    let message = e.to_string();
    assert!(message.contains("board 2"), "{message}");
    assert!(message.contains("without --network eth"), "{message}");
}
