//! The simulated port: the host and the emulated boards share one simulated
//! 1394 bus in virtual time.
//!
//! Each transaction goes through the PC's link node ([`HostLink`]) on the
//! bus, so it pays real arbitration, gaps, transmission and ack times. The
//! optional [`HostModel`] adds the PC's per-call software overhead around
//! PC-initiated transactions (seed 000's measured 32 us reads and 34 us
//! writes by default), which is what makes the simulated I/O times comparable
//! with the papers' PC-side measurements.
//!
//! Blocking calls (reads, unicast writes) return when the transaction
//! completes; broadcast writes return after the call overhead, as the
//! non-blocking `raw1394_start_write` of seed 000 does, while the packet goes
//! out on the bus behind them (or, with
//! [`SimPort::with_blocking_broadcasts`], once the packet has gone out).
//!
//! The overhead model is anything implementing [`CallOverhead`]: seed 000's
//! [`HostModel`], or a model of another computer and operating system (seed
//! 002's real-time Linux variants live in [`crate::mahru`]).
//! [`SimPort::last_call`] gives the instants of the last call: when it was
//! made, when its request reached the link, when the ack and the answer
//! came and when it returned.

use std::time::Duration;

use firelink_bus::host::{CallCost, Completion, HostCall, Outcome, Transfer};
use firelink_bus::{Bus, HostLink, HostModel, NodeHandle, SimDuration, SimTime};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Speed};

use crate::error::{HostError, Result};
use crate::link_stats::LinkStats;
use crate::port::{Dest, LinkFilter, LinkFilters, Port, Verdict};
use crate::transaction::{CrcCheck, Expect, Refusal, Transactions};

/// Source node ID is the PC's own node (whatever its physical ID).
fn pc_node(phy: u8) -> NodeId {
    NodeId::local(phy)
}

/// The PC's software cost around one library call, as a host port
/// charges it: before the request reaches the link, and after the
/// transaction finished until the call returns.
pub trait CallOverhead: Send {
    /// The cost of one `call` moving `transfer` (a fresh draw for models
    /// with jitter).
    fn cost(&mut self, call: HostCall, transfer: Transfer) -> CallCost;
}

impl CallOverhead for HostModel {
    fn cost(&mut self, call: HostCall, transfer: Transfer) -> CallCost {
        self.cost_of(call, transfer)
    }
}

/// The instants of one call on a [`SimPort`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CallTiming {
    /// The call was made.
    pub called: SimTime,
    /// Its request reached the PC's link.
    pub submitted: SimTime,
    /// The ack arrived (a unicast request), or the broadcast went out.
    pub acked: Option<SimTime>,
    /// The transaction finished at the link (the response, for a read).
    pub completed: Option<SimTime>,
    /// The call returned.
    pub returned: SimTime,
}

/// A [`Port`] on a simulated bus.
pub struct SimPort {
    bus: Bus,
    host: NodeHandle,
    model: Option<Box<dyn CallOverhead>>,
    blocking_broadcasts: bool,
    last_call: Option<CallTiming>,
    transactions: Transactions,
    speed: Speed,
    broadcast_speed: Speed,
    timeout: SimDuration,
    out: Vec<u8>,
    filters: LinkFilters,
    /// A copy of each packet overheard, for the filters.
    overheard: Vec<u8>,
}

impl SimPort {
    /// A port using the [`HostLink`] node `host` of `bus`. The bus should
    /// have been reset (nodes numbered) already.
    pub fn new(bus: Bus, host: NodeHandle) -> SimPort {
        let transactions = Transactions::with_generation(bus.generation());
        SimPort {
            bus,
            host,
            model: None,
            blocking_broadcasts: false,
            last_call: None,
            transactions,
            speed: Speed::S400,
            broadcast_speed: Speed::S400,
            timeout: SimDuration::from_micros(20_000),
            out: vec![0; 4096],
            filters: LinkFilters::default(),
            overheard: Vec::with_capacity(4096),
        }
    }

    /// Add the PC software overhead model.
    pub fn with_host_model(mut self, model: HostModel) -> SimPort {
        self.model = Some(Box::new(model));
        self
    }

    /// Add another computer's overhead model.
    pub fn with_overhead(mut self, model: impl CallOverhead + 'static) -> SimPort {
        self.model = Some(Box::new(model));
        self
    }

