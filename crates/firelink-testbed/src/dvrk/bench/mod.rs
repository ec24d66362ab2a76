//! The I/O benchmark of seed 000's Fig. 11: I/O time per cycle against the
//! number of boards, for each protocol, on the simulated bus with the
//! seed-000 PC model and measured for real over loopback UDP against an
//! in-process bridge emulator; the maximum control rate each point allows
//! and seed 002's time budget at a chosen period. Counts above 16 (the
//! board-ID space of one bus) come from a cost model fitted to the largest
//! measured count, and say so.
//!
//! Each UDP point is measured for every wait mode asked for (the host
//! blocking in the kernel or spinning on its socket) and beside its
//! *floor*: the same requests, datagram sizes and host waits against a
//! responder that answers at once, interleaved in blocks of cycles in the
//! same run (see [`udp`]); with the CPU time per cycle of the host's
//! thread and of the emulator's server thread. The UDP points can also
//! run against any bridge ([`BenchOptions::udp_target`]).
//!
//! Each `fw` point (FirewirePort through the preloaded /dev/fw* twin and
//! an in-process twin server) is measured beside its floor: as many bare
//! request -> completion-event round trips over the same kind of
//! `SOCK_SEQPACKET` sockets against a responder that models nothing (see
//! [`fw`]); its host CPU per cycle is set against the same point's
//! simulation cost on `sim` when both were measured in the run.
//!
//! The `eth` points ([`eth`]) measure the broadcast cycle of FPGA V3
//! boards at Rev 9 on the Ethernet-only network (in process, or at an
//! address given), beside the bridge with FPGA V2 boards at Rev 8 and at
//! Rev 9 at the same board counts, each with its floor, the host waiting
//! as the Rev 9 host does on each, and the firmware's stated timing of
//! the chain ([`EthComparison`](eth::EthComparison)).
//!
//! Beside the I/O, the host's own CPU per 28-axis dVRK cycle (parse,
//! PID, build commands) is measured over a recorded cycle with no I/O
//! ([`host_cpu`]).
//!
//! The library behind `firelink bench` (whose options are a
//! [`BenchRequest`]) and the Python package's `run_bench`;
//! [`BenchReport`] serialises to `firelink bench --json`.

pub mod eth;
pub mod fw;
pub mod host_cpu;
mod request;
mod server_thread;
pub mod udp;

pub use request::{BenchRequest, bridge_address};

use std::fmt;
use std::net::SocketAddr;
use std::time::Duration;

use serde::Serialize;

use firelink_board::qla::config::Profile;
use firelink_bus::{Detail, DetailReport};
use firelink_control::budget::CycleBudget;
use firelink_control::config::presets;
use firelink_control::runner::{Pacing, Percentiles, Robot, RobotSettings};
use firelink_host::Port;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::WaitMode;

use crate::TestbedError;
use crate::rig;

/// Where a benchmark point runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum BenchTransport {
    /// The simulated bus with the seed-000 PC model (virtual time).
    Sim,
    /// UDP to a bridge: an in-process emulator on loopback, or
    /// [`BenchOptions::udp_target`] (wall clock).
    #[cfg_attr(
        feature = "clap",
        value(help = "Loopback UDP to an in-process bridge emulator (wall clock)")
    )]
    Udp,
    /// `FirewirePort` through the /dev/fw* twin (wall clock; see [`fw`]).
    #[cfg_attr(
        feature = "clap",
        value(help = "FirewirePort through the /dev/fw* twin, served in-process (wall clock)")
    )]
    Fw,
    /// The Ethernet-only network of FPGA V3 boards at Rev 9 (wall clock;
    /// see [`eth`]): an in-process network on loopback, measured beside
    /// the bridge with FPGA V2 boards at Rev 8 and at Rev 9 and the
    /// firmware's stated timing ([`eth::EthComparison`]); or
    /// [`BenchOptions::udp_target`] when that is such a network.
    #[cfg_attr(
        feature = "clap",
        value(
            help = "The Ethernet-only network of FPGA V3 boards at Rev 9 (in process on \
                      loopback, or `--port udp:HOST` to one), its broadcast cycle beside the \
                      bridge with FPGA V2 boards at Rev 8 and Rev 9 and the firmware's stated \
                      timing (wall clock)"
        )
    )]
    Eth,
}

impl BenchTransport {
    /// The name in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BenchTransport::Sim => "sim",
            BenchTransport::Udp => "udp",
            BenchTransport::Fw => "fw",
            BenchTransport::Eth => "eth",
        }
    }

    /// The names [`BenchTransport::from_name`] takes, for messages.
    pub const NAMES: &'static str = "sim, udp, fw or eth";

    /// Parse `sim`, `udp`, `fw` or `eth`.
    pub fn from_name(name: &str) -> Option<BenchTransport> {
        match name {
            "sim" => Some(BenchTransport::Sim),
            "udp" => Some(BenchTransport::Udp),
            "fw" => Some(BenchTransport::Fw),
            "eth" => Some(BenchTransport::Eth),
            _ => None,
        }
    }
}

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchOptions {
    /// Transports, in order.
    pub transports: Vec<BenchTransport>,
    /// Board counts, 1..=62; counts above 16 are modelled (see
    /// [`check_board_counts`]).
    pub boards: Vec<usize>,
    /// Protocols, in order.
    pub protocols: Vec<Protocol>,
    /// Measured cycles per point (after 20 warm-up cycles), at least 1.
    pub cycles: u64,
    /// Firmware of the emulated boards.
    pub firmware: Profile,
    /// Control period for the budget check, us.
    pub period_us: f64,
    /// Broadcast protocol: the host's wait between a query and its hub
    /// read, us per board the query selects (seed 000's PC sleeps 5 us x
    /// N; boards in two broadcast groups wait 5 us x the larger group after
    /// each query).
    pub wait_us_per_board: f64,
    /// Idle bus time between cycles, us (a paced loop leaves the bus idle).
    pub idle_us: f64,
    /// UDP points: how the host's reads wait. Every mode is measured at
    /// every UDP point, side by side (their blocks of cycles alternate).
    pub udp_waits: Vec<WaitMode>,
    /// UDP points: how long the host waits for an answer before the cycle
    /// counts an error (a real host's servo time-out, 20 ms, by default).
    /// A test on a busy machine raises it, so that a stalled thread is not
    /// counted as a lost packet.
    pub udp_timeout: std::time::Duration,
    /// UDP points: the boards at this address (a running `firelink
    /// emulate` or a real bridge board) instead of an in-process emulator;
    /// one point per protocol with the boards the scan finds there (the
    /// board counts apply to the simulated bus only), and no emulator CPU.
    pub udp_target: Option<SocketAddr>,
    /// The simulated bus's level of detail (`sim` points and the
    /// in-process emulator's bus; the same answer either way).
    pub detail: Detail,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            transports: vec![BenchTransport::Sim, BenchTransport::Udp],
            boards: vec![2, 4, 8, 16, 32, 62],
            protocols: vec![Protocol::Sequential, Protocol::Broadcast],
            cycles: 1000,
            firmware: Profile::Rev8,
            period_us: 1e6 / 6000.0,
            wait_us_per_board: 5.0,
            idle_us: 50.0,
            udp_waits: vec![WaitMode::Blocking],
            udp_timeout: crate::rig::UDP_TIMEOUT,
            udp_target: None,
            detail: Detail::Fast,
        }
    }
}

