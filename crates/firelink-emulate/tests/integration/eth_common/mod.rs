//! The Rev 9 host's side of the Ethernet-only network as raw datagrams
//! (EthBasePort.cpp, EthUdpPort.cpp): every request with the no-forward
//! flag, source `0xFFD0`, destination `0xFFC0 | node` (a board ID, or 63),
//! transaction labels counting up; replies decoded with their extra data;
//! the unsolicited hub block placed by the board ID in each entry's
//! STATUS, as `BasePort` does when the blocks are not in board order.
//! Replies are decoded by the bridge tests' `common::decode` (the same
//! framing).
#![allow(dead_code)]

use firelink_board::qla::config::{BoardConfig, FpgaVersion, Hardware, Profile};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};
use firelink_wire::qla::broadcast::emit_command_block;
use firelink_wire::qla::realtime::WriteBlockRepr;
use firelink_wire::qla::registers::DacWord;

pub use crate::common::{Answer, decode, request_datagram};

/// The host's source ID.
pub const HOST: NodeId = NodeId(0xFFD0);
/// STATUS (register 0).
pub const STATUS: u64 = 0;
/// HARDWARE_VERSION (register 4).
pub const HARDWARE_VERSION: u64 = 4;
/// FIRMWARE_VERSION (register 7).
pub const FIRMWARE_VERSION: u64 = 7;
/// REG_IPADDR (register 11).
pub const IP_ADDRESS: u64 = 11;
/// ETH_STATUS (register 12).
pub const ETH_STATUS: u64 = 12;
/// 169.254.0.100 as the host writes it (`sin_addr.s_addr` read as a
/// little-endian quadlet): the first byte lowest.
pub const BASE_IP: u32 = u32::from_le_bytes([169, 254, 0, 100]);
/// QLA1's fourcc.
pub const QLA1: u32 = 0x514C_4131;
/// Quadlets of a QLA1 Rev 9 hub entry (header + 32).
pub const ENTRY: usize = 33;

/// QLA1 boards on FPGA V3 at Rev 9 with these IDs, in this order.
pub fn v3_rev9(ids: &[u8]) -> Vec<BoardConfig> {
    ids.iter()
        .map(|&id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev9).with_fpga(FpgaVersion::V3))
        .collect()
}

/// The Rev 9 host's request builder.
#[derive(Debug, Default)]
pub struct Rev9Host {
    pub tl: u8,
}

impl Rev9Host {
    fn header(&mut self, node: u8) -> AsyncHeader {
        self.tl = (self.tl + 1) & 0x3F;
        AsyncHeader::new(NodeId(0xFFC0 | u16::from(node & 0x3F)), HOST, self.tl)
    }

    fn datagram(repr: &PacketRepr<'_>) -> Vec<u8> {
        request_datagram(true, 0, repr)
    }

    pub fn qread(&mut self, node: u8, offset: u64) -> Vec<u8> {
        let header = self.header(node);
        Self::datagram(&PacketRepr::ReadQuadletRequest { header, offset })
    }

    pub fn qwrite(&mut self, node: u8, offset: u64, data: u32) -> Vec<u8> {
        let header = self.header(node);
        Self::datagram(&PacketRepr::WriteQuadletRequest {
            header,
            offset,
            data,
        })
    }

    pub fn bread(&mut self, node: u8, offset: u64, bytes: u16) -> Vec<u8> {
        let header = self.header(node);
        Self::datagram(&PacketRepr::ReadBlockRequest {
            header,
            offset,
            data_length: bytes,
            extended_tcode: 0,
        })
    }

    pub fn bwrite(&mut self, node: u8, offset: u64, data: &[u8]) -> Vec<u8> {
        let header = self.header(node);
        Self::datagram(&PacketRepr::WriteBlockRequest {
            header,
            offset,
            extended_tcode: 0,
            data,
        })
    }

    /// The query (EthBasePort `WriteBroadcastReadRequest`): sequence and
    /// board mask to node 63 at `0x1800`.
    pub fn query(&mut self, seq: u16, mask: u16) -> Vec<u8> {
        self.qwrite(63, 0x1800, u32::from(seq) << 16 | u32::from(mask))
    }

    /// The command block to node 63 at 0: each board of `ids` (ascending)
    /// gets `command` on every motor, valid.
    pub fn commands(&mut self, ids: &[u8], command: u16) -> Vec<u8> {
        let layout = v3_rev9(&[0])[0].layout();
        let mut sorted = ids.to_vec();
        sorted.sort_unstable();
        let blocks: Vec<WriteBlockRepr> = sorted
            .iter()
            .map(|&id| {
                let mut b = WriteBlockRepr::new(layout, id);
                for dac in b.dac.iter_mut().take(layout.motors()) {
                    *dac = DacWord::default().with_valid(true).with_command(command);
                }
                b
            })
            .collect();
        let mut buf = vec![0u8; 2048];
        let n = emit_command_block(&mut buf, &blocks).unwrap();
        self.bwrite(63, 0, &buf[..n])
    }
}

/// Bytes of the hub block of `n` QLA1 boards (entries and the timing
/// quadlet).
pub fn hub_bytes(n: usize) -> u16 {
    ((ENTRY * n + 1) * 4) as u16
}

