//! Every shipped configuration and every fixture shaped like a stock dVRK
//! file (`tests/data/stock/`, Firelink's own values) against what the dVRK
//! console's configuration reader requires (`config::console`, written
//! from sawRobotIO1394's data description, on the files' JSON), and
//! through Firelink's own loader: each loads, with no warning.

use std::path::{Path, PathBuf};

use firelink_control::config::console::{self, ConsoleProblem};
use firelink_control::config::{IoConfig, Warning};
use serde_json::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn fixtures() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("tests/data/stock"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

#[test]
fn shipped_configurations_pass_the_console_reader() {
    for entry in std::fs::read_dir(root().join("../../configs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let doc = json(&path);
        // (MAHRU's file is seed 002's own format, not a robot I/O file.)
        if doc["$id"] != "saw-robot-io.schema.json" {
            continue;
        }
        let issues = console::check(&doc);
        // Seed 001's own nodes are not JHU boards: the console has no
        // hardware_version SNAKE (and only that is what it would refuse).
        if path.ends_with("snake-seed001.json") {
            assert!(!issues.is_empty());
            assert!(
                issues.iter().all(|i| i.path.ends_with("hardware_version")),
                "{issues:?}"
            );
            continue;
        }
        assert_eq!(issues, [], "{}", path.display());
        let loaded = IoConfig::load_with_warnings(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(loaded.warnings, [], "{}", path.display());
    }
}

#[test]
fn stock_shaped_files_load_unmodified() {
    let names: Vec<String> = fixtures()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 7, "{names:?}");
    for path in fixtures() {
        assert_eq!(console::check(&json(&path)), [], "{}", path.display());
        let loaded = IoConfig::load_with_warnings(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(loaded.warnings, [], "{}", path.display());
    }
    // The ECM's: `$version` a number, the brakes and their calibrations.
    let ecm =
        IoConfig::load(root().join("tests/data/stock/sawRobotIO1394-ECM-90006.json")).unwrap();
    assert_eq!(ecm.version, "6");
    let r = &ecm.robots[0];
    assert_eq!(
        (r.number_of_brakes, r.brakes.as_ref().map(Vec::len)),
        (Some(3), Some(3))
    );
    assert!(r.actuators[..3].iter().all(|a| a.brake.is_some()));
    // The pedals': inputs only.
    let pedals =
        IoConfig::load(root().join("tests/data/stock/sawRobotIO1394-foot-pedals.json")).unwrap();
    assert!(pedals.robots.is_empty());
    assert_eq!(pedals.board_slots(), 2);
}

#[test]
fn what_the_console_refuses_is_a_warning_with_its_path() {
    let path = root().join("tests/data/stock/sawRobotIO1394-PSM1-90003.json");
    let mut doc = json(&path);
    // Firelink's PSM1 file before issue 29: no number_of_brakes.
    doc["robots"][0]
        .as_object_mut()
        .unwrap()
        .remove("number_of_brakes");
    // A key the console and Firelink read past.
    doc["robots"][0]["actuators"][0]["encoder"]["units"] = Value::from("rad");
    let loaded = IoConfig::from_json_str_with_warnings(&doc.to_string(), "psm.json").unwrap();
    let shown: Vec<String> = loaded.warnings.iter().map(ToString::to_string).collect();
    assert_eq!(
        shown,
        [
            "psm.json: robots[0].actuators[0].encoder.units: ignored (a key Firelink does not use)",
            "psm.json: robots[0].number_of_brakes: required key missing or empty (the dVRK console's reader refuses this)",
        ]
    );
    assert!(matches!(
        &loaded.warnings[1].warning,
        Warning::Console(ConsoleProblem::Missing)
    ));
    // A misspelt `$id` (as in one public ECM file): read as v6, said.
    let ecm = root().join("tests/data/stock/sawRobotIO1394-ECM-90006.json");
    let mut doc = json(&ecm);
    let obj = doc.as_object_mut().unwrap();
    let id = obj.remove("$id").unwrap();
    obj.insert("$id:".into(), id);
    let loaded = IoConfig::from_json_str_with_warnings(&doc.to_string(), "ecm.json").unwrap();
    let kinds: Vec<(&str, &Warning)> = loaded
        .warnings
        .iter()
        .map(|w| (w.path.as_str(), &w.warning))
        .collect();
    assert_eq!(
        kinds,
        [("$id:", &Warning::Ignored), ("$id", &Warning::NoSchemaId)]
    );
    // A malformed value is refused, with its path.
    let mut doc = json(&ecm);
    doc["robots"][0]["brakes"][1]["release_current"] = Value::from("lots");
    let e = IoConfig::from_json_str(&doc.to_string(), "ecm.json").unwrap_err();
    assert_eq!(e.first().path, "robots[0].brakes[1].release_current", "{e}");
}
