//! Boards as nodes on the simulated 1394 bus: a PC (root) and 1..16
//! boards daisy-chained behind it, driven with the PC's link as a host
//! would.

use crate::common;

use common::*;
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_bus::host::{HostLink, Outcome};
use firelink_bus::{Bus, BusConfig, NodeConfig, NodeHandle};
use firelink_wire::packet::{Ack, NodeId, Packet, PacketRepr, Speed};
use firelink_wire::qla::broadcast::{
    BoardSlot, HubBlock, SeqRule, emit_command_block, hub_block_quadlets,
};
use firelink_wire::qla::realtime::WriteBlockRepr;
use firelink_wire::qla::registers::DacWord;

struct Rig {
    bus: Bus,
    pc: NodeHandle,
    boards: Vec<NodeHandle>,
}

fn rig(profile: Profile, n: usize) -> Rig {
    let mut bus = Bus::new(BusConfig::default());
    let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
    let boards: Vec<NodeHandle> = (0..n as u8)
        .map(|id| {
            bus.add(
                BoardNode::new(BoardConfig::new(id, Hardware::Qla1, profile)),
                NodeConfig::board(),
            )
        })
        .collect();
    let mut chain = vec![pc];
    chain.extend(&boards);
    bus.daisy_chain(&chain).unwrap();
    bus.set_root(pc).unwrap();
    bus.reset();
    Rig { bus, pc, boards }
}

impl Rig {
    /// Submit a packet from the PC, run until the bus is idle, return the
    /// completion.
    fn transact(&mut self, mut packet: Vec<u8>) -> firelink_bus::host::Completion {
        // The request comes from the PC's node ID.
        let pc = NodeId::local(self.bus.phy_id(self.pc).unwrap());
        let mut view = Packet::new_unchecked(&mut packet[..]);
        view.set_source_id(pc);
        view.fill_header_crc();
        let token = self
            .bus
            .with_node::<HostLink, _>(self.pc, |h, ctx| h.submit(ctx, packet, Speed::S400))
            .unwrap();
        assert!(self.bus.run_until_idle());
        self.bus
            .node_mut::<HostLink>(self.pc)
            .unwrap()
            .take_completion(token)
            .expect("completed")
    }

    fn node_of(&self, board: usize) -> u8 {
        self.bus.phy_id(self.boards[board]).unwrap()
    }

    fn read_block(&mut self, node: u8, offset: u64, quadlets: usize) -> Vec<u8> {
        let c = self.transact(block_read(NodeId::local(node), 1, offset, quadlets));
        assert_eq!(c.outcome, Outcome::Complete);
        assert_eq!(c.ack, Some(Ack::Pending));
        let response = c.response.unwrap();
        let PacketRepr::ReadBlockResponse { data, .. } =
            PacketRepr::parse_verified(&response).unwrap()
        else {
            panic!("not a block read response");
        };
        data.to_vec()
    }

    fn read(&mut self, node: u8, offset: u64) -> u32 {
        let c = self.transact(quadlet_read(NodeId::local(node), 2, offset));
        let response = c
            .response
            .clone()
            .unwrap_or_else(|| panic!("{c:?}\n{}", self.bus.timeline()));
        let PacketRepr::ReadQuadletResponse { data, .. } =
            PacketRepr::parse_verified(&response).unwrap()
        else {
            panic!("not a quadlet read response");
        };
        data
    }
}

#[test]
fn boards_get_node_ids_and_answer_reads() {
    let mut r = rig(Profile::Rev8, 3);
    for b in 0..3 {
        let node = r.node_of(b);
        assert!(node < 3, "the PC is the root, with the highest ID");
        let status = r.read(node, 0);
        assert_eq!((status >> 24) & 0xF, b as u32, "board ID from STATUS");
        assert_eq!(r.read(node, 7), 8);
        // The gap count through PHY_CTRL / PHY_DATA is the bus's.
        let c = r.transact(quadlet_write(NodeId::local(node), 3, 1, 1));
        assert_eq!(c.ack, Some(Ack::Complete));
        let data = r.read(node, 2);
        assert_eq!(data >> 8, 1);
        assert_eq!(
            Some((data & 0x3F) as u8),
            r.bus.gap_count(r.boards[b]),
            "gap count"
        );
    }
}

