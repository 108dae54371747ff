//! The map: every viewer position of a floor grid judged against every scene point, per
//! method, reduced to percentiles per viewer and to the floor area where they stay within the
//! thresholds (the "sweet area").

use glam::DVec3;

use super::{Gaze, Method, Setup, judge};
use crate::cave::Cave;

/// The viewer positions: a square grid over the CAVE's floor at one eye height, cells whose
/// centre lies inside the CAVE (in front of every wall, [`crate::cave::HEAD_MARGIN_M`] in).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Centre of the first cell (smallest x and z), metres.
    pub first: [f64; 2],
    /// Cell size, metres.
    pub step: f64,
    /// Cells along x and along z.
    pub columns: usize,
    pub rows: usize,
    pub eye_height: f64,
    /// Per cell (row-major, rows along z): whether a viewer may stand there.
    pub inside: Vec<bool>,
    /// Where a viewer may stand on the floor plan (x and z, least and greatest): edge cells
    /// count only their part inside it.
    pub bounds: [[f64; 2]; 2],
}

/// A cell counts as inside at least this far in front of every wall (the head's margin, less
/// the f32 rounding of the walls).
const INSIDE_M: f64 = crate::cave::HEAD_MARGIN_M as f64 - 1e-4;

/// The finest grid step, metres.
pub const MIN_STEP_M: f64 = 0.005;

/// Most cells a grid may have (a 0.01 m grid over a 10 m room): bounds memory and time.
pub const MAX_CELLS: usize = 1_000_000;

impl Grid {
    /// A grid of `step`-metre cells over the floor of `cave` at `eye_height`.
    pub fn over(cave: &Cave, step: f64, eye_height: f64) -> Result<Self, String> {
        if !(step.is_finite() && step >= MIN_STEP_M) {
            return Err(format!(
                "grid step {step} m must be at least {MIN_STEP_M} m"
            ));
        }
        let (lo, hi) = Cave::head_bounds(&cave.walls);
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        if !(lo.x.is_finite() && lo.z.is_finite() && hi.x.is_finite() && hi.z.is_finite()) {
            return Err(
                "the walls do not enclose a floor (a flat or open CAVE has no grid)".into(),
            );
        }
        // The epsilon keeps 3.2 / 0.1 at 32 cells whichever way it rounds.
        let columns = (((hi.x - lo.x) / step + 1e-9).floor() as usize) + 1;
        let rows = (((hi.z - lo.z) / step + 1e-9).floor() as usize) + 1;
        if columns.saturating_mul(rows) > MAX_CELLS {
            return Err(format!(
                "a {step} m grid has {columns} × {rows} cells, over the {MAX_CELLS} allowed"
            ));
        }
        // Centred in the bounds.
        let first = [
            0.5 * (lo.x + hi.x) - 0.5 * (columns - 1) as f64 * step,
            0.5 * (lo.z + hi.z) - 0.5 * (rows - 1) as f64 * step,
        ];
        let mut grid = Self {
            first,
            step,
            columns,
            rows,
            eye_height,
            inside: Vec::with_capacity(columns * rows),
            bounds: [[lo.x, lo.z], [hi.x, hi.z]],
        };
        for cell in 0..columns * rows {
            let g = grid.viewer(cell);
            let inside = cave
                .walls
                .iter()
                .all(|w| f64::from(w.signed_distance(g.as_vec3())) > INSIDE_M);
            grid.inside.push(inside);
        }
        Ok(grid)
    }

    /// The viewer's cyclopean eye at `cell`.
    pub fn viewer(&self, cell: usize) -> DVec3 {
        let (column, row) = (cell % self.columns, cell / self.columns);
        DVec3::new(
            self.first[0] + column as f64 * self.step,
            self.eye_height,
            self.first[1] + row as f64 * self.step,
        )
    }

    /// A grid without cells (a CAVE with no floor to stand on).
    pub fn empty(step: f64, eye_height: f64) -> Self {
        Self {
            first: [0.0; 2],
            step,
            columns: 0,
            rows: 0,
            eye_height,
            inside: Vec::new(),
            bounds: [[0.0; 2]; 2],
        }
    }

