//! The OSC receiver and the feed every source fills: a UDP socket on its own thread decodes
//! every packet, the gate judges every sample there, and only the newest accepted pose is kept
//! (no queue), with counts of what was accepted and dropped and why. It never blocks the
//! renderer: the render loop only tries the lock on a slot the thread holds for a copy.

use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, TryLockError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};

use super::TrackingError;
use super::gate::{GateCounters, GateSettings, Refusal, SourceGate, Stream, StreamSenders};
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

/// The newest state the tracker has sent (tracker frame). OSC merges a pose sent in parts
/// (position and orientation in separate packets), each part for at most the tracking timeout;
/// the "tracked" flag is never carried from one packet to the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerSample {
    /// Samples of this stream published so far (the feed numbers them); changes with every
    /// sample the gate accepts.
    pub seq: u64,
    /// When the newest accepted packet came off the socket.
    pub arrived: Instant,
    /// When it was decoded and stored for the render loop (microseconds after `arrived`,
    /// unless the receiver thread was preempted in between).
    pub stored: Instant,
    pub position: Option<Vec3>,
    pub orientation: Option<TrackedOrientation>,
    /// The tracker's own flag (NatNet `tracked`, a DTrack frame without the body), if this
    /// sample says.
    pub tracked: Option<bool>,
    pub sender: SocketAddr,
    /// When the sender says it took the sample (`None`: the protocol does not say, as OSC).
    pub sent: Option<SentAt>,
    /// The gate took it as a confirmed jump (the filter starts afresh from it).
    pub jumped: bool,
}

/// When a sender says it took a sample: its clock or its frame counter. A sample older than
/// the newest accepted from the same sender is stale (a reordered or replayed packet).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SentAt {
    /// Seconds on the sender's clock (a VRPN message's time, DTrack's `ts`).
    Seconds(f64),
    /// The tracker's frame counter (DTrack's `fr`, NatNet's frame number).
    Frame(u64),
}

impl SentAt {
    /// Whether `self` comes before `newest` on the same clock (never across kinds).
    pub fn is_before(self, newest: SentAt) -> bool {
        match (self, newest) {
            (Self::Seconds(a), Self::Seconds(b)) => a < b,
            (Self::Frame(a), Self::Frame(b)) => a < b,
            _ => false,
        }
    }
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
    /// Samples of accepted packets the gate then refused, by reason.
    pub gate: GateCounters,
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

/// The gate's settings as the render loop last set them; `generation` changes with them.
#[derive(Debug, Default, Clone, Copy)]
struct Configured {
    settings: GateSettings,
    generation: u64,
}

/// The gate, the settings' generation it has seen, and the samples published per stream.
/// Only the sources' threads take its lock (never while logging).
#[derive(Debug, Default)]
struct GateState {
    gate: SourceGate,
    generation: u64,
    published: [u64; 2],
}

/// What the receiver shares with the render loop. The render loop only tries the slots'
/// locks and reads atomics: it never waits on a source.
#[derive(Debug, Default)]
struct Shared {
    latest: Mutex<Option<TrackerSample>>,
    wand: Mutex<Option<TrackerSample>>,
    controls: Mutex<Controls>,
    counters: AtomicCounters,
    configured: Mutex<Configured>,
    gate: Mutex<GateState>,
    /// Samples the gate refused, in [`Refusal::counter_index`] order.
    refusals: [AtomicU64; GateCounters::COUNT],
    /// Who drives each stream, as the gate last said.
    senders: Mutex<[StreamSenders; 3]>,
    refusal_log: Mutex<LogLimiter>,
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

    /// Sets what the gate judges samples against (the render loop, when it changes; never
    /// waits: should the receiver hold the settings this instant, the next frame sets them).
    /// A change forgets the accepted history, which was judged in the old frame.
    pub fn configure(&self, settings: GateSettings) {
        if let Ok(mut c) = self.shared.configured.try_lock()
            && c.settings != settings
        {
            c.settings = settings;
            c.generation += 1;
        }
    }

    /// The gate's settings now.
    pub fn gate_settings(&self) -> GateSettings {
        lock(&self.shared.configured).settings
    }

    /// Who drives each stream, and a second sender being refused (by [`Stream::index`]);
    /// `None` only if a source holds them this instant.
    pub fn try_senders(&self) -> Option<[StreamSenders; 3]> {
        try_copy(&self.shared.senders)
    }

    /// A source offers the head's newest sample: the gate judges it, and only an accepted one
    /// becomes the head's newest.
    pub fn publish_head(&self, sample: TrackerSample) {
        self.publish(Stream::Head, sample);
    }

    /// A source offers the wand's newest sample, judged like the head's.
    pub fn publish_wand(&self, sample: TrackerSample) {
        self.publish(Stream::Wand, sample);
    }

    fn publish(&self, stream: Stream, sample: TrackerSample) {
        let configured = *lock(&self.shared.configured);
        let (judged, senders) = {
            let mut state = lock(&self.shared.gate);
            let state = &mut *state;
            if state.generation != configured.generation {
                state.generation = configured.generation;
                state.gate.reset_history();
            }
            let judged = state.gate.judge(stream, sample, &configured.settings);
            let judged = judged.map(|mut accepted| {
                let n = &mut state.published[usize::from(stream == Stream::Wand)];
                *n += 1;
                accepted.seq = *n;
                accepted
            });
            let senders = state.gate.senders(stream, configured.settings.timeout);
            (judged, senders)
        };
        lock(&self.shared.senders)[stream.index()] = senders;
        match judged {
            Ok(mut accepted) => {
                let slot = match stream {
                    Stream::Wand => &self.shared.wand,
                    _ => &self.shared.latest,
                };
                accepted.stored = Instant::now();
                *lock(slot) = Some(accepted);
            }
            Err(refusal) => self.refused(stream, &sample, refusal),
        }
    }

