//! When to split an edge (by depth, projected length or size, or how far it is drawn off).
//! Each decision depends on the edge alone.

use glam::Vec3;

use super::{Bary, TessView, point_position, project};

/// A split criterion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Criterion {
    /// Split every edge until depth N.
    Uniform(u32),
    /// Split while the projected edge is longer than this many pixels (Doggett & Hirche);
    /// x-length only on vertical walls, as the thesis does, full length on floor/ceiling.
    Edge(f32),
    /// Split while the projected diameter of the edge's bounding sphere exceeds this many
    /// pixels (Cantlay).
    Sphere(f32),
    /// Split while the projected midpoint lies more than this many pixels from the middle of
    /// the projected endpoints and a point of the edge (of three tested) is drawn more than
    /// this many pixels from where its eye sees it: bounds the error the viewer sees. See
    /// [`split_edge`]. The panorama (its own projection, `pano_split_edge` in the shader)
    /// applies the first test alone, in its pixels.
    Error(f32),
}

impl Criterion {
    /// Code used in the GPU uniforms (keep in sync with shaders/tessellate.wgsl).
    pub fn gpu_code(self) -> (u32, f32) {
        match self {
            Criterion::Uniform(n) => (1, n as f32),
            Criterion::Edge(px) => (2, px),
            Criterion::Sphere(px) => (3, px),
            Criterion::Error(px) => (4, px),
        }
    }
}

impl std::fmt::Display for Criterion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Criterion::Uniform(n) => write!(f, "uniform:{n}"),
            Criterion::Edge(px) => write!(f, "edge:{px}"),
            Criterion::Sphere(px) => write!(f, "sphere:{px}"),
            Criterion::Error(px) => write!(f, "error:{px}"),
        }
    }
}

/// Parses `none`, `uniform:N`, `edge:PX`, `sphere:PX` or `error:PX`.
pub fn parse_criterion(s: &str) -> Result<Option<Criterion>, String> {
    let s = s.trim();
    if s == "none" {
        return Ok(None);
    }
    let (kind, value) = s.split_once(':').ok_or_else(|| {
        format!("expected none, uniform:N, edge:PX, sphere:PX or error:PX, got '{s}'")
    })?;
    let px = || -> Result<f32, String> {
        let v: f32 = value
            .parse()
            .map_err(|_| format!("'{value}' is not a number of pixels in '{s}'"))?;
        if v.is_finite() && (0.01..=10_000.0).contains(&v) {
            Ok(v)
        } else {
            Err(format!("{v} pixels is outside 0.01..=10000 in '{s}'"))
        }
    };
    match kind {
        "uniform" => {
            let n: u32 = value
                .parse()
                .map_err(|_| format!("'{value}' is not a whole number of levels in '{s}'"))?;
            if n > super::MAX_DEPTH_LIMIT {
                return Err(format!(
                    "uniform level {n} exceeds the limit of {}",
                    super::MAX_DEPTH_LIMIT
                ));
            }
            Ok(Some(Criterion::Uniform(n)))
        }
        "edge" => Ok(Some(Criterion::Edge(px()?))),
        "sphere" => Ok(Some(Criterion::Sphere(px()?))),
        "error" => Ok(Some(Criterion::Error(px()?))),
        _ => Err(format!(
            "unknown criterion '{kind}' in '{s}'; expected none, uniform, edge, sphere or error"
        )),
    }
}

/// Tessellation settings of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TessSettings {
    /// `None`: no tessellation (the plain warp).
    pub criterion: Option<Criterion>,
    /// Deepest subdivision: 12 gives up to 4096 segments per edge. Hardware tessellators stop
    /// at 64 (depth 6), which leaves a large quad (the city's 640 m ground) visibly bent near
    /// the viewer; the criteria stop far earlier wherever the picture allows. An edge that
    /// runs behind the viewer is split towards where it leaves the view whatever the
    /// criterion, down to this depth: at 10 (segments of 0.6 m on the city's ground) the
    /// last one still misses the exact curve by 2.5 px at 480×270 with the head near a
    /// corner, at 12 by 0.55 px.
    pub max_depth: u32,
    pub backface_cull: bool,
    pub frustum_cull: bool,
    /// Clusters whose warp error is provably below the criterion (see `tess::clusters`) are
    /// drawn through the ordinary path; only the rest are tessellated.
    pub skip_fine: bool,
    /// Both eyes of a wall share one refinement (see [`super::EyeShare`]).
    pub shared_eyes: bool,
}