    /// Wait at most `timeout` for a transaction to finish (default 20 ms).
    pub fn with_timeout(mut self, timeout: Duration) -> SimPort {
        self.timeout = SimDuration::from_micros_f64(timeout.as_secs_f64() * 1e6);
        self
    }

    /// Broadcast writes wait until the packet has gone out on the bus (and
    /// then pay the call's `after` cost), as a driver that reports the
    /// transmit completion does.
    pub fn with_blocking_broadcasts(mut self) -> SimPort {
        self.blocking_broadcasts = true;
        self
    }

    /// The instants of the last call that reached the link.
    pub fn last_call(&self) -> Option<CallTiming> {
        self.last_call
    }

    /// Speed of broadcast packets (seed 000 patched the driver for S400;
    /// stock drivers send broadcasts at S100).
    pub fn with_broadcast_speed(mut self, speed: Speed) -> SimPort {
        self.broadcast_speed = speed;
        self
    }

    /// Speed of every packet the PC sends, broadcasts included (S400 by
    /// default).
    pub fn with_speed(mut self, speed: Speed) -> SimPort {
        self.speed = speed;
        self.broadcast_speed = speed;
        self
    }

    /// The bus, for inspection (trace, fault log, nodes).
    pub fn bus(&self) -> &Bus {
        &self.bus
    }

    /// The bus, mutable (faults, topology changes, running it forward).
    pub fn bus_mut(&mut self) -> &mut Bus {
        &mut self.bus
    }

    /// The PC's node on the bus.
    pub fn host(&self) -> NodeHandle {
        self.host
    }

    /// The PC's link node (open and finished transactions, packets kept).
    pub fn host_link(&self) -> Option<&HostLink> {
        self.bus.node::<HostLink>(self.host)
    }

    /// What the PC's link sent and received, refusals by reason.
    pub fn stats(&self) -> LinkStats {
        self.transactions.stats()
    }

    fn host_phy(&self) -> u8 {
        self.bus.phy_id(self.host).unwrap_or(0)
    }

    /// Run one transaction: the request goes through the PC's link and the
    /// engine judges what came back. Returns the response packet of reads.
    fn transact(
        &mut self,
        expect: Expect,
        repr: PacketRepr<'_>,
        call: HostCall,
    ) -> Result<Option<Vec<u8>>> {
        self.transactions.observe_generation(self.bus.generation());
        self.transactions.check_generation(expect.dest)?;
        let (len, sealed) = self.emit(&repr)?;
        let called = self.bus.now();
        let cost = self
            .model
            .as_mut()
            .map(|m| m.cost(call, Transfer::of(&repr)));
        if let Some(c) = cost {
            self.bus.run_for(c.before);
        }
        let Some(token) = self.submit(len, sealed, &expect)? else {
            // Lost on the way: nobody answers.
            if call == HostCall::BroadcastWrite {
                return Ok(None);
            }
            return Err(self.wait_out(&expect, self.bus.now()));
        };
        let submitted = self.bus.now();
        let blocking = self.blocking_broadcasts && expect.dest.is_broadcast();
        if call == HostCall::BroadcastWrite && !blocking {
            // Non-blocking (a broadcast, or a write started without
            // waiting): the packet goes out while the caller goes on, and
            // nobody will take its completion.
            if let Some(l) = self.bus.node_mut::<HostLink>(self.host) {
                l.abandon(token);
            }
            self.last_call = Some(CallTiming {
                called,
                submitted,
                acked: None,
                completed: None,
                returned: submitted,
            });
            return Ok(None);
        }
        let submitted_generation = self.bus.generation();
        let deadline = submitted + self.timeout;
        let completion = HostLink::wait_on(&mut self.bus, self.host, token, deadline);
        if let Some(c) = cost {
            self.bus.run_for(c.after);
        }
        self.last_call = Some(CallTiming {
            called,
            submitted,
            acked: completion.as_ref().and_then(|c| c.acked_at),
            completed: completion.as_ref().map(|c| c.completed_at),
            returned: self.bus.now(),
        });
        // A request lost in a bus reset failed because of the reset: say
        // so (node numbers may have moved), not "no answer".
        if self.bus.generation() != submitted_generation
            && !completion
                .as_ref()
                .is_some_and(|c| c.outcome == Outcome::Complete)
        {
            self.transactions.observe_generation(self.bus.generation());
            self.transactions.check_generation(expect.dest)?;
        }
        let Some(done) = completion else {
            let waited = (self.bus.now() - submitted).as_micros_f64() as u32;
            return Err(self.transactions.timed_out(&expect, waited));
        };
        self.judge(&expect, done, submitted)
    }

