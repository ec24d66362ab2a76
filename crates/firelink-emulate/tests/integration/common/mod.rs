//! The emulator's test rigs: bridges over emulated boards, served on
//! loopback UDP ([`Server`]) or driven without sockets by the reference
//! host's side of the bridge protocol as raw datagrams ([`RefHost`],
//! `fpga-board.md` §8: a control word, then a 1394 request with source
//! `0xFFD0` and destination `0xFFC0 | node`), so a test replays an exact
//! request sequence in virtual time.
#![allow(dead_code)]

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::SimDuration;
use firelink_emulate::{Bridge, BridgeStats, Handled, ServeConfig, bind, serve};
use firelink_host::udp::UdpPort;
use firelink_wire::bridge::{ControlWord, ExtraData, split_board_datagram};
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Tcode};

/// The reference host's source ID.
pub const HOST: NodeId = NodeId(0xFFD0);

/// A bridge over `boards`, the first one Ethernet-connected.
pub fn bridge(boards: Vec<BoardConfig>) -> Bridge {
    let rig = BoardRig::daisy_chain(boards, &RigOptions::default());
    let first = rig.boards[0];
    Bridge::new(rig.bus, rig.host, first)
}

/// `n` QLA1 boards with IDs 0..n running `profile`.
pub fn qla1s(n: u8, profile: Profile) -> Vec<BoardConfig> {
    (0..n)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, profile))
        .collect()
}

/// A bridge over `boards` serving 127.0.0.1 (an ephemeral port) on its own
/// thread until stopped or dropped.
pub struct Server {
    /// Where it listens.
    pub addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<BridgeStats>>,
}

