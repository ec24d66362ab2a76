//! Bus reset and self-ID: queues flushed (their nodes told), the
//! generation incremented, the tree identified and numbered (post-order
//! from the root, children in port order, root highest), PHY
//! configuration packets applied (gap count, forced root), every node told
//! its new physical ID.

use super::*;

impl Bus {
    pub(super) fn apply_phy_config(&mut self, force_root: Option<u8>, gap_count: Option<u8>) {
        for slot in &mut self.slots {
            let Some(phy) = slot.phy else {
                continue;
            };
            if let Some(g) = gap_count {
                slot.regs.set_gap_count(g);
            }
            if let Some(r) = force_root {
                slot.regs.set_root_holdoff(phy == r);
            }
        }
        if gap_count.is_some() {
            self.gap_set_since_reset = true;
        }
        self.note(format!(
            "PHY configuration: gap count {gap_count:?}, force root {force_root:?}"
        ));
    }

    pub(super) fn start_reset(&mut self, short: bool, cause: String) {
        let now = self.now;
        self.detail.reset();
        self.epoch += 1;
        self.arb_at = None;
        self.started = true;
        for sub in self.subs.take_all() {
            if sub.kind == PacketKind::Request && !sub.notified {
                self.push(
                    now,
                    None,
                    Ev::Notify {
                        node: sub.sender,
                        token: sub.token,
                        kind: sub.kind,
                        ack: None,
                    },
                );
            }
        }
        self.flush_queues(|_| true);
        self.medium = Medium::Resetting;
        self.log_event(TraceEvent::ResetStart { cause, short });
        if !self.gap_set_since_reset {
            for slot in &mut self.slots {
                slot.regs.set_gap_count(DEFAULT_GAP_COUNT);
            }
        }
        self.gap_set_since_reset = false;
        let designated = self.root.unwrap_or(0);
        let component = self.topo.component(designated);
        let root = component
            .iter()
            .copied()
            .find(|&n| self.slots[n].regs.root_holdoff())
            .unwrap_or(designated);
        let speeds: Vec<Speed> = self.slots.iter().map(|s| s.cfg.max_speed).collect();
        self.tree = self.topo.tree(root, &speeds);
        let t = self.cfg.timing;
        let signal = if short { t.reset_short } else { t.reset_long };
        let tree_id = t.hop_delay * (2 * u64::from(self.tree.diameter()));
        let self_id = t.data_prefix + t.bits(PHY_PACKET_BITS, Speed::S100) + t.data_end;
        let count = self.tree.node_count() as u64;
        let done = now + signal + tree_id + (self_id + t.self_id_gap) * count;
        self.reset_began = now + signal + tree_id;
        self.push_epoch(done, Ev::ResetDone);
    }

    pub(super) fn flush_queues(&mut self, which: impl Fn(&Slot) -> bool) {
        let now = self.now;
        let mut flushed = Vec::new();
        for (i, slot) in self.slots.iter_mut().enumerate() {
            if !which(slot) {
                continue;
            }
            for p in slot.queue.drain(..) {
                if p.kind == PacketKind::Request {
                    flushed.push((i, p.token));
                }
            }
        }
        for (node, token) in flushed {
            self.push(
                now,
                None,
                Ev::Notify {
                    node,
                    token,
                    kind: PacketKind::Request,
                    ack: None,
                },
            );
        }
    }

    /// The bus reset and self-ID are over: a new generation, every node's
    /// physical ID from the tree, the self-ID packets in the trace, the
    /// reset's faults given their evidence, every node told; the cycle
    /// master starts if it is on, and arbitration resumes.
    pub(super) fn reset_done(&mut self) {
        let now = self.now;
        self.generation += 1;
        self.medium = Medium::Idle { since: now };
        let root = self.tree.root;
        let count = self.tree.node_count();
        for (i, slot) in self.slots.iter_mut().enumerate() {
            slot.phy = self.tree.phy_of.get(i).copied().flatten();
            slot.arb_enable = true;
            slot.regs.set_identity(
                slot.phy.unwrap_or(NodeId::BROADCAST_PHY),
                slot.phy.is_some() && i == root,
            );
        }
        if self.cfg.trace >= TraceLevel::Packets {
            self.record_self_ids();
        }
        let root_phy = count.saturating_sub(1) as u8;
        self.log_event(TraceEvent::ResetDone {
            generation: self.generation,
            node_count: count as u8,
            root_phy,
        });
        for f in std::mem::take(&mut self.reset_faults) {
            self.log.add_evidence(
                f,
                Evidence {
                    time: now,
                    node: root,
                    kind: EvidenceKind::BusReset {
                        generation: self.generation,
                    },
                },
            );
        }
        self.flush_queues(|s| s.phy.is_none());
        let generation = self.generation;
        for phy in 0..count {
            let node = self.tree.by_phy[phy];
            let info = ResetInfo {
                phy_id: phy as u8,
                generation,
                node_count: count as u8,
                root_phy_id: root_phy,
            };
            self.dispatch(node, |n, ctx| n.on_bus_reset(now, &info, ctx));
        }
        if self.cfg.cycle_master && !self.cycle_tick_scheduled {
            let period = self.cfg.timing.cycle_period.0.max(1);
            let next = SimTime((now.0 / period + 1) * period);
            self.cycle_tick_scheduled = true;
            self.push(next, None, Ev::CycleTick);
        }
        self.arbitrate();
    }

