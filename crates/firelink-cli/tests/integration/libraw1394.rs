//! Unmodified libraw1394 programs through the /dev/fw* twin (`firelink
//! fw-run`): Debian's `testlibraw` runs to its end, and a dVRK-style host
//! built against libraw1394 (`data/dvrk_style_host.c`, compiled here with
//! the system's `cc`) reads the same register values as Firelink's own
//! `--port fw`.
//!
//! Needs Debian's `libraw1394-11`, `libraw1394-dev` and `libraw1394-tools`
//! (`scripts/test` installs them with apt-get when missing) and a C
//! compiler; without them these tests fail saying so.

use std::path::{Path, PathBuf};
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

fn fw_run(emulate: &[&str], program: &[&str]) -> Output {
    library();
    Command::new(env!("CARGO_BIN_EXE_firelink"))
        .arg("fw-run")
        .args(emulate)
        .arg("--")
        .args(program)
        .output()
        .expect("run firelink fw-run")
}

fn require(path: &str, package: &str) {
    assert!(
        Path::new(path).exists(),
        "{path} is missing: install Debian's {package} (scripts/test does)"
    );
}

#[test]
fn testlibraw_runs_to_its_end_through_the_twin() {
    require("/usr/bin/testlibraw", "libraw1394-tools");
    let out = fw_run(&["--boards", "2"], &["testlibraw"]);
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    for expected in [
        "1 card found",
        "3 nodes on bus, local ID is 2",
        // Quadlet reads in CSR space of every node: the boards' config ROM
        // header, asynchronously through a custom tag handler (printed in
        // host byte order) and synchronously.
        "read from node 0... completed with value 0x96840404",
        "read from node 1... completed with value 0x96840404",
        "read from node 0... completed with value 0x04048496",
        "read from node 1... completed with value 0x04048496",
        "get_config_rom returned 0",
        "cycle timer:",
        // The end of the program.
        "raw1394_loop_iterate() returned 0xdeadbeef",
    ] {
        assert!(text.contains(expected), "no {expected:?} in:\n{text}");
    }
    // Reads through the custom tag handler complete too (no failure).
    assert!(!text.contains("failed: Bad address"), "{text}");
}

#[test]
fn a_dvrk_style_libraw1394_host_reads_what_firelinks_port_reads() {
    require("/usr/include/libraw1394/raw1394.h", "libraw1394-dev");
    let dir = std::env::temp_dir().join(format!("dvrk-host-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exe = dir.join("dvrk_style_host");
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/dvrk_style_host.c");
    let built = Command::new("cc")
        .arg("-o")
        .arg(&exe)
        .arg(&source)
        .arg("-lraw1394")
        .output()
        .expect("a C compiler (cc)");
    assert!(built.status.success(), "{built:?}");
    let out = fw_run(&["--boards", "3"], &[exe.to_str().unwrap()]);
    let _ = std::fs::remove_dir_all(&dir);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("nodes 4 local 3"), "{text}");
    assert!(text.ends_with("done\n"), "{text}");
    // The same registers through Firelink's own port.
    let firelink = env!("CARGO_BIN_EXE_firelink");
    for board in 0..3u32 {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("node {board} ")))
            .unwrap_or_else(|| panic!("no line for node {board}:\n{text}"));
        let read = |offset: &str| -> String {
            let out = fw_run(
                &["--boards", "3"],
                &[
                    firelink,
                    "read",
                    "--port",
                    "fw",
                    "--board",
                    &board.to_string(),
                    offset,
                ],
            );
            assert!(out.status.success(), "{out:?}");
            let shown = String::from_utf8_lossy(&out.stdout).into_owned();
            shown.trim().rsplit(' ').next().unwrap_or("").to_string()
        };
        let hw = read("4");
        let fw = read("7");
        assert!(line.contains(&format!("hw {hw} ")), "{line} vs {hw}");
        assert!(line.contains(&format!("fw {fw} ")), "{line} vs {fw}");
        // The watchdog register holds what the C host wrote; the block
        // read completed with its two quadlets.
        assert!(
            line.contains(&format!("wd {:08x} ", 0x1680 + board)),
            "{line}"
        );
        assert!(line.contains(" block ") && line.contains(','), "{line}");
    }
}
