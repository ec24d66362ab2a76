//! A stopped program stops the robot: `firelink demo` (and the programs
//! `firelink web` becomes) driving emulated boards behind `firelink
//! emulate`, ended by SIGTERM, SIGINT or SIGHUP as a supervisor, a user or
//! a closed terminal would; afterwards a second client reads the boards'
//! STATUS registers. The robot is the bench board (four gentle axes) with a
//! 300 ms watchdog, so that a loaded machine cannot end the run on its own
//! before the signal does.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// A running `firelink emulate` of the bench board on an ephemeral
/// loopback port.
struct Emulate {
    server: Child,
    port: String,
}

impl Emulate {
    fn bench() -> Emulate {
        let config = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/bench-1board.json"
        );
        let mut server = Command::new(env!("CARGO_BIN_EXE_firelink"))
            .args(["emulate", "--config", config])
            .args(["--listen", "127.0.0.1:0", "--no-broadcast"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start emulate");
        let stdout = server.stdout.take().expect("piped stdout");
        let mut addr = None;
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(rest) = line.strip_prefix("listening on udp ") {
                addr = rest.split_whitespace().next().map(str::to_string);
                break;
            }
        }
        let addr = addr.expect("emulate prints its address");
        Emulate {
            server,
            port: format!("udp:{addr}"),
        }
    }

    /// Board 0's STATUS as a second client reads it (quadlet reads only:
    /// they do not disturb a running program's cycles).
    fn status(&self) -> Status {
        let out = Command::new(env!("CARGO_BIN_EXE_firelink"))
            .args([
                "read",
                "--port",
                &self.port,
                "--node",
                "0",
                "--timeout-ms",
                "500",
            ])
            .arg("status")
            .output()
            .expect("firelink read");
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "read: {text} {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let word = text
            .split_whitespace()
            .last()
            .and_then(|w| u32::from_str_radix(w, 16).ok())
            .unwrap_or_else(|| panic!("a STATUS word in {text:?}"));
        Status(word)
    }
}

impl Drop for Emulate {
    fn drop(&mut self) {
        let _ = self.server.kill();
        let _ = self.server.wait();
    }
}

/// STATUS (`fpga-board.md` §2): power bit 18, amplifiers bits 3:0.
#[derive(Debug, Clone, Copy)]
struct Status(u32);

impl Status {
    fn powered(self) -> bool {
        self.0 & (1 << 18) != 0
    }
    fn amplifiers(self) -> u32 {
        self.0 & 0xF
    }
}

/// `firelink ARGS` running with its stderr lines readable.
struct Running {
    child: Child,
    lines: std::io::Lines<BufReader<std::process::ChildStderr>>,
    seen: Vec<String>,
}

