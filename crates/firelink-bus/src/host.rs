//! The PC side: its link layer on the bus, and its software overhead.
//!
//! - [`HostLink`] is the PC's link (what an OHCI controller does): a
//!   [`Node`] that sends the request packets a host library hands it
//!   (arbitrating fair, like a PC), collects each transaction's ack and
//!   response (matched by the responder's node ID and the transaction
//!   label), acks the responses it receives, and keeps the broadcasts it
//!   hears. A host library drives it through
//!   [`Bus::with_node`](crate::bus::Bus::with_node).
//! - [`HostModel`] is the PC's software overhead per library call (the OS
//!   latency around each transaction), calibrated to seed 000's PC: a
//!   blocking block read costs 32 us and a block write 34 us in total, a
//!   broadcast write call 2.51 us. It is a separate piece: a host port adds
//!   its costs around the bus transactions. With jitter on, the costs are
//!   drawn from a seeded distribution with seed 000's standard deviations.
//!   [`HostModel::seed001`] is seed 001's PC instead: quadlet and block
//!   transactions priced apart, blocks by their size (Fig. 20 and 21).

use std::collections::VecDeque;

use firelink_wire::packet::{Ack, NodeId, Packet, Speed, Tcode};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

use crate::node::{ArbitrationClass, Node, NodeCtx, ResetInfo, RxReply, TransmitRequest};
use crate::time::{SimDuration, SimTime};
use crate::timing::BusTiming;

/// How a transaction ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Done: ack_complete for a write, a response for a read, or a broadcast
    /// that went out.
    Complete,
    /// No ack came (nobody there, corrupt packet, lost ack).
    NoAck,
    /// The responder was busy.
    Busy,
    /// The responder answered with an error ack (data or type error).
    AckError,
    /// An ack_pending came but no response within the split timeout.
    ResponseTimeout,
    /// The response arrived with a bad data CRC.
    ResponseCorrupt,
    /// A bus reset flushed the request.
    BusReset,
}

impl Outcome {
    /// How a transaction whose response arrived ends: complete, or
    /// corrupt when its data CRC failed (`data_ok` false).
    fn of_response(data_ok: bool) -> Outcome {
        if data_ok {
            Outcome::Complete
        } else {
            Outcome::ResponseCorrupt
        }
    }
}

/// One finished transaction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Completion {
    /// The token [`HostLink::submit`] returned.
    pub token: u64,
    /// Destination of the request.
    pub destination: NodeId,
    /// Transaction label of the request.
    pub tl: u8,
    /// Tcode of the request.
    pub tcode: Tcode,
    /// The ack received (`None` for broadcasts or when none came).
    pub ack: Option<Ack>,
    /// The response packet, if one came (bytes as received).
    pub response: Option<Vec<u8>>,
    /// When the request was handed to the link.
    pub submitted_at: SimTime,
    /// When the ack arrived (or the request finished, for broadcasts).
    pub acked_at: Option<SimTime>,
    /// When the transaction finished.
    pub completed_at: SimTime,
    /// How it ended.
    pub outcome: Outcome,
    /// Bus generation when it finished.
    pub generation: u32,
}

/// A packet the PC received that was not a response to one of its requests
/// (broadcasts, snooped traffic, requests addressed to the PC).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Received {
    /// When it arrived.
    pub at: SimTime,
    /// Its bytes as received.
    pub bytes: Vec<u8>,
    /// Its speed.
    pub speed: Speed,
    /// Whether every CRC in it checked out.
    pub crc_ok: bool,
}

#[derive(Clone, Debug)]
struct Pending {
    destination: NodeId,
    tl: u8,
    tcode: Tcode,
    submitted_at: SimTime,
    acked_at: Option<SimTime>,
    ack: Option<Ack>,
    awaiting_response: bool,
    response: Option<(Vec<u8>, bool)>,
}

/// The open transactions by token, in token order (a few at a time, and
/// tokens only grow: a sorted vector, where a new one goes at the end).
#[derive(Debug, Default)]
struct OpenTransactions(Vec<(u64, Pending)>);

impl OpenTransactions {
    fn position(&self, token: u64) -> Result<usize, usize> {
        self.0.binary_search_by_key(&token, |e| e.0)
    }

    /// Open `token` (replacing an open one with the same token).
    fn insert(&mut self, token: u64, p: Pending) {
        match self.position(token) {
            Ok(i) => {
                if let Some(e) = self.0.get_mut(i) {
                    e.1 = p;
                }
            }
            Err(i) => self.0.insert(i, (token, p)),
        }
    }

    fn contains_key(&self, token: &u64) -> bool {
        self.position(*token).is_ok()
    }

    fn len(&self) -> usize {
        self.0.len()
    }

    fn get(&self, token: &u64) -> Option<&Pending> {
        let i = self.position(*token).ok()?;
        self.0.get(i).map(|e| &e.1)
    }

    fn get_mut(&mut self, token: &u64) -> Option<&mut Pending> {
        let i = self.position(*token).ok()?;
        self.0.get_mut(i).map(|e| &mut e.1)
    }

