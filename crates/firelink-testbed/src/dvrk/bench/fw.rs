//! The benchmark's `fw` points: the real `IoSystem` over `FirewirePort`,
//! through the preloaded /dev/fw* twin (`libfirelink_fwcdev.so`), against
//! an in-process twin server with the emulated boards on the simulated bus
//! (`firelink emulate --fw-cdev`'s [`Twin`] and [`fw_cdev::serve`]), and
//! beside it the *floor*: the same number of request -> completion-event
//! round trips, with the same payload sizes and host waits (recorded from
//! one of the point's own cycles), made bare over a pair of the same
//! `SOCK_SEQPACKET` sockets (a control socket and an event socket, the
//! twin's own message format) against a thread that answers every
//! request at once and models no board, no bus and no time.
//!
//! The point's cycles and the floor's alternate in blocks of
//! [`super::udp::BLOCK`] cycles. CPU time comes from thread clocks: the
//! host's thread around each cycle's I/O, the twin server's thread and the
//! floor responder's thread around each block (their idle time included).
//!
//! The process must run with the twin preloaded and `FIRELINK_FW_CDEV`
//! naming a socket path for the server to bind (`firelink bench
//! --transport fw` re-runs itself so); elsewhere the points fail with a
//! [`TestbedError::Config`] that says so.

