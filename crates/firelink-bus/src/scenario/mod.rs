//! One I/O cycle of the seed papers, simulated: the library behind
//! `firelink sim`.
//!
//! [`simulate_cycle`] builds a bus with a PC ([`HostLink`], the root) and N
//! boards in a daisy chain (PC - board N-1 - ... - board 0, so self-ID gives
//! board *i* physical ID *i* and the PC ID N), then runs one cycle of either
//! protocol and reports the wire time of each phase:
//!
//! - **broadcast** (seed 000): *query* (the PC's quadlet write to 0x1800),
//!   *broadcast* (from the end of the query to the end of the last board's
//!   status broadcast), *hub_read* (the PC's block read of hub memory from
//!   the hub board, from the request to the PC's final ack), *command* (the
//!   PC's block write of every board's commands).
//! - **sequential**: per board, a block *read* (request to final ack) and a
//!   block *write* (request to ack).
//!
//! Without host overhead the PC issues each transaction as soon as the
//! previous one finished (for the hub read: as soon as it has heard every
//! status broadcast), so phases are pure wire time and `total_us` spans
//! the first packet's start to the last packet's end, including the gaps
//! the PC's fair arbitration waits for. With host overhead the PC pays
//! [`HostModel`] costs around each call and sleeps 5 us x N after the query
//! (seed 000, section III-A); phases then follow the PC's timeline.
//!
//! The hub is the board next to the PC (physical ID N-1). Payload sizes come
//! from [`Profile`]; see its docs for the seed-profile assumptions.

mod minimal_board;

pub use minimal_board::{BoardStats, MinimalBoard, clocks};

use firelink_wire::board::broadcast::HubHeader;
use firelink_wire::board::realtime::BlockFormat;
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Speed, Tcode};

use crate::bus::{Bus, BusConfig, NodeConfig, NodeHandle, TraceLevel};
use crate::fault::{FaultPlan, FaultRecord};
use crate::host::{Completion, HostCall, HostLink, HostModel, Outcome};
use crate::node::ArbitrationClass;
use crate::phy::phy_config_packet;
use crate::time::{SimDuration, SimTime};
use crate::trace::{PacketId, PacketKind, PacketRecord, Trace};

/// Firmware generation, which fixes payload sizes and slot timing.
///
/// | | seed | rev7 | rev8 |
/// |---|---|---|---|
/// | status broadcast (quadlets) | 1 + 12 | 1 + 28 | 1 + 32 |
/// | hub read (quadlets) | 16 x 13 = 208 | 29 N + 1 | 33 N + 1 |
/// | command per board (quadlets) | 4 | 5 | 6 |
/// | sequential read / write (bytes) | 48 / 16 | 112 / 20 | 128 / 24 |
/// | slots | fixed TDMA | chain | chain |
/// | query and command sent to | node 63 (broadcast) | node 0 (snooped) | node 0 (snooped) |
///
/// Seed-profile assumptions (seed 000 does not state every size of its
/// era): the real-time block is the 48 bytes the paper's sequential
/// protocol reads (12 quadlets), so a status broadcast is a sequence
/// header plus 12 quadlets; the PC reads a fixed 16-board hub block, as the
/// reference host library did before Rev 7 (it read 16 x 17 quadlets for
/// the 16-quadlet blocks of its time), giving 16 x 13 = 208 quadlets; the
/// command is 16 bytes per board (128 bytes for 8 boards, Fig. 10a).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    /// Seed 000's firmware (fixed TDMA slots).
    Seed,
    /// Firmware Rev 7 (chained broadcasts, QLA1 28-quadlet block).
    Rev7,
    /// Firmware Rev 8 (chained broadcasts, QLA1 32-quadlet block).
    Rev8,
}

