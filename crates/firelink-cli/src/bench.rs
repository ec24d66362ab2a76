//! `firelink bench`: I/O time per cycle against the number of boards, for
//! the sequential and broadcast protocols, on the simulated bus with the
//! seed-000 PC model (seed 000, Fig. 11) and measured for real over
//! loopback UDP against an in-process `firelink emulate`, side by side.
//! Plus the maximum sustainable control rate and seed 002's time budget.

use std::io::Write;
use std::time::Duration;

use clap::Args;
use serde_json::{Value, json};

use firelink_control::budget::CycleBudget;
use firelink_control::config::presets;
use firelink_control::runner::loopback::LoopbackPort;
use firelink_control::runner::{Pacing, Percentiles, Robot, RobotSettings};
use firelink_host::Port;
use firelink_host::io::{IoConfig as HostIoConfig, IoSystem};
use firelink_host::scan::Protocol;

use crate::CliError;
use firelink_testbed::rig;

/// Options of `firelink bench`.
#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    /// Transports: sim, udp (comma-separated).
    #[arg(long, default_value = "sim,udp")]
    pub transport: String,
    /// Board counts (comma-separated); above 16 (the board-ID space) the
    /// figures come from the cost model fitted to the 16-board run.
    #[arg(long, default_value = "2,4,8,16,32,62")]
    pub boards: String,
    /// Protocols: sequential, broadcast (comma-separated).
    #[arg(long, default_value = "sequential,broadcast")]
    pub protocol: String,
    /// Measured cycles per point (after 20 warm-up cycles), at least 1.
    #[arg(long, default_value_t = 1000, value_parser = crate::args::cycles)]
    pub cycles: u64,
    /// Firmware of the emulated boards: 7, 8 or seed.
    #[arg(long, default_value = "8")]
    pub firmware: String,
    /// Control period for the seed-002 budget check, us (default: 6 kHz).
    #[arg(long = "period-us", default_value_t = 166.67, value_parser = crate::args::period_us)]
    pub period_us: f64,
    /// Broadcast protocol: the host's wait between the query and the hub
    /// read, us per board (seed 000's PC sleeps 5 us x N).
    #[arg(long = "wait-us", default_value_t = 5.0, value_parser = crate::args::wait_us)]
    pub wait_us: f64,
    /// Idle time between cycles, us: a paced control loop leaves the bus
    /// idle between cycles (longer than the 21 us arbitration reset gap, so
    /// the PC's fairness interval restarts), as at seed 000's 6 kHz.
    #[arg(long = "idle-us", default_value_t = 50.0, value_parser = crate::args::wait_us)]
    pub idle_us: f64,
    /// Write a PNG plot of I/O time against boards here.
    #[arg(long)]
    pub plot: Option<String>,
    /// Print JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// One measured point.
#[derive(Debug, Clone)]
struct Point {
    transport: String,
    protocol: Protocol,
    asked: Protocol,
    boards: usize,
    io: Percentiles,
    read: f64,
    write: f64,
    cycles: u64,
    errors: u64,
    note: Option<String>,
}

fn list<T>(s: &str, f: impl Fn(&str) -> Option<T>, what: &str) -> Result<Vec<T>, CliError> {
    s.split(',')
        .filter(|x| !x.trim().is_empty())
        .map(|x| f(x.trim()).ok_or_else(|| CliError::Conflict(format!("bad {what}: {x:?}"))))
        .collect()
}

/// The `--boards` list: each count 1..=62; counts above 16 (the board-ID
/// space of one bus) are extrapolated from the largest measured count
/// before them, so one must come first.
fn board_counts(text: &str) -> Result<Vec<usize>, CliError> {
    let counts = list(
        text,
        |s| s.parse::<usize>().ok().filter(|n| (1..=62).contains(n)),
        "board count (1..=62)",
    )?;
    if counts.is_empty() {
        return Err(CliError::Conflict("--boards: no board count given".into()));
    }
    let mut measured = false;
    for &n in &counts {
        if n <= 16 {
            measured = true;
        } else if !measured {
            return Err(CliError::Conflict(format!(
                "--boards: {n} boards is extrapolated from a measured count (1..=16) that \
                 must come before it in the list"
            )));
        }
    }
    Ok(counts)
}

