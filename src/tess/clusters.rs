//! Clusters of source triangles with bounds computed once at load, and the conservative test
//! of what a cluster needs in a view: nothing (hidden: behind every eye or drawn wholly off the
//! wall), the ordinary indexed path with the per-vertex warp (fine: no edge would be split), or
//! the tessellator (needy). Only the needy enter the tessellator.
//!
//! # The bounds
//!
//! A point V of the scene is drawn where the ray from its eye E(V) through V meets the wall:
//! Π(V) = E + s_E · W / u, with W = V − E, s the signed distance from the wall plane (positive
//! on the viewer's side) and u = s_E − s_V > 0. (The similar-triangle and intersection-point
//! warps both put the warped vertex, seen from the view's centre, exactly there.) Along an
//! edge X(t) = A + t·d, |d| ≤ L, |n·d| ≤ N, the curve f(t) = Π(X(t)) is what an exact renderer
//! draws and the chord is what the rasteriser draws; the split criteria measure, at depth 0:
//!
//! - `error`: |f(½) − (f(0) + f(1))/2| ≤ max|f''| / 8 (the criterion's first test; its second,
//!   where points are drawn against where they are seen, only spares edges the first would
//!   split, so an edge this bound clears is never split);
//! - `edge`: |f(1) − f(0)| ≤ max|f'|;
//! - `sphere`: L · s_C / w · k, w the warped midpoint's clip w ≥ s_C · u / s_E.
//!
//! With g(W) = W/(−n·W): |g| = τ = |W|/u, |Dg[w]| ≤ (|w| + τ|n·w|)/u,
//! |D²g[w, w]| ≤ 2|n·w|(|w| + τ|n·w|)/u². With the eye function's derivatives |∇E| ≤ G1 and
//! ‖∇²E‖ ≤ G2 (below), W' = d − E' has |W'| ≤ L(1 + G1) =: L₁ and |n·W'| ≤ N + G1·L =: N₁, and
//! f = E + s_E·g(W) gives
//!
//! - |f'| ≤ G1·L·(1 + τ) + s_E·(L₁ + τ·N₁)/u,
//! - |f''| ≤ G2·L²·(1 + τ) + 2·G1·L·(L₁ + τ·N₁)/u + s_E·[2·N₁·(L₁ + τ·N₁)/u² + G2·L²·(1 + τ)/u],
//!
//! each taken at its worst over the cluster (its box along the wall's normal for u, its ball
//! of centre c and radius R elsewhere) and the ball the eyes lie on (the head h, radius
//! r = IPD/2; a fixed eye has r = 0 and G1 = G2 = 0). N comes from the cluster's largest edge
//! extent along each scene axis (a facade's vertical edges have none across a vertical wall).
//! Times k, the wall's pixels per metre (the larger of its two axes), these are pixels.
//!
//! The omnistereo eye is E = h + m(el)·R(az), with R the horizontal unit vector across the
//! direction to V, az its azimuth and el its elevation from the head, and m = r·φ(el) the pole
//! merge's fade (smoothstep from 1 to 0 between its two angles). With ρ the horizontal and D the
//! full distance from the head: |∇az| = 1/ρ, ‖∇²az‖ = 1/ρ², |∇el| = 1/D,
//! ‖∇²el‖ ≤ 1/D² + 1/(ρD) (taken as twice that), |φ'| ≤ 1.5/Δ, |φ''| ≤ 6/Δ² (Δ the fade's
//! width in radians). So G1 = r·(φ'/D + 1/ρ) and
//! G2 = r·(φ''/D² + φ'·‖∇²el‖) + 2·r·φ'/(Dρ) + 2·r/ρ², where the fade's terms vanish when the
//! whole ball lies below its start and E = h (G1 = G2 = 0) when it lies above its end.
//!
//! Hidden: the whole box lies further from the wall than every eye (u < 0: behind them); or
//! the whole ball lies beyond the plane through an eye and a border of the wall (moved 4 px
//! outwards) for every eye of the ball (see `BorderPlane`): a point there is behind its eye
//! or drawn beyond that border, which also hides what straddles the eyes' plane, such as a
//! model beyond the front wall in a side wall's or the floor's view; or the centre's image Π(c)
//! lies beyond one side of the wall by more than the first-derivative bound over R (every
//! point's image is within that of Π(c)) plus 4 px.
//!
//! A cluster is needy unless it lies wholly in front of every eye (u > 0, the warped points
//! beyond twice the near plane) and every bound, with a margin for the GPU's rounding, stays
//! under the criterion. `tests` check the bounds against the CPU twin of the criteria
//! (`split_edge`) and projection on random triangles, heads, walls and placements.

use glam::{Mat4, Vec3};

use super::{Criterion, TessView};
use crate::cave::omni::PoleMerge;
use crate::scene::Scene;

/// Triangles per cluster (a workgroup of the tessellator's culling pass takes one; smaller
/// clusters have tighter bounds: measured on the bundled scenes, 16 refines fewer triangles
/// than 64 does).
pub const CLUSTER_TRIANGLES: u32 = 16;

/// A run of up to [`CLUSTER_TRIANGLES`] consecutive source triangles of one draw, with its
/// bounds in scene space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cluster {
    /// The draw (the renderer's, see `SceneGpu`) whose indices hold it.
    pub draw: u32,
    /// First source triangle (its indices start at 3 × this).
    pub first_triangle: u32,
    pub triangle_count: u32,
    /// Bounding ball of its corners, scene space (the centre is also the box's).
    pub centre: Vec3,
    pub radius: f32,
    /// Half the size of its corners' bounding box, scene space: a tighter extent than the
    /// ball's along a wall's normal.
    pub half_size: Vec3,
    /// Longest edge of any of its triangles, scene space.
    pub max_edge: f32,
    /// Largest extent of any edge along each axis, scene space: bounds an edge's component
    /// along a wall's normal (a facade's vertical edges have none on a vertical wall).
    pub edge_extent: Vec3,
}

