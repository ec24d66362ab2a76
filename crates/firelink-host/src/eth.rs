//! The Ethernet-only port: FPGA V3 boards at firmware Rev 9 on their own
//! network, every board its own UDP address, no FireWire bus behind.
//!
//! Facts (`rev9-fpga-v3.md`, EthBasePort and EthUdpPort of the dVRK host):
//! every request sets the control word's no-forward flag, so a board
//! matches the destination node against its board ID and answers with its
//! board ID as source; a request for board N goes as a unicast datagram to
//! board N's address, the base + N (REG_IPADDR stores base + board ID once
//! the host wrote the base to the group); requests to node 63 (the IP
//! write, broadcast reads, the broadcast query at `0x1800`, the command
//! block) go to the group address: the multicast group 224.0.0.100 where
//! the network has it, or a subnet broadcast address (on loopback
//! 127.255.255.255, where `firelink emulate --network eth` listens).
//!
//! The broadcast read: the socket is flushed before the query (EthBasePort
//! `WriteBroadcastReadRequest`); the hub board then sends one unsolicited
//! block read response with every selected board's status block, under the
//! query's transaction label, which
//! [`Port::receive_broadcast_response`] takes (from whichever board is the
//! hub); when it does not come within the read time-out the caller reads
//! the hub instead (counted in [`EthStats::fallbacks`]). The blocks are in
//! chain order; [`IoSystem`](crate::qla::io::IoSystem) places each by the board
//! ID in its STATUS.
//!
//! Responses are judged by the one [transaction engine](crate::transaction)
//! through the bridge's reply path ([`judge_reply`]); datagrams from
//! outside the boards' addresses, damaged ones and late ones are counted
//! and dropped. Buffers are allocated once: a transaction allocates
//! nothing. Reads wait in the kernel (a blocking socket with its receive
//! time-out).

use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use firelink_wire::bridge::{ControlWord, ExtraData};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};
use firelink_wire::qla::address::{BoardRegister, HUB_QUERY_OFFSET, Register};

use crate::error::{HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::{Dest, LinkFilter, Port};
use crate::transaction::{Expect, Transactions};
use crate::udp::{
    HOST_SOURCE_ID, Socket, fill_request, is_wait_over, judge_reply, read_block_request, time_left,
    write_block_request, write_quadlet_request,
};

/// The Rev 9 host's multicast group (EthUdpPort's default).
pub const MULTICAST_GROUP: Ipv4Addr = Ipv4Addr::new(224, 0, 0, 100);

/// The loopback network's broadcast address (the group on loopback).
pub const LOOPBACK_BROADCAST: Ipv4Addr = Ipv4Addr::new(127, 255, 255, 255);

/// Board 0's address on loopback, as `firelink emulate --network eth`
/// serves it.
pub const LOOPBACK_BASE: Ipv4Addr = Ipv4Addr::new(127, 0, 0, 100);

/// Board 0's address on a real network (the dVRK's 169.254.0.100).
pub const STOCK_BASE: Ipv4Addr = Ipv4Addr::new(169, 254, 0, 100);

/// The clock of the Ethernet-only network's hub timers (the 15-bit update
/// time in each hub header, the 16-bit timing quadlet): 125 MHz, where the
/// FireWire hub counts the 49.152 MHz system clock (EthBasePort
/// `GetBroadcastReadClockPeriod`: `1.0e-6/125.0` when not using the
/// bridge).
pub const ETH_HUB_CLOCK_HZ: u32 = 125_000_000;

/// The Rev 9 host's wait between the broadcast query and the hub's
/// response on the Ethernet-only network, for a configuration of `boards`
/// boards: 3 + 38 (N - 1) us (EthBasePort `WaitBroadcastRead` when not
/// using the bridge, "based on measurements, assuming contiguous Ethernet
/// chain"; there N is every board the configuration uses, and the host
/// waits longer when the last measured update time was longer). With the
/// bridge the same host waits 10 + 10 (N - 1) us.
pub fn ethernet_only_broadcast_wait(boards: usize) -> Duration {
    Duration::from_micros(3 + 38 * boards.saturating_sub(1) as u64)
}

/// Largest request datagram: control word, header, 2048-byte payload,
/// data CRC.
const MAX_DATAGRAM: usize = 2 + 20 + 2048 + 4 + 16;

/// Where the boards are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EthAddresses {
    /// Board 0's address; board N is at this + N (in the last byte).
    pub base: Ipv4Addr,
    /// The UDP port of every board (1394).
    pub port: u16,
    /// Where requests to node 63 go: the multicast group or a broadcast
    /// address.
    pub group: Ipv4Addr,
}

