//! Rev 9 on FPGA V2: the bridge stays (FireWire behind one Ethernet
//! board) and takes the host's Ethernet broadcasts by UDP multicast, as
//! the Rev 9 host sends them once it has read the bridge's firmware as 9
//! or later (EthUdpPort `PacketSend`: `DEST_MULTICAST` to
//! 224.0.0.100:1394; everything else by unicast to base + the hub's board
//! ID). Driven as raw datagrams inside a
//! network namespace the test makes itself (`unshare -n`, root): the
//! stock 169.254.0.100 address on `lo`, the multicast route, the group
//! joined by the emulator. A Rev 8 bridge ignores the group (it answers
//! the subnet broadcast only). Without root, `unshare` or `ip` the test
//! says so and skips.

use crate::common;
use crate::eth_common;

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use common::qla1s;
use eth_common::{
    Answer, BASE_IP, ENTRY, ETH_STATUS, FIRMWARE_VERSION, HARDWARE_VERSION, IP_ADDRESS, QLA1,
    decode, hub_bytes, in_own_network_namespace, request_datagram, stock_addresses_on_lo,
};
use firelink_board::qla::config::{FpgaVersion, Profile};
use firelink_emulate::qla::eth_serve::MULTICAST_GROUP;
use firelink_emulate::{BridgeStats, ServeConfig, bind, bind_multicast, serve_groups};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr, Tcode};

/// Long enough never to fire on a loaded machine; no test measures time.
const RECEIVE_TIMEOUT: Duration = Duration::from_secs(5);
/// The UDP port of the boards (EthUdpPort's `UDP_port`).
const PORT: u16 = 1394;
/// The bridge board's address at Rev 9: base + its board ID (0).
const BRIDGE_IP: Ipv4Addr = Ipv4Addr::new(169, 254, 0, 100);
/// Boards on the FireWire bus behind the bridge.
const BOARDS: u8 = 4;
/// Broadcast cycles run through the group.
const CYCLES: u32 = 500;

/// A bridge of V2 boards at `profile` serving `BRIDGE_IP` and the group.
struct Served {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<BridgeStats>>,
}