    fn remove(&mut self, token: &u64) -> Option<Pending> {
        let i = self.position(*token).ok()?;
        Some(self.0.remove(i).1)
    }

    /// Every open transaction, in token order.
    fn iter(&self) -> std::slice::Iter<'_, (u64, Pending)> {
        self.0.iter()
    }

    /// Every open token, in order.
    fn tokens(&self) -> impl Iterator<Item = u64> + '_ {
        self.0.iter().map(|e| e.0)
    }
}

/// The PC's link layer. See the module docs.
#[derive(Debug)]
pub struct HostLink {
    name: String,
    class: ArbitrationClass,
    next_token: u64,
    pending: OpenTransactions,
    completions: VecDeque<Completion>,
    received: VecDeque<Received>,
    received_limit: usize,
    /// Buffers of packets forgotten, kept for the next ones (a link that
    /// hears every broadcast allocates nothing per packet).
    spare: Vec<Vec<u8>>,
    /// Buffers of responses given back ([`recycle`](Self::recycle)), kept
    /// for the next responses (apart from `spare`, so that the buffers of
    /// received packets keep the sizes of the packets they go round with).
    spare_responses: Vec<Vec<u8>>,
    received_total: u64,
    split_timeout: SimDuration,
    phy_id: u8,
    generation: u32,
    resets: u32,
}

/// Received-packet buffers a link keeps for reuse.
const SPARE_BUFFERS: usize = 64;

/// Timer tokens of [`HostLink`] are the transaction tokens (split timeouts).
impl HostLink {
    /// A link named `name` that arbitrates fair and waits 100 ms for split
    /// responses.
    pub fn new(name: impl Into<String>) -> HostLink {
        HostLink {
            name: name.into(),
            class: ArbitrationClass::Fair,
            next_token: 1,
            pending: OpenTransactions::default(),
            completions: VecDeque::new(),
            received: VecDeque::new(),
            received_limit: 4096,
            spare: Vec::new(),
            spare_responses: Vec::new(),
            received_total: 0,
            split_timeout: SimDuration::from_millis(100),
            phy_id: NodeId::BROADCAST_PHY,
            generation: 0,
            resets: 0,
        }
    }

    /// Use `class` for every request (a PC uses fair).
    pub fn with_class(mut self, class: ArbitrationClass) -> HostLink {
        self.class = class;
        self
    }

    /// Wait `timeout` for split responses after an ack_pending.
    pub fn with_split_timeout(mut self, timeout: SimDuration) -> HostLink {
        self.split_timeout = timeout;
        self
    }

    /// Change the split time-out of later transactions (the Linux
    /// kernel's is 2 s; the /dev/fw* twin sets it on a built bus).
    pub fn set_split_timeout(&mut self, timeout: SimDuration) {
        self.split_timeout = timeout;
    }

    /// Keep at most `limit` received packets (older ones are dropped).
    pub fn with_received_limit(mut self, limit: usize) -> HostLink {
        self.received_limit = limit;
        self
    }

    /// The PC's physical ID (63 before the first reset).
    pub fn phy_id(&self) -> u8 {
        self.phy_id
    }

    /// The PC's node ID on the local bus.
    pub fn node_id(&self) -> NodeId {
        NodeId::local(self.phy_id)
    }

    /// The bus generation the link last saw.
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// Bus resets seen.
    pub fn resets(&self) -> u32 {
        self.resets
    }

    /// Send a complete request packet (with CRCs) at `speed`; returns the
    /// token its [`Completion`] will carry. Broadcast requests and PHY
    /// packets (link-internal form) complete when they have gone out;
    /// unicast ones when acked (and answered, after an ack_pending).
    pub fn submit(&mut self, ctx: &mut NodeCtx<'_>, packet: Vec<u8>, speed: Speed) -> u64 {
        self.submit_as(ctx, packet, speed, false)
    }

    /// [`submit`](Self::submit) a request whose header CRC and data CRC
    /// the bus writes ([`NodeCtx::transmit_sealed`]: whatever those fields
    /// hold is overwritten): the bytes that go out are those of the same
    /// request with its CRCs filled, and the bus does not check them again
    /// at delivery unless a fault changes them.
    pub fn submit_sealed(&mut self, ctx: &mut NodeCtx<'_>, packet: Vec<u8>, speed: Speed) -> u64 {
        self.submit_as(ctx, packet, speed, true)
    }

    fn submit_as(
        &mut self,
        ctx: &mut NodeCtx<'_>,
        packet: Vec<u8>,
        speed: Speed,
        sealed: bool,
    ) -> u64 {
        let token = self.next_token;
        self.next_token += 1;
        let view = Packet::new_unchecked(&packet[..]);
        self.pending.insert(
            token,
            Pending {
                destination: view.destination_id(),
                tl: view.tl(),
                tcode: view.tcode(),
                submitted_at: ctx.now(),
                acked_at: None,
                ack: None,
                awaiting_response: false,
                response: None,
            },
        );
        let request = TransmitRequest {
            packet,
            speed,
            class: self.class,
            token,
        };
        if sealed {
            ctx.transmit_sealed(request);
        } else {
            ctx.transmit(request);
        }
        token
    }

