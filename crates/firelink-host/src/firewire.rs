//! `FirewirePort`: the boards through a PC's FireWire card, over the Linux
//! kernel's firewire-cdev devices (`/dev/fw*`), as the dVRK's own
//! FirewirePort reaches them through libraw1394.
//!
//! ## What the kernel gives, and how it is used
//! - One `/dev/fwN` per node of the bus, the PC's card included. At open
//!   every `/dev/fw*` is opened and asked GET_INFO (ABI 6: RESPONSE2
//!   events); those of card `N` (`fw:N`) are kept, each by its node
//!   number, the one whose node ID is the local node's being the card.
//! - A request (SEND_REQUEST) goes to the target node's fd with a closure
//!   and the port's bus generation; its completion is read from that fd,
//!   one event per `read()`, after `poll`. Completions are matched by
//!   closure: one that arrives after the port stopped waiting for it is
//!   dropped when it is read, and counted (`LinkStats::late`).
//! - Started writes (`Port::start_write_quadlet`/`start_write_block`, the
//!   broadcast protocol's query and commands) return once the kernel took
//!   the request, as libraw1394's `raw1394_start_write` does for the
//!   dVRK: their completions are read by later calls on the same fd (the
//!   hub read that follows the query, the next cycle's), a failed one is
//!   reported by the next call, a stale generation as a bus reset. At most
//!   eight stay open; the ninth first waits for the oldest.
//! - Two deadlines bound every wait, both far shorter than the kernel's
//!   2 s split time-out: each call's own ([`FwOptions::timeout`], a
//!   [`HostError::Timeout`]), and within a servo cycle (from
//!   [`Port::begin_cycle`] to [`Port::end_cycle`], which `IoSystem` calls)
//!   the cycle's budget for waiting ([`FwOptions::cycle_budget`]): the
//!   time all the cycle's calls have waited for completions together. A
//!   call that would wait past it ends the cycle's wait with
//!   [`HostError::CycleDeadline`], so a transaction the kernel holds
//!   until its split time-out never stalls a cycle by more than the
//!   budget, however many requests the cycle makes.
//! - A bus reset queues a BUS_RESET event on every fd. The call that meets
//!   one (or a completion with RCODE_GENERATION) fails once with
//!   [`HostError::BusReset`]; the port then takes the new generation,
//!   drops the nodes that left, opens those that joined, and the program
//!   rescans between cycles (`IoSystem::recover`).
//! - Broadcasts: the kernel refuses a broadcast write below
//!   `0xFFFF_F000_0800` (EACCES) and sends the others at S100. Register
//!   writes to node 63 (power, relays, encoder preload) therefore go to
//!   every node in turn, which the port says once on stderr; broadcasts
//!   into the units space (the command block at `0xFFFF_FFFF_0000`) are
//!   sent as the kernel allows. The broadcast I/O protocol should use the
//!   snooped-node-0 route (`BroadcastRoute::SnoopedNode0`), as the dVRK
//!   does on FireWire.
//! - At open the port writes 0x100 to the card's STATE_CLEAR register
//!   (`0xFFFF_F000_0000`): the PC stops sending cycle-start packets, as
//!   the dVRK's host does ([`FwOptions::stop_cycle_master`], on by
//!   default).
//!
//! Every call goes through glibc (`open`, `ioctl`, `poll`, `read`), so the
//! /dev/fw* twin (`firelink fw-run`) can stand in for the kernel.
//!
//! ## Tracing and faults
//! The kernel shows no packets, only requests and their completions. When
//! a link filter is added (`TracingPort`, `FaultyPort`, `--pcap`), the
//! port synthesises the 1394 packets from them: the request from its
//! arguments, the response from its rcode and data (source: the node,
//! destination: the card), with correct CRCs. A filter that drops the
//! request means it is never sent (the call fails as a time-out); one that
//! drops or damages the response means the completion is lost or corrupt.
//! Synthesised packets carry transaction labels counted by the port, not
//! those the card used.
#![allow(unsafe_code)]

use std::fs::OpenOptions;
use std::io::Write as _;
use std::os::fd::{AsFd, AsRawFd, OwnedFd};
use std::os::unix::fs::OpenOptionsExt;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};

use firelink_wire::fw_cdev::{
    self, BusResetRecord, GetInfoArgs, IOC_GET_INFO, IOC_INITIATE_BUS_RESET,
    IOC_SEND_BROADCAST_REQUEST, IOC_SEND_REQUEST, ResponseEvent, SendRequestArgs, rcode,
};
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode};

