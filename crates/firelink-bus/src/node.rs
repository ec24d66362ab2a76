//! The node contract: what a device on the bus implements and what the bus
//! lets it do.
//!
//! A node (an emulated board, the PC's link, a test responder) implements
//! [`Node`]. The bus calls it when the bus resets, when a packet arrives,
//! when one of its transmissions finished and when one of its timers fires.
//! In each call the node gets a [`NodeCtx`] through which it asks for the
//! bus ([`NodeCtx::transmit`]), sets timers and reads or writes its PHY
//! registers. The node never sees the clock except as the `now` it is given,
//! and it never touches other nodes: everything goes through the bus, which
//! owns all timing.
//!
//! The bus applies what a node asked for after the callback returns, in the
//! order asked.
//!
//! ```
//! use firelink_bus::{Bus, BusConfig, NodeConfig, Node, NodeCtx, ResetInfo, RxReply, SimTime};
//! use firelink_wire::packet::{Ack, Packet, Speed};
//!
//! /// Acks every unicast write addressed to it; counts broadcasts.
//! struct Counter { phy_id: u8, broadcasts: u32 }
//!
//! impl Node for Counter {
//!     fn name(&self) -> &str { "counter" }
//!     fn on_bus_reset(&mut self, _now: SimTime, info: &ResetInfo, _ctx: &mut NodeCtx<'_>) {
//!         self.phy_id = info.phy_id;
//!     }
//!     fn on_receive(&mut self, _now: SimTime, bytes: &[u8], _speed: Speed,
//!                   ctx: &mut NodeCtx<'_>) -> RxReply {
//!         let Ok(p) = Packet::new_checked(bytes) else { return RxReply::Silent };
//!         if p.verify().is_err() {
//!             ctx.report_error("CRC error");
//!             return RxReply::Silent;
//!         }
//!         if p.destination_id().is_broadcast() {
//!             self.broadcasts += 1;
//!             RxReply::Silent
//!         } else if p.destination_id().phy() == self.phy_id {
//!             RxReply::Ack(Ack::Complete)
//!         } else {
//!             RxReply::Silent
//!         }
//!     }
//! }
//!
//! let mut bus = Bus::new(BusConfig::default());
//! let a = bus.add(Counter { phy_id: 63, broadcasts: 0 }, NodeConfig::pc());
//! let b = bus.add(Counter { phy_id: 63, broadcasts: 0 }, NodeConfig::board());
//! bus.connect(a, b).unwrap();
//! bus.reset();
//! assert_eq!(bus.node::<Counter>(b).unwrap().phy_id, 0);
//! assert_eq!(bus.node::<Counter>(a).unwrap().phy_id, 1);
//! ```

use std::any::Any;
use std::fmt;

use firelink_wire::packet::{Ack, CrcStatus, Packet, Speed};

use crate::phy::PhyRegisters;
use crate::time::SimTime;

/// Names a node added to a [`Bus`](crate::Bus) (its index, in order of
/// addition).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub struct NodeHandle(pub usize);

/// How a transmit request arbitrates for the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ArbitrationClass {
    /// Fair asynchronous request: waits for a subaction gap, and at most one
    /// win per fairness interval (until the next arbitration reset gap).
    Fair,
    /// Priority asynchronous request: waits for a subaction gap, not limited
    /// by the fairness interval.
    Priority,
    /// Isochronous-style request: waits only for the isochronous gap (the
    /// "bus arbitration acceleration" of seed 000). Serialized as `iso`.
    #[serde(rename = "iso")]
    Isochronous,
}

impl ArbitrationClass {
    /// A short name for timelines and JSON.
    pub fn name(self) -> &'static str {
        match self {
            ArbitrationClass::Fair => "fair",
            ArbitrationClass::Priority => "priority",
            ArbitrationClass::Isochronous => "iso",
        }
    }

    /// Parse `fair`, `priority` or `iso` (also `isochronous`).
    pub fn from_name(name: &str) -> Option<ArbitrationClass> {
        match name {
            "fair" => Some(ArbitrationClass::Fair),
            "priority" => Some(ArbitrationClass::Priority),
            "iso" | "isochronous" => Some(ArbitrationClass::Isochronous),
            _ => None,
        }
    }
}

/// A node's request to send one packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TransmitRequest {
    /// A complete 1394 packet with CRCs (firelink_wire format). PHY packets
    /// use the link-internal form (tcode 0xE, 12 bytes).
    pub packet: Vec<u8>,
    /// The speed to send at.
    pub speed: Speed,
    /// How to arbitrate.
    pub class: ArbitrationClass,
    /// Echoed back in [`Node::on_transmitted`].
    pub token: u64,
}

