//! Cartographic projections of view directions to image coordinates and back: perspective,
//! equirectangular, Hammer, Albers equal-area conic and azimuthal equidistant.
//!
//! View space: x right, y up, −z ahead (the navigation direction). A direction has a
//! longitude (0 ahead, positive to the right, ±π behind) and a latitude (positive up). Image
//! coordinates are normalised device coordinates: x right, y up, the field of view filling
//! [−1, 1] on both axes.

use std::f32::consts::{FRAC_PI_2, PI, SQRT_2};

use glam::{Vec2, Vec3};

/// A map of the sphere of directions onto a plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Projection {
    /// The ordinary camera: straight lines stay straight, below 180° only.
    Perspective,
    /// Longitude and latitude as x and y (cylindrical; 2:1 for the whole sphere).
    Equirectangular,
    /// Hammer's equal-area projection: the whole sphere in a 2:1 ellipse.
    Hammer,
    /// Albers' equal-area conic projection, standard parallels [`ALBERS_PARALLELS_DEG`]: true
    /// to shape between them; the poles do not fit.
    AlbersConic,
    /// Distance from the image centre proportional to the angle from straight ahead (the
    /// fisheye mapping), up to the direction straight behind.
    AzimuthalEquidistant,
}

/// Standard parallels of [`Projection::AlbersConic`] (degrees): one at the horizon, one
/// above it, so that the view ahead is true to shape and the cone opens downwards. Keep in
/// sync with the `ALBERS_*` constants in shaders/common.wgsl (derived from these).
pub const ALBERS_PARALLELS_DEG: [f32; 2] = [0.0, 45.0];

crate::named_enum!(Projection {
    Self::Perspective => "perspective",
    Self::Equirectangular => "equirectangular",
    Self::Hammer => "hammer",
    Self::AlbersConic => "albers",
    Self::AzimuthalEquidistant => "azimuthal-equidistant",
});

impl Projection {
    /// The projection's number in WGSL (`pano_map` in shaders/common.wgsl; keep in step).
    pub fn code(self) -> u32 {
        match self {
            Self::Perspective => 0,
            Self::Equirectangular => 1,
            Self::Hammer => 2,
            Self::AlbersConic => 3,
            Self::AzimuthalEquidistant => 4,
        }
    }

    /// Whether the geometric route (per-vertex projection with pre-clip) can draw it: the
    /// cylindrical and pseudo-cylindrical ones, whose only discontinuities are the rear
    /// meridian and the poles.
    pub fn geometric(self) -> bool {
        matches!(self, Self::Equirectangular | Self::Hammer)
    }

    /// The largest field of view (horizontal, vertical; radians) the projection can show.
    pub fn max_fov(self) -> (f32, f32) {
        match self {
            // Perspective: just under 180° (the image plane would be infinitely large).
            Self::Perspective => (170f32.to_radians(), 170f32.to_radians()),
            Self::AzimuthalEquidistant => (2.0 * PI, 2.0 * PI),
            // Albers: the poles do not fit; stop 5° short of them.
            Self::AlbersConic => (2.0 * PI, 170f32.to_radians()),
            Self::Equirectangular | Self::Hammer => (2.0 * PI, PI),
        }
    }
}

/// Longitude (0 ahead, positive right) and latitude (positive up) of a unit view-space
/// direction (the equirectangular sky's convention too).
pub fn lon_lat(unit: Vec3) -> (f32, f32) {
    (unit.x.atan2(-unit.z), unit.y.clamp(-1.0, 1.0).asin())
}

/// The unit view-space direction of a longitude and latitude.
pub fn direction(lon: f32, lat: f32) -> Vec3 {
    Vec3::new(lat.cos() * lon.sin(), lat.sin(), -lat.cos() * lon.cos())
}

/// Albers' constants for the standard parallels: n, C and ρ0 (the radius at latitude 0).
fn albers_constants() -> (f32, f32, f32) {
    let [a, b] = ALBERS_PARALLELS_DEG.map(f32::to_radians);
    let n = 0.5 * (a.sin() + b.sin());
    let c = a.cos() * a.cos() + 2.0 * n * a.sin();
    (n, c, c.sqrt() / n)
}

