//! Firelink's own host library (`firelink_host::eth::EthPort` under
//! `IoSystem`) on the Ethernet-only network served over real UDP on
//! loopback (`eth_serve`, boards at 127.0.0.100 + ID, the group requests
//! through the loopback broadcast address): discovery by board ID at 1, 4,
//! 8 and 16 boards; 2000 broadcast cycles at 4 and 8 boards with 0 errors,
//! each answered by the hub's unsolicited response; the fallback hub read
//! when the response is not the one asked for. No test measures time.

use crate::common;
use crate::eth_common;

use std::time::Duration;

use eth_common::{ServedNetwork, shuffled};
use firelink_emulate::qla::eth_serve::EthServeConfig;
use firelink_host::eth::{EthAddresses, EthPort};
use firelink_host::port::Port;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_wire::qla::registers::FpgaVersion;

/// Long enough never to fire on a loaded machine.
const TIMEOUT: Duration = Duration::from_secs(5);

/// The scan's time-out: each absent board ID (of 16) is waited out once,
/// as the Rev 9 host's scan does; a present board on loopback answers in
/// microseconds, so a second is far beyond what load adds.
const SCAN_TIMEOUT: Duration = Duration::from_secs(1);

/// The boards of `chain` (in chain order from the host), served on a
/// free port.
struct Served(ServedNetwork);

impl Served {
    fn start(chain: &[u8]) -> Served {
        let config = EthServeConfig {
            port: 0,
            ..EthServeConfig::default()
        };
        Served(ServedNetwork::start(chain, &config))
    }

    /// An initialised host port on this network, with the scan's
    /// time-out.
    fn host(&self) -> EthPort {
        let mut port = EthPort::open(EthAddresses::loopback(self.0.port)).unwrap();
        port.set_timeout(SCAN_TIMEOUT);
        port.init().unwrap();
        port
    }

    fn stop(self) -> firelink_emulate::qla::eth_network::NetworkStats {
        self.0.stop()
    }
}

fn scan_finds(n: u8) {
    let chain = shuffled(n);
    let served = Served::start(&chain);
    let mut port = served.host();
    let (hub, hw, fw, eth) = port.hub_identity().unwrap();
    assert_eq!(hub, chain[0], "the board nearest the host is the hub");
    assert_eq!(hw, 0x514C_4131, "QLA1");
    assert_eq!(fw, 9);
    assert_eq!(FpgaVersion::from_eth_status(eth), Ok(FpgaVersion::V3));
    let report = scan(&mut port).unwrap();
    let mut ids = chain.clone();
    ids.sort_unstable();
    let found: Vec<u8> = report.boards.iter().map(|b| b.board_id).collect();
    assert_eq!(found, ids);
    for b in &report.boards {
        assert_eq!(b.node, b.board_id, "addressed by board ID");
        assert_eq!(b.fpga, FpgaVersion::V3);
    }
    assert_eq!(
        report.bridge_board,
        Some(chain[0]),
        "the hub answers node 63"
    );
    assert_eq!(report.protocol, Protocol::Broadcast);
    // Every board at base + ID holds that address.
    for &id in &ids {
        let ip = port
            .read_quadlet(firelink_host::port::Dest::node(id), 11)
            .unwrap();
        assert_eq!(ip.to_le_bytes(), [127, 0, 0, 100 + id]);
    }
    let stats = served.stop();
    assert_eq!(stats.dropped(), 0, "{stats}");
}

#[test]
fn scan_finds_1_board_by_id() {
    scan_finds(1);
}

#[test]
fn scan_finds_4_boards_by_id() {
    scan_finds(4);
}

#[test]
fn scan_finds_8_boards_by_id() {
    scan_finds(8);
}

#[test]
fn scan_finds_16_boards_by_id() {
    scan_finds(16);
}

/// `cycles` broadcast cycles (read, then the command block) through
/// `IoSystem`; returns the system.
fn run(served: &Served, options: IoOptions, cycles: u32) -> IoSystem<EthPort> {
    let mut port = served.host();
    let report = scan(&mut port).unwrap();
    assert_eq!(report.protocol, Protocol::Broadcast);
    port.set_timeout(TIMEOUT);
    let mut io = IoSystem::with_scan(port, &report, options).unwrap();
    for _ in 0..cycles {
        let r = io.read_all();
        assert!(r.all_ok(), "{:?}", r.missed_boards().collect::<Vec<_>>());
        io.write_all();
    }
    io
}

fn cycles_at(n: u8) {
    let chain = shuffled(n);
    let served = Served::start(&chain);
    let io = run(&served, IoOptions::default(), 2000);
    let stats = io.stats();
    assert_eq!(stats.cycles, 2000);
    assert_eq!(stats.clean_cycles, 2000);
    assert_eq!(stats.total_errors(), 0, "{stats:?}");
    let eth = io.port().eth_stats();
    assert_eq!(eth.queries, 2000);
    // Each query answered by the hub unasked, or (a response later than
    // the time-out, which no test relies on) by the hub read.
    assert_eq!(eth.responses + eth.fallbacks, 2000, "{eth:?}");
    assert_eq!(io.hub_board(), chain[0]);
    drop(io);
    let net = served.stop();
    assert_eq!(net.dropped(), 0, "{net}");
    assert_eq!(net.broadcast_responses, 2000, "{net}");
}