/// Check a board-count list: each 1..=62, not empty, and every count
/// above 16 preceded by a measured one (1..=16) it is modelled from.
pub fn check_board_counts(counts: &[usize]) -> Result<(), String> {
    if counts.is_empty() {
        return Err("no board count given".into());
    }
    let mut measured = false;
    for &n in counts {
        if !crate::limits::BENCH_BOARD_COUNT.contains(&(n as u64)) {
            return Err(format!("{n} boards: a board count is 1..=62"));
        }
        if n <= 16 {
            measured = true;
        } else if !measured {
            return Err(format!(
                "{n} boards is extrapolated from a measured count (1..=16) that must come \
                 before it in the list"
            ));
        }
    }
    Ok(())
}

/// A board-count list as written (`2,4,8,16,32,62`), checked as
/// [`check_board_counts`] checks it.
///
/// # Errors
/// A count that is not a number in 1..=62, or the list's rule broken.
pub fn parse_board_counts(text: &str) -> Result<Vec<usize>, String> {
    let counts = text
        .split(',')
        .filter(|x| !x.trim().is_empty())
        .map(|x| {
            x.trim()
                .parse::<usize>()
                .ok()
                .filter(|&n| crate::limits::BENCH_BOARD_COUNT.contains(&(n as u64)))
                .ok_or_else(|| format!("{x:?} is not a board count (1..=62)"))
        })
        .collect::<Result<Vec<usize>, String>>()?;
    check_board_counts(&counts)?;
    Ok(counts)
}

/// I/O time statistics of a point, us; `max` is absent for modelled points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IoTime {
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Maximum (measured points only).
    pub max: Option<f64>,
    /// Mean.
    pub mean: f64,
}

/// Seed 002's budget `t(Te) + t(Tf) + t(Tg)` against the period.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BudgetFit {
    /// The period, us.
    pub period_us: f64,
    /// The budget's total, us.
    pub total_us: f64,
    /// Whether it fits in the period.
    pub fits: bool,
}

/// What a measured UDP point adds: its floor, and CPU time per cycle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UdpFigures {
    /// Where the boards were: `in-process emulator`, or the address given.
    pub target: String,
    /// The floor: the point's own port calls (requests, datagram sizes,
    /// host waits) against a loopback responder that answers every read at
    /// once and emulates nothing, with the same wait mode; measured in
    /// blocks alternating with the point's own. Time per cycle, us.
    pub floor_us: IoTime,
    /// The point's I/O median over the floor's median.
    pub floor_ratio: f64,
    /// Floor cycles that failed (a time-out).
    pub floor_errors: u64,
    /// CPU time of the host's thread per cycle (the cycle's I/O, not the
    /// idle time between cycles), us.
    pub host_cpu_us: f64,
    /// The same for the floor's cycles, us.
    pub floor_host_cpu_us: f64,
    /// System calls on the host's socket per cycle.
    pub socket_calls_per_cycle: f64,
    /// CPU time of the in-process emulator's server thread per cycle
    /// (user and system, everything it did while the point's cycles ran,
    /// the idle time between cycles included), us; absent for a bridge
    /// given by address or where thread clocks cannot be read.
    pub emulator_cpu_us: Option<f64>,
    /// CPU time of the floor's responder thread per floor cycle (user and
    /// system, the idle time between cycles included), us: what receiving
    /// and answering the same datagrams costs a server that emulates
    /// nothing, on this machine. The part of `emulator_cpu_us` above it is
    /// the emulation's; absent where thread clocks cannot be read.
    pub floor_server_cpu_us: Option<f64>,
    /// `emulator_cpu_us` over `floor_server_cpu_us`, both from this run:
    /// the emulator's CPU against the bare responder's on the same
    /// datagrams; absent when either is.
    pub emulator_cpu_ratio: Option<f64>,
}

/// What a measured `fw` point adds: its floor, and CPU time per cycle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FwFigures {
    /// The floor: as many bare request -> completion-event round trips
    /// (same payload sizes, same host waits) over a pair of
    /// `SOCK_SEQPACKET` sockets against a responder that answers at once
    /// and models nothing; measured in blocks alternating with the
    /// point's own. Time per cycle, us.
    pub floor_us: IoTime,
    /// The point's I/O median over the floor's median: the port's, the
    /// preloaded library's and the twin's overhead (and the simulated bus
    /// time the twin paces its events to).
    pub floor_ratio: f64,
    /// Floor cycles that failed.
    pub floor_errors: u64,
    /// Request -> completion round trips per cycle.
    pub round_trips: f64,
    /// CPU time of the host's thread per cycle (the cycle's I/O), us.
    pub host_cpu_us: f64,
    /// The same for the floor's cycles, us.
    pub floor_host_cpu_us: f64,
    /// CPU of the twin server's thread per cycle (idle time included), us.
    pub twin_cpu_us: Option<f64>,
    /// CPU of the floor responder's thread per floor cycle, us.
    pub floor_server_cpu_us: Option<f64>,
    /// `host_cpu_us` over the simulation cost per cycle of the same
    /// protocol and boards on `sim` in the same run (absent without one).
    pub host_cpu_vs_sim: Option<f64>,
}

