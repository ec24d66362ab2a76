//! `firelink web` and `firelink ros2`: the web console and the ROS 2 node
//! live in their own crates (with their HTTP and DDS stacks) so that the CLI
//! and the demo build without them; these subcommands run their binaries
//! from next to this one, passing the options through.

use std::process::Command;

use crate::CliError;

/// Run the companion binary `name` (e.g. `firelink-web`) with `args`; its
/// exit status becomes ours.
pub fn run(name: &str, args: &[String]) -> Result<(), CliError> {
    let here = std::env::current_exe()?;
    let binary = here.with_file_name(name);
    if !binary.exists() {
        return Err(CliError::CompanionMissing {
            name: name.to_string(),
            path: binary.display().to_string(),
        });
    }
    let status = Command::new(&binary).args(args).status()?;
    if status.success() {
        Ok(())
    } else {
        Err(CliError::CompanionFailed {
            name: name.to_string(),
            status,
        })
    }
}
