//! One subaction on the wire: the faults decided for the packet, its bits
//! at its speed, delivery to every node its path reaches, the addressee's
//! ack after the ack gap (and a concatenated response right after it), and
//! the end of the subaction when the last bit has reached every node.

use super::*;

impl Bus {
    /// Decide and apply packet faults (other than delay) to a packet about
    /// to start. Returns whether a duplicate must follow, and the bytes as
    /// they were before a corruption or truncation changed them (`None`:
    /// unchanged).
    pub(super) fn decide_faults(&mut self, sub: &mut Sub, now: SimTime) -> (bool, Option<Vec<u8>>) {
        if self.injector.is_empty()
            || matches!(sub.kind, PacketKind::Duplicate | PacketKind::Babble)
        {
            return (false, None);
        }
        let d = self
            .injector
            .decide(NodeHandle(sub.sender), sub.kind, &sub.bytes, now);
        if d.fired.is_empty() {
            return (false, None);
        }
        let mut original = None;
        if !d.mutations.is_empty() || d.truncate.is_some() {
            let mut bytes = sub.bytes.clone();
            for m in &d.mutations {
                m.apply(&mut bytes);
            }
            if let Some(keep) = d.truncate {
                bytes.truncate(keep.max(4));
            }
            original = Some(std::mem::replace(&mut sub.bytes, bytes));
            // Changed on the way: checked again at delivery.
            sub.crc = None;
        }
        for (what, _, rule) in d.fired {
            let id = self.log.add(
                now,
                what.clone(),
                Some(sub.id),
                Some(sub.sender),
                Some(FaultSource::Rule(rule)),
            );
            self.log_event(TraceEvent::Fault { id, what });
            sub.faults.push(id);
        }
        sub.drop_ack |= d.drop_ack;
        sub.corrupt_ack |= d.corrupt_ack;
        sub.busy |= d.busy;
        sub.dropped |= d.drop;
        (d.duplicate, original)
    }

    /// A packet starts on the wire now (after arbitration begun at
    /// `arb_start` in `class`): its bits and end, the trace, its delivery
    /// to every node it reaches, then the addressee's ack, or the end of
    /// the subaction when none will come.
    pub(super) fn tx_start(
        &mut self,
        id: PacketId,
        arb_start: Option<SimTime>,
        class: Option<ArbitrationClass>,
    ) {
        let now = self.now;
        let t = self.cfg.timing;
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        let shape = WireShape::of(sub, &t, now);
        sub.end = shape.end;
        let (sender, sender_phy) = (sub.sender, sub.sender_phy);
        if self.cfg.trace >= TraceLevel::Packets {
            self.record_packet(id, arb_start, class, &shape);
        }
        self.log_event(TraceEvent::PacketStart(id));
        let dest_node = shape
            .dest_phy
            .filter(|_| shape.unicast)
            .and_then(|d| self.tree.by_phy.get(usize::from(d)).copied());
        let (dest_receives, mute_fault) = self.schedule_deliveries(id, &shape, dest_node);
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        if let Some(f) = mute_fault {
            sub.faults.push(f);
        }
        // Its level of detail, decided and counted once its faults are
        // known (a dropped packet, which reaches no one, counts too).
        let level = packet_level_why(&self.cfg, sub);
        sub.level = level;
        self.detail.packet(level);
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        let idle_at = shape.end + t.hop_delay * u64::from(self.tree.eccentricity(sender_phy));
        if shape.unicast && dest_receives {
            let dest = dest_node.unwrap_or(0);
            sub.dest = Some(dest);
            let dest_phy = self.slots[dest].phy.unwrap_or(0);
            let at = shape.end
                + t.hop_delay * u64::from(self.tree.hops(sender_phy, dest_phy))
                + t.ack_gap;
            self.push_epoch(at, Ev::AckStart { sub: id });
        } else {
            if !shape.unicast && shape.kind == PacketKind::Request {
                sub.notified = true;
                let token = sub.token;
                self.push(
                    shape.end,
                    None,
                    Ev::Notify {
                        node: sender,
                        token,
                        kind: shape.kind,
                        ack: None,
                    },
                );
            }
            if shape.unicast {
                self.no_ack(id, idle_at);
            }
            self.push_epoch(idle_at, Ev::SubEnd { sub: id });
        }
        if self.cfg.trace >= TraceLevel::Normal {
            self.push_epoch(shape.end, Ev::PacketEnd(id));
        }
    }

