//! The Ethernet-only network without sockets: the Rev 9 host's sequences
//! (EthUdpPort `InitNodes` and `ScanNodes`, EthBasePort's broadcast read,
//! the fallback hub read, the command block) as raw datagrams into
//! [`EthNetwork`] in virtual time, every reply checked byte by byte.

use crate::eth_common;

use std::net::{Ipv4Addr, SocketAddr};

use eth_common::*;
use firelink_board::qla::config::{BoardConfig, FpgaVersion, Hardware, Profile};
use firelink_bus::ethernet::{EthTiming, SwitchPort};
use firelink_bus::{SimDuration, SimTime};
use firelink_emulate::qla::eth_network::{Destination, EthNetwork, NetworkError, Outgoing};
use firelink_wire::packet::{Rcode, Tcode};

const HOST_ADDR: SocketAddr = SocketAddr::new(std::net::IpAddr::V4(Ipv4Addr::LOCALHOST), 40000);

/// The network and the host's clock.
struct Rig {
    net: EthNetwork,
    now: SimTime,
    host: Rev9Host,
    out: Vec<Outgoing>,
}

impl Rig {
    fn new(ids: &[u8]) -> Rig {
        Rig {
            net: EthNetwork::new(v3_rev9(ids), EthTiming::default()).unwrap(),
            now: SimTime::from_micros(10),
            host: Rev9Host::default(),
            out: Vec::new(),
        }
    }

    fn send(&mut self, to: Destination, datagram: &[u8]) {
        self.net.handle(self.now, to, HOST_ADDR, datagram);
    }

    /// Let `us` of virtual time pass; the replies that reached the host.
    fn wait(&mut self, us: u64) -> Vec<Outgoing> {
        self.now += SimDuration::from_micros(us);
        self.net.advance_to(self.now);
        self.out.clear();
        self.net.take_due(self.now, &mut self.out);
        self.out.clone()
    }

    fn ask(&mut self, to: Destination, datagram: &[u8]) -> Vec<Outgoing> {
        self.send(to, datagram);
        self.wait(100)
    }

    fn qread(&mut self, board: u8, offset: u64) -> Answer {
        let d = self.host.qread(board, offset);
        let out = self.ask(Destination::Board(board), &d);
        assert_eq!(out.len(), 1, "one reply to a read of board {board}");
        assert_eq!(out[0].from, board);
        let a = decode(&out[0].bytes);
        assert_eq!(a.source.phy(), board, "the board ID as source");
        assert_eq!(a.tl, self.host.tl);
        assert_eq!(a.rcode, Rcode::Complete);
        a
    }

    /// EthUdpPort::InitNodes and ScanNodes, Ethernet-only.
    fn discover(&mut self) -> Vec<u8> {
        let d = self.host.qwrite(63, IP_ADDRESS, BASE_IP);
        assert!(
            self.ask(Destination::Group, &d).is_empty(),
            "writes get no reply"
        );
        self.wait(1_000);
        let d = self.host.qread(63, HARDWARE_VERSION);
        let out = self.ask(Destination::Group, &d);
        assert_eq!(out.len(), 1, "only the hub answers a broadcast read");
        let hub = out[0].from;
        assert_eq!(decode(&out[0].bytes).quadlets, vec![QLA1]);
        let d = self.host.qread(63, FIRMWARE_VERSION);
        assert_eq!(
            decode(&self.ask(Destination::Group, &d)[0].bytes).quadlets,
            vec![9]
        );
        let d = self.host.qread(63, ETH_STATUS);
        let eth = decode(&self.ask(Destination::Group, &d)[0].bytes).quadlets[0];
        assert_eq!(
            eth >> 30,
            0b01,
            "FPGA V3: the host picks the Ethernet-only network"
        );
        let _ = hub;
        // ScanNodes: node = board ID, unicast to base + ID.
        let mut found = Vec::new();
        for id in 0..16u8 {
            if !self.net.board_ids().contains(&id) {
                continue; // no board there: nothing listens at its address
            }
            let status = self.qread(id, STATUS).quadlets[0];
            assert_eq!((status >> 24) & 0xF, u32::from(id));
            found.push(id);
        }
        found
    }
}

#[test]
fn discovery_by_board_id_and_ip_assignment() {
    let mut rig = Rig::new(&[3, 1, 0, 2]);
    assert_eq!(rig.discover(), vec![0, 1, 2, 3]);
    for id in 0..4u8 {
        let a = rig.qread(id, IP_ADDRESS);
        let [a0, a1, a2, a3] = a.quadlets[0].to_le_bytes();
        assert_eq!([a0, a1, a2, a3], [169, 254, 0, 100 + id], "base + board ID");
        assert!(a.extra.flags.no_forward);
        assert_eq!(a.extra.flags.source_port, 0, "requests come in by Eth1");
    }
    assert_eq!(rig.net.chain().hub(), Some(3), "the board nearest the host");
    assert_eq!(rig.net.stats().dropped(), 0);
}

