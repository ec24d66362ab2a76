//! Receiving a datagram together with the moment it arrived.
//!
//! The server handles each datagram at its arrival time in virtual time,
//! not at the moment its thread got round to reading it: a busy machine
//! that keeps the server off the CPU for milliseconds then delays the
//! answers, but does not make the boards see the host's writes late (no
//! spurious watchdog time-outs, no distorted timestamps). On Linux the
//! kernel stamps each datagram as it is queued (`SO_TIMESTAMPNS`);
//! elsewhere the moment of reading stands in for it.

use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use firelink_host::udp::is_wait_over;

/// One datagram: its length in the buffer, its sender and when it arrived.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Received {
    pub len: usize,
    pub from: SocketAddr,
    pub at: Instant,
}

/// Kernel stamps older than this are not believed (a clock step while the
/// datagram waited): the moment of reading is used instead.
const MAX_AGE: Duration = Duration::from_secs(1);

/// Receives datagrams with their arrival time from one socket.
pub(crate) struct Receiver {
    #[cfg(target_os = "linux")]
    control: Vec<u8>,
}

impl Receiver {
    /// Ask the kernel to stamp `socket`'s datagrams (where it can).
    pub fn new(socket: &UdpSocket) -> io::Result<Receiver> {
        #[cfg(target_os = "linux")]
        {
            use nix::sys::socket::{setsockopt, sockopt::ReceiveTimestampns};
            setsockopt(socket, ReceiveTimestampns, &true).map_err(io::Error::from)?;
            Ok(Receiver {
                control: nix::cmsg_space!(nix::sys::time::TimeSpec),
            })
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = socket;
            Ok(Receiver {})
        }
    }

    /// The next datagram into `buf`: `wait` blocks up to the socket's read
    /// time-out, otherwise only what is queued now is taken. `Ok(None)`
    /// when nothing came. A datagram longer than `buf` is cut to it.
    pub fn receive(
        &mut self,
        socket: &UdpSocket,
        buf: &mut [u8],
        wait: bool,
    ) -> io::Result<Option<Received>> {
        match self.receive_inner(socket, buf, wait) {
            Ok(r) => Ok(Some(r)),
            // A host that went away (ICMP port unreachable) is no reason
            // to stop serving the others.
            Err(e) if is_wait_over(&e) || e.kind() == io::ErrorKind::ConnectionRefused => Ok(None),
            Err(e) => Err(e),
        }
    }

    #[cfg(target_os = "linux")]
    fn receive_inner(
        &mut self,
        socket: &UdpSocket,
        buf: &mut [u8],
        wait: bool,
    ) -> io::Result<Received> {
        use nix::sys::socket::{ControlMessageOwned, MsgFlags, SockaddrStorage, recvmsg};
        use std::os::fd::AsRawFd;
        let flags = if wait {
            MsgFlags::empty()
        } else {
            MsgFlags::MSG_DONTWAIT
        };
        let mut iov = [io::IoSliceMut::new(buf)];
        let msg = recvmsg::<SockaddrStorage>(
            socket.as_raw_fd(),
            &mut iov,
            Some(&mut self.control),
            flags,
        )
        .map_err(io::Error::from)?;
        let read_at = Instant::now();
        let stamped = msg.cmsgs().ok().and_then(|mut c| {
            c.find_map(|m| match m {
                ControlMessageOwned::ScmTimestampns(ts) => Some(ts),
                _ => None,
            })
        });
        let age = stamped.and_then(|ts| {
            let stamp = std::time::UNIX_EPOCH
                + Duration::new(ts.tv_sec().max(0) as u64, ts.tv_nsec().max(0) as u32);
            std::time::SystemTime::now().duration_since(stamp).ok()
        });
        let at = age
            .filter(|a| *a <= MAX_AGE)
            .and_then(|a| read_at.checked_sub(a))
            .unwrap_or(read_at);
        let from = msg
            .address
            .and_then(|a| {
                a.as_sockaddr_in()
                    .map(|v4| SocketAddr::V4((*v4).into()))
                    .or_else(|| a.as_sockaddr_in6().map(|v6| SocketAddr::V6((*v6).into())))
            })
            .ok_or_else(|| io::Error::other("datagram without an IP source address"))?;
        Ok(Received {
            len: msg.bytes,
            from,
            at,
        })
    }

    #[cfg(not(target_os = "linux"))]
    fn receive_inner(
        &mut self,
        socket: &UdpSocket,
        buf: &mut [u8],
        wait: bool,
    ) -> io::Result<Received> {
        socket.set_nonblocking(!wait)?;
        let r = socket.recv_from(buf);
        socket.set_nonblocking(false)?;
        let (len, from) = r?;
        Ok(Received {
            len,
            from,
            at: Instant::now(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A datagram read long after it arrived carries its arrival time, not
    /// the time it was read (generous bounds: only the order is asserted).
    /// The kernel switches stamping on a little after the first socket asks
    /// (deferred work), and stamps a datagram that came before that when it
    /// is read: so the check is repeated until stamping is on.
    #[test]
    fn a_late_read_keeps_the_arrival_time() {
        let rx_socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx_socket
            .set_read_timeout(Some(Duration::from_secs(5)))
            .unwrap();
        let mut rx = Receiver::new(&rx_socket).unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut buf = [0u8; 64];
        // Nothing queued: a non-waiting receive returns at once.
        assert!(rx.receive(&rx_socket, &mut buf, false).unwrap().is_none());
        let mut stamped = false;
        for _ in 0..20 {
            tx.send_to(b"hello", rx_socket.local_addr().unwrap())
                .unwrap();
            let sent = Instant::now();
            std::thread::sleep(Duration::from_millis(100));
            let read = Instant::now();
            let r = rx.receive(&rx_socket, &mut buf, true).unwrap().unwrap();
            assert_eq!(&buf[..r.len], b"hello");
            assert_eq!(r.from, tx.local_addr().unwrap());
            assert!(r.at <= Instant::now());
            if r.at <= sent + Duration::from_millis(20)
                && read.duration_since(r.at) >= Duration::from_millis(80)
            {
                stamped = true;
                break;
            }
        }
        assert!(stamped || !cfg!(target_os = "linux"), "no arrival stamps");
    }
}
