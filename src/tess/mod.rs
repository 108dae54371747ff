//! Adaptive tessellation before the omnistereo warp by conforming edge bisection (no GPU):
//! split criteria, culling, and the CPU twin of the compute tessellator
//! (src/render/tessellator.rs + shaders/tessellate.wgsl), which tests compare bit for bit.
//!
//! Every round, each live triangle decides for each of its edges, from that edge alone, whether
//! to split it at its midpoint; 0 split edges finish the triangle, 1, 2 or 3 give 2, 3 or 4
//! children. A shared edge is judged identically by both triangles and halved at the same
//! point, so neighbours always agree: no T-junctions, no cracks, at any depth. Points are kept
//! as exact fixed-point barycentric coordinates of their source triangle; points on a source
//! edge are interpolated between the edge's two vertices in a canonical order, so triangles of
//! different primitives that share positions compute bit-identical points.

pub mod clusters;
pub mod criteria;
pub mod error;
pub mod posed_clusters;

pub use criteria::{Criterion, TessSettings, parse_criterion};

use glam::{Mat4, Vec2, Vec3, Vec4};

use crate::cave::omni::{OmniSettings, omni_eye, warp};
use crate::cave::{ViewSetup, Wall};
use crate::scene::Scene;

/// Fixed-point 1.0 of barycentric coordinates: depth ≤ 16 halvings stay exact.
pub const BARY_ONE: u32 = 1 << 16;
/// Deepest subdivision supported (2^16 segments per edge).
pub const MAX_DEPTH_LIMIT: u32 = 16;

/// Deepest a fallback refinement goes (see [`fallback_depth`]). Keep in sync with
/// shaders/tessellate.wgsl: there it is the culling dispatch's own levels, so the fallback
/// needs no split dispatch.
pub const FALLBACK_DEPTH_LIMIT: u32 = 12;

/// The maximum depth of the fallback refinement of a view whose output budget ran out: the
/// deepest `d ≤ most` at which `roots` kept source triangles, each split into at most 4^d
/// triangles, still fit `capacity`. Refined to that depth, no split is ever refused, so
/// neighbours agree on every shared edge (mirrors `fallback_depth` in shaders/tessellate.wgsl).
pub fn fallback_depth(roots: usize, capacity: usize, most: u32) -> u32 {
    let mut d = 0;
    while d < most && 2 * (d + 1) < 32 && roots <= capacity >> (2 * (d + 1)) {
        d += 1;
    }
    d
}

/// A point of a source triangle: weights of its vertices 1 and 2 (vertex 0 gets the rest), in
/// units of 1/BARY_ONE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Bary {
    pub b1: u32,
    pub b2: u32,
}

impl Bary {
    pub const V0: Bary = Bary { b1: 0, b2: 0 };
    pub const V1: Bary = Bary {
        b1: BARY_ONE,
        b2: 0,
    };
    pub const V2: Bary = Bary {
        b1: 0,
        b2: BARY_ONE,
    };

    pub fn b0(self) -> u32 {
        BARY_ONE - self.b1 - self.b2
    }

    /// Exact midpoint (both coordinates are multiples of 2^-depth with depth < 16).
    pub fn midpoint(self, other: Bary) -> Bary {
        Bary {
            b1: (self.b1 + other.b1) / 2,
            b2: (self.b2 + other.b2) / 2,
        }
    }
}

/// One output triangle: which source triangle, and its corners in that triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TessTriangle {
    pub source: u32,
    pub corners: [Bary; 3],
}

/// Per-view counts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TessStats {
    pub input: u32,
    pub culled_backface: u32,
    pub culled_frustum: u32,
    pub emitted: u32,
    /// The output budget ran out at the asked refinement.
    pub overflowed: bool,
    /// Then the view was refined again with this maximum depth instead (see
    /// [`fallback_depth`]): less refined than asked, but conforming.
    pub fallback_depth: Option<u32>,
}

impl TessStats {
    /// What a user must know when the output budget ran out (`None` when it did not): what
    /// was asked, what was drawn instead, and what to change.
    pub fn shortfall(&self, settings: &TessSettings, capacity: u32) -> Option<String> {
        if !self.overflowed {
            return None;
        }
        let mut asked = settings.max_depth.min(MAX_DEPTH_LIMIT);
        if let Some(Criterion::Uniform(n)) = settings.criterion {
            asked = asked.min(n);
        }
        let criterion = settings
            .criterion
            .map_or_else(|| "none".to_string(), |c| c.to_string());
        Some(match self.fallback_depth {
            Some(depth) => format!(
                "the output budget of {capacity} triangles a view cannot hold {criterion} at \
                 depth {asked}: refined to depth {depth} instead ({} triangles), less than \
                 asked but crack-free; coarsen the criterion or lower max_depth",
                self.emitted
            ),
            None => format!(
                "the output budget of {capacity} triangles a view cannot hold even the \
                 {} source triangles to refine: some are not drawn; coarsen the scene",
                self.input
            ),
        })
    }
}

