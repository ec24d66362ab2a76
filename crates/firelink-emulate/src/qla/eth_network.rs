//! Emulated FPGA V3 boards at firmware Rev 9 on the Ethernet-only network:
//! no 1394 bus, every board its own UDP endpoint, the chain's timing from
//! [`firelink_bus::ethernet`]. No sockets, no clock: datagrams go in with
//! the virtual time they arrived ([`EthNetwork::handle`]), replies come
//! out with the virtual time they reach the host
//! ([`EthNetwork::take_due`]); the server ([`crate::qla::eth_serve`]) does the
//! sockets and the pacing.
//!
//! What each board does with a datagram (EthernetIO.v, Rev 9):
//! - With the control word's no-forward flag set a board takes a packet
//!   addressed to its **board ID** and answers with the board ID as
//!   source (`reply_node_id`). Without it a unicast is for the FireWire
//!   side, which this network does not have: dropped and counted.
//! - A packet to node 63: writes are taken by every board; reads only by
//!   a board that might be the hub (`isHub`, what its switch learned) and
//!   only with the no-forward flag.
//! - A write to REG_IPADDR (11) stores base + board ID (the firmware's
//!   part, `firelink_board`), then the board multicasts a raw quadlet
//!   write so the switches learn where it is.
//! - The broadcast read: a quadlet write to node 63 at `0x1800` with the
//!   no-forward flag is the query (sequence << 16 | board mask); every
//!   selected board multicasts its status block (`hubSend`), every board
//!   stores the blocks in arrival order (the chain's order, not board
//!   order), with the update time counted at 125 MHz; the hub nearest the
//!   host (`isBcHub`) then sends the host one block read response it never
//!   asked for, holding the whole hub memory and the timing quadlet, with
//!   the query's transaction label and the board ID as source. A host that
//!   missed it reads the hub at `0x1000` as from any board.
//! - The command block: a block write to node 63 at 0; each board takes
//!   its slice.
//! - Every reply carries the 8 bytes of extra data: the no-forward flag,
//!   `srcPort` (bits 6:5: the switch port the request came in by), the
//!   receive and total times in 49.152 MHz ticks as the host reads them.
//!
//! Malformed datagrams and packets whose CRC fails are counted and dropped
//! before any board sees them; nothing is half-applied.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;

use firelink_board::qla::config::{BoardConfig, FpgaVersion, Profile};
use firelink_board::qla::{Firmware, PhyRegisters, Reply};
use firelink_bus::ethernet::{ChainError, EthChain, EthTiming, Framing, SwitchPort};
use firelink_bus::{SimDuration, SimTime};
use firelink_wire::bridge::{CONTROL_WORD_LEN, ExtraData, ExtraFlags, split_host_datagram};
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, Tcode};
use firelink_wire::qla::address::HUB_QUERY_OFFSET;
use firelink_wire::qla::broadcast::Query;

/// REG_IPADDR's address in the main space.
const IP_ADDRESS_OFFSET: u64 = 0x0B;
/// The raw multicast quadlet write a board sends when its IP is set: the
/// control word and a 20-byte quadlet write (EthernetIO.v `ipWrite`).
const IP_WRITE_MULTICAST_BYTES: usize = CONTROL_WORD_LEN + 20;
/// How often, in virtual time, every board's own events are run forward
/// when no packet reaches it (the watchdog, amplifier enables).
const IDLE_STEP: SimDuration = SimDuration::from_micros(200);

/// Why a network cannot be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NetworkError {
    /// A board is not an FPGA V3 at Rev 9. An FPGA V2 has one 100 Mb/s
    /// Ethernet port and no switch, and no firmware puts it on this
    /// network: a set with V2 boards is a FireWire chain behind a bridge
    /// (on real hardware, and in `firelink emulate` without `--network
    /// eth`).
    #[error(
        "board {board} is {fpga:?} at {profile:?}: the Ethernet-only network needs FPGA V3 boards at firmware Rev 9 \
         (an FPGA V2 has one 100 Mb/s port, no switch and no Ethernet-only firmware); a set with V2 boards runs \
         as the bridge over FireWire: emulate it without --network eth, with a V2 board as the bridge \
         (--bridge-board), and `udp:` keeps the bridge as the Rev 9 host does"
    )]
    NotV3Rev9 {
        /// The board.
        board: u8,
        /// Its FPGA.
        fpga: FpgaVersion,
        /// Its firmware.
        profile: Profile,
    },
    /// The chain itself.
    #[error(transparent)]
    Chain(#[from] ChainError),
}

