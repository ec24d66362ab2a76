//! `firelink web` and `firelink ros2`: the web console and the ROS 2 node
//! live in their own crates (with their HTTP and DDS stacks) so that the CLI
//! and the demo build without them; these subcommands *become* their
//! binaries from next to this one (`exec`), passing the options through.
//!
//! `exec` rather than spawning a child: the companion then has this
//! process's PID, so a supervisor's `kill` (SIGTERM), a closed terminal
//! (SIGHUP) or Ctrl-C reaches the program that drives the robot, which
//! powers it down, and no wrapper is left to die while an orphaned child
//! keeps feeding the boards' watchdogs with the amplifiers on.

use std::os::unix::process::CommandExt;
use std::process::Command;

use crate::error::CliError;

/// Replace this process with the companion binary `name` (e.g.
/// `firelink-web`) run with `args`. Returns only if that failed.
pub fn run(name: &str, args: &[String]) -> Result<(), CliError> {
    let here = std::env::current_exe()?;
    let binary = here.with_file_name(name);
    if !binary.exists() {
        return Err(CliError::CompanionMissing {
            name: name.to_string(),
            path: binary.display().to_string(),
        });
    }
    let error = Command::new(&binary).args(args).exec();
    Err(error.into())
}
