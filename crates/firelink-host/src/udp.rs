//! The UDP port: the FPGA V2 Ethernet bridge protocol of firmware Rev 7/8.
//!
//! Every request is one datagram to the board's port 1394: a 16-bit control
//! word (no-forward bit, the host's bus generation) and a complete 1394
//! packet with CRCs computed here. Read responses come back as the 1394
//! response packet followed by 8 bytes of extra data; writes get no reply.
//! Facts: `fpga-board.md` §8.
//!
//! Responses are matched to their request by source node, transaction label,
//! tcode and length; anything else (a late answer to an earlier request, a
//! stray datagram) is counted and dropped. Buffers are allocated once, so a
//! transaction allocates nothing.

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use firelink_wire::bridge::{ControlWord, ExtraData, split_board_datagram};
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Tcode};

use crate::error::{HostError, Result};
use crate::port::{Dest, Port};

/// Source node ID the reference host uses (`fpga-board.md` §8).
pub const HOST_SOURCE_ID: NodeId = NodeId(0xFFD0);

/// Largest request datagram: control word, 20-byte header+CRC, 2048-byte
/// payload, data CRC.
const MAX_DATAGRAM: usize = 2 + 20 + 2048 + 4 + 16;

/// Counters of what the port saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UdpStats {
    /// Datagrams sent.
    pub sent: u64,
    /// Responses matched to a request.
    pub matched: u64,
    /// Well-formed datagrams that answered no current request (stale tl,
    /// wrong node, tcode or length), dropped.
    pub stale: u64,
    /// Datagrams that did not decode, dropped.
    pub garbage: u64,
    /// Responses whose CRC failed.
    pub crc_errors: u64,
    /// Reads that timed out.
    pub timeouts: u64,
    /// Bus generation changes seen in the extra data.
    pub bus_resets: u64,
}

