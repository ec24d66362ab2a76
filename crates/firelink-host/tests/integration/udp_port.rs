//! The UDP port against a scripted responder on loopback: bad responses
//! (wrong tl, wrong length, bad CRC, stale generation, truncated and
//! garbage datagrams) are rejected with the right error or counted and
//! dropped, and the matching response is still found.

use std::net::UdpSocket;
use std::thread;
use std::time::Duration;

use firelink_host::link_stats::LinkStats;
use firelink_host::udp::{UdpPort, WaitMode};
use firelink_host::{Dest, HostError, Port};
use firelink_wire::bridge::{ExtraData, split_host_datagram};
use firelink_wire::packet::{AsyncHeader, PacketRepr, Rcode};

/// What the responder sends back for one request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Answer {
    /// The correct response, with this bus generation in the extra data.
    Good { generation: u8 },
    /// A response with another transaction label.
    WrongTl,
    /// A block response of the wrong length.
    WrongLength,
    /// The correct response with its header CRC broken.
    BadCrc,
    /// The first 10 bytes of the correct response.
    Truncated,
    /// Random bytes.
    Garbage,
    /// Nothing.
    Silence,
}

fn response(request: &[u8], answer: Answer) -> Option<Vec<u8>> {
    let (_, packet) = split_host_datagram(request).ok()?;
    let req = PacketRepr::parse(&packet).ok()?;
    let mut header: AsyncHeader = req.header()?.response();
    let data = [0x11u8, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88];
    let mut generation = 0;
    let repr = |header: AsyncHeader, len: usize| match req {
        PacketRepr::ReadQuadletRequest { .. } => PacketRepr::ReadQuadletResponse {
            header,
            rcode: Rcode::Complete,
            data: 0x5151_4131,
        },
        _ => PacketRepr::ReadBlockResponse {
            header,
            rcode: Rcode::Complete,
            extended_tcode: 0,
            data: &data[..len],
        },
    };
    let requested = match req {
        PacketRepr::ReadBlockRequest { data_length, .. } => usize::from(data_length),
        _ => 4,
    };
    let built = match answer {
        Answer::Good { generation: g } => {
            generation = g;
            repr(header, requested)
        }
        Answer::WrongTl => {
            header.tl = (header.tl + 1) & 0x3F;
            repr(header, requested)
        }
        Answer::WrongLength => repr(header, 4),
        Answer::BadCrc | Answer::Truncated => repr(header, requested),
        Answer::Garbage => return Some(vec![0xDE, 0xAD, 0xBE, 0xEF, 0x00, 0x01, 0x02]),
        Answer::Silence => return None,
    };
    let mut out = vec![0u8; built.buffer_len()];
    built.emit(&mut out).ok()?;
    if let Answer::BadCrc = answer {
        out[12] ^= 0xFF;
    }
    out.extend_from_slice(
        &ExtraData {
            generation,
            ..ExtraData::default()
        }
        .to_bytes(),
    );
    if let Answer::Truncated = answer {
        out.truncate(10);
    }
    Some(out)
}

/// A responder answering each request with the next script entry (a list
/// of datagrams per request).
fn responder(script: Vec<Vec<Answer>>) -> std::net::SocketAddr {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let addr = socket.local_addr().unwrap();
    thread::spawn(move || {
        let mut buf = [0u8; 4096];
        for answers in script {
            let Ok((len, from)) = socket.recv_from(&mut buf) else {
                return;
            };
            for a in answers {
                if let Some(reply) = response(&buf[..len], a) {
                    let _ = socket.send_to(&reply, from);
                }
            }
        }
    });
    addr
}

/// A port that has learnt the bus generation (the responder's first script
/// entry answers that), with its counters from then on in `since`.
fn port(addr: std::net::SocketAddr) -> (UdpPort, LinkStats) {
    let mut p = UdpPort::open(addr).unwrap();
    // An answer the responder thread sends comes when the machine runs
    // that thread: the time-out only bounds a failing test (the tests that
    // expect a time-out set their own).
    p.set_timeout(Duration::from_secs(5));
    p.learn_generation().unwrap();
    let since = p.stats();
    (p, since)
}

/// The answer to the port's first request: its generation query.
fn learn() -> Vec<Answer> {
    vec![Answer::Good { generation: 0 }]
}

#[test]
fn good_response_is_returned() {
    let addr = responder(vec![learn(), vec![Answer::Good { generation: 0 }]]);
    let (mut p, since) = port(addr);
    assert_eq!(p.read_quadlet(Dest::node(2), 4).unwrap(), 0x5151_4131);
    assert_eq!(p.stats().since(&since).matched, 1);
}