    /// Hand a response the port is done with back to the PC's link, whose
    /// next received packet reuses its memory (no allocation per read).
    fn recycle(&mut self, response: Vec<u8>) {
        if let Some(link) = self.bus.node_mut::<HostLink>(self.host) {
            link.recycle(response);
        }
    }

    /// The request `repr` into the port's packet buffer; returns its
    /// length and whether its CRCs are left for the bus to write (a read
    /// or write request while no outgoing filter is there to see the
    /// bytes: [`PacketRepr::emit_unsealed`]).
    fn emit(&mut self, repr: &PacketRepr<'_>) -> Result<(usize, bool)> {
        let len = repr.buffer_len();
        if self.out.len() < len {
            self.out.resize(len, 0);
        }
        let buf = self.out.get_mut(..len).ok_or(HostError::InvalidRequest {
            what: "packet size",
            value: len as u32,
        })?;
        if self.filters.is_empty() && is_request(repr) {
            repr.emit_unsealed(buf)?;
            return Ok((len, true));
        }
        repr.emit(buf)?;
        Ok((len, false))
    }

    /// Hand the request in the packet buffer (`len` bytes) to the PC's
    /// link, through the outgoing filters: its token, or `None` when a
    /// filter lost it. A `sealed` request's CRCs are written by the bus
    /// ([`HostLink::submit_sealed`]).
    fn submit(&mut self, len: usize, sealed: bool, expect: &Expect) -> Result<Option<u64>> {
        let now_ps = self.bus.now().0;
        let buf = self.out.get_mut(..len).ok_or(HostError::InvalidRequest {
            what: "packet size",
            value: len as u32,
        })?;
        if self.filters.outgoing(now_ps, buf) == Verdict::Drop {
            self.transactions.sent();
            return Ok(None);
        }
        // The link copies the packet into its FIFO (the simulated
        // hardware's memory): this port allocates nothing per packet.
        let speed = if expect.dest.is_broadcast() {
            self.broadcast_speed
        } else {
            self.speed
        };
        let host = self.host;
        let submitted = if sealed {
            HostLink::submit_sealed_on(&mut self.bus, host, buf, speed)
        } else {
            HostLink::submit_on(&mut self.bus, host, buf, speed)
        };
        let token = submitted.map_err(|_| HostError::InvalidRequest {
            what: "the simulated bus has no host link",
            value: host.0 as u32,
        })?;
        self.transactions.sent();
        Ok(Some(token))
    }

    /// What the link says of the transaction `expect`, submitted at
    /// `submitted`: the read's response, the engine's verdict on it, or
    /// the error that ended it.
    fn judge(
        &mut self,
        expect: &Expect,
        done: Completion,
        submitted: SimTime,
    ) -> Result<Option<Vec<u8>>> {
        match done.outcome {
            Outcome::Complete | Outcome::ResponseCorrupt => {}
            Outcome::NoAck | Outcome::ResponseTimeout => {
                let waited = (done.completed_at - done.submitted_at).as_micros_f64() as u32;
                return Err(self.transactions.timed_out(expect, waited));
            }
            Outcome::Busy | Outcome::AckError => {
                return Err(HostError::Ack {
                    node: expect.dest.node,
                    ack: done.ack.unwrap_or(Ack::Unknown(0)),
                });
            }
            Outcome::BusReset => {
                self.transactions.observe_generation(done.generation);
                self.transactions.check_generation(expect.dest)?;
                return Err(HostError::BusReset {
                    old: done.generation,
                    new: done.generation,
                });
            }
        }
        let Some(mut response) = done.response else {
            // A unicast write: ack_complete is its answer.
            return Ok(None);
        };
        if self.filters.incoming(self.bus.now().0, &mut response) == Verdict::Drop {
            return Err(self.wait_out(expect, submitted));
        }
        // The engine checks what the link matched: CRCs (a damaged
        // response fails with the CRCs it carries and should carry), tcode,
        // size and rcode. A complete transaction's response passed the
        // link's CRC check (a header CRC error drops it, a data CRC error
        // makes it corrupt): unless a filter could have changed its bytes
        // since, its CRCs are known good.
        let crc = if done.outcome == Outcome::Complete && self.filters.is_empty() {
            CrcCheck::KnownGood
        } else {
            CrcCheck::Always
        };
        match self.transactions.accept(&response, expect, crc)? {
            Ok(_) => Ok(Some(response)),
            Err(refusal) => Err(refusal_error(refusal, expect)),
        }
    }

