//! The CAN model against the bit-level definitions: CRC-15, stuffing,
//! frame time on the bus, arbitration, error frames, fault confinement.

use core::time::Duration;

use firelink_can::bus::{CanBus, CanConfig, ErrorState, Outcome};
use firelink_can::frame::{CanId, Frame, crc15, worst_case_bits};
use proptest::prelude::*;

fn bits_of(bytes: &[u8]) -> Vec<bool> {
    bytes
        .iter()
        .flat_map(|b| (0..8).rev().map(move |i| b >> i & 1 != 0))
        .collect()
}

fn us(n: u64) -> Duration {
    Duration::from_micros(n)
}

#[test]
fn crc15_check_value() {
    // The catalogued check value of CRC-15/CAN over "123456789".
    assert_eq!(crc15(bits_of(b"123456789")), 0x059E);
    let reference = crc::Crc::<u16>::new(&crc::CRC_15_CAN);
    assert_eq!(reference.checksum(b"123456789"), 0x059E);
}

#[test]
fn a_frame_of_zeros_by_hand() {
    // ID 0, DLC 0: SOF, 11 ID bits, RTR, IDE, r0 and 4 DLC bits are 19
    // zeros; the CRC of zeros is zero: 34 zeros in the stuffed part. A
    // stuff bit follows every fifth zero: after bits 5, 10, ..., 30, six in
    // all. 47 + 6 = 53 bits, 53 us at 1 Mb/s.
    let f = Frame::data(CanId::new(0).unwrap(), &[]).unwrap();
    assert_eq!(f.crc(), 0);
    assert_eq!(f.stuff_bits(), 6);
    assert_eq!(f.bits(), 53);
    let mut bus = CanBus::new(CanConfig::default()).unwrap();
    let n = bus.add_node("n");
    bus.submit(n, f, us(7)).unwrap();
    let d = bus.step().unwrap();
    assert_eq!(d.started_at, us(7));
    assert_eq!(
        d.delivered_at,
        us(7 + 50),
        "end of frame before the intermission"
    );
    assert_eq!(d.bus_free_at, us(7 + 53));
}

proptest! {
    #[test]
    fn crc_matches_the_reference_on_bytes(data in proptest::collection::vec(any::<u8>(), 0..64)) {
        let reference = crc::Crc::<u16>::new(&crc::CRC_15_CAN);
        prop_assert_eq!(crc15(bits_of(&data)), reference.checksum(&data));
    }

    #[test]
    fn frame_time_is_its_bit_count(id in 0u16..0x800, data in proptest::collection::vec(any::<u8>(), 0..=8), rate_k in prop::sample::select(vec![125u64, 250, 500, 1000])) {
        let f = Frame::data(CanId::new(id).unwrap(), &data).unwrap();
        let n = data.len();
        // Exact length between the unstuffed length and the worst case.
        prop_assert!(f.bits() >= 47 + 8 * n);
        prop_assert!(f.bits() <= worst_case_bits(n));
        prop_assert_eq!(f.bits(), 47 + 8 * n + f.stuff_bits());
        let mut bus = CanBus::new(CanConfig { bit_rate: rate_k * 1000, ..CanConfig::default() }).unwrap();
        let node = bus.add_node("n");
        bus.submit(node, f, Duration::ZERO).unwrap();
        let d = bus.step().unwrap();
        prop_assert_eq!(d.bus_free_at - d.started_at, bus.bit_time() * f.bits() as u32);
        prop_assert_eq!(bus.bit_time(), Duration::from_nanos(1_000_000 / rate_k));
    }
}

