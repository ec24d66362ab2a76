//! Host CPU cost of one I/O cycle, 8 QLA1 Rev 8 boards:
//! - `host_only`: the host library alone, against a port that replays a
//!   recorded hub block instantly (query word, hub parse and checks, 8 read
//!   blocks parsed, command block built);
//! - `with_simulated_bus`: the same cycle on the in-process simulated bus
//!   with emulated boards (host + bus + firmware + plants).
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_host::sim::SimPort;
use firelink_host::{Dest, Port, Result};

fn sim_port(n: u8) -> SimPort {
    let boards = (0..n)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
        .collect();
    let rig = BoardRig::daisy_chain(boards, &RigOptions::default());
    SimPort::new(rig.bus, rig.host)
}

/// Replays a recorded hub block: the sequence in each entry's header is
/// patched to the current query, so every cycle passes its checks.
struct ReplayPort {
    hub: Vec<u8>,
    seq: u16,
    entries: Vec<usize>,
}

impl Port for ReplayPort {
    fn name(&self) -> &str {
        "replay"
    }
    fn read_quadlet(&mut self, _: Dest, _: u64) -> Result<u32> {
        Ok(0)
    }
    fn write_quadlet(&mut self, _: Dest, _: u64, value: u32) -> Result<()> {
        self.seq = (value >> 16) as u16;
        Ok(())
    }
    fn read_block(&mut self, _: Dest, _: u64, out: &mut [u8]) -> Result<()> {
        for &at in &self.entries {
            if let Some(b) = self.hub.get_mut(at + 1) {
                *b = self.seq as u8;
            }
        }
        out.copy_from_slice(&self.hub[..out.len()]);
        Ok(())
    }
    fn write_block(&mut self, _: Dest, _: u64, data: &[u8]) -> Result<()> {
        black_box(data);
        Ok(())
    }
    fn wait(&mut self, _: Duration) {}
    fn now(&self) -> Duration {
        Duration::ZERO
    }
    fn generation(&self) -> u32 {
        0
    }
}

fn cycle(c: &mut Criterion) {
    let mut group = c.benchmark_group("broadcast_cycle_8_boards");

    // Record one hub block from the emulated boards.
    let mut p = sim_port(8);
    let report = scan(&mut p).unwrap();
    let (mut io, _) = IoSystem::open(p, IoOptions::default()).unwrap();
    io.cycle();
    let quadlets = 8 * 33 + 1;
    let mut hub = vec![0u8; quadlets * 4];
    io.port_mut()
        .read_block(Dest::node(0), 0x1000, &mut hub)
        .unwrap();
    let entries = (0..8).map(|i| i * 33 * 4).collect();
    let replay = ReplayPort {
        hub,
        seq: 0,
        entries,
    };
    let config = IoOptions {
        protocol: Some(Protocol::Broadcast),
        ..IoOptions::default()
    };
    let mut host_only = IoSystem::with_scan(replay, &report, config).unwrap();
    assert!(
        host_only.cycle().all_ok(),
        "replayed cycle passes every check"
    );
    group.bench_function("host_only", |b| {
        b.iter(|| {
            for board in host_only.boards_mut() {
                board.set_dac(0, 0x8100).unwrap();
            }
            black_box(host_only.cycle().missed)
        })
    });

    group.bench_function("with_simulated_bus", |b| {
        b.iter(|| black_box(io.cycle().missed))
    });
    group.finish();
}

criterion_group!(benches, cycle);
criterion_main!(benches);