#[test]
fn two_thousand_broadcast_cycles_at_4_boards() {
    cycles_at(4);
}

#[test]
fn two_thousand_broadcast_cycles_at_8_boards() {
    cycles_at(8);
}

/// A hub read longer than the hub block: the unsolicited response (the
/// hub block's length) is not the answer asked for, so every cycle falls
/// back to reading the hub, and the blocks still land by board ID.
#[test]
fn fallback_hub_read_when_the_response_does_not_answer() {
    const CYCLES: u64 = 5;
    let chain = [2u8, 0, 3, 1];
    let served = Served::start(&chain);
    let mut port = served.host();
    let report = scan(&mut port).unwrap();
    // The refused response is waited out every cycle: a time-out long
    // enough for any loaded machine, few cycles.
    port.set_timeout(Duration::from_secs(1));
    let options = IoOptions {
        hub_read_quadlets: Some(4 * 33 + 1 + 8),
        ..IoOptions::default()
    };
    let mut io = IoSystem::with_scan(port, &report, options).unwrap();
    for _ in 0..CYCLES {
        let r = io.read_all();
        assert!(r.all_ok(), "{:?}", r.missed_boards().collect::<Vec<_>>());
        io.write_all();
    }
    let eth = io.port().eth_stats();
    assert_eq!(eth.queries, CYCLES);
    assert_eq!(eth.responses, 0, "{eth:?}");
    assert_eq!(eth.fallbacks, CYCLES, "{eth:?}");
    assert_eq!(io.stats().total_errors(), 0, "{:?}", io.stats());
    let refused = io.port().link_stats().refused();
    assert!(
        refused >= CYCLES,
        "each response refused and counted: {refused}"
    );
    drop(io);
    let _ = served.stop();
}

/// The probe `udp:HOST` makes before choosing: the Ethernet-only network
/// answers at the loopback broadcast address from the hub's own address
/// (V3, Rev 9: Ethernet-only, board 0 at 127.0.0.100); a V2 bridge at Rev
/// 8 answers from its address and is not.
#[test]
fn probe_tells_the_ethernet_only_network_from_the_bridge() {
    let chain = [3u8, 1, 0, 2];
    let served = Served::start(&chain);
    let group = std::net::SocketAddr::new(
        std::net::IpAddr::V4(firelink_host::eth::LOOPBACK_BROADCAST),
        served.0.port,
    );
    let probe = EthPort::probe(group, TIMEOUT).unwrap();
    assert!(probe.is_ethernet_only(), "{probe:?}");
    assert_eq!(probe.board, 3, "the hub");
    assert_eq!(
        probe.ethernet_only_addresses(),
        Some(EthAddresses::loopback(served.0.port))
    );
    let _ = served.stop();

    let bridge =
        common::Server::start(common::qla1s(2, firelink_board::qla::config::Profile::Rev8));
    let probe = EthPort::probe(bridge.addr, TIMEOUT).unwrap();
    assert!(!probe.is_ethernet_only(), "{probe:?}");
    assert_eq!(probe.from, bridge.addr);
    assert_eq!(probe.firmware, 8);
    let _ = bridge.stop();
}

/// `udp:HOST` and `udpfw:HOST` as the port strings open them
/// (`UdpNetPort`): at the Ethernet-only network's group address `udp`
/// chooses that network and scans its boards by ID, `udpfw` the bridge,
/// which finds no bridge there; at a V2 bridge at Rev 8 `udp` keeps the
/// bridge and scans through it.
#[test]
fn udp_chooses_the_ethernet_only_network_and_udpfw_the_bridge() {
    use firelink_host::eth::UdpNetPort;
    use firelink_host::udp::WaitMode;
    let chain = [1u8, 0];
    let served = Served::start(&chain);
    let group = std::net::SocketAddr::new(
        std::net::IpAddr::V4(firelink_host::eth::LOOPBACK_BROADCAST),
        served.0.port,
    );
    let mut port = UdpNetPort::open(group, false, SCAN_TIMEOUT, WaitMode::Blocking).unwrap();
    assert!(port.is_ethernet_only());
    let found: Vec<u8> = scan(&mut port)
        .unwrap()
        .boards
        .iter()
        .map(|b| b.board_id)
        .collect();
    assert_eq!(found, vec![0, 1]);
    let forced = UdpNetPort::open(group, true, SCAN_TIMEOUT, WaitMode::Blocking).unwrap();
    assert!(!forced.is_ethernet_only());
    drop(forced);
    let _ = served.stop();

    let bridge =
        common::Server::start(common::qla1s(2, firelink_board::qla::config::Profile::Rev8));
    let mut port = UdpNetPort::open(bridge.addr, false, SCAN_TIMEOUT, WaitMode::Blocking).unwrap();
    assert!(!port.is_ethernet_only());
    let report = scan(&mut port).unwrap();
    assert_eq!(report.boards.len(), 2);
    assert_eq!(report.bridge_board, Some(0));
    let _ = bridge.stop();
}