impl EthAddresses {
    /// Loopback, as `firelink emulate --network eth --listen 127.0.0.1:PORT`
    /// serves it.
    pub fn loopback(port: u16) -> EthAddresses {
        EthAddresses {
            base: LOOPBACK_BASE,
            port,
            group: LOOPBACK_BROADCAST,
        }
    }

    /// Board `id`'s address, if base + ID stays in the last byte.
    pub fn board(&self, id: u8) -> Option<SocketAddr> {
        let [a, b, c, d] = self.base.octets();
        let d = d.checked_add(id)?;
        Some(SocketAddr::new(
            IpAddr::V4(Ipv4Addr::new(a, b, c, d)),
            self.port,
        ))
    }

    /// The group's socket address.
    pub fn group(&self) -> SocketAddr {
        SocketAddr::new(IpAddr::V4(self.group), self.port)
    }

    /// The board ID whose address `from` is (board IDs 0..=15).
    fn board_of(&self, from: SocketAddr) -> Option<u8> {
        let IpAddr::V4(ip) = from.ip() else {
            return None;
        };
        if from.port() != self.port {
            return None;
        }
        let (o, b) = (ip.octets(), self.base.octets());
        if o[..3] != b[..3] {
            return None;
        }
        o[3].checked_sub(b[3]).filter(|&id| id < 16)
    }
}

/// Who answered a [`EthPort::probe`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Probe {
    /// Where the probe went.
    pub host: SocketAddr,
    /// Where the answer came from.
    pub from: SocketAddr,
    /// The answering board's ID (the source node of its answer).
    pub board: u8,
    /// Its HARDWARE_VERSION.
    pub hardware: u32,
    /// Its FIRMWARE_VERSION.
    pub firmware: u32,
    /// Its ETH_STATUS (bits 31:30 name the FPGA version).
    pub eth_status: u32,
}

impl Probe {
    /// Whether the answering board is an FPGA V3 at firmware Rev 9 or
    /// later: the Rev 9 host then uses the Ethernet-only network, else the
    /// bridge.
    pub fn is_ethernet_only(&self) -> bool {
        let v3 = matches!(
            firelink_wire::qla::registers::FpgaVersion::from_eth_status(self.eth_status),
            Ok(firelink_wire::qla::registers::FpgaVersion::V3)
        );
        v3 && self.firmware >= 9
    }

    /// The Ethernet-only network's addresses this answer shows: board 0
    /// at the answering board's address less its ID; requests to node 63
    /// to the probed address when it was a broadcast or multicast one,
    /// else to the loopback broadcast address (a loopback board) or the
    /// multicast group 224.0.0.100 (the Rev 9 host's choice). `None`: not
    /// an IPv4 answer, or an ID beyond the address.
    pub fn ethernet_only_addresses(&self) -> Option<EthAddresses> {
        let (IpAddr::V4(from), IpAddr::V4(host)) = (self.from.ip(), self.host.ip()) else {
            return None;
        };
        let [a, b, c, d] = from.octets();
        let base = Ipv4Addr::new(a, b, c, d.checked_sub(self.board)?);
        let group = if host.is_multicast() || host.is_broadcast() || host.octets()[3] == 255 {
            host
        } else if host.is_loopback() {
            LOOPBACK_BROADCAST
        } else {
            MULTICAST_GROUP
        };
        Some(EthAddresses {
            base,
            port: self.from.port(),
            group,
        })
    }
}

