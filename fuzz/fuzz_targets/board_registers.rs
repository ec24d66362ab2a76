//! Fuzz the emulated board's register file and packet handling: a stream of
//! arbitrary packets (CRCs pass under `cfg(fuzzing)`) at arbitrary times,
//! for every board profile. The firmware never panics, every response it
//! sends is a well-formed packet, and its broadcasts are too.
#![no_main]

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::{Firmware, PhyRegisters, Reply};
use firelink_board::time::{SimTime, SimDuration};
use firelink_wire::packet::Packet;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, mut rest)) = data.split_first() else {
        return;
    };
    let profile = match selector % 4 {
        0 => Profile::Seed,
        1 => Profile::Rev7,
        2 => Profile::Rev8,
        _ => Profile::Rev9,
    };
    let hardware = if selector & 0x04 == 0 { Hardware::Qla1 } else { Hardware::Dqla };
    let board_id = (selector >> 4) & 0x0F;
    let mut firmware = Firmware::new(BoardConfig::new(board_id, hardware, profile));
    let mut phy = PhyRegisters::new(2);
    firmware.bus_reset(SimTime::ZERO, 2, 1);
    let mut now = SimTime::ZERO;
    // Each packet: one byte of elapsed time (x 1 us), one length byte
    // (quadlets), then the packet bytes.
    while let [gap, quadlets, tail @ ..] = rest {
        now = SimTime(now.0 + SimDuration::from_micros(u64::from(*gap)).0);
        let len = (usize::from(*quadlets) * 4).min(tail.len());
        let (bytes, after) = tail.split_at(len);
        rest = after;
        match firmware.receive(now, bytes, &mut phy) {
            Reply::AckThenResponse { response, .. } => {
                Packet::new_checked(&response[..]).expect("response is a well-formed packet");
            }
            Reply::Ack(_) | Reply::Silent => {}
        }
        let _ = firmware.take_rx_error();
        // A status broadcast whose slot has come goes out now.
        if let Some(out) = firmware.poll_transmit(now) {
            Packet::new_checked(&out[..]).expect("broadcast is a well-formed packet");
            firmware.transmitted(now);
        }
    }
});
