//! The gate every tracker sample passes in its receiver thread, for every source and stream
//! (head, wand, buttons): one sender drives a stream at a time, each sample is judged on its
//! own, jumps and "not tracked" claims need agreeing samples over time, and nothing is carried
//! forward from a single packet.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};

use super::calibration::Calibration;
use super::plausibility::{
    CONFIRMATION_TIME, Candidate, Implausible, JUMP_CONFIRMATIONS, PlausibilityGate,
    PlausibilityLimits, Verdict, unit_quaternion,
};
use super::receiver::{SentAt, TrackedOrientation, TrackerSample};

/// A hand moves and turns faster than a head: the wand's limits are the head's times this.
const WAND_LIMIT_FACTOR: f32 = 2.0;
/// "Not tracked" claims further apart than this are separate claims, not one confirming the
/// other (a tracker at 30 Hz sends one every 33 ms).
const CLAIM_GAP: Duration = Duration::from_millis(100);

/// What the gate needs to judge samples in CAVE space; the render loop sets it
/// ([`super::TrackerFeed::configure`]) and changes it when the calibration, the CAVE or the
/// limits change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateSettings {
    pub calibration: Calibration,
    /// Where a head may be (the CAVE's box, min and max corners); `None`: anywhere within
    /// [`super::plausibility::MAX_TRACKED_DISTANCE_M`].
    pub bounds: Option<(Vec3, Vec3)>,
    pub limits: PlausibilityLimits,
    /// A sender silent this long gives up its streams; a component of a pose (an orientation
    /// sent alone) older than this is forgotten.
    pub timeout: Duration,
}

impl Default for GateSettings {
    fn default() -> Self {
        Self {
            calibration: Calibration::default(),
            bounds: None,
            limits: PlausibilityLimits::default(),
            timeout: Duration::from_millis(500),
        }
    }
}

/// The streams a source feeds, each with its own sender and history.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    Head,
    Wand,
    /// Buttons and analogs.
    Controls,
}

impl Stream {
    pub const ALL: [Stream; 3] = [Stream::Head, Stream::Wand, Stream::Controls];

    pub fn name(self) -> &'static str {
        match self {
            Self::Head => "head",
            Self::Wand => "wand",
            Self::Controls => "buttons",
        }
    }

    /// The stream's place in per-stream arrays (head 0, wand 1, buttons 2).
    pub fn index(self) -> usize {
        self as usize
    }
}

/// Why the gate refused a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refusal {
    /// Another sender drives this stream.
    Conflicting,
    /// Not finite, or outside the CAVE by more than the margin.
    Implausible(Implausible),
    /// Faster than a head moves from the accepted pose, not (yet) confirmed as a jump.
    UnconfirmedJump(Implausible),
    /// "Not tracked" (a flag or an empty frame), not (yet) confirmed.
    UnconfirmedLoss,
    /// Taken before the newest sample accepted from the same sender (its clock or frame
    /// counter says so): a reordered or replayed packet.
    Stale,
}

impl Refusal {
    pub fn describe(self) -> String {
        match self {
            Self::Conflicting => "from a second sender while the first still sends".into(),
            Self::Implausible(why) => why.describe(),
            Self::UnconfirmedJump(why) => format!("{}, not confirmed", why.describe()),
            Self::UnconfirmedLoss => "\"not tracked\", not confirmed".into(),
            Self::Stale => "older than the newest sample from the same sender".into(),
        }
    }
}

/// Samples the gate refused, by reason, since the source started (all streams).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GateCounters {
    /// From a second sender while the stream's sender still sends.
    pub conflicting: u64,
    /// Not finite, or outside the CAVE by more than the margin.
    pub implausible: u64,
    /// A jump not (yet) confirmed by agreeing samples over time.
    pub unconfirmed_jump: u64,
    /// A "not tracked" claim not (yet) confirmed.
    pub unconfirmed_loss: u64,
    /// Older than the newest sample from the same sender.
    pub stale: u64,
}

impl Refusal {
    /// The refusal's counter in [`GateCounters::as_array`] order.
    pub fn counter_index(self) -> usize {
        match self {
            Self::Conflicting => 0,
            Self::Implausible(_) => 1,
            Self::UnconfirmedJump(_) => 2,
            Self::UnconfirmedLoss => 3,
            Self::Stale => 4,
        }
    }
}