/// Everything about one wall/eye view the criteria and culling need.
#[derive(Debug, Clone, Copy)]
pub struct TessView<'a> {
    pub view: &'a ViewSetup,
    pub wall: &'a Wall,
    pub cave_from_world: Mat4,
    /// `Some` in the omnistereo modes.
    pub omni: Option<OmniSettings>,
    pub near: f32,
    /// The other eye of the same wall when one refinement serves both (see
    /// [`TessView::paired_with`]): an edge splits where either eye's criterion asks, a
    /// triangle is culled only where both eyes' tests cull it.
    pub partner: Option<&'a ViewSetup>,
}

impl<'a> TessView<'a> {
    /// The same view refined for both eyes of its wall: `other` is the second eye.
    pub fn paired_with(self, other: &'a ViewSetup) -> Self {
        Self {
            partner: Some(other),
            ..self
        }
    }

    /// The eyes whose criteria and culling decide: this view's, then its partner's.
    pub fn eyes(&self) -> impl Iterator<Item = TessView<'a>> + '_ {
        let alone = Self {
            partner: None,
            ..*self
        };
        std::iter::once(alone).chain(self.partner.map(move |view| Self {
            view,
            near: view.near,
            partner: None,
            ..*self
        }))
    }
}

/// Interpolates a source triangle's attribute at a barycentric point, canonically: a vertex is
/// returned as is; a point on an edge is `a + t·(b − a)` with `a` the edge endpoint whose
/// position sorts first; an interior point uses the fixed vertex order 0, 1, 2.
pub fn interpolate<T>(
    values: [T; 3],
    positions: [Vec3; 3],
    at: Bary,
    lerp: impl Fn(T, T, f32) -> T,
    weighted: impl Fn([T; 3], [f32; 3]) -> T,
) -> T
where
    T: Copy,
{
    let w = [at.b0(), at.b1, at.b2];
    let zeros = w.iter().filter(|&&x| x == 0).count();
    if zeros == 2 {
        let i = w.iter().position(|&x| x != 0).unwrap_or(0);
        return values[i];
    }
    if zeros == 1 {
        let z = w.iter().position(|&x| x == 0).unwrap_or(0);
        let (mut i, mut j) = ((z + 1) % 3, (z + 2) % 3);
        if position_order(positions[j], positions[i]) {
            std::mem::swap(&mut i, &mut j);
        }
        let t = w[j] as f32 / BARY_ONE as f32;
        return lerp(values[i], values[j], t);
    }
    let inv = 1.0 / BARY_ONE as f32;
    weighted(
        values,
        [w[0] as f32 * inv, w[1] as f32 * inv, w[2] as f32 * inv],
    )
}

/// Canonical order of positions: lexicographic on (x, y, z); `true` if `a` sorts before `b`.
pub fn position_order(a: Vec3, b: Vec3) -> bool {
    (a.x, a.y, a.z) < (b.x, b.y, b.z)
}

/// Position (scene space) of a point of a source triangle, computed canonically.
pub fn point_position(p: [Vec3; 3], at: Bary) -> Vec3 {
    interpolate(
        p,
        p,
        at,
        |a, b, t| a + t * (b - a),
        |v, w| w[0] * v[0] + w[1] * v[1] + w[2] * v[2],
    )
}

/// A point as drawn: clip coordinates after the (optional) omnistereo warp, and its pixel.
#[derive(Debug, Clone, Copy)]
pub struct Projected {
    pub clip: Vec4,
    /// Pixel coordinates (x right, y down); meaningful only when `clip.w > 0`.
    pub pixel: Vec2,
}

/// Projects a scene-space point the way the vertex shader does: CAVE space, per-vertex eye and
/// warp in omnistereo, then the view's projection.
pub fn project(tv: &TessView<'_>, world: Vec3) -> Projected {
    let p = tv.cave_from_world.transform_point3(world);
    let warped = match (tv.omni, tv.view.omni, tv.view.eye) {
        (Some(settings), Some(o), Some(eye)) => {
            let e = omni_eye(o.head, p, o.ipd, eye, settings.pole_merge);
            warp(settings.warp, p, e, tv.view.eye_position, o.wall_plane)
        }
        _ => p,
    };
    let clip = tv.view.clip_from_cave * warped.extend(1.0);
    Projected {
        clip,
        pixel: clip_to_pixel(clip, tv.wall.resolution),
    }
}

