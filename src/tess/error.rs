//! Accuracy of a tessellation as the viewer sees it (no GPU): the geometric error between the
//! exact omnistereo image of each drawn edge and the straight segment the rasteriser draws,
//! and the jump of scene edges where they cross from one wall to the next.

use glam::{Vec2, Vec3};

use super::{Bary, Projected, TessOutput, TessView, clip_to_pixel, point_position, project};
use crate::scene::Scene;

/// Geometric error statistics in pixels.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ErrorStats {
    pub max: f32,
    pub p99: f32,
    pub samples: usize,
}

impl ErrorStats {
    /// Statistics of a set of per-sample errors.
    pub fn from_samples(mut errors: Vec<f32>) -> Self {
        if errors.is_empty() {
            return Self::default();
        }
        errors.sort_by(f32::total_cmp);
        let p99 = errors[((errors.len() - 1) as f32 * 0.99).round() as usize];
        Self {
            max: errors[errors.len() - 1],
            p99,
            samples: errors.len(),
        }
    }
}

/// Distance from `p` to the segment `a`–`b`.
pub fn point_segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + t * ab - p).length()
}

/// The drawn part of a segment between two projected points, clipped at the near plane in
/// clip space as the rasteriser does (straight in clip space, so straight on screen).
fn drawn_segment(a: Projected, b: Projected, tv: &TessView<'_>) -> Option<(Vec2, Vec2)> {
    let near = tv.near;
    let (va, vb) = (a.clip.w > near, b.clip.w > near);
    match (va, vb) {
        (true, true) => Some((a.pixel, b.pixel)),
        (false, false) => None,
        _ => {
            let t = (near - a.clip.w) / (b.clip.w - a.clip.w);
            let cut = clip_to_pixel(a.clip + t * (b.clip - a.clip), tv.wall.resolution);
            Some(if va { (a.pixel, cut) } else { (cut, b.pixel) })
        }
    }
}

/// The scene-space corners of source triangle `t` (of a loaded scene, whose indices are in
/// range).
pub fn source_positions(scene: &Scene, t: u32) -> [Vec3; 3] {
    [0, 1, 2]
        .map(|k| Vec3::from(scene.vertices[scene.indices[3 * t as usize + k] as usize].position))
}

/// The corners each source edge joins, in triangle order; edge `z` is the one that does not
/// touch corner `z`.
const EDGE_CORNERS: [[usize; 2]; 3] = [[1, 2], [0, 2], [0, 1]];

/// A piece of a source (scene) edge drawn as one edge of an output triangle.
#[derive(Debug, Clone, Copy)]
struct SubEdge {
    source: u32,
    /// Which edge of the source triangle (see [`EDGE_CORNERS`]).
    edge: usize,
    ends: [Bary; 2],
    /// The ends as drawn in the view.
    drawn: [Projected; 2],
    /// The source triangle's corners (scene space).
    corners: [Vec3; 3],
}

/// Every output triangle edge of `out` that lies on a source edge, with its ends projected in
/// `tv` (an edge shared by two output triangles comes once from each).
fn source_sub_edges<'a>(
    scene: &'a Scene,
    tv: &'a TessView<'_>,
    out: &'a TessOutput,
) -> impl Iterator<Item = SubEdge> + 'a {
    out.drawn().flat_map(move |tri| {
        let corners = source_positions(scene, tri.source);
        let drawn = tri.corners.map(|c| project(tv, point_position(corners, c)));
        (0..3).filter_map(move |k| {
            let ends = [tri.corners[k], tri.corners[(k + 1) % 3]];
            let edge = source_edge(ends[0], ends[1])?;
            Some(SubEdge {
                source: tri.source,
                edge,
                ends,
                drawn: [drawn[k], drawn[(k + 1) % 3]],
                corners,
            })
        })
    })
}

fn lerp_bary(a: Bary, b: Bary, s: f32) -> (f32, f32) {
    (
        a.b1 as f32 + s * (b.b1 as f32 - a.b1 as f32),
        a.b2 as f32 + s * (b.b2 as f32 - a.b2 as f32),
    )
}

