//! A closed pipe on either side of the command line: `firelink demo 2>&1 |
//! head` must not panic mid-run (the robot's power-down would be left to
//! the boards' watchdogs), and `firelink sim --timeline | head` stops
//! without a message, with SIGPIPE's status (141). The pipes are made,
//! and their read ends closed, before the program starts, so every write
//! of the program meets the closed pipe.

use std::io::Read;
use std::process::{Command, Stdio};

/// A pipe whose read end is already closed.
fn closed_pipe() -> Stdio {
    // Close-on-exec: no other test's child may inherit the read end.
    let (reader, writer) = nix::unistd::pipe2(nix::fcntl::OFlag::O_CLOEXEC).expect("a pipe");
    drop(reader);
    Stdio::from(writer)
}

#[test]
fn progress_lines_to_a_closed_stderr_do_not_stop_the_program() {
    // Progress on (no FIRELINK_QUIET): every line goes to the closed pipe.
    let mut child = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args(["demo", "--duration", "0.05", "--json"])
        .env_remove("FIRELINK_QUIET")
        .stdout(Stdio::piped())
        .stderr(closed_pipe())
        .spawn()
        .expect("run firelink");
    let mut out = String::new();
    child
        .stdout
        .take()
        .expect("stdout")
        .read_to_string(&mut out)
        .expect("read stdout");
    let status = child.wait().expect("wait");
    assert!(status.success(), "the demo ended with {status}");
    let report: serde_json::Value = serde_json::from_str(&out).expect("the demo's JSON report");
    assert!(report.is_object(), "{out}");
}

#[test]
fn a_closed_stdout_ends_the_program_without_a_message_as_sigpipe_would() {
    let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args(["sim", "--timeline"])
        .stdout(closed_pipe())
        .stderr(Stdio::piped())
        .output()
        .expect("run firelink");
    assert_eq!(out.status.code(), Some(141), "{:?}", out.status);
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_closed_stdout_and_stderr_do_not_panic() {
    let status = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args(["sim", "--timeline"])
        .stdout(closed_pipe())
        .stderr(closed_pipe())
        .status()
        .expect("run firelink");
    assert_eq!(status.code(), Some(141), "{status:?}");
}