impl Server {
    /// Start serving `boards` (the first one Ethernet-connected).
    pub fn start(boards: Vec<BoardConfig>) -> Server {
        let (unicast, _) = bind(&ServeConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            loopback_broadcast: false,
        })
        .unwrap();
        let addr = unicast.local_addr().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut b = bridge(boards);
            serve(&mut b, &unicast, None, &flag, |_| {}).unwrap();
            b.stats()
        });
        Server {
            addr,
            stop,
            thread: Some(thread),
        }
    }

    /// A UDP port to it with read time-out `timeout`.
    pub fn port(&self, timeout: Duration) -> UdpPort {
        let mut p = UdpPort::open(self.addr).unwrap();
        p.set_timeout(timeout);
        p
    }

    /// Stop serving; the bridge's counters.
    pub fn stop(mut self) -> BridgeStats {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// One answer: the response packet's fields and the extra data.
#[derive(Debug, Clone)]
pub struct Answer {
    pub source: NodeId,
    pub destination: NodeId,
    pub tcode: Tcode,
    pub rcode: Rcode,
    /// The transaction label.
    pub tl: u8,
    /// The quadlet (quadlet response) or the payload as quadlets.
    pub quadlets: Vec<u32>,
    pub extra: ExtraData,
    /// Whole reply datagram length.
    pub len: usize,
}

/// Decode a reply datagram: the response packet and the extra data.
pub fn decode(bytes: &[u8]) -> Answer {
    let (p, extra) = split_board_datagram(bytes).expect("a reply with its extra data");
    let quadlets = if p.tcode() == Tcode::ReadQuadletResponse {
        vec![p.quadlet_data()]
    } else {
        p.payload()
            .chunks_exact(4)
            .map(|c| u32::from_be_bytes(c.try_into().unwrap()))
            .collect()
    };
    Answer {
        source: p.source_id(),
        destination: p.destination_id(),
        tcode: p.tcode(),
        rcode: p.rcode(),
        tl: p.tl(),
        quadlets,
        extra,
        len: bytes.len(),
    }
}

/// A host-to-bridge datagram: the control word (`no_forward`, the bus
/// `generation` the host believes in), then the packet of `repr`.
pub fn request_datagram(no_forward: bool, generation: u8, repr: &PacketRepr<'_>) -> Vec<u8> {
    let mut d = ControlWord {
        no_forward,
        generation,
    }
    .to_bytes()
    .to_vec();
    let mut pkt = vec![0u8; repr.buffer_len()];
    repr.emit(&mut pkt).unwrap();
    d.extend_from_slice(&pkt);
    d
}

/// The reference host talking to one bridge.
pub struct RefHost {
    pub bridge: Bridge,
    tl: u8,
    pub generation: u8,
    reply: Vec<u8>,
}

impl RefHost {
    pub fn new(bridge: Bridge) -> RefHost {
        let generation = bridge.generation();
        RefHost {
            bridge,
            tl: 0,
            generation,
            reply: Vec::new(),
        }
    }

    fn header(&mut self, node: u8) -> AsyncHeader {
        self.tl = (self.tl + 1) & 0x3F;
        AsyncHeader::new(NodeId(0xFFC0 | u16::from(node & 0x3F)), HOST, self.tl)
    }

    /// The datagram of `repr` with the host's generation.
    pub fn datagram(&self, no_forward: bool, repr: &PacketRepr<'_>) -> Vec<u8> {
        request_datagram(no_forward, self.generation, repr)
    }

    /// Hand one datagram to the bridge.
    pub fn send(&mut self, datagram: &[u8]) -> Handled {
        self.bridge.handle(datagram, &mut self.reply)
    }

    /// The last reply, decoded.
    pub fn answer(&mut self, handled: Handled) -> Option<Answer> {
        let Handled::Reply(n) = handled else {
            return None;
        };
        let answer = decode(&self.reply[..n]);
        self.generation = answer.extra.generation;
        Some(answer)
    }

    pub fn try_qread(&mut self, node: u8, no_forward: bool, offset: u64) -> Option<Answer> {
        let header = self.header(node);
        let d = self.datagram(
            no_forward,
            &PacketRepr::ReadQuadletRequest { header, offset },
        );
        let h = self.send(&d);
        self.answer(h)
    }

    /// Quadlet read of a (forwarded) node; panics without an answer.
    pub fn qread(&mut self, node: u8, offset: u64) -> u32 {
        let a = self
            .try_qread(node, false, offset)
            .unwrap_or_else(|| panic!("no answer to a read of node {node} offset {offset:#x}"));
        assert_eq!(a.rcode, Rcode::Complete);
        a.quadlets[0]
    }

    pub fn qwrite(&mut self, node: u8, offset: u64, data: u32) -> Handled {
        let header = self.header(node);
        let d = self.datagram(
            false,
            &PacketRepr::WriteQuadletRequest {
                header,
                offset,
                data,
            },
        );
        self.send(&d)
    }

    pub fn try_bread(&mut self, node: u8, offset: u64, bytes: u16) -> Option<Answer> {
        let header = self.header(node);
        let d = self.datagram(
            false,
            &PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: bytes,
                extended_tcode: 0,
            },
        );
        let h = self.send(&d);
        self.answer(h)
    }

    /// Block read of `bytes` bytes; panics without a complete answer.
    pub fn bread(&mut self, node: u8, offset: u64, bytes: u16) -> Vec<u32> {
        let a = self
            .try_bread(node, offset, bytes)
            .unwrap_or_else(|| panic!("no answer to a block read of node {node} at {offset:#x}"));
        assert_eq!(a.rcode, Rcode::Complete, "block read at {offset:#x}");
        a.quadlets
    }

    pub fn bwrite(&mut self, node: u8, offset: u64, quadlets: &[u32]) -> Handled {
        let header = self.header(node);
        let data: Vec<u8> = quadlets.iter().flat_map(|q| q.to_be_bytes()).collect();
        let d = self.datagram(
            false,
            &PacketRepr::WriteBlockRequest {
                header,
                offset,
                extended_tcode: 0,
                data: &data,
            },
        );
        self.send(&d)
    }

    /// Let `us` microseconds of virtual time pass (the host's sleeps).
    pub fn sleep_us(&mut self, us: u64) {
        let t = self.bridge.bus().now() + SimDuration::from_micros(us);
        self.bridge.advance_to(t);
    }
}

/// A header check for a response packet that must verify.
pub fn verified(bytes: &[u8]) -> bool {
    Packet::new_checked(bytes).is_ok_and(|p| p.verify().is_ok())
}

/// The name libtest runs the test `function` of the module at
/// `module_path` (its `module_path!()`) by: the module path without the
/// test binary's own name in front, then the function, as `--exact` wants
/// it when a test runs its own binary again as a child process.
pub fn libtest_name(module_path: &str, function: &str) -> String {
    match module_path.split_once("::") {
        Some((_binary, module)) => format!("{module}::{function}"),
        None => function.to_string(),
    }
}
