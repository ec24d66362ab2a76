//! `firelink emulate`: emulated boards behind an Ethernet bridge on UDP
//! (or, with `--fw-cdev`, as the kernel's /dev/fw* devices on a unix
//! socket for the preloaded twin; with `--network eth`, FPGA V3 boards at
//! Rev 9 on the Ethernet-only network, each at its own address), paced to
//! wall-clock time, until SIGINT or SIGTERM. The options and the servers
//! are the testbed's ([`EmulateRequest`]); this file prints.

use std::io::Write;

use firelink_testbed::emulation::EmulateRequest;

use crate::error::CliError;

/// `firelink emulate`: the notes on stderr, the banner, then each server
/// event as its line, at once.
pub fn run(args: &EmulateRequest, out: &mut impl Write) -> Result<(), CliError> {
    let emulation = args.open(&mut |line| say!("{line}"))?;
    for line in emulation.banner() {
        writeln!(out, "{line}")?;
    }
    out.flush()?;
    emulation.serve(|event| {
        let _ = writeln!(out, "{event}");
        let _ = out.flush();
    })?;
    Ok(())
}
