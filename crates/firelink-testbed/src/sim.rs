//! One I/O cycle on the simulated bus, measured phase by phase: the
//! library behind `firelink sim`.
//!
//! [`run`] builds N emulated boards ([`firelink_board`]) in a daisy chain
//! with the PC's link at the root (PC - board N-1 - ... - board 0, so self-ID
//! gives board *i* physical ID *i* and the PC ID N), opens the host
//! library's [`IoSystem`] on a [`SimPort`] (scan and protocol set-up
//! included), lets the bus go quiet, runs one cycle of the protocol and
//! reads the wire time of each phase from the bus trace:
//!
//! - **broadcast** (seed 000): *query* (the PC's quadlet write to 0x1800),
//!   *broadcast* (from the end of the query to the end of the last board's
//!   status broadcast), *hub_read* (the PC's block read of hub memory from
//!   the board next to it, from the request to the PC's final ack),
//!   *command* (the PC's block write of every board's commands).
//! - **sequential**: per board, a block *read* (request to the end of the
//!   response; the PC's ack of it follows) and a block *write* (request to
//!   ack).
//!
//! Without host overhead the PC issues each transaction as soon as the
//! previous one finished; between the query and the hub read it listens
//! to the boards' status broadcasts and reads as soon as it has heard them
//! all ([`IoOptions::listen_for_broadcasts`]). Phases are then pure wire
//! time and `total_us` spans the first packet's start to the last packet's
//! end, including the gaps the PC's fair arbitration waits for. With host
//! overhead the PC pays [`HostModel`] costs around each call and sleeps
//! 5 us x N after the query (seed 000, section III-A); phases then follow
//! the PC's timeline (the port's clock before and after each call).
//!
//! The profiles are the boards' firmware: `seed` is seed 000's own (Rev 4:
//! fixed TDMA slots, 48-byte blocks, a fixed 16-board hub read, query and
//! commands to broadcast node 63 as its patched driver allowed); `rev7` and
//! `rev8` chain their broadcasts, and the PC sends the query and the
//! commands to node 0, which every board snoops, as stock FireWire stacks
//! must.
//!
//! ```
//! use firelink_board::qla::config::Profile;
//! use firelink_host::qla::scan::Protocol;
//! use firelink_testbed::sim::{SimOptions, simulate};
//! let report = simulate(&SimOptions::new(8, Profile::Seed, Protocol::Broadcast)).unwrap();
//! // The command broadcast of seed 000 takes about 3.26 us at S400.
//! let command = report.phase_us("command").unwrap();
//! assert!((command - 3.26).abs() / 3.26 < 0.10);
//! ```

use std::time::Duration;

