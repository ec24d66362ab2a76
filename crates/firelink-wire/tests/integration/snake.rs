//! Property tests of the Snake node codecs (seed 001): untrusted words and
//! blocks never panic, everything accepted round-trips bit for bit, and
//! every meaning emitted parses back to itself.

use firelink_wire::snake::address::SnakeRegister;
use firelink_wire::snake::block::{
    READ_BLOCK_LEN, ReadBlock, ReadBlockRepr, WRITE_BLOCK_LEN, WriteBlock, WriteBlockRepr,
};
use firelink_wire::snake::registers::{
    AdcData, ChannelCommand, DacCommand, EncoderPreload, PotCommand, adc_to_api, api_to_adc,
};
use proptest::prelude::*;

proptest! {
    #[test]
    fn any_read_block_round_trips(bytes in proptest::collection::vec(any::<u8>(), READ_BLOCK_LEN)) {
        let view = ReadBlock::new_checked(&bytes[..]).unwrap();
        let repr = ReadBlockRepr::parse(&view).unwrap();
        let mut out = vec![0xA5u8; READ_BLOCK_LEN];
        repr.emit(&mut out).unwrap();
        // ADC bits 31:30 and 15:14 are not part of the meaning.
        let view2 = ReadBlock::new_checked(&out[..]).unwrap();
        prop_assert_eq!(ReadBlockRepr::parse(&view2).unwrap(), repr);
    }

    #[test]
    fn any_length_is_checked(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let r = ReadBlock::new_checked(&bytes[..]);
        prop_assert_eq!(r.is_ok(), bytes.len() == READ_BLOCK_LEN);
        let w = WriteBlock::new_checked(&bytes[..]);
        prop_assert_eq!(w.is_ok(), bytes.len() == WRITE_BLOCK_LEN);
        if let Ok(w) = w {
            let _ = WriteBlockRepr::parse(&w);
        }
    }

    #[test]
    fn write_blocks_round_trip(commands in proptest::array::uniform7(proptest::option::of(any::<u16>()))) {
        let repr = WriteBlockRepr { commands };
        let mut out = [0xA5u8; WRITE_BLOCK_LEN];
        repr.emit(&mut out).unwrap();
        let back = WriteBlockRepr::parse(&WriteBlock::new_checked(&out[..]).unwrap()).unwrap();
        prop_assert_eq!(back, repr);
    }

    #[test]
    fn accepted_words_round_trip(word in any::<u32>()) {
        if let Ok(c) = PotCommand::parse(word) {
            prop_assert_eq!(c.to_word(), word);
        }
        if let Ok(c) = DacCommand::parse(word) {
            prop_assert_eq!(c.to_word(), word);
        }
        if let Ok(c) = ChannelCommand::parse(word) {
            prop_assert_eq!(c.to_word(), word);
        }
        if let Ok(p) = EncoderPreload::parse(word) {
            prop_assert_eq!(p.to_word(), word);
        }
        let adc = AdcData(word);
        prop_assert!(adc.pot_api() <= 16383 && adc.current_api() <= 16383);
        prop_assert_eq!(api_to_adc(adc.pot_api()).unwrap(), adc.pot());
    }

    #[test]
    fn offsets_decode_or_fail_cleanly(offset in any::<u64>()) {
        if let Ok(r) = SnakeRegister::from_offset(offset) {
            prop_assert_eq!(r.offset(), offset);
        }
    }

    #[test]
    fn adc_api_is_monotonic(a in -8192i16..=8191, b in -8192i16..=8191) {
        prop_assert_eq!(a < b, adc_to_api(a) < adc_to_api(b));
    }
}