    /// A write to `dest` as library call `call`: `request` builds the
    /// packet from its header.
    fn write<'a>(
        &mut self,
        dest: Dest,
        call: HostCall,
        request: impl FnOnce(AsyncHeader) -> PacketRepr<'a>,
    ) -> Result<()> {
        let header = self.header(dest);
        self.transact(Expect::write(dest, header.tl), request(header), call)?;
        Ok(())
    }

    fn quadlet_write(&mut self, dest: Dest, offset: u64, value: u32, call: HostCall) -> Result<()> {
        self.write(dest, call, |header| PacketRepr::WriteQuadletRequest {
            header,
            offset,
            data: value,
        })
    }

    fn block_write(&mut self, dest: Dest, offset: u64, data: &[u8], call: HostCall) -> Result<()> {
        crate::port::check_block(data.len())?;
        self.write(dest, call, |header| PacketRepr::WriteBlockRequest {
            header,
            offset,
            extended_tcode: 0,
            data,
        })
    }

    /// The answer to `expect`, asked at `since`, is lost: the host waits
    /// out its time-out and says so.
    fn wait_out(&mut self, expect: &Expect, since: SimTime) -> HostError {
        let deadline = since + self.timeout;
        self.bus.run_until(deadline);
        let waited = (self.bus.now() - since).as_micros_f64() as u32;
        self.transactions.timed_out(expect, waited)
    }

    fn header(&mut self, dest: Dest) -> AsyncHeader {
        let tl = self.transactions.next_label();
        AsyncHeader::new(NodeId::local(dest.node), pc_node(self.host_phy()), tl)
    }
}

/// The link matched a response the engine refuses: say what was wrong.
fn refusal_error(refusal: Refusal, expect: &Expect) -> HostError {
    match refusal {
        Refusal::Garbage(e) | Refusal::BadCrc(e) => HostError::Wire(e),
        Refusal::Late { tl } | Refusal::Unmatched { tl } => {
            HostError::Wire(firelink_wire::Error::Malformed {
                what: if tl == expect.tl {
                    "response (tcode or size does not answer the request)"
                } else {
                    "response (another transaction label)"
                },
                value: u32::from(tl),
            })
        }
    }
}

/// The library call a write to `dest` is: a broadcast cannot be
/// acknowledged, so it returns once sent (`raw1394_start_write`).
fn write_call(dest: Dest) -> HostCall {
    if dest.is_broadcast() {
        HostCall::BroadcastWrite
    } else {
        HostCall::Write
    }
}

fn sim_duration(d: Duration) -> SimDuration {
    SimDuration::from_micros_f64(d.as_secs_f64() * 1e6)
}

/// A read with label `tl` finished without its response.
fn no_response(tl: u8) -> HostError {
    HostError::Wire(firelink_wire::Error::Malformed {
        what: "read completed without a response",
        value: u32::from(tl),
    })
}

impl Port for SimPort {
    fn name(&self) -> &str {
        "sim"
    }

