//! `firelink demo`: which robot's demo the options ask for (the dVRK by
//! default, `--teleop`, `--robot snake` or a Snake configuration,
//! `--robot mahru`), and running it.

use std::io::Write;

use super::{DemoArgs, DemoRobot};
use super::{dvrk, mahru, snake};
use crate::error::CliError;

/// Run `firelink demo`.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    if args.teleop {
        return dvrk::run_teleop(args, out);
    }
    if args.robot == DemoRobot::Mahru {
        return mahru::run_demo(args, out);
    }
    if snake::wanted(args)? {
        return snake::run(args, out);
    }
    dvrk::run(args, out)
}
