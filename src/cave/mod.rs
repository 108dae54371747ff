//! The CAVE model: walls, head, eye placement and per-wall projections (pure math, no GPU).
//!
//! Conventions (shared with config, CLI and tests): CAVE space is right-handed, in metres, origin
//! at the centre of the CAVE floor, +x towards the right wall, +y up, −z towards the front wall.

pub mod omni;
pub mod placement;
mod projection;
pub mod wand;

pub use projection::{WallProjection, off_axis_projection};

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};

/// World up in CAVE space.
pub const UP: Vec3 = Vec3::Y;

/// One projection screen: a planar rectangle given by three corners, plus its pixel size.
#[derive(Debug, Clone, PartialEq)]
pub struct Wall {
    /// Name used for output files and the UI (`left`, `front`, `right`, …).
    pub name: String,
    /// Lower-left corner, CAVE space (metres).
    pub lower_left: Vec3,
    /// Lower-right corner.
    pub lower_right: Vec3,
    /// Upper-left corner.
    pub upper_left: Vec3,
    /// Pixel size (width, height) of the image shown on this wall.
    pub resolution: [u32; 2],
}

impl Wall {
    /// Unit vector along the wall's bottom edge (screen +x).
    pub fn right_axis(&self) -> Vec3 {
        (self.lower_right - self.lower_left).normalize()
    }

    /// Unit vector along the wall's left edge (screen +y).
    pub fn up_axis(&self) -> Vec3 {
        (self.upper_left - self.lower_left).normalize()
    }

    /// Unit normal pointing out of the screen, towards the viewer inside the CAVE.
    pub fn normal(&self) -> Vec3 {
        self.right_axis().cross(self.up_axis()).normalize()
    }

    /// Physical width and height in metres.
    pub fn size_m(&self) -> Vec2 {
        Vec2::new(
            (self.lower_right - self.lower_left).length(),
            (self.upper_left - self.lower_left).length(),
        )
    }

    /// The four corners: lower left, lower right, upper right, upper left.
    pub fn corners(&self) -> [Vec3; 4] {
        let up = self.upper_left - self.lower_left;
        [
            self.lower_left,
            self.lower_right,
            self.lower_right + up,
            self.upper_left,
        ]
    }

    /// Centre of the wall rectangle.
    pub fn centre(&self) -> Vec3 {
        self.lower_left
            + 0.5 * (self.lower_right - self.lower_left)
            + 0.5 * (self.upper_left - self.lower_left)
    }

    /// Signed distance of `p` from the wall plane, positive on the viewer's side.
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        (p - self.lower_left).dot(self.normal())
    }

    /// Where the ray from `eye` through `point` meets the wall plane, in pixel coordinates
    /// (x right, y down, origin at the top-left corner of the image, pixel centres at +0.5).
    ///
    /// This is the CPU reference for "where does this point appear on this wall": it does not use
    /// any projection matrix, so tests can check the matrices against it. Returns `None` when the
    /// point is not in front of the eye as seen through this wall (ray parallel to the plane, or
    /// the intersection lies behind the eye). Points outside the rectangle still give coordinates
    /// (outside `0..width`, `0..height`).
    pub fn pixel_of_ray(&self, eye: Vec3, point: Vec3) -> Option<Vec2> {
        let n = self.normal();
        let dir = point - eye;
        let denom = dir.dot(n);
        if denom.abs() < 1e-9 {
            return None;
        }
        // Eye is on the positive side; the ray must travel towards the wall (t > 0).
        let t = (self.lower_left - eye).dot(n) / denom;
        if t.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !t.is_finite() {
            return None;
        }
        let hit = eye + t * dir;
        Some(self.pixel_of_wall_point(hit))
    }

    /// Pixel coordinates (x right, y down) of a point lying on the wall plane.
    pub fn pixel_of_wall_point(&self, p: Vec3) -> Vec2 {
        let size = self.size_m();
        let local = p - self.lower_left;
        let u = local.dot(self.right_axis()) / size.x;
        let v = local.dot(self.up_axis()) / size.y;
        Vec2::new(
            u * self.resolution[0] as f32,
            (1.0 - v) * self.resolution[1] as f32,
        )
    }

    /// The point on the wall plane at pixel coordinates (x right, y down).
    pub fn wall_point_of_pixel(&self, pixel: Vec2) -> Vec3 {
        let u = pixel.x / self.resolution[0] as f32;
        let v = 1.0 - pixel.y / self.resolution[1] as f32;
        self.lower_left
            + u * (self.lower_right - self.lower_left)
            + v * (self.upper_left - self.lower_left)
    }
}