/// Run `cycles` I/O cycles on an open system; percentiles of the I/O time.
fn measure<P: Port>(
    mut io: IoSystem<P>,
    cycles: u64,
    idle: Duration,
) -> (Percentiles, f64, f64, u64) {
    for _ in 0..20 {
        io.cycle();
        io.port_mut().wait(idle);
    }
    let mut t = Vec::with_capacity(cycles as usize);
    let (mut r, mut w) = (0.0, 0.0);
    for _ in 0..cycles {
        let rep = *io.cycle();
        let _ = io.recover();
        t.push((rep.io_time().as_secs_f64() * 1e6) as f32);
        r += rep.read_time.as_secs_f64() * 1e6;
        w += rep.write_time.as_secs_f64() * 1e6;
        io.port_mut().wait(idle);
    }
    let n = cycles.max(1) as f64;
    (
        Percentiles::of(&mut t),
        r / n,
        w / n,
        io.stats().total_errors(),
    )
}

fn point<P: Port>(
    port: P,
    transport: &str,
    protocol: Protocol,
    boards: usize,
    cycles: u64,
    wait_us_per_board: f64,
    idle: Duration,
) -> Result<Point, CliError> {
    let mut port = port;
    let scan = firelink_host::scan::scan(&mut port)?;
    let used = protocol.min(scan.protocol);
    let note = (used != protocol).then(|| scan.protocol_reason.to_string());
    let io = IoSystem::with_scan(
        port,
        &scan,
        HostIoConfig {
            protocol: Some(used),
            broadcast_wait: Some(Duration::from_secs_f64(
                wait_us_per_board * boards as f64 / 1e6,
            )),
            ..HostIoConfig::default()
        },
    )?;
    let (p, r, w, errors) = measure(io, cycles, idle);
    Ok(Point {
        transport: transport.into(),
        protocol: used,
        asked: protocol,
        boards,
        io: p,
        read: r,
        write: w,
        cycles,
        errors,
        note,
    })
}

/// The compute time of the 28-axis dVRK cycle (median, us), measured with
/// the runner on the port-level board model.
fn compute_time_us() -> f64 {
    let config = presets::dvrk_seed000();
    let port = LoopbackPort::from_config(&config, |i| rig::start_position(&config, i));
    let Ok((io, _)) = IoSystem::open(port, HostIoConfig::default()) else {
        return 0.0;
    };
    let settings = RobotSettings {
        rate_hz: 6000.0,
        ..RobotSettings::default()
    };
    let Ok(mut robot) = Robot::new(io, &config, settings) else {
        return 0.0;
    };
    let ok = robot.configure().is_ok() && robot.power_on().is_ok() && robot.home().is_ok();
    if !ok || robot.activate().is_err() {
        return 0.0;
    }
    let _ = robot.run(3000, Pacing::Virtual, 0, |_| {});
    let mut c = robot.times().compute_us.clone();
    let n = c.len().min(3000);
    let start = c.len() - n;
    Percentiles::of(&mut c[start..]).median
}

/// Extrapolate beyond 16 boards from the per-transaction costs of the
/// largest measured point of the same transport and protocol.
fn model(base: &Point, boards: usize) -> Point {
    let n = base.boards.max(1) as f64;
    let m = boards as f64;
    let io = match base.protocol {
        // Per board: one read and one write.
        Protocol::Sequential => base.io.median / n * m,
        // Per board: one read; one broadcast write.
        Protocol::SequentialReadBroadcastWrite => base.read / n * m + base.write,
        // One bus holds 16 board IDs (15 per hub at Rev 8): groups of 15,
        // each with its own query, wait, hub read and command broadcast.
        Protocol::Broadcast => base.io.median * (m / 15.0).ceil(),
    };
    Point {
        transport: base.transport.clone(),
        protocol: base.protocol,
        asked: base.asked,
        boards,
        io: Percentiles {
            median: io,
            p99: io * base.io.p99 / base.io.median.max(1e-9),
            max: f64::NAN,
            mean: io,
        },
        read: f64::NAN,
        write: f64::NAN,
        cycles: 0,
        errors: 0,
        note: Some(format!(
            "model: extrapolated from the {}-board measurement (a 1394 bus addresses 16 boards)",
            base.boards
        )),
    }
}

