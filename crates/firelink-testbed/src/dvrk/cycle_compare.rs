//! Two simulated runs of the demo robot compared cycle by cycle.
//!
//! Issue 33 asks for a second level of detail on the simulated bus that
//! gives exactly the packet level's answer. This module is the yardstick
//! for that: it brings up two robots on two simulated buses from the same
//! options, steps them in lockstep and, after every servo cycle, compares
//! what each run holds:
//! - the bus: its clock (to the picosecond) and the packets put on the
//!   wire so far;
//! - every board: [`Firmware::state_digest`](firelink_board::qla::Firmware::state_digest) (registers, hub memory, the
//!   waiting broadcast, the received-packet memory, the plant);
//! - the host: every joint's position, velocity, potentiometer, measured
//!   and commanded current as the control program holds them (bit for
//!   bit), the robot's state and its I/O error counts.
//!
//! The first cycle at which anything differs is reported with what
//! differed. A hook runs on each side before every cycle with the robot
//! and the cycle number, which is where a caller changes one side (a
//! level of detail, a disturbance) and not the other.

use std::fmt;

use firelink_board::qla::node::BoardNode;
use firelink_bus::{Bus, NodeHandle};
use firelink_control::runner::{Pacing, Robot};
use firelink_host::qla::io::IoSystem;
use firelink_host::sim::SimPort;

use crate::TestbedError;
use crate::demo::bring_up;
use crate::dvrk::demo::{DemoOptions, open_robot};
use crate::port_spec::PortSpec;
use crate::{ports, rig};

/// The demo robot on the simulated bus.
pub type SimRobot = Robot<IoSystem<SimPort>>;

/// One side of a comparison: the robot and its boards' nodes on the bus.
pub struct ComparedRun {
    /// The robot (host library, control program, simulated port).
    pub robot: SimRobot,
    /// The boards' nodes, in board order.
    pub boards: Vec<NodeHandle>,
}

impl ComparedRun {
    /// The simulated bus.
    pub fn bus(&self) -> &Bus {
        self.robot.io().port().bus()
    }

    /// The simulated bus, mutably (e.g. to disturb a board).
    pub fn bus_mut(&mut self) -> &mut Bus {
        self.robot.io_mut().port_mut().bus_mut()
    }

    /// What this run holds after `cycle` servo cycles (see the module
    /// docs).
    pub fn state(&self, cycle: u64) -> CycleState {
        let bus = self.bus();
        let boards = self
            .boards
            .iter()
            .map(|&h| {
                bus.node::<BoardNode>(h)
                    .map(|b| b.firmware().state_digest())
            })
            .collect();
        let r = &self.robot;
        let joints = (0..r.joint_count())
            .map(|i| {
                [
                    r.position(i),
                    r.velocity(i),
                    r.potentiometer(i),
                    r.measured_current(i),
                    r.commanded_current(i),
                ]
                .map(|v| v.map(f64::to_bits))
            })
            .collect();
        CycleState {
            cycle,
            now_ps: bus.now().0,
            packets_sent: bus.packets_sent(),
            boards,
            joints,
            robot: format!("{:?} {:?}", r.state(), r.io_stats()),
        }
    }
}

/// What one run holds after a cycle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CycleState {
    /// Servo cycles run since the comparison began.
    pub cycle: u64,
    /// The bus clock, picoseconds.
    pub now_ps: u64,
    /// Packets put on the wire so far.
    pub packets_sent: u64,
    /// Each board's [`Firmware::state_digest`](firelink_board::qla::Firmware::state_digest)
    /// (`None`: not a board node).
    pub boards: Vec<Option<u64>>,
    /// Each joint's position, velocity, potentiometer, measured and
    /// commanded current as the host holds them (bit patterns).
    pub joints: Vec<[Option<u64>; 5]>,
    /// The robot's state and I/O error counts.
    pub robot: String,
}

