//! The host's own CPU per servo cycle: seed 000's 28-axis dVRK on 8 QLA1
//! Rev 8 boards, broadcast protocol, with the I/O replaced by a recorded
//! hub block (`firelink_testbed::dvrk::bench::host_cpu`): no simulated bus, no
//! sockets.
//!
//! - `cycle_28_axes`: one whole host cycle (`Robot::cycle`): the hub block
//!   checked and parsed into 8 read blocks and latched, the runner's
//!   checks and compute for 28 axes, the command block built;
//! - `parse_8_boards`: the read phase alone (`IoSystem::read_all`);
//! - `build_commands_8_boards`: the write phase alone
//!   (`IoSystem::write_all`).
//!
//! (The port's own part, the replayed block copied into the host's
//! buffer and 8 sequence numbers patched, is in all three.)
// `criterion_group!` generates an undocumented public function.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use firelink_host::RobotIo;
use firelink_testbed::dvrk::bench::host_cpu::RecordedCycle;

fn host_cycle(c: &mut Criterion) {
    let mut recorded = RecordedCycle::record().expect("the recorded cycle sets up");
    let mut group = c.benchmark_group("host_cpu");
    group.bench_function("cycle_28_axes", |b| {
        b.iter(|| black_box(recorded.cycle().is_ok()))
    });
    group.bench_function("parse_8_boards", |b| {
        b.iter(|| black_box(recorded.robot_mut().io_mut().latch_all_inputs().missed))
    });
    group.bench_function("build_commands_8_boards", |b| {
        b.iter(|| black_box(recorded.robot_mut().io_mut().apply_all_outputs().missed))
    });
    group.finish();
}

criterion_group!(benches, host_cycle);
criterion_main!(benches);
