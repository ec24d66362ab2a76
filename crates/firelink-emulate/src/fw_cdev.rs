//! The kernel's side of /dev/fw* over the simulated bus: what the Linux
//! firewire-cdev driver does for each open device file, answered from the
//! emulated boards (the twin that `firelink emulate --fw-cdev` serves and
//! the preloaded `libfirelink_fwcdev.so` forwards to).
//!
//! [`Twin`] has no sockets and no clock: the caller passes virtual time in
//! ([`Twin::advance`], every request's `now`) and takes the events out,
//! each with the virtual time it is due ([`Twin::take_ready`]). The server
//! loop ([`serve`]) pairs virtual time with the wall clock and moves the
//! bytes.
//!
//! ## Model
//! - Devices: /dev/fw`N` is the bus node with handle `N`: `fw0` the PC's
//!   card (the [`HostLink`], the root, highest node ID), `fw1..` the boards
//!   in the order they were added. A device exists while its node is on
//!   the bus.
//! - GET_INFO: ABI version 6 returned, the client's version recorded
//!   (responses in RESPONSE layout below 6, RESPONSE2 from 6); the node's
//!   config ROM (read from the board over the bus, as the kernel reads it
//!   at discovery; the card's own is the twin's); the bus-reset record;
//!   from then on a BUS_RESET event after every bus reset.
//! - SEND_REQUEST: the kernel's refusals first
//!   ([`SendRequestArgs::check`]); a stale generation completes at once
//!   with RCODE_GENERATION; requests to the card itself are answered from
//!   its CSRs (STATE_CLEAR/STATE_SET, NODE_IDS, CYCLE_TIME, config ROM;
//!   anything else RCODE_ADDRESS); the rest go out on the simulated bus
//!   from the PC's link, and complete with the rcode the kernel derives
//!   from the ack, the response or their absence. Every accepted request
//!   completes exactly once: a response lost or damaged on the bus ends in
//!   RCODE_CANCELLED after the split time-out (2 s, the kernel's default;
//!   [`Twin::set_split_timeout`] shortens it for tests), and an
//!   `ack_busy` from a board completes with RCODE_BUSY.
//!   Lock requests go nowhere: the boards do not acknowledge them, so they
//!   complete with RCODE_NO_ACK (the card's CSRs: RCODE_TYPE).
//! - A node that leaves the bus hangs up every connection of its device.
//! - Bus resets: every connection that asked GET_INFO gets one BUS_RESET
//!   event per reset, generations rising by one each, also when several
//!   resets (a storm) happen between two looks at the bus; the records of
//!   the resets of one storm carry the topology found after its last.
//!
//! Faults come from the simulated bus's seeded fault plan
//! (`firelink_bus::FaultRule`, `TimedFault`): lost responses
//! (`PacketFault::Drop`), busy acks (`PacketFault::AckBusy`), bus resets
//! and unplugged boards, as `firelink emulate` sets them up.

use std::collections::{BTreeMap, VecDeque};

use firelink_bus::host::{Completion, Outcome};
use firelink_bus::{Bus, DetailReport, HostLink, NodeHandle, SimDuration, SimTime, TimedFault};
use firelink_wire::fw_cdev::{
    self, BusResetRecord, KERNEL_ABI_VERSION, SendRequestArgs, errno, rcode,
};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Speed};

mod serve;

pub use serve::{ServeEvent, bind, serve, serve_with};

/// The kernel's default split time-out (`DEFAULT_SPLIT_TIMEOUT`, 2 s).
pub const SPLIT_TIMEOUT: SimDuration = SimDuration::from_millis(2000);
/// How far virtual time may run ahead of the caller's `now` while a
/// request is followed to its completion (the rest is picked up by
/// [`Twin::advance`]).
const LOOKAHEAD: SimDuration = SimDuration::from_micros(500);
/// CSR space base: STATE_CLEAR is at +0, the config ROM at +0x400.
const CSR_BASE: u64 = 0xFFFF_F000_0000;
/// The speed code of every node (S400).
pub const SPEED_CODE: u8 = 2;