#[test]
fn stale_and_foreign_datagrams_are_dropped_before_the_match() {
    let addr = responder(vec![
        learn(),
        vec![
            Answer::WrongTl,
            Answer::WrongLength,
            Answer::Garbage,
            Answer::Truncated,
            Answer::Good { generation: 0 },
        ],
    ]);
    let (mut p, since) = port(addr);
    let mut out = [0u8; 8];
    p.read_block(Dest::node(1), 0, &mut out).unwrap();
    assert_eq!(out, [0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]);
    let s = p.stats().since(&since);
    assert_eq!(s.unmatched, 2, "{s:?}");
    assert_eq!(s.garbage, 2, "{s:?}");
    assert_eq!(s.matched, 1);
}

#[test]
fn bad_crc_is_an_error() {
    let addr = responder(vec![learn(), vec![Answer::BadCrc]]);
    let (mut p, since) = port(addr);
    let err = p.read_quadlet(Dest::node(0), 4).unwrap_err();
    assert!(
        matches!(err, HostError::Wire(firelink_wire::Error::HeaderCrc { .. })),
        "{err}"
    );
    assert_eq!(p.stats().since(&since).bad_crc, 1);
}

#[test]
fn no_answer_is_a_timeout_naming_node_and_label() {
    let addr = responder(vec![learn(), vec![Answer::Silence]]);
    let (mut p, since) = port(addr);
    p.set_timeout(Duration::from_millis(30));
    let err = p.read_quadlet(Dest::node(5), 4).unwrap_err();
    // Label 1 went to the generation query; this read is label 2.
    assert!(
        matches!(err, HostError::Timeout { node: 5, tl: 2, .. }),
        "{err}"
    );
    assert_eq!(p.stats().since(&since).timeouts, 1);
}

#[test]
fn a_new_generation_fails_the_next_request_once() {
    let addr = responder(vec![
        learn(),
        vec![Answer::Good { generation: 3 }],
        vec![Answer::Good { generation: 3 }],
    ]);
    let (mut p, _) = port(addr);
    // The data of this read is good; the extra data reports a bus reset.
    assert!(p.read_quadlet(Dest::node(0), 4).is_ok());
    let err = p.read_quadlet(Dest::node(0), 4).unwrap_err();
    assert_eq!(err, HostError::BusReset { old: 0, new: 3 });
    assert_eq!(p.generation(), 3);
    // The host adopted it: the next request goes out and succeeds.
    assert!(p.read_quadlet(Dest::node(0), 4).is_ok());
    assert_eq!(p.stats().bus_resets, 1);
}

#[test]
fn invalid_block_sizes_are_refused_before_sending() {
    let addr = responder(vec![learn()]);
    let (mut p, since) = port(addr);
    let mut odd = [0u8; 6];
    assert!(matches!(
        p.read_block(Dest::node(0), 0, &mut odd),
        Err(HostError::InvalidRequest { .. })
    ));
    assert!(matches!(
        p.write_block(Dest::node(0), 0, &[0u8; 4096]),
        Err(HostError::InvalidRequest { .. })
    ));
    assert_eq!(p.stats().since(&since).sent, 0);
}

/// A bridge that answers every request the same bad way, for as long as
/// requests come (it stops after a quiet second).
fn misbehaving(answer: Answer) -> std::net::SocketAddr {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(1)))
        .unwrap();
    let addr = socket.local_addr().unwrap();
    thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok((len, from)) = socket.recv_from(&mut buf) {
            if let Some(reply) = response(&buf[..len], answer) {
                let _ = socket.send_to(&reply, from);
            }
        }
    });
    addr
}

/// A scan against a bridge that never answers properly fails with "no
/// boards found" and says what came instead, by reason.
#[test]
fn no_boards_found_says_what_came_instead() {
    for (answer, what) in [
        (Answer::Garbage, "garbage"),
        (Answer::Truncated, "garbage"),
        (Answer::BadCrc, "bad CRC"),
        (Answer::WrongTl, "answering no request"),
        (Answer::Silence, "timed out"),
    ] {
        let mut p = UdpPort::open(misbehaving(answer)).unwrap();
        // Silence is a time-out whatever its length; an answer must come
        // in time to be counted as what it is, with room for a loaded
        // machine to be slow to run the responder's thread.
        let timeout = if answer == Answer::Silence { 20 } else { 100 };
        p.set_timeout(Duration::from_millis(timeout));
        let err = firelink_host::qla::scan::scan(&mut p).unwrap_err();
        let HostError::NoBoards { seen } = err else {
            panic!("{answer:?}: {err}");
        };
        assert_eq!(seen.matched, 0, "{answer:?}: {seen}");
        let count = match answer {
            Answer::Garbage | Answer::Truncated => seen.garbage,
            Answer::BadCrc => seen.bad_crc,
            Answer::WrongTl => seen.unmatched,
            _ => seen.timeouts,
        };
        assert!(count > 0, "{answer:?}: {seen}");
        assert!(err.to_string().contains(what), "{answer:?}: {err}");
    }
}

