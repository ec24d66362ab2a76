//! The dVRK's wing: what only the QLA/DQLA arms of the da Vinci Research
//! Kit do, beside `snake/` and `mahru/`.
//!
//! - [`demo`]: the dVRK demo's options and its run on any port;
//! - [`console_homing`]: what the dVRK console does to an arm after
//!   power-on (pots and encoders, the stops);
//! - [`teleop`]: a teleoperation session, PSM1 following the MTMR.
//!
//! The demo program, its report and faults, the plants, ports and rigs
//! every robot shares stay at the crate's root.

pub mod console_homing;
pub mod demo;
pub mod teleop;
