//! The judgement of one logged fault against what the host saw in the cycle it
//! hit (and the next): detected with the reason the fault must produce, harmless
//! because the data was proven fresh or the command was held again, or
//! undetected.

use super::*;

/// Whether the PC's link refused the packet this fault damaged (the bus
/// records what noticed each fault).
pub(super) fn host_rejected(log: &FaultLog, id: FaultId, host: NodeHandle) -> bool {
    log.get(id).is_some_and(|r| {
        r.evidence
            .iter()
            .any(|e| e.node == host.0 && matches!(e.kind, EvidenceKind::Report(_)))
    })
}

/// The board's block in the hub was not this cycle's: an old sequence
/// number, none at all, a corrupt query flagged, or (the hub packs blocks
/// in arrival order) another board's block or the wrong size in its place.
pub(super) fn stale(reason: Option<MissReason>) -> bool {
    matches!(
        reason,
        Some(
            MissReason::Sequence { .. }
                | MissReason::NotUpdated
                | MissReason::CorruptQuery
                | MissReason::WrongBoardId { .. }
                | MissReason::BlockSize { .. }
        )
    )
}

pub(super) fn missed(report: &CycleReport, board: u8) -> Option<MissReason> {
    if report.missed & (1 << board) == 0 {
        return None;
    }
    report.reasons.get(usize::from(board)).copied().flatten()
}

/// Whether `report` shows what a fault of `entry` must produce: the
/// host's own reason for the cycle.
pub(super) fn shows(entry: &Entry, report: &CycleReport) -> bool {
    // Some board's block was not this cycle's (sequence numbers).
    let any_stale = report.reasons.iter().any(|r| stale(*r));
    let timeout = matches!(report.error, Some(HostError::Timeout { .. }));
    let bad_packet = matches!(report.error, Some(HostError::Wire(_)));
    let nack = matches!(report.error, Some(HostError::Ack { .. }));
    let reset = report.bus_reset;
    // A late or repeated packet shifts the cycle's timing: what the host
    // must then see is stale data (or a time-out), whichever packet it was.
    let timing = matches!(
        entry.kind,
        Kind::ShortDelay | Kind::LongDelay | Kind::Duplicate
    ) && (any_stale || timeout);
    timing
        || match entry.target {
            // No query, no status broadcasts: every block is stale.
            Target::Query => any_stale,
            // A board's broadcast lost: its block, and in the Rev 7/8 chain
            // those of the boards after it, are stale in the hub.
            Target::Status => entry
                .board
                .is_some_and(|b| (b..16).any(|j| stale(missed(report, j)))),
            Target::HubRequest => timeout || nack,
            Target::HubResponse => timeout || bad_packet,
            Target::Command => false,
            Target::Bus => match entry.kind {
                Kind::BusReset => reset,
                Kind::Unplug => reset || report.missed != 0,
                _ => report.missed != 0 || report.error.is_some(),
            },
        }
}

pub(super) fn verdict(entry: &Entry, window: &[Seen], resets_before: u64) -> Verdict {
    // A bus reset the host noticed between cycles (a register write outside
    // the cycle got it first) was detected all the same: it rescanned.
    if matches!(entry.kind, Kind::BusReset | Kind::Unplug)
        && window
            .iter()
            .take(3)
            .any(|s| s.resets_noticed > resets_before)
    {
        return Verdict::Detected;
    }
    if entry.target == Target::Command {
        // Invisible to the host by design (broadcasts are not
        // acknowledged): harmless if every board holds the host's command
        // again within the next two periods.
        return if window.iter().skip(1).take(2).any(|s| s.commands_converged) {
            Verdict::Harmless(Harmless::CommandHeld)
        } else {
            Verdict::Undetected
        };
    }
    // The cycle it hit, and for a late or repeated packet the next one
    // too (it can spill over); a loss or damage touches only its own.
    let spill = matches!(
        entry.kind,
        Kind::ShortDelay
            | Kind::LongDelay
            | Kind::Duplicate
            | Kind::Babble
            | Kind::Unplug
            | Kind::BusReset
    );
    let first_two = || window.iter().take(if spill { 2 } else { 1 });
    if first_two().any(|s| shows(entry, &s.report)) {
        return Verdict::Detected;
    }
    // A damaged or lost hub response the host needed fails its hub read
    // (a time-out or a bad packet); the read completing means the host got
    // another, valid one: the faulted packet was a spare.
    if entry.target == Target::HubResponse
        && window.first().is_some_and(|s| s.report.error.is_none())
    {
        return Verdict::Harmless(Harmless::Spare);
    }
    // Otherwise each of those cycles must have been either clean (every
    // block the host used proven this cycle's) or thrown away whole for
    // another fault the host detected (a failed hub read, a bus reset).
    let mut masked = false;
    for s in first_two() {
        if s.report.all_ok() {
            continue;
        }
        if rejected_whole(&s.report) {
            masked = true;
            continue;
        }
        return Verdict::Undetected;
    }
    Verdict::Harmless(if masked {
        Harmless::Masked
    } else {
        Harmless::Fresh
    })
}

/// The host discarded every board's data of this cycle, for a reason it
/// reported (no block of it was used).
pub(super) fn rejected_whole(r: &CycleReport) -> bool {
    let mut reasons = r.reasons.iter().flatten().peekable();
    let any = reasons.peek().is_some();
    r.error.is_some() && any && reasons.all(|m| *m == MissReason::Transaction)
}
