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
//! out on the bus behind them.

use std::time::Duration;

use firelink_bus::host::{HostCall, Outcome};
use firelink_bus::{Bus, HostLink, HostModel, NodeHandle, SimDuration, SimTime};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed, Tcode};

use crate::error::{HostError, Result};
use crate::port::{Dest, Port};

/// Source node ID is the PC's own node (whatever its physical ID).
fn pc_node(phy: u8) -> NodeId {
    NodeId::local(phy)
}

/// Counters of the simulated port.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SimPortStats {
    /// Transactions submitted.
    pub transactions: u64,
    /// Transactions that did not complete.
    pub failed: u64,
    /// Bus resets noticed.
    pub bus_resets: u64,
}

/// A [`Port`] on a simulated bus.
pub struct SimPort {
    bus: Bus,
    host: NodeHandle,
    model: Option<HostModel>,
    tl: u8,
    speed: Speed,
    broadcast_speed: Speed,
    timeout: SimDuration,
    generation: u32,
    stats: SimPortStats,
    out: Vec<u8>,
}

impl SimPort {
    /// A port using the [`HostLink`] node `host` of `bus`. The bus should
    /// have been reset (nodes numbered) already.
    pub fn new(bus: Bus, host: NodeHandle) -> SimPort {
        let generation = bus.generation();
        SimPort {
            bus,
            host,
            model: None,
            tl: 0,
            speed: Speed::S400,
            broadcast_speed: Speed::S400,
            timeout: SimDuration::from_micros(20_000),
            generation,
            stats: SimPortStats::default(),
            out: vec![0; 4096],
        }
    }

    /// Add the PC software overhead model.
    pub fn with_host_model(mut self, model: HostModel) -> SimPort {
        self.model = Some(model);
        self
    }