/// Pixel coordinates (x right, y down) of a clip-space point on an image of `resolution`.
pub fn clip_to_pixel(clip: Vec4, resolution: [u32; 2]) -> Vec2 {
    let [w, h] = resolution.map(|v| v as f32);
    Vec2::new(
        (clip.x / clip.w * 0.5 + 0.5) * w,
        (0.5 - clip.y / clip.w * 0.5) * h,
    )
}

/// The eye position(s) of a view for back-face culling: a point and a radius within which
/// every eye of the view lies (the head and IPD/2 in omnistereo, the eye itself otherwise;
/// with a `partner`, the ball through both eyes). The GPU gets the same from
/// `TessUniforms::new`, so both cull alike bit for bit.
pub fn eye_ball(view: &ViewSetup, partner: Option<&ViewSetup>, omni: bool) -> (Vec3, f32) {
    match (omni, view.omni) {
        (true, Some(o)) => (o.head, 0.5 * o.ipd),
        _ => match partner {
            Some(other) => (
                0.5 * (view.eye_position + other.eye_position),
                0.5 * view.eye_position.distance(other.eye_position),
            ),
            None => (view.eye_position, 0.0),
        },
    }
}

/// Slack for back-face culling (metres): a face must be this clearly turned away.
pub const BACKFACE_EPSILON: f32 = 1e-4;

/// Whether a single-sided source triangle (CAVE-space corners) faces away from every eye of
/// the view: conservative, so the warp (which may turn faces slightly) never loses one.
pub fn is_backfacing(tv: &TessView<'_>, cave: [Vec3; 3]) -> bool {
    let n = (cave[1] - cave[0]).cross(cave[2] - cave[0]);
    let len = n.length();
    if len <= 0.0 {
        return false;
    }
    let (centre, radius) = eye_ball(tv.view, tv.partner, tv.omni.is_some());
    n.dot(centre - cave[0]) / len < -(radius + BACKFACE_EPSILON)
}

/// Fraction of w by which a source triangle's sampled points must lie beyond a frustum side to
/// be culled: warped edges are curves, and the samples can miss a bulge into the view.
pub const CULL_MARGIN: f32 = 0.25;

/// Whether points (clip space) all lie outside one frustum plane (or all behind the eye).
pub fn all_outside(points: &[Vec4], near: f32) -> bool {
    all_outside_by(points, near, 0.0)
}

/// As [`all_outside`], with the sides moved outwards by `margin` × w.
pub fn all_outside_by(points: &[Vec4], near: f32, margin: f32) -> bool {
    if points.iter().all(|c| c.w < near) {
        return true;
    }
    if points.iter().any(|c| c.w <= 0.0) {
        return false;
    }
    // Same arithmetic as outside_all in shaders/tessellate.wgsl: m = w·(1 + margin).
    let m = |c: &Vec4| c.w * (1.0 + margin);
    let sides: [&dyn Fn(&Vec4) -> bool; 4] =
        [&|c| c.x > m(c), &|c| c.x < -m(c), &|c| c.y > m(c), &|c| {
            c.y < -m(c)
        }];
    sides.iter().any(|side| points.iter().all(side))
}

/// Result of tessellating all of a scene's triangles for one view.
#[derive(Debug, Clone, Default)]
pub struct TessOutput {
    /// What the tessellator emits.
    pub triangles: Vec<TessTriangle>,
    /// Source triangles of clusters proven fine (`TessSettings::skip_fine`): drawn whole
    /// through the ordinary path, never seen by the tessellator; those its culling tests find
    /// invisible are left out (the rasteriser drops them).
    pub fine: Vec<u32>,
    pub stats: TessStats,
}

impl TessOutput {
    /// Every triangle drawn: the tessellator's, then the fine ones whole.
    pub fn drawn(&self) -> impl Iterator<Item = TessTriangle> + '_ {
        self.triangles
            .iter()
            .copied()
            .chain(self.fine.iter().map(|&t| TessTriangle {
                source: t,
                corners: [Bary::V0, Bary::V1, Bary::V2],
            }))
    }
}

