//! Head and wand tracking: the sources (OSC as in thesis 7.2, VRPN, ART DTrack), tracker-to-CAVE
//! calibration with the eye offset, plausibility, filtering, and the simulator. No GPU and no
//! windows here.

pub mod calibration;
pub mod dtrack;
pub mod filter;
pub mod gate;
pub mod head;
pub mod natnet;
pub mod osc;
pub mod plausibility;
pub mod receiver;
pub mod sim;
pub mod source;
pub mod vrpn;
pub mod vrpn_wire;

use std::net::SocketAddr;
use std::path::PathBuf;

pub use calibration::Calibration;
pub use dtrack::DTrackSettings;
pub use filter::OneEuroParams;
pub use gate::{GateCounters, GateSettings, Stream, StreamSenders};
pub use head::{HeadPose, HeadTracker, TrackingSettings, TrackingStats, TrackingStatus};
pub use natnet::NatNetSettings;
pub use osc::{OscMapping, QuaternionOrder};
pub use plausibility::PlausibilityLimits;
pub use receiver::{Controls, Counters, OscReceiver, ReceiverSettings, TrackerFeed, TrackerSample};
pub use source::{LinkState, SourceKind, SourceSettings, TrackingSource};
pub use vrpn::{VrpnClient, VrpnDevice, VrpnSettings};

/// What a button of the tracked input device does: fly along the wand's ray while held, pick
/// what the ray hits, or one of the gamepad's actions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ButtonAction {
    Fly,
    Select,
    Action(crate::gamepad::GamepadAction),
}

impl ButtonAction {
    /// "fly", "select" or a gamepad action's name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "fly" => Some(Self::Fly),
            "select" => Some(Self::Select),
            other => crate::gamepad::GamepadAction::from_name(other).map(Self::Action),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Fly => "fly",
            Self::Select => "select",
            Self::Action(a) => a.name(),
        }
    }
}

/// Default UDP port for OSC head tracking (documented in `config/cave.toml`).
pub const DEFAULT_OSC_PORT: u16 = 7000;

/// Everything that can go wrong in tracking, named by address or file.
#[derive(Debug, thiserror::Error)]
pub enum TrackingError {
    #[error("cannot listen for tracking data (UDP) on {address}: {source}")]
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
