//! The UDP port: the FPGA V2 Ethernet bridge protocol of firmware Rev 7/8.
//!
//! Every request is one datagram to the board's port 1394: a 16-bit control
//! word (no-forward bit, the host's bus generation) and a complete 1394
//! packet with CRCs computed here. Read responses come back as the 1394
//! response packet followed by 8 bytes of extra data; writes get no reply.
//! Facts: `fpga-board.md` §8.
//!
//! Responses are matched to their request by the [transaction
//! engine](crate::transaction): source node, transaction label, tcode and
//! length; anything else (garbage, a bad CRC, a late answer to an earlier
//! request, a stray datagram) is counted under its reason and dropped.
//! Buffers are allocated once, so a transaction allocates nothing.
//!
//! How a read waits for its answer is the program's choice, made once
//! ([`UdpPort::set_wait_mode`]): [`WaitMode::Blocking`] sleeps in the
//! kernel (low CPU), [`WaitMode::Spinning`] polls a non-blocking socket
//! (low latency, one core busy while waiting). The socket is put in that
//! mode once and its receive time-out set once, so a broadcast cycle
//! (query, hub read request, hub read answer, commands) is four system
//! calls when nothing stray arrives: no per-read mode switching and no
//! per-read draining (a datagram left over from an earlier request is
//! judged and counted by the receive loop like any other; only after a
//! read timed out is the socket drained once before the next read, since
//! its late answer may then be queued). [`UdpPort::socket_calls`] counts
//! the calls.

use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use firelink_wire::bridge::{ControlWord, EXTRA_DATA_LEN, ExtraData};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};
use firelink_wire::qla::address::{BoardRegister, Register};

use crate::error::{AddressProblem, HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::{Dest, LinkFilter, LinkFilters, Port, Verdict};
use crate::transaction::{CrcCheck, Expect, Transactions, copy_answer};

/// Source node ID the reference host uses (`fpga-board.md` §8).
pub const HOST_SOURCE_ID: NodeId = NodeId(0xFFD0);

/// Largest request datagram: control word, 20-byte header+CRC, 2048-byte
/// payload, data CRC.
const MAX_DATAGRAM: usize = 2 + 20 + 2048 + 4 + 16;

/// How a [`UdpPort`] waits for the answer to a read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum WaitMode {
    /// Sleep in the kernel until a datagram arrives or the time-out
    /// passes (a blocking socket with its receive time-out): no CPU while
    /// waiting; the answer costs a wake-up of the sleeping thread.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(
            name = "block",
            alias = "blocking",
            help = "Sleep in the kernel until the answer or the time-out: low CPU"
        )
    )]
    Blocking,
    /// Poll the non-blocking socket in a loop until the answer arrives or
    /// the time-out passes: the answer is taken as soon as it is queued,
    /// at the price of one core busy for the whole wait.
    #[cfg_attr(
        feature = "clap",
        value(
            name = "spin",
            alias = "spinning",
            help = "Poll the socket until the answer or the time-out: low latency, one \
                    core busy while waiting"
        )
    )]
    Spinning,
}

impl WaitMode {
    /// Both modes, blocking first.
    pub const ALL: [WaitMode; 2] = [WaitMode::Blocking, WaitMode::Spinning];

    /// The name on the command line and in reports: `block` or `spin`.
    pub fn name(self) -> &'static str {
        match self {
            WaitMode::Blocking => "block",
            WaitMode::Spinning => "spin",
        }
    }

    /// Parse [`name`](Self::name) (also `blocking`, `spinning`).
    pub fn from_name(name: &str) -> Option<WaitMode> {
        match name {
            "block" | "blocking" => Some(WaitMode::Blocking),
            "spin" | "spinning" => Some(WaitMode::Spinning),
            _ => None,
        }
    }
}

impl core::fmt::Display for WaitMode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// The system calls a [`UdpPort`] made on its socket, by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct SocketCalls {
    /// Datagrams sent (`sendto`).
    pub sends: u64,
    /// Receive calls (`recvfrom`), whether a datagram came or not.
    pub receives: u64,
    /// Receive calls that returned no datagram (nothing queued on a
    /// non-blocking socket, the receive time-out, a signal).
    pub empty_receives: u64,
    /// Changes of the socket's settings: blocking mode (`ioctl`) and
    /// receive time-out (`setsockopt`).
    pub settings: u64,
}