use serde::Serialize;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, GapCount, RigOptions};
use firelink_bus::fault::{FaultPlan, FaultRecord};
use firelink_bus::trace::{PacketId, PacketKind, PacketRecord, Trace};
use firelink_bus::{
    ArbitrationClass, Detail, DetailReport, HostModel, NodeHandle, SimDuration, SimTime, TraceLevel,
};
use firelink_host::qla::io::{BroadcastRoute, IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::sim::SimPort;
use firelink_host::trace::{CallKind, CallRecord, TracingPort};
use firelink_host::{MissReason, Port};
use firelink_wire::packet::{Packet, Speed, Tcode};
use firelink_wire::qla::broadcast::status_broadcast_board;
use firelink_wire::qla::realtime::FirmwareRev;

use crate::TestbedError;

/// What to simulate.
#[derive(Clone, Debug, PartialEq)]
pub struct SimOptions {
    /// Number of boards (1 to 16).
    pub boards: usize,
    /// The boards' firmware.
    pub profile: Profile,
    /// I/O protocol: [`Protocol::Broadcast`] or [`Protocol::Sequential`].
    pub protocol: Protocol,
    /// Gap count to set with a PHY configuration packet before the cycle
    /// (`None`: the power-up 63).
    pub gap_count: Option<u8>,
    /// How boards arbitrate for their status broadcasts.
    pub arbitration: ArbitrationClass,
    /// Speed of every packet.
    pub speed: Speed,
    /// Seed (faults, host jitter, the plants' noise).
    pub seed: u64,
    /// Add the PC's software overhead ([`HostModel::seed000`]).
    pub host_overhead: bool,
    /// Draw host overheads from a seeded distribution.
    pub host_jitter: bool,
    /// Run the cycle master (cycle start every 125 us).
    pub cycle_master: bool,
    /// Faults, with times relative to the start of the cycle.
    pub faults: FaultPlan,
    /// The bus's level of detail (both give the same answer).
    pub detail: Detail,
}

/// What `firelink sim` asks for (clap's `Args` behind the `clap`
/// feature): [`SimOptions`] without a fault plan, as typed;
/// [`SimRequest::options`] makes them.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct SimRequest {
    /// Number of boards (1 to 16).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=16))
    )]
    pub boards: u8,
    /// The boards' firmware (`--firmware` too).
    #[cfg_attr(
        feature = "clap",
        arg(long, alias = "firmware", default_value = "seed", value_parser = crate::cli_args::firmware())
    )]
    pub profile: Profile,
    /// I/O protocol: broadcast or sequential (the phase tables' two).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = Protocol::Broadcast))]
    pub protocol: Protocol,
    /// Gap count to set (PHY configuration packet and bus reset) before the
    /// cycle; default the power-up 63.
    #[cfg_attr(
        feature = "clap",
        arg(long = "gap-count", value_parser = clap::value_parser!(u8).range(0..=63))
    )]
    pub gap_count: Option<u8>,
    /// Arbitration of the boards' status broadcasts.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "iso", value_parser = crate::cli_args::arbitration())
    )]
    pub arbitration: ArbitrationClass,
    /// Speed of every packet in Mb/s.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "400", value_parser = crate::cli_args::speed())
    )]
    pub speed: Speed,
    /// Seed of the fault injector and the host jitter.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0))]
    pub seed: u64,
    /// Add the PC's software overhead (seed 000's PC: read 32 us, write
    /// 34 us, broadcast write call 2.51 us).
    #[cfg_attr(feature = "clap", arg(long = "host-overhead"))]
    pub host_overhead: bool,
    /// With --host-overhead: draw the overheads from a seeded distribution.
    #[cfg_attr(feature = "clap", arg(long, requires = "host_overhead"))]
    pub jitter: bool,
    /// Run the cycle master (cycle start every 125 us; off in seed 000).
    #[cfg_attr(feature = "clap", arg(long = "cycle-master"))]
    pub cycle_master: bool,
    /// The bus's level of detail: `fast` (a packet's deliveries in one
    /// batch where that is exact) or `packet` (every delivery an event);
    /// the same answer either way.
    #[cfg_attr(feature = "clap", arg(long, default_value = "fast"))]
    pub detail: Detail,
}

impl SimRequest {
    /// The options the request makes (no faults).
    pub fn options(&self) -> SimOptions {
        SimOptions {
            gap_count: self.gap_count,
            arbitration: self.arbitration,
            speed: self.speed,
            seed: self.seed,
            host_overhead: self.host_overhead,
            host_jitter: self.jitter,
            cycle_master: self.cycle_master,
            detail: self.detail,
            ..SimOptions::new(usize::from(self.boards), self.profile, self.protocol)
        }
    }
}

impl SimOptions {
    /// Defaults: gap count 63, isochronous-style arbitration for the status
    /// broadcasts, S400, seed 0, no host overhead, no cycle master.
    pub fn new(boards: usize, profile: Profile, protocol: Protocol) -> SimOptions {
        SimOptions {
            boards,
            profile,
            protocol,
            gap_count: None,
            arbitration: ArbitrationClass::Isochronous,
            speed: Speed::S400,
            seed: 0,
            host_overhead: false,
            host_jitter: false,
            cycle_master: false,
            faults: FaultPlan::new(),
            detail: Detail::Fast,
        }
    }

