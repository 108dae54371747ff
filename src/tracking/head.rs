//! From the samples the gate accepted to the head pose a frame uses: calibration, One Euro
//! filter, clamping to the CAVE, loss of tracking, and the latency from a packet's arrival to
//! the frame using it.

use std::time::{Duration, Instant};

use glam::{Quat, Vec3};

use super::calibration::Calibration;
use super::filter::{OneEuro, OneEuroParams};
use super::gate::GateSettings;
use super::plausibility::PlausibilityLimits;
use super::receiver::{LOG_INTERVAL, LogLimiter, TrackedOrientation, TrackerSample, held_back};

/// How samples become head poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingSettings {
    pub calibration: Calibration,
    /// `None`: no filtering.
    pub filter: Option<OneEuroParams>,
    /// No packet for this long: tracking is lost (the head holds its last pose).
    pub timeout: Duration,
    /// What a head can do: the gate refuses samples beyond it in the receiver thread.
    pub plausibility: PlausibilityLimits,
    /// From the tracked body's origin to the midpoint of the eyes, in the body's calibrated
    /// frame (metres): the eyes are at `position + orientation · eye_offset`.
    pub eye_offset: Vec3,
}

impl TrackingSettings {
    /// What the receiver's gate needs to judge samples for a CAVE of box `bounds`.
    pub fn gate(&self, bounds: Option<(Vec3, Vec3)>) -> GateSettings {
        GateSettings {
            calibration: self.calibration,
            bounds,
            limits: self.plausibility,
            timeout: self.timeout,
        }
    }
}

impl Default for TrackingSettings {
    fn default() -> Self {
        Self {
            calibration: Calibration::default(),
            filter: Some(OneEuroParams::default()),
            timeout: Duration::from_millis(500),
            plausibility: PlausibilityLimits::default(),
            eye_offset: Vec3::ZERO,
        }
    }
}

/// Where tracking stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackingStatus {
    /// No packet yet.
    Waiting,
    Tracking,
    /// No accepted sample within the timeout: the head holds its last pose.
    Lost,
    /// The tracker says it cannot see the body (NatNet `tracked 0`, confirmed by the gate):
    /// the head holds.
    NotVisible,
}

impl TrackingStatus {
    pub fn describe(self) -> &'static str {
        match self {
            Self::Waiting => "waiting for packets",
            Self::Tracking => "tracking",
            Self::Lost => "tracking lost",
            Self::NotVisible => "tracking lost (tracker cannot see the head)",
        }
    }
}

/// A head pose in CAVE space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadPose {
    pub position: Vec3,
    /// `None` if the tracker sends positions only.
    pub orientation: Option<Quat>,
}

/// Figures over the last completed second.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrackingStats {
    /// Packets accepted per second (the tracker's rate as it arrives; frames may use fewer).
    pub rate_hz: f64,
    /// From a packet coming off the socket to the start of the frame that used it, ms.
    pub latency_avg_ms: f64,
    pub latency_max_ms: f64,
    /// The largest wait from a pose being ready (decoded and stored) to the frame that used it,
    /// as a fraction of that frame's interval: ≤ 1 means every pose was used by the first
    /// frame that started after it was ready.
    pub latency_max_frames: f64,
    /// The newest sample's latency (arrival to the frame using it), ms.
    pub latency_last_ms: f64,
    /// Positions clamped into the CAVE since start.
    pub clamped: u64,
    /// Times tracking was lost (no accepted sample within the timeout) since start.
    pub lost_events: u64,
}

#[derive(Debug, Clone, Copy, Default)]
struct Window {
    samples: u32,
    latency_sum_ms: f64,
    latency_max_ms: f64,
    latency_max_frames: f64,
}

/// The render loop's tracking state: call [`HeadTracker::update`] once per frame.
#[derive(Debug, Clone)]
pub struct HeadTracker {
    pub settings: TrackingSettings,
    status: TrackingStatus,
    last_seq: Option<u64>,
    lost_since: Option<Instant>,
    pose: Option<HeadPose>,
    position_filter: OneEuro,
    orientation_filter: OneEuro,
    last_frame: Option<Instant>,
    window_start: Option<Instant>,
    /// The newest sequence number when the window started.
    window_seq: Option<u64>,
    window: Window,
    stats: TrackingStats,
    clamp_log: LogLimiter,
    /// When the last accepted sample arrived (the filter's time step runs from it).
    last_accepted_arrival: Option<Instant>,
    /// The newest tracked body's pose in CAVE space before the eye offset (for calibrating it).
    body: Option<(Vec3, Quat)>,
}

