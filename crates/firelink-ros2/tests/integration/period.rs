//! `--period` and its older spelling `--rate` from the command line to the
//! robot loop: the program runs the robot on the simulated bus without DDS
//! (`--no-dds`, so no socket is opened) and its report says what period
//! the loop was asked to keep. Nothing here is timed: only the asked
//! figures, which do not depend on how the machine kept up, are compared.

use std::process::{Command, Output};

use serde_json::Value;

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_firelink-ros2"))
        .args(["--port", "sim", "--no-dds", "--no-rt", "--seconds", "0.2"])
        .args(args)
        .output()
        .expect("run firelink-ros2")
}

/// The report's figures that follow from the arguments alone: the asked
/// control rate and period. (Without DDS nothing is published, so the
/// report's measured_js figures, asked and measured, are 0 whatever the
/// arguments: checked here, not compared.)
fn asked(args: &[&str]) -> (f64, f64) {
    let out = run(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {stderr}");
    let report: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{args:?}: {e}: {}", String::from_utf8_lossy(&out.stdout)));
    let number = |key: &str| {
        report[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} in {report}"))
    };
    assert_eq!(
        (number("measured_js_asked_hz"), number("measured_js_hz")),
        (0.0, 0.0),
        "{args:?}: {report}"
    );
    (
        number("control_asked_hz"),
        number("control_asked_period_us"),
    )
}

#[test]
fn the_period_and_the_older_rate_ask_the_loop_for_the_same_period() {
    let by_period = asked(&["--period", "1ms"]);
    assert_eq!(by_period, (1000.0, 1000.0));
    assert_eq!(asked(&["--rate", "1000"]), by_period);
    assert_eq!(asked(&["--period", "1kHz"]), by_period);
    let quarter = asked(&["--period", "250us"]);
    assert_eq!(quarter, (4000.0, 250.0));
}

#[test]
fn a_period_out_of_range_is_refused_with_the_reason_before_anything_runs() {
    for args in [["--period", "5us"], ["--rate", "0"]] {
        let out = run(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("out of range, 10 us to 1 s (100 kHz to 1 Hz)"),
            "{args:?}: {stderr}"
        );
        assert!(out.stdout.is_empty(), "{args:?}");
    }
}