    /// The firmware the boards report: seed 000's own (Rev 4) for the seed
    /// profile.
    fn firmware(&self) -> FirmwareRev {
        match self.profile {
            Profile::Seed => FirmwareRev::Rev4,
            p => p.firmware_rev(),
        }
    }

    /// Where the PC sends the query and the commands.
    fn route(&self) -> BroadcastRoute {
        match self.profile {
            Profile::Seed => BroadcastRoute::Node63,
            Profile::Rev7 | Profile::Rev8 | Profile::Rev9 => BroadcastRoute::SnoopedNode0,
        }
    }
}

/// Phase times in microseconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Phases {
    /// Broadcast protocol phases.
    Broadcast {
        /// The query.
        query: f64,
        /// The status broadcasts.
        broadcast: f64,
        /// The hub block read with its final ack.
        hub_read: f64,
        /// The command broadcast.
        command: f64,
    },
    /// Sequential protocol: mean per board.
    Sequential {
        /// Block read.
        read: f64,
        /// Block write.
        write: f64,
    },
}

/// One board's transactions in the sequential protocol.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoardTiming {
    /// Board ID (= physical ID here).
    pub board: usize,
    /// Block read, microseconds.
    pub read_us: f64,
    /// Block write, microseconds.
    pub write_us: f64,
}

/// Sizes used in the cycle.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Sizes {
    /// Quadlets per status broadcast.
    pub status_quadlets: usize,
    /// Quadlets of the hub read.
    pub hub_read_quadlets: usize,
    /// Bytes of the command broadcast.
    pub command_bytes: usize,
    /// Bytes of a sequential read.
    pub read_bytes: usize,
    /// Bytes of a sequential write.
    pub write_bytes: usize,
}

/// What one simulated cycle took, printed by `firelink sim --json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SimReport {
    /// Number of boards.
    pub boards: usize,
    /// The boards' firmware profile.
    #[serde(serialize_with = "profile_name")]
    pub profile: Profile,
    /// Protocol.
    pub protocol: Protocol,
    /// Speed in Mb/s (100, 200, 400).
    pub speed: u32,
    /// Gap count in force during the cycle.
    pub gap_count: u8,
    /// Arbitration class of the boards' broadcasts.
    pub arbitration: ArbitrationClass,
    /// Whether host overhead was added.
    pub host_overhead: bool,
    /// Seed.
    pub seed: u64,
    /// Phase times in microseconds.
    pub phases_us: Phases,
    /// Per-board times (sequential protocol only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub per_board: Option<Vec<BoardTiming>>,
    /// Whole cycle in microseconds.
    pub total_us: f64,
    /// Packets on the wire during the cycle (acks included).
    pub packets: usize,
    /// Payload sizes.
    pub sizes: Sizes,
    /// Boards whose fresh data the PC got.
    pub boards_ok: usize,
    /// Problems the PC saw.
    pub errors: Vec<String>,
    /// Faults injected (empty without a fault plan).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<FaultRecord>,
    /// What ran at which level of detail in the cycle (from its start;
    /// the scan and set-up before it are not counted).
    pub detail: DetailReport,
}

fn profile_name<S: serde::Serializer>(p: &Profile, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(p.name())
}

impl SimReport {
    /// One phase by name (`query`, `broadcast`, `hub_read`, `command`,
    /// `read`, `write`).
    pub fn phase_us(&self, name: &str) -> Option<f64> {
        self.phases()
            .into_iter()
            .find(|(n, _)| *n == name)
            .map(|p| p.1)
    }

    /// The phases in order, by name.
    pub fn phases(&self) -> Vec<(&'static str, f64)> {
        match self.phases_us {
            Phases::Broadcast {
                query,
                broadcast,
                hub_read,
                command,
            } => vec![
                ("query", query),
                ("broadcast", broadcast),
                ("hub_read", hub_read),
                ("command", command),
            ],
            Phases::Sequential { read, write } => vec![("read", read), ("write", write)],
        }
    }
}

