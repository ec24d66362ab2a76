//! `--servo-stream ARM`, the benchmark's comparison run without DDS (the
//! client's stream made in the node's process): what the command line
//! refuses, before anything runs. (What the stream sends is pinned by the
//! library's unit test `the_in_process_stream_queues_the_benchmark_clients_points`.)

use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_firelink-ros2"))
        .args(["--port", "sim", "--no-rt", "--seconds", "0.2"])
        .args(args)
        .output()
        .expect("run firelink-ros2")
}

#[test]
fn a_servo_stream_needs_no_dds() {
    let out = run(&["--servo-stream", "PSM1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--no-dds"), "{stderr}");
    assert!(out.stdout.is_empty());
}

#[test]
fn a_servo_stream_for_an_arm_the_configuration_lacks_is_refused_by_name() {
    let out = run(&["--no-dds", "--servo-stream", "PSM9"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("servo stream: no arm named PSM9"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
}