    /// The self-ID packets of the reset that just ended, one per node in
    /// physical-ID order at S100, for the record.
    fn record_self_ids(&mut self) {
        let t = self.cfg.timing;
        let mut at = self.reset_began;
        for phy in 0..self.tree.node_count() {
            let node = self.tree.by_phy[phy];
            let slot = &self.slots[node];
            let ports = &self.tree.port_status[node];
            let port = |k: usize| {
                ports
                    .get(k)
                    .copied()
                    .unwrap_or(firelink_wire::phy::PortStatus::NotPresent)
            };
            let packet = PhyPacket::SelfId(SelfId {
                phy_id: phy as u8,
                link_active: slot.regs.link_active(),
                gap_count: slot.regs.gap_count(),
                speed: slot.cfg.max_speed.code(),
                contender: slot.regs.contender(),
                power_class: 4,
                ports: [port(0), port(1), port(2)],
                initiated_reset: false,
            });
            let bits_end = at + t.data_prefix + t.bits(PHY_PACKET_BITS, Speed::S100);
            let end = bits_end + t.data_end;
            let id = self.next_id;
            self.next_id += 1;
            self.trace.packets.push(PacketRecord {
                id,
                kind: PacketKind::SelfId,
                sender: node,
                sender_phy: phy as u8,
                arb_start: None,
                class: None,
                start: at,
                bits_end,
                end,
                speed: Speed::S100,
                bytes: Arc::from(phy_packet_bytes(&packet)),
                answers: None,
                generation: self.generation,
                faults: Vec::new(),
            });
            at = end + t.self_id_gap;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::probe::{chain, probe, qwrite, send};
    use super::*;
    use crate::phy::phy_config_packet;

    #[test]
    fn self_id_numbers_the_chain_from_the_far_end_root_highest() {
        let (bus, nodes) = chain(4, BusConfig::default());
        // Node 0 is the root at one end of the chain: the far end is 0.
        let ids: Vec<u8> = nodes.iter().map(|&n| bus.phy_id(n).unwrap()).collect();
        assert_eq!(ids, vec![3, 2, 1, 0]);
        let info = probe(&bus, nodes[2]).resets[0];
        assert_eq!(
            (info.generation, info.node_count, info.root_phy_id),
            (1, 4, 3)
        );
    }

    #[test]
    fn each_reset_increments_the_generation_and_flushes_the_queues() {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        let p0 = bus.phy_id(nodes[0]).unwrap();
        // Queued, then a reset before it could go out.
        send(&mut bus, nodes[0], qwrite(p0, 63), ArbitrationClass::Fair);
        bus.initiate_reset(false);
        bus.run_until_idle();
        assert_eq!(bus.generation(), 2);
        assert_eq!(probe(&bus, nodes[1]).resets.len(), 2);
        let sent = &probe(&bus, nodes[0]).transmitted;
        assert_eq!(sent.len(), 1);
        assert_eq!(sent[0].2, None, "flushed: told, no ack");
        assert!(probe(&bus, nodes[1]).received.is_empty());
    }

    #[test]
    fn a_gap_count_set_by_phy_configuration_survives_one_reset_only() {
        let (mut bus, nodes) = chain(3, BusConfig::default());
        assert_eq!(bus.gap_count(nodes[1]), Some(DEFAULT_GAP_COUNT));
        send(
            &mut bus,
            nodes[0],
            phy_config_packet(Some(5), None),
            ArbitrationClass::Fair,
        );
        bus.run_until_idle();
        // Every PHY took it at the end of the subaction.
        assert!(nodes.iter().all(|&n| bus.gap_count(n) == Some(5)));
        bus.reset();
        bus.run_until_idle();
        assert_eq!(bus.gap_count(nodes[2]), Some(5), "kept over the reset");
        bus.reset();
        bus.run_until_idle();
        assert_eq!(
            bus.gap_count(nodes[2]),
            Some(DEFAULT_GAP_COUNT),
            "a reset without a new configuration returns to 63"
        );
    }
}
