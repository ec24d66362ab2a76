//! The port wrappers over a simulated bus of emulated boards: the tracing
//! port records every call and packet, the faulty port loses and damages
//! packets and the library reports each as a live link would.

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_host::fault::{FaultyPort, LinkFaults};
use firelink_host::port::Direction;
use firelink_host::qla::scan::scan;
use firelink_host::sim::SimPort;
use firelink_host::trace::{CallKind, TracingPort};
use firelink_host::{Dest, HostError, Port};
use firelink_wire::packet::{Packet, Tcode};
use firelink_wire::pcap::Records;

fn port(n: u8) -> SimPort {
    let boards = (0..n)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
        .collect();
    let rig = BoardRig::daisy_chain(boards, &RigOptions::default());
    SimPort::new(rig.bus, rig.host)
}

#[test]
fn the_tracing_port_records_calls_and_packets_and_writes_them_as_pcap() {
    let mut port = TracingPort::new(port(2));
    assert!(port.captures_packets());
    let report = scan(&mut port).unwrap();
    assert_eq!(report.boards.len(), 2);
    let calls = port.calls();
    // The scan's broadcast no-forward read is refused before it is sent;
    // then five identity reads per board.
    assert_eq!(calls.len(), 1 + 5 * 2);
    assert!(
        calls
            .iter()
            .skip(1)
            .all(|c| c.kind == CallKind::ReadQuadlet && c.error.is_none())
    );
    let packets = port.packets();
    assert_eq!(packets.len(), 2 * 10, "a request and a response per read");
    for pair in packets.chunks(2) {
        assert_eq!(pair[0].direction, Direction::Sent);
        assert_eq!(pair[1].direction, Direction::Received);
        let (req, resp) = (
            Packet::new_checked(&pair[0].bytes[..]).unwrap(),
            Packet::new_checked(&pair[1].bytes[..]).unwrap(),
        );
        assert_eq!(req.tcode(), Tcode::ReadQuadletRequest);
        assert_eq!(resp.tcode(), Tcode::ReadQuadletResponse);
        assert_eq!(req.tl(), resp.tl());
        assert!(pair[1].at_ps > pair[0].at_ps);
    }
    let mut file = Vec::new();
    port.write_pcap(&mut file).unwrap();
    let records: Vec<_> = Records::new(&file).unwrap().map(Result::unwrap).collect();
    assert_eq!(records.len(), packets.len());
    assert_eq!(records[1].direction(), Some(Direction::Received));
    assert_eq!(records[1].payload, &packets[1].bytes[..]);
}

#[test]
fn lost_packets_are_time_outs_naming_the_real_label() {
    let faults = LinkFaults {
        drop: 1.0,
        corrupt: 0.0,
    };
    let mut port = FaultyPort::new(port(2), faults, 3).unwrap();
    for expected_tl in 1..=3 {
        let e = port.read_quadlet(Dest::node(1), 4).unwrap_err();
        assert!(
            matches!(e, HostError::Timeout { node: 1, tl, .. } if tl == expected_tl),
            "{e}"
        );
    }
    assert_eq!(port.counts().dropped, 3);
    assert_eq!(port.link_stats().timeouts, 3);
}

#[test]
fn damaged_packets_are_crc_errors_or_refusals_never_data() {
    let faults = LinkFaults {
        drop: 0.0,
        corrupt: 1.0,
    };
    let mut port = FaultyPort::new(port(2), faults, 9).unwrap();
    for _ in 0..20 {
        match port.read_quadlet(Dest::node(0), 4) {
            // The request was damaged: the board drops it (header CRC) or
            // the answer is: either way no value comes back.
            Err(HostError::Timeout { .. } | HostError::Wire(_) | HostError::Ack { .. }) => {}
            other => panic!("a damaged exchange gave {other:?}"),
        }
    }
    assert_eq!(port.counts().corrupted, port.counts().packets);
}

#[test]
fn the_same_seed_hurts_the_same_packets() {
    let run = |seed| {
        let faults = LinkFaults {
            drop: 0.3,
            corrupt: 0.3,
        };
        let mut port = FaultyPort::new(port(2), faults, seed).unwrap();
        let outcomes: Vec<String> = (0..30)
            .map(|_| format!("{:?}", port.read_quadlet(Dest::node(1), 4)))
            .collect();
        (outcomes, port.counts())
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5).0, run(6).0);
}
