//! The kernel's behaviours through the preloaded twin, one test each.
//!
//! Each test runs the twin's server on a thread of this process (two Rev 8
//! boards, /dev/fw1 and /dev/fw2; the PC's card is /dev/fw0) and this test
//! executable again as a child with `libfirelink_fwcdev.so` preloaded and
//! `FIRELINK_FW_CDEV` set: the child calls glibc's `open`, `ioctl`, `read`,
//! `poll` and `close` exactly as a program on a real card does, checks what
//! the twin answers, and exits 0 when all is as the kernel does it. Every
//! wait in the child is bounded (a lost event fails the test, never hangs
//! it); nothing asserts a duration.
#![allow(unsafe_code)]

use std::ffi::CString;
use std::io::{BufRead, BufReader};
use std::os::fd::OwnedFd;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::{FaultRule, PacketFault, PacketMatch, TimedFault};
use firelink_emulate::fw_cdev::{self, Twin};
use firelink_wire::fw_cdev::{
    BusResetRecord, GetInfoArgs, IOC_GET_INFO, IOC_INITIATE_BUS_RESET, IOC_SEND_BROADCAST_REQUEST,
    IOC_SEND_REQUEST, ResponseEvent, SendRequestArgs, errno, rcode,
};
use firelink_wire::packet::Tcode;

const CHILD_ENV: &str = "FWCDEV_TEST_CHILD";

/// The preloaded library, built by cargo beside this test's directory.
fn library() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    let dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let lib = dir.join("libfirelink_fwcdev.so");
    assert!(
        lib.exists(),
        "{} is missing: `cargo test --workspace` builds it (or `cargo build -p firelink-fwcdev`)",
        lib.display()
    );
    lib
}

/// How the server side of one test is set up.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Setup {
    Plain,
    /// Board 1 (/dev/fw2) never answers.
    MuteSecond,
    /// The next quadlet read response on the bus is lost.
    DropOneResponse,
    /// Board 0 (/dev/fw1, the far end of the chain) is unplugged once the
    /// child says "unplug".
    UnplugOnCue,
}

