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
mod session;
mod state;
mod view;

pub use commands::HELP;
pub use error::ToolError;
pub use session::Session;
pub use state::{ChannelState, Factors, STATE_VERSION, StateFile};
pub use view::{ChannelView, NodeView, render};