/// A readable table.
impl std::fmt::Display for SimReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{} protocol, {} boards, profile {}, S{}, gap count {}, {} arbitration{}",
            self.protocol.name(),
            self.boards,
            self.profile.name(),
            self.speed,
            self.gap_count,
            self.arbitration.name(),
            if self.host_overhead {
                ", with host overhead"
            } else {
                ", wire time only"
            }
        )?;
        writeln!(f, "  {:<20} {:>10}", "phase", "us")?;
        for (name, us) in self.phases() {
            let name = match name {
                "read" => "read (mean/board)",
                "write" => "write (mean/board)",
                n => n,
            };
            writeln!(f, "  {name:<20} {us:>10.3}")?;
        }
        if let Some(per_board) = &self.per_board {
            writeln!(f, "  {:<20} {:>10} {:>10}", "board", "read", "write")?;
            for b in per_board {
                writeln!(
                    f,
                    "  {:<20} {:>10.3} {:>10.3}",
                    b.board, b.read_us, b.write_us
                )?;
            }
        }
        writeln!(f, "  {:<20} {:>10.3}", "total", self.total_us)?;
        writeln!(
            f,
            "  {} packets, {}/{} boards ok",
            self.packets, self.boards_ok, self.boards
        )?;
        writeln!(f, "  {}", self.detail)?;
        for e in &self.errors {
            writeln!(f, "  error: {e}")?;
        }
        Ok(())
    }
}

/// The I/O system of a simulated cycle: the host library on a traced
/// simulated port.
pub type SimIo = IoSystem<TracingPort<SimPort>>;

/// A finished cycle: the report, and the I/O system with the bus (for its
/// trace, pcap and nodes).
pub struct SimRun {
    /// The report.
    pub report: SimReport,
    /// The host library after the cycle; its port holds the bus.
    pub io: SimIo,
    /// The PC's node.
    pub pc: NodeHandle,
    /// The boards' nodes, by board ID.
    pub boards: Vec<NodeHandle>,
    /// First packet of the cycle (earlier ones are setup: resets, PHY
    /// configuration, the scan).
    pub first_packet: PacketId,
}

impl SimRun {
    /// The simulated port.
    pub fn port(&self) -> &SimPort {
        self.io.port().inner()
    }

    /// The simulated port, mutable (to run the bus on).
    pub fn port_mut(&mut self) -> &mut SimPort {
        self.io.port_mut().inner_mut()
    }
}

/// The boards set up and scanned, the bus quiet: ready to
/// [`run`](Self::run) the cycle. Splitting preparation from the cycle lets
/// a benchmark time the cycle alone.
pub struct PreparedSim {
    options: SimOptions,
    io: SimIo,
    pc: NodeHandle,
    boards: Vec<NodeHandle>,
    gap_count: u8,
    hub_read_quadlets: usize,
}

/// How long the PC waits at most for the status broadcasts without host
/// overhead: 200 us beyond the 5 us per board of seed 000.
const LISTEN_MARGIN: Duration = Duration::from_micros(200);

/// Quiet time before the cycle (longer than an arbitration reset gap).
const QUIET: Duration = Duration::from_micros(50);

/// Simulate one cycle and report it.
///
/// # Errors
/// As [`prepare`].
pub fn simulate(options: &SimOptions) -> Result<SimReport, TestbedError> {
    Ok(run(options)?.report)
}

/// Simulate one cycle and keep the bus for inspection.
///
/// # Errors
/// As [`prepare`].
pub fn run(options: &SimOptions) -> Result<SimRun, TestbedError> {
    Ok(prepare(options)?.run())
}

