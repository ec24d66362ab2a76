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

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use firelink_wire::board::address::{BoardRegister, Register};
use firelink_wire::bridge::{ControlWord, EXTRA_DATA_LEN, ExtraData};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};

use crate::error::{HostError, Result};
use crate::port::{Dest, LinkFilter, LinkFilters, Port, Verdict};
use crate::transaction::{CrcCheck, Expect, LinkStats, Transactions, copy_answer};

/// Source node ID the reference host uses (`fpga-board.md` §8).
pub const HOST_SOURCE_ID: NodeId = NodeId(0xFFD0);

/// Largest request datagram: control word, 20-byte header+CRC, 2048-byte
/// payload, data CRC.
const MAX_DATAGRAM: usize = 2 + 20 + 2048 + 4 + 16;

/// A port speaking the Ethernet bridge protocol over UDP.
pub struct UdpPort {
    name: String,
    socket: UdpSocket,
    target: SocketAddr,
    timeout: Duration,
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
            socket,
            target,
            timeout: Self::DEFAULT_TIMEOUT,
            transactions: Transactions::new(),
            tx: vec![0; MAX_DATAGRAM],
            rx: vec![0; MAX_DATAGRAM + 64],
            opened: Instant::now(),
            last_extra: None,
            filters: LinkFilters::default(),
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
        let len = 2 + repr.buffer_len();
        let Some(buf) = self.tx.get_mut(..len) else {
            return Err(HostError::InvalidRequest {
                what: "request larger than a datagram",
                value: len as u32,
            });
        };
        buf[..2].copy_from_slice(&control.to_bytes());
        repr.emit(&mut buf[2..])?;
        let now_ps = self.now_ps();
        let Some(buf) = self.tx.get_mut(..len) else {
            return Ok(());
        };
        let lost = self.filters.outgoing(now_ps, &mut buf[2..]) == Verdict::Drop;
        if !lost {
            self.socket.send_to(buf, self.target)?;
        }
        self.transactions.sent();
        Ok(())
    }

    /// Drop anything already queued (answers to requests that timed out).
    fn flush(&mut self) -> Result<()> {
        self.socket.set_nonblocking(true)?;
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

    /// Wait for the answer to `expect` and copy its payload (or quadlet)
    /// into `out`; every other datagram is counted by the engine under the
    /// reason it was refused.
    fn receive(&mut self, expect: Expect, out: &mut [u8]) -> Result<()> {
        let started = Instant::now();
        loop {
            let elapsed = started.elapsed();
            let Some(remaining) = self.timeout.checked_sub(elapsed).filter(|d| !d.is_zero()) else {
                let waited = elapsed.as_micros().min(u128::from(u32::MAX)) as u32;
                return Err(self.transactions.timed_out(&expect, waited));
            };
            self.socket.set_read_timeout(Some(remaining))?;
            let len = match self.socket.recv_from(&mut self.rx) {
                Ok((len, from)) if from == self.target => len,
                Ok(_) => {
                    self.transactions.refused_unmatched();
                    continue;
                }
                Err(e) if is_wait_over(&e) => {
                    continue;
                }
                Err(e) => return Err(e.into()),
            };
            if self.heard(len) == Verdict::Drop {
                continue;
            }
            let datagram = self.rx.get(..len).unwrap_or(&[]);
            if let Some(extra) = judge_reply(&mut self.transactions, datagram, &expect, out)? {
                self.last_extra = Some(extra);
                return Ok(());
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
        self.flush()?;
        let header = self.header(dest);
        self.send(dest, &PacketRepr::ReadQuadletRequest { header, offset })?;
        let mut out = [0u8; 4];
        self.receive(Expect::quadlet(dest, header.tl), &mut out)?;
        Ok(u32::from_be_bytes(out))
    }
}

/// Whether a socket error only says that nothing arrived in time (or the
/// wait was interrupted): the caller waits on, it is not a failure.
pub fn is_wait_over(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::TimedOut
            | std::io::ErrorKind::Interrupted
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
        self.receive(Expect::block(dest, header.tl, out.len()), out)
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
        self.transactions.generation()
    }

    fn link_stats(&self) -> LinkStats {
        self.transactions.stats()
    }

    fn acknowledges_writes(&self) -> bool {
        false
    }

    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        self.filters.add(filter);
        Ok(())
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
