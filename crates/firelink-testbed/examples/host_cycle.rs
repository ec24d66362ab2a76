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
//!
//! `host_cycle N --digest` runs the same cycles and prints two FNV-1a
//! digests: of every command block written, and of the robot's state
//! (every joint's position, velocity, setpoint, commanded current and pot)
//! after every cycle. Two builds that compute the same bits print the same
//! digests (the check that a change to the cycle kept every result).

use std::process::ExitCode;

use firelink_testbed::dvrk::bench::host_cpu::{FNV_OFFSET, RecordedCycle};

/// `cycles` replayed cycles; false if one failed.
#[inline(never)]
fn replay(recorded: &mut RecordedCycle, cycles: u64) -> bool {
    (0..cycles).all(|_| recorded.cycle().is_ok())
}

/// `cycles` replayed cycles, the robot's state folded into a digest after
/// each; `None` if one failed.
fn replay_digest(recorded: &mut RecordedCycle, cycles: u64) -> Option<u64> {
    let mut states = FNV_OFFSET;
    for _ in 0..cycles {
        recorded.cycle().ok()?;
        states = recorded.fold_state(states);
    }
    Some(states)
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let usage = "usage: host_cycle [CYCLES [--digest]]";
    let cycles = match args.next() {
        None => 10_000,
        Some(a) => match a.parse() {
            Ok(n) => n,
            Err(_) => {
                eprintln!("host_cycle: {a:?} is not a cycle count; {usage}");
                return ExitCode::from(2);
            }
        },
    };
    let digest = match args.next().as_deref() {
        None => false,
        Some("--digest") => true,
        Some(other) => {
            eprintln!("host_cycle: unknown argument {other:?}; {usage}");
            return ExitCode::from(2);
        }
    };
    let mut recorded = match RecordedCycle::record() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("host_cycle: {e}");
            return ExitCode::FAILURE;
        }
    };
    if digest {
        recorded.robot_mut().io_mut().port_mut().digest_writes();
        let Some(states) = replay_digest(&mut recorded, cycles) else {
            eprintln!("host_cycle: a replayed cycle failed");
            return ExitCode::FAILURE;
        };
        let commands = recorded
            .robot()
            .io()
            .port()
            .written_digest()
            .unwrap_or_default();
        println!("{cycles} replayed 28-axis host cycles");
        println!("digest: commands {commands:016x} states {states:016x}");
        return ExitCode::SUCCESS;
    }
    if !replay(&mut recorded, cycles) {
        eprintln!("host_cycle: a replayed cycle failed");
        return ExitCode::FAILURE;
    }
    println!("{cycles} replayed 28-axis host cycles");
    ExitCode::SUCCESS
}
