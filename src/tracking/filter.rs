//! The One Euro filter (Casiez, Roussel and Vogel, CHI 2012) against tracker jitter: a low-pass
//! whose cutoff rises with speed, so a still head is steady and a moving one does not lag.

use glam::{DVec4, Quat, Vec4};

/// Filter parameters (the panel and `[tracking.filter]` set them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneEuroParams {
    /// Cutoff at rest, Hz: lower = steadier, more lag at slow speeds.
    pub min_cutoff_hz: f32,
    /// How fast the cutoff rises with speed (per unit/s): higher = less lag when moving.
    pub beta: f32,
    /// Cutoff of the speed estimate, Hz.
    pub derivative_cutoff_hz: f32,
}

impl Default for OneEuroParams {
    fn default() -> Self {
        // Tuned for head positions in metres at 60–240 Hz: ~1 mm of jitter at rest is
        // smoothed to a fraction of that; moving, the cutoff rises to min + beta·speed, so the
        // lag of a steady walk, speed / (2π·cutoff), stays under 1/(2π·beta) = 1.6 cm (16 ms
        // of a 1 m/s walk).
        Self {
            min_cutoff_hz: 1.0,
            beta: 10.0,
            derivative_cutoff_hz: 1.0,
        }
    }
}

/// Smoothing factor of an exponential low-pass at `cutoff_hz` for a step of `dt` seconds.
fn alpha(cutoff_hz: f64, dt: f64) -> f64 {
    let tau = 1.0 / (std::f64::consts::TAU * cutoff_hz.max(1e-3));
    1.0 / (1.0 + tau / dt)
}

/// A One Euro filter over a vector of up to four channels (position: 3, quaternion: 4).
///
/// Its state is kept in f64 and is finite whatever it is fed: a non-finite input is not
/// taken, and should a finite one still overflow (±`f32::MAX` alternating), the filter
/// restarts from that input instead of keeping infinities (a NaN state would pin its output
/// for ever). The plausibility gate keeps such samples away; this is the second net.
#[derive(Debug, Clone, Copy, Default)]
pub struct OneEuro {
    state: Option<(DVec4, DVec4)>,
}

impl OneEuro {
    /// Forgets the history (after tracking was lost: the next sample passes unfiltered).
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Whether the state is finite (always; for tests).
    pub fn is_finite(&self) -> bool {
        self.state
            .is_none_or(|(x, v)| x.is_finite() && v.is_finite())
    }

    /// Filters `x` measured `dt` seconds after the previous sample.
    pub fn filter(&mut self, x: Vec4, dt: f32, p: &OneEuroParams) -> Vec4 {
        let x64 = x.as_dvec4();
        if !x64.is_finite() {
            // Not taken: the previous output stands (or the input, if there is none).
            return self.state.map_or(x, |(prev, _)| prev.as_vec4());
        }
        let Some((prev, prev_speed)) = self.state else {
            self.state = Some((x64, DVec4::ZERO));
            return x;
        };
        let dt = f64::from(dt);
        if !(dt.is_finite() && dt > 0.0) {
            // Two samples at once: keep the newer value's direction, no new speed estimate.
            return prev.as_vec4();
        }
        let speed = (x64 - prev) / dt;
        let speed = prev_speed.lerp(speed, alpha(f64::from(p.derivative_cutoff_hz), dt));
        let cutoff = f64::from(p.min_cutoff_hz) + f64::from(p.beta) * speed.length();
        let out = prev.lerp(x64, alpha(cutoff, dt));
        if out.is_finite() && speed.is_finite() && out.as_vec4().is_finite() {
            self.state = Some((out, speed));
            out.as_vec4()
        } else {
            self.state = Some((x64, DVec4::ZERO));
            x
        }
    }

    /// Filters a quaternion (kept in the previous output's hemisphere, renormalised).
    pub fn filter_quat(&mut self, q: Quat, dt: f32, p: &OneEuroParams) -> Quat {
        let mut v = Vec4::from(q);
        if let Some((prev, _)) = self.state
            && prev.as_vec4().dot(v) < 0.0
        {
            v = -v;
        }
        let out = self.filter(v, dt, p);
        super::plausibility::unit_quaternion(Quat::from_vec4(out)).unwrap_or(q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic ±1 mm jitter.
    fn jitter(i: u32) -> f32 {
        let h = i.wrapping_mul(2_654_435_761) >> 16;
        (h % 2001) as f32 / 1000.0 - 1.0
    }

    #[test]
    fn still_head_is_steadied_and_moving_head_follows() {
        let p = OneEuroParams::default();
        let dt = 1.0 / 120.0;
        let mut f = OneEuro::default();
        let mut worst_still: f32 = 0.0;
        for i in 0..240 {
            let x = Vec4::new(0.001 * jitter(i), 1.7, 0.0, 0.0);
            let y = f.filter(x, dt, &p);
            if i > 120 {
                worst_still = worst_still.max(y.x.abs());
            }
        }
        // Raw jitter is up to 1 mm; filtered at rest it must be well under half of that.
        assert!(worst_still < 0.0004, "{worst_still}");
        // A 1 m/s walk: after half a second the lag is under 1/(2π·beta) = 1.6 cm.
        let mut x = 0.0;
        let mut y = Vec4::ZERO;
        for _ in 0..60 {
            x += dt;
            y = f.filter(Vec4::new(x, 1.7, 0.0, 0.0), dt, &p);
        }
        assert!((x - y.x).abs() < 0.016, "lag {}", x - y.x);
    }

    #[test]
    fn quaternion_sign_flips_do_not_spin() {
        let p = OneEuroParams::default();
        let mut f = OneEuro::default();
        let q = Quat::from_rotation_y(0.5);
        f.filter_quat(q, 0.01, &p);
        let out = f.filter_quat(-q, 0.01, &p);
        assert!(out.angle_between(q) < 1e-5);
    }
}
