//! Run a number of replayed 28-axis host cycles (see
//! `firelink_testbed::dvrk::bench::host_cpu`) and nothing else, for profilers
//! that count instructions:
//!
//! ```sh
//! cargo build --release -p firelink-testbed --example host_cycle
//! valgrind --tool=callgrind --toggle-collect='*host_cycle::replay*' \
//!     target/release/examples/host_cycle 10000
//! ```
//!
//! Instructions per cycle = the collected total / the cycles asked for.

use std::process::ExitCode;

use firelink_testbed::dvrk::bench::host_cpu::RecordedCycle;

/// `cycles` replayed cycles; false if one failed.
#[inline(never)]
fn replay(recorded: &mut RecordedCycle, cycles: u64) -> bool {
    (0..cycles).all(|_| recorded.cycle().is_ok())
}

fn main() -> ExitCode {
    let cycles = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(10_000);
    let mut recorded = match RecordedCycle::record() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("host_cycle: {e}");
            return ExitCode::FAILURE;
        }
    };
    if !replay(&mut recorded, cycles) {
        eprintln!("host_cycle: a replayed cycle failed");
        return ExitCode::FAILURE;
    }
    println!("{cycles} replayed 28-axis host cycles");
    ExitCode::SUCCESS
}
