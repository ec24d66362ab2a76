//! `firelink fw-run`: the emulated boards as /dev/fw* for an unmodified
//! program, and that program's exit status passed on.
//!
//! The preloaded library (`libfirelink_fwcdev.so`) is built beside the
//! `firelink` binary by `cargo test --workspace` (the firelink-fwcdev
//! crate's own tests need it too); a lone `cargo test -p firelink-cli`
//! must build it first (`cargo build -p firelink-fwcdev`).

use std::path::PathBuf;
use std::process::{Command, Output};

fn library() -> PathBuf {
    let lib = PathBuf::from(env!("CARGO_BIN_EXE_firelink")).with_file_name("libfirelink_fwcdev.so");
    assert!(
        lib.exists(),
        "{} is missing: run `cargo build -p firelink-fwcdev` (cargo test --workspace builds it)",
        lib.display()
    );
    lib
}

fn fw_run(args: &[&str]) -> Output {
    library();
    Command::new(env!("CARGO_BIN_EXE_firelink"))
        .arg("fw-run")
        .args(args)
        .output()
        .expect("run firelink fw-run")
}

#[test]
fn the_program_sees_a_device_per_node_in_dev() {
    // `ls` lists /dev with opendir/readdir: the card and three boards.
    let out = fw_run(&["--boards", "3", "--", "ls", "/dev"]);
    assert!(out.status.success(), "{out:?}");
    let listing = String::from_utf8_lossy(&out.stdout);
    let mut fw: Vec<&str> = listing.lines().filter(|l| l.starts_with("fw")).collect();
    fw.sort_unstable();
    assert_eq!(fw, ["fw0", "fw1", "fw2", "fw3"], "{listing}");
}

#[test]
fn the_programs_exit_status_is_fw_runs() {
    let out = fw_run(&["--boards", "1", "--", "sh", "-c", "exit 7"]);
    assert_eq!(out.status.code(), Some(7), "{out:?}");
    // A signal: 128 + its number, as a shell reports it.
    let out = fw_run(&["--boards", "1", "--", "sh", "-c", "kill -TERM $$"]);
    assert_eq!(out.status.code(), Some(128 + 15), "{out:?}");
    // A program that is not there is fw-run's own error.
    let out = fw_run(&["--boards", "1", "--", "/nonexistent/program"]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot run"));
}

#[test]
fn scan_through_the_twin_finds_eight_boards() {
    let out = fw_run(&[
        "--boards",
        "8",
        "--",
        env!("CARGO_BIN_EXE_firelink"),
        "scan",
        "--port",
        "fw",
    ]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with("8 board(s) on fw:"), "{text}");
    assert!(text.contains("protocol: broadcast"), "{text}");
}

#[test]
fn a_pcap_of_a_fw_session_holds_the_synthesised_packets() {
    let dir = std::env::temp_dir().join(format!("fw-pcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pcap = dir.join("fw.pcap");
    let out = fw_run(&[
        "--boards",
        "2",
        "--",
        env!("CARGO_BIN_EXE_firelink"),
        "scan",
        "--port",
        "fw",
        "--pcap",
        pcap.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{out:?}");
    let bytes = std::fs::read(&pcap).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    // A pcap header and, for a scan of two boards, dozens of packets.
    assert!(bytes.len() > 24 + 40 * 16, "{} bytes", bytes.len());
}

#[test]
fn bench_measures_the_fw_port_beside_its_floor_and_sim() {
    // `--transport fw` runs the command again with the twin preloaded.
    library();
    let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args([
            "bench",
            "--transport",
            "sim,fw",
            "--boards",
            "2",
            "--protocol",
            "broadcast",
            "--cycles",
            "60",
            "--json",
        ])
        .output()
        .expect("run firelink bench");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let results = report["results"].as_array().expect("results");
    let fw = results
        .iter()
        .find(|r| r["transport"] == "fw")
        .expect("an fw point");
    assert_eq!(fw["boards"], 2);
    assert_eq!(fw["cycles"], 60);
    assert_eq!(fw["errors"], 0, "{fw}");
    let figures = &fw["fw"];
    // The snooped-node-0 route: query, hub read, command write.
    assert_eq!(figures["round_trips"], 3.0, "{figures}");
    assert_eq!(figures["floor_errors"], 0);
    assert!(figures["floor_us"]["median"].as_f64().unwrap() > 0.0);
    assert!(figures["host_cpu_vs_sim"].as_f64().is_some(), "{figures}");
}