/// `reads` reads of a port in `mode` from a bridge played by this thread
/// between them: each read times out (nothing answers while it waits),
/// then this thread takes its request and answers it (all but the last),
/// so the answer is queued at the port before its next read, which counts
/// it as late. Nothing depends on when another thread runs. The port's
/// counters after the reads.
fn reads_answered_late(mode: WaitMode, reads: u32) -> LinkStats {
    let bridge = UdpSocket::bind("127.0.0.1:0").unwrap();
    // Only a guard against a hang: each request is sent before its read
    // times out, so it is queued here already.
    bridge
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    let mut p = UdpPort::open(bridge.local_addr().unwrap()).unwrap();
    p.set_wait_mode(mode);
    p.set_timeout(Duration::from_millis(100));
    let mut buf = [0u8; 4096];
    for k in 1..=reads {
        let err = p.read_quadlet(Dest::BROADCAST, 4).unwrap_err();
        assert!(matches!(err, HostError::Timeout { .. }), "{mode}: {err}");
        let (len, from) = bridge.recv_from(&mut buf).expect("the request");
        if k < reads {
            let reply = response(&buf[..len], Answer::Good { generation: 0 }).expect("a read");
            bridge.send_to(&reply, from).unwrap();
        }
    }
    p.stats()
}

/// A bridge one answer behind (each answer comes after its request timed
/// out) and one that answers twice: every read fails or succeeds cleanly,
/// and the late and the duplicated answers are counted as such.
#[test]
fn late_and_duplicated_answers_are_told_apart() {
    // Late: the answers to the first two requests come after they timed
    // out, the third's never.
    let s = reads_answered_late(WaitMode::Blocking, 3);
    assert_eq!(s.timeouts, 3, "{s}");
    assert_eq!(s.late, 2, "{s}");
    assert_eq!(s.matched, 0, "{s}");

    // Duplicated: every answer comes twice; the copy answers no request.
    let addr = responder(vec![
        vec![
            Answer::Good { generation: 0 },
            Answer::Good { generation: 0 },
        ],
        vec![
            Answer::Good { generation: 0 },
            Answer::Good { generation: 0 },
        ],
    ]);
    let mut p = UdpPort::open(addr).unwrap();
    p.set_timeout(Duration::from_secs(5));
    assert_eq!(p.read_quadlet(Dest::BROADCAST, 4).unwrap(), 0x5151_4131);
    assert_eq!(p.read_quadlet(Dest::BROADCAST, 4).unwrap(), 0x5151_4131);
    let s = p.stats();
    assert_eq!(s.matched, 2, "{s}");
    assert!(s.unmatched >= 1, "{s}");
}

/// A bridge that answers every read at once (a quadlet, or zeros of the
/// length asked for) and takes writes silently, for as long as requests
/// come (it stops after a quiet second).
fn mirror() -> std::net::SocketAddr {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(1)))
        .unwrap();
    let addr = socket.local_addr().unwrap();
    thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok((len, from)) = socket.recv_from(&mut buf) {
            let read = split_host_datagram(&buf[..len])
                .ok()
                .and_then(|(_, packet)| PacketRepr::parse(&packet).ok())
                .is_some_and(|req| {
                    matches!(
                        req,
                        PacketRepr::ReadQuadletRequest { .. } | PacketRepr::ReadBlockRequest { .. }
                    )
                });
            if let (true, Some(reply)) =
                (read, response(&buf[..len], Answer::Good { generation: 0 }))
            {
                let _ = socket.send_to(&reply, from);
            }
        }
    });
    addr
}

/// One broadcast cycle's requests: the query (a quadlet write), the hub
/// read (a block read and its answer), the commands (a block write).
fn broadcast_cycle(p: &mut UdpPort, hub: &mut [u8]) {
    p.write_quadlet(Dest::BROADCAST, 0x1800, 0x0001_0003)
        .unwrap();
    p.read_block(Dest::node(0), 0x1000, hub).unwrap();
    p.write_block(Dest::BROADCAST, 0, &[0u8; 64]).unwrap();
}

