//! The host library against recorded exchanges (`tests/data/*.pcap`, see
//! `tests/data/README.md`): the same calls must send exactly the recorded
//! requests and reach the recorded result, with no board and no bus.

use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_host::replay::ReplayPort;
use firelink_host::{HostError, Port};

fn replay(name: &str) -> ReplayPort {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    ReplayPort::from_pcap(name, &bytes).unwrap()
}

/// Every recorded packet played, nothing asked that was not recorded.
fn played_to_the_end(port: &ReplayPort) {
    assert_eq!(port.divergence(), None);
    assert_eq!(port.remaining(), 0, "packets left unplayed");
}

#[test]
fn a_scan_of_four_boards_on_the_simulated_bus() {
    let mut port = replay("scan-sim4-rev8.pcap");
    let report = scan(&mut port).unwrap();
    assert_eq!(report.boards.len(), 4);
    assert!(report.boards.iter().all(|b| b.firmware == 8));
    assert_eq!(report.protocol, Protocol::Broadcast);
    assert_eq!(report.bridge_board, None);
    played_to_the_end(&port);
}

/// `monitor --once N`: open the I/O system, then N cycles.
fn cycles(name: &str, protocol: Protocol, n: usize, boards: usize) {
    let port = replay(name);
    let config = IoOptions {
        protocol: Some(protocol),
        ..IoOptions::default()
    };
    let (mut io, scan) = IoSystem::open(port, config).unwrap();
    assert_eq!(scan.boards.len(), boards);
    for _ in 0..n {
        let r = *io.cycle();
        assert!(r.all_ok(), "{name}: {r:?}");
        io.recover().unwrap();
    }
    assert_eq!(io.stats().total_errors(), 0);
    assert!(io.boards().iter().all(|b| b.is_valid()));
    played_to_the_end(io.port());
}

#[test]
fn broadcast_cycles_of_four_boards_on_the_simulated_bus() {
    cycles("cycles-sim4-rev8-broadcast.pcap", Protocol::Broadcast, 5, 4);
}

#[test]
fn sequential_cycles_of_two_seed_profile_boards() {
    cycles(
        "cycles-sim2-seed-sequential.pcap",
        Protocol::Sequential,
        3,
        2,
    );
}

#[test]
fn a_scan_through_the_ethernet_bridge() {
    let mut port = replay("scan-udp2-rev8.pcap");
    let report = scan(&mut port).unwrap();
    assert_eq!(report.boards.len(), 2);
    assert_eq!(report.bridge_board, Some(0));
    played_to_the_end(&port);
}

#[test]
fn broadcast_cycles_through_the_ethernet_bridge() {
    cycles("cycles-udp2-rev8-broadcast.pcap", Protocol::Broadcast, 5, 2);
}

#[test]
fn a_library_that_asks_something_else_is_caught() {
    // The recording starts with the scan; a register write instead diverges.
    let mut port = replay("scan-sim4-rev8.pcap");
    let e = port
        .write_quadlet(firelink_host::Dest::node(2), 0, 1)
        .unwrap_err();
    assert!(matches!(e, HostError::InvalidRequest { .. }), "{e}");
    assert!(port.divergence().is_some());
}

#[test]
fn a_damaged_answer_in_the_recording_is_a_crc_error() {
    let path = format!(
        "{}/tests/data/scan-sim4-rev8.pcap",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut bytes = std::fs::read(path).unwrap();
    // The second record is the first answer: flip a bit of its data
    // quadlet, which the header CRC covers.
    let records: Vec<usize> = {
        let mut at = 24;
        let mut starts = Vec::new();
        while at + 16 <= bytes.len() {
            starts.push(at);
            let incl = u32::from_le_bytes(bytes[at + 8..at + 12].try_into().unwrap()) as usize;
            at += 16 + incl;
        }
        starts
    };
    let answer = records[1] + 16 + 28;
    bytes[answer + 13] ^= 0x01;
    let mut port = ReplayPort::from_pcap("damaged", &bytes).unwrap();
    // The scan's first read (HW_VERSION of node 0) gets the damaged answer.
    let e = port
        .read_quadlet(firelink_host::Dest::node(0), 4)
        .unwrap_err();
    assert!(matches!(e, HostError::Wire(_)), "{e}");
    assert_eq!(port.link_stats().bad_crc, 1);
}
