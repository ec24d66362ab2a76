//! The `firelink` command line.
//!
//! Each subcommand is a thin layer over the library crates; this file only
//! parses arguments, prints results and maps errors to one line on stderr
//! with a non-zero exit status: 1 for an error, 2 for a usage error (clap),
//! 3 for a run that finished but failed its check ([`EXIT_STATUS`]). When
//! the reader of stdout goes away (`| head`), the program stops without a
//! message, with status 141 as a program SIGPIPE ended; lines for stderr
//! never panic (`stderr`: `say!`).

#[macro_use]
mod stderr;

mod args;
mod bench;
mod board_cmd;
mod companion;
mod demo;
mod emulate_cmd;
mod error;
mod fw_run;
mod monitor;
mod packet_cmd;
#[cfg(test)]
mod port_strings_test;
mod ports;
mod sim;
mod snake_tool;
mod soak_cmd;
mod tour;

use std::io::Write;
use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

use error::{CliError, EXIT_STATUS};

/// Firelink: real-time robot control over IEEE 1394 and its Ethernet bridge,
/// with the bus and the boards emulated in software.
#[derive(Parser)]
#[command(name = "firelink", version, about, long_about = None, after_help = EXIT_STATUS)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Decode or build single 1394 packets.
    #[command(subcommand)]
    Packet(packet_cmd::PacketCommand),
    /// Print the IEEE 1394 CRC-32 of hex bytes.
    Crc {
        /// Bytes as hex (whitespace allowed).
        #[arg(required = true, num_args = 1..)]
        hex: Vec<String>,
    },
    /// Build and decode every packet of one broadcast I/O cycle (the default).
    Tour(tour::TourArgs),
    /// Find the boards behind a port and pick the protocol.
    Scan(board_cmd::ScanArgs),
    /// Identity and live state of every board.
    Info(board_cmd::ScanArgs),
    /// Read board registers (hex output).
    Read(board_cmd::ReadArgs),
    /// Write board registers.
    Write(board_cmd::WriteArgs),
    /// Live view of every axis of every board (keys toggle power and amps).
    Monitor(monitor::MonitorArgs),
    /// Simulate one I/O cycle on the simulated 1394a bus; print phase times.
    Sim(sim::SimArgs),
    /// The main job: the 28-axis dVRK of seed 000 on emulated boards (the default;
    /// `--robot mahru`: seed 002's humanoid walking).
    Demo(Box<demo::DemoArgs>),
    /// I/O time per cycle vs boards and protocol: simulated bus and loopback UDP.
    Bench(bench::BenchArgs),
    /// Seed 002's timing analysis of the MAHRU humanoid: Table I (the time
    /// budget, from simulated transactions and end to end), Table III
    /// (read time by payload, Xenomai and RTLinux), Table IV (CAN vs 1394).
    Budget(Box<demo::mahru::BudgetArgs>),
    /// Emulated boards behind an Ethernet bridge on UDP (127.0.0.1:1394),
    /// or as /dev/fw* devices (`--fw-cdev SOCKET`).
    Emulate(Box<firelink_testbed::emulation::EmulateRequest>),
    /// Run a program with the emulated boards as /dev/fw* devices (the
    /// firewire-cdev twin preloaded): `firelink fw-run --boards 8 --
    /// firelink scan --port fw`.
    FwRun(Box<fw_run::FwRunArgs>),
    /// Fault soak: millions of servo cycles with faulted packets, every
    /// fault accounted for; then the watchdog proof.
    Soak(soak_cmd::SoakArgs),
    /// Seed 001's test and configuration program for its Snake nodes
    /// (terminal UI, or scripted with `exec`).
    SnakeTool(snake_tool::SnakeToolArgs),
    /// The web console (runs `firelink-web`, built by `cargo build -p
    /// firelink-web`; its options: `firelink web --help`).
    #[command(disable_help_flag = true)]
    Web {
        /// Options for firelink-web (--robot dvrk|snake|mahru, --port, --config, --listen, --period, --watchdog-ms, --timeout-ms, --help).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// The robot as a ROS 2 node with the dVRK's CRTK topics (runs
    /// `firelink-ros2`, built by `cargo build -p firelink-ros2`; its options:
    /// `firelink ros2 --help`).
    #[command(disable_help_flag = true)]
    Ros2 {
        /// Options for firelink-ros2 (--port, --config, --period, --publish-hz, --domain, --rt/--no-rt, --no-dds, --servo-stream, --seconds, --help).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

/// Commands that power a robot turn SIGINT, SIGTERM and SIGHUP into a stop
/// request: the loop returns between cycles, the robot is powered down,
/// and the process exits with 128 + the signal's number. (A second signal
/// ends it at once; the boards' watchdogs then turn the amplifiers off.)
fn drives_a_robot(command: &Command) -> bool {
    matches!(
        command,
        Command::Demo(_) | Command::Monitor(_) | Command::SnakeTool(_) | Command::Soak(_)
    )
}

fn run(cli: Cli) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    let command = cli.command.unwrap_or_else(|| Command::Demo(Box::default()));
    if drives_a_robot(&command) {
        firelink_host::stop::install_signal_handlers()?;
    }
    match command {
        Command::Packet(command) => packet_cmd::run(&command, &mut out)?,
        Command::Crc { hex } => {
            writeln!(out, "{:08x}", packet_cmd::crc(&hex.join(" "))?)?;
        }
        Command::Tour(args) => tour::run(&args, &mut out)?,
        Command::Scan(args) => board_cmd::run_scan(&args, &mut out)?,
        Command::Info(args) => board_cmd::run_info(&args, &mut out)?,
        Command::Read(args) => board_cmd::run_read(&args, &mut out)?,
        Command::Write(args) => board_cmd::run_write(&args, &mut out)?,
        Command::Monitor(args) => monitor::run(&args, &mut out)?,
        Command::Emulate(args) => emulate_cmd::run(&args, &mut out)?,
        // Handled in main (it exits with the program's status).
        Command::FwRun(_) => {}
        Command::Sim(args) => sim::run(&args, &mut out)?,
        Command::Demo(args) => demo::robot::run(&args, &mut out)?,
        Command::Bench(args) => bench::run(&args, &mut out)?,
        Command::Budget(args) => demo::mahru::run_budget_cmd(&args, &mut out)?,
        Command::Soak(args) => soak_cmd::run(&args, &mut out)?,
        Command::SnakeTool(args) => snake_tool::run(&args, &mut out)?,
        Command::Web { args } => companion::run("firelink-web", &args)?,
        Command::Ros2 { args } => companion::run("firelink-ros2", &args)?,
    }
    Ok(())
}

/// The exit status when stdout's reader went away: a shell's status for a
/// program that SIGPIPE ended (128 + 13).
const CLOSED_PIPE_STATUS: u8 = 141;

fn main() -> ExitCode {
    let matches = Cli::command().get_matches();
    let mut cli =
        Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.format(&mut Cli::command()).exit());
    // What was given on the command line, for the runs that refuse the
    // options they would ignore.
    if let (Some(Command::Demo(args)), Some(m)) =
        (&mut cli.command, matches.subcommand_matches("demo"))
    {
        args.note_given(m);
    }
    if let Some(Command::FwRun(args)) = &cli.command {
        return match fw_run::run(args) {
            Ok(code) => ExitCode::from(code),
            Err(err) => {
                say!("firelink fw-run: {err}");
                ExitCode::from(err.exit_code())
            }
        };
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of the output went away (`firelink sim --timeline |
        // head`): stop without a message, with the status of a tool that
        // SIGPIPE ended (128 + 13), not success: the run's own verdict (a
        // demo's check) may not have been reached.
        Err(CliError::Io(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            ExitCode::from(CLOSED_PIPE_STATUS)
        }
        Err(err) => {
            say!("firelink: {err}");
            ExitCode::from(err.exit_code())
        }
    }
}