/// Per source triangle: what becomes of its cluster in view `tv` (all `Needy`, the old way,
/// unless `settings.skip_fine` and a criterion are set). Clusters as the renderer makes them:
/// per draw with a material, [`clusters::CLUSTER_TRIANGLES`] at a time.
pub fn cluster_verdicts(
    scene: &Scene,
    tv: &TessView<'_>,
    settings: &TessSettings,
) -> Vec<clusters::Verdict> {
    let mut verdicts = vec![clusters::Verdict::Needy; scene.triangle_count()];
    // Every eye the refinement serves must prove a cluster fine (see `ClusterSplit::classify`).
    let tests: Vec<_> = tv
        .eyes()
        .map(|eye| clusters::ClusterTest::for_settings(&eye, settings, true))
        .collect();
    if tests.iter().any(Option::is_none) {
        return verdicts;
    }
    let draws = scene
        .draws
        .iter()
        .enumerate()
        .filter(|(_, d)| scene.materials.get(d.material).is_some())
        .map(|(i, d)| (i as u32, d.first_index, d.index_count));
    for c in clusters::build_clusters(scene, draws) {
        let range = c.first_triangle as usize..(c.first_triangle + c.triangle_count) as usize;
        let mut judged = tests.iter().flatten().map(|t| t.verdict(&c));
        let own = judged.next().unwrap_or(clusters::Verdict::Needy);
        let verdict = if judged.any(|v| v == clusters::Verdict::Needy) {
            clusters::Verdict::Needy
        } else {
            own
        };
        if let Some(v) = verdicts.get_mut(range) {
            v.fill(verdict);
        }
    }
    verdicts
}

/// The CPU twin of the compute tessellator: culls, then splits round by round.
/// `double_sided[t]` says whether source triangle `t` may be seen from behind (`None`: not
/// drawn at all; see [`double_sided_flags`]); `capacity`
/// bounds the live triangles of a round and, separately, the output, as the GPU's buffers do.
/// If the budget runs out, the view is refined again to [`fallback_depth`] (as cs_fallback
/// does): less refined than asked, never cracked.
pub fn tessellate(
    scene: &Scene,
    double_sided: &[Option<bool>],
    tv: &TessView<'_>,
    settings: &TessSettings,
    capacity: usize,
) -> TessOutput {
    let verdicts = cluster_verdicts(scene, tv, settings);
    let (out, roots) =
        tessellate_once(scene, double_sided, tv, settings, capacity, &verdicts, None);
    if !out.stats.overflowed || settings.criterion.is_none() {
        return out;
    }
    let most = settings
        .max_depth
        .min(MAX_DEPTH_LIMIT)
        .min(FALLBACK_DEPTH_LIMIT);
    // Roots the criterion left whole stay one triangle at any depth; the others share the rest.
    let flat = roots.flat.min(roots.kept);
    let depth = fallback_depth(roots.kept - flat, capacity.saturating_sub(flat), most);
    let fallback = TessSettings {
        max_depth: depth,
        ..*settings
    };
    let (mut out, _) = tessellate_once(
        scene,
        double_sided,
        tv,
        &fallback,
        capacity,
        &verdicts,
        Some(roots.kept),
    );
    out.stats.overflowed = true;
    out.stats.fallback_depth = Some(depth);
    out
}

/// Source triangles a refinement kept for splitting, and those of them the criterion left
/// whole at depth 0 (mirrors the GPU's `C_ROOTS` and `C_FLAT_ROOTS`).
#[derive(Debug, Clone, Copy, Default)]
struct Roots {
    kept: usize,
    flat: usize,
}

/// One refinement of a view (see [`tessellate`]); returns it and its roots.
/// `fallback_roots`: in a fallback refinement, the triangles the first one kept, whose output
/// slots are the only ones reserved.
fn tessellate_once(
    scene: &Scene,
    double_sided: &[Option<bool>],
    tv: &TessView<'_>,
    settings: &TessSettings,
    capacity: usize,
    verdicts: &[clusters::Verdict],
    fallback_roots: Option<usize>,
) -> (TessOutput, Roots) {
    let mut run = TessRun {
        scene,
        tv,
        settings,
        capacity,
        out: TessOutput::default(),
        flat_roots: 0,
    };
    let tri_count = scene.triangle_count();
    run.out.stats.input = tri_count as u32;
    // Triangles added by splitting; a split happens only if they and every source triangle
    // that may be kept (reserved up front, as cs_init splits before every triangle is kept:
    // the GPU's `root_bound`, there every source triangle outside cluster mode) fit
    // `capacity`, so every triangle gets an output slot and an exhausted budget means less
    // refinement, not missing triangles.
    let root_bound = fallback_roots.unwrap_or_else(|| {
        (0..tri_count)
            .filter(|&t| {
                matches!(double_sided.get(t), Some(Some(_)))
                    && verdicts.get(t) == Some(&clusters::Verdict::Needy)
            })
            .count()
    });
    let room = capacity.saturating_sub(root_bound);
    let (live, kept) = run.seed(double_sided, verdicts);

    let Some(criterion) = settings.criterion else {
        run.out.stats.emitted = run.out.triangles.len() as u32;
        return (run.out, Roots { kept, flat: 0 });
    };
    let live = run.refine(live, &criterion, room);
    for tri in live {
        run.emit(tri);
    }
    run.out.stats.emitted = run.out.triangles.len() as u32;
    let flat = run.flat_roots;
    (run.out, Roots { kept, flat })
}