/// One point of the benchmark.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchPoint {
    /// `sim`, `udp`, `fw` or `eth`.
    pub transport: &'static str,
    /// The boards, where a transport measures more than one kind (the
    /// `eth` transport's network and its bridge companions).
    pub board_set: Option<&'static str>,
    /// UDP: how the host's reads waited, `block` or `spin`.
    pub wait: Option<&'static str>,
    /// The protocol used.
    pub protocol: &'static str,
    /// The protocol asked for (the scan may refuse it: see `note`).
    pub protocol_asked: &'static str,
    /// Broadcast protocol: queries per cycle (one per broadcast group:
    /// 16 QLA1 Rev 8 boards take two); 0 for the other protocols.
    pub broadcast_groups: usize,
    /// Boards.
    pub boards: usize,
    /// I/O time per cycle.
    pub io_time_us: IoTime,
    /// Mean read phase, us (measured points only).
    pub read_us: Option<f64>,
    /// Mean write phase, us (measured points only).
    pub write_us: Option<f64>,
    /// Cycles measured (0: modelled).
    pub cycles: u64,
    /// I/O errors while measuring.
    pub errors: u64,
    /// Whether the point comes from the cost model rather than a run.
    pub model: bool,
    /// The highest control rate: 1 / (I/O median + compute median), Hz.
    pub max_rate_hz: f64,
    /// Seed 002's budget at the chosen period.
    pub budget: BudgetFit,
    /// Why the protocol differs, or where a modelled point comes from.
    pub note: Option<String>,
    /// A measured UDP point's floor and CPU figures.
    pub udp: Option<UdpFigures>,
    /// A measured `fw` point's floor and CPU figures.
    pub fw: Option<FwFigures>,
    /// A measured point on the simulated bus: CPU per cycle of simulating
    /// it (host library, bus, boards and their plants; the idle bus time
    /// between cycles included), us, and that per board.
    pub sim_cpu_us: Option<f64>,
    /// `sim_cpu_us` over the boards.
    pub sim_cpu_per_board_us: Option<f64>,
    /// A measured point on a simulated bus (`sim`, or the in-process
    /// emulator's bus behind a `udp` point): what ran at which level of
    /// detail, warm-up and scan included (the emulator counts each
    /// datagram as one span, the `sim` port each cycle).
    pub detail: Option<DetailReport>,
}

/// The paper's figures the benchmark is compared with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaperFigures {
    /// Sequential protocol, 8 boards, us.
    pub sequential_8_us: f64,
    /// Broadcast protocol, 8 boards, us.
    pub broadcast_8_us: f64,
    /// Where they come from.
    pub source: &'static str,
}

/// The whole benchmark.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchReport {
    /// Every point, in the order measured.
    pub results: Vec<BenchPoint>,
    /// Compute time of the 28-axis dVRK cycle (median), us.
    pub compute_us: f64,
    /// The host's own CPU per 28-axis dVRK cycle: the hub block parsed,
    /// the runner's check and compute, the command block built, timed
    /// over a recorded cycle with no I/O; absent when it could not run.
    pub host_cpu_per_cycle_us: Option<HostCpu>,
    /// The paper's figures.
    pub paper: PaperFigures,
    /// Firmware of the emulated boards.
    pub firmware: &'static str,
    /// Measured cycles per point.
    pub cycles: u64,
    /// The simulated bus's level of detail asked for (`--detail`).
    pub detail: Detail,
    /// UDP points: cycles per block (the point's and its floor's blocks
    /// alternate).
    pub udp_block_cycles: u64,
    /// The simulation cost per cycle against boards, per protocol measured
    /// on the simulated bus at three or more board counts.
    pub sim_cost: Vec<SimCostFit>,
    /// The `eth` transport: the Ethernet-only network against the bridge
    /// and the firmware's stated timing, per board count.
    pub eth_comparison: Vec<eth::EthComparison>,
}

/// The host's CPU per 28-axis cycle (parse, PID, build commands), us per
/// cycle over a recorded cycle replayed without I/O
/// ([`host_cpu::RecordedCycle`]), each cycle timed on the monotonic clock.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HostCpu {
    /// Median.
    pub median: f64,
    /// 99th percentile (on a shared machine: preemption included).
    pub p99: f64,
    /// Mean.
    pub mean: f64,
    /// Cycles timed.
    pub cycles: u64,
    /// The floor, in the same run: the bare loop's median, us
    /// ([`host_cpu::RecordedCycle::bare_cycle`]: the frozen port's own
    /// part of a cycle, the query, the hub block replayed and the command
    /// block handed over, with no parse, control or command built), timed
    /// in blocks alternating with the host cycle's.
    pub floor_median: f64,
    /// The bare loop's 99th percentile, us.
    pub floor_p99: f64,
    /// `median` over `floor_median`.
    pub floor_ratio: f64,
    /// Axes computed per cycle.
    pub axes: usize,
    /// Boards whose blocks are parsed per cycle.
    pub boards: usize,
}

/// Cycles timed for [`HostCpu`], after [`HOST_CPU_WARM_UP`] untimed ones.
pub const HOST_CPU_CYCLES: usize = 20_000;
/// Untimed cycles before [`HOST_CPU_CYCLES`].
pub const HOST_CPU_WARM_UP: u64 = 2_000;

/// Measure the host's CPU per 28-axis cycle ([`HostCpu`]).
///
/// # Errors
/// The recorded cycle could not be set up or one of its cycles failed.
pub fn host_cpu_per_cycle() -> Result<HostCpu, TestbedError> {
    let mut recorded = host_cpu::RecordedCycle::record()?;
    let m = recorded.measure_with_floor(HOST_CPU_WARM_UP, HOST_CPU_CYCLES)?;
    let (p, floor) = (m.cycle, m.floor);
    let robot = recorded.robot();
    Ok(HostCpu {
        median: round3(p.median),
        p99: round3(p.p99),
        mean: round3(p.mean),
        cycles: HOST_CPU_CYCLES as u64,
        floor_median: round3(floor.median),
        floor_p99: round3(floor.p99),
        floor_ratio: ratio3(p.median, floor.median),
        axes: robot.joint_count(),
        boards: robot.io().boards().len(),
    })
}