/// The hub block's entries placed by the board ID in each one's STATUS
/// (entry quadlet 2): (board ID, entry) in the order they came, checked
/// against the query's sequence (its low byte, and no sequence error).
pub fn place(hub: &[u32], n: usize, seq: u16) -> Vec<(u8, Vec<u32>)> {
    assert_eq!(hub.len(), ENTRY * n + 1, "hub block length");
    hub.chunks(ENTRY)
        .take(n)
        .map(|e| {
            assert_eq!(e[0] >> 24, ENTRY as u32, "entry size in the header");
            assert_eq!(
                (e[0] >> 16) & 0xFF,
                u32::from(seq & 0xFF),
                "sequence low byte"
            );
            assert_eq!(e[0] & 0x8000, 0, "sequence error bit");
            (((e[2] >> 24) & 0xF) as u8, e.to_vec())
        })
        .collect()
}

/// A network of V3 Rev 9 QLA1 boards (`chain` in chain order from the
/// host) served by `eth_serve` on its own thread.
pub struct ServedNetwork {
    /// (board ID, its address).
    pub addrs: Vec<(u8, std::net::SocketAddr)>,
    /// The port every board listens on.
    pub port: u16,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<firelink_emulate::qla::eth_network::NetworkStats>>,
}

impl ServedNetwork {
    /// Bind as `config` says and serve.
    pub fn start(chain: &[u8], config: &firelink_emulate::qla::eth_serve::EthServeConfig) -> Self {
        use firelink_emulate::qla::eth_network::EthNetwork;
        use firelink_emulate::qla::eth_serve::{eth_bind, eth_serve};
        let mut net =
            EthNetwork::new(v3_rev9(chain), firelink_bus::ethernet::EthTiming::default()).unwrap();
        let sockets = eth_bind(config, chain).unwrap();
        let addrs = chain
            .iter()
            .map(|&id| (id, sockets.board_addr(id).unwrap()))
            .collect();
        let port = sockets.port;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = std::sync::Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            eth_serve(&mut net, &sockets, &flag, |_| {}).unwrap();
            net.stats()
        });
        ServedNetwork {
            addrs,
            port,
            stop,
            thread: Some(thread),
        }
    }

    /// Board `id`'s address.
    pub fn addr(&self, id: u8) -> std::net::SocketAddr {
        self.addrs.iter().find(|a| a.0 == id).unwrap().1
    }

    /// Stop serving; the network's counters.
    pub fn stop(mut self) -> firelink_emulate::qla::eth_network::NetworkStats {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

/// The chain for `n` boards, not in board order: the highest ID first,
/// then alternately from the bottom and the top.
pub fn shuffled(n: u8) -> Vec<u8> {
    let (mut lo, mut hi) = (0u8, n);
    let mut out = Vec::with_capacity(usize::from(n));
    while lo < hi {
        hi -= 1;
        out.push(hi);
        if lo < hi {
            out.push(lo);
            lo += 1;
        }
    }
    out
}

/// Run `body` inside a network namespace of its own: outside it (no
/// `env` in the environment) run this test binary again as `unshare -n --
/// BINARY --exact module::name`, with `env` set, and check that the body
/// ran and passed; inside it run `body`. `module` is the calling test's
/// `module_path!()`. Multicast is sent only there. Without root, `unshare`
/// or `ip` the test says so and returns (skipped).
pub fn in_own_network_namespace(module: &str, name: &str, env: &str, body: impl FnOnce()) {
    if std::env::var_os(env).is_some() {
        body();
        return;
    }
    let name = &crate::common::libtest_name(module, name);
    let succeeds = |program: &str, arg: &str| {
        std::process::Command::new(program)
            .arg(arg)
            .output()
            .is_ok_and(|o| o.status.success())
    };
    // Root, as `id -u` says.
    let root = std::process::Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0\n"));
    let unshare = succeeds("unshare", "--version");
    let ip = succeeds("ip", "-V");
    if !(root && unshare && ip) {
        eprintln!(
            "SKIPPED {name}: needs root, unshare and ip (root {root}, unshare {unshare}, ip \
             {ip}); multicast is sent only inside a namespace the test makes"
        );
        return;
    }
    let out = std::process::Command::new("unshare")
        .arg("-n")
        .arg("--")
        .arg(std::env::current_exe().unwrap())
        .args(["--exact", name, "--nocapture", "--test-threads=1"])
        .env(env, "1")
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "in the namespace:\n{text}");
    assert!(text.contains("1 passed"), "the body ran:\n{text}");
}

/// `ip ARGS` inside the test's namespace, which must succeed.
pub fn ip(args: &[&str]) {
    let ok = std::process::Command::new("ip")
        .args(args)
        .status()
        .unwrap()
        .success();
    assert!(ok, "ip {args:?}");
}

/// Inside the test's namespace: `lo` up with multicast, the multicast
/// route on it, the host's 169.254.0.1/16 and `boards` at 169.254.0.100 +
/// ID.
pub fn stock_addresses_on_lo(boards: &[u8]) {
    ip(&["link", "set", "lo", "up"]);
    ip(&["link", "set", "lo", "multicast", "on"]);
    for id in boards {
        ip(&[
            "addr",
            "add",
            &format!("169.254.0.{}/32", 100 + id),
            "dev",
            "lo",
        ]);
    }
    ip(&["addr", "add", "169.254.0.1/16", "dev", "lo"]);
    ip(&["route", "add", "224.0.0.0/4", "dev", "lo"]);
}
