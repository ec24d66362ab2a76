//! The Classic MTM (master tool manipulator): its seven joints from the
//! dVRK's `share/kinematic/mtmr.json` (standard DH, the same for MTML),
//! the pots-to-joints coupling of its arm, the forward kinematics to the
//! gripper frame and an inverse that moves the arm to a position and the
//! wrist to an orientation.
//!
//! The joints: outer yaw, shoulder pitch, elbow pitch (the arm), then the
//! wrist platform, pitch, yaw and roll. The four wrist axes meet in one
//! point, the origin of the gripper frame: its position depends on the arm
//! only, its orientation on all seven. The wrist is redundant (four joints
//! for three angles); the inverse chooses the platform the way the dVRK
//! console does (`mtsIntuitiveResearchKitMTM::InverseKinematics`): the
//! platform turns by `q6 cos(q5)` until the wrist yaw is zero, so the
//! platform faces the operator's hand.

use super::KinematicsError;
use super::dh::{Convention, DhLink, chain};
use super::frame::{Frame, Rotation, Vec3, norm, sub};
use core::f64::consts::{FRAC_PI_2, PI};

/// Joints of the MTM.
pub const MTM_JOINTS: usize = 7;

/// The MTM's links, standard DH (`share/kinematic/mtmr.json`; the file's
/// 1.5708 read as pi/2), with its joint limits as the file writes them
/// (`qmin`, `qmax`: its rounded numbers kept, so the limits are the
/// console's to the last digit).
#[allow(clippy::approx_constant)]
pub const MTM_LINKS: [DhLink; MTM_JOINTS] = [
    // outer yaw: -65 to 40 degrees
    DhLink::revolute(FRAC_PI_2, 0.0, 0.0, -FRAC_PI_2, (-1.13446, 0.698132)),
    // shoulder pitch: -15 to 50 degrees
    DhLink::revolute(0.0, 0.2794, 0.0, -FRAC_PI_2, (-0.261799, 0.872665)),
    // elbow pitch: -50 to 35 degrees
    DhLink::revolute(-FRAC_PI_2, 0.3645, 0.0, FRAC_PI_2, (-0.872665, 0.610865)),
    // wrist platform: -70 to 230 degrees
    DhLink::revolute(FRAC_PI_2, 0.0, 0.1506, 0.0, (-1.22173, 4.01426)),
    // wrist pitch: -90 to 180 degrees
    DhLink::revolute(-FRAC_PI_2, 0.0, 0.0, 0.0, (-1.5708, 3.14159)),
    // wrist yaw: -45 to 45 degrees
    DhLink::revolute(FRAC_PI_2, 0.0, 0.0, -FRAC_PI_2, (-0.785398, 0.785398)),
    // wrist roll: -480 to 450 degrees
    DhLink::revolute(0.0, 0.0, 0.0, FRAC_PI_2, (-8.37758, 7.85398)),
];

/// Actuator positions to joint positions
/// (`mtmr.json`, `coupling.ActuatorToJointPosition`): the elbow's motor
/// turns the elbow relative to the shoulder, and the platform's cable runs
/// over both.
pub const MTM_ACTUATOR_TO_JOINT: [[f64; MTM_JOINTS]; MTM_JOINTS] = [
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, -1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 0.6697, -0.6697, 1.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
];

/// Joint positions from actuator positions.
pub fn mtm_joints(actuators: &[f64; MTM_JOINTS]) -> [f64; MTM_JOINTS] {
    let mut q = [0.0; MTM_JOINTS];
    for (qi, row) in q.iter_mut().zip(&MTM_ACTUATOR_TO_JOINT) {
        *qi = row.iter().zip(actuators).map(|(w, a)| w * a).sum();
    }
    q
}

/// Actuator positions from joint positions (the coupling's inverse: the
/// dVRK's `JointToActuatorPosition` for the MTM's pots).
pub fn mtm_actuators(q: &[f64; MTM_JOINTS]) -> [f64; MTM_JOINTS] {
    let mut a = *q;
    a[2] = q[1] + q[2];
    a[3] = q[3] + 0.6697 * q[2];
    a
}

/// The gripper frame in the MTM's base frame at joint positions `q`.
pub fn mtm_forward(q: &[f64; MTM_JOINTS]) -> Frame {
    chain(&MTM_LINKS, Convention::Standard, q)
}

/// The frame of the arm's last link (after the elbow), whose origin plus
/// `d4` along its z axis is the wrist centre.
fn arm_frame(q: &[f64; 3]) -> Frame {
    chain(&MTM_LINKS[..3], Convention::Standard, q)
}

/// The wrist centre (the gripper frame's origin) for the arm joints `q`.
fn wrist_centre(q: &[f64; 3]) -> Vec3 {
    let f = arm_frame(q);
    f.apply([0.0, 0.0, MTM_LINKS[3].d])
}

