//! # firelink-emulate: emulated boards behind an Ethernet bridge
//!
//! The FPGA V2 boards of firmware Rev 7/8 can bridge UDP onto FireWire: the
//! host sends each 1394 request in a datagram to port 1394 of one board (the
//! Ethernet-connected one), which handles it itself or forwards it onto the
//! FireWire bus, and returns read responses with 8 bytes of extra data
//! (`fpga-board.md` §8). This crate puts that bridge in front of a simulated
//! bus of emulated boards so that host software, ours or the reference dVRK
//! tools, can drive them over loopback UDP.
//!
//! - [`Bridge`]: the protocol, over a [`Bus`] in virtual time: one datagram
//!   in, at most one datagram out. No sockets, no clock.
//! - [`serve`]: the server loop: sockets bound to loopback (and the loopback
//!   broadcast address, for the reference host's discovery), virtual time
//!   paced to the wall clock, clean stop on a flag.
//! - [`latency`]: how late the server answers, from each datagram's
//!   arrival to its reply sent (the counters on the stop line).
//! - [`qla`]: the QLA family's wing: [`qla::eth_network`] and
//!   [`qla::eth_serve`], FPGA V3 boards at firmware Rev 9
//!   on the Ethernet-only network (no bridge, no 1394 bus): each board its
//!   own UDP address, the broadcast read answered unasked by the hub, the
//!   chain's timing from `firelink_bus::ethernet` (`firelink emulate
//!   --network eth`).
//! - [`fw_cdev`]: the other front end: the Linux kernel's /dev/fw* side
//!   (firewire-cdev) over the same simulated bus, served on a unix socket
//!   to the preloaded twin library (`firelink emulate --fw-cdev`).
//!
//! ## Model
//! The bridge board's link onto FireWire is a [`HostLink`] node at the root
//! of the bus (the place the PC takes when it is on FireWire). A request for
//! the bridge board itself (no-forward bit, or broadcast no-forward) is sent
//! to that board's node over the bus; the reply is the same as the real
//! board's local answer, with the no-forward flag set in the extra data.
//! Forwarded requests whose bus generation does not match the board's are
//! dropped, as the firmware does (broadcasts excepted).

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

mod arrival;
mod event_text;
#[cfg(target_os = "linux")]
pub mod fw_cdev;
pub mod latency;
pub mod qla;

use arrival::{Received, Receiver};
use firelink_board::qla::node::BoardNode;
use firelink_bus::host::{Completion, Outcome};
use firelink_bus::{Bus, DetailReport, HostLink, NodeHandle, SimDuration, SimTime};
use firelink_host::link_stats::LinkStats;
use firelink_host::transaction::{CrcCheck, Expect, Transactions};
use firelink_host::{Dest, HostError};
use firelink_wire::bridge::{ExtraData, ExtraFlags, split_host_datagram};
use firelink_wire::packet::{NodeId, Packet, Speed, Tcode};
use latency::{AnswerLatency, LatencySummary};

/// What the bridge did with one datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handled {
    /// A read: the reply datagram has this many bytes.
    Reply(usize),
    /// A write went out; writes get no reply.
    Written,
    /// Dropped: the reason, for the event log.
    Dropped(DropReason),
}

/// Why a datagram got no reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DropReason {
    /// Not a control word plus a complete 1394 packet.
    Malformed,
    /// Header or data CRC wrong.
    BadCrc,
    /// Forwarded request with a stale bus generation.
    StaleGeneration,
    /// The transaction failed on the bus (no ack, error ack, time-out).
    BusFailure,
    /// A tcode the bridge does not handle (only quadlet and block reads
    /// and writes are bridged).
    Unsupported,
}