/// Clusters of every draw given as (draw, first index, index count) into `scene.indices`.
/// Degenerate or out-of-range indices only make the bounds larger (a missing vertex counts
/// at the origin), never smaller than the triangles drawn.
pub fn build_clusters(
    scene: &Scene,
    draws: impl IntoIterator<Item = (u32, u32, u32)>,
) -> Vec<Cluster> {
    let position = |i: u32| {
        scene
            .vertices
            .get(i as usize)
            .map_or(Vec3::ZERO, |v| Vec3::from(v.position))
    };
    let corner = |t: u32, k: u32| {
        position(
            scene
                .indices
                .get((3 * t + k) as usize)
                .copied()
                .unwrap_or(0),
        )
    };
    let mut out = Vec::new();
    for (draw, first_index, index_count) in draws {
        let first = first_index / 3;
        let count = index_count / 3;
        let mut t = first;
        while t < first + count {
            let n = CLUSTER_TRIANGLES.min(first + count - t);
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            let mut max_edge = 0.0f32;
            let mut edge_extent = Vec3::ZERO;
            for tri in t..t + n {
                let p = [corner(tri, 0), corner(tri, 1), corner(tri, 2)];
                for k in 0..3 {
                    lo = lo.min(p[k]);
                    hi = hi.max(p[k]);
                    max_edge = max_edge.max(p[k].distance(p[(k + 1) % 3]));
                    edge_extent = edge_extent.max((p[k] - p[(k + 1) % 3]).abs());
                }
            }
            let centre = 0.5 * (lo + hi);
            let mut radius = 0.0f32;
            for tri in t..t + n {
                for k in 0..3 {
                    radius = radius.max(corner(tri, k).distance(centre));
                }
            }
            out.push(Cluster {
                draw,
                first_triangle: t,
                triangle_count: n,
                centre,
                half_size: 0.5 * (hi - lo) * (1.0 + 1e-6),
                // One part in a million more: the distances above are rounded too.
                radius: radius * (1.0 + 1e-6),
                max_edge: max_edge * (1.0 + 1e-6),
                edge_extent: edge_extent * (1.0 + 1e-6),
            });
            t += n;
        }
    }
    out
}

/// Slack for the GPU's rounding: a bound must stay this far under the criterion (pixels,
/// relative and absolute). Criteria are measured in f32 on pixel coordinates up to a few
/// thousand, so a few thousandths of a pixel; a hundredth plus 2 % is ample.
const MARGIN_RELATIVE: f32 = 1.02;
const MARGIN_PX: f32 = 0.01;

/// What becomes of a cluster in a view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Provably invisible: wholly behind every eye, or its image wholly off the wall.
    Hidden,
    /// Drawn whole through the ordinary path: no edge would be split.
    Fine,
    /// To the tessellator.
    Needy,
}

/// What the test needs of one view, computed once per view and frame.
#[derive(Debug, Clone, Copy)]
pub struct ClusterTest {
    /// `None`: visibility only (an untessellated frame: every visible cluster is drawn whole).
    criterion: Option<Criterion>,
    cave_from_world: Mat4,
    /// Scale of `cave_from_world` (its largest axis): scene lengths to CAVE metres.
    scale: f32,
    /// Wall plane: s(X) = n·X + d, n towards the viewer.
    normal: Vec3,
    offset: f32,
    /// Mᵀn for M the linear part of `cave_from_world`: a scene-space edge d has n·(M d) =
    /// (Mᵀn)·d along the wall's normal in CAVE space.
    normal_in_scene: Vec3,
    /// The wall's corner, axes (unit) and size, for where an image point lies on it.
    lower_left: Vec3,
    right: Vec3,
    up: Vec3,
    size: glam::Vec2,
    /// The view's centre of projection and its distance from the wall.
    s_centre: f32,
    /// The ball the eyes lie on: the head and IPD/2 (omnistereo), else the eye and 0.
    head: Vec3,
    eye_radius: f32,
    /// Which omnistereo eye (`None`: the fixed eye `head`).
    eye: Option<crate::cave::Eye>,
    pole: Option<PoleMerge>,
    /// Pixels per metre on the wall: the larger axis, and x alone.
    px_per_m: f32,
    px_per_m_x: f32,
    near: f32,
    /// The four planes through the eyes and the wall's borders (`None` only for a degenerate
    /// wall: the eyes' ball lies in front of the wall, so it never reaches a border's line).
    borders: [Option<BorderPlane>; 4],
}

/// The plane through the head and one border of the wall (moved [`OFF_WALL_PX`] outwards),
/// and how far it can turn about that border for an eye elsewhere in the eyes' ball.
///
/// In the section across the border's line, a point is (γ, δ): γ towards the head, δ outwards.
/// The plane through an eye E of the ball holds the line and E; it is the head's turned by at
/// most α, sin α = r / (the head's distance from the line). A point is beyond every such plane
/// when δ·cos α − |γ|·sin α > 0: then, for any eye, it lies behind that eye (not drawn) or its
/// image lies beyond the border. Both coordinates are linear in the point, so a ball of
/// radius R is beyond when (δ(c) − R)·cos α > (|γ(c)| + R)·sin α.
///
/// What the rasteriser draws is hidden too, not only each point's exact image: for one eye E,
/// the similar-triangle warp is affine, keeps the wall's plane, takes E to the view's centre
/// and has a positive determinant, so it takes the plane through E and the border onto the
/// view's own frustum plane through that border, sides kept. Every warped corner of the
/// cluster, behind its eye or not, lies beyond that frustum plane, and so does every triangle
/// between them. (The intersection-point warp, which the user guide advises against, draws a
/// corner behind its eye where the backward ray meets the wall: those ghosts are not drawn.)
#[derive(Debug, Clone, Copy)]
struct BorderPlane {
    /// A point of the (moved) border's line.
    origin: Vec3,
    /// Unit: outwards across the plane (δ), and within it towards the head (γ).
    outwards: Vec3,
    towards_head: Vec3,
    sin_turn: f32,
    cos_turn: f32,
}