    /// The bus counts what ran at which level of detail cycle by cycle
    /// ([`Bus::begin_cycle`]).
    fn begin_cycle(&mut self) {
        self.bus.begin_cycle();
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        crate::port::refuse_broadcast_read(dest)?;
        let header = self.header(dest);
        let response = self.transact(
            Expect::quadlet(dest, header.tl),
            PacketRepr::ReadQuadletRequest { header, offset },
            HostCall::Read,
        )?;
        let response = response.ok_or(no_response(header.tl))?;
        let value = Packet::new_unchecked(&response[..]).quadlet_data();
        self.recycle(response);
        Ok(value)
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.quadlet_write(dest, offset, value, write_call(dest))
    }

    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.quadlet_write(dest, offset, value, HostCall::BroadcastWrite)
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        crate::port::check_block(out.len())?;
        crate::port::refuse_broadcast_read(dest)?;
        let header = self.header(dest);
        let response = self.transact(
            Expect::block(dest, header.tl, out.len()),
            PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: out.len() as u16,
                extended_tcode: 0,
            },
            HostCall::Read,
        )?;
        let response = response.ok_or(no_response(header.tl))?;
        let payload = Packet::new_unchecked(&response[..]).payload();
        if payload.len() != out.len() {
            return Err(HostError::Wire(firelink_wire::Error::BlockSize {
                what: "read response",
                expected: out.len() / 4,
                found: payload.len() / 4,
            }));
        }
        out.copy_from_slice(payload);
        self.recycle(response);
        Ok(())
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.block_write(dest, offset, data, write_call(dest))
    }

    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.block_write(dest, offset, data, HostCall::BroadcastWrite)
    }

    fn wait(&mut self, duration: Duration) {
        self.bus.run_for(sim_duration(duration));
    }

    fn wait_until_heard(&mut self, limit: Duration, heard: &mut dyn FnMut(&[u8]) -> bool) -> bool {
        let deadline = self.bus.now() + sim_duration(limit);
        let host = self.host;
        let mut seen = self.host_link().map_or(0, HostLink::received_total);
        let mut done = false;
        let SimPort {
            bus,
            filters,
            overheard,
            ..
        } = self;
        bus.run_until_with(deadline, |bus| {
            let Some(link) = bus.node::<HostLink>(host) else {
                return true;
            };
            let total = link.received_total();
            let new = usize::try_from(total.saturating_sub(seen)).unwrap_or(usize::MAX);
            seen = total;
            // Oldest first; the link keeps the most recent packets only.
            let kept = link.received().len();
            for r in link.received().skip(kept.saturating_sub(new)) {
                if filters.is_empty() {
                    done = done || heard(&r.bytes);
                    continue;
                }
                overheard.clear();
                overheard.extend_from_slice(&r.bytes);
                if filters.incoming(r.at.0, overheard) == Verdict::Pass {
                    done = done || heard(overheard);
                }
            }
            done
        });
        if !done {
            self.bus.run_until(deadline);
        }
        done
    }

    fn now(&self) -> Duration {
        let SimTime(ps) = self.bus.now();
        Duration::from_nanos(ps / 1000)
    }

    fn now_ps(&self) -> u64 {
        self.bus.now().0
    }

    fn generation(&self) -> u32 {
        self.transactions.generation()
    }

    fn link_stats(&self) -> LinkStats {
        self.transactions.stats()
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        // The PC is the root with the highest physical ID; boards are below.
        0..self.host_phy()
    }

    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        self.filters.add(filter);
        Ok(())
    }

    fn takes_link_filters(&self) -> bool {
        true
    }
}

/// Whether `repr` is a read or write request: what the port leaves for
/// the bus to seal ([`HostLink::submit_sealed`]).
fn is_request(repr: &PacketRepr<'_>) -> bool {
    matches!(
        repr,
        PacketRepr::WriteQuadletRequest { .. }
            | PacketRepr::WriteBlockRequest { .. }
            | PacketRepr::ReadQuadletRequest { .. }
            | PacketRepr::ReadBlockRequest { .. }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The port leaves exactly the read and write requests for the bus to
    /// seal (the bytes: `PacketRepr::emit_unsealed`'s own test).
    #[test]
    fn only_requests_are_left_for_the_bus_to_seal() {
        let header = AsyncHeader::new(NodeId::local(3), NodeId::local(0), 17);
        let rcode = firelink_wire::packet::Rcode::Complete;
        let sealed_by_the_bus = [
            PacketRepr::WriteQuadletRequest {
                header,
                offset: 0,
                data: 1,
            },
            PacketRepr::WriteBlockRequest {
                header,
                offset: 0,
                extended_tcode: 0,
                data: &[1, 2, 3, 4],
            },
            PacketRepr::ReadQuadletRequest { header, offset: 4 },
            PacketRepr::ReadBlockRequest {
                header,
                offset: 0x1000,
                data_length: 24,
                extended_tcode: 0,
            },
        ];
        assert!(sealed_by_the_bus.iter().all(is_request));
        let others = [
            PacketRepr::WriteResponse { header, rcode },
            PacketRepr::ReadQuadletResponse {
                header,
                rcode,
                data: 0,
            },
            PacketRepr::ReadBlockResponse {
                header,
                rcode,
                extended_tcode: 0,
                data: &[],
            },
        ];
        assert!(!others.iter().any(is_request));
    }
}