impl Default for TessSettings {
    fn default() -> Self {
        Self {
            criterion: None,
            max_depth: 12,
            backface_cull: true,
            frustum_cull: true,
            skip_fine: true,
            shared_eyes: true,
        }
    }
}

/// Whether the wall counts as vertical (then edge lengths are measured along x only).
pub fn is_vertical_wall(tv: &TessView<'_>) -> bool {
    wall_is_vertical(tv.wall)
}

/// A wall whose normal is closer to horizontal than to vertical (not a floor or ceiling).
pub fn wall_is_vertical(wall: &crate::cave::Wall) -> bool {
    wall.normal().y.abs() < 0.5
}

/// Decides whether the edge `a`→`b` of a source triangle with scene-space corners `p` is
/// split in round `depth`: where any eye of `tv` asks (one, or both eyes of a wall sharing
/// one refinement). A pure function of the edge: both triangles sharing it agree.
pub fn split_edge(
    tv: &TessView<'_>,
    criterion: &Criterion,
    depth: u32,
    p: [Vec3; 3],
    a: Bary,
    b: Bary,
) -> bool {
    tv.eyes()
        .any(|eye| split_edge_for_eye(&eye, criterion, depth, p, a, b))
}

/// [`split_edge`] for one eye.
fn split_edge_for_eye(
    tv: &TessView<'_>,
    criterion: &Criterion,
    depth: u32,
    p: [Vec3; 3],
    a: Bary,
    b: Bary,
) -> bool {
    if let Criterion::Uniform(n) = criterion {
        return depth < *n;
    }
    let pa = point_position(p, a);
    let pb = point_position(p, b);
    let ja = project(tv, pa);
    let jb = project(tv, pb);
    let (va, vb) = (ja.clip.w > tv.near, jb.clip.w > tv.near);
    if !va && !vb {
        // Wholly behind the projective viewpoint: invisible on this wall.
        return false;
    }
    if va != vb {
        // Crosses behind the viewpoint: refine towards the clip boundary, unless the part in
        // front (from the visible end to where the drawn edge is clipped, and the midpoint if
        // in front) lies wholly beyond one side of the view, with the frustum cull's margin.
        // Without this test the strips along the viewpoint's plane, mostly far outside the
        // image, double with every level up to the maximum depth.
        // Computed from the visible end, whichever order the edge comes in: both triangles
        // sharing the edge must reach the same answer bit for bit (no T-junctions).
        let (seen, hidden) = if va {
            (ja.clip, jb.clip)
        } else {
            (jb.clip, ja.clip)
        };
        let t = (tv.near - seen.w) / (hidden.w - seen.w);
        let cut = seen + t * (hidden - seen);
        let m = project(tv, point_position(p, a.midpoint(b))).clip;
        let m_seen = if m.w > tv.near { m } else { seen };
        return !super::all_outside_by(&[seen, cut, m_seen], tv.near, super::CULL_MARGIN);
    }
    let mid = project(tv, point_position(p, a.midpoint(b)));
    if super::all_outside(&[ja.clip, jb.clip, mid.clip], tv.near) {
        // Entirely beyond one side of the view: invisible, whatever its (huge, near the
        // viewpoint's plane) projected size. Without this every criterion refines what
        // nobody sees until the budget runs out.
        return false;
    }
    match criterion {
        Criterion::Uniform(_) => unreachable!("handled above"),
        Criterion::Edge(px) => {
            let d = jb.pixel - ja.pixel;
            let len = if is_vertical_wall(tv) {
                d.x.abs()
            } else {
                d.length()
            };
            len > *px
        }
        Criterion::Sphere(px) => {
            let (ca, cb) = (
                tv.cave_from_world.transform_point3(pa),
                tv.cave_from_world.transform_point3(pb),
            );
            let radius = 0.5 * (cb - ca).length();
            let centre = project(tv, 0.5 * (pa + pb));
            if centre.clip.w <= tv.near {
                return true;
            }
            let px_per_m = tv.wall.resolution[0] as f32 / tv.wall.size_m().x;
            let wall_distance = tv.wall.signed_distance(tv.view.eye_position);
            2.0 * radius * wall_distance / centre.clip.w * px_per_m > *px
        }
        Criterion::Error(px) => {
            if mid.clip.w <= tv.near {
                return true;
            }
            // First the midpoint against the chord's middle: what the load-time cluster bound
            // proves small (see `tess::clusters`), so that a cluster it passes would split no
            // edge here either. Only edges failing it go on to the second test.
            if (mid.pixel - 0.5 * (ja.pixel + jb.pixel)).length() <= *px {
                return false;
            }
            // Then where points are drawn against where their eyes see them. The chord test
            // alone also splits edges whose image is straight but foreshortened (a floor seen
            // at a grazing angle): perspective moves the midpoint's image along the line,
            // which the rasteriser's perspective-correct interpolation already draws right.
            drawn_off_by_more_than(tv, pa, pb, ja.clip, jb.clip, *px)
        }
    }
}