/// An event ready for one connection.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outgoing {
    /// One kernel event's bytes, due at a virtual time.
    Event {
        /// The connection.
        connection: u64,
        /// When the kernel would queue it.
        due: SimTime,
        /// The event, as `read()` returns it.
        bytes: Vec<u8>,
    },
    /// The connection's node left the bus: hang it up (EPOLLHUP).
    HangUp {
        /// The connection.
        connection: u64,
    },
}

/// An answer to one control request: errno 0 or the failure, a value, a
/// payload (see [`fw_cdev::TwinReply`]).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Answer {
    /// 0 or the errno.
    pub errno: i32,
    /// The value.
    pub value: u64,
    /// The payload.
    pub payload: Vec<u8>,
}

impl Answer {
    fn fail(errno: i32) -> Answer {
        Answer {
            errno,
            ..Answer::default()
        }
    }
    fn value(value: u64) -> Answer {
        Answer {
            value,
            ..Answer::default()
        }
    }
}

/// Counters of the twin.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TwinStats {
    /// Requests accepted (each completes exactly once).
    pub requests: u64,
    /// Completion events queued.
    pub completions: u64,
    /// Of those, with an rcode other than COMPLETE.
    pub failed: u64,
    /// Bus resets seen.
    pub bus_resets: u64,
    /// Ioctls refused with an errno.
    pub refused: u64,
    /// What the bus ran at which level of detail, each accepted request
    /// counted as one span (the same answer either way).
    pub detail: DetailReport,
}

impl core::fmt::Display for TwinStats {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} requests, {} completions ({} not complete), {} bus resets, {} ioctls refused; {}",
            self.requests,
            self.completions,
            self.failed,
            self.bus_resets,
            self.refused,
            self.detail.counted_in("requests")
        )
    }
}

struct Device {
    handle: NodeHandle,
    /// The node's config ROM (big-endian bytes), read when it joined.
    rom: Vec<u8>,
    present: bool,
}

struct Connection {
    device: usize,
    /// ABI version from GET_INFO (`None` before: no bus-reset events).
    version: Option<u32>,
    bus_reset_closure: u64,
}

struct InFlight {
    token: u64,
    connection: u64,
    closure: u64,
    tcode: u32,
    length: u32,
}

/// The kernel's side of every open /dev/fw*. See the module docs.
pub struct Twin {
    bus: Bus,
    link: NodeHandle,
    devices: Vec<Device>,
    connections: BTreeMap<u64, Connection>,
    next_connection: u64,
    in_flight: Vec<InFlight>,
    ready: VecDeque<Outgoing>,
    generation: u32,
    next_tl: u8,
    /// The card's STATE bits (STATE_SET / STATE_CLEAR), cycle master on.
    state: u32,
    stats: TwinStats,
    /// The card index GET_INFO reports.
    card: u32,
    /// Faults to start when this many requests have been accepted, each
    /// this long after that moment.
    deferred: Option<(u64, Vec<(SimDuration, TimedFault)>)>,
    /// How long a request waits for its response before it is cancelled.
    split_timeout: SimDuration,
}

/// STATE_CLEAR's cycle-master bit (`CSR_STATE_BIT_CMSTR`).
pub const STATE_CMSTR: u32 = 0x100;

impl Twin {
    /// The twin over `bus`, whose PC link is the node `link` (a
    /// [`HostLink`]); every node on it becomes a device. The boards'
    /// config ROMs are read now, over the bus, in virtual time.
    pub fn new(bus: Bus, link: NodeHandle) -> Twin {
        let mut bus = bus;
        if let Some(l) = bus.node_mut::<HostLink>(link) {
            l.set_split_timeout(SPLIT_TIMEOUT);
        }
        let devices = (0..bus.len())
            .map(|i| Device {
                handle: NodeHandle(i),
                rom: Vec::new(),
                present: false,
            })
            .collect();
        let generation = bus.generation();
        let mut twin = Twin {
            bus,
            link,
            devices,
            connections: BTreeMap::new(),
            next_connection: 1,
            in_flight: Vec::new(),
            ready: VecDeque::new(),
            generation,
            next_tl: 0,
            state: STATE_CMSTR,
            stats: TwinStats::default(),
            card: 0,
            deferred: None,
            split_timeout: SPLIT_TIMEOUT,
        };
        twin.refresh_devices();
        twin
    }

