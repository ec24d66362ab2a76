//! The bridge under a flood of garbage mixed with valid requests (in
//! process, seeded, no sockets): it keeps answering every valid request
//! correctly, every datagram is counted under exactly one outcome
//! (malformed + bad CRC + unsupported + stale + forwarded + local =
//! received, and each equals what was sent of its kind), and nothing
//! accumulates between datagrams, however many arrive.

use crate::common;

use common::request_datagram;
use firelink_board::qla::config::Profile;
use firelink_emulate::{Bridge, BridgeStats, DropReason, Handled};
use firelink_wire::bridge::split_board_datagram;
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const BOARDS: u8 = 8;

fn bridge() -> Bridge {
    common::bridge(common::qla1s(BOARDS, Profile::Rev8))
}

fn header(rng: &mut ChaCha8Rng, node: u16) -> AsyncHeader {
    AsyncHeader::new(
        NodeId(0xFFC0 | node),
        NodeId(0xFFD0),
        rng.random_range(0..64),
    )
}

/// What the flood sent, by the outcome each datagram must have.
#[derive(Default, Debug, PartialEq, Eq)]
struct Sent {
    malformed: u64,
    bad_crc: u64,
    unsupported: u64,
    stale: u64,
    forwarded: u64,
    local: u64,
}

impl Sent {
    /// What the bridge's counters say was sent, in the same categories.
    fn counted_by(s: &BridgeStats) -> Sent {
        Sent {
            malformed: s.malformed,
            bad_crc: s.bad_crc,
            unsupported: s.unsupported,
            stale: s.stale_generation,
            forwarded: s.forwarded,
            local: s.local,
        }
    }
}

#[test]
fn flood_of_garbage_and_valid_requests() {
    let mut b = bridge();
    let generation = b.generation();
    let mut rng = ChaCha8Rng::seed_from_u64(0x00F1_00D5);
    let mut reply = Vec::with_capacity(4096);
    let mut sent = Sent::default();
    let mut status_reads = 0u64;
    for i in 0..30_000u32 {
        let kind = rng.random_range(0..100u32);
        let node = rng.random_range(0..u16::from(BOARDS));
        match kind {
            // Garbage of every length (a control word and a few bytes, or
            // nothing at all): malformed.
            0..=34 => {
                let len = rng.random_range(0..40usize);
                let mut d: Vec<u8> = (0..len).map(|_| rng.random()).collect();
                // Keep the outcome certain: a 1394 header needs 12 bytes.
                d.truncate(13);
                sent.malformed += 1;
                let h = b.handle(&d, &mut reply);
                assert_eq!(h, Handled::Dropped(DropReason::Malformed), "datagram {i}");
            }
            // A valid read with one bit flipped in its header: bad CRC.
            35..=44 => {
                let repr = PacketRepr::ReadQuadletRequest {
                    header: header(&mut rng, node),
                    offset: rng.random_range(0..0x1_0000u64),
                };
                let mut d = request_datagram(false, generation, &repr);
                // Source ID, offset or the CRC itself (a flipped tcode or
                // length would make another, malformed, packet).
                let bit = rng.random_range(32..128usize);
                d[2 + bit / 8] ^= 1 << (bit % 8);
                sent.bad_crc += 1;
                let h = b.handle(&d, &mut reply);
                assert_eq!(h, Handled::Dropped(DropReason::BadCrc), "datagram {i}");
            }
            // A well-formed response packet sent to the bridge: not a
            // request it handles.
            45..=49 => {
                let repr = PacketRepr::WriteResponse {
                    header: header(&mut rng, node),
                    rcode: firelink_wire::packet::Rcode::Complete,
                };
                sent.unsupported += 1;
                let h = b.handle(&request_datagram(false, generation, &repr), &mut reply);
                assert_eq!(h, Handled::Dropped(DropReason::Unsupported), "datagram {i}");
            }
            // Forwarded with a stale generation.
            50..=59 => {
                let repr = PacketRepr::ReadQuadletRequest {
                    header: header(&mut rng, node),
                    offset: 0,
                };
                sent.stale += 1;
                let h = b.handle(
                    &request_datagram(false, generation.wrapping_add(1), &repr),
                    &mut reply,
                );
                assert_eq!(
                    h,
                    Handled::Dropped(DropReason::StaleGeneration),
                    "datagram {i}"
                );
            }
            // Valid forwarded STATUS reads: answered, naming the board.
            60..=79 => {
                let repr = PacketRepr::ReadQuadletRequest {
                    header: header(&mut rng, node),
                    offset: 0,
                };
                sent.forwarded += 1;
                let Handled::Reply(n) =
                    b.handle(&request_datagram(false, generation, &repr), &mut reply)
                else {
                    panic!("datagram {i}: valid STATUS read of node {node} got no reply");
                };
                let (packet, _) = split_board_datagram(&reply[..n]).unwrap();
                packet.verify().unwrap();
                assert_eq!(
                    (packet.quadlet_data() >> 24) & 0xF,
                    u32::from(node),
                    "datagram {i}"
                );
                status_reads += 1;
            }
            // Valid block reads at random offsets and lengths: forwarded,
            // answered or failed on the bus, never half-handled.
            80..=89 => {
                let repr = PacketRepr::ReadBlockRequest {
                    header: header(&mut rng, node),
                    offset: u64::from(rng.random_range(0..0x1_0000u32)) * 4,
                    data_length: rng.random_range(1..=512u16) * 4,
                    extended_tcode: 0,
                };
                sent.forwarded += 1;
                let h = b.handle(&request_datagram(false, generation, &repr), &mut reply);
                assert!(
                    matches!(
                        h,
                        Handled::Reply(_) | Handled::Dropped(DropReason::BusFailure)
                    ),
                    "datagram {i}: {h:?}"
                );
            }
            // Local reads of the bridge board, any generation.
            _ => {
                let repr = PacketRepr::ReadQuadletRequest {
                    header: header(&mut rng, 0x3F),
                    offset: 4,
                };
                sent.local += 1;
                let d = request_datagram(true, rng.random(), &repr);
                let Handled::Reply(n) = b.handle(&d, &mut reply) else {
                    panic!("datagram {i}: local read got no reply");
                };
                let (packet, _) = split_board_datagram(&reply[..n]).unwrap();
                assert_eq!(packet.quadlet_data(), 0x514C_4131, "HW_VERSION");
            }
        }
        // Nothing stays behind in the bridge's link between datagrams.
        assert_eq!(b.link_backlog(), 0, "after datagram {i}");
    }
    let s: BridgeStats = b.stats();
    assert_eq!(s.datagrams, 30_000);
    assert_eq!(s.accounted(), s.datagrams, "{s}");
    assert_eq!(Sent::counted_by(&s), sent, "{s}");
    assert!(status_reads > 5_000);
}

