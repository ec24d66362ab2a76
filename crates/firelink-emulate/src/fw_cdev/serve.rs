//! The twin's server loop: a `SOCK_SEQPACKET` unix socket, one event
//! connection and one control connection per open /dev/fwN (the protocol:
//! [`firelink_wire::fw_cdev`]), virtual time paced to the wall clock.
//!
//! Each event is sent when the wall clock reaches the virtual time the
//! simulated bus finished it at (the server sleeps in `ppoll` with
//! nanosecond time-outs and a 1 ns timer slack); between requests the bus
//! runs on with the wall clock, so bus resets, fault plans and the boards'
//! watchdogs happen on time. Every wait is bounded (1 ms), and a stop flag
//! ends the loop.

use std::collections::VecDeque;
use std::io;
use std::os::fd::{AsFd, AsRawFd, FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, ppoll};
use nix::sys::socket::{
    AddressFamily, Backlog, MsgFlags, Shutdown, SockFlag, SockType, UnixAddr, accept4,
    bind as nix_bind, listen, recv, send, shutdown, socket,
};
use nix::sys::time::TimeSpec;

use firelink_bus::{SimDuration, SimTime};
use firelink_wire::fw_cdev::{self, TwinReply, TwinRequest, errno};

use super::{Answer, Outgoing, Twin, TwinStats};

/// Something worth one line to the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ServeEvent {
    /// The socket is bound.
    Listening(PathBuf),
    /// A program opened /dev/fw`device`.
    Opened {
        /// The N of /dev/fwN.
        device: u32,
        /// Its connection.
        connection: u64,
    },
    /// The bus generation changed.
    BusReset(u32),
    /// The server stopped.
    Stopped(TwinStats),
}

/// Bind the twin's socket at `path` (a stale socket file left there by an
/// earlier server is replaced; any other file is an error).
///
/// # Errors
/// I/O errors of creating, binding or listening.
pub fn bind(path: &Path) -> io::Result<OwnedFd> {
    use std::os::unix::fs::FileTypeExt;
    if let Ok(meta) = std::fs::symlink_metadata(path) {
        if !meta.file_type().is_socket() {
            return Err(io::Error::new(
                io::ErrorKind::AlreadyExists,
                format!("{} exists and is not a socket", path.display()),
            ));
        }
        std::fs::remove_file(path)?;
    }
    let fd = socket(
        AddressFamily::Unix,
        SockType::SeqPacket,
        SockFlag::SOCK_CLOEXEC | SockFlag::SOCK_NONBLOCK,
        None,
    )?;
    nix_bind(fd.as_raw_fd(), &UnixAddr::new(path)?)?;
    listen(&fd, Backlog::new(64)?)?;
    Ok(fd)
}

enum Role {
    /// No message yet.
    New,
    /// The event connection of an open device file.
    Event(u64),
    /// The control connection of one.
    Control(u64),
}

struct Conn {
    fd: OwnedFd,
    role: Role,
    queue: VecDeque<Vec<u8>>,
    /// Close once the queue is sent (a listing, a refused open).
    close_after: bool,
    closed: bool,
}

/// The longest the loop sleeps: the bus's own events (resets, the boards'
/// watchdogs) happen at most this late.
const TICK: Duration = Duration::from_millis(1);

/// Serve `twin` on `listener` until `stop` is set.
///
/// # Errors
/// Errors of the listening socket (a client's failures only end that
/// client's connection).
pub fn serve(
    twin: &mut Twin,
    listener: &OwnedFd,
    stop: &AtomicBool,
    on_event: impl FnMut(ServeEvent),
) -> io::Result<()> {
    serve_with(twin, listener, stop, on_event, |_| {})
}