impl GateCounters {
    pub fn count(&mut self, refusal: Refusal) {
        let counter = match refusal {
            Refusal::Conflicting => &mut self.conflicting,
            Refusal::Implausible(_) => &mut self.implausible,
            Refusal::UnconfirmedJump(_) => &mut self.unconfirmed_jump,
            Refusal::UnconfirmedLoss => &mut self.unconfirmed_loss,
            Refusal::Stale => &mut self.stale,
        };
        *counter += 1;
    }

    /// How many reasons there are.
    pub const COUNT: usize = 5;

    /// From the counts in [`Refusal::counter_index`] order.
    pub fn from_array(
        [
            conflicting,
            implausible,
            unconfirmed_jump,
            unconfirmed_loss,
            stale,
        ]: [u64; Self::COUNT],
    ) -> Self {
        Self {
            conflicting,
            implausible,
            unconfirmed_jump,
            unconfirmed_loss,
            stale,
        }
    }

    /// The counts with their reasons' names, in [`Refusal::counter_index`] order.
    pub fn by_reason(&self) -> [(&'static str, u64); Self::COUNT] {
        [
            ("conflicting", self.conflicting),
            ("implausible", self.implausible),
            ("unconfirmed jump", self.unconfirmed_jump),
            ("unconfirmed not-tracked", self.unconfirmed_loss),
            ("stale", self.stale),
        ]
    }

    /// "0 conflicting, 0 implausible, …" (the stats line, the panel and the bench report).
    pub fn describe(&self) -> String {
        self.by_reason()
            .map(|(reason, n)| format!("{n} {reason}"))
            .join(", ")
    }

    pub fn total(&self) -> u64 {
        self.by_reason().iter().map(|(_, n)| n).sum()
    }
}

/// Who drives a stream: its sender, and the newest second sender refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StreamSenders {
    pub owner: Option<SocketAddr>,
    pub conflicting: Option<SocketAddr>,
}

/// The sender driving a stream and when it was last heard.
#[derive(Debug, Clone, Copy)]
struct Owner {
    sender: SocketAddr,
    heard: Instant,
}

/// "Not tracked" claims in a row: the first's and the newest's arrival, how many.
#[derive(Debug, Clone, Copy)]
struct Claims {
    since: Instant,
    newest: Instant,
    count: u32,
}

impl Claims {
    /// [`JUMP_CONFIRMATIONS`] claims spanning [`CONFIRMATION_TIME`].
    fn confirmed(&self) -> bool {
        self.count >= JUMP_CONFIRMATIONS
            && self.newest.saturating_duration_since(self.since) >= CONFIRMATION_TIME
    }
}

/// A run of claims with one more at `at`; a claim more than [`CLAIM_GAP`] after the run's
/// newest starts a new run.
fn extend(run: Option<Claims>, at: Instant) -> Claims {
    match run {
        Some(c) if at.saturating_duration_since(c.newest) <= CLAIM_GAP => Claims {
            newest: at,
            count: c.count + 1,
            ..c
        },
        _ => Claims {
            since: at,
            newest: at,
            count: 1,
        },
    }
}

/// One stream's gate.
#[derive(Debug, Clone, Default)]
struct StreamGate {
    owner: Option<Owner>,
    /// The newest second sender refused, and when.
    conflicting: Option<(SocketAddr, Instant)>,
    plausibility: PlausibilityGate,
    /// "Not tracked" claims being confirmed (samples without a flag leave them be).
    loss: Option<Claims>,
    /// The stream is published as not tracked (a confirmed loss): the next pose starts afresh.
    lost: bool,
    /// The sender's time of the newest sample not refused as stale.
    newest_sent: Option<SentAt>,
    /// Stale samples in a row (a sender whose clock or counter restarted sends only these).
    behind: Option<Claims>,
}