/// Counters of the bridge.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BridgeStats {
    /// Datagrams received.
    pub datagrams: u64,
    /// Requests handled by the bridge board itself.
    pub local: u64,
    /// Requests forwarded onto the bus.
    pub forwarded: u64,
    /// Replies sent.
    pub replies: u64,
    /// Datagrams that did not decode.
    pub malformed: u64,
    /// Datagrams with a bad CRC.
    pub bad_crc: u64,
    /// Requests dropped for a stale generation.
    pub stale_generation: u64,
    /// Well-formed packets of a tcode the bridge does not handle.
    pub unsupported: u64,
    /// Transactions that failed on the bus.
    pub bus_failures: u64,
    /// Quadlet reads of node 63 without the no-forward bit: answered by
    /// the bridge board (counted as local) and also forwarded onto
    /// FireWire, where every board ignores them.
    pub broadcast_reads: u64,
    /// How late the replies left, from each datagram's arrival to its
    /// reply sent (recorded by the server, [`Bridge::record_answer`]).
    pub answers: LatencySummary,
    /// What the bus behind the bridge ran at which level of detail, each
    /// host datagram counted as one span (`--detail packet|fast`; the same
    /// answer either way).
    pub detail: DetailReport,
}

impl BridgeStats {
    /// Count a datagram dropped for `reason` (every drop goes through here,
    /// so none is silent).
    fn count_drop(&mut self, reason: DropReason) -> Handled {
        match reason {
            DropReason::Malformed => self.malformed += 1,
            DropReason::BadCrc => self.bad_crc += 1,
            DropReason::StaleGeneration => self.stale_generation += 1,
            DropReason::BusFailure => self.bus_failures += 1,
            DropReason::Unsupported => self.unsupported += 1,
        }
        Handled::Dropped(reason)
    }

    /// Datagrams dropped, whatever the reason.
    pub fn dropped(&self) -> u64 {
        self.malformed + self.bad_crc + self.unsupported + self.stale_generation + self.bus_failures
    }

    /// Datagrams accounted for by exactly one outcome: every datagram is
    /// malformed, has a bad CRC, is unsupported, stale, forwarded or local.
    /// Equal to [`datagrams`](Self::datagrams) at all times.
    pub fn accounted(&self) -> u64 {
        self.malformed
            + self.bad_crc
            + self.unsupported
            + self.stale_generation
            + self.forwarded
            + self.local
    }
}

/// One line: every counter, drop reasons included.
impl core::fmt::Display for BridgeStats {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} datagrams, {} replies, {} forwarded, {} local ({} broadcast reads), \
             {} dropped: {} malformed, {} bad CRC, {} unsupported tcode, \
             {} stale generation, {} bus failures; {}; {}",
            self.datagrams,
            self.replies,
            self.forwarded,
            self.local,
            self.broadcast_reads,
            self.dropped(),
            self.malformed,
            self.bad_crc,
            self.unsupported,
            self.stale_generation,
            self.bus_failures,
            self.answers,
            self.detail.counted_in("datagrams")
        )
    }
}

/// The bridge protocol over a simulated bus.
pub struct Bridge {
    bus: Bus,
    link: NodeHandle,
    bridge_board: NodeHandle,
    /// Every emulated board on the bus (their status slots are completed
    /// before the next datagram is handled).
    boards: Vec<NodeHandle>,
    /// Per board, while settling: (its dispatch count when looked at, its
    /// next status slot then).
    wakeups: Vec<(Option<u64>, Option<SimTime>)>,
    stats: BridgeStats,
    timeout: SimDuration,
    /// The host library's transaction engine, judging what comes back
    /// from the bus for each forwarded request.
    transactions: Transactions,
    /// Every reply's latency, as the server measured it.
    answers: AnswerLatency,
}

/// The longest a datagram waits, in virtual time, for the boards to finish
/// the status broadcasts the datagrams before it started: more than a full
/// Rev 7+ chain of 16 boards with every predecessor silent
/// (16 x [`CHAIN_TIMEOUT_PER_BOARD`](firelink_board::qla::CHAIN_TIMEOUT_PER_BOARD)).
const SETTLE_LIMIT: SimDuration = SimDuration::from_micros(2_000);

/// 49.152 MHz ticks in a virtual duration, saturating at 16 bits.
fn ticks16(d: SimDuration) -> u16 {
    u16::try_from(d.as_clocks()).unwrap_or(u16::MAX)
}