    /// Start `faults` (unplugging, muting, bus resets), each the given
    /// time after the moment the `after_requests`-th request is accepted,
    /// rather than at a time: a test or a user can then fault a running
    /// program wherever it is in its run, however long it took to start.
    pub fn defer_faults(&mut self, after_requests: u64, faults: Vec<(SimDuration, TimedFault)>) {
        self.deferred = Some((after_requests, faults));
    }

    /// The split time-out: a request whose response does not come (lost,
    /// damaged) completes with RCODE_CANCELLED this long after it was
    /// sent, in the bus's virtual time (the kernel's default, and this
    /// twin's, is [`SPLIT_TIMEOUT`]; a short one keeps tests of lost
    /// responses short).
    pub fn set_split_timeout(&mut self, timeout: SimDuration) {
        self.split_timeout = timeout;
        let link = self.link;
        if let Some(l) = self.bus.node_mut::<HostLink>(link) {
            l.set_split_timeout(timeout);
        }
    }

    /// The bus.
    pub fn bus(&self) -> &Bus {
        &self.bus
    }

    /// The bus, mutable (faults).
    pub fn bus_mut(&mut self) -> &mut Bus {
        &mut self.bus
    }

    /// Counters so far.
    pub fn stats(&self) -> TwinStats {
        TwinStats {
            detail: self.bus.detail_report(),
            ..self.stats
        }
    }

    /// The card's STATE bits (bit 8: cycle master).
    pub fn card_state(&self) -> u32 {
        self.state
    }

    /// Device numbers present (/dev/fwN).
    pub fn device_numbers(&self) -> Vec<u32> {
        self.devices
            .iter()
            .enumerate()
            .filter(|(_, d)| d.present)
            .map(|(i, _)| i as u32)
            .collect()
    }

    /// Requests sent and not yet completed.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Open /dev/fw`device`: a connection ID.
    ///
    /// # Errors
    /// ENOENT-like: [`errno::ENODEV`] when there is no such device.
    pub fn open(&mut self, device: u32) -> Result<u64, i32> {
        let d = device as usize;
        if !self.devices.get(d).is_some_and(|d| d.present) {
            return Err(errno::ENODEV);
        }
        let id = self.next_connection;
        self.next_connection += 1;
        self.connections.insert(
            id,
            Connection {
                device: d,
                version: None,
                bus_reset_closure: 0,
            },
        );
        Ok(id)
    }

    /// The connection was closed: its requests still in flight complete
    /// into nothing.
    pub fn close(&mut self, connection: u64) {
        self.connections.remove(&connection);
    }

    /// Let virtual time run to `now`: transactions finish, bus resets
    /// happen, and their events become ready.
    pub fn advance(&mut self, now: SimTime) {
        if now > self.bus.now() {
            self.bus.run_until(now);
        }
        self.collect();
        self.check_reset();
    }

    /// When the earliest ready event is due, if any.
    pub fn next_due(&self) -> Option<SimTime> {
        self.ready
            .iter()
            .map(|o| match o {
                Outgoing::Event { due, .. } => *due,
                Outgoing::HangUp { .. } => SimTime::ZERO,
            })
            .min()
    }

    /// Take every event due by `now` (and every hang-up), in order.
    pub fn take_ready(&mut self, now: SimTime, out: &mut Vec<Outgoing>) {
        let mut keep = VecDeque::with_capacity(self.ready.len());
        for o in self.ready.drain(..) {
            match &o {
                Outgoing::Event { due, .. } if *due > now => keep.push_back(o),
                _ => out.push(o),
            }
        }
        self.ready = keep;
    }