/// Where a datagram was sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Destination {
    /// To one board's own address.
    Board(u8),
    /// To the multicast group (or the subnet broadcast): every board.
    Group,
}

/// A datagram for the host.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outgoing {
    /// When its last byte reaches the host.
    pub at: SimTime,
    /// The board that sends it (its address is the source).
    pub from: u8,
    /// The host's address (of the request it answers).
    pub to: SocketAddr,
    /// The datagram: the 1394 response and the extra data.
    pub bytes: Vec<u8>,
}

/// Counters of the network; every datagram ends in exactly one of
/// `taken`, `malformed`, `bad_crc`, `unsupported`, `not_addressed`,
/// `needs_no_forward`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NetworkStats {
    /// Datagrams received.
    pub datagrams: u64,
    /// Datagrams at least one board took.
    pub taken: u64,
    /// Not a control word and one whole 1394 packet.
    pub malformed: u64,
    /// Header or data CRC wrong.
    pub bad_crc: u64,
    /// A tcode the boards do not take over Ethernet.
    pub unsupported: u64,
    /// Sent to a board's address but naming another board (or none
    /// answered a broadcast read).
    pub not_addressed: u64,
    /// A unicast without the no-forward flag (for a FireWire bus this
    /// network does not have).
    pub needs_no_forward: u64,
    /// Replies sent (the unsolicited responses included).
    pub replies: u64,
    /// Broadcast read queries taken.
    pub queries: u64,
    /// Unsolicited broadcast read responses sent.
    pub broadcast_responses: u64,
}

impl NetworkStats {
    /// Datagrams dropped, whatever the reason.
    pub fn dropped(&self) -> u64 {
        self.malformed
            + self.bad_crc
            + self.unsupported
            + self.not_addressed
            + self.needs_no_forward
    }
}

impl core::fmt::Display for NetworkStats {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} datagrams, {} replies ({} unsolicited broadcast responses to {} queries), \
             {} dropped: {} malformed, {} bad CRC, {} unsupported tcode, {} not addressed, \
             {} without the no-forward flag",
            self.datagrams,
            self.replies,
            self.broadcast_responses,
            self.queries,
            self.dropped(),
            self.malformed,
            self.bad_crc,
            self.unsupported,
            self.not_addressed,
            self.needs_no_forward
        )
    }
}

/// One board on the network.
struct NetBoard {
    fw: Firmware,
    phy: PhyRegisters,
    /// Virtual time its own events last ran to.
    advanced: SimTime,
}

/// A packet on its way to one board.
struct Delivery {
    board: u8,
    packet: Arc<[u8]>,
    no_forward: bool,
    host: SocketAddr,
    /// When the host's datagram arrived (for the extra data's times).
    sent: SimTime,
}

/// Something the network does at a time.
enum Event {
    /// A host packet reaches a board's real-time side.
    Deliver(Delivery),
    /// A selected board takes its status block and multicasts it.
    TakeStatus { board: u8, query: u64 },
    /// A status block lands in a board's hub.
    Land { board: u8, sender: u8, query: u64 },
}

/// The broadcast read in progress.
struct BroadcastRead {
    id: u64,
    host: SocketAddr,
    source: NodeId,
    tl: u8,
    /// The hub that answers, if any board is the hub.
    hub: Option<u8>,
    answered: bool,
    sent: SimTime,
    /// Status blocks taken so far, by board.
    blocks: Vec<(u8, Arc<[u8]>)>,
}

/// The boards and the chain.
pub struct EthNetwork {
    chain: EthChain,
    boards: Vec<NetBoard>,
    events: BTreeMap<(SimTime, u64), Event>,
    next_seq: u64,
    outbox: BTreeMap<(SimTime, u64), Outgoing>,
    read: Option<BroadcastRead>,
    now: SimTime,
    stats: NetworkStats,
}