/// Hammer's map coordinates of a longitude and latitude.
fn hammer(lon: f32, lat: f32) -> Vec2 {
    let den = (1.0 + lat.cos() * (0.5 * lon).cos()).sqrt();
    Vec2::new(
        2.0 * SQRT_2 * lat.cos() * (0.5 * lon).sin() / den,
        SQRT_2 * lat.sin() / den,
    )
}

/// Map coordinates of a direction, before fitting the field of view; `None` where the
/// projection has no image of it (behind a perspective camera).
fn map(projection: Projection, d: Vec3) -> Option<Vec2> {
    let d = d.normalize();
    let (lon, lat) = lon_lat(d);
    match projection {
        Projection::Perspective => (-d.z > 1e-6).then(|| Vec2::new(d.x, d.y) / -d.z),
        Projection::Equirectangular => Some(Vec2::new(lon, lat)),
        Projection::Hammer => Some(hammer(lon, lat)),
        Projection::AlbersConic => {
            let (n, c, rho0) = albers_constants();
            let rho = (c - 2.0 * n * lat.sin()).max(0.0).sqrt() / n;
            let theta = n * lon;
            Some(Vec2::new(rho * theta.sin(), rho0 - rho * theta.cos()))
        }
        Projection::AzimuthalEquidistant => {
            let angle = (-d.z).clamp(-1.0, 1.0).acos();
            let sideways = Vec2::new(d.x, d.y);
            let len = sideways.length();
            Some(if len > 1e-12 {
                sideways * (angle / len)
            } else if angle > FRAC_PI_2 {
                // Straight behind: the whole outer circle; pick its left point.
                Vec2::new(-PI, 0.0)
            } else {
                Vec2::ZERO
            })
        }
    }
}

/// The direction at map coordinates, if the map shows one there.
fn unmap(projection: Projection, m: Vec2) -> Option<Vec3> {
    match projection {
        Projection::Perspective => Some(Vec3::new(m.x, m.y, -1.0).normalize()),
        Projection::Equirectangular => {
            (m.x.abs() <= PI && m.y.abs() <= FRAC_PI_2).then(|| direction(m.x, m.y))
        }
        Projection::Hammer => {
            // Inside the ellipse x²/8 + y²/2 ≤ 1.
            let e = m.x * m.x / 8.0 + m.y * m.y / 2.0;
            if e > 1.0 {
                return None;
            }
            let z = (1.0 - m.x * m.x / 16.0 - m.y * m.y / 4.0).max(0.0).sqrt();
            let lon = 2.0 * (z * m.x).atan2(2.0 * (2.0 * z * z - 1.0));
            let lat = (z * m.y).clamp(-1.0, 1.0).asin();
            Some(direction(lon, lat))
        }
        Projection::AlbersConic => {
            let (n, c, rho0) = albers_constants();
            let dy = rho0 - m.y;
            let rho = m.x.hypot(dy);
            let lon = m.x.atan2(dy) / n;
            let s = (c - rho * rho * n * n) / (2.0 * n);
            (lon.abs() <= PI && s.abs() <= 1.0).then(|| direction(lon, s.asin()))
        }
        Projection::AzimuthalEquidistant => {
            let angle = m.length();
            if angle > PI {
                return None;
            }
            let sideways = if angle > 0.0 { m / angle } else { Vec2::ZERO };
            let s = angle.sin();
            Some(Vec3::new(s * sideways.x, s * sideways.y, -angle.cos()))
        }
    }
}

/// A projection fitted to a field of view: image coordinates in [−1, 1] cover it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PanoProjection {
    pub projection: Projection,
    /// Centre and half size of the field of view in map coordinates.
    centre: Vec2,
    half: Vec2,
    /// The field of view (radians, horizontal and vertical) after clamping.
    fov: Vec2,
}

