//! The demo and the bench as library calls: typed reports, the same
//! report for the same inputs, faults detected with the safety chain.

use firelink_host::qla::scan::Protocol;
use firelink_testbed::demo::{DemoFault, DemoProgress, PortSpec};
use firelink_testbed::dvrk::bench::{BenchOptions, BenchTransport, check_board_counts, run_bench};
use firelink_testbed::dvrk::demo::{DemoOptions, run_demo};

fn short(fault: DemoFault) -> DemoOptions {
    DemoOptions {
        duration_s: 0.1,
        fault,
        ..DemoOptions::default()
    }
}

#[test]
fn the_demo_runs_the_dvrk_and_reports_the_same_twice() {
    let mut events = Vec::new();
    let a = run_demo(&short(DemoFault::None), None, |e| events.push(e)).unwrap();
    assert_eq!(a.verdict(), Ok(()));
    assert_eq!((a.boards, a.axes), (8, 28));
    assert_eq!(a.errors.total, 0);
    assert_eq!(a.protocol, "broadcast");
    assert_eq!(a.motion_cycles, 600);
    assert!(a.tracking_error.contains_key("PSM1"));
    assert!(matches!(
        events.first(),
        Some(DemoProgress::Found { boards: 8, .. })
    ));
    assert!(matches!(events.last(), Some(DemoProgress::PoweredOff(_))));
    let mut b = run_demo(&short(DemoFault::None), None, |_| {}).unwrap();
    // Only what the host's own clock measures may differ: wall time and
    // the compute part of the cycle (host CPU time).
    b.wall_time_s = a.wall_time_s;
    b.speed_vs_real_time = a.speed_vs_real_time;
    b.compute_time_us = a.compute_time_us;
    b.cycle_time_us = a.cycle_time_us;
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );
}

