//! The Ethernet-only network served over real UDP (`eth_serve`), driven by
//! the Rev 9 host's sequences as raw datagrams (EthUdpPort `InitNodes`
//! and `ScanNodes`, EthBasePort's broadcast read and command block, the
//! fallback hub read): at 1, 2, 4, 8 and 16 boards over loopback, 2000
//! cycles each as fast as the test goes, 0 sequence errors; the group
//! requests through the loopback broadcast address. The same at 1, 2, 4,
//! 8 and 16 boards by the multicast group 224.0.0.100 on the stock
//! 169.254.0.100 + ID addresses, inside a network namespace the test
//! makes itself (`unshare -n`, root); without root or `unshare` that test
//! says so and skips.

use crate::eth_common;

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::time::Duration;

use eth_common::*;
use firelink_emulate::qla::eth_network::NetworkStats;
use firelink_emulate::qla::eth_serve::{EthServeConfig, MULTICAST_GROUP};
use firelink_wire::packet::Tcode;

/// Long enough never to fire on a loaded machine; no test measures time.
const RECEIVE_TIMEOUT: Duration = Duration::from_secs(5);

/// A served network and the address of its group requests.
struct Served {
    net: ServedNetwork,
    group: SocketAddr,
}

impl Served {
    fn start(chain: &[u8], config: EthServeConfig, group: Option<Ipv4Addr>) -> Served {
        let net = ServedNetwork::start(chain, &config);
        let group_ip = group.unwrap_or(Ipv4Addr::new(127, 255, 255, 255));
        let group = SocketAddr::new(IpAddr::V4(group_ip), net.port);
        Served { net, group }
    }

    fn addr(&self, id: u8) -> SocketAddr {
        self.net.addr(id)
    }

    fn stop(self) -> NetworkStats {
        self.net.stop()
    }
}

/// The host's socket and request builder.
struct Host {
    socket: UdpSocket,
    req: Rev9Host,
    buf: Vec<u8>,
}

impl Host {
    fn new(bind: Ipv4Addr) -> Host {
        let socket = UdpSocket::bind(SocketAddr::new(IpAddr::V4(bind), 0)).unwrap();
        socket.set_broadcast(true).unwrap();
        socket.set_read_timeout(Some(RECEIVE_TIMEOUT)).unwrap();
        Host {
            socket,
            req: Rev9Host::default(),
            buf: vec![0; 4096],
        }
    }

    /// Drop whatever is queued (EthBasePort flushes before each read).
    fn flush(&mut self) -> usize {
        self.socket.set_nonblocking(true).unwrap();
        let mut n = 0;
        while self.socket.recv_from(&mut self.buf).is_ok() {
            n += 1;
        }
        self.socket.set_nonblocking(false).unwrap();
        n
    }

    fn send(&self, to: SocketAddr, d: &[u8]) {
        self.socket.send_to(d, to).unwrap();
    }

    fn receive(&mut self) -> (SocketAddr, Answer) {
        let (n, from) = self.socket.recv_from(&mut self.buf).expect("a reply");
        (from, decode(&self.buf[..n]))
    }

    fn qread(&mut self, to: SocketAddr, node: u8, offset: u64) -> (SocketAddr, Answer) {
        self.flush();
        let d = self.req.qread(node, offset);
        self.send(to, &d);
        let (from, a) = self.receive();
        assert_eq!(a.tl, self.req.tl);
        (from, a)
    }
}

