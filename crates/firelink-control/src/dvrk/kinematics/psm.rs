//! The Classic PSM (patient side manipulator) with a Large Needle Driver:
//! the arm's three joints from the dVRK's `share/kinematic/psm.json`
//! (modified DH) and the instrument's three wrist joints, jaw, tool-tip
//! rotation and actuator-to-joint coupling from
//! `share/tool/LARGE_NEEDLE_DRIVER_400006.json`.
//!
//! The arm is a remote centre of motion (RCM): the outer yaw and pitch
//! turn the instrument's shaft about a fixed point (the origin of the base
//! frame), the insertion slides it through that point. At the end of the
//! shaft the wrist: roll about the shaft, pitch, then yaw 9.1 mm further
//! (the tip frame sits on the yaw axis). The jaw opens about the yaw axis
//! and does not move the tip frame.
//!
//! [`psm_inverse`] is closed form. With `p` the tip position and `z6` the
//! yaw axis (from the goal's rotation), the pitch-to-yaw link `x5` is
//! perpendicular to `z6` and coplanar with `z6` and the shaft, so it is
//! the part of `p` perpendicular to `z6`, normalised; the wrist point is
//! `w = p - 9.1 mm x5`, on the shaft: it gives yaw, pitch and insertion;
//! the pitch axis is `x5 x z6`, which gives the roll; then pitch and yaw
//! follow. The other branch (`-x5`) needs a wrist pitch beyond 90 degrees,
//! outside the instrument's range; the roll (260 degrees either way) is
//! taken the turn nearest the seed.

use super::KinematicsError;
use super::dh::{Convention, DhLink, chain};
use super::frame::{Frame, Rotation, cross, dot, norm, scale, sub};
use super::mtm::nearest_turn;
use core::f64::consts::FRAC_PI_2;

/// Joints of the PSM that move the tip frame (the jaw apart).
pub const PSM_JOINTS: usize = 6;

/// Actuators of the PSM (the last four drive the instrument's disks).
pub const PSM_ACTUATORS: usize = 7;

/// The arm's and the instrument's links, modified DH, with their limits
/// (arm: `psm.json`; instrument: the Large Needle Driver's file).
pub const PSM_LINKS: [DhLink; PSM_JOINTS] = [
    // outer yaw: the file's +-270 degrees
    DhLink::revolute(FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, (-4.71239, 4.71239)),
    // outer pitch: +-53 degrees
    DhLink::revolute(-FRAC_PI_2, 0.0, 0.0, -FRAC_PI_2, (-0.925025, 0.925025)),
    // insertion: 0 to 240 mm; the shaft's frame 431.8 mm back at 0
    DhLink::prismatic(FRAC_PI_2, 0.0, 0.0, -0.4318, (0.0, 0.24)),
    // instrument roll: +-260 degrees; the wrist 416.2 mm down the shaft
    DhLink::revolute(0.0, 0.0, 0.4162, 0.0, (-4.53786, 4.53786)),
    // wrist pitch: +-80 degrees
    DhLink::revolute(-FRAC_PI_2, 0.0, 0.0, -FRAC_PI_2, (-1.39626, 1.39626)),
    // wrist yaw: +-80 degrees, 9.1 mm past the pitch axis
    DhLink::revolute(-FRAC_PI_2, 0.0091, 0.0, -FRAC_PI_2, (-1.39626, 1.39626)),
];

/// The jaw's range, rad: -40 to 80 degrees (the dVRK's override of the
/// maker's 0 to 30: negative to squeeze harder, 80 to open wide).
pub const JAW_LIMITS: (f64, f64) = (-0.698132, 1.39626);

/// The rotation from the last DH frame to the tip frame (the file's
/// `tooltip-offset`, to match the maker's convention).
pub const TOOLTIP_ROTATION: Rotation =
    Rotation([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]]);

/// The instrument's coupling, disk (actuator) positions to roll, pitch,
/// yaw and jaw (`coupling.ActuatorToJointPosition`, from the dVRK user
/// guide): the yaw cables run over the pitch pulley, the two jaw halves
/// are driven by the last two disks together (yaw) and apart (jaw).
pub const LND_ACTUATOR_TO_JOINT: [[f64; 4]; 4] = [
    [-1.5632, 0.0, 0.0, 0.0],
    [0.0, 1.0186, 0.0, 0.0],
    [0.0, -0.8306, 0.6089, 0.6089],
    [0.0, 0.0, -1.2177, 1.2177],
];