/// [`serve`], calling `between` with the twin once per turn of the loop
/// (before virtual time is brought up to the wall clock): how a test or a
/// tool injects a fault at a moment of its choosing (a board unplugged
/// once its program has the device open).
///
/// # Errors
/// As [`serve`].
pub fn serve_with(
    twin: &mut Twin,
    listener: &OwnedFd,
    stop: &AtomicBool,
    mut on_event: impl FnMut(ServeEvent),
    mut between: impl FnMut(&mut Twin),
) -> io::Result<()> {
    // Sleep to the nanosecond asked for, not 50 us later.
    let _ = nix::sys::prctl::set_timerslack(1);
    let path = nix::sys::socket::getsockname::<UnixAddr>(listener.as_raw_fd())
        .ok()
        .and_then(|a| a.path().map(Path::to_path_buf))
        .unwrap_or_default();
    on_event(ServeEvent::Listening(path));
    let wall_origin = Instant::now();
    let virtual_origin = twin.bus().now();
    let virtual_at = |at: Instant| {
        virtual_origin + SimDuration::from_nanos(at.duration_since(wall_origin).as_nanos() as u64)
    };
    let mut conns: Vec<Conn> = Vec::new();
    let mut ready = Vec::new();
    let mut buf = vec![0u8; fw_cdev::TWIN_MAX_MESSAGE + 16];
    let mut generation = twin.bus().generation();
    while !stop.load(Ordering::Relaxed) {
        between(twin);
        let now = virtual_at(Instant::now());
        twin.advance(now);
        if twin.bus().generation() != generation {
            generation = twin.bus().generation();
            on_event(ServeEvent::BusReset(generation));
        }
        deliver(twin, now, &mut ready, &mut conns);
        for c in conns.iter_mut() {
            flush(c);
        }
        conns.retain(|c| !c.closed);
        // Sleep until the next event is due, a message arrives, or a tick.
        let wait = twin
            .next_due()
            .map(|due| Duration::from_nanos(due.saturating_since(now).as_nanos()))
            .unwrap_or(TICK)
            .min(TICK);
        let mut fds = Vec::with_capacity(conns.len() + 1);
        fds.push(PollFd::new(listener.as_fd(), PollFlags::POLLIN));
        for c in &conns {
            let mut flags = PollFlags::POLLIN;
            if !c.queue.is_empty() {
                flags |= PollFlags::POLLOUT;
            }
            fds.push(PollFd::new(c.fd.as_fd(), flags));
        }
        match ppoll(&mut fds, Some(TimeSpec::from_duration(wait)), None) {
            Ok(_) | Err(Errno::EINTR) => {}
            Err(e) => return Err(e.into()),
        }
        let listener_ready = fds
            .first()
            .and_then(PollFd::revents)
            .is_some_and(|r| r.contains(PollFlags::POLLIN));
        let readable: Vec<bool> = fds
            .iter()
            .skip(1)
            .map(|f| {
                f.revents().is_some_and(|r| {
                    r.intersects(PollFlags::POLLIN | PollFlags::POLLHUP | PollFlags::POLLERR)
                })
            })
            .collect();
        drop(fds);
        for (c, r) in conns.iter_mut().zip(readable) {
            if r {
                receive(twin, c, &mut buf, virtual_at, &mut on_event);
            }
        }
        if listener_ready {
            loop {
                match accept4(
                    listener.as_raw_fd(),
                    SockFlag::SOCK_CLOEXEC | SockFlag::SOCK_NONBLOCK,
                ) {
                    Ok(fd) => conns.push(Conn {
                        // accept4 returned a new descriptor we own.
                        fd: own(fd),
                        role: Role::New,
                        queue: VecDeque::new(),
                        close_after: false,
                        closed: false,
                    }),
                    Err(Errno::EAGAIN | Errno::ECONNABORTED | Errno::EINTR) => break,
                    Err(Errno::EMFILE | Errno::ENFILE) => break,
                    Err(e) => return Err(e.into()),
                }
            }
        }
        for c in conns.iter_mut() {
            flush(c);
        }
        conns.retain(|c| !c.closed);
    }
    on_event(ServeEvent::Stopped(twin.stats()));
    Ok(())
}

/// A descriptor accept4 just returned, owned from now on.
#[allow(unsafe_code)]
fn own(fd: std::os::fd::RawFd) -> OwnedFd {
    // SAFETY: `fd` is a fresh descriptor from accept4 that nothing else
    // owns or closes.
    unsafe { OwnedFd::from_raw_fd(fd) }
}

/// Move the events due by `now` into their connections' queues.
fn deliver(twin: &mut Twin, now: SimTime, ready: &mut Vec<Outgoing>, conns: &mut [Conn]) {
    ready.clear();
    twin.take_ready(now, ready);
    for o in ready.drain(..) {
        match o {
            Outgoing::Event {
                connection, bytes, ..
            } => {
                if let Some(c) = conns
                    .iter_mut()
                    .find(|c| matches!(c.role, Role::Event(id) if id == connection))
                {
                    c.queue.push_back(bytes);
                }
            }
            Outgoing::HangUp { connection } => {
                // The control connection first: once the program sees
                // EPOLLHUP on its fd, its ioctls already fail (ENODEV).
                let control = |c: &Conn| matches!(c.role, Role::Control(id) if id == connection);
                let event = |c: &Conn| matches!(c.role, Role::Event(id) if id == connection);
                for c in conns.iter_mut().filter(|c| control(c)) {
                    hang_up_conn(c);
                }
                for c in conns.iter_mut().filter(|c| event(c)) {
                    hang_up_conn(c);
                }
            }
        }
    }
}

/// Shut `c` down for good: the peer sees EPOLLHUP once what is queued is
/// read, and its sends fail (EPIPE).
fn hang_up_conn(c: &mut Conn) {
    flush(c);
    let _ = shutdown(c.fd.as_raw_fd(), Shutdown::Both);
    c.closed = true;
}