    /// GET_INFO on `connection` at `now`.
    pub fn get_info(
        &mut self,
        connection: u64,
        version: u32,
        rom_length: u32,
        bus_reset_closure: u64,
        now: SimTime,
    ) -> Answer {
        self.advance(now);
        let Some(c) = self.connections.get_mut(&connection) else {
            return self.refuse(errno::ENODEV);
        };
        c.version = Some(version);
        c.bus_reset_closure = bus_reset_closure;
        let device = c.device;
        let Some(record) = self.record_of(device) else {
            return self.refuse(errno::ENODEV);
        };
        let rom = self.devices.get(device).map(|d| &d.rom[..]).unwrap_or(&[]);
        let mut payload = Vec::with_capacity(8 + fw_cdev::BUS_RESET_EVENT_LEN + rom.len());
        payload.extend_from_slice(&self.card.to_le_bytes());
        payload.extend_from_slice(&(rom.len() as u32).to_le_bytes());
        let mut rec = [0u8; fw_cdev::BUS_RESET_EVENT_LEN];
        let _ = record.emit(bus_reset_closure, &mut rec);
        payload.extend_from_slice(&rec);
        let sent = rom.len().min(rom_length as usize);
        payload.extend_from_slice(rom.get(..sent).unwrap_or(&[]));
        Answer {
            errno: 0,
            value: u64::from(KERNEL_ABI_VERSION),
            payload,
        }
    }