impl EthNetwork {
    /// The boards of `configs`, chained in that order from the host (the
    /// first is nearest), each board's Eth1 toward the host.
    ///
    /// # Errors
    /// A board that is not an FPGA V3 at Rev 9; any [`ChainError`].
    pub fn new(configs: Vec<BoardConfig>, timing: EthTiming) -> Result<EthNetwork, NetworkError> {
        for c in &configs {
            if c.fpga != FpgaVersion::V3 || c.profile != Profile::Rev9 {
                return Err(NetworkError::NotV3Rev9 {
                    board: c.board_id,
                    fpga: c.fpga,
                    profile: c.profile,
                });
            }
        }
        let ids: Vec<u8> = configs.iter().map(|c| c.board_id).collect();
        let chain = EthChain::new(timing, &ids)?;
        let boards = configs
            .into_iter()
            .map(|c| {
                let id = c.board_id;
                let mut fw = Firmware::new(c);
                // No FireWire: the firmware's node is its board ID (the
                // no-forward addressing).
                fw.bus_reset(SimTime::ZERO, id, 1);
                fw.set_ethernet_link(true);
                fw.use_ethernet_hub();
                NetBoard {
                    fw,
                    phy: PhyRegisters::new(2),
                    advanced: SimTime::ZERO,
                }
            })
            .collect();
        Ok(EthNetwork {
            chain,
            boards,
            events: BTreeMap::new(),
            next_seq: 0,
            outbox: BTreeMap::new(),
            read: None,
            now: SimTime::ZERO,
            stats: NetworkStats::default(),
        })
    }

    /// The same network with board `id` cabled the other way round (its
    /// Eth2 toward the host).
    pub fn with_host_side(mut self, id: u8, port: SwitchPort) -> EthNetwork {
        self.chain = self.chain.with_host_side(id, port);
        self
    }

    /// Board IDs, nearest the host first.
    pub fn board_ids(&self) -> Vec<u8> {
        self.chain.order().collect()
    }

    /// The chain (its timing, what the switches learned).
    pub fn chain(&self) -> &EthChain {
        &self.chain
    }

    /// Counters so far.
    pub fn stats(&self) -> NetworkStats {
        self.stats
    }

    /// Virtual time now.
    pub fn now(&self) -> SimTime {
        self.now
    }

    /// Board `id`'s firmware.
    pub fn firmware(&self, id: u8) -> Option<&Firmware> {
        self.boards
            .iter()
            .find(|b| b.fw.board_id() == id)
            .map(|b| &b.fw)
    }

    /// Board `id`'s firmware, mutable (plants, faults).
    pub fn firmware_mut(&mut self, id: u8) -> Option<&mut Firmware> {
        self.boards
            .iter_mut()
            .find(|b| b.fw.board_id() == id)
            .map(|b| &mut b.fw)
    }

    fn schedule(&mut self, at: SimTime, event: Event) {
        self.events.insert((at, self.next_seq), event);
        self.next_seq += 1;
    }

    fn send(&mut self, out: Outgoing) {
        self.stats.replies += 1;
        self.outbox.insert((out.at, self.next_seq), out);
        self.next_seq += 1;
    }

    /// Take one datagram that arrived at `now` from `host`, sent to `to`.
    /// Virtual time first runs to `now`.
    pub fn handle(&mut self, now: SimTime, to: Destination, host: SocketAddr, datagram: &[u8]) {
        self.advance_to(now);
        let now = self.now.max(now);
        self.stats.datagrams += 1;
        let Ok((control, packet)) = split_host_datagram(datagram) else {
            self.stats.malformed += 1;
            return;
        };
        if packet.verify().is_err() {
            self.stats.bad_crc += 1;
            return;
        }
        let tcode = packet.tcode();
        let is_read = matches!(tcode, Tcode::ReadQuadletRequest | Tcode::ReadBlockRequest);
        let is_write = matches!(tcode, Tcode::WriteQuadletRequest | Tcode::WriteBlockRequest);
        if !is_read && !is_write {
            self.stats.unsupported += 1;
            return;
        }
        let dest = packet.destination_id();
        let broadcast = dest.phy() == NodeId::BROADCAST_PHY;
        if !broadcast && !control.no_forward {
            self.stats.needs_no_forward += 1;
            return;
        }
        let bytes: Arc<[u8]> = Arc::from(&packet.as_bytes()[..packet.total_len()]);
        let length = datagram.len();
        // Who takes it: a board's address reaches that board only; the
        // group reaches every board, each deciding by the 1394 address.
        let arrivals = match to {
            Destination::Board(id) => self.chain.from_host(now, Framing::Udp, length, Some(id)),
            Destination::Group => self.chain.from_host(now, Framing::Udp, length, None),
        };
        // A broadcast read goes to every board; each decides whether it is
        // the hub when it arrives (what its switch has learned by then).
        let takes = |id: u8| {
            if broadcast {
                is_write || control.no_forward
            } else {
                dest.phy() == id
            }
        };
        let taken: Vec<(u8, SimTime)> = arrivals
            .iter()
            .copied()
            .filter(|&(id, _)| takes(id))
            .collect();
        if taken.is_empty() {
            self.stats.not_addressed += 1;
            return;
        }
        self.stats.taken += 1;
        let query = broadcast
            && control.no_forward
            && tcode == Tcode::WriteQuadletRequest
            && packet.offset() & 0xFFFF == HUB_QUERY_OFFSET;
        if query {
            self.start_broadcast_read(now, host, &packet, &taken);
        }
        for (board, at) in taken {
            self.schedule(
                at,
                Event::Deliver(Delivery {
                    board,
                    packet: bytes.clone(),
                    no_forward: control.no_forward,
                    host,
                    sent: now,
                }),
            );
        }
    }