use crate::error::{HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::{Dest, LinkFilter, LinkFilters, Port, Verdict};

nix::ioctl_readwrite_bad!(
    /// FW_CDEV_IOC_GET_INFO.
    ioctl_get_info,
    IOC_GET_INFO,
    [u8; fw_cdev::GET_INFO_LEN]
);
nix::ioctl_write_ptr_bad!(
    /// FW_CDEV_IOC_SEND_REQUEST.
    ioctl_send_request,
    IOC_SEND_REQUEST,
    [u8; fw_cdev::SEND_REQUEST_LEN]
);
nix::ioctl_write_ptr_bad!(
    /// FW_CDEV_IOC_SEND_BROADCAST_REQUEST.
    ioctl_send_broadcast,
    IOC_SEND_BROADCAST_REQUEST,
    [u8; fw_cdev::SEND_REQUEST_LEN]
);
nix::ioctl_write_ptr_bad!(
    /// FW_CDEV_IOC_INITIATE_BUS_RESET.
    ioctl_bus_reset,
    IOC_INITIATE_BUS_RESET,
    [u8; 4]
);

/// Where the device files are.
const DEVICE_DIR: &str = "/dev";
/// The card's STATE_CLEAR register.
const STATE_CLEAR: u64 = 0xFFFF_F000_0000;
/// STATE_CLEAR's cycle-master bit.
const STATE_CMSTR: u32 = 0x100;
/// Largest event the port reads (a 2048-byte block plus the header).
const EVENT_BUFFER: usize = 4096 + 64;
/// Most writes started and not yet completed (`Port::start_write_*`):
/// starting one more first waits for the oldest.
const MAX_STARTED: usize = 8;

/// A write started without waiting for it: its completion is taken from
/// a later read of its node's fd.
#[derive(Debug, Clone, Copy)]
struct StartedWrite {
    closure: u64,
    /// Index in `nodes` of the fd it was sent on.
    index: usize,
    node: u8,
}

/// How to open a [`FirewirePort`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FwOptions {
    /// The card (`fw:N`; `fw` is card 0).
    pub card: u32,
    /// Stop the PC's cycle-start packets at open (STATE_CLEAR 0x100 to
    /// the card), as the dVRK's host does.
    pub stop_cycle_master: bool,
    /// How long one call waits for its completion.
    pub timeout: Duration,
    /// How long the calls of one servo cycle may wait for their
    /// completions together (see the module docs).
    pub cycle_budget: Duration,
}

impl Default for FwOptions {
    fn default() -> Self {
        FwOptions {
            card: 0,
            stop_cycle_master: true,
            timeout: Duration::from_millis(20),
            cycle_budget: Duration::from_millis(20),
        }
    }
}

/// One node's device file.
struct NodeFile {
    file: OwnedFd,
    /// Its node ID (`0xffc0 | phy`) as of the last bus reset seen on it.
    node_id: u32,
    /// /dev/fwN's N.
    device: u32,
}

/// A port over a Linux FireWire card. See the module docs.
pub struct FirewirePort {
    name: String,
    options: FwOptions,
    nodes: Vec<NodeFile>,
    /// Index in `nodes` of each physical ID (64 entries, 63 unused).
    by_phy: [Option<u8>; 64],
    /// Index of the card's own node.
    local: usize,
    generation: u32,
    /// A newer generation seen in a BUS_RESET event, not yet taken.
    reset_seen: Option<u32>,
    next_closure: u64,
    tl: u8,
    opened: Instant,
    filters: LinkFilters,
    stats: LinkStats,
    said_node63: bool,
    /// Time the current cycle's calls have waited, while a cycle is open.
    cycle_waited: Option<Duration>,
    /// Writes started and not completed (at most [`MAX_STARTED`]).
    started: Vec<StartedWrite>,
    /// The failure of a started write, reported by the next call.
    started_failed: Option<HostError>,
    event: Vec<u8>,
    scratch: Vec<u8>,
}

fn errno_error(what: &'static str, e: Errno) -> HostError {
    HostError::Device {
        what,
        errno: e as i32,
    }
}

fn io_error(what: &'static str, e: &std::io::Error) -> HostError {
    HostError::Device {
        what,
        errno: e.raw_os_error().unwrap_or(0),
    }
}

