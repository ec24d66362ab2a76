//! Fuzz the /dev/fw* codecs (`firelink_wire::fw_cdev`): the ioctl
//! arguments the preloaded library copies from a program, the events a
//! client reads, and the twin's own messages, all bytes from outside.
//! Every parser gives a value or a named error and never panics; a value
//! written back with its `emit` parses to the same value (a one-way
//! SEND_REQUEST message also when its head is written in front of a
//! payload already in place, as the preloaded library does); the kernel's
//! argument checks give Ok or one of the errnos the kernel uses.
#![no_main]

use firelink_wire::fw_cdev::{
    self, BusResetRecord, GetInfoArgs, Ioctl, ResponseEvent, SendRequestArgs, TwinReply,
    TwinRequest, errno,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, bytes)) = data.split_first() else {
        return;
    };
    // Pre-filled so that a field `emit` leaves unset shows.
    let mut out = vec![0xA5u8; bytes.len() + fw_cdev::TWIN_MAX_MESSAGE + 64];
    match selector % 8 {
        0 => {
            if let Ok(a) = GetInfoArgs::parse(bytes) {
                a.emit(&mut out).expect("40 bytes fit");
                assert_eq!(GetInfoArgs::parse(&out[..fw_cdev::GET_INFO_LEN]), Ok(a));
            }
        }
        1 => {
            if let Ok(a) = SendRequestArgs::parse(bytes) {
                a.emit(&mut out).expect("40 bytes fit");
                assert_eq!(SendRequestArgs::parse(&out[..fw_cdev::SEND_REQUEST_LEN]), Ok(a));
                for broadcast in [false, true] {
                    for speed in 0..=6 {
                        if let Err(e) = a.check(broadcast, speed) {
                            assert!([errno::EINVAL, errno::EACCES, errno::EIO].contains(&e));
                        }
                    }
                }
            }
        }
        2 => {
            if let Ok((closure, record)) = BusResetRecord::parse(bytes) {
                let n = record.emit(closure, &mut out).expect("the record fits");
                assert_eq!(BusResetRecord::parse(&out[..n]), Ok((closure, record)));
            }
        }
        3 => {
            if let Ok(r) = ResponseEvent::parse(bytes) {
                let n = fw_cdev::emit_response(6, r.closure, r.rcode, r.data, (0, 0), &mut out)
                    .expect("the event fits");
                let back = ResponseEvent::parse(&out[..n]).expect("written events parse");
                assert_eq!((back.closure, back.rcode, back.data), (r.closure, r.rcode, r.data));
            }
            let _ = fw_cdev::event_type(bytes);
        }
        4 => {
            if let Ok(r) = TwinRequest::parse(bytes) {
                let n = r.emit(&mut out).expect("a parsed request fits");
                assert_eq!(TwinRequest::parse(&out[..n]), Ok(r));
                // SEND_REQUEST alone is one-way; its head written in front
                // of a payload already in place gives the same message.
                let one_way = matches!(r, TwinRequest::SendRequest { .. });
                assert_eq!(r.expects_reply(), !one_way);
                if let TwinRequest::SendRequest { broadcast, args, payload } = r {
                    let mut again = vec![0x5Au8; n];
                    let at = fw_cdev::SEND_REQUEST_PAYLOAD_AT;
                    again[at..at + payload.len()].copy_from_slice(payload);
                    let m = fw_cdev::emit_send_request_head(broadcast, &args, &mut again)
                        .expect("the message fits");
                    assert_eq!(&again[..m], &out[..n]);
                }
            }
        }
        5 => {
            if let Ok(r) = TwinReply::parse(bytes) {
                let n = r.emit(&mut out).expect("a parsed reply fits");
                assert_eq!(TwinReply::parse(&out[..n]), Ok(r));
            }
        }
        6 => {
            if let Ok((_, rom_length, record, rom)) = fw_cdev::split_info_payload(bytes) {
                assert_eq!(record.len(), fw_cdev::BUS_RESET_EVENT_LEN);
                assert!(8 + record.len() + rom.len() == bytes.len());
                let _ = rom_length;
            }
        }
        _ => {
            if let Some(q) = bytes.first_chunk::<8>() {
                let _ = Ioctl::from_request(u64::from_le_bytes(*q));
            }
        }
    }
});