#[test]
fn arbitration_by_identifier() {
    let mut bus = CanBus::new(CanConfig::default()).unwrap();
    let nodes: Vec<_> = (0..3).map(|i| bus.add_node(format!("n{i}"))).collect();
    let frame = |id| Frame::data(CanId::new(id).unwrap(), &[0xAA; 8]).unwrap();
    bus.submit(nodes[0], frame(0x300), us(0)).unwrap();
    bus.submit(nodes[1], frame(0x100), us(0)).unwrap();
    bus.submit(nodes[2], frame(0x200), us(0)).unwrap();
    // A remote frame with the data frame's identifier loses to it.
    bus.submit(
        nodes[2],
        Frame::remote(CanId::new(0x100).unwrap(), 8).unwrap(),
        us(0),
    )
    .unwrap();
    let done = bus.run_until_idle();
    let ids: Vec<u16> = done.iter().map(|d| d.frame.id().raw()).collect();
    assert_eq!(ids, [0x100, 0x100, 0x200, 0x300]);
    assert!(!done[0].frame.is_remote());
    assert_eq!(done[3].lost_arbitration, 3);
    // Back to back: each starts when the previous one freed the bus.
    for w in done.windows(2) {
        assert_eq!(w[1].started_at, w[0].bus_free_at);
    }
    // A frame that arrives later waits for the bus but then wins at once.
    let mut bus = CanBus::new(CanConfig::default()).unwrap();
    let a = bus.add_node("a");
    let b = bus.add_node("b");
    bus.submit(a, frame(0x400), us(0)).unwrap();
    bus.submit(a, frame(0x401), us(0)).unwrap();
    bus.submit(b, frame(0x001), us(10)).unwrap();
    let done = bus.run_until_idle();
    assert_eq!(
        done[1].frame.id().raw(),
        0x001,
        "non-preemptive, then priority"
    );
}

#[test]
fn an_error_frame_costs_its_bits_and_the_frame_is_sent_again() {
    let mut bus = CanBus::new(CanConfig::default()).unwrap();
    let a = bus.add_node("a");
    let _b = bus.add_node("b");
    let f = Frame::data(CanId::new(0x123).unwrap(), &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    bus.inject_error(10);
    bus.submit(a, f, Duration::ZERO).unwrap();
    let d = bus.step().unwrap();
    // Bits 0..=10, 6 + 6 flag bits, 8 delimiter bits, 3 intermission.
    let lost = 11 + 6 + 6 + 8 + 3;
    assert_eq!(bus.errors()[0].lost, us(lost));
    assert_eq!(d.attempts, 2);
    assert_eq!(d.started_at, us(lost));
    assert_eq!(d.bus_free_at, us(lost + f.bits() as u64));
    assert_eq!(bus.transmit_errors(a), Some(7));
}

#[test]
fn fault_confinement() {
    let mut bus = CanBus::new(CanConfig::default()).unwrap();
    let a = bus.add_node("a");
    let f = Frame::data(CanId::new(0x10).unwrap(), &[0; 8]).unwrap();
    for _ in 0..16 {
        bus.inject_error(0);
    }
    bus.submit(a, f, Duration::ZERO).unwrap();
    let d = bus.step().unwrap();
    assert_eq!(d.attempts, 17);
    // 16 errors: 128, then one success: 127, active again.
    assert_eq!(bus.transmit_errors(a), Some(127));
    assert_eq!(bus.error_state(a), Some(ErrorState::Active));
    for _ in 0..40 {
        bus.inject_error(0);
    }
    bus.submit(a, f, bus.now()).unwrap();
    let d = bus.step().unwrap();
    assert_eq!(d.outcome, Outcome::BusOff);
    assert_eq!(bus.error_state(a), Some(ErrorState::BusOff));
    // Error-passive transmitters wait 8 more bits after each error.
    let gaps: Vec<Duration> = bus.errors().windows(2).map(|w| w[1].at - w[0].at).collect();
    assert!(gaps.iter().any(|g| *g == us(1 + 6 + 6 + 8 + 3 + 8)));
}

#[test]
fn random_errors_are_seeded() {
    let run = |seed| {
        let mut bus = CanBus::new(CanConfig {
            error_probability: 0.2,
            seed,
            ..CanConfig::default()
        })
        .unwrap();
        let a = bus.add_node("a");
        for i in 0..50u16 {
            let f = Frame::data(CanId::new(i).unwrap(), &[i as u8; 8]).unwrap();
            bus.submit(a, f, Duration::ZERO).unwrap();
        }
        let done = bus.run_until_idle();
        (done.last().unwrap().bus_free_at, bus.errors().len())
    };
    assert_eq!(run(1), run(1));
    assert_ne!(run(1), run(2));
    assert!(run(1).1 > 0);
    assert!(
        CanBus::new(CanConfig {
            bit_rate: 0,
            ..CanConfig::default()
        })
        .is_err()
    );
    assert!(
        CanBus::new(CanConfig {
            error_probability: 1.5,
            ..CanConfig::default()
        })
        .is_err()
    );
}
