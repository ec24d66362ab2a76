//! Fuzz the Ethernet bridge framing in both directions.
#![no_main]

use firelink_wire::bridge::{ExtraData, split_board_datagram, split_host_datagram};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((control, packet)) = split_host_datagram(data) {
        assert_eq!(packet.total_len() + 2, data.len());
        let _ = control.to_u16();
    }
    if let Ok((packet, extra)) = split_board_datagram(data) {
        assert_eq!(packet.total_len() + 8, data.len());
        assert_eq!(ExtraData::parse(&extra.to_bytes()), Ok(extra));
    }
});
