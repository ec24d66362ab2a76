//! `firelink emulate` as a user runs it: start it, scan it over loopback
//! UDP with `firelink scan --json`, read a register, stop it with SIGTERM.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use serde_json::Value;

fn firelink() -> Command {
    Command::new(env!("CARGO_BIN_EXE_firelink"))
}

type Lines = std::io::Lines<BufReader<std::process::ChildStdout>>;

/// `firelink emulate` with `args` on an ephemeral loopback port: the
/// server, its remaining output lines and the `--port` string to reach it.
fn start_emulate(args: &[&str]) -> (std::process::Child, Lines, String) {
    let mut server = firelink()
        .arg("emulate")
        .args(args)
        .args(["--listen", "127.0.0.1:0", "--no-broadcast"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start emulate");
    let stdout = server.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    let mut addr = None;
    for line in lines.by_ref() {
        let line = line.unwrap();
        if let Some(rest) = line.strip_prefix("listening on udp ") {
            addr = rest.split_whitespace().next().map(str::to_string);
            break;
        }
    }
    let addr = addr.expect("emulate prints its address");
    (server, lines, format!("udp:{addr}"))
}

/// `firelink scan --json` of the boards at `port`.
fn scan(port: &str) -> Value {
    let out = firelink()
        .args(["scan", "--port", port, "--json", "--timeout-ms", "100"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn emulate_serves_each_stock_arm_configuration() {
    let configs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
    // (file, boards on the bus, (board, DIGIN bits 11:0 expected)).
    for (file, boards, digin) in [
        // PSM1 on boards 6-7: sterile adapter in (bit 10), no instrument
        // (bit 7), as the file's simulation section says.
        ("dvrk-psm1-28007.json", 8, Some((7, 0x400))),
        ("dvrk-mtmr-28247.json", 4, None),
        ("dvrk-ecm-29738.json", 6, None),
    ] {
        let path = configs.join(file);
        let (mut server, _lines, port) = start_emulate(&["--config", path.to_str().unwrap()]);
        let out = firelink()
            .args(["scan", "--port", &port, "--json", "--timeout-ms", "100"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["boards"].as_array().unwrap().len(), boards, "{file}");
        if let Some((board, bits)) = digin {
            let out = firelink()
                .args(["read", "--port", &port, "--board", &board.to_string(), "10"])
                .args(["--timeout-ms", "100"])
                .output()
                .unwrap();
            assert!(out.status.success(), "{file}");
            let text = String::from_utf8(out.stdout).unwrap();
            let value = u32::from_str_radix(text.trim().rsplit(' ').next().unwrap(), 16).unwrap();
            assert_eq!(value & 0x0FFF, bits, "{file}: DIGIN {text}");
        }
        server.kill().unwrap();
        server.wait().unwrap();
    }
}

#[test]
fn emulate_scan_read_and_clean_shutdown() {
    let (mut server, lines, port) = start_emulate(&["--boards", "3"]);

    let v = scan(&port);
    let boards = v["boards"].as_array().unwrap();
    assert_eq!(boards.len(), 3);
    for (i, b) in boards.iter().enumerate() {
        assert_eq!(b["board_id"], i);
        assert_eq!(b["node"], i);
        assert_eq!(b["hardware"], "QLA1");
        assert_eq!(b["firmware"], 8);
        assert_eq!(b["fpga"], 2);
    }
    assert_eq!(v["protocol"], "broadcast");

    let out = firelink()
        .args([
            "read",
            "--port",
            &port,
            "--board",
            "2",
            "hw_version",
            "--timeout-ms",
            "100",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        String::from_utf8(out.stdout).unwrap().trim(),
        "0x0004: 514c4131"
    );

    // SIGTERM: the server says it stopped, with its counters, and exits 0.
    let status = Command::new("kill")
        .args(["-TERM", &server.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let exit = server.wait().unwrap();
    assert!(exit.success(), "{exit:?}");
    assert!(rest.iter().any(|l| l.starts_with("stopped:")), "{rest:?}");
    assert!(rest.iter().any(|l| l.starts_with("host 127.0.0.1")));
}

#[test]
fn emulate_refuses_bad_options() {
    let out = firelink()
        .args(["emulate", "--boards", "17", "--listen", "127.0.0.1:0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("between 1 and 16 boards"));
    let out = firelink()
        .args(["emulate", "--firmware", "9"])
        .output()
        .unwrap();
    assert!(!out.status.success());
}

#[test]
fn sim_port_strings_work_everywhere() {
    let out = firelink()
        .args(["scan", "--port", "sim:5:7", "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["boards"].as_array().unwrap().len(), 5);
    assert_eq!(v["boards"][0]["firmware"], 7);
    let out = firelink()
        .args(["monitor", "--port", "sim:2", "--once", "20"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("cycles 20"), "{text}");
    assert!(text.contains("errors 0"), "{text}");
    let out = firelink()
        .args(["scan", "--port", "sim:99"])
        .output()
        .unwrap();
    assert!(!out.status.success());
}

/// Per-board settings: companion board type and serials from the command
/// line (and, with --config, the arms' serial numbers), shown at start;
/// settings the boards cannot hold are refused with the reason.
#[test]
fn emulate_board_settings() {
    let mut server = firelink()
        .args([
            "emulate",
            "--boards",
            "2",
            "--board-set",
            "1:hardware=DQLA,qla-serial=22723,fpga-serial=5496-07,supply-volts=36",
            "--listen",
            "127.0.0.1:0",
            "--no-broadcast",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start emulate");
    let stdout = server.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    let mut seen = Vec::new();
    let mut addr = None;
    for line in lines.by_ref() {
        let line = line.unwrap();
        if let Some(rest) = line.strip_prefix("listening on udp ") {
            addr = rest.split_whitespace().next().map(str::to_string);
            break;
        }
        seen.push(line);
    }
    let board1 = seen
        .iter()
        .find(|l| l.contains("board 1:"))
        .expect("board 1 line");
    assert!(board1.contains("DQLA"), "{board1}");
    assert!(board1.contains("FPGA serial 5496-07"), "{board1}");
    assert!(board1.contains("QLA serial 22723 / 22723"), "{board1}");
    assert!(board1.contains("36 V"), "{board1}");
    let board0 = seen
        .iter()
        .find(|l| l.contains("board 0:"))
        .expect("board 0 line");
    assert!(board0.contains("QLA1"), "{board0}");
    let port = format!("udp:{}", addr.expect("address"));
    let out = firelink()
        .args(["scan", "--port", &port, "--json", "--timeout-ms", "100"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["boards"][1]["hardware"], "DQLA");
    let _ = Command::new("kill")
        .args(["-TERM", &server.id().to_string()])
        .status();
    assert!(server.wait().unwrap().success());

    // The stock dVRK configuration: each arm's boards carry its serial.
    let config = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/dvrk-seed000.json"
    );
    let out = firelink()
        .args(["emulate", "--config", config, "--listen", "127.0.0.1:0"])
        .args(["--no-broadcast", "--duration-s", "0.2"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("board 0: QLA1, FPGA serial 8801-01, QLA serial 22723"),
        "{text}"
    );

    for (setting, words) in [
        ("1:qla-serial=123456789", "QLA serial number"),
        ("5:qla-serial=1", "no such board"),
        ("1:colour=red", "unknown key"),
    ] {
        let out = firelink()
            .args(["emulate", "--boards", "2", "--board-set", setting])
            .args(["--listen", "127.0.0.1:0", "--duration-s", "0.1"])
            .output()
            .unwrap();
        assert!(!out.status.success(), "{setting}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(words), "{setting}: {err}");
    }
}