/// An edge two walls share (CAVE space).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seam {
    pub walls: [usize; 2],
    pub from: Vec3,
    pub to: Vec3,
}

/// The CAVE: its walls and the viewer-independent settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Cave {
    pub walls: Vec<Wall>,
    /// Near and far clip distances (metres) of every wall's projection.
    pub near: f32,
    pub far: f32,
    /// Horizontal view direction assumed by fixed-direction stereo (normally ⟂ the front wall).
    pub stereo_view_direction: Vec3,
    /// Fixed projective viewpoint of the on-axis omnistereo warp (normally the CAVE's centre).
    pub projection_centre: Vec3,
}

/// A head is kept this far inside the walls.
pub const HEAD_MARGIN_M: f32 = 0.05;

impl Cave {
    /// The default on-axis projective viewpoint: the centre of the walls' bounding box (the
    /// room's centre) when it lies at least 1 cm in front of every wall; otherwise (a single
    /// wall, walls in a row) the mean of the points half a wall-width in front of each wall's
    /// centre.
    pub fn default_projection_centre(walls: &[Wall]) -> Vec3 {
        let centre = Self::bounding_centre(walls);
        if walls.iter().all(|w| w.signed_distance(centre) >= 0.01) {
            return centre;
        }
        let sum: Vec3 = walls
            .iter()
            .map(|w| w.centre() + 0.5 * w.size_m().x * w.normal())
            .sum();
        sum / walls.len().max(1) as f32
    }

    /// Where a head may be: the walls' bounding box less [`HEAD_MARGIN_M`] (flat axes, as of
    /// a single wall, are unbounded). The tracking gate and the head's clamp use it.
    pub fn head_bounds(walls: &[Wall]) -> (Vec3, Vec3) {
        let (min, max) = Self::bounding_box(walls);
        let margin = Vec3::splat(HEAD_MARGIN_M);
        let mut lo = min + margin;
        let mut hi = (max - margin).max(lo);
        for axis in 0..3 {
            if max[axis] - min[axis] <= 2.0 * HEAD_MARGIN_M {
                lo[axis] = f32::NEG_INFINITY;
                hi[axis] = f32::INFINITY;
            }
        }
        (lo, hi)
    }

    /// The walls' axis-aligned bounding box (min, max corners; inverted infinities for no
    /// walls).
    pub fn bounding_box(walls: &[Wall]) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for w in walls {
            for p in w.corners() {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        (lo, hi)
    }

    /// Centre of the walls' bounding box.
    pub fn bounding_centre(walls: &[Wall]) -> Vec3 {
        if walls.is_empty() {
            return Vec3::ZERO;
        }
        let (lo, hi) = Self::bounding_box(walls);
        0.5 * (lo + hi)
    }

    /// Why a head at `p` cannot be rendered for, if it cannot: it must be in front of every
    /// wall (for a closed CAVE: inside it), or that wall's image has no meaning.
    pub fn head_problem(&self, p: Vec3) -> Option<String> {
        if !p.is_finite() {
            return Some("is not finite".into());
        }
        self.walls
            .iter()
            .find(|w| w.signed_distance(p) <= 0.0)
            .map(|w| {
                format!(
                    "is behind or on wall '{}' ({:.3} m); the head must be in front of every wall",
                    w.name,
                    w.signed_distance(p)
                )
            })
    }

    /// Pairs of walls that share an edge (two corners within 1 mm), with the shared edge's
    /// ends: where a scene edge must continue from one wall's image to the other's.
    pub fn seams(&self) -> Vec<Seam> {
        let mut seams = Vec::new();
        for (a, wa) in self.walls.iter().enumerate() {
            for (b, wb) in self.walls.iter().enumerate().skip(a + 1) {
                let shared: Vec<Vec3> = wa
                    .corners()
                    .into_iter()
                    .filter(|p| wb.corners().iter().any(|q| p.distance(*q) < 1e-3))
                    .collect();
                if let [from, to] = shared[..] {
                    seams.push(Seam {
                        walls: [a, b],
                        from,
                        to,
                    });
                }
            }
        }
        seams
    }

    /// Index of the wall with this name.
    pub fn wall_index(&self, name: &str) -> Option<usize> {
        self.walls.iter().position(|w| w.name == name)
    }
}

/// The tracked (or assumed) head: position and orientation in CAVE space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Head {
    pub position: Vec3,
    /// Orientation; identity looks down −z (towards the front wall) with +y up.
    pub orientation: Quat,
}