impl StreamGate {
    /// Whether `from` may drive the stream now: the sender established first keeps it until
    /// it has been silent for `timeout`.
    fn admit(
        &mut self,
        stream: Stream,
        from: SocketAddr,
        at: Instant,
        timeout: Duration,
    ) -> Result<(), Refusal> {
        match self.owner {
            // Back after a silence: it may have restarted (its counter from zero), and a slow
            // tracker's restart would never look confirmed against a time from before.
            Some(o) if o.sender == from && at.saturating_duration_since(o.heard) > timeout => {
                self.newest_sent = None;
                self.behind = None;
            }
            Some(o) if o.sender == from => {}
            Some(o) if at.saturating_duration_since(o.heard) <= timeout => {
                self.conflicting = Some((from, at));
                return Err(Refusal::Conflicting);
            }
            previous => {
                match previous {
                    Some(o) => tracing::info!(
                        "tracking: the {} stream now comes from {from} ({} silent for {:.2} s)",
                        stream.name(),
                        o.sender,
                        at.saturating_duration_since(o.heard).as_secs_f64()
                    ),
                    None => {
                        tracing::info!("tracking: the {} stream comes from {from}", stream.name())
                    }
                }
                // A new sender's samples are judged afresh, not against another's history.
                *self = Self {
                    conflicting: self.conflicting.filter(|(c, _)| *c != from),
                    ..Self::default()
                };
            }
        }
        self.owner = Some(Owner {
            sender: from,
            heard: at,
        });
        Ok(())
    }

    /// Judges a pose sample from the stream's sender; what to publish if it passes.
    fn judge_pose(
        &mut self,
        sample: TrackerSample,
        settings: &GateSettings,
        limits: &PlausibilityLimits,
    ) -> Result<TrackerSample, Refusal> {
        match sample.tracked {
            Some(false) => return self.judge_loss(sample),
            Some(true) => self.loss = None,
            // No flag (a bridge may send it in a packet of its own): claims stay, until they
            // stop coming.
            None => {
                if self
                    .loss
                    .is_some_and(|c| sample.arrived.saturating_duration_since(c.newest) > CLAIM_GAP)
                {
                    self.loss = None;
                }
                if self.lost && self.loss.is_some() {
                    // Confirmed lost and still said so: a pose between the claims is stale.
                    return Ok(TrackerSample {
                        position: None,
                        orientation: None,
                        tracked: Some(false),
                        ..sample
                    });
                }
            }
        }
        let Some(raw) = sample.position else {
            // An orientation before any position: nothing to place, nothing to judge.
            return Ok(sample);
        };
        let cal = &settings.calibration;
        let orientation = sample.orientation.map(|o| {
            let q = match o {
                TrackedOrientation::Tracker(q) => cal.orientation(q),
                TrackedOrientation::CaveAxes(q) => cal.orientation_in_cave_axes(q),
            };
            // A quaternion without a direction is refused as not finite.
            unit_quaternion(q).unwrap_or(Quat::from_xyzw(f32::NAN, 0.0, 0.0, 0.0))
        });
        let candidate = Candidate {
            position: cal.position(raw),
            orientation,
            arrived: sample.arrived,
        };
        if self.lost {
            // Seen again after a confirmed loss: judged by the bounds alone.
            self.plausibility.reset();
        }
        match self.plausibility.judge(candidate, settings.bounds, limits) {
            Verdict::Accept => {
                self.lost = false;
                Ok(sample)
            }
            Verdict::AcceptJump => {
                self.lost = false;
                Ok(TrackerSample {
                    jumped: true,
                    ..sample
                })
            }
            Verdict::Unconfirmed(why) => Err(Refusal::UnconfirmedJump(why)),
            Verdict::Refuse(why) => Err(Refusal::Implausible(why)),
        }
    }

    /// Refuses a sample taken before the newest one accepted from this sender, unless such
    /// samples keep coming for [`CONFIRMATION_TIME`] (the sender's clock or frame counter
    /// restarted, or wrapped at midnight: it is followed from there). Only an accepted sample
    /// moves the newest time on ([`Self::accepted_sent`]): a refused one (out of bounds, say)
    /// with a time far ahead cannot make the tracker's own samples stale.
    fn judge_sent(&mut self, stream: Stream, sample: &TrackerSample) -> Result<(), Refusal> {
        let Some(sent) = sample.sent else {
            return Ok(());
        };
        if let Some(newest) = self.newest_sent
            && sent.is_before(newest)
        {
            let run = extend(self.behind, sample.arrived);
            self.behind = Some(run);
            if !run.confirmed() {
                return Err(Refusal::Stale);
            }
            tracing::info!(
                "tracking: the {} stream's sender {} restarted its clock or frame counter \
                 ({newest:?} before, {sent:?} now)",
                stream.name(),
                sample.sender
            );
        }
        Ok(())
    }

