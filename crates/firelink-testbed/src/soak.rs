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

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use firelink_board::config::{BoardConfig, Profile};
use firelink_board::node::BoardNode;
use firelink_board::rig::{BoardRig, RigOptions};
use firelink_bus::fault::{EvidenceKind, FaultId, FaultLog, FaultSource, PacketFault};
use firelink_bus::trace::PacketKind;
use firelink_bus::{
    FaultPlan, FaultRule, NodeHandle, PacketMatch, SimDuration, SimTime, TimedFault,
};
use firelink_control::State;
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::{Pacing, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, Sinusoid};
use firelink_host::io::{CycleReport, IoOptions, IoSystem};
use firelink_host::scan::Protocol;
use firelink_host::sim::SimPort;
use firelink_host::{HostError, MissReason, WatchdogSetting};
use firelink_wire::board::address::HUB_QUERY_OFFSET;
use firelink_wire::packet::Tcode;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::TestbedError;
use crate::rig::board_configs;

/// What to run.
#[derive(Debug, Clone)]
pub struct SoakSettings {
    /// Servo cycles to run (re-arming included).
    pub cycles: u64,
    /// Seed of every random choice (faults, bus, plants).
    pub seed: u64,
    /// Share of all packets on the bus to fault. Faults go to the packets
    /// of the I/O cycle (12 a cycle with 8 boards: query, status
    /// broadcasts, hub read and response, command), each with the chance
    /// that makes this share of everything on the bus (acks included).
    pub packet_fault_rate: f64,
    /// On average one bus-level fault (reset, babble, unplug) per this
    /// many cycles.
    pub bus_fault_every: u64,
    /// Control rate, Hz.
    pub rate_hz: f64,
}

impl Default for SoakSettings {
    fn default() -> Self {
        SoakSettings {
            cycles: 1_000_000,
            seed: 1,
            packet_fault_rate: 0.01,
            bus_fault_every: 2_000,
            rate_hz: 6_000.0,
        }
    }
}

/// Which packets a fault hits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    /// The host's broadcast query.
    Query,
    /// A board's status broadcast.
    Status,
    /// The host's hub read request.
    HubRequest,
    /// The hub board's response.
    HubResponse,
    /// The host's command broadcast.
    Command,
    /// The bus as a whole (resets, babble, cables).
    Bus,
}

/// What a fault does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// The packet is lost.
    Drop,
    /// Two bits flipped (CRCs left as they were).
    BitFlip,
    /// Held back 3 us.
    ShortDelay,
    /// Held back 60 us.
    LongDelay,
    /// Sent twice.
    Duplicate,
    /// Cut to its first two quadlets.
    Truncate,
    /// A bus reset.
    BusReset,
    /// A board sends garbage back to back for up to 300 us.
    Babble,
    /// A board's cable is unplugged and plugged back 1 to 5 ms later.
    Unplug,
}

impl Kind {
    const PACKET: [Kind; 6] = [
        Kind::Drop,
        Kind::BitFlip,
        Kind::ShortDelay,
        Kind::LongDelay,
        Kind::Duplicate,
        Kind::Truncate,
    ];

    fn name(self) -> &'static str {
        match self {
            Kind::Drop => "drop",
            Kind::BitFlip => "bit_flip",
            Kind::ShortDelay => "short_delay",
            Kind::LongDelay => "long_delay",
            Kind::Duplicate => "duplicate",
            Kind::Truncate => "truncate",
            Kind::BusReset => "bus_reset",
            Kind::Babble => "babble",
            Kind::Unplug => "unplug",
        }
    }

    fn fault(self) -> Option<PacketFault> {
        Some(match self {
            Kind::Drop => PacketFault::Drop,
            Kind::BitFlip => PacketFault::FlipBits { count: 2 },
            Kind::ShortDelay => PacketFault::Delay(SimDuration::from_micros(3)),
            Kind::LongDelay => PacketFault::Delay(SimDuration::from_micros(60)),
            Kind::Duplicate => PacketFault::Duplicate,
            Kind::Truncate => PacketFault::Truncate { quadlets: 2 },
            _ => return None,
        })
    }
}