    /// Whether the transaction with `token` is still open.
    pub fn is_pending(&self, token: u64) -> bool {
        self.pending.contains_key(&token)
    }

    /// Open transactions.
    pub fn pending_count(&self) -> usize {
        self.pending.len()
    }

    /// Finished transactions not yet taken.
    pub fn completions(&self) -> impl Iterator<Item = &Completion> {
        self.completions.iter()
    }

    /// Take the completion of `token`, if it finished.
    pub fn take_completion(&mut self, token: u64) -> Option<Completion> {
        let i = self.completions.iter().position(|c| c.token == token)?;
        self.completions.remove(i)
    }

    /// Give up on the transaction `token`: it is forgotten whether it is
    /// still open or already finished, and a late answer to it is dropped
    /// like any unmatched packet. A caller that stops waiting must call
    /// this, or finished transactions pile up.
    pub fn abandon(&mut self, token: u64) {
        if self.pending.remove(&token).is_none() {
            if let Some(i) = self.completions.iter().position(|c| c.token == token) {
                self.completions.remove(i);
            }
        }
    }

    /// Forget every packet received that was not a response (a bridge has
    /// no use for other nodes' broadcasts).
    pub fn clear_received(&mut self) {
        for r in self.received.drain(..) {
            if self.spare.len() < SPARE_BUFFERS {
                self.spare.push(r.bytes);
            }
        }
    }

    /// Give back the memory of a [`Completion`]'s response once the
    /// caller is done with it: the link copies its next response into it
    /// instead of allocating. At most a few are kept; the rest are freed.
    pub fn recycle(&mut self, mut response: Vec<u8>) {
        if self.spare_responses.len() < SPARE_BUFFERS {
            response.clear();
            self.spare_responses.push(response);
        }
    }

    /// Take every finished transaction.
    pub fn take_completions(&mut self) -> Vec<Completion> {
        self.completions.drain(..).collect()
    }

    /// Packets received that were not responses to our requests.
    pub fn received(&self) -> impl DoubleEndedIterator<Item = &Received> + ExactSizeIterator {
        self.received.iter()
    }

    /// Packets received so far (taken or not, dropped over the limit or
    /// not).
    pub fn received_total(&self) -> u64 {
        self.received_total
    }

    /// Take every received packet.
    pub fn take_received(&mut self) -> Vec<Received> {
        self.received.drain(..).collect()
    }

    /// Submit `packet` through the link node `link` of `bus` (how a host
    /// port or a bridge drives its link from outside the simulation). The
    /// link copies the packet into its transmit FIFO (a spare packet
    /// buffer of the bus, [`NodeCtx::take_buffer`]): the caller keeps its
    /// buffer.
    ///
    /// # Errors
    /// [`BusError`](crate::BusError) if `link` is not a [`HostLink`].
    pub fn submit_on(
        bus: &mut crate::Bus,
        link: crate::NodeHandle,
        packet: &[u8],
        speed: Speed,
    ) -> Result<u64, crate::BusError> {
        Self::submit_on_as(bus, link, packet, speed, false)
    }

    /// [`submit_on`](Self::submit_on) a request for the bus to seal
    /// ([`submit_sealed`](Self::submit_sealed)): its CRC fields may hold
    /// anything.
    ///
    /// # Errors
    /// [`BusError`](crate::BusError) if `link` is not a [`HostLink`].
    pub fn submit_sealed_on(
        bus: &mut crate::Bus,
        link: crate::NodeHandle,
        packet: &[u8],
        speed: Speed,
    ) -> Result<u64, crate::BusError> {
        Self::submit_on_as(bus, link, packet, speed, true)
    }

    fn submit_on_as(
        bus: &mut crate::Bus,
        link: crate::NodeHandle,
        packet: &[u8],
        speed: Speed,
        sealed: bool,
    ) -> Result<u64, crate::BusError> {
        bus.with_node::<HostLink, _>(link, |l, ctx| {
            let mut fifo = ctx.take_buffer();
            fifo.extend_from_slice(packet);
            l.submit_as(ctx, fifo, speed, sealed)
        })
    }

    /// Run `bus` until the transaction `token` of the link `link` finishes
    /// or the next event is after `deadline`, and take its completion. On a
    /// time-out the transaction is [abandoned](Self::abandon): `None`, and
    /// nothing of it stays behind.
    pub fn wait_on(
        bus: &mut crate::Bus,
        link: crate::NodeHandle,
        token: u64,
        deadline: SimTime,
    ) -> Option<Completion> {
        // The link's state changes only when the bus calls into it.
        let mut looked_at = None;
        bus.run_until_with(deadline, |b| {
            b.called_since(link, &mut looked_at)
                && b.node::<HostLink>(link)
                    .is_some_and(|l| !l.is_pending(token))
        });
        let l = bus.node_mut::<HostLink>(link)?;
        let done = l.take_completion(token);
        if done.is_none() {
            // Timed out: nobody will take it later.
            l.abandon(token);
        }
        done
    }