fn round3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// A raw measurement, before rounding and the budget.
#[derive(Debug, Clone)]
struct Raw {
    transport: BenchTransport,
    board_set: Option<&'static str>,
    wait: Option<WaitMode>,
    udp: Option<(String, udp::ModeRun)>,
    fw: Option<fw::FwRun>,
    protocol: Protocol,
    asked: Protocol,
    groups: usize,
    boards: usize,
    io: Percentiles,
    read: f64,
    write: f64,
    cycles: u64,
    errors: u64,
    note: Option<String>,
    /// Simulated bus: CPU per cycle of simulating it, us.
    sim_cpu: Option<f64>,
    /// A simulated bus's count of what ran at which level of detail.
    detail: Option<DetailReport>,
}

/// How a point runs the protocol asked on the boards a scan found.
struct Plan {
    /// The protocol used (the one asked, or the best the boards allow).
    protocol: Protocol,
    /// Broadcast groups (0 for the sequential protocols).
    groups: usize,
    /// Why the protocol or its groups are not the plain one asked.
    note: Option<String>,
    /// The host's wait after each query.
    wait: Duration,
    /// Boards each query selects (the largest group).
    per_query: usize,
}

/// How long the host waits between a broadcast query and its hub read
/// (or the hub's response).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum HostWait {
    /// [`BenchOptions::wait_us_per_board`] x the boards the query selects
    /// (seed 000's PC: 5 us x N).
    PerBoard,
    /// The port's own ([`firelink_host::Port::broadcast_wait`]: on the
    /// Ethernet-only network the Rev 9 host's 3 + 38 (N - 1) us).
    Port,
    /// The Rev 9 host's wait through the bridge: 10 + 10 (N - 1) us
    /// (EthBasePort `WaitBroadcastRead`).
    Rev9Bridge,
}

impl Plan {
    fn of(
        scan: &firelink_host::qla::scan::ScanReport,
        protocol: Protocol,
        options: &BenchOptions,
    ) -> Plan {
        let used = protocol.min(scan.protocol);
        let groups = match used {
            Protocol::Broadcast => scan.broadcast_groups.len(),
            _ => 0,
        };
        let note = if used != protocol {
            Some(scan.protocol_reason.to_string())
        } else if groups > 1 {
            let masks: Vec<String> = scan
                .broadcast_groups
                .iter()
                .map(|&m| firelink_host::qla::scan::mask_boards(m))
                .collect();
            Some(format!(
                "{groups} broadcast groups (boards {}): {}",
                masks.join(" | "),
                scan.protocol_reason
            ))
        } else {
            None
        };
        // The wait after each query: per board it selects (the largest
        // group).
        let per_query = scan
            .broadcast_groups
            .iter()
            .map(|m| m.count_ones() as usize)
            .max()
            .filter(|_| groups > 0)
            .unwrap_or(scan.boards.len());
        Plan {
            protocol: used,
            groups,
            note,
            wait: Duration::from_secs_f64(
                options.wait_us_per_board.max(0.0) * per_query as f64 / 1e6,
            ),
            per_query,
        }
    }

    /// The system's options with the host waiting as `wait` says.
    fn options_with(&self, wait: HostWait) -> IoOptions {
        let broadcast_wait = match wait {
            HostWait::PerBoard => Some(self.wait),
            HostWait::Port => None,
            HostWait::Rev9Bridge => Some(Duration::from_micros(
                10 + 10 * self.per_query.saturating_sub(1) as u64,
            )),
        };
        IoOptions {
            broadcast_wait,
            ..self.options()
        }
    }

    fn options(&self) -> IoOptions {
        IoOptions {
            protocol: Some(self.protocol),
            broadcast_wait: Some(self.wait),
            ..IoOptions::default()
        }
    }
}

/// Run `cycles` I/O cycles on an open system: I/O-time percentiles, mean
/// read and write phases, errors.
fn measure<P: Port>(
    io: &mut IoSystem<P>,
    cycles: u64,
    idle: Duration,
) -> (Percentiles, f64, f64, u64, Option<f64>) {
    for _ in 0..20 {
        io.cycle();
        io.port_mut().wait(idle);
    }
    // The thread's CPU over the measured cycles: on the simulated bus, the
    // cost of simulating them (host library, bus, boards and plants).
    let clock = crate::cpu::ThreadCpuClock::current();
    let cpu_before = clock.and_then(|c| c.now());
    let mut t = Vec::with_capacity(cycles as usize);
    let (mut r, mut w) = (0.0, 0.0);
    for _ in 0..cycles {
        let rep = *io.cycle();
        let _ = io.recover();
        t.push((rep.io_time().as_secs_f64() * 1e6) as f32);
        r += rep.read_time.as_secs_f64() * 1e6;
        w += rep.write_time.as_secs_f64() * 1e6;
        io.port_mut().wait(idle);
    }
    let n = cycles.max(1) as f64;
    let cpu = match (cpu_before, clock.and_then(|c| c.now())) {
        (Some(a), Some(b)) => Some(b.saturating_sub(a).as_secs_f64() * 1e6 / n),
        _ => None,
    };
    (
        Percentiles::of(&mut t),
        r / n,
        w / n,
        io.stats().total_errors(),
        cpu,
    )
}

fn point<P: Port + 'static>(
    mut port: P,
    transport: BenchTransport,
    protocol: Protocol,
    boards: usize,
    options: &BenchOptions,
) -> Result<Raw, TestbedError> {
    let scan = firelink_host::qla::scan::scan(&mut port)?;
    let plan = Plan::of(&scan, protocol, options);
    let (used, groups, note) = (plan.protocol, plan.groups, plan.note.clone());
    let mut system = IoSystem::with_scan(port, &scan, plan.options())?;
    let idle = Duration::from_secs_f64(options.idle_us.max(0.0) / 1e6);
    let (io, read, write, errors, cpu) = measure(&mut system, options.cycles.max(1), idle);
    Ok(Raw {
        detail: crate::dvrk::demo::sim_detail_report(system.port()),
        transport,
        board_set: None,
        wait: None,
        udp: None,
        fw: None,
        sim_cpu: if transport == BenchTransport::Sim {
            cpu
        } else {
            None
        },
        protocol: used,
        asked: protocol,
        groups,
        boards,
        io,
        read,
        write,
        cycles: options.cycles.max(1),
        errors,
        note,
    })
}