    /// SEND_REQUEST (or SEND_BROADCAST_REQUEST) on `connection` at `now`.
    /// On success the completion event follows (exactly one), also for
    /// what the kernel reports only by event: a stale generation
    /// (RCODE_GENERATION), a node gone from the bus (RCODE_NO_ACK), a
    /// packet that cannot be sent (RCODE_SEND_ERROR).
    ///
    /// # Errors
    /// The kernel's synchronous refusals, which the preloaded library
    /// makes itself before it sends anything (so through it they never
    /// reach here): ENODEV for a closed connection, EINVAL/EIO/EACCES from
    /// [`SendRequestArgs::check`], EFAULT for a payload of another length.
    /// Nothing follows a refusal.
    pub fn send_request(
        &mut self,
        connection: u64,
        broadcast: bool,
        args: &SendRequestArgs,
        payload: &[u8],
        now: SimTime,
    ) -> Result<(), i32> {
        self.advance(now);
        let Some(device) = self.connections.get(&connection).map(|c| c.device) else {
            return Err(self.refuse(errno::ENODEV).errno);
        };
        if let Err(e) = args.check(broadcast, SPEED_CODE) {
            return Err(self.refuse(e).errno);
        }
        if payload.len() != args.payload_len() {
            return Err(self.refuse(errno::EFAULT).errno);
        }
        self.stats.requests += 1;
        // What the bus runs from here to the next request is this one's.
        self.bus.begin_cycle();
        let at = self.bus.now();
        if self
            .deferred
            .as_ref()
            .is_some_and(|(n, _)| self.stats.requests >= *n)
            && let Some((_, faults)) = self.deferred.take()
        {
            for (after, f) in faults {
                self.bus.schedule_fault(at + after, f);
            }
        }
        if !broadcast && args.generation != self.bus.generation() {
            self.complete(connection, args.closure, rcode::GENERATION, &[], at);
            return Ok(());
        }
        let Some(phy) = self
            .devices
            .get(device)
            .filter(|d| d.present)
            .and_then(|d| self.bus.phy_id(d.handle))
        else {
            // Gone between the bus reset and the hang-up of its device.
            self.complete(connection, args.closure, rcode::NO_ACK, &[], at);
            return Ok(());
        };
        let local = device == self.link.0;
        if local && !broadcast {
            let (rc, data) = self.local_csr(args, payload, at);
            self.complete(connection, args.closure, rc, &data, at);
            return Ok(());
        }
        if matches!(args.tcode, 0x11..=0x17) {
            // The boards do not acknowledge lock requests.
            self.complete(connection, args.closure, rcode::NO_ACK, &[], at);
            return Ok(());
        }
        let link_phy = self.bus.phy_id(self.link).unwrap_or(0);
        let tl = self.next_label();
        let header = AsyncHeader::new(
            if broadcast {
                NodeId::local(NodeId::BROADCAST_PHY)
            } else {
                NodeId::local(phy)
            },
            NodeId::local(link_phy),
            tl,
        );
        let offset = args.offset & 0xFFFF_FFFF_FFFF;
        let quadlet = |p: &[u8]| {
            p.get(..4)
                .and_then(|q| q.try_into().ok())
                .map_or(0, u32::from_be_bytes)
        };
        let repr = match args.tcode {
            0 => PacketRepr::WriteQuadletRequest {
                header,
                offset,
                data: quadlet(payload),
            },
            1 => PacketRepr::WriteBlockRequest {
                header,
                offset,
                extended_tcode: 0,
                data: payload,
            },
            4 => PacketRepr::ReadQuadletRequest { header, offset },
            _ => PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: args.length as u16,
                extended_tcode: 0,
            },
        };
        let mut bytes = vec![0u8; repr.buffer_len()];
        if repr.emit(&mut bytes).is_err() {
            self.complete(connection, args.closure, rcode::SEND_ERROR, &[], at);
            return Ok(());
        }
        let speed = if broadcast { Speed::S100 } else { Speed::S400 };
        let link = self.link;
        let Ok(token) = HostLink::submit_on(&mut self.bus, link, &bytes, speed) else {
            self.complete(connection, args.closure, rcode::SEND_ERROR, &[], at);
            return Ok(());
        };
        self.in_flight.push(InFlight {
            token,
            connection,
            closure: args.closure,
            tcode: args.tcode,
            length: args.length,
        });
        // Follow it a little way in virtual time: most transactions are
        // done within microseconds.
        let deadline = self.bus.now() + LOOKAHEAD;
        let mut looked_at = None;
        self.bus.run_until_with(deadline, |b| {
            b.called_since(link, &mut looked_at)
                && b.node::<HostLink>(link)
                    .is_some_and(|l| !l.is_pending(token))
        });
        self.collect();
        self.check_reset();
        Ok(())
    }

    /// INITIATE_BUS_RESET at `now` (BUS_RESET events follow).
    pub fn initiate_bus_reset(&mut self, connection: u64, short: bool, now: SimTime) -> Answer {
        self.advance(now);
        if !self.connections.contains_key(&connection) {
            return self.refuse(errno::ENODEV);
        }
        self.bus.initiate_reset(short);
        Answer::default()
    }

    /// The card's cycle timer at `now` (24.576 MHz: seconds 7 bits, cycles
    /// 13, offset 12), and the bus time in microseconds.
    pub fn cycle_timer(&mut self, now: SimTime) -> Answer {
        self.advance(now);
        let t = self.bus.now();
        let ticks = u128::from(t.as_nanos()) * 24_576 / 1_000_000;
        let offset = (ticks % 3072) as u32;
        let cycles = ticks / 3072;
        let cycle = (cycles % 8000) as u32;
        let seconds = ((cycles / 8000) % 128) as u32;
        Answer {
            errno: 0,
            value: u64::from((seconds << 25) | (cycle << 12) | offset),
            payload: (t.as_nanos() / 1000).to_le_bytes().to_vec(),
        }
    }

    /// GET_SPEED.
    pub fn speed(&mut self, connection: u64) -> Answer {
        if !self.connections.contains_key(&connection) {
            return self.refuse(errno::ENODEV);
        }
        Answer::value(u64::from(SPEED_CODE))
    }

    /// A message the server could not take (counted as refused).
    fn note_refused(&mut self) {
        self.stats.refused += 1;
    }

    fn refuse(&mut self, e: i32) -> Answer {
        self.stats.refused += 1;
        Answer::fail(e)
    }

    fn next_label(&mut self) -> u8 {
        let tl = self.next_tl;
        self.next_tl = (self.next_tl + 1) % 64;
        tl
    }

    /// Queue the completion event of one request.
    fn complete(&mut self, connection: u64, closure: u64, rc: u32, data: &[u8], due: SimTime) {
        self.stats.completions += 1;
        if rc != rcode::COMPLETE {
            self.stats.failed += 1;
        }
        let Some(c) = self.connections.get(&connection) else {
            return;
        };
        let version = c.version.unwrap_or(0);
        let stamp = |t: SimTime| (t.as_nanos() / 125_000 % 8000) as u32;
        let mut bytes = vec![0u8; fw_cdev::RESPONSE2_HEADER_LEN + data.len() + 4];
        if let Ok(n) = fw_cdev::emit_response(
            version,
            closure,
            rc,
            data,
            (stamp(due), stamp(due)),
            &mut bytes,
        ) {
            bytes.truncate(n);
            self.ready.push_back(Outgoing::Event {
                connection,
                due,
                bytes,
            });
        }
    }

    /// Turn finished transactions into completion events.
    fn collect(&mut self) {
        let done: Vec<Completion> = match self.bus.node_mut::<HostLink>(self.link) {
            Some(l) => {
                l.clear_received();
                l.take_completions()
            }
            None => return,
        };
        for c in done {
            let Some(i) = self.in_flight.iter().position(|f| f.token == c.token) else {
                continue;
            };
            let f = self.in_flight.swap_remove(i);
            let (rc, data, due) = judge(&c, f.tcode, f.length, self.split_timeout);
            self.complete(f.connection, f.closure, rc, &data, due);
        }
    }

    /// After bus resets: devices come and go, every connection that asked
    /// for GET_INFO gets a BUS_RESET event for each reset, in order.
    fn check_reset(&mut self) {
        let generation = self.bus.generation();
        if generation == self.generation {
            return;
        }
        // One event per reset (a storm's count bounded: a client that
        // missed more learns the newest generation all the same).
        let resets = generation.wrapping_sub(self.generation).clamp(1, 256);
        let first = generation.wrapping_sub(resets - 1);
        self.generation = generation;
        self.refresh_devices();
        for k in 0..resets {
            self.stats.bus_resets += 1;
            self.queue_bus_reset(first.wrapping_add(k));
        }
    }

    /// Queue the BUS_RESET event of `generation` on every connection (a
    /// connection whose node is gone is hung up instead).
    fn queue_bus_reset(&mut self, generation: u32) {
        let at = self.bus.now();
        let ids: Vec<u64> = self.connections.keys().copied().collect();
        for id in ids {
            let Some(c) = self.connections.get(&id) else {
                continue;
            };
            let (device, version, closure) = (c.device, c.version, c.bus_reset_closure);
            if !self.devices.get(device).is_some_and(|d| d.present) {
                self.connections.remove(&id);
                self.ready.push_back(Outgoing::HangUp { connection: id });
                continue;
            }
            if version.is_none() {
                continue;
            }
            if let Some(mut record) = self.record_of(device) {
                record.generation = generation;
                let mut bytes = vec![0u8; fw_cdev::BUS_RESET_EVENT_LEN];
                let _ = record.emit(closure, &mut bytes);
                self.ready.push_back(Outgoing::Event {
                    connection: id,
                    due: at,
                    bytes,
                });
            }
        }
    }

    /// Which nodes are on the bus; the ROM of each that joined is read.
    fn refresh_devices(&mut self) {
        for i in 0..self.devices.len() {
            let handle = NodeHandle(i);
            let present = self.bus.phy_id(handle).is_some();
            let joined = present && !self.devices.get(i).is_some_and(|d| d.present);
            if let Some(d) = self.devices.get_mut(i) {
                d.present = present;
            }
            if joined {
                let rom = if handle == self.link {
                    card_rom()
                } else {
                    self.read_rom(handle)
                };
                if let Some(d) = self.devices.get_mut(i) {
                    d.rom = rom;
                }
            }
        }
    }

    /// The bus-reset record of `device` now.
    fn record_of(&self, device: usize) -> Option<BusResetRecord> {
        let d = self.devices.get(device)?;
        let phy = self.bus.phy_id(d.handle)?;
        let local = NodeId::local(self.bus.phy_id(self.link)?).0;
        let root = self
            .bus
            .root()
            .and_then(|r| self.bus.phy_id(r))
            .map_or(local, |p| NodeId::local(p).0);
        Some(BusResetRecord {
            node_id: u32::from(NodeId::local(phy).0),
            local_node_id: u32::from(local),
            bm_node_id: u32::from(local),
            irm_node_id: u32::from(root),
            root_node_id: u32::from(root),
            generation: self.bus.generation(),
        })
    }

    /// One quadlet read from the PC's link, in virtual time.
    fn read_quadlet(&mut self, handle: NodeHandle, offset: u64) -> Option<u32> {
        let phy = self.bus.phy_id(handle)?;
        let link_phy = self.bus.phy_id(self.link)?;
        let tl = self.next_label();
        let repr = PacketRepr::ReadQuadletRequest {
            header: AsyncHeader::new(NodeId::local(phy), NodeId::local(link_phy), tl),
            offset,
        };
        let mut bytes = vec![0u8; repr.buffer_len()];
        repr.emit(&mut bytes).ok()?;
        let link = self.link;
        let token = HostLink::submit_on(&mut self.bus, link, &bytes, Speed::S400).ok()?;
        let deadline = self.bus.now() + SimDuration::from_millis(10);
        let done = HostLink::wait_on(&mut self.bus, link, token, deadline)?;
        let response = done.response?;
        let p = Packet::new_checked(&response[..]).ok()?;
        (done.outcome == Outcome::Complete && p.rcode() == firelink_wire::packet::Rcode::Complete)
            .then(|| p.quadlet_data())
    }

    /// A node's config ROM as the kernel reads it: the header quadlet, the
    /// bus information block and the root directory (a minimal ROM is its
    /// one quadlet).
    fn read_rom(&mut self, handle: NodeHandle) -> Vec<u8> {
        let base = CSR_BASE + 0x400;
        let Some(first) = self.read_quadlet(handle, base) else {
            return Vec::new();
        };
        let mut quadlets = vec![first];
        let info_len = first >> 24;
        if info_len > 1 {
            let root_at = 1 + info_len as u64;
            for k in 1..root_at {
                match self.read_quadlet(handle, base + 4 * k) {
                    Some(q) => quadlets.push(q),
                    None => break,
                }
            }
            if let Some(root) = self.read_quadlet(handle, base + 4 * root_at) {
                quadlets.push(root);
                let root_len = u64::from(root >> 16).min(250);
                for k in 1..=root_len {
                    match self.read_quadlet(handle, base + 4 * (root_at + k)) {
                        Some(q) => quadlets.push(q),
                        None => break,
                    }
                }
            }
        }
        quadlets.iter().flat_map(|q| q.to_be_bytes()).collect()
    }

    /// A request to the card itself, answered as the kernel's core does
    /// (its CSRs and its config ROM).
    fn local_csr(&mut self, args: &SendRequestArgs, payload: &[u8], at: SimTime) -> (u32, Vec<u8>) {
        let Some(k) = args.offset.checked_sub(CSR_BASE) else {
            return (rcode::ADDRESS_ERROR, Vec::new());
        };
        let write_value = payload
            .get(..4)
            .and_then(|q| q.try_into().ok())
            .map(u32::from_be_bytes);
        let read = matches!(args.tcode, 4 | 5);
        if matches!(args.tcode, 0x11..=0x17) {
            return (rcode::TYPE_ERROR, Vec::new());
        }
        let quadlet = |v: u32| (rcode::COMPLETE, v.to_be_bytes().to_vec());
        match (k, read) {
            (0x000 | 0x004, true) => quadlet(self.state),
            (0x000, false) => {
                self.state &= !write_value.unwrap_or(0);
                (rcode::COMPLETE, Vec::new())
            }
            (0x004, false) => {
                self.state |= write_value.unwrap_or(0);
                (rcode::COMPLETE, Vec::new())
            }
            (0x008, true) => {
                quadlet(u32::from(NodeId::local(self.bus.phy_id(self.link).unwrap_or(0)).0) << 16)
            }
            (0x200, true) => {
                let a = self.cycle_timer(at);
                quadlet(a.value as u32)
            }
            (0x400..0x800, true) => {
                let rom = self.devices.get(self.link.0).map(|d| d.rom.clone());
                let start = (k - 0x400) as usize;
                let data = rom
                    .as_deref()
                    .and_then(|r| r.get(start..start + args.length as usize))
                    .map(<[u8]>::to_vec);
                match data {
                    Some(d) => (rcode::COMPLETE, d),
                    None => (rcode::ADDRESS_ERROR, Vec::new()),
                }
            }
            _ => (rcode::ADDRESS_ERROR, Vec::new()),
        }
    }
}

