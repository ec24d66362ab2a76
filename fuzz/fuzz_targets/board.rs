//! Fuzz the board protocol parsers: real-time blocks, hub blocks and the
//! concatenated command block, for every layout.
#![no_main]

use firelink_wire::qla::broadcast::{
    BoardSlot, HubBlock, SeqRule, command_slices, find_command_block,
};
use firelink_wire::qla::realtime::{
    BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr, WriteBlock, WriteBlockRepr,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, data)) = data.split_first() else {
        return;
    };
    let layouts = [
        BoardLayout::qla1(FirmwareRev::Rev7),
        BoardLayout::qla1(FirmwareRev::Rev8),
        BoardLayout::dqla(FirmwareRev::Rev8),
    ];
    for layout in layouts {
        if let Ok(view) = ReadBlock::new_checked(data, layout) {
            if let Ok(repr) = ReadBlockRepr::parse(&view) {
                let mut out = vec![0u8; repr.buffer_len()];
                repr.emit(&mut out).expect("emit parsed read block");
                assert_eq!(out, data);
            }
        }
        if let Ok(view) = WriteBlock::new_checked(data, layout) {
            let _ = WriteBlockRepr::parse(&view);
        }
        for slice in command_slices(data, layout).take(64) {
            if slice.is_err() {
                break;
            }
        }
        let _ = find_command_block(data, selector & 0x0F, layout);
        let boards = usize::from(selector % 17);
        let slots: Vec<BoardSlot> = (0..boards as u8)
            .map(|id| BoardSlot { id, layout })
            .collect();
        if let Ok(hub) = HubBlock::new_checked(data, &slots) {
            for entry in hub.entries() {
                let _ = entry.validate(SeqRule::for_firmware(layout.firmware()), 1);
            }
            let _ = hub.timing();
            let _ = hub.check_sequences(SeqRule::Seed000, 0x1234);
        }
    }
});