/// EthUdpPort::InitNodes and ScanNodes: the IP write to the group, the
/// hub's registers by broadcast read, every board by its ID at its own
/// address (base + ID). Returns the hub.
fn init_and_scan(host: &mut Host, served: &Served, ids: &[u8]) -> u8 {
    let d = host.req.qwrite(63, IP_ADDRESS, BASE_IP);
    host.send(served.group, &d);
    // The reference host sleeps 0.2 s here (the boards' multicasts teach
    // the switches meanwhile, so only the hub answers broadcast reads).
    std::thread::sleep(Duration::from_millis(200));
    let (from, a) = host.qread(served.group, 63, HARDWARE_VERSION);
    assert_eq!(a.quadlets, vec![QLA1]);
    let hub = a.source.phy();
    assert_eq!(
        from,
        served.addr(hub),
        "the hub answers from its own address"
    );
    let (_, a) = host.qread(served.group, 63, FIRMWARE_VERSION);
    assert_eq!(a.quadlets, vec![9]);
    let (_, a) = host.qread(served.group, 63, ETH_STATUS);
    assert_eq!(a.quadlets[0] >> 30, 0b01, "FPGA V3");
    for &id in ids {
        let (from, a) = host.qread(served.addr(id), id, STATUS);
        assert_eq!(from, served.addr(id));
        assert_eq!(a.source.phy(), id);
        assert_eq!((a.quadlets[0] >> 24) & 0xF, u32::from(id));
        assert!(a.extra.flags.no_forward);
        let (_, a) = host.qread(served.addr(id), id, IP_ADDRESS);
        let last = a.quadlets[0].to_le_bytes()[3];
        assert_eq!(last, 100 + id, "the IP register holds base + ID");
    }
    hub
}

/// Sequence errors of one broadcast read answered by `a`: every entry
/// placed by its board ID, with the query's sequence; the boards expected
/// all there, once.
fn sequence_errors(a: &Answer, group: &[u8], seq: u16) -> u64 {
    let n = group.len();
    if a.tcode != Tcode::ReadBlockResponse || a.quadlets.len() != ENTRY * n + 1 {
        return n as u64;
    }
    let mut errors = 0;
    let mut seen = 0u16;
    for e in a.quadlets.chunks(ENTRY).take(n) {
        let board = ((e[2] >> 24) & 0xF) as u8;
        let ok_seq = (e[0] >> 16) & 0xFF == u32::from(seq & 0xFF) && e[0] & 0x8000 == 0;
        if !ok_seq || !group.contains(&board) || seen & (1 << board) != 0 {
            errors += 1;
        }
        seen |= 1 << board;
    }
    errors
}

/// 2000 broadcast cycles of the Rev 9 host on `n` boards; every 50th
/// cycle the host "misses" the unsolicited response and reads the hub.
/// Boards whose blocks overflow one hub (more than 15 QLA1 boards) are
/// read in groups of 8, each with its own query, as Firelink's host does.
fn cycles(served: &Served, host: &mut Host, chain: &[u8], cycles: u32) -> (u64, u64) {
    let mut ids = chain.to_vec();
    ids.sort_unstable();
    let hub = init_and_scan(host, served, &ids);
    assert_eq!(hub, chain[0], "the board nearest the host is the hub");
    let groups: Vec<Vec<u8>> = if ids.len() > 15 {
        ids.chunks(8).map(<[u8]>::to_vec).collect()
    } else {
        vec![ids.clone()]
    };
    let (mut errors, mut fallbacks) = (0, 0);
    let mut seq: u16 = 0;
    for cycle in 0..cycles {
        for group in &groups {
            seq = seq.wrapping_add(1).max(1);
            let mask = group.iter().fold(0u16, |m, &b| m | 1 << b);
            host.flush();
            let d = host.req.query(seq, mask);
            let tl = host.req.tl;
            host.send(served.group, &d);
            let (from, a) = host.receive();
            if from != served.addr(hub) || a.tl != tl || a.source.phy() != hub {
                errors += 1;
                continue;
            }
            // Placed by board ID: the entries come in chain order.
            let came: Vec<u8> = a
                .quadlets
                .chunks(ENTRY)
                .take(group.len())
                .map(|e| ((e[2] >> 24) & 0xF) as u8)
                .collect();
            let expected: Vec<u8> = chain
                .iter()
                .copied()
                .filter(|b| group.contains(b))
                .collect();
            if came != expected {
                errors += 1;
            }
            errors += sequence_errors(&a, group, seq);
            if cycle % 50 == 0 {
                // Missed on the host's side: the fallback hub read.
                fallbacks += 1;
                host.flush();
                let d = host.req.bread(hub, 0x1000, hub_bytes(group.len()));
                host.send(served.addr(hub), &d);
                let (_, h) = host.receive();
                if h.tl != host.req.tl
                    || h.quadlets[..ENTRY * group.len()] != a.quadlets[..ENTRY * group.len()]
                {
                    errors += 1;
                }
                errors += sequence_errors(&h, group, seq);
            }
        }
        let d = host.req.commands(&ids, 0x8000 + (cycle % 64) as u16);
        host.send(served.group, &d);
    }
    (errors, fallbacks)
}