/// Build the bus, reset it, set the gap count, scan the boards and set up
/// the protocol, without running the cycle.
///
/// # Errors
/// [`TestbedError::Config`] for a board count outside 1..=16 or the
/// sequential-read/broadcast-write protocol (not a phase table), or boards
/// that run the broadcast protocol in more than one group (16 Rev 8
/// boards: two queries and hub reads per cycle, not the one-query phase
/// table); the host library's errors when the protocol cannot run on these
/// boards (a hub block larger than one packet at the chosen speed).
pub fn prepare(options: &SimOptions) -> Result<PreparedSim, TestbedError> {
    let n = options.boards;
    if !(1..=16).contains(&n) {
        return Err(TestbedError::Config(format!(
            "{n} boards: 1 to 16 (board IDs are 4 bits)"
        )));
    }
    if options.protocol == Protocol::SequentialReadBroadcastWrite {
        return Err(TestbedError::Config(
            "the phase tables are for the broadcast and sequential protocols".into(),
        ));
    }
    let firmware = options.firmware();
    let configs = (0..n as u8)
        .map(|id| {
            BoardConfig::new(id, Hardware::Qla1, options.profile)
                .with_firmware(firmware)
                .with_seed(options.seed)
        })
        .collect::<Vec<_>>();
    let layout = configs.first().map(BoardConfig::layout);
    let mut rig = BoardRig::daisy_chain(
        configs,
        &RigOptions {
            seed: options.seed,
            trace: TraceLevel::Normal,
            cycle_master: options.cycle_master,
            gap_count: options.gap_count.map(GapCount::Fixed),
            broadcast_speed: options.speed,
            broadcast_class: options.arbitration,
        },
    );
    rig.bus.set_detail(options.detail);
    let gap_count = rig.bus.gap_count(rig.host).unwrap_or(63);
    let (pc, boards) = (rig.host, rig.boards.clone());
    let model = options.host_overhead.then(|| {
        let m = HostModel::seed000(rig.bus.timing());
        if options.host_jitter {
            m.with_jitter(options.seed)
        } else {
            m
        }
    });
    let mut port = SimPort::new(rig.bus, rig.host).with_speed(options.speed);
    if let Some(m) = model {
        port = port.with_host_model(m);
    }
    // The hub read: the hub block (seed 000's hosts: 16 boards' worth), in
    // one packet at the bus speed.
    let per_board = layout.map_or(0, |l| l.broadcast_quadlets());
    let hub_block = layout.map_or(0, |l| {
        firelink_wire::qla::broadcast::hub_block_quadlets(std::iter::repeat_n(l, n))
    });
    let fixed = if firmware == FirmwareRev::Rev4 {
        hub_block.max(16 * per_board)
    } else {
        hub_block
    };
    let hub_read_quadlets = fixed.min(options.speed.max_async_payload() / 4);
    let wait = Duration::from_micros(5 * n as u64);
    let config = IoOptions {
        protocol: Some(options.protocol),
        hub_board: Some(n as u8 - 1),
        broadcast_wait: Some(if options.host_overhead {
            wait
        } else {
            wait + LISTEN_MARGIN
        }),
        seq_rule: None,
        hub_read_quadlets: (options.protocol == Protocol::Broadcast).then_some(hub_read_quadlets),
        broadcast_route: options.route(),
        listen_for_broadcasts: !options.host_overhead,
    };
    let (mut io, _) = IoSystem::open(TracingPort::new(port), config)?;
    let groups = io.broadcast_groups().len();
    if groups > 1 {
        return Err(TestbedError::Config(format!(
            "{n} boards run the broadcast protocol in {groups} groups (their hub blocks \
             exceed one hub memory): the phase table is for one query per cycle"
        )));
    }
    // Start from a quiet bus.
    io.port_mut().wait(QUIET);
    io.port_mut().clear();
    Ok(PreparedSim {
        options: options.clone(),
        io,
        pc,
        boards,
        gap_count,
        hub_read_quadlets,
    })
}

