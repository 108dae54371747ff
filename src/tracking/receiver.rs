//! The OSC receiver: a UDP socket on its own thread that decodes every packet and keeps only the
//! newest pose (no queue), counting what it accepts and drops. It never blocks the renderer: the
//! render loop only tries the lock on a slot the thread holds for a copy of a few fields.

use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, TryLockError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};

use super::TrackingError;
use super::osc::{OscMapping, PacketOutcome, PoseUpdate, decode_packet};

/// Largest UDP payload: every datagram fits whole.
const MAX_DATAGRAM: usize = 65_536;
/// How often the thread wakes to see whether it should stop.
const POLL: Duration = Duration::from_millis(50);
/// At most one log line per kind of problem in this interval (the rest are counted).
pub const LOG_INTERVAL: Duration = Duration::from_secs(2);

/// An orientation as the tracker sent it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TrackedOrientation {
    /// A rotation in the tracker's frame (quaternion messages).
    Tracker(Quat),
    /// Already in CAVE axes (yaw/pitch/roll messages).
    CaveAxes(Quat),
}

/// The newest state the tracker has sent (tracker frame), merged over packets: a packet with
/// only an orientation keeps the last position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerSample {
    /// Accepted packets so far; changes with every accepted packet.
    pub seq: u64,
    /// When the newest accepted packet came off the socket.
    pub arrived: Instant,
    /// When it was decoded and stored for the render loop (microseconds after `arrived`,
    /// unless the receiver thread was preempted in between).
    pub stored: Instant,
    pub position: Option<Vec3>,
    pub orientation: Option<TrackedOrientation>,
    /// The tracker's own flag (NatNet `tracked`), if it sends one.
    pub tracked: Option<bool>,
    pub sender: SocketAddr,
}

/// Packet counts. Every received packet is counted once in exactly one of accepted, ignored,
/// malformed, non-finite or refused, so those add up to `received`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counters {
    pub received: u64,
    /// At least one message for us, all valid: the pose was updated.
    pub accepted: u64,
    /// Valid OSC, nothing for us.
    pub ignored: u64,
    /// Not OSC, or a message for us with wrong arguments.
    pub malformed: u64,
    /// A message for us with NaN, infinite or absurdly large numbers (beyond
    /// [`super::osc::MAX_ABS_NUMBER`]).
    pub non_finite: u64,
    /// From a sender not in `allowed_senders`.
    pub refused: u64,
    /// Socket errors (not packets).
    pub socket_errors: u64,
}

impl Counters {
    /// Whether every received packet is accounted for exactly once.
    pub fn adds_up(&self) -> bool {
        self.accepted + self.ignored + self.malformed + self.non_finite + self.refused
            == self.received
    }

    /// Packets dropped as bad (malformed, not finite or refused).
    pub fn dropped(&self) -> u64 {
        self.malformed + self.non_finite + self.refused
    }
}

#[derive(Debug, Default)]
struct AtomicCounters {
    received: AtomicU64,
    accepted: AtomicU64,
    ignored: AtomicU64,
    malformed: AtomicU64,
    non_finite: AtomicU64,
    refused: AtomicU64,
    socket_errors: AtomicU64,
}

/// Most buttons a source reports (VRPN's own limit is 256; a wand has a handful).
pub const MAX_BUTTONS: usize = 64;
/// Most analog channels a source reports (VRPN's `vrpn_CHANNEL_MAX` is 128).
pub const MAX_ANALOGS: usize = 32;

/// The buttons and analogs of the tracked input device (VRPN button and analog devices, a DTrack
/// flystick, OSC buttons).
#[derive(Debug, Clone, PartialEq)]
pub struct Controls {
    /// Bit `i`: button `i` is held now.
    pub held: u64,
    /// Presses of each button so far: a press released again before the next frame still
    /// counts, so the application compares counts rather than states.
    pub presses: [u32; MAX_BUTTONS],
    /// The newest value of each analog channel (joystick axes: −1 to 1).
    pub analogs: Vec<f64>,
}

impl Default for Controls {
    fn default() -> Self {
        Self {
            held: 0,
            presses: [0; MAX_BUTTONS],
            analogs: Vec::new(),
        }
    }
}

