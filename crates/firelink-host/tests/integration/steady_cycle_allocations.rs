//! The real-time path does not allocate: once a simulated bus of QLA
//! boards and the host's broadcast I/O have run for a while (every buffer,
//! queue and ring at its working size), a servo cycle (query, hub read,
//! command write, and the boards' status broadcasts on the bus) makes no
//! heap allocation, host side or board side.
//!
//! The counting allocator below is the global allocator of this crate's
//! integration-test binary. Every call goes on unchanged to the system
//! allocator, so the other tests of the binary are not affected; it counts
//! only on the thread that asked for counting, so the other tests and the
//! test harness's own threads, running beside, do not disturb the figure.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::TraceLevel;
use firelink_host::Port;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::sim::SimPort;

/// The system allocator, counting the allocations (and reallocations) of
/// a thread while that thread asks it to.
struct CountingAllocator;

thread_local! {
    /// Allocations seen on this thread while counting; `None`: not
    /// counting.
    static ALLOCATIONS: Cell<Option<u64>> = const { Cell::new(None) };
}

fn note_allocation() {
    // `try_with`: a thread being torn down has no counter, and is not
    // counting.
    let _ = ALLOCATIONS.try_with(|n| {
        if let Some(count) = n.get() {
            n.set(Some(count + 1));
        }
    });
}

// SAFETY: every call is passed on unchanged to the system allocator; the
// counter touches no heap memory. (A global allocator cannot be written
// without `unsafe`: test-only.)
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_allocation();
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note_allocation();
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note_allocation();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Allocations made on this thread by `f`.
fn allocations_in(f: impl FnOnce()) -> u64 {
    ALLOCATIONS.with(|n| n.set(Some(0)));
    f();
    ALLOCATIONS.with(|n| n.replace(None)).unwrap_or(0)
}

#[test]
fn a_steady_broadcast_cycle_allocates_nothing() {
    let boards = (0..8)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
        .collect();
    let rig = BoardRig::daisy_chain(
        boards,
        &RigOptions {
            trace: TraceLevel::Off,
            ..RigOptions::default()
        },
    );
    let (mut io, _) = IoSystem::open(SimPort::new(rig.bus, rig.host), IoOptions::default())
        .expect("the boards answer");
    assert_eq!(io.protocol(), Protocol::Broadcast);
    let cycle = |io: &mut IoSystem<SimPort>| {
        let report = *io.cycle();
        assert!(report.all_ok(), "{report:?}");
        // The command write is not waited for: let it onto the bus.
        io.port_mut().wait(Duration::from_micros(100));
    };
    // Warm up: the PC's link keeps the last 4096 packets it heard, so its
    // ring of received packets is full after some 500 cycles.
    for _ in 0..1500 {
        cycle(&mut io);
    }
    let allocations = allocations_in(|| {
        for _ in 0..200 {
            cycle(&mut io);
        }
    });
    assert_eq!(allocations, 0, "allocations in 200 steady cycles");
}