    /// Keep the record of a packet that starts now.
    fn record_packet(
        &mut self,
        id: PacketId,
        arb_start: Option<SimTime>,
        class: Option<ArbitrationClass>,
        shape: &WireShape,
    ) {
        let Some(sub) = self.subs.get(&id) else {
            return;
        };
        self.trace.packets.push(PacketRecord {
            id,
            kind: sub.kind,
            sender: sub.sender,
            sender_phy: sub.sender_phy,
            arb_start,
            class,
            start: self.now,
            bits_end: shape.bits_end,
            end: shape.end,
            speed: sub.speed,
            bytes: Arc::from(&sub.bytes[..]),
            answers: sub.answers,
            generation: self.generation,
            faults: sub.faults.clone(),
        });
    }

    /// Deliver packet `id` to every node its path reaches at its speed
    /// (none when it was dropped; a muted node hears nothing), each when
    /// its last bit arrives there. Returns whether the addressee
    /// `dest_node` receives it, and the fault that muted the addressee.
    fn schedule_deliveries(
        &mut self,
        id: PacketId,
        shape: &WireShape,
        dest_node: Option<usize>,
    ) -> (bool, Option<FaultId>) {
        let t = self.cfg.timing;
        let mut dest_receives = false;
        let mut mute_fault = None;
        let mut arrivals = std::mem::take(&mut self.arrivals);
        arrivals.clear();
        // Nearest first (with a hop delay): the arrivals are listed in time
        // order, and the queue numbers them in this order; equal times keep
        // ID order, as when listed by ID.
        let nearest_first = t.hop_delay > SimDuration::ZERO;
        let mut consider = |phy: u8| {
            let Some(&node) = self.tree.by_phy.get(usize::from(phy)) else {
                return;
            };
            if node == shape.sender {
                return;
            }
            let slot = &self.slots[node];
            if slot.muted {
                if Some(node) == dest_node {
                    mute_fault = slot.mute_fault;
                }
                return;
            }
            if shape.dropped || shape.speed > self.tree.path_speed(shape.sender_phy, phy) {
                return;
            }
            if Some(node) == dest_node {
                dest_receives = true;
            } else if shape.unicast && !slot.hears_others && shape.dest_phy != Some(0) {
                // Addressed to another node, and this one ignores those.
                return;
            }
            let at =
                shape.bits_end + t.hop_delay * u64::from(self.tree.hops(shape.sender_phy, phy));
            arrivals.push((at, node));
        };
        // The listeners' row walked as a slice where there is one (what
        // `Tree::listeners` gives, without its iterator chain per node).
        match self
            .tree
            .nearest_first(shape.sender_phy)
            .filter(|_| nearest_first)
        {
            Some(row) => row.iter().for_each(|&phy| consider(phy)),
            None => self
                .tree
                .listeners(shape.sender_phy, false)
                .for_each(&mut consider),
        }
        self.events
            .push_wave(id, self.epoch, arrivals.iter().copied());
        self.arrivals = arrivals;
        (dest_receives, mute_fault)
    }

    pub(super) fn no_ack(&mut self, id: PacketId, idle_at: SimTime) {
        let Some(sub) = self.subs.get_mut(&id) else {
            return;
        };
        sub.notified = true;
        if sub.kind == PacketKind::Babble {
            return;
        }
        let gap = self.slots[sub.sender].regs.gap_count();
        let at = idle_at + self.cfg.timing.subaction_gap(gap);
        let ev = Ev::NoAck(Box::new(NoAckInfo {
            packet: sub.id,
            node: sub.sender,
            token: sub.token,
            kind: sub.kind,
            faults: sub.faults.clone(),
        }));
        self.push(at, None, ev);
    }