impl BorderPlane {
    /// The plane through `head` and the line through `origin` along the unit `along`, with
    /// `off_wall` (in the wall's plane, pointing away from the wall) on its outer side;
    /// `None` when the ball of radius `r` around `head` reaches the line (or `along` is not a
    /// unit vector's worth of direction: a degenerate wall).
    fn new(head: Vec3, origin: Vec3, along: Vec3, off_wall: Vec3, r: f32) -> Option<Self> {
        let to_head = head - origin;
        let across = to_head - to_head.dot(along) * along;
        let distance = across.length();
        if !(distance > r && distance.is_finite() && along.length_squared() > 0.5) {
            return None;
        }
        let towards_head = across / distance;
        let normal = along.cross(towards_head);
        let outwards = if normal.dot(off_wall) >= 0.0 {
            normal
        } else {
            -normal
        };
        let sin_turn = r / distance;
        Some(Self {
            origin,
            outwards,
            towards_head,
            sin_turn,
            cos_turn: (1.0 - sin_turn * sin_turn).max(0.0).sqrt(),
        })
    }

    /// Whether every point of the ball (`centre`, `radius`) lies beyond the plane of every
    /// eye of the ball.
    fn excludes(&self, centre: Vec3, radius: f32) -> bool {
        let v = centre - self.origin;
        let beyond = self.outwards.dot(v) - radius;
        let along_plane = self.towards_head.dot(v).abs() + radius;
        beyond > 0.0 && beyond * self.cos_turn > along_plane * self.sin_turn
    }
}

/// Pixels an image must lie beyond the wall's border to count as off it (as the
/// tessellator's frustum cull keeps a margin).
const OFF_WALL_PX: f32 = 4.0;

