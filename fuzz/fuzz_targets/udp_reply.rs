//! Fuzz the host's UDP reply path: arbitrary datagrams judged against an
//! open request of any kind. It never panics, each datagram is either the
//! answer (its payload fills the buffer exactly), refused and counted under
//! one reason, or an error naming what was wrong with the answer itself.
#![no_main]

use firelink_host::Dest;
use firelink_host::transaction::{Expect, Transactions};
use firelink_host::udp::judge_reply;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&[kind, node, tl, len], datagrams)) = data.split_first_chunk::<4>() else {
        return;
    };
    let dest = match kind % 3 {
        0 => Dest::node(node % 64),
        1 => Dest::BROADCAST,
        _ => Dest {
            node: node % 64,
            no_forward: true,
        },
    };
    let tl = tl % 64;
    let expect = if kind & 0x80 == 0 {
        Expect::quadlet(dest, tl)
    } else {
        Expect::block(dest, tl, usize::from(len) * 4)
    };
    let mut out = vec![0u8; expect.len];
    let mut t = Transactions::with_generation(1);
    let mut rest = datagrams;
    while let [n, tail @ ..] = rest {
        let n = usize::from(*n).min(tail.len());
        let (datagram, after) = tail.split_at(n);
        rest = after;
        let before = t.stats();
        match judge_reply(&mut t, datagram, &expect, &mut out) {
            Ok(Some(_)) => assert_eq!(t.stats().matched, before.matched + 1),
            Ok(None) => assert_eq!(t.stats().refused(), before.refused() + 1),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
});
