//! Kinematics of the da Vinci Research Kit's arms from the dVRK's public
//! DH tables: the MTM's forward kinematics to its gripper frame and an
//! inverse for a pose or an orientation ([`mtm`]), the PSM's forward and
//! closed-form inverse kinematics with a Large Needle Driver, its jaw and
//! the instrument's disk coupling ([`psm`]), on small `Copy` frames
//! ([`frame`]) and DH links ([`dh`]).
//!
//! Pure functions of their arguments: no allocation, no clock, bounded
//! loops; the same bits on every platform (`libm`). A servo loop calls them
//! every cycle.
//!
//! ```
//! use firelink_control::dvrk::kinematics::psm::{psm_forward, psm_inverse};
//! let q = [0.2, -0.1, 0.12, 0.3, 0.2, -0.4];
//! let tip = psm_forward(&q);
//! let back = psm_inverse(&tip, &q).unwrap();
//! assert!(back.iter().zip(q).all(|(a, b)| (a - b).abs() < 1e-9));
//! ```

pub mod dh;
pub mod frame;
pub mod mtm;
pub mod psm;

pub use frame::{Frame, Rotation, Vec3};

/// Why an inverse found no joints.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    /// The goal is out of the arm's reach (or not finite).
    #[error("{what} out of reach")]
    Unreachable {
        /// What could not be reached.
        what: &'static str,
    },
    /// The goal sits where the joints are not determined.
    #[error("singular: {what}")]
    Singular {
        /// Where.
        what: &'static str,
    },
    /// The solution needs a joint beyond its limit.
    #[error("joint {joint} would be at {value:.4}, outside [{lower:.4}, {upper:.4}]")]
    JointLimit {
        /// The joint (0-based).
        joint: usize,
        /// The value it would need.
        value: f64,
        /// Its lower limit.
        lower: f64,
        /// Its upper limit.
        upper: f64,
    },
}