/// How the faults of one kind ended.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Outcomes {
    /// Injected (the bus logged them).
    pub injected: u64,
    /// Reported by the host with the right reason.
    pub detected: u64,
    /// Shown to have done no harm.
    pub harmless: u64,
    /// Neither.
    pub undetected: u64,
}

impl Outcomes {
    fn add(&mut self, verdict: Verdict) {
        self.injected += 1;
        match verdict {
            Verdict::Detected => self.detected += 1,
            Verdict::Harmless(_) => self.harmless += 1,
            Verdict::Undetected => self.undetected += 1,
        }
    }
}

/// The soak's result (`firelink soak --json`).
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    /// Servo cycles run.
    pub cycles: u64,
    /// The seed.
    pub seed: u64,
    /// Virtual time run, seconds.
    pub virtual_s: f64,
    /// Packets on the bus.
    pub packets: u64,
    /// Faults injected.
    pub injected: u64,
    /// Share of packets faulted (packet faults over packets).
    pub packet_fault_share: f64,
    /// Faults the host reported with the right reason.
    pub detected: u64,
    /// Faults shown harmless.
    pub harmless: u64,
    /// Of those: the data the host used was proven fresh.
    pub harmless_fresh: u64,
    /// Of those: the host rejected the whole cycle for another fault.
    pub harmless_masked: u64,
    /// Of those: a lost or late command, held by every board a period
    /// later.
    pub harmless_command_held: u64,
    /// Of those: a spare hub response (answering a duplicated request)
    /// while the host's own hub read completed.
    pub harmless_spare: u64,
    /// Faults neither detected nor harmless (must be 0).
    pub undetected: u64,
    /// Commands a board applied that the host never sent (must be 0).
    pub bad_commands_applied: u64,
    /// Cycles in which a board that had acknowledged "amplifiers off" had
    /// one on while the robot was in Fault (must be 0).
    pub amplifier_on_after_off: u64,
    /// Cycles in Fault before every board acknowledged "amplifiers off"
    /// (the broadcast command and the watchdog cover them; for the record).
    pub disable_pending_cycles: u64,
    /// Faults the robot raised (each one re-armed).
    pub robot_faults: u64,
    /// Times the robot was re-armed (clear, configure, power, enable).
    pub rearms: u64,
    /// Faults by kind.
    pub by_kind: BTreeMap<String, Outcomes>,
    /// Faults by kind and target (`kind/target`).
    pub by_fault: BTreeMap<String, Outcomes>,
    /// The first few undetected faults, described.
    pub undetected_examples: Vec<String>,
}

impl SoakReport {
    /// Whether every fault was accounted for and both safety invariants
    /// held.
    pub fn passed(&self) -> bool {
        self.undetected == 0 && self.bad_commands_applied == 0 && self.amplifier_on_after_off == 0
    }
}

/// One plan entry: what it targets and what it does.
#[derive(Debug, Clone, Copy)]
struct Entry {
    target: Target,
    kind: Kind,
    /// The board concerned (status broadcasts, babble, unplug).
    board: Option<u8>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    Detected,
    Harmless(Harmless),
    Undetected,
}

/// How a fault was shown harmless.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Harmless {
    /// Every board's data the host used in the cycles it could touch was
    /// proven this cycle's (sequence numbers, CRCs, board IDs, sizes).
    Fresh,
    /// The host rejected the whole cycle for another fault it detected:
    /// nothing of that cycle was used.
    Masked,
    /// A command lost or late: every board held the host's command again
    /// one or two periods later (broadcasts are never acknowledged).
    CommandHeld,
    /// A hub response the host did not need: its hub read completed with
    /// another, valid response (the faulted one answered a duplicated
    /// request).
    Spare,
}

/// A logged fault waiting for the cycles that show its effect.
#[derive(Debug, Clone)]
struct Pending {
    entry: Entry,
    time: Duration,
    what: String,
    /// Its record in the bus's fault log.
    id: FaultId,
}

