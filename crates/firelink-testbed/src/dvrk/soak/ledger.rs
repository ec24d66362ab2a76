//! The soak's running ledger: what the host saw each cycle, the commands it
//! sent, the faults still waiting for their cycle, the safety invariants checked
//! from the boards' own state after every cycle, and the re-arming after each
//! fault the robot raises.

use super::*;

/// One plan entry: what it targets and what it does.
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    pub(super) target: Target,
    pub(super) kind: Kind,
    /// The board concerned (status broadcasts, babble, unplug).
    pub(super) board: Option<u8>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Verdict {
    Detected,
    Harmless(Harmless),
    Undetected,
}

/// How a fault was shown harmless.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Harmless {
    /// Every board's data the host used in the cycles it could touch was
    /// proven this cycle's (sequence numbers, CRCs, board IDs, sizes).
    Fresh,
    /// The host rejected the whole cycle for another fault it detected:
    /// nothing of that cycle was used.
    Masked,
    /// A command lost or late: every board held the host's command again
    /// one or two periods later (broadcasts are never acknowledged).
    CommandHeld,
    /// A hub response the host did not need: its hub read completed with
    /// another, valid response (the faulted one answered a duplicated
    /// request).
    Spare,
}

/// A logged fault waiting for the cycles that show its effect.
#[derive(Debug, Clone)]
pub(super) struct Pending {
    pub(super) entry: Entry,
    pub(super) time: Duration,
    pub(super) what: String,
    /// Its record in the bus's fault log.
    pub(super) id: FaultId,
}

/// What one cycle showed, kept for judging faults.
#[derive(Debug, Clone, Copy)]
pub(super) struct Seen {
    pub(super) report: CycleReport,
    /// Every board held the host's latest command (or, still in flight,
    /// the one before) after this cycle.
    pub(super) commands_converged: bool,
    /// The bus generation after this cycle.
    pub(super) generation: u32,
    /// Bus resets the host has noticed so far (in cycles or between them).
    pub(super) resets_noticed: u64,
}

/// Commands sent to one axis recently (the DAC codes), newest last.
pub(super) const COMMAND_MEMORY: usize = 6;

pub(super) struct Soak {
    pub(super) entries: Vec<Entry>,
    pub(super) timed: Vec<Entry>,
    pub(super) boards: Vec<NodeHandle>,
    pub(super) seen_faults: usize,
    pub(super) pending: Vec<Pending>,
    /// The last faults logged, judged or not (to name a fault's company).
    pub(super) recent: VecDeque<Pending>,
    pub(super) cycles: VecDeque<Seen>,
    pub(super) sent: Vec<[[u16; COMMAND_MEMORY]; 4]>,
    pub(super) report: SoakReport,
}

impl Soak {
    pub(super) fn new(settings: &SoakSettings, boards: Vec<NodeHandle>) -> Soak {
        let n = boards.len();
        Soak {
            entries: Vec::new(),
            timed: Vec::new(),
            boards,
            seen_faults: 0,
            pending: Vec::new(),
            recent: VecDeque::with_capacity(64),
            cycles: VecDeque::with_capacity(64),
            sent: vec![[[0u16; COMMAND_MEMORY]; 4]; n],
            report: SoakReport {
                cycles: 0,
                seed: settings.seed,
                detail: DetailReport::default(),
                period_us: settings.period.as_micros_f64(),
                virtual_s: 0.0,
                packets: 0,
                injected: 0,
                packet_fault_share: 0.0,
                detected: 0,
                harmless: 0,
                harmless_fresh: 0,
                harmless_masked: 0,
                harmless_command_held: 0,
                harmless_spare: 0,
                undetected: 0,
                bad_commands_applied: 0,
                amplifier_on_after_off: 0,
                disable_pending_cycles: 0,
                robot_faults: 0,
                rearms: 0,
                by_kind: BTreeMap::new(),
                by_fault: BTreeMap::new(),
                undetected_examples: Vec::new(),
            },
        }
    }

    /// Bring a robot that is not Active back: settle in Fault a few cycles
    /// (outputs off), clear, configure, power, enable, move.
    pub(super) fn rearm(&mut self, robot: &mut Robot<IoSystem<SimPort>>, config: &IoConfig) {
        // A few cycles in the current state first (the boards see the safe
        // outputs; a reconnecting board has time to come back).
        for _ in 0..6 {
            let _ = robot.step(Pacing::Virtual);
            self.observe(robot);
        }
        if robot.state() == State::Fault {
            let _ = robot.clear_fault();
        }
        let _ = robot.io_mut().recover();
        let _ = config;
        if robot.state() == State::Unconfigured && robot.configure().is_err() {
            return;
        }
        if robot.state() == State::Configured {
            let mut each = |r: &Robot<IoSystem<SimPort>>| self.observe(r);
            if robot.power_on_observed(&mut each).is_err() {
                return;
            }
            if robot.activate().is_ok() {
                move_joints(robot);
                self.report.rearms += 1;
            }
        }
    }

