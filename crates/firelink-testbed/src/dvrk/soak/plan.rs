//! The soak's fault plan: from the seed and the fault rate, the bus injector's
//! rules for every packet kind of the I/O cycle and the timed bus-level faults
//! (resets, a babbling board, an unplugged board), each remembered as an entry
//! to judge later.

use super::*;

pub(super) type Plan = (FaultPlan, Vec<Entry>);

/// The fault plan: packet rules for every target and kind, each with its
/// share of the fault rate, and the bus-level faults at seeded instants.
pub(super) fn fault_plan(
    settings: &SoakSettings,
    scale: f64,
    boards: &[NodeHandle],
    host: NodeHandle,
    start: SimTime,
) -> (Plan, Vec<Entry>) {
    let p = (settings.packet_fault_rate * scale).min(1.0) / Kind::PACKET.len() as f64;
    let mut plan = FaultPlan::new();
    let mut entries = Vec::new();
    let mut add = |matcher: PacketMatch, target: Target, board: Option<u8>| {
        for kind in Kind::PACKET {
            if let Some(fault) = kind.fault() {
                plan.rules
                    .push(FaultRule::random(matcher.clone(), fault, p));
                entries.push(Entry {
                    target,
                    kind,
                    board,
                });
            }
        }
    };
    let from_pc = PacketMatch::any().from(host);
    add(
        from_pc
            .clone()
            .tcode(Tcode::WriteQuadletRequest)
            .offset(HUB_QUERY_OFFSET as u16),
        Target::Query,
        None,
    );
    for (id, &b) in boards.iter().enumerate() {
        add(
            PacketMatch::any()
                .from(b)
                .tcode(Tcode::WriteBlockRequest)
                .to_phy(63),
            Target::Status,
            Some(id as u8),
        );
    }
    add(
        from_pc.clone().tcode(Tcode::ReadBlockRequest),
        Target::HubRequest,
        None,
    );
    add(
        PacketMatch::any()
            .tcode(Tcode::ReadBlockResponse)
            .kind(PacketKind::ConcatResponse),
        Target::HubResponse,
        None,
    );
    add(
        from_pc.tcode(Tcode::WriteBlockRequest),
        Target::Command,
        None,
    );

    // Bus-level faults at seeded instants, in order of time.
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed ^ 0x50A4_B05F);
    let period = SimDuration::from_micros_f64(settings.period.as_micros_f64());
    let span = period * settings.cycles;
    let every = period * settings.bus_fault_every.max(1);
    let mut timed = Vec::new();
    let mut t = start + SimDuration(every.0 / 2);
    while t < start + span {
        let board = rng.random_range(0..boards.len()) as u8;
        let node = boards.get(usize::from(board)).copied().unwrap_or(host);
        let (kind, fault) = match rng.random_range(0..3u8) {
            0 => (Kind::BusReset, TimedFault::BusReset),
            1 => (
                Kind::Babble,
                TimedFault::Babble {
                    node,
                    duration: SimDuration::from_micros(rng.random_range(20..=300)),
                    packet_len: 64,
                },
            ),
            _ => (
                Kind::Unplug,
                TimedFault::Disconnect {
                    node,
                    reconnect_after: Some(SimDuration::from_micros(
                        rng.random_range(1_000..=5_000),
                    )),
                },
            ),
        };
        plan.timed.push((t, fault));
        timed.push(Entry {
            target: Target::Bus,
            kind,
            board: Some(board),
        });
        let jitter = rng.random_range(0.5..1.5);
        t += SimDuration::from_micros_f64(every.as_micros_f64() * jitter);
    }
    ((plan, entries), timed)
}