/// A host request the bridge took.
struct HostRequest {
    /// The packet as the host sent it.
    bytes: Vec<u8>,
    tcode: Tcode,
    tl: u8,
    /// A block request's data length.
    data_length: usize,
    destination: NodeId,
    host_source: NodeId,
    is_write: bool,
    /// A read of node 63: local and also forwarded (unless no-forward).
    broadcast_read: bool,
    /// Answered by the bridge board itself.
    local: bool,
    /// The control word's no-forward bit.
    no_forward: bool,
}

impl Bridge {
    /// A bridge whose FireWire link is the [`HostLink`] node `link` of `bus`
    /// and whose own registers are those of the board node `bridge_board`.
    pub fn new(bus: Bus, link: NodeHandle, bridge_board: NodeHandle) -> Bridge {
        let boards = (0..bus.len())
            .map(NodeHandle)
            .filter(|h| bus.node::<BoardNode>(*h).is_some())
            .collect();
        let mut bus = bus;
        // The bridge board's Ethernet port is the one connected.
        if let Some(b) = bus.node_mut::<BoardNode>(bridge_board) {
            b.firmware_mut().set_ethernet_link(true);
        }
        Bridge {
            bus,
            link,
            bridge_board,
            boards,
            wakeups: Vec::new(),
            stats: BridgeStats::default(),
            timeout: SimDuration::from_micros(10_000),
            transactions: Transactions::new(),
            answers: AnswerLatency::new(),
        }
    }

    /// Whether the bridge board takes requests sent to the UDP multicast
    /// group: firmware Rev 9 and later, on an FPGA V2 as on a V3 (the
    /// Rev 9 host sends a bridge's group requests to 224.0.0.100 once it
    /// has read the hub's firmware as 9 or later, EthUdpPort `PacketSend`;
    /// earlier firmware answers the subnet broadcast only).
    pub fn takes_multicast(&self) -> bool {
        self.bus
            .node::<BoardNode>(self.bridge_board)
            .is_some_and(|b| b.firmware().config().firmware.number() >= 9)
    }

    /// The bus.
    pub fn bus(&self) -> &Bus {
        &self.bus
    }

    /// The bus, mutable (faults, running it forward).
    pub fn bus_mut(&mut self) -> &mut Bus {
        &mut self.bus
    }

    /// Counters so far, the answer latency's included.
    pub fn stats(&self) -> BridgeStats {
        BridgeStats {
            answers: self.answers.summary(),
            detail: self.bus.detail_report(),
            ..self.stats
        }
    }

    /// A reply left `latency` after its datagram arrived (the server
    /// measures it: from the kernel's receive stamp to the send's return).
    /// Allocates nothing.
    pub fn record_answer(&mut self, latency: Duration) {
        self.answers.record(latency);
    }

    /// What the bridge's link sent onto the bus and what came back, by
    /// outcome (the host library's engine judged it).
    pub fn link_stats(&self) -> LinkStats {
        self.transactions.stats()
    }

    /// The board generation as the extra data reports it.
    pub fn generation(&self) -> u8 {
        self.bus.generation() as u8
    }

    /// Let virtual time run up to `t` (nothing happens if it is already later).
    pub fn advance_to(&mut self, t: SimTime) {
        if t > self.bus.now() {
            self.bus.run_until(t);
            self.forget_received();
        }
    }

    /// Let the boards finish, in virtual time, what the datagrams handled
    /// so far started: every status broadcast a query scheduled is sent
    /// (and stored in every hub) before the next datagram is looked at.
    /// Real boards finish their slots within microseconds of the query,
    /// sooner than any host can get its hub read to the bridge; here a
    /// query and a hub read that queue up back to back (a busy host or
    /// emulator thread) would otherwise meet almost no virtual time apart.
    /// A board that can no longer send (muted, unplugged) is not waited
    /// for once its slot has passed; the wait is bounded by
    /// `SETTLE_LIMIT`.
    /// Finish now, in virtual time, what the datagrams handled so far
    /// started (the status broadcasts a query scheduled): the server calls
    /// this while it waits for the next datagram, so the boards' work is
    /// done while the host waits after its query, not when its hub read
    /// arrives. [`handle`](Self::handle) does it first anyway.
    pub fn finish_pending(&mut self) {
        self.settle();
    }