/// Broadcast writes (every I/O cycle has two) complete when sent; the
/// bridge keeps nothing of them either.
#[test]
fn broadcast_writes_leave_nothing_behind() {
    let mut b = bridge();
    let mut reply = Vec::new();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for k in 0..2_000u32 {
        let repr = PacketRepr::WriteQuadletRequest {
            header: header(&mut rng, 0x3F),
            offset: 3,
            data: 0x1680 + k % 16,
        };
        assert_eq!(
            b.handle(&request_datagram(false, 0, &repr), &mut reply),
            Handled::Written
        );
        let t = b.bus().now() + firelink_bus::SimDuration::from_micros(50);
        b.advance_to(t);
        assert_eq!(b.link_backlog(), 0, "after broadcast {k}");
    }
}

/// A quadlet read of node 63 (fpgatest `8`) is answered by the bridge
/// board from its own registers, whatever the generation, and counted.
#[test]
fn broadcast_quadlet_read_is_answered_by_the_bridge() {
    let mut b = bridge();
    let mut reply = Vec::new();
    let repr = PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(NodeId::BROADCAST, NodeId(0xFFD0), 9),
        offset: 0,
    };
    let Handled::Reply(n) = b.handle(&request_datagram(false, 0xEE, &repr), &mut reply) else {
        panic!("no reply to a node-63 read");
    };
    let (packet, _) = split_board_datagram(&reply[..n]).unwrap();
    packet.verify().unwrap();
    // STATUS of board 0 (the bridge), from the bridge's own node.
    assert_eq!((packet.quadlet_data() >> 24) & 0xF, 0);
    assert_eq!(packet.source_id().0 & 0xFFC0, 0xFFC0);
    assert_eq!(b.stats().local, 1);
    assert_eq!(b.stats().accounted(), b.stats().datagrams);
}

