//! The fault soak: the 28-axis robot runs for a million servo cycles on the
//! simulated bus while one packet in a hundred is faulted, and every fault
//! is accounted for.
//!
//! Faults come from the bus's own injector (seeded, so a run is a pure
//! function of its settings): per packet of each kind the I/O cycle uses
//! (the query, each board's status broadcast, the hub read request, the
//! hub's response, the command broadcast) a drop, bit flips, a short or a
//! long delay, a duplicate or a truncation; and now and then a bus-level
//! fault: a bus reset, a babbling board, a board unplugged and plugged back.
//! The bus logs each fault it injects, naming the plan entry that fired.
//!
//! Each logged fault is then judged against what the host saw in the cycle
//! it hit (and the next one):
//! - **detected**: the host reported it, with the reason this fault must
//!   produce (a board missing its status broadcast is a miss of *that*
//!   board with a sequence reason; a lost hub read is a time-out; a damaged
//!   response is a bad packet; a bus reset is a bus reset);
//! - **harmless**: the host saw nothing and nothing went wrong: its data
//!   was fresh (sequence numbers and CRCs prove it) or, for a lost command,
//!   every board holds the host's command again one period later;
//! - **undetected**: anything else. A correct system has none.
//!
//! Two safety invariants are checked after every cycle, from the boards'
//! own state (not the host's belief):
//! - no board ever applies a current command the host did not send (a
//!   corrupted packet's command would show as a value nobody sent);
//! - once a board has acknowledged the fault path's "amplifiers off", its
//!   amplifiers stay off for every cycle the robot stays in Fault.
//!
//! After each fault the robot raises, the soak re-arms it as an operator
//! would (clear, configure, power, enable) and carries on, so the fault
//! paths run thousands of times.
//!
//! Private submodules: `report` (settings, fault kinds, outcomes and the
//! report, re-exported here), `request` (the soak and the watchdog proof
//! after it, as `firelink soak` asks for them: [`SoakRequest`]), `plan`
//! (the seeded fault plan), `ledger` (the running account and the safety
//! invariants) and `judgement` (one logged fault's verdict).

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::fault::{EvidenceKind, FaultId, FaultLog, FaultSource, PacketFault};
use firelink_bus::trace::PacketKind;
use firelink_bus::{
    Detail, DetailReport, FaultPlan, FaultRule, NodeHandle, PacketMatch, SimDuration, SimTime,
    TimedFault,
};
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, Sinusoid};
use firelink_control::{ServoPeriod, State};
use firelink_host::cycle_report::CycleReport;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::sim::SimPort;
use firelink_host::{HostError, MissReason, WatchdogSetting};
use firelink_wire::packet::Tcode;
use firelink_wire::qla::address::HUB_QUERY_OFFSET;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::TestbedError;
use crate::rig::board_configs;

mod judgement;
mod ledger;
mod plan;
mod report;
mod request;
mod text;

use judgement::*;
use ledger::*;
use plan::*;
pub use report::*;
pub use request::{SoakOutcome, SoakRequest, watchdog_allows};