/// Which source edge (by the vertex whose weight is zero along it) the sub-edge `a`–`b` lies
/// on, if any (an interior edge of a subdivided triangle lies on none).
fn source_edge(a: Bary, b: Bary) -> Option<usize> {
    let zero = |c: Bary| [c.b0() == 0, c.b1 == 0, c.b2 == 0];
    (0..3).find(|&i| zero(a)[i] && zero(b)[i])
}

/// The scene point at fraction `s` from `a` to `b` of the source triangle with corners `p`.
fn point_between(p: [Vec3; 3], a: Bary, b: Bary, s: f32) -> Vec3 {
    let (b1, b2) = lerp_bary(a, b, s);
    let inv = 1.0 / super::BARY_ONE as f32;
    let (w1, w2) = (b1 * inv, b2 * inv);
    (1.0 - w1 - w2) * p[0] + w1 * p[1] + w2 * p[2]
}

/// Where view `tv` shows `world` exactly, if in front of the projective viewpoint and inside
/// the image.
pub fn exact_pixel(tv: &TessView<'_>, world: Vec3) -> Option<Vec2> {
    let [w, h] = tv.wall.resolution.map(|v| v as f32);
    let exact = project(tv, world);
    let q = exact.pixel;
    (exact.clip.w > tv.near && q.is_finite() && q.x >= 0.0 && q.y >= 0.0 && q.x <= w && q.y <= h)
        .then_some(q)
}

/// Per-sample errors of every drawn edge of `out` in view `tv`: for each edge of each output
/// triangle, the exact image of points along it (each seen from its own eye) against the
/// straight segment the rasteriser draws between its endpoints (clipped at the near plane).
/// Samples outside the image or behind the projective viewpoint are skipped; occlusion is not
/// considered.
pub fn edge_errors(
    scene: &Scene,
    tv: &TessView<'_>,
    out: &TessOutput,
    samples_per_edge: u32,
) -> Vec<f32> {
    let mut per_edge: std::collections::HashMap<(u32, usize), f32> =
        std::collections::HashMap::new();
    for e in source_sub_edges(scene, tv, out) {
        let Some((da, db)) = drawn_segment(e.drawn[0], e.drawn[1], tv) else {
            continue;
        };
        for i in 1..samples_per_edge {
            let world = point_between(
                e.corners,
                e.ends[0],
                e.ends[1],
                i as f32 / samples_per_edge as f32,
            );
            let Some(q) = exact_pixel(tv, world) else {
                continue;
            };
            let err = point_segment_distance(q, da, db);
            let slot = per_edge.entry((e.source, e.edge)).or_insert(0.0);
            *slot = slot.max(err);
        }
    }
    per_edge.into_values().collect()
}

/// Error samples along every drawn source edge of `out` in view `drawn`, against the exact
/// image of the same points in view `ideal` (the same wall and eye in omnistereo, where every
/// point is seen from its own eye; `ideal` may be `drawn` itself). Samples are spaced about
/// `spacing_px` apart along the drawn segment (at least 2, at most 256 per segment), so the
/// distribution weighs edges by their length on screen: its 99th percentile says how much of
/// the picture is wrong by more than that, its maximum how wrong the worst edge is. Points the
/// ideal shows on an edge that is not drawn at all (wholly behind the near plane) count as off
/// by the image's diagonal.
pub fn edge_error_samples(
    scene: &Scene,
    drawn: &TessView<'_>,
    out: &TessOutput,
    ideal: &TessView<'_>,
    spacing_px: f32,
) -> Vec<f32> {
    let [w, h] = ideal.wall.resolution.map(|v| v as f32);
    let mut errors = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for e in source_sub_edges(scene, drawn, out) {
        let [a, b] = e.ends;
        let p = e.corners;
        // Each sub-edge once (neighbouring output triangles share it).
        if !seen.insert((e.source, a.min(b), a.max(b))) {
            continue;
        }
        // An edge wholly behind the near plane is not drawn at all: whatever of it the ideal
        // shows is missing, counted as off by the image's diagonal.
        let segment = drawn_segment(e.drawn[0], e.drawn[1], drawn);
        let length = segment.map_or(
            (project(ideal, point_position(p, a)).pixel
                - project(ideal, point_position(p, b)).pixel)
                .length(),
            |(da, db)| (da - db).length(),
        );
        let n = if length.is_finite() {
            (length / spacing_px.max(0.1)).clamp(2.0, 256.0) as u32
        } else {
            256
        };
        for i in 0..=n {
            let Some(q) = exact_pixel(ideal, point_between(p, a, b, i as f32 / n as f32)) else {
                continue;
            };
            errors.push(match segment {
                Some((da, db)) => point_segment_distance(q, da, db),
                None => w.hypot(h),
            });
        }
    }
    errors
}