    /// Floor area of `cell` inside the bounds, m² (the cells are centred on the room, so the
    /// outermost ones reach half a step past its edge: counting them whole would make the
    /// areas depend on the step).
    pub fn cell_area(&self, cell: usize) -> f64 {
        let v = self.viewer(cell);
        let h = 0.5 * self.step;
        let [[x0, z0], [x1, z1]] = self.bounds;
        let span = |c: f64, lo: f64, hi: f64| ((c + h).min(hi) - (c - h).max(lo)).max(0.0);
        span(v.x, x0, x1) * span(v.z, z0, z1)
    }
}

/// When a viewer's view counts as good.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// The 95th percentile of |vertical disparity| stays below this (fusion fails beyond
    /// about 20 arcmin).
    pub vertical_arcmin: f64,
    /// The 95th percentile of the direction error stays below this.
    pub direction_degrees: f64,
}

impl Thresholds {
    /// The vertical limit alone: where the two images can be fused at all, wherever the
    /// point appears.
    pub fn fusion_only(&self) -> Self {
        Self {
            direction_degrees: f64::INFINITY,
            ..*self
        }
    }
}

impl Default for Thresholds {
    fn default() -> Self {
        Self {
            vertical_arcmin: 20.0,
            direction_degrees: 1.0,
        }
    }
}

/// One viewer's figures over the points the method shows them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewerFigures {
    /// Points judged (shown by the method and in front of the viewer).
    pub seen: usize,
    /// 95th percentiles of |vertical disparity|, the direction error and |horizontal
    /// disparity error|, arc minutes.
    pub vertical_p95: f64,
    pub direction_p95: f64,
    pub horizontal_p95: f64,
    /// 5th, 50th and 95th percentiles of the depth ratio.
    pub depth_p5: f64,
    pub depth_median: f64,
    pub depth_p95: f64,
}

impl ViewerFigures {
    /// Whether this viewer's view is within `limits`.
    pub fn within(&self, limits: &Thresholds) -> bool {
        self.seen > 0
            && self.vertical_p95 < limits.vertical_arcmin
            && self.direction_p95 < limits.direction_degrees * 60.0
    }
}

/// One method's map.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodMap {
    pub method: Method,
    /// The method whose computation this map is (itself, or the other omnistereo mode with
    /// the same eyes, see [`Method::eye_rule`]).
    pub computed_as: Method,
    /// Per cell of the grid; `None` outside the CAVE or where no point is seen.
    pub cells: Vec<Option<ViewerFigures>>,
    /// Points the method draws on the walls for both eyes (of those given).
    pub shown_points: usize,
    /// How far a viewer may step from the assumed head within the limits, per direction
    /// ([`REACH_DIRECTIONS`] from +x towards +z), metres; and the area they bound, m².
    pub reach_m: Vec<f64>,
    pub reach_area_m2: f64,
    /// The area within reach under the vertical limit alone ([`Thresholds::fusion_only`]).
    pub fusion_reach_area_m2: f64,
}

/// Directions [`sweet_reach`] walks for a map.
pub const REACH_DIRECTIONS: usize = 24;
/// Its coarse step, metres.
pub const REACH_STEP_M: f64 = 0.05;

impl MethodMap {
    /// Floor area (m²) of the cells within `limits`.
    pub fn sweet_area(&self, grid: &Grid, limits: &Thresholds) -> f64 {
        self.cells
            .iter()
            .enumerate()
            .filter(|(_, f)| f.is_some_and(|f| f.within(limits)))
            .map(|(cell, _)| grid.cell_area(cell))
            .sum::<f64>()
            // An empty sum is −0.
            + 0.0
    }

    /// Floor area (m²) of the cells inside the CAVE.
    pub fn floor_area(grid: &Grid) -> f64 {
        (0..grid.inside.len())
            .filter(|c| grid.inside[*c])
            .map(|c| grid.cell_area(c))
            .sum::<f64>()
            + 0.0
    }
}

/// Most scene points one map judges.
pub const MAX_POINTS: usize = 200_000;

/// Most point-and-viewer judgements one `omnicave guests` run makes (cells × points × distinct
/// methods × eye heights): about half a minute on 2 cores.
pub const MAX_JUDGEMENTS: u64 = 1_000_000_000;

