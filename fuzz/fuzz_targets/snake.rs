//! Fuzz seed 001's Snake node: its wire codecs (blocks, register words,
//! Table 1 addresses) and the emulated node's whole receive path with
//! packets whose CRCs are made right, so the fuzzer reaches the register
//! map, the pot commands and the blocks.
#![no_main]

use firelink_board::qla::{PhyRegisters, Reply};
use firelink_board::snake::{SnakeFirmware, SnakeNodeConfig};
use firelink_board::time::SimTime;
use firelink_wire::packet::Packet;
use firelink_wire::snake::address::SnakeRegister;
use firelink_wire::snake::block::{ReadBlock, ReadBlockRepr, WriteBlock, WriteBlockRepr};
use firelink_wire::snake::registers::{DacCommand, EncoderPreload, PotCommand};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(view) = ReadBlock::new_checked(data) {
        let repr = ReadBlockRepr::parse(&view).expect("any 23 quadlets parse");
        let mut out = vec![0u8; repr.buffer_len()];
        repr.emit(&mut out).expect("emit");
        assert_eq!(out, data);
    }
    if let Ok(view) = WriteBlock::new_checked(data) {
        let _ = WriteBlockRepr::parse(&view);
    }
    for chunk in data.chunks_exact(4) {
        let w = u32::from_be_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        if let Ok(c) = PotCommand::parse(w) {
            assert_eq!(c.to_word(), w);
        }
        let _ = DacCommand::parse(w);
        let _ = EncoderPreload::parse(w);
        let _ = SnakeRegister::from_offset(u64::from(w));
    }
    // Packets to a node: split the input into packets, repair CRCs, aim
    // them at the node (physical ID 0) and deliver them in order.
    let mut node = SnakeFirmware::new(SnakeNodeConfig::new(1));
    let mut phy = PhyRegisters::new(0);
    node.bus_reset(SimTime::ZERO, 0, 1);
    let mut t = SimTime::from_micros(1);
    for piece in data.split(|b| *b == 0xFE) {
        let mut bytes = piece.to_vec();
        if let Ok(mut p) = Packet::new_checked(&mut bytes[..]) {
            p.set_destination_id(firelink_wire::packet::NodeId::local(0));
            p.fill_header_crc();
            if p.tcode().has_data_block() {
                p.fill_data_crc();
            }
        }
        t = SimTime(t.0 + 30_000_000);
        match node.receive(t, &bytes, &mut phy) {
            Reply::AckThenResponse { response, .. } => {
                let r = Packet::new_checked(&response[..]).expect("a whole response");
                assert!(r.verify().is_ok());
            }
            Reply::Ack(_) | Reply::Silent => {}
        }
    }
});
