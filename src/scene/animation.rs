//! glTF animation sampling on the CPU: one channel's keyframes evaluated at a time, with
//! STEP, LINEAR (spherical for rotations) and CUBICSPLINE interpolation as the glTF 2.0
//! specification defines them (§3.11 and Appendix C). The pose evaluation and the GPU pose
//! pass build on this; it is their CPU twin.

use glam::{Quat, Vec4};

/// How a sampler fills the time between keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// The previous keyframe's value until the next keyframe.
    Step,
    /// Linear (spherical linear for rotations, along the shorter arc).
    Linear,
    /// Cubic Hermite spline with an in-tangent and an out-tangent per keyframe.
    CubicSpline,
}

/// What a sampler's values are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Values {
    /// 3 components a keyframe (translation, scale).
    Vector3,
    /// A unit quaternion (x, y, z, w) a keyframe.
    Rotation,
    /// This many morph target weights a keyframe.
    Weights(usize),
}

impl Values {
    /// Floats a keyframe holds (without CUBICSPLINE's tangents).
    pub fn components(self) -> usize {
        match self {
            Values::Vector3 => 3,
            Values::Rotation => 4,
            Values::Weights(n) => n,
        }
    }
}

/// Why keyframes cannot be sampled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SamplerError {
    #[error("no keyframes")]
    Empty,
    #[error("keyframe time {index} ({time}) is not finite")]
    TimeNotFinite { index: usize, time: f32 },
    #[error("keyframe times must increase: time {index} ({time}) follows {previous}")]
    TimesNotIncreasing {
        index: usize,
        time: f32,
        previous: f32,
    },
    #[error(
        "{got} output values for {keyframes} keyframes of {components} components \
         ({interpolation:?} needs {expected})"
    )]
    WrongOutputCount {
        got: usize,
        expected: usize,
        keyframes: usize,
        components: usize,
        interpolation: Interpolation,
    },
    #[error("output value {index} ({value}) is not finite")]
    ValueNotFinite { index: usize, value: f32 },
    #[error("a morph target weight channel has no targets to weigh")]
    NoWeights,
}

/// One animation sampler: keyframe times and their values, checked once.
#[derive(Debug, Clone, PartialEq)]
pub struct Sampler {
    times: Vec<f32>,
    /// Per keyframe: the value (STEP, LINEAR) or in-tangent, value, out-tangent (CUBICSPLINE),
    /// each `values.components()` floats.
    output: Vec<f32>,
    interpolation: Interpolation,
    values: Values,
}

impl Sampler {
    /// Checks and keeps a sampler: at least one keyframe, finite times strictly increasing,
    /// finite values, and as many values as the keyframes and interpolation need.
    pub fn new(
        times: Vec<f32>,
        output: Vec<f32>,
        interpolation: Interpolation,
        values: Values,
    ) -> Result<Self, SamplerError> {
        if times.is_empty() {
            return Err(SamplerError::Empty);
        }
        if values == Values::Weights(0) {
            return Err(SamplerError::NoWeights);
        }
        for (index, &time) in times.iter().enumerate() {
            if !time.is_finite() {
                return Err(SamplerError::TimeNotFinite { index, time });
            }
            if index > 0 && time <= times[index - 1] {
                return Err(SamplerError::TimesNotIncreasing {
                    index,
                    time,
                    previous: times[index - 1],
                });
            }
        }
        let per_key = match interpolation {
            Interpolation::CubicSpline => 3,
            _ => 1,
        } * values.components();
        let expected = times.len() * per_key;
        if output.len() != expected {
            return Err(SamplerError::WrongOutputCount {
                got: output.len(),
                expected,
                keyframes: times.len(),
                components: values.components(),
                interpolation,
            });
        }
        if let Some((index, &value)) = output.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(SamplerError::ValueNotFinite { index, value });
        }
        Ok(Self {
            times,
            output,
            interpolation,
            values,
        })
    }

    /// The first and last keyframe times.
    pub fn time_range(&self) -> (f32, f32) {
        (self.times[0], self.times[self.times.len() - 1])
    }

    pub fn values(&self) -> Values {
        self.values
    }

    /// The keyframe value `k` (for CUBICSPLINE: its value, not a tangent).
    fn value(&self, k: usize) -> &[f32] {
        let n = self.values.components();
        let start = match self.interpolation {
            Interpolation::CubicSpline => (3 * k + 1) * n,
            _ => k * n,
        };
        &self.output[start..start + n]
    }

    /// Keyframe `k`'s in-tangent (CUBICSPLINE only).
    fn in_tangent(&self, k: usize) -> &[f32] {
        let n = self.values.components();
        &self.output[3 * k * n..(3 * k + 1) * n]
    }

    /// Keyframe `k`'s out-tangent (CUBICSPLINE only).
    fn out_tangent(&self, k: usize) -> &[f32] {
        let n = self.values.components();
        &self.output[(3 * k + 2) * n..(3 * k + 3) * n]
    }

    /// The value at `time` into `out` (`values().components()` floats). Before the first
    /// keyframe the first value holds, after the last the last (the clock wraps or clamps
    /// the time before it gets here). Rotations come out unit length.
    pub fn sample(&self, time: f32, out: &mut [f32]) {
        let n = self.values.components();
        let out = &mut out[..n];
        let last = self.times.len() - 1;
        let time = if time.is_finite() {
            time
        } else {
            self.times[0]
        };
        // The keyframe at or before `time`.
        let k = self.times.partition_point(|&t| t <= time);
        if k == 0 {
            out.copy_from_slice(self.value(0));
            return;
        }
        if k > last {
            out.copy_from_slice(self.value(last));
            return;
        }
        let k = k - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let s = ((time - t0) / dt).clamp(0.0, 1.0);
        match self.interpolation {
            Interpolation::Step => out.copy_from_slice(self.value(k)),
            Interpolation::Linear if self.values == Values::Rotation => {
                let q = slerp(quat(self.value(k)), quat(self.value(k + 1)), s);
                out.copy_from_slice(&q.to_array());
            }
            Interpolation::Linear => {
                let (a, b) = (self.value(k), self.value(k + 1));
                for i in 0..n {
                    out[i] = a[i] + s * (b[i] - a[i]);
                }
            }
            Interpolation::CubicSpline => {
                // Hermite basis (glTF Appendix C), tangents scaled by the keyframe interval.
                let (s2, s3) = (s * s, s * s * s);
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = s3 - 2.0 * s2 + s;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = s3 - s2;
                let (p0, p1) = (self.value(k), self.value(k + 1));
                let (m0, m1) = (self.out_tangent(k), self.in_tangent(k + 1));
                for i in 0..n {
                    out[i] = h00 * p0[i] + h10 * dt * m0[i] + h01 * p1[i] + h11 * dt * m1[i];
                }
                if self.values == Values::Rotation {
                    // A spline between q and −q with flat tangents passes through zero: the
                    // nearer keyframe's rotation then.
                    let q = Vec4::from(quat(out))
                        .try_normalize()
                        .map(Quat::from_vec4)
                        .unwrap_or_else(|| quat(if s < 0.5 { p0 } else { p1 }).normalize());
                    out.copy_from_slice(&q.to_array());
                }
            }
        }
    }
}

