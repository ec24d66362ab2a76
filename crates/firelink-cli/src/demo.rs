//! `firelink demo`: the README's main job. The 28-axis dVRK of seed 000 on
//! emulated boards: configure, power on, home, follow trajectories on all
//! four arms, power off, and report.

use std::io::Write;
use std::time::{Duration, Instant};

use clap::Args;
use serde_json::{Value, json};

use firelink_bus::NodeHandle;
use firelink_bus::fault::{FaultPlan, PacketFault, PacketMatch, TimedFault};
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::loopback::LoopbackPort;
use firelink_control::runner::{Pacing, Percentiles, Robot, RobotSettings, RunnerError};
use firelink_control::trajectory::{Motion, PointToPoint, Sinusoid};
use firelink_control::{FaultKind, FaultReport, State};
use firelink_host::Port;
use firelink_host::io::{IoConfig as HostIoConfig, IoSystem};
use firelink_host::scan::Protocol;
use firelink_host::sim::SimPort;
use firelink_host::udp::UdpPort;
use firelink_wire::packet::Tcode;

use crate::CliError;
use crate::rt;
use firelink_testbed::rig;

/// Options of `firelink demo`.
#[derive(Args, Debug, Clone)]
pub struct DemoArgs {
    /// Control rate, Hz (1 to 100000).
    #[arg(long, default_value_t = 6000.0, value_parser = crate::args::rate_hz)]
    pub rate: f64,
    /// I/O protocol: broadcast, sequential or seq-bc.
    #[arg(long, default_value = "broadcast")]
    pub protocol: String,
    /// Seconds of motion after homing (above 0, at most a day).
    #[arg(long, default_value_t = 3.0, value_parser = crate::args::run_seconds)]
    pub duration: f64,
    /// Where the boards are: `sim` (emulated boards on the simulated bus,
    /// in-process), `emulate` (the same boards behind an in-process
    /// `firelink emulate`, over loopback UDP), `udp:HOST[:PORT]` (a running
    /// `firelink emulate` or a real bridge board) or `loopback` (the
    /// port-level board model, no bus).
    #[arg(long, default_value = "sim")]
    pub port: String,
    /// Board firmware of the emulated boards: 7, 8 or seed.
    #[arg(long, default_value = "8")]
    pub firmware: String,
    /// Inject a fault half-way: none, stop-host, corrupt-query, board-loss,
    /// following-error.
    #[arg(long, default_value = "none")]
    pub fault: String,
    /// virtual (as fast as the simulation goes, virtual time) or realtime
    /// (wall clock); default: virtual for sim and loopback, realtime over UDP.
    #[arg(long)]
    pub pacing: Option<String>,
    /// Board watchdog period in ms (above 0, at most 341), or `off`
    /// (a stopped host then leaves the amplifiers on: say so explicitly).
    #[arg(long = "watchdog-ms", default_value = "20", value_parser = crate::args::watchdog)]
    pub watchdog: crate::args::WatchdogSetting,
    /// Do not try SCHED_FIFO, mlockall and a 1 ns timer slack with
    /// realtime pacing.
    #[arg(long = "no-rt")]
    pub no_rt: bool,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress lines on stderr.
    #[arg(long)]
    pub quiet: bool,
}