#[test]
fn a_lost_board_is_named_and_every_amplifier_ends_off() {
    let r = run_demo(&short(DemoFault::BoardLoss), None, |_| {}).unwrap();
    assert_eq!(r.verdict(), Ok(()), "{r}");
    let fault = r.fault.as_ref().unwrap();
    assert_eq!(fault.board, Some(4), "{fault:?}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false));
    assert!(r.boards_not_answering.contains(&4));
    // What the host cannot see is reported as unknown, not as "off" or
    // "not expired".
    assert_eq!(r.watchdog.unknown_boards, r.boards_not_answering);
    assert!(
        r.watchdog
            .expired_boards
            .iter()
            .all(|b| !r.boards_not_answering.contains(b))
    );
    assert!(r.power_down.unknown.contains(&4), "{:?}", r.power_down);
    assert!(r.power_down.still_on.is_empty());
    let text = r.to_string();
    assert!(
        text.contains("amplifiers off on the boards that answer"),
        "{text}"
    );
    assert!(
        text.contains("not answering: amplifier state unknown"),
        "{text}"
    );
    assert!(text.contains("did not answer: state unknown"), "{text}");
    assert!(!text.contains("expired on boards []"), "{text}");
}

#[test]
fn a_verdict_fails_when_an_injected_fault_goes_unseen() {
    let mut r = run_demo(
        &DemoOptions {
            port: PortSpec::SIM,
            ..short(DemoFault::None)
        },
        None,
        |_| {},
    )
    .unwrap();
    assert_eq!(r.verdict(), Ok(()));
    r.fault_injected = DemoFault::StopHost.name().into();
    assert!(r.verdict().unwrap_err().contains("not detected"));
}

#[test]
fn bad_demo_options_are_refused_with_the_reason() {
    // A rate of 0 is no servo period.
    let e = firelink_control::ServoPeriod::from_rate_hz(0.0).unwrap_err();
    assert!(e.to_string().contains("out of range"), "{e}");
    let e = run_demo(
        &DemoOptions {
            duration_s: 0.0,
            ..DemoOptions::default()
        },
        None,
        |_| {},
    )
    .unwrap_err();
    assert!(e.to_string().contains("duration"), "{e}");
    assert!("meteor".parse::<DemoFault>().is_err());
    assert!("nowhere".parse::<PortSpec>().is_err());
    assert_eq!(
        "board-loss".parse::<DemoFault>().unwrap(),
        DemoFault::BoardLoss
    );
}

#[test]
fn the_bench_measures_models_and_says_which_is_which() {
    let options = BenchOptions {
        transports: vec![BenchTransport::Sim],
        boards: vec![2, 8, 32],
        protocols: vec![Protocol::Sequential, Protocol::Broadcast],
        cycles: 20,
        ..BenchOptions::default()
    };
    let mut heard = Vec::new();
    let r = run_bench(&options, |t, p, n| heard.push((t, p, n))).unwrap();
    assert_eq!(heard.len(), 4, "32 boards is modelled, not run");
    assert_eq!(r.results.len(), 6);
    let at = |proto: &str, n: usize| {
        r.results
            .iter()
            .find(|p| p.protocol_asked == proto && p.boards == n)
            .unwrap()
    };
    assert!(!at("sequential", 8).model && at("sequential", 32).model);
    assert_eq!(at("sequential", 32).io_time_us.max, None);
    assert!(at("broadcast", 8).io_time_us.median < at("sequential", 8).io_time_us.median);
    assert!(r.results.iter().all(|p| p.errors == 0));
    // The I/O figures are deterministic on the simulated bus (the compute
    // time, and the rate and budget built on it, are the host's own CPU).
    let again = run_bench(&options, |_, _, _| {}).unwrap();
    let io = |r: &firelink_testbed::dvrk::bench::BenchReport| {
        r.results
            .iter()
            .map(|p| (p.io_time_us, p.read_us, p.write_us, p.errors, p.model))
            .collect::<Vec<_>>()
    };
    assert_eq!(io(&r), io(&again));
    assert!(check_board_counts(&[32, 8]).is_err());
    assert!(check_board_counts(&[]).is_err());
    assert!(check_board_counts(&[0]).is_err());
}

/// Today's controllers: `configs/dvrk-dqla-rev9.json`'s arms, one DQLA
/// (FPGA V3, firmware Rev 9) each, for a short run.
fn dqla(fault: DemoFault) -> DemoOptions {
    DemoOptions {
        config: firelink_control::config::presets::dqla_rev9(),
        firmware: firelink_board::qla::config::Profile::Rev9,
        ..short(fault)
    }
}

#[test]
fn the_demo_runs_dqla_arms_at_rev9_with_no_errors() {
    let r = run_demo(&dqla(DemoFault::None), None, |_| {}).unwrap();
    assert_eq!(r.verdict(), Ok(()), "{r}");
    // MTMR 7 + ECM 4 + PSM1 7 axes on three DQLAs (IDs 2, 4, 6: the IDs
    // between are no board).
    assert_eq!((r.boards, r.axes), (3, 18), "{r}");
    assert_eq!(r.firmware, Some(9));
    assert_eq!(r.errors.total, 0, "{r}");
    assert_eq!(r.protocol, "broadcast");
    for arm in ["MTMR", "ECM", "PSM1"] {
        assert!(r.tracking_error.contains_key(arm), "{arm}: {r}");
    }
    assert!(r.power_down.still_on.is_empty(), "{:?}", r.power_down);
}

#[test]
fn a_lost_dqla_board_is_named_and_every_amplifier_ends_off() {
    let r = run_demo(&dqla(DemoFault::BoardLoss), None, |_| {}).unwrap();
    assert_eq!(r.verdict(), Ok(()), "{r}");
    // Board 4 is the ECM's DQLA.
    let fault = r.fault.as_ref().unwrap();
    assert_eq!(fault.board, Some(4), "{fault:?}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false), "{r}");
    assert!(r.boards_not_answering.contains(&4), "{r}");
    assert!(r.power_down.unknown.contains(&4), "{:?}", r.power_down);
    assert!(r.power_down.still_on.is_empty(), "{:?}", r.power_down);
    // The DQLA before the lost one in the status broadcasts' chain still
    // answers, switched off (the one after it may not be read in time).
    assert!(r.power_down.off.contains(&2), "{:?}", r.power_down);
}

#[test]
fn a_stopped_host_trips_the_dqla_watchdogs() {
    let r = run_demo(&dqla(DemoFault::StopHost), None, |_| {}).unwrap();
    assert_eq!(r.verdict(), Ok(()), "{r}");
    assert!(r.fault.is_some(), "{r}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false), "{r}");
    assert!(r.power_down.still_on.is_empty(), "{:?}", r.power_down);
}

/// The DQLA arms on the Ethernet-only network (`firelink emulate
/// --network eth`, here served in-process on loopback) driven through
/// `udp:` at the network's group address (the port `firelink demo --port
/// udp:` opens, with a time-out that only guards against a hang): every
/// broadcast cycle read with no error. The servo loop is paced by the wall
/// clock here, so on a loaded machine late cycles may end the motion in a
/// fault; what is checked of that is the safety chain (amplifiers off).
#[test]
fn the_demo_runs_dqla_arms_over_the_ethernet_only_network() {
    use firelink_control::runner::{Pacing, Robot};
    use firelink_emulate::qla::eth_network::EthNetwork;
    use firelink_emulate::qla::eth_serve::{EthServeConfig, eth_bind, eth_serve};
    use firelink_host::WatchdogSetting;
    use firelink_host::eth::UdpNetPort;
    use firelink_host::qla::io::{IoOptions, IoSystem};
    use firelink_host::udp::WaitMode;
    use firelink_testbed::demo::{DemoPlan, RealtimeStatus, run_program};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::time::{Duration, Instant};
    let config = firelink_control::config::presets::dqla_rev9();
    let boards = firelink_testbed::rig::board_configs(
        &config,
        firelink_board::qla::config::Profile::Rev9,
        config.board_slots(),
    );
    let ids: Vec<u8> = boards.iter().map(|b| b.board_id).collect();
    assert_eq!(ids, vec![2, 4, 6]);
    let mut net = EthNetwork::new(boards, Default::default()).unwrap();
    let serve = EthServeConfig {
        port: 0,
        ..EthServeConfig::default()
    };
    let sockets = eth_bind(&serve, &ids).unwrap();
    let group = std::net::SocketAddr::new(
        std::net::IpAddr::V4(firelink_host::eth::LOOPBACK_BROADCAST),
        sockets.port,
    );
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let server = std::thread::spawn(move || {
        eth_serve(&mut net, &sockets, &flag, |_| {}).unwrap();
        net.stats()
    });
    // The scan waits the time-out once per absent board ID (13 of them),
    // as the Rev 9 host's scan does: 1 s, far beyond any reply.
    let port = UdpNetPort::open(group, false, Duration::from_secs(1), WaitMode::Blocking).unwrap();
    assert!(port.is_ethernet_only());
    let options = IoOptions {
        protocol: Some(Protocol::Broadcast),
        ..IoOptions::default()
    };
    let (io, scan) = IoSystem::open(port, options).unwrap();
    assert_eq!(scan.boards.len(), 3);
    let plan = DemoPlan {
        config: &config,
        period: firelink_control::ServoPeriod::KHZ_1,
        duration_s: 0.3,
        fault: DemoFault::None,
        script: None,
        watchdog: WatchdogSetting::from_ms(300.0).unwrap(),
        pacing: Pacing::WallClock,
    };
    let robot = Robot::new(io, &config, plan.settings()).unwrap();
    let wall = Instant::now();
    let run = run_program(
        robot,
        &plan,
        &firelink_testbed::fault_script::FaultTarget::link(),
        "udp".into(),
        RealtimeStatus::default(),
        wall,
        &mut |_| {},
    );
    stop.store(true, Ordering::Relaxed);
    let stats = server.join().unwrap();
    let r = run.unwrap().report;
    assert_eq!((r.boards, r.axes), (3, 18), "{r}");
    assert_eq!(r.firmware, Some(9));
    assert!(r.motion_cycles > 0, "{r}");
    assert_eq!(r.errors.total, 0, "{r}; {stats}");
    assert!(stats.broadcast_responses > 0, "{stats}");
    assert_eq!(stats.dropped(), 0, "{stats}");
    if r.fault.is_some() {
        assert_eq!(r.amplifiers_on_after_fault, Some(false), "{r}");
    }
    assert!(r.power_down.unknown.is_empty(), "{:?}", r.power_down);
    assert!(r.power_down.still_on.is_empty(), "{:?}", r.power_down);
}

/// A script's board loss at a servo cycle (`mute@cycle=300:id=4`): the
/// runner counts the motion's cycles and has the rig's fault target mute
/// board 4, found by its ID, at the 300th; the board is named and every
/// amplifier that answers ends off, well before the half-way fault moment.
#[test]
fn a_board_lost_at_a_cycle_is_named_and_every_amplifier_ends_off() {
    let options = DemoOptions {
        duration_s: 0.2,
        faults: Some("mute@cycle=300:id=4".parse().unwrap()),
        ..DemoOptions::default()
    };
    let mut injected = Vec::new();
    let r = run_demo(&options, None, |e| {
        if let DemoProgress::Injecting(what) = e {
            injected.push(what);
        }
    })
    .unwrap();
    assert_eq!(injected, ["mute@cycle=300:id=4"]);
    assert_eq!(r.fault_injected, "mute@cycle=300:id=4");
    assert_eq!(r.verdict(), Ok(()), "{r}");
    let fault = r.fault.as_ref().unwrap();
    assert_eq!(fault.board, Some(4), "{fault:?}");
    assert_eq!(r.amplifiers_on_after_fault, Some(false), "{r}");
    assert!(r.boards_not_answering.contains(&4), "{r}");
    // The motion's cycles start after homing: the fault came after its
    // 300th cycle and before half way (600 of 1200).
    let setup = r.cycles - r.motion_cycles;
    assert!(
        fault.cycle > setup + 300 && fault.cycle < setup + 600,
        "setup {setup}, {fault:?}"
    );
    assert!(r.power_down.still_on.is_empty(), "{:?}", r.power_down);
}

/// What a port cannot apply is refused by name before the boards are
/// touched (not even scanned: no event at all): a board the rig does not
/// have, an entry that cannot happen within the motion, a preset and a
/// script at once.
#[test]
fn faults_a_port_cannot_apply_are_refused_before_the_run() {
    let refused = |options: DemoOptions| {
        let mut events = Vec::new();
        let e = run_demo(&options, None, |e| events.push(e)).unwrap_err();
        assert!(events.is_empty(), "{events:?}");
        e.to_string()
    };
    // 0.1 s at 6 kHz: 600 motion cycles, the fault moment at the 300th,
    // 0.05 s before the end.
    for late in [
        "mute@cycle=600:id=4",
        "drop@cycle=100000:rate=0.5",
        "mute@t=50000us:id=4",
    ] {
        let e = refused(DemoOptions {
            faults: Some(late.parse().unwrap()),
            ..short(DemoFault::None)
        });
        assert_eq!(
            e,
            format!(
                "configuration: fault {late} cannot happen within the motion: it is 600 \
                 cycles (0.1 s) long, `cycle=` counts from its start and `t=` from half way \
                 (0.05 s before its end)"
            )
        );
    }
    // The last cycle and the last moment before the end are within it.
    for within in ["mute@cycle=599:id=4", "mute@t=49000us:id=4"] {
        let r = run_demo(
            &DemoOptions {
                faults: Some(within.parse().unwrap()),
                ..short(DemoFault::None)
            },
            None,
            |_| {},
        )
        .unwrap();
        assert_eq!(r.fault_injected, within);
    }
    let e = refused(DemoOptions {
        faults: Some("mute@cycle=10:id=9".parse().unwrap()),
        ..short(DemoFault::None)
    });
    assert_eq!(e, "muted board 9: no such board on the rig");
    let e = refused(DemoOptions {
        faults: Some("host-pause@t=5000us:for=100us".parse().unwrap()),
        ..short(DemoFault::None)
    });
    assert_eq!(
        e,
        "configuration: fault host-pause@t=5000us:for=100us cannot be applied on sim: \
         a host pause starts at its moment: give t=0us or cycle=N"
    );
    let e = run_demo(
        &DemoOptions {
            faults: Some("mute@start:id=4".parse().unwrap()),
            ..short(DemoFault::StopHost)
        },
        None,
        |_| {},
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "configuration: fault stop-host and a fault script: give one of the two"
    );
}