/// The same over loopback UDP, against the real server loop: a client
/// sends garbage, damaged and unsupported datagrams with valid reads mixed
/// in (each valid read waits for its answer, so the socket buffers never
/// overflow and every datagram reaches the server). Every valid read is
/// answered, and when the server stops its counters match what was sent,
/// kind by kind, with nothing left behind in its link.
#[test]
fn flood_over_loopback_udp() {
    use std::net::UdpSocket;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::time::Duration;

    let config = firelink_emulate::ServeConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        loopback_broadcast: false,
    };
    let (server, _) = firelink_emulate::bind(&config).unwrap();
    let addr = server.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let thread = std::thread::spawn(move || {
        let mut b = bridge();
        firelink_emulate::serve(&mut b, &server, None, &flag, |_| {}).unwrap();
        (b.stats(), b.link_backlog())
    });
    let client = UdpSocket::bind("127.0.0.1:0").unwrap();
    // Generous: a loaded machine can stall the server for a while.
    client
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0xF100D);
    let mut sent = Sent::default();
    let mut buf = [0u8; 4096];
    for round in 0..600u32 {
        for _ in 0..10 {
            let kind = rng.random_range(0..4u32);
            let node = rng.random_range(0..u16::from(BOARDS));
            let d = match kind {
                0 => {
                    sent.malformed += 1;
                    let len = rng.random_range(0..13usize);
                    (0..len).map(|_| rng.random()).collect()
                }
                1 => {
                    sent.bad_crc += 1;
                    let repr = PacketRepr::ReadQuadletRequest {
                        header: header(&mut rng, node),
                        offset: 0,
                    };
                    let mut d = request_datagram(false, 0, &repr);
                    d[2 + 12] ^= 0x40; // the header CRC itself
                    d
                }
                2 => {
                    sent.unsupported += 1;
                    let repr = PacketRepr::WriteResponse {
                        header: header(&mut rng, node),
                        rcode: firelink_wire::packet::Rcode::Complete,
                    };
                    request_datagram(false, 0, &repr)
                }
                _ => {
                    sent.local += 1;
                    // A local write of the bridge board's watchdog (no
                    // reply: writes get none).
                    let repr = PacketRepr::WriteQuadletRequest {
                        header: header(&mut rng, 0x3F),
                        offset: 3,
                        data: 0x1680,
                    };
                    request_datagram(true, 0, &repr)
                }
            };
            client.send_to(&d, addr).unwrap();
        }
        // A valid local read: answered, after everything before it.
        sent.local += 1;
        let repr = PacketRepr::ReadQuadletRequest {
            header: header(&mut rng, 0x3F),
            offset: 4,
        };
        client
            .send_to(&request_datagram(true, 0, &repr), addr)
            .unwrap();
        let (n, _) = client
            .recv_from(&mut buf)
            .unwrap_or_else(|e| panic!("round {round}: no answer to a valid read: {e}"));
        let (packet, _) = split_board_datagram(&buf[..n]).unwrap();
        assert_eq!(packet.quadlet_data(), 0x514C_4131, "round {round}");
    }
    stop.store(true, Ordering::Relaxed);
    let (s, backlog) = thread.join().unwrap();
    assert_eq!(s.datagrams, 600 * 11, "{s}");
    assert_eq!(s.accounted(), s.datagrams, "{s}");
    assert_eq!(Sent::counted_by(&s), sent, "{s}");
    assert_eq!(s.replies, 600);
    assert_eq!(backlog, 0);
}

/// The bridge judges what the bus gives back with the host library's
/// transaction engine: a read of a board is matched, a read of a node that
/// is not there times out, naming its label.
#[test]
fn the_bridges_link_is_judged_by_the_host_engine() {
    let mut b = bridge();
    let g = b.generation();
    let mut reply = Vec::new();
    let read = |node: u16, tl: u8| PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(NodeId(0xFFC0 | node), NodeId(0xFFD0), tl),
        offset: 4,
    };
    assert!(matches!(
        b.handle(&request_datagram(false, g, &read(2, 7)), &mut reply),
        Handled::Reply(_)
    ));
    assert_eq!(
        b.handle(&request_datagram(false, g, &read(40, 8)), &mut reply),
        Handled::Dropped(DropReason::BusFailure)
    );
    let s = b.link_stats();
    assert_eq!((s.sent, s.matched, s.timeouts), (2, 1, 1));
    assert_eq!(s.refused(), 0);
}