impl HeadTracker {
    pub fn new(settings: TrackingSettings) -> Self {
        Self {
            settings,
            status: TrackingStatus::Waiting,
            last_seq: None,
            lost_since: None,
            pose: None,
            position_filter: OneEuro::default(),
            orientation_filter: OneEuro::default(),
            last_frame: None,
            window_start: None,
            window_seq: None,
            window: Window::default(),
            stats: TrackingStats::default(),
            clamp_log: LogLimiter::default(),
            last_accepted_arrival: None,
            body: None,
        }
    }

    /// Sets the filter; switching it on starts from the next sample (no stale history).
    pub fn set_filter(&mut self, filter: Option<OneEuroParams>) {
        if filter.is_some() && self.settings.filter.is_none() {
            self.position_filter.reset();
            self.orientation_filter.reset();
        }
        self.settings.filter = filter;
    }

    pub fn status(&self) -> TrackingStatus {
        self.status
    }

    /// The last pose (held while tracking is lost).
    pub fn pose(&self) -> Option<HeadPose> {
        self.pose
    }

    /// The newest tracked body's pose (CAVE space, before the eye offset).
    pub fn body(&self) -> Option<(Vec3, Quat)> {
        self.body
    }

    /// The eye offset that puts the eyes on the line of sight from the tracked body to
    /// `target` (a point the viewer looks straight at, e.g. the front wall's centre): its
    /// sideways and vertical parts are where `target` lies off the body's forward axis, its
    /// forward part stays `forward` (the line of sight fixes only those two).
    pub fn eye_offset_looking_at(body: (Vec3, Quat), target: Vec3, forward: f32) -> Vec3 {
        let (position, orientation) = body;
        let v = orientation.inverse() * (target - position);
        Vec3::new(v.x, v.y, forward)
    }

    pub fn stats(&self) -> TrackingStats {
        self.stats
    }

    /// Seconds since tracking was lost, if it is.
    pub fn lost_for(&self, now: Instant) -> Option<f64> {
        self.lost_since
            .map(|t| now.saturating_duration_since(t).as_secs_f64())
    }

    /// Takes the newest sample at the start of a frame (`now`); returns the pose this frame
    /// should use if there is a new one. `bounds` (min, max corners) is where the head may be:
    /// positions outside are clamped, with a warning.
    pub fn update(
        &mut self,
        sample: Option<TrackerSample>,
        now: Instant,
        bounds: Option<(Vec3, Vec3)>,
    ) -> Option<HeadPose> {
        let frame_interval = self.last_frame.map(|t| now.saturating_duration_since(t));
        self.last_frame = Some(now);
        self.roll_window(now);

        let fresh = sample.filter(|s| Some(s.seq) != self.last_seq);
        let Some(sample) = fresh else {
            self.check_timeout(now);
            return None;
        };
        self.last_seq = Some(sample.seq);
        self.record_latency(&sample, now, frame_interval);

        if sample.tracked == Some(false) {
            // The gate confirmed it: the tracker cannot see the head.
            self.set_status(TrackingStatus::NotVisible, now);
            return None;
        }
        let Some(raw_position) = sample.position else {
            // An orientation without a (recent) position: nothing to place, and no tracking.
            self.check_timeout(now);
            return None;
        };
        let (position, orientation) = self.calibrated_eyes(raw_position, sample.orientation);
        if !position.is_finite() || orientation.is_some_and(|q| !q.is_finite()) {
            return None; // the gate refuses these; a second net
        }
        let dt = self.last_accepted_arrival.map_or(0.0, |t| {
            sample.arrived.saturating_duration_since(t).as_secs_f32()
        });
        self.last_accepted_arrival = Some(sample.arrived);
        if self.status != TrackingStatus::Tracking || sample.jumped {
            // Fresh start, resuming after a loss, or a confirmed jump: no smoothing from the
            // stale pose.
            self.position_filter.reset();
            self.orientation_filter.reset();
            self.set_status(TrackingStatus::Tracking, now);
        }
        let mut position = position;
        let mut orientation = orientation;
        if let Some(params) = self.settings.filter {
            position = self
                .position_filter
                .filter(position.extend(0.0), dt, &params)
                .truncate();
            orientation = orientation.map(|q| self.orientation_filter.filter_quat(q, dt, &params));
        }
        let position = self.clamped(position, bounds, now);
        // The orientation is this sample's: a tracker that stopped sending one has none.
        let pose = HeadPose {
            position,
            orientation,
        };
        self.pose = Some(pose);
        Some(pose)
    }