    /// The sample was accepted: its time is the newest.
    fn accepted_sent(&mut self, sent: Option<SentAt>) {
        if sent.is_some() {
            self.newest_sent = sent;
            self.behind = None;
        }
    }

    /// A "not tracked" sample: published once [`JUMP_CONFIRMATIONS`] claims, each within
    /// [`CLAIM_GAP`] of the one before, span [`CONFIRMATION_TIME`].
    fn judge_loss(&mut self, sample: TrackerSample) -> Result<TrackerSample, Refusal> {
        let claims = extend(self.loss, sample.arrived);
        self.loss = Some(claims);
        if self.lost || claims.confirmed() {
            self.lost = true;
            Ok(TrackerSample {
                position: None,
                orientation: None,
                ..sample
            })
        } else {
            Err(Refusal::UnconfirmedLoss)
        }
    }
}

/// The gates of a source's three streams.
#[derive(Debug, Clone, Default)]
pub struct SourceGate {
    streams: [StreamGate; 3],
}

impl SourceGate {
    /// Judges a head or wand sample; the sample to publish, or why not.
    pub fn judge(
        &mut self,
        stream: Stream,
        sample: TrackerSample,
        settings: &GateSettings,
    ) -> Result<TrackerSample, Refusal> {
        let gate = &mut self.streams[stream.index()];
        gate.admit(stream, sample.sender, sample.arrived, settings.timeout)
            .and_then(|()| {
                let limits = match stream {
                    Stream::Wand => PlausibilityLimits {
                        max_speed_mps: settings.limits.max_speed_mps * WAND_LIMIT_FACTOR,
                        max_turn_dps: settings.limits.max_turn_dps * WAND_LIMIT_FACTOR,
                        ..settings.limits
                    },
                    _ => settings.limits,
                };
                gate.judge_sent(stream, &sample)?;
                let sent = sample.sent;
                let accepted = gate.judge_pose(sample, settings, &limits)?;
                gate.accepted_sent(sent);
                Ok(accepted)
            })
    }

    /// Whether `from` may change the buttons now.
    pub fn admit_controls(
        &mut self,
        from: SocketAddr,
        at: Instant,
        settings: &GateSettings,
    ) -> Result<(), Refusal> {
        self.streams[Stream::Controls.index()].admit(Stream::Controls, from, at, settings.timeout)
    }

    /// Forgets every stream's history (the calibration or the CAVE changed: the accepted poses
    /// are in another frame); senders keep their streams.
    pub fn reset_history(&mut self) {
        for gate in &mut self.streams {
            gate.plausibility.reset();
            gate.loss = None;
            gate.behind = None;
        }
    }