/// A node's answer to a packet it received.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RxReply {
    /// Broadcast packets, packets not addressed to this node, or a node that
    /// stays silent: no ack.
    Silent,
    /// Unicast packet accepted or rejected: this ack goes out after the ack
    /// gap.
    Ack(Ack),
    /// Concatenated transaction: the ack (normally [`Ack::Pending`]) and then,
    /// without releasing the bus (no subaction gap, no arbitration), this
    /// complete response packet.
    AckThenResponse {
        /// The ack sent first.
        ack: Ack,
        /// The complete response packet (with CRCs).
        response: Vec<u8>,
        /// Speed of the response.
        speed: Speed,
    },
    /// [`AckThenResponse`](Self::AckThenResponse) with a response whose
    /// header CRC and data CRC the bus writes (as for
    /// [`NodeCtx::transmit_sealed`]: whatever those fields held is
    /// overwritten, the data block's padding zeroed first). The bytes that
    /// go out are those of the same response with both CRCs filled by the
    /// node, and the bus, knowing them good, does not check them again at
    /// delivery unless a fault changes them on the way. A response whose
    /// bytes do not form a whole packet goes as it is, checked as any
    /// other.
    AckThenSealedResponse {
        /// The ack sent first.
        ack: Ack,
        /// The response packet, its CRC fields for the bus to write.
        response: Vec<u8>,
        /// Speed of the response.
        speed: Speed,
    },
}

/// What a node learns after a bus reset and self-ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct ResetInfo {
    /// The node's new physical ID.
    pub phy_id: u8,
    /// The bus generation (increments on every reset).
    pub generation: u32,
    /// Nodes on the bus after the reset.
    pub node_count: u8,
    /// Physical ID of the root (the highest on the bus).
    pub root_phy_id: u8,
}

/// Helper supertrait that lets the bus downcast `dyn Node` without trait
/// upcasting. Implemented for every `'static` type; nodes never implement it
/// by hand.
pub trait AsAny: Any {
    /// `self` as `&dyn Any`.
    fn as_any(&self) -> &dyn Any;
    /// `self` as `&mut dyn Any`.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Any> AsAny for T {
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// A device on the bus. Behaviour is pluggable: the emulated boards, the
/// PC's link ([`HostLink`](crate::host::HostLink)) and test responders all
/// implement this one trait. Nodes are `Send` so that a whole bus can move
/// to another thread (the Python package releases the GIL while it runs).
pub trait Node: Any + AsAny + Send {
    /// A short name for traces.
    fn name(&self) -> &str;

    /// Whether [`on_receive`](Self::on_receive) must see unicast packets
    /// addressed to another node (except node 0's, which everyone sees:
    /// boards snoop them). A node that ignores them says `false` and the
    /// bus does not call it for them (asked once, when the node is added).
    /// Default `true`: every packet, as the wire repeats it.
    fn hears_others(&self) -> bool {
        true
    }

