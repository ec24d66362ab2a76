//! The event loop: events in a queue ordered by (virtual time, insertion
//! order), each one handled in turn, and the calls into nodes with the
//! commands they give back (transmit requests, timers, PHY register writes,
//! error reports) applied afterwards.

use super::*;

impl Bus {
    /// Time of the next event, if any.
    pub fn next_event_time(&self) -> Option<SimTime> {
        self.events.peek_time()
    }

    /// Process the next event (one delivery of a packet, at either level
    /// of detail). Returns false if there was none.
    pub fn step(&mut self) -> bool {
        self.step_batch(SimTime::MAX, Batch::One)
    }

    /// Process the next event if it comes at `deadline` or before (at the
    /// fast level, a delivery goes on with the packet's next ones while
    /// each is the next event: see [`detail`](super::detail)).
    /// Returns whether there was one.
    #[inline]
    pub(super) fn step_until(&mut self, deadline: SimTime) -> bool {
        self.step_batch(deadline, Batch::All)
    }

    /// [`step_until`](Self::step_until), a batch of deliveries going as
    /// far as `batch` says.
    #[inline]
    pub(super) fn step_batch(&mut self, deadline: SimTime, batch: Batch<'_>) -> bool {
        match self.events.pop_until(deadline) {
            Some(Taken::Delivery(d)) => {
                self.now = self.now.max(d.time);
                if d.epoch == self.epoch {
                    self.deliver_from(d, deadline, batch);
                }
                true
            }
            Some(Taken::Event(q)) => {
                self.now = self.now.max(q.time);
                if q.epoch.is_none_or(|e| e == self.epoch) {
                    self.handle(q.ev);
                }
                true
            }
            None => false,
        }
    }

    pub(super) fn push(&mut self, time: SimTime, epoch: Option<u64>, ev: Ev) {
        self.events.push(time, epoch, ev);
    }

    pub(super) fn push_epoch(&mut self, time: SimTime, ev: Ev) {
        self.push(time, Some(self.epoch), ev);
    }

    pub(super) fn log_event(&mut self, event: TraceEvent) {
        if self.cfg.trace >= TraceLevel::Normal {
            self.trace.entries.push(TraceEntry {
                time: self.now,
                event,
            });
        }
    }

    pub(super) fn note(&mut self, text: String) {
        self.log_event(TraceEvent::Note(text));
    }

    pub(super) fn handle(&mut self, ev: Ev) {
        match ev {
            Ev::Timer { node, token, stamp } => self.fire_timer(node, token, stamp),
            Ev::Arbitrate => {
                if self.arb_at == Some(self.now) {
                    self.arb_at = None;
                }
                self.arbitrate();
            }
            Ev::TxStart {
                sub,
                arb_start,
                class,
            } => self.tx_start(sub, arb_start, class),
            #[cfg(test)]
            Ev::Deliver { sub, node } => self.deliver(sub, node),
            Ev::AckStart { sub } => self.ack_start(sub),
            Ev::Notify {
                node,
                token,
                kind,
                ack,
            } => self.notify(node, token, kind, ack),
            Ev::SubEnd { sub } => self.sub_end(sub),
            Ev::ResetDone => self.reset_done(),
            Ev::CycleTick => self.cycle_tick(),
            Ev::Timed(i) => self.timed_fault(i),
            Ev::Reconnect { links, fault } => self.reconnect(&links, fault),
            Ev::PacketEnd(id) => self.log_event(TraceEvent::PacketEnd(id)),
            Ev::NoAck(info) => {
                let NoAckInfo {
                    packet,
                    node,
                    token,
                    kind,
                    faults,
                } = *info;
                self.log_event(TraceEvent::NoAck { packet });
                for f in faults {
                    self.log.add_evidence(
                        f,
                        Evidence {
                            time: self.now,
                            node,
                            kind: EvidenceKind::NoAck,
                        },
                    );
                }
                self.notify(node, token, kind, None);
            }
            Ev::Unmute { node } => {
                if let Some(s) = self.slots.get_mut(node) {
                    s.muted = false;
                }
                self.note(format!("{} answers again", self.trace.name_of(node)));
            }
        }
    }