/// Run `firelink bench`.
pub fn run(args: &BenchArgs, out: &mut impl Write) -> Result<(), CliError> {
    let transports = list(
        &args.transport,
        |s| (s == "sim" || s == "udp").then(|| s.to_string()),
        "transport",
    )?;
    let boards = board_counts(&args.boards)?;
    let protocols = list(&args.protocol, Protocol::from_name, "protocol")?;
    let profile = crate::args::profile(&args.firmware)?;
    let generic = presets::bench_1board();
    let quiet = crate::args::quiet();
    let mut points: Vec<Point> = Vec::new();
    for t in &transports {
        for &proto in &protocols {
            let mut last: Option<Point> = None;
            for &n in &boards {
                if n > 16 {
                    if let Some(b) = &last {
                        points.push(model(b, n));
                    }
                    continue;
                }
                if !quiet {
                    eprintln!("bench: {t} {} {n} boards", proto.name());
                }
                // I/O timing needs no motors: idle channels keep the
                // emulator's plant cheap (it must keep up with the wall
                // clock over UDP).
                let cfgs: Vec<_> = rig::board_configs(&generic, profile, n)
                    .into_iter()
                    .map(|b| b.with_axes(vec![firelink_board::plant::presets::unused_channel(); 4]))
                    .collect();
                let p = if t == "sim" {
                    let (port, _) = rig::sim_port(cfgs, true)?;
                    point(
                        port,
                        t,
                        proto,
                        n,
                        args.cycles,
                        args.wait_us,
                        Duration::from_secs_f64(args.idle_us.max(0.0) / 1e6),
                    )?
                } else {
                    let emu = rig::Emulator::start(cfgs)?;
                    point(
                        emu.port()?,
                        t,
                        proto,
                        n,
                        args.cycles,
                        args.wait_us,
                        Duration::from_secs_f64(args.idle_us.max(0.0) / 1e6),
                    )?
                };
                last = Some(p.clone());
                points.push(p);
            }
        }
    }
    let compute = compute_time_us();
    let period = Duration::from_secs_f64(args.period_us.max(0.0) / 1e6);
    let results: Vec<Value> = points
        .iter()
        .map(|p| {
            let rate = 1e6 / (p.io.median + compute);
            let (te, tg) = if p.read.is_finite() {
                (p.read, p.write)
            } else {
                (p.io.median, 0.0)
            };
            let budget = CycleBudget {
                t_e: Duration::from_secs_f64(te.max(0.0) / 1e6),
                t_f: Duration::from_secs_f64(compute / 1e6),
                t_g: Duration::from_secs_f64(tg.max(0.0) / 1e6),
                t_s: Duration::ZERO,
            }
            .check(period);
            let r2 = |x: f64| if x.is_finite() { json!((x * 100.0).round() / 100.0) } else { Value::Null };
            json!({
                "transport": p.transport,
                "protocol": p.protocol.name(),
                "protocol_asked": p.asked.name(),
                "boards": p.boards,
                "io_time_us": {"median": r2(p.io.median), "p99": r2(p.io.p99), "max": r2(p.io.max), "mean": r2(p.io.mean)},
                "read_us": r2(p.read),
                "write_us": r2(p.write),
                "cycles": p.cycles,
                "errors": p.errors,
                "max_rate_hz": r2(rate),
                "budget": {"period_us": args.period_us, "total_us": r2(budget.total.as_secs_f64() * 1e6), "fits": budget.total < budget.period},
                "note": p.note,
            })
        })
        .collect();
    let paper = json!({"sequential_8_us": 496.0, "broadcast_8_us": 115.77, "source": "seed 000, Fig. 11 and section IV"});
    let report = json!({
        "results": results,
        "compute_us": (compute * 100.0).round() / 100.0,
        "paper": paper,
        "firmware": args.firmware,
        "cycles": args.cycles,
    });
    if let Some(path) = &args.plot {
        plot(&points, path)?;
    }
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&report)?)?;
        return Ok(());
    }
    writeln!(
        out,
        "I/O time per cycle (us), seed-000 PC model on the simulated bus (sim) and measured over loopback UDP (udp)"
    )?;
    writeln!(
        out,
        "{:<5} {:<32} {:>6} {:>9} {:>9} {:>9} {:>11} {:>10}  note",
        "trans", "protocol", "boards", "median", "p99", "max", "max rate", "budget"
    )?;
    for r in report["results"].as_array().into_iter().flatten() {
        let f = |v: &Value| v.as_f64().map_or("-".to_string(), |x| format!("{x:.1}"));
        writeln!(
            out,
            "{:<5} {:<32} {:>6} {:>9} {:>9} {:>9} {:>8} Hz {:>10}  {}",
            r["transport"].as_str().unwrap_or(""),
            r["protocol"].as_str().unwrap_or(""),
            r["boards"],
            f(&r["io_time_us"]["median"]),
            f(&r["io_time_us"]["p99"]),
            f(&r["io_time_us"]["max"]),
            f(&r["max_rate_hz"]),
            if r["budget"]["fits"] == json!(true) {
                "fits"
            } else {
                "over"
            },
            r["note"].as_str().unwrap_or("")
        )?;
    }
    writeln!(
        out,
        "compute (28-axis dVRK cycle, median): {compute:.1} us; budget = seed 002's t(Te)+t(Tf)+t(Tg) < {:.1} us",
        args.period_us
    )?;
    writeln!(
        out,
        "paper (seed 000, 8 boards): sequential 496 us measured, broadcast 115.77 us"
    )?;
    Ok(())
}