use std::os::fd::{AsFd, AsRawFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::socket::{
    AddressFamily, MsgFlags, Shutdown, SockFlag, SockType, recv, send, shutdown, socketpair,
};

use firelink_board::qla::config::BoardConfig;
use firelink_control::runner::Percentiles;
use firelink_emulate::fw_cdev::{self, Twin, TwinStats};
use firelink_host::Port;
use firelink_host::firewire::{FirewirePort, FwOptions};
use firelink_host::qla::io::IoSystem;
use firelink_host::qla::scan::Protocol;
use firelink_wire::fw_cdev::{
    KERNEL_ABI_VERSION, ResponseEvent, SendRequestArgs, TWIN_MAX_MESSAGE, TwinRequest,
    emit_response, rcode,
};

use super::server_thread::ServerThread;
use super::udp::{BLOCK, Recorder, Step};
use super::{BenchTransport, Raw};
use crate::TestbedError;
use crate::cpu::ThreadCpuClock;
use crate::fw_run::SOCKET_ENV;
use crate::rig;

/// Warm-up cycles before measuring (the point's and the floor's).
const WARM_UP: u64 = 20;

/// What an `fw` point adds to its raw measurement: the floor beside it
/// and CPU times.
#[derive(Debug, Clone)]
pub(super) struct FwRun {
    /// Request -> completion round trips per cycle (the floor makes as
    /// many).
    pub round_trips: f64,
    /// The floor's time per cycle.
    pub floor: Percentiles,
    /// Floor cycles that failed.
    pub floor_errors: u64,
    /// The host's thread over each cycle's I/O, per cycle, us.
    pub host_cpu: f64,
    /// The same over the floor's cycles, us.
    pub floor_host_cpu: f64,
    /// The twin server's thread per cycle, us.
    pub twin_cpu: Option<f64>,
    /// The floor responder's thread per floor cycle, us.
    pub floor_server_cpu: Option<f64>,
}

/// Whether this process runs with the twin preloaded: the socket path.
fn twin_socket() -> Result<PathBuf, TestbedError> {
    let preloaded = std::env::var("LD_PRELOAD").is_ok_and(|p| {
        p.split([' ', ':'])
            .any(|l| l.ends_with("libfirelink_fwcdev.so"))
    });
    match std::env::var_os(SOCKET_ENV) {
        Some(path) if preloaded => Ok(PathBuf::from(path)),
        _ => Err(TestbedError::Config(format!(
            "the fw points run FirewirePort through the /dev/fw* twin: this process needs \
             libfirelink_fwcdev.so in LD_PRELOAD and {SOCKET_ENV} naming a socket path to \
             serve (`firelink bench --transport fw` sets both up)"
        ))),
    }
}

/// The twin's server on a thread of this process, and the socket path it
/// binds (removed when it stops).
struct TwinServer {
    /// (Taken when stopped.)
    server: Option<ServerThread<std::io::Result<TwinStats>>>,
    path: PathBuf,
}

impl TwinServer {
    fn start(
        boards: Vec<BoardConfig>,
        path: PathBuf,
        detail: firelink_bus::Detail,
    ) -> Result<TwinServer, TestbedError> {
        let (mut bus, host, _) = rig::build_bus(boards)?;
        bus.set_detail(detail);
        let mut twin = Twin::new(bus, host);
        let listener = fw_cdev::bind(&path)?;
        let server = ServerThread::spawn(move |stop: &std::sync::Arc<AtomicBool>| {
            fw_cdev::serve(&mut twin, &listener, stop, |_| {}).map(|()| twin.stats())
        });
        Ok(TwinServer {
            server: Some(server),
            path,
        })
    }

    /// Stop serving; the twin's counters (`None`: the server failed).
    fn stop(mut self) -> Option<TwinStats> {
        self.server.take()?.stop()?.ok()
    }

    fn cpu_time(&self) -> Option<Duration> {
        self.server.as_ref()?.cpu_time()
    }
}

impl Drop for TwinServer {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The floor: a control and an event socket (`SOCK_SEQPACKET` pairs), the
/// far ends served by a thread that answers each SEND_REQUEST at once
/// with a RESPONSE2 event of the length asked on the event socket (as the
/// twin does, nothing goes back on the control socket).
struct Floor {
    control: OwnedFd,
    event: OwnedFd,
    thread: Option<JoinHandle<()>>,
    cpu: Option<ThreadCpuClock>,
    request: Vec<u8>,
    reply: Vec<u8>,
    closure: u64,
    /// Closures of started writes whose completions are not read yet.
    started: Vec<u64>,
}

fn seqpacket_pair() -> Result<(OwnedFd, OwnedFd), TestbedError> {
    socketpair(
        AddressFamily::Unix,
        SockType::SeqPacket,
        None,
        SockFlag::SOCK_CLOEXEC,
    )
    .map_err(|e| TestbedError::Io(e.into()))
}

/// Answer every request on `control` until the other end closes.
fn floor_server(control: OwnedFd, event: OwnedFd) {
    let mut rx = vec![0u8; TWIN_MAX_MESSAGE];
    let mut tx = vec![0u8; TWIN_MAX_MESSAGE];
    let zeros = [0u8; 4096];
    loop {
        let n = match recv(control.as_raw_fd(), &mut rx, MsgFlags::empty()) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let Ok(TwinRequest::SendRequest { args, .. }) = TwinRequest::parse(&rx[..n]) else {
            return;
        };
        let data = if matches!(args.tcode, 4 | 5) {
            zeros.get(..args.length as usize).unwrap_or(&[])
        } else {
            &[]
        };
        let Ok(len) = emit_response(
            KERNEL_ABI_VERSION,
            args.closure,
            rcode::COMPLETE,
            data,
            (0, 0),
            &mut tx,
        ) else {
            return;
        };
        if send(event.as_raw_fd(), &tx[..len], MsgFlags::MSG_NOSIGNAL).is_err() {
            return;
        }
    }
}

impl Floor {
    fn start() -> Result<Floor, TestbedError> {
        let (control, far_control) = seqpacket_pair()?;
        let (event, far_event) = seqpacket_pair()?;
        let thread = std::thread::spawn(move || floor_server(far_control, far_event));
        let cpu = ThreadCpuClock::of(&thread);
        Ok(Floor {
            control,
            event,
            thread: Some(thread),
            cpu,
            request: vec![0u8; TWIN_MAX_MESSAGE],
            reply: vec![0u8; TWIN_MAX_MESSAGE],
            closure: 1,
            started: Vec::with_capacity(8),
        })
    }

    fn cpu_time(&self) -> Option<Duration> {
        self.cpu
            .and_then(|c| c.now_while_running(self.thread.as_ref()))
    }

    /// Send one bare request on the control socket; its closure.
    fn send_request(&mut self, tcode: u32, length: usize) -> Result<u64, Errno> {
        static PAYLOAD: [u8; 2048] = [0; 2048];
        let closure = self.closure;
        self.closure += 1;
        let args = SendRequestArgs {
            tcode,
            length: length as u32,
            offset: 0xFFFF_0000_0000,
            closure,
            data: 0,
            generation: 1,
        };
        let request = TwinRequest::SendRequest {
            broadcast: false,
            args,
            payload: PAYLOAD.get(..length).unwrap_or(&[]),
        };
        let n = request.emit(&mut self.request).map_err(|_| Errno::EINVAL)?;
        send(
            self.control.as_raw_fd(),
            &self.request[..n],
            MsgFlags::MSG_NOSIGNAL,
        )?;
        Ok(closure)
    }

    /// Poll and read completion events until the one of `closure`; those
    /// of started writes on the way are taken, as the port takes them.
    fn await_completion(&mut self, closure: u64) -> Result<(), Errno> {
        loop {
            let mut fds = [PollFd::new(self.event.as_fd(), PollFlags::POLLIN)];
            match poll(&mut fds, PollTimeout::from(1000u16)) {
                Ok(0) => return Err(Errno::ETIMEDOUT),
                Ok(_) => {}
                Err(Errno::EINTR) => continue,
                Err(e) => return Err(e),
            }
            let got = recv(self.event.as_raw_fd(), &mut self.reply, MsgFlags::empty())?;
            let r = ResponseEvent::parse(&self.reply[..got]).map_err(|_| Errno::EIO)?;
            if r.closure == closure {
                return Ok(());
            }
            match self.started.iter().position(|&c| c == r.closure) {
                Some(k) => {
                    self.started.swap_remove(k);
                }
                None => return Err(Errno::EIO),
            }
        }
    }

    /// One bare round trip: the request, then its completion event.
    fn round_trip(&mut self, tcode: u32, length: usize) -> Result<(), Errno> {
        let closure = self.send_request(tcode, length)?;
        self.await_completion(closure)
    }

    /// A started write: the request alone (the oldest waited for first
    /// when as many are open as the port keeps).
    fn start_write(&mut self, tcode: u32, length: usize) -> Result<(), Errno> {
        if self.started.len() >= 8 {
            let oldest = self.started.remove(0);
            self.await_completion(oldest)?;
        }
        let closure = self.send_request(tcode, length)?;
        self.started.push(closure);
        Ok(())
    }

    /// The floor's cycle: the calls of `script`, bare.
    fn replay(&mut self, script: &[Step]) -> Result<(), Errno> {
        for step in script {
            match *step {
                Step::ReadQuadlet(..) => self.round_trip(4, 4)?,
                Step::WriteQuadlet(..) => self.round_trip(0, 4)?,
                Step::ReadBlock(_, _, len) => self.round_trip(5, len)?,
                Step::WriteBlock(_, _, len) => self.round_trip(1, len)?,
                Step::StartWriteQuadlet(..) => self.start_write(0, 4)?,
                Step::StartWriteBlock(_, _, len) => self.start_write(1, len)?,
                Step::Wait(d) => std::thread::sleep(d),
                // Only the Ethernet-only network answers a query unasked.
                Step::BroadcastResponse(_) => {}
            }
        }
        Ok(())
    }
}

impl Drop for Floor {
    fn drop(&mut self) {
        // Shutting our end down ends the responder's loop.
        let _ = shutdown(self.control.as_raw_fd(), Shutdown::Both);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn cpu_of(clock: Option<ThreadCpuClock>) -> Option<Duration> {
    clock.and_then(|c| c.now())
}

fn since(before: Option<Duration>, after: Option<Duration>) -> Duration {
    match (before, after) {
        (Some(a), Some(b)) => b.saturating_sub(a),
        _ => Duration::ZERO,
    }
}

/// Measure one `fw` point: `protocol` on `boards` through the twin, with
/// its floor, interleaved in blocks.
pub(super) fn measure_point(
    boards: Vec<BoardConfig>,
    protocol: Protocol,
    options: &super::BenchOptions,
) -> Result<Raw, TestbedError> {
    let path = twin_socket()?;
    let server = TwinServer::start(boards, path, options.detail)?;
    let idle = Duration::from_secs_f64(options.idle_us.max(0.0) / 1e6);
    let mut port = Recorder::new(FirewirePort::open(FwOptions::default())?);
    let scan = firelink_host::qla::scan::scan(&mut port)?;
    let plan = super::Plan::of(&scan, protocol, options);
    let mut io = IoSystem::with_scan(port, &scan, plan.options())?;
    for _ in 0..WARM_UP {
        io.cycle();
        let _ = io.recover();
        io.port_mut().wait(idle);
    }
    io.port_mut().script = Some(Vec::new());
    let sent_before = io.port().link_stats().sent;
    io.cycle();
    let sent = io.port().link_stats().sent - sent_before;
    let script = io.port_mut().script.take().unwrap_or_default();
    io.port_mut().wait(idle);
    let mut floor = Floor::start()?;
    for _ in 0..WARM_UP {
        let _ = floor.replay(&script);
        std::thread::sleep(idle);
    }
    let host = ThreadCpuClock::current();
    let cycles = options.cycles.max(1);
    let (mut times, mut floor_times) = (Vec::new(), Vec::new());
    let (mut read, mut write) = (0.0, 0.0);
    let (mut host_cpu, mut floor_host_cpu) = (Duration::ZERO, Duration::ZERO);
    let (mut twin_cpu, mut floor_cpu) = (Duration::ZERO, Duration::ZERO);
    let twin_clock = server.cpu_time().is_some();
    let floor_clock = floor.cpu_time().is_some();
    let mut floor_errors = 0;
    let mut done = 0;
    while done < cycles {
        let n = BLOCK.min(cycles - done);
        let twin_before = server.cpu_time();
        for _ in 0..n {
            let before = cpu_of(host);
            let report = *io.cycle();
            host_cpu += since(before, cpu_of(host));
            let _ = io.recover();
            times.push(us(report.io_time()) as f32);
            read += us(report.read_time);
            write += us(report.write_time);
            io.port_mut().wait(idle);
        }
        twin_cpu += since(twin_before, server.cpu_time());
        let floor_before = floor.cpu_time();
        for _ in 0..n {
            let before = cpu_of(host);
            let started = Instant::now();
            let ok = floor.replay(&script).is_ok();
            let took = started.elapsed();
            floor_host_cpu += since(before, cpu_of(host));
            floor_errors += u64::from(!ok);
            floor_times.push(us(took) as f32);
            std::thread::sleep(idle);
        }
        floor_cpu += since(floor_before, floor.cpu_time());
        done += n;
    }
    let errors = io.stats().total_errors();
    drop(io);
    drop(floor);
    let twin_stats = server.stop();
    let per = |d: Duration| us(d) / cycles as f64;
    Ok(Raw {
        transport: BenchTransport::Fw,
        board_set: None,
        wait: None,
        protocol: plan.protocol,
        asked: protocol,
        groups: plan.groups,
        boards: scan.boards.len(),
        io: Percentiles::of(&mut times),
        read: read / cycles as f64,
        write: write / cycles as f64,
        cycles,
        errors,
        note: plan.note,
        udp: None,
        fw: Some(FwRun {
            round_trips: sent as f64,
            floor: Percentiles::of(&mut floor_times),
            floor_errors,
            host_cpu: per(host_cpu),
            floor_host_cpu: per(floor_host_cpu),
            twin_cpu: twin_clock.then(|| per(twin_cpu)),
            floor_server_cpu: floor_clock.then(|| per(floor_cpu)),
        }),
        sim_cpu: None,
        detail: twin_stats.map(|s| s.detail),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_host::Dest;

    /// The floor answers every kind of request with exactly one completion
    /// of the closure sent, for every payload size the cycles use.
    #[test]
    fn the_floor_completes_each_round_trip_with_its_own_closure() {
        let mut floor = Floor::start().unwrap();
        let script = [
            Step::ReadQuadlet(Dest::node(0), 0),
            Step::WriteQuadlet(Dest::node(0), 0x1800),
            Step::ReadBlock(Dest::node(0), 0x1000, 268),
            Step::WriteBlock(Dest::node(0), 0xFFFF_FFFF_0000, 2048),
            Step::StartWriteQuadlet(Dest::node(0), 0x1800),
            Step::ReadBlock(Dest::node(0), 0x1000, 1060),
            Step::StartWriteBlock(Dest::node(0), 0xFFFF_FFFF_0000, 192),
        ];
        for _ in 0..10 {
            floor.replay(&script).unwrap();
        }
        assert_eq!(floor.closure, 71);
        // The last cycle's command write is still open (each earlier one
        // was taken by the next cycle's first read, each query by the hub
        // read after it).
        assert_eq!(floor.started.len(), 1);
    }
}
