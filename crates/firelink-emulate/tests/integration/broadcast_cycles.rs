//! Issue 13, item 2: the broadcast protocol over loopback UDP never sees a
//! hub that still holds the previous cycle, at any board count and however
//! the host's and the emulator's threads are scheduled. 16 QLA1 Rev 8
//! boards overflow one hub and run in two broadcast groups: two queries
//! and two hub reads per cycle, each of which must see its own query.
//!
//! On real boards the status broadcasts of every selected board are on the
//! bus within a few microseconds of the query, long before a host can get a
//! hub read to the bridge. The emulator guarantees the same in virtual
//! time: a datagram is handled only once the consequences of the ones
//! before it (the boards' status slots after a query) are complete, so the
//! hub read that follows a query always sees that query's cycle. The host
//! here waits *nothing* between query and hub read (the worst case; the
//! reference host waits a few microseconds), so any regression shows as
//! sequence errors at once.
//!
//! Run it under load to see it hold: start two CPU-bound processes
//! (`( while :; do :; done ) &` twice), run
//! `cargo test -p firelink-emulate --test broadcast_cycles`, then kill them.

use crate::common;

use common::{Server, qla1s};

use std::time::Duration;

use firelink_board::qla::config::Profile;
use firelink_emulate::BridgeStats;
use firelink_host::cycle_report::IoStats;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;

/// Run `cycles` broadcast cycles (query and hub read per group, command
/// write) against `boards` emulated boards; the host does not wait between
/// a query and its hub read. Returns the broadcast groups too.
fn run(boards: u8, profile: Profile, cycles: u64) -> (IoStats, BridgeStats, usize) {
    let server = Server::start(qla1s(boards, profile));
    let port = server.port(Duration::from_millis(100));
    let config = IoOptions {
        protocol: Some(Protocol::Broadcast),
        broadcast_wait: Some(Duration::ZERO),
        ..IoOptions::default()
    };
    let (mut io, scan) = IoSystem::open(port, config).unwrap();
    assert_eq!(scan.boards.len(), usize::from(boards));
    assert_eq!(io.protocol(), Protocol::Broadcast);
    let groups = io.broadcast_groups().len();
    // Generous once discovery is done (absent nodes cost discovery one
    // time-out each): a time-out here would be a scheduling stall, not a
    // hub that missed its cycle, and must not turn into a later mismatch.
    io.port_mut().set_timeout(Duration::from_secs(2));
    for _ in 0..cycles {
        io.cycle();
    }
    let stats = *io.stats();
    drop(io);
    (stats, server.stop(), groups)
}

#[test]
fn broadcast_cycles_over_udp_never_miss_their_query() {
    // 16 QLA1 boards fit the 512-quadlet hub in one group with Rev 7
    // blocks; with Rev 8 blocks they take two groups.
    let runs: Vec<(u8, IoStats, BridgeStats)> = [
        (1u8, Profile::Rev8, 1),
        (2, Profile::Rev8, 1),
        (4, Profile::Rev8, 1),
        (8, Profile::Rev8, 1),
        (16, Profile::Rev7, 1),
        (16, Profile::Rev8, 2),
    ]
    .into_iter()
    .map(|(boards, profile, expected_groups)| {
        let (io, bridge, groups) = run(boards, profile, 2000);
        eprintln!(
            "{boards:2} boards ({}, {groups} group(s)): {} sequence errors, {} time-outs, {} clean of {} cycles; bridge: {bridge}",
            profile.name(),
            io.sequence_errors,
            io.timeouts,
            io.clean_cycles,
            io.cycles
        );
        assert_eq!(groups, expected_groups, "{boards} boards {profile:?}");
        (boards, io, bridge)
    })
    .collect();
    for (boards, io, bridge) in runs {
        assert_eq!(io.cycles, 2000);
        assert_eq!(
            io.sequence_errors, 0,
            "{boards} boards: hub reads that missed their query: {io:?}"
        );
        assert_eq!(io.timeouts, 0, "{boards} boards: {io:?}");
        assert_eq!(io.clean_cycles, 2000, "{boards} boards: {io:?}");
        assert_eq!(bridge.accounted(), bridge.datagrams, "{bridge}");
    }
}