    fn settle(&mut self) {
        let deadline = self.bus.now() + SETTLE_LIMIT;
        let boards = &self.boards;
        // Each board's next status slot, looked up again only after the
        // bus called into the board (nothing else changes it meanwhile).
        let wakeups = &mut self.wakeups;
        wakeups.clear();
        wakeups.resize(boards.len(), (None, None));
        self.bus.run_until_with(deadline, |bus| {
            // Not done while a packet is on the wire or waiting to go (most
            // of the events of a broadcast phase): the boards are looked
            // at only when the bus falls quiet.
            if bus.has_pending_traffic() {
                return false;
            }
            let now = bus.now();
            let mut owed = false;
            for (h, (looked_at, due)) in boards.iter().zip(wakeups.iter_mut()) {
                if bus.called_since(*h, looked_at) {
                    *due = bus
                        .node::<BoardNode>(*h)
                        .and_then(|b| b.firmware().next_wakeup());
                }
                // A broadcast whose slot has not passed yet.
                owed |= due.is_some_and(|due| due >= now);
            }
            !owed
        });
        self.forget_received();
    }

    /// Other nodes' broadcasts reach the bridge's link too; the bridge has
    /// no use for them, so they are not kept.
    fn forget_received(&mut self) {
        if let Some(l) = self.bus.node_mut::<HostLink>(self.link) {
            l.clear_received();
        }
    }

    /// Transactions the bridge's link holds open or finished and untaken
    /// plus packets it keeps: 0 between datagrams (nothing accumulates,
    /// whatever the traffic).
    pub fn link_backlog(&self) -> usize {
        self.bus.node::<HostLink>(self.link).map_or(0, |l| {
            l.pending_count() + l.completions().count() + l.received().len()
        })
    }

    /// Handle one host datagram; a reply, if any, is written to `reply`.
    pub fn handle(&mut self, datagram: &[u8], reply: &mut Vec<u8>) -> Handled {
        self.settle();
        // What the bus runs from here to the next datagram is this one's.
        self.bus.begin_cycle();
        self.stats.datagrams += 1;
        let req = match self.take(datagram) {
            Ok(r) => r,
            Err(reason) => return self.stats.count_drop(reason),
        };
        if req.local {
            self.stats.local += 1;
        } else {
            self.stats.forwarded += 1;
        }
        // With the no-forward bit set the board only answers itself.
        if req.broadcast_read && !req.no_forward {
            self.stats.broadcast_reads += 1;
            self.transmit_broadcast(req.bytes.clone());
        }
        if req.is_write && req.destination.is_broadcast() && !req.local {
            return match self.transmit_broadcast(req.bytes) {
                true => Handled::Written,
                false => self.stats.count_drop(DropReason::BusFailure),
            };
        }
        let received_at = self.bus.now();
        let done = match self.transact(&req, received_at) {
            Ok(d) => d,
            Err(reason) => return self.stats.count_drop(reason),
        };
        let Some(response) = done.response.as_deref() else {
            return Handled::Written;
        };
        let extra = ExtraData {
            flags: ExtraFlags {
                no_forward: req.local,
                ..ExtraFlags::default()
            },
            generation: self.generation(),
            invalid_states: 0,
            packet_errors: self.stats.bad_crc.min(255) as u8,
            receive_time: ticks16(done.submitted_at - received_at),
            total_time: ticks16(done.completed_at - received_at),
        };
        reply.clear();
        reply.extend_from_slice(response);
        // Hand the response back addressed to the host, as the bridge does.
        if Packet::new_checked(&reply[..]).is_ok() {
            let mut p = Packet::new_unchecked(&mut reply[..]);
            p.set_destination_id(req.host_source);
            p.fill_header_crc();
        }
        reply.extend_from_slice(&extra.to_bytes());
        self.stats.replies += 1;
        Handled::Reply(reply.len())
    }

