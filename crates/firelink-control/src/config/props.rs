//! Property tests of the loader: a shipped configuration with random and
//! extreme numbers in any of its numeric fields is either refused with an
//! error naming a path, or gives a configuration whose every implied
//! duration, loop count and conversion is bounded and finite.

use proptest::prelude::*;
use serde_json::Value;

use super::bounds;
use super::presets;
use super::{IoConfig, Limits};
use crate::pid::{Measurement, Pid, Setpoint};
use crate::trajectory::PointToPoint;

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

/// Values a person might type, or a fuzzer find: extremes, tiny ones,
/// signs, zero, the ordinary range.
fn extreme() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(1e300),
        Just(-1e300),
        Just(1e308),
        Just(-1e308),
        Just(f64::MAX),
        Just(1e-300),
        Just(-1e-300),
        Just(f64::MIN_POSITIVE),
        Just(0.0),
        Just(1e12),
        Just(1e-12),
        -1e3..1e3f64,
        any::<f64>().prop_filter("JSON has no NaN or infinity", |x| x.is_finite()),
    ]
}

/// The shipped configurations as JSON, with every numeric pointer.
fn shipped() -> Vec<(Value, Vec<String>)> {
    [
        presets::dvrk_seed000(),
        presets::stock_mtmr(),
        presets::stock_psm1(),
        presets::snake_seed001(),
    ]
    .iter()
    .map(|c| {
        let v = serde_json::to_value(c).unwrap();
        let mut ptrs = Vec::new();
        numbers(&v, String::new(), &mut ptrs);
        (v, ptrs)
    })
    .collect()
}

/// The longest move `limits` allow between two points of `soft` at this
/// velocity and acceleration, seconds.
fn move_time(soft: Limits, velocity: f64, acceleration: f64) -> f64 {
    PointToPoint::new(soft.lower, soft.upper, velocity, acceleration)
        .map(|m| m.duration())
        .unwrap_or(f64::INFINITY)
}

