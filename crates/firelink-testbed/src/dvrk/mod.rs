//! The dVRK's wing: what only the QLA/DQLA arms of the da Vinci Research
//! Kit do, beside `snake/` and `mahru/`.
//!
//! - [`demo`]: the dVRK demo's options and its run on any port;
//! - [`console_homing`]: what the dVRK console does to an arm after
//!   power-on (pots and encoders, the stops);
//! - [`teleop`]: a teleoperation session, PSM1 following the MTMR;
//! - [`soak`]: the fault soak of the 28-axis robot on the simulated bus,
//!   and [`watchdog`], the watchdog proof over it;
//! - [`bench`](mod@bench): seed 000's I/O benchmark (Fig. 11) of the QLA
//!   boards' protocols, simulated and measured;
//! - [`service`]: the robot as a service for the web console's dVRK view
//!   and the ROS 2 node (one thread owns the robot and its QLA I/O
//!   system); how its commands and its loop end is every robot loop's
//!   ([`crate::loop_outcome`]);
//! - [`cycle_compare`]: two simulated runs of the demo robot compared
//!   cycle by cycle (boards by their firmware's state digest).
//!
//! The demo program, its report and faults, the plants, ports and rigs
//! every robot shares stay at the crate's root.

pub mod bench;
pub mod console_homing;
pub mod cycle_compare;
pub mod demo;
pub mod service;
pub mod soak;
pub mod teleop;
pub mod watchdog;