    /// After every bus reset / self-ID: the node's new physical ID (as a PHY
    /// register-0 status transfer would report).
    fn on_bus_reset(&mut self, now: SimTime, info: &ResetInfo, ctx: &mut NodeCtx<'_>);

    /// A packet arrived (called at the end of the packet, as seen at this
    /// node). The raw bytes as they arrived: faults may have corrupted them,
    /// so the node must check CRCs itself. Every packet on the bus reaches
    /// every node (1394 repeats everything); for unicast packets addressed to
    /// this node return [`RxReply::Ack`], [`RxReply::AckThenResponse`] or
    /// [`RxReply::AckThenSealedResponse`].
    /// Replies from nodes the packet is not addressed to are ignored.
    fn on_receive(
        &mut self,
        now: SimTime,
        packet: &[u8],
        speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply;

    /// One of our transmit requests finished: `ack` is the ack received for
    /// a unicast packet, `None` for broadcast or when no ack came (also when
    /// a bus reset flushed the request).
    fn on_transmitted(
        &mut self,
        _now: SimTime,
        _token: u64,
        _ack: Option<Ack>,
        _ctx: &mut NodeCtx<'_>,
    ) {
    }

    /// A concatenated response we sent (via [`RxReply::AckThenResponse`]
    /// or [`RxReply::AckThenSealedResponse`]) was acknowledged (`None`: no valid ack came back).
    fn on_response_acked(&mut self, _now: SimTime, _ack: Option<Ack>, _ctx: &mut NodeCtx<'_>) {}

    /// A timer set with [`NodeCtx::set_timer`] fired.
    fn on_timer(&mut self, _now: SimTime, _token: u64, _ctx: &mut NodeCtx<'_>) {}
}

/// Everything a node asked for during one callback; applied by the bus after
/// the callback returns.
#[derive(Debug, Default)]
pub(crate) struct Commands {
    /// Each request with its packet's CRC status when the bus already
    /// knows it ([`NodeCtx::transmit_sealed`]).
    pub transmits: Vec<(TransmitRequest, Option<CrcStatus>)>,
    pub timers: Vec<TimerCommand>,
    pub phy_writes: Vec<(u8, u8)>,
    pub reports: Vec<String>,
}

impl Commands {
    pub fn is_empty(&self) -> bool {
        self.transmits.is_empty()
            && self.timers.is_empty()
            && self.phy_writes.is_empty()
            && self.reports.is_empty()
    }
}

/// Packet buffers of finished subactions, kept for nodes to build their
/// next packets in, so that a steady bus allocates no packet memory: a
/// finished subaction's bytes come back here
/// ([`give`](Self::give)), and a node borrows one with
/// [`NodeCtx::take_buffer`]. At most [`LIMIT`](Self::LIMIT) are kept (a
/// burst of packets cannot grow it without bound); the rest are freed.
#[derive(Debug, Default)]
pub(crate) struct PacketPool(Vec<Vec<u8>>);

impl PacketPool {
    /// The most spare buffers kept.
    pub const LIMIT: usize = 64;

    /// A spare buffer, empty; a new one (not yet allocated) if none is
    /// left.
    pub fn take(&mut self) -> Vec<u8> {
        self.0.pop().unwrap_or_default()
    }

    /// Keep `buffer` (emptied) for a later [`take`](Self::take), unless it
    /// holds no memory or the pool is full.
    pub fn give(&mut self, mut buffer: Vec<u8>) {
        if buffer.capacity() > 0 && self.0.len() < Self::LIMIT {
            buffer.clear();
            self.0.push(buffer);
        }
    }
}

/// Write the header CRC and the data CRC of the packet in `bytes`; its CRC
/// status, both matching (`None`: not a whole packet, nothing written).
pub(crate) fn seal(bytes: &mut [u8]) -> Option<CrcStatus> {
    let mut packet = Packet::new_checked(bytes).ok()?;
    let tcode = packet.tcode();
    packet.fill_header_crc();
    packet.fill_data_crc();
    let status = CrcStatus {
        header_ok: tcode.has_header_crc().then_some(true),
        data_ok: packet.has_data().then_some(true),
    };
    debug_assert_eq!(status, packet.crc_status(), "a sealed packet's CRCs");
    Some(status)
}

/// A timer change asked by a node.
#[derive(Debug, Clone, Copy)]
pub(crate) enum TimerCommand {
    Set { at: SimTime, token: u64 },
    Cancel { token: u64 },
}

/// What a node may see and do during a callback.
pub struct NodeCtx<'a> {
    pub(crate) now: SimTime,
    pub(crate) rx_crc: Option<CrcStatus>,
    pub(crate) phy_id: u8,
    pub(crate) generation: u32,
    pub(crate) node_count: u8,
    pub(crate) bus_idle: bool,
    /// The node's armed timers: (token, stamp, when).
    pub(crate) timers: &'a [(u64, u64, SimTime)],
    pub(crate) regs: &'a mut PhyRegisters,
    pub(crate) cmds: &'a mut Commands,
    /// The bus's spare packet buffers ([`take_buffer`](Self::take_buffer)).
    pub(crate) spare_packets: &'a mut PacketPool,
}

impl fmt::Debug for NodeCtx<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("NodeCtx")
            .field("now", &self.now)
            .field("phy_id", &self.phy_id)
            .field("generation", &self.generation)
            .finish_non_exhaustive()
    }
}

impl NodeCtx<'_> {
    /// The current virtual time.
    pub fn now(&self) -> SimTime {
        self.now
    }

    /// While a packet is being received ([`Node::on_receive`]): what its
    /// CRCs say, as [`Packet::crc_status`](firelink_wire::packet::Packet::crc_status)
    /// would for the bytes the node got (the bus works it out once for
    /// every node the packet reaches). `None` in other callbacks.
    pub fn received_crc_status(&self) -> Option<CrcStatus> {
        self.rx_crc
    }