/// Solve `m x = b` for a 3 x 3 `m` (Cramer's rule); `None` when singular.
fn solve3(m: &[[f64; 3]; 3], b: Vec3) -> Option<Vec3> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    if d.abs() < 1e-12 {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut mk = *m;
        for (row, bi) in mk.iter_mut().zip(b) {
            row[k] = bi;
        }
        *xk = det(&mk) / d;
    }
    Some(x)
}

/// The arm joints that put the wrist centre at `target`, by Newton's
/// method from `seed` (at most 30 steps, each at most 0.2 rad per joint).
fn arm_inverse(target: Vec3, seed: [f64; 3]) -> Result<[f64; 3], KinematicsError> {
    let mut q = seed;
    for _ in 0..30 {
        let p = wrist_centre(&q);
        let e = sub(target, p);
        if norm(e) < 1e-11 {
            return Ok(q);
        }
        // Jacobian by central differences (three joints, cheap).
        let h = 1e-7;
        let mut jac = [[0.0; 3]; 3];
        for k in 0..3 {
            let (mut qp, mut qm) = (q, q);
            qp[k] += h;
            qm[k] -= h;
            let d = sub(wrist_centre(&qp), wrist_centre(&qm));
            for (row, dk) in jac.iter_mut().zip(d) {
                row[k] = dk / (2.0 * h);
            }
        }
        let step = solve3(&jac, e).ok_or(KinematicsError::Singular { what: "MTM arm" })?;
        let longest = step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        let k = if longest > 0.2 { 0.2 / longest } else { 1.0 };
        for (qi, s) in q.iter_mut().zip(step) {
            *qi += k * s;
        }
    }
    let p = wrist_centre(&q);
    if norm(sub(target, p)) < 1e-9 {
        Ok(q)
    } else {
        Err(KinematicsError::Unreachable {
            what: "MTM position",
        })
    }
}

/// The wrist pitch, yaw and roll that give `goal` with the arm at `arm`
/// and the platform at `q4` (rad), the roll nearest `roll_near`.
fn wrist_for(arm: &[f64; 3], q4: f64, goal: &Rotation, roll_near: f64) -> [f64; 3] {
    // R4 = R3 Rz(q4) Rx(alpha4); then M = R4^T goal = Rz(q5) Ry(q6 - pi/2)
    // Rz(q7 + pi/2) (the wrist's twists make a Z-Y-Z sequence).
    let r4 = arm_frame(arm).rotation * MTM_LINKS[3].frame(Convention::Standard, q4).rotation;
    let m = (r4.transpose() * *goal).0;
    // The yaw's range (-45 to 45 degrees) keeps sin(q6 - pi/2) negative.
    let s6 = -(m[0][2] * m[0][2] + m[1][2] * m[1][2]).sqrt();
    let theta6 = libm::atan2(s6, m[2][2]);
    let q5 = libm::atan2(-m[1][2], -m[0][2]);
    let theta7 = libm::atan2(-m[2][1], m[2][0]);
    let q6 = theta6 + FRAC_PI_2;
    let q7 = nearest_turn(theta7 - FRAC_PI_2, roll_near);
    // The pitch's range is -90 to 180 degrees: past -90 it is the same
    // angle a turn up.
    let q5 = if q5 < MTM_LINKS[4].limits.0 {
        q5 + 2.0 * PI
    } else {
        q5
    };
    [q5, q6, q7]
}

/// `angle` plus the whole turns that bring it nearest `near`.
pub fn nearest_turn(angle: f64, near: f64) -> f64 {
    let turns = libm::round((near - angle) / (2.0 * PI));
    angle + turns * 2.0 * PI
}

/// The first joint out of its limits (widened by 1e-9), if any.
fn out_of_limits(q: &[f64; MTM_JOINTS]) -> Option<KinematicsError> {
    super::dh::out_of_limits(&MTM_LINKS, q)
}

/// The joints that orient the gripper as `goal` (in the base frame),
/// keeping the arm (`seed[0..3]`, so the position) as it is: the platform
/// chosen as the console chooses it, else kept where `seed` has it; the
/// roll the turn nearest the seed's.
///
/// # Errors
/// [`KinematicsError::JointLimit`] when no platform choice keeps every
/// wrist joint within its limits; a non-finite goal is
/// [`KinematicsError::Unreachable`].
pub fn mtm_orient(
    seed: &[f64; MTM_JOINTS],
    goal: &Rotation,
) -> Result<[f64; MTM_JOINTS], KinematicsError> {
    if !goal.is_finite() {
        return Err(KinematicsError::Unreachable {
            what: "MTM orientation",
        });
    }
    let arm = [seed[0], seed[1], seed[2]];
    let (lo4, hi4) = MTM_LINKS[3].limits;
    let full = |q4: f64| {
        let [q5, q6, q7] = wrist_for(&arm, q4, goal, seed[6]);
        [arm[0], arm[1], arm[2], q4, q5, q6, q7]
    };
    // The console's platform rule, run to its fixed point (wrist yaw 0).
    let mut q4 = seed[3].clamp(lo4, hi4);
    let mut q = full(q4);
    for _ in 0..60 {
        let step = q[5] * libm::cos(q[4]);
        let next = (q4 + step).clamp(lo4, hi4);
        if (next - q4).abs() < 1e-12 {
            break;
        }
        q4 = next;
        q = full(q4);
    }
    match out_of_limits(&q) {
        None => Ok(q),
        Some(first) => {
            // The seed's own platform.
            let kept = full(seed[3]);
            match out_of_limits(&kept) {
                None => Ok(kept),
                Some(_) => Err(first),
            }
        }
    }
}