impl SocketCalls {
    /// Every system call counted.
    pub fn total(&self) -> u64 {
        self.sends + self.receives + self.settings
    }

    /// Calls since `earlier` (a snapshot taken before).
    pub fn since(&self, earlier: &SocketCalls) -> SocketCalls {
        SocketCalls {
            sends: self.sends.saturating_sub(earlier.sends),
            receives: self.receives.saturating_sub(earlier.receives),
            empty_receives: self.empty_receives.saturating_sub(earlier.empty_receives),
            settings: self.settings.saturating_sub(earlier.settings),
        }
    }
}

/// The port's socket: every call counted, and its settings remembered so
/// that setting what it already has costs no system call.
pub(crate) struct Socket {
    pub(crate) udp: UdpSocket,
    nonblocking: bool,
    read_timeout: Option<Duration>,
    pub(crate) calls: SocketCalls,
}

impl Socket {
    pub(crate) fn new(udp: UdpSocket) -> Socket {
        Socket {
            udp,
            nonblocking: false,
            read_timeout: None,
            calls: SocketCalls::default(),
        }
    }

    pub(crate) fn send_to(&mut self, buf: &[u8], target: SocketAddr) -> io::Result<usize> {
        self.calls.sends += 1;
        self.udp.send_to(buf, target)
    }

    pub(crate) fn recv_from(&mut self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
        self.calls.receives += 1;
        let r = self.udp.recv_from(buf);
        if r.is_err() {
            self.calls.empty_receives += 1;
        }
        r
    }

    pub(crate) fn set_nonblocking(&mut self, on: bool) -> io::Result<()> {
        if self.nonblocking != on {
            self.calls.settings += 1;
            self.udp.set_nonblocking(on)?;
            self.nonblocking = on;
        }
        Ok(())
    }

    /// Set the receive time-out of a blocking socket (at least 1 us: the
    /// socket takes no zero).
    pub(crate) fn set_read_timeout(&mut self, limit: Duration) -> io::Result<()> {
        let limit = limit.max(Duration::from_micros(1));
        if self.read_timeout != Some(limit) {
            self.calls.settings += 1;
            self.udp.set_read_timeout(Some(limit))?;
            self.read_timeout = Some(limit);
        }
        Ok(())
    }
}

/// A port speaking the Ethernet bridge protocol over UDP.
pub struct UdpPort {
    name: String,
    socket: Socket,
    target: SocketAddr,
    timeout: Duration,
    wait_mode: WaitMode,
    /// A read timed out since the socket was last drained: its answer may
    /// be queued.
    drain_before_read: bool,
    transactions: Transactions,
    tx: Vec<u8>,
    rx: Vec<u8>,
    opened: Instant,
    last_extra: Option<ExtraData>,
    filters: LinkFilters,
}

impl UdpPort {
    /// Default time to wait for a read response (the reference host's 20 ms).
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(20);

    /// Open a port to a bridge board at `target`. The local socket binds to
    /// loopback for a loopback target, otherwise to any address.
    ///
    /// # Errors
    /// [`HostError::Io`] if the socket cannot be created.
    pub fn open(target: SocketAddr) -> Result<UdpPort> {
        let local: IpAddr = if target.ip().is_loopback() {
            IpAddr::V4(Ipv4Addr::LOCALHOST)
        } else {
            IpAddr::V4(Ipv4Addr::UNSPECIFIED)
        };
        let socket = UdpSocket::bind(SocketAddr::new(local, 0))?;
        Ok(UdpPort {
            name: format!("udp:{target}"),
            socket: Socket::new(socket),
            target,
            timeout: Self::DEFAULT_TIMEOUT,
            wait_mode: WaitMode::default(),
            drain_before_read: false,
            transactions: Transactions::new(),
            tx: vec![0; MAX_DATAGRAM],
            rx: vec![0; MAX_DATAGRAM + 64],
            opened: Instant::now(),
            last_extra: None,
            filters: LinkFilters::default(),
        })
    }