#[test]
fn broadcast_read_one_unsolicited_response_in_chain_order() {
    let order = [3, 1, 0, 2];
    let mut rig = Rig::new(&order);
    rig.discover();
    for seq in 1..=20u16 {
        let d = rig.host.query(seq, 0b1111);
        let tl = rig.host.tl;
        rig.send(Destination::Group, &d);
        // Nothing before the host's own wait for four boards ...
        let early = rig.wait(EthTiming::host_wait(4).as_nanos() / 1000 - 10);
        assert!(early.is_empty());
        // ... one response within a little more.
        let out = rig.wait(100);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].from, 3);
        let a = decode(&out[0].bytes);
        assert_eq!(a.tcode, Tcode::ReadBlockResponse);
        assert_eq!((a.source.phy(), a.destination, a.tl), (3, HOST, tl));
        assert!(a.extra.flags.no_forward);
        let placed = place(&a.quadlets, 4, seq);
        let came: Vec<u8> = placed.iter().map(|p| p.0).collect();
        assert_eq!(came, order, "in chain order, not board order");
        // Update times count 125 MHz and rise entry by entry (38 us apart:
        // 4750 ticks).
        let times: Vec<u32> = placed.iter().map(|p| p.1[0] & 0x7FFF).collect();
        for w in times.windows(2) {
            assert_eq!(w[1] - w[0], 4750, "{times:?}");
        }
        assert!(
            times[0] >= 375 && times[0] < 500,
            "own block 3 us after the query: {times:?}"
        );
        // The timing quadlet: read start and now, 16 bits at 125 MHz.
        let timing = a.quadlets[ENTRY * 4];
        assert!((timing & 0xFFFF) >= times[3], "{timing:#x}");
    }
    assert_eq!(rig.net.stats().broadcast_responses, 20);
}

#[test]
fn a_host_that_missed_the_response_reads_the_hub() {
    let mut rig = Rig::new(&[2, 0, 1]);
    rig.discover();
    let d = rig.host.query(7, 0b111);
    rig.send(Destination::Group, &d);
    let missed = rig.wait(200);
    assert_eq!(missed.len(), 1, "sent, and lost on the host's side");
    let d = rig.host.bread(2, 0x1000, hub_bytes(3));
    let out = rig.ask(Destination::Board(2), &d);
    let a = decode(&out[0].bytes);
    let unsolicited = decode(&missed[0].bytes);
    assert_eq!(a.quadlets[..ENTRY * 3], unsolicited.quadlets[..ENTRY * 3]);
    let placed = place(&a.quadlets, 3, 7);
    assert_eq!(
        placed.iter().map(|p| p.0).collect::<Vec<_>>(),
        vec![2, 0, 1]
    );
    // Every board holds every block: another board's hub reads the same
    // blocks, its own first, then in the order they arrived there.
    let d = rig.host.bread(1, 0x1000, hub_bytes(3));
    let a = decode(&rig.ask(Destination::Board(1), &d)[0].bytes);
    let mut came: Vec<u8> = place(&a.quadlets, 3, 7).iter().map(|p| p.0).collect();
    assert_eq!(came[0], 1);
    came.sort_unstable();
    assert_eq!(came, vec![0, 1, 2]);
}

#[test]
fn a_partial_mask_and_the_command_block() {
    let mut rig = Rig::new(&[0, 1, 2, 3]);
    rig.discover();
    let d = rig.host.query(9, 0b1010);
    rig.send(Destination::Group, &d);
    let out = rig.wait(200);
    assert_eq!(out.len(), 1);
    let placed = place(&decode(&out[0].bytes).quadlets, 2, 9);
    assert_eq!(placed.iter().map(|p| p.0).collect::<Vec<_>>(), vec![1, 3]);
    let d = rig.host.commands(&[0, 1, 2, 3], 0x9000);
    assert!(rig.ask(Destination::Group, &d).is_empty());
    for id in 0..4 {
        let fw = rig.net.firmware(id).unwrap();
        assert_eq!(fw.axis_command(0), Some(0x9000), "board {id}");
    }
}

#[test]
fn addressing_needs_the_board_id_and_the_no_forward_flag() {
    let mut rig = Rig::new(&[0, 1]);
    rig.discover();
    // To board 1's address but naming board 0: not taken.
    let d = rig.host.qread(0, STATUS);
    assert!(rig.ask(Destination::Board(1), &d).is_empty());
    assert_eq!(rig.net.stats().not_addressed, 1);
    // Without the no-forward flag: for a FireWire bus there is not.
    let mut d = rig.host.qread(1, STATUS);
    d[0] = 0;
    assert!(rig.ask(Destination::Board(1), &d).is_empty());
    assert_eq!(rig.net.stats().needs_no_forward, 1);
    // Damaged: counted, nothing answered or applied.
    let mut d = rig.host.qwrite(1, STATUS, 0x000F_0000);
    let last = d.len() - 1;
    d[last] ^= 1;
    assert!(rig.ask(Destination::Board(1), &d).is_empty());
    assert_eq!(rig.net.stats().bad_crc, 1);
    assert!(rig.ask(Destination::Board(1), &[0, 1, 2]).is_empty());
    assert_eq!(rig.net.stats().malformed, 1);
}

#[test]
fn a_reversed_board_reports_its_source_port() {
    let net = EthNetwork::new(v3_rev9(&[0, 1]), EthTiming::default())
        .unwrap()
        .with_host_side(1, SwitchPort::Eth2);
    let mut rig = Rig::new(&[0]);
    rig.net = net;
    rig.discover();
    assert_eq!(rig.qread(1, STATUS).extra.flags.source_port, 1);
    assert_eq!(rig.qread(0, STATUS).extra.flags.source_port, 0);
}

#[test]
fn only_v3_rev9_boards_join() {
    let v2 = BoardConfig::new(0, Hardware::Qla1, Profile::Rev9);
    assert!(matches!(
        EthNetwork::new(vec![v2], EthTiming::default()),
        Err(NetworkError::NotV3Rev9 {
            board: 0,
            fpga: FpgaVersion::V2,
            ..
        })
    ));
    let rev8 = BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_fpga(FpgaVersion::V3);
    let e = EthNetwork::new(vec![rev8], EthTiming::default())
        .err()
        .unwrap();
    assert!(
        e.to_string().contains("FPGA V3 boards at firmware Rev 9"),
        "{e}"
    );
}
