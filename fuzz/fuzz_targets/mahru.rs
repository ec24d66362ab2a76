//! Fuzz the MAHRU module protocol's parsers (seed 002): arbitrary bytes
//! never panic, and whatever parses encodes back to the same bytes.
#![no_main]

use firelink_wire::mahru::{
    Command, FtBlock, IdCheck, Identity, JointBlock, ModId, ParameterRecord, SetpointSlot,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(b) = JointBlock::parse(data) {
        let mut out = [0u8; JointBlock::LEN];
        assert_eq!(b.emit(&mut out), Ok(JointBlock::LEN));
        assert_eq!(&out[..], data);
    }
    if let Ok(b) = FtBlock::parse(data) {
        let mut out = [0u8; FtBlock::LEN];
        assert_eq!(b.emit(&mut out), Ok(FtBlock::LEN));
        assert_eq!(&out[..], data);
    }
    if let Ok(r) = ParameterRecord::parse(data) {
        let mut out = [0u8; ParameterRecord::LEN];
        assert_eq!(r.emit(&mut out), Ok(ParameterRecord::LEN));
        assert_eq!(&out[..], data);
    }
    let _ = SetpointSlot::parse(data);
    if let Some(&id) = data.first() {
        let _ = SetpointSlot::slice(data, ModId(id));
        let _ = ParameterRecord::find(data, ModId(id));
    }
    if let Some(q) = data.get(..4) {
        let q = u32::from_be_bytes([q[0], q[1], q[2], q[3]]);
        if let Ok(i) = Identity::from_quadlet(q) {
            assert_eq!(i.to_quadlet(), Ok(q));
        }
        if let Ok(c) = IdCheck::from_quadlet(q) {
            assert_eq!(c.to_quadlet(), Ok(q));
        }
        let _ = Command::from_offset(u64::from(q));
    }
});