/// Open `/dev/fw<device>` and ask GET_INFO: (the file, its card, its
/// bus-reset record).
fn open_device(device: u32) -> Result<(OwnedFd, u32, BusResetRecord)> {
    let path = format!("{DEVICE_DIR}/fw{device}");
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(nix::libc::O_CLOEXEC)
        .open(&path)
        .map_err(|e| io_error("open", &e))?;
    let file = OwnedFd::from(file);
    let (card, record) = get_info(&file)?;
    Ok((file, card, record))
}

/// GET_INFO on an open device: its card and its current bus-reset record
/// (a node that left fails with ENODEV).
fn get_info(file: &OwnedFd) -> Result<(u32, BusResetRecord)> {
    let mut record = [0u8; fw_cdev::BUS_RESET_EVENT_LEN];
    let args = GetInfoArgs {
        version: fw_cdev::KERNEL_ABI_VERSION,
        rom_length: 0,
        rom: 0,
        bus_reset: record.as_mut_ptr() as u64,
        bus_reset_closure: 0,
        card: 0,
    };
    let mut a = [0u8; fw_cdev::GET_INFO_LEN];
    args.emit(&mut a).map_err(HostError::Wire)?;
    // SAFETY: `a` is a GET_INFO argument whose `bus_reset` points to
    // `record`, writable for the 40 bytes the kernel copies.
    unsafe { ioctl_get_info(file.as_raw_fd(), &mut a) }.map_err(|e| errno_error("GET_INFO", e))?;
    let back = GetInfoArgs::parse(&a).map_err(HostError::Wire)?;
    let (_, rec) = BusResetRecord::parse(&record).map_err(HostError::Wire)?;
    Ok((back.card, rec))
}

/// The N of every `/dev/fw<N>`.
fn device_numbers() -> Vec<u32> {
    let mut found: Vec<u32> = std::fs::read_dir(DEVICE_DIR)
        .map(|dir| {
            dir.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let name = e.file_name();
                    let digits = name.to_str()?.strip_prefix("fw")?.to_string();
                    (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()))
                        .then(|| digits.parse().ok())
                        .flatten()
                })
                .collect()
        })
        .unwrap_or_default();
    found.sort_unstable();
    found.dedup();
    found
}

impl FirewirePort {
    /// Open card `options.card`: every node's device file.
    ///
    /// # Errors
    /// [`HostError::Device`] when no device of that card can be opened
    /// (errno ENOENT: no card, or no permission: see the README's udev
    /// rule); errors of the STATE_CLEAR write.
    pub fn open(options: FwOptions) -> Result<FirewirePort> {
        let mut port = FirewirePort {
            name: if options.card == 0 {
                "fw".to_string()
            } else {
                format!("fw:{}", options.card)
            },
            options,
            nodes: Vec::new(),
            by_phy: [None; 64],
            local: 0,
            generation: 0,
            reset_seen: None,
            next_closure: 1,
            tl: 0,
            opened: Instant::now(),
            filters: LinkFilters::default(),
            stats: LinkStats::default(),
            said_node63: false,
            cycle_waited: None,
            started: Vec::with_capacity(MAX_STARTED),
            started_failed: None,
            event: vec![0u8; EVENT_BUFFER],
            scratch: vec![0u8; EVENT_BUFFER],
        };
        port.join_new_devices()?;
        if port.nodes.is_empty() {
            return Err(HostError::Device {
                what: "no /dev/fw* device of this card",
                errno: nix::libc::ENOENT,
            });
        }
        port.index()?;
        if options.stop_cycle_master {
            let local = port.local_phy();
            port.write_quadlet(Dest::node(local), STATE_CLEAR, STATE_CMSTR)?;
        }
        Ok(port)
    }

