//! The reference host's side of the bridge protocol as raw datagrams
//! (`fpga-board.md` §8): a control word, then a 1394 request with source
//! `0xFFD0` and destination `0xFFC0 | node`, handed to a [`Bridge`]
//! without sockets, so every test replays an exact request sequence in
//! virtual time.
#![allow(dead_code)]

use firelink_board::config::BoardConfig;
use firelink_board::rig::{BoardRig, RigOptions};
use firelink_bus::SimDuration;
use firelink_emulate::{Bridge, Handled};
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

/// One answer: the response packet's fields and the extra data.
#[derive(Debug, Clone)]
pub struct Answer {
    pub source: NodeId,
    pub destination: NodeId,
    pub tcode: Tcode,
    pub rcode: Rcode,
    /// The quadlet (quadlet response) or the payload as quadlets.
    pub quadlets: Vec<u32>,
    pub extra: ExtraData,
    /// Whole reply datagram length.
    pub len: usize,
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
        let mut d = ControlWord {
            no_forward,
            generation: self.generation,
        }
        .to_bytes()
        .to_vec();
        let mut pkt = vec![0u8; repr.buffer_len()];
        repr.emit(&mut pkt).unwrap();
        d.extend_from_slice(&pkt);
        d
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
        let (p, extra) = split_board_datagram(&self.reply[..n]).unwrap();
        self.generation = extra.generation;
        let quadlets = if p.tcode() == Tcode::ReadQuadletResponse {
            vec![p.quadlet_data()]
        } else {
            p.payload()
                .chunks_exact(4)
                .map(|c| u32::from_be_bytes(c.try_into().unwrap()))
                .collect()
        };
        Some(Answer {
            source: p.source_id(),
            destination: p.destination_id(),
            tcode: p.tcode(),
            rcode: p.rcode(),
            quadlets,
            extra,
            len: n,
        })
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
