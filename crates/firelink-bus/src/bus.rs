//! The bus: a discrete-event simulation of one 1394a cable bus.
//!
//! [`Bus`] owns the nodes, the cables, the PHY registers and all timing. It
//! runs an event queue ordered by (virtual time, insertion order), so a run
//! is a pure function of the nodes, the topology, the configuration and the
//! seed.
//!
//! # The life of a packet
//! 1. A node calls [`NodeCtx::transmit`]; the request joins the node's queue.
//! 2. When the bus is idle, each queued request becomes eligible once the
//!    bus has been idle for the gap its class needs (isochronous gap,
//!    subaction gap, or the arbitration reset gap for a fair request whose
//!    node already won in this fairness interval). Its request reaches the
//!    root after `hops x repeat delay`; the first to arrive wins (ties: the
//!    node nearer the root, then the lower physical ID). The grant comes
//!    back down, and the packet starts.
//! 3. Faults are decided (delay, drop, corruption...).
//! 4. Data prefix, the packet's bits at its speed, data end. Every other node
//!    on the bus whose path supports the speed receives the packet when its
//!    last bit arrives there ([`Node::on_receive`]).
//! 5. A unicast packet's addressee acks after the ack gap (the ack is sent at
//!    the packet's speed); its [`RxReply::AckThenResponse`] makes it send the
//!    response at once after the ack (concatenated). The requester's
//!    [`Node::on_transmitted`] gets the ack when it arrives.
//! 6. The bus is idle when the last data end has reached every node.
//!
//! # Bus reset
//! [`Bus::reset`], a cable change (when `auto_reset`), a disconnect fault or
//! a node setting IBR/ISBR starts a reset. In-flight and queued requests are
//! flushed (their nodes get `on_transmitted(.., None)`), the generation
//! increments, self-ID numbers the nodes in topology order with the root
//! highest, and every node gets [`Node::on_bus_reset`] with its new ID.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, VecDeque};
use std::sync::Arc;

use firelink_wire::crc::crc1394;
use firelink_wire::packet::{Ack, NodeId, Speed, Tcode};
use firelink_wire::phy::{PhyPacket, SelfId};
use rand_chacha::rand_core::RngCore;

use crate::error::BusError;
use crate::fault::{
    Evidence, EvidenceKind, FaultId, FaultInjector, FaultLog, FaultPlan, FaultRule, FaultSource,
    TimedFault, corrupt_ack_byte,
};
use crate::node::{
    ArbitrationClass, Commands, Node, NodeCtx, ResetInfo, RxReply, TimerCommand, TransmitRequest,
};
use crate::phy::{PhyRegisters, parse_phy_packet, phy_packet_bytes};
use crate::time::{SimDuration, SimTime};
use crate::timing::{BusTiming, DEFAULT_GAP_COUNT, PHY_PACKET_BITS};
use crate::topology::{Topology, Tree};
use crate::trace::{PacketId, PacketKind, PacketRecord, Trace, TraceEntry, TraceEvent};

/// Names a node added to a [`Bus`] (its index, in order of addition).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub struct NodeHandle(pub usize);

/// The PHY of a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// Number of cable ports (1394a PHYs have 1 to 16).
    pub ports: u8,
    /// Fastest speed the PHY supports.
    pub max_speed: Speed,
}

impl Default for NodeConfig {
    fn default() -> Self {
        NodeConfig {
            ports: 3,
            max_speed: Speed::S400,
        }
    }
}

impl NodeConfig {
    /// A PC FireWire card: 3 ports, S400.
    pub fn pc() -> NodeConfig {
        NodeConfig::default()
    }

    /// An FPGA1394 board: 2 ports, S400.
    pub fn board() -> NodeConfig {
        NodeConfig {
            ports: 2,
            max_speed: Speed::S400,
        }
    }

    /// The same with `ports` ports.
    pub fn with_ports(mut self, ports: u8) -> NodeConfig {
        self.ports = ports;
        self
    }

    /// The same with maximum speed `speed`.
    pub fn with_speed(mut self, speed: Speed) -> NodeConfig {
        self.max_speed = speed;
        self
    }
}

/// How much the bus records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum TraceLevel {
    /// Nothing (fastest).
    Off,
    /// Packet records only.
    Packets,
    /// Packet records and bus events (default).
    Normal,
    /// Also every delivery and idle period.
    Verbose,
}

/// Configuration of a [`Bus`].
#[derive(Clone, Debug, PartialEq)]
pub struct BusConfig {
    /// Timing figures.
    pub timing: BusTiming,
    /// Seed of the fault injector's RNG.
    pub seed: u64,
    /// Whether the root acts as cycle master (cycle start every 125 us).
    /// Off by default, as in seed 000.
    pub cycle_master: bool,
    /// What to record.
    pub trace: TraceLevel,
    /// Reset the bus when a cable is connected or disconnected (after the
    /// first reset).
    pub auto_reset: bool,
    /// Enforce the fairness interval for fair requests.
    pub fairness: bool,
    /// Longest packet the bus accepts from a node, in bytes.
    pub max_packet_len: usize,
}

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig {
            timing: BusTiming::default(),
            seed: 0,
            cycle_master: false,
            trace: TraceLevel::Normal,
            auto_reset: true,
            fairness: true,
            max_packet_len: 8192,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Medium {
    Idle { since: SimTime },
    Busy,
    Resetting,
}

#[derive(Debug)]
struct Pending {
    bytes: Arc<[u8]>,
    speed: Speed,
    class: ArbitrationClass,
    token: Option<u64>,
    kind: PacketKind,
    ready_at: SimTime,
    delayed: bool,
    faults: Vec<FaultId>,
}

#[derive(Debug, Clone, Copy)]
struct BabbleState {
    until: SimTime,
    len: usize,
    fault: FaultId,
}

struct Slot {
    node: Option<Box<dyn Node>>,
    name: String,
    cfg: NodeConfig,
    regs: PhyRegisters,
    phy: Option<u8>,
    queue: VecDeque<Pending>,
    arb_enable: bool,
    timers: BTreeMap<u64, u64>,
    muted: bool,
    mute_fault: Option<FaultId>,
    babble: Option<BabbleState>,
}

#[derive(Debug)]
struct Sub {
    id: PacketId,
    kind: PacketKind,
    sender: usize,
    sender_phy: u8,
    bytes: Arc<[u8]>,
    speed: Speed,
    token: Option<u64>,
    dest: Option<usize>,
    reply: Option<RxReply>,
    end: SimTime,
    faults: Vec<FaultId>,
    drop_ack: bool,
    corrupt_ack: bool,
    dropped: bool,
    notified: bool,
    answers: Option<PacketId>,
}

#[derive(Debug)]
enum Ev {
    Timer {
        node: usize,
        token: u64,
        stamp: u64,
    },
    Arbitrate,
    TxStart {
        sub: PacketId,
        arb_start: Option<SimTime>,
        class: Option<ArbitrationClass>,
    },
    Deliver {
        sub: PacketId,
        node: usize,
    },
    AckStart {
        sub: PacketId,
    },
    Notify {
        node: usize,
        token: Option<u64>,
        kind: PacketKind,
        ack: Option<Ack>,
    },
    SubEnd {
        sub: PacketId,
    },
    ResetDone,
    CycleTick,
    Timed(usize),
    Reconnect {
        links: Box<[(usize, u8, usize, u8)]>,
        fault: FaultId,
    },
    Unmute {
        node: usize,
    },
    PacketEnd(PacketId),
    NoAck(Box<NoAckInfo>),
}

#[derive(Debug)]
struct NoAckInfo {
    packet: PacketId,
    node: usize,
    token: Option<u64>,
    kind: PacketKind,
    faults: Vec<FaultId>,
}

#[derive(Debug)]
struct Queued {
    time: SimTime,
    seq: u64,
    epoch: Option<u64>,
    ev: Ev,
}

impl PartialEq for Queued {
    fn eq(&self, other: &Self) -> bool {
        (self.time, self.seq) == (other.time, other.seq)
    }
}
impl Eq for Queued {}
impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Queued {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.time, self.seq).cmp(&(other.time, other.seq))
    }
}