// ------------------------------------------------------------------ plot ---

use crate::bitmap_font;

const W: usize = 900;
const H: usize = 560;

const BLACK: [u8; 3] = [0, 0, 0];
const GREY: [u8; 3] = [225, 225, 225];
const WHITE: [u8; 3] = [255, 255, 255];
const COLOURS: [[u8; 3]; 6] = [
    [200, 30, 30],
    [30, 30, 200],
    [240, 140, 20],
    [20, 160, 60],
    [150, 40, 170],
    [90, 90, 90],
];

/// Is this point from the cost model rather than measured?
fn extrapolated(p: &Point) -> bool {
    p.cycles == 0 && p.note.as_deref().is_some_and(|n| n.starts_with("model"))
}

/// A round gridline step giving at most about eight lines up to `max`.
fn nice_step(max: f64) -> f64 {
    let raw = (max / 8.0).max(1e-9);
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * mag)
}

/// Draw `s` with its top left corner at (x, y).
fn text(img: &mut [[u8; 3]], x: f64, y: f64, s: &str, scale: usize, c: [u8; 3]) {
    let (x, y) = (x.round() as i64, y.round() as i64);
    bitmap_font::render(s, scale, |dx, dy| put(img, x + dx as i64, y + dy as i64, c));
}

fn text_w(s: &str, scale: usize) -> f64 {
    bitmap_font::text_width(s, scale) as f64
}

/// A square marker centred on (x, y): filled, or hollow (white inside).
fn marker(img: &mut [[u8; 3]], x: f64, y: f64, hollow: bool, c: [u8; 3]) {
    rect(img, x - 4.0, y - 4.0, 9, 9, c);
    if hollow {
        rect(img, x - 2.0, y - 2.0, 5, 5, WHITE);
    }
}