impl Head {
    /// A head at `position` looking towards the front wall.
    pub fn at(position: Vec3) -> Self {
        Self {
            position,
            orientation: Quat::IDENTITY,
        }
    }

    /// Orientation from yaw (about +y, positive turns left), pitch (about the head's x, positive
    /// looks up) and roll (about the view axis), all in degrees.
    pub fn orientation_from_degrees(yaw: f32, pitch: f32, roll: f32) -> Quat {
        Quat::from_rotation_y(yaw.to_radians())
            * Quat::from_rotation_x(pitch.to_radians())
            * Quat::from_rotation_z(roll.to_radians())
    }
}

/// How the eyes are placed for a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RenderMode {
    /// One image per wall, seen from the head position.
    Mono,
    /// Off-axis stereo with eyes placed for a fixed view direction (⟂ the front wall).
    Stereo,
    /// Off-axis stereo with eyes placed by the tracked head orientation (classic CAVE).
    TrackedStereo,
    /// Omnistereo: per-vertex eyes, warped towards the fixed CAVE centre, one on-axis
    /// projection per wall for both eyes (thesis 5.1).
    OmniOnAxis,
    /// Omnistereo: per-vertex eyes, warped towards the fixed-direction stereo eyes, off-axis
    /// projection per wall and eye (thesis 5.2).
    OmniOffAxis,
}

crate::named_enum!(RenderMode {
    Self::Mono => "mono",
    Self::Stereo => "stereo",
    Self::TrackedStereo => "tracked-stereo",
    Self::OmniOnAxis => "omni-onaxis",
    Self::OmniOffAxis => "omni-offaxis",
});

impl RenderMode {
    /// Whether the two eyes see different images.
    pub fn is_stereo(self) -> bool {
        !matches!(self, Self::Mono)
    }

    /// Whether vertices get their own eyes (omnidirectional stereo).
    pub fn is_omni(self) -> bool {
        matches!(self, Self::OmniOnAxis | Self::OmniOffAxis)
    }
}

/// Which eye an image is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Eye {
    Left,
    Right,
}

impl Eye {
    pub const BOTH: [Eye; 2] = [Eye::Left, Eye::Right];

    pub fn name(self) -> &'static str {
        match self {
            Eye::Left => "left",
            Eye::Right => "right",
        }
    }

    /// −1 for the left eye, +1 for the right: the eye sits at head + sign·(IPD/2)·right.
    pub fn sign(self) -> f32 {
        match self {
            Eye::Left => -1.0,
            Eye::Right => 1.0,
        }
    }
}

/// The horizontal unit vector pointing to the viewer's left when looking along `view_dir`
/// (`view_dir` need not be horizontal or normalised). `None` if `view_dir` is (nearly) vertical.
pub fn left_of(view_dir: Vec3) -> Option<Vec3> {
    let horizontal = Vec3::new(view_dir.x, 0.0, view_dir.z);
    let len = horizontal.length();
    if len < 1e-6 {
        return None;
    }
    Some(UP.cross(horizontal / len))
}

/// Eye positions for one frame, given the mode. For `Mono` both eyes are the head.
pub fn eye_positions(
    mode: RenderMode,
    head: &Head,
    ipd: f32,
    stereo_view_direction: Vec3,
) -> [Vec3; 2] {
    let half = 0.5 * ipd;
    match mode {
        RenderMode::Mono => [head.position; 2],
        // Omnistereo eyes are per vertex; these are the fixed-direction eyes, which the
        // off-axis warp uses as its projective viewpoints.
        RenderMode::Stereo | RenderMode::OmniOnAxis | RenderMode::OmniOffAxis => {
            // Config validation guarantees a horizontal direction; fall back to −z regardless.
            let left = left_of(stereo_view_direction).unwrap_or(Vec3::NEG_X);
            [head.position + half * left, head.position - half * left]
        }
        RenderMode::TrackedStereo => {
            let right = head.orientation * Vec3::X;
            [head.position - half * right, head.position + half * right]
        }
    }
}

