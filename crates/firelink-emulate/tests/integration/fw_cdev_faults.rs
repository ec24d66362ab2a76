//! The /dev/fw* twin under the simulated bus's seeded faults, in virtual
//! time (no sockets, no wall clock: the test passes time in): a lost
//! response ends in exactly one RCODE_CANCELLED completion at the split
//! time-out, a busy ack in RCODE_BUSY, a storm of bus resets in one
//! BUS_RESET event per reset on every open device with rising
//! generations; lock requests get the rcode the kernel would report.

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::trace::PacketKind;
use firelink_bus::{FaultRule, PacketFault, PacketMatch, SimDuration, SimTime, TimedFault};
use firelink_emulate::fw_cdev::{Outgoing, Twin};
use firelink_wire::fw_cdev::{BusResetRecord, ResponseEvent, SendRequestArgs, errno, rcode};
use firelink_wire::packet::Tcode;

/// A twin of `boards` Rev 8 boards (/dev/fw1.. ; /dev/fw0 is the card)
/// and the rig's host link handle.
fn twin(boards: u8) -> (Twin, firelink_bus::NodeHandle) {
    let configs = (0..boards)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8).with_seed(u64::from(id)))
        .collect();
    let rig = BoardRig::daisy_chain(configs, &RigOptions::default());
    let host = rig.host;
    (Twin::new(rig.bus, rig.host), host)
}

/// Open /dev/fw`device` and GET_INFO it at ABI 6: its connection and
/// bus-reset record.
fn open(twin: &mut Twin, device: u32, closure: u64) -> (u64, BusResetRecord) {
    let c = twin.open(device).expect("device present");
    let now = twin.bus().now();
    let a = twin.get_info(c, 6, 0, closure, now);
    assert_eq!(a.errno, 0);
    let record = a.payload.get(8..8 + 40).expect("record");
    let (_, rec) = BusResetRecord::parse(record).unwrap();
    (c, rec)
}

fn read_quadlet(closure: u64, offset: u64, generation: u32) -> SendRequestArgs {
    SendRequestArgs {
        tcode: 4,
        length: 4,
        offset,
        closure,
        data: 0,
        generation,
    }
}

/// The events of `connection` due by `now` (every other connection's are
/// dropped).
fn events_of(twin: &mut Twin, connection: u64, now: SimTime) -> Vec<Vec<u8>> {
    twin.advance(now);
    let mut out = Vec::new();
    twin.take_ready(now, &mut out);
    out.into_iter()
        .filter_map(|o| match o {
            Outgoing::Event {
                connection: c,
                bytes,
                ..
            } if c == connection => Some(bytes),
            _ => None,
        })
        .collect()
}

#[test]
fn a_lost_response_completes_once_cancelled_at_the_split_timeout() {
    let (mut twin, _) = twin(1);
    twin.set_split_timeout(SimDuration::from_millis(5));
    twin.bus_mut().add_fault_rule(FaultRule::once(
        PacketMatch::any().tcode(Tcode::ReadQuadletResponse),
        PacketFault::Drop,
    ));
    let (c, rec) = open(&mut twin, 1, 0);
    let sent = twin.bus().now();
    let a = twin.send_request(
        c,
        false,
        &read_quadlet(7, 0xFFFF_F000_0400, rec.generation),
        &[0; 4],
        sent,
    );
    assert_eq!(a, Ok(()));
    // Nothing before the split time-out...
    assert!(events_of(&mut twin, c, sent + SimDuration::from_millis(4)).is_empty());
    // ...then exactly one completion, cancelled, and never another.
    let got = events_of(&mut twin, c, sent + SimDuration::from_millis(6));
    assert_eq!(got.len(), 1);
    let r = ResponseEvent::parse(&got[0]).unwrap();
    assert_eq!((r.closure, r.rcode), (7, rcode::CANCELLED));
    assert!(events_of(&mut twin, c, sent + SimDuration::from_millis(100)).is_empty());
    // The next request (no fault left) is answered.
    let now = twin.bus().now();
    twin.send_request(
        c,
        false,
        &read_quadlet(8, 0xFFFF_F000_0400, rec.generation),
        &[0; 4],
        now,
    )
    .unwrap();
    let got = events_of(&mut twin, c, now + SimDuration::from_millis(1));
    assert_eq!(got.len(), 1);
    let r = ResponseEvent::parse(&got[0]).unwrap();
    assert_eq!((r.closure, r.rcode), (8, rcode::COMPLETE));
    let s = twin.stats();
    assert_eq!(s.requests, s.completions, "{s}");
    // Each request is one span of the bus's level-of-detail count: the
    // one whose response the fault dropped ran at the packet level, the
    // next one fast.
    let d = s.detail;
    assert_eq!((d.fast_cycles, d.packet_level_cycles), (1, 1), "{s}");
    assert_eq!(d.packet_level_cycles_why.fault, 1, "{s}");
    assert!(
        s.to_string()
            .contains("detail fast: requests 1 fast, 1 at the packet level (fault 1)"),
        "{s}"
    );
}