/// What one cycle showed, kept for judging faults.
#[derive(Debug, Clone, Copy)]
struct Seen {
    report: CycleReport,
    /// Every board held the host's latest command (or, still in flight,
    /// the one before) after this cycle.
    commands_converged: bool,
    /// The bus generation after this cycle.
    generation: u32,
    /// Bus resets the host has noticed so far (in cycles or between them).
    resets_noticed: u64,
}

/// Commands sent to one axis recently (the DAC codes), newest last.
const COMMAND_MEMORY: usize = 6;

struct Soak {
    entries: Vec<Entry>,
    timed: Vec<Entry>,
    boards: Vec<NodeHandle>,
    seen_faults: usize,
    pending: Vec<Pending>,
    /// The last faults logged, judged or not (to name a fault's company).
    recent: VecDeque<Pending>,
    cycles: VecDeque<Seen>,
    sent: Vec<[[u16; COMMAND_MEMORY]; 4]>,
    report: SoakReport,
}

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
    let rig = BoardRig::daisy_chain(
        boards,
        &RigOptions {
            seed: settings.seed,
            ..RigOptions::default()
        },
    );
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
        rate_hz: settings.rate_hz,
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

type Plan = (FaultPlan, Vec<Entry>);

/// The fault plan: packet rules for every target and kind, each with its
/// share of the fault rate, and the bus-level faults at seeded instants.
fn fault_plan(
    settings: &SoakSettings,
    scale: f64,
    boards: &[NodeHandle],
    host: NodeHandle,
    start: SimTime,
) -> (Plan, Vec<Entry>) {
    let p = (settings.packet_fault_rate * scale).min(1.0) / Kind::PACKET.len() as f64;
    let mut plan = FaultPlan::new();
    let mut entries = Vec::new();
    let mut add = |matcher: PacketMatch, target: Target, board: Option<u8>| {
        for kind in Kind::PACKET {
            if let Some(fault) = kind.fault() {
                plan.rules
                    .push(FaultRule::random(matcher.clone(), fault, p));
                entries.push(Entry {
                    target,
                    kind,
                    board,
                });
            }
        }
    };
    let from_pc = PacketMatch::any().from(host);
    add(
        from_pc
            .clone()
            .tcode(Tcode::WriteQuadletRequest)
            .offset(HUB_QUERY_OFFSET as u16),
        Target::Query,
        None,
    );
    for (id, &b) in boards.iter().enumerate() {
        add(
            PacketMatch::any()
                .from(b)
                .tcode(Tcode::WriteBlockRequest)
                .to_phy(63),
            Target::Status,
            Some(id as u8),
        );
    }
    add(
        from_pc.clone().tcode(Tcode::ReadBlockRequest),
        Target::HubRequest,
        None,
    );
    add(
        PacketMatch::any()
            .tcode(Tcode::ReadBlockResponse)
            .kind(PacketKind::ConcatResponse),
        Target::HubResponse,
        None,
    );
    add(
        from_pc.tcode(Tcode::WriteBlockRequest),
        Target::Command,
        None,
    );

    // Bus-level faults at seeded instants, in order of time.
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed ^ 0x50A4_B05F);
    let period = SimDuration::from_micros_f64(1e6 / settings.rate_hz);
    let span = period * settings.cycles;
    let every = period * settings.bus_fault_every.max(1);
    let mut timed = Vec::new();
    let mut t = start + SimDuration(every.0 / 2);
    while t < start + span {
        let board = rng.random_range(0..boards.len()) as u8;
        let node = boards.get(usize::from(board)).copied().unwrap_or(host);
        let (kind, fault) = match rng.random_range(0..3u8) {
            0 => (Kind::BusReset, TimedFault::BusReset),
            1 => (
                Kind::Babble,
                TimedFault::Babble {
                    node,
                    duration: SimDuration::from_micros(rng.random_range(20..=300)),
                    packet_len: 64,
                },
            ),
            _ => (
                Kind::Unplug,
                TimedFault::Disconnect {
                    node,
                    reconnect_after: Some(SimDuration::from_micros(
                        rng.random_range(1_000..=5_000),
                    )),
                },
            ),
        };
        plan.timed.push((t, fault));
        timed.push(Entry {
            target: Target::Bus,
            kind,
            board: Some(board),
        });
        let jitter = rng.random_range(0.5..1.5);
        t += SimDuration::from_micros_f64(every.as_micros_f64() * jitter);
    }
    ((plan, entries), timed)
}