/// A point on a source edge: source triangle, edge (the index of the corner it does not touch)
/// and sample number along the edge.
pub type EdgePoint = (u32, u8, u32);

/// Weight of corner `corner` in `b`, as a fraction.
fn corner_weight(b: Bary, corner: usize) -> f32 {
    let w = match corner {
        0 => b.b0(),
        1 => b.b1,
        _ => b.b2,
    };
    w as f32 / super::BARY_ONE as f32
}

/// Where the rasteriser draws `per_edge + 1` evenly spaced points of every drawn source edge of
/// `out` in view `tv` (pixels; perspective-correct along the straight drawn sub-edge that
/// contains each point, as the GPU interpolates). Points behind the near plane are left out;
/// points outside the image are kept (they are drawn on the plane, just not shown).
/// `per_edge` is at least 1.
pub fn drawn_edge_points(
    scene: &Scene,
    tv: &TessView<'_>,
    out: &TessOutput,
    per_edge: u32,
) -> std::collections::HashMap<EdgePoint, Vec2> {
    let per_edge = per_edge.max(1);
    let mut points = std::collections::HashMap::new();
    for e in source_sub_edges(scene, tv, out) {
        // Position of each end along the source edge: the weight of the edge's second corner.
        let [ta, tb] = e.ends.map(|b| corner_weight(b, EDGE_CORNERS[e.edge][1]));
        let [ca, cb] = e.drawn.map(|d| d.clip);
        let first = (ta.min(tb) * per_edge as f32).ceil() as u32;
        let last = ((ta.max(tb) * per_edge as f32).floor() as u32).min(per_edge);
        for i in first..=last {
            let t = i as f32 / per_edge as f32;
            let s = if tb != ta { (t - ta) / (tb - ta) } else { 0.0 };
            let clip = ca + s * (cb - ca);
            if clip.w > tv.near && clip.is_finite() {
                points.insert(
                    (e.source, e.edge as u8, i),
                    clip_to_pixel(clip, tv.wall.resolution),
                );
            }
        }
    }
    points
}

/// The scene point of an [`EdgePoint`] with `per_edge` samples per edge.
pub fn edge_point_position(scene: &Scene, point: EdgePoint, per_edge: u32) -> Vec3 {
    let (source, edge, i) = point;
    let p = source_positions(scene, source);
    let [from, to] = EDGE_CORNERS[usize::from(edge).min(2)];
    p[from].lerp(p[to], i as f32 / per_edge.max(1) as f32)
}

