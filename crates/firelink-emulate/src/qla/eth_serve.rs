//! The Ethernet-only network served over real UDP: one socket per board at
//! its own address (base + board ID, as the Rev 9 firmware numbers them),
//! the group sockets (the loopback broadcast address the host's first
//! requests go to, and the multicast group 224.0.0.100 when asked), the
//! network's virtual time paced to the wall clock, every reply sent from
//! its board's socket when the wall clock reaches the time the timing
//! model says it reaches the host.
//!
//! Loopback by default (127.0.0.100 + ID: every 127/8 address is local,
//! nothing to configure). The stock 169.254.0.100 + ID addresses and the
//! multicast group need those addresses on an interface and a multicast
//! route: tests do that on `lo` inside a network namespace of their own.

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use firelink_bus::{SimDuration, SimTime};

use crate::qla::eth_network::{Destination, EthNetwork, NetworkStats, Outgoing};

/// The Rev 9 host's multicast group (EthUdpPort: `MulticastIP` default).
pub const MULTICAST_GROUP: Ipv4Addr = Ipv4Addr::new(224, 0, 0, 100);

/// The loopback network's broadcast address.
const LOOPBACK_BROADCAST: Ipv4Addr = Ipv4Addr::new(127, 255, 255, 255);

/// Largest datagram read whole.
const MAX_DATAGRAM: usize = 4096;

/// Longest the loop waits when nothing is due (a datagram arriving ends
/// the wait at once).
const IDLE_SLEEP: Duration = Duration::from_micros(200);

/// Where the network listens.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EthServeConfig {
    /// Board 0's address; board N listens at this address + N (the last
    /// byte; 127.0.0.100 by default).
    pub base: Ipv4Addr,
    /// The UDP port of every board (1394; 0 picks a free one for all).
    pub port: u16,
    /// Also receive on the loopback broadcast address (the host's first
    /// requests, before it knows the hub's firmware, go to the subnet
    /// broadcast).
    pub loopback_broadcast: bool,
    /// Join this multicast group (224.0.0.100) on the interface of the
    /// multicast route: only inside a network namespace or on a network
    /// meant for it.
    pub multicast: Option<Ipv4Addr>,
}

impl Default for EthServeConfig {
    fn default() -> Self {
        EthServeConfig {
            base: Ipv4Addr::new(127, 0, 0, 100),
            port: 1394,
            loopback_broadcast: true,
            multicast: None,
        }
    }
}

impl EthServeConfig {
    /// Board `id`'s address, if base + ID stays in the last byte.
    pub fn board_address(&self, id: u8) -> Option<Ipv4Addr> {
        let [a, b, c, d] = self.base.octets();
        d.checked_add(id).map(|d| Ipv4Addr::new(a, b, c, d))
    }
}

/// The bound sockets.
#[derive(Debug)]
pub struct EthSockets {
    /// (board ID, its socket).
    pub boards: Vec<(u8, UdpSocket)>,
    /// The loopback broadcast socket, if bound.
    pub broadcast: Option<UdpSocket>,
    /// The multicast socket, if joined.
    pub multicast: Option<UdpSocket>,
    /// The port all of them use.
    pub port: u16,
}

impl EthSockets {
    /// Board `id`'s socket address.
    pub fn board_addr(&self, id: u8) -> Option<SocketAddr> {
        self.boards
            .iter()
            .find(|(b, _)| *b == id)
            .and_then(|(_, s)| s.local_addr().ok())
    }
}

fn bind_boards(config: &EthServeConfig, ids: &[u8], port: u16) -> std::io::Result<EthSockets> {
    let mut boards = Vec::with_capacity(ids.len());
    let mut port = port;
    for &id in ids {
        let ip = config.board_address(id).ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "board {id}: {} + {id} leaves the address's last byte",
                    config.base
                ),
            )
        })?;
        let socket = UdpSocket::bind(SocketAddr::new(IpAddr::V4(ip), port))?;
        port = socket.local_addr()?.port();
        socket.set_nonblocking(true)?;
        boards.push((id, socket));
    }
    Ok(EthSockets {
        boards,
        broadcast: None,
        multicast: None,
        port,
    })
}