impl Default for DemoArgs {
    fn default() -> Self {
        DemoArgs {
            rate: 6000.0,
            protocol: "broadcast".into(),
            duration: 3.0,
            port: "sim".into(),
            firmware: "8".into(),
            fault: "none".into(),
            pacing: None,
            watchdog: crate::args::WatchdogSetting::Period(Duration::from_millis(20)),
            no_rt: false,
            json: false,
            quiet: false,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Inject {
    None,
    StopHost,
    CorruptQuery,
    BoardLoss,
    FollowingError,
}

impl Inject {
    fn parse(s: &str) -> Result<Inject, CliError> {
        Ok(match s {
            "none" => Inject::None,
            "stop-host" => Inject::StopHost,
            "corrupt-query" => Inject::CorruptQuery,
            "board-loss" => Inject::BoardLoss,
            "following-error" => Inject::FollowingError,
            _ => {
                return Err(CliError::Conflict(format!(
                    "unknown fault {s:?}: none, stop-host, corrupt-query, board-loss, following-error"
                )));
            }
        })
    }

    fn name(self) -> &'static str {
        match self {
            Inject::None => "none",
            Inject::StopHost => "stop-host",
            Inject::CorruptQuery => "corrupt-query",
            Inject::BoardLoss => "board-loss",
            Inject::FollowingError => "following-error",
        }
    }
}

/// The board whose loss the demo simulates (PSM1's first board).
const LOST_BOARD: u8 = 4;

/// Port-specific fault injection.
trait Injector: Port {
    fn inject(&mut self, fault: Inject, watchdog: Duration) -> Result<(), CliError>;
}

impl Injector for SimPort {
    fn inject(&mut self, fault: Inject, watchdog: Duration) -> Result<(), CliError> {
        match fault {
            Inject::StopHost => self.wait(watchdog * 3),
            Inject::CorruptQuery => {
                let m = PacketMatch::any()
                    .tcode(Tcode::WriteQuadletRequest)
                    .offset(0x1800);
                self.bus_mut().set_fault_plan(FaultPlan::new().once(
                    m,
                    PacketFault::CorruptQuadlet {
                        index: 3,
                        xor: 0x0100_0000,
                    },
                ));
            }
            Inject::BoardLoss => {
                let now = self.bus().now();
                // Handles are in order of addition: the PC, then boards 0...
                let node = NodeHandle(usize::from(LOST_BOARD) + 1);
                self.bus_mut().set_fault_plan(FaultPlan::new().at(
                    now,
                    TimedFault::StopAnswering {
                        node,
                        duration: None,
                    },
                ));
            }
            Inject::None | Inject::FollowingError => {}
        }
        Ok(())
    }
}

impl Injector for LoopbackPort {
    fn inject(&mut self, fault: Inject, watchdog: Duration) -> Result<(), CliError> {
        match fault {
            Inject::StopHost => self.advance(watchdog * 3),
            Inject::CorruptQuery => self.corrupt_next_queries(1),
            Inject::BoardLoss => self.set_board_lost(LOST_BOARD, true),
            Inject::FollowingError => self.set_axis_blocked(0, 0, true),
            Inject::None => {}
        }
        Ok(())
    }
}

impl Injector for UdpPort {
    fn inject(&mut self, fault: Inject, watchdog: Duration) -> Result<(), CliError> {
        match fault {
            Inject::StopHost => std::thread::sleep(watchdog * 3),
            Inject::CorruptQuery | Inject::BoardLoss => {
                return Err(CliError::Conflict(format!(
                    "--fault {} needs --port sim or loopback (the bus is in another process)",
                    fault.name()
                )));
            }
            Inject::None | Inject::FollowingError => {}
        }
        Ok(())
    }
}

fn progress(quiet: bool, text: &str) {
    if !quiet {
        eprintln!("demo: {text}");
    }
}

/// The motions: on every arm, even joints follow a sinusoid (10 % of the
/// joint's range, 0.4 to 0.7 Hz), odd joints move point to point by 5 %.
fn motion_for(config: &IoConfig, i: usize, here: f64) -> Motion {
    let Some(j) = config.joints().nth(i) else {
        return Motion::Hold(here);
    };
    let a = j.actuator;
    let span = a.encoder.position_limits_soft.span();
    let (v, acc) = a.limits.map_or((0.5, 2.0), |l| {
        (0.3 * l.velocity, l.acceleration.unwrap_or(1.0) * 0.3)
    });
    if i % 2 == 0 {
        let f = 0.4 + 0.1 * (i % 4) as f64;
        Sinusoid::new(0.05 * span, f, 0.0, here, 0.5)
            .map(Motion::Sinusoid)
            .unwrap_or(Motion::Hold(here))
    } else {
        PointToPoint::new(here, here + 0.05 * span, v, acc)
            .map(Motion::PointToPoint)
            .unwrap_or(Motion::Hold(here))
    }
}

fn fault_json(f: &FaultReport) -> Value {
    let kind = format!("{:?}", f.kind);
    let name = kind.split([' ', '{', '(']).next().unwrap_or("").to_string();
    let board = match f.kind {
        FaultKind::MissedBoard { board_id, .. }
        | FaultKind::Sequence { board_id, .. }
        | FaultKind::Watchdog { board_id }
        | FaultKind::Power { board_id }
        | FaultKind::Amplifier { board_id, .. } => Some(board_id),
        _ => None,
    };
    json!({"kind": name, "board": board, "time_s": f.time, "cycle": f.cycle, "text": f.to_string()})
}

fn pct(p: Percentiles) -> Value {
    json!({"median": round(p.median), "p99": round(p.p99), "max": round(p.max), "mean": round(p.mean)})
}

fn round(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

/// Run the demo on any injectable port.
fn run_robot<P: Injector>(
    port: P,
    args: &DemoArgs,
    port_name: &str,
    pacing: Pacing,
) -> Result<Value, CliError> {
    let quiet = args.quiet || crate::args::quiet();
    let rt = (pacing == Pacing::WallClock && !args.no_rt).then(|| rt::setup(80));
    if let Some(s) = &rt {
        progress(
            quiet,
            &format!(
                "real time: SCHED_FIFO {}, memory locked {}, timer slack 1 ns {}{}",
                s.sched_fifo.is_some(),
                s.memory_locked,
                s.timer_slack_1ns,
                if s.errors.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", s.errors.join("; "))
                }
            ),
        );
    }
    let config = presets::dvrk_seed000();
    let protocol = Protocol::from_name(&args.protocol)
        .ok_or_else(|| CliError::Conflict(format!("unknown protocol {:?}", args.protocol)))?;
    let inject = Inject::parse(&args.fault)?;
    let wall = Instant::now();
    let (io, scan) = IoSystem::open(
        port,
        HostIoConfig {
            protocol: Some(protocol),
            ..HostIoConfig::default()
        },
    )?;
    progress(
        quiet,
        &format!(
            "found {} boards on {port_name} ({}), protocol {}",
            scan.boards.len(),
            scan.protocol_reason,
            io.protocol().name()
        ),
    );
    if let Some(w) = args.watchdog.warning() {
        eprintln!("demo: {w}");
    }
    let watchdog = args.watchdog.period();
    let settings = RobotSettings {
        rate_hz: args.rate,
        watchdog,
        ..RobotSettings::default()
    };
    let mut robot = Robot::new(io, &config, settings).map_err(runner_err)?;
    robot.configure().map_err(runner_err)?;
    progress(quiet, "configured; powering on");
    robot.power_on().map_err(runner_err)?;
    progress(
        quiet,
        &format!("powered at t = {:.3} s; homing", robot.now()),
    );
    robot.home().map_err(runner_err)?;
    robot.activate().map_err(runner_err)?;
    progress(
        quiet,
        &format!(
            "homed and active at t = {:.3} s; moving all four arms",
            robot.now()
        ),
    );
    for i in 0..robot.joint_count() {
        let here = robot.position(i).unwrap_or(0.0);
        robot
            .set_motion(i, motion_for(&config, i, here))
            .map_err(runner_err)?;
    }
    robot.reset_tracking();
    let setup_cycles = robot.cycles();
    let rate = args.rate;
    let total = (args.duration.max(0.0) * rate).round() as u64;
    let every = (rate / 4.0).max(1.0) as u64;
    let half = total / 2;
    let mut fault: Option<FaultReport> = None;
    let report_progress = |r: &Robot<P>| {
        if !quiet {
            let mut io = r.times().io_us.clone();
            let n = io.len().min(2000);
            let start = io.len() - n;
            let p = Percentiles::of(&mut io[start..]);
            eprint!(
                "\rdemo: t = {:7.3} s  cycles {:8}  io median {:6.1} us  errors {}   ",
                r.now(),
                r.cycles(),
                p.median,
                r.io_stats().total_errors()
            );
        }
    };
    let first = if inject == Inject::None { total } else { half };
    let mut outcome = robot.run(first, pacing, every, report_progress);
    if outcome.is_ok() && inject != Inject::None {
        if !quiet {
            eprintln!();
        }
        progress(quiet, &format!("injecting fault: {}", inject.name()));
        robot.io_mut().port_mut().inject(inject, watchdog)?;
        if inject == Inject::FollowingError {
            // A setpoint jump the joint cannot follow within the grace time.
            let _ = robot.step_setpoint(0, 0.5);
        }
        outcome = robot.run(total - half, pacing, every, report_progress);
    }
    if !quiet {
        eprintln!();
    }
    match outcome {
        Ok(()) => {}
        Err(RunnerError::Fault(f)) => {
            fault = Some(f);
            progress(quiet, &format!("FAULT: {f}"));
            // Cycles in Fault for twice the watchdog period: outputs stay
            // safe, and a board that stopped answering has time to turn
            // its own amplifiers off.
            let n = ((2.0 * watchdog.as_secs_f64() * rate).ceil() as u64).max(3);
            for _ in 0..n {
                let _ = robot.step(Pacing::Virtual);
            }
            progress(
                quiet,
                &format!(
                    "safety chain: state {}, amplifiers {}",
                    robot.state(),
                    if robot.any_amp_on() { "ON" } else { "off" }
                ),
            );
        }
        Err(e) => return Err(runner_err(e)),
    }
    let amps_after_fault = robot.any_amp_on();
    let silent: Vec<u8> = robot
        .io()
        .boards()
        .iter()
        .filter(|b| !b.is_valid())
        .map(|b| b.board_id())
        .collect();
    let state_after = robot.state();
    let motion_cycles = robot.cycles() - setup_cycles;
    let expired: Vec<u8> = robot
        .io()
        .boards()
        .iter()
        .filter(|b| b.watchdog_expired())
        .map(|b| b.board_id())
        .collect();
    robot.shutdown().map_err(runner_err)?;
    progress(
        quiet,
        &format!(
            "powered off; wall time {:.2} s",
            wall.elapsed().as_secs_f64()
        ),
    );
    let times = robot.times().clone();
    let (mut c, mut io, mut comp) = (times.cycle_us, times.io_us, times.compute_us);
    let s = *robot.io_stats();
    let tracking = robot.tracking();
    let mut te = serde_json::Map::new();
    let mut detail = serde_json::Map::new();
    for t in &tracking {
        te.insert(t.name.clone(), json!(t.rms_rad));
        detail.insert(
            t.name.clone(),
            json!({"rms_rad": t.rms_rad, "max_rad": t.max_rad, "prismatic_rms_mm": t.rms_mm, "prismatic_max_mm": t.max_mm, "samples": t.samples}),
        );
    }
    let axes = robot.joint_count();
    Ok(json!({
        "port": port_name,
        "boards": robot.io().boards().len(),
        "axes": axes,
        "firmware": robot.io().boards().first().map(|b| b.info().firmware),
        "protocol": robot.io().protocol().name(),
        "rate_hz": args.rate,
        "pacing": match pacing { Pacing::Virtual => "virtual", Pacing::WallClock => "realtime" },
        "cycles": robot.cycles(),
        "motion_cycles": motion_cycles,
        "port_time_s": robot.now(),
        "wall_time_s": wall.elapsed().as_secs_f64(),
        "cycle_time_us": pct(Percentiles::of(&mut c)),
        "io_time_us": pct(Percentiles::of(&mut io)),
        "compute_time_us": pct(Percentiles::of(&mut comp)),
        "overruns": times.overruns,
        "realtime": rt.as_ref().map_or(json!({"requested": false}), rt::RtStatus::to_json),
        "tracking_error": Value::Object(te),
        "tracking_error_unit": "rad RMS over each arm's revolute joints (prismatic: tracking_error_detail, mm)",
        "tracking_error_detail": Value::Object(detail),
        "errors": {
            "total": s.total_errors(),
            "timeouts": s.timeouts,
            "bus_resets": s.bus_resets,
            "bad_packets": s.bad_packets,
            "nacks": s.nacks,
            "sequence_errors": s.sequence_errors,
            "corrupt_queries": s.corrupt_queries,
            "wrong_board": s.wrong_board,
            "block_size": s.block_size,
            "other": s.other,
            "missed_by_board": s.missed_by_board,
        },
        "watchdog": {"period_ms": args.watchdog.millis(), "expired_boards": expired},
        "fault_injected": inject.name(),
        "fault": fault.as_ref().map(fault_json),
        "state_after_run": state_after.to_string(),
        "amplifiers_on_after_fault": fault.map(|_| amps_after_fault),
        "boards_not_answering": silent,
        "state": robot.state().to_string(),
    }))
}

fn runner_err(e: RunnerError) -> CliError {
    CliError::Conflict(e.to_string())
}

/// Run `firelink demo`.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    let profile = crate::args::profile(&args.firmware)?;
    let config = presets::dvrk_seed000();
    let pacing_for = |default: Pacing| -> Result<Pacing, CliError> {
        match args.pacing.as_deref() {
            None => Ok(default),
            Some("virtual") => Ok(Pacing::Virtual),
            Some("realtime") => Ok(Pacing::WallClock),
            Some(p) => Err(CliError::Conflict(format!(
                "unknown pacing {p:?}: virtual or realtime"
            ))),
        }
    };
    let report = match args.port.as_str() {
        "sim" => {
            let (port, _) = rig::sim_port(rig::board_configs(&config, profile, 8), false)?;
            run_robot(port, args, "sim", pacing_for(Pacing::Virtual)?)?
        }
        "loopback" => {
            let port = LoopbackPort::from_config(&config, |i| rig::start_position(&config, i));
            run_robot(port, args, "loopback", pacing_for(Pacing::Virtual)?)?
        }
        "emulate" => {
            let emu = rig::Emulator::start(rig::board_configs(&config, profile, 8))?;
            let name = format!("udp:{} (in-process firelink emulate)", emu.addr);
            run_robot(emu.port()?, args, &name, pacing_for(Pacing::WallClock)?)?
        }
        p if p.starts_with("udp") => {
            let addr = UdpPort::parse_address(p)?;
            let mut port = UdpPort::open(addr)?;
            port.set_timeout(Duration::from_millis(20));
            run_robot(port, args, p, pacing_for(Pacing::WallClock)?)?
        }
        p => {
            return Err(CliError::Conflict(format!(
                "unknown port {p:?}: sim, emulate, loopback or udp:HOST[:PORT]"
            )));
        }
    };
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&report)?)?;
    } else {
        print_text(&report, out)?;
    }
    let injected = args.fault != "none";
    let faulted = !report["fault"].is_null();
    if injected && !faulted {
        return Err(CliError::Conflict(format!(
            "the injected fault {} was not detected",
            args.fault
        )));
    }
    if !injected && faulted {
        return Err(CliError::Conflict("the run ended in a fault".into()));
    }
    if injected && report["amplifiers_on_after_fault"] == json!(true) {
        return Err(CliError::Conflict(
            "amplifiers still on after the fault".into(),
        ));
    }
    let _ = State::Active;
    Ok(())
}

