//! Test helpers: a recording node with a scripted reply, and packet builders.
#![allow(dead_code)]

use firelink_bus::node::{Node, NodeCtx, ResetInfo, RxReply, TransmitRequest};
use firelink_bus::trace::{PacketKind, PacketRecord};
use firelink_bus::{ArbitrationClass, Bus, NodeHandle, SimTime};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed};

/// How a [`Recorder`] answers packets addressed to it.
#[derive(Clone, Debug)]
pub enum Reply {
    /// ack_complete for every unicast packet with good CRCs.
    Complete,
    /// This ack, whatever arrives.
    Fixed(Ack),
    /// ack_pending + a concatenated quadlet read response.
    Concatenated,
    /// As a board's link: reads answered like `Concatenated`, writes
    /// `Complete` (ack_data_error on a bad data CRC).
    Board,
    /// ack_pending, then a split response after `delay_us`.
    Split { delay_us: f64 },
    /// These exact reply bytes as a concatenated response (garbage test).
    Garbage(Vec<u8>),
    /// Never answer.
    Silent,
}

/// A node that records everything and answers as scripted.
#[derive(Debug)]
pub struct Recorder {
    pub name: String,
    pub reply: Reply,
    pub phy_id: u8,
    pub received: Vec<(SimTime, Vec<u8>)>,
    pub resets: Vec<ResetInfo>,
    pub transmitted: Vec<(SimTime, u64, Option<Ack>)>,
    pub response_acks: Vec<Option<Ack>>,
    pub timers: Vec<(SimTime, u64)>,
    pub crc_errors: u32,
    /// Requests to this node received twice in a row, byte for byte.
    pub duplicates: u32,
    pending_split: Option<Vec<u8>>,
}

impl Recorder {
    pub fn new(name: &str, reply: Reply) -> Recorder {
        Recorder {
            name: name.to_string(),
            reply,
            phy_id: 63,
            received: Vec::new(),
            resets: Vec::new(),
            transmitted: Vec::new(),
            response_acks: Vec::new(),
            timers: Vec::new(),
            crc_errors: 0,
            duplicates: 0,
            pending_split: None,
        }
    }
}

fn quadlet_response(request: &Packet<&[u8]>) -> Vec<u8> {
    let header =
        AsyncHeader::new(request.destination_id(), request.source_id(), request.tl()).response();
    let repr = PacketRepr::ReadQuadletResponse {
        header,
        rcode: Rcode::Complete,
        data: 0x1234_5678,
    };
    let mut out = vec![0; repr.buffer_len()];
    repr.emit(&mut out).unwrap();
    out
}