fn broadcast_cycle(profile: Profile, n: usize) {
    let mut r = rig(profile, n);
    let mask = ((1u32 << n) - 1) as u16;
    let seq = 0x0102;
    let c = r.transact(quadlet_write(
        NodeId::BROADCAST,
        4,
        0x1800,
        (u32::from(seq) << 16) | u32::from(mask),
    ));
    assert_eq!(c.outcome, Outcome::Complete);
    let slots: Vec<BoardSlot> = (0..n as u8)
        .map(|id| BoardSlot {
            id,
            layout: BoardConfig::new(id, Hardware::Qla1, profile).layout(),
        })
        .collect();
    let quadlets = hub_block_quadlets(slots.iter().map(|s| s.layout));
    let rule = match profile {
        Profile::Seed => SeqRule::Seed000,
        _ => SeqRule::for_firmware(slots[0].layout.firmware()),
    };
    // Rev 7+ boards answer in board-ID order. Seed boards answer in
    // node-ID slots, but on a long chain a slot is shorter than a packet
    // plus its repeat delays, so arbitration decides: take the order from
    // the hub itself and check it holds every board once.
    let arrival: Vec<BoardSlot> = if profile == Profile::Seed {
        let node = r.node_of(0);
        let hub = quads(&r.read_block(node, 0x1000, quadlets));
        let per = slots[0].layout.broadcast_quadlets();
        let mut ids: Vec<u8> = (0..n)
            .map(|k| ((hub[k * per + 2] >> 24) & 0xF) as u8)
            .collect();
        let order = ids.clone();
        ids.sort();
        assert_eq!(ids, (0..n as u8).collect::<Vec<_>>());
        order.iter().map(|&b| slots[usize::from(b)]).collect()
    } else {
        slots.clone()
    };
    let mut first: Option<Vec<Vec<u8>>> = None;
    for b in 0..n {
        let node = r.node_of(b);
        let hub = r.read_block(node, 0x1000, quadlets);
        let block = HubBlock::new_checked(&hub[..], &arrival).unwrap();
        block.check_sequences(rule, seq).unwrap();
        let blocks: Vec<Vec<u8>> = block
            .entries()
            .map(|e| {
                assert_eq!(e.block.status().board_id(), e.slot.id);
                e.block.as_bytes().to_vec()
            })
            .collect();
        match &first {
            None => first = Some(blocks),
            Some(f) => assert_eq!(f, &blocks, "board {b} holds the same hub"),
        }
    }
}

#[test]
fn query_on_the_bus_rev8_1_to_15_boards() {
    for n in [1, 2, 4, 8, 15] {
        broadcast_cycle(Profile::Rev8, n);
    }
}

#[test]
fn query_on_the_bus_rev7_and_seed_16_boards() {
    broadcast_cycle(Profile::Rev7, 16);
    broadcast_cycle(Profile::Seed, 16);
    broadcast_cycle(Profile::Seed, 3);
}

#[test]
fn command_broadcast_on_the_bus() {
    for profile in [Profile::Rev7, Profile::Rev8] {
        let n = 4;
        let mut r = rig(profile, n);
        let layout = BoardConfig::new(0, Hardware::Qla1, profile).layout();
        let blocks: Vec<WriteBlockRepr> = (0..n as u8)
            .map(|id| {
                let mut b = WriteBlockRepr::new(layout, id);
                b.dac[0] = DacWord::valid_command(0x9000 + u16::from(id));
                b
            })
            .collect();
        let mut buf = vec![0u8; 512];
        let len = emit_command_block(&mut buf, &blocks).unwrap();
        let payload = quads(&buf[..len]);
        // Both ways of the spec: node 63 offset 0, node 0 snooped.
        for (dest, offset) in [
            (NodeId::BROADCAST, 0u64),
            (NodeId::local(0), 0xFFFF_FFFF_0000),
        ] {
            let c = r.transact(block_write(dest, 5, offset, &payload));
            assert_eq!(c.outcome, Outcome::Complete);
            for b in 0..n {
                let node = r.node_of(b);
                assert_eq!(r.read(node, 0x11), 0x9000 + b as u32);
            }
            // Change the commands for the second route.
            let c = r.transact(block_write(
                NodeId::BROADCAST,
                6,
                0,
                &quads(&{
                    let zero: Vec<WriteBlockRepr> = (0..n as u8)
                        .map(|id| {
                            let mut b = WriteBlockRepr::new(layout, id);
                            b.dac[0] = DacWord::valid_command(0x8000);
                            b
                        })
                        .collect();
                    let mut z = vec![0u8; 512];
                    let l = emit_command_block(&mut z, &zero).unwrap();
                    z.truncate(l);
                    z
                }),
            ));
            assert_eq!(c.outcome, Outcome::Complete);
        }
    }
}

#[test]
fn a_corrupted_write_on_the_bus_is_not_applied() {
    let mut r = rig(Profile::Rev8, 1);
    let node = r.node_of(0);
    let mut p = block_write(NodeId::local(node), 7, 0, &[6, 0x8000_9000, 0, 0, 0, 0]);
    p[24] ^= 0x04;
    let c = r.transact(p);
    assert_eq!(c.ack, Some(Ack::DataError));
    assert_eq!(r.read(node, 0x11), 0x8000);
}