/// Send what is queued, as far as the socket takes it.
fn flush(c: &mut Conn) {
    while let Some(m) = c.queue.front() {
        match send(
            c.fd.as_raw_fd(),
            m,
            MsgFlags::MSG_DONTWAIT | MsgFlags::MSG_NOSIGNAL,
        ) {
            Ok(_) => {
                c.queue.pop_front();
            }
            Err(Errno::EAGAIN | Errno::EINTR) => return,
            Err(_) => {
                c.closed = true;
                return;
            }
        }
    }
    if c.close_after {
        c.closed = true;
    }
}

/// Read every message waiting on `c` and answer it.
fn receive(
    twin: &mut Twin,
    c: &mut Conn,
    buf: &mut [u8],
    virtual_at: impl Fn(Instant) -> SimTime,
    on_event: &mut impl FnMut(ServeEvent),
) {
    loop {
        let n = match recv(c.fd.as_raw_fd(), buf, MsgFlags::MSG_DONTWAIT) {
            Ok(0) => {
                hang_up(twin, c);
                return;
            }
            Ok(n) => n,
            Err(Errno::EAGAIN | Errno::EINTR) => return,
            Err(_) => {
                hang_up(twin, c);
                return;
            }
        };
        let now = virtual_at(Instant::now());
        let message = buf.get(..n).unwrap_or(&[]);
        let answer = match TwinRequest::parse(message) {
            Ok(request) => answer(twin, c, request, now, on_event),
            // The library never sends a message it cannot parse. On a
            // control connection no reply is safe (a request that expects
            // none would take it for the next call's): the connection is
            // closed, and the program's next ioctl on it fails (ENODEV).
            Err(_) if matches!(c.role, Role::Control(_)) => {
                twin.note_refused();
                c.closed = true;
                return;
            }
            Err(_) => {
                c.close_after = true;
                Some(Answer {
                    errno: errno::EINVAL,
                    ..Answer::default()
                })
            }
        };
        if let Some(a) = answer {
            let mut out = vec![0u8; 16 + a.payload.len()];
            let reply = TwinReply {
                errno: a.errno,
                value: a.value,
                payload: &a.payload,
            };
            if reply.emit(&mut out).is_ok() {
                c.queue.push_back(out);
            }
        }
    }
}

/// The connection's peer went away.
fn hang_up(twin: &mut Twin, c: &mut Conn) {
    if let Role::Event(id) = c.role {
        twin.close(id);
    }
    c.closed = true;
}

/// The answer to one request on `c` (`None`: nothing to send back).
fn answer(
    twin: &mut Twin,
    c: &mut Conn,
    request: TwinRequest<'_>,
    now: SimTime,
    on_event: &mut impl FnMut(ServeEvent),
) -> Option<Answer> {
    let fail = |errno| {
        Some(Answer {
            errno,
            ..Answer::default()
        })
    };
    match (&c.role, request) {
        (Role::New, TwinRequest::Open { device }) => {
            twin.advance(now);
            match twin.open(device) {
                Ok(id) => {
                    c.role = Role::Event(id);
                    on_event(ServeEvent::Opened {
                        device,
                        connection: id,
                    });
                    Some(Answer::value(id))
                }
                Err(e) => {
                    c.close_after = true;
                    fail(e)
                }
            }
        }
        (Role::New, TwinRequest::Attach { connection }) => {
            // The reply's value is the node's speed code.
            let a = twin.speed(connection);
            if a.errno == 0 {
                c.role = Role::Control(connection);
            } else {
                c.close_after = true;
            }
            Some(a)
        }
        (Role::New, TwinRequest::List) => {
            twin.advance(now);
            c.close_after = true;
            Some(Answer {
                errno: 0,
                value: 0,
                payload: twin
                    .device_numbers()
                    .iter()
                    .flat_map(|d| d.to_le_bytes())
                    .collect(),
            })
        }
        (
            Role::Control(id),
            TwinRequest::GetInfo {
                version,
                rom_length,
                bus_reset_closure,
            },
        ) => Some(twin.get_info(*id, version, rom_length, bus_reset_closure, now)),
        (
            Role::Control(id),
            TwinRequest::SendRequest {
                broadcast,
                args,
                payload,
            },
        ) => {
            // One-way: the outcome is the completion event (a refusal here
            // is one the library already makes, so only a client that
            // bypasses it meets one; it is counted and gets nothing).
            let _ = twin.send_request(*id, broadcast, &args, payload, now);
            None
        }
        (Role::Control(id), TwinRequest::InitiateBusReset { short }) => {
            Some(twin.initiate_bus_reset(*id, short, now))
        }
        (Role::Control(_), TwinRequest::CycleTimer) => Some(twin.cycle_timer(now)),
        (Role::Control(id), TwinRequest::GetSpeed) => Some(twin.speed(*id)),
        // An event connection only receives; anything else is out of turn.
        (Role::Event(_), _) => None,
        // A one-way message out of turn gets no reply either.
        (_, TwinRequest::SendRequest { .. }) => None,
        _ => fail(errno::EINVAL),
    }
}