/// A PNG of I/O time (median) against boards, one line per transport and
/// protocol, linear axes, with a title, axis names, tick labels and a
/// legend (5x7 bitmap font at 2x). Points from the cost model (beyond 16
/// boards) are hollow markers joined by dashed segments.
fn plot(points: &[Point], path: &str) -> Result<(), CliError> {
    let mut img = vec![WHITE; W * H];
    let (x0, y0, x1, y1) = (90.0, 70.0, (W - 270) as f64, (H - 70) as f64);
    let max_b = points.iter().map(|p| p.boards).max().unwrap_or(1) as f64;
    let max_t = points
        .iter()
        .map(|p| p.io.median)
        .filter(|x| x.is_finite())
        .fold(1.0f64, f64::max);
    let step = nice_step(max_t);
    let top = (max_t / step).ceil() * step;
    let sx = |b: f64| x0 + (x1 - x0) * b / max_b;
    let sy = |t: f64| y1 - (y1 - y0) * t / top;

    let title = "I/O time per cycle vs boards (seed 000 Fig. 11 and beyond)";
    text(
        &mut img,
        (W as f64 - text_w(title, 2)) / 2.0,
        16.0,
        title,
        2,
        BLACK,
    );

    // Y gridlines and labels (us).
    let mut k = 0.0;
    while k * step <= top + step * 1e-6 {
        let t = k * step;
        let y = sy(t);
        if k > 0.0 {
            line(&mut img, x0, y, x1, y, GREY);
        }
        line(&mut img, x0 - 5.0, y, x0, y, BLACK);
        let label = format!("{t}");
        text(
            &mut img,
            x0 - 10.0 - text_w(&label, 2),
            y - 7.0,
            &label,
            2,
            BLACK,
        );
        k += 1.0;
    }
    text(
        &mut img,
        x0 - 10.0 - text_w("us", 2),
        y0 - 36.0,
        "us",
        2,
        BLACK,
    );

    // X ticks at the board counts present.
    let mut counts: Vec<usize> = points.iter().map(|p| p.boards).collect();
    counts.sort_unstable();
    counts.dedup();
    let mut right_edge = f64::NEG_INFINITY;
    for &n in &counts {
        let x = sx(n as f64);
        line(&mut img, x, y1, x, y1 + 5.0, BLACK);
        let label = n.to_string();
        let lx = x - text_w(&label, 2) / 2.0;
        // Skip a label that would run into the previous one.
        if lx > right_edge + 4.0 {
            text(&mut img, lx, y1 + 10.0, &label, 2, BLACK);
            right_edge = lx + text_w(&label, 2);
        }
    }
    let name = "boards";
    text(
        &mut img,
        (x0 + x1 - text_w(name, 2)) / 2.0,
        y1 + 36.0,
        name,
        2,
        BLACK,
    );
    line(&mut img, x0, y1, x1, y1, BLACK);
    line(&mut img, x0, y0, x0, y1, BLACK);

    // Series: one per (transport, asked protocol), in order of appearance.
    let mut series: Vec<(String, Protocol)> = Vec::new();
    for p in points {
        if !series
            .iter()
            .any(|(t, q)| *t == p.transport && *q == p.asked)
        {
            series.push((p.transport.clone(), p.asked));
        }
    }
    let lx = x1 + 20.0;
    let mut ly = y0;
    for (k, (tr, proto)) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let pts: Vec<(f64, f64, bool)> = points
            .iter()
            .filter(|p| p.transport == *tr && p.asked == *proto && p.io.median.is_finite())
            .map(|p| (sx(p.boards as f64), sy(p.io.median), extrapolated(p)))
            .collect();
        for w in pts.windows(2) {
            if let [a, b] = w {
                let dashed = a.2 || b.2;
                dline(&mut img, a.0, a.1, b.0, b.1, colour, dashed);
                dline(&mut img, a.0, a.1 + 1.0, b.0, b.1 + 1.0, colour, dashed);
            }
        }
        for &(x, y, model) in &pts {
            marker(&mut img, x, y, model, colour);
        }
        // Legend entry: swatch line with marker, then the name.
        line(&mut img, lx, ly + 7.0, lx + 24.0, ly + 7.0, colour);
        line(&mut img, lx, ly + 8.0, lx + 24.0, ly + 8.0, colour);
        marker(&mut img, lx + 12.0, ly + 7.0, false, colour);
        let label = format!("{tr} {}", proto.name());
        let room = W as f64 - 10.0 - (lx + 32.0);
        let scale = if text_w(&label, 2) <= room { 2 } else { 1 };
        text(
            &mut img,
            lx + 32.0,
            ly + if scale == 2 { 0.0 } else { 4.0 },
            &label,
            scale,
            BLACK,
        );
        ly += 26.0;
    }
    // Legend note on the extrapolated points.
    ly += 10.0;
    dline(&mut img, lx, ly + 7.0, lx + 24.0, ly + 7.0, BLACK, true);
    marker(&mut img, lx + 12.0, ly + 7.0, true, BLACK);
    text(&mut img, lx + 32.0, ly, "hollow, dashed =", 2, BLACK);
    text(&mut img, lx + 32.0, ly + 20.0, "extrapolated", 2, BLACK);
    text(&mut img, lx + 32.0, ly + 40.0, "model", 2, BLACK);
    ly += 70.0;
    dline(&mut img, lx, ly + 7.0, lx + 24.0, ly + 7.0, BLACK, false);
    marker(&mut img, lx + 12.0, ly + 7.0, false, BLACK);
    text(&mut img, lx + 32.0, ly, "filled = measured", 2, BLACK);
    text(
        &mut img,
        lx,
        ly + 30.0,
        "each point: median I/O time per cycle",
        1,
        BLACK,
    );

    std::fs::write(path, png(&img, W, H))?;
    Ok(())
}