/// The PSM's joints (six, and the jaw) from its seven actuator positions
/// (the arm's three are its joints).
pub fn psm_joints(actuators: &[f64; PSM_ACTUATORS]) -> ([f64; PSM_JOINTS], f64) {
    let mut q = [0.0; PSM_JOINTS];
    q[..3].copy_from_slice(&actuators[..3]);
    let disks = [actuators[3], actuators[4], actuators[5], actuators[6]];
    let mut tool = [0.0; 4];
    for (t, row) in tool.iter_mut().zip(&LND_ACTUATOR_TO_JOINT) {
        *t = row.iter().zip(&disks).map(|(w, a)| w * a).sum();
    }
    q[3..].copy_from_slice(&tool[..3]);
    (q, tool[3])
}

/// The seven actuator positions that give joints `q` and `jaw` (the
/// coupling's inverse).
pub fn psm_actuators(q: &[f64; PSM_JOINTS], jaw: f64) -> [f64; PSM_ACTUATORS] {
    let c = &LND_ACTUATOR_TO_JOINT;
    let a4 = q[3] / c[0][0];
    let a5 = q[4] / c[1][1];
    // Yaw: c22 a5 + c23 (a6 + a7); jaw: c33 (a7 - a6).
    let sum = (q[5] - c[2][1] * a5) / c[2][2];
    let difference = jaw / c[3][3];
    [
        q[0],
        q[1],
        q[2],
        a4,
        a5,
        0.5 * (sum - difference),
        0.5 * (sum + difference),
    ]
}

/// The tip frame in the PSM's base frame (origin at the RCM) at joints `q`.
pub fn psm_forward(q: &[f64; PSM_JOINTS]) -> Frame {
    let f = chain(&PSM_LINKS, Convention::Modified, q);
    Frame::new(f.rotation * TOOLTIP_ROTATION, f.translation)
}

/// The first joint out of its limits (widened by 1e-9), if any.
fn out_of_limits(q: &[f64; PSM_JOINTS]) -> Option<KinematicsError> {
    super::dh::out_of_limits(&PSM_LINKS, q)
}

