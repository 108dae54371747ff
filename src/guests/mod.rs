//! Where guests may stand: the disparity distortion a viewer away from the assumed head sees,
//! per render method, by the ray-intersection model of stereoscopic viewing (Woods et al.
//! 1993; Held & Banks 2008). No GPU types: `omnicave guests`, the panel's floor map and
//! `render --viewer` all use this.
//!
//! A method draws a scene point P on the walls at S_L, S_R: where the ray from the eye that
//! the method assigns to P meets the first wall. A viewer whose cyclopean eye is at G, eyes
//! G_L, G_R on a horizontal axis (perpendicular to the direction from G to P when the viewer
//! looks at P), sees the rays G_L→S_L and G_R→S_R. The viewer perceives P′, the midpoint of
//! the shortest segment between the two rays. Angles are measured in the viewer's head frame
//! in Helmholtz coordinates (elevation: the rotation about the eye axis; lateral angle: the
//! angle from the plane perpendicular to it), where two rays meet exactly when their
//! elevations are equal: the vertical disparity is that difference.

pub mod grid;
pub mod heatmap;
pub mod points;
pub mod report;
pub mod reproject;
pub mod sweep;

use glam::{DVec3, Vec3};

use crate::cave::omni::{PoleMerge, pole_merge_factor};
use crate::cave::{Cave, Eye, Head, RenderMode, Wall};

/// Arc minutes in a radian.
pub const ARCMIN_PER_RADIAN: f64 = 60.0 * 180.0 / std::f64::consts::PI;

const UP: DVec3 = DVec3::Y;

/// Where the method assumes the head is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Assumed {
    /// The tracked head (the config's `[head]`, or `--head`).
    Head,
    /// The middle of the CAVE's floor at the tracked head's eye height: the untracked set-up
    /// for a group.
    Centre,
}

crate::named_enum!(Assumed {
    Self::Head => "head",
    Self::Centre => "centre",
});

/// One way of rendering: a render mode and where it assumes the head to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Method {
    pub mode: RenderMode,
    pub assumed: Assumed,
}

impl Method {
    /// `mode@assumed`, e.g. `omni-onaxis@centre`.
    pub fn name(&self) -> String {
        format!("{}@{}", self.mode.name(), self.assumed.name())
    }

    /// Parses `mode` (the tracked head assumed) or `mode@head|centre`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let (mode, assumed) = s.split_once('@').unwrap_or((s, "head"));
        let mode = RenderMode::from_name(mode.trim()).ok_or_else(|| {
            format!(
                "unknown render mode '{mode}' in method '{s}' (one of: {})",
                RenderMode::NAMES.join(", ")
            )
        })?;
        let assumed = Assumed::from_name(assumed.trim()).ok_or_else(|| {
            format!("unknown assumed head '{assumed}' in method '{s}' (head or centre)")
        })?;
        Ok(Self { mode, assumed })
    }

    /// The methods a lab chooses between for a group: tracked stereo, fixed-direction stereo
    /// and omnistereo for the tracked head, and omnistereo from the CAVE's centre.
    pub fn defaults() -> Vec<Method> {
        let m = |mode, assumed| Method { mode, assumed };
        vec![
            m(RenderMode::TrackedStereo, Assumed::Head),
            m(RenderMode::Stereo, Assumed::Head),
            m(RenderMode::OmniOnAxis, Assumed::Head),
            m(RenderMode::OmniOffAxis, Assumed::Head),
            m(RenderMode::OmniOnAxis, Assumed::Centre),
        ]
    }

    /// The two omnistereo modes draw every point where the same per-point eyes see it (they
    /// differ only in how a triangle is rasterised, which the bench measures), so their maps
    /// are one computation.
    pub fn eye_rule(&self) -> (RenderMode, Assumed) {
        let mode = match self.mode {
            RenderMode::OmniOffAxis => RenderMode::OmniOnAxis,
            m => m,
        };
        (mode, self.assumed)
    }
}

/// A wall in double precision: its corner, its edge vectors and its pixel grid.
#[derive(Debug, Clone, PartialEq)]
struct WallGeometry {
    origin: DVec3,
    right: DVec3,
    up: DVec3,
    /// Unit normal towards the viewer.
    normal: DVec3,
    resolution: [u32; 2],
}

impl WallGeometry {
    fn of(wall: &Wall) -> Self {
        let origin = wall.lower_left.as_dvec3();
        let right = wall.lower_right.as_dvec3() - origin;
        let up = wall.upper_left.as_dvec3() - origin;
        Self {
            origin,
            right,
            up,
            normal: right.cross(up).normalize(),
            resolution: wall.resolution,
        }
    }

    fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p - self.origin)
    }

    /// Where the ray from `eye` through `p` meets this wall, as the distance parameter along
    /// `p − eye` and the wall's (u, v) in 0..1, if it meets the rectangle going forwards.
    fn hit(&self, eye: DVec3, p: DVec3) -> Option<(f64, [f64; 2])> {
        let se = self.signed_distance(eye);
        let toward = self.normal.dot(p - eye);
        if se <= 0.0 || toward >= 0.0 {
            return None;
        }
        let t = -se / toward;
        let x = eye + t * (p - eye) - self.origin;
        let u = x.dot(self.right) / self.right.length_squared();
        let v = x.dot(self.up) / self.up.length_squared();
        ((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)).then_some((t, [u, v]))
    }

    fn point(&self, uv: [f64; 2]) -> DVec3 {
        self.origin + uv[0] * self.right + uv[1] * self.up
    }

    /// `uv` moved to the centre of the pixel it falls in.
    fn snap(&self, uv: [f64; 2]) -> [f64; 2] {
        let snap = |x: f64, n: u32| {
            let n = f64::from(n.max(1));
            ((x * n).floor().min(n - 1.0) + 0.5) / n
        };
        [
            snap(uv[0], self.resolution[0]),
            snap(uv[1], self.resolution[1]),
        ]
    }
}

/// What the map is computed for: the CAVE, the tracked head, the eyes and pole merge.
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    walls: Vec<WallGeometry>,
    /// Where a viewer may stand: [`Cave::head_bounds`] (the open side of a three-wall CAVE
    /// ends with the walls).
    bounds: (DVec3, DVec3),
    /// The tracked head.
    pub head: Head,
    /// The assumed head of [`Assumed::Centre`].
    pub centre: DVec3,
    pub ipd: f64,
    pub stereo_view_direction: Vec3,
    pub pole_merge: Option<PoleMerge>,
    /// Draw wall points at their pixel's centre (the quantisation a wall's resolution adds).
    pub quantise: bool,
}

impl Setup {
    pub fn new(cave: &Cave, head: Head, ipd: f64, pole_merge: Option<PoleMerge>) -> Self {
        let mid = Cave::bounding_centre(&cave.walls).as_dvec3();
        let (lo, hi) = Cave::head_bounds(&cave.walls);
        Self {
            walls: cave.walls.iter().map(WallGeometry::of).collect(),
            bounds: (lo.as_dvec3(), hi.as_dvec3()),
            head,
            centre: DVec3::new(mid.x, f64::from(head.position.y), mid.z),
            ipd,
            stereo_view_direction: cave.stereo_view_direction,
            pole_merge,
            quantise: false,
        }
    }

    /// Whether `g` is inside the head bounds (on the floor plan) and at least `margin` metres
    /// in front of every wall.
    pub fn inside(&self, g: DVec3, margin: f64) -> bool {
        let (lo, hi) = self.bounds;
        (lo.x..=hi.x).contains(&g.x)
            && (lo.z..=hi.z).contains(&g.z)
            && self.walls.iter().all(|w| w.signed_distance(g) > margin)
    }

    /// The head `method` renders for (its orientation is the tracked head's).
    pub fn assumed_head(&self, assumed: Assumed) -> Head {
        match assumed {
            Assumed::Head => self.head,
            Assumed::Centre => Head {
                position: self.centre.as_vec3(),
                orientation: self.head.orientation,
            },
        }
    }

    /// Where the ray from `eye` through `p` meets the first wall (at its pixel's centre when
    /// quantising), or `None` where it meets no wall.
    pub fn wall_point(&self, eye: DVec3, p: DVec3) -> Option<DVec3> {
        let (wall, _, uv) = self
            .walls
            .iter()
            .filter_map(|w| w.hit(eye, p).map(|(t, uv)| (w, t, uv)))
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        Some(wall.point(if self.quantise { wall.snap(uv) } else { uv }))
    }

    /// The eyes `method` renders `p` for (left, right).
    pub fn method_eyes(&self, method: Method, p: DVec3) -> [DVec3; 2] {
        let head = self.assumed_head(method.assumed);
        let h = head.position.as_dvec3();
        match method.mode {
            RenderMode::Mono => [h; 2],
            // As `cave::eye_positions` places them, in double precision.
            RenderMode::Stereo => {
                let d = self.stereo_view_direction.as_dvec3();
                let left = UP
                    .cross(DVec3::new(d.x, 0.0, d.z))
                    .try_normalize()
                    .unwrap_or(DVec3::NEG_X);
                [h + 0.5 * self.ipd * left, h - 0.5 * self.ipd * left]
            }
            RenderMode::TrackedStereo => {
                // The f32 quaternion is unit only to 1e-7, which would scale the IPD.
                let right = (head.orientation.as_dquat().normalize() * DVec3::X).normalize();
                [h - 0.5 * self.ipd * right, h + 0.5 * self.ipd * right]
            }
            RenderMode::OmniOnAxis | RenderMode::OmniOffAxis => {
                Eye::BOTH.map(|eye| omni_eye(h, p, self.ipd, eye, self.pole_merge))
            }
        }
    }

    /// Where `method` draws `p` for the left and right eye, if it draws it on a wall for both.
    pub fn shown_at(&self, method: Method, p: DVec3) -> Option<[DVec3; 2]> {
        let [l, r] = self.method_eyes(method, p);
        Some([self.wall_point(l, p)?, self.wall_point(r, p)?])
    }
}

