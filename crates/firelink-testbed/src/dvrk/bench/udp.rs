//! The benchmark's UDP points: the real `IoSystem` over `UdpPort` against a
//! bridge (the in-process emulator or an address given), each wait mode
//! asked for, and beside each the *floor*: the same port calls (the same
//! requests, datagram sizes and host waits, recorded from one of the
//! point's own cycles) against a responder on loopback that answers every
//! read at once with a response of the size asked and emulates nothing.
//!
//! The point's cycles and the floor's alternate in blocks of [`BLOCK`]
//! cycles, for every wait mode in turn, so the machine's noise hits all of
//! them alike. CPU time is read from thread clocks ([`ThreadCpuClock`]):
//! the host's thread around each cycle's I/O (not the idle time between
//! cycles), the emulator's server thread around each block of the point's
//! own cycles (everything it did meanwhile, the idle time between cycles
//! included: virtual time runs on).

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use firelink_control::runner::Percentiles;
use firelink_host::eth::EthPort;
use firelink_host::link_stats::LinkStats;
use firelink_host::qla::io::IoSystem;
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::{SocketCalls, UdpPort, WaitMode, is_wait_over};
use firelink_host::{Dest, LinkFilter, Port};
use firelink_wire::bridge::{ExtraData, split_host_datagram};
use firelink_wire::packet::{NodeId, PacketRepr, Rcode};
use firelink_wire::qla::address::HUB_QUERY_OFFSET;

use super::server_thread::ServerThread;
use crate::TestbedError;
use crate::cpu::ThreadCpuClock;
use crate::rig;

/// Cycles per block: the point's own cycles and the floor's alternate in
/// blocks of this many.
pub const BLOCK: u64 = 50;

/// Warm-up cycles before measuring (the point's and the floor's).
const WARM_UP: u64 = 20;

/// The read time-out while scanning (a node that is not there costs it
/// once per scan).
const SCAN_TIMEOUT: Duration = Duration::from_millis(100);

/// One port call of a cycle, as the floor repeats it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Step {
    ReadQuadlet(Dest, u64),
    WriteQuadlet(Dest, u64),
    ReadBlock(Dest, u64, usize),
    WriteBlock(Dest, u64, usize),
    /// A write started without waiting for its completion.
    StartWriteQuadlet(Dest, u64),
    /// A block write started without waiting for its completion.
    StartWriteBlock(Dest, u64, usize),
    Wait(Duration),
    /// The hub's unsolicited response to a query taken (the Ethernet-only
    /// network), of this many bytes.
    BroadcastResponse(usize),
}

/// A port that writes down its calls while asked to (the script of one
/// cycle, which the floor repeats); otherwise it only passes them on.
pub(super) struct Recorder<P: Port> {
    pub(super) inner: P,
    /// The calls written down while `Some`.
    pub(super) script: Option<Vec<Step>>,
}

impl<P: Port> Recorder<P> {
    pub(super) fn new(inner: P) -> Recorder<P> {
        Recorder {
            inner,
            script: None,
        }
    }

    fn note(&mut self, step: Step) {
        if let Some(s) = &mut self.script {
            s.push(step);
        }
    }
}