/// A simulated 1394a bus. See the module docs.
pub struct Bus {
    cfg: BusConfig,
    now: SimTime,
    slots: Vec<Slot>,
    topo: Topology,
    tree: Tree,
    root: Option<usize>,
    generation: u32,
    started: bool,
    events: BinaryHeap<Reverse<Queued>>,
    seq: u64,
    epoch: u64,
    medium: Medium,
    subs: BTreeMap<PacketId, Sub>,
    next_id: PacketId,
    arb_at: Option<SimTime>,
    trace: Trace,
    injector: FaultInjector,
    log: FaultLog,
    timed: Vec<TimedFault>,
    reset_faults: Vec<FaultId>,
    gap_set_since_reset: bool,
    cycle_tick_scheduled: bool,
    current_rx: Option<(PacketId, Vec<FaultId>)>,
    scratch: Commands,
    timer_stamp: u64,
    reset_began: SimTime,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("now", &self.now)
            .field("nodes", &self.slots.len())
            .field("generation", &self.generation)
            .finish_non_exhaustive()
    }
}

impl Bus {
    /// An empty bus.
    pub fn new(cfg: BusConfig) -> Bus {
        let injector = FaultInjector::new(cfg.seed);
        Bus {
            cfg,
            now: SimTime::ZERO,
            slots: Vec::new(),
            topo: Topology::default(),
            tree: Tree::default(),
            root: None,
            generation: 0,
            started: false,
            events: BinaryHeap::new(),
            seq: 0,
            epoch: 0,
            medium: Medium::Idle {
                since: SimTime::ZERO,
            },
            subs: BTreeMap::new(),
            next_id: 0,
            arb_at: None,
            trace: Trace::default(),
            injector,
            log: FaultLog::default(),
            timed: Vec::new(),
            reset_faults: Vec::new(),
            gap_set_since_reset: false,
            cycle_tick_scheduled: false,
            current_rx: None,
            scratch: Commands::default(),
            timer_stamp: 0,
            reset_began: SimTime::ZERO,
        }
    }

    // ----- building -------------------------------------------------------

    /// Add a node with its PHY configuration. The first node added is the
    /// root unless [`set_root`](Self::set_root) says otherwise.
    pub fn add_node(&mut self, node: Box<dyn Node>, cfg: NodeConfig) -> NodeHandle {
        let name = node.name().to_string();
        let index = self.topo.add_node(cfg.ports);
        self.trace.names.push(name.clone());
        self.slots.push(Slot {
            node: Some(node),
            name,
            cfg,
            regs: PhyRegisters::new(cfg.ports, cfg.max_speed),
            phy: None,
            queue: VecDeque::new(),
            arb_enable: true,
            timers: BTreeMap::new(),
            muted: false,
            mute_fault: None,
            babble: None,
        });
        if self.root.is_none() {
            self.root = Some(index);
        }
        NodeHandle(index)
    }

    /// [`add_node`](Self::add_node) for a node by value.
    pub fn add<N: Node>(&mut self, node: N, cfg: NodeConfig) -> NodeHandle {
        self.add_node(Box::new(node), cfg)
    }

    /// Make `node` the root at the next reset (as a PC with force-root would
    /// be; it then gets the highest physical ID).
    pub fn set_root(&mut self, node: NodeHandle) -> Result<(), BusError> {
        self.check(node)?;
        self.root = Some(node.0);
        Ok(())
    }

    fn check(&self, node: NodeHandle) -> Result<(), BusError> {
        if node.0 < self.slots.len() {
            Ok(())
        } else {
            Err(BusError::NoSuchNode(node.0))
        }
    }

    /// Join the lowest free ports of `a` and `b` with a cable.
    ///
    /// # Errors
    /// See [`Topology::connect`].
    pub fn connect(&mut self, a: NodeHandle, b: NodeHandle) -> Result<(), BusError> {
        self.topo.connect(a.0, b.0)?;
        self.topology_changed("cable connected");
        Ok(())
    }

    /// Join port `pa` of `a` and port `pb` of `b`.
    ///
    /// # Errors
    /// See [`Topology::connect_ports`].
    pub fn connect_ports(
        &mut self,
        a: NodeHandle,
        pa: u8,
        b: NodeHandle,
        pb: u8,
    ) -> Result<(), BusError> {
        self.topo.connect_ports(a.0, pa, b.0, pb)?;
        self.topology_changed("cable connected");
        Ok(())
    }

    /// Remove the cable between `a` and `b`.
    ///
    /// # Errors
    /// [`BusError::NotConnected`].
    pub fn disconnect(&mut self, a: NodeHandle, b: NodeHandle) -> Result<(), BusError> {
        self.topo.disconnect(a.0, b.0)?;
        self.topology_changed("cable disconnected");
        Ok(())
    }

    /// Connect `nodes` in a daisy chain: `nodes[0]` - `nodes[1]` - ... The
    /// dVRK wiring is `daisy_chain(&[pc, board_a, board_b, ...])`; self-ID
    /// then gives the far end physical ID 0.
    ///
    /// # Errors
    /// See [`connect`](Self::connect).
    pub fn daisy_chain(&mut self, nodes: &[NodeHandle]) -> Result<(), BusError> {
        for pair in nodes.windows(2) {
            self.connect(pair[0], pair[1])?;
        }
        Ok(())
    }

    /// Connect `root` to the first node of each chain, and each chain as a
    /// daisy chain (e.g. a 3-port PC card with a chain on each port, as in
    /// seed 002's humanoid).
    ///
    /// # Errors
    /// See [`connect`](Self::connect).
    pub fn tree_with_chains(
        &mut self,
        root: NodeHandle,
        chains: &[&[NodeHandle]],
    ) -> Result<(), BusError> {
        for chain in chains {
            if let Some(&first) = chain.first() {
                self.connect(root, first)?;
                self.daisy_chain(chain)?;
            }
        }
        Ok(())
    }

    fn topology_changed(&mut self, cause: &str) {
        if self.started && self.cfg.auto_reset {
            self.start_reset(false, cause.to_string());
        }
    }

    // ----- faults -----------------------------------------------------------

    /// Install a fault plan (added to any earlier rules and timed faults).
    pub fn set_fault_plan(&mut self, plan: FaultPlan) {
        for rule in plan.rules {
            self.injector.add_rule(rule);
        }
        for (at, fault) in plan.timed {
            self.schedule_fault(at, fault);
        }
    }

    /// Add one packet fault rule.
    pub fn add_fault_rule(&mut self, rule: FaultRule) {
        self.injector.add_rule(rule);
    }

    /// Change the chance of every packet fault rule by `factor` (clamped
    /// to 0..=1): a soak keeps the faulted share of packets where it wants
    /// it as the traffic mix changes.
    pub fn scale_fault_probabilities(&mut self, factor: f64) {
        self.injector.scale_probabilities(factor);
    }

    /// Schedule a timed fault.
    pub fn schedule_fault(&mut self, at: SimTime, fault: TimedFault) {
        self.timed.push(fault);
        let index = self.timed.len() - 1;
        self.push(at.max(self.now), None, Ev::Timed(index));
    }

    /// Every fault injected so far.
    pub fn fault_log(&self) -> &FaultLog {
        &self.log
    }

    /// Record that something above the bus (a host library, a test)
    /// detected fault `id`.
    pub fn record_detection(&mut self, id: FaultId, node: NodeHandle, what: impl Into<String>) {
        self.log.add_evidence(
            id,
            Evidence {
                time: self.now,
                node: node.0,
                kind: EvidenceKind::Report(what.into()),
            },
        );
    }

    // ----- inspection ---------------------------------------------------------

    /// The current virtual time.
    pub fn now(&self) -> SimTime {
        self.now
    }