impl ClusterTest {
    /// The test for `tv` with `criterion` at depth 0 (`None`: visibility only); `None` when
    /// nothing can be proven (a view whose eye is not in front of its wall).
    pub fn new(tv: &TessView<'_>, criterion: Option<Criterion>) -> Option<Self> {
        let wall = tv.wall;
        let normal = wall.normal();
        let offset = -normal.dot(wall.lower_left);
        let (head, eye_radius, eye, pole) = match (tv.omni, tv.view.omni, tv.view.eye) {
            (Some(settings), Some(o), Some(eye)) => {
                (o.head, 0.5 * o.ipd, Some(eye), settings.pole_merge)
            }
            _ => (tv.view.eye_position, 0.0, None, None),
        };
        let s_centre = normal.dot(tv.view.eye_position) + offset;
        if !(s_centre > 0.0 && normal.dot(head) + offset - eye_radius > 0.0) {
            return None;
        }
        let m = tv.cave_from_world;
        let scale = m
            .x_axis
            .truncate()
            .length()
            .max(m.y_axis.truncate().length())
            .max(m.z_axis.truncate().length());
        let size = wall.size_m();
        let [w, h] = wall.resolution.map(|v| v as f32);
        let (kx, ky) = (w / size.x, h / size.y);
        let finite = [scale, kx, ky, s_centre, tv.near]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0);
        let (right, up) = (wall.right_axis(), wall.up_axis());
        let margin = OFF_WALL_PX / kx.max(ky);
        let corner = wall.lower_left;
        let border = |origin: Vec3, along: Vec3, off_wall: Vec3| {
            BorderPlane::new(
                head,
                origin + margin * off_wall,
                along,
                off_wall,
                eye_radius,
            )
        };
        // The borders are where a point's coordinates along `right` and `up` (as the image
        // test below reads them) reach 0 or the wall's size: lines across `right` (or `up`)
        // within the wall, which differ from `up` (or `right`) on a wall whose axes are not
        // quite square.
        let across_right = normal.cross(right).normalize_or_zero();
        let across_up = up.cross(normal).normalize_or_zero();
        let borders = [
            border(corner, across_right, -right),
            border(corner + size.x * right, across_right, right),
            border(corner, across_up, -up),
            border(corner + size.y * up, across_up, up),
        ];
        finite.then_some(Self {
            // Uniform:0 splits nothing: as good as none.
            criterion: criterion.filter(|c| *c != Criterion::Uniform(0)),
            cave_from_world: m,
            scale,
            normal,
            offset,
            normal_in_scene: glam::Mat3::from_mat4(m).transpose() * normal,
            lower_left: wall.lower_left,
            right,
            up,
            size,
            s_centre,
            head,
            eye_radius,
            eye,
            pole,
            px_per_m: kx.max(ky),
            px_per_m_x: kx,
            near: tv.near,
            borders,
        })
    }

    /// The test a frame with `settings` uses in view `tv` when `tessellating` (else one of
    /// visibility only); `None` when every triangle is to go the old way: all to the
    /// tessellator (`skip_fine` off) or all drawn.
    pub fn for_settings(
        tv: &TessView<'_>,
        settings: &super::TessSettings,
        tessellating: bool,
    ) -> Option<Self> {
        if !tessellating {
            return Self::new(tv, None);
        }
        match (settings.skip_fine, settings.criterion) {
            (true, Some(c)) if settings.max_depth > 0 => Self::new(tv, Some(c)),
            (true, Some(_)) => Self::new(tv, None),
            _ => None,
        }
    }

    /// Where `cluster` goes in this view, proven by the bounds in the module documentation.
    pub fn verdict(&self, cluster: &Cluster) -> Verdict {
        // What cannot be proven invisible or fine: refined when tessellating, else drawn.
        let unproven = if self.criterion.is_some() {
            Verdict::Needy
        } else {
            Verdict::Fine
        };
        if matches!(self.criterion, Some(Criterion::Uniform(_))) {
            // Uniform subdivision splits every edge, seen or not: a hidden cluster's edges
            // would be split by its neighbours only (T-junctions, if out of sight).
            return Verdict::Needy;
        }
        let c = self.cave_from_world.transform_point3(cluster.centre);
        let radius = cluster.radius * self.scale;
        let length = cluster.max_edge * self.scale;
        // Any edge's component along the wall's normal (never more than its length).
        let across = self
            .normal_in_scene
            .abs()
            .dot(cluster.edge_extent)
            .min(length);
        let r = self.eye_radius;
        let s = |x: Vec3| self.normal.dot(x) + self.offset;
        let s_head = s(self.head);
        let s_eye_max = s_head + r;
        // How far the cluster reaches along the wall's normal: its box, or its ball.
        let depth = self
            .normal_in_scene
            .abs()
            .dot(cluster.half_size)
            .min(radius);
        if s(c) - depth > s_eye_max {
            // Every point lies behind every eye (further from the wall): not in this view.
            return Verdict::Hidden;
        }
        if self
            .borders
            .iter()
            .flatten()
            .any(|border| border.excludes(c, radius))
        {
            // Beyond a border for every eye: seen through another wall, or behind the eyes.
            return Verdict::Hidden;
        }
        let u_min = (s_head - r) - (s(c) + depth);
        if u_min <= 0.0 {
            return unproven;
        }
        // The warped points' clip w (their depth from the view's centre): beyond twice the
        // near plane, so no criterion takes its "behind the viewpoint" branch.
        let w_min = self.s_centre * u_min / s_eye_max;
        if w_min.is_nan() || w_min <= 2.0 * self.near {
            return unproven;
        }
        let to_centre = c - self.head;
        let distance = to_centre.length();
        let tau = (distance + radius + r) / u_min;
        let (g1, g2) = if r > 0.0 {
            match eye_derivatives(to_centre, radius, r, self.pole) {
                Some(g) => g,
                None => return unproven,
            }
        } else {
            (0.0, 0.0)
        };
        // Where the centre is drawn on the wall (seen from its own eye), and how far any
        // point of the cluster can be drawn from it (the first-derivative bound over R).
        let eye = match self.eye {
            Some(e) => crate::cave::omni::omni_eye(self.head, c, 2.0 * r, e, self.pole),
            None => self.head,
        };
        let u_c = s(eye) - s(c);
        let image = eye + s(eye) / u_c * (c - eye) - self.lower_left;
        let spread = radius * (1.0 + tau) * (g1 + s_eye_max * (1.0 + g1) / u_min)
            + OFF_WALL_PX / self.px_per_m;
        let (x, y) = (image.dot(self.right), image.dot(self.up));
        if spread.is_finite()
            && (x + spread < 0.0
                || x - spread > self.size.x
                || y + spread < 0.0
                || y - spread > self.size.y)
        {
            return Verdict::Hidden;
        }
        let Some(criterion) = self.criterion else {
            return Verdict::Fine;
        };
        let k = self.px_per_m;
        let (bound, limit) = match criterion {
            Criterion::Uniform(0) => return Verdict::Fine,
            Criterion::Uniform(_) => return Verdict::Needy,
            Criterion::Error(px) => {
                // With |W'| ≤ L(1 + G1) and |n·W'| ≤ N + G1·L (N: `across`).
                let (l, n) = (length, across);
                let w1 = l * (1.0 + g1);
                let nw1 = n + g1 * l;
                let second = g2 * l * l * (1.0 + tau)
                    + 2.0 * g1 * l * (w1 + tau * nw1) / u_min
                    + s_eye_max
                        * (2.0 * nw1 * (w1 + tau * nw1) / (u_min * u_min)
                            + g2 * l * l * (1.0 + tau) / u_min);
                (k * second / 8.0, px)
            }
            Criterion::Edge(px) => {
                let (l, n) = (length, across);
                let first = g1 * l * (1.0 + tau)
                    + s_eye_max * (l * (1.0 + g1) + tau * (n + g1 * l)) / u_min;
                (k * first, px)
            }
            Criterion::Sphere(px) => (length * self.s_centre * self.px_per_m_x / w_min, px),
        };
        if bound.is_finite() && bound * MARGIN_RELATIVE + MARGIN_PX < limit {
            Verdict::Fine
        } else {
            Verdict::Needy
        }
    }
}

