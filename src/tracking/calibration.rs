//! The tracker-to-CAVE calibration: axis remap (up axis, handedness), scale, rotation, offset.

use glam::{Mat3, Quat, Vec3};

/// One CAVE axis as a signed tracker axis: `"x"`, `"-z"`, …
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SignedAxis {
    /// 0 = x, 1 = y, 2 = z (of the tracker).
    pub axis: usize,
    pub negative: bool,
}

impl SignedAxis {
    pub fn parse(s: &str) -> Option<Self> {
        let (negative, name) = match s.trim() {
            n if n.starts_with('-') => (true, &n[1..]),
            n if n.starts_with('+') => (false, &n[1..]),
            n => (false, n),
        };
        let axis = match name {
            "x" | "X" => 0,
            "y" | "Y" => 1,
            "z" | "Z" => 2,
            _ => return None,
        };
        Some(Self { axis, negative })
    }

    pub fn name(self) -> String {
        format!(
            "{}{}",
            if self.negative { "-" } else { "" },
            ["x", "y", "z"][self.axis]
        )
    }
}

/// Maps tracker coordinates to CAVE space:
/// `cave = offset + rotation · (scale · remap · tracker)`.
///
/// `remap` is a signed permutation (the CAVE's x, y, z as signed tracker axes), so it fixes both
/// the up axis (y-up vs z-up trackers) and the handedness; orientations are conjugated by it, so
/// a left-handed tracker's rotations become proper rotations in the right-handed CAVE frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    pub remap: Mat3,
    /// Tracker units to metres (0.001 for millimetres).
    pub scale: f32,
    pub rotation: Quat,
    /// CAVE-space position of the tracker's origin, metres.
    pub offset: Vec3,
}

impl Default for Calibration {
    fn default() -> Self {
        Self {
            remap: Mat3::IDENTITY,
            scale: 1.0,
            rotation: Quat::IDENTITY,
            offset: Vec3::ZERO,
        }
    }
}

/// What is wrong with an axis remap.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AxesError {
    #[error("'{0}' is not an axis (x, y, z, optionally with a sign: -z)")]
    NotAnAxis(String),
    #[error("tracker axis {0} is used twice: each must map to exactly one CAVE axis")]
    Repeated(&'static str),
}

impl Calibration {
    /// The remap matrix from the CAVE's x, y, z written as signed tracker axes, e.g.
    /// `["x", "z", "-y"]` for a right-handed z-up tracker, `["x", "y", "-z"]` for a left-handed
    /// y-up one.
    pub fn remap_from_axes(axes: &[String; 3]) -> Result<Mat3, AxesError> {
        let mut rows = [Vec3::ZERO; 3];
        let mut used = [false; 3];
        for (row, name) in rows.iter_mut().zip(axes) {
            let a = SignedAxis::parse(name).ok_or_else(|| AxesError::NotAnAxis(name.clone()))?;
            if used[a.axis] {
                return Err(AxesError::Repeated(["x", "y", "z"][a.axis]));
            }
            used[a.axis] = true;
            row[a.axis] = if a.negative { -1.0 } else { 1.0 };
        }
        Ok(Mat3::from_cols(rows[0], rows[1], rows[2]).transpose())
    }

    /// A tracker position in CAVE space.
    pub fn position(&self, tracker: Vec3) -> Vec3 {
        self.offset + self.rotation * (self.scale * (self.remap * tracker))
    }

    /// A tracker orientation in CAVE space.
    pub fn orientation(&self, tracker: Quat) -> Quat {
        let in_cave_axes = self.remap * Mat3::from_quat(tracker) * self.remap.transpose();
        (self.rotation * Quat::from_mat3(&in_cave_axes)).normalize()
    }

    /// An orientation already in CAVE axes (yaw/pitch/roll messages): only the rotation applies.
    pub fn orientation_in_cave_axes(&self, q: Quat) -> Quat {
        (self.rotation * q).normalize()
    }

    /// The tracker position that maps to `cave` (the simulator sends what a tracker would).
    pub fn tracker_position(&self, cave: Vec3) -> Vec3 {
        let scale = if self.scale.abs() > 0.0 {
            self.scale
        } else {
            1.0
        };
        self.remap.transpose() * (self.rotation.inverse() * (cave - self.offset)) / scale
    }

    /// The tracker orientation that maps to `cave`.
    pub fn tracker_orientation(&self, cave: Quat) -> Quat {
        let in_cave_axes = Mat3::from_quat(self.rotation.inverse() * cave);
        Quat::from_mat3(&(self.remap.transpose() * in_cave_axes * self.remap)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes(a: [&str; 3]) -> [String; 3] {
        a.map(str::to_owned)
    }

    #[test]
    fn z_up_tracker_maps_up_to_y() {
        let remap = Calibration::remap_from_axes(&axes(["x", "z", "-y"])).expect("axes");
        let c = Calibration {
            remap,
            ..Calibration::default()
        };
        // Tracker: 1.7 m up (z), 0.5 m forward (+y, away from the viewer = CAVE −z).
        assert!((c.position(Vec3::new(0.2, 0.5, 1.7)) - Vec3::new(0.2, 1.7, -0.5)).length() < 1e-6);
        // A yaw about the tracker's up axis is a yaw about the CAVE's.
        let q = c.orientation(Quat::from_rotation_z(0.4));
        assert!(q.angle_between(Quat::from_rotation_y(0.4)) < 1e-5, "{q}");
    }

    #[test]
    fn left_handed_tracker_rotations_become_proper_rotations() {
        let remap = Calibration::remap_from_axes(&axes(["x", "y", "-z"])).expect("axes");
        let c = Calibration {
            remap,
            ..Calibration::default()
        };
        // Left-handed y-up (Unity): +z is forward, a positive yaw turns right.
        assert!((c.position(Vec3::new(0.0, 1.7, 1.0)) - Vec3::new(0.0, 1.7, -1.0)).length() < 1e-6);
        let forward_t = Vec3::Z;
        let turned_t = Mat3::from_quat(Quat::from_rotation_y(0.5)) * forward_t;
        let q = c.orientation(Quat::from_rotation_y(0.5));
        // The CAVE-space rotation turns the mapped forward to the mapped turned direction.
        let expected = remap * turned_t;
        assert!((q * (remap * forward_t) - expected).length() < 1e-5);
    }

    #[test]
    fn inverse_round_trips() {
        let c = Calibration {
            remap: Calibration::remap_from_axes(&axes(["-y", "z", "x"])).expect("axes"),
            scale: 0.001,
            rotation: Quat::from_rotation_y(0.3),
            offset: Vec3::new(0.1, -0.2, 0.3),
        };
        let p = Vec3::new(0.4, 1.6, -0.3);
        assert!((c.position(c.tracker_position(p)) - p).length() < 1e-5);
        let q = Quat::from_rotation_y(1.1) * Quat::from_rotation_x(0.2);
        assert!(c.orientation(c.tracker_orientation(q)).angle_between(q) < 1e-4);
    }

    #[test]
    fn bad_axes_are_named() {
        assert_eq!(
            Calibration::remap_from_axes(&axes(["x", "x", "z"])),
            Err(AxesError::Repeated("x"))
        );
        assert!(matches!(
            Calibration::remap_from_axes(&axes(["x", "w", "z"])),
            Err(AxesError::NotAnAxis(_))
        ));
    }
}
