//! A port that records what goes through it: [`TracingPort`] wraps any
//! [`Port`] (the simulated bus, the UDP bridge, another wrapper) and keeps
//! one [`CallRecord`] per call, with the port's clock before and after it,
//! and every 1394 packet the port sent and received
//! ([`CapturedPacket`], through the port's [link filters](LinkFilter)),
//! which [`TracingPort::write_pcap`] saves for Wireshark or for a replay
//! test ([`crate::replay`]). [`PcapWriter`] streams the packets of a long
//! run straight to a file instead.
//!
//! Recording is for understanding and testing, not for the real-time path:
//! the capture takes a lock and allocates per packet.
//!
//! ```
//! # #[cfg(feature = "sim")] {
//! use firelink_host::trace::{CallKind, TracingPort};
//! use firelink_host::{Dest, Port};
//! # let mut bus = firelink_bus::Bus::new(firelink_bus::BusConfig::default());
//! # let pc = bus.add(firelink_bus::HostLink::new("pc"), firelink_bus::NodeConfig::pc());
//! # bus.reset();
//! # let port = firelink_host::sim::SimPort::new(bus, pc);
//! let mut port = TracingPort::new(port);
//! port.wait(std::time::Duration::from_micros(5));
//! // Nobody answers at node 3: the call fails, and the record says so.
//! assert!(port.read_quadlet(Dest::node(3), 0).is_err());
//! let calls = port.calls();
//! assert_eq!(calls[1].kind, CallKind::ReadQuadlet);
//! assert!(calls[1].error.is_some());
//! assert!(calls[1].finished_ps > calls[1].started_ps);
//! // The request went out; no answer came.
//! assert_eq!(port.packets().len(), 1);
//! # }
//! ```

use std::io::{self, Write};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use firelink_wire::packet::Packet;
use firelink_wire::pcap::{self, Direction, RECORD_OVERHEAD};

use crate::error::{HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::{Dest, LinkFilter, Port, Verdict};

/// Which port call a record is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CallKind {
    /// [`Port::read_quadlet`].
    ReadQuadlet,
    /// [`Port::write_quadlet`].
    WriteQuadlet,
    /// [`Port::read_block`].
    ReadBlock,
    /// [`Port::write_block`].
    WriteBlock,
    /// [`Port::start_write_quadlet`].
    StartWriteQuadlet,
    /// [`Port::start_write_block`].
    StartWriteBlock,
    /// [`Port::wait`].
    Wait,
    /// [`Port::wait_until_heard`].
    WaitUntilHeard,
}

/// One call through a [`TracingPort`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CallRecord {
    /// The call.
    pub kind: CallKind,
    /// Where it went (`Dest::BROADCAST` for waits).
    pub dest: Dest,
    /// Its offset (0 for waits).
    pub offset: u64,
    /// Bytes moved (4 for quadlets, 0 for waits).
    pub len: usize,
    /// The port's clock when the call began, picoseconds
    /// ([`Port::now_ps`]).
    pub started_ps: u64,
    /// The port's clock when it returned, picoseconds.
    pub finished_ps: u64,
    /// How it failed, if it did.
    pub error: Option<HostError>,
    /// [`Port::wait_until_heard`]: whether what it waited for was heard.
    pub heard: Option<bool>,
}

/// One packet a port sent or received.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CapturedPacket {
    /// When, on the port's clock, picoseconds.
    pub at_ps: u64,
    /// Which way.
    pub direction: Direction,
    /// The 1394 packet as it left or arrived (after any filter added
    /// before the capture changed it).
    pub bytes: Vec<u8>,
}

/// Write `packets` as a pcap file (the format of [`firelink_wire::pcap`]:
/// the host's side marked, so a replay knows which way each went).
///
/// # Errors
/// I/O errors of `out`.
pub fn write_pcap<'a>(
    packets: impl IntoIterator<Item = &'a CapturedPacket>,
    out: &mut impl Write,
) -> io::Result<()> {
    let mut header = [0u8; pcap::FILE_HEADER_LEN];
    let n = pcap::write_file_header(&mut header).map_err(io::Error::other)?;
    out.write_all(&header[..n])?;
    let mut record = Vec::new();
    for p in packets {
        write_record(&mut record, p.at_ps, p.direction, &p.bytes)?;
        out.write_all(&record)?;
    }
    Ok(())
}