impl Soak {
    fn new(settings: &SoakSettings, boards: Vec<NodeHandle>) -> Soak {
        let n = boards.len();
        Soak {
            entries: Vec::new(),
            timed: Vec::new(),
            boards,
            seen_faults: 0,
            pending: Vec::new(),
            recent: VecDeque::with_capacity(64),
            cycles: VecDeque::with_capacity(64),
            sent: vec![[[0u16; COMMAND_MEMORY]; 4]; n],
            report: SoakReport {
                cycles: 0,
                seed: settings.seed,
                virtual_s: 0.0,
                packets: 0,
                injected: 0,
                packet_fault_share: 0.0,
                detected: 0,
                harmless: 0,
                harmless_fresh: 0,
                harmless_masked: 0,
                harmless_command_held: 0,
                harmless_spare: 0,
                undetected: 0,
                bad_commands_applied: 0,
                amplifier_on_after_off: 0,
                disable_pending_cycles: 0,
                robot_faults: 0,
                rearms: 0,
                by_kind: BTreeMap::new(),
                by_fault: BTreeMap::new(),
                undetected_examples: Vec::new(),
            },
        }
    }

    /// Bring a robot that is not Active back: settle in Fault a few cycles
    /// (outputs off), clear, configure, power, enable, move.
    fn rearm(&mut self, robot: &mut Robot<IoSystem<SimPort>>, config: &IoConfig) {
        // A few cycles in the current state first (the boards see the safe
        // outputs; a reconnecting board has time to come back).
        for _ in 0..6 {
            let _ = robot.step(Pacing::Virtual);
            self.observe(robot);
        }
        if robot.state() == State::Fault {
            let _ = robot.clear_fault();
        }
        let _ = robot.io_mut().recover();
        let _ = config;
        if robot.state() == State::Unconfigured && robot.configure().is_err() {
            return;
        }
        if robot.state() == State::Configured {
            let mut each = |r: &Robot<IoSystem<SimPort>>| self.observe(r);
            if robot.power_on_observed(&mut each).is_err() {
                return;
            }
            if robot.activate().is_ok() {
                move_joints(robot);
                self.report.rearms += 1;
            }
        }
    }

    /// After every cycle: the safety invariants from the boards' own
    /// state, the cycle's report, and the faults the bus logged.
    fn observe(&mut self, robot: &Robot<IoSystem<SimPort>>) {
        let Some(report) = robot.last_report().copied() else {
            return;
        };
        let bus = robot.io().port().bus();
        let in_fault = robot.state() == State::Fault;
        let acknowledged = robot.disable_acknowledged();
        let mut converged = true;
        let mut pending_disable = false;
        for (slot, &handle) in self.boards.iter().enumerate() {
            let Some(fw) = bus.node::<BoardNode>(handle).map(BoardNode::firmware) else {
                continue;
            };
            let id = fw.board_id();
            let host = robot.io().board(id).map(|b| b.output());
            let Some(sent) = self.sent.get_mut(slot) else {
                continue;
            };
            for axis in 0..4usize {
                let applied = fw.axis_command(axis).unwrap_or(0);
                if let (Some(out), Some(memory)) = (host, sent.get_mut(axis)) {
                    let now = out.dac.get(axis).map_or(0, |d| d.command());
                    if memory.last() != Some(&now) {
                        memory.rotate_left(1);
                        if let Some(last) = memory.last_mut() {
                            *last = now;
                        }
                    }
                    if !memory.contains(&applied) {
                        self.report.bad_commands_applied += 1;
                    }
                    // The latest command, or the one before when the
                    // latest broadcast is still on its way (a cycle that
                    // overran its period is observed before its command
                    // has arrived).
                    let previous = memory.get(COMMAND_MEMORY - 2).copied();
                    converged &= applied == now || Some(applied) == previous;
                }
                if in_fault && fw.amplifier_on(axis) {
                    if acknowledged & (1 << id) != 0 {
                        self.report.amplifier_on_after_off += 1;
                    } else {
                        pending_disable = true;
                    }
                }
            }
        }
        self.report.disable_pending_cycles += u64::from(pending_disable);
        if self.cycles.len() == self.cycles.capacity() {
            self.cycles.pop_front();
        }
        self.cycles.push_back(Seen {
            report,
            commands_converged: converged,
            generation: bus.generation(),
            resets_noticed: robot.io().stats().bus_resets,
        });
        // New faults from the bus's log.
        let records = bus.fault_log().records();
        for r in records.iter().skip(self.seen_faults) {
            let entry = match r.source {
                Some(FaultSource::Rule(i)) => self.entries.get(i).copied(),
                Some(FaultSource::Timed(i)) => self.timed.get(i).copied(),
                None => None,
            };
            if let Some(entry) = entry {
                let p = Pending {
                    entry,
                    time: Duration::from_nanos(r.time.0 / 1000),
                    what: r.what.clone(),
                    id: r.id,
                };
                if self.recent.len() == self.recent.capacity() {
                    self.recent.pop_front();
                }
                self.recent.push_back(p.clone());
                self.pending.push(p);
            }
        }
        self.seen_faults = records.len();
        let log = bus.fault_log();
        let host = robot.io().port().host();
        self.judge_all(report.cycle, log, host);
    }