impl PreparedSim {
    /// Run the cycle and measure it.
    pub fn run(self) -> SimRun {
        let PreparedSim {
            options,
            mut io,
            pc,
            boards,
            gap_count,
            hub_read_quadlets,
        } = self;
        let bus = io.port_mut().inner_mut().bus_mut();
        let t0 = bus.now();
        let first_packet = next_packet_id(bus.trace());
        bus.set_fault_plan(shifted(&options.faults, t0));
        let report = *io.cycle();
        // Let the last transaction and its acks finish.
        let bus = io.port_mut().inner_mut().bus_mut();
        let settle = bus.now() + SimDuration::from_millis(2);
        bus.run_until_with(settle, |b| !b.has_pending_traffic());
        let calls = io.port().calls().to_vec();
        let bus = io.port().inner().bus();
        let trace = bus.trace();
        let mut errors = Vec::new();
        let measure = Measure {
            trace,
            pc,
            first_packet,
            t0,
            timeline: options.host_overhead,
        };
        let (phases, per_board, total_us) = match options.protocol {
            Protocol::Broadcast => measure.broadcast(&calls, &mut errors),
            _ => measure.sequential(&calls, boards.len(), &mut errors),
        };
        let n = boards.len();
        let missed = report.missed.count_ones() as usize;
        describe_misses(&report, options.protocol, &mut errors);
        if let Some(e) = report.error {
            errors.push(e.to_string());
        }
        for c in &calls {
            if c.heard == Some(false) {
                errors.push("not every status broadcast reached the PC".to_string());
            }
        }
        let packets = trace
            .packets()
            .iter()
            .filter(|p| p.id >= first_packet && p.kind != PacketKind::SelfId)
            .count();
        let layout = io.boards().first().map(|b| b.info().layout);
        let sizes = Sizes {
            status_quadlets: layout.map_or(0, |l| l.broadcast_quadlets()),
            hub_read_quadlets,
            command_bytes: io
                .boards()
                .iter()
                .map(|b| b.info().layout.write_block_len())
                .sum(),
            read_bytes: layout.map_or(0, |l| l.read_block_len()),
            write_bytes: layout.map_or(0, |l| l.write_block_len()),
        };
        let report = SimReport {
            boards: n,
            profile: options.profile,
            protocol: options.protocol,
            speed: match options.speed {
                Speed::S100 => 100,
                Speed::S200 => 200,
                Speed::S400 => 400,
            },
            gap_count,
            arbitration: options.arbitration,
            host_overhead: options.host_overhead,
            seed: options.seed,
            phases_us: phases,
            per_board,
            total_us,
            packets,
            sizes,
            boards_ok: n.saturating_sub(missed),
            errors,
            faults: bus.fault_log().records().to_vec(),
            detail: bus.detail_report(),
        };
        SimRun {
            report,
            io,
            pc,
            boards,
            first_packet,
        }
    }
}

/// The fault plan with its times made relative to `t0`.
fn shifted(plan: &FaultPlan, t0: SimTime) -> FaultPlan {
    let mut plan = plan.clone();
    for (at, _) in &mut plan.timed {
        *at = t0 + SimDuration(at.0);
    }
    for rule in &mut plan.rules {
        rule.matcher.after = rule.matcher.after.map(|a| t0 + SimDuration(a.0));
        rule.matcher.before = rule.matcher.before.map(|b| t0 + SimDuration(b.0));
    }
    plan
}

/// The boards that missed the cycle, in words.
fn describe_misses(
    report: &firelink_host::cycle_report::CycleReport,
    protocol: Protocol,
    errors: &mut Vec<String>,
) {
    let mut stale = 0u16;
    for (id, reason) in report.missed_boards() {
        match reason {
            MissReason::CorruptQuery => {
                errors.push(format!("board {id} saw a corrupt query (sequence 0xFFFF)"))
            }
            MissReason::Transaction => {}
            MissReason::NotUpdated | MissReason::Sequence { .. } => stale |= 1 << id,
            other => errors.push(format!("board {id}: {other}")),
        }
    }
    if stale != 0 {
        let what = match protocol {
            Protocol::Broadcast => "hub read",
            _ => "read",
        };
        errors.push(format!("{what}: no fresh data from boards {stale:#06x}"));
    }
}