/// Run the soak.
///
/// # Errors
/// The rig could not be built or the robot could not be brought up the
/// first time (before any fault is injected).
pub fn run(
    settings: &SoakSettings,
    mut progress: impl FnMut(u64, &SoakReport),
) -> Result<SoakReport, TestbedError> {
    let config = presets::dvrk_seed000();
    let RunningRobot {
        mut robot,
        boards,
        host,
    } = bring_up_robot(&config, settings)?;
    let mut soak = Soak::new(settings, boards.clone());
    // Packets on the bus per cycle, measured, against those a fault is
    // aimed at, so that the faulted share of all packets is the one asked.
    let (p0, c0) = (robot.io().port().bus().packets_sent(), robot.cycles());
    for _ in 0..100 {
        robot.step(Pacing::Virtual)?;
    }
    let per_cycle =
        (robot.io().port().bus().packets_sent() - p0) as f64 / (robot.cycles() - c0).max(1) as f64;
    let aimed = (4 + boards.len()) as f64;
    let scale = (per_cycle / aimed).max(1.0);
    let (plan, timed) = fault_plan(
        settings,
        scale,
        &boards,
        host,
        robot.io().port().bus().now(),
    );
    soak.entries = plan.1;
    soak.timed = timed;
    robot.io_mut().port_mut().bus_mut().set_fault_plan(plan.0);
    soak.remember_commands(&robot);

    let target = robot.cycles() + settings.cycles;
    let first_cycle = robot.cycles();
    let mut next_progress = first_cycle + 50_000;
    let mut next_adjust = first_cycle + 10_000;
    while robot.cycles() < target {
        // A signal (the process's stop request) ends the soak between
        // cycles; the robot is powered down as the I/O system is dropped.
        if let Some(reason) = robot.stop_request().reason() {
            return Err(TestbedError::Runner(
                firelink_control::runner::RunnerError::Stopped(reason),
            ));
        }
        if robot.state() == State::Active {
            let _ = robot.step(Pacing::Virtual);
            soak.observe(&robot);
            if robot.state() == State::Fault {
                soak.report.robot_faults += 1;
            }
        } else {
            soak.rearm(&mut robot, &config);
        }
        if robot.cycles() >= next_adjust {
            // Keep the faulted share of all packets at the one asked (re-arming
            // adds scans and register writes that no rule aims at).
            next_adjust += 10_000;
            let bus = robot.io_mut().port_mut().bus_mut();
            let faults = bus
                .fault_log()
                .records()
                .iter()
                .filter(|r| matches!(r.source, Some(FaultSource::Rule(_))))
                .count() as f64;
            let share = faults / bus.packets_sent().max(1) as f64;
            if share > 0.0 {
                bus.scale_fault_probabilities(
                    (settings.packet_fault_rate / share).clamp(0.8, 1.25),
                );
            }
        }
        if robot.cycles() >= next_progress {
            next_progress += 50_000;
            progress(robot.cycles() - first_cycle, &soak.report);
        }
    }
    // No new faults; let the last faults' cycles finish, then judge what
    // is left.
    robot
        .io_mut()
        .port_mut()
        .bus_mut()
        .scale_fault_probabilities(0.0);
    for _ in 0..6 {
        let _ = robot.step(Pacing::Virtual);
        soak.observe(&robot);
    }
    {
        let bus = robot.io().port().bus();
        let host = robot.io().port().host();
        soak.judge_all(u64::MAX, bus.fault_log(), host);
    }
    let bus = robot.io().port().bus();
    soak.report.cycles = robot.cycles() - first_cycle;
    soak.report.virtual_s = bus.now().as_micros_f64() / 1e6;
    soak.report.packets = bus.packets_sent();
    let packet_faults = bus
        .fault_log()
        .records()
        .iter()
        .filter(|r| matches!(r.source, Some(FaultSource::Rule(_))))
        .count();
    soak.report.packet_fault_share = packet_faults as f64 / (soak.report.packets.max(1)) as f64;
    soak.report.detail = bus.detail_report();
    Ok(soak.report)
}

/// A robot moving on the simulated bus, and where its nodes are.
pub struct RunningRobot {
    /// The robot.
    pub robot: Robot<IoSystem<SimPort>>,
    /// The boards' nodes, by board ID.
    pub boards: Vec<NodeHandle>,
    /// The PC's node.
    pub host: NodeHandle,
}

/// The dVRK of seed 000 on its 8 boards, configured, powered, homed and
/// moving, with no fault injected yet.
///
/// # Errors
/// The boards were not found or the robot did not come up.
pub fn bring_up_robot(
    config: &IoConfig,
    settings: &SoakSettings,
) -> Result<RunningRobot, TestbedError> {
    let boards: Vec<BoardConfig> = board_configs(config, Profile::Rev8, 8)
        .into_iter()
        .map(|b| {
            let seed = b.seed;
            b.with_seed(seed ^ settings.seed.rotate_left(17))
        })
        .collect();
    let mut rig = BoardRig::daisy_chain(
        boards,
        &RigOptions {
            seed: settings.seed,
            ..RigOptions::default()
        },
    );
    rig.bus.set_detail(settings.detail);
    let (handles, host) = (rig.boards.clone(), rig.host);
    let port = SimPort::new(rig.bus, rig.host);
    let (io, _) = IoSystem::open(
        port,
        IoOptions {
            protocol: Some(Protocol::Broadcast),
            ..IoOptions::default()
        },
    )?;
    let robot_settings = RobotSettings {
        period: settings.period,
        watchdog: WatchdogSetting::default(),
        max_samples: 1,
        ..RobotSettings::default()
    };
    let mut robot = Robot::new(io, config, robot_settings)?;
    robot.configure()?;
    robot.power_on()?;
    robot.home()?;
    robot.activate()?;
    move_joints(&mut robot);
    Ok(RunningRobot {
        robot,
        boards: handles,
        host,
    })
}

/// Small sinusoids on every joint around where it stands.
fn move_joints(robot: &mut Robot<IoSystem<SimPort>>) {
    for i in 0..robot.joint_count() {
        let Some(p) = robot.position(i) else {
            continue;
        };
        let f = 0.3 + 0.05 * (i % 5) as f64;
        if let Ok(s) = Sinusoid::new(0.01, f, 0.0, p, 0.2) {
            let _ = robot.set_motion(i, Motion::Sinusoid(s));
        }
    }
}
