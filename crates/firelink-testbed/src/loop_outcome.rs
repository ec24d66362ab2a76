//! How a robot loop's commands and the loop itself end, for every robot's
//! loop: a command's [`Verdict`] and [`CommandOutcome`], and the loop's
//! [`LoopExit`] (what the final power-down found, a panic, the stop
//! request that ended it). The dVRK's robot service
//! ([`crate::dvrk::service`]) and the web console's Snake and MAHRU loops
//! answer in these words.

use std::fmt;

use firelink_host::PowerDown;
use firelink_host::stop::StopReason;

/// How a command ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Done.
    Ok,
    /// Refused: the robot's state does not allow it (or its arguments are
    /// wrong); nothing was changed.
    Refused,
    /// Tried and not done (a time-out, a fault or a port error on the
    /// way): the frames show where the robot is.
    Failed,
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Verdict::Ok => "ok",
            Verdict::Refused => "refused",
            Verdict::Failed => "failed",
        })
    }
}

/// What happened to a command.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CommandOutcome {
    /// The id it was queued with (the dVRK service's
    /// [`Shared::requests`](crate::dvrk::service::Shared::requests)); 0 for
    /// a command queued without one
    /// ([`Shared::commands`](crate::dvrk::service::Shared::commands)).
    pub id: u64,
    /// The command, as text (`configure`, `amplifiers on`, ...).
    pub command: String,
    /// Done, refused or failed.
    pub result: Verdict,
    /// What it found when done (configure: boards an earlier program left
    /// powered; disable: what the power-down found) or why it was refused
    /// or failed.
    pub detail: String,
}

impl fmt::Display for CommandOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.command, self.result)?;
        if !self.detail.is_empty() {
            write!(f, ": {}", self.detail)?;
        }
        Ok(())
    }
}

/// How a robot loop ended: the dVRK service's
/// [`Service::stop`](crate::dvrk::service::Service::stop) returns it (it is
/// also in [`Shared::exit`](crate::dvrk::service::Shared::exit) once the
/// loop has ended; a panic ends it early), and so does each of the web
/// console's Snake and MAHRU loops.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoopExit {
    /// What the final power-down found (`None` if the power-down itself
    /// panicked: then the I/O system's own drop powered the boards down
    /// without reporting).
    pub power_down: Option<PowerDown>,
    /// The loop's panic, if it panicked.
    pub panic: Option<String>,
    /// The signal (or caller) whose stop request ended the loop, if one did.
    pub stopped_by: Option<StopReason>,
}

impl LoopExit {
    /// Whether the loop ended without a panic and every board answered the
    /// power-down with everything off.
    pub fn is_clean(&self) -> bool {
        self.panic.is_none() && self.power_down.is_some_and(|p| p.all_off())
    }
}

impl fmt::Display for LoopExit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(p) = &self.panic {
            write!(f, "the robot loop panicked ({p}); ")?;
        }
        match &self.power_down {
            Some(p) => write!(f, "{p}"),
            None => f.write_str(
                "the power-down did not finish: the boards' watchdogs turn their amplifiers off",
            ),
        }
    }
}
