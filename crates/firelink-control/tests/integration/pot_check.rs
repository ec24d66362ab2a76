//! The safety monitor's encoder-to-pot check once the robot is homed: the
//! `homed` flag that keeps an unhomed robot from being compared
//! (`runner::an_unhomed_robot_is_not_faulted_...`) must never switch the
//! check off for a homed one.

use crate::common;

use firelink_control::config::presets;
use firelink_control::runner::{Pacing, Robot, RobotSettings, RunnerError};
use firelink_control::{FaultKind, ServoPeriod, State};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::{Dest, Port};
use firelink_wire::qla::address::{AxisRegister, Register};

/// Joints start inside their soft limits, away from the encoders' zero.
fn start(i: usize) -> f64 {
    let config = presets::dvrk_seed000();
    let l = config
        .joints()
        .nth(i)
        .unwrap()
        .actuator
        .encoder
        .position_limits_soft;
    0.5 * (l.lower + l.upper)
}

/// A homed, active robot whose joint's encoder is shifted afterwards (its
/// count preloaded further on, as a slipped encoder or a stray preload
/// write would) while its pot stays where the joint is: the monitor
/// faults with a pot mismatch on that joint.
#[test]
fn a_homed_robot_whose_encoder_is_shifted_faults_on_that_joints_pot() {
    let config = presets::dvrk_seed000();
    // The first joint that has a pot tolerance, and a following-error
    // limit well above it (the shift must not look like a following error).
    let (joint, tolerance) = config
        .joints()
        .find_map(|j| {
            let t = j.potentiometer_tolerance()?;
            let fe = j.actuator.limits?.following_error;
            (t.distance > 0.0 && fe > 3.0 * t.distance).then_some((j, t.distance))
        })
        .expect("a joint with a pot tolerance");
    let (index, label) = (joint.index, joint.label);
    let (board_id, axis) = (joint.actuator.board_id, joint.actuator.axis_id);
    let scale = joint.actuator.encoder.bits_to_position.scale;
    let port = common::port(&config, false, start);
    let io_options = IoOptions {
        protocol: Some(Protocol::Broadcast),
        ..IoOptions::default()
    };
    let (io, _) = IoSystem::open(port, io_options).unwrap();
    let settings = RobotSettings {
        period: ServoPeriod::from_rate_hz(2000.0).unwrap(),
        ..RobotSettings::default()
    };
    let mut r = Robot::new(io, &config, settings).unwrap();
    r.configure().unwrap();
    r.power_on().unwrap();
    r.home().unwrap();
    r.activate().unwrap();
    // Homed and holding: encoder and pot agree, no fault.
    for _ in 0..1000 {
        r.step(Pacing::Virtual).unwrap();
    }
    assert_eq!(r.state(), State::Active);
    // The encoder's count creeps on (at half the velocity limit, so that
    // no velocity check fires) until it is twice the tolerance ahead of
    // the joint; the servo then holds the encoder where it was, so the
    // joint itself, and its pot, move the other way.
    let node = r
        .io()
        .boards()
        .iter()
        .find(|b| b.info().board_id == board_id)
        .map(|b| b.info().node)
        .expect("the joint's board");
    let register = |reg| Register::axis(axis + 1, reg).offset().unwrap();
    let velocity_limit = joint.actuator.limits.map_or(1.0, |l| l.velocity);
    let step = ((0.5 * velocity_limit / 2000.0) / scale.abs()).max(1.0) as i64;
    let mut shifted = 0;
    let wanted = (2.0 * tolerance / scale.abs()).ceil() as i64;
    let before = r.position(index).unwrap();
    let mut fault = None;
    for _ in 0..20_000 {
        if shifted < wanted {
            let port = r.io_mut().port_mut();
            let count = port
                .read_quadlet(Dest::node(node), register(AxisRegister::EncPosition))
                .unwrap()
                & 0xFF_FFFF;
            let preload = (i64::from(count) + step).rem_euclid(1 << 24) as u32;
            port.write_quadlet(
                Dest::node(node),
                register(AxisRegister::EncPreload),
                preload,
            )
            .unwrap();
            shifted += step;
        }
        match r.step(Pacing::Virtual) {
            Ok(()) => {}
            Err(RunnerError::Fault(f)) => {
                fault = Some(f);
                break;
            }
            Err(e) => panic!("{e}"),
        }
    }
    let fault = fault.unwrap_or_else(|| {
        panic!(
            "no fault after the encoder of {label} moved (position {before} -> {:?})",
            r.position(index)
        )
    });
    match fault.kind {
        FaultKind::PotentiometerMismatch {
            joint, difference, ..
        } => {
            assert_eq!(joint, label);
            assert!(difference.abs() > tolerance, "{difference}");
        }
        other => panic!("expected a pot mismatch on {label}, got {other:?}"),
    }
}
