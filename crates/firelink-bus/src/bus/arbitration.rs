//! Arbitration: when the bus has been idle for the gap a queued request's
//! class needs (isochronous, subaction, or the arbitration reset gap for a
//! fair request whose node already won in this fairness interval), its
//! request travels to the root; the first to arrive wins (ties: the node
//! nearer the root, then the lower physical ID) and the grant comes back.

use super::cycle::{CYCLE_START_CRC, cycle_start_packet};
use super::*;

impl Bus {
    pub(super) fn schedule_arbitration(&mut self, at: SimTime) {
        let at = at.max(self.now);
        if self.arb_at.is_none_or(|t| at < t) {
            self.arb_at = Some(at);
            self.push(at, None, Ev::Arbitrate);
        }
    }

    pub(super) fn needed_gap(&self, slot: &Slot, pending: &Pending) -> SimDuration {
        let t = &self.cfg.timing;
        let g = slot.regs.gap_count();
        if pending.kind == PacketKind::CycleStart {
            return t.subaction_gap(g);
        }
        match pending.class {
            ArbitrationClass::Isochronous => t.iso_gap,
            ArbitrationClass::Priority => t.subaction_gap(g),
            ArbitrationClass::Fair => {
                if self.cfg.fairness && !slot.arb_enable {
                    t.arb_reset_gap(g)
                } else {
                    t.subaction_gap(g)
                }
            }
        }
    }

    pub(super) fn refill_babblers(&mut self) {
        // No babbling node (every arbitration but under a babble fault):
        // nothing to look at.
        if !self.babbling {
            return;
        }
        let now = self.now;
        for i in 0..self.slots.len() {
            let Some(b) = self.slots[i].babble else {
                continue;
            };
            if now >= b.until {
                self.slots[i].babble = None;
                self.slots[i].queue.retain(|p| p.kind != PacketKind::Babble);
                continue;
            }
            if self.slots[i]
                .queue
                .iter()
                .any(|p| p.kind == PacketKind::Babble)
            {
                continue;
            }
            let mut bytes = vec![0u8; b.len];
            self.injector.rng.fill_bytes(&mut bytes);
            let speed = self.slots[i].cfg.max_speed;
            self.slots[i].queue.push_front(Pending {
                bytes,
                speed,
                class: ArbitrationClass::Isochronous,
                token: None,
                kind: PacketKind::Babble,
                ready_at: now,
                delayed: true,
                faults: vec![b.fault],
                crc: None,
            });
        }
        self.babbling = self.slots.iter().any(|s| s.babble.is_some());
    }

    /// The bus is idle: the node whose request reaches the root first
    /// (ties: a cycle start first, then the nearer node, the lower
    /// physical ID) wins, unless a delay fault sends its packet back to
    /// wait; the winner's packet starts after the arbitration time. If no
    /// request has reached the root yet, arbitration is scheduled for
    /// when the first will.
    pub(super) fn arbitrate(&mut self) {
        loop {
            let Medium::Idle { since } = self.medium else {
                return;
            };
            let now = self.now;
            self.refill_babblers();
            let Some(w) = self.first_request(since) else {
                return;
            };
            if w.at_root > now {
                self.schedule_arbitration(w.at_root);
                return;
            }
            // A new fairness interval for every PHY that saw an arbitration
            // reset gap.
            let idle = now - since;
            for slot in &mut self.slots {
                if idle >= self.cfg.timing.arb_reset_gap(slot.regs.gap_count()) {
                    slot.arb_enable = true;
                }
            }
            let Some(pending) = self.slots[w.idx].queue.pop_front() else {
                return;
            };
            // Delay faults first: the packet goes back to wait.
            let Some(pending) = self.delay_fault(w.idx, pending) else {
                continue;
            };
            self.grant(&w, pending);
            return;
        }
    }

    /// The request that reaches the root first, the bus idle since
    /// `since`.
    fn first_request(&self, since: SimTime) -> Option<Winner> {
        let hop = self.cfg.timing.hop_delay;
        // (arrival at root, not-urgent, depth, phy, index, eligible)
        let mut best: Option<(SimTime, u8, u32, u8, usize, SimTime)> = None;
        for (i, slot) in self.slots.iter().enumerate() {
            let (Some(phy), Some(p)) = (slot.phy, slot.queue.front()) else {
                continue;
            };
            if slot.muted {
                continue;
            }
            let eligible = p.ready_at.max(since + self.needed_gap(slot, p));
            let depth = self.tree.depth.get(i).copied().unwrap_or(0);
            let at_root = eligible + hop * u64::from(depth);
            let urgent = u8::from(p.kind != PacketKind::CycleStart);
            let key = (at_root, urgent, depth, phy, i, eligible);
            if best.is_none_or(|b| key < b) {
                best = Some(key);
            }
        }
        best.map(|(at_root, _, depth, phy, idx, eligible)| Winner {
            at_root,
            depth,
            phy,
            idx,
            eligible,
        })
    }

    /// A delay fault for node `idx`'s request `pending`, if one fires: the
    /// packet goes back to the front of its queue, ready later (`None`).
    /// Otherwise the packet.
    fn delay_fault(&mut self, idx: usize, mut pending: Pending) -> Option<Pending> {
        if self.injector.is_empty() || pending.delayed || pending.kind != PacketKind::Request {
            return Some(pending);
        }
        let now = self.now;
        let d = self
            .injector
            .decide_delay(NodeHandle(idx), pending.kind, &pending.bytes, now);
        let Some((delay, what, rule)) = d else {
            return Some(pending);
        };
        let source = rule.map(FaultSource::Rule);
        let id = self.log.add(now, what.clone(), None, Some(idx), source);
        self.log_event(TraceEvent::Fault { id, what });
        pending.delayed = true;
        pending.ready_at = now + delay;
        pending.faults.push(id);
        self.slots[idx].queue.push_front(pending);
        None
    }

