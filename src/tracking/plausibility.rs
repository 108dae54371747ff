//! Plausibility of one stream's samples: inside the CAVE (with a margin), no faster than a head
//! moves, finite throughout; a jump only when agreeing samples confirm it over time.

use std::time::Instant;

use glam::{DQuat, DVec3, Quat, Vec3};

/// Limits of a plausible head (`[tracking.plausibility]` sets them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlausibilityLimits {
    /// How far outside the CAVE's box a sample may be, metres (closer ones are clamped).
    pub outside_margin_m: f32,
    /// Fastest head movement accepted, m/s.
    pub max_speed_mps: f32,
    /// Fastest head turn accepted, degrees per second.
    pub max_turn_dps: f32,
}

impl Default for PlausibilityLimits {
    fn default() -> Self {
        // A head moves at up to ~3 m/s and turns at up to ~800°/s (saccadic head turns peak
        // there); twice that leaves room for tracker noise and a stumble while still refusing
        // a single flipped bit. 0.5 m: a participant leaning out of an open CAVE side.
        Self {
            outside_margin_m: 0.5,
            max_speed_mps: 6.0,
            max_turn_dps: 1600.0,
        }
    }
}

/// Farther than this from the CAVE's origin on any axis is never a head, whatever the walls
/// (a single wall leaves its normal axis unbounded), metres.
pub const MAX_TRACKED_DISTANCE_M: f64 = 1000.0;
/// Jitter allowed on top of the speed limit (two packets a microsecond apart still differ by
/// the tracker's noise), metres and radians.
const JITTER_M: f64 = 0.02;
const JITTER_RAD: f64 = 0.02;
/// Timing jitter allowed on top of the time between two samples: packets of a 120 Hz tracker
/// that arrive 2 ms apart (±3 ms of network jitter) still carry 8 ms of movement, seconds.
const JITTER_S: f64 = 0.006;
/// Consecutive samples that agree with one another (each plausible from the one before) that
/// make a claim real (a jump: a tracker re-homed or a calibration changed; "not tracked"): at
/// least this many, spanning at least [`CONFIRMATION_TIME`]. Counting samples alone would let a
/// sender at 1 200 packets/s confirm anything in 2 ms; the time makes a burst count as one.
pub const JUMP_CONFIRMATIONS: u32 = 3;
/// The least time from the first to the last sample confirming a claim: six samples of a
/// 120 Hz tracker, a head held 40 ms on a real jump.
pub const CONFIRMATION_TIME: std::time::Duration = std::time::Duration::from_millis(40);

/// Why a sample was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Implausible {
    NonFinite,
    /// Outside the CAVE's box by more than the margin (or past [`MAX_TRACKED_DISTANCE_M`]).
    Outside,
    /// Moved faster than `max_speed_mps` since the last accepted sample (m/s).
    TooFast(f64),
    /// Turned faster than `max_turn_dps` (degrees per second).
    TurnedTooFast(f64),
}

impl Implausible {
    pub fn describe(self) -> String {
        match self {
            Self::NonFinite => "a non-finite number".into(),
            Self::Outside => "outside the CAVE by more than the margin".into(),
            Self::TooFast(v) => format!("a jump at {v:.3e} m/s"),
            Self::TurnedTooFast(v) => format!("a turn at {v:.3e}°/s"),
        }
    }
}

/// A calibrated sample: position in CAVE metres, orientation if any, when it arrived.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    pub position: Vec3,
    pub orientation: Option<Quat>,
    pub arrived: Instant,
}

/// A claim being confirmed: when its first sample arrived, its newest sample, how many agree.
#[derive(Debug, Clone, Copy)]
struct Streak {
    since: Instant,
    newest: Candidate,
    agreeing: u32,
}

/// The last accepted sample and a possible jump being confirmed.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlausibilityGate {
    accepted: Option<Candidate>,
    jump: Option<Streak>,
}

/// What the gate decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Plausible: filter it.
    Accept,
    /// A jump confirmed by [`JUMP_CONFIRMATIONS`] agreeing samples over [`CONFIRMATION_TIME`]:
    /// take it unfiltered.
    AcceptJump,
    /// Not from the last accepted pose, and not yet confirmed as a jump.
    Unconfirmed(Implausible),
    Refuse(Implausible),
}

impl PlausibilityGate {
    /// Forgets the history: the next sample is judged by the bounds alone (tracking resumed).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Judges `sample` against `limits`, the CAVE's box `bounds` (min, max; infinite sides
    /// allowed) and the last accepted sample.
    pub fn judge(
        &mut self,
        sample: Candidate,
        bounds: Option<(Vec3, Vec3)>,
        limits: &PlausibilityLimits,
    ) -> Verdict {
        if let Err(why) = check_alone(&sample, bounds, limits) {
            return Verdict::Refuse(why);
        }
        let Some(last) = self.accepted else {
            self.accepted = Some(sample);
            return Verdict::Accept;
        };
        match step(&last, &sample, limits) {
            Ok(()) => {
                self.accepted = Some(sample);
                self.jump = None;
                Verdict::Accept
            }
            Err(why) => {
                // Not from the last accepted pose: perhaps the start of a real jump.
                let streak = match self.jump {
                    Some(s) if step(&s.newest, &sample, limits).is_ok() => Streak {
                        newest: sample,
                        agreeing: s.agreeing + 1,
                        ..s
                    },
                    _ => Streak {
                        since: sample.arrived,
                        newest: sample,
                        agreeing: 1,
                    },
                };
                let lasted = sample.arrived.saturating_duration_since(streak.since);
                if streak.agreeing >= JUMP_CONFIRMATIONS && lasted >= CONFIRMATION_TIME {
                    self.accepted = Some(sample);
                    self.jump = None;
                    Verdict::AcceptJump
                } else {
                    self.jump = Some(streak);
                    Verdict::Unconfirmed(why)
                }
            }
        }
    }
}