    /// Counts a fresh sample's latency (arrival to this frame, and the wait from its being
    /// stored in frames of `frame_interval`) into the window's figures.
    fn record_latency(
        &mut self,
        sample: &TrackerSample,
        now: Instant,
        frame_interval: Option<Duration>,
    ) {
        let latency = now.saturating_duration_since(sample.arrived);
        let latency_ms = latency.as_secs_f64() * 1e3;
        self.stats.latency_last_ms = latency_ms;
        self.window.samples += 1;
        self.window.latency_sum_ms += latency_ms;
        self.window.latency_max_ms = self.window.latency_max_ms.max(latency_ms);
        if let Some(interval) = frame_interval.filter(|i| !i.is_zero()) {
            let waited = now.saturating_duration_since(sample.stored);
            let frames = waited.as_secs_f64() / interval.as_secs_f64();
            self.window.latency_max_frames = self.window.latency_max_frames.max(frames);
        }
    }

    /// The eyes' position and the orientation in CAVE space from a raw sample (a
    /// non-unit orientation is made non-finite, for the gate to refuse); remembers the
    /// tracked body's pose.
    fn calibrated_eyes(
        &mut self,
        raw_position: Vec3,
        raw_orientation: Option<TrackedOrientation>,
    ) -> (Vec3, Option<Quat>) {
        let cal = &self.settings.calibration;
        let position = cal.position(raw_position);
        let orientation = raw_orientation.map(|o| match o {
            TrackedOrientation::Tracker(q) => cal.orientation(q),
            TrackedOrientation::CaveAxes(q) => cal.orientation_in_cave_axes(q),
        });
        let orientation = match orientation {
            Some(q) => match super::plausibility::unit_quaternion(q) {
                Some(unit) => Some(unit),
                None => Some(Quat::from_xyzw(f32::NAN, 0.0, 0.0, 0.0)), // refused below
            },
            None => None,
        };
        if let Some(q) = orientation.filter(|q| q.is_finite() && position.is_finite()) {
            self.body = Some((position, q));
        }
        // The tracked body's origin is not between the eyes: move to them along the body's
        // own axes (unrotated while the tracker sends positions only).
        let position = position + orientation.unwrap_or(Quat::IDENTITY) * self.settings.eye_offset;
        (position, orientation)
    }

    /// `position` clamped into `bounds` (counted, with a warning, where it was outside).
    fn clamped(&mut self, position: Vec3, bounds: Option<(Vec3, Vec3)>, now: Instant) -> Vec3 {
        let Some((min, max)) = bounds else {
            return position;
        };
        let clamped = position.clamp(min, max.max(min));
        if clamped != position {
            self.stats.clamped += 1;
            if let Some(held) = self.clamp_log.allow(now, LOG_INTERVAL) {
                tracing::warn!(
                    "tracked head ({:.3}, {:.3}, {:.3}) m is outside the CAVE: clamped to \
                     ({:.3}, {:.3}, {:.3}){}",
                    position.x,
                    position.y,
                    position.z,
                    clamped.x,
                    clamped.y,
                    clamped.z,
                    held_back(held)
                );
            }
            return clamped;
        }
        position
    }

    /// Lost once the newest accepted sample is older than the timeout (the gate publishes
    /// only accepted ones: a stream of refused samples is no tracking).
    fn check_timeout(&mut self, now: Instant) {
        if let Some(arrival) = self.last_accepted_arrival
            && self.status == TrackingStatus::Tracking
            && now.saturating_duration_since(arrival) > self.settings.timeout
        {
            self.set_status(TrackingStatus::Lost, now);
        }
    }