impl<P: Port> Port for Recorder<P> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> firelink_host::Result<u32> {
        self.note(Step::ReadQuadlet(dest, offset));
        self.inner.read_quadlet(dest, offset)
    }
    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> firelink_host::Result<()> {
        self.note(Step::WriteQuadlet(dest, offset));
        self.inner.write_quadlet(dest, offset, value)
    }
    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> firelink_host::Result<()> {
        self.note(Step::ReadBlock(dest, offset, out.len()));
        self.inner.read_block(dest, offset, out)
    }
    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> firelink_host::Result<()> {
        self.note(Step::WriteBlock(dest, offset, data.len()));
        self.inner.write_block(dest, offset, data)
    }
    fn start_write_quadlet(
        &mut self,
        dest: Dest,
        offset: u64,
        value: u32,
    ) -> firelink_host::Result<()> {
        self.note(Step::StartWriteQuadlet(dest, offset));
        self.inner.start_write_quadlet(dest, offset, value)
    }
    fn start_write_block(
        &mut self,
        dest: Dest,
        offset: u64,
        data: &[u8],
    ) -> firelink_host::Result<()> {
        self.note(Step::StartWriteBlock(dest, offset, data.len()));
        self.inner.start_write_block(dest, offset, data)
    }
    fn wait(&mut self, duration: Duration) {
        self.note(Step::Wait(duration));
        self.inner.wait(duration);
    }
    fn begin_cycle(&mut self) {
        self.inner.begin_cycle();
    }
    fn end_cycle(&mut self) {
        self.inner.end_cycle();
    }
    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        // Over UDP nothing is overheard: the whole limit is waited.
        self.note(Step::Wait(limit));
        self.inner.wait_until_heard(limit, heard)
    }
    fn receive_broadcast_response(&mut self, out: &mut [u8]) -> Option<firelink_host::Result<()>> {
        let response = self.inner.receive_broadcast_response(out);
        if response.is_some() {
            self.note(Step::BroadcastResponse(out.len()));
        }
        response
    }
    fn broadcast_wait(&self, boards: usize) -> Duration {
        self.inner.broadcast_wait(boards)
    }
    fn hub_clock_hz(&self) -> u32 {
        self.inner.hub_clock_hz()
    }
    fn now(&self) -> Duration {
        self.inner.now()
    }
    fn now_ps(&self) -> u64 {
        self.inner.now_ps()
    }
    fn generation(&self) -> u32 {
        self.inner.generation()
    }
    fn acknowledges_writes(&self) -> bool {
        self.inner.acknowledges_writes()
    }
    fn refuses_broadcast_registers(&self) -> bool {
        // The system's broadcast route depends on it (the fw port's
        // snooped-node-0 route).
        self.inner.refuses_broadcast_registers()
    }
    fn link_stats(&self) -> LinkStats {
        self.inner.link_stats()
    }
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.inner.candidate_nodes()
    }
    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> firelink_host::Result<()> {
        self.inner.add_link_filter(filter)
    }

    fn takes_link_filters(&self) -> bool {
        self.inner.takes_link_filters()
    }
}

/// Largest payload a block request asks for (2048 bytes), zeros.
static ZEROS: [u8; 2048] = [0; 2048];

/// The floor's answer to one host datagram: a read gets the response of
/// the size it asks for (zeros, correct CRCs, then the bridge's 8 bytes of
/// extra data) written into `reply`; with `query_answer` above 0, a
/// broadcast query (a quadlet write to node 63 at `0x1800`) gets a block
/// read response of that many bytes under its label, as the Ethernet-only
/// network's hub answers it unasked; anything else gets nothing.
pub fn floor_answer(request: &[u8], reply: &mut [u8], query_answer: usize) -> Option<usize> {
    let (_, packet) = split_host_datagram(request).ok()?;
    let response = match PacketRepr::parse(&packet).ok()? {
        PacketRepr::WriteQuadletRequest { header, offset, .. }
            if query_answer > 0
                && offset == HUB_QUERY_OFFSET
                && header.destination.phy() == NodeId::BROADCAST_PHY =>
        {
            PacketRepr::ReadBlockResponse {
                header: header.response(),
                rcode: Rcode::Complete,
                extended_tcode: 0,
                data: ZEROS.get(..query_answer)?,
            }
        }
        PacketRepr::ReadQuadletRequest { header, .. } => PacketRepr::ReadQuadletResponse {
            header: header.response(),
            rcode: Rcode::Complete,
            data: 0,
        },
        PacketRepr::ReadBlockRequest {
            header,
            data_length,
            ..
        } => PacketRepr::ReadBlockResponse {
            header: header.response(),
            rcode: Rcode::Complete,
            extended_tcode: 0,
            data: ZEROS.get(..usize::from(data_length))?,
        },
        _ => return None,
    };
    let n = response.emit(reply).ok()?;
    let extra = ExtraData::default().to_bytes();
    reply.get_mut(n..n + extra.len())?.copy_from_slice(&extra);
    Some(n + extra.len())
}

/// The floor's responder: a thread on 127.0.0.1 answering as
/// [`floor_answer`] says, at once, from a blocking socket (as the
/// emulator's server waits).
pub(super) struct Responder {
    pub(super) addr: SocketAddr,
    /// Bytes of the response a broadcast query gets (0: none).
    query_answer: Arc<AtomicUsize>,
    /// Its thread, whose CPU clock tells what receiving and answering the
    /// floor's datagrams costs a server that emulates nothing.
    server: ServerThread<()>,
}