/// The CPU tessellator's state for one view: its inputs and the output so far.
struct TessRun<'a> {
    scene: &'a Scene,
    tv: &'a TessView<'a>,
    settings: &'a TessSettings,
    capacity: usize,
    out: TessOutput,
    /// Source triangles the criterion left whole at depth 0.
    flat_roots: usize,
}

impl TessRun<'_> {
    /// Scene-space corners of source triangle `t`.
    fn positions(&self, t: usize) -> [Vec3; 3] {
        let scene = self.scene;
        [0, 1, 2].map(|k| Vec3::from(scene.vertices[scene.indices[3 * t + k] as usize].position))
    }

    /// Appends a finished triangle (see [`emit`]).
    fn emit(&mut self, tri: TessTriangle) {
        emit(&mut self.out, tri, self.capacity);
    }

    /// The first pass over the source triangles (mirrors cs_init): leaves out the hidden,
    /// sets aside the fine, counts the culled, emits the rest without a criterion and
    /// returns the triangles to refine and how many source triangles it kept for splitting.
    fn seed(
        &mut self,
        double_sided: &[Option<bool>],
        verdicts: &[clusters::Verdict],
    ) -> (Vec<TessTriangle>, usize) {
        let settings = self.settings;
        let root = [Bary::V0, Bary::V1, Bary::V2];
        let mut live: Vec<TessTriangle> = Vec::new();
        let mut roots = 0;
        for t in 0..self.scene.triangle_count() {
            // Triangles without a (valid) draw are never drawn (mirrors cs_init).
            let Some(&Some(double_sided_t)) = double_sided.get(t) else {
                continue;
            };
            let verdict = verdicts.get(t).copied().unwrap_or(clusters::Verdict::Needy);
            if verdict == clusters::Verdict::Hidden {
                // Provably invisible in this view: neither drawn nor tessellated.
                continue;
            }
            if verdict == clusters::Verdict::Fine {
                // Drawn directly by this eye alone: the rasteriser, not the tessellator, drops
                // what this eye's culling tests find invisible (kept out of the tessellator's
                // counts, as on the GPU).
                let own = TessView {
                    partner: None,
                    ..*self.tv
                };
                let (backfacing, outside) = self.cull_in(&own, self.positions(t), double_sided_t);
                if !(backfacing || outside) {
                    self.out.fine.push(t as u32);
                }
                continue;
            }
            let (backfacing, outside) = self.cull_in(self.tv, self.positions(t), double_sided_t);
            if backfacing {
                self.out.stats.culled_backface += 1;
                continue;
            }
            if outside {
                self.out.stats.culled_frustum += 1;
                continue;
            }
            let tri = TessTriangle {
                source: t as u32,
                corners: root,
            };
            if settings.criterion.is_none() || settings.max_depth == 0 {
                self.emit(tri);
                continue;
            }
            roots += 1;
            if live.len() < self.capacity {
                live.push(tri);
            } else {
                self.out.stats.overflowed = true;
                self.emit(tri);
            }
        }
        (live, roots)
    }

    /// The culling tests on a source triangle (scene-space corners `p`) in `tv`: whether it
    /// faces away from every eye, and (if not) whether it lies outside every eye's view.
    fn cull_in(&self, tv: &TessView<'_>, p: [Vec3; 3], double_sided: bool) -> (bool, bool) {
        let settings = self.settings;
        let root = [Bary::V0, Bary::V1, Bary::V2];
        let backfacing = settings.backface_cull
            && !double_sided
            && is_backfacing(tv, p.map(|q| tv.cave_from_world.transform_point3(q)));
        // Outside only if outside every eye's view (a shared refinement serves both).
        let outside = !backfacing
            && settings.frustum_cull
            && tv.eyes().all(|eye| {
                let mut pts = [Vec4::ZERO; 6];
                for k in 0..3 {
                    pts[k] = project(&eye, p[k]).clip;
                    pts[k + 3] =
                        project(&eye, point_position(p, root[k].midpoint(root[(k + 1) % 3]))).clip;
                }
                all_outside_by(&pts, eye.near, CULL_MARGIN)
            });
        (backfacing, outside)
    }

    /// The rounds of splitting: each live triangle splits the edges `criterion` asks for
    /// while the `room` for added triangles lasts, or is emitted; returns the triangles
    /// still live after the deepest round.
    fn refine(
        &mut self,
        mut live: Vec<TessTriangle>,
        criterion: &Criterion,
        room: usize,
    ) -> Vec<TessTriangle> {
        let mut added = 0usize;
        let max_depth = self.settings.max_depth.min(MAX_DEPTH_LIMIT);
        for depth in 0..max_depth {
            if live.is_empty() {
                break;
            }
            let mut next = Vec::with_capacity(live.len() * 2);
            for tri in live {
                let p = self.positions(tri.source as usize);
                let c = tri.corners;
                let split = [0, 1, 2].map(|k| {
                    criteria::split_edge(self.tv, criterion, depth, p, c[k], c[(k + 1) % 3])
                });
                let n_split = split.iter().filter(|&&s| s).count();
                if n_split == 0 {
                    if depth == 0 {
                        self.flat_roots += 1;
                    }
                    self.emit(tri);
                    continue;
                }
                let kids = children(c, split, p);
                let extra = kids.len() - 1;
                if added + extra > room {
                    // Budget: stop refining this triangle and draw it as it is.
                    self.out.stats.overflowed = true;
                    self.emit(tri);
                    continue;
                }
                added += extra;
                next.extend(kids.into_iter().map(|corners| TessTriangle {
                    source: tri.source,
                    corners,
                }));
            }
            live = next;
        }
        live
    }
}

