//! The tracked wand's ray: from the wand's calibrated pose (CAVE space) along its pointing
//! direction (the wand's −z, as a head looks along its −z), for drawing, flying and picking.

use glam::{Quat, Vec3};

/// The longest ray drawn, metres (also where a pick gives up).
pub const MAX_RAY_LENGTH_M: f32 = 100.0;

/// A ray from the wand, CAVE space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WandRay {
    pub origin: Vec3,
    /// Unit length.
    pub direction: Vec3,
    /// How far it is drawn, metres.
    pub length: f32,
}

impl WandRay {
    /// The ray of a wand at `position` turned by `orientation`, drawn `length` metres (clamped to
    /// [`MAX_RAY_LENGTH_M`]); `None` for a pose that is not finite.
    pub fn from_pose(position: Vec3, orientation: Quat, length: f32) -> Option<Self> {
        let direction = (orientation * Vec3::NEG_Z).try_normalize()?;
        (position.is_finite() && length.is_finite() && length > 0.0).then_some(Self {
            origin: position,
            direction,
            length: length.min(MAX_RAY_LENGTH_M),
        })
    }

    /// The point `t` metres along the ray.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.direction
    }

    /// The end of the drawn ray.
    pub fn tip(&self) -> Vec3 {
        self.at(self.length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wand_points_along_its_minus_z() {
        let r = WandRay::from_pose(Vec3::new(0.0, 1.0, 0.0), Quat::IDENTITY, 2.0).expect("ray");
        assert_eq!(r.tip(), Vec3::new(0.0, 1.0, -2.0));
        let left = Quat::from_rotation_y(90f32.to_radians());
        let r = WandRay::from_pose(Vec3::ZERO, left, 1.0).expect("ray");
        assert!((r.direction - Vec3::NEG_X).length() < 1e-6);
        assert!(WandRay::from_pose(Vec3::NAN, Quat::IDENTITY, 1.0).is_none());
        assert_eq!(
            WandRay::from_pose(Vec3::ZERO, Quat::IDENTITY, 1e9).map(|r| r.length),
            Some(MAX_RAY_LENGTH_M)
        );
    }
}