    /// Who drives `stream`, and a second sender refused within `timeout` of the owner's
    /// newest sample.
    pub fn senders(&self, stream: Stream, timeout: Duration) -> StreamSenders {
        let gate = &self.streams[stream.index()];
        let recent = |at: Instant| {
            gate.owner
                .is_some_and(|o| o.heard.saturating_duration_since(at) <= timeout)
        };
        StreamSenders {
            owner: gate.owner.map(|o| o.sender),
            conflicting: gate
                .conflicting
                .filter(|&(c, at)| recent(at) && Some(c) != gate.owner.map(|o| o.sender))
                .map(|(c, _)| c),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A gate and its refusals by reason (the feed counts them in the app).
    #[derive(Default)]
    struct Counting {
        gate: SourceGate,
        counters: GateCounters,
    }

    impl Counting {
        fn judge(
            &mut self,
            stream: Stream,
            sample: TrackerSample,
            settings: &GateSettings,
        ) -> Result<TrackerSample, Refusal> {
            let judged = self.gate.judge(stream, sample, settings);
            if let Err(refusal) = judged {
                self.counters.count(refusal);
            }
            judged
        }
    }

    fn sample(from: u16, ms: u64, t0: Instant, position: Option<Vec3>) -> TrackerSample {
        TrackerSample {
            seq: 0,
            arrived: t0 + Duration::from_millis(ms),
            stored: t0,
            position,
            orientation: None,
            tracked: None,
            sender: SocketAddr::from(([127, 0, 0, 1], from)),
            sent: None,
            jumped: false,
        }
    }

    #[test]
    fn not_tracked_in_packets_of_its_own_is_confirmed_across_poses() {
        // A bridge sending position and "tracked 0" as separate packets, 8 ms apart.
        let t0 = Instant::now();
        let settings = GateSettings::default();
        let mut gate = Counting::default();
        let p = Some(Vec3::new(0.0, 1.6, 0.0));
        let mut confirmed = None;
        for tick in 0..8u64 {
            assert!(
                gate.judge(Stream::Head, sample(1, tick * 8, t0, p), &settings)
                    .is_ok()
            );
            let lost = TrackerSample {
                tracked: Some(false),
                ..sample(1, tick * 8 + 1, t0, None)
            };
            if gate.judge(Stream::Head, lost, &settings).is_ok() && confirmed.is_none() {
                confirmed = Some(tick);
            }
        }
        // Claims at 1, 9, …, 41 ms: the sixth spans 40 ms.
        assert_eq!(confirmed, Some(5));
    }

    #[test]
    fn the_first_sender_keeps_a_stream_until_silent() {
        let t0 = Instant::now();
        let settings = GateSettings::default();
        let mut gate = Counting::default();
        let p = Some(Vec3::new(0.0, 1.6, 0.0));
        assert!(
            gate.judge(Stream::Head, sample(1, 0, t0, p), &settings)
                .is_ok()
        );
        assert_eq!(
            gate.judge(Stream::Head, sample(2, 1, t0, p), &settings),
            Err(Refusal::Conflicting)
        );
        // The wand is another stream: the second sender may drive it.
        assert!(
            gate.judge(Stream::Wand, sample(2, 1, t0, p), &settings)
                .is_ok()
        );
        // Sender 1 silent for longer than the timeout: sender 2 takes the head.
        assert!(
            gate.judge(Stream::Head, sample(2, 502, t0, p), &settings)
                .is_ok()
        );
        assert_eq!(
            gate.judge(Stream::Head, sample(1, 503, t0, p), &settings),
            Err(Refusal::Conflicting)
        );
        assert_eq!(gate.counters.conflicting, 2);
        let s = gate.gate.senders(Stream::Head, settings.timeout);
        assert_eq!(s.owner.map(|a| a.port()), Some(2));
        assert_eq!(s.conflicting.map(|a| a.port()), Some(1));
    }

    #[test]
    fn not_tracked_needs_confirmation_over_time() {
        let t0 = Instant::now();
        let settings = GateSettings::default();
        let mut gate = Counting::default();
        let p = Some(Vec3::new(0.0, 1.6, 0.0));
        let lost = |ms| TrackerSample {
            tracked: Some(false),
            ..sample(1, ms, t0, None)
        };
        assert!(
            gate.judge(Stream::Head, sample(1, 0, t0, p), &settings)
                .is_ok()
        );
        // One claim, then poses: nothing published; 100 ms on, the claim is forgotten.
        assert_eq!(
            gate.judge(Stream::Head, lost(8), &settings),
            Err(Refusal::UnconfirmedLoss)
        );
        for ms in [16, 120] {
            let pose = gate.judge(Stream::Head, sample(1, ms, t0, p), &settings);
            assert_eq!(pose.map(|s| s.position), Ok(p));
        }
        // A burst of claims within a millisecond: still nothing.
        for _ in 0..10 {
            assert!(gate.judge(Stream::Head, lost(121), &settings).is_err());
        }
        // Claims for 40 ms: the loss is published, without a pose.
        let mut published = None;
        for ms in (129..=161).step_by(8) {
            published = gate.judge(Stream::Head, lost(ms), &settings).ok();
        }
        let published = published.expect("confirmed");
        assert_eq!((published.tracked, published.position), (Some(false), None));
        // A pose between further claims is stale: published as not tracked.
        let stale = gate.judge(Stream::Head, sample(1, 165, t0, p), &settings);
        assert_eq!(stale.map(|s| s.tracked), Ok(Some(false)));
        // Claims stopped for longer than the gap: seen again, far away, judged afresh.
        let far = Some(Vec3::new(1.5, 1.6, 0.0));
        let seen = gate.judge(Stream::Head, sample(1, 270, t0, far), &settings);
        assert_eq!(seen.map(|s| s.position), Ok(far));
        // The first claim, the burst of ten and four before the fifth at 40 ms.
        assert_eq!(gate.counters.unconfirmed_loss, 1 + 10 + 4);
    }

    #[test]
    fn a_sample_older_than_the_newest_is_stale_until_the_clock_restarted() {
        let t0 = Instant::now();
        let settings = GateSettings::default();
        let mut gate = Counting::default();
        let p = Some(Vec3::new(0.0, 1.6, 0.0));
        let at = |ms: u64, frame: u64| TrackerSample {
            sent: Some(SentAt::Frame(frame)),
            ..sample(1, ms, t0, p)
        };
        for (ms, frame) in [(0, 100), (8, 101), (16, 103)] {
            assert!(gate.judge(Stream::Head, at(ms, frame), &settings).is_ok());
        }
        // Reordered (frame 102 after 103) and replayed (frame 50): stale.
        assert_eq!(
            gate.judge(Stream::Head, at(17, 102), &settings),
            Err(Refusal::Stale)
        );
        assert_eq!(
            gate.judge(Stream::Head, at(18, 50), &settings),
            Err(Refusal::Stale)
        );
        // The same frame again (a duplicate) is not older.
        assert!(gate.judge(Stream::Head, at(20, 103), &settings).is_ok());
        // Seconds and frames are different clocks: never compared.
        let secs = TrackerSample {
            sent: Some(SentAt::Seconds(1.0)),
            ..sample(1, 24, t0, p)
        };
        assert!(gate.judge(Stream::Head, secs, &settings).is_ok());
        // The tracker restarted: frames from 0 again, every 8 ms. Refused until they have
        // kept coming for 40 ms, then followed.
        let mut gate = Counting::default();
        assert!(gate.judge(Stream::Head, at(0, 90_000), &settings).is_ok());
        let verdicts: Vec<bool> = (0..8u64)
            .map(|i| {
                gate.judge(Stream::Head, at(100 + 8 * i, i), &settings)
                    .is_ok()
            })
            .collect();
        assert_eq!(
            verdicts,
            [false, false, false, false, false, true, true, true]
        );
        assert_eq!(gate.counters.stale, 5);
        // Another sender's clock is its own: a new owner starts afresh.
        let other = TrackerSample {
            sent: Some(SentAt::Frame(1)),
            ..sample(2, 1000, t0, p)
        };
        assert!(gate.judge(Stream::Head, other, &settings).is_ok());
        // A refused sample (a kilometre away) with a frame far ahead, every 30 ms, under the
        // tracker's address: it moves nothing on, the tracker's frames stay accepted.
        let mut gate = Counting::default();
        for i in 0..20u64 {
            assert!(
                gate.judge(Stream::Head, at(8 * i, 10 + i), &settings)
                    .is_ok()
            );
            if i % 4 == 0 {
                let future = TrackerSample {
                    sent: Some(SentAt::Frame(u64::from(u32::MAX))),
                    ..sample(1, 8 * i + 1, t0, Some(Vec3::new(1000.0, 1.6, 0.0)))
                };
                assert!(gate.judge(Stream::Head, future, &settings).is_err());
            }
        }
        assert_eq!(gate.counters.stale, 0);
        // The same tracker silent for longer than the timeout, back with its counter from
        // zero at 5 Hz (each frame 200 ms apart): followed at once.
        assert!(gate.judge(Stream::Head, at(2000, 0), &settings).is_ok());
        assert!(gate.judge(Stream::Head, at(2200, 1), &settings).is_ok());
    }
}