    /// Delivery `d`, just taken off the queue, and, when its packet goes at
    /// the fast level, the packet's next deliveries after it, each while it
    /// is the queue's next event, due by `deadline`, and as far as `batch`
    /// allows (a callback that started a bus reset ends the batch too: the
    /// rest of the packet is left to the queue, which drops it).
    pub(super) fn deliver_from(&mut self, d: Delivery, deadline: SimTime, mut batch: Batch<'_>) {
        let id = d.sub;
        let Ok(pos) = self.subs.position(id) else {
            return;
        };
        let Some(sub) = self.subs.0.get_mut(pos) else {
            return;
        };
        if sub.level.is_some() {
            self.deliver(id, d.node);
            return;
        }
        let crc = *sub.crc.get_or_insert_with(|| crc_status_of(&sub.bytes));
        let (speed, dest) = (sub.speed, sub.dest);
        self.current_rx = Some(id);
        self.rx_crc = Some(crc);
        self.detail.batch();
        let mut node = d.node;
        // Taken once: within the batch only the time moves (a bus reset,
        // which would change the rest, ends it).
        let mut view = self.ctx_view();
        loop {
            self.detail.batched_delivery();
            view.now = self.now;
            let reply = self.dispatch_receive_in(view, node, pos, speed);
            let is_dest = dest == Some(node);
            if let Some(reply) = reply
                && (reply != RxReply::Silent || is_dest)
            {
                self.take_reply(id, node, is_dest, reply);
            }
            let stop = match &mut batch {
                Batch::One => true,
                Batch::All => false,
                Batch::Until(done) => done(self),
            };
            if stop {
                break;
            }
            let Some(next) = self.events.pop_wave_next(id, self.epoch, deadline) else {
                break;
            };
            self.now = self.now.max(next.time);
            node = next.node;
        }
        self.rx_crc = None;
        self.current_rx = None;
    }

    /// What node `node` answered to packet `id`: kept for the ack when it
    /// is the addressee (`is_dest`), noted otherwise unless it kept
    /// silent.
    #[inline(never)]
    fn take_reply(&mut self, id: PacketId, node: usize, is_dest: bool, reply: RxReply) {
        if is_dest {
            // Looked up again: what the node asked for (a reset) may have
            // changed the table.
            if let Some(sub) = self.subs.get_mut(&id) {
                sub.reply = Some(reply);
            }
        } else if reply != RxReply::Silent {
            let text = format!(
                "{} answered #{id}, which is not addressed to it (ignored)",
                self.slots[node].name
            );
            self.note(text);
        }
    }

    /// One delivery at the packet level: packet `id` reaches `node` now.
    pub(super) fn deliver(&mut self, id: PacketId, node: usize) {
        let Ok(pos) = self.subs.position(id) else {
            return;
        };
        let Some(sub) = self.subs.0.get_mut(pos) else {
            return;
        };
        let crc = *sub.crc.get_or_insert_with(|| crc_status_of(&sub.bytes));
        let speed = sub.speed;
        let is_dest = sub.dest == Some(node);
        if is_dest && sub.busy {
            // A busy addressee takes nothing and says so.
            sub.reply = Some(RxReply::Ack(Ack::BusyX));
            return;
        }
        if self.cfg.trace >= TraceLevel::Verbose {
            self.log_event(TraceEvent::Deliver { packet: id, node });
        }
        // The packet's bytes and faults stay in its subaction, which
        // outlives the call (a report looks the faults up there).
        self.current_rx = Some(id);
        self.rx_crc = Some(crc);
        let reply = self.dispatch_receive(node, pos, speed);
        self.rx_crc = None;
        self.current_rx = None;
        if let Some(reply) = reply
            && (reply != RxReply::Silent || is_dest)
        {
            self.take_reply(id, node, is_dest, reply);
        }
    }

    pub(super) fn ack_start(&mut self, id: PacketId) {
        let Some(mut sub) = self.subs.remove(&id) else {
            return;
        };
        let reply = sub.reply.take().unwrap_or(RxReply::Silent);
        match reply {
            RxReply::Silent => {
                let hop = self.cfg.timing.hop_delay;
                let idle_at = self
                    .now
                    .max(sub.end + hop * u64::from(self.tree.eccentricity(sub.sender_phy)));
                self.subs.insert(id, sub);
                self.no_ack(id, idle_at);
                self.push_epoch(idle_at, Ev::SubEnd { sub: id });
            }
            RxReply::Ack(ack) => self.send_ack(sub, ack, None),
            RxReply::AckThenResponse {
                ack,
                response,
                speed,
            } => self.send_ack(sub, ack, Some((response, speed, None))),
            RxReply::AckThenSealedResponse {
                ack,
                mut response,
                speed,
            } => {
                let crc = seal(&mut response);
                self.send_ack(sub, ack, Some((response, speed, crc)));
            }
        }
    }