    /// Set the command memory to what the host sends now.
    fn remember_commands(&mut self, robot: &Robot<IoSystem<SimPort>>) {
        let bus = robot.io().port().bus();
        for (slot, &handle) in self.boards.iter().enumerate() {
            let Some(fw) = bus.node::<BoardNode>(handle).map(BoardNode::firmware) else {
                continue;
            };
            let out = robot.io().board(fw.board_id()).map(|b| b.output());
            if let (Some(out), Some(sent)) = (out, self.sent.get_mut(slot)) {
                for (axis, memory) in sent.iter_mut().enumerate() {
                    let applied = fw.axis_command(axis).unwrap_or(0);
                    let now = out.dac.get(axis).map_or(0, |d| d.command());
                    *memory = [applied; COMMAND_MEMORY];
                    if let Some(last) = memory.last_mut() {
                        *last = now;
                    }
                }
            }
        }
    }

    /// Judge the pending faults whose effect cycles are over (all of them
    /// with `u64::MAX`).
    fn judge_all(&mut self, last_cycle: u64, log: &FaultLog, host: NodeHandle) {
        let mut keep = Vec::new();
        for p in std::mem::take(&mut self.pending) {
            // The cycle the fault hit: the last one started at or before it.
            let hit = self
                .cycles
                .iter()
                .rev()
                .find(|s| s.report.started <= p.time)
                .map(|s| s.report.cycle);
            let Some(hit) = hit else {
                // Before any cycle we still remember: judge against the
                // oldest we have.
                let oldest = self.cycles.front().map_or(0, |s| s.report.cycle);
                self.judge(&p, oldest, host_rejected(log, p.id, host));
                continue;
            };
            // Wait for the cycles after it (a lost command shows one period
            // later; a bus-level fault lasts a while).
            let span = match p.entry.kind {
                Kind::Unplug | Kind::Babble => 4,
                _ => 2,
            };
            if last_cycle != u64::MAX && last_cycle < hit + span {
                keep.push(p);
                continue;
            }
            self.judge(&p, hit, host_rejected(log, p.id, host));
        }
        self.pending = keep;
    }