/// The rcode, data and due time the kernel derives from a finished
/// transaction.
fn judge(
    c: &Completion,
    tcode: u32,
    length: u32,
    split_timeout: SimDuration,
) -> (u32, Vec<u8>, SimTime) {
    let at = c.completed_at;
    match c.outcome {
        Outcome::Complete => {}
        Outcome::NoAck => return (rcode::NO_ACK, Vec::new(), at),
        Outcome::Busy => return (rcode::BUSY, Vec::new(), at),
        Outcome::AckError => {
            let rc = match c.ack {
                Some(Ack::TypeError) => rcode::TYPE_ERROR,
                Some(Ack::DataError) => rcode::DATA_ERROR,
                _ => rcode::SEND_ERROR,
            };
            return (rc, Vec::new(), at);
        }
        Outcome::ResponseTimeout => return (rcode::CANCELLED, Vec::new(), at),
        // The card's controller drops a response with a bad CRC: the
        // transaction is cancelled when the split time-out runs out.
        Outcome::ResponseCorrupt => {
            return (rcode::CANCELLED, Vec::new(), c.submitted_at + split_timeout);
        }
        Outcome::BusReset => return (rcode::GENERATION, Vec::new(), at),
    }
    let Some(response) = c.response.as_deref() else {
        // A write acknowledged complete, or a broadcast sent.
        return (rcode::COMPLETE, Vec::new(), at);
    };
    let Ok(p) = Packet::new_checked(response) else {
        return (rcode::CANCELLED, Vec::new(), c.submitted_at + split_timeout);
    };
    let rc = u32::from(u8::from(p.rcode()));
    if rc != rcode::COMPLETE {
        return (rc, Vec::new(), at);
    }
    let data = match tcode {
        4 => p.quadlet_data().to_be_bytes().to_vec(),
        5 => {
            let payload = p.payload();
            payload
                .get(..payload.len().min(length as usize))
                .unwrap_or(&[])
                .to_vec()
        }
        _ => Vec::new(),
    };
    (rc, data, at)
}