#[test]
fn a_busy_ack_completes_with_rcode_busy() {
    let (mut twin, host) = twin(2);
    twin.bus_mut().add_fault_rule(FaultRule::once(
        PacketMatch::any().from(host).kind(PacketKind::Request),
        PacketFault::AckBusy,
    ));
    let (c, rec) = open(&mut twin, 2, 0);
    let mut rcodes = Vec::new();
    for closure in 1..=3 {
        let now = twin.bus().now();
        twin.send_request(
            c,
            false,
            &read_quadlet(closure, 0, rec.generation),
            &[0; 4],
            now,
        )
        .unwrap();
        let got = events_of(&mut twin, c, now + SimDuration::from_millis(1));
        assert_eq!(got.len(), 1, "one completion per request");
        let r = ResponseEvent::parse(&got[0]).unwrap();
        assert_eq!(r.closure, closure);
        rcodes.push(r.rcode);
    }
    assert_eq!(rcodes, [rcode::BUSY, rcode::COMPLETE, rcode::COMPLETE]);
}

#[test]
fn a_storm_of_bus_resets_reaches_every_device_once_per_reset() {
    let (mut twin, _) = twin(2);
    let opened: Vec<(u64, BusResetRecord)> = (0..3)
        .map(|d| open(&mut twin, d, 100 + u64::from(d)))
        .collect();
    let start = twin.bus().now();
    const STORM: u32 = 6;
    for k in 0..STORM {
        twin.bus_mut().schedule_fault(
            start + SimDuration::from_micros(50 + 500 * u64::from(k)),
            TimedFault::BusReset,
        );
    }
    // One look at the bus after the whole storm.
    let end = start + SimDuration::from_millis(5);
    twin.advance(end);
    let mut out = Vec::new();
    twin.take_ready(end, &mut out);
    for (d, (c, before)) in opened.iter().enumerate() {
        let generations: Vec<u32> = out
            .iter()
            .filter_map(|o| match o {
                Outgoing::Event {
                    connection, bytes, ..
                } if connection == c => BusResetRecord::parse(bytes).ok(),
                _ => None,
            })
            .map(|(closure, rec)| {
                assert_eq!(closure, 100 + d as u64);
                assert_eq!(rec.node_id, before.node_id);
                rec.generation
            })
            .collect();
        let expected: Vec<u32> = (1..=STORM).map(|k| before.generation + k).collect();
        assert_eq!(generations, expected, "device {d}");
    }
    assert_eq!(twin.stats().bus_resets, u64::from(STORM));
}

#[test]
fn lock_requests_get_the_rcode_the_kernel_reports() {
    let (mut twin, _) = twin(1);
    let (board, rec) = open(&mut twin, 1, 0);
    let (card, _) = open(&mut twin, 0, 0);
    let lock = |closure| SendRequestArgs {
        // TCODE_LOCK_COMPARE_SWAP: 8 bytes (argument and data).
        tcode: 0x12,
        length: 8,
        offset: 0xFFFF_F000_0220,
        closure,
        data: 0,
        generation: rec.generation,
    };
    // The boards' link takes no lock request: no ack, RCODE_NO_ACK.
    let now = twin.bus().now();
    assert_eq!(
        twin.send_request(board, false, &lock(1), &[0; 8], now),
        Ok(())
    );
    let got = events_of(&mut twin, board, now + SimDuration::from_millis(1));
    let r = ResponseEvent::parse(&got[0]).unwrap();
    assert_eq!((r.closure, r.rcode), (1, rcode::NO_ACK));
    // The card's own CSRs: a type error, as the kernel's core answers.
    let now = twin.bus().now();
    assert_eq!(
        twin.send_request(card, false, &lock(2), &[0; 8], now),
        Ok(())
    );
    let got = events_of(&mut twin, card, now + SimDuration::from_millis(1));
    let r = ResponseEvent::parse(&got[0]).unwrap();
    assert_eq!((r.closure, r.rcode), (2, rcode::TYPE_ERROR));
    // The wire's own lock tcode (9) is not an ioctl tcode: EINVAL.
    let raw = SendRequestArgs {
        tcode: 9,
        ..lock(3)
    };
    let now = twin.bus().now();
    assert_eq!(
        twin.send_request(board, false, &raw, &[0; 8], now),
        Err(errno::EINVAL)
    );
    let s = twin.stats();
    assert_eq!(s.requests, s.completions, "{s}");
}