/// The compute time of the 28-axis dVRK cycle (median, us), measured with
/// the runner on emulated boards on the simulated bus (the bus's own time is
/// not in it: compute is timed between the read and the write).
pub fn compute_time_us() -> f64 {
    let config = presets::dvrk_seed000();
    let boards = rig::board_configs(&config, Profile::Rev8, config.board_slots());
    let Ok((port, _)) = rig::sim_port(boards, false) else {
        return 0.0;
    };
    let Ok((io, _)) = IoSystem::open(port, IoOptions::default()) else {
        return 0.0;
    };
    let Ok(period) = crate::demo::servo_period(6000.0) else {
        return 0.0;
    };
    let settings = RobotSettings {
        period,
        ..RobotSettings::default()
    };
    let Ok(mut robot) = Robot::new(io, &config, settings) else {
        return 0.0;
    };
    let ok = robot.configure().is_ok() && robot.power_on().is_ok() && robot.home().is_ok();
    if !ok || robot.activate().is_err() {
        return 0.0;
    }
    let _ = robot.run(3000, Pacing::Virtual, 0, |_| {});
    let mut c = robot.times().compute_us.clone();
    let n = c.len().min(3000);
    let start = c.len() - n;
    Percentiles::of(&mut c[start..]).median
}

/// Extrapolate beyond 16 boards from the per-transaction costs of the
/// largest measured point of the same transport and protocol.
fn model(base: &Raw, boards: usize) -> Raw {
    let n = base.boards.max(1) as f64;
    let m = boards as f64;
    let io = match base.protocol {
        // Per board: one read and one write.
        Protocol::Sequential => base.io.median / n * m,
        // Per board: one read; one broadcast write.
        Protocol::SequentialReadBroadcastWrite => base.read / n * m + base.write,
        // Per board: its share of the measured cycle (its status broadcast
        // and hub entry, and of its group's query, wait and hub read and of
        // the command write). A bus holds 16 board IDs, in two broadcast
        // groups at Rev 8, so more boards take more buses or groups of the
        // same kind.
        Protocol::Broadcast => base.io.median / n * m,
    };
    Raw {
        boards,
        io: Percentiles {
            median: io,
            p90: io * base.io.p90 / base.io.median.max(1e-9),
            p99: io * base.io.p99 / base.io.median.max(1e-9),
            max: f64::NAN,
            mean: io,
        },
        read: f64::NAN,
        write: f64::NAN,
        // The same groups per board as measured.
        groups: (base.groups as f64 * m / n).ceil() as usize,
        cycles: 0,
        errors: 0,
        note: Some(format!(
            "model: extrapolated from the {}-board measurement (a 1394 bus addresses 16 boards)",
            base.boards
        )),
        udp: None,
        fw: None,
        sim_cpu: None,
        detail: None,
        ..base.clone()
    }
}

fn round2(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then(|| round2(x))
}

/// Measured percentiles as a report shows them (the maximum only where
/// one was measured).
fn io_time(p: &Percentiles) -> IoTime {
    IoTime {
        median: round2(p.median),
        p90: round2(p.p90),
        p99: round2(p.p99),
        max: finite(p.max),
        mean: round2(p.mean),
    }
}

/// `a / b` to three decimals.
fn ratio3(a: f64, b: f64) -> f64 {
    (a / b.max(1e-9) * 1000.0).round() / 1000.0
}

fn finish(raw: &Raw, compute: f64, period_us: f64) -> BenchPoint {
    let (te, tg) = if raw.read.is_finite() {
        (raw.read, raw.write)
    } else {
        (raw.io.median, 0.0)
    };
    let budget = CycleBudget {
        t_e: Duration::from_secs_f64(te.max(0.0) / 1e6),
        t_f: Duration::from_secs_f64(compute.max(0.0) / 1e6),
        t_g: Duration::from_secs_f64(tg.max(0.0) / 1e6),
        t_s: Duration::ZERO,
    }
    .check(Duration::from_secs_f64(period_us.max(0.0) / 1e6));
    BenchPoint {
        transport: raw.transport.name(),
        board_set: raw.board_set,
        protocol: raw.protocol.name(),
        protocol_asked: raw.asked.name(),
        broadcast_groups: raw.groups,
        boards: raw.boards,
        io_time_us: io_time(&raw.io),
        read_us: finite(raw.read),
        write_us: finite(raw.write),
        cycles: raw.cycles,
        errors: raw.errors,
        model: raw.cycles == 0,
        max_rate_hz: round2(1e6 / (raw.io.median + compute)),
        budget: BudgetFit {
            period_us,
            total_us: round2(budget.total.as_secs_f64() * 1e6),
            fits: budget.total < budget.period,
        },
        note: raw.note.clone(),
        sim_cpu_us: raw.sim_cpu.map(round2),
        sim_cpu_per_board_us: raw.sim_cpu.map(|c| round2(c / raw.boards.max(1) as f64)),
        detail: raw.detail,
        udp: raw.udp.as_ref().map(|(target, m)| UdpFigures {
            target: target.clone(),
            floor_us: io_time(&m.floor),
            floor_ratio: ratio3(raw.io.median, m.floor.median),
            floor_errors: m.floor_errors,
            host_cpu_us: round2(m.host_cpu),
            floor_host_cpu_us: round2(m.floor_host_cpu),
            socket_calls_per_cycle: round2(m.socket_calls),
            emulator_cpu_us: m.emulator_cpu.map(round2),
            floor_server_cpu_us: m.floor_server_cpu.map(round2),
            emulator_cpu_ratio: m
                .emulator_cpu
                .map(round2)
                .zip(m.floor_server_cpu.map(round2))
                .map(|(emulator, floor)| ratio3(emulator, floor)),
        }),
        fw: raw.fw.as_ref().map(|m| FwFigures {
            floor_us: io_time(&m.floor),
            floor_ratio: ratio3(raw.io.median, m.floor.median),
            floor_errors: m.floor_errors,
            round_trips: round2(m.round_trips),
            host_cpu_us: round2(m.host_cpu),
            floor_host_cpu_us: round2(m.floor_host_cpu),
            twin_cpu_us: m.twin_cpu.map(round2),
            floor_server_cpu_us: m.floor_server_cpu.map(round2),
            host_cpu_vs_sim: None,
        }),
        wait: raw.wait.map(WaitMode::name),
    }
}