    /// After every cycle: the safety invariants from the boards' own
    /// state, the cycle's report, and the faults the bus logged.
    pub(super) fn observe(&mut self, robot: &Robot<IoSystem<SimPort>>) {
        let Some(report) = robot.last_report().copied() else {
            return;
        };
        let bus = robot.io().port().bus();
        let in_fault = robot.state() == State::Fault;
        let acknowledged = robot.disable_acknowledged();
        let mut converged = true;
        let mut pending_disable = false;
        for (slot, &handle) in self.boards.iter().enumerate() {
            let Some(fw) = bus.node::<BoardNode>(handle).map(BoardNode::firmware) else {
                continue;
            };
            let id = fw.board_id();
            let host = robot.io().board(id).map(|b| b.output());
            let Some(sent) = self.sent.get_mut(slot) else {
                continue;
            };
            for axis in 0..4usize {
                let applied = fw.axis_command(axis).unwrap_or(0);
                if let (Some(out), Some(memory)) = (host, sent.get_mut(axis)) {
                    let now = out.dac.get(axis).map_or(0, |d| d.command());
                    if memory.last() != Some(&now) {
                        memory.rotate_left(1);
                        if let Some(last) = memory.last_mut() {
                            *last = now;
                        }
                    }
                    if !memory.contains(&applied) {
                        self.report.bad_commands_applied += 1;
                    }
                    // The latest command, or the one before when the
                    // latest broadcast is still on its way (a cycle that
                    // overran its period is observed before its command
                    // has arrived).
                    let previous = memory.get(COMMAND_MEMORY - 2).copied();
                    converged &= applied == now || Some(applied) == previous;
                }
                if in_fault && fw.amplifier_on(axis) {
                    if acknowledged & (1 << id) != 0 {
                        self.report.amplifier_on_after_off += 1;
                    } else {
                        pending_disable = true;
                    }
                }
            }
        }
        self.report.disable_pending_cycles += u64::from(pending_disable);
        if self.cycles.len() == self.cycles.capacity() {
            self.cycles.pop_front();
        }
        self.cycles.push_back(Seen {
            report,
            commands_converged: converged,
            generation: bus.generation(),
            resets_noticed: robot.io().stats().bus_resets,
        });
        // New faults from the bus's log.
        let records = bus.fault_log().records();
        for r in records.iter().skip(self.seen_faults) {
            let entry = match r.source {
                Some(FaultSource::Rule(i)) => self.entries.get(i).copied(),
                Some(FaultSource::Timed(i)) => self.timed.get(i).copied(),
                None => None,
            };
            if let Some(entry) = entry {
                let p = Pending {
                    entry,
                    time: Duration::from_nanos(r.time.0 / 1000),
                    what: r.what.clone(),
                    id: r.id,
                };
                if self.recent.len() == self.recent.capacity() {
                    self.recent.pop_front();
                }
                self.recent.push_back(p.clone());
                self.pending.push(p);
            }
        }
        self.seen_faults = records.len();
        let log = bus.fault_log();
        let host = robot.io().port().host();
        self.judge_all(report.cycle, log, host);
    }

    /// Set the command memory to what the host sends now.
    pub(super) fn remember_commands(&mut self, robot: &Robot<IoSystem<SimPort>>) {
        let bus = robot.io().port().bus();
        for (slot, &handle) in self.boards.iter().enumerate() {
            let Some(fw) = bus.node::<BoardNode>(handle).map(BoardNode::firmware) else {
                continue;
            };
            let out = robot.io().board(fw.board_id()).map(|b| b.output());
            if let (Some(out), Some(sent)) = (out, self.sent.get_mut(slot)) {
                for (axis, memory) in sent.iter_mut().enumerate() {
                    let applied = fw.axis_command(axis).unwrap_or(0);
                    let now = out.dac.get(axis).map_or(0, |d| d.command());
                    *memory = [applied; COMMAND_MEMORY];
                    if let Some(last) = memory.last_mut() {
                        *last = now;
                    }
                }
            }
        }
    }

