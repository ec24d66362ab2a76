//! The shared table of port strings (`firelink_testbed::port_spec::TABLE`)
//! through the clap arguments of every command that takes `--port`: the
//! same meaning as the shared parser, or the same refusal; the commands
//! that take only some kinds of port refuse the others by name.

use clap::Parser;

use firelink_testbed::port_spec::{PortKind, PortSpec, disagreements_with_table};

use crate::{Cli, Command};

/// The port a parsed command line carries.
fn port_of(command: Command) -> Option<PortSpec> {
    match command {
        Command::Scan(a) | Command::Info(a) => Some(a.port.port),
        Command::Read(a) => Some(a.target.port.port),
        Command::Write(a) => Some(a.target.port.port),
        Command::Monitor(a) => Some(a.port.port),
        Command::Demo(a) => Some(a.request.port),
        Command::SnakeTool(a) => Some(a.port),
        Command::Bench(a) => a.request.port,
        _ => None,
    }
}

/// `firelink COMMAND --port TEXT ARGS...` as clap parses it: the port,
/// or clap's error message.
fn parse(command: &[&str], text: &str) -> Result<PortSpec, String> {
    let (name, args) = command.split_first().ok_or("no command")?;
    let line = ["firelink", name, "--port", text]
        .into_iter()
        .chain(args.iter().copied());
    let cli = Cli::try_parse_from(line).map_err(|e| e.to_string())?;
    let command = cli.command.ok_or("no command")?;
    port_of(command).ok_or_else(|| "no port".to_string())
}

#[test]
fn every_command_reads_port_strings_as_the_table_says() {
    let any = |_: &PortSpec| true;
    for args in [
        &["scan"][..],
        &["info"],
        &["read", "0"],
        &["write", "0", "0"],
        &["monitor"],
        &["demo"],
    ] {
        let wrong = disagreements_with_table(|t| parse(args, t), any);
        assert!(wrong.is_empty(), "{args:?}: {wrong:#?}");
    }
    // The Snake tool: the configuration's nodes (plain sim), UDP or
    // FireWire; the benchmark's --port: a bridge on UDP.
    let snake = |p: &PortSpec| {
        matches!(p, PortSpec::Sim(None)) || matches!(p.kind(), PortKind::Udp | PortKind::Fw)
    };
    let wrong = disagreements_with_table(|t| parse(&["snake-tool", "show"], t), snake);
    assert!(wrong.is_empty(), "snake-tool: {wrong:#?}");
    let udp = |p: &PortSpec| p.kind() == PortKind::Udp;
    let wrong = disagreements_with_table(|t| parse(&["bench"], t), udp);
    assert!(wrong.is_empty(), "bench: {wrong:#?}");
}
