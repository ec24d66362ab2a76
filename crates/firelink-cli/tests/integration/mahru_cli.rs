//! `firelink demo --robot mahru` and `firelink budget` end to end, in
//! short virtual-time runs, parsing their JSON; bad options fail with one
//! line.

use crate::common;

use common::{firelink, json};

#[test]
fn mahru_demo_walks_and_reports() {
    let config = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/mahru-seed002.json"
    );
    let r = json(&[
        "demo",
        "--robot",
        "mahru",
        "--duration",
        "0.4",
        "--config",
        config,
        "--json",
    ]);
    assert_eq!(r["period_us"], 2000.0);
    assert_eq!(r["periods"], 200);
    assert_eq!(r["errors"]["total"], 0);
    assert_eq!(r["modules"].as_array().unwrap().len(), 14);
    assert_eq!(r["force_torque"].as_array().unwrap().len(), 4);
    assert!(r["fastest"]["period_us"].as_f64().unwrap() < 2000.0);
    assert_eq!(r["stopped_cleanly"], true);
}

#[test]
fn mahru_demo_too_fast_fails() {
    let out = firelink(&[
        "demo",
        "--robot",
        "mahru",
        "--duration",
        "0.05",
        "--period-us",
        "900",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("overruns"), "{err}");
}

#[test]
fn budget_tables() {
    let r = json(&[
        "budget",
        "--tables",
        "1,3",
        "--rtos",
        "rtlinux",
        "--samples",
        "5",
        "--periods",
        "50",
        "--reads",
        "300",
        "--json",
    ]);
    let t1 = &r["table_i"]["per_rtos"][0];
    assert_eq!(t1["rtos"], "rtlinux");
    assert_eq!(t1["example"]["paper_total_us"], 1560.0);
    assert_eq!(t1["table"].as_array().unwrap().len(), 8);
    let points = r["table_iii"]["points"].as_array().unwrap();
    assert_eq!(points.len(), 6);
    assert!(r.get("table_iv").is_none());
}

#[test]
fn budget_refuses_bad_options() {
    for args in [
        &["budget", "--tables", "2"][..],
        &["budget", "--rtos", "qnx"],
        &["budget", "--period-us", "-5"],
        &["budget", "--can-errors", "2"],
        &["demo", "--robot", "asimo"],
    ] {
        let out = firelink(args);
        assert!(!out.status.success(), "{args:?}");
    }
    let out = firelink(&["budget", "--config", "/nonexistent.json"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent.json"));
}

/// The seed's configuration with one top-level number replaced, written
/// to a temporary file named `name`.
fn mahru_config_with(name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> std::path::PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/mahru-seed002.json"
    ))
    .unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut v);
    let dir = std::env::temp_dir().join(format!("firelink-mahru-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, v.to_string()).unwrap();
    path
}

#[test]
fn huge_numbers_in_the_configuration_are_refused_not_a_panic_or_a_hang() {
    for (name, field, value) in [
        ("period.json", "period_us", 1e300),
        ("slack.json", "slack_us", 1e300),
        ("compute.json", "compute_us", 1e300),
        ("period12.json", "period_us", 1e12),
    ] {
        let path = mahru_config_with(name, |v| v[field] = value.into());
        let path = path.to_str().unwrap();
        for args in [
            &["budget", "--tables", "1", "--config", path][..],
            &[
                "demo",
                "--robot",
                "mahru",
                "--duration",
                "0.1",
                "--config",
                path,
            ],
        ] {
            let out = firelink(args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
            let shown = if value == 1e300 { "1e300" } else { "1e12" };
            assert!(
                err.contains(&format!("{name}: {field}: out of range: {shown}")),
                "{err}"
            );
            assert!(err.contains("100 to 1000000 us") || err.contains("0 to 1000000 us"));
            assert_eq!(err.lines().count(), 1, "{err}");
        }
    }
    let path = mahru_config_with("servo.json", |v| {
        v["chains"][0]["modules"][0]["device"]["motor"]["servo_hz"] = 1e300.into();
    });
    let out = firelink(&["budget", "--config", path.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("chains[0].modules[0].device.motor.servo_hz: out of range: 1e300"),
        "{err}"
    );
    if let Some(dir) = path.parent() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

#[test]
fn periods_beyond_the_bounds_are_usage_errors() {
    for args in [
        &["demo", "--robot", "mahru", "--period-us", "0.001"][..],
        &["demo", "--robot", "mahru", "--period-us", "1e300"],
        &["budget", "--period-us", "1e12"],
        &["budget", "--reads", "1000000000"],
        &["budget", "--samples", "1000000000"],
        &["budget", "--can-cycles", "4000000000"],
    ] {
        let out = firelink(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("out of range"), "{args:?}: {err}");
    }
}

#[test]
fn a_budget_that_does_not_fit_exits_3() {
    let args = [
        "budget",
        "--tables",
        "1",
        "--rtos",
        "xenomai",
        "--samples",
        "5",
        "--periods",
        "20",
        "--period-us",
        "1000",
    ];
    let out = firelink(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("does NOT fit"));
    assert!(err.contains("the budget does not fit: xenomai"), "{err}");
    // The same at the seed's 2 ms fits: 0.
    let out = firelink(&args[..args.len() - 2]);
    assert_eq!(out.status.code(), Some(0));
}
