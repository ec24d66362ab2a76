//! The phase tables of `firelink sim`, pinned.
//!
//! `data/sim_phases.json` holds what `firelink sim --json` printed for 226
//! configurations before the simulation moved onto the emulated boards and
//! the host library (issue 10): every profile (seed, rev7, rev8), both
//! protocols, 1 to 16 boards, wire time only and with the seed-000 PC
//! model; the gap-count and arbitration table of BENCHMARKS.md; S100 and
//! S200. (Configurations that failed then, such as 16 Rev 8 boards whose
//! hub block does not fit the hub memory, are not in the file.) Each case
//! runs again here and must print the same phase times, per-board times,
//! total, packet count, sizes and gap count, with every board answering:
//! the figures are virtual wire times, so they may not move by more than
//! rounding (a picosecond).
//!
//! Each case also runs at `--detail packet` and must print exactly what
//! the default fast level printed, but for the count of what ran.
//!
//! To record the file again (only when a change is meant to move the
//! figures, and say so in BENCHMARKS.md), run each case's arguments through
//! `firelink sim --json` and keep the keys compared below.

use std::process::Command;

use serde_json::Value;

/// One picosecond, in microseconds, plus float rounding.
const TOLERANCE_US: f64 = 1.5e-6;

fn sim(args: &[String]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .arg("sim")
        .arg("--json")
        .args(args)
        .output()
        .expect("run firelink");
    assert!(
        out.status.success(),
        "firelink sim {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

/// Compare `found` with `expected`: numbers within [`TOLERANCE_US`],
/// everything else exactly. Differences are pushed as lines.
fn compare(path: &str, expected: &Value, found: &Value, out: &mut Vec<String>) {
    match (expected, found) {
        (Value::Number(e), Value::Number(f)) => {
            let (e, f) = (
                e.as_f64().unwrap_or(f64::NAN),
                f.as_f64().unwrap_or(f64::NAN),
            );
            if (e - f).abs() > TOLERANCE_US || e.is_nan() || f.is_nan() {
                out.push(format!("{path}: expected {e}, found {f}"));
            }
        }
        (Value::Object(e), Value::Object(f)) => {
            for (k, ev) in e {
                match f.get(k) {
                    Some(fv) => compare(&format!("{path}.{k}"), ev, fv, out),
                    None => out.push(format!("{path}.{k}: missing")),
                }
            }
        }
        (Value::Array(e), Value::Array(f)) if e.len() == f.len() => {
            for (i, (ev, fv)) in e.iter().zip(f).enumerate() {
                compare(&format!("{path}[{i}]"), ev, fv, out);
            }
        }
        (e, f) if e == f => {}
        (e, f) => out.push(format!("{path}: expected {e}, found {f}")),
    }
}

/// `report` without its count of what ran at which level of detail.
fn without_detail(report: &Value) -> Value {
    let mut v = report.clone();
    if let Some(map) = v.as_object_mut() {
        map.remove("detail");
    }
    v
}

#[test]
fn phase_tables_do_not_move() {
    let text = include_str!("../data/sim_phases.json");
    let pinned: Value = serde_json::from_str(text).expect("pinned tables");
    let cases = pinned["cases"].as_array().expect("cases");
    assert!(cases.len() > 200, "{} cases", cases.len());
    let mut failures = Vec::new();
    for case in cases {
        let args: Vec<String> = case["args"]
            .as_array()
            .expect("args")
            .iter()
            .map(|a| a.as_str().expect("string").to_string())
            .collect();
        let found = sim(&args);
        let mut diffs = Vec::new();
        if found["errors"] != Value::Array(Vec::new()) {
            diffs.push(format!("errors: {}", found["errors"]));
        }
        compare("", &case["expected"], &found, &mut diffs);
        // The packet level (every delivery an event) gives the fast
        // level's answer exactly; only the count of what ran differs.
        let mut packet_args = args.clone();
        packet_args.extend(["--detail".to_string(), "packet".to_string()]);
        let packet = sim(&packet_args);
        if without_detail(&packet) != without_detail(&found) {
            diffs.push(format!(
                "--detail packet differs:\n    fast   {found}\n    packet {packet}"
            ));
        }
        if found["detail"]["fast_cycles"] != 1 || packet["detail"]["packet_level_cycles"] != 1 {
            diffs.push(format!(
                "levels run: fast {} / packet {}",
                found["detail"], packet["detail"]
            ));
        }
        if !diffs.is_empty() {
            failures.push(format!(
                "firelink sim {}:\n  {}",
                args.join(" "),
                diffs.join("\n  ")
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases moved:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