impl Controls {
    /// Records button `index`'s state; buttons past [`MAX_BUTTONS`] are ignored.
    pub fn set_button(&mut self, index: usize, down: bool) {
        if index >= MAX_BUTTONS {
            return;
        }
        let bit = 1u64 << index;
        if down && self.held & bit == 0 {
            self.presses[index] = self.presses[index].wrapping_add(1);
        }
        if down {
            self.held |= bit;
        } else {
            self.held &= !bit;
        }
    }

    /// Replaces the analog channels (at most [`MAX_ANALOGS`]; non-finite values read as 0).
    pub fn set_analogs(&mut self, values: impl IntoIterator<Item = f64>) {
        self.analogs.clear();
        self.analogs.extend(
            values
                .into_iter()
                .take(MAX_ANALOGS)
                .map(|v| if v.is_finite() { v } else { 0.0 }),
        );
    }

    pub fn is_held(&self, index: usize) -> bool {
        index < MAX_BUTTONS && self.held & (1 << index) != 0
    }
}

/// What the receiver shares with the render loop.
#[derive(Debug, Default)]
struct Shared {
    latest: Mutex<Option<TrackerSample>>,
    wand: Mutex<Option<TrackerSample>>,
    controls: Mutex<Controls>,
    counters: AtomicCounters,
}

/// One packet's (or message's) fate, for [`TrackerFeed::count`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    Accepted,
    Ignored,
    Malformed,
    NonFinite,
    Refused,
}

/// Tries a slot a few spins; `None` if the writer holds it (the next frame gets it).
fn try_copy<T: Clone>(slot: &Mutex<T>) -> Option<T> {
    for _ in 0..64 {
        match slot.try_lock() {
            Ok(guard) => return Some(guard.clone()),
            Err(TryLockError::Poisoned(p)) => return Some(p.into_inner().clone()),
            Err(TryLockError::WouldBlock) => std::hint::spin_loop(),
        }
    }
    None
}

/// The render loop's view of a receiver: the newest sample and the counters.
#[derive(Debug, Clone, Default)]
pub struct TrackerFeed {
    shared: Arc<Shared>,
}

impl TrackerFeed {
    /// The newest sample, or `None` if there is none yet. Never waits: the receiver holds the
    /// slot only to copy a few fields in, so a few spins find it free; should they not, this
    /// frame goes without and the next one gets the sample.
    pub fn try_latest(&self) -> Option<TrackerSample> {
        try_copy(&self.shared.latest).flatten()
    }

    /// The newest sample of the wand (the second tracked body), like [`Self::try_latest`].
    pub fn try_wand(&self) -> Option<TrackerSample> {
        try_copy(&self.shared.wand).flatten()
    }

    /// The buttons and analogs; `None` only if the source holds them this instant.
    pub fn try_controls(&self) -> Option<Controls> {
        try_copy(&self.shared.controls)
    }

    /// A source stores the head's newest sample.
    pub fn publish_head(&self, sample: TrackerSample) {
        *lock(&self.shared.latest) = Some(sample);
    }

    /// A source stores the wand's newest sample.
    pub fn publish_wand(&self, sample: TrackerSample) {
        *lock(&self.shared.wand) = Some(sample);
    }

    /// A source changes the buttons and analogs.
    pub fn update_controls(&self, change: impl FnOnce(&mut Controls)) {
        change(&mut lock(&self.shared.controls));
    }

    /// A source counts one received packet or message and its fate.
    pub fn count(&self, fate: Fate) {
        let c = &self.shared.counters;
        let counter = match fate {
            Fate::Accepted => &c.accepted,
            Fate::Ignored => &c.ignored,
            Fate::Malformed => &c.malformed,
            Fate::NonFinite => &c.non_finite,
            Fate::Refused => &c.refused,
        };
        counter.fetch_add(1, Ordering::AcqRel);
        c.received.fetch_add(1, Ordering::AcqRel);
    }

    /// A source counts a socket error (not a packet).
    pub fn count_socket_error(&self) {
        self.shared
            .counters
            .socket_errors
            .fetch_add(1, Ordering::AcqRel);
    }