/// What an [`EthPort`] counted of the broadcast read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct EthStats {
    /// Queries sent (broadcast writes to `0x1800`).
    pub queries: u64,
    /// Unsolicited responses taken.
    pub responses: u64,
    /// Queries whose response did not come (or came damaged): the hub was
    /// read instead.
    pub fallbacks: u64,
}

/// A port on the Ethernet-only network of Rev 9 FPGA V3 boards.
pub struct EthPort {
    name: String,
    socket: Socket,
    addrs: EthAddresses,
    timeout: Duration,
    transactions: Transactions,
    tx: Vec<u8>,
    rx: Vec<u8>,
    opened: Instant,
    last_extra: Option<ExtraData>,
    /// The board whose address the last matched response came from.
    last_source: u8,
    /// The source node (board ID) of the last matched response.
    last_node: u8,
    /// Probing: answers are taken from any address on the port, the last
    /// one's remembered.
    accept_any: bool,
    last_from: Option<SocketAddr>,
    /// The label of the last query, until its response is taken.
    query_tl: Option<u8>,
    stats: EthStats,
}

impl EthPort {
    /// Default time to wait for a read response (the reference host's 20 ms).
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(20);

    /// Open a port to boards at `addrs`, without a word to them yet (see
    /// [`init`](Self::init)). The socket binds to loopback for a loopback
    /// base, otherwise to any address, and may send to a broadcast address.
    ///
    /// # Errors
    /// [`HostError::Io`] if the socket cannot be created.
    pub fn open(addrs: EthAddresses) -> Result<EthPort> {
        let local = if addrs.base.is_loopback() {
            Ipv4Addr::LOCALHOST
        } else {
            Ipv4Addr::UNSPECIFIED
        };
        let udp = UdpSocket::bind(SocketAddr::new(IpAddr::V4(local), 0))?;
        udp.set_broadcast(true)?;
        if addrs.group.is_multicast() {
            udp.set_multicast_loop_v4(true)?;
        }
        Ok(EthPort {
            name: format!("udp:{}:{} (Ethernet-only)", addrs.group, addrs.port),
            socket: Socket::new(udp),
            addrs,
            timeout: Self::DEFAULT_TIMEOUT,
            transactions: Transactions::new(),
            tx: vec![0; MAX_DATAGRAM],
            rx: vec![0; MAX_DATAGRAM + 64],
            opened: Instant::now(),
            last_extra: None,
            last_source: 0,
            last_node: 0,
            accept_any: false,
            last_from: None,
            query_tl: None,
            stats: EthStats::default(),
        })
    }

    /// Give every board its address (EthUdpPort's `InitNodes`): the base
    /// written to REG_IPADDR by the group, each board storing base + its
    /// ID; then the 0.2 s the Rev 9 host leaves the boards' multicasts to
    /// teach the switches (so that only the hub answers broadcast reads).
    ///
    /// # Errors
    /// The send's failure.
    pub fn init(&mut self) -> Result<()> {
        let offset = Register::board(BoardRegister::IpAddr).offset()?;
        let value = u32::from_le_bytes(self.addrs.base.octets());
        self.write_quadlet(Dest::BROADCAST, offset, value)?;
        std::thread::sleep(Duration::from_millis(200));
        Ok(())
    }

    /// Ask whoever answers at `host` (a board, a bridge, a broadcast or
    /// multicast address) who it is, as the Rev 9 host does before it
    /// chooses the Ethernet-only network or the bridge: a no-forward read
    /// of node 63's hardware, firmware and Ethernet status. The boards are
    /// not written to.
    ///
    /// # Errors
    /// No answer within `timeout`, socket failures.
    pub fn probe(host: SocketAddr, timeout: Duration) -> Result<Probe> {
        let IpAddr::V4(ip) = host.ip() else {
            return Err(HostError::InvalidRequest {
                what: "the Ethernet-only network is IPv4",
                value: 0,
            });
        };
        let mut port = EthPort::open(EthAddresses {
            base: ip,
            port: host.port(),
            group: ip,
        })?;
        port.accept_any = true;
        port.set_timeout(timeout);
        let (board, hardware, firmware, eth) = port.hub_identity()?;
        let from = port.last_from.unwrap_or(host);
        Ok(Probe {
            host,
            from,
            board,
            hardware,
            firmware,
            eth_status: eth,
        })
    }