    /// Counts a refused sample and logs it, at most once per [`LOG_INTERVAL`].
    fn refused(&self, stream: Stream, sample: &TrackerSample, refusal: Refusal) {
        self.shared.refusals[refusal.counter_index()].fetch_add(1, Ordering::AcqRel);
        let allowed = lock(&self.shared.refusal_log).allow(sample.arrived, LOG_INTERVAL);
        if let Some(held) = allowed {
            let at = sample
                .position
                .map(|p| {
                    format!(
                        " at ({:.3e}, {:.3e}, {:.3e}) (tracker units)",
                        p.x, p.y, p.z
                    )
                })
                .unwrap_or_default();
            tracing::warn!(
                "tracking: refused a {} sample from {}{at}: {}{}",
                stream.name(),
                sample.sender,
                refusal.describe(),
                held_back(held)
            );
        }
    }

    /// A source changes the buttons and analogs, as `from` sent them at `arrived`: only the
    /// sender driving the buttons may (others are counted as conflicting).
    pub fn update_controls(
        &self,
        from: SocketAddr,
        arrived: Instant,
        change: impl FnOnce(&mut Controls),
    ) {
        let settings = lock(&self.shared.configured).settings;
        let (admitted, senders) = {
            let mut state = lock(&self.shared.gate);
            let admitted = state.gate.admit_controls(from, arrived, &settings);
            let senders = state.gate.senders(Stream::Controls, settings.timeout);
            (admitted, senders)
        };
        lock(&self.shared.senders)[Stream::Controls.index()] = senders;
        match admitted {
            Ok(()) => change(&mut lock(&self.shared.controls)),
            Err(refusal) => {
                let sample = TrackerSample {
                    seq: 0,
                    arrived,
                    stored: arrived,
                    position: None,
                    orientation: None,
                    tracked: None,
                    sender: from,
                    sent: None,
                    jumped: false,
                };
                self.refused(Stream::Controls, &sample, refusal);
            }
        }
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
            gate: GateCounters::from_array(self.shared.refusals.each_ref().map(get)),
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
    /// Each recent sender's newest position and orientation (a pose may come in parts).
    parts: Vec<SenderParts>,
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
            parts: Vec::new(),
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

    /// Offers the pose `update` completes to the gate. A part the packet lacks (the position
    /// of an orientation-only packet) is the same sender's last one, if it arrived within the
    /// timeout; the "tracked" flag is this packet's own.
    fn store(&mut self, update: PoseUpdate, from: SocketAddr, arrived: Instant) {
        let timeout = self.feed.gate_settings().timeout;
        let index = match self.parts.iter().position(|p| p.sender == from) {
            Some(i) => i,
            None => {
                if self.parts.len() >= MAX_PART_SENDERS {
                    // Forget the sender heard least recently, never the head's own.
                    let owner = self.feed.try_senders().and_then(|s| s[0].owner);
                    let oldest = (0..self.parts.len())
                        .filter(|&i| Some(self.parts[i].sender) != owner)
                        .min_by_key(|&i| self.parts[i].heard);
                    if let Some(i) = oldest {
                        self.parts.swap_remove(i);
                    }
                }
                self.parts.push(SenderParts {
                    sender: from,
                    heard: arrived,
                    position: None,
                    orientation: None,
                });
                self.parts.len() - 1
            }
        };
        let parts = &mut self.parts[index];
        parts.heard = arrived;
        if let Some(p) = update.position {
            parts.position = Some((p, arrived));
        }
        let orientation = match (update.orientation, update.orientation_cave_axes) {
            (Some(q), _) => Some(TrackedOrientation::Tracker(q)),
            (None, Some(q)) => Some(TrackedOrientation::CaveAxes(q)),
            (None, None) => None,
        };
        if let Some(o) = orientation {
            parts.orientation = Some((o, arrived));
        }
        let recent = |at: Instant| arrived.saturating_duration_since(at) <= timeout;
        let sample = TrackerSample {
            seq: 0,
            arrived,
            stored: arrived,
            position: parts.position.filter(|&(_, at)| recent(at)).map(|(p, _)| p),
            orientation: parts
                .orientation
                .filter(|&(_, at)| recent(at))
                .map(|(o, _)| o),
            tracked: update.tracked,
            sender: from,
            // OSC carries no sample time (bundles' time tags say when to act, not when taken).
            sent: None,
            jumped: false,
        };
        self.feed.publish_head(sample);
    }
}

/// Most senders whose pose parts the OSC receiver keeps (the head's sender is never evicted).
const MAX_PART_SENDERS: usize = 8;

/// One sender's newest position and orientation, each with its arrival.
#[derive(Debug, Clone, Copy)]
struct SenderParts {
    sender: SocketAddr,
    heard: Instant,
    position: Option<(Vec3, Instant)>,
    orientation: Option<(TrackedOrientation, Instant)>,
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
    allowed_senders: Vec<IpAddr>,
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
        Ok(Self {
            feed,
            udp,
            allowed_senders: settings.allowed_senders.clone(),
        })
    }

    /// The senders allowed (empty: any).
    pub fn allowed_senders(&self) -> &[IpAddr] {
        &self.allowed_senders
    }

    /// The address the socket is bound to (with the port chosen when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.udp.local_addr()
    }

    pub fn feed(&self) -> &TrackerFeed {
        &self.feed
    }
}
