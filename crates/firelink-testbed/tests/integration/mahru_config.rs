//! The MAHRU configuration loader at its boundary: every number in the
//! file is bounded, errors name the file, the JSON path and the range with
//! the number as written, and whatever it accepts gives durations, loop
//! counts and rates that end (property tests over every numeric field).

use proptest::prelude::*;
use serde_json::Value;

use firelink_testbed::mahru::MahruConfig;
use firelink_testbed::mahru::config::bounds;

fn seed_json() -> Value {
    serde_json::to_value(MahruConfig::seed002()).unwrap()
}

/// JSON pointers of every number in `v`.
fn numbers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                numbers(x, format!("{at}/{k}"), out);
            }
        }
        Value::Array(items) => {
            for (i, x) in items.iter().enumerate() {
                numbers(x, format!("{at}/{i}"), out);
            }
        }
        Value::Number(_) => out.push(at),
        _ => {}
    }
}

fn load(v: &Value) -> Result<MahruConfig, String> {
    MahruConfig::from_json_str(&v.to_string(), "m.json").map_err(|e| e.to_string())
}

fn set(v: &mut Value, ptr: &str, x: f64) {
    if let Some(slot) = v.pointer_mut(ptr) {
        *slot = serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number);
    }
}

/// What an accepted configuration implies is bounded: the period and the
/// phases as durations, the number of periods of a day-long walk, every
/// module's servo tick and watchdog.
fn assert_bounded(c: &MahruConfig) {
    let period = c.period();
    let us = period.as_secs_f64() * 1e6;
    assert!(
        (bounds::PERIOD_US.0..=bounds::PERIOD_US.1).contains(&us),
        "{us}"
    );
    let periods_a_day = 86_400.0 / period.as_secs_f64();
    assert!(periods_a_day <= 1e9, "{periods_a_day}");
    assert!(c.compute_us <= bounds::PHASE_US && c.slack_us <= bounds::PHASE_US);
    let t = c.responder_timing();
    assert!(t.poll.as_micros_f64() <= bounds::RESPONDER_US);
    for chain in c.module_configs() {
        for m in chain {
            if let firelink_board::mahru::DeviceConfig::Motor(j) = m.device {
                assert!(j.servo_hz >= bounds::SERVO_HZ.0 && j.servo_hz <= bounds::SERVO_HZ.1);
                assert!(j.watchdog.as_micros_f64() <= bounds::WATCHDOG_MS.1 * 1e3);
                assert!(j.inertia > 0.0 && j.inertia.is_finite());
            }
        }
    }
    c.layout().unwrap().validate().unwrap();
}

#[test]
fn the_reported_values_are_refused_with_path_and_range() {
    for (ptr, x, path, range) in [
        ("/period_us", 1e300, "period_us", "100 to 1000000 us"),
        ("/period_us", 1e12, "period_us", "100 to 1000000 us"),
        ("/slack_us", 1e300, "slack_us", "0 to 1000000 us"),
        ("/compute_us", 1e300, "compute_us", "0 to 1000000 us"),
        (
            "/chains/0/modules/0/device/motor/servo_hz",
            1e300,
            "chains[0].modules[0].device.motor.servo_hz",
            "100 to 20000 Hz",
        ),
        (
            "/chains/1/modules/2/device/motor/watchdog_ms",
            1e300,
            "chains[1].modules[2].device.motor.watchdog_ms",
            "0.1 to 10000 ms",
        ),
    ] {
        let mut v = seed_json();
        set(&mut v, ptr, x);
        let e = load(&v).unwrap_err();
        let shown = format!("{}", firelink_wire::human::Number(x));
        assert!(
            e.contains(&format!("m.json: {path}: out of range: {shown}")),
            "{e}"
        );
        assert!(e.contains(range), "{e}");
        assert!(!e.contains("000000000000"), "{e}");
    }
}

#[test]
fn every_problem_is_reported_with_its_path() {
    let mut v = seed_json();
    set(&mut v, "/period_us", -1.0);
    set(&mut v, "/gait/stride_s", 0.0);
    set(
        &mut v,
        "/chains/2/modules/1/device/force_torque/noise/0",
        1e300,
    );
    let e = load(&v).unwrap_err();
    for path in [
        "m.json: period_us:",
        "m.json: gait.stride_s:",
        "m.json: chains[2].modules[1].device.force_torque.noise[0]:",
    ] {
        assert!(e.contains(path), "{e}");
    }
}

#[test]
fn each_field_at_extremes() {
    let base = seed_json();
    let mut ptrs = Vec::new();
    numbers(&base, String::new(), &mut ptrs);
    for ptr in &ptrs {
        for x in [1e300, -1e300, 1e-300, 0.0, 1e12] {
            let mut v = base.clone();
            set(&mut v, ptr, x);
            match load(&v) {
                Ok(c) => assert_bounded(&c),
                Err(e) => assert!(e.contains("m.json"), "{ptr} = {x}: {e}"),
            }
        }
    }
}

fn extreme() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(1e300),
        Just(-1e300),
        Just(f64::MAX),
        Just(1e-300),
        Just(0.0),
        Just(1e12),
        -1e4..1e4f64,
        any::<f64>().prop_filter("JSON has no NaN or infinity", |x| x.is_finite()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Up to four numbers replaced at random: refused naming the file, or
    /// bounded.
    #[test]
    fn random_numbers_are_refused_or_bounded(
        picks in proptest::collection::vec((any::<prop::sample::Index>(), extreme()), 1..5),
    ) {
        let base = seed_json();
        let mut ptrs = Vec::new();
        numbers(&base, String::new(), &mut ptrs);
        let mut v = base.clone();
        for (index, x) in &picks {
            let ptr: &String = index.get(&ptrs);
            set(&mut v, ptr, *x);
        }
        match load(&v) {
            Ok(c) => assert_bounded(&c),
            Err(e) => {
                prop_assert!(e.contains("m.json"), "{}", e);
                prop_assert!(!e.contains("0000000000000"), "{}", e);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// An accepted configuration with random numbers walks: a short demo
    /// ends (with or without errors), it does not panic or hang.
    #[test]
    fn accepted_configurations_walk(
        picks in proptest::collection::vec((any::<prop::sample::Index>(), -1e4..1e4f64), 1..3),
    ) {
        let base = seed_json();
        let mut ptrs = Vec::new();
        numbers(&base, String::new(), &mut ptrs);
        let mut v = base.clone();
        for (index, x) in &picks {
            let ptr: &String = index.get(&ptrs);
            set(&mut v, ptr, *x);
        }
        if let Ok(config) = load(&v) {
            let options = firelink_testbed::mahru::MahruDemoOptions {
                config,
                duration_s: 0.01,
                period: None,
                find_fastest: false,
                detail: firelink_bus::Detail::Fast,
            };
            let _ = firelink_testbed::mahru::run_mahru_demo(&options, |_| {});
        }
    }
}