/// A port speaking the Ethernet bridge protocol over UDP.
pub struct UdpPort {
    name: String,
    socket: UdpSocket,
    target: SocketAddr,
    timeout: Duration,
    tl: u8,
    generation: u8,
    /// A generation seen in a board's extra data that the host has not
    /// adopted yet.
    pending_generation: Option<u8>,
    tx: Vec<u8>,
    rx: Vec<u8>,
    stats: UdpStats,
    opened: Instant,
    last_extra: Option<ExtraData>,
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
            socket,
            target,
            timeout: Self::DEFAULT_TIMEOUT,
            tl: 0,
            generation: 0,
            pending_generation: None,
            tx: vec![0; MAX_DATAGRAM],
            rx: vec![0; MAX_DATAGRAM + 64],
            stats: UdpStats::default(),
            opened: Instant::now(),
            last_extra: None,
        })
    }

    /// Parse a port string: `udp:HOST` (port 1394) or `udp:HOST:PORT`.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for text that is not such an address.
    pub fn parse_address(text: &str) -> Result<SocketAddr> {
        let rest = text.strip_prefix("udp:").unwrap_or(text);
        let bad = HostError::InvalidRequest {
            what: "port string (expected udp:HOST or udp:HOST:PORT)",
            value: 0,
        };
        if let Ok(ip) = rest.parse::<IpAddr>() {
            return Ok(SocketAddr::new(ip, firelink_wire::bridge::BRIDGE_UDP_PORT));
        }
        rest.parse::<SocketAddr>().map_err(|_| bad)
    }

    /// Set the read time-out.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// What the port has counted so far.
    pub fn stats(&self) -> UdpStats {
        self.stats
    }

    /// The extra data of the last matched response.
    pub fn last_extra_data(&self) -> Option<ExtraData> {
        self.last_extra
    }

    fn next_tl(&mut self) -> u8 {
        self.tl = (self.tl + 1) & 0x3F;
        self.tl
    }

    /// Fail once if the boards reported a new bus generation, adopting it.
    fn check_generation(&mut self, dest: Dest) -> Result<()> {
        if let Some(new) = self.pending_generation.take() {
            let old = self.generation;
            self.generation = new;
            if !dest.is_broadcast() {
                return Err(HostError::BusReset {
                    old: u32::from(old),
                    new: u32::from(new),
                });
            }
        }
        Ok(())
    }

    fn send(&mut self, dest: Dest, repr: &PacketRepr<'_>) -> Result<()> {
        let control = ControlWord {
            no_forward: dest.no_forward,
            generation: self.generation,
        };
        let len = 2 + repr.buffer_len();
        let Some(buf) = self.tx.get_mut(..len) else {
            return Err(HostError::InvalidRequest {
                what: "request larger than a datagram",
                value: len as u32,
            });
        };
        buf[..2].copy_from_slice(&control.to_bytes());
        repr.emit(&mut buf[2..])?;
        self.socket.send_to(buf, self.target)?;
        self.stats.sent += 1;
        Ok(())
    }

    /// Drop anything already queued (answers to requests that timed out).
    fn flush(&mut self) -> Result<()> {
        self.socket.set_nonblocking(true)?;
        loop {
            match self.socket.recv_from(&mut self.rx) {
                Ok(_) => self.stats.stale += 1,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                Err(e) => {
                    self.socket.set_nonblocking(false)?;
                    return Err(e.into());
                }
            }
        }
        self.socket.set_nonblocking(false)?;
        Ok(())
    }

    /// Wait for the response matching (node, tl, tcode, length) and copy its
    /// payload (or quadlet) into `out`.
    fn receive(&mut self, dest: Dest, tl: u8, tcode: Tcode, out: &mut [u8]) -> Result<()> {
        let started = Instant::now();
        loop {
            let elapsed = started.elapsed();
            let Some(remaining) = self.timeout.checked_sub(elapsed).filter(|d| !d.is_zero()) else {
                self.stats.timeouts += 1;
                return Err(HostError::Timeout {
                    node: dest.node,
                    tl,
                    waited_us: elapsed.as_micros().min(u128::from(u32::MAX)) as u32,
                });
            };
            self.socket.set_read_timeout(Some(remaining))?;
            let len = match self.socket.recv_from(&mut self.rx) {
                Ok((len, from)) if from == self.target => len,
                Ok(_) => {
                    self.stats.garbage += 1;
                    continue;
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    continue;
                }
                Err(e) => return Err(e.into()),
            };
            let datagram = &self.rx[..len];
            let Ok((packet, extra)) = split_board_datagram(datagram) else {
                self.stats.garbage += 1;
                continue;
            };
            if extra.generation != self.generation {
                if self.pending_generation != Some(extra.generation) {
                    self.stats.bus_resets += 1;
                }
                self.pending_generation = Some(extra.generation);
            }
            if !Self::matches(&packet, dest, tl, tcode, out.len()) {
                self.stats.stale += 1;
                continue;
            }
            // Locally generated responses may carry 0 in their CRC fields.
            let local_zero_crc = extra.flags.no_forward && packet.header_crc() == Some(0);
            if !local_zero_crc {
                if let Err(e) = packet.verify() {
                    self.stats.crc_errors += 1;
                    return Err(e.into());
                }
            }
            self.stats.matched += 1;
            self.last_extra = Some(extra);
            let rcode = packet.rcode();
            if rcode != Rcode::Complete {
                return Err(HostError::Rcode {
                    node: packet.source_id().phy(),
                    rcode,
                });
            }
            if tcode == Tcode::ReadQuadletResponse {
                out.copy_from_slice(&packet.quadlet_data().to_be_bytes());
            } else {
                out.copy_from_slice(packet.payload());
            }
            return Ok(());
        }
    }

    fn matches(packet: &Packet<&[u8]>, dest: Dest, tl: u8, tcode: Tcode, len: usize) -> bool {
        if packet.tcode() != tcode || packet.tl() != tl {
            return false;
        }
        if !dest.is_broadcast() && !dest.no_forward && packet.source_id().phy() != dest.node {
            return false;
        }
        match tcode {
            Tcode::ReadQuadletResponse => len == 4,
            _ => usize::from(packet.data_length()) == len,
        }
    }

    fn header(&mut self, dest: Dest) -> AsyncHeader {
        let tl = self.next_tl();
        AsyncHeader::new(NodeId::local(dest.node), HOST_SOURCE_ID, tl)
    }
}

impl Port for UdpPort {
    fn name(&self) -> &str {
        &self.name
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.check_generation(dest)?;
        self.flush()?;
        let header = self.header(dest);
        self.send(dest, &PacketRepr::ReadQuadletRequest { header, offset })?;
        let mut out = [0u8; 4];
        self.receive(dest, header.tl, Tcode::ReadQuadletResponse, &mut out)?;
        Ok(u32::from_be_bytes(out))
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.check_generation(dest)?;
        let header = self.header(dest);
        self.send(
            dest,
            &PacketRepr::WriteQuadletRequest {
                header,
                offset,
                data: value,
            },
        )
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        crate::port::check_block(out.len())?;
        self.check_generation(dest)?;
        self.flush()?;
        let header = self.header(dest);
        self.send(
            dest,
            &PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: out.len() as u16,
                extended_tcode: 0,
            },
        )?;
        self.receive(dest, header.tl, Tcode::ReadBlockResponse, out)
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        crate::port::check_block(data.len())?;
        self.check_generation(dest)?;
        let header = self.header(dest);
        self.send(
            dest,
            &PacketRepr::WriteBlockRequest {
                header,
                offset,
                extended_tcode: 0,
                data,
            },
        )
    }

    fn wait(&mut self, duration: Duration) {
        crate::pacing::precise_sleep(duration);
    }

    fn now(&self) -> Duration {
        self.opened.elapsed()
    }

    fn generation(&self) -> u32 {
        u32::from(self.generation)
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
        assert!(UdpPort::parse_address("udp:nowhere").is_err());
    }
}
