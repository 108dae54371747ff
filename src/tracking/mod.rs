//! Head tracking over OSC (thesis 7.2): decoding, tracker-to-CAVE calibration, filtering, the
//! receiver thread and the simulator. No GPU and no windows here.

pub mod calibration;
pub mod filter;
pub mod head;
pub mod osc;
pub mod plausibility;
pub mod receiver;
pub mod sim;

use std::net::SocketAddr;
use std::path::PathBuf;

pub use calibration::Calibration;
pub use filter::OneEuroParams;
pub use head::{HeadPose, HeadTracker, TrackingSettings, TrackingStats, TrackingStatus};
pub use osc::{OscMapping, QuaternionOrder};
pub use plausibility::PlausibilityLimits;
pub use receiver::{Counters, OscReceiver, ReceiverSettings, TrackerFeed, TrackerSample};

/// Default UDP port for OSC head tracking (documented in `config/cave.toml`).
pub const DEFAULT_OSC_PORT: u16 = 7000;

/// Everything that can go wrong in tracking, named by address or file.
#[derive(Debug, thiserror::Error)]
pub enum TrackingError {
    #[error("cannot listen for OSC on {address}: {source}")]
    Bind {
        address: SocketAddr,
        source: std::io::Error,
    },
    #[error("cannot start the OSC receiver thread: {source}")]
    Thread { source: std::io::Error },
    #[error("cannot send OSC to {target}: {source}")]
    Send {
        target: SocketAddr,
        source: std::io::Error,
    },
    #[error("'{target}' is not a host:port to send OSC to: {message}")]
    Target { target: String, message: String },
    #[error("cannot read path file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("path file {path}, line {line}: {message}")]
    Csv {
        path: PathBuf,
        line: usize,
        message: String,
    },
}