/// The joints that put the gripper frame at `goal` (base frame): the arm
/// by Newton's method from `seed`, then the wrist as [`mtm_orient`].
///
/// # Errors
/// [`KinematicsError::Unreachable`] for a position the arm cannot reach
/// (or a non-finite goal), [`KinematicsError::Singular`] at an arm
/// singularity, [`KinematicsError::JointLimit`] for a solution outside the
/// limits.
pub fn mtm_inverse(
    goal: &Frame,
    seed: &[f64; MTM_JOINTS],
) -> Result<[f64; MTM_JOINTS], KinematicsError> {
    if !goal.is_finite() {
        return Err(KinematicsError::Unreachable { what: "MTM pose" });
    }
    let arm = arm_inverse(goal.translation, [seed[0], seed[1], seed[2]])?;
    let mut with_arm = *seed;
    with_arm[..3].copy_from_slice(&arm);
    if let Some(e) = out_of_limits(&with_arm)
        .filter(|e| matches!(e, KinematicsError::JointLimit { joint, .. } if *joint < 3))
    {
        return Err(e);
    }
    mtm_orient(&with_arm, &goal.rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn within(l: &DhLink, margin: f64, t: f64) -> f64 {
        let (lo, hi) = l.limits;
        lo + margin + (hi - lo - 2.0 * margin) * t
    }

    #[test]
    fn at_zero_the_gripper_points_as_the_dh_table_says() {
        let f = mtm_forward(&[0.0; 7]);
        // Arm: yaw offset -90, shoulder -90, elbow +90: the wrist centre
        // lies in the base's y-z plane.
        let p = f.translation;
        assert!(p[0].abs() < 1e-12, "{p:?}");
        assert!(
            (norm(p)
                - wrist_centre(&[0.0; 3])
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt())
            .abs()
                < 1e-15
        );
        // The coupling and its inverse agree.
        let q = [0.1, 0.2, -0.3, 0.4, 0.5, -0.2, 1.0];
        let back = mtm_joints(&mtm_actuators(&q));
        for (a, b) in q.iter().zip(back) {
            assert!((a - b).abs() < 1e-15);
        }
    }

    proptest! {
        // Every pose the MTM reaches with its joints inside their limits,
        // the inverse reaches again, inside the limits.
        #[test]
        fn forward_of_inverse_is_the_pose(
            t in proptest::array::uniform7(0.0f64..1.0),
            nudge in proptest::array::uniform7(-0.05f64..0.05),
        ) {
            let mut q = [0.0; 7];
            for ((qi, l), ti) in q.iter_mut().zip(&MTM_LINKS).zip(t) {
                *qi = within(l, 0.1, ti);
            }
            let goal = mtm_forward(&q);
            // Seeded near the true joints, as a servo loop seeds it.
            let mut seed = q;
            for (s, n) in seed.iter_mut().zip(nudge) {
                *s += n;
            }
            let sol = mtm_inverse(&goal, &seed).unwrap();
            let got = mtm_forward(&sol);
            prop_assert!(norm(sub(got.translation, goal.translation)) < 1e-9);
            prop_assert!(got.rotation.angle_to(&goal.rotation) < 1e-9);
            for (l, v) in MTM_LINKS.iter().zip(sol) {
                prop_assert!(l.allows(v, 1e-9));
            }
        }

        #[test]
        fn orienting_keeps_the_position(
            t in proptest::array::uniform7(0.0f64..1.0),
            v in proptest::array::uniform3(-0.4f64..0.4),
        ) {
            let mut q = [0.0; 7];
            for ((qi, l), ti) in q.iter_mut().zip(&MTM_LINKS).zip(t) {
                *qi = within(l, 0.5, ti);
            }
            let here = mtm_forward(&q);
            let goal = here.rotation * Rotation::from_rotation_vector(v);
            if let Ok(sol) = mtm_orient(&q, &goal) {
                let got = mtm_forward(&sol);
                prop_assert!(norm(sub(got.translation, here.translation)) < 1e-12);
                prop_assert!(got.rotation.angle_to(&goal) < 1e-9);
            }
        }
    }

    #[test]
    fn the_platform_turns_until_the_wrist_yaw_is_zero() {
        let q = [0.0, 0.2, 0.1, 0.3, 0.4, 0.3, 0.0];
        let goal = mtm_forward(&q).rotation;
        let sol = mtm_orient(&q, &goal).unwrap();
        assert!(sol[5].abs() < 1e-9, "{sol:?}");
        assert!(mtm_forward(&sol).rotation.angle_to(&goal) < 1e-9);
    }
}