    /// Each call's deadline for its completion.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.options.timeout = timeout;
    }

    /// The budget for waiting of each servo cycle.
    pub fn set_cycle_budget(&mut self, budget: Duration) {
        self.options.cycle_budget = budget;
    }

    /// The card's physical ID (the highest on a bus of boards).
    pub fn local_phy(&self) -> u8 {
        self.nodes
            .get(self.local)
            .map_or(63, |n| (n.node_id & 0x3f) as u8)
    }

    /// Nodes on the bus, the card included.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Ask the card for a bus reset (`short`: arbitrated); the next call
    /// reports it.
    ///
    /// # Errors
    /// [`HostError::Device`].
    pub fn initiate_bus_reset(&mut self, short: bool) -> Result<()> {
        let file = self
            .nodes
            .get(self.local)
            .map(|n| n.file.as_raw_fd())
            .ok_or(HostError::UnknownBoard(63))?;
        let kind = u32::from(short).to_ne_bytes();
        // SAFETY: a 4-byte INITIATE_BUS_RESET argument.
        unsafe { ioctl_bus_reset(file, &kind) }
            .map_err(|e| errno_error("INITIATE_BUS_RESET", e))?;
        Ok(())
    }

    /// Open every /dev/fw* not open yet; keep those of this card.
    fn join_new_devices(&mut self) -> Result<()> {
        for device in device_numbers() {
            if self.nodes.iter().any(|n| n.device == device) {
                continue;
            }
            // A device of another card, or one that vanished meanwhile, is
            // not this port's.
            let Ok((file, card, record)) = open_device(device) else {
                continue;
            };
            if card != self.options.card {
                continue;
            }
            if record.generation > self.generation {
                self.generation = record.generation;
            }
            if record.node_id == record.local_node_id {
                self.local = self.nodes.len();
            }
            self.nodes.push(NodeFile {
                file,
                node_id: record.node_id,
                device,
            });
        }
        Ok(())
    }

    /// Rebuild the physical-ID index.
    fn index(&mut self) -> Result<()> {
        self.by_phy = [None; 64];
        let mut local = None;
        for (i, n) in self.nodes.iter().enumerate() {
            let phy = (n.node_id & 0x3f) as usize;
            if let Some(slot) = self.by_phy.get_mut(phy) {
                *slot = Some(i as u8);
            }
            if i == self.local {
                local = Some(i);
            }
        }
        if local.is_none() {
            return Err(HostError::Device {
                what: "the card's own /dev/fw* device is missing",
                errno: nix::libc::ENODEV,
            });
        }
        Ok(())
    }

    /// After a bus reset: every fd's queued events read, its node ID and
    /// the generation asked again (GET_INFO: the current record, whether
    /// or not the reset's event has been queued on that fd yet), the nodes
    /// that left dropped, the ones that joined opened.
    fn refresh(&mut self) -> Result<()> {
        // Started writes meet the reset (their completions are read below
        // or never come; the fds are indexed anew), and the reset is what
        // the program hears of them.
        self.started.clear();
        self.started_failed = None;
        let local_device = self.nodes.get(self.local).map(|n| n.device);
        let mut kept = Vec::with_capacity(self.nodes.len());
        // The generation the devices report now (queued events only tell
        // what is past).
        let mut generation = None;
        for mut n in std::mem::take(&mut self.nodes) {
            let mut seen = 0;
            if !drain(&mut n, &mut self.scratch, &mut seen) {
                continue;
            }
            let Ok((_, record)) = get_info(&n.file) else {
                continue;
            };
            n.node_id = record.node_id;
            generation = generation.max(Some(record.generation));
            kept.push(n);
        }
        if let Some(g) = generation {
            self.generation = g;
        }
        self.nodes = kept;
        self.local = self
            .nodes
            .iter()
            .position(|n| Some(n.device) == local_device)
            .unwrap_or(usize::MAX);
        self.join_new_devices()?;
        self.index()
    }

    fn file_of(&self, node: u8) -> Option<usize> {
        self.by_phy
            .get(usize::from(node))
            .copied()
            .flatten()
            .map(usize::from)
    }

    /// Send one write to `node` (or a broadcast) and return without
    /// waiting for its completion, as libraw1394's `raw1394_start_write`
    /// (the dVRK's query and commands): the completion is taken by a later
    /// read of the same fd, or waited for when [`MAX_STARTED`] are open.
    /// With link filters the write waits (the filters see its response).
    fn start_write(
        &mut self,
        node: u8,
        broadcast: bool,
        tcode: u32,
        offset: u64,
        data: &[u8],
    ) -> Result<()> {
        let wait = !self.filters.is_empty();
        if !wait && self.started.len() >= MAX_STARTED {
            self.settle_oldest()?;
        }
        self.transact(node, broadcast, tcode, offset, data, &mut [], wait)
    }

    /// Wait for the oldest started write's completion (its failure is
    /// reported at once; if none comes in time, it is given up and its
    /// completion, if it comes later, is dropped as late).
    fn settle_oldest(&mut self) -> Result<()> {
        let Some(oldest) = self.started.first().copied() else {
            return Ok(());
        };
        self.started.remove(0);
        let tl = self.tl;
        match self.wait_for(
            oldest.index,
            oldest.closure,
            oldest.node,
            tl,
            Instant::now(),
        ) {
            Ok((rc, _)) => self.judge_started(oldest.node, rc),
            // Given up: dropped as late if it comes.
            Err(HostError::Timeout { .. } | HostError::CycleDeadline { .. }) => {}
            Err(e) => return Err(e),
        }
        match self.started_failed.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Note the completion of a started write: counted when complete, a
    /// stale generation seen as a bus reset, any other failure kept for
    /// the next call to report.
    fn judge_started(&mut self, node: u8, rc: u32) {
        match rc {
            rcode::COMPLETE => self.stats.matched += 1,
            rcode::GENERATION => {
                self.reset_seen
                    .get_or_insert(self.generation.wrapping_add(1));
            }
            1..=0xF => {
                self.started_failed.get_or_insert(HostError::Rcode {
                    node,
                    rcode: Rcode::from(rc as u8),
                });
            }
            other => {
                self.started_failed
                    .get_or_insert(HostError::Driver { node, rcode: other });
            }
        }
    }

    /// Send one request to `node` (or a broadcast); with `wait`, wait for
    /// its completion (read data lands in `out`), else keep it as a
    /// started write.
    #[allow(clippy::too_many_arguments)]
    fn transact(
        &mut self,
        node: u8,
        broadcast: bool,
        tcode: u32,
        offset: u64,
        data: &[u8],
        out: &mut [u8],
        wait: bool,
    ) -> Result<()> {
        if let Some(new) = self.reset_seen.take() {
            return self.take_reset(new);
        }
        if let Some(e) = self.started_failed.take() {
            return Err(e);
        }
        let index = if broadcast {
            self.local
        } else {
            self.file_of(node).ok_or(HostError::Driver {
                node,
                rcode: rcode::NO_ACK,
            })?
        };
        let length = if matches!(tcode, 4 | 5) {
            out.len()
        } else {
            data.len()
        };
        let tl = self.tl;
        self.tl = (self.tl + 1) % 64;
        if !self.filters.is_empty()
            && self.filter_request(node, broadcast, tcode, offset, data, length, tl)
        {
            self.stats.sent += 1;
            self.stats.timeouts += 1;
            return Err(HostError::Timeout {
                node,
                tl,
                waited_us: 0,
            });
        }
        let closure = self.next_closure;
        self.next_closure += 1;
        // Reads give the kernel a buffer to copy `length` bytes from, as
        // it does for every tcode.
        let source = if matches!(tcode, 4 | 5) {
            out.as_ptr()
        } else {
            data.as_ptr()
        };
        let args = SendRequestArgs {
            tcode,
            length: length as u32,
            offset,
            closure,
            data: source as u64,
            generation: self.generation,
        };
        let mut a = [0u8; fw_cdev::SEND_REQUEST_LEN];
        args.emit(&mut a).map_err(HostError::Wire)?;
        let file = self
            .nodes
            .get(index)
            .map(|n| n.file.as_raw_fd())
            .ok_or(HostError::UnknownBoard(node))?;
        // SAFETY: `a` is a SEND_REQUEST argument whose `data` points to
        // `length` readable bytes that outlive the call (the kernel copies
        // them before it returns).
        let sent = if broadcast {
            unsafe { ioctl_send_broadcast(file, &a) }
        } else {
            unsafe { ioctl_send_request(file, &a) }
        };
        self.stats.sent += 1;
        match sent {
            Ok(_) => {}
            // The node left the bus (its device is shut down): a bus reset
            // came with it.
            Err(Errno::ENODEV) => {
                let new = self.generation.wrapping_add(1);
                return self.take_reset(new);
            }
            Err(e) => return Err(errno_error("SEND_REQUEST", e)),
        }
        if !wait {
            if self.started.len() < MAX_STARTED {
                self.started.push(StartedWrite {
                    closure,
                    index,
                    node,
                });
            }
            return Ok(());
        }
        let started = Instant::now();
        let (rc, len) = self.wait_for(index, closure, node, tl, started)?;
        if !self.filters.is_empty() {
            self.filter_response(node, tcode, rc, len, tl)?;
        }
        if let Some(new) = self.reset_seen.take() {
            // The call met a bus reset: reported once, whatever it got.
            return self.take_reset(new);
        }
        match rc {
            rcode::COMPLETE => {
                if matches!(tcode, 4 | 5) {
                    let data = self.event.get(..len).unwrap_or(&[]);
                    if data.len() != out.len() {
                        return Err(HostError::Wire(firelink_wire::Error::BlockSize {
                            what: "read response",
                            expected: out.len() / 4,
                            found: data.len() / 4,
                        }));
                    }
                    out.copy_from_slice(data);
                }
                self.stats.matched += 1;
                Ok(())
            }
            1..=0xF => Err(HostError::Rcode {
                node,
                rcode: Rcode::from(rc as u8),
            }),
            rcode::GENERATION => {
                let new = self.generation.wrapping_add(1);
                self.take_reset(new)
            }
            other => Err(HostError::Driver { node, rcode: other }),
        }
    }

    /// Report a bus reset once and take the new generation and nodes.
    fn take_reset(&mut self, new: u32) -> Result<()> {
        let old = self.generation;
        self.stats.bus_resets += 1;
        self.refresh()?;
        if self.generation == old {
            // No device told a newer generation (none left to ask).
            self.generation = self.generation.max(new);
        }
        Err(HostError::BusReset {
            old,
            new: self.generation,
        })
    }

    /// Wait for the completion with `closure` on node `index` until the
    /// call's deadline or, in a cycle, the end of the cycle's budget,
    /// whichever comes first; the time waited is charged to the cycle.
    fn wait_for(
        &mut self,
        index: usize,
        closure: u64,
        node: u8,
        tl: u8,
        started: Instant,
    ) -> Result<(u32, usize)> {
        let call = self.options.timeout;
        let budget = self.options.cycle_budget;
        let left_in_cycle = self.cycle_waited.map(|w| budget.saturating_sub(w));
        let limit = left_in_cycle.map_or(call, |left| left.min(call));
        let result = self.wait_until(index, closure, node, tl, started, started + limit);
        if let Some(waited) = self.cycle_waited.as_mut() {
            *waited += started.elapsed();
        }
        match result {
            Err(HostError::Timeout { .. }) if left_in_cycle.is_some_and(|left| left < call) => {
                Err(HostError::CycleDeadline {
                    node,
                    budget_us: u32::try_from(budget.as_micros()).unwrap_or(u32::MAX),
                })
            }
            other => other,
        }
    }

    /// Read events from node `index` until the completion with `closure`
    /// (its rcode and data length; the data is in `self.event`), or
    /// `deadline`. Late completions of earlier calls are dropped; bus
    /// resets are noted.
    fn wait_until(
        &mut self,
        index: usize,
        closure: u64,
        node: u8,
        tl: u8,
        started: Instant,
        deadline: Instant,
    ) -> Result<(u32, usize)> {
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let file = self
                .nodes
                .get(index)
                .map(|n| n.file.as_fd())
                .ok_or(HostError::UnknownBoard(node))?;
            let mut fds = [PollFd::new(file, PollFlags::POLLIN)];
            let ms = u16::try_from(left.as_micros().div_ceil(1000)).unwrap_or(u16::MAX);
            let ready = match poll(&mut fds, PollTimeout::from(ms)) {
                Ok(n) => n,
                Err(Errno::EINTR) => continue,
                Err(e) => return Err(errno_error("poll", e)),
            };
            let revents = fds[0].revents().unwrap_or(PollFlags::empty());
            if ready == 0 {
                self.stats.timeouts += 1;
                return Err(HostError::Timeout {
                    node,
                    tl,
                    waited_us: u32::try_from(started.elapsed().as_micros()).unwrap_or(u32::MAX),
                });
            }
            if !revents.contains(PollFlags::POLLIN) {
                // The node left the bus.
                self.reset_seen
                    .get_or_insert(self.generation.wrapping_add(1));
                return Ok((rcode::NO_ACK, 0));
            }
            let Some(file) = self.nodes.get(index).map(|n| &n.file) else {
                return Err(HostError::UnknownBoard(node));
            };
            let n = match nix::unistd::read(file, &mut self.event) {
                Ok(0) => {
                    self.reset_seen
                        .get_or_insert(self.generation.wrapping_add(1));
                    return Ok((rcode::NO_ACK, 0));
                }
                Ok(n) => n,
                Err(Errno::EINTR | Errno::EAGAIN) => continue,
                Err(e) => return Err(errno_error("read", e)),
            };
            let event = self.event.get(..n).unwrap_or(&[]);
            match fw_cdev::event_type(event) {
                Some(fw_cdev::EVENT_BUS_RESET) => {
                    if let Ok((_, rec)) = BusResetRecord::parse(event) {
                        if let Some(n) = self.nodes.get_mut(index) {
                            n.node_id = rec.node_id;
                        }
                        if rec.generation > self.generation {
                            self.reset_seen = Some(rec.generation);
                        }
                    }
                }
                Some(fw_cdev::EVENT_RESPONSE | fw_cdev::EVENT_RESPONSE2) => {
                    let Ok(r) = ResponseEvent::parse(event) else {
                        self.stats.garbage += 1;
                        continue;
                    };
                    if r.closure != closure {
                        let rc = r.rcode;
                        match self.started.iter().position(|w| w.closure == r.closure) {
                            Some(k) => {
                                let w = self.started.swap_remove(k);
                                self.judge_started(w.node, rc);
                            }
                            None => self.stats.late += 1,
                        }
                        continue;
                    }
                    let (rc, len) = (r.rcode, r.data.len());
                    // Move the data to the front of the buffer.
                    let at = r.data.as_ptr() as usize - self.event.as_ptr() as usize;
                    self.event.copy_within(at..at + len, 0);
                    return Ok((rc, len));
                }
                _ => self.stats.unmatched += 1,
            }
        }
    }

    /// Show the filters the request as a packet; true when it is dropped.
    #[allow(clippy::too_many_arguments)]
    fn filter_request(
        &mut self,
        node: u8,
        broadcast: bool,
        tcode: u32,
        offset: u64,
        data: &[u8],
        length: usize,
        tl: u8,
    ) -> bool {
        let destination = NodeId::local(if broadcast { 63 } else { node });
        let header = AsyncHeader::new(destination, NodeId::local(self.local_phy()), tl);
        let quadlet = data
            .get(..4)
            .and_then(|q| q.try_into().ok())
            .map_or(0, u32::from_be_bytes);
        let repr = match tcode {
            0 => PacketRepr::WriteQuadletRequest {
                header,
                offset,
                data: quadlet,
            },
            1 => PacketRepr::WriteBlockRequest {
                header,
                offset,
                extended_tcode: 0,
                data,
            },
            4 => PacketRepr::ReadQuadletRequest { header, offset },
            _ => PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: length as u16,
                extended_tcode: 0,
            },
        };
        let mut bytes = vec![0u8; repr.buffer_len()];
        if repr.emit(&mut bytes).is_err() {
            return false;
        }
        let at = self.now_ps();
        self.filters.outgoing(at, &mut bytes) == Verdict::Drop
    }

    /// Show the filters the completion as a response packet: lost or
    /// damaged means the call fails.
    fn filter_response(&mut self, node: u8, tcode: u32, rc: u32, len: usize, tl: u8) -> Result<()> {
        let header = AsyncHeader::new(NodeId::local(self.local_phy()), NodeId::local(node), tl);
        let wire_rcode = Rcode::from(if rc <= 0xF { rc as u8 } else { 0 });
        let data = self.event.get(..len).unwrap_or(&[]).to_vec();
        let repr = match tcode {
            4 => PacketRepr::ReadQuadletResponse {
                header,
                rcode: wire_rcode,
                data: data
                    .get(..4)
                    .and_then(|q| q.try_into().ok())
                    .map_or(0, u32::from_be_bytes),
            },
            5 => PacketRepr::ReadBlockResponse {
                header,
                rcode: wire_rcode,
                extended_tcode: 0,
                data: &data,
            },
            _ => PacketRepr::WriteResponse {
                header,
                rcode: wire_rcode,
            },
        };
        let mut bytes = vec![0u8; repr.buffer_len()];
        if repr.emit(&mut bytes).is_err() {
            return Ok(());
        }
        let at = self.now_ps();
        if self.filters.incoming(at, &mut bytes) == Verdict::Drop {
            self.stats.timeouts += 1;
            return Err(HostError::Timeout {
                node,
                tl,
                waited_us: 0,
            });
        }
        let packet = Packet::new_checked(&bytes[..]).map_err(HostError::Wire)?;
        if let Err(e) = packet.verify() {
            self.stats.bad_crc += 1;
            return Err(HostError::Wire(e));
        }
        Ok(())
    }

    /// A write to node 63 below the units space, which the kernel refuses:
    /// one write per node instead.
    fn write_each_node(&mut self, offset: u64, tcode: u32, data: &[u8]) -> Result<()> {
        if !self.said_node63 {
            self.said_node63 = true;
            let _ = writeln!(
                std::io::stderr(),
                "firelink: {}: the kernel refuses broadcast writes below 0xffff_f000_0800; \
                 register writes to node 63 go to each node in turn",
                self.name
            );
        }
        let local = self.local_phy();
        let mut first_error = None;
        for node in 0..local {
            if self.file_of(node).is_none() {
                continue;
            }
            if let Err(e) = self.transact(node, false, tcode, offset, data, &mut [], true) {
                if matches!(e, HostError::BusReset { .. }) {
                    return Err(e);
                }
                first_error.get_or_insert(e);
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// A write to `dest`, waited for or only `started` (see
    /// [`start_write`](Self::start_write)); node 63 below the units space
    /// goes to each node in turn, waiting.
    fn write(
        &mut self,
        dest: Dest,
        offset: u64,
        tcode: u32,
        data: &[u8],
        started: bool,
    ) -> Result<()> {
        if dest.is_broadcast() && offset < fw_cdev::BROADCAST_MIN_OFFSET {
            return self.write_each_node(offset, tcode, data);
        }
        let broadcast = dest.is_broadcast();
        if started {
            self.start_write(dest.node, broadcast, tcode, offset, data)
        } else {
            self.transact(dest.node, broadcast, tcode, offset, data, &mut [], true)
        }
    }
}

/// Read every queued event of `n`: the node ID of the last bus reset, the
/// newest generation; false when the node is gone.
fn drain(n: &mut NodeFile, buf: &mut [u8], generation: &mut u32) -> bool {
    loop {
        let mut fds = [PollFd::new(n.file.as_fd(), PollFlags::POLLIN)];
        match poll(&mut fds, PollTimeout::ZERO) {
            Ok(0) => return true,
            Ok(_) => {}
            Err(Errno::EINTR) => continue,
            Err(_) => return false,
        }
        let revents = fds[0].revents().unwrap_or(PollFlags::empty());
        if !revents.contains(PollFlags::POLLIN) {
            return false;
        }
        match nix::unistd::read(&n.file, buf) {
            Ok(0) | Err(_) => return false,
            Ok(len) => {
                let event = buf.get(..len).unwrap_or(&[]);
                if fw_cdev::event_type(event) == Some(fw_cdev::EVENT_BUS_RESET)
                    && let Ok((_, rec)) = BusResetRecord::parse(event)
                {
                    n.node_id = rec.node_id;
                    *generation = (*generation).max(rec.generation);
                }
            }
        }
    }
}

impl Port for FirewirePort {
    fn name(&self) -> &str {
        &self.name
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        crate::port::refuse_broadcast_read(dest)?;
        let mut q = [0u8; 4];
        self.transact(dest.node, false, 4, offset, &[], &mut q, true)?;
        Ok(u32::from_be_bytes(q))
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.write(dest, offset, 0, &value.to_be_bytes(), false)
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        crate::port::check_block(out.len())?;
        crate::port::refuse_broadcast_read(dest)?;
        self.transact(dest.node, false, 5, offset, &[], out, true)
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        crate::port::check_block(data.len())?;
        self.write(dest, offset, 1, data, false)
    }

    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.write(dest, offset, 0, &value.to_be_bytes(), true)
    }

    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        crate::port::check_block(data.len())?;
        self.write(dest, offset, 1, data, true)
    }

    fn wait(&mut self, duration: Duration) {
        std::thread::sleep(duration);
    }

    fn begin_cycle(&mut self) {
        self.cycle_waited = Some(Duration::ZERO);
    }

    fn end_cycle(&mut self) {
        self.cycle_waited = None;
    }

    fn now(&self) -> Duration {
        self.opened.elapsed()
    }

    fn generation(&self) -> u32 {
        self.generation
    }

    fn link_stats(&self) -> LinkStats {
        self.stats
    }

    fn refuses_broadcast_registers(&self) -> bool {
        true
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        // The PC is the highest node; the boards are below it.
        0..self.local_phy().min(63)
    }

    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        self.filters.add(filter);
        Ok(())
    }

    fn takes_link_filters(&self) -> bool {
        true
    }
}