fn quat(v: &[f32]) -> Quat {
    Quat::from_vec4(Vec4::new(v[0], v[1], v[2], v[3]))
}

/// Spherical linear interpolation along the shorter arc: a keyframe stored with the opposite
/// sign (the same rotation) does not send the rotation the long way round.
pub fn slerp(a: Quat, b: Quat, s: f32) -> Quat {
    let a = a.normalize();
    let mut b = b.normalize();
    let mut dot = a.dot(b);
    if dot < 0.0 {
        b = -b;
        dot = -dot;
    }
    if dot > 0.9995 {
        // Nearly the same rotation: linear, renormalised (slerp's division would lose digits).
        return (a + (b - a) * s).normalize();
    }
    let theta = dot.clamp(-1.0, 1.0).acos();
    let sin = theta.sin();
    let wa = ((1.0 - s) * theta).sin() / sin;
    let wb = (s * theta).sin() / sin;
    (a * wa + b * wb).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(s: &Sampler, t: f32) -> Vec<f32> {
        let mut out = vec![0.0; s.values().components()];
        s.sample(t, &mut out);
        out
    }

    fn scalar_track(interpolation: Interpolation, output: Vec<f32>) -> Sampler {
        // Three weights of one target each keyframe: a scalar track.
        Sampler::new(
            vec![0.0, 1.0, 3.0],
            output,
            interpolation,
            Values::Weights(1),
        )
        .unwrap()
    }

    #[test]
    fn step_holds_the_previous_keyframe() {
        let s = scalar_track(Interpolation::Step, vec![0.0, 10.0, 20.0]);
        assert_eq!(sample(&s, -1.0), [0.0]);
        assert_eq!(sample(&s, 0.0), [0.0]);
        assert_eq!(sample(&s, 0.999), [0.0]);
        assert_eq!(sample(&s, 1.0), [10.0]);
        assert_eq!(sample(&s, 2.9), [10.0]);
        assert_eq!(sample(&s, 3.0), [20.0]);
        assert_eq!(sample(&s, 99.0), [20.0]);
    }

    #[test]
    fn linear_interpolates_within_each_interval() {
        let s = scalar_track(Interpolation::Linear, vec![0.0, 10.0, 20.0]);
        assert_eq!(sample(&s, 0.25), [2.5]);
        // The second interval is 2 s long: half way at 2 s.
        assert_eq!(sample(&s, 2.0), [15.0]);
        assert_eq!(sample(&s, 3.5), [20.0]);
    }

    #[test]
    fn cubic_spline_follows_the_hermite_basis_with_scaled_tangents() {
        // Keyframes (in-tangent, value, out-tangent): (0, 0, 1) at 0 s, (0, 1, 0) at 1 s,
        // (2, 4, 0) at 3 s.
        let s = scalar_track(
            Interpolation::CubicSpline,
            vec![0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 2.0, 4.0, 0.0],
        );
        // s = 0.5 in [0, 1]: h00 = 0.5, h10 = 0.125, h01 = 0.5, h11 = -0.125;
        // 0.5·0 + 0.125·1·1 + 0.5·1 + (−0.125)·1·0 = 0.625.
        assert!((sample(&s, 0.5)[0] - 0.625).abs() < 1e-6);
        // s = 0.5 in [1, 3] (dt = 2): 0.5·1 + 0.125·2·0 + 0.5·4 + (−0.125)·2·2 = 2.0.
        assert!((sample(&s, 2.0)[0] - 2.0).abs() < 1e-6);
        // At a keyframe, its value exactly.
        assert_eq!(sample(&s, 1.0), [1.0]);
        assert_eq!(sample(&s, 3.0), [4.0]);
    }

    /// A LINEAR rotation track from `a` at 0 s to `b` at 1 s.
    fn rotation_track(a: Quat, b: Quat) -> Sampler {
        let output = [a, b].iter().flat_map(|q| q.to_array()).collect();
        Sampler::new(
            vec![0.0, 1.0],
            output,
            Interpolation::Linear,
            Values::Rotation,
        )
        .unwrap()
    }

    #[test]
    fn rotations_take_the_shorter_arc_whatever_the_keyframes_sign() {
        let quarter = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        // The second keyframe stored negated: the same rotation, the opposite sign.
        let s = rotation_track(Quat::IDENTITY, -quarter);
        let half = quat(&sample(&s, 0.5));
        let expected = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
        assert!(half.angle_between(expected) < 1e-5, "{half:?}");
        // Identity to its own negation: no motion at all, and no NaN.
        let s = rotation_track(Quat::IDENTITY, -Quat::IDENTITY);
        let q = quat(&sample(&s, 0.3));
        assert!(
            q.is_finite() && q.angle_between(Quat::IDENTITY) < 1e-5,
            "{q:?}"
        );
    }

    #[test]
    fn cubic_spline_rotations_come_out_unit_length() {
        let a = Quat::from_rotation_x(0.3);
        let b = Quat::from_rotation_x(1.2);
        let mut output = Vec::new();
        for q in [a, b] {
            output.extend([0.0; 4]);
            output.extend(q.to_array());
            output.extend([0.0; 4]);
        }
        let s = Sampler::new(
            vec![0.0, 2.0],
            output,
            Interpolation::CubicSpline,
            Values::Rotation,
        )
        .unwrap();
        let q = quat(&sample(&s, 1.0));
        assert!((q.length() - 1.0).abs() < 1e-6);
        // Zero tangents and equal weights half way: the normalised mean, 0.75 rad about x.
        assert!(q.angle_between(Quat::from_rotation_x(0.75)) < 1e-4, "{q:?}");
    }

    #[test]
    fn malformed_keyframes_are_refused_with_what_is_wrong() {
        let weights = Values::Weights(2);
        let err = |times: Vec<f32>, output: Vec<f32>, i| {
            Sampler::new(times, output, i, weights)
                .unwrap_err()
                .to_string()
        };
        assert!(err(vec![], vec![], Interpolation::Linear).contains("no keyframes"));
        assert!(err(vec![0.0, 2.0, 1.0], vec![0.0; 6], Interpolation::Linear).contains("increase"));
        assert!(err(vec![0.0, 1.0, 1.0], vec![0.0; 6], Interpolation::Step).contains("increase"));
        assert!(err(vec![0.0, f32::NAN], vec![0.0; 4], Interpolation::Linear).contains("finite"));
        assert!(
            err(vec![0.0, 1.0], vec![0.0; 4], Interpolation::CubicSpline)
                .contains("4 output values for 2 keyframes of 2 components")
        );
        assert!(
            err(
                vec![0.0, 1.0],
                vec![0.0, 1.0, f32::INFINITY, 0.0],
                Interpolation::Linear
            )
            .contains("output value 2")
        );
        assert!(
            Sampler::new(vec![0.0], vec![], Interpolation::Step, Values::Weights(0))
                .unwrap_err()
                .to_string()
                .contains("no targets")
        );
    }

    #[test]
    fn a_cubic_spline_through_the_zero_quaternion_stays_a_rotation() {
        // q to −q (the same rotation) with flat tangents: half-way the blend is zero.
        let q = Quat::from_rotation_y(0.4);
        let output: Vec<f32> = [q, -q]
            .iter()
            .flat_map(|k| [[0.0; 4], k.to_array(), [0.0; 4]].concat())
            .collect();
        let s = Sampler::new(
            vec![0.0, 1.0],
            output,
            Interpolation::CubicSpline,
            Values::Rotation,
        )
        .unwrap();
        let out = sample(&s, 0.5);
        let r = Quat::from_array([out[0], out[1], out[2], out[3]]);
        assert!(r.is_finite() && r.angle_between(q) < 1e-5, "{r:?}");
    }

    #[test]
    fn a_non_finite_time_samples_the_first_keyframe() {
        let s = scalar_track(Interpolation::Linear, vec![5.0, 10.0, 20.0]);
        assert_eq!(sample(&s, f32::NAN), [5.0]);
    }
}