/// Appends a finished triangle, or drops it (flagging overflow) when the output is full.
fn emit(out: &mut TessOutput, tri: TessTriangle, capacity: usize) {
    if out.triangles.len() < capacity {
        out.triangles.push(tri);
    } else {
        out.stats.overflowed = true;
    }
}

/// How much shorter (as a fraction of its squared length) the other diagonal of a two-edge
/// split's quadrilateral must be to be drawn instead of the default one: a margin far above
/// float rounding, so that the GPU and the CPU twin never choose differently on a tie (a
/// square's two diagonals, say). Keep in sync with shaders/tessellate.wgsl.
pub const DIAGONAL_MARGIN: f32 = 1.0 / 1024.0;

/// Children of a triangle with corners `c` (in the source triangle with scene-space corners
/// `p`) whose edges k (c[k]→c[k+1]) are split as given. The same table is in
/// shaders/tessellate.wgsl.
///
/// Two split edges leave a corner triangle and a quadrilateral, which is cut along its shorter
/// diagonal in the scene: the children stay well shaped, where always cutting from the
/// unsplit corner fans out long slivers. Every edge the rasteriser draws then costs fragment
/// work on both sides (the pixels it crosses are shaded for each triangle), so the shorter
/// cut means less work for the same picture; the source edges' subdivision, which the
/// criteria decide edge by edge, is the same either way.
pub fn children(c: [Bary; 3], split: [bool; 3], p: [Vec3; 3]) -> Vec<[Bary; 3]> {
    let m = [0, 1, 2].map(|k| c[k].midpoint(c[(k + 1) % 3]));
    match split {
        [false, false, false] => vec![c],
        [true, true, true] => vec![
            [c[0], m[0], m[2]],
            [m[0], c[1], m[1]],
            [m[2], m[1], c[2]],
            [m[0], m[1], m[2]],
        ],
        _ => {
            // Rotate so the split edges start at edge 0: one split → edge 0; two → edges 0, 1.
            let n = split.iter().filter(|&&s| s).count();
            let r = (0..3)
                .find(|&r| {
                    if n == 1 {
                        split[r]
                    } else {
                        split[r] && split[(r + 1) % 3]
                    }
                })
                .unwrap_or(0);
            let (a, b, cc) = (c[r], c[(r + 1) % 3], c[(r + 2) % 3]);
            let (m0, m1) = (m[r], m[(r + 1) % 3]);
            if n == 1 {
                vec![[a, m0, cc], [m0, b, cc]]
            } else if cut_from_corner(p, a, m0, m1, cc) {
                vec![[a, m0, m1], [m0, b, m1], [a, m1, cc]]
            } else {
                vec![[a, m0, cc], [m0, b, m1], [m0, m1, cc]]
            }
        }
    }
}