/// A line, dashed (8 on, 6 off) when `dashed`.
fn dline(img: &mut [[u8; 3]], xa: f64, ya: f64, xb: f64, yb: f64, c: [u8; 3], dashed: bool) {
    let steps = (xb - xa).abs().max((yb - ya).abs()).ceil().max(1.0) as i64;
    for i in 0..=steps {
        if dashed && i % 14 >= 8 {
            continue;
        }
        let f = i as f64 / steps as f64;
        put(
            img,
            (xa + (xb - xa) * f).round() as i64,
            (ya + (yb - ya) * f).round() as i64,
            c,
        );
    }
}

fn put(img: &mut [[u8; 3]], x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as usize) < W && (y as usize) < H {
        if let Some(p) = img.get_mut(y as usize * W + x as usize) {
            *p = c;
        }
    }
}

fn rect(img: &mut [[u8; 3]], x: f64, y: f64, w: i64, h: i64, c: [u8; 3]) {
    for dy in 0..h {
        for dx in 0..w {
            put(img, x as i64 + dx, y as i64 + dy, c);
        }
    }
}

fn line(img: &mut [[u8; 3]], xa: f64, ya: f64, xb: f64, yb: f64, c: [u8; 3]) {
    dline(img, xa, ya, xb, yb, c, false);
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(out.get(start..).unwrap_or(&[]));
    out.extend_from_slice(&crc.to_be_bytes());
}

/// An 8-bit RGB PNG with uncompressed (stored) deflate blocks.
fn png(img: &[[u8; 3]], w: usize, h: usize) -> Vec<u8> {
    let mut raw = Vec::with_capacity(h * (1 + 3 * w));
    for row in img.chunks(w) {
        raw.push(0);
        for p in row {
            raw.extend_from_slice(p);
        }
    }
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65535).collect();
    for (i, b) in blocks.iter().enumerate() {
        z.push(u8::from(i + 1 == blocks.len()));
        let len = b.len() as u16;
        z.extend_from_slice(&len.to_le_bytes());
        z.extend_from_slice(&(!len).to_le_bytes());
        z.extend_from_slice(b);
    }
    let (mut a, mut bsum) = (1u32, 0u32);
    for &x in &raw {
        a = (a + u32::from(x)) % 65521;
        bsum = (bsum + a) % 65521;
    }
    z.extend_from_slice(&((bsum << 16) | a).to_be_bytes());
    let mut out = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&(w as u32).to_be_bytes());
    ihdr.extend_from_slice(&(h as u32).to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    chunk(&mut out, b"IDAT", &z);
    chunk(&mut out, b"IEND", &[]);
    out
}
