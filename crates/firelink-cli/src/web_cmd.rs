//! `firelink web`: the web console lives in its own crate (`firelink-web`,
//! with its HTTP stack) so that the CLI and the demo build without it; this
//! runs its binary from next to this one, passing the options through.

use std::process::Command;

use crate::CliError;

/// Run `firelink-web` with `args`; its exit status becomes ours.
pub fn run(args: &[String]) -> Result<(), CliError> {
    let here = std::env::current_exe()?;
    let web = here.with_file_name("firelink-web");
    if !web.exists() {
        return Err(CliError::Conflict(format!(
            "the web console is not built: run `cargo build --release -p firelink-web` \
             (looked for {})",
            web.display()
        )));
    }
    let status = Command::new(&web).args(args).status()?;
    if status.success() {
        Ok(())
    } else {
        Err(CliError::Conflict(format!(
            "firelink-web exited with {status}"
        )))
    }
}
