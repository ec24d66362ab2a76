//! The benchmark's UDP points: each wait mode with its floor and CPU
//! figures, against the in-process emulator and against a bridge given by
//! address. Figures are measured, never judged here (the machine is
//! shared): only that they are there and make sense.

use firelink_board::qla::config::{Hardware, Profile};
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::WaitMode;
use firelink_testbed::dvrk::bench::{BenchOptions, BenchTransport, run_bench};
use firelink_testbed::rig;

#[test]
fn each_wait_mode_is_a_point_with_its_floor_and_cpu() {
    let report = run_bench(
        &BenchOptions {
            transports: vec![BenchTransport::Udp],
            boards: vec![2],
            protocols: vec![Protocol::Broadcast],
            cycles: 60,
            udp_waits: WaitMode::ALL.to_vec(),
            ..BenchOptions::default()
        },
        |_, _, _| {},
    )
    .unwrap();
    assert_eq!(report.results.len(), 2);
    for (p, wait) in report.results.iter().zip(["block", "spin"]) {
        assert_eq!(p.wait, Some(wait));
        assert_eq!((p.boards, p.cycles), (2, 60));
        let u = p.udp.as_ref().unwrap();
        assert_eq!(u.target, "in-process emulator");
        assert!(u.floor_us.median > 0.0, "{u:?}");
        assert!(u.floor_ratio > 0.0, "{u:?}");
        assert!(u.host_cpu_us > 0.0 && u.floor_host_cpu_us > 0.0, "{u:?}");
        assert!(u.emulator_cpu_us.is_some_and(|c| c > 0.0), "{u:?}");
        // The floor's responder answered the floor's reads: its thread ran.
        assert!(u.floor_server_cpu_us.is_some_and(|c| c > 0.0), "{u:?}");
        // The two, set against each other in the same run.
        assert_eq!(
            u.emulator_cpu_ratio,
            Some(
                ((u.emulator_cpu_us.unwrap() / u.floor_server_cpu_us.unwrap()) * 1000.0).round()
                    / 1000.0
            ),
            "{u:?}"
        );
        // Query, hub read and its answer, commands: at least four calls.
        assert!(u.socket_calls_per_cycle >= 4.0, "{u:?}");
    }
    let text = report.to_string();
    assert!(
        text.contains("udp/block") && text.contains("udp/spin"),
        "{text}"
    );
    assert!(text.contains("floor"), "{text}");
}

#[test]
fn a_bridge_given_by_address_is_measured_with_the_boards_it_has() {
    let emu =
        rig::Emulator::start(rig::generic_boards(3, Hardware::Qla1, Profile::Rev8, 7)).unwrap();
    let addr = emu.addr;
    let mut seen = Vec::new();
    let report = run_bench(
        &BenchOptions {
            transports: vec![BenchTransport::Udp],
            // Board counts are the simulated bus's: not used here.
            boards: vec![2, 62],
            protocols: vec![Protocol::Sequential, Protocol::Broadcast],
            cycles: 40,
            udp_target: Some(addr),
            ..BenchOptions::default()
        },
        |t, proto, n| seen.push((t, proto, n)),
    )
    .unwrap();
    emu.stop().unwrap();
    assert_eq!(
        seen,
        [
            (BenchTransport::Udp, Protocol::Sequential, 0),
            (BenchTransport::Udp, Protocol::Broadcast, 0)
        ]
    );
    assert_eq!(report.results.len(), 2);
    for p in &report.results {
        assert_eq!((p.transport, p.boards, p.model), ("udp", 3, false));
        let u = p.udp.as_ref().unwrap();
        assert_eq!(u.target, format!("udp:{addr}"));
        assert_eq!(u.emulator_cpu_us, None);
        // The floor's responder is in this process whatever the target.
        assert!(u.floor_server_cpu_us.is_some_and(|c| c > 0.0), "{u:?}");
        assert!(u.floor_us.median > 0.0 && u.floor_ratio > 0.0, "{u:?}");
    }
}