/// A UDP point's raw measurement per wait mode.
fn udp_raws(
    bridge: &udp::Bridge<'_>,
    target: &str,
    protocol: Protocol,
    options: &BenchOptions,
) -> Result<Vec<Raw>, TestbedError> {
    let runs = udp::measure_point(bridge, protocol, options, HostWait::PerBoard)?;
    Ok(runs
        .into_iter()
        .map(|m| raw_of_run(BenchTransport::Udp, target, protocol, m))
        .collect())
}

/// The raw point of one measured datagram run (`udp` or `eth`).
fn raw_of_run(transport: BenchTransport, target: &str, asked: Protocol, m: udp::ModeRun) -> Raw {
    Raw {
        transport,
        board_set: None,
        wait: Some(m.wait),
        protocol: m.protocol,
        asked,
        groups: m.groups,
        boards: m.boards,
        io: m.io,
        read: m.read,
        write: m.write,
        cycles: m.cycles,
        errors: m.errors,
        note: m.note.clone(),
        udp: Some((target.to_string(), m)),
        fw: None,
        sim_cpu: None,
        detail: None,
    }
}

fn profile_name(p: Profile) -> &'static str {
    match p {
        Profile::Seed => "seed",
        Profile::Rev7 => "7",
        Profile::Rev9 => "9",
        _ => "8",
    }
}

/// `n` boards of the benchmark's generic configuration at `profile`, with
/// idle channels: I/O timing needs no motors, and idle channels keep the
/// emulator's plants cheap (it must keep up with the wall clock over UDP).
fn bench_boards(
    generic: &firelink_control::config::IoConfig,
    profile: Profile,
    n: usize,
) -> Vec<firelink_board::qla::config::BoardConfig> {
    rig::board_configs(generic, profile, n)
        .into_iter()
        .map(|b| b.with_axes(vec![firelink_board::plant::presets::unused_channel(); 4]))
        .collect()
}

/// Run the benchmark; `progress` hears of each point before it runs (the
/// board count is 0 for the UDP points of a [`BenchOptions::udp_target`],
/// whose boards the scan finds).
pub fn run_bench(
    options: &BenchOptions,
    mut progress: impl FnMut(BenchTransport, Protocol, usize),
) -> Result<BenchReport, TestbedError> {
    check_board_counts(&options.boards).map_err(TestbedError::Config)?;
    if options.transports.is_empty() || options.protocols.is_empty() {
        return Err(TestbedError::Config(
            "bench: at least one transport and one protocol".into(),
        ));
    }
    let generic = presets::bench_1board();
    let mut raws: Vec<Raw> = Vec::new();
    let mut eth_stated: Vec<(usize, eth::StatedTiming)> = Vec::new();
    for &t in &options.transports {
        for &proto in &options.protocols {
            if t == BenchTransport::Eth {
                // The Ethernet-only network's point is its broadcast cycle.
                if proto == Protocol::Broadcast {
                    let (points, stated) = eth::eth_raws(&generic, options, &mut progress)?;
                    raws.extend(points);
                    eth_stated.extend(stated);
                }
                continue;
            }
            if let (BenchTransport::Udp, Some(addr)) = (t, options.udp_target) {
                progress(t, proto, 0);
                let bridge = udp::Bridge {
                    addr,
                    emulator: None,
                };
                raws.extend(udp_raws(&bridge, &format!("udp:{addr}"), proto, options)?);
                continue;
            }
            // The last measured point of each wait mode (sim: one).
            let mut last: Vec<Raw> = Vec::new();
            for &n in &options.boards {
                if n > 16 {
                    raws.extend(last.iter().map(|b| model(b, n)));
                    continue;
                }
                progress(t, proto, n);
                let cfgs = bench_boards(&generic, options.firmware, n);
                let points = match t {
                    // Measured above, once for every protocol.
                    BenchTransport::Eth => Vec::new(),
                    BenchTransport::Sim => {
                        let (mut port, _) = rig::sim_port(cfgs, true)?;
                        port.bus_mut().set_detail(options.detail);
                        vec![point(port, t, proto, n, options)?]
                    }
                    BenchTransport::Fw => {
                        vec![fw::measure_point(cfgs, proto, options)?]
                    }
                    BenchTransport::Udp => {
                        let emu = rig::Emulator::start_rig(
                            rig::RigBuilder::qla(cfgs).detail(options.detail),
                        )?;
                        let bridge = udp::Bridge {
                            addr: emu.addr,
                            emulator: Some(&emu),
                        };
                        let p = udp_raws(&bridge, "in-process emulator", proto, options);
                        let stats = emu.stop()?;
                        let mut p = p?;
                        for raw in &mut p {
                            raw.detail = Some(stats.detail);
                        }
                        p
                    }
                };
                last.clone_from(&points);
                raws.extend(points);
            }
        }
    }
    let compute = compute_time_us();
    let host_cpu = host_cpu_per_cycle().ok();
    let mut report = BenchReport {
        results: raws
            .iter()
            .map(|r| finish(r, compute, options.period_us))
            .collect(),
        sim_cost: Vec::new(),
        compute_us: round2(compute),
        host_cpu_per_cycle_us: host_cpu,
        paper: PaperFigures {
            sequential_8_us: 496.0,
            broadcast_8_us: 115.77,
            source: "seed 000, Fig. 11 and section IV",
        },
        firmware: profile_name(options.firmware),
        cycles: options.cycles,
        detail: options.detail,
        udp_block_cycles: udp::BLOCK,
        eth_comparison: Vec::new(),
    };
    report.sim_cost = report.sim_cost_fits();
    report.eth_comparison = eth::comparisons(&report.results, &eth_stated);
    report.compare_fw_with_sim();
    Ok(report)
}

