//! Seed 001's test and configuration program (Fig. 19) for its Snake
//! nodes, as a model any front end can drive: the command line's
//! `firelink snake-tool` (terminal UI and scripts) today, the web console
//! and Python tomorrow.
//!
//! A [`Session`] holds one [`SnakeSystem`](firelink_host::snake::SnakeSystem)
//! behind any port, the board and channel selected, what the tool
//! commanded on each channel ([`ChannelState`]) and the conversion
//! factors ([`Factors`]). It is driven by the command language
//! ([`Session::command`], [`Session::run_script`], listed in [`HELP`]),
//! which returns what a command prints as text, and read as a
//! [`NodeView`] (the selected node's seven channels, converted; [`render`]
//! lays it out as text). [`Session::save`] and [`Session::load`] keep
//! every channel of every node, EEPROM included, in a versioned JSON
//! [`StateFile`].
//!
//! Rules:
//! - The session does no I/O of its own beyond the port it was given and
//!   the state files it is named; time passes only through the port
//!   (`wait MS`).
//! - A refused command changes nothing and returns a
//!   [`ToolError::Command`] naming the command and what was wrong.
//! - [`Session::finish`] turns off every amplifier the tool turned on; a
//!   front end calls it on every way out.

mod commands;
mod error;
mod keys;
mod open;
mod session;
mod state;
mod view;

pub use commands::HELP;
pub use error::ToolError;
pub use keys::{KEYS, key_command, outcome_line};
pub use open::open_tool_port;
pub use session::Session;
pub use state::{ChannelState, Factors, STATE_VERSION, StateFile};
pub use view::{ChannelView, NodeView, render};

#[cfg(test)]
mod tests {
    use firelink_control::config::presets;
    use firelink_host::sim::SimPort;
    use firelink_host::snake::SnakeSystem;

    use super::*;

    /// A session on seed 001's nodes on the simulated bus.
    fn session() -> Session<SimPort> {
        let config = presets::snake_seed001();
        let nodes = crate::snake::node_configs(&config, 1).expect("the seed's nodes");
        let port = crate::snake::sim_port(nodes, false, None).expect("a simulated bus");
        let system = SnakeSystem::open(port).expect("the nodes answer");
        Session::new(system, Some(config)).expect("a session")
    }

    /// Commands print what they did, and the view shows it.
    #[test]
    fn commands_print_and_the_view_follows() {
        let mut s = session();
        let b = s.board();
        let text = s.run_script("channel 2; wiper 649").expect("the script");
        assert_eq!(
            text.lines().next(),
            Some("channel 2"),
            "the first command's line: {text}"
        );
        assert!(
            text.contains(&format!("board {b} channel 2: wiper 649")),
            "{text}"
        );
        let view = s.view().expect("the view");
        assert_eq!(view.board, b);
        assert_eq!(view.channels.len(), 7);
        assert_eq!(view.channels[1].wiper, 649);
        assert!(render(&view, 2).lines().any(|l| l.starts_with("> 2")));
    }

    /// A refused command changes nothing and names itself; a script names
    /// the position of the command that failed.
    #[test]
    fn refused_commands_are_named() {
        let mut s = session();
        let e = s.command("frob").expect_err("no such command");
        assert_eq!(e.to_string(), "unknown command \"frob\" (try help)");
        let e = s.command("channel 8").expect_err("7 channels");
        assert!(matches!(e, ToolError::Host(_)), "{e:?}");
        assert_eq!(s.channel(), 1);
        let e = s
            .run_script("channel 3\n# a comment\nvoltage 9")
            .expect_err("out of range");
        assert_eq!(
            e.to_string(),
            "command 2 (\"voltage 9\"): voltage (V from the 1.25 V midpoint): 9 is out of range: -1.25 to 1.25"
        );
    }

    /// Every amplifier the tool turned on is off when the session ends.
    #[test]
    fn finish_turns_off_what_the_tool_turned_on() {
        let mut s = session();
        let b = s.board();
        s.run_script("enable on; wait 1").expect("enable");
        assert!(s.view().expect("the view").channels[0].enabled);
        assert_eq!(s.finish().expect("finish"), vec![b]);
        s.command("wait 1").expect("time passes");
        assert!(!s.view().expect("the view").channels[0].enabled);
        assert_eq!(s.finish().expect("again"), Vec::<u8>::new());
    }
}