/// Run the child scenario `name` against a twin of two boards; the test
/// fails with the child's output unless it exits 0 having run that one
/// test.
fn run_child(name: &str, setup: Setup) {
    if std::env::var_os(CHILD_ENV).is_some() {
        return;
    }
    let boards = (0..2)
        .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8).with_seed(u64::from(id)))
        .collect();
    let mut rig = BoardRig::daisy_chain(boards, &RigOptions::default());
    let first = rig.boards[0];
    let second = rig.boards[1];
    if setup == Setup::MuteSecond {
        let at = rig.bus.now();
        rig.bus.schedule_fault(
            at,
            TimedFault::StopAnswering {
                node: second,
                duration: None,
            },
        );
    }
    let mut twin = Twin::new(rig.bus, rig.host);
    if setup == Setup::DropOneResponse {
        twin.bus_mut().add_fault_rule(FaultRule::once(
            PacketMatch::any().tcode(Tcode::ReadQuadletResponse),
            PacketFault::Drop,
        ));
    }
    let dir = std::env::temp_dir().join(format!("fwcdev-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let socket = dir.join("twin.sock");
    let listener: OwnedFd = fw_cdev::bind(&socket).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let unplug = Arc::new(AtomicBool::new(false));
    let server = {
        let (stop, unplug) = (Arc::clone(&stop), Arc::clone(&unplug));
        std::thread::spawn(move || {
            let mut unplugged = false;
            fw_cdev::serve_with(
                &mut twin,
                &listener,
                &stop,
                |_| {},
                |t: &mut Twin| {
                    if !unplugged && unplug.load(Ordering::Relaxed) {
                        unplugged = true;
                        let at = t.bus().now();
                        t.bus_mut().schedule_fault(
                            at,
                            TimedFault::Disconnect {
                                node: first,
                                reconnect_after: None,
                            },
                        );
                    }
                },
            )
            .unwrap();
            twin
        })
    };
    // libtest's name for the test: this module's path in the test binary,
    // without the binary's own name, then the function.
    let exact = match module_path!().split_once("::") {
        Some((_binary, module)) => format!("{module}::{name}"),
        None => name.to_string(),
    };
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args([exact.as_str(), "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, name)
        .env("LD_PRELOAD", library())
        .env("FIRELINK_FW_CDEV", &socket)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = Vec::new();
    for line in BufReader::new(child.stdout.take().unwrap()).lines() {
        let line = line.unwrap();
        if line.contains("CUE unplug") {
            unplug.store(true, Ordering::Relaxed);
        }
        lines.push(line);
    }
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    let twin = server.join().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        out.status.success(),
        "child {name} failed ({}):\n{}\n{}",
        out.status,
        lines.join("\n"),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        lines
            .iter()
            .any(|l| l.contains("test result: ok. 1 passed")),
        "{exact} did not run in the child:\n{}",
        lines.join("\n")
    );
    // Every request the twin accepted was completed exactly once.
    let stats = twin.stats();
    assert_eq!(stats.requests, stats.completions, "{stats}");
}

fn in_child(name: &str) -> bool {
    std::env::var(CHILD_ENV).is_ok_and(|c| c == name)
}

// ---- what the child does: glibc calls, as a program on a real card ----

fn open_dev(n: u32) -> i32 {
    let path = CString::new(format!("/dev/fw{n}")).unwrap();
    // SAFETY: a C string path.
    let fd = unsafe { libc::open(path.as_ptr(), libc::O_RDWR) };
    assert!(
        fd >= 0,
        "open /dev/fw{n}: {}",
        std::io::Error::last_os_error()
    );
    fd
}

fn ioctl(fd: i32, request: u64, arg: &mut [u8]) -> Result<i32, i32> {
    // SAFETY: `arg` is the argument's bytes, writable.
    let r = unsafe { libc::ioctl(fd, request as libc::c_ulong, arg.as_mut_ptr()) };
    if r < 0 {
        Err(std::io::Error::last_os_error().raw_os_error().unwrap())
    } else {
        Ok(r)
    }
}

/// GET_INFO at ABI `version`: (kernel version, rom, bus-reset record).
fn get_info(fd: i32, version: u32, closure: u64) -> (u32, Vec<u8>, BusResetRecord, u32) {
    let mut rom = vec![0xA5u8; 1024];
    let mut record = [0xA5u8; 40];
    let args = GetInfoArgs {
        version,
        rom_length: rom.len() as u32,
        rom: rom.as_mut_ptr() as u64,
        bus_reset: record.as_mut_ptr() as u64,
        bus_reset_closure: closure,
        card: 99,
    };
    let mut a = [0u8; 40];
    args.emit(&mut a).unwrap();
    ioctl(fd, IOC_GET_INFO, &mut a).expect("GET_INFO");
    let back = GetInfoArgs::parse(&a).unwrap();
    rom.truncate(back.rom_length as usize);
    let (c, rec) = BusResetRecord::parse(&record).unwrap();
    assert_eq!(c, closure);
    (back.version, rom, rec, back.card)
}

fn send(
    fd: i32,
    broadcast: bool,
    tcode: u32,
    offset: u64,
    data: &mut [u8],
    closure: u64,
    generation: u32,
) -> Result<i32, i32> {
    let args = SendRequestArgs {
        tcode,
        length: data.len() as u32,
        offset,
        closure,
        data: data.as_mut_ptr() as u64,
        generation,
    };
    let mut a = [0u8; 40];
    args.emit(&mut a).unwrap();
    let request = if broadcast {
        IOC_SEND_BROADCAST_REQUEST
    } else {
        IOC_SEND_REQUEST
    };
    ioctl(fd, request, &mut a)
}

/// Wait (bounded) for the next event on `fd`; its bytes.
fn next_event(fd: i32) -> Vec<u8> {
    let mut p = libc::pollfd {
        fd,
        events: libc::POLLIN,
        revents: 0,
    };
    // SAFETY: one pollfd.
    let r = unsafe { libc::poll(&mut p, 1, 30_000) };
    assert_eq!(r, 1, "no event within 30 s (a client would hang)");
    let mut buf = [0u8; 8192];
    // SAFETY: buf is writable.
    let n = unsafe { libc::read(fd, buf.as_mut_ptr().cast(), buf.len()) };
    assert!(n > 0, "read: {n} {}", std::io::Error::last_os_error());
    buf[..n as usize].to_vec()
}

fn close(fd: i32) {
    // SAFETY: our fd.
    assert_eq!(unsafe { libc::close(fd) }, 0);
}

// ---- the tests ----

#[test]
fn get_info_reports_abi_6_the_record_and_each_rom() {
    run_child(
        "get_info_reports_abi_6_the_record_and_each_rom",
        Setup::Plain,
    );
    if !in_child("get_info_reports_abi_6_the_record_and_each_rom") {
        return;
    }
    for version in [4, 5, 6] {
        let fd = open_dev(1);
        let (v, rom, rec, card) = get_info(fd, version, 0x1234);
        assert_eq!(v, 6);
        assert_eq!(card, 0);
        // The Rev 8 board's ROM from 0xFFFFF0000400: header, bus info
        // block, root directory (11 quadlets).
        assert_eq!(rom.len(), 44);
        assert_eq!(&rom[..8], &[0x04, 0x04, 0x84, 0x96, 0x31, 0x33, 0x39, 0x34]);
        // Two boards (phy 0 and 1) and the PC at the root, phy 2.
        assert_eq!(rec.node_id, 0xffc0);
        assert_eq!(rec.local_node_id, 0xffc2);
        assert_eq!(rec.root_node_id, 0xffc2);
        assert!(rec.generation >= 1);
        close(fd);
    }
    let fd = open_dev(0);
    let (_, rom, rec, _) = get_info(fd, 4, 0);
    assert_eq!(rec.node_id, rec.local_node_id);
    assert_eq!(&rom[4..8], b"1394");
    close(fd);
    // No /dev/fw3: the path is not there.
    let path = CString::new("/dev/fw3").unwrap();
    // SAFETY: a C string path.
    let fd = unsafe { libc::open(path.as_ptr(), libc::O_RDWR) };
    assert_eq!(fd, -1);
    assert_eq!(
        std::io::Error::last_os_error().raw_os_error(),
        Some(libc::ENOENT)
    );
}

#[test]
fn requests_complete_in_the_layout_of_the_client_abi() {
    run_child(
        "requests_complete_in_the_layout_of_the_client_abi",
        Setup::Plain,
    );
    if !in_child("requests_complete_in_the_layout_of_the_client_abi") {
        return;
    }
    // ABI 4: RESPONSE, the data at 20 and, for 4 bytes, again at 24.
    let fd = open_dev(1);
    let (_, _, rec, _) = get_info(fd, 4, 0);
    let g = rec.generation;
    let mut q = [0u8; 4];
    send(fd, false, 4, 0xFFFF_F000_0400, &mut q, 11, g).unwrap();
    let e = next_event(fd);
    assert_eq!(e.len(), 28);
    assert_eq!(u32::from_ne_bytes(e[8..12].try_into().unwrap()), 1);
    assert_eq!(&e[20..24], &[0x04, 0x04, 0x84, 0x96]);
    assert_eq!(&e[24..28], &[0x04, 0x04, 0x84, 0x96]);
    // Block read of 8 bytes: 24 + 8 bytes, data at 20 (the Rev 8 board
    // answers block reads of its ROM space with zeros).
    let mut b = [0u8; 8];
    send(fd, false, 5, 0xFFFF_F000_0400, &mut b, 12, g).unwrap();
    let e = next_event(fd);
    assert_eq!(e.len(), 32);
    let r = ResponseEvent::parse(&e).unwrap();
    assert_eq!((r.closure, r.rcode), (12, rcode::COMPLETE));
    assert_eq!(r.data.len(), 8);
    // Quadlet and block writes (the board's LED-free scratch: the
    // watchdog register, 3) complete with no data.
    let mut w = 0u32.to_be_bytes();
    send(fd, false, 0, 3, &mut w, 13, g).unwrap();
    let r = next_event(fd);
    let r = ResponseEvent::parse(&r).unwrap();
    assert_eq!((r.closure, r.rcode, r.data.len()), (13, rcode::COMPLETE, 0));
    let mut wb = [0u8; 8];
    send(fd, false, 1, 0x1000, &mut wb, 14, g).unwrap();
    let r = next_event(fd);
    assert_eq!(ResponseEvent::parse(&r).unwrap().closure, 14);
    close(fd);
    // ABI 6: RESPONSE2, data at 32, no second copy.
    let fd = open_dev(1);
    get_info(fd, 6, 0);
    send(fd, false, 4, 0xFFFF_F000_0400, &mut q, 21, g).unwrap();
    let e = next_event(fd);
    assert_eq!(e.len(), 36);
    assert_eq!(u32::from_ne_bytes(e[8..12].try_into().unwrap()), 0x0b);
    assert_eq!(&e[32..36], &[0x04, 0x04, 0x84, 0x96]);
    close(fd);
}

#[test]
fn refusals_are_the_kernels_errnos() {
    run_child("refusals_are_the_kernels_errnos", Setup::Plain);
    if !in_child("refusals_are_the_kernels_errnos") {
        return;
    }
    let fd = open_dev(0);
    let (_, _, rec, _) = get_info(fd, 4, 0);
    let g = rec.generation;
    let mut q = 1u32.to_be_bytes();
    // Broadcasts below the units space: EACCES; above: sent, completed.
    assert_eq!(
        send(fd, true, 0, 0xFFFF_F000_0000, &mut q, 1, g),
        Err(errno::EACCES)
    );
    assert_eq!(
        send(fd, true, 0, 0xFFFF_F000_07FC, &mut q, 1, g),
        Err(errno::EACCES)
    );
    assert_eq!(
        send(fd, true, 4, 0xFFFF_FFFF_0000, &mut q, 1, g),
        Err(errno::EINVAL)
    );
    send(fd, true, 0, 0xFFFF_F000_0800, &mut q, 2, g).unwrap();
    let r = next_event(fd);
    let r = ResponseEvent::parse(&r).unwrap();
    assert_eq!((r.closure, r.rcode), (2, rcode::COMPLETE));
    // Lengths: a short quadlet write EINVAL, over S400's 2048 EIO, a
    // tcode that is not a request EINVAL.
    let mut short = [0u8; 2];
    assert_eq!(send(fd, false, 0, 0, &mut short, 3, g), Err(errno::EINVAL));
    let mut big = vec![0u8; 2052];
    assert_eq!(send(fd, false, 5, 0, &mut big, 3, g), Err(errno::EIO));
    let mut huge = vec![0u8; 4100];
    assert_eq!(send(fd, false, 1, 0, &mut huge, 3, g), Err(errno::EIO));
    assert_eq!(send(fd, false, 2, 0, &mut q, 3, g), Err(errno::EINVAL));
    // Ioctls the twin does not implement: ENOTTY (also a known number with
    // the wrong size).
    let mut junk = [0u8; 64];
    assert_eq!(ioctl(fd, 0x5401, &mut junk), Err(libc::ENOTTY));
    assert_eq!(ioctl(fd, 0xc024_2300, &mut junk), Err(libc::ENOTTY));
    assert_eq!(ioctl(fd, 0xc018_2308, &mut junk), Err(libc::ENOTTY));
    // An fd that is not the twin's still reaches the real ioctl.
    assert_eq!(
        ioctl(0, 0xc028_2300, &mut junk).err().map(|e| e != 0),
        Some(true)
    );
    close(fd);
}

#[test]
fn every_request_completes_exactly_once_and_stale_generations_fail() {
    run_child(
        "every_request_completes_exactly_once_and_stale_generations_fail",
        Setup::Plain,
    );
    if !in_child("every_request_completes_exactly_once_and_stale_generations_fail") {
        return;
    }
    let fd = open_dev(2);
    let (_, _, rec, _) = get_info(fd, 4, 0);
    let g = rec.generation;
    let mut q = [0u8; 4];
    for closure in 0..50 {
        send(fd, false, 4, 0, &mut q, closure, g).unwrap();
    }
    send(fd, false, 4, 0, &mut q, 1000, g.wrapping_sub(1)).unwrap();
    let mut seen = Vec::new();
    loop {
        let e = next_event(fd);
        let r = ResponseEvent::parse(&e).unwrap();
        seen.push(r.closure);
        if r.closure == 1000 {
            assert_eq!(r.rcode, rcode::GENERATION);
            break;
        }
        assert_eq!(r.rcode, rcode::COMPLETE);
    }
    assert_eq!(seen, (0..50).chain([1000]).collect::<Vec<_>>());
    close(fd);
}

#[test]
fn an_absent_node_is_no_ack_and_a_lost_response_is_cancelled() {
    run_child(
        "an_absent_node_is_no_ack_and_a_lost_response_is_cancelled",
        Setup::MuteSecond,
    );
    run_child(
        "an_absent_node_is_no_ack_and_a_lost_response_is_cancelled",
        Setup::DropOneResponse,
    );
    if !in_child("an_absent_node_is_no_ack_and_a_lost_response_is_cancelled") {
        return;
    }
    // Under MuteSecond, board 1 never acks; under DropOneResponse the
    // first quadlet read's response is lost on the bus: the kernel waits
    // out its split time-out and cancels.
    let fd = open_dev(2);
    let (_, rom, rec, _) = get_info(fd, 4, 0);
    let mut q = [0u8; 4];
    send(fd, false, 4, 0, &mut q, 5, rec.generation).unwrap();
    let e = next_event(fd);
    let r = ResponseEvent::parse(&e).unwrap();
    let expected = if rom.is_empty() {
        rcode::NO_ACK
    } else {
        rcode::CANCELLED
    };
    assert_eq!((r.closure, r.rcode), (5, expected));
    close(fd);
}

#[test]
fn a_bus_reset_reaches_every_fd_and_an_unplugged_node_hangs_up() {
    run_child(
        "a_bus_reset_reaches_every_fd_and_an_unplugged_node_hangs_up",
        Setup::UnplugOnCue,
    );
    if !in_child("a_bus_reset_reaches_every_fd_and_an_unplugged_node_hangs_up") {
        return;
    }
    let fds: Vec<i32> = (0..3).map(open_dev).collect();
    let mut generation = 0;
    for (i, &fd) in fds.iter().enumerate() {
        let (_, _, rec, _) = get_info(fd, 4, 100 + i as u64);
        generation = rec.generation;
    }
    let mut arg = 0u32.to_ne_bytes();
    ioctl(fds[0], IOC_INITIATE_BUS_RESET, &mut arg).unwrap();
    let expected_nodes = [0xffc2, 0xffc0, 0xffc1];
    for (i, &fd) in fds.iter().enumerate() {
        let e = next_event(fd);
        let (closure, rec) = BusResetRecord::parse(&e).unwrap();
        assert_eq!(e.len(), 40);
        assert_eq!(closure, 100 + i as u64);
        assert_eq!(rec.node_id, expected_nodes[i]);
        assert!(rec.generation > generation);
    }
    // Unplug board 0 (/dev/fw1): its fd hangs up, the others see a reset.
    println!("CUE unplug");
    use std::io::Write;
    std::io::stdout().flush().unwrap();
    let mut p = libc::pollfd {
        fd: fds[1],
        events: libc::POLLIN,
        revents: 0,
    };
    // SAFETY: one pollfd.
    assert_eq!(unsafe { libc::poll(&mut p, 1, 30_000) }, 1);
    assert!(p.revents & libc::POLLHUP != 0, "revents {:#x}", p.revents);
    // The device is gone: its ioctls fail with ENODEV, as the kernel's do
    // on a shut-down device, and reading it ends (no event will come).
    let mut a = [0u8; 40];
    GetInfoArgs {
        version: 4,
        rom_length: 0,
        rom: 0,
        bus_reset: 0,
        bus_reset_closure: 0,
        card: 0,
    }
    .emit(&mut a)
    .unwrap();
    assert_eq!(ioctl(fds[1], IOC_GET_INFO, &mut a), Err(errno::ENODEV));
    let mut q = [0u8; 4];
    assert_eq!(
        send(fds[1], false, 4, 0, &mut q, 9, generation),
        Err(errno::ENODEV)
    );
    let mut buf = [0u8; 64];
    // SAFETY: a read into a local buffer.
    let n = unsafe { libc::read(fds[1], buf.as_mut_ptr().cast(), buf.len()) };
    assert_eq!(n, 0, "a read after the hang-up ends");
    let e = next_event(fds[2]);
    let (_, rec) = BusResetRecord::parse(&e).unwrap();
    // One board left (phy 0) and the PC (phy 1, the root).
    assert_eq!(rec.node_id, 0xffc0);
    assert_eq!(rec.root_node_id, 0xffc1);
    for fd in fds {
        close(fd);
    }
}

#[test]
fn the_card_answers_its_own_csrs() {
    run_child("the_card_answers_its_own_csrs", Setup::Plain);
    if !in_child("the_card_answers_its_own_csrs") {
        return;
    }
    // What a dVRK host does at open: STATE_CLEAR 0x100 (cycle master off)
    // on the local node, then read it back.
    let fd = open_dev(0);
    let (_, _, rec, _) = get_info(fd, 4, 0);
    let mut w = 0x100u32.to_be_bytes();
    send(fd, false, 0, 0xFFFF_F000_0000, &mut w, 1, rec.generation).unwrap();
    let e = next_event(fd);
    assert_eq!(ResponseEvent::parse(&e).unwrap().rcode, rcode::COMPLETE);
    let mut q = [0u8; 4];
    send(fd, false, 4, 0xFFFF_F000_0000, &mut q, 2, rec.generation).unwrap();
    let e = next_event(fd);
    let r = ResponseEvent::parse(&e).unwrap();
    assert_eq!(r.data, &[0, 0, 0, 0]);
    send(fd, false, 4, 0xFFFF_F000_0F00, &mut q, 3, rec.generation).unwrap();
    let e = next_event(fd);
    assert_eq!(
        ResponseEvent::parse(&e).unwrap().rcode,
        rcode::ADDRESS_ERROR
    );
    // /dev lists the twin's devices after the real entries.
    let names: Vec<String> = std::fs::read_dir("/dev")
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("fw"))
        .collect();
    for n in ["fw0", "fw1", "fw2"] {
        assert!(names.iter().any(|x| x == n), "{names:?}");
    }
    close(fd);
}
