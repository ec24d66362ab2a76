//! Cost of simulating one I/O cycle (CPU time per simulated cycle).
//!
//! `seed_broadcast_8` is the whole of `firelink_testbed::sim::simulate`
//! for seed 000's 8-board broadcast cycle: building the bus and the
//! emulated boards, the bus reset, the host library's scan, the cycle
//! (about 110 us of virtual time) and the report;
//! `seed_broadcast_8_cycle_only` times the cycle alone. BENCHMARKS.md
//! compares them with the virtual time they model.
// `criterion_group!` generates an undocumented public function.
#![allow(missing_docs)]

use criterion::BatchSize;
use criterion::{Criterion, criterion_group, criterion_main};
use firelink_board::qla::config::Profile;
use firelink_host::qla::scan::Protocol;
use firelink_testbed::sim::{SimOptions, prepare, simulate};
use std::hint::black_box;

fn cycle(c: &mut Criterion) {
    let seed = SimOptions::new(8, Profile::Seed, Protocol::Broadcast);
    c.bench_function("seed_broadcast_8", |b| {
        b.iter(|| black_box(simulate(black_box(&seed))))
    });
    // The cycle alone: the bus is built, reset and scanned outside the
    // timing.
    c.bench_function("seed_broadcast_8_cycle_only", |b| {
        b.iter_batched(
            || prepare(&seed),
            |prepared| black_box(prepared.map(|p| p.run().report)),
            BatchSize::PerIteration,
        )
    });
    let rev8 = SimOptions::new(8, Profile::Rev8, Protocol::Broadcast);
    c.bench_function("rev8_broadcast_8", |b| {
        b.iter(|| black_box(simulate(black_box(&rev8))))
    });
    let seq = SimOptions::new(8, Profile::Seed, Protocol::Sequential);
    c.bench_function("seed_sequential_8", |b| {
        b.iter(|| black_box(simulate(black_box(&seq))))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = cycle
}
criterion_main!(benches);