/// One image to render: a wall seen from one centre of projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewSetup {
    pub wall: usize,
    /// `None` in mono (one image serves both eyes).
    pub eye: Option<Eye>,
    /// Centre of projection in CAVE space (in omnistereo: the projective viewpoint C).
    pub eye_position: Vec3,
    /// Clip space from CAVE space (wgpu conventions: depth 0..1, y up in NDC).
    pub clip_from_cave: Mat4,
    /// Near plane of `clip_from_cave` (metres along the wall normal): see [`view_near`].
    pub near: f32,
    /// In omnistereo: what the per-vertex eyes and the warp need.
    pub omni: Option<OmniView>,
}

/// Per-view data of the omnistereo warp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OmniView {
    pub head: Vec3,
    pub ipd: f32,
    /// The wall plane (n, d), s(X) = n·X + d, n towards the viewer.
    pub wall_plane: Vec4,
}

/// The near plane of a view whose centre of projection is `distance` from its wall: the
/// CAVE's, or half the distance where the centre is closer to the wall than that. A near
/// plane beyond the wall would cut away what lies just behind the wall, which fills the
/// image's borders when an eye is a few centimetres from the screen (the stability sweep's
/// heads 5 cm from a wall lost up to 14 % of their pixels). Never below 0.1 mm, which keeps
/// the matrix finite for an eye on the wall.
pub fn view_near(cave_near: f32, distance: f32) -> f32 {
    cave_near.min(0.5 * distance).max(1e-4)
}

/// The list of images a frame needs: per wall one (mono) or two (stereo) views.
pub fn view_setups(cave: &Cave, head: &Head, mode: RenderMode, ipd: f32) -> Vec<ViewSetup> {
    let eyes = eye_positions(mode, head, ipd, cave.stereo_view_direction);
    let mut views = Vec::with_capacity(cave.walls.len() * 2);
    for (wall_index, wall) in cave.walls.iter().enumerate() {
        let view = |eye: Option<Eye>, centre: Vec3| {
            let near = view_near(cave.near, wall.signed_distance(centre));
            ViewSetup {
                wall: wall_index,
                eye,
                eye_position: centre,
                clip_from_cave: off_axis_projection(wall, centre, near, cave.far).clip_from_cave,
                near,
                omni: mode.is_omni().then(|| OmniView {
                    head: head.position,
                    ipd,
                    wall_plane: omni::wall_plane(wall),
                }),
            }
        };
        if mode.is_stereo() {
            for eye in Eye::BOTH {
                let centre = match mode {
                    RenderMode::OmniOnAxis => cave.projection_centre,
                    _ => eyes[eye as usize],
                };
                views.push(view(Some(eye), centre));
            }
        } else {
            views.push(view(None, head.position));
        }
    }
    views
}

