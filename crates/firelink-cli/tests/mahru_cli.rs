//! `firelink demo --robot mahru` and `firelink budget` end to end, in
//! short virtual-time runs, parsing their JSON; bad options fail with one
//! line.

mod common;

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
