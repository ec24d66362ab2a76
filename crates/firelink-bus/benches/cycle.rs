//! Cost of simulating one I/O cycle (CPU time per simulated cycle).
//!
//! `seed_broadcast_8` is the whole of `simulate_cycle` for seed 000's
//! 8-board broadcast cycle: building the bus, the initial bus reset, the
//! cycle (about 110 us of virtual time) and the report;
//! `seed_broadcast_8_cycle_only` times the cycle alone. BENCHMARKS.md
//! compares them with the virtual time they model.
// `criterion_group!` generates an undocumented public function.
#![allow(missing_docs)]

use criterion::BatchSize;
use criterion::{Criterion, criterion_group, criterion_main};
use firelink_bus::scenario::{CycleConfig, Profile, Protocol, prepare_cycle, simulate_cycle};
use std::hint::black_box;

fn cycle(c: &mut Criterion) {
    let seed = CycleConfig::new(8, Profile::Seed, Protocol::Broadcast);
    c.bench_function("seed_broadcast_8", |b| {
        b.iter(|| black_box(simulate_cycle(black_box(&seed))))
    });
    // The cycle alone: the bus is built and reset outside the timing.
    c.bench_function("seed_broadcast_8_cycle_only", |b| {
        b.iter_batched(
            || prepare_cycle(&seed),
            |prepared| black_box(prepared.run()),
            BatchSize::PerIteration,
        )
    });
    let rev8 = CycleConfig::new(8, Profile::Rev8, Protocol::Broadcast);
    c.bench_function("rev8_broadcast_8", |b| {
        b.iter(|| black_box(simulate_cycle(black_box(&rev8))))
    });
    let seq = CycleConfig::new(8, Profile::Seed, Protocol::Sequential);
    c.bench_function("seed_sequential_8", |b| {
        b.iter(|| black_box(simulate_cycle(black_box(&seq))))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = cycle
}
criterion_main!(benches);