    /// The addressee's `ack` to `sub`, and the concatenated `response` it
    /// asked for, if any (with its CRC status when the bus knows it: a
    /// sealed response).
    pub(super) fn send_ack(
        &mut self,
        mut sub: Sub,
        ack: Ack,
        response: Option<(Vec<u8>, Speed, Option<CrcStatus>)>,
    ) {
        let t = self.cfg.timing;
        let now = self.now;
        let Some(dest) = sub.dest else {
            return;
        };
        let dest_phy = self.slots[dest].phy.unwrap_or(0);
        let hops = self.tree.hops(sub.sender_phy, dest_phy);
        let response = self.acceptable_response(&sub, dest, response);
        let byte = if sub.corrupt_ack {
            corrupt_ack_byte(ack)
        } else {
            ack.to_byte()
        };
        let bits_end = now + t.data_prefix + t.bits(crate::timing::ACK_BITS, sub.speed);
        let end = if response.is_some() {
            bits_end
        } else {
            bits_end + t.data_end
        };
        self.record_ack(&sub, dest, dest_phy, byte, bits_end, end);
        let seen = if sub.drop_ack {
            None
        } else {
            Ack::from_byte(byte).ok()
        };
        let arrival = bits_end + t.hop_delay * u64::from(hops);
        self.ack_evidence(&sub, dest, ack, seen, arrival);
        if matches!(sub.kind, PacketKind::Request | PacketKind::ConcatResponse) {
            sub.notified = true;
            // A valid ack is known when it arrives; a lost or corrupt one
            // only when the bus falls idle for a subaction gap (after any
            // concatenated response).
            let at = if seen.is_some() {
                arrival
            } else {
                let last_end = match &response {
                    Some((bytes, speed, _)) => {
                        bits_end
                            + t.concat_prefix
                            + t.payload_time(bytes.len(), *speed)
                            + t.data_end
                    }
                    None => end,
                };
                let gap = self.slots[sub.sender].regs.gap_count();
                last_end
                    + t.hop_delay * u64::from(self.tree.eccentricity(dest_phy))
                    + t.subaction_gap(gap)
            };
            self.push(
                at,
                None,
                Ev::Notify {
                    node: sub.sender,
                    token: sub.token,
                    kind: sub.kind,
                    ack: seen,
                },
            );
        }
        match response {
            Some((bytes, speed, crc)) => {
                self.start_concat_response(&sub, dest, dest_phy, (bytes, speed, crc), bits_end);
                // The request's subaction ends here (its response's goes
                // on): its memory serves a node's next packet.
                self.spare_packets.give(sub.bytes);
            }
            None => {
                let idle_at = end + t.hop_delay * u64::from(self.tree.eccentricity(dest_phy));
                let id = sub.id;
                self.subs.insert(id, sub);
                self.push_epoch(idle_at, Ev::SubEnd { sub: id });
            }
        }
    }

    /// The response a node asked to concatenate to its ack, unless it may
    /// not: a response to a response, or one longer than the bus accepts.
    fn acceptable_response(
        &mut self,
        sub: &Sub,
        dest: usize,
        response: Option<(Vec<u8>, Speed, Option<CrcStatus>)>,
    ) -> Option<(Vec<u8>, Speed, Option<CrcStatus>)> {
        match response {
            Some(_) if sub.kind == PacketKind::ConcatResponse => {
                self.note(format!(
                    "{} tried to concatenate a response to a response (ignored)",
                    self.slots[dest].name
                ));
                None
            }
            Some((bytes, _, _)) if bytes.len() > self.cfg.max_packet_len => {
                self.note(format!(
                    "{} response of {} bytes is longer than the bus accepts (dropped)",
                    self.slots[dest].name,
                    bytes.len()
                ));
                None
            }
            other => other,
        }
    }