    /// Judge the pending faults whose effect cycles are over (all of them
    /// with `u64::MAX`).
    pub(super) fn judge_all(&mut self, last_cycle: u64, log: &FaultLog, host: NodeHandle) {
        let mut keep = Vec::new();
        for p in std::mem::take(&mut self.pending) {
            // The cycle the fault hit: the last one started at or before it.
            let hit = self
                .cycles
                .iter()
                .rev()
                .find(|s| s.report.started <= p.time)
                .map(|s| s.report.cycle);
            let Some(hit) = hit else {
                // Before any cycle we still remember: judge against the
                // oldest we have.
                let oldest = self.cycles.front().map_or(0, |s| s.report.cycle);
                self.judge(&p, oldest, host_rejected(log, p.id, host));
                continue;
            };
            // Wait for the cycles after it (a lost command shows one period
            // later; a bus-level fault lasts a while).
            let span = match p.entry.kind {
                Kind::Unplug | Kind::Babble => 4,
                _ => 2,
            };
            if last_cycle != u64::MAX && last_cycle < hit + span {
                keep.push(p);
                continue;
            }
            self.judge(&p, hit, host_rejected(log, p.id, host));
        }
        self.pending = keep;
    }

    pub(super) fn judge(&mut self, p: &Pending, hit: u64, rejected_by_host: bool) {
        let others: Vec<String> = self
            .recent
            .iter()
            .filter(|o| o.time != p.time)
            .filter(|o| {
                self.cycles
                    .iter()
                    .rev()
                    .find(|s| s.report.started <= o.time)
                    .is_some_and(|s| s.report.cycle == hit)
            })
            .map(|o| format!("{} on {:?}", o.what, o.entry.target))
            .collect();
        let window: Vec<Seen> = self
            .cycles
            .iter()
            .filter(|s| s.report.cycle >= hit && s.report.cycle <= hit + 3)
            .copied()
            .collect();
        // Resets the host had noticed before the hit cycle.
        let resets_before = self
            .cycles
            .iter()
            .rev()
            .find(|s| s.report.cycle < hit)
            .or(window.first())
            .map_or(0, |s| s.resets_noticed);
        let verdict = if rejected_by_host && p.entry.target == Target::HubResponse {
            // A response the host's link itself refused (its CRC failed,
            // or it answered nothing the host had asked, e.g. the second
            // answer to a duplicated request): the host never used it.
            Verdict::Detected
        } else {
            verdict(&p.entry, &window, resets_before)
        };
        let key = p.entry.kind.name().to_string();
        self.report
            .by_kind
            .entry(key.clone())
            .or_default()
            .add(verdict);
        let target = match p.entry.target {
            Target::Query => "query",
            Target::Status => "status",
            Target::HubRequest => "hub_request",
            Target::HubResponse => "hub_response",
            Target::Command => "command",
            Target::Bus => "bus",
        };
        self.report
            .by_fault
            .entry(format!("{key}/{target}"))
            .or_default()
            .add(verdict);
        self.report.injected += 1;
        match verdict {
            Verdict::Detected => self.report.detected += 1,
            Verdict::Harmless(how) => {
                self.report.harmless += 1;
                match how {
                    Harmless::Fresh => self.report.harmless_fresh += 1,
                    Harmless::Masked => self.report.harmless_masked += 1,
                    Harmless::CommandHeld => self.report.harmless_command_held += 1,
                    Harmless::Spare => self.report.harmless_spare += 1,
                }
            }
            Verdict::Undetected => {
                self.report.undetected += 1;
                if self.report.undetected_examples.len() < 10 {
                    let reports: Vec<String> = window
                        .iter()
                        .map(|s| {
                            format!(
                                "cycle {}: missed {:#06x} {:?} error {:?}{}, bus generation {}",
                                s.report.cycle,
                                s.report.missed,
                                s.report.reasons.iter().flatten().next(),
                                s.report.error,
                                if s.report.bus_reset {
                                    ", bus reset"
                                } else {
                                    ""
                                },
                                s.generation
                            )
                        })
                        .collect();
                    self.report.undetected_examples.push(format!(
                        "{} on {target} (board {:?}) at {:?} in cycle {hit}: {}; other faults then: {:?}",
                        p.what,
                        p.entry.board,
                        p.time,
                        if reports.is_empty() {
                            "no cycle seen".to_string()
                        } else {
                            reports.join("; ")
                        },
                        others
                    ));
                }
            }
        }
    }
}
