//! The maps drawn: a top view of the CAVE (CAVE −z up: the bundled config's front wall) with each grid cell coloured by one
//! metric of one method, the walls, the assumed head, the sweet area's outline and a legend;
//! one colour scale per metric, shared by every method. SVG, and PNG through the bench's
//! renderer.

use std::fmt::Write as _;

use glam::DVec3;

use super::grid::{Grid, MethodMap, Thresholds, ViewerFigures};
use crate::cave::Cave;

/// What a map colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Metric {
    /// 95th percentile of |vertical disparity|, arcmin.
    Vertical,
    /// 95th percentile of the direction error, arcmin.
    Direction,
    /// 95th percentile of |horizontal disparity error|, arcmin.
    Horizontal,
    /// Median depth ratio |P′ − G| / |P − G|.
    Depth,
}

crate::named_enum!(Metric {
    Self::Vertical => "vertical-disparity",
    Self::Direction => "direction-error",
    Self::Horizontal => "horizontal-disparity-error",
    Self::Depth => "depth-ratio",
});

impl Metric {
    /// The metric's value for one viewer.
    pub fn of(self, f: &ViewerFigures) -> f64 {
        match self {
            Metric::Vertical => f.vertical_p95,
            Metric::Direction => f.direction_p95,
            Metric::Horizontal => f.horizontal_p95,
            Metric::Depth => f.depth_median,
        }
    }

    /// What the legend says.
    pub fn title(self) -> &'static str {
        match self {
            Metric::Vertical => "vertical disparity, 95th percentile (arcmin)",
            Metric::Direction => "direction error, 95th percentile (arcmin)",
            Metric::Horizontal => "horizontal disparity error, 95th percentile (arcmin)",
            Metric::Depth => "depth ratio |P'−G| / |P−G|, median",
        }
    }

    /// The threshold marked on the legend, in the metric's unit.
    fn threshold(self, limits: &Thresholds) -> Option<f64> {
        match self {
            Metric::Vertical => Some(limits.vertical_arcmin),
            Metric::Direction => Some(limits.direction_degrees * 60.0),
            _ => None,
        }
    }
}

/// Smallest error the arcmin scales resolve.
const LOG_FLOOR_ARCMIN: f64 = 1.0;

/// A logarithmic colour scale: from [`LOG_FLOOR_ARCMIN`] up (arcmin metrics) or around 1 (the
/// depth ratio).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    pub metric: Metric,
    pub lo: f64,
    pub hi: f64,
}

impl Scale {
    /// One scale for `metric` over every map: logarithmic from 1 arcmin (below: the first
    /// colour) to the largest value drawn, rounded up; the depth ratio from 1/2 to 2. The
    /// errors span three decades between a viewer at the assumed head and one at a wall, so a
    /// linear scale would show one colour almost everywhere.
    pub fn shared(metric: Metric, maps: &[MethodMap], limits: &Thresholds) -> Self {
        if metric == Metric::Depth {
            return Self {
                metric,
                lo: 0.5,
                hi: 2.0,
            };
        }
        let largest = maps
            .iter()
            .flat_map(|m| m.cells.iter().flatten())
            .map(|f| metric.of(f))
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        let threshold = metric.threshold(limits).unwrap_or(1.0);
        Self {
            metric,
            lo: LOG_FLOOR_ARCMIN,
            hi: nice_ceiling(largest.max(2.0 * threshold).max(10.0 * LOG_FLOOR_ARCMIN)),
        }
    }

    /// 0..1 along the scale (clamped; logarithmic).
    pub fn position(&self, v: f64) -> f64 {
        let t = (v.max(1e-12).ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln());
        if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) }
    }

    /// The legend's ticks: 1, 2 and 5 of each decade (0.5 to 2 in quarters and halves for
    /// the depth ratio), and the scale's ends.
    fn ticks(&self) -> Vec<f64> {
        if self.metric == Metric::Depth {
            return vec![0.5, 0.75, 1.0, 1.5, 2.0];
        }
        let mut ticks = vec![self.lo];
        let mut decade = 10f64.powf(self.lo.log10().floor());
        while decade <= self.hi {
            for m in [1.0, 2.0, 5.0] {
                let t = m * decade;
                if t > self.lo * 1.0001 && t < self.hi * 0.9999 {
                    ticks.push(t);
                }
            }
            decade *= 10.0;
        }
        ticks.push(self.hi);
        ticks
    }
}

/// The smallest of 1, 2, 2.5, 5 × 10ⁿ at or above `v`.
fn nice_ceiling(v: f64) -> f64 {
    let decade = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|x| *x >= v * 0.9999)
        .unwrap_or(10.0 * decade)
}