/// Whether the quadrilateral a, m0, m1, cc is cut along a–m1 rather than m0–cc: only where
/// a–m1 is shorter in the scene by more than [`DIAGONAL_MARGIN`].
fn cut_from_corner(p: [Vec3; 3], a: Bary, m0: Bary, m1: Bary, cc: Bary) -> bool {
    let length2 = |u: Bary, v: Bary| {
        let d = point_position(p, u) - point_position(p, v);
        d.dot(d)
    };
    length2(a, m1) < length2(m0, cc) * (1.0 - DIAGONAL_MARGIN)
}

/// How a view's refinement is shared with the other eye of its wall.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EyeShare {
    /// Refined for itself alone.
    Alone,
    /// Refined for itself and view `partner` (the next view, its wall's other eye).
    Leads { partner: usize },
    /// Draws view `leader`'s refinement (the previous view) with its own warp.
    Follows { leader: usize },
}

/// Each view's [`EyeShare`] in a frame's `views` (walls' eyes in order, as
/// [`crate::cave::view_setups`] lists them), into `out`: consecutive views of one wall with
/// both eyes share one refinement when `shared` is on; everything else is refined alone.
pub fn eye_shares(views: &[ViewSetup], shared: bool, out: &mut Vec<EyeShare>) {
    out.clear();
    out.resize(views.len(), EyeShare::Alone);
    if !shared {
        return;
    }
    let mut i = 0;
    while i + 1 < views.len() {
        let (a, b) = (&views[i], &views[i + 1]);
        if a.wall == b.wall && a.eye.is_some() && b.eye.is_some() && a.eye != b.eye {
            out[i] = EyeShare::Leads { partner: i + 1 };
            out[i + 1] = EyeShare::Follows { leader: i };
            i += 2;
        } else {
            i += 1;
        }
    }
}

/// The other eye whose refinement view `index` of `views` shares with `settings`, as the
/// renderer pairs them (see [`eye_shares`]): for the CPU twin of what view `index` draws.
pub fn shared_partner<'v>(
    views: &'v [ViewSetup],
    index: usize,
    settings: &TessSettings,
) -> Option<&'v ViewSetup> {
    let mut shares = Vec::new();
    eye_shares(
        views,
        settings.criterion.is_some() && settings.shared_eyes,
        &mut shares,
    );
    match shares.get(index)? {
        EyeShare::Alone => None,
        EyeShare::Leads { partner: other } | EyeShare::Follows { leader: other } => {
            views.get(*other)
        }
    }
}

/// One view's context from the usual renderer inputs (the near plane is the view's).
pub fn tess_view<'a>(
    view: &'a ViewSetup,
    wall: &'a Wall,
    world_from_cave: Mat4,
    omni: Option<OmniSettings>,
) -> TessView<'a> {
    TessView {
        view,
        wall,
        cave_from_world: world_from_cave.inverse(),
        omni,
        near: view.near,
        partner: None,
    }
}