    /// This node's physical ID; 63 (`0x3F`) until the first bus reset or
    /// while the node is not attached to the bus.
    pub fn phy_id(&self) -> u8 {
        self.phy_id
    }

    /// The bus generation seen by this node (0 before the first reset).
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// Nodes on the bus after the last reset (0 before the first).
    pub fn node_count(&self) -> u8 {
        self.node_count
    }

    /// Whether the bus is idle at this instant (no packet, ack or
    /// concatenated response in progress, no reset).
    pub fn bus_is_idle(&self) -> bool {
        self.bus_idle
    }

    /// Ask for the bus. The request waits for the gap its class needs and
    /// for arbitration; [`Node::on_transmitted`] reports the outcome.
    /// Requests of one node go out in the order they were made.
    pub fn transmit(&mut self, request: TransmitRequest) {
        self.cmds.transmits.push((request, None));
    }

    /// [`transmit`](Self::transmit) a packet whose header CRC and data CRC
    /// the bus writes now (whatever those fields held is overwritten; the
    /// data block's padding is zeroed first): the bytes are what a node
    /// that filled them itself with
    /// [`fill_header_crc`](firelink_wire::packet::Packet::fill_header_crc)
    /// and [`fill_data_crc`](firelink_wire::packet::Packet::fill_data_crc)
    /// sends, and the bus, knowing both match, does not check them again
    /// at delivery (unless a fault changes the bytes on the way). A packet
    /// whose bytes do not form a whole packet goes as it is, checked as
    /// any other.
    pub fn transmit_sealed(&mut self, mut request: TransmitRequest) {
        let status = seal(&mut request.packet);
        self.cmds.transmits.push((request, status));
    }

    /// An empty buffer to build a packet in (for a [`TransmitRequest`] or
    /// an [`RxReply::AckThenResponse`] or
    /// [`RxReply::AckThenSealedResponse`]): the memory of a packet whose
    /// subaction finished, so a node that builds its packets here does
    /// not allocate once the bus is running. A node may keep it for
    /// later; a buffer never handed back to the bus is simply freed.
    pub fn take_buffer(&mut self) -> Vec<u8> {
        self.spare_packets.take()
    }

    /// Fire [`Node::on_timer`] with `token` at `at` (at once if `at` is in
    /// the past). Setting a token again replaces its earlier timer.
    pub fn set_timer(&mut self, at: SimTime, token: u64) {
        self.cmds.timers.push(TimerCommand::Set { at, token });
    }

    /// When the timer with `token` fires, if it is armed (as of the start
    /// of this callback).
    pub fn timer(&self, token: u64) -> Option<SimTime> {
        self.timers.iter().find(|t| t.0 == token).map(|t| t.2)
    }

    /// [`timer`](Self::timer) for two tokens at once (one look at the
    /// armed timers; a token is armed at most once, as setting it again
    /// replaces it).
    pub fn timer_pair(&self, first: u64, second: u64) -> (Option<SimTime>, Option<SimTime>) {
        let (mut a, mut b) = (None, None);
        for t in self.timers {
            if t.0 == first {
                a = Some(t.2);
            }
            if t.0 == second {
                b = Some(t.2);
            }
        }
        (a, b)
    }

    /// Cancel the timer with `token`, if any.
    pub fn cancel_timer(&mut self, token: u64) {
        self.cmds.timers.push(TimerCommand::Cancel { token });
    }

    /// Read one of this node's PHY registers (1394a register map; see
    /// [`PhyRegisters`]). Registers past the map read as 0.
    pub fn read_phy_register(&self, reg: u8) -> u8 {
        self.regs.read(reg)
    }

    /// Write one of this node's PHY registers. The value is visible at once
    /// to [`read_phy_register`](Self::read_phy_register). A gap-count write
    /// (register 1, bits 5:0) takes effect immediately for this PHY only (the
    /// standard way to change the whole bus is a PHY configuration packet
    /// followed by a bus reset). Setting IBR (register 1 bit 6) or ISBR
    /// (register 5 bit 6) starts a long or short bus reset.
    pub fn write_phy_register(&mut self, reg: u8, value: u8) {
        self.regs.write(reg, value);
        self.cmds.phy_writes.push((reg, value));
    }

    /// Report a problem this node detected (a CRC error, a late or duplicate
    /// packet, a corrupt query...). It goes into the trace; when made while
    /// receiving a packet that carries an injected fault, it is recorded as
    /// evidence that the fault was detected downstream.
    pub fn report_error(&mut self, what: impl Into<String>) {
        self.cmds.reports.push(what.into());
    }
}