impl Profile {
    /// `seed`, `rev7` or `rev8`.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Seed => "seed",
            Profile::Rev7 => "rev7",
            Profile::Rev8 => "rev8",
        }
    }

    /// Parse a [`name`](Self::name).
    pub fn from_name(name: &str) -> Option<Profile> {
        match name {
            "seed" => Some(Profile::Seed),
            "rev7" => Some(Profile::Rev7),
            "rev8" => Some(Profile::Rev8),
            _ => None,
        }
    }

    /// Whether status broadcasts use fixed TDMA slots (else the chain).
    pub fn uses_tdma(self) -> bool {
        self == Profile::Seed
    }

    /// Quadlets of the real-time block.
    pub fn block_quadlets(self) -> usize {
        match self {
            Profile::Seed => 12,
            Profile::Rev7 => 28,
            Profile::Rev8 => 32,
        }
    }

    /// Quadlets of a status broadcast (header + block).
    pub fn status_broadcast_quadlets(self) -> usize {
        1 + self.block_quadlets()
    }

    /// Quadlets the PC reads from the hub for `boards` boards.
    pub fn hub_read_quadlets(self, boards: usize) -> usize {
        match self {
            Profile::Seed => 16 * self.status_broadcast_quadlets(),
            Profile::Rev7 | Profile::Rev8 => self.status_broadcast_quadlets() * boards + 1,
        }
    }

    /// Command quadlets per board in the command broadcast.
    pub fn command_quadlets_per_board(self) -> usize {
        match self {
            Profile::Seed => 4,
            Profile::Rev7 => 5,
            Profile::Rev8 => 6,
        }
    }

    /// Bytes of the sequential protocol's block read.
    pub fn read_bytes(self) -> usize {
        match self {
            Profile::Seed => 48,
            _ => self.block_quadlets() * 4,
        }
    }

    /// Bytes of the sequential protocol's block write.
    pub fn write_bytes(self) -> usize {
        self.command_quadlets_per_board() * 4
    }

    /// Firmware version a board reports.
    pub fn firmware_version(self) -> u32 {
        match self {
            Profile::Seed => 4,
            Profile::Rev7 => 7,
            Profile::Rev8 => 8,
        }
    }

    /// Whether the PC broadcasts the query and the command to node 63 (else
    /// it sends them to node 0, which the other boards snoop).
    pub fn pc_broadcasts(self) -> bool {
        self == Profile::Seed
    }
}

/// Which I/O protocol the cycle uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Protocol {
    /// Query, status broadcasts, hub read, command broadcast (seed 000).
    Broadcast,
    /// One block read and one block write per board.
    Sequential,
}

impl Protocol {
    /// `broadcast` or `sequential`.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Broadcast => "broadcast",
            Protocol::Sequential => "sequential",
        }
    }

    /// Parse a [`name`](Self::name).
    pub fn from_name(name: &str) -> Option<Protocol> {
        match name {
            "broadcast" => Some(Protocol::Broadcast),
            "sequential" => Some(Protocol::Sequential),
            _ => None,
        }
    }
}

/// What to simulate.
#[derive(Clone, Debug, PartialEq)]
pub struct CycleConfig {
    /// Number of boards (1 to 16).
    pub boards: usize,
    /// Firmware profile.
    pub profile: Profile,
    /// I/O protocol.
    pub protocol: Protocol,
    /// Gap count to set with a PHY configuration packet before the cycle
    /// (`None`: the power-up 63).
    pub gap_count: Option<u8>,
    /// How boards arbitrate for their status broadcasts.
    pub arbitration: ArbitrationClass,
    /// Speed of every packet.
    pub speed: Speed,
    /// Seed (faults and host jitter).
    pub seed: u64,
    /// Add the PC's software overhead ([`HostModel::seed000`]).
    pub host_overhead: bool,
    /// Draw host overheads from a seeded distribution.
    pub host_jitter: bool,
    /// Run the cycle master (cycle start every 125 us).
    pub cycle_master: bool,
    /// Override the hub read size (quadlets).
    pub hub_read_quadlets: Option<usize>,
    /// Faults, with times relative to the start of the cycle.
    pub faults: FaultPlan,
}