    /// Ask the hub (a broadcast read) for its hardware, firmware and
    /// Ethernet status: `(board ID, HARDWARE_VERSION, FIRMWARE_VERSION,
    /// ETH_STATUS)`.
    ///
    /// # Errors
    /// The reads' failures (no board answering).
    pub fn hub_identity(&mut self) -> Result<(u8, u32, u32, u32)> {
        let reg = |r| Register::board(r).offset();
        let hw = self.read_quadlet(Dest::BROADCAST, reg(BoardRegister::HwVersion)?)?;
        let from = self.last_node;
        let fw = self.read_quadlet(Dest::BROADCAST, reg(BoardRegister::FwVersion)?)?;
        let eth = self.read_quadlet(Dest::BROADCAST, reg(BoardRegister::EthStatus)?)?;
        Ok((from, hw, fw, eth))
    }

    /// Set the read time-out.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The read time-out.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Where the boards are.
    pub fn addresses(&self) -> EthAddresses {
        self.addrs
    }

    /// The broadcast read's counts.
    pub fn eth_stats(&self) -> EthStats {
        self.stats
    }

    /// The system calls made on the port's socket so far, by kind.
    pub fn socket_calls(&self) -> crate::udp::SocketCalls {
        self.socket.calls
    }

    /// The extra data of the last matched response (byte 0 carries the
    /// srcPort of the replying board's switch).
    pub fn last_extra_data(&self) -> Option<ExtraData> {
        self.last_extra
    }

    fn target(&self, dest: Dest) -> Result<SocketAddr> {
        if dest.is_broadcast() {
            return Ok(self.addrs.group());
        }
        self.addrs
            .board(dest.node)
            .ok_or(HostError::InvalidRequest {
                what: "board address beyond the last byte of the base",
                value: u32::from(dest.node),
            })
    }

    /// The board a datagram from `from` may come from (probing: any
    /// sender on the boards' port; its board ID is then in the packet).
    fn sender(&self, from: SocketAddr) -> Option<u8> {
        if self.accept_any && from.port() == self.addrs.port {
            return Some(self.addrs.board_of(from).unwrap_or(0));
        }
        self.addrs.board_of(from)
    }

    fn header(&mut self, dest: Dest) -> AsyncHeader {
        let tl = self.transactions.next_label();
        AsyncHeader::new(NodeId::local(dest.node), HOST_SOURCE_ID, tl)
    }

