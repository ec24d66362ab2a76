//! The runner's whole cycle (read -> check -> compute -> write, through the
//! host library's `IoSystem`) allocates nothing once set up, on a port that
//! allocates nothing itself (the port-level loopback boards).
//!
//! Counted per thread (`allocation-counter`), so libtest's own threads
//! cannot show up in the figure (see `alloc_free.rs`).

use firelink_control::config::presets;
use firelink_control::runner::loopback::LoopbackPort;
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, Sinusoid};
use firelink_host::io::{IoConfig as HostIoConfig, IoSystem};
use firelink_host::scan::Protocol;

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
        let port = LoopbackPort::from_config(&config, start);
        let (io, _) = IoSystem::open(
            port,
            HostIoConfig {
                protocol: Some(protocol),
                ..HostIoConfig::default()
            },
        )
        .unwrap();
        let settings = RobotSettings {
            rate_hz: 6000.0,
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
