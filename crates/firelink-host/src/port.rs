//! The one narrow transport trait every protocol talks through.
//!
//! A [`Port`] moves 1394 asynchronous transactions to nodes and back; it
//! never knows what the bytes mean. The simulated bus and the UDP bridge
//! implement it, so the same protocol code drives emulated boards in-process
//! and real boards over Ethernet.

use std::time::Duration;

use crate::error::Result;

/// Where a request goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Dest {
    /// Physical node ID 0..=62, or 63 for broadcast.
    pub node: u8,
    /// UDP bridge only: handle on the Ethernet-connected board itself and
    /// match `node` against its board ID (control word bit 8). Ignored by
    /// other ports.
    pub no_forward: bool,
}

impl Dest {
    /// Broadcast to every node.
    pub const BROADCAST: Dest = Dest {
        node: 63,
        no_forward: false,
    };

    /// One node by physical ID.
    pub const fn node(node: u8) -> Dest {
        Dest {
            node,
            no_forward: false,
        }
    }

    /// Whether this is the broadcast node.
    pub const fn is_broadcast(&self) -> bool {
        self.node == 63
    }
}

/// Refuse a read addressed to the broadcast node: a 1394 bus has no
/// broadcast read (ports that reach a bus call this before sending).
///
/// # Errors
/// [`HostError::InvalidRequest`](crate::HostError::InvalidRequest).
#[cfg_attr(
    not(any(feature = "sim", all(target_os = "linux", feature = "firewire"))),
    allow(dead_code)
)]
pub(crate) fn refuse_broadcast_read(dest: Dest) -> Result<()> {
    if dest.is_broadcast() {
        return Err(crate::HostError::InvalidRequest {
            what: "reads cannot be broadcast on a 1394 bus",
            value: u32::from(dest.node),
        });
    }
    Ok(())
}

/// Check a block transfer size: 4..=2048 bytes (the S400 maximum payload)
/// in whole quadlets. Ports call this before sending anything.
///
/// # Errors
/// [`HostError::InvalidRequest`](crate::HostError::InvalidRequest).
pub(crate) fn check_block(len: usize) -> Result<()> {
    let max = firelink_wire::packet::Speed::S400.max_async_payload();
    if len == 0 || len % 4 != 0 || len > max {
        return Err(crate::HostError::InvalidRequest {
            what: "block size must be 4..=2048 bytes in whole quadlets",
            value: len as u32,
        });
    }
    Ok(())
}