fn loopback_run(n: u8) {
    let chain = shuffled(n);
    let served = Served::start(
        &chain,
        EthServeConfig {
            port: 0,
            ..EthServeConfig::default()
        },
        None,
    );
    let mut host = Host::new(Ipv4Addr::LOCALHOST);
    let (errors, fallbacks) = cycles(&served, &mut host, &chain, 2000);
    let stats = served.stop();
    assert_eq!(errors, 0, "{n} boards: sequence errors; {stats}");
    let groups = if n > 15 { 2 } else { 1 };
    assert_eq!(fallbacks, 40 * groups);
    assert_eq!(stats.dropped(), 0, "{stats}");
    assert_eq!(stats.broadcast_responses, 2000 * groups, "{stats}");
}

#[test]
fn rev9_host_on_1_board_over_loopback() {
    loopback_run(1);
}

#[test]
fn rev9_host_on_2_boards_over_loopback() {
    loopback_run(2);
}

#[test]
fn rev9_host_on_4_boards_over_loopback() {
    loopback_run(4);
}

#[test]
fn rev9_host_on_8_boards_over_loopback() {
    loopback_run(8);
}

#[test]
fn rev9_host_on_16_boards_over_loopback() {
    loopback_run(16);
}

/// Inside the namespace: the stock addresses of 16 boards on `lo`, the
/// multicast route; then at each board count the group joined and the
/// host's group requests by multicast, 2000 cycles, 0 sequence errors.
fn namespace_body() {
    stock_addresses_on_lo(&(0..16).collect::<Vec<u8>>());
    for n in BOARD_COUNTS {
        let chain = shuffled(n);
        let served = Served::start(
            &chain,
            EthServeConfig {
                base: Ipv4Addr::new(169, 254, 0, 100),
                port: 1394,
                loopback_broadcast: false,
                multicast: Some(MULTICAST_GROUP),
            },
            Some(MULTICAST_GROUP),
        );
        let mut host = Host::new(Ipv4Addr::new(169, 254, 0, 1));
        host.socket.set_multicast_loop_v4(true).unwrap();
        let (errors, fallbacks) = cycles(&served, &mut host, &chain, 2000);
        let stats = served.stop();
        let groups = if n > 15 { 2 } else { 1 };
        assert_eq!(errors, 0, "{n} boards: sequence errors; {stats}");
        assert_eq!(fallbacks, 40 * groups, "{n} boards");
        assert_eq!(
            stats.broadcast_responses,
            2000 * groups,
            "{n} boards: {stats}"
        );
        assert_eq!(stats.dropped(), 0, "{n} boards: {stats}");
    }
}

/// The board counts of the proof (issue 31).
const BOARD_COUNTS: [u8; 5] = [1, 2, 4, 8, 16];

#[test]
fn rev9_host_by_multicast_at_1_to_16_boards_in_a_network_namespace() {
    in_own_network_namespace(
        module_path!(),
        "rev9_host_by_multicast_at_1_to_16_boards_in_a_network_namespace",
        "FIRELINK_ETH_NETNS",
        namespace_body,
    );
}
