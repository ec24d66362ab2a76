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

    // ----- inspection ---------------------------------------------------------

    pub(super) fn timed_fault(&mut self, index: usize) {
        let Some(fault) = self.timed.get(index).cloned() else {
            return;
        };
        let now = self.now;
        match fault {
            TimedFault::Disconnect {
                node,
                reconnect_after,
            } => {
                let n = node.0;
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
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    Some(n),
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                self.reset_faults.push(id);
                self.start_reset(false, "cable unplugged (fault)".to_string());
                if let Some(d) = reconnect_after {
                    let links = links.into_boxed_slice();
                    self.push(now + d, None, Ev::Reconnect { links, fault: id });
                }
            }
            TimedFault::BusReset => {
                let what = "bus reset".to_string();
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    None,
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                self.reset_faults.push(id);
                self.start_reset(false, "bus reset (fault)".to_string());
            }
            TimedFault::StopAnswering { node, duration } => {
                let n = node.0;
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
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    Some(n),
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                let slot = &mut self.slots[n];
                slot.muted = true;
                slot.mute_fault = Some(id);
                slot.queue.clear();
                slot.timers.clear();
                if let Some(d) = duration {
                    self.push(now + d, None, Ev::Unmute { node: n });
                }
            }
            TimedFault::Babble {
                node,
                duration,
                packet_len,
            } => {
                let n = node.0;
                if n >= self.slots.len() {
                    return;
                }
                let len = packet_len.min(self.cfg.max_packet_len);
                let what = format!(
                    "{} babbles {len}-byte garbage for {duration}",
                    self.slots[n].name
                );
                let id = self.log.add(
                    now,
                    what.clone(),
                    None,
                    Some(n),
                    Some(FaultSource::Timed(index)),
                );
                self.log_event(TraceEvent::Fault { id, what });
                self.slots[n].babble = Some(BabbleState {
                    until: now + duration,
                    len,
                    fault: id,
                });
                self.push(now + duration, None, Ev::Arbitrate);
                if self.is_idle() {
                    self.schedule_arbitration(now);
                }
            }
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
