//! End-to-end tests of `firelink sim`, run as a user would run it.

use crate::common;

use common::firelink;

use serde_json::Value;

fn sim_json(args: &[&str]) -> Value {
    let mut all = vec!["sim", "--json"];
    all.extend_from_slice(args);
    let out = firelink(&all);
    assert!(
        out.status.success(),
        "{all:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

fn near(v: &Value, paper: f64, tolerance: f64) -> bool {
    let x = v.as_f64().expect("a number");
    (x - paper).abs() / paper <= tolerance
}

#[test]
fn seed_broadcast_cycle_matches_the_paper() {
    let v = sim_json(&[
        "--boards",
        "8",
        "--profile",
        "seed",
        "--protocol",
        "broadcast",
    ]);
    assert_eq!(v["boards"], 8);
    let p = &v["phases_us"];
    assert!(near(&p["broadcast"], 40.71, 0.10), "{p}");
    assert!(near(&p["hub_read"], 20.0, 0.20), "{p}");
    assert!(near(&p["command"], 3.26, 0.10), "{p}");
    assert!(p["query"].as_f64().unwrap() < 1.0);
    assert!(v["total_us"].as_f64().unwrap() > 60.0);
    assert_eq!(v["packets"], 14);
    assert_eq!(v["boards_ok"], 8);
}

#[test]
fn sequential_cycle_reports_read_and_write_per_board() {
    let v = sim_json(&["--boards", "4", "--protocol", "sequential"]);
    let p = &v["phases_us"];
    assert!(p["read"].as_f64().unwrap() < 5.0);
    assert!(p["write"].as_f64().unwrap() < 5.0);
    assert_eq!(v["per_board"].as_array().unwrap().len(), 4);
    let v = sim_json(&[
        "--boards",
        "8",
        "--protocol",
        "sequential",
        "--host-overhead",
    ]);
    assert!(near(&v["phases_us"]["read"], 32.0, 0.05));
    assert!(near(&v["phases_us"]["write"], 34.0, 0.05));
}

#[test]
fn flags_change_the_cycle() {
    let iso = sim_json(&[]);
    let fair = sim_json(&["--arbitration", "fair", "--gap-count", "26"]);
    assert_eq!(fair["gap_count"], 26);
    assert!(
        fair["phases_us"]["broadcast"].as_f64().unwrap()
            > iso["phases_us"]["broadcast"].as_f64().unwrap() + 10.0
    );
    let slow = sim_json(&["--speed", "100"]);
    assert!(
        slow["phases_us"]["command"].as_f64().unwrap()
            > 3.0 * iso["phases_us"]["command"].as_f64().unwrap()
    );
    let rev8 = sim_json(&["--profile", "rev8"]);
    assert_eq!(rev8["sizes"]["hub_read_quadlets"], 33 * 8 + 1);
    let a = sim_json(&["--host-overhead", "--jitter", "--seed", "3"]);
    let b = sim_json(&["--host-overhead", "--jitter", "--seed", "3"]);
    assert_eq!(a, b);
}

#[test]
fn table_pcap_and_errors() {
    let dir = std::env::temp_dir().join(format!("firelink-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pcap = dir.join("cycle.pcap");
    let out = firelink(&[
        "sim",
        "--boards",
        "2",
        "--pcap",
        pcap.to_str().unwrap(),
        "--timeline",
    ]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("hub_read"));
    assert!(text.contains("read_request_block"));
    let bytes = std::fs::read(&pcap).unwrap();
    assert_eq!(&bytes[..4], &0xA1B2_3C4Du32.to_le_bytes());
    assert!(bytes.len() > 24 + 10 * 28);
    std::fs::remove_dir_all(&dir).unwrap();
    for bad in [
        &["sim", "--boards", "0"][..],
        &["sim", "--speed", "800"],
        &["sim", "--profile", "rev10"],
        &["sim", "--gap-count", "64"],
        &["sim", "--jitter"],
    ] {
        assert!(!firelink(bad).status.success(), "{bad:?} should fail");
    }
}

/// Every board answers and the wire times equal those of the minimal
/// responder the bus was first validated with (it is gone: one board model
/// per board type; its figures are the pinned ones of `sim_phases.rs`,
/// recorded when both models still ran and agreed for rev7 and rev8).
#[test]
fn emulated_boards_time_like_the_minimal_responder() {
    let pinned: serde_json::Value =
        serde_json::from_str(include_str!("../data/sim_phases.json")).unwrap();
    for profile in ["rev7", "rev8"] {
        let args = [
            "--profile",
            profile,
            "--protocol",
            "broadcast",
            "--boards",
            "8",
        ];
        let minimal = pinned["cases"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["args"] == serde_json::json!(args))
            .map(|c| c["expected"].clone())
            .unwrap();
        let emulated = sim_json(&args);
        assert_eq!(emulated["boards_ok"], 8, "{profile}: {emulated}");
        assert_eq!(emulated["errors"].as_array().unwrap().len(), 0);
        assert_eq!(emulated["phases_us"], minimal["phases_us"], "{profile}");
    }
}