    fn finish(&mut self, token: u64, now: SimTime, outcome: Outcome, ctx: &mut NodeCtx<'_>) {
        let Some(p) = self.pending.remove(&token) else {
            return;
        };
        ctx.cancel_timer(token);
        self.completions.push_back(Completion {
            token,
            destination: p.destination,
            tl: p.tl,
            tcode: p.tcode,
            ack: p.ack,
            response: p.response.map(|(b, _)| b),
            submitted_at: p.submitted_at,
            acked_at: p.acked_at,
            completed_at: now,
            outcome,
            generation: self.generation,
        });
    }

    /// A buffer holding `packet` (a spare one when there is one).
    fn copy_of(&mut self, packet: &[u8]) -> Vec<u8> {
        copy_from_spare(&mut self.spare, packet)
    }

    fn keep(&mut self, received: Received) {
        if self.received.len() >= self.received_limit
            && let Some(old) = self.received.pop_front()
            && self.spare.len() < SPARE_BUFFERS
        {
            // The oldest goes; its buffer stays for the next packet.
            self.spare.push(old.bytes);
        }
        self.received.push_back(received);
        self.received_total += 1;
    }
}

/// A buffer holding `packet`: one of `spare` when there is one.
fn copy_from_spare(spare: &mut Vec<Vec<u8>>, packet: &[u8]) -> Vec<u8> {
    let mut bytes = spare.pop().unwrap_or_default();
    bytes.clear();
    bytes.extend_from_slice(packet);
    bytes
}

/// The response tcode that answers a request tcode.
fn response_tcode(request: Tcode) -> Option<Tcode> {
    match request {
        Tcode::WriteQuadletRequest | Tcode::WriteBlockRequest => Some(Tcode::WriteResponse),
        Tcode::ReadQuadletRequest => Some(Tcode::ReadQuadletResponse),
        Tcode::ReadBlockRequest => Some(Tcode::ReadBlockResponse),
        Tcode::LockRequest => Some(Tcode::LockResponse),
        _ => None,
    }
}

impl Node for HostLink {
    fn name(&self) -> &str {
        &self.name
    }

    fn on_bus_reset(&mut self, now: SimTime, info: &ResetInfo, ctx: &mut NodeCtx<'_>) {
        self.phy_id = info.phy_id;
        self.generation = info.generation;
        self.resets += 1;
        let open: Vec<u64> = self.pending.tokens().collect();
        for token in open {
            self.finish(token, now, Outcome::BusReset, ctx);
        }
    }

    fn on_receive(
        &mut self,
        now: SimTime,
        packet: &[u8],
        speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply {
        let Ok(view) = Packet::new_checked(packet) else {
            ctx.report_error("host: malformed packet");
            return RxReply::Silent;
        };
        let status = ctx
            .received_crc_status()
            .unwrap_or_else(|| view.crc_status());
        // A response whose header CRC fails is dropped here and one whose
        // data CRC fails completes `ResponseCorrupt`, never `Complete`:
        // the host's transaction engine takes a `Complete` response as
        // checked (`CrcCheck::KnownGood` in firelink-host) and relies on it.
        if status.header_ok == Some(false) {
            ctx.report_error("host: header CRC error");
            return RxReply::Silent;
        }
        let tcode = view.tcode();
        let to_us = view.destination_id().phy() == self.phy_id;
        if to_us && tcode.is_response() {
            let source = view.source_id();
            let tl = view.tl();
            let found = self.pending.iter().find_map(|&(token, ref p)| {
                (p.destination.phy() == source.phy()
                    && p.tl == tl
                    && response_tcode(p.tcode) == Some(tcode)
                    && p.response.is_none())
                .then_some(token)
            });
            let data_ok = status.data_ok != Some(false);
            if !data_ok {
                ctx.report_error("host: response data CRC error");
            }
            let Some(token) = found else {
                ctx.report_error("host: response matches no open transaction");
                return RxReply::Ack(if data_ok {
                    Ack::Complete
                } else {
                    Ack::DataError
                });
            };
            if let Some(p) = self.pending.get_mut(&token) {
                p.response = Some((copy_from_spare(&mut self.spare_responses, packet), data_ok));
                if p.awaiting_response {
                    self.finish(token, now, Outcome::of_response(data_ok), ctx);
                }
            }
            return RxReply::Ack(if data_ok {
                Ack::Complete
            } else {
                Ack::DataError
            });
        }
        let bytes = self.copy_of(packet);
        self.keep(Received {
            at: now,
            bytes,
            speed,
            crc_ok: status.all_ok(),
        });
        if !to_us || view.destination_id().is_broadcast() {
            return RxReply::Silent;
        }
        if status.data_ok == Some(false) {
            return RxReply::Ack(Ack::DataError);
        }
        match tcode {
            Tcode::WriteQuadletRequest | Tcode::WriteBlockRequest => RxReply::Ack(Ack::Complete),
            _ => RxReply::Ack(Ack::TypeError),
        }
    }

    fn on_transmitted(
        &mut self,
        now: SimTime,
        token: u64,
        ack: Option<Ack>,
        ctx: &mut NodeCtx<'_>,
    ) {
        let Some(p) = self.pending.get_mut(&token) else {
            return;
        };
        p.ack = ack;
        p.acked_at = Some(now);
        // Broadcasts and PHY packets are never acked.
        let broadcast = p.destination.is_broadcast() || p.tcode == Tcode::LinkInternal;
        match ack {
            None if broadcast => self.finish(token, now, Outcome::Complete, ctx),
            // A lost ack may still be followed by the response.
            None => match p.response {
                Some((_, ok)) => self.finish(token, now, Outcome::of_response(ok), ctx),
                None => self.finish(token, now, Outcome::NoAck, ctx),
            },
            Some(Ack::Complete) => self.finish(token, now, Outcome::Complete, ctx),
            Some(Ack::Pending) => {
                if let Some((_, ok)) = p.response {
                    self.finish(token, now, Outcome::of_response(ok), ctx);
                } else {
                    p.awaiting_response = true;
                    ctx.set_timer(now + self.split_timeout, token);
                }
            }
            Some(Ack::BusyX | Ack::BusyA | Ack::BusyB) => {
                self.finish(token, now, Outcome::Busy, ctx)
            }
            Some(_) => self.finish(token, now, Outcome::AckError, ctx),
        }
    }

    fn on_timer(&mut self, now: SimTime, token: u64, ctx: &mut NodeCtx<'_>) {
        if self
            .pending
            .get(&token)
            .is_some_and(|p| p.awaiting_response)
        {
            ctx.report_error("host: split response timeout");
            self.finish(token, now, Outcome::ResponseTimeout, ctx);
        }
    }
}

/// Which library call a cost is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HostCall {
    /// A blocking read (`raw1394_read`).
    Read,
    /// A blocking write (`raw1394_write`).
    Write,
    /// A non-blocking broadcast write (`raw1394_start_write`).
    BroadcastWrite,
}