/// Bounds (G1, G2) on the first and second derivatives of the omnistereo eye over the ball at
/// `to_centre` from the head with `radius`, for eyes `r` from the head; `None` where the ball
/// reaches the vertical through the head (the eye's direction turns without bound there)
/// unless the eyes have merged over all of it.
fn eye_derivatives(
    to_centre: Vec3,
    radius: f32,
    r: f32,
    pole: Option<PoleMerge>,
) -> Option<(f32, f32)> {
    let distance = to_centre.length();
    let horizontal = (to_centre.x * to_centre.x + to_centre.z * to_centre.z).sqrt();
    let d_min = distance - radius;
    if d_min <= 0.0 {
        return None;
    }
    // Elevations the ball spans.
    let elevation = to_centre.y.abs().atan2(horizontal);
    let spread = (radius / distance).clamp(0.0, 1.0).asin();
    let (el_lo, el_hi) = ((elevation - spread).max(0.0), elevation + spread);
    let (d1, d2) = match pole {
        None => (0.0, 0.0),
        Some(p) => {
            let (a, b) = (p.start_degrees.to_radians(), p.end_degrees.to_radians());
            if el_lo > b.max(a) {
                // The eyes have merged into the head everywhere in the ball: E = h.
                return Some((0.0, 0.0));
            }
            if el_hi < a {
                (0.0, 0.0)
            } else if b <= a {
                // A step: the eye jumps inside the ball.
                return None;
            } else {
                let width = b - a;
                (1.5 / width, 6.0 / (width * width))
            }
        }
    };
    let rho_min = horizontal - radius;
    if rho_min <= 0.0 {
        return None;
    }
    let hess_el = 2.0 * (1.0 / (d_min * d_min) + 1.0 / (rho_min * d_min));
    let g1 = r * (d1 / d_min + 1.0 / rho_min);
    let g2 = r * (d2 / (d_min * d_min) + d1 * hess_el)
        + 2.0 * r * d1 / (d_min * rho_min)
        + 2.0 * r / (rho_min * rho_min);
    Some((g1, g2))
}

/// One view's split of the clusters: index ranges drawn through the ordinary path (per draw,
/// consecutive fine clusters merged) and the clusters the tessellator refines, as (first
/// triangle, triangle count). Reused frame to frame: nothing grows past the scene's clusters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ClusterSplit {
    /// (draw, first index, index count).
    pub fine: Vec<(u32, u32, u32)>,
    pub needy: Vec<[u32; 2]>,
    /// The draws with a cluster in `needy`, ascending, each once (the clusters come in draw
    /// order): the only draws whose tessellated output can be non-empty.
    pub needy_draws: Vec<u32>,
}

impl ClusterSplit {
    /// Classifies `clusters` for the view whose test is `tests[0]` (a `None` test gives every
    /// cluster `unproven`); hidden ones are in neither list. Further tests are the other eyes
    /// one refinement serves: a cluster any of them refines is refined for this one too, so
    /// their needy lists are the same and none draws a cluster both directly and refined.
    pub fn classify(
        &mut self,
        clusters: &[Cluster],
        tests: &[Option<&ClusterTest>],
        unproven: Verdict,
    ) {
        self.fine.clear();
        self.needy.clear();
        self.needy_draws.clear();
        let judge =
            |test: &Option<&ClusterTest>, c: &Cluster| test.map_or(unproven, |t| t.verdict(c));
        let (own, others) = match tests.split_first() {
            Some((own, others)) => (*own, others),
            None => (None, &[][..]),
        };
        for c in clusters {
            let mut verdict = judge(&own, c);
            if verdict != Verdict::Needy && others.iter().any(|t| judge(t, c) == Verdict::Needy) {
                verdict = Verdict::Needy;
            }
            if verdict == Verdict::Hidden {
                continue;
            }
            if verdict == Verdict::Fine {
                match self.fine.last_mut() {
                    Some((draw, first, count))
                        if *draw == c.draw && *first + *count == 3 * c.first_triangle =>
                    {
                        *count += 3 * c.triangle_count;
                    }
                    _ => self
                        .fine
                        .push((c.draw, 3 * c.first_triangle, 3 * c.triangle_count)),
                }
            } else {
                self.needy.push([c.first_triangle, c.triangle_count]);
                if self.needy_draws.last() != Some(&c.draw) {
                    self.needy_draws.push(c.draw);
                }
            }
        }
    }