/// Reading phase times off the bus trace and the port's call records.
struct Measure<'a> {
    trace: &'a Trace,
    pc: NodeHandle,
    first_packet: PacketId,
    t0: SimTime,
    /// Phases on the PC's timeline (host overhead) rather than wire time.
    timeline: bool,
}

impl Measure<'_> {
    /// The PC's requests of the cycle, in order.
    fn requests(&self) -> impl Iterator<Item = &PacketRecord> {
        self.trace.packets().iter().filter(|p| {
            p.id >= self.first_packet && p.sender == self.pc.0 && p.kind == PacketKind::Request
        })
    }

    fn broadcast(
        &self,
        calls: &[CallRecord],
        errors: &mut Vec<String>,
    ) -> (Phases, Option<Vec<BoardTiming>>, f64) {
        let spans: Vec<(SimTime, SimTime)> = self
            .requests()
            .take(3)
            .map(|p| transaction_span(self.trace, p, SpanEnd::FinalAck))
            .collect();
        let (q, h, c) = match spans.as_slice() {
            [q, h, c] => (*q, *h, *c),
            _ => {
                errors.push("the cycle is incomplete".to_string());
                let z = (self.t0, self.t0);
                (z, z, z)
            }
        };
        let last_status_end = self
            .trace
            .packets()
            .iter()
            .filter(|p| p.id >= self.first_packet && p.sender != self.pc.0 && is_status(p))
            .map(|p| p.end)
            .max()
            .unwrap_or(q.1);
        let call = |kind: CallKind| calls.iter().find(|c| c.kind == kind);
        let query = call(CallKind::StartWriteQuadlet);
        let hub = call(CallKind::ReadBlock);
        let command = call(CallKind::StartWriteBlock);
        let (query_return, hub_call, hub_return, command_call, command_return) =
            match (query, hub, command) {
                (Some(q), Some(h), Some(c)) => (
                    SimTime(q.finished_ps),
                    SimTime(h.started_ps),
                    SimTime(h.finished_ps),
                    SimTime(c.started_ps),
                    SimTime(c.finished_ps),
                ),
                _ => (self.t0, self.t0, self.t0, self.t0, self.t0),
            };
        let phases = if self.timeline {
            Phases::Broadcast {
                query: us(query_return.max(q.1) - self.t0),
                broadcast: us(hub_call - query_return.max(q.1)),
                hub_read: us(hub_return - hub_call),
                command: us(command_return.max(c.1) - command_call),
            }
        } else {
            Phases::Broadcast {
                query: us(q.1 - q.0),
                broadcast: us(last_status_end - q.1),
                hub_read: us(h.1 - h.0),
                command: us(c.1 - c.0),
            }
        };
        let end = c.1.max(command_return);
        let start = if self.timeline { self.t0 } else { q.0 };
        (phases, None, us(end - start))
    }

    fn sequential(
        &self,
        calls: &[CallRecord],
        boards: usize,
        errors: &mut Vec<String>,
    ) -> (Phases, Option<Vec<BoardTiming>>, f64) {
        let requests: Vec<&PacketRecord> = self.requests().collect();
        let reads = calls.iter().filter(|c| c.kind == CallKind::ReadBlock);
        let writes = calls.iter().filter(|c| c.kind == CallKind::WriteBlock);
        let mut per_board = Vec::with_capacity(boards);
        let mut last_end = self.t0;
        let mut first_start = None;
        for (b, (read, write)) in reads.zip(writes).enumerate().take(boards) {
            let span_to = |node: u8, tcode_write: bool| {
                requests
                    .iter()
                    .find(|p| {
                        let v = Packet::new_unchecked(&p.bytes[..]);
                        v.destination_id().phy() == node
                            && (v.tcode() == Tcode::WriteBlockRequest) == tcode_write
                    })
                    .map(|p| transaction_span(self.trace, p, SpanEnd::Response))
            };
            let (read_call, write_call) = (SimTime(read.started_ps), SimTime(write.started_ps));
            let (rs, re) = span_to(read.dest.node, false).unwrap_or((read_call, read_call));
            let (ws, we) = span_to(write.dest.node, true).unwrap_or((write_call, write_call));
            first_start = Some(first_start.map_or(rs, |s: SimTime| s.min(rs)));
            last_end = last_end.max(we).max(SimTime(write.finished_ps));
            per_board.push(if self.timeline {
                BoardTiming {
                    board: b,
                    read_us: us(SimTime(read.finished_ps) - read_call),
                    write_us: us(SimTime(write.finished_ps) - write_call),
                }
            } else {
                BoardTiming {
                    board: b,
                    read_us: us(re - rs),
                    write_us: us(we - ws),
                }
            });
        }
        if per_board.len() < boards {
            errors.push("the cycle is incomplete".to_string());
        }
        let n = per_board.len().max(1) as f64;
        let phases = Phases::Sequential {
            read: per_board.iter().map(|b| b.read_us).sum::<f64>() / n,
            write: per_board.iter().map(|b| b.write_us).sum::<f64>() / n,
        };
        let start = if self.timeline {
            self.t0
        } else {
            first_start.unwrap_or(self.t0)
        };
        (phases, Some(per_board), us(last_end - start))
    }
}