    /// The ack `byte` from node `dest` on the wire from now to `end`: its
    /// trace record and events.
    fn record_ack(
        &mut self,
        sub: &Sub,
        dest: usize,
        dest_phy: u8,
        byte: u8,
        bits_end: SimTime,
        end: SimTime,
    ) {
        let ack_id = self.next_id;
        self.next_id += 1;
        if self.cfg.trace >= TraceLevel::Packets {
            let faults = if sub.drop_ack || sub.corrupt_ack {
                sub.faults.clone()
            } else {
                Vec::new()
            };
            self.trace.packets.push(PacketRecord {
                id: ack_id,
                kind: PacketKind::Ack,
                sender: dest,
                sender_phy: dest_phy,
                arb_start: None,
                class: None,
                start: self.now,
                bits_end,
                end,
                speed: sub.speed,
                bytes: Arc::from(&[byte][..]),
                answers: Some(sub.id),
                generation: self.generation,
                faults,
            });
        }
        self.log_event(TraceEvent::PacketStart(ack_id));
        if self.cfg.trace >= TraceLevel::Normal {
            self.push_epoch(end, Ev::PacketEnd(ack_id));
        }
    }

    /// What the faults on `sub` left as evidence: an error ack from the
    /// addressee, or no valid ack at the sender when it was due (`arrival`).
    fn ack_evidence(
        &mut self,
        sub: &Sub,
        dest: usize,
        ack: Ack,
        seen: Option<Ack>,
        arrival: SimTime,
    ) {
        let now = self.now;
        if !sub.faults.is_empty() {
            if !matches!(ack, Ack::Complete | Ack::Pending) {
                for &f in &sub.faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: now,
                            node: dest,
                            kind: EvidenceKind::ErrorAck(u8::from(ack)),
                        },
                    );
                }
            }
            if seen.is_none() {
                for &f in &sub.faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: arrival,
                            node: sub.sender,
                            kind: EvidenceKind::NoAck,
                        },
                    );
                }
            }
        }
        if seen.is_none() {
            self.log_event(TraceEvent::NoAck { packet: sub.id });
        }
    }

    /// The response `dest` concatenates to its ack (its bytes, speed and,
    /// when the bus sealed it, CRC status): on the wire right after the
    /// ack's bits (`bits_end`), no gap, no arbitration.
    fn start_concat_response(
        &mut self,
        sub: &Sub,
        dest: usize,
        dest_phy: u8,
        (bytes, speed, crc): (Vec<u8>, Speed, Option<CrcStatus>),
        bits_end: SimTime,
    ) {
        let now = self.now;
        let rid = self.next_id;
        self.next_id += 1;
        let mut rsub = Sub {
            id: rid,
            kind: PacketKind::ConcatResponse,
            sender: dest,
            sender_phy: dest_phy,
            bytes,
            speed,
            token: None,
            dest: None,
            reply: None,
            end: bits_end,
            faults: Vec::new(),
            drop_ack: false,
            corrupt_ack: false,
            busy: false,
            dropped: false,
            notified: false,
            // Known when sealed; a fault that changes the bytes forgets it.
            crc,
            level: None,
            answers: Some(sub.id),
        };
        let mut start = bits_end;
        if !self.injector.is_empty() {
            if let Some((delay, what, rule)) = self.injector.decide_delay(
                NodeHandle(dest),
                PacketKind::ConcatResponse,
                &rsub.bytes,
                now,
            ) {
                let source = rule.map(FaultSource::Rule);
                let fid = self
                    .log
                    .add(now, what.clone(), Some(rid), Some(dest), source);
                self.log_event(TraceEvent::Fault { id: fid, what });
                rsub.faults.push(fid);
                start += delay;
            }
        }
        if self.decide_faults(&mut rsub, now).0 {
            self.slots[dest].queue.push_back(Pending {
                bytes: rsub.bytes.clone(),
                speed,
                class: ArbitrationClass::Fair,
                token: None,
                kind: PacketKind::Duplicate,
                ready_at: now,
                delayed: true,
                faults: rsub.faults.clone(),
                crc: None,
            });
        }
        self.subs.insert(rid, rsub);
        self.push_epoch(
            start,
            Ev::TxStart {
                sub: rid,
                arb_start: None,
                class: None,
            },
        );
    }

    pub(super) fn sub_end(&mut self, id: PacketId) {
        if let Some(sub) = self.subs.remove(&id) {
            if !sub.dropped {
                if let Some(PhyPacket::Config {
                    force_root,
                    gap_count,
                }) = parse_phy_packet(&sub.bytes)
                {
                    self.apply_phy_config(force_root, gap_count);
                }
            }
            // The packet's memory serves a node's next packet.
            self.spare_packets.give(sub.bytes);
        }
        self.medium = Medium::Idle { since: self.now };
        if self.cfg.trace >= TraceLevel::Verbose {
            self.log_event(TraceEvent::Idle);
        }
        self.arbitrate();
    }
}