impl Responder {
    pub(super) fn start() -> Result<Responder, TestbedError> {
        let socket = UdpSocket::bind(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0))?;
        // Only to look at the stop flag now and then.
        socket.set_read_timeout(Some(Duration::from_millis(50)))?;
        let addr = socket.local_addr()?;
        let query_answer = Arc::new(AtomicUsize::new(0));
        let answer = Arc::clone(&query_answer);
        let server = ServerThread::spawn(move |stop: &Arc<AtomicBool>| {
            let mut rx = vec![0u8; 4096];
            let mut tx = vec![0u8; 4096];
            while !stop.load(Ordering::Relaxed) {
                match socket.recv_from(&mut rx) {
                    Ok((len, from)) => {
                        let request = rx.get(..len).unwrap_or(&[]);
                        let query = answer.load(Ordering::Relaxed);
                        if let Some(n) = floor_answer(request, &mut tx, query) {
                            let _ = socket.send_to(&tx[..n], from);
                        }
                    }
                    Err(e) if is_wait_over(&e) => {}
                    Err(_) => return,
                }
            }
        });
        Ok(Responder {
            addr,
            query_answer,
            server,
        })
    }

    /// Answer broadcast queries with `bytes` of hub (0: do not).
    fn answer_queries_with(&self, bytes: usize) {
        self.query_answer.store(bytes, Ordering::Relaxed);
    }

    /// CPU time its thread has used so far, while it runs.
    fn cpu_time(&self) -> Option<Duration> {
        self.server.cpu_time()
    }
}

/// Make the calls of `script` on `port` (the floor's cycle); the first
/// failure ends it.
fn replay<P: Port>(port: &mut P, script: &[Step], buf: &mut [u8]) -> firelink_host::Result<()> {
    for step in script {
        match *step {
            Step::ReadQuadlet(dest, offset) => {
                port.read_quadlet(dest, offset)?;
            }
            Step::WriteQuadlet(dest, offset) => port.write_quadlet(dest, offset, 0)?,
            Step::StartWriteQuadlet(dest, offset) => port.start_write_quadlet(dest, offset, 0)?,
            Step::ReadBlock(dest, offset, len) => {
                let out = buf.get_mut(..len).unwrap_or_default();
                port.read_block(dest, offset, out)?;
            }
            Step::WriteBlock(dest, offset, len) => {
                port.write_block(dest, offset, ZEROS.get(..len).unwrap_or_default())?;
            }
            Step::StartWriteBlock(dest, offset, len) => {
                port.start_write_block(dest, offset, ZEROS.get(..len).unwrap_or_default())?;
            }
            Step::Wait(d) => port.wait(d),
            Step::BroadcastResponse(len) => {
                let out = buf.get_mut(..len).unwrap_or_default();
                if let Some(r) = port.receive_broadcast_response(out) {
                    r?;
                }
            }
        }
    }
    Ok(())
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

/// CPU time a thread clock counted over `work` (zero when it cannot be
/// read).
fn cpu_over<T>(clock: Option<ThreadCpuClock>, work: impl FnOnce() -> T) -> (T, Duration) {
    let before = clock.and_then(|c| c.now());
    let out = work();
    let after = clock.and_then(|c| c.now());
    let spent = match (before, after) {
        (Some(a), Some(b)) => b.saturating_sub(a),
        _ => Duration::ZERO,
    };
    (out, spent)
}

/// What one wait mode of a UDP point measured.
#[derive(Debug, Clone)]
pub(super) struct ModeRun {
    pub wait: WaitMode,
    pub protocol: Protocol,
    /// Broadcast groups (0: a sequential protocol).
    pub groups: usize,
    pub boards: usize,
    pub note: Option<String>,
    pub io: Percentiles,
    pub read: f64,
    pub write: f64,
    pub cycles: u64,
    pub errors: u64,
    pub floor: Percentiles,
    pub floor_errors: u64,
    /// Per cycle, us.
    pub host_cpu: f64,
    /// Per cycle, us.
    pub floor_host_cpu: f64,
    /// Per cycle.
    pub socket_calls: f64,
    /// Per cycle, us.
    pub emulator_cpu: Option<f64>,
    /// The floor responder's thread, per floor cycle, us.
    pub floor_server_cpu: Option<f64>,
}

/// A datagram port the benchmark drives: its read time-out can be set and
/// its socket's system calls are counted.
pub(super) trait DatagramPort: Port {
    /// Set every read's time-out.
    fn set_read_timeout(&mut self, timeout: Duration);
    /// The system calls made on its socket so far.
    fn socket_calls(&self) -> SocketCalls;
}

impl DatagramPort for UdpPort {
    fn set_read_timeout(&mut self, timeout: Duration) {
        self.set_timeout(timeout);
    }
    fn socket_calls(&self) -> SocketCalls {
        UdpPort::socket_calls(self)
    }
}

impl DatagramPort for EthPort {
    fn set_read_timeout(&mut self, timeout: Duration) {
        self.set_timeout(timeout);
    }
    fn socket_calls(&self) -> SocketCalls {
        EthPort::socket_calls(self)
    }
}

/// CPU time an emulator's server thread has used so far (`None`: no
/// emulator in this process, or thread clocks cannot be read).
pub(super) type ServerCpu<'a> = &'a dyn Fn() -> Option<Duration>;

/// One wait mode's side of a point while it runs.
pub(super) struct Side<P: DatagramPort> {
    wait: WaitMode,
    protocol: Protocol,
    groups: usize,
    boards: usize,
    note: Option<String>,
    io: IoSystem<Recorder<P>>,
    floor: P,
    script: Vec<Step>,
    times: Vec<f32>,
    floor_times: Vec<f32>,
    read: f64,
    write: f64,
    host_cpu: Duration,
    floor_host_cpu: Duration,
    floor_errors: u64,
    socket_calls: u64,
    emulator_cpu: Option<Duration>,
    floor_server_cpu: Option<Duration>,
}

/// Where the boards of a UDP point are.
pub(super) struct Bridge<'a> {
    /// Their address.
    pub addr: SocketAddr,
    /// The in-process emulator serving them, whose CPU is measured.
    pub emulator: Option<&'a rig::Emulator>,
}