/// Checks that need no history: finite, near the CAVE.
fn check_alone(
    sample: &Candidate,
    bounds: Option<(Vec3, Vec3)>,
    limits: &PlausibilityLimits,
) -> Result<(), Implausible> {
    let p = sample.position.as_dvec3();
    if !p.is_finite() || sample.orientation.is_some_and(|q| !q.is_finite()) {
        return Err(Implausible::NonFinite);
    }
    if p.abs().max_element() > MAX_TRACKED_DISTANCE_M {
        return Err(Implausible::Outside);
    }
    if let Some((lo, hi)) = bounds {
        let margin = DVec3::splat(f64::from(limits.outside_margin_m));
        // Infinite sides stay infinite; f64 keeps a huge finite side from overflowing.
        let (lo, hi) = (lo.as_dvec3() - margin, hi.as_dvec3() + margin);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            return Err(Implausible::Outside);
        }
    }
    Ok(())
}

/// Whether `to` can follow `from` at a head's speed.
fn step(from: &Candidate, to: &Candidate, limits: &PlausibilityLimits) -> Result<(), Implausible> {
    let dt = to
        .arrived
        .saturating_duration_since(from.arrived)
        .as_secs_f64()
        + JITTER_S;
    let moved = (to.position.as_dvec3() - from.position.as_dvec3()).length();
    if moved > f64::from(limits.max_speed_mps) * dt + JITTER_M {
        return Err(Implausible::TooFast(moved / dt.max(1e-6)));
    }
    if let (Some(a), Some(b)) = (from.orientation, to.orientation) {
        let turned = a.as_dquat().angle_between(b.as_dquat());
        if turned > f64::from(limits.max_turn_dps).to_radians() * dt + JITTER_RAD {
            return Err(Implausible::TurnedTooFast(
                turned.to_degrees() / dt.max(1e-6),
            ));
        }
    }
    Ok(())
}

/// A quaternion from a tracker made unit length in f64 (huge or tiny components do not
/// overflow), or `None` if it has no direction.
pub fn unit_quaternion(q: Quat) -> Option<Quat> {
    let q: DQuat = q.as_dquat();
    let length = q.length();
    (length.is_finite() && length > 1e-12).then(|| (q / length).as_quat())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn at(t0: Instant, ms: u64, p: Vec3) -> Candidate {
        Candidate {
            position: p,
            orientation: None,
            arrived: t0 + Duration::from_millis(ms),
        }
    }

    #[test]
    fn a_jump_is_refused_until_confirmed() {
        let t0 = Instant::now();
        let limits = PlausibilityLimits::default();
        let mut gate = PlausibilityGate::default();
        let bounds = Some((Vec3::splat(-2.0), Vec3::splat(2.0)));
        let a = Vec3::new(0.0, 1.6, 0.0);
        let b = Vec3::new(1.5, 1.6, 0.0);
        assert_eq!(gate.judge(at(t0, 0, a), bounds, &limits), Verdict::Accept);
        // 1.5 m in 8 ms is 187 m/s.
        assert!(matches!(
            gate.judge(at(t0, 8, b), bounds, &limits),
            Verdict::Unconfirmed(Implausible::TooFast(_))
        ));
        // A burst: three agreeing samples within a millisecond confirm nothing.
        for _ in 0..3 {
            assert!(matches!(
                gate.judge(at(t0, 9, b), bounds, &limits),
                Verdict::Unconfirmed(_)
            ));
        }
        // 40 ms after the streak began it is a jump.
        assert!(matches!(
            gate.judge(at(t0, 47, b), bounds, &limits),
            Verdict::Unconfirmed(_)
        ));
        assert_eq!(
            gate.judge(at(t0, 48, b), bounds, &limits),
            Verdict::AcceptJump
        );
        assert_eq!(
            gate.judge(at(t0, 56, b + Vec3::X * 0.01), bounds, &limits),
            Verdict::Accept
        );
        // Outside by more than the margin, and huge: refused alone.
        assert_eq!(
            gate.judge(at(t0, 64, Vec3::new(2.6, 1.6, 0.0)), bounds, &limits),
            Verdict::Refuse(Implausible::Outside)
        );
        assert_eq!(
            gate.judge(at(t0, 72, Vec3::new(3e38, 1.6, 0.2)), None, &limits),
            Verdict::Refuse(Implausible::Outside)
        );
    }

    #[test]
    fn a_fast_turn_is_refused() {
        let t0 = Instant::now();
        let limits = PlausibilityLimits::default();
        let mut gate = PlausibilityGate::default();
        let mut c = at(t0, 0, Vec3::new(0.0, 1.6, 0.0));
        c.orientation = Some(Quat::IDENTITY);
        assert_eq!(gate.judge(c, None, &limits), Verdict::Accept);
        c.arrived += Duration::from_millis(8);
        c.orientation = Some(Quat::from_rotation_y(3.0));
        assert!(matches!(
            gate.judge(c, None, &limits),
            Verdict::Unconfirmed(Implausible::TurnedTooFast(_))
        ));
        c.orientation = Some(Quat::from_rotation_y(0.05));
        assert_eq!(gate.judge(c, None, &limits), Verdict::Accept);
    }

    #[test]
    fn huge_quaternions_normalise_without_overflow() {
        let q = unit_quaternion(Quat::from_xyzw(3e38, 0.0, 0.0, 3e38)).unwrap();
        assert!((q.length() - 1.0).abs() < 1e-6);
        assert_eq!(unit_quaternion(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)), None);
        assert_eq!(
            unit_quaternion(Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0)),
            None
        );
    }
}