/// Where each drawn source edge of `out` in view `tv` crosses the border `from`–`to` of the
/// image (pixels), as fractions along that border: a scene edge crossing from one wall to the
/// next crosses the shared border on both walls, and in an exact image it does so at the same
/// place on the shared physical edge. Keyed by (source triangle, edge); a warped edge may
/// cross more than once. The crossing is found in clip space (the border's line is linear in
/// clip coordinates), so the far-off pixels of a segment clipped at the near plane never enter
/// the arithmetic.
pub fn border_crossings(
    scene: &Scene,
    tv: &TessView<'_>,
    out: &TessOutput,
    from: Vec2,
    to: Vec2,
) -> std::collections::HashMap<(u32, u8), Vec<f32>> {
    let [w, h] = tv.wall.resolution.map(|v| v as f32);
    // The border in NDC, and the side of its line a clip-space point lies on (times w).
    let ndc = |p: Vec2| Vec2::new(p.x / w * 2.0 - 1.0, 1.0 - p.y / h * 2.0);
    let (nf, nt) = (ndc(from), ndc(to));
    let dir = nt - nf;
    let side = |c: glam::Vec4| (c.x - nf.x * c.w) * dir.y - (c.y - nf.y * c.w) * dir.x;
    let border = to - from;
    let mut crossings: std::collections::HashMap<(u32, u8), Vec<f32>> =
        std::collections::HashMap::new();
    for e in source_sub_edges(scene, tv, out) {
        let [ca, cb] = e.drawn.map(|d| d.clip);
        let (sa, sb) = (side(ca), side(cb));
        if !(sa.is_finite() && sb.is_finite()) || sa == sb || sa * sb > 0.0 {
            continue;
        }
        let clip = ca + (sa / (sa - sb)) * (cb - ca);
        if clip.w <= tv.near {
            continue;
        }
        // An edge running along the border (within about 3°) has no single crossing.
        if let Some((da, db)) = drawn_segment(e.drawn[0], e.drawn[1], tv) {
            let d = db - da;
            if d.perp_dot(border).abs() <= 0.05 * d.length() * border.length() {
                continue;
            }
        }
        let u =
            (clip_to_pixel(clip, tv.wall.resolution) - from).dot(border) / border.length_squared();
        if (0.0..=1.0).contains(&u) {
            crossings
                .entry((e.source, e.edge as u8))
                .or_default()
                .push(u);
        }
    }
    crossings
}

/// Where the rasteriser draws the scene point `world`, which lies on source triangle `source`
/// at barycentric weights (w1, w2): inside the output triangle that contains it, the point is
/// interpolated linearly between the *warped* corners (perspective-correct interpolation is
/// linear in the space the projection is applied to), then projected. `None` if no output
/// triangle of that source contains it or it lies behind the projective viewpoint.
pub fn drawn_point(
    scene: &Scene,
    tv: &TessView<'_>,
    out: &TessOutput,
    source: u32,
    w1: f32,
    w2: f32,
) -> Option<Vec2> {
    let p = source_positions(scene, source);
    let one = super::BARY_ONE as f32;
    let q = Vec2::new(w1 * one, w2 * one);
    for tri in out.drawn().filter(|t| t.source == source) {
        let c = tri.corners.map(|b| Vec2::new(b.b1 as f32, b.b2 as f32));
        let area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
        if area == 0.0 {
            continue;
        }
        let l1 = (q - c[0]).perp_dot(c[2] - c[0]) / area;
        let l2 = (c[1] - c[0]).perp_dot(q - c[0]) / area;
        let l0 = 1.0 - l1 - l2;
        let eps = -1e-4;
        if l0 < eps || l1 < eps || l2 < eps {
            continue;
        }
        let warped = tri.corners.map(|b| warped_point(tv, point_position(p, b)));
        let v = l0 * warped[0] + l1 * warped[1] + l2 * warped[2];
        let clip = tv.view.clip_from_cave * v.extend(1.0);
        if clip.w <= tv.near {
            return None;
        }
        return Some(clip_to_pixel(clip, tv.wall.resolution));
    }
    None
}

/// The CAVE-space point the vertex shader hands to the projection (after the warp).
fn warped_point(tv: &TessView<'_>, world: Vec3) -> Vec3 {
    let p = tv.cave_from_world.transform_point3(world);
    match (tv.omni, tv.view.omni, tv.view.eye) {
        (Some(settings), Some(o), Some(eye)) => {
            let e = crate::cave::omni::omni_eye(o.head, p, o.ipd, eye, settings.pole_merge);
            crate::cave::omni::warp(settings.warp, p, e, tv.view.eye_position, o.wall_plane)
        }
        _ => p,
    }
}
