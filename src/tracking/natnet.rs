//! OptiTrack NatNet natively (Motive's own streaming protocol, through the `natnet` crate): the
//! command handshake gives the stream's version and whether it is multicast; frames of data
//! come over the multicast group or, unicast, back to the command socket (kept alive every
//! 250 ms). Rigid bodies become head and wand samples on the same [`TrackerFeed`] as every
//! other source. A server that is absent or goes quiet is retried.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use natnet::net::{CommandClient, DataClient, RawCommandClient};
use natnet::{Decoder, Message};

use super::TrackingError;
use super::osc::MAX_ABS_NUMBER;
use super::receiver::{
    Fate, LOG_INTERVAL, LogLimiter, SentAt, TrackedOrientation, TrackerFeed, TrackerSample,
    held_back,
};

/// Motive's command port.
pub const DEFAULT_COMMAND_PORT: u16 = 1510;
/// How long the handshake waits for Motive's answer.
const HANDSHAKE_WAIT: Duration = Duration::from_secs(1);
/// Unicast streams stop unless kept alive this often.
const KEEPALIVE: Duration = Duration::from_millis(250);
const POLL: Duration = Duration::from_millis(50);
/// The largest datagram read (NatNet frames stay under a UDP payload).
const MAX_DATAGRAM: usize = 65_536;

/// Where Motive is and which rigid bodies are the head and the wand.
#[derive(Debug, Clone, PartialEq)]
pub struct NatNetSettings {
    /// Motive's command address (port 1510 unless configured otherwise).
    pub server: SocketAddrV4,
    /// The local interface to talk and join multicast on (0.0.0.0: the system's choice).
    pub interface: Ipv4Addr,
    pub head_rigid_body: i32,
    pub wand_rigid_body: Option<i32>,
    /// Wait between connection attempts.
    pub retry: Duration,
    /// Addresses Motive may be at (`tracking.allowed_senders`; empty: any).
    pub allowed_senders: Vec<std::net::IpAddr>,
    /// No frame for this long (`tracking.timeout_seconds`): reconnect.
    pub idle: Duration,
}

/// A running NatNet client.
#[derive(Debug)]
pub struct NatNetClient {
    feed: TrackerFeed,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    server: SocketAddrV4,
    /// A session is up (handshake done, until the stream goes quiet).
    connected: Arc<AtomicBool>,
}

impl NatNetClient {
    /// Starts connecting in the background (an absent server is retried, not an error).
    pub fn start(settings: &NatNetSettings) -> Result<Self, TrackingError> {
        let feed = TrackerFeed::default();
        let stop = Arc::new(AtomicBool::new(false));
        let connected = Arc::new(AtomicBool::new(false));
        let link = Link {
            settings: settings.clone(),
            feed: feed.clone(),
            stop: stop.clone(),
            connected: connected.clone(),
            quiet_log: LogLimiter::default(),
            head_seq: 0,
            wand_seq: 0,
            bad_log: LogLimiter::default(),
        };
        let thread = std::thread::Builder::new()
            .name("natnet-client".into())
            .spawn(move || link.run())
            .map_err(|source| TrackingError::Thread { source })?;
        tracing::info!("NatNet tracking: connecting to {}", settings.server);
        Ok(Self {
            feed,
            stop,
            thread: Some(thread),
            server: settings.server,
            connected,
        })
    }

    /// Whether a session with Motive is up now.
    pub fn connected(&self) -> bool {
        self.connected.load(Ordering::Acquire)
    }

    pub fn feed(&self) -> &TrackerFeed {
        &self.feed
    }

    pub fn server(&self) -> SocketAddrV4 {
        self.server
    }
}

impl Drop for NatNetClient {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Where frames arrive: the multicast group's socket, or the command socket (unicast).
enum Stream {
    Multicast(DataClient),
    Unicast(RawCommandClient),
}

impl Stream {
    fn recv(&self, buf: &mut [u8]) -> std::io::Result<(usize, SocketAddr)> {
        match self {
            Self::Multicast(d) => d.recv(buf),
            Self::Unicast(c) => c.recv(buf),
        }
    }
}

struct Link {
    settings: NatNetSettings,
    feed: TrackerFeed,
    stop: Arc<AtomicBool>,
    connected: Arc<AtomicBool>,
    quiet_log: LogLimiter,
    head_seq: u64,
    wand_seq: u64,
    bad_log: LogLimiter,
}

impl Link {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }

    fn run(mut self) {
        let mut absent_log = LogLimiter::default();
        while !self.stopped() {
            let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| self.session()));
            self.connected.store(false, Ordering::Release);
            match outcome {
                Ok(Ok(())) => {}
                Ok(Err(why)) => {
                    if let Some(held) = absent_log.allow(Instant::now(), LOG_INTERVAL * 5) {
                        tracing::warn!(
                            "NatNet {}: {why}; retrying every {:.1} s{}",
                            self.settings.server,
                            self.settings.retry.as_secs_f32(),
                            held_back(held)
                        );
                    }
                }
                Err(_) => tracing::error!("NatNet {}: the client panicked", self.settings.server),
            }
            let end = Instant::now() + self.settings.retry;
            while !self.stopped() && Instant::now() < end {
                std::thread::sleep(POLL);
            }
        }
    }

    /// One connection: the handshake, then frames until the stream goes quiet.
    fn session(&mut self) -> Result<(), String> {
        let server = self.settings.server;
        let allowed = &self.settings.allowed_senders;
        let server_ip = std::net::IpAddr::V4(*server.ip());
        if !allowed.is_empty() && !allowed.iter().any(|ip| ip.to_canonical() == server_ip) {
            return Err(format!("{server_ip} is not in tracking.allowed_senders"));
        }
        let mut client = CommandClient::bind(self.settings.interface, server)
            .map_err(|e| format!("cannot open a command socket: {e}"))?;
        let info = client
            .connect_handshake(HANDSHAKE_WAIT)
            .map_err(|e| format!("no handshake ({e}); is Motive streaming there?"))?;
        let version = info.protocol_version;
        let decoder = Decoder::new(version).map_err(|e| format!("NatNet {version:?}: {e}"))?;
        let stream = if info.connection.multicast {
            let group = info.multicast_group();
            let socket = UdpSocket::bind(SocketAddrV4::new(
                Ipv4Addr::UNSPECIFIED,
                info.connection.data_port,
            ))
            .map_err(|e| format!("cannot bind the data port: {e}"))?;
            socket
                .join_multicast_v4(&group, &self.settings.interface)
                .map_err(|e| format!("cannot join {group}: {e}"))?;
            let data = DataClient::from_socket(socket);
            data.set_read_timeout(Some(POLL))
                .map_err(|e| e.to_string())?;
            Stream::Multicast(data)
        } else {
            let raw = client.into_raw();
            raw.set_read_timeout(Some(POLL))
                .map_err(|e| e.to_string())?;
            Stream::Unicast(raw)
        };
        tracing::info!(
            "NatNet {server}: connected to {} (NatNet {:?}, {})",
            info.application_name,
            version,
            if info.connection.multicast {
                "multicast"
            } else {
                "unicast"
            }
        );
        self.connected.store(true, Ordering::Release);
        let mut buf = vec![0u8; MAX_DATAGRAM];
        let mut last_frame = Instant::now();
        let mut last_keepalive: Option<Instant> = None;
        while !self.stopped() {
            if let Stream::Unicast(raw) = &stream
                && last_keepalive.is_none_or(|t| t.elapsed() >= KEEPALIVE)
            {
                let _ = raw.send(&natnet::command::keepalive_datagram());
                last_keepalive = Some(Instant::now());
            }
            if last_frame.elapsed() > self.settings.idle {
                // Motive paused or its multicast blocked: this repeats every retry.
                if let Some(held) = self.quiet_log.allow(Instant::now(), LOG_INTERVAL * 5) {
                    tracing::warn!(
                        "NatNet {server}: no frame for {:.1} s; reconnecting{}",
                        self.settings.idle.as_secs_f64(),
                        held_back(held)
                    );
                }
                return Ok(());
            }
            match stream.recv(&mut buf) {
                Ok((n, from)) => {
                    if from.ip() != std::net::IpAddr::V4(*server.ip()) && !from.ip().is_loopback() {
                        self.feed.count(Fate::Refused);
                        continue;
                    }
                    if self.datagram(decoder, &buf[..n], from) {
                        last_frame = Instant::now();
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => {
                    self.feed.count_socket_error();
                    return Err(format!("socket error: {e}"));
                }
            }
        }
        if let Stream::Unicast(raw) = &stream {
            let _ = raw.send(&natnet::command::disconnect_datagram());
        }
        Ok(())
    }

    /// Handles one datagram; whether it was a frame of data.
    fn datagram(&mut self, decoder: Decoder, bytes: &[u8], from: SocketAddr) -> bool {
        let arrived = Instant::now();
        let message = match decoder.parse(bytes) {
            Ok(m) => m.into_message(),
            Err(e) => {
                self.feed.count(Fate::Malformed);
                if let Some(held) = self.bad_log.allow(arrived, LOG_INTERVAL) {
                    tracing::warn!(
                        "NatNet: dropped a datagram from {from}: {e}{}",
                        held_back(held)
                    );
                }
                return false;
            }
        };
        let Message::FrameOfData(frame) = message else {
            self.feed.count(Fate::Ignored);
            return false;
        };
        // A frame number below zero is no order at all.
        let sent = u64::try_from(frame.frame_number).ok().map(SentAt::Frame);
        let sample = |b: &natnet::RigidBody, seq: u64| -> Option<TrackerSample> {
            let numbers = b.position.iter().chain(&b.orientation);
            if numbers
                .clone()
                .any(|v| !v.is_finite() || f64::from(v.abs()) > MAX_ABS_NUMBER)
            {
                return None;
            }
            let [x, y, z, w] = b.orientation;
            Some(TrackerSample {
                seq,
                arrived,
                stored: Instant::now(),
                position: Some(Vec3::from_array(b.position)),
                orientation: Some(TrackedOrientation::Tracker(Quat::from_xyzw(x, y, z, w))),
                tracked: Some(b.tracking_valid()),
                sender: from,
                sent,
                jumped: false,
            })
        };
        let mut fate = Fate::Ignored;
        for body in &frame.rigid_bodies {
            let head = body.id == self.settings.head_rigid_body;
            let wand = Some(body.id) == self.settings.wand_rigid_body;
            if !head && !wand {
                continue;
            }
            let seq = if head {
                self.head_seq += 1;
                self.head_seq
            } else {
                self.wand_seq += 1;
                self.wand_seq
            };
            match sample(body, seq) {
                Some(s) if head => {
                    self.feed.publish_head(s);
                    fate = Fate::Accepted;
                }
                Some(s) => {
                    self.feed.publish_wand(s);
                    fate = Fate::Accepted;
                }
                None => fate = Fate::NonFinite,
            }
        }
        self.feed.count(fate);
        true
    }
}
