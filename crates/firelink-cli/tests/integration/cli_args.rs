//! Every number the command line takes is checked before anything runs:
//! out-of-range, non-finite and non-numeric values are usage errors (exit
//! status 2, one line naming the option and the range), never a panic
//! (101) and never silently accepted (0). Node IDs do not wrap into a
//! broadcast, and the watchdog cannot be turned off by a number.

use std::process::Command;

fn firelink(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args(args)
        .env("FIRELINK_QUIET", "1")
        .output()
        .expect("run firelink");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn out_of_range_numbers_are_usage_errors() {
    let cases: &[&[&str]] = &[
        &["bench", "--wait-us=-5"],
        &["bench", "--wait-us", "NaN"],
        &["bench", "--idle-us", "1e300"],
        &["bench", "--period-us", "1e300"],
        &["bench", "--cycles", "0"],
        &["bench", "--udp-timeout-ms", "0"],
        &["bench", "--udp-timeout-ms", "1e300"],
        &["emulate", "--duration-s", "1e300"],
        &["emulate", "--duration-s=-1"],
        &["emulate", "--drop-rate", "2"],
        &["emulate", "--boards", "17"],
        &["emulate", "--mute-board", "16"],
        &["demo", "--rate", "1e-300"],
        &["demo", "--rate", "0"],
        &["demo", "--period", "9us"],
        &["demo", "--period", "1e300s"],
        &["demo", "--period", "0.5Hz"],
        &["demo", "--robot", "mahru", "--period=-1ms"],
        &["budget", "--period", "2s"],
        &["budget", "--period", "50us"],
        &["demo", "--watchdog-ms", "1e300"],
        &["demo", "--watchdog-ms=-5"],
        &["demo", "--watchdog-ms", "0"],
        &["demo", "--duration", "NaN"],
        &["demo", "--duration", "0"],
        &["monitor", "--rate", "1e-300"],
        &["monitor", "--watchdog-ms", "0"],
        &["read", "--node", "64", "status"],
        &["read", "--board", "16", "status"],
        &["read", "--count", "513", "status"],
        &["write", "--node", "127", "status", "1"],
        &["scan", "--timeout-ms", "0"],
    ];
    for args in cases {
        let (code, err) = firelink(args);
        assert_eq!(code, 2, "{args:?} exited {code}: {err}");
        assert!(
            err.contains("out of range") || err.contains("not a number"),
            "{args:?}: {err}"
        );
        assert_eq!(
            err.lines().filter(|l| l.starts_with("error:")).count(),
            1,
            "{args:?}: {err}"
        );
    }
}

#[test]
fn a_servo_period_without_its_unit_or_twice_is_a_usage_error() {
    for (args, says) in [
        (&["demo", "--period", "1000"][..], "no unit"),
        (&["demo", "--period", "1 fortnight"], "unknown unit"),
        (
            &["demo", "--period", "1ms", "--rate", "1000"],
            "cannot be used with",
        ),
        (
            &["budget", "--period", "2ms", "--period-us", "2000"],
            "cannot be used with",
        ),
        (
            &["soak", "--period", "25ms"],
            "the boards' watchdog is 20 ms; the servo period must be shorter",
        ),
        (&["soak", "--period", "5us"], "out of range, 10 us to 1 s"),
    ] {
        let (code, err) = firelink(args);
        assert_eq!(code, 2, "{args:?} exited {code}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

/// The demo's hidden `--rate` is read by the one parser the web console's
/// and the ROS 2 node's share (`limits::servo_rate_hz`): its refusal is
/// the servo period's own range rule, as theirs is.
#[test]
fn the_demos_older_rate_is_refused_by_the_servo_periods_rule() {
    for rate in ["0", "1e6", "NaN"] {
        let (code, err) = firelink(&["demo", "--rate", rate]);
        assert_eq!(code, 2, "--rate {rate} exited {code}: {err}");
        assert!(
            err.contains("out of range, 10 us to 1 s (100 kHz to 1 Hz)"),
            "--rate {rate}: {err}"
        );
    }
}

#[test]
fn bench_board_lists_are_checked() {
    for list in ["17", "0", "63", "2,x"] {
        let (code, err) = firelink(&["bench", "--boards", list]);
        assert_eq!(code, 1, "--boards {list}: {err}");
        assert!(err.starts_with("firelink: "), "--boards {list}: {err}");
        assert!(
            err.contains("board count") || err.contains("extrapolated"),
            "{err}"
        );
    }
}

#[test]
fn watchdog_off_must_be_asked_for_and_is_announced() {
    let (code, err) = firelink(&[
        "demo",
        "--watchdog-ms",
        "off",
        "--duration",
        "0.01",
        "--rate",
        "500",
        "--port",
        "sim",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("watchdogs are OFF"), "{err}");
}

#[test]
fn a_write_over_udp_to_nobody_is_not_reported_as_done() {
    // A port on loopback where nothing listens: the generation query gets
    // no answer, so nothing claims a write happened.
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = format!("udp:{}", socket.local_addr().unwrap());
    drop(socket);
    let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args(["write", "--port", &port, "--node", "2", "watchdog", "0x100"])
        .output()
        .unwrap();
    assert_ne!(out.status.code(), Some(0));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!stdout.contains("wrote"), "{stdout}");
}

/// The teleoperation session takes only --period (or its older
/// spellings), --firmware, --json and --quiet: every other option, given
/// on the command line, is refused by name, even at its default value, and
/// before anything runs (a --config is not even read: no warning of its).
#[test]
fn teleop_refuses_every_option_it_would_ignore() {
    let config = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/dvrk-seed000.json"
    );
    for (args, option) in [
        (&["--duration", "3"][..], "--duration"),
        (&["--robot", "dvrk"], "--robot"),
        (&["--config", config], "--config"),
        (&["--port", "sim"], "--port"),
        (&["--protocol", "broadcast"], "--protocol"),
        (&["--udp-wait", "block"], "--udp-wait"),
        (&["--watchdog-ms", "20"], "--watchdog-ms"),
        (&["--pacing", "virtual"], "--pacing"),
        (&["--no-rt"], "--no-rt"),
        (&["--no-rate-search"], "--no-rate-search"),
        (&["--fault", "none"], "--fault none"),
    ] {
        let (code, err) = firelink(&[&["demo", "--teleop"], args].concat());
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(
            err.contains(&format!("firelink demo --teleop cannot honour {option}")),
            "{args:?}: {err}"
        );
        assert!(!err.contains("warning"), "{args:?}: {err}");
    }
}

#[test]
fn a_level_of_detail_other_than_packet_or_fast_is_a_usage_error_naming_both() {
    for command in ["demo", "sim", "soak", "bench", "emulate"] {
        for bad in ["exact", "0", "1e300", "", "FAST"] {
            let (code, err) = firelink(&[command, "--detail", bad]);
            assert_eq!(code, 2, "{command} --detail {bad:?}: {err}");
            assert!(
                err.contains(&format!("unknown level of detail '{bad}' (packet or fast)")),
                "{command} --detail {bad:?}: {err}"
            );
        }
    }
    // A bench whose every point is outside the simulated bus has no level
    // of detail to set: refused before anything is measured.
    let (code, err) = firelink(&["bench", "--port", "udp:127.0.0.1:9", "--detail", "packet"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("--detail packet: no point of this run is on a simulated 1394 bus"),
        "{err}"
    );
}
