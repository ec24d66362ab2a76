//! The shipped configurations load and validate; malformed ones produce
//! errors that name the file, the JSON path and the problem.

use firelink_control::config::{
    ConfigErrors, DvrkArm, FpgaGeneration, HardwareVersion, IoConfig, PlantPreset, Problem,
    StopSide, presets,
};
use serde_json::{Value, json};
use std::path::PathBuf;

fn configs_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}

fn load(name: &str) -> IoConfig {
    IoConfig::load(configs_dir().join(name)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn dvrk_seed000_loads() {
    let c = load("dvrk-seed000.json");
    assert_eq!(c.robots.len(), 4);
    let names: Vec<&str> = c.robots.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(names, ["MTML", "MTMR", "PSM1", "PSM2"]);
    assert_eq!(c.actuator_count(), 28);
    let boards = c.boards();
    assert_eq!(boards.len(), 8);
    assert_eq!(c.board_set().0, 0x00FF);
    for b in &boards {
        assert_eq!(b.hardware, HardwareVersion::Qla1);
    }
    // Each arm on two boards: 4 axes on the first, 3 on the second.
    assert_eq!(boards[0].axes_used, 0b1111);
    assert_eq!(boards[1].axes_used, 0b0111);
    assert_eq!(boards[4].robot.as_str(), "PSM1");
    // PSM joint 3 is the prismatic one, with a psm_j3 plant.
    let psm1 = c.robot("PSM1").unwrap();
    let j3 = &psm1.actuators[2];
    assert_eq!(j3.simulation.unwrap().plant, PlantPreset::PsmJ3);
    assert_eq!((j3.board_id, j3.axis_id), (4, 2));
    let j5 = &psm1.actuators[4];
    assert_eq!((j5.board_id, j5.axis_id), (5, 0));
    // Joint labels follow the file's indexing.
    let last = c.joints().last().unwrap();
    assert_eq!(last.label.as_str(), "PSM2[6]");
    assert_eq!(last.index, 27);
}

#[test]
fn bench_and_snake_load() {
    let b = load("bench-1board.json");
    assert_eq!((b.robots.len(), b.actuator_count()), (1, 4));
    assert_eq!(b.board_set().0, 1);
    let s = load("snake-36axes.json");
    assert_eq!(s.actuator_count(), 36);
    assert_eq!(s.robots.len(), 4);
    assert_eq!(s.robot("SNAKE1").unwrap().actuators.len(), 11);
    assert_eq!(s.robot("MASTER2").unwrap().actuators.len(), 7);
    let hw: Vec<HardwareVersion> = s.boards().iter().map(|b| b.hardware).collect();
    assert_eq!(
        hw,
        [
            HardwareVersion::Dqla,
            HardwareVersion::Dqla,
            HardwareVersion::Dqla,
            HardwareVersion::Dqla,
            HardwareVersion::Qla1,
            HardwareVersion::Qla1,
            HardwareVersion::Qla1,
            HardwareVersion::Qla1
        ]
    );
    assert!(s.description.as_deref().unwrap().contains("7-channel"));
}

#[test]
fn snake_seed001_is_the_seeds_arrangement() {
    let s = load("snake-seed001.json");
    assert_eq!(s.actuator_count(), 36);
    let boards = s.boards();
    assert_eq!(boards.len(), 6);
    assert!(boards.iter().all(|b| b.hardware == HardwareVersion::Snake));
    // Each Snake: 7 axes on its actuation-unit node, 4 on its second node;
    // each master: 7 on one node.
    let used: Vec<(u8, u32)> = boards
        .iter()
        .map(|b| (b.board_id, b.axes_used.count_ones()))
        .collect();
    assert_eq!(used, [(0, 7), (1, 4), (2, 7), (3, 4), (4, 7), (5, 7)]);
    let a = &s.robot("SNAKE2").unwrap().actuators[8];
    assert_eq!((a.board_id, a.axis_id), (3, 1));
    // The node's conventions: pot 0..=16383 over 2.5 V, monitor around 8192.
    let pot = a.potentiometer.unwrap();
    assert!((pot.bits_to_voltage.apply(16384.0) - 2.5).abs() < 1e-12);
    assert!(a.drive.bits_to_current(8192).abs() < 1e-9);
    assert_eq!(a.drive.zero_current_bits(), 0x8000);
}

#[test]
fn shipped_files_match_the_presets() {
    for (name, preset) in presets::shipped() {
        let text = std::fs::read_to_string(configs_dir().join(name)).unwrap();
        assert_eq!(
            text,
            preset.to_json_pretty(),
            "configs/{name} is stale: run `cargo run -p firelink-control --example write_configs`"
        );
        // And it round-trips through the parser.
        let parsed = IoConfig::from_json_str(&text, name).unwrap();
        assert_eq!(parsed.to_json_pretty(), text);
    }
}

/// A small valid file: robot A with two actuators on board 0, robot B with
/// one on board 1.
fn base() -> Value {
    let actuator = |board: u8, axis: u8| {
        json!({
            "board_id": board, "axis_id": axis,
            "drive": {
                "current_to_bits": { "scale": 5242.88, "offset": 32768 },
                "bits_to_current": { "scale": 0.000190735, "offset": -6.25 },
                "effort_to_current": { "scale": 0.36 },
                "maximum_current": 0.67
            },
            "encoder": {
                "bits_to_position": { "scale": 2.5e-5 },
                "position_limits_soft": { "lower": -1.0, "upper": 1.0 }
            },
            "potentiometer": {
                "bits_to_voltage": { "scale": 6.866455078125e-05 },
                "voltage_to_position": { "scale": 0.9, "offset": -2.0 }
            }
        })
    };
    json!({
        "$id": "saw-robot-io.schema.json",
        "$version": "6",
        "robots": [
            { "name": "A", "serial_number": "1", "number_of_actuators": 2,
              "actuators": [actuator(0, 0), actuator(0, 1)] },
            { "name": "B", "serial_number": "2", "number_of_actuators": 1,
              "actuators": [actuator(1, 0)] }
        ]
    })
}

/// The base with the value at a JSON pointer set (an object key is added
/// if missing).
fn with(pointer: &str, value: Value) -> String {
    let mut v = base();
    let (parent, key) = pointer.rsplit_once('/').unwrap();
    match v.pointer_mut(parent) {
        Some(Value::Object(map)) => {
            map.insert(key.to_string(), value);
        }
        Some(Value::Array(items)) => items[key.parse::<usize>().unwrap()] = value,
        _ => panic!("no {parent}"),
    }
    v.to_string()
}

fn without(parent: &str, key: &str) -> String {
    let mut v = base();
    v.pointer_mut(parent)
        .and_then(Value::as_object_mut)
        .unwrap()
        .remove(key)
        .unwrap();
    v.to_string()
}

fn errors(text: &str) -> ConfigErrors {
    match IoConfig::from_json_str(text, "bad.json") {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e,
    }
}

/// Asserts exactly one error, at `path`, and returns it as text.
fn single(text: &str, path: &str) -> (Problem, String) {
    let e = errors(text);
    assert_eq!(e.errors().len(), 1, "{e}");
    let first = e.first();
    assert_eq!(first.file, "bad.json");
    assert_eq!(first.path, path, "{e}");
    let shown = first.to_string();
    assert!(shown.starts_with(&format!("bad.json: {path}: ")), "{shown}");
    (first.problem.clone(), shown)
}

#[test]
fn the_base_is_valid() {
    IoConfig::from_json_str(&base().to_string(), "base.json").unwrap();
}

#[test]
fn wrong_type_names_the_path() {
    let (p, shown) = single(
        &with(
            "/robots/1/actuators/0/drive/current_to_bits/scale",
            json!("big"),
        ),
        "robots[1].actuators[0].drive.current_to_bits.scale",
    );
    assert!(matches!(p, Problem::Type(_)));
    assert!(
        shown.contains("invalid type: string \"big\", expected f64"),
        "{shown}"
    );
}

#[test]
fn missing_field_names_the_object() {
    let (_, shown) = single(
        &without("/robots/0/actuators/1/drive", "maximum_current"),
        "robots[0].actuators[1].drive",
    );
    assert!(shown.contains("missing field `maximum_current`"), "{shown}");
    let (_, shown) = single(&without("/robots/0", "name"), "robots[0]");
    assert!(shown.contains("missing field `name`"), "{shown}");
}

#[test]
fn unknown_keys_are_warned_about_and_bad_values_refused() {
    // A key Firelink does not use: loaded, one warning naming its path.
    let text = with("/robots/0/actuators/0/drive/maximum_curent", json!(0.5));
    let loaded = IoConfig::from_json_str_with_warnings(&text, "typo.json").unwrap();
    let ignored: Vec<String> = loaded
        .warnings
        .iter()
        .filter(|w| w.warning == firelink_control::config::Warning::Ignored)
        .map(|w| w.to_string())
        .collect();
    assert_eq!(
        ignored,
        [
            "typo.json: robots[0].actuators[0].drive.maximum_curent: ignored (a key Firelink does not use)"
        ]
    );
    // The typo instead of the key: the key is missing.
    let text = base()
        .to_string()
        .replacen("\"maximum_current\"", "\"maximum_curent\"", 1);
    let (_, shown) = single(&text, "robots[0].actuators[0].drive");
    assert!(shown.contains("missing field `maximum_current`"), "{shown}");
    let (_, shown) = single(
        &with(
            "/robots/0/actuators/0/encoder/velocity_source",
            json!("MAGIC"),
        ),
        "robots[0].actuators[0].encoder.velocity_source",
    );
    assert!(shown.contains("unknown variant `MAGIC`"), "{shown}");
    let mut v = base();
    v["robots"][0]["actuators"][0]["simulation"] = json!({ "plant": "mtm_j8" });
    let (_, shown) = single(&v.to_string(), "robots[0].actuators[0].simulation.plant");
    assert!(shown.contains("unknown variant `mtm_j8`"), "{shown}");
    // A board ID that does not fit in a byte is a type error.
    let (_, shown) = single(
        &with("/robots/0/actuators/0/board_id", json!(300)),
        "robots[0].actuators[0].board_id",
    );
    assert!(shown.contains("300"), "{shown}");
}

#[test]
fn syntax_errors_give_line_and_column() {
    let e = errors("{\n  \"$id\": \"saw-robot-io.schema.json\",\n  \"robots\": [ , ]\n}");
    let shown = e.to_string();
    assert!(matches!(e.first().problem, Problem::Syntax(_)), "{shown}");
    assert!(shown.contains("line 3"), "{shown}");
    let e = errors(&format!("{} trailing", base()));
    assert!(matches!(e.first().problem, Problem::Syntax(_)), "{e}");
}

#[test]
fn zero_scale() {
    let (p, _) = single(
        &with(
            "/robots/1/actuators/0/drive/current_to_bits/scale",
            json!(0.0),
        ),
        "robots[1].actuators[0].drive.current_to_bits.scale",
    );
    assert_eq!(p, Problem::ZeroScale);
    let (p, _) = single(
        &with(
            "/robots/0/actuators/0/encoder/bits_to_position/scale",
            json!(0),
        ),
        "robots[0].actuators[0].encoder.bits_to_position.scale",
    );
    assert_eq!(p, Problem::ZeroScale);
}

#[test]
fn duplicate_board_axis() {
    let (p, shown) = single(
        &with("/robots/1/actuators/0/board_id", json!(0)),
        "robots[1].actuators[0]",
    );
    assert_eq!(
        p,
        Problem::Duplicate {
            what: "(board_id 0, axis_id 0)".into(),
            first: "robots[0].actuators[0]".into()
        }
    );
    assert!(
        shown.contains("duplicate (board_id 0, axis_id 0)"),
        "{shown}"
    );
}

#[test]
fn axis_beyond_the_board() {
    let (p, shown) = single(
        &with("/robots/0/actuators/1/axis_id", json!(4)),
        "robots[0].actuators[1].axis_id",
    );
    assert!(matches!(
        p,
        Problem::AxisBeyondBoard {
            axis_id: 4,
            board_id: 0,
            axes: 4,
            hardware: "QLA1"
        }
    ));
    assert!(shown.contains("QLA1 has 4"), "{shown}");
    // The same axis is fine on a DQLA (8 axes).
    let mut v = base();
    v["robots"][0]["hardware_version"] = json!("DQLA");
    v["robots"][0]["actuators"][1]["axis_id"] = json!(4);
    IoConfig::from_json_str(&v.to_string(), "dqla.json").unwrap();
}

#[test]
fn board_out_of_range_and_type_conflict() {
    let (p, _) = single(
        &with("/robots/1/actuators/0/board_id", json!(16)),
        "robots[1].actuators[0].board_id",
    );
    assert!(matches!(p, Problem::OutOfRange { value, .. } if value == 16.0));
    // Board 0 declared QLA1 by robot A and DQLA by robot B.
    let mut v = base();
    v["robots"][1]["hardware_version"] = json!("DQLA");
    v["robots"][1]["actuators"][0]["board_id"] = json!(0);
    v["robots"][1]["actuators"][0]["axis_id"] = json!(5);
    let (p, _) = single(&v.to_string(), "robots[1].actuators[0].board_id");
    assert!(matches!(p, Problem::Mismatch(m) if m.contains("DQLA here but QLA1")));
}

#[test]
fn empty_position_range() {
    let mut v = base();
    v["robots"][0]["actuators"][0]["encoder"]["position_limits_soft"] =
        json!({ "lower": 1.0, "upper": 1.0 });
    let (p, shown) = single(
        &v.to_string(),
        "robots[0].actuators[0].encoder.position_limits_soft",
    );
    assert_eq!(
        p,
        Problem::EmptyRange {
            lower: 1.0,
            upper: 1.0
        }
    );
    assert!(shown.contains("lower 1 is not below upper 1"), "{shown}");
}

#[test]
fn counts_ranges_and_signs() {
    let (p, _) = single(
        &with("/robots/0/number_of_actuators", json!(3)),
        "robots[0].number_of_actuators",
    );
    assert!(matches!(p, Problem::Mismatch(m) if m.contains("is 3 but 2")));
    let (p, shown) = single(
        &with("/robots/0/actuators/0/drive/maximum_current", json!(10.0)),
        "robots[0].actuators[0].drive.maximum_current",
    );
    assert!(matches!(p, Problem::OutOfRange { .. }), "{shown}");
    // 32767 codes / 5242.88 codes per A.
    assert!(shown.contains("at most 6.2498 A"), "{shown}");
    let (p, _) = single(
        &with("/robots/0/actuators/0/drive/maximum_current", json!(-1)),
        "robots[0].actuators[0].drive.maximum_current",
    );
    assert!(matches!(p, Problem::OutOfRange { .. }));
    let (p, _) = single(
        &with(
            "/robots/0/actuators/0/drive/bits_to_current/scale",
            json!(-0.000190735),
        ),
        "robots[0].actuators[0].drive.bits_to_current.scale",
    );
    assert!(matches!(p, Problem::Mismatch(m) if m.contains("sign")));
    let (p, _) = single(
        &with(
            "/robots/0/actuators/0/drive/current_to_bits/offset",
            json!(70000),
        ),
        "robots[0].actuators[0].drive.current_to_bits.offset",
    );
    assert!(matches!(p, Problem::OutOfRange { .. }));
    let (p, _) = single(
        &with(
            "/robots/0/actuators/0/encoder/position_limits_soft/upper",
            json!(1000.0),
        ),
        "robots[0].actuators[0].encoder.position_limits_soft.upper",
    );
    assert!(matches!(p, Problem::OutOfRange { expected, .. } if expected.contains("24-bit")));
}

#[test]
fn schema_id_and_version() {
    let (p, _) = single(&with("/$version", json!("5")), "$version");
    assert_eq!(
        p,
        Problem::Unsupported {
            found: "5".into(),
            expected: "6"
        }
    );
    // A number reads as the console reads it (jsoncpp's asString).
    let c = IoConfig::from_json_str(&with("/$version", json!(6)), "six.json").unwrap();
    assert_eq!(c.version, "6");
    let (_, shown) = single(&with("/$version", json!([6])), "$version");
    assert!(shown.contains("a string (or a number)"), "{shown}");
    let (p, _) = single(&with("/$id", json!("x.json")), "$id");
    assert!(matches!(p, Problem::Unsupported { .. }));
    let (p, _) = single(&with("/robots", json!([])), "robots");
    assert_eq!(p, Problem::Empty);
    let (p, _) = single(&with("/robots/1/name", json!("A")), "robots[1].name");
    assert!(matches!(p, Problem::Duplicate { first, .. } if first == "robots[0].name"));
}

#[test]
fn extension_sections_are_checked() {
    let mut v = base();
    v["robots"][0]["actuators"][0]["limits"] =
        json!({ "velocity": 0.0, "following_error": 0.1, "saturation_time": -1 });
    v["robots"][0]["actuators"][1]["simulation"] = json!({
        "plant": "generic",
        "pid": { "kp": -1.0, "ki": 0.0, "kd": 0.1 },
        "homing": { "position": 3.0, "velocity": 0.1, "acceleration": 0.5 }
    });
    v["robots"][0]["potentiometers"] = json!({
        "potentiometers_type": "ANALOG",
        "tolerances": [
            { "axis_id": 0, "distance": 0.1, "latency": 0.01 },
            { "axis_id": 0, "distance": 0.1, "latency": 0.01 },
            { "axis_id": 7, "distance": -0.1, "latency": 0.01 }
        ]
    });
    let e = errors(&v.to_string());
    let paths: Vec<&str> = e.errors().iter().map(|e| e.path.as_str()).collect();
    assert_eq!(
        paths,
        [
            "robots[0].potentiometers.tolerances[1].axis_id",
            "robots[0].potentiometers.tolerances[2].axis_id",
            "robots[0].potentiometers.tolerances[2].distance",
            "robots[0].actuators[0].limits.velocity",
            "robots[0].actuators[0].limits.saturation_time",
            "robots[0].actuators[1].simulation.pid.kp",
            "robots[0].actuators[1].simulation.homing.position",
        ],
        "{e}"
    );
    // Every error is printed, one per line.
    assert_eq!(e.to_string().lines().count(), 7);
}

#[test]
fn all_errors_are_reported_at_once() {
    let mut v = base();
    v["robots"][0]["actuators"][0]["drive"]["effort_to_current"]["scale"] = json!(0.0);
    v["robots"][1]["actuators"][0]["axis_id"] = json!(9);
    v["robots"][1]["actuators"][0]["encoder"]["position_limits_soft"]["lower"] = json!(2.0);
    let e = errors(&v.to_string());
    assert_eq!(e.errors().len(), 3, "{e}");
    assert!(e.has_path("robots[0].actuators[0].drive.effort_to_current.scale"));
    assert!(e.has_path("robots[1].actuators[0].axis_id"));
    assert!(e.has_path("robots[1].actuators[0].encoder.position_limits_soft"));
}

#[test]
fn older_names_are_accepted() {
    let text = base()
        .to_string()
        .replace("\"current_to_bits\"", "\"amps_to_bits\"")
        .replace("\"bits_to_current\"", "\"bits_to_feedback_amps\"")
        .replace("\"effort_to_current\"", "\"nm_to_amps\"")
        .replace("\"voltage_to_position\"", "\"sensor_to_position\"");
    let c = IoConfig::from_json_str(&text, "old.json").unwrap();
    assert_eq!(
        c.robots[0].actuators[0].drive.current_to_bits.scale,
        5242.88
    );
    // Validation errors name the v6 key, whatever alias the file used.
    let bad = text.replacen("\"scale\":5242.88", "\"scale\":0", 1);
    let (_, shown) = single(&bad, "robots[0].actuators[0].drive.current_to_bits.scale");
    assert!(shown.contains("zero scale"), "{shown}");
}

#[test]
fn v6_extras_are_accepted() {
    let mut v = base();
    v["digital_inputs"] = json!([{ "name": "clutch", "board_id": 0, "bit_id": 0 }]);
    v["dallas_chips"] = json!([{ "name": "PSM1_dallas", "board_id": 1 }]);
    v["robots"][0]["brakes"] = json!([]);
    v["robots"][0]["number_of_brakes"] = json!(0);
    v["robots"][0]["only_IO"] = json!(false);
    v["robots"][0]["actuators"][0]["joint_type"] = json!("PRISMATIC");
    v["robots"][0]["actuators"][0]["actuator_id"] = json!(0);
    IoConfig::from_json_str(&v.to_string(), "extras.json").unwrap();
    let (p, _) = single(
        &with("/robots/0/actuators/1/actuator_id", json!(0)),
        "robots[0].actuators[1].actuator_id",
    );
    assert!(matches!(p, Problem::Mismatch(_)));
}

#[test]
fn missing_file_is_named() {
    let e = IoConfig::load("/nonexistent/robot.json").unwrap_err();
    assert!(matches!(e.first().problem, Problem::Io(_)));
    assert!(
        e.to_string()
            .starts_with("/nonexistent/robot.json: cannot read")
    );
}

#[test]
fn stock_arm_files_load_with_their_dvrk_facts() {
    let psm = load("dvrk-psm1-28007.json");
    let r = &psm.robots[0];
    assert_eq!(
        (r.name.as_str(), r.serial_number.as_str()),
        ("PSM1", "28007")
    );
    assert_eq!(r.dvrk_arm(), Some(DvrkArm::Psm));
    // The dVRK's board IDs for PSM1, its adapter and tool inputs.
    assert_eq!(psm.board_set().0, 0b1100_0000);
    let contact = |name: &str| {
        let d = psm.digital_input(name).unwrap();
        (d.board_id, d.bit_id, d.pressed_value)
    };
    assert_eq!(contact("PSM1_adapter"), (7, 10, true));
    assert_eq!(contact("PSM1_tool"), (7, 7, true));
    assert_eq!(psm.board_slots(), 8);
    let serial = psm.board_serial(6).unwrap();
    assert_eq!(
        (serial.fpga.as_deref(), serial.qla.as_deref()),
        (Some("3116-01"), Some("3791-15"))
    );
    // A calibrated file: DAC zero offsets are not all equal (the console
    // refuses a file where they are).
    let offsets: Vec<f64> = r
        .actuators
        .iter()
        .map(|a| a.drive.current_to_bits.offset)
        .collect();
    assert!(offsets.windows(2).any(|w| w[0] != w[1]));
    // Every actuator states stops beyond its soft limits.
    for a in &r.actuators {
        let s = a.simulation.unwrap().hard_stops.unwrap();
        let soft = a.encoder.position_limits_soft;
        assert!(s.lower < soft.lower && soft.upper < s.upper);
    }

    let mtm = load("dvrk-mtmr-28247.json");
    let r = &mtm.robots[0];
    assert_eq!(r.dvrk_arm(), Some(DvrkArm::Mtm));
    let c = r.pot_coupling().unwrap();
    assert_eq!(c.size(), 7);
    assert_eq!((c.get(2, 1), c.get(3, 2), c.get(3, 3)), (1.0, 0.6697, 1.0));
    let roll = r.actuators[6].simulation.unwrap();
    let search = roll.homing.unwrap().stop_search.unwrap();
    assert_eq!(search.side, StopSide::Lower);
    assert!((search.stop_position.to_degrees() + 480.0).abs() < 1e-9);
    assert_eq!(
        r.potentiometers.as_ref().unwrap().tolerances[6].distance,
        0.0
    );

    let ecm = load("dvrk-ecm-29738.json");
    let r = &ecm.robots[0];
    assert_eq!((r.actuators.len(), r.number_of_brakes), (4, Some(3)));
    // The brakes' board (5) is one the robot drives, though no actuator
    // uses it.
    assert_eq!(ecm.board_set().0, 0b11_0000);
    let brakes = r.brakes.as_ref().unwrap();
    assert_eq!((brakes[2].board_id, brakes[2].axis_id), (5, 2));
    assert!(r.actuators[0].brake.is_some() && r.actuators[3].brake.is_none());
    assert_eq!(ecm.board_slots(), 6);
}

#[test]
fn simulation_sections_are_checked() {
    // Stops inside the soft limits.
    let (p, _) = single(
        &with(
            "/robots/0/actuators/0/simulation",
            json!({ "plant": "psm_j1", "hard_stops": { "lower": -0.5, "upper": 1.5 } }),
        ),
        "robots[0].actuators[0].simulation.hard_stops",
    );
    assert!(matches!(p, Problem::OutOfRange { value, .. } if value == -0.5));
    // A stop search that cannot move.
    let (_, shown) = single(
        &with(
            "/robots/0/actuators/0/simulation",
            json!({ "plant": "mtm_j7", "homing": { "velocity": 1.0, "acceleration": 1.0,
                "stop_search": { "side": "lower", "velocity": 0.0, "acceleration": 1.0,
                    "stall_error": 1.0, "stop_position": -1.1, "max_travel": 5.0 } } }),
        ),
        "robots[0].actuators[0].simulation.homing.stop_search.velocity",
    );
    assert!(shown.contains("> 0"), "{shown}");
    // A serial number no PROM can hold, a board listed twice, a tool
    // without a name.
    let mut v = base();
    v["robots"][0]["simulation"] = json!({
        "arm": "PSM", "adapter": true,
        "tool": { "name": "", "model": 400006 },
        "boards": [
            { "board_id": 0, "serial": { "fpga": "3116-01", "qla": "a serial far too long" } },
            { "board_id": 0, "serial": {} }
        ]
    });
    let e = errors(&v.to_string());
    assert_eq!(e.errors().len(), 3, "{e}");
    assert!(e.has_path("robots[0].simulation.tool.name"));
    assert!(e.has_path("robots[0].simulation.boards[0].serial.qla"));
    assert!(e.has_path("robots[0].simulation.boards[1].board_id"));
    // An unknown arm is a type error naming its path.
    let (_, shown) = single(
        &with("/robots/0/simulation", json!({ "arm": "SUJ" })),
        "robots[0].simulation.arm",
    );
    assert!(shown.contains("unknown variant `SUJ`"), "{shown}");
}

#[test]
fn pot_couplings_must_fit_and_invert() {
    let coupling = |m: Value| {
        let mut v = base();
        v["robots"][0]["potentiometers"] = json!({ "coupling": { "JointToActuatorPosition": m } });
        v.to_string()
    };
    let (p, _) = single(
        &coupling(json!([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])),
        "robots[0].potentiometers.coupling.JointToActuatorPosition",
    );
    assert!(
        matches!(p, Problem::Mismatch(ref m) if m.contains("2 x 2")),
        "{p:?}"
    );
    let (p, _) = single(
        &coupling(json!([[1.0, 2.0], [0.5, 1.0]])),
        "robots[0].potentiometers.coupling.JointToActuatorPosition",
    );
    assert!(
        matches!(p, Problem::Mismatch(ref m) if m.contains("singular")),
        "{p:?}"
    );
    let c = IoConfig::from_json_str(&coupling(json!([[1.0, 0.0], [1.0, 1.0]])), "ok.json").unwrap();
    let m = c.robots[0].pot_coupling().unwrap();
    let inv = m.inverse().unwrap();
    assert_eq!((inv.get(1, 0), inv.get(1, 1)), (-1.0, 1.0));
}

/// A DQLA exists only on an FPGA V3 (the firmware builds no V2 DQLA
/// image): a robot's `simulation.boards[].fpga_version` of "V2" under a
/// DQLA robot is refused by name; "V3" or none loads; a firmware other
/// than 7, 8 or 9 is refused.
#[test]
fn a_v2_dqla_is_refused_at_loading() {
    use firelink_control::config::{BoardSerial, BoardSimulation, RobotSimulation};
    let with = |fpga: Option<FpgaGeneration>, firmware: Option<u32>| {
        let mut c = presets::snake_36axes();
        c.robots[0].simulation = Some(RobotSimulation {
            boards: vec![BoardSimulation {
                board_id: 0,
                serial: BoardSerial {
                    fpga: None,
                    qla: None,
                },
                fpga_version: fpga,
                firmware,
            }],
            ..RobotSimulation::default()
        });
        assert_eq!(c.robots[0].hardware_version, HardwareVersion::Dqla);
        c.validate("snake.json")
    };
    assert!(with(None, None).is_ok());
    assert!(with(Some(FpgaGeneration::V3), Some(9)).is_ok());
    let e = with(Some(FpgaGeneration::V2), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("fpga_version") && e.contains("only on an FPGA V3"),
        "{e}"
    );
    let e = with(None, Some(10)).unwrap_err().to_string();
    assert!(e.contains("firmware 10"), "{e}");
    // The field as a file spells it.
    let b: BoardSimulation = serde_json::from_str(
        r#"{"board_id": 3, "serial": {}, "fpga_version": "V3", "firmware": 9}"#,
    )
    .unwrap();
    assert_eq!(
        (b.fpga_version, b.firmware),
        (Some(FpgaGeneration::V3), Some(9))
    );
}

/// `dvrk-dqla-rev9.json`: each arm on one DQLA as the dVRK's configuration
/// generator lays out a DQLA arm (every actuator on the arm's first board
/// ID, axis = actuator index; the ECM's brakes on axes 4-6; the PSM's
/// instrument and adapter on the second QLA's lines, bits 23 and 26), each
/// board an FPGA V3 at Rev 9; the same file with a V2 under a DQLA is
/// refused.
#[test]
fn the_dqla_arms_are_one_board_each_as_the_dvrk_lays_them_out() {
    let c = load("dvrk-dqla-rev9.json");
    c.validate("dvrk-dqla-rev9.json").unwrap();
    let boards = c.boards();
    let ids: Vec<u8> = boards.iter().map(|b| b.board_id).collect();
    assert_eq!(ids, [2, 4, 6]);
    for (robot, board) in [("MTMR", 2u8), ("ECM", 4), ("PSM1", 6)] {
        let r = c.robot(robot).unwrap();
        assert_eq!(r.hardware_version, HardwareVersion::Dqla, "{robot}");
        for (i, a) in r.actuators.iter().enumerate() {
            assert_eq!(
                (a.board_id, usize::from(a.axis_id)),
                (board, i),
                "{robot} {i}"
            );
        }
        let sim = c.board_simulation(board).unwrap();
        assert_eq!(
            (sim.fpga_version, sim.firmware),
            (Some(FpgaGeneration::V3), Some(9)),
            "{robot}"
        );
    }
    let brakes: Vec<(u8, u8)> = c
        .robot("ECM")
        .unwrap()
        .brakes
        .iter()
        .flatten()
        .map(|b| (b.board_id, b.axis_id))
        .collect();
    assert_eq!(brakes, [(4, 4), (4, 5), (4, 6)]);
    let input = |name: &str| {
        let d = c.digital_inputs.iter().flatten().find(|d| d.name == name);
        d.map(|d| (d.board_id, d.bit_id))
    };
    assert_eq!(input("PSM1_tool"), Some((6, 23)));
    assert_eq!(input("PSM1_adapter"), Some((6, 26)));
    assert_eq!(input("ECM_arm_clutch"), Some((4, 0)));

    // A DQLA exists only on an FPGA V3.
    let text = std::fs::read_to_string(configs_dir().join("dvrk-dqla-rev9.json")).unwrap();
    let v2 = text.replacen("\"fpga_version\": \"V3\"", "\"fpga_version\": \"V2\"", 1);
    assert_ne!(v2, text);
    let e = IoConfig::from_json_str(&v2, "v2.json")
        .unwrap_err()
        .to_string();
    assert!(e.contains("only on an FPGA V3"), "{e}");
}