/// The cost of one call around its bus transaction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CallCost {
    /// From the call to the request reaching the link.
    pub before: SimDuration,
    /// From the transaction finishing at the link to the call returning
    /// (0 for non-blocking calls, which return after `before`).
    pub after: SimDuration,
}

/// How the cost of one kind of call varies from call to call (used when
/// jitter is on).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Spread {
    /// A normal deviate with this standard deviation (seed 000's figures).
    Normal(SimDuration),
    /// Discrete bands, as seed 001's Fig. 20 shows: the total lands at the
    /// mean plus `offsets_us[i]` with probability `weights[i]` (weights sum
    /// to 1 and the offsets average to 0, so the mean is kept).
    Bands {
        /// Offsets from the mean total, us.
        offsets_us: [f64; 3],
        /// Probability of each band.
        weights: [f64; 3],
    },
}

/// Mean costs and spread of one kind of call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CallModel {
    /// Mean time before the request reaches the link.
    pub before: SimDuration,
    /// Mean time after the transaction until the call returns.
    pub after: SimDuration,
    /// Extra time per quadlet of block payload (copying it through the
    /// OS): after the transaction for reads, before it for writes.
    pub per_quadlet: SimDuration,
    /// How the total varies (used when jitter is on).
    pub spread: Spread,
}

/// What a call moves: one quadlet, or a block of some quadlets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transfer {
    /// A quadlet read or write.
    Quadlet,
    /// A block read or write of this many quadlets.
    Block {
        /// Quadlets of payload.
        quadlets: usize,
    },
}

impl Transfer {
    /// What a request packet moves (anything but a block request counts
    /// as a quadlet transaction).
    pub fn of(request: &firelink_wire::packet::PacketRepr<'_>) -> Transfer {
        use firelink_wire::packet::PacketRepr;
        match request {
            PacketRepr::ReadBlockRequest { data_length, .. } => Transfer::Block {
                quadlets: usize::from(*data_length).div_ceil(4),
            },
            PacketRepr::WriteBlockRequest { data, .. } => Transfer::Block {
                quadlets: data.len().div_ceil(4),
            },
            _ => Transfer::Quadlet,
        }
    }

    /// Payload bytes moved: 4 for a quadlet, else the block's quadlets
    /// (at least one).
    pub fn bytes(self) -> usize {
        match self {
            Transfer::Quadlet => 4,
            Transfer::Block { quadlets } => 4 * quadlets.max(1),
        }
    }
}

/// The PC's per-call software overhead. See the module docs.
#[derive(Clone, Debug)]
pub struct HostModel {
    /// Blocking block read.
    pub read: CallModel,
    /// Blocking block write.
    pub write: CallModel,
    /// Non-blocking broadcast write.
    pub broadcast_write: CallModel,
    /// Blocking quadlet read, when it costs differently from a block read
    /// (`None`: as a block read).
    pub quadlet_read: Option<CallModel>,
    /// Blocking quadlet write, when it costs differently from a block
    /// write (`None`: as a block write).
    pub quadlet_write: Option<CallModel>,
    rng: Option<ChaCha8Rng>,
}