    /// Parse a port string: `udp:HOST` (port 1394) or `udp:HOST:PORT`,
    /// HOST an IPv4 address, an IPv6 address (in brackets with a port:
    /// `udp:[::1]:1394`) or a host name. A name is resolved, and its IPv4
    /// address preferred (`udp:localhost` is 127.0.0.1, where `firelink
    /// emulate` listens).
    ///
    /// # Errors
    /// [`HostError::Address`]: the text is not such an address, the port
    /// is not 1..=65535, or the name does not resolve.
    pub fn parse_address(text: &str) -> Result<SocketAddr> {
        let bad = |p| HostError::Address(p);
        let rest = text.trim().strip_prefix("udp:").unwrap_or(text.trim());
        if let Ok(ip) = rest.parse::<IpAddr>() {
            return Ok(SocketAddr::new(ip, firelink_wire::bridge::BRIDGE_UDP_PORT));
        }
        if let Ok(addr) = rest.parse::<SocketAddr>() {
            if addr.port() == 0 {
                return Err(bad(AddressProblem::Port));
            }
            return Ok(addr);
        }
        // A host name, with or without a port.
        let (host, port) = match rest.rsplit_once(':') {
            Some((host, port)) => {
                let port = port
                    .parse::<u16>()
                    .ok()
                    .filter(|&p| p != 0)
                    .ok_or(bad(AddressProblem::Port))?;
                (host, port)
            }
            None => (rest, firelink_wire::bridge::BRIDGE_UDP_PORT),
        };
        let name_ok = !host.is_empty()
            && host.len() <= 253
            && host
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'.' || b == b'_');
        if !name_ok {
            return Err(bad(AddressProblem::Syntax));
        }
        let addrs: Vec<SocketAddr> = (host, port)
            .to_socket_addrs()
            .map_err(|_| bad(AddressProblem::Unresolved))?
            .collect();
        addrs
            .iter()
            .find(|a| a.is_ipv4())
            .or_else(|| addrs.first())
            .copied()
            .ok_or(bad(AddressProblem::Unresolved))
    }

    /// Set the read time-out. A blocking port gives it to its socket at
    /// the next read, once (not before every read).
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The read time-out.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Choose how reads wait for their answer (default
    /// [`WaitMode::Blocking`]). The socket takes the mode at the next read
    /// and keeps it.
    pub fn set_wait_mode(&mut self, mode: WaitMode) {
        self.wait_mode = mode;
    }

    /// How reads wait for their answer.
    pub fn wait_mode(&self) -> WaitMode {
        self.wait_mode
    }

    /// The system calls made on the socket so far, by kind.
    pub fn socket_calls(&self) -> SocketCalls {
        self.socket.calls
    }

    /// The local address of the port's socket (where answers come to).
    ///
    /// # Errors
    /// [`HostError::Io`] from the socket.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.socket.udp.local_addr()?)
    }

    /// What the port has counted so far: requests, answers, time-outs and
    /// every refused datagram by reason.
    pub fn stats(&self) -> LinkStats {
        self.transactions.stats()
    }

    /// The extra data of the last matched response.
    pub fn last_extra_data(&self) -> Option<ExtraData> {
        self.last_extra
    }

    /// Before a request: learn the bus generation if it is not known yet
    /// (the bridge drops forwarded requests of another generation without
    /// a word), then fail once whenever the boards reported a new one.
    fn check_generation(&mut self, dest: Dest) -> Result<()> {
        if !self.transactions.generation_known() && !dest.no_forward && !dest.is_broadcast() {
            self.learn_generation()?;
        }
        self.transactions.check_generation(dest)
    }

    /// Ask the bridge board itself (a no-forward read of HW_VERSION, which
    /// it answers whatever the generation, as the reference host's
    /// discovery does first) and adopt the generation its reply carries.
    ///
    /// # Errors
    /// The read's failure (no bridge answering).
    pub fn learn_generation(&mut self) -> Result<u32> {
        let dest = Dest {
            node: 63,
            no_forward: true,
        };
        let offset = Register::board(BoardRegister::HwVersion).offset()?;
        self.read_quadlet_now(dest, offset)?;
        Ok(self.generation())
    }

    fn send(&mut self, dest: Dest, repr: &PacketRepr<'_>) -> Result<()> {
        let control = ControlWord {
            no_forward: dest.no_forward,
            generation: self.transactions.generation() as u8,
        };
        let len = fill_request(&mut self.tx, control, repr)?;
        let now_ps = self.now_ps();
        let Some(buf) = self.tx.get_mut(..len) else {
            return Ok(());
        };
        let lost = self.filters.outgoing(now_ps, &mut buf[2..]) == Verdict::Drop;
        if !lost {
            // A spinning port's socket does not block: a full send buffer
            // (rare) is waited out, at most the time-out.
            let started = Instant::now();
            loop {
                match self.socket.send_to(buf, self.target) {
                    Ok(_) => break,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e)
                        if e.kind() == io::ErrorKind::WouldBlock
                            && started.elapsed() < self.timeout =>
                    {
                        std::hint::spin_loop();
                    }
                    Err(e) => return Err(e.into()),
                }
            }
        }
        self.transactions.sent();
        Ok(())
    }

    /// Before a read: after a read timed out, its answer may have come in
    /// the meantime; drop (and count) everything queued, once. Otherwise
    /// nothing: whatever else is queued is judged by the receive loop.
    fn drain_if_stale(&mut self) -> Result<()> {
        if !self.drain_before_read {
            return Ok(());
        }
        self.drain_before_read = false;
        self.socket.set_nonblocking(true)?;
        let drained = self.drain();
        // The mode the reads use (spinning keeps the socket non-blocking).
        self.socket
            .set_nonblocking(self.wait_mode == WaitMode::Spinning)?;
        drained
    }

    fn drain(&mut self) -> Result<()> {
        loop {
            match self.socket.recv_from(&mut self.rx) {
                Ok((len, from)) => {
                    if self.heard(len) == Verdict::Drop {
                        continue;
                    }
                    let packet = self.rx.get(..len.saturating_sub(EXTRA_DATA_LEN));
                    match packet {
                        Some(bytes) if from == self.target => {
                            self.transactions.refuse_unsolicited(bytes);
                        }
                        _ => self.transactions.refused_unmatched(),
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// Wait for the answer to `expect` and copy its payload (or quadlet)
    /// into `out`; every other datagram is counted by the engine under the
    /// reason it was refused.
    ///
    /// Blocking: one `recvfrom` with the socket's receive time-out, which
    /// is set to the port's time-out once and kept; only after a datagram
    /// that is not the answer does the wait go on with what is left of the
    /// time-out (and the next read sets the whole time-out back).
    /// Spinning: `recvfrom` on the non-blocking socket until the answer or
    /// the time-out.
    fn receive(&mut self, expect: Expect, out: &mut [u8]) -> Result<()> {
        let started = Instant::now();
        let spinning = self.wait_mode == WaitMode::Spinning;
        self.socket.set_nonblocking(spinning)?;
        let mut limit = self.timeout;
        loop {
            if !spinning {
                self.socket.set_read_timeout(limit)?;
            }
            let received = self.socket.recv_from(&mut self.rx);
            let judged = match received {
                Ok((len, from)) if from == self.target => {
                    if self.heard(len) == Verdict::Drop {
                        None
                    } else {
                        let datagram = self.rx.get(..len).unwrap_or(&[]);
                        judge_reply(&mut self.transactions, datagram, &expect, out)?
                    }
                }
                Ok(_) => {
                    self.transactions.refused_unmatched();
                    None
                }
                Err(e) if is_wait_over(&e) => {
                    if spinning {
                        std::hint::spin_loop();
                    }
                    None
                }
                Err(e) => return Err(e.into()),
            };
            if let Some(extra) = judged {
                self.last_extra = Some(extra);
                return Ok(());
            }
            match time_left(&mut self.transactions, &expect, started, self.timeout) {
                Ok(remaining) => limit = remaining,
                Err(e) => {
                    self.drain_before_read = true;
                    return Err(e);
                }
            }
        }
    }

    /// A datagram of `len` bytes arrived in the receive buffer: its 1394
    /// packet (without the extra data) goes through the filters.
    fn heard(&mut self, len: usize) -> Verdict {
        if self.filters.is_empty() {
            return Verdict::Pass;
        }
        let packet_len = len.checked_sub(EXTRA_DATA_LEN).unwrap_or(len);
        let now_ps = self.now_ps();
        match self.rx.get_mut(..packet_len) {
            Some(packet) => self.filters.incoming(now_ps, packet),
            None => Verdict::Pass,
        }
    }

    fn header(&mut self, dest: Dest) -> AsyncHeader {
        let tl = self.transactions.next_label();
        AsyncHeader::new(NodeId::local(dest.node), HOST_SOURCE_ID, tl)
    }

    /// A quadlet read without the generation check (used to learn it).
    fn read_quadlet_now(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.drain_if_stale()?;
        let header = self.header(dest);
        self.send(dest, &PacketRepr::ReadQuadletRequest { header, offset })?;
        let mut out = [0u8; 4];
        self.receive(Expect::quadlet(dest, header.tl), &mut out)?;
        Ok(u32::from_be_bytes(out))
    }
}

/// The quadlet write request of `value` (both datagram ports).
pub(crate) fn write_quadlet_request(
    header: AsyncHeader,
    offset: u64,
    value: u32,
) -> PacketRepr<'static> {
    PacketRepr::WriteQuadletRequest {
        header,
        offset,
        data: value,
    }
}

/// The block read request of `len` bytes (both datagram ports).
pub(crate) fn read_block_request(
    header: AsyncHeader,
    offset: u64,
    len: usize,
) -> PacketRepr<'static> {
    PacketRepr::ReadBlockRequest {
        header,
        offset,
        data_length: len as u16,
        extended_tcode: 0,
    }
}

/// The block write request of `data` (both datagram ports).
pub(crate) fn write_block_request(header: AsyncHeader, offset: u64, data: &[u8]) -> PacketRepr<'_> {
    PacketRepr::WriteBlockRequest {
        header,
        offset,
        extended_tcode: 0,
        data,
    }
}

/// Write `control` and `repr` into `tx` as one request datagram; its
/// length.
///
/// # Errors
/// The request does not fit a datagram, or does not encode.
pub(crate) fn fill_request(
    tx: &mut [u8],
    control: ControlWord,
    repr: &PacketRepr<'_>,
) -> Result<usize> {
    let len = 2 + repr.buffer_len();
    let Some(buf) = tx.get_mut(..len) else {
        return Err(HostError::InvalidRequest {
            what: "request larger than a datagram",
            value: len as u32,
        });
    };
    buf[..2].copy_from_slice(&control.to_bytes());
    repr.emit(&mut buf[2..])?;
    Ok(len)
}

/// What is left of `timeout` since `started`, or the time-out error of
/// `expect` (the wait in us) from the engine when nothing is.
pub(crate) fn time_left(
    transactions: &mut Transactions,
    expect: &Expect,
    started: Instant,
    timeout: Duration,
) -> Result<Duration> {
    let elapsed = started.elapsed();
    match timeout.checked_sub(elapsed).filter(|d| !d.is_zero()) {
        Some(remaining) => Ok(remaining),
        None => {
            let waited = elapsed.as_micros().min(u128::from(u32::MAX)) as u32;
            Err(transactions.timed_out(expect, waited))
        }
    }
}

/// Whether a socket error only says that nothing arrived in time (or the
/// wait was interrupted): the caller waits on, it is not a failure.
pub fn is_wait_over(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// One datagram from a bridge board, judged against the open request
/// `expect`: the response packet, then 8 bytes of extra data (which carry
/// the bus generation, adopted through the engine). The UDP port's whole
/// reply path, without the socket (fuzzed).
///
/// Returns `Ok(Some(extra))` for the answer (its payload, or its quadlet,
/// copied into `out`, which must be `expect.len` bytes), `Ok(None)` for a
/// datagram refused and counted by the engine.
///
/// # Errors
/// The answer itself damaged, or carrying an error rcode.
pub fn judge_reply(
    transactions: &mut Transactions,
    datagram: &[u8],
    expect: &Expect,
    out: &mut [u8],
) -> Result<Option<ExtraData>> {
    let Some(split) = datagram.len().checked_sub(EXTRA_DATA_LEN) else {
        // Too short for the extra data: not a bridge reply.
        let _ = transactions.accept(datagram, expect, CrcCheck::Always)?;
        return Ok(None);
    };
    let (packet_bytes, extra_bytes) = datagram.split_at(split);
    let Ok(extra) = ExtraData::parse(extra_bytes) else {
        let _ = transactions.accept(&[], expect, CrcCheck::Always)?;
        return Ok(None);
    };
    // Responses the bridge board makes itself may carry 0 in their CRC
    // fields.
    let crc = if extra.flags.no_forward {
        CrcCheck::ZeroMeansUnset
    } else {
        CrcCheck::Always
    };
    let Ok(packet) = transactions.accept(packet_bytes, expect, crc)? else {
        return Ok(None);
    };
    copy_answer(&packet, expect, out)?;
    transactions.observe_generation(u32::from(extra.generation));
    Ok(Some(extra))
}

/// The [`Port`] methods a datagram port (the bridge's, the Ethernet-only
/// network's) has in common: the wall clock since `opened`, the engine's
/// generation and counts in `transactions`, writes never acknowledged.
macro_rules! datagram_port_clock_and_counts {
    () => {
        fn wait(&mut self, duration: Duration) {
            crate::pacing::precise_sleep(duration);
        }

        fn now(&self) -> Duration {
            self.opened.elapsed()
        }

        fn generation(&self) -> u32 {
            self.transactions.generation()
        }

        fn link_stats(&self) -> LinkStats {
            self.transactions.stats()
        }

        fn acknowledges_writes(&self) -> bool {
            false
        }
    };
}
pub(crate) use datagram_port_clock_and_counts;

impl Port for UdpPort {
    fn name(&self) -> &str {
        &self.name
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.check_generation(dest)?;
        self.read_quadlet_now(dest, offset)
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.check_generation(dest)?;
        let header = self.header(dest);
        self.send(dest, &write_quadlet_request(header, offset, value))
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        crate::port::check_block(out.len())?;
        self.check_generation(dest)?;
        self.drain_if_stale()?;
        let header = self.header(dest);
        self.send(dest, &read_block_request(header, offset, out.len()))?;
        self.receive(Expect::block(dest, header.tl, out.len()), out)
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        crate::port::check_block(data.len())?;
        self.check_generation(dest)?;
        let header = self.header(dest);
        self.send(dest, &write_block_request(header, offset, data))
    }

    datagram_port_clock_and_counts!();

    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        self.filters.add(filter);
        Ok(())
    }

    fn takes_link_filters(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn port_strings() {
        assert_eq!(
            UdpPort::parse_address("udp:127.0.0.1").unwrap(),
            "127.0.0.1:1394".parse().unwrap()
        );
        assert_eq!(
            UdpPort::parse_address("udp:127.0.0.1:4000").unwrap(),
            "127.0.0.1:4000".parse().unwrap()
        );
        // Host names resolve, IPv4 first (the hosts file: no DNS).
        assert_eq!(
            UdpPort::parse_address("udp:localhost").unwrap(),
            "127.0.0.1:1394".parse().unwrap()
        );
        assert_eq!(
            UdpPort::parse_address("udp:localhost:4000").unwrap(),
            "127.0.0.1:4000".parse().unwrap()
        );
        assert_eq!(
            UdpPort::parse_address("udp:[::1]:4000").unwrap(),
            "[::1]:4000".parse().unwrap()
        );
        for (text, problem) in [
            ("udp:", AddressProblem::Syntax),
            ("udp:a b", AddressProblem::Syntax),
            ("udp:localhost:99999", AddressProblem::Port),
            ("udp:localhost:0", AddressProblem::Port),
            ("udp:127.0.0.1:0", AddressProblem::Port),
            ("udp:localhost:http", AddressProblem::Port),
        ] {
            assert_eq!(
                UdpPort::parse_address(text),
                Err(HostError::Address(problem)),
                "{text}"
            );
        }
        let shown = UdpPort::parse_address("udp:").unwrap_err().to_string();
        assert!(!shown.contains("value 0"), "{shown}");
    }
}