/// Bind a socket per board of `ids` and the group sockets `config` asks
/// for. With port 0 the first board's free port is tried for every
/// board (a few times, should another program take it meanwhile).
///
/// # Errors
/// Binding a board's socket or joining the multicast group; the loopback
/// broadcast socket is optional.
pub fn eth_bind(config: &EthServeConfig, ids: &[u8]) -> std::io::Result<EthSockets> {
    let mut sockets = {
        let mut tries = 0;
        loop {
            match bind_boards(config, ids, config.port) {
                Err(e) if config.port == 0 && tries < 8 => {
                    tries += 1;
                    if e.kind() != std::io::ErrorKind::AddrInUse {
                        return Err(e);
                    }
                }
                other => break other?,
            }
        }
    };
    let port = sockets.port;
    if config.loopback_broadcast && config.base.is_loopback() {
        sockets.broadcast = UdpSocket::bind(SocketAddr::new(IpAddr::V4(LOOPBACK_BROADCAST), port))
            .ok()
            .filter(|s| s.set_nonblocking(true).is_ok());
    }
    if let Some(group) = config.multicast {
        let socket = UdpSocket::bind(SocketAddr::new(IpAddr::V4(group), port))?;
        socket.join_multicast_v4(&group, &Ipv4Addr::UNSPECIFIED)?;
        socket.set_nonblocking(true)?;
        sockets.multicast = Some(socket);
    }
    Ok(sockets)
}

/// Something worth one line to the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EthEvent {
    /// Sockets are bound: each board's address, the group addresses.
    Listening {
        /// (board ID, address).
        boards: Vec<(u8, SocketAddr)>,
        /// The loopback broadcast address, if bound.
        broadcast: Option<SocketAddr>,
        /// The multicast group, if joined.
        multicast: Option<SocketAddr>,
    },
    /// The first datagram from a new host address.
    HostSeen(SocketAddr),
    /// Virtual time fell behind the wall clock by more than 10 ms.
    Lagging(Duration),
    /// The server stopped: its counters.
    Stopped(NetworkStats),
}