impl BenchReport {
    /// The `fw` points' floor and CPU table.
    fn fmt_fw(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let fw: Vec<(&BenchPoint, &FwFigures)> = self
            .results
            .iter()
            .filter_map(|r| r.fw.as_ref().map(|u| (r, u)))
            .collect();
        if fw.is_empty() {
            return Ok(());
        }
        let num = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.2}"));
        writeln!(
            f,
            "\nfw through the /dev/fw* twin: the floor (as many bare request -> completion-event \
             round trips, same sizes and host waits, over SOCK_SEQPACKET sockets to a responder \
             that models nothing) in blocks of {} cycles alternating with the point's own; \
             CPU per cycle, us (host: the cycle's I/O; twin: its server thread; floor srv: the \
             responder's thread; vs sim: host cpu over the same point's simulation cost)",
            self.udp_block_cycles
        )?;
        writeln!(
            f,
            "{:<9} {:<32} {:>6} {:>9} {:>9} {:>6} {:>6} {:>9} {:>9} {:>9} {:>9} {:>7}",
            "trans",
            "protocol",
            "boards",
            "median",
            "floor",
            "ratio",
            "trips",
            "host cpu",
            "floor cpu",
            "twin cpu",
            "floor srv",
            "vs sim"
        )?;
        for (r, u) in fw {
            writeln!(
                f,
                "{:<9} {:<32} {:>6} {:>9.1} {:>9.1} {:>6.2} {:>6.1} {:>9.2} {:>9.2} {:>9} {:>9} {:>7}",
                r.transport,
                r.protocol,
                r.boards,
                r.io_time_us.median,
                u.floor_us.median,
                u.floor_ratio,
                u.round_trips,
                u.host_cpu_us,
                u.floor_host_cpu_us,
                num(u.twin_cpu_us),
                num(u.floor_server_cpu_us),
                num(u.host_cpu_vs_sim)
            )?;
        }
        Ok(())
    }
}

/// A point's note column: its board set (where the transport measures
/// several), then its note.
fn point_note(r: &BenchPoint) -> String {
    match (r.board_set, r.note.as_deref()) {
        (Some(set), Some(note)) => format!("{set}; {note}"),
        (Some(set), None) => set.to_string(),
        (None, note) => note.unwrap_or("").to_string(),
    }
}

/// A straight line through a protocol's simulation cost against boards.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimCostFit {
    /// The protocol.
    pub protocol: &'static str,
    /// Boards of the points fitted.
    pub boards: Vec<usize>,
    /// Cost of one more board, us per cycle.
    pub per_board_us: f64,
    /// Cost with no board (the host's share), us per cycle.
    pub fixed_us: f64,
    /// The largest distance of a point from the line, as a fraction of the
    /// point's cost.
    pub worst_deviation: f64,
}

impl fmt::Display for SimCostFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: cpu = {:.2} + {:.2} x boards us (least squares over {:?} boards; every point within {:.1} % of the line)",
            self.protocol,
            self.fixed_us,
            self.per_board_us,
            self.boards,
            self.worst_deviation * 100.0
        )
    }
}

impl BenchReport {
    /// Set each `fw` point's host CPU against the simulation cost of the
    /// same protocol and boards on `sim`, where the run measured both.
    fn compare_fw_with_sim(&mut self) {
        let sims: Vec<(&'static str, usize, f64)> = self
            .results
            .iter()
            .filter_map(|r| r.sim_cpu_us.map(|c| (r.protocol, r.boards, c)))
            .collect();
        for r in &mut self.results {
            let (protocol, boards) = (r.protocol, r.boards);
            if let Some(f) = &mut r.fw {
                f.host_cpu_vs_sim = sims
                    .iter()
                    .find(|s| s.0 == protocol && s.1 == boards && s.2 > 0.0)
                    .map(|s| ratio3(f.host_cpu_us, s.2));
            }
        }
    }

    /// For each protocol measured on the simulated bus at three or more
    /// board counts: the least-squares line of its simulation cost.
    pub fn sim_cost_fits(&self) -> Vec<SimCostFit> {
        let mut fits = Vec::new();
        let mut protocols: Vec<&'static str> = self
            .results
            .iter()
            .filter(|r| r.sim_cpu_us.is_some())
            .map(|r| r.protocol)
            .collect();
        protocols.dedup();
        for protocol in protocols {
            let points: Vec<(f64, f64)> = self
                .results
                .iter()
                .filter(|r| r.protocol == protocol)
                .filter_map(|r| r.sim_cpu_us.map(|c| (r.boards as f64, c)))
                .collect();
            if points.len() < 3 {
                continue;
            }
            let n = points.len() as f64;
            let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
            let my = points.iter().map(|p| p.1).sum::<f64>() / n;
            let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
            let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
            let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
            let intercept = my - slope * mx;
            let worst = points
                .iter()
                .map(|&(x, y)| ((intercept + slope * x) - y).abs() / y.max(1e-9))
                .fold(0.0, f64::max);
            fits.push(SimCostFit {
                protocol,
                boards: points.iter().map(|p| p.0 as usize).collect(),
                per_board_us: round2(slope),
                fixed_us: round2(intercept),
                worst_deviation: (worst * 1000.0).round() / 1000.0,
            });
        }
        fits
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "I/O time per cycle (us), seed-000 PC model on the simulated bus (sim) and measured over UDP (udp/WAIT: the host's reads block or spin) and through the /dev/fw* twin (fw)"
        )?;
        writeln!(
            f,
            "{:<9} {:<32} {:>6} {:>9} {:>9} {:>9} {:>11} {:>10}  note",
            "trans", "protocol", "boards", "median", "p99", "max", "max rate", "budget"
        )?;
        for r in &self.results {
            writeln!(
                f,
                "{:<9} {:<32} {:>6} {:>9} {:>9} {:>9} {:>8} Hz {:>10}  {}",
                transport_label(r),
                firelink_host::qla::scan::protocol_label(
                    Protocol::from_name(r.protocol).unwrap_or(Protocol::Sequential),
                    r.broadcast_groups
                ),
                r.boards,
                figure_or_dash(Some(r.io_time_us.median)),
                figure_or_dash(Some(r.io_time_us.p99)),
                figure_or_dash(r.io_time_us.max),
                figure_or_dash(Some(r.max_rate_hz)),
                if r.budget.fits { "fits" } else { "over" },
                point_note(r)
            )?;
        }
        let period = self.results.first().map_or(0.0, |r| r.budget.period_us);
        writeln!(
            f,
            "compute (28-axis dVRK cycle, median): {:.1} us; budget = seed 002's t(Te)+t(Tf)+t(Tg) < {period:.1} us",
            self.compute_us
        )?;
        match &self.host_cpu_per_cycle_us {
            Some(h) => writeln!(
                f,
                "host CPU per {}-axis cycle (parse, PID, build commands): median {:.2} us, p99 {:.2} us \
                 ({} boards' blocks parsed; {} recorded cycles replayed with no I/O); \
                 floor (the bare loop: the replaying port alone, same run) median {:.2} us, \
                 p99 {:.2} us; ratio {:.2}",
                h.axes,
                h.median,
                h.p99,
                h.boards,
                h.cycles,
                h.floor_median,
                h.floor_p99,
                h.floor_ratio
            )?,
            None => writeln!(
                f,
                "host CPU per 28-axis cycle (parse, PID, build commands): not measured"
            )?,
        }
        writeln!(
            f,
            "paper (seed 000, 8 boards): sequential {} us measured, broadcast {} us",
            self.paper.sequential_8_us, self.paper.broadcast_8_us
        )?;
        self.fmt_sim(f)?;
        self.fmt_fw(f)?;
        eth::fmt_comparisons(&self.eth_comparison, f)?;
        self.fmt_udp(f)?;
        self.fmt_detail(f)
    }
}

