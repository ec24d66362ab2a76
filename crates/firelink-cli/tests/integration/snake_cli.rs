//! Seed 001 from the command line: `firelink demo --robot snake`,
//! `firelink bench --seed 001` and `firelink snake-tool`, end to end on
//! the simulated bus (virtual time), parsing what they print.

use crate::common;

use common::{fails, ok};

use serde_json::Value;

/// The last JSON line of a tool's output.
fn last_json(text: &str) -> Value {
    let line = text
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .expect("a JSON line");
    serde_json::from_str(line).unwrap()
}

fn repo_file(name: &str) -> String {
    format!("{}/../../configs/{name}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn demo_runs_the_36_axis_snake_system() {
    let r: Value = serde_json::from_str(&ok(&[
        "demo",
        "--robot",
        "snake",
        "--duration",
        "0.4",
        "--no-rate-search",
        "--json",
    ]))
    .unwrap();
    assert_eq!(r["boards"], 6);
    assert_eq!(r["axes"], 36);
    assert_eq!(r["rate_hz"], 1000.0);
    assert_eq!(r["errors"]["total"], 0);
    assert_eq!(r["nodes"], serde_json::json!([0, 1, 2, 3, 4, 5]));
    assert!(r["fault"].is_null());
    assert_eq!(r["tracking_error"].as_object().unwrap().len(), 4);
    // A Snake configuration given with --config is enough.
    let r: Value = serde_json::from_str(&ok(&[
        "demo",
        "--config",
        &repo_file("snake-seed001.json"),
        "--duration",
        "0.2",
        "--no-rate-search",
        "--json",
    ]))
    .unwrap();
    assert_eq!(r["axes"], 36);
    fails(
        &["demo", "--robot", "snake", "--fault", "corrupt-query"],
        "broadcast",
    );
}

#[test]
fn bench_reproduces_seed_001_with_a_figure() {
    let png = std::env::temp_dir().join(format!("firelink-s001-{}.png", std::process::id()));
    let r: Value = serde_json::from_str(&ok(&[
        "bench",
        "--seed",
        "001",
        "--iterations",
        "1000",
        "--json",
        "--plot",
        png.to_str().unwrap(),
    ]))
    .unwrap();
    let rows = r["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 8);
    assert!(
        rows.iter().all(|row| row["within_tolerance"] == true),
        "{rows:?}"
    );
    let bytes = std::fs::read(&png).unwrap();
    std::fs::remove_file(&png).unwrap();
    assert_eq!(&bytes[..4], b"\x89PNG");
    let text = ok(&["bench", "--seed", "001", "--iterations", "500"]);
    assert!(text.contains("quadlet read, mean (Fig. 20)"), "{text}");
    fails(&["bench", "--seed", "002"], "002");
}

#[test]
fn snake_tool_sets_and_reads_back_every_kind_of_setting() {
    let out = ok(&[
        "snake-tool",
        "exec",
        "board 4; channel 2; wiper 649; switch speed; current-limit 500; \
         write-protect off; eeprom-write 3 0xbeef; eeprom-write-float 4 3.57727; \
         eeprom-read 3; eeprom-read-float 4; enable on; voltage 0.1; wait 100; show json",
    ]);
    assert!(out.contains("feedback gain 3.57727"), "{out}");
    assert!(out.contains("EEPROM 0x23: 0xbeef"), "{out}");
    assert!(out.contains("EEPROM 0x24: 3.57727 (float)"), "{out}");
    let view = last_json(&out);
    assert_eq!(view["board"], 4);
    let ch = &view["channels"][1];
    assert_eq!(ch["channel"], 2);
    assert_eq!(ch["wiper"], 649);
    assert!((ch["feedback_gain"].as_f64().unwrap() - 3.57727).abs() < 1e-5);
    assert_eq!(ch["speed_mode"], true);
    assert_eq!(ch["write_protect"], false);
    assert_eq!(ch["enabled"], true);
    assert!((ch["current_limit_ma"].as_f64().unwrap() - 500.0).abs() < 0.1);
    assert!((ch["motor_volts"].as_f64().unwrap() - 0.1).abs() < 1e-3);
    // Channel 1 kept its power-up settings.
    assert_eq!(view["channels"][0]["wiper"], 375);
    assert_eq!(view["channels"][0]["write_protect"], true);
}

#[test]
fn snake_tool_state_survives_a_file() {
    let path = std::env::temp_dir().join(format!("firelink-snake-{}.json", std::process::id()));
    let p = path.to_str().unwrap();
    ok(&[
        "snake-tool",
        "exec",
        &format!(
            "board 1; channel 3; wiper 100; current-limit 250; write-protect off; \
             eeprom-write 0 4660; write-protect on; switch speed; save {p}"
        ),
    ]);
    // A fresh simulated system, then the file.
    let out = ok(&[
        "snake-tool",
        "exec",
        &format!("load {p}; board 1; channel 3; eeprom-read 0; show json"),
    ]);
    std::fs::remove_file(&path).unwrap();
    assert!(out.contains("loaded and sent 42 channels"), "{out}");
    assert!(out.contains("EEPROM 0x30: 0x1234"), "{out}");
    let ch = &last_json(&out)["channels"][2];
    assert_eq!(ch["wiper"], 100);
    assert_eq!(ch["write_protect"], true);
    assert_eq!(ch["speed_mode"], true);
    assert!((ch["current_limit_ma"].as_f64().unwrap() - 250.0).abs() < 0.1);
    fails(
        &["snake-tool", "exec", "load /nonexistent/state.json"],
        "No such file",
    );
}

#[test]
fn snake_tool_refuses_bad_inputs_clearly() {
    for (script, needle) in [
        ("channel 8", "channel (1..=7)"),
        ("channel 0", "channel (1..=7)"),
        ("board 9", "no such node"),
        ("wiper 1024", "wiper (0..=1023)"),
        ("eeprom-write 14 1", "EEPROM word (0..=13)"),
        ("write-protect off; eeprom-write-float 13 1.0", "0..=12"),
        ("eeprom-write 2 1", "write protection"),
        ("voltage 2", "out of range"),
        ("current-limit -5", "out of range"),
        ("switch fast", "torque or speed"),
        ("preload 16777216", "preload"),
        ("jump", "unknown command"),
    ] {
        fails(&["snake-tool", "exec", script], needle);
    }
    fails(&["snake-tool", "--port", "tcp:x", "show"], "unknown port");
    // Numbers are echoed as typed, never written out in 300 digits.
    let err = fails(&["snake-tool", "exec", "wait 1e300"], "out of range");
    assert!(
        err.contains("wait (ms): 1e300 is out of range: 0 to 60000"),
        "{err}"
    );
    assert!(!err.contains("00000000000"), "{err}");
}

#[test]
fn snake_tool_shows_a_node() {
    let text = ok(&["snake-tool", "--board", "5", "show"]);
    assert!(text.starts_with("board 5"), "{text}");
    assert_eq!(text.lines().count(), 2 + 7);
    let v = last_json(&ok(&["snake-tool", "show", "--json"]));
    assert_eq!(v["board"], 0);
    assert_eq!(v["channels"].as_array().unwrap().len(), 7);
}