fn print_text(r: &Value, out: &mut impl Write) -> Result<(), CliError> {
    let f = |v: &Value| v.as_f64().unwrap_or(0.0);
    writeln!(
        out,
        "Firelink demo: seed 000's dVRK (MTML, MTMR, PSM1, PSM2)"
    )?;
    writeln!(
        out,
        "  port {}  boards {}  axes {}  firmware {}  protocol {}  rate {} Hz  pacing {}",
        r["port"].as_str().unwrap_or(""),
        r["boards"],
        r["axes"],
        r["firmware"],
        r["protocol"].as_str().unwrap_or(""),
        r["rate_hz"],
        r["pacing"].as_str().unwrap_or("")
    )?;
    writeln!(
        out,
        "  cycles {} ({} with motion), {:.3} s on the port's clock, {:.2} s wall",
        r["cycles"],
        r["motion_cycles"],
        f(&r["port_time_s"]),
        f(&r["wall_time_s"])
    )?;
    writeln!(
        out,
        "  late cycles (started over half a period late, wall-clock pacing): {}",
        r["overruns"]
    )?;
    for (name, key) in [
        ("cycle time", "cycle_time_us"),
        ("I/O time", "io_time_us"),
        ("compute", "compute_time_us"),
    ] {
        let p = &r[key];
        writeln!(
            out,
            "  {name:<10} median {:8.2} us  p99 {:8.2} us  max {:8.2} us",
            f(&p["median"]),
            f(&p["p99"]),
            f(&p["max"])
        )?;
    }
    writeln!(out, "  tracking error (RMS; revolute rad, prismatic mm):")?;
    if let Some(d) = r["tracking_error_detail"].as_object() {
        for (arm, t) in d {
            writeln!(
                out,
                "    {arm:<5} {:.5} rad (max {:.5})  prismatic {:.3} mm (max {:.3})",
                f(&t["rms_rad"]),
                f(&t["max_rad"]),
                f(&t["prismatic_rms_mm"]),
                f(&t["prismatic_max_mm"])
            )?;
        }
    }
    let e = &r["errors"];
    writeln!(
        out,
        "  errors: total {}  timeouts {}  sequence {}  corrupt queries {}  bus resets {}  bad packets {}  nacks {}",
        e["total"],
        e["timeouts"],
        e["sequence_errors"],
        e["corrupt_queries"],
        e["bus_resets"],
        e["bad_packets"],
        e["nacks"]
    )?;
    writeln!(
        out,
        "  watchdog: {} ms, expired on boards {}",
        r["watchdog"]["period_ms"], r["watchdog"]["expired_boards"]
    )?;
    match r["fault"].as_object() {
        None => writeln!(
            out,
            "  faults: none; final state {}",
            r["state"].as_str().unwrap_or("")
        )?,
        Some(fl) => writeln!(
            out,
            "  FAULT ({} injected): {}\n  safety chain: left active, amplifiers {}",
            r["fault_injected"].as_str().unwrap_or(""),
            fl.get("text").and_then(Value::as_str).unwrap_or(""),
            if r["amplifiers_on_after_fault"] == json!(true) {
                "STILL ON"
            } else {
                "off"
            }
        )?,
    }
    Ok(())
}