impl CycleState {
    /// What differs between `self` and `other`, the first thing found
    /// (`None`: the same).
    pub fn difference(&self, other: &CycleState) -> Option<String> {
        if self.now_ps != other.now_ps {
            return Some(format!(
                "bus clock {} ps against {} ps",
                self.now_ps, other.now_ps
            ));
        }
        if self.packets_sent != other.packets_sent {
            return Some(format!(
                "{} packets sent against {}",
                self.packets_sent, other.packets_sent
            ));
        }
        if let Some(i) = first_mismatch(&self.boards, &other.boards) {
            return Some(format!("board node {i}: state differs"));
        }
        if let Some(i) = first_mismatch(&self.joints, &other.joints) {
            return Some(format!("joint {i}: what the host read differs"));
        }
        (self.robot != other.robot).then(|| format!("robot {} against {}", self.robot, other.robot))
    }
}

/// The first index where `a` and `b` differ (a length difference counts).
fn first_mismatch<T: PartialEq>(a: &[T], b: &[T]) -> Option<usize> {
    a.iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .or_else(|| (a.len() != b.len()).then(|| a.len().min(b.len())))
}

/// The first cycle at which two runs differ, and what differed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Divergence {
    /// Servo cycles run since the comparison began (0: right after
    /// bring-up).
    pub cycle: u64,
    /// What differed.
    pub what: String,
}

impl fmt::Display for Divergence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the runs differ after cycle {}: {}",
            self.cycle, self.what
        )
    }
}

/// The demo robot of `options` (a `sim` port) brought up as the demo
/// does it: configured, powered, homed, active, every joint moving.
///
/// # Errors
/// A port other than `sim`; the bring-up's.
pub fn demo_run(options: &DemoOptions) -> Result<ComparedRun, TestbedError> {
    if !matches!(options.port, PortSpec::Sim(_)) {
        return Err(TestbedError::Config(format!(
            "a cycle-by-cycle comparison needs a simulated port, not {}",
            options.port
        )));
    }
    let boards = ports::sim_boards(&options.port, &options.config, options.firmware);
    let (port, handles) = rig::sim_port(boards, false)?;
    let (mut robot, _) = open_robot(port, options, Pacing::Virtual, |_, _| {})?;
    bring_up(&mut robot, &options.config, &mut |_| {})?;
    Ok(ComparedRun {
        robot,
        boards: handles,
    })
}