impl PanoProjection {
    /// `h_fov` × `v_fov` (radians) around the view direction, each clamped to what the
    /// projection can show ([`Projection::max_fov`]) and to at least 1°.
    pub fn new(projection: Projection, h_fov: f32, v_fov: f32) -> Self {
        let (max_h, max_v) = projection.max_fov();
        let min = 1f32.to_radians();
        let h = if h_fov.is_finite() {
            h_fov.clamp(min, max_h)
        } else {
            max_h
        };
        let v = if v_fov.is_finite() {
            v_fov.clamp(min, max_v)
        } else {
            max_v
        };
        let (hh, hv) = (0.5 * h, 0.5 * v);
        let (centre, half) = match projection {
            Projection::Perspective => (Vec2::ZERO, Vec2::new(hh.tan(), hv.tan())),
            Projection::Equirectangular | Projection::AzimuthalEquidistant => {
                (Vec2::ZERO, Vec2::new(hh, hv))
            }
            // From the angles, not through a direction: at ±180° a direction's longitude
            // may come back with the other sign.
            Projection::Hammer => (Vec2::ZERO, Vec2::new(hammer(hh, 0.0).x, hammer(0.0, hv).y)),
            Projection::AlbersConic => {
                // Not symmetric: the box around the outline of the longitude/latitude
                // rectangle (the parallels are arcs, the meridians straight lines).
                let mut lo = Vec2::splat(f32::INFINITY);
                let mut hi = Vec2::splat(f32::NEG_INFINITY);
                const STEPS: usize = 256;
                for i in 0..=STEPS {
                    let t = i as f32 / STEPS as f32;
                    let lon = -hh + t * h;
                    let lat = -hv + t * v;
                    for (a, b) in [(lon, -hv), (lon, hv), (-hh, lat), (hh, lat)] {
                        if let Some(m) = map(projection, direction(a, b)) {
                            lo = lo.min(m);
                            hi = hi.max(m);
                        }
                    }
                }
                (0.5 * (lo + hi), 0.5 * (hi - lo))
            }
        };
        Self {
            projection,
            centre,
            half,
            fov: Vec2::new(h, v),
        }
    }

    /// The field of view shown (radians, horizontal and vertical), after clamping.
    pub fn fov(&self) -> Vec2 {
        self.fov
    }

    /// Image coordinates (NDC, y up) of a view-space direction; `None` where the projection
    /// has no image of it. Points outside [−1, 1] are outside the field of view.
    pub fn project(&self, d: Vec3) -> Option<Vec2> {
        map(self.projection, d).map(|m| (m - self.centre) / self.half)
    }

    /// The unit view-space direction shown at image coordinates `ndc`; `None` outside the
    /// projection's outline (the corners of a Hammer image, beyond 180° in azimuthal
    /// equidistant).
    pub fn unproject(&self, ndc: Vec2) -> Option<Vec3> {
        unmap(self.projection, self.centre + ndc * self.half)
    }

    /// Centre and half size of the field of view in map coordinates, as the shaders take them
    /// (`[centre.x, centre.y, half.x, half.y]`).
    pub fn map_window(&self) -> [f32; 4] {
        [self.centre.x, self.centre.y, self.half.x, self.half.y]
    }