    /// Triangles drawn through the ordinary path.
    pub fn fine_triangles(&self) -> u32 {
        self.fine.iter().map(|f| f.2 / 3).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::omni::OmniSettings;
    use crate::cave::{Cave, Head, RenderMode, Wall, thesis_cave, view_setups};
    use crate::scene::{Draw, Vertex};
    use crate::tess::criteria::split_edge;
    use crate::tess::{Bary, tess_view};
    use glam::Quat;

    struct Rng(u64);
    impl Rng {
        fn unit(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.unit()
        }
        fn direction(&mut self) -> Vec3 {
            loop {
                let v = Vec3::new(
                    self.range(-1.0, 1.0),
                    self.range(-1.0, 1.0),
                    self.range(-1.0, 1.0),
                );
                if (0.01..1.0).contains(&v.length_squared()) {
                    return v.normalize();
                }
            }
        }
    }

    /// A scene of one cluster: `n` random triangles of size up to `size` around `centre`; with
    /// `aligned`, each has two edges along scene axes (as boxes and facades do).
    fn random_cluster(
        rng: &mut Rng,
        centre: Vec3,
        spread: f32,
        size: f32,
        n: usize,
        aligned: bool,
    ) -> Scene {
        let mut scene = Scene::default();
        for _ in 0..n {
            let at = centre + spread * rng.unit() * rng.direction();
            let axes = [Vec3::X, Vec3::Y, Vec3::Z];
            let (i, j) = ((rng.unit() * 2.99) as usize, (rng.unit() * 1.99) as usize);
            let (a, b) = (axes[i], axes[(i + 1 + j) % 3]);
            let corners = [
                at,
                at + size * rng.range(-1.0, 1.0) * a,
                at + size * rng.range(-1.0, 1.0) * b,
            ];
            for corner in corners {
                let p = if aligned {
                    corner
                } else {
                    at + size * rng.unit() * rng.direction()
                };
                scene.indices.push(scene.vertices.len() as u32);
                scene
                    .vertices
                    .push(Vertex::new(p.to_array(), [0.0, 1.0, 0.0], [0.0, 0.0]));
            }
        }
        scene.draws.push(Draw {
            first_index: 0,
            index_count: scene.indices.len() as u32,
            material: 0,
        });
        scene
    }

    /// One random situation of [`fine_clusters_split_no_edge_in_the_cpu_twin`]: a head, a
    /// render mode, a scene placement, a cluster of 8 triangles and a criterion.
    struct Trial {
        trial: usize,
        head: Head,
        mode: RenderMode,
        world_from_cave: Mat4,
        scene: Scene,
        clusters: Vec<Cluster>,
        criterion: Criterion,
    }

    /// What the trials counted: cluster views proven fine, hidden and tested, and the edges
    /// of fine clusters checked.
    #[derive(Default)]
    struct FineCounts {
        fine: usize,
        hidden: usize,
        tested: usize,
        edges: usize,
    }

    /// The thesis CAVE with a floor.
    fn cave_with_floor() -> Cave {
        let mut cave = thesis_cave();
        cave.walls.push(Wall {
            name: "floor".into(),
            lower_left: Vec3::new(-1.65, 0.0, 1.65),
            lower_right: Vec3::new(1.65, 0.0, 1.65),
            upper_left: Vec3::new(-1.65, 0.0, -1.65),
            resolution: [1280, 1280],
        });
        cave
    }

    /// Trial number `trial`, drawn from `rng`.
    fn random_trial(rng: &mut Rng, trial: usize) -> Trial {
        let head = Head::at(Vec3::new(
            rng.range(-1.3, 1.3),
            rng.range(0.8, 2.2),
            rng.range(-1.3, 1.3),
        ));
        let mode = [
            RenderMode::OmniOffAxis,
            RenderMode::OmniOnAxis,
            RenderMode::Stereo,
        ][trial % 3];
        let world_from_cave = Mat4::from_scale_rotation_translation(
            Vec3::splat(rng.range(0.5, 2.0)),
            Quat::from_rotation_y(rng.range(-3.0, 3.0)),
            Vec3::new(
                rng.range(-5.0, 5.0),
                rng.range(-1.0, 1.0),
                rng.range(-5.0, 5.0),
            ),
        );
        let distance = 10f32.powf(rng.range(-0.3, 1.8));
        let centre_cave = head.position + distance * rng.direction();
        let size = distance * 10f32.powf(rng.range(-3.0, -0.3));
        let scene = random_cluster(
            rng,
            world_from_cave.transform_point3(centre_cave),
            size,
            size,
            8,
            trial % 5 < 2,
        );
        let clusters = build_clusters(&scene, [(0, 0, scene.indices.len() as u32)]);
        let criterion = match trial % 4 {
            0 => Criterion::Error(rng.range(0.25, 4.0)),
            1 => Criterion::Edge(rng.range(8.0, 64.0)),
            2 => Criterion::Sphere(rng.range(8.0, 64.0)),
            _ => Criterion::Error(0.5),
        };
        Trial {
            trial,
            head,
            mode,
            world_from_cave,
            scene,
            clusters,
            criterion,
        }
    }

    #[test]
    fn fine_clusters_split_no_edge_in_the_cpu_twin() {
        // The bound against the criteria themselves: over random clusters (near and far, small
        // and large triangles), heads, scene placements, walls (three walls and a floor, at a
        // quick and a full resolution), render modes and criteria, no edge of a cluster proven
        // fine is split at depth 0 by the CPU twin, and the proof is not vacuous (a good share
        // of clusters is proven fine, and some that are not do split).
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut cave = cave_with_floor();
        let mut counts = FineCounts::default();
        for trial in 0..400 {
            let resolution = if trial % 2 == 0 {
                [192, 108]
            } else {
                [1280, 720]
            };
            for wall in cave.walls.iter_mut().take(3) {
                wall.resolution = resolution;
            }
            let t = random_trial(&mut rng, trial);
            check_trial_views(&cave, &t, &mut counts);
        }
        let FineCounts {
            fine,
            hidden,
            tested,
            edges,
        } = counts;
        eprintln!(
            "{fine} of {tested} cluster views proven fine ({edges} edges checked), {hidden} \
             hidden"
        );
        let visible = tested - hidden;
        assert!(
            fine * 5 > visible,
            "{fine} of {visible}: the bound proves too little"
        );
        assert!(
            hidden * 5 > tested,
            "{hidden} of {tested}: the bound hides too little"
        );
        assert!(
            fine + hidden < tested,
            "every cluster proven: nothing was tested"
        );
    }

    /// Every view of trial `t`: hidden clusters are invisible, and no edge of a fine one
    /// splits at depth 0.
    fn check_trial_views(cave: &Cave, t: &Trial, counts: &mut FineCounts) {
        let omni = t.mode.is_omni().then(OmniSettings::default);
        for view in view_setups(cave, &t.head, t.mode, 0.064) {
            let wall = &cave.walls[view.wall];
            let tv = tess_view(&view, wall, t.world_from_cave, omni);
            let Some(test) = ClusterTest::new(&tv, Some(t.criterion)) else {
                continue;
            };
            for cluster in &t.clusters {
                counts.tested += 1;
                let verdict = test.verdict(cluster);
                if verdict == Verdict::Hidden {
                    counts.hidden += 1;
                    assert_invisible(&tv, &t.scene, cluster, t.trial);
                    continue;
                }
                if verdict == Verdict::Needy {
                    continue;
                }
                counts.fine += 1;
                counts.edges += assert_no_edge_splits(&tv, t, cluster, &wall.name);
            }
        }
    }

    /// No edge of any triangle of `cluster` splits at depth 0 in view `tv`; returns the
    /// edges checked.
    fn assert_no_edge_splits(
        tv: &TessView<'_>,
        t: &Trial,
        cluster: &Cluster,
        wall_name: &str,
    ) -> usize {
        let (scene, criterion, trial, mode) = (&t.scene, t.criterion, t.trial, t.mode);
        let mut edges = 0;
        for tri in cluster.first_triangle..cluster.first_triangle + cluster.triangle_count {
            let p = [0, 1, 2].map(|k| {
                Vec3::from(scene.vertices[scene.indices[3 * tri as usize + k] as usize].position)
            });
            let corners = [Bary::V0, Bary::V1, Bary::V2];
            for k in 0..3 {
                edges += 1;
                assert!(
                    !split_edge(tv, &criterion, 0, p, corners[k], corners[(k + 1) % 3]),
                    "trial {trial}: {criterion} splits an edge of a cluster proven \
                     fine ({mode:?}, wall {wall_name}, head {:?}, cluster {cluster:?})",
                    t.head.position
                );
            }
        }
        edges
    }

    /// Every point of every triangle of `cluster` (corners, edge points and interior points
    /// on a grid of eighths) is drawn off the view: behind its eye or outside the clip volume.
    fn assert_invisible(tv: &TessView<'_>, scene: &Scene, cluster: &Cluster, trial: usize) {
        for t in cluster.first_triangle..cluster.first_triangle + cluster.triangle_count {
            let p = [0, 1, 2].map(|k| {
                Vec3::from(scene.vertices[scene.indices[3 * t as usize + k] as usize].position)
            });
            for i in 0..=8u32 {
                for j in 0..=8 - i {
                    let at = Bary {
                        b1: i * (crate::tess::BARY_ONE / 8),
                        b2: j * (crate::tess::BARY_ONE / 8),
                    };
                    let clip = crate::tess::project(tv, crate::tess::point_position(p, at)).clip;
                    let visible = clip.w > 0.0 && clip.x.abs() <= clip.w && clip.y.abs() <= clip.w;
                    assert!(
                        !visible,
                        "trial {trial}: a point of a hidden cluster is drawn at {clip:?} \
                         ({cluster:?})"
                    );
                }
            }
        }
    }

    #[test]
    fn a_border_plane_excludes_only_what_lies_beyond_every_eyes_plane() {
        // Random walls (a plane through a border line), heads in front of them, eye balls and
        // cluster balls placed near the head's plane (where the turn of the plane matters):
        // whenever `excludes` holds, every sampled point of the ball (out to its surface)
        // lies strictly beyond the plane through every sampled eye (on the ball's surface,
        // where the plane turns most) and the line. And the test is not vacuous: it excludes
        // a good share, some of them within the turn of the head's plane.
        let mut rng = Rng(0x0b0d_e2a1_7e57_0042);
        let (mut tried, mut excluded, mut within_turn) = (0, 0, 0);
        for _ in 0..3000 {
            let wall_normal = rng.direction();
            let along = wall_normal.any_orthonormal_vector();
            let off_wall = if rng.unit() < 0.5 {
                wall_normal.cross(along)
            } else {
                along.cross(wall_normal)
            };
            let origin = Vec3::new(
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
            );
            let r = if rng.unit() < 0.2 {
                0.0
            } else {
                rng.range(0.0, 0.1)
            };
            let head = origin
                + rng.range(-2.0, 2.0) * along
                + rng.range(-2.0, 2.0) * off_wall
                + (r + rng.range(0.05, 2.0)) * wall_normal;
            let Some(plane) = BorderPlane::new(head, origin, along, off_wall, r) else {
                panic!("no plane for a head in front of its wall");
            };
            // A ball near the head's plane, on either side of the line.
            let centre = origin
                + rng.range(-3.0, 3.0) * along
                + rng.range(-6.0, 6.0) * plane.towards_head
                + rng.range(-0.1, 0.6) * plane.outwards;
            let radius = rng.range(0.0, 0.2);
            tried += 1;
            if !plane.excludes(centre, radius) {
                continue;
            }
            excluded += 1;
            let head_side = plane.outwards.dot(centre - origin) - radius;
            let gamma = plane.towards_head.dot(centre - origin).abs() + radius;
            if head_side < gamma * plane.sin_turn * 4.0 {
                within_turn += 1;
            }
            for _ in 0..60 {
                let eye = head + r * rng.direction();
                let point = centre + radius * rng.unit().sqrt() * rng.direction();
                let normal = along.cross(eye - origin);
                let outer = normal.dot(off_wall).signum();
                assert!(
                    outer * normal.dot(point - origin) > 0.0,
                    "{point} is not beyond the plane of eye {eye} ({plane:?})"
                );
            }
        }
        eprintln!("{excluded} of {tried} balls excluded, {within_turn} near the turn");
        assert!(excluded * 5 > tried, "{excluded} of {tried}");
        assert!(within_turn * 20 > excluded, "{within_turn} of {excluded}");
    }

    #[test]
    fn a_model_beyond_the_front_wall_is_hidden_from_the_other_walls() {
        // A model a lab stands beyond the front wall straddles the eyes' plane parallel to
        // each side wall and to the floor (some of it nearer that wall than the eyes, some
        // further), so "in front of every eye" proves nothing there; the planes through the
        // eyes and the walls' borders do. Over random heads (down to 5 cm from a wall), modes
        // and small clusters beyond the front wall: every cluster proven hidden is invisible
        // point by point, the side walls and the floor hide at least 99 % (without the border
        // planes, 86 %), and the front wall, which shows them, hides none whose centre it
        // draws.
        let mut rng = Rng(0x5151_2026_1207_0042);
        let cave = cave_with_floor();
        let h = 1.65;
        let (mut other_views, mut other_hidden, mut front_drawn) = (0, 0, 0);
        for trial in 0..300 {
            let mode = [
                RenderMode::OmniOffAxis,
                RenderMode::OmniOnAxis,
                RenderMode::Stereo,
            ][trial % 3];
            let near_wall = trial % 5 == 0;
            let head = Head::at(Vec3::new(
                if near_wall {
                    -h + 0.05
                } else {
                    rng.range(-1.3, 1.3)
                },
                rng.range(1.0, 2.0),
                if trial % 5 == 1 {
                    -h + 0.05
                } else {
                    rng.range(-1.3, 1.3)
                },
            ));
            let centre = Vec3::new(
                rng.range(-1.3, 1.3),
                rng.range(0.1, 2.5),
                rng.range(-5.0, -2.0),
            );
            let size = 10f32.powf(rng.range(-2.0, -0.7));
            let scene = random_cluster(&mut rng, centre, size, size, 8, trial % 2 == 0);
            let clusters = build_clusters(&scene, [(0, 0, scene.indices.len() as u32)]);
            let omni = mode.is_omni().then(OmniSettings::default);
            for view in view_setups(&cave, &head, mode, 0.064) {
                let wall = &cave.walls[view.wall];
                let tv = tess_view(&view, wall, Mat4::IDENTITY, omni);
                let test = ClusterTest::new(&tv, Some(Criterion::Error(1.0))).expect("test");
                let verdict = test.verdict(&clusters[0]);
                if verdict == Verdict::Hidden {
                    assert_invisible(&tv, &scene, &clusters[0], trial);
                }
                if wall.name == "front" {
                    let clip = crate::tess::project(&tv, centre).clip;
                    if clip.w > 0.0 && clip.x.abs() < 0.9 * clip.w && clip.y.abs() < 0.9 * clip.w {
                        front_drawn += 1;
                        assert_ne!(verdict, Verdict::Hidden, "trial {trial}: drawn, hidden");
                    }
                } else {
                    other_views += 1;
                    other_hidden += usize::from(verdict == Verdict::Hidden);
                }
            }
        }
        eprintln!(
            "{other_hidden} of {other_views} side-wall and floor views hidden; the front wall \
             draws {front_drawn}"
        );
        assert!(
            other_hidden * 100 >= other_views * 99,
            "{other_hidden} of {other_views}: the side walls and floor hide too little"
        );
        assert!(
            front_drawn > 200,
            "{front_drawn}: the front wall drew too few"
        );
    }

    #[test]
    fn clusters_cover_every_draw_once_and_fine_ranges_merge() {
        let mut rng = Rng(7);
        let scene = random_cluster(&mut rng, Vec3::ZERO, 1.0, 0.1, 150, false);
        let n = scene.indices.len() as u32;
        // Two draws: 100 triangles, then 50.
        let clusters = build_clusters(&scene, [(0, 0, 300), (1, 300, n - 300)]);
        let counts: Vec<(u32, u32, u32)> = clusters
            .iter()
            .map(|c| (c.draw, c.first_triangle, c.triangle_count))
            .collect();
        // Runs of CLUSTER_TRIANGLES from each draw's start, the last one shorter.
        let mut expected = Vec::new();
        for (draw, first, count) in [(0u32, 0u32, 100u32), (1, 100, 50)] {
            let mut t = first;
            while t < first + count {
                let n = CLUSTER_TRIANGLES.min(first + count - t);
                expected.push((draw, t, n));
                t += n;
            }
        }
        assert_eq!(counts, expected);
        for c in &clusters {
            for t in c.first_triangle..c.first_triangle + c.triangle_count {
                for k in 0..3 {
                    let p = Vec3::from(
                        scene.vertices[scene.indices[(3 * t + k) as usize] as usize].position,
                    );
                    assert!(p.distance(c.centre) <= c.radius, "{c:?}");
                }
            }
        }
        let mut split = ClusterSplit::default();
        split.classify(&clusters, &[None], Verdict::Needy);
        assert_eq!(split.needy.len(), expected.len());
        assert!(split.fine.is_empty());
        assert_eq!(split.needy_draws, [0, 1]);
        // Everything fine (uniform:0 splits nothing): consecutive clusters of a draw merge.
        let cave = thesis_cave();
        let views = view_setups(
            &cave,
            &Head::at(Vec3::new(0.0, 1.6, 0.0)),
            RenderMode::Stereo,
            0.064,
        );
        let tv = tess_view(&views[0], &cave.walls[0], Mat4::IDENTITY, None);
        split.classify(&clusters, &[None], Verdict::Fine);
        assert_eq!(split.fine, vec![(0, 0, 300), (1, 300, 150)]);
        assert!(split.needy.is_empty() && split.needy_draws.is_empty());
        assert_eq!(split.fine_triangles(), 150);
        // Uniform subdivision refines every visible cluster; uniform:0 none.
        let test = ClusterTest::new(&tv, Some(Criterion::Uniform(1))).expect("test");
        split.classify(&clusters, &[Some(&test)], Verdict::Needy);
        assert!(split.fine.is_empty());
        let test = ClusterTest::new(&tv, Some(Criterion::Uniform(0))).expect("test");
        split.classify(&clusters, &[Some(&test)], Verdict::Needy);
        assert!(split.needy.is_empty());
    }
}