    /// What a host datagram asks, if the bridge takes it: a well-formed,
    /// intact read or write request, of this bus generation unless it is
    /// local or a broadcast. The bridge board's Ethernet debug window sees
    /// every packet that decodes.
    fn take(&mut self, datagram: &[u8]) -> Result<HostRequest, DropReason> {
        let (control, packet) = split_host_datagram(datagram).map_err(|_| DropReason::Malformed)?;
        let received = &packet.as_bytes()[..packet.total_len()];
        if let Some(b) = self.bus.node_mut::<BoardNode>(self.bridge_board) {
            b.firmware_mut().ethernet_received(received);
        }
        if packet.verify().is_err() {
            return Err(DropReason::BadCrc);
        }
        let tcode = packet.tcode();
        let is_read = matches!(tcode, Tcode::ReadQuadletRequest | Tcode::ReadBlockRequest);
        let is_write = matches!(tcode, Tcode::WriteQuadletRequest | Tcode::WriteBlockRequest);
        if !is_read && !is_write {
            return Err(DropReason::Unsupported);
        }
        let destination = packet.destination_id();
        // A read of node 63 is both local and remote (fpga-board-extras.md
        // section 9): the bridge answers it from its own registers and also
        // forwards it onto FireWire, where every board ignores broadcast
        // reads. The generation is not checked for broadcasts.
        let broadcast_read = is_read && destination.is_broadcast();
        let local = control.no_forward || broadcast_read;
        if !local && !destination.is_broadcast() && control.generation != self.generation() {
            return Err(DropReason::StaleGeneration);
        }
        Ok(HostRequest {
            bytes: received.to_vec(),
            tcode,
            tl: packet.tl(),
            data_length: usize::from(packet.data_length()),
            destination,
            host_source: packet.source_id(),
            is_write,
            broadcast_read,
            local,
            no_forward: control.no_forward,
        })
    }

    /// Send `req` on FireWire from the bridge's link (local requests to the
    /// bridge board's node) and wait for it; the host's transaction engine
    /// judges the answer. An error rcode is forwarded (the host judges it);
    /// anything else wrong is a bus failure.
    fn transact(
        &mut self,
        req: &HostRequest,
        received_at: SimTime,
    ) -> Result<Completion, DropReason> {
        // The bridge transmits on FireWire with its own node ID as source
        // (responses must come back to it); local requests go to the bridge
        // board's node.
        let board_phy = self.bus.phy_id(self.bridge_board).unwrap_or(0);
        let mut bytes = req.bytes.clone();
        {
            let link_phy = self.bus.phy_id(self.link).unwrap_or(0);
            let mut p = Packet::new_unchecked(&mut bytes[..]);
            p.set_source_id(NodeId::local(link_phy));
            if req.local {
                p.set_destination_id(NodeId::local(board_phy));
            }
            p.fill_header_crc();
        }
        let dest = Dest {
            node: if req.local {
                board_phy
            } else {
                req.destination.phy()
            },
            no_forward: req.local,
        };
        let expect = match req.tcode {
            Tcode::ReadQuadletRequest => Expect::quadlet(dest, req.tl),
            Tcode::ReadBlockRequest => Expect::block(dest, req.tl, req.data_length),
            _ => Expect::write(dest, req.tl),
        };
        let link = self.link;
        let token = HostLink::submit_on(&mut self.bus, link, &bytes, Speed::S400)
            .map_err(|_| DropReason::BusFailure)?;
        self.transactions.sent();
        let deadline = self.bus.now() + self.timeout;
        let done = HostLink::wait_on(&mut self.bus, link, token, deadline);
        self.forget_received();
        let Some(done) = done.filter(|d| d.outcome == Outcome::Complete) else {
            let waited = (self.bus.now() - received_at).as_micros_f64() as u32;
            let _ = self.transactions.timed_out(&expect, waited);
            return Err(DropReason::BusFailure);
        };
        if req.is_write {
            return Ok(done);
        }
        let response = done.response.as_deref().ok_or(DropReason::BusFailure)?;
        match self
            .transactions
            .accept(response, &expect, CrcCheck::Always)
        {
            Ok(Ok(_)) | Err(HostError::Rcode { .. }) => Ok(done),
            Ok(Err(_)) | Err(_) => Err(DropReason::BusFailure),
        }
    }