    /// The configuration.
    pub fn config(&self) -> &BusConfig {
        &self.cfg
    }

    /// The timing figures.
    pub fn timing(&self) -> &BusTiming {
        &self.cfg.timing
    }

    /// The bus generation (0 before the first reset).
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// Nodes added (on the bus or not).
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether no node was added.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Nodes on the bus after the last reset.
    pub fn node_count(&self) -> usize {
        self.tree.node_count()
    }

    /// Physical ID of `node` (`None` before the first reset or when it is
    /// not on the bus).
    pub fn phy_id(&self, node: NodeHandle) -> Option<u8> {
        self.slots.get(node.0).and_then(|s| s.phy)
    }

    /// The node with physical ID `phy`.
    pub fn node_by_phy(&self, phy: u8) -> Option<NodeHandle> {
        self.tree
            .by_phy
            .get(usize::from(phy))
            .map(|&i| NodeHandle(i))
    }

    /// Handles in physical-ID order.
    pub fn nodes_by_phy(&self) -> Vec<NodeHandle> {
        self.tree.by_phy.iter().map(|&i| NodeHandle(i)).collect()
    }

    /// The root (after the last reset).
    pub fn root(&self) -> Option<NodeHandle> {
        (self.tree.node_count() > 0).then_some(NodeHandle(self.tree.root))
    }

    /// Hops between two nodes on the bus (0 if either is not on it).
    pub fn hops(&self, a: NodeHandle, b: NodeHandle) -> u32 {
        match (self.phy_id(a), self.phy_id(b)) {
            (Some(pa), Some(pb)) => self.tree.hops(pa, pb),
            _ => 0,
        }
    }

    /// A node's PHY registers.
    pub fn phy_registers(&self, node: NodeHandle) -> Option<&PhyRegisters> {
        self.slots.get(node.0).map(|s| &s.regs)
    }

    /// A node's gap count.
    pub fn gap_count(&self, node: NodeHandle) -> Option<u8> {
        self.phy_registers(node).map(PhyRegisters::gap_count)
    }

    /// The node's name.
    pub fn name(&self, node: NodeHandle) -> Option<&str> {
        self.slots.get(node.0).map(|s| s.name.as_str())
    }

    /// The node, if it is a `T`.
    pub fn node<T: Node>(&self, node: NodeHandle) -> Option<&T> {
        let boxed = self.slots.get(node.0)?.node.as_ref()?;
        boxed.as_ref().as_any().downcast_ref::<T>()
    }

    /// The node, mutably, if it is a `T`. Changes made here happen outside
    /// virtual time; to let the node transmit or set timers use
    /// [`with_node`](Self::with_node).
    pub fn node_mut<T: Node>(&mut self, node: NodeHandle) -> Option<&mut T> {
        let boxed = self.slots.get_mut(node.0)?.node.as_mut()?;
        boxed.as_mut().as_any_mut().downcast_mut::<T>()
    }

