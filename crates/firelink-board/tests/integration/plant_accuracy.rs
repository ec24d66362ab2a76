//! The plant's exact integration in spans of at most 100 us
//! (`DEFAULT_STEP`) against the reference: the semi-implicit integration
//! at 5 us that the plant used before
//! (`Integrator::SemiImplicitEuler`, `REFERENCE_STEP`). Both are driven
//! with the same DAC codes at the same instants, open loop, and compared
//! at every millisecond.
//!
//! Tolerances (stated in `BENCHMARKS.md`, "Simulation speed"): joint
//! position within 1 % of the motion's range plus 2 encoder counts,
//! velocity within 3 % of its peak, motor current within 0.5 % of its peak,
//! the encoder count within 1 % of the counts travelled plus 2.

use firelink_board::plant::{
    AxisParams, DEFAULT_STEP, Integrator, Plant, QLA_AMPS_PER_BIT, REFERENCE_STEP, presets,
};
use firelink_board::time::{SimDuration, SimTime};

/// The DAC code for `amps`.
fn dac(amps: f64) -> u16 {
    (32768.0 + amps / QLA_AMPS_PER_BIT)
        .round()
        .clamp(0.0, 65535.0) as u16
}

/// Axes that cover the motor classes, with and without gravity, and a
/// joint that meets its stop.
fn axes() -> Vec<(&'static str, AxisParams)> {
    vec![
        ("generic", presets::generic_motor()),
        ("MTM joint 2 (gravity)", presets::mtm_joint(2).unwrap()),
        ("MTM wrist roll", presets::mtm_joint(7).unwrap()),
        ("PSM joint 1 (large)", presets::psm_joint(1).unwrap()),
        ("PSM joint 3 (prismatic)", presets::psm_joint(3).unwrap()),
        ("ECM joint 1", presets::ecm_joint(1).unwrap()),
    ]
}

/// What one run records every millisecond.
#[derive(Debug, Clone, Copy)]
struct Sample {
    position: f64,
    velocity: f64,
    current: f64,
    count: i64,
}

/// Drive `params` with `amps(t)` held for `period`, for `duration`, and
/// sample every millisecond.
fn run(
    params: &AxisParams,
    integrator: Integrator,
    step: SimDuration,
    period: SimDuration,
    duration: SimDuration,
    amps: &dyn Fn(f64) -> f64,
) -> Vec<Sample> {
    let mut plant = Plant::with_integrator(vec![params.clone()], 3, step, integrator);
    let mut samples = Vec::new();
    let mut next_command = SimTime::ZERO;
    let mut next_sample = SimTime::ZERO;
    let end = SimTime::ZERO + duration;
    let ms = SimDuration::from_millis(1);
    while next_sample <= end {
        if next_command <= next_sample {
            plant.advance_to(next_command);
            let t = next_command.as_micros_f64() * 1e-6;
            plant.axis_mut(0).unwrap().set_drive(dac(amps(t)), true);
            next_command += period;
            continue;
        }
        plant.advance_to(next_sample);
        let a = plant.axis(0).unwrap();
        samples.push(Sample {
            position: a.joint_position(),
            velocity: a.joint_velocity(),
            current: a.current(),
            count: a.encoder().count(),
        });
        next_sample += ms;
    }
    samples
}

/// The largest differences between `fast` and `reference`, each against
/// its scale; panics with the figures when one is beyond its tolerance.
fn compare(what: &str, params: &AxisParams, fast: &[Sample], reference: &[Sample]) {
    assert_eq!(fast.len(), reference.len());
    let span = |f: fn(&Sample) -> f64| {
        let (lo, hi) = reference
            .iter()
            .map(f)
            .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
        hi - lo
    };
    let peak = |f: fn(&Sample) -> f64| reference.iter().map(|s| f(s).abs()).fold(0.0, f64::max);
    let worst = |f: fn(&Sample) -> f64| {
        fast.iter()
            .zip(reference)
            .map(|(a, b)| (f(a) - f(b)).abs())
            .fold(0.0, f64::max)
    };
    let counts_per_unit = params.counts_per_joint_unit().abs();
    let position_tol = 0.01 * span(|s| s.position) + 2.0 / counts_per_unit;
    let velocity_tol = 0.03 * peak(|s| s.velocity) + 1e-9;
    let current_tol = 0.005 * peak(|s| s.current) + 1e-6;
    let travelled = reference
        .windows(2)
        .map(|w| w[0].count.abs_diff(w[1].count))
        .sum::<u64>() as f64;
    let count_tol = 0.01 * travelled + 2.0;
    let dp = worst(|s| s.position);
    let dv = worst(|s| s.velocity);
    let di = worst(|s| s.current);
    let dc = fast
        .iter()
        .zip(reference)
        .map(|(a, b)| a.count.abs_diff(b.count))
        .max()
        .unwrap_or(0) as f64;
    println!(
        "{what}: position {dp:.3e} (tol {position_tol:.3e}), velocity {dv:.3e} (tol \
         {velocity_tol:.3e}), current {di:.3e} (tol {current_tol:.3e}), count {dc} (tol \
         {count_tol:.0})"
    );
    assert!(dp <= position_tol, "{what}: position {dp} > {position_tol}");
    assert!(dv <= velocity_tol, "{what}: velocity {dv} > {velocity_tol}");
    assert!(di <= current_tol, "{what}: current {di} > {current_tol}");
    assert!(dc <= count_tol, "{what}: count {dc} > {count_tol}");
}

/// Both integrations of one input.
fn agree(input: &str, period: SimDuration, duration: SimDuration, amps: &dyn Fn(f64) -> f64) {
    for (name, params) in axes() {
        let reference = run(
            &params,
            Integrator::SemiImplicitEuler,
            REFERENCE_STEP,
            period,
            duration,
            amps,
        );
        let fast = run(
            &params,
            Integrator::Exact,
            DEFAULT_STEP,
            period,
            duration,
            amps,
        );
        compare(&format!("{input}, {name}"), &params, &fast, &reference);
    }
}

#[test]
fn a_current_step_agrees_with_the_reference_integration() {
    // 30 % of the QLA's range for 0.3 s: every joint accelerates hard,
    // several into their stops.
    agree(
        "step",
        SimDuration::from_micros(1000),
        SimDuration::from_millis(300),
        &|_| 0.3,
    );
}

#[test]
fn a_sinusoidal_current_agrees_with_the_reference_integration() {
    // A 2 Hz sinusoid commanded at 6 kHz (as the demo's servo loop does),
    // with a bias so stiction is crossed at different currents.
    agree(
        "sinusoid",
        SimDuration::from_nanos(166_667),
        SimDuration::from_millis(1000),
        &|t| 0.05 + 0.4 * (2.0 * std::f64::consts::PI * 2.0 * t).sin(),
    );
}

#[test]
fn small_currents_start_and_stop_at_the_same_moments() {
    // Around the breakaway current: stiction decides when the joint moves.
    agree(
        "stiction",
        SimDuration::from_nanos(166_667),
        SimDuration::from_millis(500),
        &|t| 0.15 * (2.0 * std::f64::consts::PI * 5.0 * t).sin(),
    );
}
