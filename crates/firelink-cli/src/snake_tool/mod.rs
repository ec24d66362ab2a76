//! `firelink snake-tool`: seed 001's test and configuration program
//! (Fig. 19) for its Snake nodes, as a terminal UI and as scriptable
//! commands: per channel the motor voltage and current limit, the
//! feedback readouts with their conversion factors, encoder reset, the
//! EEPROM's write protection, the torque/speed switch, the digital pot's
//! wiper and the gain it sets, EEPROM words raw and as floats, and the
//! whole state saved to and loaded from a file.
//!
//! ```text
//! firelink snake-tool                                  # terminal UI on the simulated 36-axis system
//! firelink snake-tool --port udp:127.0.0.1 tui         # nodes behind `firelink emulate --robot snake`
//! firelink snake-tool exec "board 4; channel 2; wiper 649; show"
//! firelink snake-tool exec --file setup.txt
//! firelink snake-tool show --board 0 --json
//! ```

mod tui;

use std::io::Write;
use std::path::PathBuf;

use clap::{Args, Subcommand};

use firelink_control::config::{IoConfig, presets};
use firelink_host::Port;
use firelink_host::snake::SnakeSystem;
use firelink_host::udp::WaitMode;
use firelink_testbed::port_spec::{PortKind, PortSpec};
use firelink_testbed::ports::PortOptions;
use firelink_testbed::snake::tool::{Session, open_tool_port, render};

use crate::error::CliError;

/// `--port` (clap): the port grammar; plain `sim` (the configuration's
/// nodes), `udp:` or `fw`.
fn parse_tool_port(text: &str) -> Result<PortSpec, CliError> {
    let spec = crate::ports::parse_port_for(
        text,
        "firelink snake-tool",
        &[PortKind::Sim, PortKind::Udp, PortKind::Fw],
    )?;
    spec.refuse_board_count(
        "firelink snake-tool",
        "Snake nodes come from the configuration and have no QLA firmware",
    )?;
    Ok(spec)
}

/// Options of `firelink snake-tool`.
#[derive(Args, Debug)]
pub struct SnakeToolArgs {
    /// Where the nodes are: `sim` (the configuration's nodes on an
    /// in-process simulated bus; the state lasts one invocation),
    /// `udp:HOST[:PORT]` (a running `firelink emulate --robot snake`, or a
    /// bridge to real nodes) or `fw` / `fw:N` (FireWire card 0 / N).
    #[arg(long, default_value = "sim", value_parser = parse_tool_port)]
    pub port: PortSpec,
    /// The robot configuration: nodes to simulate, and the conversion
    /// factors of the channels it maps (default: configs/snake-seed001.json).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Read time-out in milliseconds (1..=60000).
    #[arg(long = "timeout-ms", default_value_t = 100, value_parser = crate::args::timeout_ms)]
    pub timeout_ms: u64,
    /// How the UDP port's reads wait for the answer: `block` (low CPU) or
    /// `spin` (low latency, one core busy while waiting).
    #[arg(long = "udp-wait", value_enum, default_value_t = WaitMode::Blocking)]
    pub udp_wait: WaitMode,
    /// Start on this board (default: the lowest ID found).
    #[arg(long, value_parser = crate::args::board_id)]
    pub board: Option<u8>,
    /// What to do (default: the terminal UI).
    #[command(subcommand)]
    pub command: Option<ToolCommand>,
}

/// What the tool does.
#[derive(Subcommand, Debug)]
pub enum ToolCommand {
    /// The interactive terminal UI.
    Tui,
    /// Run commands (`;` or new lines between them; `help` lists them).
    Exec {
        /// The commands.
        #[arg(required_unless_present = "file")]
        script: Option<String>,
        /// Read the commands from this file.
        #[arg(long, conflicts_with = "script")]
        file: Option<PathBuf>,
    },
    /// Print one node's readouts.
    Show {
        /// As JSON.
        #[arg(long)]
        json: bool,
    },
}

fn open(args: &SnakeToolArgs) -> Result<(Box<dyn Port>, IoConfig), CliError> {
    let config = match &args.config {
        Some(path) => crate::demo::load_config(path)?,
        None => presets::snake_seed001(),
    };
    let options = PortOptions {
        timeout: std::time::Duration::from_millis(args.timeout_ms),
        udp_wait: args.udp_wait,
        ..PortOptions::default()
    };
    Ok((open_tool_port(&args.port, &config, &options)?, config))
}

/// `firelink snake-tool`.
pub fn run(args: &SnakeToolArgs, out: &mut impl Write) -> Result<(), CliError> {
    let (port, config) = open(args)?;
    let system = SnakeSystem::open(port)?;
    let mut session = Session::new(system, Some(config))?;
    if let Some(b) = args.board {
        session.select_board(b)?;
    }
    let result: Result<(), CliError> = match &args.command {
        None | Some(ToolCommand::Tui) => tui::run(&mut session, out),
        Some(ToolCommand::Exec { script, file }) => {
            let text = match (script, file) {
                (Some(s), _) => s.clone(),
                (None, Some(f)) => std::fs::read_to_string(f)?,
                // clap asks for one of the two.
                (None, None) => return Err(CliError::Missing("exec: the commands or --file")),
            };
            session
                .run_script(&text)
                .map_err(CliError::from)
                .and_then(|text| Ok(write!(out, "{text}")?))
        }
        Some(ToolCommand::Show { json }) => {
            let view = session.view()?;
            if *json {
                writeln!(out, "{}", serde_json::to_string(&view)?)?;
            } else {
                write!(out, "{}", render(&view, session.channel()))?;
            }
            Ok(())
        }
    };
    // Whatever happened, no amplifier the tool turned on stays on.
    let finished = session.finish();
    if let Ok(boards) = &finished {
        if !boards.is_empty() {
            say!("snake-tool: amplifiers turned off on exit (boards {boards:?})");
        }
    }
    result.and(finished.map(|_| ()).map_err(CliError::from))
}