/// Most worker threads a map uses.
pub const MAX_THREADS: usize = 64;

/// Every method's map over `grid` for `points`, on `threads` threads (0: as many as the
/// machine has). Methods that share an eye rule (the two omnistereo modes) are computed once.
pub fn compute(
    setup: &Setup,
    methods: &[Method],
    points: &[DVec3],
    grid: &Grid,
    gaze: Gaze,
    limits: &Thresholds,
    threads: usize,
) -> Vec<MethodMap> {
    let points = &points[..points.len().min(MAX_POINTS)];
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
    .clamp(1, MAX_THREADS);
    let mut maps: Vec<MethodMap> = Vec::with_capacity(methods.len());
    for &method in methods {
        if let Some(done) = maps
            .iter()
            .find(|m| m.method.eye_rule() == method.eye_rule())
        {
            let mut copy = done.clone();
            copy.method = method;
            maps.push(copy);
            continue;
        }
        let drawn = drawn(setup, method, points);
        let cells = map_cells(setup.ipd, grid, gaze, &drawn, threads);
        let centre = setup.assumed_head(method.assumed).position.as_dvec3();
        let centre = DVec3::new(centre.x, grid.eye_height, centre.z);
        let (reach_m, reach_area_m2) = sweet_reach(setup, &drawn, centre, gaze, limits);
        let (_, fusion_reach_area_m2) =
            sweet_reach(setup, &drawn, centre, gaze, &limits.fusion_only());
        maps.push(MethodMap {
            method,
            computed_as: method,
            cells,
            shown_points: drawn.len(),
            reach_m,
            reach_area_m2,
            fusion_reach_area_m2,
        });
    }
    maps
}

/// [`compute`] with each assumed head's own points: `points_for` gives the points judged for
/// methods assuming the head at its argument (what that head sees). Maps in `methods`' order;
/// also returns the most points any head was given.
pub fn compute_each_assumed(
    setup: &Setup,
    methods: &[Method],
    points_for: impl Fn(DVec3) -> Vec<DVec3>,
    grid: &Grid,
    gaze: Gaze,
    limits: &Thresholds,
    threads: usize,
) -> (Vec<MethodMap>, usize) {
    let mut maps: Vec<MethodMap> = Vec::with_capacity(methods.len());
    let mut most = 0;
    for assumed in [super::Assumed::Head, super::Assumed::Centre] {
        let group: Vec<Method> = methods
            .iter()
            .copied()
            .filter(|m| m.assumed == assumed)
            .collect();
        if group.is_empty() {
            continue;
        }
        let points = points_for(setup.assumed_head(assumed).position.as_dvec3());
        most = most.max(points.len());
        maps.extend(compute(setup, &group, &points, grid, gaze, limits, threads));
    }
    maps.sort_by_key(|m| methods.iter().position(|r| *r == m.method));
    (maps, most)
}

/// Where `method` draws each of `points` (those it draws for both eyes): the same for every
/// viewer.
pub fn drawn(setup: &Setup, method: Method, points: &[DVec3]) -> Vec<(DVec3, [DVec3; 2])> {
    points
        .iter()
        .filter_map(|&p| setup.shown_at(method, p).map(|s| (p, s)))
        .collect()
}

/// Each cell's figures, the cells split between `threads` threads.
fn map_cells(
    ipd: f64,
    grid: &Grid,
    gaze: Gaze,
    drawn: &[(DVec3, [DVec3; 2])],
    threads: usize,
) -> Vec<Option<ViewerFigures>> {
    let cells: Vec<usize> = (0..grid.inside.len()).collect();
    let chunk = cells.len().div_ceil(threads.max(1)).max(1);
    let mut out = vec![None; cells.len()];
    std::thread::scope(|scope| {
        let handles: Vec<_> = out
            .chunks_mut(chunk)
            .zip(cells.chunks(chunk))
            .map(|(slots, ids)| {
                scope.spawn(move || {
                    let mut scratch = Scratch::default();
                    for (slot, &cell) in slots.iter_mut().zip(ids) {
                        if grid.inside[cell] {
                            *slot =
                                viewer_figures(ipd, grid.viewer(cell), gaze, drawn, &mut scratch);
                        }
                    }
                })
            })
            .collect();
        for handle in handles {
            // A panicking worker is a bug: said in the log; its cells stay empty.
            if handle.join().is_err() {
                tracing::error!("a guest map worker panicked; some cells are left empty");
            }
        }
    });
    out
}