fn is_status(p: &PacketRecord) -> bool {
    Packet::new_checked(&p.bytes[..])
        .ok()
        .is_some_and(|v| status_broadcast_board(&v).is_some())
}

/// Where a transaction's span ends.
#[derive(Clone, Copy, PartialEq, Eq)]
enum SpanEnd {
    /// At the last packet answering it: ack, response, the response's ack.
    FinalAck,
    /// At its ack or its response, whichever ends later (the PC's ack of
    /// the response not included).
    Response,
}

/// The span of a transaction in the trace: from its request's start to the
/// end of the packets answering it (see [`SpanEnd`]).
fn transaction_span(trace: &Trace, request: &PacketRecord, until: SpanEnd) -> (SimTime, SimTime) {
    let mut end = request.end;
    let mut frontier = vec![request.id];
    for p in trace.packets().iter().filter(|p| p.id > request.id) {
        let Some(a) = p.answers else {
            continue;
        };
        let direct = a == request.id;
        if direct || (until == SpanEnd::FinalAck && frontier.contains(&a)) {
            end = end.max(p.end);
            frontier.push(p.id);
        }
    }
    (request.start, end)
}

fn next_packet_id(trace: &Trace) -> PacketId {
    trace.packets().last().map_or(0, |p| p.id + 1)
}

fn us(d: SimDuration) -> f64 {
    d.as_micros_f64()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_sets_every_option_it_names() {
        let request = SimRequest {
            boards: 4,
            profile: Profile::Rev8,
            protocol: Protocol::Sequential,
            gap_count: Some(10),
            arbitration: ArbitrationClass::Priority,
            speed: Speed::S200,
            seed: 3,
            host_overhead: true,
            jitter: true,
            cycle_master: true,
            detail: Detail::Packet,
        };
        let options = request.options();
        let expected = SimOptions {
            gap_count: Some(10),
            speed: Speed::S200,
            seed: 3,
            host_overhead: true,
            host_jitter: true,
            cycle_master: true,
            arbitration: ArbitrationClass::Priority,
            detail: Detail::Packet,
            ..SimOptions::new(4, Profile::Rev8, Protocol::Sequential)
        };
        // (Every value above is not the default, so a dropped one shows.)
        assert_ne!(
            SimOptions::new(4, Profile::Rev8, Protocol::Sequential).arbitration,
            ArbitrationClass::Priority
        );
        assert_eq!(options, expected);
    }
}
