//! The runner's whole cycle (read -> check -> compute -> write, through the
//! host library's `IoSystem` and `SimPort`) allocates nothing once set up.
//! The emulated boards and the simulated bus under the port are the plant,
//! not the host: what they allocate is not counted (`NotCounted`).
//!
//! Counted per thread (`allocation-counter`), so libtest's own threads
//! cannot show up in the figure (see `alloc_free.rs`).

use crate::common;

use std::time::Duration;

use firelink_control::config::presets;
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, Sinusoid};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::{Dest, Port, Result};

#[test]
fn runner_cycle_does_not_allocate() {
    for protocol in [Protocol::Broadcast, Protocol::Sequential] {
        let config = presets::dvrk_seed000();
        let start = |i: usize| {
            let l = config
                .joints()
                .nth(i)
                .map(|j| j.actuator.encoder.position_limits_soft);
            l.map_or(0.0, |l| 0.5 * (l.lower + l.upper))
        };
        let port = NotCounted(common::port(&config, false, start));
        let (io, _) = IoSystem::open(
            port,
            IoOptions {
                protocol: Some(protocol),
                ..IoOptions::default()
            },
        )
        .unwrap();
        let settings = RobotSettings {
            period: firelink_control::ServoPeriod::from_rate_hz(6000.0).unwrap(),
            max_samples: 10_000,
            ..RobotSettings::default()
        };
        let mut robot = Robot::new(io, &config, settings).unwrap();
        robot.configure().unwrap();
        robot.power_on().unwrap();
        robot.home().unwrap();
        robot.activate().unwrap();
        for i in 0..robot.joint_count() {
            let p = robot.position(i).unwrap();
            let s = Sinusoid::new(0.02, 0.5, 0.0, p, 0.2).unwrap();
            robot.set_motion(i, Motion::Sinusoid(s)).unwrap();
        }
        let stats = allocation_counter::measure(|| {
            robot.run(3000, Pacing::Virtual, 0, |_| {}).unwrap();
        });
        assert_eq!(stats.count_total, 0, "{protocol:?}: {stats:?}");
    }
}

/// A port whose own work (here: the simulated bus and the emulated boards
/// it runs) is left out of the allocation count.
struct NotCounted<P: Port>(P);

impl<P: Port> NotCounted<P> {
    fn quiet<T>(&mut self, f: impl FnOnce(&mut P) -> T) -> T {
        let mut out = None;
        allocation_counter::opt_out(|| out = Some(f(&mut self.0)));
        out.expect("the closure ran")
    }
}

impl<P: Port> Port for NotCounted<P> {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.quiet(|p| p.read_quadlet(dest, offset))
    }
    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.quiet(|p| p.write_quadlet(dest, offset, value))
    }
    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        self.quiet(|p| p.read_block(dest, offset, out))
    }
    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.quiet(|p| p.write_block(dest, offset, data))
    }
    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.quiet(|p| p.start_write_quadlet(dest, offset, value))
    }
    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.quiet(|p| p.start_write_block(dest, offset, data))
    }
    fn wait(&mut self, duration: Duration) {
        self.quiet(|p| p.wait(duration));
    }
    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        self.quiet(|p| p.wait_until_heard(limit, heard))
    }
    fn now(&self) -> Duration {
        self.0.now()
    }
    fn generation(&self) -> u32 {
        self.0.generation()
    }
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.0.candidate_nodes()
    }
}
