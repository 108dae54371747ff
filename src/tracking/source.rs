//! Where tracking comes from: OSC, a VRPN server or ART DTrack. Each source runs on its own
//! threads and fills the same [`TrackerFeed`]: the head, the wand, buttons and analogs, with
//! the same counters. Calibration, plausibility, filter, timeout and latency figures are
//! applied after it, the same for all.

use std::net::SocketAddr;

use super::TrackingError;
use super::dtrack::{DTrackReceiver, DTrackSettings};
use super::receiver::{OscReceiver, ReceiverSettings, TrackerFeed};
use super::vrpn::{VrpnClient, VrpnSettings};

/// Which tracking system feeds the head.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SourceKind {
    /// OSC over UDP (the thesis's interface, and NatNet-to-OSC bridges).
    #[default]
    Osc,
    /// A VRPN server (`Tracker0@host`).
    Vrpn,
    /// ART DTrack's ASCII frames over UDP.
    DTrack,
}

crate::named_enum!(SourceKind {
    Self::Osc => "osc",
    Self::Vrpn => "vrpn",
    Self::DTrack => "dtrack",
});

/// A validated source, ready to start.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceSettings {
    /// OSC, with the receiver settings kept beside it (`TrackingConfig::receiver`).
    Osc,
    Vrpn(VrpnSettings),
    DTrack(DTrackSettings),
}

/// A running source.
#[derive(Debug)]
pub enum TrackingSource {
    Osc(OscReceiver),
    Vrpn(VrpnClient),
    DTrack(DTrackReceiver),
}

impl TrackingSource {
    /// Starts the source; OSC listens as `osc` says.
    pub fn start(settings: &SourceSettings, osc: &ReceiverSettings) -> Result<Self, TrackingError> {
        Ok(match settings {
            SourceSettings::Osc => Self::Osc(OscReceiver::start(osc)?),
            SourceSettings::Vrpn(s) => Self::Vrpn(VrpnClient::start(s)?),
            SourceSettings::DTrack(s) => Self::DTrack(DTrackReceiver::start(s)?),
        })
    }

    pub fn feed(&self) -> &TrackerFeed {
        match self {
            Self::Osc(r) => r.feed(),
            Self::Vrpn(c) => c.feed(),
            Self::DTrack(r) => r.feed(),
        }
    }

    /// The local address packets arrive at (OSC and DTrack; VRPN's ports change per connection).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match self {
            Self::Osc(r) => Some(r.local_addr()),
            Self::Vrpn(_) => None,
            Self::DTrack(r) => Some(r.local_addr()),
        }
    }

    /// One line for the panel: the source and where it listens or connects.
    pub fn describe(&self) -> String {
        match self {
            Self::Osc(r) => format!("OSC on {}", r.local_addr()),
            Self::Vrpn(c) => format!("VRPN from {}", c.servers().join(", ")),
            Self::DTrack(r) => format!("DTrack on {}", r.local_addr()),
        }
    }
}