    /// Put a broadcast packet (as the host sent it) onto FireWire with the
    /// link's node ID as source. Nobody answers a broadcast, so nothing of
    /// it is kept. Returns whether the link took it.
    fn transmit_broadcast(&mut self, mut bytes: Vec<u8>) -> bool {
        let link_phy = self.bus.phy_id(self.link).unwrap_or(0);
        {
            let mut p = Packet::new_unchecked(&mut bytes[..]);
            p.set_source_id(NodeId::local(link_phy));
            p.fill_header_crc();
        }
        let link = self.link;
        let Ok(token) = HostLink::submit_on(&mut self.bus, link, &bytes, Speed::S400) else {
            return false;
        };
        self.transactions.sent();
        if let Some(l) = self.bus.node_mut::<HostLink>(link) {
            l.abandon(token);
        }
        true
    }
}

/// A socket error that is not the server's failure: the host went away
/// (an ICMP refusal reported on the socket), or nothing to do right now.
pub(crate) fn not_the_servers_failure(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::ConnectionRefused
            | std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::Interrupted
    )
}

/// Largest datagram the server reads whole (anything longer is cut, and
/// then does not decode): more than any request the bridge takes.
const MAX_DATAGRAM: usize = 8192;

/// Where and how the server listens.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// Unicast address (default 127.0.0.1:1394).
    pub listen: SocketAddr,
    /// Also receive on the loopback broadcast address 127.255.255.255 (same
    /// port) when listening on loopback, as the reference host's discovery
    /// sends its first requests there.
    pub loopback_broadcast: bool,
}

impl Default for ServeConfig {
    fn default() -> Self {
        ServeConfig {
            listen: SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 1394),
            loopback_broadcast: true,
        }
    }
}

/// Something worth one line to the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// Sockets are bound.
    Listening {
        /// The unicast address actually bound.
        addr: SocketAddr,
        /// Whether the loopback broadcast address is bound too.
        broadcast: bool,
    },
    /// The first datagram from a new host address.
    HostSeen(SocketAddr),
    /// The bus generation changed (bus reset).
    BusReset(u8),
    /// Virtual time fell behind the wall clock by more than 10 ms (the
    /// machine is too busy to run the emulation in real time).
    Lagging(Duration),
    /// The server stopped: its counters, the answer latency included.
    Stopped(Box<BridgeStats>),
}

/// Bind the sockets of `config`: the unicast socket, and when asked and
/// possible the loopback broadcast socket.
///
/// # Errors
/// I/O errors of binding the unicast socket (the broadcast one is optional).
pub fn bind(config: &ServeConfig) -> std::io::Result<(UdpSocket, Option<UdpSocket>)> {
    let unicast = UdpSocket::bind(config.listen)?;
    let port = unicast.local_addr()?.port();
    let broadcast = match config.listen.ip() {
        IpAddr::V4(ip) if config.loopback_broadcast && ip.is_loopback() => UdpSocket::bind(
            SocketAddr::new(IpAddr::V4(Ipv4Addr::new(127, 255, 255, 255)), port),
        )
        .ok(),
        _ => None,
    };
    Ok((unicast, broadcast))
}