impl Node for Recorder {
    fn name(&self) -> &str {
        &self.name
    }
    fn on_bus_reset(&mut self, _now: SimTime, info: &ResetInfo, _ctx: &mut NodeCtx<'_>) {
        self.phy_id = info.phy_id;
        self.resets.push(*info);
    }
    fn on_receive(
        &mut self,
        now: SimTime,
        packet: &[u8],
        speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply {
        self.received.push((now, packet.to_vec()));
        let Ok(view) = Packet::new_checked(packet) else {
            self.crc_errors += 1;
            ctx.report_error("malformed");
            return RxReply::Silent;
        };
        let ok = view.verify().is_ok();
        if !ok {
            self.crc_errors += 1;
            ctx.report_error("crc error");
        }
        let dest = view.destination_id();
        if dest.is_broadcast() || dest.phy() != self.phy_id {
            // Broadcasts are never acked: a reply here must be ignored by the bus.
            return if matches!(self.reply, Reply::Fixed(_)) && dest.is_broadcast() {
                RxReply::Ack(Ack::Complete)
            } else {
                RxReply::Silent
            };
        }
        if view.header_crc_ok() == Some(false) {
            return RxReply::Silent;
        }
        let before = self.received.len().checked_sub(2);
        if before
            .and_then(|i| self.received.get(i))
            .is_some_and(|(_, p)| p == packet)
        {
            self.duplicates += 1;
            ctx.report_error("duplicate request (same label)");
        }
        match &self.reply {
            Reply::Complete if ok => RxReply::Ack(Ack::Complete),
            Reply::Complete => RxReply::Ack(Ack::DataError),
            Reply::Fixed(a) => RxReply::Ack(*a),
            Reply::Board
                if !matches!(
                    view.tcode(),
                    firelink_wire::packet::Tcode::ReadQuadletRequest
                        | firelink_wire::packet::Tcode::ReadBlockRequest
                ) =>
            {
                RxReply::Ack(if ok { Ack::Complete } else { Ack::DataError })
            }
            Reply::Concatenated | Reply::Board => RxReply::AckThenResponse {
                ack: Ack::Pending,
                response: quadlet_response(&view),
                speed,
            },
            Reply::Split { delay_us } => {
                self.pending_split = Some(quadlet_response(&view));
                ctx.set_timer(
                    now + firelink_bus::SimDuration::from_micros_f64(*delay_us),
                    7,
                );
                RxReply::Ack(Ack::Pending)
            }
            Reply::Garbage(bytes) => RxReply::AckThenResponse {
                ack: Ack::Pending,
                response: bytes.clone(),
                speed,
            },
            Reply::Silent => RxReply::Silent,
        }
    }
    fn on_transmitted(
        &mut self,
        now: SimTime,
        token: u64,
        ack: Option<Ack>,
        _ctx: &mut NodeCtx<'_>,
    ) {
        self.transmitted.push((now, token, ack));
    }
    fn on_response_acked(&mut self, _now: SimTime, ack: Option<Ack>, _ctx: &mut NodeCtx<'_>) {
        self.response_acks.push(ack);
    }
    fn on_timer(&mut self, now: SimTime, token: u64, ctx: &mut NodeCtx<'_>) {
        self.timers.push((now, token));
        if token == 7 {
            if let Some(packet) = self.pending_split.take() {
                ctx.transmit(TransmitRequest {
                    packet,
                    speed: Speed::S400,
                    class: ArbitrationClass::Fair,
                    token: 99,
                });
            }
        }
    }
}

/// Emit a packet representation.
pub fn emit(repr: &PacketRepr<'_>) -> Vec<u8> {
    let mut out = vec![0; repr.buffer_len()];
    repr.emit(&mut out).unwrap();
    out
}

/// A quadlet write from `src` to `dst` (physical IDs).
pub fn qwrite(src: u8, dst: u8, offset: u64, data: u32) -> Vec<u8> {
    emit(&PacketRepr::WriteQuadletRequest {
        header: AsyncHeader::new(NodeId::local(dst), NodeId::local(src), 1),
        offset,
        data,
    })
}

/// A block write from `src` to `dst`.
pub fn bwrite(src: u8, dst: u8, offset: u64, data: &[u8]) -> Vec<u8> {
    emit(&PacketRepr::WriteBlockRequest {
        header: AsyncHeader::new(NodeId::local(dst), NodeId::local(src), 2),
        offset,
        extended_tcode: 0,
        data,
    })
}

/// A quadlet read from `src` to `dst`.
pub fn qread(src: u8, dst: u8, offset: u64) -> Vec<u8> {
    emit(&PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(NodeId::local(dst), NodeId::local(src), 3),
        offset,
    })
}

/// Make `node` (a Recorder) transmit `packet` now.
pub fn send(bus: &mut Bus, node: NodeHandle, packet: Vec<u8>, class: ArbitrationClass, token: u64) {
    bus.with_node::<Recorder, _>(node, |_, ctx| {
        ctx.transmit(TransmitRequest {
            packet,
            speed: Speed::S400,
            class,
            token,
        })
    })
    .unwrap();
}

/// The recorder at `node`.
/// [`send`] with fair arbitration (an ordinary asynchronous request).
pub fn send_fair(bus: &mut Bus, node: NodeHandle, packet: Vec<u8>, token: u64) {
    send(bus, node, packet, ArbitrationClass::Fair, token);
}

/// The packets of `kind` in the bus's trace, in wire order.
pub fn packets_of(bus: &Bus, kind: PacketKind) -> Vec<PacketRecord> {
    bus.trace()
        .packets()
        .iter()
        .filter(|p| p.kind == kind)
        .cloned()
        .collect()
}

pub fn rec(bus: &Bus, node: NodeHandle) -> &Recorder {
    bus.node::<Recorder>(node).unwrap()
}

impl Recorder {
    /// Write requests addressed to this node that arrived intact.
    pub fn writes(&self) -> usize {
        self.received
            .iter()
            .filter(|(_, p)| {
                Packet::new_checked(&p[..]).is_ok_and(|v| {
                    v.verify().is_ok()
                        && v.destination_id().phy() == self.phy_id
                        && matches!(
                            v.tcode(),
                            firelink_wire::packet::Tcode::WriteQuadletRequest
                                | firelink_wire::packet::Tcode::WriteBlockRequest
                        )
                })
            })
            .count()
    }
}