/// The default CAVE of the thesis (VRVis): three walls, 3.3 m × 3.3 m floor, 2.9 m high,
/// 1280×720 pixels each. Used by tests and as the documented reference; `config/cave.toml`
/// describes the same room.
pub fn thesis_cave() -> Cave {
    let h = 1.65;
    let top = 2.9;
    let res = [1280, 720];
    let walls = vec![
        Wall {
            name: "left".into(),
            lower_left: Vec3::new(-h, 0.0, h),
            lower_right: Vec3::new(-h, 0.0, -h),
            upper_left: Vec3::new(-h, top, h),
            resolution: res,
        },
        Wall {
            name: "front".into(),
            lower_left: Vec3::new(-h, 0.0, -h),
            lower_right: Vec3::new(h, 0.0, -h),
            upper_left: Vec3::new(-h, top, -h),
            resolution: res,
        },
        Wall {
            name: "right".into(),
            lower_left: Vec3::new(h, 0.0, -h),
            lower_right: Vec3::new(h, 0.0, h),
            upper_left: Vec3::new(h, top, -h),
            resolution: res,
        },
    ];
    Cave {
        projection_centre: Cave::default_projection_centre(&walls),
        walls,
        near: 0.05,
        far: 2000.0,
        stereo_view_direction: Vec3::NEG_Z,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_thesis_cave_has_two_vertical_seams() {
        let cave = thesis_cave();
        let seams = cave.seams();
        assert_eq!(seams.len(), 2, "{seams:?}");
        for s in &seams {
            // Vertical, the walls' full height.
            assert!((s.to - s.from).normalize().y.abs() > 0.999, "{s:?}");
            let names = s.walls.map(|w| cave.walls[w].name.as_str());
            assert!(names.contains(&"front"), "{names:?}");
        }
    }

    #[test]
    fn the_near_plane_stays_in_front_of_the_wall() {
        // Far from the wall: the CAVE's near plane; 2 cm from it: half that distance, so what
        // lies just behind the wall is not clipped; on it: still a finite, positive plane.
        assert_eq!(view_near(0.05, 1.5), 0.05);
        assert_eq!(view_near(0.05, 0.02), 0.01);
        assert_eq!(view_near(0.05, 0.0), 1e-4);
        let cave = thesis_cave();
        let head = Head::at(Vec3::new(1.6, 1.5, -1.6));
        for v in view_setups(&cave, &head, RenderMode::Stereo, 0.064) {
            let d = cave.walls[v.wall].signed_distance(v.eye_position);
            assert!(v.near < d && v.near > 0.0, "{v:?} is {d} m from its wall");
            assert!(v.clip_from_cave.is_finite());
        }
    }

    #[test]
    fn thesis_walls_face_the_centre() {
        let cave = thesis_cave();
        let centre = Vec3::new(0.0, 1.45, 0.0);
        for wall in &cave.walls {
            assert!(
                (wall.signed_distance(centre) - 1.65).abs() < 1e-5,
                "{}",
                wall.name
            );
        }
    }

    #[test]
    fn thesis_projection_centre_is_the_room_centre() {
        let c = thesis_cave().projection_centre;
        assert!((c - Vec3::new(0.0, 1.45, 0.0)).length() < 1e-6, "{c}");
    }

    #[test]
    fn a_single_wall_gets_a_projection_centre_in_front_of_it() {
        let front = thesis_cave().walls[1].clone();
        let c = Cave::default_projection_centre(std::slice::from_ref(&front));
        assert!((front.signed_distance(c) - 1.65).abs() < 1e-5, "{c}");
    }

    #[test]
    fn fixed_direction_eyes_are_split_along_x() {
        let head = Head::at(Vec3::new(0.2, 1.7, 0.1));
        let [l, r] = eye_positions(RenderMode::Stereo, &head, 0.064, Vec3::NEG_Z);
        assert!((l - Vec3::new(0.168, 1.7, 0.1)).length() < 1e-6);
        assert!((r - Vec3::new(0.232, 1.7, 0.1)).length() < 1e-6);
    }

    #[test]
    fn tracked_eyes_follow_yaw() {
        // Turning 90° left (facing −x, the left wall): the left eye moves towards +z.
        let head = Head {
            position: Vec3::new(0.0, 1.7, 0.0),
            orientation: Head::orientation_from_degrees(90.0, 0.0, 0.0),
        };
        let [l, r] = eye_positions(RenderMode::TrackedStereo, &head, 0.064, Vec3::NEG_Z);
        assert!((l - Vec3::new(0.0, 1.7, 0.032)).length() < 1e-6, "{l}");
        assert!((r - Vec3::new(0.0, 1.7, -0.032)).length() < 1e-6, "{r}");
    }

    #[test]
    fn pixel_round_trip() {
        let wall = &thesis_cave().walls[1];
        let p = Vec2::new(100.25, 600.5);
        let q = wall.pixel_of_wall_point(wall.wall_point_of_pixel(p));
        assert!((p - q).length() < 1e-3);
        // Top-left corner of the image is the upper-left wall corner.
        assert!(wall.pixel_of_wall_point(wall.upper_left).length() < 1e-4);
    }

    #[test]
    fn ray_behind_eye_is_rejected() {
        let wall = &thesis_cave().walls[1];
        let eye = Vec3::new(0.0, 1.5, 0.0);
        assert!(wall.pixel_of_ray(eye, Vec3::new(0.0, 1.5, 1.0)).is_none());
        assert!(wall.pixel_of_ray(eye, Vec3::new(0.0, 1.5, -5.0)).is_some());
    }
}