/// Per-thread buffers reused from cell to cell.
#[derive(Debug, Default)]
pub struct Scratch {
    vertical: Vec<f64>,
    direction: Vec<f64>,
    horizontal: Vec<f64>,
    depth: Vec<f64>,
}

/// One viewer's figures over `drawn` (each point and where it is drawn).
pub fn viewer_figures(
    ipd: f64,
    g: DVec3,
    gaze: Gaze,
    drawn: &[(DVec3, [DVec3; 2])],
    scratch: &mut Scratch,
) -> Option<ViewerFigures> {
    scratch.vertical.clear();
    scratch.direction.clear();
    scratch.horizontal.clear();
    scratch.depth.clear();
    for &(p, shown) in drawn {
        if let Some(j) = judge(g, ipd, gaze, p, shown) {
            scratch.vertical.push(j.vertical_arcmin.abs());
            scratch.direction.push(j.direction_arcmin);
            scratch.horizontal.push(j.horizontal_arcmin.abs());
            scratch.depth.push(j.depth_ratio);
        }
    }
    let seen = scratch.vertical.len();
    (seen > 0).then(|| ViewerFigures {
        seen,
        vertical_p95: percentile(&mut scratch.vertical, 0.95),
        direction_p95: percentile(&mut scratch.direction, 0.95),
        horizontal_p95: percentile(&mut scratch.horizontal, 0.95),
        depth_p5: percentile(&mut scratch.depth, 0.05),
        depth_median: percentile(&mut scratch.depth, 0.5),
        depth_p95: percentile(&mut scratch.depth, 0.95),
    })
}

/// How far a viewer may step from `centre` in each of [`REACH_DIRECTIONS`] evenly spread
/// horizontal directions (metres) and stay within `limits`, and the area of the star-shaped
/// region those reaches bound. Each direction is walked in [`REACH_STEP_M`] steps to the first
/// viewer outside the limits (or the walls), then bisected to 1/64 of a step (0.8 mm): finer
/// than any grid, for the sweep.
/// Assumes the region is star-shaped around `centre` (the errors grow with the distance from
/// the assumed head; a region with holes is under-reported).
pub fn sweet_reach(
    setup: &Setup,
    drawn: &[(DVec3, [DVec3; 2])],
    centre: DVec3,
    gaze: Gaze,
    limits: &Thresholds,
) -> (Vec<f64>, f64) {
    let (directions, coarse) = (REACH_DIRECTIONS, REACH_STEP_M);
    let mut scratch = Scratch::default();
    let mut good = |g: DVec3| {
        setup.inside(g, INSIDE_M)
            && viewer_figures(setup.ipd, g, gaze, drawn, &mut scratch)
                .is_some_and(|f| f.within(limits))
    };
    if !good(centre) {
        return (vec![0.0; directions], 0.0);
    }
    let reaches: Vec<f64> = (0..directions)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / directions as f64;
            let dir = DVec3::new(a.cos(), 0.0, a.sin());
            let mut r = 0.0;
            // The CAVE is at most a few tens of metres across.
            while r < 100.0 && good(centre + (r + coarse) * dir) {
                r += coarse;
            }
            let (mut lo, mut hi) = (r, r + coarse);
            for _ in 0..6 {
                let mid = 0.5 * (lo + hi);
                if good(centre + mid * dir) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        })
        .collect();
    let wedge = (std::f64::consts::TAU / directions as f64).sin();
    let area = (0..directions)
        .map(|k| 0.5 * reaches[k] * reaches[(k + 1) % directions] * wedge)
        .sum();
    (reaches, area)
}

/// The nearest-rank percentile `q` (0..1) of `values` (reordered); NaN when empty.
pub fn percentile(values: &mut [f64], q: f64) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    let rank = ((q * n as f64).ceil() as usize).clamp(1, n) - 1;
    *values.select_nth_unstable_by(rank, f64::total_cmp).1
}