impl Running {
    fn start(args: &[&str]) -> Running {
        let mut child = Command::new(env!("CARGO_BIN_EXE_firelink"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start firelink");
        let lines = BufReader::new(child.stderr.take().expect("stderr")).lines();
        Running {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// Read stderr until a line contains `needle` (the program's own
    /// progress: no sleeping for a guessed time).
    fn wait_for(&mut self, needle: &str) {
        for line in self.lines.by_ref().map_while(Result::ok) {
            let done = line.contains(needle);
            self.seen.push(line);
            if done {
                return;
            }
        }
        panic!("never printed {needle:?}: {:?}", self.seen);
    }

    /// Send `signal` (by name, as `kill -NAME`) and collect the rest.
    fn signal(mut self, signal: &str) -> (ExitStatus, String) {
        let kill = Command::new("kill")
            .args([&format!("-{signal}"), &self.child.id().to_string()])
            .status()
            .expect("kill");
        assert!(kill.success());
        self.seen.extend(self.lines.by_ref().map_while(Result::ok));
        let status = self.child.wait().expect("exit status");
        (status, self.seen.join("\n"))
    }
}

/// A test that fails on the way does not leave its program running.
impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn demo_args(port: &str) -> Vec<String> {
    let config = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/bench-1board.json"
    );
    [
        "demo",
        "--port",
        port,
        "--config",
        config,
        "--duration",
        "3600",
        "--rate",
        "1000",
        "--watchdog-ms",
        "300",
        // The boards' server is another process, which a loaded machine
        // may keep waiting: at the default 20 ms a slow answer is a missed
        // board, a fault that ends the demo before the signal (2 runs in
        // 2 under load). Each absent node costs the scan this much.
        "--timeout-ms",
        "250",
        "--no-rt",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

fn stopping_the_demo_powers_it_down(signal: &str, number: i32) {
    let emu = Emulate::bench();
    let args = demo_args(&emu.port);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut demo = Running::start(&args);
    // Powered, homed and enabled: the lifecycle checked the boards' own
    // STATUS before it said so. Signal at once (a loaded machine can make
    // a long run fault by itself; that is not what this test is about).
    demo.wait_for("homed and active");
    let (status, stderr) = demo.signal(signal);
    assert_eq!(
        std::os::unix::process::ExitStatusExt::into_raw(status) >> 8,
        128 + number,
        "exit status after SIG{signal}: {status:?}\n{stderr}"
    );
    assert!(
        stderr.contains(&format!("stopped by SIG{signal}"))
            && stderr.contains("then powered down: amplifiers and motor power off on boards 0"),
        "{stderr}"
    );
    let off = emu.status();
    assert!(
        !off.powered() && off.amplifiers() == 0,
        "after SIG{signal}: {off:?}"
    );
}

#[test]
fn sigterm_stops_the_demo_with_the_robot_powered_down() {
    stopping_the_demo_powers_it_down("TERM", 15);
}

#[test]
fn sigint_stops_the_demo_with_the_robot_powered_down() {
    stopping_the_demo_powers_it_down("INT", 2);
}

#[test]
fn sighup_stops_the_demo_with_the_robot_powered_down() {
    stopping_the_demo_powers_it_down("HUP", 1);
}

/// Read board 0's STATUS until `done` holds (bounded).
fn wait_for_status(emu: &Emulate, what: &str, done: impl Fn(Status) -> bool) -> Status {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let s = emu.status();
        if done(s) {
            return s;
        }
        assert!(Instant::now() < deadline, "{what}: {s:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `kill -9` runs nothing on the way out: the boards' watchdog is what
/// turns the amplifiers off, and the next program takes the boards over.
#[test]
fn after_kill_9_the_watchdog_turns_the_amplifiers_off_and_the_next_run_takes_over() {
    let emu = Emulate::bench();
    let args = demo_args(&emu.port);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut demo = Running::start(&args);
    demo.wait_for("homed and active");
    let _ = demo.signal("KILL");
    let s = wait_for_status(&emu, "the watchdog fires", |s| s.0 & (1 << 23) != 0);
    assert!(s.powered() && s.amplifiers() == 0, "{s:?}");
    // The next run finds the boards as the killed one left them, powers
    // them down first, and runs.
    let mut next = Running::start(&args);
    next.wait_for("homed and active");
    let (_, stderr) = next.signal("TERM");
    assert!(
        stderr.contains("found motor power on at boards 0")
            && stderr.contains("watchdog timed out at boards 0"),
        "{stderr}"
    );
    let off = emu.status();
    assert!(!off.powered() && off.amplifiers() == 0, "{off:?}");
}

/// `firelink web` and `firelink ros2` *become* their companion binaries:
/// the process a supervisor started is the one that drives the robot, so
/// its signal reaches that program and no wrapper is left to die while an
/// orphan keeps the amplifiers on. Shown with a stand-in companion (a
/// shell script next to a copy of `firelink`) that reports its PID and the
/// signal it gets.
#[test]
fn web_and_ros2_become_their_companion_so_signals_reach_it() {
    use std::os::unix::fs::PermissionsExt;
    let dir = std::env::temp_dir().join(format!("firelink-companion-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let firelink = dir.join("firelink");
    std::fs::copy(env!("CARGO_BIN_EXE_firelink"), &firelink).expect("copy firelink");
    for (command, name) in [("web", "firelink-web"), ("ros2", "firelink-ros2")] {
        let script = dir.join(name);
        let marker = dir.join(format!("{name}.term"));
        std::fs::write(
            &script,
            format!(
                "#!/bin/sh\n\
                 trap 'echo \"$*\" > {m}; exit 0' TERM\n\
                 echo \"pid $$ args $*\"\n\
                 while :; do sleep 0.05; done\n",
                m = marker.display()
            ),
        )
        .expect("write the stand-in");
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).expect("chmod");
        let mut child = Command::new(&firelink)
            .args([command, "--port", "sim", "--listen", "127.0.0.1:0"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start firelink");
        let mut lines = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let first = lines
            .next()
            .and_then(Result::ok)
            .expect("the companion's line");
        // The same process: exec, not a child.
        assert_eq!(
            first,
            format!("pid {} args --port sim --listen 127.0.0.1:0", child.id()),
            "{command}"
        );
        let kill = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .expect("kill");
        assert!(kill.success());
        let status = child.wait().expect("exit");
        assert!(status.success(), "{command}: {status:?}");
        let got = std::fs::read_to_string(&marker).expect("the companion got SIGTERM");
        assert_eq!(got.trim(), "--port sim --listen 127.0.0.1:0", "{command}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
