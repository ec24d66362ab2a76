//! A node for the bus's unit tests: it records what happens to it and
//! answers like a board's link (unicast writes `ack_complete`, quadlet reads
//! `ack_pending` and the response at once).

use firelink_wire::packet::{
    Ack, AsyncHeader, CrcStatus, NodeId, Packet, PacketRepr, Rcode, Speed, Tcode,
};

use super::{Bus, BusConfig, NodeConfig, NodeHandle};
use crate::node::{ArbitrationClass, Node, NodeCtx, ResetInfo, RxReply, TransmitRequest};
use crate::time::SimTime;

/// See the module docs.
#[derive(Debug, Default)]
pub(super) struct Probe {
    pub phy: u8,
    pub received: Vec<(SimTime, Vec<u8>)>,
    /// What the bus said of each received packet's CRCs.
    pub received_crc: Vec<Option<CrcStatus>>,
    pub transmitted: Vec<(SimTime, u64, Option<Ack>)>,
    pub resets: Vec<ResetInfo>,
    pub timers: Vec<(SimTime, u64)>,
    /// Packets to send when a timer fires, by token.
    pub on_timer_send: Vec<(u64, Vec<u8>)>,
    /// Read responses go for the bus to seal
    /// ([`RxReply::AckThenSealedResponse`]), their CRC fields garbled.
    pub seal_responses: bool,
}

impl Node for Probe {
    fn name(&self) -> &str {
        "probe"
    }

    fn on_bus_reset(&mut self, _now: SimTime, info: &ResetInfo, _ctx: &mut NodeCtx<'_>) {
        self.phy = info.phy_id;
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
        self.received_crc.push(ctx.received_crc_status());
        let Ok(view) = Packet::new_checked(packet) else {
            return RxReply::Silent;
        };
        let dest = view.destination_id();
        if dest.is_broadcast() || dest.phy() != self.phy || view.verify().is_err() {
            return RxReply::Silent;
        }
        match view.tcode() {
            Tcode::ReadQuadletRequest => {
                let header = AsyncHeader::new(dest, view.source_id(), view.tl()).response();
                let response = emit(&PacketRepr::ReadQuadletResponse {
                    header,
                    rcode: Rcode::Complete,
                    data: 0x1394,
                });
                if self.seal_responses {
                    let mut response = response;
                    // Header CRC (quadlet 4) garbled: the bus writes it.
                    if let Some(crc) = response.get_mut(16..20) {
                        crc.fill(0xA5);
                    }
                    RxReply::AckThenSealedResponse {
                        ack: Ack::Pending,
                        response,
                        speed,
                    }
                } else {
                    RxReply::AckThenResponse {
                        ack: Ack::Pending,
                        response,
                        speed,
                    }
                }
            }
            _ => RxReply::Ack(Ack::Complete),
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

    fn on_timer(&mut self, now: SimTime, token: u64, ctx: &mut NodeCtx<'_>) {
        self.timers.push((now, token));
        if let Some(i) = self.on_timer_send.iter().position(|(t, _)| *t == token) {
            let (_, packet) = self.on_timer_send.remove(i);
            ctx.transmit(TransmitRequest {
                packet,
                speed: Speed::S400,
                class: ArbitrationClass::Fair,
                token,
            });
        }
    }
}

/// `n` probes in a daisy chain, the first the root, after the first reset
/// (probe i gets physical ID n-1-i... as self-ID numbers them: the root
/// highest).
pub(super) fn chain(n: usize, cfg: BusConfig) -> (Bus, Vec<NodeHandle>) {
    let mut bus = Bus::new(cfg);
    let nodes: Vec<NodeHandle> = (0..n)
        .map(|_| bus.add(Probe::default(), NodeConfig::board()))
        .collect();
    bus.daisy_chain(&nodes).expect("a chain");
    if let Some(&first) = nodes.first() {
        bus.set_root(first).expect("a root");
    }
    bus.reset();
    bus.run_until_idle();
    (bus, nodes)
}

/// The probe at `node`.
pub(super) fn probe(bus: &Bus, node: NodeHandle) -> &Probe {
    bus.node::<Probe>(node).expect("a probe")
}

/// Make `node` transmit `packet` now.
pub(super) fn send(bus: &mut Bus, node: NodeHandle, packet: Vec<u8>, class: ArbitrationClass) {
    bus.with_node::<Probe, _>(node, |_, ctx| {
        ctx.transmit(TransmitRequest {
            packet,
            speed: Speed::S400,
            class,
            token: 1,
        })
    })
    .expect("a probe");
}

/// A packet's bytes.
pub(super) fn emit(repr: &PacketRepr<'_>) -> Vec<u8> {
    let mut out = vec![0; repr.buffer_len()];
    let _ = repr.emit(&mut out);
    out
}

/// A quadlet write from physical ID `src` to `dst` (63: broadcast).
pub(super) fn qwrite(src: u8, dst: u8) -> Vec<u8> {
    emit(&PacketRepr::WriteQuadletRequest {
        header: AsyncHeader::new(NodeId::local(dst), NodeId::local(src), 1),
        offset: 0x1000,
        data: 7,
    })
}

/// A quadlet read from `src` to `dst`.
pub(super) fn qread(src: u8, dst: u8) -> Vec<u8> {
    emit(&PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(NodeId::local(dst), NodeId::local(src), 2),
        offset: 4,
    })
}