impl Served {
    fn start(profile: Profile) -> Served {
        let boards: Vec<_> = qla1s(BOARDS, profile)
            .into_iter()
            .map(|b| b.with_fpga(FpgaVersion::V2))
            .collect();
        let (unicast, _) = bind(&ServeConfig {
            listen: SocketAddr::new(IpAddr::V4(BRIDGE_IP), PORT),
            loopback_broadcast: false,
        })
        .unwrap();
        let group = bind_multicast(MULTICAST_GROUP, PORT).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut bridge = common::bridge(boards);
            serve_groups(&mut bridge, &unicast, &[&group], &flag, |_| {}).unwrap();
            bridge.stats()
        });
        Served {
            stop,
            thread: Some(thread),
        }
    }

    fn stop(mut self) -> BridgeStats {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

/// The Rev 9 host over a bridge: its socket, labels and the bus
/// generation its replies carry.
struct BridgeHost {
    socket: UdpSocket,
    tl: u8,
    generation: u8,
    buf: Vec<u8>,
}

impl BridgeHost {
    fn new() -> BridgeHost {
        let socket = UdpSocket::bind(SocketAddr::new(
            IpAddr::V4(Ipv4Addr::new(169, 254, 0, 1)),
            0,
        ))
        .unwrap();
        socket.set_multicast_loop_v4(true).unwrap();
        socket.set_read_timeout(Some(RECEIVE_TIMEOUT)).unwrap();
        BridgeHost {
            socket,
            tl: 0,
            generation: 0,
            buf: vec![0; 4096],
        }
    }

    fn header(&mut self, node: u8) -> AsyncHeader {
        self.tl = (self.tl + 1) & 0x3F;
        AsyncHeader::new(
            NodeId(0xFFC0 | u16::from(node & 0x3F)),
            common::HOST,
            self.tl,
        )
    }

    /// Send `repr` to the group (`group`) or to the bridge.
    fn send(&mut self, group: bool, no_forward: bool, repr: &PacketRepr<'_>) {
        let d = request_datagram(no_forward, self.generation, repr);
        let to = if group {
            IpAddr::V4(MULTICAST_GROUP)
        } else {
            IpAddr::V4(BRIDGE_IP)
        };
        self.socket.send_to(&d, SocketAddr::new(to, PORT)).unwrap();
    }

    /// The next reply, its label checked; the generation kept.
    fn receive(&mut self) -> (SocketAddr, Answer) {
        let (n, from) = self.socket.recv_from(&mut self.buf).expect("a reply");
        let a = decode(&self.buf[..n]);
        assert_eq!(a.tl, self.tl, "the reply to the last request");
        self.generation = a.extra.generation;
        (from, a)
    }

    fn qread(&mut self, group: bool, node: u8, no_forward: bool, offset: u64) -> Answer {
        let header = self.header(node);
        self.send(
            group,
            no_forward,
            &PacketRepr::ReadQuadletRequest { header, offset },
        );
        let (from, a) = self.receive();
        assert_eq!(from, SocketAddr::new(IpAddr::V4(BRIDGE_IP), PORT));
        a
    }

    fn qwrite(&mut self, group: bool, node: u8, offset: u64, data: u32) {
        let header = self.header(node);
        let repr = PacketRepr::WriteQuadletRequest {
            header,
            offset,
            data,
        };
        self.send(group, false, &repr);
    }
}

/// The Rev 9 host's `InitNodes` through the group (its requests flagged
/// for Ethernet broadcast, sent by multicast once it knows the bridge runs
/// Rev 9): the hub's identity read by node 63 with the no-forward flag,
/// answered by the bridge from its own address; the IP write, after which
/// every board holds base + its ID. Then `CYCLES` broadcast cycles as the
/// host runs them over a bridge: the query, the hub read and the command
/// block by unicast to base + the hub's ID. Returns the sequence errors.
fn rev9_bridge_by_multicast() -> u64 {
    let mut host = BridgeHost::new();
    let a = host.qread(true, 63, true, HARDWARE_VERSION);
    assert_eq!(a.quadlets, vec![QLA1]);
    let a = host.qread(true, 63, true, FIRMWARE_VERSION);
    assert_eq!(a.quadlets, vec![9]);
    let a = host.qread(true, 63, true, ETH_STATUS);
    assert_eq!(
        a.quadlets[0] >> 30,
        0b10,
        "FPGA V2: Ethernet present, not V3"
    );
    host.qwrite(true, 63, IP_ADDRESS, BASE_IP);
    // The write came by the group, the reads come by unicast: read the
    // bridge's own IP until the write has been taken (the reference host
    // sleeps 0.2 s instead); each read is bounded by the receive guard.
    let mut bridge_ip = 0;
    for _ in 0..1000 {
        bridge_ip = host.qread(false, 63, true, IP_ADDRESS).quadlets[0];
        if bridge_ip == BASE_IP {
            break;
        }
    }
    assert_eq!(bridge_ip.to_le_bytes(), [169, 254, 0, 100]);
    // Each node behind the bridge, by its FireWire node ID: its board ID
    // (STATUS bits 27:24) and the IP it stored.
    let mut ids = Vec::new();
    for node in 0..BOARDS {
        let status = host.qread(false, node, false, 0).quadlets[0];
        let id = ((status >> 24) & 0xF) as u8;
        let a = host.qread(false, node, false, IP_ADDRESS);
        assert_eq!(a.quadlets[0].to_le_bytes(), [169, 254, 0, 100 + id]);
        ids.push(id);
    }
    ids.sort_unstable();
    assert_eq!(ids, (0..BOARDS).collect::<Vec<_>>());
    let n = usize::from(BOARDS);
    let mask = (1u16 << BOARDS) - 1;
    let mut errors = 0;
    for cycle in 0..CYCLES {
        let seq = (cycle % 0xFFFF + 1) as u16;
        host.qwrite(false, 63, 0x1800, u32::from(seq) << 16 | u32::from(mask));
        let header = host.header(0);
        host.send(
            false,
            false,
            &PacketRepr::ReadBlockRequest {
                header,
                offset: 0x1000,
                data_length: hub_bytes(n),
                extended_tcode: 0,
            },
        );
        let (_, hub) = host.receive();
        if hub.tcode != Tcode::ReadBlockResponse || hub.quadlets.len() != ENTRY * n + 1 {
            errors += 1;
            continue;
        }
        // Every board's entry once, with this query's sequence.
        let mut seen = 0u16;
        for e in hub.quadlets.chunks(ENTRY).take(n) {
            let board = (e[2] >> 24) & 0xF;
            let ok = (e[0] >> 16) & 0xFF == u32::from(seq & 0xFF) && e[0] & 0x8000 == 0;
            if !ok || seen & (1 << board) != 0 {
                errors += 1;
            }
            seen |= 1 << board;
        }
        if seen != mask {
            errors += 1;
        }
        let header = host.header(63);
        let commands = command_block(n, cycle);
        host.send(
            false,
            false,
            &PacketRepr::WriteBlockRequest {
                header,
                offset: 0,
                extended_tcode: 0,
                data: &commands,
            },
        );
    }
    errors
}

/// The command block of `n` QLA1 Rev 9 boards: every motor's command
/// valid and changing with the cycle.
fn command_block(n: usize, cycle: u32) -> Vec<u8> {
    use firelink_wire::qla::broadcast::emit_command_block;
    use firelink_wire::qla::realtime::WriteBlockRepr;
    use firelink_wire::qla::registers::DacWord;
    let layout = qla1s(1, Profile::Rev9)[0].layout();
    let blocks: Vec<WriteBlockRepr> = (0..n as u8)
        .map(|id| {
            let mut b = WriteBlockRepr::new(layout, id);
            for dac in b.dac.iter_mut().take(layout.motors()) {
                *dac = DacWord::default()
                    .with_valid(true)
                    .with_command(0x8000 + (cycle % 64) as u16);
            }
            b
        })
        .collect();
    let mut buf = vec![0u8; 2048];
    let len = emit_command_block(&mut buf, &blocks).unwrap();
    buf.truncate(len);
    buf
}

/// A Rev 8 bridge: a request to the group is foreign traffic (no reply);
/// the same request by unicast is answered.
fn rev8_bridge_ignores_the_group() {
    let mut host = BridgeHost::new();
    host.socket
        .set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let header = host.header(63);
    host.send(
        true,
        true,
        &PacketRepr::ReadQuadletRequest {
            header,
            offset: FIRMWARE_VERSION,
        },
    );
    let mut buf = [0u8; 256];
    assert!(
        host.socket.recv_from(&mut buf).is_err(),
        "a Rev 8 bridge answered a multicast request"
    );
    host.socket.set_read_timeout(Some(RECEIVE_TIMEOUT)).unwrap();
    let a = host.qread(false, 63, true, FIRMWARE_VERSION);
    assert_eq!(a.quadlets, vec![8]);
}

/// Inside the namespace: the addresses, the multicast route; both bridges.
fn namespace_body() {
    stock_addresses_on_lo(&[0]);
    let served = Served::start(Profile::Rev9);
    let errors = rev9_bridge_by_multicast();
    let stats = served.stop();
    assert_eq!(errors, 0, "sequence errors; {stats}");
    assert_eq!(stats.dropped(), 0, "{stats}");

    let served = Served::start(Profile::Rev8);
    rev8_bridge_ignores_the_group();
    let _ = served.stop();
}

#[test]
fn rev9_v2_bridge_takes_group_requests_by_multicast_in_a_network_namespace() {
    in_own_network_namespace(
        module_path!(),
        "rev9_v2_bridge_takes_group_requests_by_multicast_in_a_network_namespace",
        "FIRELINK_BRIDGE_MULTICAST_NETNS",
        namespace_body,
    );
}