    fn judge(&mut self, p: &Pending, hit: u64, rejected_by_host: bool) {
        let others: Vec<String> = self
            .recent
            .iter()
            .filter(|o| o.time != p.time)
            .filter(|o| {
                self.cycles
                    .iter()
                    .rev()
                    .find(|s| s.report.started <= o.time)
                    .is_some_and(|s| s.report.cycle == hit)
            })
            .map(|o| format!("{} on {:?}", o.what, o.entry.target))
            .collect();
        let window: Vec<Seen> = self
            .cycles
            .iter()
            .filter(|s| s.report.cycle >= hit && s.report.cycle <= hit + 3)
            .copied()
            .collect();
        // Resets the host had noticed before the hit cycle.
        let resets_before = self
            .cycles
            .iter()
            .rev()
            .find(|s| s.report.cycle < hit)
            .or(window.first())
            .map_or(0, |s| s.resets_noticed);
        let verdict = if rejected_by_host && p.entry.target == Target::HubResponse {
            // A response the host's link itself refused (its CRC failed,
            // or it answered nothing the host had asked, e.g. the second
            // answer to a duplicated request): the host never used it.
            Verdict::Detected
        } else {
            verdict(&p.entry, &window, resets_before)
        };
        let key = p.entry.kind.name().to_string();
        self.report
            .by_kind
            .entry(key.clone())
            .or_default()
            .add(verdict);
        let target = match p.entry.target {
            Target::Query => "query",
            Target::Status => "status",
            Target::HubRequest => "hub_request",
            Target::HubResponse => "hub_response",
            Target::Command => "command",
            Target::Bus => "bus",
        };
        self.report
            .by_fault
            .entry(format!("{key}/{target}"))
            .or_default()
            .add(verdict);
        self.report.injected += 1;
        match verdict {
            Verdict::Detected => self.report.detected += 1,
            Verdict::Harmless(how) => {
                self.report.harmless += 1;
                match how {
                    Harmless::Fresh => self.report.harmless_fresh += 1,
                    Harmless::Masked => self.report.harmless_masked += 1,
                    Harmless::CommandHeld => self.report.harmless_command_held += 1,
                    Harmless::Spare => self.report.harmless_spare += 1,
                }
            }
            Verdict::Undetected => {
                self.report.undetected += 1;
                if self.report.undetected_examples.len() < 10 {
                    let reports: Vec<String> = window
                        .iter()
                        .map(|s| {
                            format!(
                                "cycle {}: missed {:#06x} {:?} error {:?}{}, bus generation {}",
                                s.report.cycle,
                                s.report.missed,
                                s.report.reasons.iter().flatten().next(),
                                s.report.error,
                                if s.report.bus_reset {
                                    ", bus reset"
                                } else {
                                    ""
                                },
                                s.generation
                            )
                        })
                        .collect();
                    self.report.undetected_examples.push(format!(
                        "{} on {target} (board {:?}) at {:?} in cycle {hit}: {}; other faults then: {:?}",
                        p.what,
                        p.entry.board,
                        p.time,
                        if reports.is_empty() {
                            "no cycle seen".to_string()
                        } else {
                            reports.join("; ")
                        },
                        others
                    ));
                }
            }
        }
    }
}

/// Whether the PC's link refused the packet this fault damaged (the bus
/// records what noticed each fault).
fn host_rejected(log: &FaultLog, id: FaultId, host: NodeHandle) -> bool {
    log.get(id).is_some_and(|r| {
        r.evidence
            .iter()
            .any(|e| e.node == host.0 && matches!(e.kind, EvidenceKind::Report(_)))
    })
}

/// The board's block in the hub was not this cycle's: an old sequence
/// number, none at all, a corrupt query flagged, or (the hub packs blocks
/// in arrival order) another board's block or the wrong size in its place.
fn stale(reason: Option<MissReason>) -> bool {
    matches!(
        reason,
        Some(
            MissReason::Sequence { .. }
                | MissReason::NotUpdated
                | MissReason::CorruptQuery
                | MissReason::WrongBoardId { .. }
                | MissReason::BlockSize { .. }
        )
    )
}

fn missed(report: &CycleReport, board: u8) -> Option<MissReason> {
    if report.missed & (1 << board) == 0 {
        return None;
    }
    report.reasons.get(usize::from(board)).copied().flatten()
}