    fn set_status(&mut self, status: TrackingStatus, now: Instant) {
        if status == self.status {
            return;
        }
        match status {
            TrackingStatus::Tracking => {
                match self.lost_for(now) {
                    Some(s) => tracing::info!("tracking resumed after {s:.1} s"),
                    None => tracing::info!("tracking: first packet"),
                }
                self.lost_since = None;
            }
            TrackingStatus::Lost => {
                tracing::warn!(
                    "tracking lost: no packet for {:.2} s; the head holds its last pose",
                    self.settings.timeout.as_secs_f64()
                );
                self.lost_since = Some(now);
                self.stats.lost_events += 1;
            }
            TrackingStatus::NotVisible => {
                tracing::warn!("tracking lost: the tracker reports the head as not tracked");
                self.lost_since = Some(now);
            }
            TrackingStatus::Waiting => {}
        }
        self.status = status;
    }

    fn roll_window(&mut self, now: Instant) {
        let start = *self.window_start.get_or_insert(now);
        let elapsed = now.saturating_duration_since(start);
        if elapsed < Duration::from_secs(1) {
            return;
        }
        let w = self.window;
        let packets = match (self.last_seq, self.window_seq) {
            (Some(now), Some(then)) => now.saturating_sub(then),
            (Some(now), None) => now,
            _ => 0,
        };
        self.window_seq = self.last_seq;
        self.stats = TrackingStats {
            rate_hz: packets as f64 / elapsed.as_secs_f64(),
            latency_avg_ms: if w.samples > 0 {
                w.latency_sum_ms / f64::from(w.samples)
            } else {
                0.0
            },
            latency_max_ms: w.latency_max_ms,
            latency_max_frames: w.latency_max_frames,
            latency_last_ms: self.stats.latency_last_ms,
            clamped: self.stats.clamped,
            lost_events: self.stats.lost_events,
        };
        self.window = Window::default();
        self.window_start = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::SocketAddr;

    fn sample(seq: u64, arrived: Instant, p: Vec3) -> TrackerSample {
        TrackerSample {
            seq,
            arrived,
            stored: arrived,
            position: Some(p),
            orientation: None,
            tracked: None,
            sender: SocketAddr::from(([127, 0, 0, 1], 9)),
            sent: None,
            jumped: false,
        }
    }

    fn unfiltered() -> HeadTracker {
        HeadTracker::new(TrackingSettings {
            filter: None,
            ..TrackingSettings::default()
        })
    }

    #[test]
    fn lost_after_the_timeout_and_holds_then_resumes() {
        let t0 = Instant::now();
        let mut t = unfiltered();
        let p = Vec3::new(0.1, 1.6, 0.2);
        assert_eq!(
            t.update(Some(sample(1, t0, p)), t0, None)
                .map(|h| h.position),
            Some(p)
        );
        assert_eq!(t.status(), TrackingStatus::Tracking);
        // The same sample again (no new packet) gives nothing new.
        let later = t0 + Duration::from_millis(400);
        assert_eq!(t.update(Some(sample(1, t0, p)), later, None), None);
        assert_eq!(t.status(), TrackingStatus::Tracking);
        let later = t0 + Duration::from_millis(600);
        assert_eq!(t.update(Some(sample(1, t0, p)), later, None), None);
        assert_eq!(t.status(), TrackingStatus::Lost);
        assert_eq!(t.pose().map(|h| h.position), Some(p));
        let q = Vec3::new(-0.2, 1.7, 0.0);
        let back = t0 + Duration::from_millis(900);
        assert_eq!(
            t.update(Some(sample(2, back, q)), back, None)
                .map(|h| h.position),
            Some(q)
        );
        assert_eq!(t.status(), TrackingStatus::Tracking);
    }

    #[test]
    fn outside_positions_are_clamped_and_counted() {
        let t0 = Instant::now();
        let mut t = unfiltered();
        let bounds = (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0));
        // 0.3 m outside: within the gate's 0.5 m margin (farther is refused there), clamped.
        let got = t.update(
            Some(sample(1, t0, Vec3::new(1.3, 1.0, -0.5))),
            t0,
            Some(bounds),
        );
        assert_eq!(got.map(|h| h.position), Some(Vec3::new(1.0, 1.0, -0.5)));
        assert_eq!(t.stats.clamped, 1);
    }
}