/// Where along an edge the `error` criterion compares the drawn point with the seen one, as
/// fractions of the drawn edge on screen. One sample (the midpoint) misses an edge close to
/// the viewer, whose error peaks towards its near end; and samples evenly spaced along the
/// edge in the scene miss a long one, whose near end perspective crowds into its last few
/// pixels on screen (the city's ground diagonal runs 450 m up to the viewer). Measured on the
/// bundled scenes at 480×270, every bench case: the midpoint alone leaves 3.1 px in the
/// living room at `error:1`; a quarter, half and three quarters of the scene's length leave
/// 1.2 px on the city at `error:2` (depth 12); these, 0.55 px. Keep in sync with
/// shaders/tessellate.wgsl (tests/gpu_layout.rs checks).
pub const ERROR_SAMPLES: [f32; 3] = [0.25, 0.5, 0.75];

/// Whether a point of the edge `pa`–`pb` (drawn at clip `ca`, `cb`, both in front of the
/// near plane) at any of [`ERROR_SAMPLES`] is drawn more than `px` pixels from where it is
/// seen. The point drawn a fraction σ of the way along the drawn edge is the clip-space
/// interpolation at s = σ·w₀ / ((1 − σ)·w₁ + σ·w₀) (perspective-correct interpolation), and
/// the scene point it stands for is the same fraction s of the edge; it is seen where its own
/// eye and warp project it. Computed from the endpoint that sorts first, so that both
/// triangles sharing the edge decide alike, bit for bit.
fn drawn_off_by_more_than(
    tv: &TessView<'_>,
    pa: Vec3,
    pb: Vec3,
    ca: glam::Vec4,
    cb: glam::Vec4,
    px: f32,
) -> bool {
    let ((p0, c0), (p1, c1)) = if super::position_order(pb, pa) {
        ((pb, cb), (pa, ca))
    } else {
        ((pa, ca), (pb, cb))
    };
    ERROR_SAMPLES.iter().any(|&sigma| {
        let s = sigma * c0.w / ((1.0 - sigma) * c1.w + sigma * c0.w);
        let seen = project(tv, p0 + s * (p1 - p0));
        if seen.clip.w <= tv.near {
            return true;
        }
        let drawn = super::clip_to_pixel(c0 + s * (c1 - c0), tv.wall.resolution);
        (seen.pixel - drawn).length() > px
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn criteria_parse_and_print() {
        for s in ["uniform:3", "edge:8", "sphere:12.5", "error:0.5"] {
            let c = parse_criterion(s).expect(s).expect("some");
            assert_eq!(c.to_string(), s);
        }
        assert_eq!(parse_criterion("none"), Ok(None));
        for bad in [
            "error",
            "error:-1",
            "error:nan",
            "uniform:99",
            "blob:3",
            "edge:x",
        ] {
            assert!(parse_criterion(bad).is_err(), "{bad}");
        }
    }
}