impl CycleConfig {
    /// Defaults: gap count 63, isochronous-style arbitration for the status
    /// broadcasts, S400, seed 0, no host overhead, no cycle master.
    pub fn new(boards: usize, profile: Profile, protocol: Protocol) -> CycleConfig {
        CycleConfig {
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
            hub_read_quadlets: None,
            faults: FaultPlan::new(),
        }
    }
}

/// Phase times in microseconds.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
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
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BoardTiming {
    /// Board ID (= physical ID here).
    pub board: usize,
    /// Block read, microseconds.
    pub read_us: f64,
    /// Block write, microseconds.
    pub write_us: f64,
}

/// Sizes used in the cycle.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
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

/// The result of [`simulate_cycle`], printed by `firelink sim --json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CycleReport {
    /// Number of boards.
    pub boards: usize,
    /// Firmware profile.
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
}

impl CycleReport {
    /// One phase by name (`query`, `broadcast`, `hub_read`, `command`,
    /// `read`, `write`).
    pub fn phase_us(&self, name: &str) -> Option<f64> {
        match (&self.phases_us, name) {
            (Phases::Broadcast { query, .. }, "query") => Some(*query),
            (Phases::Broadcast { broadcast, .. }, "broadcast") => Some(*broadcast),
            (Phases::Broadcast { hub_read, .. }, "hub_read") => Some(*hub_read),
            (Phases::Broadcast { command, .. }, "command") => Some(*command),
            (Phases::Sequential { read, .. }, "read") => Some(*read),
            (Phases::Sequential { write, .. }, "write") => Some(*write),
            _ => None,
        }
    }

    /// A readable table.
    pub fn table(&self) -> String {
        use std::fmt::Write as _;
        let mut out = String::new();
        let _ = writeln!(
            out,
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
        );
        let phases: Vec<(&str, f64)> = match &self.phases_us {
            Phases::Broadcast {
                query,
                broadcast,
                hub_read,
                command,
            } => vec![
                ("query", *query),
                ("broadcast", *broadcast),
                ("hub_read", *hub_read),
                ("command", *command),
            ],
            Phases::Sequential { read, write } => {
                vec![("read (mean/board)", *read), ("write (mean/board)", *write)]
            }
        };
        let _ = writeln!(out, "  {:<20} {:>10}", "phase", "us");
        for (name, us) in phases {
            let _ = writeln!(out, "  {name:<20} {us:>10.3}");
        }
        if let Some(per_board) = &self.per_board {
            let _ = writeln!(out, "  {:<20} {:>10} {:>10}", "board", "read", "write");
            for b in per_board {
                let _ = writeln!(
                    out,
                    "  {:<20} {:>10.3} {:>10.3}",
                    b.board, b.read_us, b.write_us
                );
            }
        }
        let _ = writeln!(out, "  {:<20} {:>10.3}", "total", self.total_us);
        let _ = writeln!(
            out,
            "  {} packets, {}/{} boards ok",
            self.packets, self.boards_ok, self.boards
        );
        for e in &self.errors {
            let _ = writeln!(out, "  error: {e}");
        }
        out
    }
}

/// A finished cycle: the report and the bus (for its trace and pcap).
#[derive(Debug)]
pub struct CycleRun {
    /// The report.
    pub report: CycleReport,
    /// The bus after the cycle.
    pub bus: Bus,
    /// The PC's node.
    pub pc: NodeHandle,
    /// The boards' nodes, by board ID.
    pub boards: Vec<NodeHandle>,
    /// First packet of the cycle (earlier ones are setup: resets, PHY
    /// configuration).
    pub first_packet: PacketId,
}

/// Simulate one cycle and report it.
pub fn simulate_cycle(cfg: &CycleConfig) -> CycleReport {
    run_cycle(cfg).report
}

#[derive(Debug)]
struct Driver {
    bus: Bus,
    pc: NodeHandle,
    model: Option<HostModel>,
    speed: Speed,
    next_tl: u8,
    errors: Vec<String>,
}

/// How long the PC waits for one transaction before giving up.
const TRANSACTION_DEADLINE: SimDuration = SimDuration::from_millis(2);

