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
//! # Levels of detail
//! At the default fast level a packet's deliveries (step 4) go to their
//! nodes in one batch while each is the queue's next event; at the packet
//! level each is an event of its own. Both give the same answer; see
//! [`detail`] for when the packet level runs and what is
//! counted ([`Bus::detail_report`]).
//!
//! # Bus reset
//! [`Bus::reset`], a cable change (when `auto_reset`), a disconnect fault or
//! a node setting IBR/ISBR starts a reset. In-flight and queued requests are
//! flushed (their nodes get `on_transmitted(.., None)`), the generation
//! increments, self-ID numbers the nodes in topology order with the root
//! highest, and every node gets [`Node::on_bus_reset`] with its new ID.

mod arbitration;
mod cycle;
pub mod detail;
mod events;
#[cfg(test)]
mod probe;
mod queue;
mod reset;
mod timed_fault;
mod transmission;

use std::collections::VecDeque;
use std::sync::Arc;

use firelink_wire::crc::crc1394;
use firelink_wire::packet::{Ack, CrcStatus, NodeId, Packet, Speed, Tcode};
use firelink_wire::phy::{PhyPacket, SelfId};
use rand_chacha::rand_core::RngCore;

use crate::error::BusError;
use crate::fault::{
    Evidence, EvidenceKind, FaultId, FaultInjector, FaultLog, FaultPlan, FaultRule, FaultSource,
    TimedFault, corrupt_ack_byte,
};
pub use crate::node::NodeHandle;
use crate::node::{
    ArbitrationClass, Commands, Node, NodeCtx, PacketPool, ResetInfo, RxReply, TimerCommand,
    TransmitRequest, seal,
};
use crate::phy::{PhyRegisters, parse_phy_packet, phy_packet_bytes};
use crate::time::{SimDuration, SimTime};
use crate::timing::{BusTiming, DEFAULT_GAP_COUNT, PHY_PACKET_BITS};
use crate::topology::{Topology, Tree};
use crate::trace::{PacketId, PacketKind, PacketRecord, Trace, TraceEntry, TraceEvent};
use events::Batch;
use queue::{Delivery, EventQueue, Taken};

use detail::DetailTally;
pub use detail::{CountedIn, Detail, DetailReport, PacketLevelWhy, UnknownDetail, WhyCounts};

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
    /// How much of each packet is worked out event by event (both levels
    /// give the same answer; see [`Detail`]).
    pub detail: Detail,
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
            detail: Detail::Fast,
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
    /// The packet as the node handed it over (moved, not copied, into
    /// its subaction; a trace record copies it).
    bytes: Vec<u8>,
    speed: Speed,
    class: ArbitrationClass,
    token: Option<u64>,
    kind: PacketKind,
    ready_at: SimTime,
    delayed: bool,
    faults: Vec<FaultId>,
    /// The CRC status of `bytes` when the bus already knows it (a sealed
    /// packet, a cycle start); `None`: worked out at the first delivery.
    crc: Option<CrcStatus>,
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
    /// Armed timers: (token, stamp of its event, when it fires).
    timers: Vec<(u64, u64, SimTime)>,
    muted: bool,
    mute_fault: Option<FaultId>,
    babble: Option<BabbleState>,
    /// The node wants unicast packets addressed to other nodes (see
    /// [`Node::hears_others`]).
    hears_others: bool,
    /// Calls into the node so far ([`Bus::dispatch_count`]).
    dispatches: u64,
}

#[derive(Debug)]
struct Sub {
    id: PacketId,
    kind: PacketKind,
    sender: usize,
    sender_phy: u8,
    bytes: Vec<u8>,
    speed: Speed,
    token: Option<u64>,
    dest: Option<usize>,
    reply: Option<RxReply>,
    end: SimTime,
    faults: Vec<FaultId>,
    drop_ack: bool,
    corrupt_ack: bool,
    /// The addressee acknowledges ack_busy_X without taking the packet.
    busy: bool,
    dropped: bool,
    notified: bool,
    answers: Option<PacketId>,
    /// The CRC status of `bytes`, worked out once for every node that
    /// receives them (known from the start for a sealed packet or a cycle
    /// start, until a fault changes the bytes).
    crc: Option<CrcStatus>,
    /// Why its deliveries go event by event (`None`: in batches), decided
    /// when it starts ([`detail`]).
    level: Option<PacketLevelWhy>,
}

/// The subactions in progress by packet ID (a few at a time: a sorted
/// vector, which allocates nothing per packet, where a tree would).
#[derive(Debug, Default)]
struct SubTable(Vec<Sub>);

impl SubTable {
    fn position(&self, id: PacketId) -> Result<usize, usize> {
        self.0.binary_search_by_key(&id, |s| s.id)
    }