    /// A query reached the boards at `taken`: plan the status blocks.
    fn start_broadcast_read(
        &mut self,
        now: SimTime,
        host: SocketAddr,
        packet: &Packet<&[u8]>,
        taken: &[(u8, SimTime)],
    ) {
        let Ok(q) = Query::parse(packet.quadlet_data()) else {
            return;
        };
        if q.seq == 0 {
            return; // not a query (the firmware ignores it)
        }
        self.stats.queries += 1;
        let id = self.read.as_ref().map_or(0, |r| r.id + 1);
        let hub = self.chain.hub();
        // The blocks' size: every selected board's layout (header + block).
        let block_bytes = taken
            .iter()
            .filter(|(b, _)| q.board_mask & (1 << b) != 0)
            .filter_map(|(b, _)| self.firmware(*b))
            .map(|fw| fw.config().layout().broadcast_quadlets() * 4)
            .max()
            .unwrap_or(0);
        let plan =
            self.chain
                .broadcast_read(taken, q.board_mask, CONTROL_WORD_LEN + 24 + block_bytes);
        for (board, at) in plan.ready {
            self.schedule(at, Event::TakeStatus { board, query: id });
        }
        for landing in plan.landings {
            for (sender, at) in landing.entries {
                self.schedule(
                    at,
                    Event::Land {
                        board: landing.board,
                        sender,
                        query: id,
                    },
                );
            }
        }
        self.read = Some(BroadcastRead {
            id,
            host,
            source: packet.source_id(),
            tl: packet.tl(),
            hub,
            answered: false,
            sent: now,
            blocks: Vec::new(),
        });
    }

    /// Run virtual time to `t`: every event due by then, in time order,
    /// and every board's own events.
    pub fn advance_to(&mut self, t: SimTime) {
        while let Some(entry) = self.events.first_entry() {
            let (at, _) = *entry.key();
            if at > t {
                break;
            }
            let event = entry.remove();
            self.now = self.now.max(at);
            self.run(at, event);
        }
        if t > self.now {
            self.now = t;
        }
        for b in &mut self.boards {
            if t >= b.advanced + IDLE_STEP {
                b.fw.advance(t);
                b.advanced = t;
            }
        }
    }

    /// When the next event is due, if any.
    pub fn next_event(&self) -> Option<SimTime> {
        self.events.keys().next().map(|k| k.0)
    }

    /// Take the datagrams for the host due by `t` (the server sends them
    /// when the wall clock reaches their time), in time order.
    pub fn take_due(&mut self, t: SimTime, out: &mut Vec<Outgoing>) {
        while let Some(entry) = self.outbox.first_entry() {
            if entry.key().0 > t {
                break;
            }
            out.push(entry.remove());
        }
    }

    /// When the next datagram for the host is due, if any.
    pub fn next_due(&self) -> Option<SimTime> {
        self.outbox.keys().next().map(|k| k.0)
    }

    fn board_mut(&mut self, id: u8) -> Option<&mut NetBoard> {
        self.boards.iter_mut().find(|b| b.fw.board_id() == id)
    }

    fn run(&mut self, at: SimTime, event: Event) {
        match event {
            Event::Deliver(d) => self.deliver(at, d),
            Event::TakeStatus { board, query } => {
                let block = self
                    .board_mut(board)
                    .and_then(|b| b.fw.take_status_block(at));
                if let (Some(block), Some(read)) = (block, self.read.as_mut())
                    && read.id == query
                {
                    read.blocks.push((board, Arc::from(block)));
                }
            }
            Event::Land {
                board,
                sender,
                query,
            } => self.land(at, board, sender, query),
        }
    }

