//! Property tests of the MAHRU module protocol (seed 002): every block
//! round-trips through emit and parse, and arbitrary bytes never panic a
//! parser (they parse or give an error naming what was wrong).

use firelink_wire::mahru::{
    Command, FtBlock, IdCheck, Identity, JointBlock, ModId, ModuleKind, ModuleState,
    ParameterRecord, QWRITE_LEN, SetpointSlot,
};
use proptest::prelude::*;

fn state() -> impl Strategy<Value = ModuleState> {
    (0u8..16).prop_map(ModuleState::from)
}

proptest! {
    #[test]
    fn joint_block_round_trips(
        id in 0u8..32, st in state(), seq: u16, pos: i32, vel: i32, cur: i32,
        target: i32, torque: i32, ticks: u32, flags: u32,
    ) {
        let b = JointBlock {
            mod_id: ModId(id), state: st, sequence: seq, position_urad: pos,
            velocity_urad_s: vel, current_ma: cur, target_urad: target,
            torque_mnm: torque, servo_ticks: ticks, flags,
        };
        let mut buf = [0xA5u8; 40];
        prop_assert_eq!(b.emit(&mut buf).unwrap(), JointBlock::LEN);
        prop_assert_eq!(JointBlock::parse(&buf[..JointBlock::LEN]).unwrap(), b);
    }

    #[test]
    fn ft_block_round_trips(f: [i32; 3], t: [i32; 3]) {
        let b = FtBlock { force_mn: f, torque_mnm: t };
        let mut buf = [0xA5u8; FtBlock::LEN];
        b.emit(&mut buf).unwrap();
        prop_assert_eq!(FtBlock::parse(&buf).unwrap(), b);
    }

    #[test]
    fn setpoint_slot_round_trips(
        id: u8, valid: bool, seq: u16, pos: i32, vel: i32, acc: i32, tq: i32,
    ) {
        let s = SetpointSlot {
            mod_id: id, valid, sequence: seq, position_urad: pos,
            velocity_urad_s: vel, acceleration_mrad_s2: acc, torque_mnm: tq,
        };
        let mut buf = [0xA5u8; SetpointSlot::LEN];
        s.emit(&mut buf).unwrap();
        prop_assert_eq!(SetpointSlot::parse(&buf).unwrap(), s);
    }

    #[test]
    fn parameter_record_round_trips(
        id in 0u8..32, gear in 0.01f32..1000.0, kp in 0f32..1e4, ki in 0f32..1e3,
        kd in 0f32..1e2, lo in -10f32..0.0, span in 0.01f32..10.0, tmax in 0.01f32..500.0,
    ) {
        let r = ParameterRecord {
            mod_id: ModId(id), gear_ratio: gear, kp, ki, kd,
            position_min: lo, position_max: lo + span, torque_max: tmax,
        };
        let mut buf = [0xA5u8; ParameterRecord::LEN];
        r.emit(&mut buf).unwrap();
        prop_assert_eq!(ParameterRecord::parse(&buf).unwrap(), r);
        prop_assert_eq!(ParameterRecord::find(&buf, ModId(id)).unwrap(), Some(r));
    }

    #[test]
    fn quadlets_round_trip(id in 0u8..32, kind in 0u8..16, fw in 0u8..16,
                           st in state(), phy in 0u8..64, generation in 0u16..1024) {
        let i = Identity { mod_id: ModId(id), kind: ModuleKind::from(kind), firmware: fw };
        prop_assert_eq!(Identity::from_quadlet(i.to_quadlet().unwrap()).unwrap(), i);
        let c = IdCheck { mod_id: ModId(id), state: st, phy_id: phy, generation };
        prop_assert_eq!(IdCheck::from_quadlet(c.to_quadlet().unwrap()).unwrap(), c);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400),
                                   id in 0u8..64, q: u32, offset: u64) {
        let _ = JointBlock::parse(&bytes);
        let _ = FtBlock::parse(&bytes);
        let _ = SetpointSlot::parse(&bytes);
        let _ = SetpointSlot::slice(&bytes, ModId(id));
        let _ = ParameterRecord::parse(&bytes);
        let _ = ParameterRecord::find(&bytes, ModId(id));
        let _ = Identity::from_quadlet(q);
        let _ = IdCheck::from_quadlet(q);
        let _ = Command::from_offset(offset);
        // A QWRITE of the right size always slices for IDs with a slot.
        if bytes.len() == QWRITE_LEN && id < 10 {
            prop_assert!(SetpointSlot::slice(&bytes, ModId(id)).is_ok());
        }
    }
}