/// A transport for 1394 asynchronous transactions.
///
/// Reads block until the matching response arrives or the port's time-out
/// expires. Writes to the bridge complete when sent (the bridge sends no
/// write response); on the simulated bus they complete with the ack.
///
/// # Errors
/// Every method reports [`HostError`](crate::HostError) values: time-outs,
/// bad acks or rcodes, bus resets (once per reset), socket failures.
pub trait Port {
    /// A short human name ("sim", "udp:127.0.0.1:1394").
    fn name(&self) -> &str;
    /// Read one quadlet.
    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32>;
    /// Write one quadlet.
    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()>;
    /// Read `out.len()` bytes (a whole number of quadlets).
    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()>;
    /// Write a block (a whole number of quadlets).
    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()>;
    /// Start a quadlet write and return without waiting for its
    /// acknowledgement, as the reference host's non-blocking
    /// `raw1394_start_write` does for the broadcast protocol's query and
    /// commands (which may go to node 0 for the boards to snoop). Ports
    /// whose writes are never acknowledged just write.
    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.write_quadlet(dest, offset, value)
    }
    /// Start a block write without waiting for its acknowledgement (see
    /// [`start_write_quadlet`](Self::start_write_quadlet)).
    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.write_block(dest, offset, data)
    }
    /// Let `duration` pass (virtual time on the simulated bus).
    fn wait(&mut self, duration: Duration);
    /// A servo cycle's I/O begins ([`IoSystem::read_all`](crate::qla::io::IoSystem::read_all),
    /// the Snake system's inputs, MAHRU's read of every module): a port
    /// that bounds the time one cycle may spend waiting for its answers
    /// (the `fw` port's cycle budget) starts that budget anew; the
    /// simulated bus counts the cycle by level of detail. Other ports
    /// ignore it.
    fn begin_cycle(&mut self) {}
    /// The cycle's I/O is over ([`IoSystem::write_all`](crate::qla::io::IoSystem::write_all)
    /// returned): calls until the next [`begin_cycle`](Self::begin_cycle)
    /// (a rescan, a register read) are bounded by their own time-outs only.
    fn end_cycle(&mut self) {}
    /// Let time pass until `heard` accepts a packet the host's link
    /// received unasked (a broadcast it overheard), at most `limit`;
    /// returns whether `heard` accepted one. Ports that cannot overhear the
    /// bus (the Ethernet bridge delivers only answers) wait the whole
    /// `limit` and return `false`.
    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        let _ = heard;
        self.wait(limit);
        false
    }
    /// The Ethernet-only network of FPGA V3 boards at Rev 9: after a
    /// broadcast query, the hub board sends the host one unsolicited block
    /// read response holding every selected board's status block (the hub
    /// memory). A port on that network waits for it (its read time-out)
    /// and copies its payload into `out` (the hub read's length): `Some(Ok)`;
    /// `Some(Err)` when it did not come or was damaged (the caller then
    /// reads the hub, as the Rev 9 host falls back). `None` (every other
    /// port): no such response, read the hub.
    fn receive_broadcast_response(&mut self, out: &mut [u8]) -> Option<Result<()>> {
        let _ = out;
        None
    }
    /// The host's wait between a broadcast query selecting `boards` boards
    /// (counted in QLA1 read blocks: a DQLA counts as two) and its hub read
    /// (or the hub's own response), when the caller gives none: 10 + 5 N us for the FireWire bus and the bridge (Firelink's
    /// default; the Rev 9 host waits 10 + 10 (N - 1) us there); the
    /// Ethernet-only network's port overrides it with the Rev 9 host's
    /// formula ([`crate::eth::ethernet_only_broadcast_wait`]).
    fn broadcast_wait(&self, boards: usize) -> Duration {
        Duration::from_micros(10 + 5 * boards as u64)
    }
    /// The clock the hub's update timers and its timing quadlet count, in
    /// Hz: the boards' 49.152 MHz system clock, or on the Ethernet-only
    /// network the 125 MHz Ethernet clock
    /// ([`crate::eth::ETH_HUB_CLOCK_HZ`]; EthBasePort
    /// `GetBroadcastReadClockPeriod`).
    fn hub_clock_hz(&self) -> u32 {
        firelink_wire::phy::SYSTEM_CLOCK_HZ
    }
    /// Time since the port was opened (virtual on the simulated bus).
    fn now(&self) -> Duration;
    /// [`now`](Self::now) in picoseconds, as finely as the port's clock
    /// goes (the simulated bus: exactly; others: whole nanoseconds).
    fn now_ps(&self) -> u64 {
        u64::try_from(self.now().as_nanos())
            .unwrap_or(u64::MAX)
            .saturating_mul(1000)
    }
    /// The bus generation the host currently uses.
    fn generation(&self) -> u32;
    /// Whether a completed write means the node took it (the simulated
    /// bus: acked). The Ethernet bridge sends nothing back for a write, so
    /// over UDP a write returns once it is sent.
    fn acknowledges_writes(&self) -> bool {
        true
    }
    /// Whether broadcast writes to register space (below
    /// `0xFFFF_F000_0800`) are refused on this port, as Linux's FireWire
    /// driver refuses them: the broadcast protocol then sends its query and
    /// commands to node 0 for the boards to snoop
    /// ([`BroadcastRoute::SnoopedNode0`](crate::qla::io::BroadcastRoute), which
    /// [`IoSystem`](crate::qla::io::IoSystem) takes by itself on such a port).
    fn refuses_broadcast_registers(&self) -> bool {
        false
    }
    /// What the port's link sent and received, refusals by reason.
    fn link_stats(&self) -> crate::link_stats::LinkStats {
        crate::link_stats::LinkStats::default()
    }
    /// Physical node IDs that may hold boards (the bridge: 0..=15; the
    /// simulated bus: every node but the PC).
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        0..16
    }
    /// Let `filter` see (and perhaps change or drop) every packet this port
    /// sends and receives from now on.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`](crate::HostError::InvalidRequest) for a
    /// port that does not show its packets.
    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        let _ = filter;
        Err(crate::HostError::InvalidRequest {
            what: "this port does not show its packets to filters",
            value: 0,
        })
    }
    /// Whether [`add_link_filter`](Self::add_link_filter) takes a filter
    /// (asked before a run, so that what a filter would do is refused
    /// before the boards are touched). Every port that overrides the one
    /// overrides the other.
    fn takes_link_filters(&self) -> bool {
        false
    }
}

