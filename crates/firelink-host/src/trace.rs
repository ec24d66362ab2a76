//! A port that records what goes through it: [`TracingPort`] wraps any
//! [`Port`] (the simulated bus, the UDP bridge, another wrapper) and keeps
//! one [`CallRecord`] per call, with the port's clock before and after it.
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
//! # }
//! ```

use std::time::Duration;

use crate::error::{HostError, Result};
use crate::port::{Dest, Port};
use crate::transaction::LinkStats;

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

/// A [`Port`] that records every call of the port it wraps. See the module
/// docs.
pub struct TracingPort<P: Port> {
    inner: P,
    calls: Vec<CallRecord>,
}

impl CallRecord {
    /// How long the call took on the port's clock.
    pub fn duration(&self) -> Duration {
        Duration::from_nanos(self.finished_ps.saturating_sub(self.started_ps) / 1000)
    }
}

impl<P: Port> TracingPort<P> {
    /// Wrap `inner`.
    pub fn new(inner: P) -> TracingPort<P> {
        TracingPort {
            inner,
            calls: Vec::new(),
        }
    }

    /// Every call so far, oldest first.
    pub fn calls(&self) -> &[CallRecord] {
        &self.calls
    }

    /// Forget the calls recorded so far.
    pub fn clear(&mut self) {
        self.calls.clear();
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

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.inner.candidate_nodes()
    }
}
