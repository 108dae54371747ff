//! Walls as other CAVE software describes them: three corners; centre + yaw/pitch/roll + size
//! (nDisplay, CalVR); origin + axes + size (Vrui); in metres, centimetres, millimetres, inches
//! or feet, y-up or z-up. Everything becomes CAVE space: metres, +y up, −z to the front wall.

use glam::{DQuat, DVec3};

/// A length unit of a file's wall geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    #[default]
    Metre,
    Centimetre,
    Millimetre,
    Inch,
    Foot,
}

crate::named_enum!(LengthUnit {
    Self::Metre => "m",
    Self::Centimetre => "cm",
    Self::Millimetre => "mm",
    Self::Inch => "inch",
    Self::Foot => "foot",
});

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            Self::Metre => 1.0,
            Self::Centimetre => 0.01,
            Self::Millimetre => 0.001,
            Self::Inch => 0.0254,
            Self::Foot => 0.3048,
        }
    }
}

/// Which axis of a file points up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpAxis {
    /// CAVE space's own: x right, y up, −z to the front.
    #[default]
    Y,
    /// Right-handed z-up (CalVR, DTrack rooms, CAD): x right, y to the front, z up.
    Z,
}

crate::named_enum!(UpAxis {
    Self::Y => "y",
    Self::Z => "z",
});

/// The frame a file writes wall geometry in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FileFrame {
    pub unit: LengthUnit,
    pub up: UpAxis,
}

impl FileFrame {
    /// A point or vector of the file in CAVE metres.
    pub fn to_cave(&self, p: DVec3) -> DVec3 {
        let p = p * self.unit.metres();
        match self.up {
            UpAxis::Y => p,
            // z-up right-handed (y to the front) → y-up right-handed (−z to the front).
            UpAxis::Z => DVec3::new(p.x, p.z, -p.y),
        }
    }

    /// A CAVE-space point in the file's frame (the inverse of [`Self::to_cave`]).
    pub fn from_cave(&self, p: DVec3) -> DVec3 {
        let p = match self.up {
            UpAxis::Y => p,
            UpAxis::Z => DVec3::new(p.x, -p.z, p.y),
        };
        p / self.unit.metres()
    }
}

/// The rotation of a wall given by yaw, pitch and roll in degrees, in CAVE axes: yaw about the
/// up axis (+ turns left), then pitch about the wall's horizontal axis (+ tilts its top
/// towards the viewer: +90 faces down, a ceiling; −90 faces up, a floor), then roll about its normal — the head's convention. A wall at
/// (0, 0, 0) is a front wall: its right edge runs along +x, its top along +y, and it faces the
/// viewer (+z).
pub fn wall_rotation(yaw_pitch_roll_degrees: [f64; 3]) -> DQuat {
    let [yaw, pitch, roll] = yaw_pitch_roll_degrees.map(f64::to_radians);
    DQuat::from_rotation_y(yaw) * DQuat::from_rotation_x(pitch) * DQuat::from_rotation_z(roll)
}

/// Lower-left, lower-right and upper-left corners of a wall given by its centre, rotation and
/// size (width, height), all in CAVE space.
pub fn corners_from_centre(centre: DVec3, rotation: DQuat, size: [f64; 2]) -> [DVec3; 3] {
    let right = rotation * DVec3::X;
    let up = rotation * DVec3::Y;
    let [w, h] = size;
    let ll = centre - 0.5 * w * right - 0.5 * h * up;
    [ll, ll + w * right, ll + h * up]
}

/// The corners of a wall given by its lower-left corner, the directions of its horizontal and
/// vertical edges (any length) and its size (Vrui's screens). `None` if an axis has no length.
pub fn corners_from_axes(
    origin: DVec3,
    horizontal: DVec3,
    vertical: DVec3,
    size: [f64; 2],
) -> Option<[DVec3; 3]> {
    let h = horizontal.try_normalize()?;
    let v = vertical.try_normalize()?;
    Some([origin, origin + size[0] * h, origin + size[1] * v])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn the_default_caves_left_wall_three_ways() {
        // config/cave.toml's left wall: ll (−1.65, 0, 1.65), lr (−1.65, 0, −1.65),
        // ul (−1.65, 2.9, 1.65): centre (−1.65, 1.45, 0), turned 90° left, 3.3 × 2.9 m.
        let want = [
            DVec3::new(-1.65, 0.0, 1.65),
            DVec3::new(-1.65, 0.0, -1.65),
            DVec3::new(-1.65, 2.9, 1.65),
        ];
        let c = corners_from_centre(
            DVec3::new(-1.65, 1.45, 0.0),
            wall_rotation([90.0, 0.0, 0.0]),
            [3.3, 2.9],
        );
        assert!(c.iter().zip(&want).all(|(a, b)| close(*a, *b)), "{c:?}");
        let a = corners_from_axes(want[0], DVec3::NEG_Z * 7.0, DVec3::Y, [3.3, 2.9]).expect("axes");
        assert!(a.iter().zip(&want).all(|(a, b)| close(*a, *b)), "{a:?}");
        // The same in a z-up millimetre file: (x, y, z)cave = (x, z, −y)file / 1000.
        let mm = FileFrame {
            unit: LengthUnit::Millimetre,
            up: UpAxis::Z,
        };
        let file = DVec3::new(-1650.0, 0.0, 1450.0);
        assert!(close(mm.to_cave(file), DVec3::new(-1.65, 1.45, 0.0)));
        assert!(close(mm.from_cave(mm.to_cave(file)), file));
        assert!(corners_from_axes(want[0], DVec3::ZERO, DVec3::Y, [1.0, 1.0]).is_none());
    }

    #[test]
    fn units_are_exact_where_defined() {
        assert!((LengthUnit::Inch.metres() * 12.0 - LengthUnit::Foot.metres()).abs() < 1e-15);
        for u in LengthUnit::ALL {
            assert_eq!(u.name().parse::<LengthUnit>(), Ok(u));
        }
    }
}
