//! Faults on the bus: the plan (rules matched against every packet as it
//! is sent, decided by the injector in [`transmission`](super::transmission)),
//! timed faults applied at their instant (a cable unplugged and back, a
//! node that stops answering or babbles, a bus reset), and detections
//! recorded in the fault log.

use super::*;

impl Bus {
    /// Install a fault plan (added to any earlier rules and timed faults).
    pub fn set_fault_plan(&mut self, plan: FaultPlan) {
        for rule in plan.rules {
            self.injector.add_rule(rule);
        }
        for (at, fault) in plan.timed {
            self.schedule_fault(at, fault);
        }
    }

    /// Add one packet fault rule.
    pub fn add_fault_rule(&mut self, rule: FaultRule) {
        self.injector.add_rule(rule);
    }

    /// Change the chance of every packet fault rule by `factor` (clamped
    /// to 0..=1): a soak keeps the faulted share of packets where it wants
    /// it as the traffic mix changes.
    pub fn scale_fault_probabilities(&mut self, factor: f64) {
        self.injector.scale_probabilities(factor);
    }

    /// Schedule a timed fault.
    pub fn schedule_fault(&mut self, at: SimTime, fault: TimedFault) {
        self.timed.push(fault);
        let index = self.timed.len() - 1;
        self.push(at.max(self.now), None, Ev::Timed(index));
    }

    /// Every fault injected so far.
    pub fn fault_log(&self) -> &FaultLog {
        &self.log
    }

    /// Record that something above the bus (a host library, a test)
    /// detected fault `id`.
    pub fn record_detection(&mut self, id: FaultId, node: NodeHandle, what: impl Into<String>) {
        self.log.add_evidence(
            id,
            Evidence {
                time: self.now,
                node: node.0,
                kind: EvidenceKind::Report(what.into()),
            },
        );
    }

    pub(super) fn timed_fault(&mut self, index: usize) {
        let Some(fault) = self.timed.get(index).cloned() else {
            return;
        };
        match fault {
            TimedFault::Disconnect {
                node,
                reconnect_after,
            } => self.unplug(index, node.0, reconnect_after),
            TimedFault::BusReset => {
                let id = self.log_timed_fault(index, "bus reset".to_string(), None);
                self.reset_faults.push(id);
                self.start_reset(false, "bus reset (fault)".to_string());
            }
            TimedFault::StopAnswering { node, duration } => self.mute(index, node.0, duration),
            TimedFault::Babble {
                node,
                duration,
                packet_len,
            } => self.babble(index, node.0, duration, packet_len),
        }
    }

    /// Record timed fault `index` (at node `node`) in the log and the trace.
    fn log_timed_fault(&mut self, index: usize, what: String, node: Option<usize>) -> FaultId {
        let id = self.log.add(
            self.now,
            what.clone(),
            None,
            node,
            Some(FaultSource::Timed(index)),
        );
        self.log_event(TraceEvent::Fault { id, what });
        id
    }

    /// Unplug the cable between node `n` and its parent (the root: all its
    /// cables), reset, and plug it back after `reconnect_after`.
    fn unplug(&mut self, index: usize, n: usize, reconnect_after: Option<SimDuration>) {
        if n >= self.slots.len() {
            return;
        }
        let parent = self
            .tree
            .parent
            .get(n)
            .copied()
            .flatten()
            .filter(|_| self.slots[n].phy.is_some());
        let peers: Vec<usize> = match parent {
            Some(p) => vec![p],
            None => self.topo.neighbours(n).collect(),
        };
        let mut links = Vec::new();
        for p in peers {
            if let Some((pa, pb)) = self.topo.link_between(n, p) {
                if self.topo.disconnect(n, p).is_ok() {
                    links.push((n, pa, p, pb));
                }
            }
        }
        let what = format!(
            "unplug {} ({} cable(s)){}",
            self.slots[n].name,
            links.len(),
            reconnect_after
                .map(|d| format!(", plug back after {d}"))
                .unwrap_or_default()
        );
        let id = self.log_timed_fault(index, what, Some(n));
        self.reset_faults.push(id);
        self.start_reset(false, "cable unplugged (fault)".to_string());
        if let Some(d) = reconnect_after {
            let links = links.into_boxed_slice();
            self.push(self.now + d, None, Ev::Reconnect { links, fault: id });
        }
    }

