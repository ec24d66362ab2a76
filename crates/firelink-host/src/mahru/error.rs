//! What can go wrong in the MAHRU motion controller.

use firelink_wire::mahru::{ModId, ModuleKind, ModuleState};

use crate::error::HostError;

/// Why a module's data for a cycle was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MissReason {
    /// Its QREAD or FTREAD failed.
    Transaction(HostError),
    /// The answer did not decode.
    Malformed(firelink_wire::Error),
    /// The joint block names another module.
    WrongModule {
        /// The ModID found in the block.
        found: ModId,
    },
}

impl core::fmt::Display for MissReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            MissReason::Transaction(e) => write!(f, "{e}"),
            MissReason::Malformed(e) => write!(f, "bad answer: {e}"),
            MissReason::WrongModule { found } => write!(f, "the answer is from {found}"),
        }
    }
}

/// A failure of the motion controller. `Copy`, so the servo cycle can pass
/// it around without allocating.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum MotionError {
    /// A port operation outside the cycle failed.
    #[error(transparent)]
    Host(#[from] HostError),
    /// The robot's layout is not usable.
    #[error("layout: {what} ({mod_id})")]
    Layout {
        /// What is wrong.
        what: &'static str,
        /// The module concerned.
        mod_id: ModId,
    },
    /// No node answered IDREQUEST with this module's ID.
    #[error("{mod_id} is not on the bus")]
    MissingModule {
        /// The module.
        mod_id: ModId,
    },
    /// Two nodes claim the same module ID.
    #[error("{mod_id} answers at nodes {first} and {second}")]
    DuplicateModule {
        /// The module ID.
        mod_id: ModId,
        /// One node.
        first: u8,
        /// The other.
        second: u8,
    },
    /// The module is of another kind than the layout says.
    #[error("{mod_id} is a {found:?} module, the layout says {expected:?}")]
    WrongKind {
        /// The module.
        mod_id: ModId,
        /// What the layout says.
        expected: ModuleKind,
        /// What it reported.
        found: ModuleKind,
    },
    /// IDCHECK did not confirm the mapping.
    #[error("IDCHECK of {mod_id} at node {node} failed: {what}")]
    IdCheck {
        /// The module.
        mod_id: ModId,
        /// The node it was mapped to.
        node: u8,
        /// What did not match.
        what: &'static str,
    },
    /// A module missed a cycle: the robot was stopped.
    #[error("{mod_id} missed the cycle: {reason}; robot stopped")]
    Missed {
        /// The module.
        mod_id: ModId,
        /// Why.
        reason: MissReason,
    },
    /// A module reports that it stopped itself (limit, watchdog) or is not
    /// running: the robot was stopped.
    #[error("{mod_id} is {state:?} (flags {flags:#x}); robot stopped")]
    ModuleFault {
        /// The module.
        mod_id: ModId,
        /// Its state.
        state: ModuleState,
        /// Its status flags.
        flags: u32,
    },
    /// Motion commands are refused in this state.
    #[error("the controller is {0:?}: motion needs Running")]
    NotRunning(super::ControllerState),
}