    pub(super) fn dispatch_any<R>(
        &mut self,
        idx: usize,
        f: impl FnOnce(&mut dyn Node, &mut NodeCtx<'_>) -> R,
    ) -> Option<R> {
        let view = self.ctx_view();
        let Bus {
            slots,
            scratch,
            spare_packets,
            ..
        } = self;
        let (result, old_gap) = call_node(slots, (scratch, spare_packets), view, idx, f)?;
        self.after_call(idx, old_gap);
        Some(result)
    }

    /// What every node sees of the bus in a callback now.
    pub(super) fn ctx_view(&self) -> CtxView {
        CtxView {
            now: self.now,
            generation: self.generation,
            node_count: self.tree.node_count().min(63) as u8,
            bus_idle: matches!(self.medium, Medium::Idle { .. }),
            rx_crc: self.rx_crc,
        }
    }

    /// Carry out what node `idx` asked for in the call that just returned
    /// (its gap count `old_gap` before it), if it asked for anything.
    #[inline(always)]
    fn after_call(&mut self, idx: usize, old_gap: u8) {
        if !self.scratch.is_empty() {
            self.apply_scratch(idx, old_gap);
        }
    }

    /// Carry out what node `idx` did in the callback that just returned,
    /// as its command list says (leaving the list empty): its PHY
    /// register writes (its gap count was `old_gap` before), its reports,
    /// timers and transmit requests; a bus reset it asked for through
    /// IBR/ISBR starts last. Each of the list's vectors is taken out only
    /// when it holds something (its memory goes back, emptied).
    #[inline(never)]
    fn apply_scratch(&mut self, idx: usize, old_gap: u8) {
        let reset = self.apply_phy_registers(idx, old_gap);
        if !self.scratch.reports.is_empty() {
            let mut reports = std::mem::take(&mut self.scratch.reports);
            for report in reports.drain(..) {
                self.apply_report(idx, report);
            }
            self.scratch.reports = reports;
        }
        if !self.scratch.timers.is_empty() {
            let mut timers = std::mem::take(&mut self.scratch.timers);
            for cmd in timers.drain(..) {
                self.apply_timer(idx, cmd);
            }
            self.scratch.timers = timers;
        }
        let mut want_arb = false;
        if !self.scratch.transmits.is_empty() {
            let mut transmits = std::mem::take(&mut self.scratch.transmits);
            for (req, crc) in transmits.drain(..) {
                want_arb |= self.queue_transmit(idx, req, crc);
            }
            self.scratch.transmits = transmits;
        }
        self.scratch.phy_writes.clear();
        if want_arb && self.is_idle() {
            self.schedule_arbitration(self.now);
        }
        if let Some(short) = reset {
            self.start_reset(short, format!("{} set IBR/ISBR", self.slots[idx].name));
        }
    }

    /// Hand node `idx` (unless it stopped answering) the packet of the
    /// subaction at `pos` in the table, as it arrives now at `speed`: the
    /// bytes are lent from the subaction, not copied. What the node asked
    /// for is carried out after the call.
    #[inline(always)]
    pub(super) fn dispatch_receive(
        &mut self,
        idx: usize,
        pos: usize,
        speed: Speed,
    ) -> Option<RxReply> {
        self.dispatch_receive_in(self.ctx_view(), idx, pos, speed)
    }

    /// [`dispatch_receive`](Self::dispatch_receive) with what the node sees
    /// of the bus, `view`, already taken (a batch takes it once: its
    /// deliveries differ only in time, as nothing else a node sees
    /// changes but through a bus reset, which ends the batch).
    #[inline(always)]
    pub(super) fn dispatch_receive_in(
        &mut self,
        view: CtxView,
        idx: usize,
        pos: usize,
        speed: Speed,
    ) -> Option<RxReply> {
        if self.slots.get(idx).is_none_or(|s| s.muted) {
            return None;
        }
        debug_assert_eq!(view, self.ctx_view(), "a batch's view of the bus");
        let now = view.now;
        let Bus {
            slots,
            scratch,
            spare_packets,
            subs,
            ..
        } = self;
        let bytes = &subs.0.get(pos)?.bytes[..];
        let (reply, old_gap) = call_node(slots, (scratch, spare_packets), view, idx, |n, ctx| {
            n.on_receive(now, bytes, speed, ctx)
        })?;
        self.after_call(idx, old_gap);
        Some(reply)
    }

    /// Dispatch to a node unless it stopped answering.
    pub(super) fn dispatch<R>(
        &mut self,
        idx: usize,
        f: impl FnOnce(&mut dyn Node, &mut NodeCtx<'_>) -> R,
    ) -> Option<R> {
        if self.slots.get(idx).is_none_or(|s| s.muted) {
            return None;
        }
        self.dispatch_any(idx, f)
    }

    /// Node `idx`'s PHY registers as a callback left them (its gap count
    /// was `old_gap` before): a gap-count change is noted, IBR and ISBR
    /// are taken. Returns the bus reset it asked for: `Some(false)` a long
    /// one (IBR), `Some(true)` a short one (ISBR only).
    fn apply_phy_registers(&mut self, idx: usize, old_gap: u8) -> Option<bool> {
        let slot = &mut self.slots[idx];
        let mut reset = None;
        if slot.regs.take_ibr() {
            reset = Some(false);
        }
        if slot.regs.take_isbr() {
            reset = reset.or(Some(true));
        }
        if slot.regs.gap_count() != old_gap {
            let text = format!(
                "{} gap count {} -> {} (register write)",
                slot.name,
                old_gap,
                slot.regs.gap_count()
            );
            self.note(text);
        }
        reset
    }

    /// A node's report about the packet it is receiving (evidence for
    /// the faults that packet carries).
    fn apply_report(&mut self, idx: usize, report: String) {
        let packet = self.current_rx;
        if let Some(sub) = packet.and_then(|p| self.subs.get(&p)) {
            for &f in &sub.faults {
                self.log.add_evidence(
                    f,
                    Evidence {
                        time: self.now,
                        node: idx,
                        kind: EvidenceKind::Report(report.clone()),
                    },
                );
            }
        }
        self.log_event(TraceEvent::Report {
            node: idx,
            text: report,
            packet,
        });
    }

    /// A node sets or cancels a timer (a timer set for the past fires now).
    fn apply_timer(&mut self, idx: usize, cmd: TimerCommand) {
        match cmd {
            TimerCommand::Set { at, token } => {
                let at = at.max(self.now);
                // Set again for the same instant: the timer already armed
                // stands (no second event).
                let timers = &mut self.slots[idx].timers;
                if let Some(i) = timers.iter().position(|t| t.0 == token) {
                    let (_, stamp, armed) = timers.swap_remove(i);
                    if armed == at {
                        timers.push((token, stamp, armed));
                        return;
                    }
                    self.events.cancel_timer(armed, stamp);
                }
                let stamp = self.events.push_timer(at, idx, token);
                self.slots[idx].timers.push((token, stamp, at));
            }
            TimerCommand::Cancel { token } => {
                let timers = &mut self.slots[idx].timers;
                if let Some(i) = timers.iter().position(|t| t.0 == token) {
                    let (_, stamp, armed) = timers.swap_remove(i);
                    self.events.cancel_timer(armed, stamp);
                }
            }
        }
    }

    /// Queue node `idx`'s packet for arbitration (its CRC status `crc`
    /// when known), or refuse it (too long, node muted or off the bus: the
    /// node is told at once). Returns whether it was queued.
    fn queue_transmit(&mut self, idx: usize, req: TransmitRequest, crc: Option<CrcStatus>) -> bool {
        let now = self.now;
        let TransmitRequest {
            packet,
            speed,
            class,
            token,
        } = req;
        let slot = &self.slots[idx];
        let refuse = if packet.len() > self.cfg.max_packet_len {
            Some(format!(
                "{} bytes is longer than the bus accepts",
                packet.len()
            ))
        } else if slot.muted {
            Some("node stopped answering".to_string())
        } else if slot.phy.is_none() && self.medium != Medium::Resetting {
            Some("node is not on the bus".to_string())
        } else {
            None
        };
        if let Some(why) = refuse {
            let text = format!("{}: transmit refused: {why}", slot.name);
            self.note(text);
            self.push(
                now,
                None,
                Ev::Notify {
                    node: idx,
                    token: Some(token),
                    kind: PacketKind::Request,
                    ack: None,
                },
            );
            return false;
        }
        self.slots[idx].queue.push_back(Pending {
            bytes: packet,
            speed,
            class,
            token: Some(token),
            kind: PacketKind::Request,
            ready_at: now,
            delayed: false,
            faults: Vec::new(),
            crc,
        });
        true
    }

    pub(super) fn fire_timer(&mut self, node: usize, token: u64, stamp: u64) {
        let Some(slot) = self.slots.get_mut(node) else {
            return;
        };
        let Some(i) = slot
            .timers
            .iter()
            .position(|t| t.0 == token && t.1 == stamp)
        else {
            return;
        };
        slot.timers.swap_remove(i);
        let now = self.now;
        self.dispatch(node, |n, ctx| n.on_timer(now, token, ctx));
    }

    pub(super) fn notify(
        &mut self,
        node: usize,
        token: Option<u64>,
        kind: PacketKind,
        ack: Option<Ack>,
    ) {
        let now = self.now;
        match (kind, token) {
            (PacketKind::Request, Some(token)) => {
                self.dispatch(node, |n, ctx| n.on_transmitted(now, token, ack, ctx));
            }
            (PacketKind::ConcatResponse, _) => {
                self.dispatch(node, |n, ctx| n.on_response_acked(now, ack, ctx));
            }
            _ => {}
        }
    }
}

/// How far a batch of a packet's deliveries may go at the fast level (see
/// [`detail`](super::detail)), besides the queue's order and the deadline.
pub(super) enum Batch<'a> {
    /// One delivery (a single step).
    One,
    /// As far as the queue's order allows.
    All,
    /// Until the condition holds after a delivery (a caller that checks
    /// it before every event).
    Until(&'a mut dyn FnMut(&Bus) -> bool),
}

/// The bus's state a [`NodeCtx`] shows, taken before the call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct CtxView {
    pub(super) now: SimTime,
    generation: u32,
    node_count: u8,
    bus_idle: bool,
    rx_crc: Option<CrcStatus>,
}

/// Call `f` on node `idx` of `slots` with a [`NodeCtx`] over `view` (and
/// the bus's spare packet buffers); what it asks for goes into `scratch`, and its PHY register writes into its
/// registers at once. Returns its result and its gap count before the
/// call (`None`: no such node, or it is in a call already).
#[inline(always)]
fn call_node<R>(
    slots: &mut [Slot],
    (scratch, spare_packets): (&mut Commands, &mut PacketPool),
    view: CtxView,
    idx: usize,
    f: impl FnOnce(&mut dyn Node, &mut NodeCtx<'_>) -> R,
) -> Option<(R, u8)> {
    // The node, its PHY registers, its timers and the command list are
    // disjoint parts of the bus: borrowed side by side, nothing moves.
    // The registers change only through `write_phy_register`, which
    // also lists the write: a callback that asked for nothing left
    // them as they were, and one that wrote them is applied at once
    // after the call (`apply_scratch`).
    let slot = slots.get_mut(idx)?;
    let node = slot.node.as_mut()?;
    slot.dispatches += 1;
    let old_gap = slot.regs.gap_count();
    let phy_id = slot.phy.unwrap_or(NodeId::BROADCAST_PHY);
    let mut ctx = NodeCtx {
        now: view.now,
        rx_crc: view.rx_crc,
        phy_id,
        generation: view.generation,
        node_count: view.node_count,
        bus_idle: view.bus_idle,
        timers: &slot.timers,
        regs: &mut slot.regs,
        cmds: scratch,
        spare_packets,
    };
    let result = f(node.as_mut(), &mut ctx);
    Some((result, old_gap))
}

#[cfg(test)]
mod tests {
    use super::super::probe::{Probe, chain, probe, qwrite};
    use super::*;

    #[test]
    fn an_empty_queue_has_nothing_to_step() {
        let mut bus = Bus::new(BusConfig::default());
        assert_eq!(bus.next_event_time(), None);
        assert!(!bus.step());
        assert!(bus.run_until_idle());
    }

    #[test]
    fn timers_fire_in_time_then_in_the_order_they_were_set() {
        let (mut bus, nodes) = chain(1, BusConfig::default());
        let at = bus.now() + SimDuration::from_micros(10);
        bus.with_node::<Probe, _>(nodes[0], |_, ctx| {
            ctx.set_timer(at + SimDuration::from_micros(1), 3);
            ctx.set_timer(at, 2);
            ctx.set_timer(at, 1);
            ctx.set_timer(at, 9);
            ctx.cancel_timer(9);
        })
        .unwrap();
        bus.run_for(SimDuration::from_micros(20));
        let fired: Vec<(SimTime, u64)> = probe(&bus, nodes[0]).timers.clone();
        assert_eq!(
            fired,
            vec![(at, 2), (at, 1), (at + SimDuration::from_micros(1), 3)]
        );
    }

    #[test]
    fn timer_pair_sees_what_two_timer_calls_see() {
        let (mut bus, nodes) = chain(1, BusConfig::default());
        let t0 = bus.now();
        let (a, b) = (
            t0 + SimDuration::from_micros(5),
            t0 + SimDuration::from_micros(9),
        );
        bus.with_node::<Probe, _>(nodes[0], |_, ctx| {
            ctx.set_timer(b, 2);
            ctx.set_timer(a, 1);
        })
        .unwrap();
        let seen = bus
            .with_node::<Probe, _>(nodes[0], |_, ctx| {
                [(1, 2), (2, 1), (1, 1), (1, 7), (7, 2)]
                    .map(|(x, y)| (ctx.timer_pair(x, y), (ctx.timer(x), ctx.timer(y))))
            })
            .unwrap();
        for (pair, two) in seen {
            assert_eq!(pair, two);
        }
        assert_eq!(seen[0].0, (Some(a), Some(b)));
        assert_eq!(seen[3].0, (Some(a), None));
    }

    #[test]
    fn a_timer_set_again_fires_once_at_its_new_time() {
        let (mut bus, nodes) = chain(1, BusConfig::default());
        let t0 = bus.now();
        bus.with_node::<Probe, _>(nodes[0], |_, ctx| {
            ctx.set_timer(t0 + SimDuration::from_micros(5), 4);
            ctx.set_timer(t0 + SimDuration::from_micros(8), 4);
        })
        .unwrap();
        bus.run_for(SimDuration::from_micros(20));
        assert_eq!(
            probe(&bus, nodes[0]).timers,
            vec![(t0 + SimDuration::from_micros(8), 4)]
        );
    }

    #[test]
    fn dispatch_counts_move_only_when_the_bus_calls_into_the_node() {
        let (mut bus, nodes) = chain(2, BusConfig::default());
        let (a, b) = (nodes[0], nodes[1]);
        let before = (bus.dispatch_count(a), bus.dispatch_count(b));
        let at = bus.now() + SimDuration::from_micros(5);
        bus.with_node::<Probe, _>(a, |_, ctx| ctx.set_timer(at, 1))
            .unwrap();
        assert_eq!(bus.dispatch_count(a), before.0 + 1);
        bus.run_for(SimDuration::from_micros(3));
        assert_eq!(bus.dispatch_count(a), before.0 + 1, "nothing due yet");
        bus.run_for(SimDuration::from_micros(10));
        assert_eq!(bus.dispatch_count(a), before.0 + 2, "the timer fired");
        assert_eq!(bus.dispatch_count(b), before.1, "b was never called");
        assert_eq!(bus.dispatch_count(NodeHandle(99)), 0);
        let mut seen = None;
        assert!(bus.called_since(a, &mut seen), "never looked at");
        assert!(!bus.called_since(a, &mut seen), "no call since");
    }

    #[test]
    fn what_a_node_asks_for_in_a_callback_happens_after_it() {
        // A timer callback transmits: the packet goes out and is received.
        let (mut bus, nodes) = chain(2, BusConfig::default());
        let dst = bus.phy_id(nodes[1]).unwrap();
        let src = bus.phy_id(nodes[0]).unwrap();
        let at = bus.now() + SimDuration::from_micros(3);
        bus.with_node::<Probe, _>(nodes[0], |p, ctx| {
            p.on_timer_send.push((5, qwrite(src, dst)));
            ctx.set_timer(at, 5);
        })
        .unwrap();
        bus.run_for(SimDuration::from_micros(50));
        let received = &probe(&bus, nodes[1]).received;
        assert_eq!(received.len(), 1);
        assert!(received[0].0 > at);
        assert_eq!(probe(&bus, nodes[0]).transmitted[0].2, Some(Ack::Complete));
    }
}