/// Step `a` and `b` `cycles` servo cycles in lockstep, running
/// `before_a` / `before_b` on each before every cycle (with the cycle
/// number, from 1), and compare them right away and after every cycle.
/// Returns the first divergence, or `None` when every cycle matched. A
/// cycle that fails on both sides alike (a fault) is compared like any
/// other; one that fails on one side only is a divergence.
pub fn compare_in_lockstep(
    a: &mut ComparedRun,
    b: &mut ComparedRun,
    cycles: u64,
    mut before_a: impl FnMut(&mut ComparedRun, u64),
    mut before_b: impl FnMut(&mut ComparedRun, u64),
) -> Option<Divergence> {
    let compare = |a: &ComparedRun, b: &ComparedRun, cycle: u64| {
        a.state(cycle)
            .difference(&b.state(cycle))
            .map(|what| Divergence { cycle, what })
    };
    if let Some(d) = compare(a, b, 0) {
        return Some(d);
    }
    for cycle in 1..=cycles {
        before_a(a, cycle);
        before_b(b, cycle);
        let ra = a.robot.step(Pacing::Virtual).map_err(|e| e.to_string());
        let rb = b.robot.step(Pacing::Virtual).map_err(|e| e.to_string());
        if ra != rb {
            return Some(Divergence {
                cycle,
                what: format!("cycle result {ra:?} against {rb:?}"),
            });
        }
        if let Some(d) = compare(a, b, cycle) {
            return Some(d);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::port_spec::PortSpec;
    use firelink_bus::time::SimTime;
    use firelink_bus::{Detail, TraceLevel};
    use firelink_control::config::presets;

    /// The demo robot: seed 000's dVRK on 8 boards (28 axes), 6 kHz.
    fn options(port: PortSpec) -> DemoOptions {
        DemoOptions {
            config: presets::dvrk_seed000(),
            port,
            ..DemoOptions::default()
        }
    }

    /// Two runs of the demo robot on the simulated bus, brought up alike.
    fn two_runs() -> (ComparedRun, ComparedRun) {
        let opts = options(PortSpec::SIM);
        let a = demo_run(&opts).expect("bring-up");
        let b = demo_run(&opts).expect("bring-up");
        (a, b)
    }

    #[test]
    fn the_same_options_give_the_same_state_every_cycle() {
        let (mut a, mut b) = two_runs();
        let found = compare_in_lockstep(&mut a, &mut b, 120, |_, _| {}, |_, _| {});
        assert_eq!(found, None);
        assert!(a.bus().now() > SimTime::ZERO);
    }

    #[test]
    fn a_board_disturbed_on_one_side_is_found_at_that_cycle() {
        let (mut a, mut b) = two_runs();
        // Board node 2's motor supply fails before cycle 40 on side b only.
        let disturb = |run: &mut ComparedRun, cycle: u64| {
            if cycle == 40 {
                let node = run.boards[2];
                let bus = run.bus_mut();
                let now = bus.now();
                if let Some(board) = bus.node_mut::<BoardNode>(node) {
                    board.firmware_mut().set_motor_supply(now, false);
                }
            }
        };
        let found = compare_in_lockstep(&mut a, &mut b, 80, |_, _| {}, disturb)
            .expect("the disturbance is seen");
        assert_eq!(found.cycle, 40, "{found}");
    }

    #[test]
    fn recording_every_event_on_every_other_cycle_changes_nothing() {
        let (mut a, mut b) = two_runs();
        // Side b records every packet, event and delivery on odd cycles
        // and nothing on even ones; side a records nothing.
        let toggle = |run: &mut ComparedRun, cycle: u64| {
            let level = if cycle % 2 == 1 {
                TraceLevel::Verbose
            } else {
                TraceLevel::Off
            };
            run.bus_mut().set_trace_level(level);
        };
        let found = compare_in_lockstep(&mut a, &mut b, 60, |_, _| {}, toggle);
        assert_eq!(found, None);
        assert!(!b.bus().trace().packets().is_empty(), "side b recorded");
        assert!(a.bus().trace().packets().is_empty(), "side a did not");
    }

    #[test]
    fn the_fast_level_gives_the_packet_levels_answer_every_cycle() {
        let (mut a, mut b) = two_runs();
        b.bus_mut().set_detail(Detail::Packet);
        let found = compare_in_lockstep(&mut a, &mut b, 120, |_, _| {}, |_, _| {});
        assert_eq!(found, None);
        let fast = a.bus().detail_report();
        let packet = b.bus().detail_report();
        // Each side ran its own level every cycle of the comparison (side
        // b's bring-up ran fast, before the packet level was chosen).
        assert!(fast.fast_cycles >= 120, "{fast}");
        assert_eq!(fast.packet_level_cycles, 0, "{fast}");
        assert_eq!(packet.packet_level_cycles, 120, "{packet}");
        assert_eq!(packet.packet_level_cycles_why.chosen, 120, "{packet}");
    }

    #[test]
    fn switching_the_level_every_other_cycle_changes_nothing() {
        let (mut a, mut b) = two_runs();
        let switch = |run: &mut ComparedRun, cycle: u64| {
            let level = if cycle % 2 == 1 {
                Detail::Packet
            } else {
                Detail::Fast
            };
            run.bus_mut().set_detail(level);
        };
        let found = compare_in_lockstep(&mut a, &mut b, 120, |_, _| {}, switch);
        assert_eq!(found, None);
        let r = b.bus().detail_report();
        assert!(r.fast_cycles >= 60 && r.packet_level_cycles >= 60, "{r}");
    }

    #[test]
    fn only_a_simulated_port_is_compared() {
        let opts = options(PortSpec::Emulate);
        assert!(matches!(demo_run(&opts), Err(TestbedError::Config(_))));
    }
}
