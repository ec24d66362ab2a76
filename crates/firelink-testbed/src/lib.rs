//! # firelink-testbed: whole emulated robots to run, measure and break
//!
//! The layers below give the parts: packets ([`firelink_wire`]), a bus in
//! virtual time ([`firelink_bus`]), emulated boards with their motors
//! ([`firelink_board`]), the host library ([`firelink_host`]) and servo
//! control ([`firelink_control`]). This crate assembles them into robots
//! that programs (the CLI, the Python package, the web console, tests)
//! can run without hardware:
//!
//! - [`emulated`]: the emulated hardware's types front ends name (board
//!   configurations, firmware profiles, the bus's fault rules);
//! - [`fault_script`]: faults as a plan: what goes wrong and when (a
//!   board by ID stops answering, packets corrupted or dropped, the host
//!   pauses), turned by the rig into the simulated bus's fault plan and,
//!   on any other port, into a link filter;
//! - [`port_spec`]: where the robot is: the one grammar of port strings
//!   (`sim[:N[:FW]]`, `emulate`, `udp:HOST[:PORT]`, `fw[:N]`) every front
//!   end parses, and opening what it names ([`ports`]);
//! - [`rig`]: a robot configuration's boards, with the plant each actuator's
//!   configuration names, built by one [`RigBuilder`](rig::RigBuilder)
//!   (boards by ID, seed, faults by board ID, the bridge board) on the
//!   simulated bus behind a [`SimPort`](firelink_host::sim::SimPort), or
//!   behind an in-process Ethernet-bridge emulator on loopback UDP
//!   ([`rig::Emulator`]);
//! - [`demo_request`]: one request for `firelink demo` whatever the robot
//!   (the dVRK, the Snake system, MAHRU, the teleoperation session) and
//!   its outcome; [`demo_text`]: the dVRK demo's progress lines and table;
//! - [`sim`]: one I/O cycle of N boards on the simulated bus, measured
//!   phase by phase (the wire times of the seed papers; `firelink sim`);
//! - [`plant_map`]: how an actuator of a configuration becomes an emulated
//!   joint: plant, mechanical stops inside what its pot can see, coupled
//!   pots, amplifier calibration, a PSM's adapter and instrument;
//! - [`dvrk`]: the dVRK's wing: the dVRK demo's options and runs
//!   ([`dvrk::demo`]), what the dVRK console does to an arm after power-on
//!   ([`dvrk::console_homing`]: bias from pots, stop searches, every joint
//!   to both software limits and back, with pot/encoder agreement and the
//!   stops watched every cycle) and a teleoperation session
//!   ([`dvrk::teleop`]: a hand moves the MTMR, PSM1 follows, 60 s of
//!   virtual time); the fault soak ([`dvrk::soak`]: a million servo
//!   cycles with one packet in a hundred faulted, every fault accounted
//!   for, amplifiers proven off whenever the safety chain says so), the
//!   watchdog proof ([`dvrk::watchdog`]: the host stopped at random
//!   moments, every board's amplifiers off within the watchdog period plus
//!   one tick), seed 000's I/O benchmark ([`dvrk::bench`]) and two
//!   simulated runs compared cycle by cycle ([`dvrk::cycle_compare`]);
//! - [`mahru`]: seed 002's MAHRU humanoid (14 modules on three chains,
//!   the MotionController walking it), its time budget (Table I), read
//!   times by payload (Table III) and the CAN comparison (Table IV);
//! - [`cycle_schedule`]: when the robot service's loop
//!   ([`dvrk::service`]) runs its next cycle: at the control rate, or at
//!   once for a waiting command; [`loop_outcome`]: how a robot loop's
//!   commands and the loop itself end, for every robot's loop;
//! - [`snake`]: seed 001's own system: Snake-node rigs, the 36-axis demo
//!   on the generic servo, and the reproduction of the seed's bus
//!   measurements with its PC model.
//!
//! On the simulated bus everything runs in virtual time and is seeded: the
//! same inputs give the same report, bit for bit. Sockets and device files
//! are opened only where a port string asks for them: [`rig::Emulator`]
//! (its server paces virtual time to the wall clock), the UDP and FireWire
//! ports of [`ports`], and the programs that run over them with wall-clock
//! pacing and measure wall-clock or CPU time (the demo and Snake demo on
//! `emulate`, `udp:` or `fw`, the [`dvrk::service`] loop, the benchmark's UDP
//! points and host-CPU figures).

#[cfg(feature = "clap")]
pub mod cli_args;
pub mod cpu;
pub mod cycle_schedule;
pub mod demo;
pub mod demo_request;
pub mod demo_text;
pub mod dvrk;
pub mod emulated;
pub mod emulation;
pub mod error;
pub mod fault_script;
pub mod fw_run;
pub mod limits;
pub mod loop_outcome;
pub mod mahru;
pub mod plant_map;
pub mod port_spec;
pub mod ports;
pub mod realtime;
pub mod rig;
pub mod sim;
pub mod snake;

pub use error::TestbedError;