    /// Run `f` on the node (if it is a `T`) with a [`NodeCtx`] at the
    /// current time, as if the node were in a callback: what it asks for
    /// (transmit, timers) is applied afterwards. This is how a host library
    /// drives [`HostLink`](crate::host::HostLink).
    ///
    /// # Errors
    /// [`BusError::NoSuchNode`], [`BusError::WrongNodeType`].
    pub fn with_node<T: Node, R>(
        &mut self,
        node: NodeHandle,
        f: impl FnOnce(&mut T, &mut NodeCtx<'_>) -> R,
    ) -> Result<R, BusError> {
        let slot = self.slots.get(node.0).ok_or(BusError::NoSuchNode(node.0))?;
        let boxed = slot.node.as_ref().ok_or(BusError::NodeBusy(node.0))?;
        if !boxed.as_ref().as_any().is::<T>() {
            return Err(BusError::WrongNodeType(node.0));
        }
        self.dispatch_any(node.0, |n, ctx| {
            n.as_any_mut().downcast_mut::<T>().map(|t| f(t, ctx))
        })
        .flatten()
        .ok_or(BusError::WrongNodeType(node.0))
    }

    /// Packets put on the wire so far (requests, responses, acks,
    /// duplicates, babble; self-ID and PHY packets included), whether or
    /// not a trace is kept.
    pub fn packets_sent(&self) -> u64 {
        self.next_id
    }

    /// The trace recorded so far.
    pub fn trace(&self) -> &Trace {
        &self.trace
    }

    /// The trace, mutably (e.g. to [`clear`](Trace::clear) it).
    pub fn trace_mut(&mut self) -> &mut Trace {
        &mut self.trace
    }

    /// The compact text timeline of the trace.
    pub fn timeline(&self) -> String {
        self.trace.timeline()
    }

    /// Write the trace as a pcap file (see [`crate::pcap`]).
    ///
    /// # Errors
    /// I/O errors of `out`.
    pub fn write_pcap(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        crate::pcap::write_pcap(&self.trace, out)
    }

    /// Whether the bus is idle now (no packet, ack or reset in progress).
    pub fn is_idle(&self) -> bool {
        matches!(self.medium, Medium::Idle { .. })
    }

    /// Whether any packet is in progress or waiting to be sent, or a reset
    /// is under way.
    pub fn has_pending_traffic(&self) -> bool {
        !matches!(self.medium, Medium::Idle { .. })
            || self.slots.iter().any(|s| !s.queue.is_empty())
    }

    // ----- running ------------------------------------------------------------

    /// Reset the bus now (a long reset, as after a cable change) and run the
    /// simulation until self-ID is done and every node knows its new ID.
    pub fn reset(&mut self) {
        self.initiate_reset(false);
        let generation = self.generation;
        self.run_until_with(SimTime::MAX, |bus| bus.generation != generation);
    }

    /// Start a bus reset now without running it (`short`: an arbitrated
    /// short reset of 1.3 us instead of 166.7 us).
    pub fn initiate_reset(&mut self, short: bool) {
        self.start_reset(short, "requested".to_string());
    }

    /// Time of the next event, if any.
    pub fn next_event_time(&self) -> Option<SimTime> {
        self.events.peek().map(|Reverse(q)| q.time)
    }

    /// Process the next event. Returns false if there was none.
    pub fn step(&mut self) -> bool {
        let Some(Reverse(q)) = self.events.pop() else {
            return false;
        };
        self.now = self.now.max(q.time);
        if q.epoch.is_some_and(|e| e != self.epoch) {
            return true;
        }
        self.handle(q.ev);
        true
    }

    /// Process every event up to and including `t`; the clock then reads `t`.
    pub fn run_until(&mut self, t: SimTime) {
        while self.next_event_time().is_some_and(|n| n <= t) {
            self.step();
        }
        self.now = self.now.max(t);
    }

    /// Run for `d` of virtual time.
    pub fn run_for(&mut self, d: SimDuration) {
        let t = self.now + d;
        self.run_until(t);
    }

    /// Process events until `done(self)` holds (checked before each event)
    /// or the next event is after `deadline`. Returns whether `done` held.
    pub fn run_until_with(
        &mut self,
        deadline: SimTime,
        mut done: impl FnMut(&Bus) -> bool,
    ) -> bool {
        loop {
            if done(self) {
                return true;
            }
            match self.next_event_time() {
                Some(t) if t <= deadline => {
                    self.step();
                }
                _ => return done(self),
            }
        }
    }

    /// Process events until nothing is left but cycle-start ticks (or the
    /// queue is empty), for at most one second of virtual time. Returns
    /// whether that state was reached. Nodes with periodic timers never let
    /// the bus become idle: use [`run_until`](Self::run_until) for them.
    pub fn run_until_idle(&mut self) -> bool {
        let limit = self.now + SimDuration::from_millis(1000);
        loop {
            let only_ticks = self
                .events
                .iter()
                .all(|Reverse(q)| matches!(q.ev, Ev::CycleTick));
            if only_ticks && self.is_idle() && !self.has_pending_traffic() {
                return true;
            }
            match self.next_event_time() {
                Some(t) if t <= limit => {
                    self.step();
                }
                _ => return false,
            }
        }
    }

    // ----- internals: events --------------------------------------------------

    fn push(&mut self, time: SimTime, epoch: Option<u64>, ev: Ev) {
        self.seq += 1;
        self.events.push(Reverse(Queued {
            time,
            seq: self.seq,
            epoch,
            ev,
        }));
    }

    fn push_epoch(&mut self, time: SimTime, ev: Ev) {
        self.push(time, Some(self.epoch), ev);
    }

    fn log_event(&mut self, event: TraceEvent) {
        if self.cfg.trace >= TraceLevel::Normal {
            self.trace.entries.push(TraceEntry {
                time: self.now,
                event,
            });
        }
    }

    fn note(&mut self, text: String) {
        self.log_event(TraceEvent::Note(text));
    }

    fn handle(&mut self, ev: Ev) {
        match ev {
            Ev::Timer { node, token, stamp } => self.fire_timer(node, token, stamp),
            Ev::Arbitrate => {
                if self.arb_at == Some(self.now) {
                    self.arb_at = None;
                }
                self.arbitrate();
            }
            Ev::TxStart {
                sub,
                arb_start,
                class,
            } => self.tx_start(sub, arb_start, class),
            Ev::Deliver { sub, node } => self.deliver(sub, node),
            Ev::AckStart { sub } => self.ack_start(sub),
            Ev::Notify {
                node,
                token,
                kind,
                ack,
            } => self.notify(node, token, kind, ack),
            Ev::SubEnd { sub } => self.sub_end(sub),
            Ev::ResetDone => self.reset_done(),
            Ev::CycleTick => self.cycle_tick(),
            Ev::Timed(i) => self.timed_fault(i),
            Ev::Reconnect { links, fault } => self.reconnect(&links, fault),
            Ev::PacketEnd(id) => self.log_event(TraceEvent::PacketEnd(id)),
            Ev::NoAck(info) => {
                let NoAckInfo {
                    packet,
                    node,
                    token,
                    kind,
                    faults,
                } = *info;
                self.log_event(TraceEvent::NoAck { packet });
                for f in faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: self.now,
                            node,
                            kind: EvidenceKind::NoAck,
                        },
                    );
                }
                self.notify(node, token, kind, None);
            }
            Ev::Unmute { node } => {
                if let Some(s) = self.slots.get_mut(node) {
                    s.muted = false;
                }
                self.note(format!("{} answers again", self.trace.name_of(node)));
            }
        }
    }

    fn schedule_arbitration(&mut self, at: SimTime) {
        let at = at.max(self.now);
        if self.arb_at.is_none_or(|t| at < t) {
            self.arb_at = Some(at);
            self.push(at, None, Ev::Arbitrate);
        }
    }

    // ----- node callbacks -------------------------------------------------------

    fn dispatch_any<R>(
        &mut self,
        idx: usize,
        f: impl FnOnce(&mut dyn Node, &mut NodeCtx<'_>) -> R,
    ) -> Option<R> {
        let now = self.now;
        let generation = self.generation;
        let node_count = self.tree.node_count().min(63) as u8;
        let bus_idle = matches!(self.medium, Medium::Idle { .. });
        let slot = self.slots.get_mut(idx)?;
        let mut node = slot.node.take()?;
        let mut regs = slot.regs;
        let phy_id = slot.phy.unwrap_or(NodeId::BROADCAST_PHY);
        let mut cmds = std::mem::take(&mut self.scratch);
        let result = {
            let mut ctx = NodeCtx {
                now,
                phy_id,
                generation,
                node_count,
                bus_idle,
                regs: &mut regs,
                cmds: &mut cmds,
            };
            f(node.as_mut(), &mut ctx)
        };
        if let Some(slot) = self.slots.get_mut(idx) {
            slot.node = Some(node);
        }
        if !cmds.is_empty() || regs != self.slots[idx].regs {
            self.apply(idx, regs, &mut cmds);
        }
        cmds.transmits.clear();
        cmds.timers.clear();
        cmds.phy_writes.clear();
        cmds.reports.clear();
        self.scratch = cmds;
        Some(result)
    }

    /// Dispatch to a node unless it stopped answering.
    fn dispatch<R>(
        &mut self,
        idx: usize,
        f: impl FnOnce(&mut dyn Node, &mut NodeCtx<'_>) -> R,
    ) -> Option<R> {
        if self.slots.get(idx).is_none_or(|s| s.muted) {
            return None;
        }
        self.dispatch_any(idx, f)
    }

    fn apply(&mut self, idx: usize, regs: PhyRegisters, cmds: &mut Commands) {
        let now = self.now;
        let mut reset: Option<bool> = None;
        {
            let slot = &mut self.slots[idx];
            let old_gap = slot.regs.gap_count();
            slot.regs = regs;
            if slot.regs.take_ibr() {
                reset = Some(false);
            }
            if slot.regs.take_isbr() {
                reset = reset.or(Some(true));
            }
            if slot.regs.gap_count() != old_gap {
                let text = format!(
                    "{} gap count {} -> {} (register write)",
                    slot.name,
                    old_gap,
                    slot.regs.gap_count()
                );
                self.note(text);
            }
        }
        for report in cmds.reports.drain(..) {
            let packet = self.current_rx.as_ref().map(|(p, _)| *p);
            if let Some((_, faults)) = &self.current_rx {
                for &f in faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: now,
                            node: idx,
                            kind: EvidenceKind::Report(report.clone()),
                        },
                    );
                }
            }
            self.log_event(TraceEvent::Report {
                node: idx,
                text: report,
                packet,
            });
        }
        for cmd in cmds.timers.drain(..) {
            match cmd {
                TimerCommand::Set { at, token } => {
                    self.timer_stamp += 1;
                    let stamp = self.timer_stamp;
                    self.slots[idx].timers.insert(token, stamp);
                    self.push(
                        at.max(now),
                        None,
                        Ev::Timer {
                            node: idx,
                            token,
                            stamp,
                        },
                    );
                }
                TimerCommand::Cancel { token } => {
                    self.slots[idx].timers.remove(&token);
                }
            }
        }
        let mut want_arb = false;
        for req in cmds.transmits.drain(..) {
            let TransmitRequest {
                packet,
                speed,
                class,
                token,
            } = req;
            let slot = &self.slots[idx];
            let refuse = if packet.len() > self.cfg.max_packet_len {
                Some(format!(
                    "{} bytes is longer than the bus accepts",
                    packet.len()
                ))
            } else if slot.muted {
                Some("node stopped answering".to_string())
            } else if slot.phy.is_none() && self.medium != Medium::Resetting {
                Some("node is not on the bus".to_string())
            } else {
                None
            };
            if let Some(why) = refuse {
                let text = format!("{}: transmit refused: {why}", slot.name);
                self.note(text);
                self.push(
                    now,
                    None,
                    Ev::Notify {
                        node: idx,
                        token: Some(token),
                        kind: PacketKind::Request,
                        ack: None,
                    },
                );
                continue;
            }
            self.slots[idx].queue.push_back(Pending {
                bytes: Arc::from(packet),
                speed,
                class,
                token: Some(token),
                kind: PacketKind::Request,
                ready_at: now,
                delayed: false,
                faults: Vec::new(),
            });
            want_arb = true;
        }
        if !cmds.phy_writes.is_empty() {
            cmds.phy_writes.clear();
        }
        if want_arb && self.is_idle() {
            self.schedule_arbitration(now);
        }
        if let Some(short) = reset {
            self.start_reset(short, format!("{} set IBR/ISBR", self.slots[idx].name));
        }
    }

    fn fire_timer(&mut self, node: usize, token: u64, stamp: u64) {
        let Some(slot) = self.slots.get_mut(node) else {
            return;
        };
        if slot.timers.get(&token) != Some(&stamp) {
            return;
        }
        slot.timers.remove(&token);
        let now = self.now;
        self.dispatch(node, |n, ctx| n.on_timer(now, token, ctx));
    }

    fn notify(&mut self, node: usize, token: Option<u64>, kind: PacketKind, ack: Option<Ack>) {
        let now = self.now;
        match (kind, token) {
            (PacketKind::Request, Some(token)) => {
                self.dispatch(node, |n, ctx| n.on_transmitted(now, token, ack, ctx));
            }
            (PacketKind::ConcatResponse, _) => {
                self.dispatch(node, |n, ctx| n.on_response_acked(now, ack, ctx));
            }
            _ => {}
        }
    }

    // ----- arbitration ----------------------------------------------------------

    fn needed_gap(&self, slot: &Slot, pending: &Pending) -> SimDuration {
        let t = &self.cfg.timing;
        let g = slot.regs.gap_count();
        if pending.kind == PacketKind::CycleStart {
            return t.subaction_gap(g);
        }
        match pending.class {
            ArbitrationClass::Isochronous => t.iso_gap,
            ArbitrationClass::Priority => t.subaction_gap(g),
            ArbitrationClass::Fair => {
                if self.cfg.fairness && !slot.arb_enable {
                    t.arb_reset_gap(g)
                } else {
                    t.subaction_gap(g)
                }
            }
        }
    }

    fn refill_babblers(&mut self) {
        let now = self.now;
        for i in 0..self.slots.len() {
            let Some(b) = self.slots[i].babble else {
                continue;
            };
            if now >= b.until {
                self.slots[i].babble = None;
                self.slots[i].queue.retain(|p| p.kind != PacketKind::Babble);
                continue;
            }
            if self.slots[i]
                .queue
                .iter()
                .any(|p| p.kind == PacketKind::Babble)
            {
                continue;
            }
            let mut bytes = vec![0u8; b.len];
            self.injector.rng.fill_bytes(&mut bytes);
            let speed = self.slots[i].cfg.max_speed;
            self.slots[i].queue.push_front(Pending {
                bytes: Arc::from(bytes),
                speed,
                class: ArbitrationClass::Isochronous,
                token: None,
                kind: PacketKind::Babble,
                ready_at: now,
                delayed: true,
                faults: vec![b.fault],
            });
        }
    }

    fn arbitrate(&mut self) {
        loop {
            let Medium::Idle { since } = self.medium else {
                return;
            };
            let now = self.now;
            self.refill_babblers();
            let hop = self.cfg.timing.hop_delay;
            // (arrival at root, not-urgent, depth, phy, index, eligible)
            let mut best: Option<(SimTime, u8, u32, u8, usize, SimTime)> = None;
            for (i, slot) in self.slots.iter().enumerate() {
                let (Some(phy), Some(p)) = (slot.phy, slot.queue.front()) else {
                    continue;
                };
                if slot.muted {
                    continue;
                }
                let eligible = p.ready_at.max(since + self.needed_gap(slot, p));
                let depth = self.tree.depth.get(i).copied().unwrap_or(0);
                let at_root = eligible + hop * u64::from(depth);
                let urgent = u8::from(p.kind != PacketKind::CycleStart);
                let key = (at_root, urgent, depth, phy, i, eligible);
                if best.is_none_or(|b| key < b) {
                    best = Some(key);
                }
            }
            let Some((at_root, _, depth, phy, idx, eligible)) = best else {
                return;
            };
            if at_root > now {
                self.schedule_arbitration(at_root);
                return;
            }
            // A new fairness interval for every PHY that saw an arbitration
            // reset gap.
            let idle = now - since;
            for slot in &mut self.slots {
                if idle >= self.cfg.timing.arb_reset_gap(slot.regs.gap_count()) {
                    slot.arb_enable = true;
                }
            }
            let Some(mut pending) = self.slots[idx].queue.pop_front() else {
                return;
            };
            let handle = NodeHandle(idx);
            // Delay faults first: the packet goes back to wait.
            if !self.injector.is_empty() && !pending.delayed && pending.kind == PacketKind::Request
            {
                let d = self
                    .injector
                    .decide_delay(handle, pending.kind, &pending.bytes, now);
                if let Some((delay, what, rule)) = d {
                    let source = rule.map(FaultSource::Rule);
                    let id = self.log.add(now, what.clone(), None, Some(idx), source);
                    self.log_event(TraceEvent::Fault { id, what });
                    pending.delayed = true;
                    pending.ready_at = now + delay;
                    pending.faults.push(id);
                    self.slots[idx].queue.push_front(pending);
                    continue;
                }
            }
            let start = now + hop * u64::from(depth) + self.cfg.timing.arbitration_base;
            if pending.kind == PacketKind::CycleStart {
                pending.bytes = Arc::from(cycle_start_packet(phy, start));
            }
            if pending.class == ArbitrationClass::Fair && pending.kind != PacketKind::CycleStart {
                self.slots[idx].arb_enable = false;
            }
            self.medium = Medium::Busy;
            self.log_event(TraceEvent::Arbitration {
                node: idx,
                class: pending.class,
                requested: eligible,
            });
            let id = self.next_id;
            self.next_id += 1;
            let mut sub = Sub {
                id,
                kind: pending.kind,
                sender: idx,
                sender_phy: phy,
                bytes: pending.bytes.clone(),
                speed: pending.speed,
                token: pending.token,
                dest: None,
                reply: None,
                end: start,
                faults: pending.faults.clone(),
                drop_ack: false,
                corrupt_ack: false,
                dropped: false,
                notified: false,
                answers: None,
            };
            let duplicate = self.decide_faults(&mut sub, now);
            if duplicate {
                self.slots[idx].queue.push_front(Pending {
                    bytes: pending.bytes.clone(),
                    speed: pending.speed,
                    class: pending.class,
                    token: None,
                    kind: PacketKind::Duplicate,
                    ready_at: now,
                    delayed: true,
                    faults: sub.faults.clone(),
                });
            }
            self.subs.insert(id, sub);
            self.push_epoch(
                start,
                Ev::TxStart {
                    sub: id,
                    arb_start: Some(eligible),
                    class: Some(pending.class),
                },
            );
            return;
        }
    }

    /// Decide and apply packet faults (other than delay) to a packet about
    /// to start. Returns whether a duplicate must follow.
    fn decide_faults(&mut self, sub: &mut Sub, now: SimTime) -> bool {
        if self.injector.is_empty()
            || matches!(sub.kind, PacketKind::Duplicate | PacketKind::Babble)
        {
            return false;
        }
        let d = self
            .injector
            .decide(NodeHandle(sub.sender), sub.kind, &sub.bytes, now);
        if d.fired.is_empty() {
            return false;
        }
        if !d.mutations.is_empty() || d.truncate.is_some() {
            let mut bytes = sub.bytes.to_vec();
            for m in &d.mutations {
                m.apply(&mut bytes);
            }
            if let Some(keep) = d.truncate {
                bytes.truncate(keep.max(4));
            }
            sub.bytes = Arc::from(bytes);
        }
        for (what, _, rule) in d.fired {
            let id = self.log.add(
                now,
                what.clone(),
                Some(sub.id),
                Some(sub.sender),
                Some(FaultSource::Rule(rule)),
            );
            self.log_event(TraceEvent::Fault { id, what });
            sub.faults.push(id);
        }
        sub.drop_ack |= d.drop_ack;
        sub.corrupt_ack |= d.corrupt_ack;
        sub.dropped |= d.drop;
        d.duplicate
    }

    // ----- transmission ---------------------------------------------------------

    fn tx_start(
        &mut self,
        id: PacketId,
        arb_start: Option<SimTime>,
        class: Option<ArbitrationClass>,
    ) {
        let now = self.now;
        let t = self.cfg.timing;
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        let dropped = sub.dropped;
        let is_phy_packet = sub.bytes.len() >= 12
            && sub
                .bytes
                .get(3)
                .is_some_and(|b| b >> 4 == u8::from(Tcode::LinkInternal));
        let bits = if is_phy_packet {
            t.bits(PHY_PACKET_BITS, sub.speed)
        } else {
            t.payload_time(sub.bytes.len(), sub.speed)
        };
        let prefix = if sub.kind == PacketKind::ConcatResponse {
            t.concat_prefix
        } else {
            t.data_prefix
        };
        let bits_end = now + prefix + bits;
        let end = bits_end + t.data_end;
        sub.end = end;
        let sender = sub.sender;
        let sender_phy = sub.sender_phy;
        let speed = sub.speed;
        let kind = sub.kind;
        let token = sub.token;
        let dest_phy = sub.bytes.get(1).map(|b| b & 0x3F);
        let unicast = !is_phy_packet
            && !matches!(kind, PacketKind::CycleStart | PacketKind::Ack)
            && dest_phy.is_some_and(|d| d != NodeId::BROADCAST_PHY);
        if self.cfg.trace >= TraceLevel::Packets {
            self.trace.packets.push(PacketRecord {
                id,
                kind,
                sender,
                sender_phy,
                arb_start,
                class,
                start: now,
                bits_end,
                end,
                speed,
                bytes: sub.bytes.clone(),
                answers: sub.answers,
                generation: self.generation,
                faults: sub.faults.clone(),
            });
        }
        self.log_event(TraceEvent::PacketStart(id));
        // Deliveries.
        let mut dest_receives = false;
        let mut dest_node = None;
        let mut mute_fault = None;
        if let Some(d) = dest_phy.filter(|_| unicast) {
            dest_node = self.tree.by_phy.get(usize::from(d)).copied();
        }
        for phy in 0..self.tree.by_phy.len() {
            let node = self.tree.by_phy[phy];
            let phy = phy as u8;
            if node == sender {
                continue;
            }
            let slot = &self.slots[node];
            if slot.muted {
                if Some(node) == dest_node {
                    mute_fault = slot.mute_fault;
                }
                continue;
            }
            if dropped || speed > self.tree.path_speed(sender_phy, phy) {
                continue;
            }
            if Some(node) == dest_node {
                dest_receives = true;
            }
            let at = bits_end + t.hop_delay * u64::from(self.tree.hops(sender_phy, phy));
            self.push_epoch(at, Ev::Deliver { sub: id, node });
        }
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        if let Some(f) = mute_fault {
            sub.faults.push(f);
        }
        let idle_at = end + t.hop_delay * u64::from(self.tree.eccentricity(sender_phy));
        if unicast && dest_receives {
            let dest = dest_node.unwrap_or(0);
            sub.dest = Some(dest);
            let dest_phy = self.slots[dest].phy.unwrap_or(0);
            let at =
                end + t.hop_delay * u64::from(self.tree.hops(sender_phy, dest_phy)) + t.ack_gap;
            self.push_epoch(at, Ev::AckStart { sub: id });
        } else {
            if !unicast && kind == PacketKind::Request {
                sub.notified = true;
                self.push(
                    end,
                    None,
                    Ev::Notify {
                        node: sender,
                        token,
                        kind,
                        ack: None,
                    },
                );
            }
            if unicast {
                self.no_ack(id, idle_at);
            }
            self.push_epoch(idle_at, Ev::SubEnd { sub: id });
        }
        if self.cfg.trace >= TraceLevel::Normal {
            self.push_epoch(end, Ev::PacketEnd(id));
        }
    }

    fn no_ack(&mut self, id: PacketId, idle_at: SimTime) {
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        sub.notified = true;
        if sub.kind == PacketKind::Babble {
            return;
        }
        let gap = self.slots[sub.sender].regs.gap_count();
        let at = idle_at + self.cfg.timing.subaction_gap(gap);
        let ev = Ev::NoAck(Box::new(NoAckInfo {
            packet: sub.id,
            node: sub.sender,
            token: sub.token,
            kind: sub.kind,
            faults: sub.faults.clone(),
        }));
        self.push(at, None, ev);
    }

    fn deliver(&mut self, id: PacketId, node: usize) {
        let Some(sub) = self.subs.get(&id) else {
            return;
        };
        let bytes = sub.bytes.clone();
        let speed = sub.speed;
        let is_dest = sub.dest == Some(node);
        let faults = sub.faults.clone();
        if self.cfg.trace >= TraceLevel::Verbose {
            self.log_event(TraceEvent::Deliver { packet: id, node });
        }
        let now = self.now;
        self.current_rx = Some((id, faults));
        let reply = self.dispatch(node, |n, ctx| n.on_receive(now, &bytes, speed, ctx));
        self.current_rx = None;
        let Some(reply) = reply else {
            return;
        };
        if is_dest {
            if let Some(sub) = self.subs.get_mut(&id) {
                sub.reply = Some(reply);
            }
        } else if reply != RxReply::Silent {
            let text = format!(
                "{} answered #{id}, which is not addressed to it (ignored)",
                self.slots[node].name
            );
            self.note(text);
        }
    }

    fn ack_start(&mut self, id: PacketId) {
        let Some(mut sub) = self.subs.remove(&id) else {
            return;
        };
        let reply = sub.reply.take().unwrap_or(RxReply::Silent);
        match reply {
            RxReply::Silent => {
                let hop = self.cfg.timing.hop_delay;
                let idle_at = self
                    .now
                    .max(sub.end + hop * u64::from(self.tree.eccentricity(sub.sender_phy)));
                self.subs.insert(id, sub);
                self.no_ack(id, idle_at);
                self.push_epoch(idle_at, Ev::SubEnd { sub: id });
            }
            RxReply::Ack(ack) => self.send_ack(sub, ack, None),
            RxReply::AckThenResponse {
                ack,
                response,
                speed,
            } => self.send_ack(sub, ack, Some((response, speed))),
        }
    }

    fn send_ack(&mut self, mut sub: Sub, ack: Ack, response: Option<(Vec<u8>, Speed)>) {
        let t = self.cfg.timing;
        let now = self.now;
        let Some(dest) = sub.dest else {
            return;
        };
        let dest_phy = self.slots[dest].phy.unwrap_or(0);
        let hops = self.tree.hops(sub.sender_phy, dest_phy);
        let response = match response {
            Some(_) if sub.kind == PacketKind::ConcatResponse => {
                self.note(format!(
                    "{} tried to concatenate a response to a response (ignored)",
                    self.slots[dest].name
                ));
                None
            }
            Some((bytes, _)) if bytes.len() > self.cfg.max_packet_len => {
                self.note(format!(
                    "{} response of {} bytes is longer than the bus accepts (dropped)",
                    self.slots[dest].name,
                    bytes.len()
                ));
                None
            }
            other => other,
        };
        let byte = if sub.corrupt_ack {
            corrupt_ack_byte(ack)
        } else {
            ack.to_byte()
        };
        let ack_id = self.next_id;
        self.next_id += 1;
        let bits_end = now + t.data_prefix + t.bits(crate::timing::ACK_BITS, sub.speed);
        let end = if response.is_some() {
            bits_end
        } else {
            bits_end + t.data_end
        };
        if self.cfg.trace >= TraceLevel::Packets {
            let faults = if sub.drop_ack || sub.corrupt_ack {
                sub.faults.clone()
            } else {
                Vec::new()
            };
            self.trace.packets.push(PacketRecord {
                id: ack_id,
                kind: PacketKind::Ack,
                sender: dest,
                sender_phy: dest_phy,
                arb_start: None,
                class: None,
                start: now,
                bits_end,
                end,
                speed: sub.speed,
                bytes: Arc::from(&[byte][..]),
                answers: Some(sub.id),
                generation: self.generation,
                faults,
            });
        }
        self.log_event(TraceEvent::PacketStart(ack_id));
        if self.cfg.trace >= TraceLevel::Normal {
            self.push_epoch(end, Ev::PacketEnd(ack_id));
        }
        let seen = if sub.drop_ack {
            None
        } else {
            Ack::from_byte(byte).ok()
        };
        let arrival = bits_end + t.hop_delay * u64::from(hops);
        if !sub.faults.is_empty() {
            if !matches!(ack, Ack::Complete | Ack::Pending) {
                for &f in &sub.faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: now,
                            node: dest,
                            kind: EvidenceKind::ErrorAck(u8::from(ack)),
                        },
                    );
                }
            }
            if seen.is_none() {
                for &f in &sub.faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: arrival,
                            node: sub.sender,
                            kind: EvidenceKind::NoAck,
                        },
                    );
                }
            }
        }
        if seen.is_none() {
            self.log_event(TraceEvent::NoAck { packet: sub.id });
        }
        if matches!(sub.kind, PacketKind::Request | PacketKind::ConcatResponse) {
            sub.notified = true;
            // A valid ack is known when it arrives; a lost or corrupt one
            // only when the bus falls idle for a subaction gap (after any
            // concatenated response).
            let at = if seen.is_some() {
                arrival
            } else {
                let last_end = match &response {
                    Some((bytes, speed)) => {
                        bits_end
                            + t.concat_prefix
                            + t.payload_time(bytes.len(), *speed)
                            + t.data_end
                    }
                    None => end,
                };
                let gap = self.slots[sub.sender].regs.gap_count();
                last_end
                    + t.hop_delay * u64::from(self.tree.eccentricity(dest_phy))
                    + t.subaction_gap(gap)
            };
            self.push(
                at,
                None,
                Ev::Notify {
                    node: sub.sender,
                    token: sub.token,
                    kind: sub.kind,
                    ack: seen,
                },
            );
        }
        match response {
            Some((bytes, speed)) => {
                let rid = self.next_id;
                self.next_id += 1;
                let mut rsub = Sub {
                    id: rid,
                    kind: PacketKind::ConcatResponse,
                    sender: dest,
                    sender_phy: dest_phy,
                    bytes: Arc::from(bytes),
                    speed,
                    token: None,
                    dest: None,
                    reply: None,
                    end: bits_end,
                    faults: Vec::new(),
                    drop_ack: false,
                    corrupt_ack: false,
                    dropped: false,
                    notified: false,
                    answers: Some(sub.id),
                };
                let mut start = bits_end;
                if !self.injector.is_empty() {
                    if let Some((delay, what, rule)) = self.injector.decide_delay(
                        NodeHandle(dest),
                        PacketKind::ConcatResponse,
                        &rsub.bytes,
                        now,
                    ) {
                        let source = rule.map(FaultSource::Rule);
                        let fid = self
                            .log
                            .add(now, what.clone(), Some(rid), Some(dest), source);
                        self.log_event(TraceEvent::Fault { id: fid, what });
                        rsub.faults.push(fid);
                        start += delay;
                    }
                }
                if self.decide_faults(&mut rsub, now) {
                    self.slots[dest].queue.push_back(Pending {
                        bytes: rsub.bytes.clone(),
                        speed,
                        class: ArbitrationClass::Fair,
                        token: None,
                        kind: PacketKind::Duplicate,
                        ready_at: now,
                        delayed: true,
                        faults: rsub.faults.clone(),
                    });
                }
                self.subs.insert(rid, rsub);
                self.push_epoch(
                    start,
                    Ev::TxStart {
                        sub: rid,
                        arb_start: None,
                        class: None,
                    },
                );
            }
            None => {
                let idle_at = end + t.hop_delay * u64::from(self.tree.eccentricity(dest_phy));
                let id = sub.id;
                self.subs.insert(id, sub);
                self.push_epoch(idle_at, Ev::SubEnd { sub: id });
            }
        }
    }

    fn sub_end(&mut self, id: PacketId) {
        if let Some(sub) = self.subs.remove(&id) {
            if !sub.dropped {
                if let Some(PhyPacket::Config {
                    force_root,
                    gap_count,
                }) = parse_phy_packet(&sub.bytes)
                {
                    self.apply_phy_config(force_root, gap_count);
                }
            }
        }
        self.medium = Medium::Idle { since: self.now };
        if self.cfg.trace >= TraceLevel::Verbose {
            self.log_event(TraceEvent::Idle);
        }
        self.arbitrate();
    }

    fn apply_phy_config(&mut self, force_root: Option<u8>, gap_count: Option<u8>) {
        for slot in &mut self.slots {
            let Some(phy) = slot.phy else {
                continue;
            };
            if let Some(g) = gap_count {
                slot.regs.set_gap_count(g);
            }
            if let Some(r) = force_root {
                slot.regs.set_root_holdoff(phy == r);
            }
        }
        if gap_count.is_some() {
            self.gap_set_since_reset = true;
        }
        self.note(format!(
            "PHY configuration: gap count {gap_count:?}, force root {force_root:?}"
        ));
    }

    // ----- reset ------------------------------------------------------------------

    fn start_reset(&mut self, short: bool, cause: String) {
        let now = self.now;
        self.epoch += 1;
        self.arb_at = None;
        self.started = true;
        let subs = std::mem::take(&mut self.subs);
        for sub in subs.into_values() {
            if sub.kind == PacketKind::Request && !sub.notified {
                self.push(
                    now,
                    None,
                    Ev::Notify {
                        node: sub.sender,
                        token: sub.token,
                        kind: sub.kind,
                        ack: None,
                    },
                );
            }
        }
        self.flush_queues(|_| true);
        self.medium = Medium::Resetting;
        self.log_event(TraceEvent::ResetStart { cause, short });
        if !self.gap_set_since_reset {
            for slot in &mut self.slots {
                slot.regs.set_gap_count(DEFAULT_GAP_COUNT);
            }
        }
        self.gap_set_since_reset = false;
        let designated = self.root.unwrap_or(0);
        let component = self.topo.component(designated);
        let root = component
            .iter()
            .copied()
            .find(|&n| self.slots[n].regs.root_holdoff())
            .unwrap_or(designated);
        let speeds: Vec<Speed> = self.slots.iter().map(|s| s.cfg.max_speed).collect();
        self.tree = self.topo.tree(root, &speeds);
        let t = self.cfg.timing;
        let signal = if short { t.reset_short } else { t.reset_long };
        let tree_id = t.hop_delay * (2 * u64::from(self.tree.diameter()));
        let self_id = t.data_prefix + t.bits(PHY_PACKET_BITS, Speed::S100) + t.data_end;
        let count = self.tree.node_count() as u64;
        let done = now + signal + tree_id + (self_id + t.self_id_gap) * count;
        self.reset_began = now + signal + tree_id;
        self.push_epoch(done, Ev::ResetDone);
    }

    fn flush_queues(&mut self, which: impl Fn(&Slot) -> bool) {
        let now = self.now;
        let mut flushed = Vec::new();
        for (i, slot) in self.slots.iter_mut().enumerate() {
            if !which(slot) {
                continue;
            }
            for p in slot.queue.drain(..) {
                if p.kind == PacketKind::Request {
                    flushed.push((i, p.token));
                }
            }
        }
        for (node, token) in flushed {
            self.push(
                now,
                None,
                Ev::Notify {
                    node,
                    token,
                    kind: PacketKind::Request,
                    ack: None,
                },
            );
        }
    }

    fn reset_done(&mut self) {
        let now = self.now;
        self.generation += 1;
        self.medium = Medium::Idle { since: now };
        let root = self.tree.root;
        let count = self.tree.node_count();
        for (i, slot) in self.slots.iter_mut().enumerate() {
            slot.phy = self.tree.phy_of.get(i).copied().flatten();
            slot.arb_enable = true;
            slot.regs.set_identity(
                slot.phy.unwrap_or(NodeId::BROADCAST_PHY),
                slot.phy.is_some() && i == root,
            );
        }
        // Self-ID packets, for the record.
        if self.cfg.trace >= TraceLevel::Packets {
            let t = self.cfg.timing;
            let mut at = self.reset_began;
            for phy in 0..count {
                let node = self.tree.by_phy[phy];
                let slot = &self.slots[node];
                let ports = &self.tree.port_status[node];
                let port = |k: usize| {
                    ports
                        .get(k)
                        .copied()
                        .unwrap_or(firelink_wire::phy::PortStatus::NotPresent)
                };
                let packet = PhyPacket::SelfId(SelfId {
                    phy_id: phy as u8,
                    link_active: slot.regs.link_active(),
                    gap_count: slot.regs.gap_count(),
                    speed: slot.cfg.max_speed.code(),
                    contender: slot.regs.contender(),
                    power_class: 4,
                    ports: [port(0), port(1), port(2)],
                    initiated_reset: false,
                });
                let bits_end = at + t.data_prefix + t.bits(PHY_PACKET_BITS, Speed::S100);
                let end = bits_end + t.data_end;
                let id = self.next_id;
                self.next_id += 1;
                self.trace.packets.push(PacketRecord {
                    id,
                    kind: PacketKind::SelfId,
                    sender: node,
                    sender_phy: phy as u8,
                    arb_start: None,
                    class: None,
                    start: at,
                    bits_end,
                    end,
                    speed: Speed::S100,
                    bytes: Arc::from(phy_packet_bytes(&packet)),
                    answers: None,
                    generation: self.generation,
                    faults: Vec::new(),
                });
                at = end + t.self_id_gap;
            }
        }
        let root_phy = count.saturating_sub(1) as u8;
        self.log_event(TraceEvent::ResetDone {
            generation: self.generation,
            node_count: count as u8,
            root_phy,
        });
        for f in std::mem::take(&mut self.reset_faults) {
            self.log.add_evidence(
                f,
                Evidence {
                    time: now,
                    node: root,
                    kind: EvidenceKind::BusReset {
                        generation: self.generation,
                    },
                },
            );
        }
        self.flush_queues(|s| s.phy.is_none());
        let generation = self.generation;
        for phy in 0..count {
            let node = self.tree.by_phy[phy];
            let info = ResetInfo {
                phy_id: phy as u8,
                generation,
                node_count: count as u8,
                root_phy_id: root_phy,
            };
            self.dispatch(node, |n, ctx| n.on_bus_reset(now, &info, ctx));
        }
        if self.cfg.cycle_master && !self.cycle_tick_scheduled {
            let period = self.cfg.timing.cycle_period.0.max(1);
            let next = SimTime((now.0 / period + 1) * period);
            self.cycle_tick_scheduled = true;
            self.push(next, None, Ev::CycleTick);
        }
        self.arbitrate();
    }

    // ----- cycle master -----------------------------------------------------------

    fn cycle_tick(&mut self) {
        if !self.cfg.cycle_master {
            self.cycle_tick_scheduled = false;
            return;
        }
        let next = self.now + self.cfg.timing.cycle_period;
        self.push(next, None, Ev::CycleTick);
        if self.medium == Medium::Resetting || self.tree.node_count() == 0 {
            return;
        }
        let root = self.tree.root;
        let now = self.now;
        let slot = &mut self.slots[root];
        if slot.muted {
            return;
        }
        if !slot
            .queue
            .front()
            .is_some_and(|p| p.kind == PacketKind::CycleStart)
        {
            slot.queue.push_front(Pending {
                bytes: Arc::from(Vec::new()),
                speed: Speed::S100,
                class: ArbitrationClass::Priority,
                token: None,
                kind: PacketKind::CycleStart,
                ready_at: now,
                delayed: true,
                faults: Vec::new(),
            });
        }
        if self.is_idle() {
            self.schedule_arbitration(now);
        }
    }

    // ----- timed faults -------------------------------------------------------------

    fn timed_fault(&mut self, index: usize) {
        let Some(fault) = self.timed.get(index).cloned() else {
            return;
        };
        let now = self.now;
        match fault {
            TimedFault::Disconnect {
                node,
                reconnect_after,
            } => {
                let n = node.0;
                if n >= self.slots.len() {
                    return;
                }
                let parent = self
                    .tree
                    .parent
                    .get(n)
                    .copied()
                    .flatten()
                    .filter(|_| self.slots[n].phy.is_some());
                let peers: Vec<usize> = match parent {
                    Some(p) => vec![p],
                    None => self.topo.neighbours(n).collect(),
                };
                let mut links = Vec::new();
                for p in peers {
                    if let Some((pa, pb)) = self.topo.link_between(n, p) {
                        if self.topo.disconnect(n, p).is_ok() {
                            links.push((n, pa, p, pb));
                        }
                    }
                }
                let what = format!(
                    "unplug {} ({} cable(s)){}",
                    self.slots[n].name,
                    links.len(),
                    reconnect_after
                        .map(|d| format!(", plug back after {d}"))
                        .unwrap_or_default()
                );
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    Some(n),
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                self.reset_faults.push(id);
                self.start_reset(false, "cable unplugged (fault)".to_string());
                if let Some(d) = reconnect_after {
                    let links = links.into_boxed_slice();
                    self.push(now + d, None, Ev::Reconnect { links, fault: id });
                }
            }
            TimedFault::BusReset => {
                let what = "bus reset".to_string();
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    None,
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                self.reset_faults.push(id);
                self.start_reset(false, "bus reset (fault)".to_string());
            }
            TimedFault::StopAnswering { node, duration } => {
                let n = node.0;
                if n >= self.slots.len() {
                    return;
                }
                let what = format!(
                    "{} stops answering{}",
                    self.slots[n].name,
                    duration
                        .map(|d| format!(" for {d}"))
                        .unwrap_or_else(|| " for ever".to_string())
                );
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    Some(n),
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                let slot = &mut self.slots[n];
                slot.muted = true;
                slot.mute_fault = Some(id);
                slot.queue.clear();
                slot.timers.clear();
                if let Some(d) = duration {
                    self.push(now + d, None, Ev::Unmute { node: n });
                }
            }
            TimedFault::Babble {
                node,
                duration,
                packet_len,
            } => {
                let n = node.0;
                if n >= self.slots.len() {
                    return;
                }
                let len = packet_len.min(self.cfg.max_packet_len);
                let what = format!(
                    "{} babbles {len}-byte garbage for {duration}",
                    self.slots[n].name
                );
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    Some(n),
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                self.slots[n].babble = Some(BabbleState {
                    until: now + duration,
                    len,
                    fault: id,
                });
                self.push(now + duration, None, Ev::Arbitrate);
                if self.is_idle() {
                    self.schedule_arbitration(now);
                }
            }
        }
    }

    fn reconnect(&mut self, links: &[(usize, u8, usize, u8)], fault: FaultId) {
        for &(a, pa, b, pb) in links {
            if let Err(e) = self.topo.connect_ports(a, pa, b, pb) {
                self.note(format!("could not plug the cable back: {e}"));
            }
        }
        self.reset_faults.push(fault);
        self.start_reset(false, "cable plugged back (fault)".to_string());
    }
}

/// A cycle start packet from `source_phy` carrying the cycle time at `at`.
fn cycle_start_packet(source_phy: u8, at: SimTime) -> Vec<u8> {
    let ticks = (u128::from(at.0) * 24_576_000 / 1_000_000_000_000) as u64;
    let offset = ticks % 3072;
    let cycles = ticks / 3072;
    let cycle_time = (((cycles / 8000) % 128) << 25) | ((cycles % 8000) << 12) | offset;
    let q = [
        0xFFFF_0000 | (u32::from(u8::from(Tcode::CycleStart)) << 4),
        (u32::from(NodeId::local(source_phy).0) << 16) | 0xFFFF,
        0xF000_0200,
        cycle_time as u32,
    ];
    let mut out = Vec::with_capacity(20);
    for w in q {
        out.extend_from_slice(&w.to_be_bytes());
    }
    let crc = crc1394(&out);
    out.extend_from_slice(&crc.to_be_bytes());
    out
}