/// Viridis at `t` in 0..1 (eight stops, linearly between), as `#rrggbb`; the depth ratio
/// uses a diverging blue–white–red instead.
fn colour(metric: Metric, t: f64) -> String {
    let [r, g, b] = colour_rgb(metric, t);
    format!("#{r:02x}{g:02x}{b:02x}")
}

/// [`colour`] as sRGB bytes (the panel's map).
pub fn colour_rgb(metric: Metric, t: f64) -> [u8; 3] {
    const VIRIDIS: [[f64; 3]; 8] = [
        [68.0, 1.0, 84.0],
        [70.0, 50.0, 127.0],
        [54.0, 92.0, 141.0],
        [39.0, 127.0, 142.0],
        [31.0, 161.0, 135.0],
        [74.0, 194.0, 109.0],
        [159.0, 218.0, 58.0],
        [253.0, 231.0, 37.0],
    ];
    const DIVERGING: [[f64; 3]; 3] = [
        [49.0, 54.0, 149.0],
        [247.0, 247.0, 247.0],
        [165.0, 0.0, 38.0],
    ];
    let stops: &[[f64; 3]] = if metric == Metric::Depth {
        &DIVERGING
    } else {
        &VIRIDIS
    };
    let x = t.clamp(0.0, 1.0) * (stops.len() - 1) as f64;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|k| (stops[i][k] + f * (stops[i + 1][k] - stops[i][k])).round() as u8)
}

/// One map as SVG: `map`'s `scale.metric` over `grid`, the walls of `cave`, the assumed head
/// at `assumed` and the outline of the cells within `limits`.
pub fn svg(
    cave: &Cave,
    grid: &Grid,
    map: &MethodMap,
    scale: &Scale,
    assumed: DVec3,
    limits: &Thresholds,
) -> String {
    let cell_px = (440.0 / grid.columns.max(grid.rows) as f64).clamp(2.0, 40.0);
    let (left, top) = (40.0, 88.0);
    let (pw, ph) = (grid.columns as f64 * cell_px, grid.rows as f64 * cell_px);
    let (w, h) = (left + pw + 150.0, top + ph + 60.0);
    // Page position of a floor point (x right, −z up: CAVE space's front at the top).
    let x0 = grid.first[0] - 0.5 * grid.step;
    let z0 = grid.first[1] - 0.5 * grid.step;
    let page = |x: f64, z: f64| {
        (
            left + (x - x0) / grid.step * cell_px,
            top + (z - z0) / grid.step * cell_px,
        )
    };
    let mut out = String::new();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="Ubuntu, DejaVu Sans, Arial, sans-serif" font-size="12" shape-rendering="crispEdges">"#
    );
    let _ = writeln!(
        out,
        r#"<rect width="{w:.0}" height="{h:.0}" fill="white"/>"#
    );
    let area = map.sweet_area(grid, limits);
    let _ = writeln!(
        out,
        r#"<text x="{left}" y="22" font-size="15">{}</text>"#,
        map.method.name()
    );
    let _ = writeln!(
        out,
        r##"<text x="{left}" y="42" fill="#444">{}</text>"##,
        scale.metric.title()
    );
    let _ = writeln!(
        out,
        r##"<text x="{left}" y="58" fill="#444">fusion area (dashed: p95 vertical &lt; {} arcmin) {:.2} m²; sweet area (solid: and direction &lt; {}°)</text><text x="{left}" y="74" fill="#444">{area:.2} m², within reach of the white dot {:.4} m²; floor {:.2} m²</text>"##,
        limits.vertical_arcmin,
        map.sweet_area(grid, &limits.fusion_only()),
        limits.direction_degrees,
        map.reach_area_m2,
        MethodMap::floor_area(grid),
    );
    for (cell, figures) in map.cells.iter().enumerate() {
        let v = grid.viewer(cell);
        let (px, py) = page(v.x - 0.5 * grid.step, v.z - 0.5 * grid.step);
        let fill = match figures {
            Some(f) => colour(scale.metric, scale.position(scale.metric.of(f))),
            None if grid.inside[cell] => "#bbbbbb".into(),
            None => continue,
        };
        let _ = writeln!(
            out,
            r#"<rect x="{px:.2}" y="{py:.2}" width="{cell_px:.2}" height="{cell_px:.2}" fill="{fill}"/>"#
        );
    }
    // The fusion area's outline (dashed) and the sweet area's (solid): every cell edge
    // between a cell within the limits and one not.
    let fusion = limits.fusion_only();
    for (lims, dash) in [(&fusion, r#" stroke-dasharray="5,3""#), (limits, "")] {
        let outline = outline_path(grid, map, lims, &page, cell_px);
        if !outline.is_empty() {
            let _ = writeln!(
                out,
                r#"<path d="{outline}" stroke="white" stroke-width="2" fill="none"{dash}/>"#
            );
        }
    }
    for wall in &cave.walls {
        let (a, b) = (wall.lower_left.as_dvec3(), wall.lower_right.as_dvec3());
        let (ax, ay) = page(a.x, a.z);
        let (bx, by) = page(b.x, b.z);
        let _ = writeln!(
            out,
            r#"<line x1="{ax:.1}" y1="{ay:.1}" x2="{bx:.1}" y2="{by:.1}" stroke="black" stroke-width="4"/>"#
        );
    }
    let (hx, hy) = page(assumed.x, assumed.z);
    let _ = writeln!(
        out,
        r#"<circle cx="{hx:.1}" cy="{hy:.1}" r="5" fill="white" stroke="black" stroke-width="1.5"/>"#
    );
    write_legend(&mut out, scale, left + pw + 30.0, top, ph, limits);
    out.push_str("</svg>\n");
    out
}

