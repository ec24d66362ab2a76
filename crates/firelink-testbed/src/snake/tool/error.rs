//! What a snake-tool command or session can fail with.

/// A snake-tool failure.
#[derive(Debug, thiserror::Error)]
pub enum ToolError {
    /// A command was refused (the message names the command and what was
    /// wrong).
    #[error("{0}")]
    Command(String),
    /// The nodes refused or did not answer.
    #[error(transparent)]
    Host(#[from] firelink_host::HostError),
    /// A JSON view or state file could not be written.
    #[error("invalid JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A state file could not be read or written.
    #[error("output: {0}")]
    Io(#[from] std::io::Error),
}

/// A refused command.
pub(super) fn refused(what: impl Into<String>) -> ToolError {
    ToolError::Command(what.into())
}
