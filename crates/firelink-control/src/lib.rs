//! # firelink-control: the servo loop
//!
//! Everything a robot program computes between reading the boards and
//! writing them, with no allocation in the cycle, and the runner that
//! drives it through the host library. The computing modules do no I/O
//! and read no clock: time is an argument (seconds, `f64`, on whatever
//! clock the caller runs: virtual or real), so the same code runs in the
//! emulator and on hardware, bit for bit. The [`runner`] is the one place that
//! does I/O (through the host library's abstract robot I/O) and reads the
//! machine's clock (wall-clock pacing, and the compute-time figures).
//!
//! - [`config`]: the robot I/O configuration in the dVRK's `saw-robot-io`
//!   version 6 JSON layout, validation with JSON-path errors, and the unit
//!   conversions (raw bits <-> SI): the only place units change.
//! - [`pid`]: per-joint PID with velocity feedforward, current limit,
//!   anti-windup and deadband.
//! - [`trajectory`]: trapezoidal and quintic point-to-point moves,
//!   sinusoids with a smooth ramp-in.
//! - [`lifecycle`]: Unconfigured / Configured / Active / Fault with checked
//!   transitions (only Active accepts motion).
//! - [`fault`]: the fault report ([`FaultReport`]), `Copy` and
//!   allocation-free.
//! - [`homing`]: make the encoders agree with the potentiometers.
//! - [`safety`]: the per-cycle safety monitor (following error, velocity,
//!   current saturation, position, pot/encoder agreement).
//! - [`dvrk`]: the dVRK's wing: its arms' kinematics
//!   ([`dvrk::kinematics`]: the MTM's and PSM's forward and inverse
//!   kinematics from their public DH tables, and the PSM instrument's
//!   coupling) and the console's teleoperation ([`dvrk::teleop`]: an MTM
//!   teleoperating a PSM, alignment, scale, clutch, gripper to jaw).
//! - [`budget`]: does the cycle fit its period (seed 002, Table I).
//! - [`period`]: [`ServoPeriod`], the servo period from configuration and
//!   command line to the runner (`1ms`, `250us`, `1kHz`).
//! - [`runner`]: [`Robot`](runner::Robot), a configuration over the host
//!   library's abstract robot I/O (`firelink_host::RobotIo`, seed 001's
//!   top layer): lifecycle, homing (pots and stop searches), motion and the
//!   safety chain, one servo cycle at a time, the same code for QLA boards
//!   and Snake nodes.
//!
//! The servo cycle, as the runner drives it (ros2_control's read / update /
//! write):
//!
//! ```
//! use firelink_control::config::presets;
//! use firelink_control::pid::{Measurement, Pid, Setpoint};
//! use firelink_control::safety::{JointSample, SafetyMonitor};
//! use firelink_control::trajectory::{Motion, PointToPoint};
//! use firelink_control::{BoardSet, Lifecycle, PowerStatus};
//!
//! let config = presets::bench_1board();
//! let joint = config.joints().next().unwrap();
//! let drive = joint.actuator.drive;
//! let encoder = joint.actuator.encoder;
//! let gains = joint.actuator.simulation.unwrap().pid.unwrap();
//!
//! // Setup (allocates): lifecycle, controllers, safety monitor.
//! let mut life = Lifecycle::from_config(&config);
//! let mut pid = Pid::new(gains, drive.maximum_current).unwrap();
//! let mut safety = SafetyMonitor::from_config(&config);
//! let motion = Motion::PointToPoint(PointToPoint::new(0.0, 0.5, 1.0, 4.0).unwrap());
//!
//! life.configure(BoardSet(0b1)).unwrap();
//! life.activate(PowerStatus { powered: BoardSet(1), amplifiers_enabled: BoardSet(1) }).unwrap();
//!
//! // One cycle at t = 10 ms (no allocation from here on).
//! let (now, dt, cycle) = (0.010, 0.001, 10);
//! life.check_cycle(BoardSet(1), now, cycle).unwrap();       // every board answered
//! let position = encoder.bits_to_position(0x80_0000 + 25);  // read: raw -> SI
//! let sp = motion.sample(now);                              // update
//! let amps = pid.update(
//!     Setpoint { position: sp.position, velocity: sp.velocity, feedforward: 0.0 },
//!     Measurement { position, velocity: 0.0 },
//!     dt,
//! );
//! let mut samples = [JointSample::default(); 4];
//! samples[0] = JointSample { setpoint: sp.position, position, current: amps, ..Default::default() };
//! assert!(safety.check(now, cycle, &samples).is_none());
//! life.require_motion().unwrap();
//! let dac = drive.current_to_bits(amps);                    // write: SI -> raw
//! assert!(dac != drive.zero_current_bits() || amps.abs() < 1e-3);
//! ```

pub mod budget;
pub mod config;
pub mod dvrk;
pub mod fault;
pub mod homing;
mod label;
pub mod lifecycle;
pub mod period;
pub mod pid;
pub mod runner;
pub mod safety;
pub mod trajectory;

pub use fault::{FaultKind, FaultReport};
pub use label::{BoardSet, Label};
pub use lifecycle::{Lifecycle, LifecycleError, PowerStatus, State};
pub use period::{ServoPeriod, ServoPeriodError};