/// Seed 000's PC: mean blocking read and write transaction times (Fig. 6).
pub const SEED000_READ_US: f64 = 32.0;
/// See [`SEED000_READ_US`].
pub const SEED000_WRITE_US: f64 = 34.0;
/// Seed 000's broadcast write call (Fig. 10a).
pub const SEED000_BROADCAST_CALL_US: f64 = 2.51;
/// Standard deviations measured in seed 000 (read, write, broadcast call).
pub const SEED000_SD_US: [f64; 3] = [12.02, 8.56, 2.71];

/// Seed 001's PC (a 2 GHz Pentium 4 under Linux, one node, S400): mean
/// quadlet read and write transaction times over 9000 iterations (§8.2).
pub const SEED001_QUADLET_READ_US: f64 = 34.5;
/// See [`SEED001_QUADLET_READ_US`].
pub const SEED001_QUADLET_WRITE_US: f64 = 30.2;
/// Seed 001's block transfers (§8.3, Fig. 21): base latency of a block
/// read and a block write, us.
pub const SEED001_BLOCK_BASE_US: [f64; 2] = [33.2, 30.7];
/// Seed 001's block transfer speeds from the slopes up to 512 quadlets,
/// Mb/s (read, write).
pub const SEED001_BLOCK_MBPS: [f64; 2] = [360.0, 290.0];
/// The bands of Fig. 20, us: quadlet reads at 30, 42 and 49, writes at 27
/// and 42, the lowest band the most common.
pub const SEED001_READ_BANDS_US: [f64; 3] = [30.0, 42.0, 49.0];
/// See [`SEED001_READ_BANDS_US`].
pub const SEED001_WRITE_BANDS_US: [f64; 2] = [27.0, 42.0];
/// Spread of block transfers: "about 20 us" of noise on Fig. 21 (§8.4),
/// taken as +-2 standard deviations.
pub const SEED001_BLOCK_SD_US: f64 = 5.0;

/// The OS part of a call whose measured mean total is `total_us` for a
/// transaction of wire time `wire`, split evenly before and after.
fn split_call(total_us: f64, wire: SimDuration, spread: Spread) -> CallModel {
    let os = SimDuration::from_micros_f64(total_us) - wire;
    CallModel {
        before: SimDuration(os.0 / 2),
        after: SimDuration(os.0 - os.0 / 2),
        per_quadlet: SimDuration::ZERO,
        spread,
    }
}

/// Three bands of totals with the paper's mean: the top band of reads
/// is taken as a tenth of the calls, the rest split so the mean holds.
fn bands(mean: f64, totals: [f64; 3], top_weight: f64) -> Spread {
    let [lo, mid, hi] = totals;
    let mid_weight = ((mean - lo) - top_weight * (hi - lo)) / (mid - lo);
    Spread::Bands {
        offsets_us: [lo - mean, mid - mean, hi - mean],
        weights: [1.0 - mid_weight - top_weight, mid_weight, top_weight],
    }
}

impl HostModel {
    /// Seed 000's PC, calibrated for `timing`: the OS part of a call is the
    /// measured total minus the nominal wire time of the transaction the
    /// paper measured (a 48-byte block read, a 16-byte block write, at S400
    /// to the adjacent board), split evenly before and after. No jitter.
    pub fn seed000(timing: &BusTiming) -> HostModel {
        let wire_read = timing.nominal_block_read(48, Speed::S400, 1);
        let wire_write = timing.nominal_block_write(16, Speed::S400, 1);
        let normal = |sd: f64| Spread::Normal(SimDuration::from_micros_f64(sd));
        HostModel {
            read: split_call(SEED000_READ_US, wire_read, normal(SEED000_SD_US[0])),
            write: split_call(SEED000_WRITE_US, wire_write, normal(SEED000_SD_US[1])),
            broadcast_write: CallModel {
                before: SimDuration::from_micros_f64(SEED000_BROADCAST_CALL_US),
                after: SimDuration::ZERO,
                per_quadlet: SimDuration::ZERO,
                spread: normal(SEED000_SD_US[2]),
            },
            quadlet_read: None,
            quadlet_write: None,
            rng: None,
        }
    }