/// How a side runs: its wait mode, host wait and protocol, the benchmark's options,
/// the idle time between cycles.
pub(super) struct SideSettings<'a> {
    pub wait: WaitMode,
    /// How long the host waits after each broadcast query.
    pub host_wait: super::HostWait,
    pub protocol: Protocol,
    pub options: &'a super::BenchOptions,
    pub idle: Duration,
}

impl<P: DatagramPort> Side<P> {
    /// Scan through `port`, warm up, record one cycle's calls and warm the
    /// floor (`floor`: the same kind of port to `responder`) up on them.
    pub(super) fn open(
        port: P,
        floor: P,
        responder: &Responder,
        settings: &SideSettings<'_>,
        server_cpu: ServerCpu<'_>,
    ) -> Result<Side<P>, TestbedError> {
        let idle = settings.idle;
        let mut port = Recorder::new(port);
        // A busy machine must not hide a board from the scan; the cycles
        // then have the servo time-out.
        port.inner.set_read_timeout(SCAN_TIMEOUT);
        let scan = firelink_host::qla::scan::scan(&mut port);
        port.inner.set_read_timeout(settings.options.udp_timeout);
        let scan = scan?;
        let plan = super::Plan::of(&scan, settings.protocol, settings.options);
        let (used, groups, note) = (plan.protocol, plan.groups, plan.note.clone());
        let boards = scan.boards.len();
        let mut io = IoSystem::with_scan(port, &scan, plan.options_with(settings.host_wait))?;
        for _ in 0..WARM_UP {
            io.cycle();
            io.port_mut().wait(idle);
        }
        // One cycle's calls: the floor's script.
        io.port_mut().script = Some(Vec::new());
        io.cycle();
        let script = io.port_mut().script.take().unwrap_or_default();
        io.port_mut().wait(idle);
        if let Some(&Step::BroadcastResponse(len)) = script
            .iter()
            .find(|s| matches!(s, Step::BroadcastResponse(_)))
        {
            responder.answer_queries_with(len);
        }
        let mut floor = floor;
        floor.set_read_timeout(settings.options.udp_timeout);
        let mut buf = vec![0u8; 2048];
        for _ in 0..WARM_UP {
            let _ = replay(&mut floor, &script, &mut buf);
            floor.wait(idle);
        }
        Ok(Side {
            wait: settings.wait,
            protocol: used,
            groups,
            boards,
            note,
            io,
            floor,
            script,
            times: Vec::new(),
            floor_times: Vec::new(),
            read: 0.0,
            write: 0.0,
            host_cpu: Duration::ZERO,
            floor_host_cpu: Duration::ZERO,
            floor_errors: 0,
            socket_calls: 0,
            emulator_cpu: server_cpu().map(|_| Duration::ZERO),
            floor_server_cpu: responder.cpu_time().map(|_| Duration::ZERO),
        })
    }