    /// The winner `w` has the bus: its packet becomes a subaction (with
    /// the packet faults decided for it, a duplicate queued behind it)
    /// that starts on the wire after the arbitration time.
    fn grant(&mut self, w: &Winner, mut pending: Pending) {
        let now = self.now;
        let idx = w.idx;
        let start =
            now + self.cfg.timing.hop_delay * u64::from(w.depth) + self.cfg.timing.arbitration_base;
        if pending.kind == PacketKind::CycleStart {
            pending.bytes = cycle_start_packet(w.phy, start);
            pending.crc = Some(CYCLE_START_CRC);
        }
        if pending.class == ArbitrationClass::Fair && pending.kind != PacketKind::CycleStart {
            self.slots[idx].arb_enable = false;
        }
        self.medium = Medium::Busy;
        self.log_event(TraceEvent::Arbitration {
            node: idx,
            class: pending.class,
            requested: w.eligible,
        });
        let id = self.next_id;
        self.next_id += 1;
        let mut sub = Sub {
            id,
            kind: pending.kind,
            sender: idx,
            sender_phy: w.phy,
            bytes: std::mem::take(&mut pending.bytes),
            speed: pending.speed,
            token: pending.token,
            dest: None,
            reply: None,
            end: start,
            faults: std::mem::take(&mut pending.faults),
            drop_ack: false,
            corrupt_ack: false,
            busy: false,
            dropped: false,
            notified: false,
            crc: pending.crc,
            level: None,
            answers: None,
        };
        let (duplicate, original) = self.decide_faults(&mut sub, now);
        if duplicate {
            // The duplicate carries the packet as the node sent it.
            let bytes = original.unwrap_or_else(|| sub.bytes.clone());
            self.slots[idx].queue.push_front(Pending {
                bytes,
                speed: pending.speed,
                class: pending.class,
                token: None,
                kind: PacketKind::Duplicate,
                ready_at: now,
                delayed: true,
                faults: sub.faults.clone(),
                crc: None,
            });
        }
        self.subs.insert(id, sub);
        self.push_epoch(
            start,
            Ev::TxStart {
                sub: id,
                arb_start: Some(w.eligible),
                class: Some(pending.class),
            },
        );
    }
}

/// The request that wins arbitration.
struct Winner {
    /// When it reaches the root.
    at_root: SimTime,
    /// Its node's depth in the tree.
    depth: u32,
    /// Its node's physical ID.
    phy: u8,
    /// Its node's slot.
    idx: usize,
    /// When it was eligible to ask.
    eligible: SimTime,
}

#[cfg(test)]
mod tests {
    use super::super::probe::{chain, qwrite, send};
    use super::*;

    /// Node 0 (the root) and node 1 both ask for the bus at once with
    /// broadcasts: the records of the two packets, in wire order.
    fn contest(class1: ArbitrationClass) -> (Bus, Vec<PacketRecord>) {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        bus.run_for(SimDuration::from_micros(100));
        bus.trace_mut().clear();
        let (p0, p1) = (bus.phy_id(nodes[0]).unwrap(), bus.phy_id(nodes[1]).unwrap());
        send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
        send(&mut bus, nodes[1], qwrite(p1, 63), class1);
        bus.run_for(SimDuration::from_micros(100));
        let packets = bus.trace().packets().to_vec();
        (bus, packets)
    }

    #[test]
    fn at_a_tie_the_node_nearer_the_root_wins() {
        let (bus, packets) = contest(ArbitrationClass::Fair);
        assert_eq!(packets.len(), 2);
        assert_eq!(packets[0].sender, 0, "the root first");
        assert!(packets[1].start > packets[0].end);
        assert_eq!(bus.generation(), 1);
    }

    #[test]
    fn each_class_waits_its_gap_after_the_bus_goes_idle() {
        let t = BusTiming::default();
        for (class, gap) in [
            (ArbitrationClass::Isochronous, t.iso_gap),
            (ArbitrationClass::Priority, t.subaction_gap(63)),
            (ArbitrationClass::Fair, t.subaction_gap(63)),
        ] {
            let (_, packets) = contest(class);
            // The bus is idle once the data end has reached every node,
            // one hop from the sender here.
            let idle = packets[0].end + t.hop_delay;
            assert_eq!(packets[1].arb_start.unwrap() - idle, gap, "{class:?}");
            // The request then travels up one hop and the grant back.
            assert_eq!(
                packets[1].start - packets[1].arb_start.unwrap(),
                t.arbitration(1)
            );
        }
    }

    #[test]
    fn a_second_fair_request_waits_for_the_arbitration_reset_gap() {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        bus.run_for(SimDuration::from_micros(100));
        bus.trace_mut().clear();
        let p0 = bus.phy_id(nodes[0]).unwrap();
        send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
        send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(100));
        let p = bus.trace().packets();
        assert_eq!(p.len(), 2);
        let t = BusTiming::default();
        let idle = p[0].end + t.hop_delay;
        assert_eq!(p[1].arb_start.unwrap() - idle, t.arb_reset_gap(63));
    }
}