/// An SVG path of every cell edge between a cell of `map` within `limits` and one not.
fn outline_path(
    grid: &Grid,
    map: &MethodMap,
    limits: &Thresholds,
    page: &dyn Fn(f64, f64) -> (f64, f64),
    cell_px: f64,
) -> String {
    let within = |c: usize| map.cells[c].is_some_and(|f| f.within(limits));
    let mut outline = String::new();
    for cell in (0..map.cells.len()).filter(|c| within(*c)) {
        let (col, row) = (cell % grid.columns, cell / grid.columns);
        let v = grid.viewer(cell);
        let (ax, ay) = page(v.x - 0.5 * grid.step, v.z - 0.5 * grid.step);
        let (bx, by) = (ax + cell_px, ay + cell_px);
        let mut edge = |x1: f64, y1: f64, x2: f64, y2: f64| {
            let _ = write!(outline, "M{x1:.2},{y1:.2}L{x2:.2},{y2:.2}");
        };
        if col == 0 || !within(cell - 1) {
            edge(ax, ay, ax, by);
        }
        if col + 1 == grid.columns || !within(cell + 1) {
            edge(bx, ay, bx, by);
        }
        if row == 0 || !within(cell - grid.columns) {
            edge(ax, ay, bx, ay);
        }
        if row + 1 == grid.rows || !within(cell + grid.columns) {
            edge(ax, by, bx, by);
        }
    }
    outline
}

/// The colour bar with its ticks and the metric's threshold marked.
fn write_legend(
    out: &mut String,
    scale: &Scale,
    x: f64,
    top: f64,
    height: f64,
    limits: &Thresholds,
) {
    let steps = 64;
    for k in 0..steps {
        let t = 1.0 - (k as f64 + 0.5) / steps as f64;
        let y = top + k as f64 * height / steps as f64;
        let _ = writeln!(
            out,
            r#"<rect x="{x:.1}" y="{y:.2}" width="18" height="{:.2}" fill="{}"/>"#,
            height / steps as f64 + 0.5,
            colour(scale.metric, t)
        );
    }
    for v in scale.ticks() {
        let y = top + (1.0 - scale.position(v)) * height;
        let mut label = format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string();
        if scale.metric != Metric::Depth && (v - scale.hi).abs() < 1e-9 {
            label = format!("≥ {label}");
        } else if scale.metric != Metric::Depth && (v - scale.lo).abs() < 1e-9 {
            label = format!("≤ {label}");
        }
        let _ = writeln!(
            out,
            r#"<text x="{:.1}" y="{:.1}">{label}</text>"#,
            x + 24.0,
            y + 4.0
        );
    }
    if let Some(threshold) = scale.metric.threshold(limits) {
        let y = top + (1.0 - scale.position(threshold)) * height;
        let _ = writeln!(
            out,
            r#"<line x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="red" stroke-width="2"/>"#,
            x - 4.0,
            x + 22.0
        );
    }
    let unit = if scale.metric == Metric::Depth {
        "ratio"
    } else {
        "arcmin"
    };
    let _ = writeln!(
        out,
        r#"<text x="{x:.1}" y="{:.1}">{unit}</text>"#,
        top + height + 20.0
    );
    let _ = writeln!(
        out,
        r##"<text x="{x:.1}" y="{:.1}" fill="#888">grey: nothing seen</text>"##,
        top + height + 38.0
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_ceilings_round_up_to_one_two_two_and_a_half_or_five() {
        assert_eq!(nice_ceiling(17.0), 20.0);
        assert_eq!(nice_ceiling(20.0), 20.0);
        assert_eq!(nice_ceiling(0.3), 0.5);
        assert_eq!(nice_ceiling(51.0), 100.0);
    }

    #[test]
    fn colours_run_from_the_first_stop_to_the_last() {
        assert_eq!(colour(Metric::Vertical, 0.0), "#440154");
        assert_eq!(colour(Metric::Vertical, 1.0), "#fde725");
        assert_eq!(colour(Metric::Depth, 0.5), "#f7f7f7");
    }
}