    pub fn counters(&self) -> Counters {
        let c = &self.shared.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Acquire);
        // A snapshot taken while a packet is being handled may be off by that packet; once
        // the receiver is idle the categories add up to `received` exactly.
        Counters {
            received: get(&c.received),
            accepted: get(&c.accepted),
            ignored: get(&c.ignored),
            malformed: get(&c.malformed),
            non_finite: get(&c.non_finite),
            refused: get(&c.refused),
            socket_errors: get(&c.socket_errors),
        }
    }
}

/// At most one message per interval; counts what it held back.
#[derive(Debug, Clone, Default)]
pub struct LogLimiter {
    last: Option<Instant>,
    held_back: u64,
}

impl LogLimiter {
    /// `Some(n)` if a line may be logged now (`n` lines were held back since the last one).
    pub fn allow(&mut self, now: Instant, interval: Duration) -> Option<u64> {
        match self.last {
            Some(t) if now.duration_since(t) < interval => {
                self.held_back += 1;
                None
            }
            _ => {
                self.last = Some(now);
                Some(std::mem::take(&mut self.held_back))
            }
        }
    }
}

/// Which packets the receiver takes.
#[derive(Debug, Clone, PartialEq)]
pub struct ReceiverSettings {
    pub listen: SocketAddr,
    /// Senders allowed (empty: any).
    pub allowed_senders: Vec<IpAddr>,
    pub mapping: OscMapping,
}

/// Decodes datagrams into the shared slot and counters (what the receiver thread runs for
/// each packet; public so the fuzz tests can drive it without a socket).
#[derive(Debug)]
pub struct PacketSink {
    mapping: OscMapping,
    allowed: Vec<IpAddr>,
    feed: TrackerFeed,
    seq: u64,
    current: Option<TrackerSample>,
    malformed_log: LogLimiter,
    refused_log: LogLimiter,
}

impl PacketSink {
    pub fn new(settings: &ReceiverSettings) -> Self {
        Self {
            mapping: settings.mapping.clone(),
            allowed: settings
                .allowed_senders
                .iter()
                .map(|ip| ip.to_canonical())
                .collect(),
            feed: TrackerFeed::default(),
            seq: 0,
            current: None,
            malformed_log: LogLimiter::default(),
            refused_log: LogLimiter::default(),
        }
    }

    pub fn feed(&self) -> TrackerFeed {
        self.feed.clone()
    }

    /// Handles one datagram from `from` that came off the socket at `arrived`. Never panics:
    /// a panic in the decoder would be caught and counted as malformed.
    pub fn handle(&mut self, bytes: &[u8], from: SocketAddr, arrived: Instant) {
        let shared = self.feed.shared.clone();
        let counters = &shared.counters;
        let bump = |a: &AtomicU64| {
            a.fetch_add(1, Ordering::AcqRel);
        };
        if !self.allowed.is_empty() && !self.allowed.contains(&from.ip().to_canonical()) {
            bump(&counters.refused);
            bump(&counters.received);
            if let Some(held) = self.refused_log.allow(arrived, LOG_INTERVAL) {
                tracing::warn!(
                    "OSC: refused a packet from {from} (not in tracking.allowed_senders){}",
                    held_back(held)
                );
            }
            return;
        }
        let mapping = &self.mapping;
        let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| decode_packet(bytes, mapping)))
            .unwrap_or_else(|_| PacketOutcome::Malformed("the decoder panicked".into()));
        match outcome {
            PacketOutcome::Pose(update) => {
                self.store(update, from, arrived);
                bump(&counters.accepted);
            }
            PacketOutcome::Ignored => bump(&counters.ignored),
            PacketOutcome::Malformed(why) => {
                bump(&counters.malformed);
                self.log_bad(from, arrived, "malformed", &why);
            }
            PacketOutcome::NonFinite(why) => {
                bump(&counters.non_finite);
                self.log_bad(from, arrived, "non-finite", &why);
            }
        }
        bump(&counters.received);
    }

    fn log_bad(&mut self, from: SocketAddr, now: Instant, what: &str, why: &str) {
        if let Some(held) = self.malformed_log.allow(now, LOG_INTERVAL) {
            tracing::warn!(
                "OSC: dropped a {what} packet from {from}: {why}{}",
                held_back(held)
            );
        }
    }

    fn store(&mut self, update: PoseUpdate, from: SocketAddr, arrived: Instant) {
        self.seq += 1;
        let previous = self.current;
        let orientation = match (update.orientation, update.orientation_cave_axes) {
            (Some(q), _) => Some(TrackedOrientation::Tracker(q)),
            (None, Some(q)) => Some(TrackedOrientation::CaveAxes(q)),
            (None, None) => previous.and_then(|p| p.orientation),
        };
        let sample = TrackerSample {
            seq: self.seq,
            arrived,
            stored: Instant::now(),
            position: update.position.or(previous.and_then(|p| p.position)),
            orientation,
            tracked: update.tracked.or(previous.and_then(|p| p.tracked)),
            sender: from,
        };
        self.current = Some(sample);
        let mut slot = self
            .feed
            .shared
            .latest
            .lock()
            .unwrap_or_else(|p| p.into_inner());
        *slot = Some(sample);
    }
}