/// The IEEE 1212 CRC-16 of config ROM quadlets.
pub fn rom_crc16(quadlets: &[u32]) -> u16 {
    let mut crc: u32 = 0;
    for &q in quadlets {
        for shift in (0..=28).rev().step_by(4) {
            let sum = ((crc >> 12) ^ (q >> shift)) & 0xF;
            crc = ((crc << 4) ^ (sum << 12) ^ (sum << 5) ^ sum) & 0xFFFF;
        }
    }
    crc as u16
}

/// The PC card's config ROM as the twin presents it: a bus information
/// block (IRM, cycle-master and bus-manager capable, max_rec 2048 bytes,
/// a GUID of the twin's own) and a root directory with node capabilities.
fn card_rom() -> Vec<u8> {
    let info = [0x3133_3934, 0xF000_A002, 0x0046_4C4B, 0x0000_0001];
    let root = [0x0C00_83C0];
    let mut q = Vec::new();
    q.push((4 << 24) | (4 << 16) | u32::from(rom_crc16(&info)));
    q.extend_from_slice(&info);
    q.push(((root.len() as u32) << 16) | u32::from(rom_crc16(&root)));
    q.extend_from_slice(&root);
    q.iter().flat_map(|x| x.to_be_bytes()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rom_crc_matches_the_boards_bus_info_block() {
        // The board's ROM (FireWire.v): the root directory header
        // 0x0005_9395 covers its five entries. The header 0x0404_8496 is
        // the CRC of the bus information block with quadlet 4 = 7: at
        // Rev 8 that quadlet holds 8 and the carried CRC (0x8496) no
        // longer matches it (0x7579), as the emulated board answers.
        assert_eq!(
            rom_crc16(&[0x3133_3934, 0x00FF_A000, 0xFA61_0E0E, 0x0000_0007]),
            0x8496
        );
        assert_eq!(
            rom_crc16(&[0x3133_3934, 0x00FF_A000, 0xFA61_0E0E, 0x0000_0008]),
            0x7579
        );
        assert_eq!(
            rom_crc16(&[
                0x0C00_83C0,
                0x03FA_610E,
                0x8100_0003,
                0x1700_0002,
                0x8100_0006
            ]),
            0x9395
        );
    }
}
