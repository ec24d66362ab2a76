//! Errors of the bus API (building topologies, addressing nodes).
//!
//! Odd traffic is never an error: garbage packets, corrupt acks and
//! misbehaving nodes are simulated and traced, not rejected. These errors are
//! only for misuse of the API.

/// What went wrong with a bus API call.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// No node has this index.
    #[error("no node {0}")]
    NoSuchNode(usize),
    /// The node has no such port.
    #[error("node {node} has no port {port}")]
    NoSuchPort {
        /// Node index.
        node: usize,
        /// Port number.
        port: u8,
    },
    /// The port already has a cable.
    #[error("port {port} of node {node} is already connected")]
    PortInUse {
        /// Node index.
        node: usize,
        /// Port number.
        port: u8,
    },
    /// Every port of the node is in use.
    #[error("node {0} has no free port")]
    NoFreePort(usize),
    /// The cable would close a loop (1394 cable buses are trees).
    #[error("connecting {a} and {b} would close a loop")]
    Loop {
        /// One end.
        a: usize,
        /// The other end.
        b: usize,
    },
    /// No cable joins the two nodes.
    #[error("nodes {a} and {b} are not connected")]
    NotConnected {
        /// One end.
        a: usize,
        /// The other end.
        b: usize,
    },
    /// A bus holds at most 63 nodes.
    #[error("a bus holds at most 63 nodes, this one would have {0}")]
    TooManyNodes(usize),
    /// The node is not of the requested type.
    #[error("node {0} is not of the requested type")]
    WrongNodeType(usize),
    /// A node callback is running (re-entrant use).
    #[error("node {0} is busy in a callback")]
    NodeBusy(usize),
}