    /// Node `n` stops answering: it hears nothing and sends nothing, for
    /// `duration` or for ever.
    fn mute(&mut self, index: usize, n: usize, duration: Option<SimDuration>) {
        if n >= self.slots.len() {
            return;
        }
        let what = format!(
            "{} stops answering{}",
            self.slots[n].name,
            duration
                .map(|d| format!(" for {d}"))
                .unwrap_or_else(|| " for ever".to_string())
        );
        let id = self.log_timed_fault(index, what, Some(n));
        let slot = &mut self.slots[n];
        slot.muted = true;
        slot.mute_fault = Some(id);
        slot.queue.clear();
        for (_, stamp, at) in std::mem::take(&mut slot.timers) {
            self.events.cancel_timer(at, stamp);
        }
        if let Some(d) = duration {
            self.push(self.now + d, None, Ev::Unmute { node: n });
        }
    }

    /// Node `n` sends garbage packets of `packet_len` bytes back to back
    /// for `duration`.
    fn babble(&mut self, index: usize, n: usize, duration: SimDuration, packet_len: usize) {
        if n >= self.slots.len() {
            return;
        }
        let now = self.now;
        let len = packet_len.min(self.cfg.max_packet_len);
        let what = format!(
            "{} babbles {len}-byte garbage for {duration}",
            self.slots[n].name
        );
        let id = self.log_timed_fault(index, what, Some(n));
        self.slots[n].babble = Some(BabbleState {
            until: now + duration,
            len,
            fault: id,
        });
        self.babbling = true;
        self.push(now + duration, None, Ev::Arbitrate);
        if self.is_idle() {
            self.schedule_arbitration(now);
        }
    }

    pub(super) fn reconnect(&mut self, links: &[(usize, u8, usize, u8)], fault: FaultId) {
        for &(a, pa, b, pb) in links {
            if let Err(e) = self.topo.connect_ports(a, pa, b, pb) {
                self.note(format!("could not plug the cable back: {e}"));
            }
        }
        self.reset_faults.push(fault);
        self.start_reset(false, "cable plugged back (fault)".to_string());
    }
}

#[cfg(test)]
mod tests {
    use super::super::probe::{chain, probe, qwrite, send};
    use super::*;

    #[test]
    fn a_node_that_stops_answering_is_silent_for_the_outage_only() {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        let now = bus.now();
        bus.schedule_fault(
            now,
            TimedFault::StopAnswering {
                node: nodes[1],
                duration: Some(SimDuration::from_micros(100)),
            },
        );
        let (p0, p1) = (bus.phy_id(nodes[0]).unwrap(), bus.phy_id(nodes[1]).unwrap());
        bus.run_for(SimDuration::from_nanos(1));
        send(&mut bus, nodes[0], qwrite(p0, p1), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        assert_eq!(probe(&bus, nodes[0]).transmitted[0].2, None, "no ack");
        assert!(probe(&bus, nodes[1]).received.is_empty());
        bus.run_for(SimDuration::from_micros(100));
        send(&mut bus, nodes[0], qwrite(p0, p1), ArbitrationClass::Fair);
        bus.run_for(SimDuration::from_micros(50));
        assert_eq!(probe(&bus, nodes[0]).transmitted[1].2, Some(Ack::Complete));
        let f = &bus.fault_log().records()[0];
        assert!(f.detected(), "the missing ack is the evidence: {f:?}");
    }

    #[test]
    fn a_cable_unplugged_and_back_resets_the_bus_twice() {
        let (mut bus, nodes) = chain(3, BusConfig::default());
        let g = bus.generation();
        let now = bus.now();
        bus.schedule_fault(
            now,
            TimedFault::Disconnect {
                node: nodes[2],
                reconnect_after: Some(SimDuration::from_micros(400)),
            },
        );
        bus.run_for(SimDuration::from_micros(300));
        assert_eq!(bus.generation(), g + 1);
        assert_eq!(bus.phy_id(nodes[2]), None, "off the bus");
        bus.run_until_idle();
        assert_eq!(bus.generation(), g + 2);
        assert!(bus.phy_id(nodes[2]).is_some(), "back");
        assert_eq!(probe(&bus, nodes[1]).resets.len(), 3);
    }

    #[test]
    fn a_detection_recorded_by_hand_completes_the_fault_record() {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        let now = bus.now();
        bus.schedule_fault(now, TimedFault::BusReset);
        bus.run_until_idle();
        let id = bus.fault_log().records()[0].id;
        bus.record_detection(id, nodes[0], "the host saw the new generation");
        let f = &bus.fault_log().records()[0];
        assert!(f.detected());
        assert!(bus.fault_log().undetected().is_empty());
    }
}