/// Blocking: once the socket has its receive time-out (set at the first
/// read), a broadcast cycle is four system calls (three sends, one
/// receive) and never touches the socket's settings.
#[test]
fn a_blocking_broadcast_cycle_is_four_system_calls() {
    let mut p = UdpPort::open(mirror()).unwrap();
    assert_eq!(p.wait_mode(), WaitMode::Blocking);
    // Long enough never to expire on a loaded machine: the count must not
    // depend on timing.
    p.set_timeout(Duration::from_secs(20));
    let mut hub = [0u8; 8];
    broadcast_cycle(&mut p, &mut hub);
    let (calls, stats) = (p.socket_calls(), p.stats());
    for _ in 0..50 {
        broadcast_cycle(&mut p, &mut hub);
    }
    let c = p.socket_calls().since(&calls);
    assert_eq!(c.sends, 150, "{c:?}");
    assert_eq!(c.receives, 50, "{c:?}");
    assert_eq!(c.settings, 0, "{c:?}");
    assert_eq!(c.total(), 4 * 50, "{c:?}");
    let s = p.stats().since(&stats);
    assert_eq!(s.matched, 50, "{s}");
    assert_eq!(hub, [0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]);
}

/// Spinning: the socket is made non-blocking once; reads poll it until
/// the answer, with no setting changed per read.
#[test]
fn a_spinning_port_sets_its_socket_once_and_reads() {
    let mut p = UdpPort::open(mirror()).unwrap();
    p.set_wait_mode(WaitMode::Spinning);
    p.set_timeout(Duration::from_secs(20));
    let mut hub = [0u8; 8];
    broadcast_cycle(&mut p, &mut hub);
    let (calls, stats) = (p.socket_calls(), p.stats());
    for _ in 0..50 {
        broadcast_cycle(&mut p, &mut hub);
        assert_eq!(p.read_quadlet(Dest::node(1), 4).unwrap(), 0x5151_4131);
    }
    let c = p.socket_calls().since(&calls);
    assert_eq!(c.sends, 200, "{c:?}");
    // Each read ends with the receive that got its answer.
    assert_eq!(c.receives - c.empty_receives, 100, "{c:?}");
    assert_eq!(c.settings, 0, "{c:?}");
    assert_eq!(p.stats().since(&stats).matched, 100);
    assert_eq!(hub, [0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]);
}

/// In both modes: silence is a time-out naming node and label, bad
/// datagrams are counted by reason before the answer, and the late answer
/// to a timed-out read is told apart.
#[test]
fn both_wait_modes_keep_the_ports_rules() {
    for mode in WaitMode::ALL {
        let addr = responder(vec![learn(), vec![Answer::Silence]]);
        let mut p = UdpPort::open(addr).unwrap();
        p.set_wait_mode(mode);
        p.set_timeout(Duration::from_millis(200));
        p.learn_generation().unwrap();
        p.set_timeout(Duration::from_millis(30));
        let err = p.read_quadlet(Dest::node(5), 4).unwrap_err();
        assert!(
            matches!(err, HostError::Timeout { node: 5, tl: 2, .. }),
            "{mode}: {err}"
        );

        let addr = responder(vec![
            learn(),
            vec![
                Answer::WrongTl,
                Answer::Garbage,
                Answer::Truncated,
                Answer::Good { generation: 0 },
            ],
        ]);
        let mut p = UdpPort::open(addr).unwrap();
        p.set_wait_mode(mode);
        p.set_timeout(Duration::from_secs(5));
        p.learn_generation().unwrap();
        let since = p.stats();
        let mut out = [0u8; 8];
        p.read_block(Dest::node(1), 0, &mut out).unwrap();
        let s = p.stats().since(&since);
        assert_eq!(
            (s.unmatched, s.garbage, s.matched),
            (1, 2, 1),
            "{mode}: {s}"
        );

        // The first request's answer comes after it timed out.
        let s = reads_answered_late(mode, 2);
        assert_eq!((s.timeouts, s.late, s.matched), (2, 1, 0), "{mode}: {s}");
    }
}

/// A datagram from a stranger is counted and the wait goes on for what is
/// left of the time-out; the next read sets the whole time-out back: the
/// only setting changes a blocking port makes after its first read.
#[test]
fn a_stray_datagram_rearms_the_rest_of_the_wait() {
    let mut p = UdpPort::open(mirror()).unwrap();
    p.set_timeout(Duration::from_secs(20));
    assert_eq!(p.read_quadlet(Dest::node(1), 4).unwrap(), 0x5151_4131);
    let (calls, stats) = (p.socket_calls(), p.stats());
    let stranger = UdpSocket::bind("127.0.0.1:0").unwrap();
    stranger
        .send_to(b"not a bridge", p.local_addr().unwrap())
        .unwrap();
    assert_eq!(p.read_quadlet(Dest::node(1), 4).unwrap(), 0x5151_4131);
    assert_eq!(p.read_quadlet(Dest::node(1), 4).unwrap(), 0x5151_4131);
    let c = p.socket_calls().since(&calls);
    let s = p.stats().since(&stats);
    assert_eq!((s.unmatched, s.matched), (1, 2), "{s}");
    assert_eq!(c.receives, 3, "{c:?}");
    assert!(c.settings <= 2, "{c:?}");
}