/// A figure with one decimal, or `-` when there is none.
fn figure_or_dash(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |x| format!("{x:.1}"))
}

/// A point's transport as the tables show it (`udp/WAIT` with its wait).
fn transport_label(r: &BenchPoint) -> String {
    match r.wait {
        Some(w) => format!("{}/{w}", r.transport),
        None => r.transport.to_string(),
    }
}

impl BenchReport {
    /// What each simulated bus ran at which level of detail: one line per
    /// measured point that has one (a `udp` point's wait modes share
    /// their emulator, said once).
    fn fmt_detail(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut said: Vec<(&str, Option<&str>, &str, usize)> = Vec::new();
        let mut lines = Vec::new();
        for r in &self.results {
            let Some(d) = &r.detail else { continue };
            let key = (r.transport, r.board_set, r.protocol, r.boards);
            if said.contains(&key) {
                continue;
            }
            said.push(key);
            // What one span between two marks is on each transport.
            let unit = match r.transport {
                "udp" => "datagrams",
                "fw" => "requests",
                _ => "cycles",
            };
            let set = r.board_set.map_or(String::new(), |s| format!(" ({s})"));
            lines.push(format!(
                "{:<4} {:<32} {:>2} boards{set}: {}",
                r.transport,
                r.protocol,
                r.boards,
                d.counted_in(unit)
            ));
        }
        if lines.is_empty() {
            return Ok(());
        }
        writeln!(
            f,
            "\nLevel of detail of the simulated buses (--detail {}; the same answer either way; \
             warm-up and scan included; udp: the emulator's bus, each datagram one span; fw: the \
             twin's, each request one span)",
            self.detail
        )?;
        for line in lines {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }

    /// The simulation-cost table of the `sim` points (none: nothing).
    fn fmt_sim(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sims: Vec<&BenchPoint> = self
            .results
            .iter()
            .filter(|r| r.sim_cpu_us.is_some())
            .collect();
        if !sims.is_empty() {
            writeln!(
                f,
                "\nSimulation cost (sim points: CPU per simulated cycle of host library, bus, \
                 boards and plants, us)"
            )?;
            writeln!(
                f,
                "{:<9} {:<32} {:>6} {:>9} {:>10}",
                "trans", "protocol", "boards", "cpu", "per board"
            )?;
            for r in &sims {
                writeln!(
                    f,
                    "{:<9} {:<32} {:>6} {:>9} {:>10}",
                    r.transport,
                    r.protocol,
                    r.boards,
                    figure_or_dash(r.sim_cpu_us),
                    figure_or_dash(r.sim_cpu_per_board_us)
                )?;
            }
            for fit in &self.sim_cost {
                writeln!(f, "{fit}")?;
            }
        }
        Ok(())
    }

    /// The UDP points' floors and CPU figures (none: nothing).
    fn fmt_udp(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let udp: Vec<(&BenchPoint, &UdpFigures)> = self
            .results
            .iter()
            .filter_map(|r| r.udp.as_ref().map(|u| (r, u)))
            .collect();
        if udp.is_empty() {
            return Ok(());
        }
        let mut targets: Vec<&str> = Vec::new();
        for (_, u) in &udp {
            if !targets.contains(&u.target.as_str()) {
                targets.push(&u.target);
            }
        }
        writeln!(
            f,
            "\nUDP against {}: the floor (the same requests, sizes and host waits against a responder \
             that answers at once) in blocks of {} cycles alternating with the point's own; \
             CPU per cycle, us (host: the cycle's I/O; emulator: its server thread; \
             floor srv: the responder's thread, a server that emulates nothing; \
             emu/srv: emulator over floor srv)",
            targets.join(", "),
            self.udp_block_cycles
        )?;
        writeln!(
            f,
            "{:<9} {:<32} {:>6} {:>9} {:>9} {:>6} {:>9} {:>9} {:>8} {:>9} {:>7} {:>7}",
            "trans",
            "protocol",
            "boards",
            "median",
            "floor",
            "ratio",
            "host cpu",
            "floor cpu",
            "emu cpu",
            "floor srv",
            "emu/srv",
            "calls"
        )?;
        for (r, u) in udp {
            writeln!(
                f,
                "{:<9} {:<32} {:>6} {:>9} {:>9} {:>6.2} {:>9} {:>9} {:>8} {:>9} {:>7} {:>7.1}",
                transport_label(r),
                r.protocol,
                r.boards,
                figure_or_dash(Some(r.io_time_us.median)),
                figure_or_dash(Some(u.floor_us.median)),
                u.floor_ratio,
                figure_or_dash(Some(u.host_cpu_us)),
                figure_or_dash(Some(u.floor_host_cpu_us)),
                figure_or_dash(u.emulator_cpu_us),
                figure_or_dash(u.floor_server_cpu_us),
                u.emulator_cpu_ratio
                    .map_or("-".to_string(), |x| format!("{x:.2}")),
                u.socket_calls_per_cycle
            )?;
        }
        Ok(())
    }
}