/// Bind a socket to the UDP multicast group `group` on `port` and join
/// it on every interface: where a Rev 9 host sends a bridge its Ethernet
/// broadcasts (the requests `InitNodes` flags for Ethernet broadcast: the
/// IP write, the PHY request, the hub's identity reads) once it has read
/// the bridge's firmware as 9 or later (EthUdpPort `PacketSend`:
/// `DEST_MULTICAST`, the subnet broadcast before; everything else, the
/// query and the command block included, goes by unicast to base + the
/// hub's board ID). The bridge takes what arrives there only at
/// Rev 9 ([`Bridge::takes_multicast`]). Needs a multicast route (e.g. on
/// `lo` inside a network namespace).
///
/// # Errors
/// Binding the socket or joining the group.
pub fn bind_multicast(group: Ipv4Addr, port: u16) -> std::io::Result<UdpSocket> {
    let socket = UdpSocket::bind(SocketAddr::new(IpAddr::V4(group), port))?;
    socket.join_multicast_v4(&group, &Ipv4Addr::UNSPECIFIED)?;
    Ok(socket)
}

/// Run the bridge until `stop` is set: receive datagrams, keep virtual time
/// in step with the wall clock, answer reads from the unicast socket.
///
/// Each datagram is handled at the virtual time of its arrival (the
/// kernel's receive stamp), and virtual time only moves past a moment of
/// the wall clock once every datagram that arrived before it has been
/// handled: a server kept off the CPU answers late, but the boards see
/// the host's requests at the times the host sent them.
///
/// # Errors
/// Socket errors other than time-outs.
pub fn serve(
    bridge: &mut Bridge,
    unicast: &UdpSocket,
    broadcast: Option<&UdpSocket>,
    stop: &Arc<AtomicBool>,
    on_event: impl FnMut(Event),
) -> std::io::Result<()> {
    let groups: Vec<&UdpSocket> = broadcast.into_iter().collect();
    serve_groups(bridge, unicast, &groups, stop, on_event)
}

/// [`serve`] with any number of group sockets (the loopback broadcast
/// address, the multicast group of [`bind_multicast`]): each is polled
/// as `serve` polls its broadcast socket. A request that reaches the
/// bridge by a multicast group is taken only when the bridge board's
/// firmware takes multicast ([`Bridge::takes_multicast`]; before Rev 9 it
/// is foreign traffic, ignored).
///
/// # Errors
/// As [`serve`].
pub fn serve_groups(
    bridge: &mut Bridge,
    unicast: &UdpSocket,
    groups: &[&UdpSocket],
    stop: &Arc<AtomicBool>,
    on_event: impl FnMut(Event),
) -> std::io::Result<()> {
    serve_inner(bridge, unicast, groups, stop, None, on_event)
}

/// [`serve`] (no group socket) with the boards' time taken from the
/// caller's clock instead of the wall clock: each datagram is handled at
/// `virtual_at(its arrival stamp)`, and a quiet moment `now` lets virtual
/// time reach `virtual_at(now)`. For an in-process host whose own time is
/// virtual (a test's): the boards then keep the host's time, and a host or
/// server kept off the CPU changes nothing the boards see. `virtual_at`
/// must not go backwards for later instants; no lag is reported.
///
/// # Errors
/// As [`serve`].
pub fn serve_following(
    bridge: &mut Bridge,
    unicast: &UdpSocket,
    stop: &Arc<AtomicBool>,
    virtual_at: &dyn Fn(Instant) -> SimTime,
    on_event: impl FnMut(Event),
) -> std::io::Result<()> {
    serve_inner(bridge, unicast, &[], stop, Some(virtual_at), on_event)
}