impl Driver {
    fn host_cost(&mut self, call: HostCall) -> (SimDuration, SimDuration) {
        match self.model.as_mut() {
            Some(m) => {
                let c = m.cost(call);
                (c.before, c.after)
            }
            None => (SimDuration::ZERO, SimDuration::ZERO),
        }
    }

    fn pc_id(&self) -> NodeId {
        NodeId::local(self.bus.phy_id(self.pc).unwrap_or(0))
    }

    fn tl(&mut self) -> u8 {
        let tl = self.next_tl;
        self.next_tl = (self.next_tl + 1) & 0x3F;
        tl
    }

    fn submit(&mut self, repr: &PacketRepr<'_>, speed: Speed) -> Option<u64> {
        let mut bytes = vec![0u8; repr.buffer_len()];
        repr.emit(&mut bytes).ok()?;
        self.bus
            .with_node::<HostLink, _>(self.pc, |link, ctx| link.submit(ctx, bytes, speed))
            .ok()
    }

    /// Run until the transaction finishes; returns its completion.
    fn wait(&mut self, token: u64, what: &str) -> Option<Completion> {
        let deadline = self.bus.now() + TRANSACTION_DEADLINE;
        let pc = self.pc;
        self.bus.run_until_with(deadline, |bus| {
            bus.node::<HostLink>(pc)
                .is_some_and(|l| !l.is_pending(token))
        });
        let completion = self
            .bus
            .node_mut::<HostLink>(pc)
            .and_then(|l| l.take_completion(token));
        match &completion {
            None => self.errors.push(format!("{what}: no completion")),
            Some(c) if c.outcome != Outcome::Complete => {
                self.errors.push(format!("{what}: {:?}", c.outcome));
            }
            _ => {}
        }
        completion
    }

    /// Run until the bus has nothing left to do (bounded).
    fn settle(&mut self) {
        let deadline = self.bus.now() + TRANSACTION_DEADLINE;
        self.bus
            .run_until_with(deadline, |bus| !bus.has_pending_traffic());
    }
}

/// The span of a transaction in the trace: from its request's start to the
/// end of the last packet answering it (ack, concatenated response, the
/// response's ack).
fn transaction_span(trace: &Trace, request: &PacketRecord) -> (SimTime, SimTime) {
    let mut end = request.end;
    let mut frontier = vec![request.id];
    for p in trace.packets().iter().filter(|p| p.id > request.id) {
        if p.answers.is_some_and(|a| frontier.contains(&a)) {
            end = end.max(p.end);
            frontier.push(p.id);
        }
    }
    (request.start, end)
}

/// The first request the PC sent at or after packet `from`.
fn first_request_from(trace: &Trace, pc: NodeHandle, from: PacketId) -> Option<&PacketRecord> {
    trace
        .packets()
        .iter()
        .find(|p| p.id >= from && p.sender == pc.0 && p.kind == PacketKind::Request)
}

fn next_packet_id(bus: &Bus) -> PacketId {
    bus.trace().packets().last().map_or(0, |p| p.id + 1)
}

fn us(d: SimDuration) -> f64 {
    d.as_micros_f64()
}

/// A bus built and reset for a cycle, ready to [`run`](Self::run). Splitting
/// preparation from the cycle lets a benchmark time the cycle alone.
#[derive(Debug)]
pub struct PreparedCycle {
    cfg: CycleConfig,
    boards: usize,
    d: Driver,
    board_nodes: Vec<NodeHandle>,
    gap_count: u8,
}

/// Simulate one cycle and keep the bus for inspection.
pub fn run_cycle(cfg: &CycleConfig) -> CycleRun {
    prepare_cycle(cfg).run()
}

/// Build the bus, reset it and set the gap count, without running the
/// cycle.
pub fn prepare_cycle(cfg: &CycleConfig) -> PreparedCycle {
    prepare_cycle_with(cfg, &mut |id, cfg| {
        Box::new(MinimalBoard::new(
            id,
            cfg.profile,
            cfg.arbitration,
            cfg.speed,
        ))
    })
}