/// Whether `report` shows what a fault of `entry` must produce: the
/// host's own reason for the cycle.
fn shows(entry: &Entry, report: &CycleReport) -> bool {
    // Some board's block was not this cycle's (sequence numbers).
    let any_stale = report.reasons.iter().any(|r| stale(*r));
    let timeout = matches!(report.error, Some(HostError::Timeout { .. }));
    let bad_packet = matches!(report.error, Some(HostError::Wire(_)));
    let nack = matches!(report.error, Some(HostError::Ack { .. }));
    let reset = report.bus_reset;
    // A late or repeated packet shifts the cycle's timing: what the host
    // must then see is stale data (or a time-out), whichever packet it was.
    let timing = matches!(
        entry.kind,
        Kind::ShortDelay | Kind::LongDelay | Kind::Duplicate
    ) && (any_stale || timeout);
    timing
        || match entry.target {
            // No query, no status broadcasts: every block is stale.
            Target::Query => any_stale,
            // A board's broadcast lost: its block, and in the Rev 7/8 chain
            // those of the boards after it, are stale in the hub.
            Target::Status => entry
                .board
                .is_some_and(|b| (b..16).any(|j| stale(missed(report, j)))),
            Target::HubRequest => timeout || nack,
            Target::HubResponse => timeout || bad_packet,
            Target::Command => false,
            Target::Bus => match entry.kind {
                Kind::BusReset => reset,
                Kind::Unplug => reset || report.missed != 0,
                _ => report.missed != 0 || report.error.is_some(),
            },
        }
}

fn verdict(entry: &Entry, window: &[Seen], resets_before: u64) -> Verdict {
    // A bus reset the host noticed between cycles (a register write outside
    // the cycle got it first) was detected all the same: it rescanned.
    if matches!(entry.kind, Kind::BusReset | Kind::Unplug)
        && window
            .iter()
            .take(3)
            .any(|s| s.resets_noticed > resets_before)
    {
        return Verdict::Detected;
    }
    if entry.target == Target::Command {
        // Invisible to the host by design (broadcasts are not
        // acknowledged): harmless if every board holds the host's command
        // again within the next two periods.
        return if window.iter().skip(1).take(2).any(|s| s.commands_converged) {
            Verdict::Harmless(Harmless::CommandHeld)
        } else {
            Verdict::Undetected
        };
    }
    // The cycle it hit, and for a late or repeated packet the next one
    // too (it can spill over); a loss or damage touches only its own.
    let spill = matches!(
        entry.kind,
        Kind::ShortDelay
            | Kind::LongDelay
            | Kind::Duplicate
            | Kind::Babble
            | Kind::Unplug
            | Kind::BusReset
    );
    let first_two = || window.iter().take(if spill { 2 } else { 1 });
    if first_two().any(|s| shows(entry, &s.report)) {
        return Verdict::Detected;
    }
    // A damaged or lost hub response the host needed fails its hub read
    // (a time-out or a bad packet); the read completing means the host got
    // another, valid one: the faulted packet was a spare.
    if entry.target == Target::HubResponse
        && window.first().is_some_and(|s| s.report.error.is_none())
    {
        return Verdict::Harmless(Harmless::Spare);
    }
    // Otherwise each of those cycles must have been either clean (every
    // block the host used proven this cycle's) or thrown away whole for
    // another fault the host detected (a failed hub read, a bus reset).
    let mut masked = false;
    for s in first_two() {
        if s.report.all_ok() {
            continue;
        }
        if rejected_whole(&s.report) {
            masked = true;
            continue;
        }
        return Verdict::Undetected;
    }
    Verdict::Harmless(if masked {
        Harmless::Masked
    } else {
        Harmless::Fresh
    })
}

/// The host discarded every board's data of this cycle, for a reason it
/// reported (no block of it was used).
fn rejected_whole(r: &CycleReport) -> bool {
    let mut reasons = r.reasons.iter().flatten().peekable();
    let any = reasons.peek().is_some();
    r.error.is_some() && any && reasons.all(|m| *m == MissReason::Transaction)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_packet_kind_has_a_fault_and_a_name() {
        for k in Kind::PACKET {
            assert!(k.fault().is_some(), "{k:?}");
            assert!(!k.name().is_empty());
        }
        assert!(Kind::BusReset.fault().is_none());
    }
}