fn lock<T>(slot: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    slot.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// `" (N more not logged)"`, or nothing when none were held back.
pub fn held_back(n: u64) -> String {
    if n == 0 {
        String::new()
    } else {
        format!(" ({n} more not logged)")
    }
}

/// A UDP socket read on its own thread until dropped (the OSC and DTrack receivers): every
/// datagram goes to a handler with its sender and arrival time; socket errors are counted on
/// the feed and logged at most once per [`LOG_INTERVAL`].
#[derive(Debug)]
pub struct UdpThread {
    local_addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl UdpThread {
    /// Binds `listen` and starts the thread `name`; `what` names the source in log lines.
    pub fn start(
        name: &str,
        what: &'static str,
        listen: SocketAddr,
        feed: TrackerFeed,
        mut handle: impl FnMut(&[u8], SocketAddr, Instant) + Send + 'static,
    ) -> Result<Self, TrackingError> {
        let bind = |source| TrackingError::Bind {
            address: listen,
            source,
        };
        let socket = UdpSocket::bind(listen).map_err(bind)?;
        let local_addr = socket.local_addr().map_err(bind)?;
        socket.set_read_timeout(Some(POLL)).map_err(bind)?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = stop.clone();
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                let mut buf = vec![0u8; MAX_DATAGRAM];
                let mut error_log = LogLimiter::default();
                while !thread_stop.load(Ordering::Acquire) {
                    match socket.recv_from(&mut buf) {
                        Ok((n, from)) => {
                            let arrived = Instant::now();
                            // The handlers catch their decoders' panics themselves; this
                            // second net keeps the thread alive should anything else panic.
                            let handled = std::panic::catch_unwind(AssertUnwindSafe(|| {
                                handle(&buf[..n], from, arrived);
                            }));
                            if handled.is_err() {
                                tracing::error!(
                                    "{what}: a packet from {from} could not be handled (panic)"
                                );
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
                            feed.count_socket_error();
                            if let Some(held) = error_log.allow(Instant::now(), LOG_INTERVAL) {
                                tracing::warn!("{what}: socket error: {e}{}", held_back(held));
                            }
                            // Do not spin on a persistent error.
                            std::thread::sleep(Duration::from_millis(10));
                        }
                    }
                }
            })
            .map_err(|source| TrackingError::Thread { source })?;
        Ok(Self {
            local_addr,
            stop,
            thread: Some(thread),
        })
    }

    /// The address the socket is bound to (with the port chosen when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }
}

impl Drop for UdpThread {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            // Wakes within POLL.
            let _ = t.join();
        }
    }
}

/// A running OSC receiver: its socket's thread and the feed the render loop reads.
#[derive(Debug)]
pub struct OscReceiver {
    feed: TrackerFeed,
    udp: UdpThread,
}

impl OscReceiver {
    /// Binds the socket and starts the thread.
    pub fn start(settings: &ReceiverSettings) -> Result<Self, TrackingError> {
        let mut sink = PacketSink::new(settings);
        let feed = sink.feed();
        let udp = UdpThread::start(
            "osc-receiver",
            "OSC",
            settings.listen,
            feed.clone(),
            move |bytes, from, arrived| sink.handle(bytes, from, arrived),
        )?;
        tracing::info!("OSC head tracking: listening on {}", udp.local_addr());
        Ok(Self { feed, udp })
    }

    /// The address the socket is bound to (with the port chosen when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.udp.local_addr()
    }

    pub fn feed(&self) -> &TrackerFeed {
        &self.feed
    }
}
