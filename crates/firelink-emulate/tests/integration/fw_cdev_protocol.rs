//! The twin server's own protocol (`firelink_wire::fw_cdev`), spoken by a
//! bare client over its socket: SEND_REQUEST is one-way (the server sends
//! the completion event and nothing on the control connection), the
//! other calls get exactly one reply each, the attach reply carries the
//! node's speed code, and a message the server cannot parse closes the
//! control connection rather than answering it out of turn. Every wait is
//! bounded; nothing asserts a duration.

use std::os::fd::{AsFd, AsRawFd, OwnedFd};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::socket::{
    AddressFamily, MsgFlags, SockFlag, SockType, UnixAddr, connect, recv, send, socket,
};

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_emulate::fw_cdev::{self, SPEED_CODE, Twin};
use firelink_wire::fw_cdev::{
    BusResetRecord, ResponseEvent, SendRequestArgs, TwinReply, TwinRequest, rcode,
    split_info_payload,
};

fn connect_to(path: &std::path::Path) -> OwnedFd {
    let fd = socket(
        AddressFamily::Unix,
        SockType::SeqPacket,
        SockFlag::SOCK_CLOEXEC,
        None,
    )
    .unwrap();
    connect(fd.as_raw_fd(), &UnixAddr::new(path).unwrap()).unwrap();
    fd
}

/// Wait (at most 30 s: a lost message fails the test, never hangs it) for
/// `fd` to be readable or hung up.
fn wait_readable(fd: &OwnedFd) {
    let mut fds = [PollFd::new(fd.as_fd(), PollFlags::POLLIN)];
    let n = poll(&mut fds, PollTimeout::from(30_000u16)).unwrap();
    assert_eq!(n, 1, "nothing from the server within 30 s");
}

fn send_request(fd: &OwnedFd, request: &TwinRequest<'_>) {
    let mut out = [0u8; 128];
    let n = request.emit(&mut out).unwrap();
    send(fd.as_raw_fd(), &out[..n], MsgFlags::MSG_NOSIGNAL).unwrap();
}

/// One request that expects a reply: the reply's (errno, value, payload).
fn call(fd: &OwnedFd, request: &TwinRequest<'_>) -> (i32, u64, Vec<u8>) {
    assert!(request.expects_reply());
    send_request(fd, request);
    wait_readable(fd);
    let mut buf = [0u8; 4096];
    let n = recv(fd.as_raw_fd(), &mut buf, MsgFlags::empty()).unwrap();
    let r = TwinReply::parse(&buf[..n]).unwrap();
    (r.errno, r.value, r.payload.to_vec())
}

#[test]
fn send_request_is_one_way_and_the_other_calls_get_one_reply_each() {
    let boards = vec![BoardConfig::new(0, Hardware::Qla1, Profile::Rev8)];
    let rig = BoardRig::daisy_chain(boards, &RigOptions::default());
    let mut twin = Twin::new(rig.bus, rig.host);
    let dir = std::env::temp_dir().join(format!("fwcdev-protocol-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("twin.sock");
    let listener = fw_cdev::bind(&path).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            fw_cdev::serve(&mut twin, &listener, &stop, |_| {}).unwrap();
            twin
        })
    };

    // /dev/fw1 (the board): its event connection, then its control one.
    let event = connect_to(&path);
    let (e, connection, _) = call(&event, &TwinRequest::Open { device: 1 });
    assert_eq!(e, 0);
    let control = connect_to(&path);
    let (e, speed, _) = call(&control, &TwinRequest::Attach { connection });
    assert_eq!((e, speed), (0, u64::from(SPEED_CODE)));
    let (e, _, payload) = call(
        &control,
        &TwinRequest::GetInfo {
            version: 6,
            rom_length: 0,
            bus_reset_closure: 0,
        },
    );
    assert_eq!(e, 0);
    let (_, _, record, _) = split_info_payload(&payload).unwrap();
    let (_, record) = BusResetRecord::parse(record).unwrap();

    // Two requests, no reply to either: a quadlet read of the ROM and one
    // from a stale generation.
    let read = |closure, generation| SendRequestArgs {
        tcode: 4,
        length: 4,
        offset: 0xFFFF_F000_0400,
        closure,
        data: 0,
        generation,
    };
    for (closure, generation) in [(5, record.generation), (6, record.generation + 7)] {
        let request = TwinRequest::SendRequest {
            broadcast: false,
            args: read(closure, generation),
            payload: &[0; 4],
        };
        assert!(!request.expects_reply());
        send_request(&control, &request);
    }
    let mut completions = Vec::new();
    for _ in 0..2 {
        wait_readable(&event);
        let mut buf = [0u8; 256];
        let n = recv(event.as_raw_fd(), &mut buf, MsgFlags::empty()).unwrap();
        let r = ResponseEvent::parse(&buf[..n]).unwrap();
        completions.push((r.closure, r.rcode));
    }
    completions.sort_unstable();
    assert_eq!(
        completions,
        [(5, rcode::COMPLETE), (6, rcode::GENERATION)],
        "one completion per request"
    );
    // Both were handled (their events came) and nothing came back on the
    // control connection.
    let mut buf = [0u8; 256];
    assert_eq!(
        recv(control.as_raw_fd(), &mut buf, MsgFlags::MSG_DONTWAIT),
        Err(Errno::EAGAIN)
    );
    // The next call's reply is its own.
    let (e, speed, _) = call(&control, &TwinRequest::GetSpeed);
    assert_eq!((e, speed), (0, u64::from(SPEED_CODE)));

    // A message that does not parse closes the control connection, with
    // no reply that a later call could take for its own.
    send(control.as_raw_fd(), &[0xEE; 6], MsgFlags::MSG_NOSIGNAL).unwrap();
    wait_readable(&control);
    assert_eq!(
        recv(control.as_raw_fd(), &mut buf, MsgFlags::empty()),
        Ok(0)
    );

    stop.store(true, Ordering::Relaxed);
    let twin = server.join().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let stats = twin.stats();
    assert_eq!((stats.requests, stats.completions), (2, 2), "{stats}");
    assert_eq!(stats.refused, 1, "{stats}");
}