/// Everything an accepted configuration implies is bounded.
fn assert_bounded(c: &IoConfig) {
    let period = 1.0 / 6000.0;
    for j in c.joints() {
        let a = j.actuator;
        let d = a.drive;
        // Conversions: finite, and the DAC code never panics.
        for amps in [0.0, d.maximum_current, -d.maximum_current, 1e300, f64::NAN] {
            let _ = d.current_to_bits(amps);
        }
        for code in [0u16, 0x8000, 0xFFFF] {
            let amps = d.bits_to_current(code);
            assert!(amps.is_finite() && amps.abs() <= bounds::CURRENT, "{amps}");
        }
        assert!(d.maximum_current > 0.0 && d.maximum_current <= bounds::CURRENT);
        let e = a.encoder;
        for bits in [0u32, 0x80_0000, 0xFF_FFFF] {
            assert!(e.bits_to_position(bits).is_finite());
        }
        let soft = e.position_limits_soft;
        assert!(soft.lower < soft.upper && soft.span() <= 2.0 * bounds::POSITION);
        let _ = e.position_to_preload_bits(soft.lower);
        if let Some(p) = a.potentiometer {
            for bits in [0u16, 0xFFFF] {
                let x = p.bits_to_position(bits);
                assert!(x.is_finite() && x.abs() <= bounds::POSITION, "{x}");
            }
        }
        // Every move the configuration implies ends, in a bounded number
        // of cycles.
        let mut moves = Vec::new();
        if let Some(l) = a.limits {
            moves.push(move_time(
                soft,
                l.velocity,
                l.acceleration.unwrap_or(4.0 * l.velocity),
            ));
            for t in [l.following_error_grace, l.saturation_time] {
                assert!((0.0..=bounds::CHECK_SECONDS).contains(&t));
            }
        }
        if let Some(s) = a.simulation {
            if let Some(h) = s.homing {
                moves.push(move_time(soft, h.velocity, h.acceleration));
                if let Some(search) = h.stop_search {
                    let travel = Limits {
                        lower: 0.0,
                        upper: search.max_travel,
                    };
                    moves.push(move_time(travel, search.velocity, search.acceleration) + 1.0);
                }
            }
            if let Some(g) = s.pid {
                let mut pid = Pid::new(g, d.maximum_current).expect("valid gains");
                let out = pid.update(
                    Setpoint::hold(soft.upper),
                    Measurement {
                        position: soft.lower,
                        velocity: -bounds::VELOCITY,
                    },
                    period,
                );
                assert!(out.is_finite() && out.abs() <= d.maximum_current);
            }
        }
        for t in moves {
            assert!(
                t <= bounds::MOVE_SECONDS + 1.0,
                "{}: a move of {t} s",
                j.label
            );
            let cycles = ((t + 0.2) / period).ceil();
            assert!(cycles < 1e8, "{cycles}");
        }
        if let Some(t) = j.potentiometer_tolerance() {
            assert!(t.latency <= bounds::CHECK_SECONDS && t.distance <= bounds::POSITION);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Up to three numbers replaced at random: refused with a path, or
    /// bounded.
    #[test]
    fn any_numbers_are_refused_or_bounded(
        which in 0usize..4,
        picks in proptest::collection::vec((any::<prop::sample::Index>(), extreme()), 1..4),
    ) {
        let configs = shipped();
        let (base, ptrs) = &configs[which];
        let mut v = base.clone();
        for (index, x) in &picks {
            let ptr = index.get(ptrs);
            if let Some(slot) = v.pointer_mut(ptr) {
                *slot = serde_json::Number::from_f64(*x).map_or(Value::Null, Value::Number);
            }
        }
        match IoConfig::from_json_str(&v.to_string(), "prop.json") {
            Ok(c) => assert_bounded(&c),
            Err(e) => {
                for err in e.errors() {
                    prop_assert_eq!(&err.file, "prop.json");
                    let shown = err.to_string();
                    // Numbers as written: never a 300-digit integer.
                    prop_assert!(shown.len() < 400, "{}", shown);
                    prop_assert!(!shown.contains("0000000000000"), "{}", shown);
                }
            }
        }
    }

    /// Every single numeric field set to an extreme value, one at a time,
    /// in the dVRK configuration.
    #[test]
    fn each_field_alone(index in any::<prop::sample::Index>(), x in extreme()) {
        let configs = shipped();
        let (base, ptrs) = &configs[0];
        let mut v = base.clone();
        let ptr = index.get(ptrs);
        if let Some(slot) = v.pointer_mut(ptr) {
            *slot = serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number);
        }
        match IoConfig::from_json_str(&v.to_string(), "one.json") {
            Ok(c) => assert_bounded(&c),
            Err(e) => prop_assert!(e.to_string().starts_with("one.json: ")),
        }
    }
}

/// `ptr` with its array indices as `*`: one per kind of field.
fn shape(ptr: &str) -> String {
    ptr.split('/')
        .map(|p| if p.parse::<usize>().is_ok() { "*" } else { p })
        .collect::<Vec<_>>()
        .join("/")
}

#[test]
fn every_field_at_1e300() {
    // Deterministically: each kind of numeric field of each shipped file
    // (its first occurrence) alone at 1e300, -1e300 and 1e-300.
    for (base, ptrs) in shipped() {
        let mut seen = std::collections::BTreeSet::new();
        for ptr in ptrs.iter().filter(|p| seen.insert(shape(p))) {
            for x in [1e300, -1e300, 1e-300] {
                let mut v = base.clone();
                if let Some(slot) = v.pointer_mut(ptr) {
                    *slot = Value::from(x);
                }
                match IoConfig::from_json_str(&v.to_string(), "f.json") {
                    Ok(c) => assert_bounded(&c),
                    Err(e) => {
                        let shown = e.to_string();
                        assert!(!shown.contains("0000000000000"), "{ptr}: {shown}");
                    }
                }
            }
        }
    }
}