/// Forward every [`Port`] method to another port: `forward_port!(s =>
/// (**s))` for a box, `forward_port!(s => s.inner)` for a wrapper whose
/// `inner` field is the port. Wrappers that change a few methods write
/// those and forward the rest by hand.
macro_rules! forward_port {
    ($s:ident => $e:expr) => {
        fn name(&self) -> &str {
            let $s = self;
            $e.name()
        }
        fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
            let $s = self;
            $e.read_quadlet(dest, offset)
        }
        fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
            let $s = self;
            $e.write_quadlet(dest, offset, value)
        }
        fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
            let $s = self;
            $e.read_block(dest, offset, out)
        }
        fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
            let $s = self;
            $e.write_block(dest, offset, data)
        }
        fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
            let $s = self;
            $e.start_write_quadlet(dest, offset, value)
        }
        fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
            let $s = self;
            $e.start_write_block(dest, offset, data)
        }
        fn wait(&mut self, duration: Duration) {
            let $s = self;
            $e.wait(duration)
        }
        fn begin_cycle(&mut self) {
            let $s = self;
            $e.begin_cycle()
        }
        fn end_cycle(&mut self) {
            let $s = self;
            $e.end_cycle()
        }
        fn wait_until_heard(
            &mut self,
            limit: Duration,
            heard: &mut dyn FnMut(&[u8]) -> bool,
        ) -> bool {
            let $s = self;
            $e.wait_until_heard(limit, heard)
        }
        fn receive_broadcast_response(&mut self, out: &mut [u8]) -> Option<Result<()>> {
            let $s = self;
            $e.receive_broadcast_response(out)
        }
        fn broadcast_wait(&self, boards: usize) -> Duration {
            let $s = self;
            $e.broadcast_wait(boards)
        }
        fn hub_clock_hz(&self) -> u32 {
            let $s = self;
            $e.hub_clock_hz()
        }
        fn now(&self) -> Duration {
            let $s = self;
            $e.now()
        }
        fn now_ps(&self) -> u64 {
            let $s = self;
            $e.now_ps()
        }
        fn generation(&self) -> u32 {
            let $s = self;
            $e.generation()
        }
        fn acknowledges_writes(&self) -> bool {
            let $s = self;
            $e.acknowledges_writes()
        }
        fn link_stats(&self) -> crate::link_stats::LinkStats {
            let $s = self;
            $e.link_stats()
        }
        fn refuses_broadcast_registers(&self) -> bool {
            let $s = self;
            $e.refuses_broadcast_registers()
        }
        fn candidate_nodes(&self) -> core::ops::Range<u8> {
            let $s = self;
            $e.candidate_nodes()
        }
        fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
            let $s = self;
            $e.add_link_filter(filter)
        }
        fn takes_link_filters(&self) -> bool {
            let $s = self;
            $e.takes_link_filters()
        }
    };
}
pub(crate) use forward_port;

impl<P: Port + ?Sized> Port for Box<P> {
    forward_port!(s => (**s));
}

/// Which way a packet went through a port (never
/// [`Direction::OnBus`]: a port sees only its own side).
pub use firelink_wire::pcap::Direction;

/// What a [`LinkFilter`] does with a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// Let it through (perhaps changed).
    Pass,
    /// It is lost: a request never reaches the bus, an answer never the
    /// host library.
    Drop,
}

/// Something that watches, or breaks, the 1394 packets a port sends and
/// receives: the port's middleware, as smoltcp's `Tracer` and
/// `FaultInjector` are around its devices. The [`Port`] trait works in
/// transactions, so wrappers reach the packets through the port's filters
/// ([`Port::add_link_filter`]); [`TracingPort`](crate::trace::TracingPort)
/// and [`FaultyPort`](crate::fault::FaultyPort) are built on them.
pub trait LinkFilter: Send {
    /// `packet` (the whole 1394 packet: header, CRCs, payload; no bridge
    /// framing) is leaving (`Sent`) or has arrived (`Received`) at `at_ps`
    /// on the port's clock ([`Port::now_ps`]). The filter may change its
    /// bytes in place, or drop it.
    fn packet(&mut self, at_ps: u64, direction: Direction, packet: &mut [u8]) -> Verdict;

    /// Whether the filter will never again change or drop a packet (a
    /// fault that has fired its count): the port's [`LinkFilters`] lets
    /// it go when the next filter is added, so that faults injected one
    /// after another do not lengthen every packet's path.
    fn is_spent(&self) -> bool {
        false
    }
}

/// The filters of one port, in the order they were added: the last added
/// (the outermost wrapper) sees an outgoing packet first and an incoming
/// one last.
#[derive(Default)]
pub struct LinkFilters {
    filters: Vec<Box<dyn LinkFilter>>,
}

impl core::fmt::Debug for LinkFilters {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "LinkFilters({})", self.filters.len())
    }
}

impl LinkFilters {
    /// Add one, letting go of those that are spent
    /// ([`LinkFilter::is_spent`]).
    pub fn add(&mut self, filter: Box<dyn LinkFilter>) {
        self.filters.retain(|f| !f.is_spent());
        self.filters.push(filter);
    }

    /// How many filters each packet goes through.
    pub fn len(&self) -> usize {
        self.filters.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.filters.is_empty()
    }

    /// A packet leaving at `at_ps`.
    pub fn outgoing(&mut self, at_ps: u64, packet: &mut [u8]) -> Verdict {
        for f in self.filters.iter_mut().rev() {
            if f.packet(at_ps, Direction::Sent, packet) == Verdict::Drop {
                return Verdict::Drop;
            }
        }
        Verdict::Pass
    }

    /// A packet arriving at `at_ps`.
    pub fn incoming(&mut self, at_ps: u64, packet: &mut [u8]) -> Verdict {
        for f in self.filters.iter_mut() {
            if f.packet(at_ps, Direction::Received, packet) == Verdict::Drop {
                return Verdict::Drop;
            }
        }
        Verdict::Pass
    }
}