    fn land(&mut self, at: SimTime, board: u8, sender: u8, query: u64) {
        let Some(read) = self.read.as_ref().filter(|r| r.id == query) else {
            return;
        };
        let Some(block) = read
            .blocks
            .iter()
            .find(|(b, _)| *b == sender)
            .map(|(_, p)| p.clone())
        else {
            return;
        };
        let Some(b) = self.board_mut(board) else {
            return;
        };
        b.fw.store_status_block(at, &block);
        let complete = b.fw.hub_complete();
        let Some(read) = self.read.as_mut() else {
            return;
        };
        if read.hub != Some(board) || read.answered || !complete {
            return;
        }
        read.answered = true;
        let (host, header, sent) = (
            read.host,
            AsyncHeader {
                destination: read.source,
                source: NodeId::local(board),
                tl: read.tl,
                rt: 0,
                pri: 0,
            },
            read.sent,
        );
        let start = at + self.chain.timing().response_latency;
        let Some(b) = self.board_mut(board) else {
            return;
        };
        let Some(response) = b.fw.broadcast_read_response(start, header) else {
            return;
        };
        self.stats.broadcast_responses += 1;
        self.reply(board, start, sent, at, true, host, response);
    }

    /// The host's packet reaches `d.board` at `at`.
    fn deliver(&mut self, at: SimTime, d: Delivery) {
        let board = d.board;
        let mut bytes = d.packet.to_vec();
        let ip_write;
        {
            let Ok(packet) = Packet::new_checked(&bytes[..]) else {
                return;
            };
            ip_write = packet.tcode() == Tcode::WriteQuadletRequest
                && packet.offset() & 0xFFFF == IP_ADDRESS_OFFSET;
            // A broadcast read is taken by the hub only (EthernetIO.v
            // `isLocal`), and answered as its own.
            let read = matches!(
                packet.tcode(),
                Tcode::ReadQuadletRequest | Tcode::ReadBlockRequest
            );
            if read && packet.destination_id().phy() == NodeId::BROADCAST_PHY {
                if !self.chain.is_hub(board) {
                    return;
                }
                let mut p = Packet::new_unchecked(&mut bytes[..]);
                p.set_destination_id(NodeId::local(board));
                p.fill_header_crc();
            }
        }
        let Some(b) = self.board_mut(board) else {
            return;
        };
        b.advanced = at;
        let reply = b.fw.receive(at, &bytes, &mut b.phy);
        if ip_write {
            // The raw multicast quadlet write that teaches the switches.
            self.chain
                .from_board(at, Framing::Raw, IP_WRITE_MULTICAST_BYTES, board);
        }
        if let Reply::AckThenResponse { response, .. } = reply {
            let start = at + self.chain.timing().response_latency;
            self.reply(board, start, d.sent, at, d.no_forward, d.host, response);
        }
    }

    /// Send `response` from `board` starting at `start` (for a request
    /// the host sent at `sent` that reached the board at `received`).
    #[allow(clippy::too_many_arguments)]
    fn reply(
        &mut self,
        board: u8,
        start: SimTime,
        sent: SimTime,
        received: SimTime,
        no_forward: bool,
        host: SocketAddr,
        mut response: Vec<u8>,
    ) {
        let port = self.chain.source_port(board).map_or(0, SwitchPort::index);
        let generation = self.firmware(board).map_or(0, |f| f.generation() as u8);
        let extra = ExtraData {
            flags: ExtraFlags {
                no_forward,
                source_port: port,
                ..ExtraFlags::default()
            },
            generation,
            invalid_states: 0,
            packet_errors: (self.stats.malformed + self.stats.bad_crc).min(255) as u8,
            receive_time: ticks16(received.saturating_since(sent)),
            total_time: ticks16(start.saturating_since(sent)),
        };
        response.extend_from_slice(&extra.to_bytes());
        let at = self
            .chain
            .to_host(start, Framing::Udp, response.len(), board);
        self.send(Outgoing {
            at,
            from: board,
            to: host,
            bytes: response,
        });
    }
}

/// 49.152 MHz ticks in a virtual duration, saturating at 16 bits (the
/// host converts the extra data's times at that rate).
fn ticks16(d: SimDuration) -> u16 {
    u16::try_from(d.as_clocks()).unwrap_or(u16::MAX)
}