/// [`crate::cave::omni::omni_eye`] in double precision (the model's tests resolve 1e-6 m).
pub fn omni_eye(head: DVec3, p: DVec3, ipd: f64, eye: Eye, pole: Option<PoleMerge>) -> DVec3 {
    let d = p - head;
    let len = (d.x * d.x + d.z * d.z).sqrt();
    let elevation = d.y.abs().atan2(len);
    let dir = if len > 1e-12 {
        DVec3::new(d.x / len, 0.0, d.z / len)
    } else {
        DVec3::NEG_Z
    };
    let right = dir.cross(UP);
    let keep = f64::from(pole_merge_factor(elevation as f32, pole));
    head + f64::from(eye.sign()) * 0.5 * ipd * keep * right
}

/// Which way the viewer's head faces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gaze {
    /// Towards each point judged (the model's viewer, who looks at what they judge).
    AtPoint,
    /// Along this horizontal direction whatever the point (a fixed head, as a camera is).
    Along(DVec3),
}

/// How one point looks to one viewer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Judged {
    /// Elevation of S_L from G_L minus that of S_R from G_R, arc minutes (0: the rays meet).
    pub vertical_arcmin: f64,
    /// The angle at the cyclopean eye between P and P′, arc minutes.
    pub direction_arcmin: f64,
    /// |P′ − G| / |P − G|: 1 is the right depth; infinite where the rays do not converge.
    pub depth_ratio: f64,
    /// The rays' horizontal disparity minus that of the true point's rays, arc minutes.
    pub horizontal_arcmin: f64,
    /// The perceived point, where the rays converge in front of the viewer.
    pub perceived: Option<DVec3>,
}

/// The viewer's eyes (left, right) and forward direction for looking at `p` from `g`, or
/// `None` when `p` is straight above or below (no horizontal eye axis faces it).
pub fn viewer_eyes(g: DVec3, ipd: f64, gaze: Gaze, p: DVec3) -> Option<([DVec3; 2], DVec3)> {
    let ahead = match gaze {
        Gaze::AtPoint => p - g,
        Gaze::Along(d) => d,
    };
    let forward = DVec3::new(ahead.x, 0.0, ahead.z).try_normalize()?;
    let right = forward.cross(UP);
    Some(([g - 0.5 * ipd * right, g + 0.5 * ipd * right], forward))
}

/// The ray-intersection model for one point `p` drawn at `shown` (S_L, S_R) and a viewer at
/// `g`: `None` where the viewer cannot see it (straight above or below, or drawn behind the
/// viewer's frontal plane).
pub fn judge(g: DVec3, ipd: f64, gaze: Gaze, p: DVec3, shown: [DVec3; 2]) -> Option<Judged> {
    let ([gl, gr], forward) = viewer_eyes(g, ipd, gaze, p)?;
    let right = forward.cross(UP);
    let (dl, dr) = (shown[0] - gl, shown[1] - gr);
    if dl.dot(forward) <= 0.0 || dr.dot(forward) <= 0.0 {
        return None;
    }
    let elevation = |d: DVec3| d.y.atan2(d.dot(forward));
    let lateral = |d: DVec3| (d.dot(right) / d.length()).clamp(-1.0, 1.0).asin();
    let vertical = elevation(dl) - elevation(dr);
    let horizontal = (lateral(dl) - lateral(dr)) - (lateral(p - gl) - lateral(p - gr));
    let perceived = closest_midpoint(gl, dl, gr, dr);
    let seen_direction = match perceived {
        Some(q) => q - g,
        // Parallel or diverging rays: seen at infinity, along their mean direction.
        None => dl.normalize() + dr.normalize(),
    };
    let truth = p - g;
    let direction = truth
        .cross(seen_direction)
        .length()
        .atan2(truth.dot(seen_direction));
    let depth_ratio = perceived.map_or(f64::INFINITY, |q| (q - g).length() / truth.length());
    Some(Judged {
        vertical_arcmin: vertical * ARCMIN_PER_RADIAN,
        direction_arcmin: direction * ARCMIN_PER_RADIAN,
        depth_ratio,
        horizontal_arcmin: horizontal * ARCMIN_PER_RADIAN,
        perceived,
    })
}

/// The midpoint of the shortest segment between the rays a + s·da and b + t·db (s, t > 0),
/// or `None` where they are parallel or meet behind the eyes.
pub fn closest_midpoint(a: DVec3, da: DVec3, b: DVec3, db: DVec3) -> Option<DVec3> {
    let w = a - b;
    let (aa, ab, bb) = (da.dot(da), da.dot(db), db.dot(db));
    let (aw, bw) = (da.dot(w), db.dot(w));
    let denom = aa * bb - ab * ab;
    if denom <= 1e-15 * aa * bb {
        return None;
    }
    let s = (ab * bw - bb * aw) / denom;
    let t = (aa * bw - ab * aw) / denom;
    (s > 0.0 && t > 0.0).then(|| 0.5 * ((a + s * da) + (b + t * db)))
}

#[cfg(test)]
mod tests;