/// The joints that put the tip frame at `goal` (base frame), the roll the
/// turn nearest `seed`'s.
///
/// # Errors
/// [`KinematicsError::Singular`] when the tip lies on the yaw axis's line
/// through the RCM or the wrist at the RCM; [`KinematicsError::Unreachable`]
/// for a non-finite goal or a wrist behind the RCM;
/// [`KinematicsError::JointLimit`] for a solution outside the limits.
pub fn psm_inverse(
    goal: &Frame,
    seed: &[f64; PSM_JOINTS],
) -> Result<[f64; PSM_JOINTS], KinematicsError> {
    if !goal.is_finite() {
        return Err(KinematicsError::Unreachable { what: "PSM pose" });
    }
    let r6 = goal.rotation * TOOLTIP_ROTATION.transpose();
    let p = goal.translation;
    let z6 = r6.column(2);
    // The pitch-to-yaw link: the part of p across the yaw axis.
    let across = sub(p, scale(dot(p, z6), z6));
    let n = norm(across);
    if n < 1e-9 {
        return Err(KinematicsError::Singular {
            what: "PSM tip on the yaw axis through the RCM",
        });
    }
    let x5 = scale(1.0 / n, across);
    let w = sub(p, scale(PSM_LINKS[5].a, x5));
    let length = norm(w);
    if length < 1e-6 {
        return Err(KinematicsError::Singular {
            what: "PSM wrist at the RCM",
        });
    }
    let z3 = scale(1.0 / length, w);
    // z3 = (sin q1 cos q2, -sin q2, -cos q1 cos q2).
    let q2 = libm::asin((-z3[1]).clamp(-1.0, 1.0));
    let q1 = libm::atan2(z3[0], -z3[2]);
    // The shaft's length past the RCM is q3 - 431.8 + 416.2 mm.
    let q3 = length - PSM_LINKS[2].offset - PSM_LINKS[3].d;
    let r3 = chain(&PSM_LINKS[..3], Convention::Modified, &[q1, q2, q3]).rotation;
    // The pitch axis: z5 = x5 x z6; in frame 3 it is (-sin q4, cos q4, 0).
    let z5 = r3.transpose().apply(cross(x5, z6));
    let q4 = nearest_turn(libm::atan2(-z5[0], z5[1]), seed[3]);
    // x5 in frame 4 is (sin q5, 0, cos q5).
    let r4 = r3 * PSM_LINKS[3].frame(Convention::Modified, q4).rotation;
    let x5_4 = r4.transpose().apply(x5);
    let q5 = libm::atan2(x5_4[0], x5_4[2]);
    // R6 = R5 Rx(-pi/2) Rz(q6 - pi/2).
    let r5 = r4 * PSM_LINKS[4].frame(Convention::Modified, q5).rotation;
    let n6 = (r5 * Rotation::about_x(PSM_LINKS[5].alpha)).transpose() * r6;
    let q6 = libm::atan2(n6.0[1][0], n6.0[0][0]) - PSM_LINKS[5].offset;
    let q = [q1, q2, q3, q4, q5, q6];
    match out_of_limits(&q) {
        Some(e) => Err(e),
        None => Ok(q),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn at_zero_the_instrument_points_down_through_the_rcm() {
        let q = [0.0, 0.0, 0.12, 0.0, 0.0, 0.0];
        let f = psm_forward(&q);
        // Shaft along -z: the tip 120 - 15.6 + 9.1 mm below the RCM.
        let expected = -(0.12 - 0.4318 + 0.4162 + 0.0091);
        assert!(f.translation[0].abs() < 1e-12 && f.translation[1].abs() < 1e-12);
        assert!(
            (f.translation[2] - expected).abs() < 1e-12,
            "{:?}",
            f.translation
        );
        let back = psm_inverse(&f, &q).unwrap();
        for (a, b) in q.iter().zip(back) {
            assert!((a - b).abs() < 1e-9, "{back:?}");
        }
    }

    #[test]
    fn the_coupling_and_its_inverse_agree() {
        let q = [0.1, -0.2, 0.1, 0.7, -0.4, 0.3];
        let a = psm_actuators(&q, 0.5);
        let (back, jaw) = psm_joints(&a);
        for (x, y) in q.iter().zip(back) {
            assert!((x - y).abs() < 1e-12);
        }
        assert!((jaw - 0.5).abs() < 1e-12);
        // Opening the jaw turns the last two disks apart, equally.
        let open = psm_actuators(&q, 0.9);
        assert!((open[5] - a[5] + open[6] - a[6]).abs() < 1e-12);
        assert!(open[6] > a[6]);
    }

    proptest! {
        // FK(IK(pose)) is the pose over the instrument's workspace, with
        // every joint within its limits.
        #[test]
        fn forward_of_inverse_is_the_pose(
            yaw in -1.5f64..1.5,
            pitch in -0.9f64..0.9,
            insertion in 0.05f64..0.24,
            roll in -4.4f64..4.4,
            wrist_pitch in -1.35f64..1.35,
            wrist_yaw in -1.35f64..1.35,
            roll_seed in -0.3f64..0.3,
        ) {
            let q = [yaw, pitch, insertion, roll, wrist_pitch, wrist_yaw];
            let goal = psm_forward(&q);
            let mut seed = q;
            seed[3] += roll_seed;
            let sol = psm_inverse(&goal, &seed).unwrap();
            let got = psm_forward(&sol);
            prop_assert!(norm(sub(got.translation, goal.translation)) < 1e-9);
            prop_assert!(got.rotation.angle_to(&goal.rotation) < 1e-9);
            for (l, v) in PSM_LINKS.iter().zip(sol) {
                prop_assert!(l.allows(v, 1e-9));
            }
            // Within the instrument's range the solution is unique.
            for (a, b) in q.iter().zip(sol) {
                prop_assert!((a - b).abs() < 1e-6, "{q:?} {sol:?}");
            }
        }

        #[test]
        fn poses_out_of_reach_are_refused(insertion in 0.25f64..0.4) {
            let q = [0.0, 0.0, insertion, 0.0, 0.0, 0.0];
            let goal = psm_forward(&q);
            let refused = matches!(
                psm_inverse(&goal, &[0.0; 6]),
                Err(KinematicsError::JointLimit { joint: 2, .. })
            );
            prop_assert!(refused);
        }
    }
}