/// Build the node of board `id` for a cycle (e.g. a full emulated board
/// from another crate instead of the [`MinimalBoard`]).
pub type BoardFactory<'a> = dyn FnMut(u8, &CycleConfig) -> Box<dyn crate::node::Node> + 'a;

/// [`prepare_cycle`] with the boards built by `factory`.
pub fn prepare_cycle_with(cfg: &CycleConfig, factory: &mut BoardFactory<'_>) -> PreparedCycle {
    let boards = cfg.boards.clamp(1, 16);
    let bus_cfg = BusConfig {
        seed: cfg.seed,
        cycle_master: cfg.cycle_master,
        trace: TraceLevel::Normal,
        ..BusConfig::default()
    };
    let mut bus = Bus::new(bus_cfg);
    let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
    let mut board_nodes = vec![NodeHandle(0); boards];
    let mut chain = vec![pc];
    for id in (0..boards).rev() {
        let h = bus.add_node(factory(id as u8, cfg), NodeConfig::board());
        board_nodes[id] = h;
        chain.push(h);
    }
    // Cannot fail: fresh nodes, a chain of at most 17.
    let _ = bus.daisy_chain(&chain);
    bus.reset();
    let model = cfg.host_overhead.then(|| {
        let m = HostModel::seed000(bus.timing());
        if cfg.host_jitter {
            m.with_jitter(cfg.seed)
        } else {
            m
        }
    });
    let mut d = Driver {
        bus,
        pc,
        model,
        speed: cfg.speed,
        next_tl: 0,
        errors: Vec::new(),
    };
    // Gap count: PHY configuration packet, then a reset (as Linux does).
    if let Some(g) = cfg.gap_count {
        if d.bus.gap_count(pc) != Some(g) {
            let bytes = phy_config_packet(Some(g), None);
            let token = d
                .bus
                .with_node::<HostLink, _>(pc, |l, ctx| l.submit(ctx, bytes, Speed::S100))
                .ok();
            if let Some(token) = token {
                d.wait(token, "PHY configuration");
            }
            d.settle();
            d.bus.reset();
        }
    }
    let gap_count = d.bus.gap_count(pc).unwrap_or(63);
    // Start from a quiet bus (longer than an arbitration reset gap).
    d.bus.run_for(SimDuration::from_micros(50));
    PreparedCycle {
        cfg: cfg.clone(),
        boards,
        d,
        board_nodes,
        gap_count,
    }
}

impl PreparedCycle {
    /// Run the cycle.
    pub fn run(self) -> CycleRun {
        let PreparedCycle {
            cfg,
            boards,
            mut d,
            board_nodes,
            gap_count,
        } = self;
        let cfg = &cfg;
        let pc = d.pc;
        let t0 = d.bus.now();
        let first_packet = next_packet_id(&d.bus);
        let mut plan = cfg.faults.clone();
        for (at, _) in &mut plan.timed {
            *at = t0 + SimDuration(at.0);
        }
        for rule in &mut plan.rules {
            rule.matcher.after = rule.matcher.after.map(|a| t0 + SimDuration(a.0));
            rule.matcher.before = rule.matcher.before.map(|b| t0 + SimDuration(b.0));
        }
        d.bus.set_fault_plan(plan);
        let hub_quadlets = cfg
            .hub_read_quadlets
            .unwrap_or_else(|| cfg.profile.hub_read_quadlets(boards))
            .clamp(1, cfg.speed.max_async_payload() / 4);
        let sizes = Sizes {
            status_quadlets: cfg.profile.status_broadcast_quadlets(),
            hub_read_quadlets: hub_quadlets,
            command_bytes: boards * cfg.profile.command_quadlets_per_board() * 4,
            read_bytes: cfg.profile.read_bytes(),
            write_bytes: cfg.profile.write_bytes(),
        };
        let (phases, per_board, total_us, boards_ok) = match cfg.protocol {
            Protocol::Broadcast => {
                broadcast_cycle(&mut d, cfg, boards, hub_quadlets, t0, first_packet)
            }
            Protocol::Sequential => sequential_cycle(&mut d, cfg, boards, t0, first_packet),
        };
        d.settle();
        let packets = d
            .bus
            .trace()
            .packets()
            .iter()
            .filter(|p| p.id >= first_packet && p.kind != PacketKind::SelfId)
            .count();
        let report = CycleReport {
            boards,
            profile: cfg.profile,
            protocol: cfg.protocol,
            speed: match cfg.speed {
                Speed::S100 => 100,
                Speed::S200 => 200,
                Speed::S400 => 400,
            },
            gap_count,
            arbitration: cfg.arbitration,
            host_overhead: cfg.host_overhead,
            seed: cfg.seed,
            phases_us: phases,
            per_board,
            total_us,
            packets,
            sizes,
            boards_ok,
            errors: d.errors,
            faults: d.bus.fault_log().records().to_vec(),
        };
        CycleRun {
            report,
            bus: d.bus,
            pc,
            boards: board_nodes,
            first_packet,
        }
    }
}

