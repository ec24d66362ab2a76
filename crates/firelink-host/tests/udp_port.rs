//! The UDP port against a scripted responder on loopback: bad responses
//! (wrong tl, wrong length, bad CRC, stale generation, truncated and
//! garbage datagrams) are rejected with the right error or counted and
//! dropped, and the matching response is still found.

use std::net::UdpSocket;
use std::thread;
use std::time::Duration;

use firelink_host::udp::UdpPort;
use firelink_host::{Dest, HostError, Port};
use firelink_wire::bridge::{ExtraData, split_host_datagram};
use firelink_wire::packet::{AsyncHeader, PacketRepr, Rcode};

/// What the responder sends back for one request.
#[derive(Clone, Copy, Debug)]
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

fn port(addr: std::net::SocketAddr) -> UdpPort {
    let mut p = UdpPort::open(addr).unwrap();
    p.set_timeout(Duration::from_millis(200));
    p
}

#[test]
fn good_response_is_returned() {
    let addr = responder(vec![vec![Answer::Good { generation: 0 }]]);
    let mut p = port(addr);
    assert_eq!(p.read_quadlet(Dest::node(2), 4).unwrap(), 0x5151_4131);
    assert_eq!(p.stats().matched, 1);
}

#[test]
fn stale_and_foreign_datagrams_are_dropped_before_the_match() {
    let addr = responder(vec![vec![
        Answer::WrongTl,
        Answer::WrongLength,
        Answer::Garbage,
        Answer::Truncated,
        Answer::Good { generation: 0 },
    ]]);
    let mut p = port(addr);
    let mut out = [0u8; 8];
    p.read_block(Dest::node(1), 0, &mut out).unwrap();
    assert_eq!(out, [0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]);
    let s = p.stats();
    assert_eq!(s.stale, 2, "{s:?}");
    assert_eq!(s.garbage, 2, "{s:?}");
    assert_eq!(s.matched, 1);
}

#[test]
fn bad_crc_is_an_error() {
    let addr = responder(vec![vec![Answer::BadCrc]]);
    let mut p = port(addr);
    let err = p.read_quadlet(Dest::node(0), 4).unwrap_err();
    assert!(
        matches!(err, HostError::Wire(firelink_wire::Error::HeaderCrc { .. })),
        "{err}"
    );
    assert_eq!(p.stats().crc_errors, 1);
}

#[test]
fn no_answer_is_a_timeout_naming_node_and_label() {
    let addr = responder(vec![vec![Answer::Silence]]);
    let mut p = port(addr);
    p.set_timeout(Duration::from_millis(30));
    let err = p.read_quadlet(Dest::node(5), 4).unwrap_err();
    assert!(
        matches!(err, HostError::Timeout { node: 5, tl: 1, .. }),
        "{err}"
    );
    assert_eq!(p.stats().timeouts, 1);
}

#[test]
fn a_new_generation_fails_the_next_request_once() {
    let addr = responder(vec![
        vec![Answer::Good { generation: 3 }],
        vec![Answer::Good { generation: 3 }],
    ]);
    let mut p = port(addr);
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
    let addr = responder(vec![]);
    let mut p = port(addr);
    let mut odd = [0u8; 6];
    assert!(matches!(
        p.read_block(Dest::node(0), 0, &mut odd),
        Err(HostError::InvalidRequest { .. })
    ));
    assert!(matches!(
        p.write_block(Dest::node(0), 0, &[0u8; 4096]),
        Err(HostError::InvalidRequest { .. })
    ));
    assert_eq!(p.stats().sent, 0);
}