    fn send(&mut self, dest: Dest, repr: &PacketRepr<'_>) -> Result<()> {
        let target = self.target(dest)?;
        let control = ControlWord {
            no_forward: true,
            generation: self.transactions.generation() as u8,
        };
        let len = fill_request(&mut self.tx, control, repr)?;
        let buf = self.tx.get(..len).unwrap_or(&[]);
        loop {
            match self.socket.send_to(buf, target) {
                Ok(_) => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        self.transactions.sent();
        Ok(())
    }

    /// Drop (and count) everything queued: before a query, whose response
    /// comes unasked, as the Rev 9 host flushes.
    fn flush(&mut self) -> Result<()> {
        self.socket.set_nonblocking(true)?;
        let result = loop {
            match self.socket.recv_from(&mut self.rx) {
                Ok(_) => self.transactions.refused_unmatched(),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => break Err(e.into()),
            }
        };
        self.socket.set_nonblocking(false)?;
        result
    }

    /// Wait for the answer to `expect` from one of the boards' addresses
    /// and copy its payload into `out`; everything else is counted and
    /// dropped.
    fn receive(&mut self, expect: Expect, out: &mut [u8]) -> Result<()> {
        let started = Instant::now();
        let mut limit = self.timeout;
        loop {
            self.socket.set_read_timeout(limit)?;
            let judged = match self.socket.recv_from(&mut self.rx) {
                Ok((len, from)) => match self.sender(from) {
                    Some(board) => {
                        self.last_from = Some(from);
                        let datagram = self.rx.get(..len).unwrap_or(&[]);
                        let judged = judge_reply(&mut self.transactions, datagram, &expect, out)?;
                        if judged.is_some() {
                            self.last_source = board;
                            // The response's source node (its board ID):
                            // quadlet 1's high half, a packet already
                            // checked.
                            self.last_node = self.rx.get(5).map_or(board, |b| b & 0x3F);
                        }
                        judged
                    }
                    None => {
                        self.transactions.refused_unmatched();
                        None
                    }
                },
                Err(e) if is_wait_over(&e) => None,
                Err(e) => return Err(e.into()),
            };
            if let Some(extra) = judged {
                self.last_extra = Some(extra);
                return Ok(());
            }
            limit = time_left(&mut self.transactions, &expect, started, self.timeout)?;
        }
    }
}

impl Port for EthPort {
    fn name(&self) -> &str {
        &self.name
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.transactions.check_generation(dest)?;
        let header = self.header(dest);
        self.send(dest, &PacketRepr::ReadQuadletRequest { header, offset })?;
        let mut out = [0u8; 4];
        self.receive(Expect::quadlet(dest, header.tl), &mut out)?;
        Ok(u32::from_be_bytes(out))
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.transactions.check_generation(dest)?;
        let query = dest.is_broadcast() && offset == HUB_QUERY_OFFSET;
        if query {
            // Its response comes unasked: nothing older may be taken for it.
            self.flush()?;
        }
        let header = self.header(dest);
        self.send(dest, &write_quadlet_request(header, offset, value))?;
        if query {
            self.query_tl = Some(header.tl);
            self.stats.queries += 1;
        }
        Ok(())
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        crate::port::check_block(out.len())?;
        self.transactions.check_generation(dest)?;
        let header = self.header(dest);
        self.send(dest, &read_block_request(header, offset, out.len()))?;
        self.receive(Expect::block(dest, header.tl, out.len()), out)
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        crate::port::check_block(data.len())?;
        self.transactions.check_generation(dest)?;
        let header = self.header(dest);
        self.send(dest, &write_block_request(header, offset, data))
    }

    fn receive_broadcast_response(&mut self, out: &mut [u8]) -> Option<Result<()>> {
        let Some(tl) = self.query_tl.take() else {
            return Some(Err(HostError::InvalidRequest {
                what: "no broadcast query waits for its response",
                value: 0,
            }));
        };
        // From the hub, whichever board it is.
        let expect = Expect::block(Dest::BROADCAST, tl, out.len());
        let r = self.receive(expect, out);
        if r.is_ok() {
            self.stats.responses += 1;
        } else {
            self.stats.fallbacks += 1;
        }
        Some(r)
    }

    fn broadcast_wait(&self, boards: usize) -> Duration {
        ethernet_only_broadcast_wait(boards)
    }

    fn hub_clock_hz(&self) -> u32 {
        ETH_HUB_CLOCK_HZ
    }

    crate::udp::datagram_port_clock_and_counts!();
}

/// What a `udp:HOST` port string opens, chosen as the Rev 9 host chooses
/// (`udp` = best for the hardware, `udpfw` = the bridge): the board
/// answering at HOST is asked who it is ([`EthPort::probe`]); an FPGA V3 at
/// Rev 9 or later means the Ethernet-only network ([`EthPort`], its
/// addresses initialised), anything else, or no answer, the bridge
/// ([`UdpPort`](crate::udp::UdpPort)). The choice follows the board that
/// answers (the hub) alone, as EthBasePort's does.
pub struct UdpNetPort {
    inner: Box<dyn Port + Send>,
    ethernet_only: bool,
}

impl UdpNetPort {
    /// Open the port for `host`; `force_bridge` (`udpfw`) skips the probe.
    /// `timeout` is every read's; `wait` how the bridge's reads wait.
    ///
    /// # Errors
    /// Sockets that cannot be opened; the Ethernet-only network's IP write.
    pub fn open(
        host: SocketAddr,
        force_bridge: bool,
        timeout: Duration,
        wait: crate::udp::WaitMode,
    ) -> Result<UdpNetPort> {
        let network = if force_bridge {
            None
        } else {
            EthPort::probe(host, timeout)
                .ok()
                .filter(Probe::is_ethernet_only)
                .and_then(|p| p.ethernet_only_addresses())
        };
        Ok(match network {
            Some(addrs) => {
                let mut port = EthPort::open(addrs)?;
                port.set_timeout(timeout);
                port.init()?;
                UdpNetPort {
                    inner: Box::new(port),
                    ethernet_only: true,
                }
            }
            None => {
                let mut port = crate::udp::UdpPort::open(host)?;
                port.set_timeout(timeout);
                port.set_wait_mode(wait);
                UdpNetPort {
                    inner: Box::new(port),
                    ethernet_only: false,
                }
            }
        })
    }

    /// Whether the Ethernet-only network was chosen (else the bridge).
    pub fn is_ethernet_only(&self) -> bool {
        self.ethernet_only
    }
}

impl Port for UdpNetPort {
    crate::port::forward_port!(s => s.inner);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycle_report::{HubReadTimes, hub_ticks_us};

    /// EthBasePort `WaitBroadcastRead` without the bridge: 3 us for one
    /// board, 38 us for each further one.
    #[test]
    fn the_rev9_hosts_wait_on_the_ethernet_only_network() {
        let us = |n| ethernet_only_broadcast_wait(n).as_micros();
        assert_eq!(us(1), 3);
        assert_eq!(us(2), 41);
        assert_eq!(us(4), 117);
        assert_eq!(us(8), 269);
        assert_eq!(us(16), 573);
        // No board: no further block to wait for.
        assert_eq!(us(0), 3);
    }

    /// The port on the network says so: the Rev 9 wait and the 125 MHz hub
    /// clock, where every other port keeps the bridge's.
    #[test]
    fn the_ethernet_only_port_waits_and_counts_as_the_rev9_host() {
        let port = EthPort::open(EthAddresses::loopback(1394)).unwrap();
        assert_eq!(port.broadcast_wait(8), Duration::from_micros(269));
        assert_eq!(port.hub_clock_hz(), 125_000_000);
        let bridge = crate::udp::UdpPort::open("127.0.0.1:1394".parse().unwrap()).unwrap();
        assert_eq!(bridge.broadcast_wait(8), Duration::from_micros(50));
        assert_eq!(bridge.hub_clock_hz(), 49_152_000);
    }

    /// A known hub header and timing quadlet at both clocks: update time
    /// 0x4E20 (20000 ticks) is 160 us at 125 MHz, 406.9 us at 49.152 MHz;
    /// the timing quadlet 0x2710_3A98 (read started at 10000 ticks, read at
    /// 15000) is 80 and 120 us at 125 MHz.
    #[test]
    fn hub_times_at_the_ethernet_clock() {
        let header = firelink_wire::qla::broadcast::HubHeader::from_word(
            0x2103_4E20,
            firelink_wire::qla::realtime::BlockFormat::Rev8,
        );
        let firelink_wire::qla::broadcast::HubHeader::Rev8 {
            quadlets,
            update_time,
            ..
        } = header
        else {
            panic!("a Rev 8 header: {header:?}");
        };
        assert_eq!((quadlets, update_time), (33, 0x4E20));
        assert_eq!(
            hub_ticks_us(u32::from(update_time), ETH_HUB_CLOCK_HZ),
            160.0
        );
        let bridge = hub_ticks_us(u32::from(update_time), 49_152_000);
        assert!((bridge - 406.901).abs() < 0.001, "{bridge}");
        // The largest 15-bit update time: 262.136 us at 125 MHz.
        assert!((hub_ticks_us(0x7FFF, ETH_HUB_CLOCK_HZ) - 262.136).abs() < 0.001);
        let times = HubReadTimes::from_word(0x2710_3A98, ETH_HUB_CLOCK_HZ);
        assert_eq!(times.read_start_us, 80.0);
        assert_eq!(times.read_end_us, 120.0);
    }
}