/// One packet's pcap record into `record` (resized): addressed from its
/// header's source to its destination (255 where it has none).
fn write_record(
    record: &mut Vec<u8>,
    at_ps: u64,
    direction: Direction,
    bytes: &[u8],
) -> io::Result<()> {
    let (src, dst) = Packet::new_checked(bytes).map_or((255, 255), |p| {
        (p.source_id().phy(), p.destination_id().phy())
    });
    record.resize(RECORD_OVERHEAD + bytes.len(), 0);
    pcap::write_record(record, at_ps / 1000, direction, src, dst, bytes)
        .map_err(io::Error::other)?;
    Ok(())
}

/// The packets a [`TracingPort`] captured so far, shared with its filter.
type Capture = Arc<Mutex<Vec<CapturedPacket>>>;

/// The link filter of a [`TracingPort`]: copies every packet.
struct CaptureFilter(Capture);

impl LinkFilter for CaptureFilter {
    fn packet(&mut self, at_ps: u64, direction: Direction, packet: &mut [u8]) -> Verdict {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(CapturedPacket {
                at_ps,
                direction,
                bytes: packet.to_vec(),
            });
        Verdict::Pass
    }
}

/// A link filter that writes every packet as a pcap record to a writer as
/// it passes (long runs: nothing is kept in memory). The first write error
/// stops it and is kept ([`PcapWriter::error`]).
pub struct PcapWriter<W: Write + Send> {
    out: W,
    record: Vec<u8>,
    error: Arc<Mutex<Option<io::Error>>>,
}

impl<W: Write + Send> PcapWriter<W> {
    /// Write the pcap file header to `out` and go on with a record per
    /// packet.
    ///
    /// # Errors
    /// Writing the header failed.
    pub fn new(mut out: W) -> io::Result<PcapWriter<W>> {
        write_pcap(&[], &mut out)?;
        Ok(PcapWriter {
            out,
            record: Vec::with_capacity(RECORD_OVERHEAD + 2048),
            error: Arc::new(Mutex::new(None)),
        })
    }

    /// Where the first write error will be kept (check it after the run).
    pub fn error(&self) -> Arc<Mutex<Option<io::Error>>> {
        self.error.clone()
    }
}

impl<W: Write + Send> LinkFilter for PcapWriter<W> {
    fn packet(&mut self, at_ps: u64, direction: Direction, packet: &mut [u8]) -> Verdict {
        let mut error = self.error.lock().unwrap_or_else(PoisonError::into_inner);
        if error.is_none() {
            let written = write_record(&mut self.record, at_ps, direction, packet)
                .and_then(|()| self.out.write_all(&self.record))
                .and_then(|()| self.out.flush());
            if let Err(e) = written {
                *error = Some(e);
            }
        }
        Verdict::Pass
    }
}

/// A [`Port`] that records every call of the port it wraps, and every
/// packet when that port shows them. See the module docs.
pub struct TracingPort<P: Port> {
    inner: P,
    calls: Vec<CallRecord>,
    packets: Option<Capture>,
}

impl CallRecord {
    /// How long the call took on the port's clock.
    pub fn duration(&self) -> Duration {
        Duration::from_nanos(self.finished_ps.saturating_sub(self.started_ps) / 1000)
    }
}

impl<P: Port> TracingPort<P> {
    /// Wrap `inner`: its calls are recorded, and its packets when it
    /// takes link filters ([`captures_packets`](Self::captures_packets)).
    pub fn new(mut inner: P) -> TracingPort<P> {
        let capture = Capture::default();
        let packets = inner
            .add_link_filter(Box::new(CaptureFilter(capture.clone())))
            .ok()
            .map(|()| capture);
        TracingPort {
            inner,
            calls: Vec::new(),
            packets,
        }
    }

