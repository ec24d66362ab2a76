//! Fuzz the packet parser: any bytes must parse or fail cleanly, and what
//! parses must re-emit to the same bytes.
#![no_main]

use firelink_wire::packet::{Packet, PacketRepr};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(packet) = Packet::new_checked(data) else {
        return;
    };
    let total = packet.total_len();
    assert!(total <= data.len());
    let _ = packet.verify();
    let _ = packet.crc_status();
    if let Ok(repr) = PacketRepr::parse(&packet) {
        let mut out = vec![0u8; repr.buffer_len()];
        if repr.emit(&mut out).is_ok() {
            // Re-parsing what we emitted gives the same meaning.
            let again = Packet::new_checked(&out[..]).expect("emitted packet is complete");
            assert_eq!(PacketRepr::parse(&again).expect("emitted packet parses"), repr);
        }
    }
});