    fn get(&self, id: &PacketId) -> Option<&Sub> {
        self.position(*id).ok().and_then(|i| self.0.get(i))
    }

    fn get_mut(&mut self, id: &PacketId) -> Option<&mut Sub> {
        self.position(*id).ok().and_then(|i| self.0.get_mut(i))
    }

    /// Insert (or replace) the subaction `sub` of packet `id` (a new
    /// packet's ID is the highest yet: it goes at the end).
    #[inline]
    fn insert(&mut self, id: PacketId, mut sub: Sub) {
        sub.id = id;
        if self.0.last().is_none_or(|last| last.id < id) {
            self.0.push(sub);
            return;
        }
        match self.position(id) {
            Ok(i) => {
                if let Some(slot) = self.0.get_mut(i) {
                    *slot = sub;
                }
            }
            Err(i) => self.0.insert(i, sub),
        }
    }

    fn remove(&mut self, id: &PacketId) -> Option<Sub> {
        self.position(*id).ok().map(|i| self.0.remove(i))
    }

    /// Every subaction, in packet order, leaving the table empty.
    fn take_all(&mut self) -> Vec<Sub> {
        std::mem::take(&mut self.0)
    }
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
    /// A packet's delivery as the queue's tests see it (the bus takes
    /// deliveries off the queue as [`queue::Delivery`], not as events).
    #[cfg(test)]
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
    events: EventQueue,
    epoch: u64,
    medium: Medium,
    subs: SubTable,
    next_id: PacketId,
    arb_at: Option<SimTime>,
    trace: Trace,
    injector: FaultInjector,
    log: FaultLog,
    timed: Vec<TimedFault>,
    reset_faults: Vec<FaultId>,
    gap_set_since_reset: bool,
    cycle_tick_scheduled: bool,
    /// Some node may be babbling (set with its babble; cleared when
    /// arbitration finds none left).
    babbling: bool,
    /// The packet being delivered (its faults are its subaction's).
    current_rx: Option<PacketId>,
    /// The CRC status of the packet being delivered.
    rx_crc: Option<CrcStatus>,
    /// Scratch list of a packet's arrivals (time, node).
    arrivals: Vec<(SimTime, usize)>,
    scratch: Commands,
    /// Memory of finished packets, lent to nodes for their next ones
    /// ([`NodeCtx::take_buffer`]).
    spare_packets: PacketPool,
    reset_began: SimTime,
    /// What ran at which level of detail.
    detail: DetailTally,
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
        let detail = DetailTally::new(cfg.detail);
        Bus {
            cfg,
            now: SimTime::ZERO,
            slots: Vec::new(),
            topo: Topology::default(),
            tree: Tree::default(),
            root: None,
            generation: 0,
            started: false,
            events: EventQueue::default(),
            epoch: 0,
            medium: Medium::Idle {
                since: SimTime::ZERO,
            },
            subs: SubTable::default(),
            next_id: 0,
            arb_at: None,
            trace: Trace::default(),
            injector,
            log: FaultLog::default(),
            timed: Vec::new(),
            reset_faults: Vec::new(),
            gap_set_since_reset: false,
            cycle_tick_scheduled: false,
            babbling: false,
            current_rx: None,
            rx_crc: None,
            arrivals: Vec::new(),
            scratch: Commands::default(),
            spare_packets: PacketPool::default(),
            reset_began: SimTime::ZERO,
            detail,
        }
    }

    /// Add a node with its PHY configuration. The first node added is the
    /// root unless [`set_root`](Self::set_root) says otherwise.
    pub fn add_node(&mut self, node: Box<dyn Node>, cfg: NodeConfig) -> NodeHandle {
        let name = node.name().to_string();
        let hears_others = node.hears_others();
        let index = self.topo.add_node(cfg.ports);
        self.trace.names.push(name.clone());
        self.slots.push(Slot {
            node: Some(node),
            name,
            cfg,
            regs: PhyRegisters::with_ports(cfg.ports, cfg.max_speed),
            phy: None,
            queue: VecDeque::new(),
            arb_enable: true,
            timers: Vec::new(),
            muted: false,
            mute_fault: None,
            babble: None,
            hears_others,
            dispatches: 0,
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

    /// The current virtual time.
    pub fn now(&self) -> SimTime {
        self.now
    }

    /// The configuration.
    pub fn config(&self) -> &BusConfig {
        &self.cfg
    }

    /// Record `level` from now on (what was recorded so far stays). What
    /// the bus records never changes what it does.
    pub fn set_trace_level(&mut self, level: TraceLevel) {
        self.cfg.trace = level;
    }

    /// Choose the level of detail from now on (see [`Detail`]; a packet
    /// already on the wire goes on at the level it started at).
    pub fn set_detail(&mut self, detail: Detail) {
        self.cfg.detail = detail;
        self.detail.report.detail = detail;
    }

    /// The level of detail chosen.
    pub fn detail(&self) -> Detail {
        self.cfg.detail
    }

    /// A servo cycle begins: what ran since the last mark is counted as
    /// one cycle in [`detail_report`](Self::detail_report) (the host's
    /// simulated port marks each cycle of its I/O).
    pub fn begin_cycle(&mut self) {
        self.detail.begin_cycle();
        self.detail.level_in_force(self.cfg.detail, self.cfg.trace);
    }

    /// What ran at which level of detail so far (the cycle under way
    /// counted as if it ended now).
    pub fn detail_report(&self) -> DetailReport {
        self.detail.snapshot()
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

    /// How many times the bus has called into the node (its callbacks and
    /// [`with_node`](Self::with_node)): a node's state changes only then
    /// (or through [`node_mut`](Self::node_mut)), so a caller that watches
    /// it while the bus runs (a [`run_until_with`](Self::run_until_with)
    /// condition) need look again only when this moved. 0 for no node.
    #[inline]
    pub fn dispatch_count(&self, node: NodeHandle) -> u64 {
        self.slots.get(node.0).map_or(0, |s| s.dispatches)
    }

    /// Whether the bus called into the node since `seen` was last
    /// updated here (`None`: never looked at, so yes); updates `seen`. For
    /// a watcher that looks at a node's state again only when it may have
    /// changed ([`dispatch_count`](Self::dispatch_count)).
    #[inline]
    pub fn called_since(&self, node: NodeHandle, seen: &mut Option<u64>) -> bool {
        let calls = Some(self.dispatch_count(node));
        let moved = calls != *seen;
        *seen = calls;
        moved
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
    #[inline]
    pub fn has_pending_traffic(&self) -> bool {
        !matches!(self.medium, Medium::Idle { .. })
            || self.slots.iter().any(|s| !s.queue.is_empty())
    }

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

    /// Process every event up to and including `t`; the clock then reads `t`.
    pub fn run_until(&mut self, t: SimTime) {
        while self.step_until(t) {}
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
        // `done` is called exactly as often as before every event: a batch
        // of deliveries checks it after each one, and what it said after
        // the last one (nothing happened since) stands for the next look.
        let mut said: Option<bool> = None;
        loop {
            let holds = match said.take() {
                Some(held) => held,
                None => done(self),
            };
            if holds {
                return true;
            }
            let mut check = |bus: &Bus| {
                let held = done(bus);
                said = Some(held);
                held
            };
            let stepped = self.step_batch(deadline, Batch::Until(&mut check));
            if !stepped {
                return done(self);
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
            let only_ticks = self.events.only_cycle_ticks();
            if only_ticks && self.is_idle() && !self.has_pending_traffic() {
                return true;
            }
            if !self.step_until(limit) {
                return false;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::probe::{Probe, chain};
    use super::*;
    use crate::host::HostLink;

    #[test]
    fn nodes_are_reached_by_handle_and_type() {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        assert_eq!(bus.node_count(), 2);
        assert!(bus.node::<Probe>(nodes[1]).is_some());
        assert!(bus.node::<HostLink>(nodes[1]).is_none(), "another type");
        assert!(bus.node::<Probe>(NodeHandle(9)).is_none());
        assert!(bus.with_node::<HostLink, _>(nodes[0], |_, _| ()).is_err());
        assert_eq!(bus.name(nodes[0]), Some("probe"));
        assert_eq!(bus.root(), Some(nodes[0]));
        assert_eq!(bus.hops(nodes[0], nodes[1]), 1);
    }

    #[test]
    fn wiring_a_node_that_does_not_exist_is_an_error() {
        let mut bus = Bus::new(BusConfig::default());
        let a = bus.add(Probe::default(), NodeConfig::board());
        assert_eq!(bus.connect(a, NodeHandle(5)), Err(BusError::NoSuchNode(5)));
        assert!(bus.set_root(NodeHandle(5)).is_err());
    }

    #[test]
    fn run_until_with_stops_when_the_condition_holds() {
        let (mut bus, _) = chain(2, BusConfig::default());
        let start = bus.now();
        let deadline = start + SimDuration::from_micros(500);
        // Nothing happens on a quiet bus: the deadline is not reached by
        // events, and the condition never held.
        assert!(!bus.run_until_with(deadline, |b| b.generation() > 1));
        assert!(bus.run_until_with(deadline, |b| b.generation() == 1));
        bus.run_until(deadline);
        assert_eq!(bus.now(), deadline);
    }
}