    /// Seed 001's PC, calibrated for `timing` the same way, per kind of
    /// transaction: quadlet reads and writes take their measured means
    /// (34.5 and 30.2 us) with the bands of Fig. 20 as their spread; a
    /// block of `n` quadlets takes the base latency (33.2 us read, 30.7 us
    /// write) plus `n` quadlets at the measured speed (360 and 290 Mb/s),
    /// the wire's own share of both subtracted (its intercept and slope
    /// at S400 to the adjacent node, up to the moment the PC's link has
    /// the answer: the response of a read, the ack of a write). No jitter
    /// until [`with_jitter`](Self::with_jitter).
    pub fn seed001(timing: &BusTiming) -> HostModel {
        // A read is done for the PC when the response has arrived; its own
        // ack of the response follows on the wire.
        let final_ack = timing.ack_gap + timing.ack_time(Speed::S400);
        let one = |f: &dyn Fn(usize) -> SimDuration, n: usize| f(n).as_micros_f64();
        let block = |f: &dyn Fn(usize) -> SimDuration, base: f64, mbps: f64| {
            // The wire is linear in the payload: fit it over the sweep.
            let (a, b) = (one(f, 1), one(f, 512));
            let wire_slope = (b - a) / 511.0;
            let wire_base = a - wire_slope;
            let target_slope = 32.0 / mbps;
            let mut m = split_call(
                base,
                SimDuration::from_micros_f64(wire_base),
                Spread::Normal(SimDuration::from_micros_f64(SEED001_BLOCK_SD_US)),
            );
            m.per_quadlet = SimDuration::from_micros_f64(target_slope - wire_slope);
            m
        };
        let read_wire = |n: usize| timing.nominal_block_read(4 * n, Speed::S400, 1) - final_ack;
        let write_wire = |n: usize| timing.nominal_block_write(4 * n, Speed::S400, 1);
        let [w_lo, w_hi] = SEED001_WRITE_BANDS_US;
        HostModel {
            read: block(&read_wire, SEED001_BLOCK_BASE_US[0], SEED001_BLOCK_MBPS[0]),
            write: block(&write_wire, SEED001_BLOCK_BASE_US[1], SEED001_BLOCK_MBPS[1]),
            // The seed's node ignores broadcasts; a broadcast call costs
            // what a write call costs before the packet goes out.
            broadcast_write: CallModel {
                before: SimDuration::from_micros_f64(SEED001_BLOCK_BASE_US[1] / 2.0),
                after: SimDuration::ZERO,
                per_quadlet: SimDuration::ZERO,
                spread: Spread::Normal(SimDuration::from_micros_f64(SEED001_BLOCK_SD_US)),
            },
            quadlet_read: Some(split_call(
                SEED001_QUADLET_READ_US,
                timing.nominal_quadlet_read(Speed::S400, 1) - final_ack,
                bands(SEED001_QUADLET_READ_US, SEED001_READ_BANDS_US, 0.1),
            )),
            quadlet_write: Some(split_call(
                SEED001_QUADLET_WRITE_US,
                timing.nominal_quadlet_write(Speed::S400, 1),
                bands(SEED001_QUADLET_WRITE_US, [w_lo, w_hi, w_hi], 0.0),
            )),
            rng: None,
        }
    }

    /// Draw each cost from a seeded distribution: the mean plus a deviate
    /// of the call's [`Spread`], never below a quarter of the mean.
    pub fn with_jitter(mut self, seed: u64) -> HostModel {
        self.rng = Some(ChaCha8Rng::seed_from_u64(seed ^ 0x05_0000_1394));
        self
    }

    /// Whether jitter is on.
    pub fn has_jitter(&self) -> bool {
        self.rng.is_some()
    }

    /// The model of one kind of call moving `transfer`.
    pub fn model_of(&self, call: HostCall, transfer: Transfer) -> CallModel {
        match (call, transfer) {
            (HostCall::Read, Transfer::Quadlet) => self.quadlet_read.unwrap_or(self.read),
            (HostCall::Write, Transfer::Quadlet) => self.quadlet_write.unwrap_or(self.write),
            (HostCall::Read, _) => self.read,
            (HostCall::Write, _) => self.write,
            (HostCall::BroadcastWrite, _) => self.broadcast_write,
        }
    }

    /// The model of one kind of call (block transfers).
    pub fn model(&self, call: HostCall) -> CallModel {
        self.model_of(call, Transfer::Block { quadlets: 0 })
    }

    /// The mean cost of one call moving `transfer`, before and after its
    /// transaction.
    pub fn mean_cost(&self, call: HostCall, transfer: Transfer) -> CallCost {
        let m = self.model_of(call, transfer);
        let quadlets = match transfer {
            Transfer::Quadlet => 0,
            Transfer::Block { quadlets } => quadlets as u64,
        };
        let copy = SimDuration(m.per_quadlet.0.saturating_mul(quadlets));
        match call {
            HostCall::Read => CallCost {
                before: m.before,
                after: m.after + copy,
            },
            HostCall::Write | HostCall::BroadcastWrite => CallCost {
                before: m.before + copy,
                after: m.after,
            },
        }
    }

    /// The cost of one call moving `transfer` (a fresh draw when jitter
    /// is on).
    pub fn cost_of(&mut self, call: HostCall, transfer: Transfer) -> CallCost {
        let mean_cost = self.mean_cost(call, transfer);
        let spread = self.model_of(call, transfer).spread;
        let Some(rng) = self.rng.as_mut() else {
            return mean_cost;
        };
        let mean = (mean_cost.before + mean_cost.after).as_micros_f64();
        let deviation = match spread {
            Spread::Normal(sd) => standard_normal(rng) * sd.as_micros_f64(),
            Spread::Bands {
                offsets_us,
                weights,
            } => {
                let u = unit(rng);
                let mut acc = 0.0;
                let mut pick = offsets_us[0];
                for (offset, weight) in offsets_us.iter().zip(weights) {
                    acc += weight;
                    pick = *offset;
                    if u < acc {
                        break;
                    }
                }
                pick
            }
        };
        let total = (mean + deviation).max(mean / 4.0);
        let scale = if mean > 0.0 { total / mean } else { 1.0 };
        CallCost {
            before: SimDuration::from_micros_f64(mean_cost.before.as_micros_f64() * scale),
            after: SimDuration::from_micros_f64(mean_cost.after.as_micros_f64() * scale),
        }
    }