    /// Speed of broadcast packets (seed 000 patched the driver for S400;
    /// stock drivers send broadcasts at S100).
    pub fn with_broadcast_speed(mut self, speed: Speed) -> SimPort {
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

    /// The PC's link node (open and finished transactions, packets kept).
    pub fn host_link(&self) -> Option<&HostLink> {
        self.bus.node::<HostLink>(self.host)
    }

    /// Counters so far.
    pub fn stats(&self) -> SimPortStats {
        self.stats
    }

    fn host_phy(&self) -> u8 {
        self.bus.phy_id(self.host).unwrap_or(0)
    }

    fn next_tl(&mut self) -> u8 {
        self.tl = (self.tl + 1) & 0x3F;
        self.tl
    }

    fn check_generation(&mut self, dest: Dest) -> Result<()> {
        let now = self.bus.generation();
        if now != self.generation {
            let old = self.generation;
            self.generation = now;
            self.stats.bus_resets += 1;
            if !dest.is_broadcast() {
                return Err(HostError::BusReset { old, new: now });
            }
        }
        Ok(())
    }

    /// Run one transaction; returns the response packet bytes of reads.
    fn transact(&mut self, dest: Dest, repr: PacketRepr<'_>, call: HostCall) -> Result<Vec<u8>> {
        self.check_generation(dest)?;
        let len = repr.buffer_len();
        if self.out.len() < len {
            self.out.resize(len, 0);
        }
        let Some(buf) = self.out.get_mut(..len) else {
            return Err(HostError::InvalidRequest {
                what: "packet size",
                value: len as u32,
            });
        };
        repr.emit(buf)?;
        let packet = buf.to_vec();
        let cost = self.model.as_mut().map(|m| m.cost(call));
        if let Some(c) = cost {
            self.bus.run_for(c.before);
        }
        let speed = if dest.is_broadcast() {
            self.broadcast_speed
        } else {
            self.speed
        };
        let host = self.host;
        let token = HostLink::submit_on(&mut self.bus, host, packet, speed).map_err(|_| {
            HostError::InvalidRequest {
                what: "the simulated bus has no host link",
                value: host.0 as u32,
            }
        })?;
        self.stats.transactions += 1;
        if call == HostCall::BroadcastWrite {
            // Non-blocking: the packet goes out while the caller goes on,
            // and nobody will take its completion.
            if let Some(l) = self.bus.node_mut::<HostLink>(host) {
                l.abandon(token);
            }
            return Ok(Vec::new());
        }
        let deadline = self.bus.now() + self.timeout;
        let completion = HostLink::wait_on(&mut self.bus, host, token, deadline);
        if let Some(c) = cost {
            self.bus.run_for(c.after);
        }
        let node = dest.node;
        let Some(done) = completion else {
            self.stats.failed += 1;
            return Err(HostError::Timeout {
                node,
                tl: 0,
                waited_us: self.timeout.as_micros_f64() as u32,
            });
        };
        let failed = |s: &mut Self, e: HostError| {
            s.stats.failed += 1;
            Err(e)
        };
        match done.outcome {
            Outcome::Complete => {}
            Outcome::NoAck | Outcome::ResponseTimeout => {
                return failed(
                    self,
                    HostError::Timeout {
                        node,
                        tl: done.tl,
                        waited_us: (done.completed_at - done.submitted_at).as_micros_f64() as u32,
                    },
                );
            }
            Outcome::Busy | Outcome::AckError => {
                return failed(
                    self,
                    HostError::Ack {
                        node,
                        ack: done.ack.unwrap_or(Ack::Unknown(0)),
                    },
                );
            }
            Outcome::ResponseCorrupt => {
                return failed(
                    self,
                    HostError::Wire(firelink_wire::Error::DataCrc {
                        carried: 0,
                        computed: 0,
                    }),
                );
            }
            Outcome::BusReset => {
                let old = self.generation;
                self.generation = self.bus.generation();
                self.stats.bus_resets += 1;
                return failed(
                    self,
                    HostError::BusReset {
                        old,
                        new: self.generation,
                    },
                );
            }
        }
        Ok(done.response.unwrap_or_default())
    }

    fn header(&mut self, dest: Dest) -> AsyncHeader {
        let tl = self.next_tl();
        AsyncHeader::new(NodeId::local(dest.node), pc_node(self.host_phy()), tl)
    }

    fn check_response(
        response: &[u8],
        tcode: Tcode,
        len: usize,
        node: u8,
    ) -> Result<Packet<&[u8]>> {
        let packet = Packet::new_checked(response)?;
        packet.verify()?;
        if packet.tcode() != tcode {
            return Err(HostError::Wire(firelink_wire::Error::UnexpectedTcode {
                tcode: u8::from(packet.tcode()),
                expected: tcode.name(),
            }));
        }
        if packet.rcode() != Rcode::Complete {
            return Err(HostError::Rcode {
                node,
                rcode: packet.rcode(),
            });
        }
        if tcode == Tcode::ReadBlockResponse && usize::from(packet.data_length()) != len {
            return Err(HostError::Wire(firelink_wire::Error::BlockSize {
                what: "read response",
                expected: len / 4,
                found: usize::from(packet.data_length()) / 4,
            }));
        }
        Ok(packet)
    }
}

fn no_broadcast_reads(dest: Dest) -> Result<()> {
    if dest.is_broadcast() {
        return Err(HostError::InvalidRequest {
            what: "reads cannot be broadcast on a 1394 bus",
            value: u32::from(dest.node),
        });
    }
    Ok(())
}

impl Port for SimPort {
    fn name(&self) -> &str {
        "sim"
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        no_broadcast_reads(dest)?;
        let header = self.header(dest);
        let response = self.transact(
            dest,
            PacketRepr::ReadQuadletRequest { header, offset },
            HostCall::Read,
        )?;
        let packet = Self::check_response(&response, Tcode::ReadQuadletResponse, 4, dest.node)?;
        Ok(packet.quadlet_data())
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        let header = self.header(dest);
        let call = if dest.is_broadcast() {
            HostCall::BroadcastWrite
        } else {
            HostCall::Write
        };
        self.transact(
            dest,
            PacketRepr::WriteQuadletRequest {
                header,
                offset,
                data: value,
            },
            call,
        )?;
        Ok(())
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        crate::port::check_block(out.len())?;
        no_broadcast_reads(dest)?;
        let header = self.header(dest);
        let response = self.transact(
            dest,
            PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: out.len() as u16,
                extended_tcode: 0,
            },
            HostCall::Read,
        )?;
        let packet =
            Self::check_response(&response, Tcode::ReadBlockResponse, out.len(), dest.node)?;
        out.copy_from_slice(packet.payload());
        Ok(())
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        crate::port::check_block(data.len())?;
        let header = self.header(dest);
        let call = if dest.is_broadcast() {
            HostCall::BroadcastWrite
        } else {
            HostCall::Write
        };
        self.transact(
            dest,
            PacketRepr::WriteBlockRequest {
                header,
                offset,
                extended_tcode: 0,
                data,
            },
            call,
        )?;
        Ok(())
    }

    fn wait(&mut self, duration: Duration) {
        self.bus
            .run_for(SimDuration::from_micros_f64(duration.as_secs_f64() * 1e6));
    }

    fn now(&self) -> Duration {
        let SimTime(ps) = self.bus.now();
        Duration::from_nanos(ps / 1000)
    }

    fn generation(&self) -> u32 {
        self.generation
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        // The PC is the root with the highest physical ID; boards are below.
        0..self.host_phy()
    }
}
