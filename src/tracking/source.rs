//! Where tracking comes from: OSC, a VRPN server, ART DTrack or OptiTrack NatNet. Each source runs on its own
//! threads and fills the same [`TrackerFeed`]: the head, the wand, buttons and analogs, with
//! the same counters. Calibration, plausibility, filter, timeout and latency figures are
//! applied after it, the same for all.

use std::net::SocketAddr;

use super::TrackingError;
use super::dtrack::{DTrackReceiver, DTrackSettings};
use super::natnet::{NatNetClient, NatNetSettings};
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
    /// OptiTrack Motive's NatNet stream.
    NatNet,
}

crate::named_enum!(SourceKind {
    Self::Osc => "osc",
    Self::Vrpn => "vrpn",
    Self::DTrack => "dtrack",
    Self::NatNet => "natnet",
});

/// A validated source, ready to start.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceSettings {
    /// OSC, with the receiver settings kept beside it (`TrackingConfig::receiver`).
    Osc,
    /// Boxed: its device names make it several times the others' size.
    Vrpn(Box<VrpnSettings>),
    DTrack(DTrackSettings),
    NatNet(NatNetSettings),
}

/// How a source stands with its tracker: it listens (OSC, DTrack: the tracker sends to us),
/// or it holds a connection (VRPN, NatNet) or is making one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkState {
    Listening,
    Connected,
    /// Connecting to these servers (at start, or again after they went silent or away).
    Reconnecting(String),
}

impl LinkState {
    pub fn describe(&self) -> String {
        match self {
            Self::Listening => "listening".into(),
            Self::Connected => "connected".into(),
            Self::Reconnecting(to) => format!("reconnecting to {to}"),
        }
    }
}

/// A running source.
#[derive(Debug)]
pub enum TrackingSource {
    Osc(OscReceiver),
    Vrpn(VrpnClient),
    DTrack(DTrackReceiver),
    NatNet(NatNetClient),
}

impl TrackingSource {
    /// Starts the source; OSC listens as `osc` says.
    pub fn start(settings: &SourceSettings, osc: &ReceiverSettings) -> Result<Self, TrackingError> {
        Ok(match settings {
            SourceSettings::Osc => Self::Osc(OscReceiver::start(osc)?),
            SourceSettings::Vrpn(s) => Self::Vrpn(VrpnClient::start(s)?),
            SourceSettings::DTrack(s) => Self::DTrack(DTrackReceiver::start(s)?),
            SourceSettings::NatNet(s) => Self::NatNet(NatNetClient::start(s)?),
        })
    }

    pub fn feed(&self) -> &TrackerFeed {
        match self {
            Self::Osc(r) => r.feed(),
            Self::Vrpn(c) => c.feed(),
            Self::DTrack(r) => r.feed(),
            Self::NatNet(c) => c.feed(),
        }
    }

    /// The local address packets arrive at (OSC and DTrack; VRPN's ports change per connection).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match self {
            Self::Osc(r) => Some(r.local_addr()),
            Self::Vrpn(_) | Self::NatNet(_) => None,
            Self::DTrack(r) => Some(r.local_addr()),
        }
    }

    /// A warning when the source listens on a network address (not loopback) and takes
    /// packets from anyone (no `tracking.allowed_senders`).
    pub fn open_warning(&self) -> Option<String> {
        let (what, listen, allowed) = match self {
            Self::Osc(r) => ("OSC", r.local_addr(), r.allowed_senders()),
            Self::DTrack(r) => ("DTrack", r.local_addr(), r.allowed_senders()),
            // Clients: they take data only from the server they connected to.
            Self::Vrpn(_) | Self::NatNet(_) => return None,
        };
        (allowed.is_empty() && !listen.ip().is_loopback()).then(|| {
            format!(
                "{what} listens on {listen} and takes tracking from any sender on the network; \
                 list the tracker's address in tracking.allowed_senders"
            )
        })
    }

    /// How the source stands with its tracker now.
    pub fn link(&self) -> LinkState {
        match self {
            Self::Osc(_) | Self::DTrack(_) => LinkState::Listening,
            Self::Vrpn(c) => {
                let absent: Vec<String> = c
                    .servers()
                    .iter()
                    .zip(c.data_ports())
                    .filter(|(_, port)| port.is_none())
                    .map(|(server, _)| server.clone())
                    .collect();
                if absent.is_empty() {
                    LinkState::Connected
                } else {
                    LinkState::Reconnecting(absent.join(", "))
                }
            }
            Self::NatNet(c) if c.connected() => LinkState::Connected,
            Self::NatNet(c) => LinkState::Reconnecting(c.server().to_string()),
        }
    }

    /// One line for the panel: the source and where it listens or connects.
    pub fn describe(&self) -> String {
        match self {
            Self::Osc(r) => format!("OSC on {}", r.local_addr()),
            Self::Vrpn(c) => format!("VRPN from {}", c.servers().join(", ")),
            Self::DTrack(r) => format!("DTrack on {}", r.local_addr()),
            Self::NatNet(c) => format!("NatNet from {}", c.server()),
        }
    }
}