    /// `n` of the point's own cycles.
    fn own_block(
        &mut self,
        n: u64,
        idle: Duration,
        host: Option<ThreadCpuClock>,
        server_cpu: ServerCpu<'_>,
    ) {
        let calls = self.io.port().inner.socket_calls();
        let emulator_before = server_cpu();
        for _ in 0..n {
            let (report, cpu) = cpu_over(host, || *self.io.cycle());
            self.host_cpu += cpu;
            let _ = self.io.recover();
            self.times.push(us(report.io_time()) as f32);
            self.read += us(report.read_time);
            self.write += us(report.write_time);
            self.io.port_mut().wait(idle);
        }
        let emulator_after = server_cpu();
        self.emulator_cpu = match (self.emulator_cpu, emulator_before, emulator_after) {
            (Some(total), Some(a), Some(b)) => Some(total + b.saturating_sub(a)),
            _ => None,
        };
        let now = self.io.port().inner.socket_calls();
        self.socket_calls += now.since(&calls).total();
    }

    /// `n` of the floor's cycles.
    fn floor_block(
        &mut self,
        n: u64,
        idle: Duration,
        host: Option<ThreadCpuClock>,
        responder: &Responder,
        buf: &mut [u8],
    ) {
        let server_before = responder.cpu_time();
        for _ in 0..n {
            let ((took, ok), cpu) = cpu_over(host, || {
                let started = Instant::now();
                let ok = replay(&mut self.floor, &self.script, buf).is_ok();
                (started.elapsed(), ok)
            });
            self.floor_host_cpu += cpu;
            self.floor_errors += u64::from(!ok);
            self.floor_times.push(us(took) as f32);
            self.floor.wait(idle);
        }
        let server_after = responder.cpu_time();
        self.floor_server_cpu = match (self.floor_server_cpu, server_before, server_after) {
            (Some(total), Some(a), Some(b)) => Some(total + b.saturating_sub(a)),
            _ => None,
        };
    }

    fn finish(mut self) -> ModeRun {
        let cycles = self.times.len().max(1) as u64;
        let per = |d: Duration| us(d) / cycles as f64;
        let floor_cycles = self.floor_times.len().max(1);
        ModeRun {
            wait: self.wait,
            protocol: self.protocol,
            groups: self.groups,
            boards: self.boards,
            note: self.note,
            io: Percentiles::of(&mut self.times),
            read: self.read / cycles as f64,
            write: self.write / cycles as f64,
            cycles,
            errors: self.io.stats().total_errors(),
            floor: Percentiles::of(&mut self.floor_times),
            floor_errors: self.floor_errors,
            host_cpu: per(self.host_cpu),
            floor_host_cpu: per(self.floor_host_cpu),
            socket_calls: self.socket_calls as f64 / cycles as f64,
            emulator_cpu: self.emulator_cpu.map(per),
            floor_server_cpu: self.floor_server_cpu.map(|d| us(d) / floor_cycles as f64),
        }
    }
}

/// Run the measured cycles of `sides` with their floors, interleaved in
/// blocks of [`BLOCK`] cycles, every side in turn.
pub(super) fn run_sides<P: DatagramPort>(
    mut sides: Vec<Side<P>>,
    responder: &Responder,
    options: &super::BenchOptions,
    server_cpu: ServerCpu<'_>,
) -> Vec<ModeRun> {
    let idle = idle_time(options);
    let host = ThreadCpuClock::current();
    let cycles = options.cycles.max(1);
    let mut buf = vec![0u8; 2048];
    let mut done = 0;
    while done < cycles {
        let n = BLOCK.min(cycles - done);
        for side in &mut sides {
            side.own_block(n, idle, host, server_cpu);
            side.floor_block(n, idle, host, responder, &mut buf);
        }
        done += n;
    }
    sides.into_iter().map(Side::finish).collect()
}