/// Run the network until `stop` is set: take datagrams on every socket at
/// the virtual time of their arrival, keep virtual time with the wall
/// clock, send each reply from its board's socket when it is due.
///
/// # Errors
/// Socket errors other than would-block.
pub fn eth_serve(
    net: &mut EthNetwork,
    sockets: &EthSockets,
    stop: &Arc<AtomicBool>,
    mut on_event: impl FnMut(EthEvent),
) -> std::io::Result<()> {
    on_event(EthEvent::Listening {
        boards: sockets
            .boards
            .iter()
            .filter_map(|(id, s)| s.local_addr().ok().map(|a| (*id, a)))
            .collect(),
        broadcast: sockets.broadcast.as_ref().and_then(|s| s.local_addr().ok()),
        multicast: sockets.multicast.as_ref().and_then(|s| s.local_addr().ok()),
    });
    let wall_origin = Instant::now();
    let virtual_origin = net.now();
    let virtual_at = |at: Instant| {
        virtual_origin
            + SimDuration::from_micros_f64(at.duration_since(wall_origin).as_secs_f64() * 1e6)
    };
    let wall_at = |t: SimTime| {
        wall_origin + Duration::from_secs_f64(t.saturating_since(virtual_origin).as_secs_f64())
    };
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut due: Vec<Outgoing> = Vec::with_capacity(64);
    const HOSTS_REMEMBERED: usize = 16;
    let mut hosts: Vec<SocketAddr> = Vec::with_capacity(HOSTS_REMEMBERED);
    let mut lag_reported = Instant::now() - Duration::from_secs(10);
    let group = sockets
        .broadcast
        .iter()
        .chain(sockets.multicast.iter())
        .map(|s| (Destination::Group, s));
    let listeners: Vec<(Destination, &UdpSocket)> = sockets
        .boards
        .iter()
        .map(|(id, s)| (Destination::Board(*id), s))
        .chain(group)
        .collect();
    let mut readable = Readable::new(listeners.iter().map(|l| l.1));
    while !stop.load(Ordering::Relaxed) {
        let mut any = false;
        for &(to, socket) in &listeners {
            loop {
                match socket.recv_from(&mut buf) {
                    Ok((n, from)) => {
                        any = true;
                        if hosts.len() < HOSTS_REMEMBERED && !hosts.contains(&from) {
                            hosts.push(from);
                            on_event(EthEvent::HostSeen(from));
                        }
                        let at = virtual_at(Instant::now());
                        net.handle(at, to, from, buf.get(..n).unwrap_or(&buf));
                    }
                    Err(e) if crate::not_the_servers_failure(&e) => break,
                    Err(e) => return Err(e),
                }
            }
        }
        let wall = Instant::now();
        let now = virtual_at(wall);
        net.advance_to(now);
        due.clear();
        net.take_due(now, &mut due);
        for out in &due {
            let Some(socket) = sockets
                .boards
                .iter()
                .find(|(id, _)| *id == out.from)
                .map(|(_, s)| s)
            else {
                continue;
            };
            match socket.send_to(&out.bytes, out.to) {
                Ok(_) => {}
                // A host that went away is not the server's failure.
                Err(e) if crate::not_the_servers_failure(&e) => {}
                Err(e) => return Err(e),
            }
        }
        let behind = wall.saturating_duration_since(wall_at(net.now()));
        if behind > Duration::from_millis(10) && lag_reported.elapsed() > Duration::from_secs(5) {
            on_event(EthEvent::Lagging(behind));
            lag_reported = Instant::now();
        }
        if !any {
            // Wait until the next reply or event is due, briefly, or until
            // a datagram arrives.
            let next = [net.next_due(), net.next_event()]
                .into_iter()
                .flatten()
                .min()
                .map(|t| wall_at(t).saturating_duration_since(Instant::now()));
            let nap = next.map_or(IDLE_SLEEP, |d| d.min(IDLE_SLEEP));
            if !nap.is_zero() {
                readable.wait(nap);
            }
        }
    }
    on_event(EthEvent::Stopped(net.stats()));
    Ok(())
}

/// Waiting for a datagram on any of the network's sockets: `ppoll` on
/// Linux (woken by the first datagram; the file descriptors gathered once),
/// a plain sleep elsewhere.
struct Readable<'s> {
    #[cfg(target_os = "linux")]
    fds: Vec<nix::poll::PollFd<'s>>,
    #[cfg(not(target_os = "linux"))]
    sockets: core::marker::PhantomData<&'s UdpSocket>,
}

impl<'s> Readable<'s> {
    fn new(sockets: impl Iterator<Item = &'s UdpSocket>) -> Readable<'s> {
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsFd;
            let flags = nix::poll::PollFlags::POLLIN;
            Readable {
                fds: sockets
                    .map(|s| nix::poll::PollFd::new(s.as_fd(), flags))
                    .collect(),
            }
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = sockets;
            Readable {
                sockets: core::marker::PhantomData,
            }
        }
    }

    /// Wait until a datagram is readable on one of the sockets, or `limit`
    /// passed (an interrupted or failed wait returns early: the loop looks
    /// at the sockets again).
    fn wait(&mut self, limit: Duration) {
        #[cfg(target_os = "linux")]
        {
            let timeout = nix::sys::time::TimeSpec::from_duration(limit);
            let _ = nix::poll::ppoll(&mut self.fds, Some(timeout), None);
        }
        #[cfg(not(target_os = "linux"))]
        std::thread::sleep(limit);
    }
}