/// Per source triangle: whether its material is double-sided (never back-face culled), or
/// `None` when no draw with a valid material covers it (the renderer never draws those).
pub fn double_sided_flags(scene: &Scene) -> Vec<Option<bool>> {
    let mut flags = vec![None; scene.triangle_count()];
    for d in &scene.draws {
        let Some(material) = scene.materials.get(d.material) else {
            continue;
        };
        let first = d.first_index as usize / 3;
        for f in flags
            .iter_mut()
            .skip(first)
            .take(d.index_count as usize / 3)
        {
            *f = Some(material.double_sided);
        }
    }
    flags
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fallback_depth_is_the_deepest_that_fits() {
        // (roots, capacity, most) → depth, worked by hand: 4^d · roots ≤ capacity.
        for (roots, capacity, most, depth) in [
            (1, 16, 12, 2),
            (1, 15, 12, 1),
            (3, 48, 12, 2),
            (3, 47, 12, 1),
            (5, 4, 12, 0),
            (1, 1 << 20, 12, 10),
            (12, 1 << 20, 12, 8),
            (1, usize::MAX, 12, 12),
            (1, usize::MAX, 3, 3),
            (0, 0, 7, 7),
        ] {
            assert_eq!(
                fallback_depth(roots, capacity, most),
                depth,
                "{roots} roots in {capacity}, at most {most}"
            );
        }
    }

    #[test]
    fn children_cover_the_parent_with_matching_winding() {
        let c = [Bary::V0, Bary::V1, Bary::V2];
        let area = |t: [Bary; 3]| {
            let p = t.map(|b| glam::DVec2::new(f64::from(b.b1), f64::from(b.b2)));
            (p[1] - p[0]).perp_dot(p[2] - p[0])
        };
        // A right triangle, a long sliver and one stretched the other way: between them every
        // two-edge split is cut along each of its diagonals somewhere.
        let shapes = [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [
                Vec3::ZERO,
                Vec3::new(8.0, 0.0, 0.0),
                Vec3::new(8.0, 0.5, 0.0),
            ],
            [
                Vec3::ZERO,
                Vec3::new(0.5, 0.0, 0.0),
                Vec3::new(0.0, 8.0, 0.0),
            ],
        ];
        let mut cuts = std::collections::HashSet::new();
        for p in shapes {
            for mask in 0..8u8 {
                let split = [mask & 1 != 0, mask & 2 != 0, mask & 4 != 0];
                let kids = children(c, split, p);
                let n = split.iter().filter(|&&s| s).count();
                assert_eq!(kids.len(), [1, 2, 3, 4][n], "{split:?}");
                let total: f64 = kids.iter().map(|&k| area(k)).sum();
                assert_eq!(total, area(c), "{split:?} children do not tile the parent");
                for k in &kids {
                    assert!(area(*k) > 0.0, "{split:?}: child {k:?} is flipped or empty");
                }
                if n == 2 {
                    // Which diagonal: does a child join the first split edge's start to the
                    // second split edge's midpoint?
                    cuts.insert(kids[0][2] != kids[2][2]);
                }
            }
        }
        assert_eq!(cuts.len(), 2, "both diagonals must occur");
    }

    #[test]
    fn a_two_edge_split_is_cut_along_the_shorter_diagonal() {
        let c = [Bary::V0, Bary::V1, Bary::V2];
        let diagonal = |p: [Vec3; 3], kids: &[[Bary; 3]]| -> f32 {
            // The edge the two non-corner children share.
            let shared: Vec<Bary> = kids[0]
                .iter()
                .copied()
                .filter(|b| kids[2].contains(b))
                .collect();
            assert_eq!(shared.len(), 2, "{kids:?}");
            point_position(p, shared[0]).distance(point_position(p, shared[1]))
        };
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut random = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 40) as f32 / (1u64 << 24) as f32 * 10.0 - 5.0
        };
        for _ in 0..500 {
            let p = [0; 3].map(|_| Vec3::new(random(), random(), random()));
            for split in [
                [true, true, false],
                [false, true, true],
                [true, false, true],
            ] {
                let kids = children(c, split, p);
                // kids[1] is the corner triangle; kids[0] and kids[2] tile the quadrilateral
                // and share the diagonal drawn. The other joins the two corners they do not share.
                let drawn = diagonal(p, &kids);
                let all: std::collections::BTreeSet<Bary> =
                    kids[0].iter().chain(&kids[2]).copied().collect();
                let others: Vec<Bary> = all
                    .iter()
                    .copied()
                    .filter(|b| !(kids[0].contains(b) && kids[2].contains(b)))
                    .collect();
                assert_eq!(others.len(), 2);
                let other = point_position(p, others[0]).distance(point_position(p, others[1]));
                // The default cut stays within the margin of a tie.
                assert!(
                    drawn * drawn * (1.0 - DIAGONAL_MARGIN) <= other * other,
                    "{split:?}: cut {drawn} where {other} was shorter"
                );
            }
        }
    }

    #[test]
    fn shared_edge_points_are_bit_identical_from_either_side() {
        // Two triangles sharing the edge a–b, listing it in opposite directions.
        let a = Vec3::new(0.1, 0.2, 0.3);
        let b = Vec3::new(1.7, -0.4, 2.9);
        let t1 = [a, b, Vec3::new(0.0, 5.0, 0.0)];
        let t2 = [b, a, Vec3::new(3.0, -5.0, 1.0)];
        for k in 1..64u32 {
            let s = k * (BARY_ONE / 64);
            // Point at parameter s along a→b: in t1 it is (b0 = 1 − s, b1 = s); in t2 b0 = s.
            let p1 = point_position(t1, Bary { b1: s, b2: 0 });
            let p2 = point_position(
                t2,
                Bary {
                    b1: BARY_ONE - s,
                    b2: 0,
                },
            );
            assert_eq!(p1, p2, "k = {k}");
        }
    }
}
