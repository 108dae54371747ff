//! Cluster mode: several processes (MPI ranks, one per PC or per wall) drive one CAVE in
//! lockstep. No windows and no GPU here: the messages, the start-up check, the per-frame
//! broadcast and barrier and the handling of lost nodes, over any [`Transport`] (MPI in
//! `mpi_transport`, in-process channels in tests).
//!
//! Per frame the master (rank 0) sends the frame's settings when they changed and its
//! [`FrameState`]; every process renders its walls; each node reports "rendered"; when every
//! live node has, the master sends "present" and all present that frame together (a software
//! swap lock). A node that does not report within `cluster.timeout_ms` is lost: reported,
//! told to stop, and either left out (`on_node_loss = "continue"`) or the cluster stops.

pub mod messages;
#[cfg(feature = "cluster")]
pub mod mpi_transport;
pub mod roles;
pub mod session;
pub mod transport;

pub use messages::{Digest, FrameState, Identity, Message, NodeFigures};
pub use roles::{identity, settings_text};
pub use session::{Master, MasterFigures, Node, NodeEvent, NodeStatus, NodeStep};
pub use transport::{MemoryTransport, Transport};

/// What went wrong in the cluster.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    #[error("cluster message refused: {0}")]
    Malformed(String),
    #[error("MPI: {0}")]
    Mpi(String),
    #[error(
        "cluster mode needs at least one render node besides the master: started with {0} process(es)"
    )]
    TooFewProcesses(usize),
    #[error(
        "wall {wall} is on node {node}, but the cluster has {size} processes (ranks 0 to {}); \
         start one per node (`mpirun -np {}`) or change [[wall]] node",
        size - 1,
        node + 1
    )]
    MissingNode {
        wall: String,
        node: usize,
        size: usize,
    },
    #[error(
        "node {node} did not report within {seconds} s of start-up (was it started, and did it load the config and scene?)"
    )]
    NoHello { node: usize, seconds: f64 },
    #[error("node {node} ({host}) refused: {what}")]
    Mismatch {
        node: usize,
        host: String,
        what: String,
    },
    #[error("refused by the master: {0}")]
    Refused(String),
    #[error(
        "the master did not answer within {seconds} s (it died, stalled, or dropped this node)"
    )]
    MasterLost { seconds: f64 },
    #[error("{0}; stopping the cluster (cluster.on_node_loss = \"stop\")")]
    NodeLostStop(String),
    #[error("expected {expected} from {from}, got {got}")]
    Unexpected {
        from: String,
        expected: &'static str,
        got: String,
    },
    #[error(
        "this build has no cluster mode: build omnicave with `--features cluster` (needs an MPI library such as Open MPI, and libclang)"
    )]
    NotBuilt,
    #[error(
        "cluster mode drives the walls' windows: it needs `app.mode = \"cave\"` (or `run --cave`), not the preview"
    )]
    NotCaveMode,
    #[error(
        "the panel is an overlay on wall {wall}, which node {node} drives: in cluster mode the panel is the master's (app.panel = \"window\", or overlay on a wall of node 0)"
    )]
    PanelOnNode { wall: String, node: usize },
}
