//! The dVRK's wing: what only the da Vinci Research Kit's arms and
//! console compute, beside the servo loop every robot shares.
//!
//! - [`kinematics`]: the MTM's and PSM's forward and inverse kinematics
//!   from the dVRK's public DH tables, and the PSM instrument's coupling;
//! - [`teleop`]: an MTM teleoperating a PSM as the dVRK console's
//!   `mtsTeleOperationPSM` does it (alignment, scale, clutch, gripper to
//!   jaw).
//!
//! The configuration, PID, trajectories, lifecycle, homing, safety, the
//! time budget and the runner stay at the crate's root: the Snake system
//! and MAHRU run on them too.

pub mod kinematics;
pub mod teleop;