    /// Width over height of the image that shows the field of view undistorted at its
    /// centre (equal scale on both axes).
    pub fn aspect(&self) -> f32 {
        self.half.x / self.half.y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn full(p: Projection) -> PanoProjection {
        let (h, v) = p.max_fov();
        PanoProjection::new(p, h, v)
    }

    #[test]
    fn names_round_trip() {
        for p in Projection::ALL {
            assert_eq!(Projection::from_name(p.name()), Some(p));
        }
        assert_eq!(Projection::from_name("mercator"), None);
    }

    #[test]
    fn ahead_is_the_image_centre() {
        for p in Projection::ALL {
            let q = full(p).project(Vec3::NEG_Z).expect("ahead");
            // Albers is not centred vertically: only x is 0 ahead.
            assert!(q.x.abs() < 1e-5, "{p:?}: {q}");
            if p != Projection::AlbersConic {
                assert!(q.y.abs() < 1e-5, "{p:?}: {q}");
            }
        }
    }

    #[test]
    fn known_points_land_where_the_formulas_say() {
        let eq = full(Projection::Equirectangular);
        // 90° to the right is halfway to the right edge of a 360° image; up is the top.
        assert!((eq.project(Vec3::X).expect("right") - Vec2::new(0.5, 0.0)).length() < 1e-5);
        assert!((eq.project(Vec3::Y).expect("up").y - 1.0).abs() < 1e-5);
        let hammer = full(Projection::Hammer);
        // The equator's ends and the poles touch the ellipse's edge.
        let behind_right = direction(PI - 1e-4, 0.0);
        assert!((hammer.project(behind_right).expect("behind").x - 1.0).abs() < 1e-3);
        assert!((hammer.project(Vec3::Y).expect("up").y - 1.0).abs() < 1e-5);
        let az = full(Projection::AzimuthalEquidistant);
        // Angle from ahead maps linearly to the radius: 90° is half way out.
        assert!((az.project(Vec3::X).expect("right") - Vec2::new(0.5, 0.0)).length() < 1e-5);
        assert!((az.project(Vec3::NEG_Y).expect("down") - Vec2::new(0.0, -0.5)).length() < 1e-5);
        let persp = PanoProjection::new(Projection::Perspective, FRAC_PI_2, FRAC_PI_2);
        let right_45 = direction(0.25 * PI, 0.0);
        assert!((persp.project(right_45).expect("45°").x - 1.0).abs() < 1e-5);
        assert_eq!(persp.project(Vec3::Z), None, "behind a camera");
    }

    #[test]
    fn unproject_inverts_project_over_the_field_of_view() {
        for p in Projection::ALL {
            let (max_h, max_v) = p.max_fov();
            for (h, v) in [(max_h, max_v), (0.5 * max_h, 0.6 * max_v)] {
                let pano = PanoProjection::new(p, h, v);
                let mut checked = 0;
                for i in 0..=24 {
                    for j in 0..=24 {
                        // Directions inside the field of view, short of its edge.
                        let lon = (i as f32 / 24.0 - 0.5) * 0.98 * h.min(2.0 * PI - 0.01);
                        let lat = (j as f32 / 24.0 - 0.5) * 0.98 * v.min(PI - 0.01);
                        let d = direction(lon, lat);
                        let Some(q) = pano.project(d) else {
                            continue;
                        };
                        let back = pano.unproject(q).unwrap_or_else(|| {
                            panic!("{p:?} {h} {v}: no direction at {q} (from {lon}, {lat})")
                        });
                        let angle = back.dot(d).clamp(-1.0, 1.0).acos();
                        // 1e-3 rad: f32 trigonometry on both ways, near the poles included.
                        assert!(
                            angle < 1e-3,
                            "{p:?}: ({lon:.3}, {lat:.3}) came back {angle} rad off"
                        );
                        checked += 1;
                    }
                }
                assert!(checked > 300, "{p:?}: only {checked} directions");
            }
        }
    }

    #[test]
    fn the_field_of_view_fills_the_image() {
        for p in [Projection::Equirectangular, Projection::Hammer] {
            let pano = PanoProjection::new(p, 2.0 * PI, PI);
            for (d, axis, want) in [
                (direction(PI - 1e-4, 0.0), 0, 1.0),
                (direction(-PI + 1e-4, 0.0), 0, -1.0),
                (Vec3::Y, 1, 1.0),
                (Vec3::NEG_Y, 1, -1.0),
            ] {
                let q = pano.project(d).expect("on the sphere");
                assert!((q[axis] - want).abs() < 1e-3, "{p:?}: {q}");
            }
            assert!(
                (pano.aspect() - 2.0).abs() < 1e-3,
                "{p:?}: aspect {}",
                pano.aspect()
            );
        }
        // Outside Hammer's ellipse there is nothing.
        let hammer = PanoProjection::new(Projection::Hammer, 2.0 * PI, PI);
        assert_eq!(hammer.unproject(Vec2::new(0.95, 0.95)), None);
    }
}