fn broadcast_cycle(
    d: &mut Driver,
    cfg: &CycleConfig,
    boards: usize,
    hub_quadlets: usize,
    t0: SimTime,
    first_packet: PacketId,
) -> (Phases, Option<Vec<BoardTiming>>, f64, usize) {
    let seq: u16 = 1;
    let mask: u16 = if boards >= 16 {
        0xFFFF
    } else {
        (1u16 << boards) - 1
    };
    let pc_id = d.pc_id();
    let target = if cfg.profile.pc_broadcasts() {
        NodeId::BROADCAST
    } else {
        NodeId::local(0)
    };
    let speed = d.speed;
    // 1. Query.
    let (before, after) = d.host_cost(HostCall::BroadcastWrite);
    d.bus.run_until(t0 + before);
    let tl = d.tl();
    let query = PacketRepr::WriteQuadletRequest {
        header: AsyncHeader::new(target, pc_id, tl),
        offset: u64::from(minimal_board::QUERY_OFFSET),
        data: (u32::from(seq) << 16) | u32::from(mask),
    };
    let query_submit = d.bus.now();
    let query_return = query_submit + after;
    if let Some(token) = d.submit(&query, speed) {
        d.wait(token, "query");
    }
    // 2. Status broadcasts: the PC sleeps 5 us x N (with host overhead) or
    // waits until it heard every board (wire time only).
    if d.model.is_some() {
        let wake = query_return + SimDuration::from_micros(5) * boards as u64;
        d.bus.run_until(wake.max(d.bus.now()));
    } else {
        let pc = d.pc;
        let deadline = d.bus.now() + SimDuration::from_micros(5 * boards as u64 + 200);
        // Look at each received packet once.
        let (mut seen, mut heard_from) = (0, 0);
        let heard = d.bus.run_until_with(deadline, |bus| {
            if let Some(l) = bus.node::<HostLink>(pc) {
                let total = l.received_total();
                if total > seen {
                    let new = (total - seen) as usize;
                    heard_from += l
                        .received()
                        .rev()
                        .take(new)
                        .filter(|r| r.at >= t0 && is_status_broadcast(&r.bytes))
                        .count();
                    seen = total;
                }
            }
            heard_from >= boards
        });
        if !heard {
            d.errors
                .push("not every status broadcast reached the PC".to_string());
        }
    }
    // 3. Hub read from the board next to the PC.
    let hub = NodeId::local(boards.saturating_sub(1) as u8);
    let (before, after) = d.host_cost(HostCall::Read);
    let hub_call = d.bus.now();
    d.bus.run_until(hub_call + before);
    let tl = d.tl();
    let read = PacketRepr::ReadBlockRequest {
        header: AsyncHeader::new(hub, pc_id, tl),
        offset: u64::from(minimal_board::HUB_OFFSET),
        data_length: (hub_quadlets * 4) as u16,
        extended_tcode: 0,
    };
    let mut boards_ok = 0;
    if let Some(token) = d.submit(&read, speed) {
        if let Some(c) = d.wait(token, "hub read") {
            boards_ok = check_hub(c.response.as_deref(), seq, mask, cfg.profile, &mut d.errors);
        }
    }
    let hub_return = d.bus.now() + after;
    d.bus.run_until(hub_return);
    // 4. Command broadcast.
    let (before, after) = d.host_cost(HostCall::BroadcastWrite);
    let command_call = d.bus.now();
    d.bus.run_until(command_call + before);
    let per = cfg.profile.command_quadlets_per_board();
    let mut data = Vec::with_capacity(boards * per * 4);
    for b in 0..boards {
        for i in 0..per {
            let q = 0x8000_0000 | ((b as u32) << 16) | i as u32;
            data.extend_from_slice(&q.to_be_bytes());
        }
    }
    let tl = d.tl();
    let command = PacketRepr::WriteBlockRequest {
        header: AsyncHeader::new(target, pc_id, tl),
        offset: if cfg.profile.pc_broadcasts() {
            0
        } else {
            minimal_board::COMMAND_SNOOP_OFFSET
        },
        extended_tcode: 0,
        data: &data,
    };
    let command_return = d.bus.now() + after;
    if let Some(token) = d.submit(&command, speed) {
        d.wait(token, "command");
    }
    d.settle();
    // Measure.
    let trace = d.bus.trace();
    let pc = d.pc;
    let mut requests = trace
        .packets()
        .iter()
        .filter(|p| p.id >= first_packet && p.sender == pc.0 && p.kind == PacketKind::Request);
    let spans: Vec<(SimTime, SimTime)> = requests
        .by_ref()
        .take(3)
        .map(|p| transaction_span(trace, p))
        .collect();
    let (q, h, c) = match spans.as_slice() {
        [q, h, c] => (*q, *h, *c),
        _ => {
            d.errors.push("the cycle is incomplete".to_string());
            let z = (t0, t0);
            (z, z, z)
        }
    };
    let last_status_end = trace
        .packets()
        .iter()
        .filter(|p| p.id >= first_packet && p.sender != pc.0 && is_status_broadcast(&p.bytes))
        .map(|p| p.end)
        .max()
        .unwrap_or(q.1);
    let phases = if d.model.is_some() {
        Phases::Broadcast {
            query: us(query_return.max(q.1) - t0),
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
    let start = if d.model.is_some() { t0 } else { q.0 };
    (phases, None, us(end - start), boards_ok)
}

fn sequential_cycle(
    d: &mut Driver,
    cfg: &CycleConfig,
    boards: usize,
    t0: SimTime,
    first_packet: PacketId,
) -> (Phases, Option<Vec<BoardTiming>>, f64, usize) {
    let pc_id = d.pc_id();
    let speed = d.speed;
    let mut per_board = Vec::with_capacity(boards);
    let mut boards_ok = 0;
    let mut last_end = t0;
    let mut first_start = None;
    for b in 0..boards {
        let dest = NodeId::local(b as u8);
        // Read.
        let (before, after) = d.host_cost(HostCall::Read);
        let call = d.bus.now();
        d.bus.run_until(call + before);
        let from = next_packet_id(&d.bus);
        let tl = d.tl();
        let read = PacketRepr::ReadBlockRequest {
            header: AsyncHeader::new(dest, pc_id, tl),
            offset: 0,
            data_length: cfg.profile.read_bytes() as u16,
            extended_tcode: 0,
        };
        let ok = d
            .submit(&read, speed)
            .and_then(|t| d.wait(t, &format!("read board {b}")))
            .is_some_and(|c| c.outcome == Outcome::Complete);
        boards_ok += usize::from(ok);
        let read_return = d.bus.now() + after;
        d.bus.run_until(read_return);
        let read_span = first_request_from(d.bus.trace(), d.pc, from)
            .map(|p| transaction_span(d.bus.trace(), p));
        // Write.
        let (before, after) = d.host_cost(HostCall::Write);
        let write_call = d.bus.now();
        d.bus.run_until(write_call + before);
        let from = next_packet_id(&d.bus);
        let tl = d.tl();
        let data: Vec<u8> = (0..cfg.profile.write_bytes()).map(|i| i as u8).collect();
        let write = PacketRepr::WriteBlockRequest {
            header: AsyncHeader::new(dest, pc_id, tl),
            offset: 0,
            extended_tcode: 0,
            data: &data,
        };
        if let Some(t) = d.submit(&write, speed) {
            d.wait(t, &format!("write board {b}"));
        }
        let write_return = d.bus.now() + after;
        d.bus.run_until(write_return);
        let write_span = first_request_from(d.bus.trace(), d.pc, from)
            .map(|p| transaction_span(d.bus.trace(), p));
        let (rs, re) = read_span.unwrap_or((call, call));
        let (ws, we) = write_span.unwrap_or((write_call, write_call));
        first_start.get_or_insert(rs);
        last_end = last_end.max(we).max(write_return);
        let timing = if d.model.is_some() {
            BoardTiming {
                board: b,
                read_us: us(read_return - call),
                write_us: us(write_return - write_call),
            }
        } else {
            BoardTiming {
                board: b,
                read_us: us(re - rs),
                write_us: us(we - ws),
            }
        };
        per_board.push(timing);
    }
    let _ = first_packet;
    let n = per_board.len().max(1) as f64;
    let phases = Phases::Sequential {
        read: per_board.iter().map(|b| b.read_us).sum::<f64>() / n,
        write: per_board.iter().map(|b| b.write_us).sum::<f64>() / n,
    };
    let start = if d.model.is_some() {
        t0
    } else {
        first_start.unwrap_or(t0)
    };
    (phases, Some(per_board), us(last_end - start), boards_ok)
}

/// Whether `bytes` is a status broadcast (block write to the hub space,
/// destination 63).
pub fn is_status_broadcast(bytes: &[u8]) -> bool {
    let view = Packet::new_unchecked(bytes);
    bytes.len() >= 20
        && view.tcode() == Tcode::WriteBlockRequest
        && view.destination_id().is_broadcast()
        && (minimal_board::HUB_OFFSET..minimal_board::HUB_OFFSET + 0x200)
            .contains(&(view.offset() as u16))
}

/// Count the boards whose block in a hub read response carries `seq`.
fn check_hub(
    response: Option<&[u8]>,
    seq: u16,
    mask: u16,
    profile: Profile,
    errors: &mut Vec<String>,
) -> usize {
    let Some(bytes) = response else {
        errors.push("hub read: no response".to_string());
        return 0;
    };
    let Ok(view) = Packet::new_checked(bytes) else {
        errors.push("hub read: malformed response".to_string());
        return 0;
    };
    if view.verify().is_err() {
        errors.push("hub read: response CRC error".to_string());
        return 0;
    }
    let quadlets: Vec<u32> = view
        .data()
        .chunks_exact(4)
        .map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let n = profile.status_broadcast_quadlets();
    let mut fresh: u16 = 0;
    for block in quadlets.chunks_exact(n) {
        let header = block[0];
        let Some(&status) = block.get(2) else {
            continue;
        };
        let board = ((status >> 24) & 0xF) as u16;
        // A Rev 8 hub keeps the rewritten header (size, sequence low byte,
        // error bit, update time); the minimal responder keeps `seq<<16`.
        let rev8_fresh = profile == Profile::Rev8
            && matches!(
                HubHeader::from_word(header, BlockFormat::Rev8),
                HubHeader::Rev8 { seq_low, seq_error: false, .. } if u16::from(seq_low) == seq & 0xFF
            );
        if header >> 16 == u32::from(seq) || rev8_fresh {
            fresh |= 1 << board;
        } else if header >> 16 == 0xFFFF {
            errors.push(format!(
                "board {board} saw a corrupt query (sequence 0xFFFF)"
            ));
        }
    }
    let missing = mask & !fresh;
    if missing != 0 {
        errors.push(format!(
            "hub read: no fresh data from boards {missing:#06x}"
        ));
    }
    (fresh & mask).count_ones() as usize
}