fn serve_inner(
    bridge: &mut Bridge,
    unicast: &UdpSocket,
    groups: &[&UdpSocket],
    stop: &Arc<AtomicBool>,
    following: Option<&dyn Fn(Instant) -> SimTime>,
    mut on_event: impl FnMut(Event),
) -> std::io::Result<()> {
    on_event(Event::Listening {
        addr: unicast.local_addr()?,
        broadcast: !groups.is_empty(),
    });
    // The unicast socket blocks briefly (a datagram wakes it at once); the
    // group sockets are polled between.
    unicast.set_nonblocking(false)?;
    unicast.set_read_timeout(Some(Duration::from_micros(500)))?;
    let mut unicast_rx = Receiver::new(unicast)?;
    // (socket, receiver, whether what it brings is taken).
    let takes_multicast = bridge.takes_multicast();
    let mut group_rx = Vec::with_capacity(groups.len());
    for &g in groups {
        g.set_nonblocking(true)?;
        let multicast = g.local_addr()?.ip().is_multicast();
        group_rx.push((g, Receiver::new(g)?, !multicast || takes_multicast));
    }
    let wall_origin = Instant::now();
    let virtual_origin = bridge.bus().now();
    let virtual_at = |at: Instant| match following {
        Some(clock) => clock(at),
        None => {
            virtual_origin
                + SimDuration::from_micros_f64(at.duration_since(wall_origin).as_secs_f64() * 1e6)
        }
    };
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut reply = Vec::with_capacity(MAX_DATAGRAM);
    // Hosts announced so far; a flood from many source ports must not
    // grow this, so only the first few are remembered (and announced).
    const HOSTS_REMEMBERED: usize = 16;
    let mut hosts: Vec<SocketAddr> = Vec::with_capacity(HOSTS_REMEMBERED);
    let mut generation = bridge.generation();
    let mut lag_reported = Instant::now() - Duration::from_secs(10);
    let mut handle = |r: Received,
                      buf: &[u8],
                      bridge: &mut Bridge,
                      on_event: &mut dyn FnMut(Event)|
     -> std::io::Result<()> {
        if hosts.len() < HOSTS_REMEMBERED && !hosts.contains(&r.from) {
            hosts.push(r.from);
            on_event(Event::HostSeen(r.from));
        }
        bridge.advance_to(virtual_at(r.at));
        if let Handled::Reply(n) = bridge.handle(buf.get(..r.len).unwrap_or(buf), &mut reply) {
            match unicast.send_to(&reply[..n], r.from) {
                // Counted from the datagram's arrival stamp: the time it
                // waited in the socket's queue is the server's lateness too.
                Ok(_) => bridge.record_answer(Instant::now().saturating_duration_since(r.at)),
                // A host that went away is not the server's failure.
                Err(e) if not_the_servers_failure(&e) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    };
    // The loopback broadcast socket carries only discovery: it is looked
    // at when the unicast socket is quiet, and at least this often.
    const BROADCAST_EVERY: Duration = Duration::from_millis(2);
    let mut broadcast_checked = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        // One system call per datagram: wait on the unicast socket (its
        // time-out is short); datagrams come out in arrival order, each
        // handled at its arrival stamp.
        if let Some(r) = unicast_rx.receive(unicast, &mut buf, true)? {
            handle(r, &buf, bridge, &mut on_event)?;
            // While the host waits, the boards finish what it started.
            bridge.finish_pending();
            if broadcast_checked.elapsed() < BROADCAST_EVERY {
                continue;
            }
        }
        // Quiet (or time to look): everything that arrived before this
        // moment is queued now: handle it at its arrival time, then let
        // virtual time reach the moment.
        let wall = Instant::now();
        broadcast_checked = wall;
        loop {
            let mut any = false;
            for (g, rx, taken) in &mut group_rx {
                if let Some(r) = rx.receive(g, &mut buf, false)? {
                    if *taken {
                        handle(r, &buf, bridge, &mut on_event)?;
                    }
                    any = true;
                }
            }
            if let Some(r) = unicast_rx.receive(unicast, &mut buf, false)? {
                handle(r, &buf, bridge, &mut on_event)?;
                any = true;
            }
            if !any {
                break;
            }
        }
        bridge.advance_to(virtual_at(wall));
        let ahead_us = bridge.bus().now().as_micros_f64() - virtual_origin.as_micros_f64();
        let behind = wall_origin.elapsed().as_secs_f64() - ahead_us / 1e6;
        if following.is_none() && behind > 0.010 && lag_reported.elapsed() > Duration::from_secs(5)
        {
            on_event(Event::Lagging(Duration::from_secs_f64(behind)));
            lag_reported = Instant::now();
        }
        if bridge.generation() != generation {
            generation = bridge.generation();
            on_event(Event::BusReset(generation));
        }
    }
    on_event(Event::Stopped(Box::new(bridge.stats())));
    Ok(())
}
