//! Fuzz the emulator's datagram handler: a stream of arbitrary datagrams
//! (CRCs pass under `cfg(fuzzing)`, so every path is reachable) into a
//! bridge in front of two emulated boards. It never panics, every datagram
//! is counted under exactly one outcome, every reply is a well-formed
//! board datagram, and nothing accumulates in the bridge's link.
#![no_main]

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_emulate::{Bridge, Handled};
use firelink_wire::bridge::split_board_datagram;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let boards = (0..2)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
        .collect();
    let rig = BoardRig::daisy_chain(boards, &RigOptions::default());
    let first = rig.boards[0];
    let mut bridge = Bridge::new(rig.bus, rig.host, first);
    let mut reply = Vec::new();
    // Each datagram: one length byte, then that many bytes.
    let mut rest = data;
    let mut sent = 0u64;
    while let [len, tail @ ..] = rest {
        let n = usize::from(*len).min(tail.len());
        let (datagram, after) = tail.split_at(n);
        rest = after;
        sent += 1;
        if let Handled::Reply(n) = bridge.handle(datagram, &mut reply) {
            let bytes = reply.get(..n).expect("reply length within the buffer");
            split_board_datagram(bytes).expect("a reply is a well-formed board datagram");
        }
        let stats = bridge.stats();
        assert_eq!(stats.datagrams, sent);
        assert_eq!(stats.accounted(), stats.datagrams, "{stats}");
        assert_eq!(bridge.link_backlog(), 0);
    }
});