/// Why a packet's deliveries go event by event under `cfg` (`None`: they
/// go in batches; see [`detail`](super::detail)).
fn packet_level_why(cfg: &BusConfig, sub: &Sub) -> Option<PacketLevelWhy> {
    if cfg.detail == Detail::Packet {
        Some(PacketLevelWhy::Chosen)
    } else if cfg.trace >= TraceLevel::Verbose {
        Some(PacketLevelWhy::Tracing)
    } else if !sub.faults.is_empty() || sub.busy || sub.dropped {
        Some(PacketLevelWhy::Fault)
    } else {
        None
    }
}

/// The CRC status of a packet's bytes (both unknown when they are not a
/// packet).
fn crc_status_of(bytes: &[u8]) -> CrcStatus {
    Packet::new_checked(bytes).map_or(
        CrcStatus {
            header_ok: None,
            data_ok: None,
        },
        |p| p.crc_status(),
    )
}

/// What a packet that starts now looks like on the wire.
struct WireShape {
    sender: usize,
    sender_phy: u8,
    speed: Speed,
    kind: PacketKind,
    dropped: bool,
    /// Its destination's physical ID (from the header).
    dest_phy: Option<u8>,
    /// Addressed to one node (not a broadcast, PHY packet, cycle start or
    /// ack): an ack is due.
    unicast: bool,
    /// Its last bit leaves the sender.
    bits_end: SimTime,
    /// The data-end after it: the sender lets go of the bus.
    end: SimTime,
}