/// The idle time between cycles.
pub(super) fn idle_time(options: &super::BenchOptions) -> Duration {
    Duration::from_secs_f64(options.idle_us.max(0.0) / 1e6)
}

/// Measure one UDP point (a protocol on the boards at `bridge`) for each
/// wait mode of `options`, with its floor, interleaved in blocks.
pub(super) fn measure_point(
    bridge: &Bridge<'_>,
    protocol: Protocol,
    options: &super::BenchOptions,
    host_wait: super::HostWait,
) -> Result<Vec<ModeRun>, TestbedError> {
    let responder = Responder::start()?;
    let mut waits = options.udp_waits.clone();
    if waits.is_empty() {
        waits.push(WaitMode::default());
    }
    let server_cpu = || bridge.emulator.and_then(rig::Emulator::server_cpu_time);
    let mut sides = Vec::with_capacity(waits.len());
    for &wait in &waits {
        let settings = SideSettings {
            wait,
            host_wait,
            protocol,
            options,
            idle: idle_time(options),
        };
        let port = rig::udp_port_with(bridge.addr, wait)?;
        let floor = rig::udp_port_with(responder.addr, wait)?;
        sides.push(Side::open(port, floor, &responder, &settings, &server_cpu)?);
    }
    let runs = run_sides(sides, &responder, options, &server_cpu);
    drop(responder);
    Ok(runs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::bridge::ControlWord;
    use firelink_wire::packet::{AsyncHeader, NodeId, Packet};

    fn request(repr: &PacketRepr<'_>) -> Vec<u8> {
        let mut out = vec![0u8; 2 + repr.buffer_len()];
        out[..2].copy_from_slice(&ControlWord::default().to_bytes());
        repr.emit(&mut out[2..]).unwrap();
        out
    }

    /// The floor answers a read with a response of the size asked, with
    /// good CRCs and the extra data; writes and garbage get nothing.
    #[test]
    fn the_floor_answers_reads_of_any_size_and_nothing_else() {
        let header = AsyncHeader::new(NodeId::local(3), NodeId(0xFFD0), 7);
        let mut reply = vec![0u8; 4096];
        for len in [4usize, 268, 2048] {
            let req = request(&PacketRepr::ReadBlockRequest {
                header,
                offset: 0x1000,
                data_length: len as u16,
                extended_tcode: 0,
            });
            let n = floor_answer(&req, &mut reply, 0).unwrap();
            assert_eq!(n, 20 + len + 4 + 8);
            let packet = Packet::new_checked(&reply[..n - 8]).unwrap();
            assert!(packet.verify().is_ok());
            assert_eq!(packet.tl(), 7);
        }
        let q = request(&PacketRepr::ReadQuadletRequest { header, offset: 4 });
        assert_eq!(floor_answer(&q, &mut reply, 0), Some(20 + 8));
        let w = request(&PacketRepr::WriteQuadletRequest {
            header,
            offset: 0x1800,
            data: 1,
        });
        assert_eq!(floor_answer(&w, &mut reply, 0), None);
        assert_eq!(floor_answer(&[0xFF; 3], &mut reply, 0), None);
        // A broadcast query: nothing on the bridge; the hub's unsolicited
        // block on the Ethernet-only network, under the query's label.
        let query = request(&PacketRepr::WriteQuadletRequest {
            header: AsyncHeader::new(NodeId::local(63), NodeId(0xFFD0), 9),
            offset: 0x1800,
            data: 0x0001_000F,
        });
        assert_eq!(floor_answer(&query, &mut reply, 0), None);
        let n = floor_answer(&query, &mut reply, 4 * 133).unwrap();
        assert_eq!(n, 20 + 4 * 133 + 4 + 8);
        let packet = Packet::new_checked(&reply[..n - 8]).unwrap();
        assert!(packet.verify().is_ok());
        assert_eq!(packet.tl(), 9);
        // A write elsewhere is still not answered.
        assert_eq!(floor_answer(&w, &mut reply, 4 * 133), None);
        // A length beyond any block: no answer, no panic.
        let mut big = request(&PacketRepr::ReadBlockRequest {
            header,
            offset: 0,
            data_length: 2048,
            extended_tcode: 0,
        });
        big[2 + 12] = 0xFF;
        let _ = floor_answer(&big, &mut reply, 0);
    }
}