    /// Whether packets are captured (the wrapped port shows them).
    pub fn captures_packets(&self) -> bool {
        self.packets.is_some()
    }

    /// Every call so far, oldest first.
    pub fn calls(&self) -> &[CallRecord] {
        &self.calls
    }

    /// Every packet so far, oldest first (a copy).
    pub fn packets(&self) -> Vec<CapturedPacket> {
        self.packets.as_ref().map_or_else(Vec::new, |c| {
            c.lock().unwrap_or_else(PoisonError::into_inner).clone()
        })
    }

    /// Write the packets so far as a pcap file.
    ///
    /// # Errors
    /// I/O errors of `out`.
    pub fn write_pcap(&self, out: &mut impl Write) -> io::Result<()> {
        write_pcap(&self.packets(), out)
    }

    /// Forget the calls and packets recorded so far.
    pub fn clear(&mut self) {
        self.calls.clear();
        if let Some(c) = &self.packets {
            c.lock().unwrap_or_else(PoisonError::into_inner).clear();
        }
    }

    /// The wrapped port.
    pub fn inner(&self) -> &P {
        &self.inner
    }

    /// The wrapped port, mutable (calls made on it directly are not
    /// recorded).
    pub fn inner_mut(&mut self) -> &mut P {
        &mut self.inner
    }

    /// Unwrap.
    pub fn into_inner(self) -> P {
        self.inner
    }

    fn record<T>(
        &mut self,
        kind: CallKind,
        dest: Dest,
        offset: u64,
        len: usize,
        call: impl FnOnce(&mut P) -> Result<T>,
    ) -> Result<T> {
        let started_ps = self.inner.now_ps();
        let result = call(&mut self.inner);
        self.calls.push(CallRecord {
            kind,
            dest,
            offset,
            len,
            started_ps,
            finished_ps: self.inner.now_ps(),
            error: result.as_ref().err().copied(),
            heard: None,
        });
        result
    }
}

impl<P: Port> Port for TracingPort<P> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.record(CallKind::ReadQuadlet, dest, offset, 4, |p| {
            p.read_quadlet(dest, offset)
        })
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.record(CallKind::WriteQuadlet, dest, offset, 4, |p| {
            p.write_quadlet(dest, offset, value)
        })
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        let len = out.len();
        self.record(CallKind::ReadBlock, dest, offset, len, |p| {
            p.read_block(dest, offset, out)
        })
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.record(CallKind::WriteBlock, dest, offset, data.len(), |p| {
            p.write_block(dest, offset, data)
        })
    }

    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.record(CallKind::StartWriteQuadlet, dest, offset, 4, |p| {
            p.start_write_quadlet(dest, offset, value)
        })
    }

    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.record(CallKind::StartWriteBlock, dest, offset, data.len(), |p| {
            p.start_write_block(dest, offset, data)
        })
    }

    fn begin_cycle(&mut self) {
        self.inner.begin_cycle();
    }

    fn end_cycle(&mut self) {
        self.inner.end_cycle();
    }

    fn wait(&mut self, duration: Duration) {
        let _ = self.record(CallKind::Wait, Dest::BROADCAST, 0, 0, |p| {
            p.wait(duration);
            Ok(())
        });
    }

    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        let done = self
            .record(CallKind::WaitUntilHeard, Dest::BROADCAST, 0, 0, |p| {
                Ok(p.wait_until_heard(limit, heard))
            })
            .unwrap_or(false);
        if let Some(last) = self.calls.last_mut() {
            last.heard = Some(done);
        }
        done
    }

    fn receive_broadcast_response(&mut self, out: &mut [u8]) -> Option<Result<()>> {
        self.inner.receive_broadcast_response(out)
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

    fn link_stats(&self) -> LinkStats {
        self.inner.link_stats()
    }

    fn refuses_broadcast_registers(&self) -> bool {
        self.inner.refuses_broadcast_registers()
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.inner.candidate_nodes()
    }

    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        self.inner.add_link_filter(filter)
    }

    fn takes_link_filters(&self) -> bool {
        self.inner.takes_link_filters()
    }
}