impl WireShape {
    fn of(sub: &Sub, t: &BusTiming, now: SimTime) -> WireShape {
        let is_phy_packet = sub.bytes.len() >= 12
            && sub
                .bytes
                .get(3)
                .is_some_and(|b| b >> 4 == u8::from(Tcode::LinkInternal));
        let bits = if is_phy_packet {
            t.bits(PHY_PACKET_BITS, sub.speed)
        } else {
            t.payload_time(sub.bytes.len(), sub.speed)
        };
        let prefix = if sub.kind == PacketKind::ConcatResponse {
            t.concat_prefix
        } else {
            t.data_prefix
        };
        let bits_end = now + prefix + bits;
        let dest_phy = sub.bytes.get(1).map(|b| b & 0x3F);
        WireShape {
            sender: sub.sender,
            sender_phy: sub.sender_phy,
            speed: sub.speed,
            kind: sub.kind,
            dropped: sub.dropped,
            dest_phy,
            unicast: !is_phy_packet
                && !matches!(sub.kind, PacketKind::CycleStart | PacketKind::Ack)
                && dest_phy.is_some_and(|d| d != NodeId::BROADCAST_PHY),
            bits_end,
            end: bits_end + t.data_end,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::probe::{chain, probe, qread, qwrite, send};
    use super::*;
    use crate::fault::{PacketFault, PacketMatch};

    /// A 3-node chain, quiet, trace cleared.
    fn quiet(n: usize) -> (Bus, Vec<NodeHandle>) {
        let (mut bus, nodes) = chain(n, BusConfig::default());
        bus.run_for(SimDuration::from_micros(100));
        bus.trace_mut().clear();
        (bus, nodes)
    }

    #[test]
    fn a_packet_takes_its_prefix_bits_and_end_at_its_speed() {
        let (mut bus, nodes) = quiet(2);
        let p0 = bus.phy_id(nodes[0]).unwrap();
        let packet = qwrite(p0, 63);
        let len = packet.len();
        send(&mut bus, nodes[0], packet, ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        let p = &bus.trace().packets()[0];
        let t = BusTiming::default();
        assert_eq!(p.end - p.start, t.packet_time(len, Speed::S400));
        assert_eq!(
            p.bits_end - p.start,
            t.data_prefix + t.payload_time(len, Speed::S400)
        );
    }

    #[test]
    fn a_broadcast_reaches_everyone_else_and_is_not_acked() {
        let (mut bus, nodes) = quiet(3);
        let p0 = bus.phy_id(nodes[0]).unwrap();
        send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        assert!(probe(&bus, nodes[0]).received.is_empty());
        for &n in &nodes[1..] {
            assert_eq!(probe(&bus, n).received.len(), 1);
        }
        // Sent, no ack: the sender hears `None`.
        assert_eq!(probe(&bus, nodes[0]).transmitted[0].2, None);
        assert_eq!(bus.trace().packets().len(), 1);
    }

    #[test]
    fn the_addressee_acks_after_the_ack_gap() {
        let (mut bus, nodes) = quiet(2);
        let (p0, p1) = (bus.phy_id(nodes[0]).unwrap(), bus.phy_id(nodes[1]).unwrap());
        send(&mut bus, nodes[0], qwrite(p0, p1), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        let p = bus.trace().packets();
        assert_eq!(p.len(), 2);
        let (request, ack) = (&p[0], &p[1]);
        assert_eq!(ack.kind, PacketKind::Ack);
        assert_eq!(ack.answers, Some(request.id));
        assert_eq!(ack.ack(), Some(Ack::Complete));
        let t = BusTiming::default();
        // The request's data end reaches the addressee one hop later.
        assert_eq!(ack.start, request.end + t.hop_delay + t.ack_gap);
        assert_eq!(probe(&bus, nodes[0]).transmitted[0].2, Some(Ack::Complete));
    }

    #[test]
    fn a_concatenated_response_follows_its_ack_at_once() {
        let (mut bus, nodes) = quiet(2);
        let (p0, p1) = (bus.phy_id(nodes[0]).unwrap(), bus.phy_id(nodes[1]).unwrap());
        send(&mut bus, nodes[0], qread(p0, p1), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        let p = bus.trace().packets();
        let kinds: Vec<PacketKind> = p.iter().map(|r| r.kind).collect();
        assert_eq!(
            kinds,
            vec![
                PacketKind::Request,
                PacketKind::Ack,
                PacketKind::ConcatResponse,
                PacketKind::Ack
            ]
        );
        let (ack, response) = (&p[1], &p[2]);
        assert_eq!(response.answers, Some(p[0].id));
        // No data end, no gap: the response's prefix follows the ack.
        let t = BusTiming::default();
        assert_eq!(
            response.start,
            ack.bits_end + t.concat_prefix - t.data_prefix
        );
        // The requester received the response and acked it.
        assert_eq!(probe(&bus, nodes[0]).received.len(), 1);
        assert_eq!(p[3].answers, Some(response.id));
    }

    /// A block write broadcast from `src` (data of 10 bytes, padded), its
    /// CRCs as a node that fills them sends it.
    fn block_broadcast(src: u8) -> Vec<u8> {
        super::super::probe::emit(&firelink_wire::packet::PacketRepr::WriteBlockRequest {
            header: firelink_wire::packet::AsyncHeader::new(
                NodeId::local(63),
                NodeId::local(src),
                3,
            ),
            offset: 0x2000,
            extended_tcode: 0,
            data: b"ten bytes!",
        })
    }

    /// Make `node` send `packet` sealed by the bus.
    fn send_sealed(bus: &mut Bus, node: NodeHandle, packet: Vec<u8>) {
        bus.with_node::<super::super::probe::Probe, _>(node, |_, ctx| {
            ctx.transmit_sealed(TransmitRequest {
                packet,
                speed: Speed::S400,
                class: ArbitrationClass::Fair,
                token: 1,
            })
        })
        .expect("a probe");
    }

    #[test]
    fn a_sealed_packet_carries_the_crcs_a_node_fills_and_a_change_on_the_way_is_still_seen() {
        let (mut bus, nodes) = quiet(3);
        let p0 = bus.phy_id(nodes[0]).unwrap();
        let filled = block_broadcast(p0);
        // The same packet with both CRCs and the padding wrong: the bus
        // writes them.
        let mut blank = filled.clone();
        for b in &mut blank[16..20] {
            *b = 0xA5;
        }
        let n = blank.len();
        for b in &mut blank[n - 6..] {
            *b = 0x5A;
        }
        assert_ne!(blank, filled);
        send_sealed(&mut bus, nodes[0], blank.clone());
        bus.run_for(SimDuration::from_micros(50));
        // Corrupted on the wire (a header quadlet, then a data quadlet):
        // the receivers are told, as for any packet.
        for index in [2, 5] {
            bus.add_fault_rule(FaultRule::once(
                PacketMatch::any(),
                PacketFault::CorruptQuadlet { index, xor: 1 },
            ));
            send_sealed(&mut bus, nodes[0], blank.clone());
            bus.run_for(SimDuration::from_micros(50));
        }
        // Not a whole packet: goes as it is.
        send_sealed(&mut bus, nodes[0], filled[..10].to_vec());
        bus.run_for(SimDuration::from_micros(50));
        let all_ok = CrcStatus {
            header_ok: Some(true),
            data_ok: Some(true),
        };
        for &node in &nodes[1..] {
            let p = probe(&bus, node);
            assert_eq!(p.received.len(), 4);
            assert_eq!(p.received[0].1, filled, "the bytes a node fills");
            let told: Vec<Option<CrcStatus>> = p.received_crc.clone();
            // Each time what the received bytes themselves say.
            for ((_, bytes), crc) in p.received.iter().zip(&told) {
                let own = Packet::new_checked(&bytes[..]).map_or(
                    CrcStatus {
                        header_ok: None,
                        data_ok: None,
                    },
                    |v| v.crc_status(),
                );
                assert_eq!(*crc, Some(own));
            }
            assert_eq!(told[0], Some(all_ok));
            assert_eq!(told[1].and_then(|c| c.header_ok), Some(false), "header hit");
            assert_eq!(told[2].and_then(|c| c.data_ok), Some(false), "data hit");
            assert_eq!(p.received[3].1, filled[..10].to_vec());
        }
    }

    #[test]
    fn a_sealed_response_carries_the_crcs_a_node_fills_and_a_change_on_the_way_is_still_seen() {
        let (mut bus, nodes) = quiet(3);
        let (p0, p1) = (bus.phy_id(nodes[0]).unwrap(), bus.phy_id(nodes[1]).unwrap());
        bus.node_mut::<super::super::probe::Probe>(nodes[1])
            .unwrap()
            .seal_responses = true;
        // What the responder would send with its CRCs filled.
        let filled =
            super::super::probe::emit(&firelink_wire::packet::PacketRepr::ReadQuadletResponse {
                header: firelink_wire::packet::AsyncHeader::new(
                    NodeId::local(p1),
                    NodeId::local(p0),
                    2,
                )
                .response(),
                rcode: firelink_wire::packet::Rcode::Complete,
                data: 0x1394,
            });
        send(&mut bus, nodes[0], qread(p0, p1), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        // The response corrupted on the wire (its header, then its data
        // quadlet): the receivers are told, as for any packet.
        for index in [1, 3] {
            bus.add_fault_rule(FaultRule::once(
                PacketMatch::any().kind(PacketKind::ConcatResponse),
                PacketFault::CorruptQuadlet { index, xor: 1 },
            ));
            send(&mut bus, nodes[0], qread(p0, p1), ArbitrationClass::Fair);
            bus.run_for(SimDuration::from_micros(50));
        }
        let all_ok = CrcStatus {
            header_ok: Some(true),
            data_ok: None,
        };
        for node in [nodes[0], nodes[2]] {
            let p = probe(&bus, node);
            let responses: Vec<(&Vec<u8>, Option<CrcStatus>)> = p
                .received
                .iter()
                .zip(&p.received_crc)
                .filter(|((_, bytes), _)| {
                    Packet::new_checked(&bytes[..])
                        .is_ok_and(|v| v.tcode() == Tcode::ReadQuadletResponse)
                })
                .map(|((_, bytes), crc)| (bytes, *crc))
                .collect();
            assert_eq!(responses.len(), 3);
            assert_eq!(*responses[0].0, filled, "the bytes a node fills");
            // Each time what the received bytes themselves say.
            for (bytes, crc) in &responses {
                let own = Packet::new_checked(&bytes[..]).unwrap().crc_status();
                assert_eq!(*crc, Some(own));
            }
            assert_eq!(responses[0].1, Some(all_ok));
            assert_eq!(
                responses[1].1.and_then(|c| c.header_ok),
                Some(false),
                "source hit"
            );
            assert_eq!(
                responses[2].1.and_then(|c| c.header_ok),
                Some(false),
                "data hit"
            );
        }
    }

    #[test]
    fn a_cycle_start_is_known_good_as_built() {
        let bytes = super::super::cycle::cycle_start_packet(2, SimTime(987_654_321));
        let status = Packet::new_checked(&bytes[..]).unwrap().crc_status();
        assert_eq!(status, super::super::cycle::CYCLE_START_CRC);
    }
}