    /// The cost of one call (block transfers of no payload; a fresh draw
    /// when jitter is on).
    pub fn cost(&mut self, call: HostCall) -> CallCost {
        self.cost_of(call, Transfer::Block { quadlets: 0 })
    }
}

/// A uniform deviate in (0, 1) from a seeded RNG.
fn unit(rng: &mut ChaCha8Rng) -> f64 {
    ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
}

/// A standard normal deviate (Box-Muller) from a seeded RNG.
fn standard_normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = unit(rng);
    let u2 = unit(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed000_calibration_adds_up() {
        let t = BusTiming::default();
        let mut m = HostModel::seed000(&t);
        let c = m.cost(HostCall::Read);
        let total = c.before + c.after + t.nominal_block_read(48, Speed::S400, 1);
        assert!((total.as_micros_f64() - 32.0).abs() < 1e-6);
        let c = m.cost(HostCall::Write);
        let total = c.before + c.after + t.nominal_block_write(16, Speed::S400, 1);
        assert!((total.as_micros_f64() - 34.0).abs() < 1e-6);
        assert_eq!(
            m.cost(HostCall::BroadcastWrite).before,
            SimDuration::from_micros_f64(2.51)
        );
    }

    #[test]
    fn seed001_calibration_adds_up() {
        let t = BusTiming::default();
        let m = HostModel::seed001(&t);
        let final_ack = t.ack_gap + t.ack_time(Speed::S400);
        let total = |call, transfer, wire: SimDuration| {
            let c = m.mean_cost(call, transfer);
            (c.before + c.after + wire).as_micros_f64()
        };
        let q = total(
            HostCall::Read,
            Transfer::Quadlet,
            t.nominal_quadlet_read(Speed::S400, 1) - final_ack,
        );
        assert!((q - 34.5).abs() < 1e-5, "{q}");
        let q = total(
            HostCall::Write,
            Transfer::Quadlet,
            t.nominal_quadlet_write(Speed::S400, 1),
        );
        assert!((q - 30.2).abs() < 1e-5, "{q}");
        // Blocks: base + n x 32 bits at the measured speed.
        for n in [1usize, 7, 23, 100, 512] {
            let r = total(
                HostCall::Read,
                Transfer::Block { quadlets: n },
                t.nominal_block_read(4 * n, Speed::S400, 1) - final_ack,
            );
            let expect = 33.2 + n as f64 * 32.0 / 360.0;
            assert!((r - expect).abs() < 1e-3, "{n}: {r} vs {expect}");
            let w = total(
                HostCall::Write,
                Transfer::Block { quadlets: n },
                t.nominal_block_write(4 * n, Speed::S400, 1),
            );
            let expect = 30.7 + n as f64 * 32.0 / 290.0;
            assert!((w - expect).abs() < 1e-3, "{n}: {w} vs {expect}");
        }
    }

    #[test]
    fn seed001_bands_keep_the_mean() {
        let t = BusTiming::default();
        let mut m = HostModel::seed001(&t).with_jitter(1);
        let final_ack = t.ack_gap + t.ack_time(Speed::S400);
        let wire = (t.nominal_quadlet_read(Speed::S400, 1) - final_ack).as_micros_f64();
        let draws: Vec<f64> = (0..20_000)
            .map(|_| {
                let c = m.cost_of(HostCall::Read, Transfer::Quadlet);
                (c.before + c.after).as_micros_f64() + wire
            })
            .collect();
        let mean = draws.iter().sum::<f64>() / draws.len() as f64;
        assert!((mean - 34.5).abs() < 0.3, "{mean}");
        // Three bands, the lowest the most common.
        let near = |b: f64| draws.iter().filter(|d| (*d - b).abs() < 0.01).count();
        let (lo, mid, hi) = (near(30.0), near(42.0), near(49.0));
        assert_eq!(lo + mid + hi, draws.len());
        assert!(lo > mid && mid > hi && hi > 0, "{lo} {mid} {hi}");
    }

    #[test]
    fn jitter_is_seeded() {
        let t = BusTiming::default();
        let draw = |seed| {
            let mut m = HostModel::seed000(&t).with_jitter(seed);
            (0..50).map(|_| m.cost(HostCall::Read)).collect::<Vec<_>>()
        };
        assert_eq!(draw(7), draw(7));
        assert_ne!(draw(7), draw(8));
        let costs = draw(3);
        let mean = costs
            .iter()
            .map(|c| (c.before + c.after).as_micros_f64())
            .sum::<f64>()
            / costs.len() as f64;
        assert!((mean - 29.0).abs() < 6.0, "{mean}");
    }
}
