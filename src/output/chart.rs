//! Charts written as SVG by hand (no plotting dependency), one series per family. The bench's
//! on log-log axes: speed against accuracy (frame time against 99th-percentile error, the
//! Pareto front marked) and scaling (frame time against the scene's triangles); on linear
//! axes, the guests sweep (sweet area against CAVE size, head distance and resolution).

use std::fmt::Write as _;

/// One point on a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartPoint {
    /// The series (e.g. render mode and criterion kind).
    pub family: String,
    /// The point's own label (e.g. the criterion's parameter), or empty.
    pub label: String,
    pub x: f64,
    pub y: f64,
}

/// What a chart's axes show and what it marks.
#[derive(Debug, Clone, PartialEq)]
pub struct Axes {
    pub x_label: String,
    pub y_label: String,
    /// Smallest y drawn, and its tick's label: points below sit on it (exact methods' 0 px).
    pub y_floor: Option<(f64, String)>,
    /// Ring the points nothing beats in both x and y, joined by a dashed staircase.
    pub pareto: bool,
    /// Logarithmic axes (the bench's charts); linear from zero otherwise.
    pub log: bool,
}

impl Axes {
    /// Speed against accuracy: frame time (x) against 99th-percentile error (y).
    pub fn speed_against_accuracy() -> Self {
        Self {
            x_label: "frame time of the whole stereo frame, ms (log)".into(),
            y_label: "99th-percentile geometric error, px (log)".into(),
            y_floor: Some((ERROR_FLOOR_PX, "≤ 0.001".into())),
            pareto: true,
            log: true,
        }
    }

    /// Scaling: the scene's triangles (x) against frame time (y).
    pub fn time_against_triangles() -> Self {
        Self {
            x_label: "triangles in the scene (log)".into(),
            y_label: "frame time of the whole stereo frame, ms (log)".into(),
            y_floor: None,
            pareto: false,
            log: true,
        }
    }

    /// Linear axes from zero (x from its smallest value) with these labels.
    pub fn linear(x_label: &str, y_label: &str) -> Self {
        Self {
            x_label: x_label.into(),
            y_label: y_label.into(),
            y_floor: None,
            pareto: false,
            log: false,
        }
    }
}

/// Smallest error drawn: exact methods (0 px) sit on this floor, labelled as such.
pub const ERROR_FLOOR_PX: f64 = 0.001;

/// Indices of the points no other point beats in both time and error (ties kept), in order
/// of increasing time.
pub fn pareto_front(points: &[ChartPoint]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].x.is_finite() && points[i].y.is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        points[a]
            .x
            .total_cmp(&points[b].x)
            .then(points[a].y.total_cmp(&points[b].y))
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in order {
        if points[i].y < best {
            best = points[i].y;
            front.push(i);
        }
    }
    front
}

const PALETTE: [&str; 10] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2",
    "#7f7f7f", "#bcbd22",
];

/// Log-scale axis: the decades and 2/5 steps covering `lo..hi`.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let mut ticks = Vec::new();
    let mut decade = 10f64.powf(lo.log10().floor());
    while decade <= hi * 1.0001 {
        for m in [1.0, 2.0, 5.0] {
            let t = decade * m;
            if t >= lo * 0.9999 && t <= hi * 1.0001 {
                ticks.push(t);
            }
        }
        decade *= 10.0;
    }
    ticks
}

fn tick_label(v: f64) -> String {
    if v >= 1e6 {
        format!("{}M", v / 1e6)
    } else if v >= 1e4 {
        format!("{}k", v / 1e3)
    } else if v >= 1.0 {
        format!("{v:.0}")
    } else {
        let digits = (-v.log10().floor()) as usize;
        format!("{v:.digits$}")
    }
}

/// Linear axis: 4 to 10 steps of 1, 2, 2.5 or 5 × 10ⁿ covering `lo..hi`.
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let step = linear_step(hi - lo);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

fn linear_step(span: f64) -> f64 {
    let rough = (span / 6.0).max(1e-12);
    let decade = 10f64.powf(rough.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|s| span / s <= 10.0)
        .unwrap_or(10.0 * decade)
}

/// Linear range: x from its smallest to its largest value, y from 0 to a tick above the
/// largest.
fn linear_range(values: impl Iterator<Item = f64>, from_zero: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if from_zero {
        lo = lo.min(0.0);
    }
    if hi - lo < 1e-12 {
        hi = lo + 1.0;
    }
    let step = linear_step(hi - lo);
    let hi = if from_zero {
        (hi / step).ceil() * step
    } else {
        hi
    };
    (lo, hi)
}

/// Padded log range of positive values.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.1, 10.0);
    }
    (
        10f64.powf(lo.log10().floor()),
        10f64.powf((hi * 1.05).log10().ceil()),
    )
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The chart's geometry: the page, the plot area and its log axes.
struct Plot {
    w: f64,
    h: f64,
    left: f64,
    top: f64,
    /// Plot area width and height.
    pw: f64,
    ph: f64,
    /// The x and y ranges drawn.
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    /// Smallest y drawn (0: none).
    floor: f64,
    log: bool,
}

impl Plot {
    /// The geometry for `points` on `axes`.
    fn new(points: &[ChartPoint], axes: &Axes) -> Self {
        let (w, h) = (960.0, 600.0);
        let (left, right, top, bottom) = (80.0, 290.0, 70.0, 70.0);
        let (pw, ph) = (w - left - right, h - top - bottom);
        let floor = axes.y_floor.as_ref().map_or(0.0, |(v, _)| *v);
        let ((x0, x1), (y0, y1)) = if axes.log {
            let (y0, y1) = log_range(points.iter().map(|p| p.y.max(floor)));
            (
                log_range(points.iter().map(|p| p.x)),
                (if floor > 0.0 { y0.min(floor) } else { y0 }, y1),
            )
        } else {
            (
                linear_range(points.iter().map(|p| p.x), false),
                linear_range(points.iter().map(|p| p.y), true),
            )
        };
        Self {
            w,
            h,
            left,
            top,
            pw,
            ph,
            x0,
            x1,
            y0,
            y1,
            floor,
            log: axes.log,
        }
    }

    /// The y a point is drawn at: its own, or the floor below it.
    fn shown(&self, p: &ChartPoint) -> f64 {
        p.y.max(self.floor)
    }

    /// Page x of a value on the x axis.
    fn sx(&self, v: f64) -> f64 {
        let (x0, x1) = (self.x0, self.x1);
        if !self.log {
            return self.left + (v - x0) / (x1 - x0) * self.pw;
        }
        self.left + (v.log10() - x0.log10()) / (x1.log10() - x0.log10()) * self.pw
    }

    /// Page y of a value on the y axis.
    fn sy(&self, v: f64) -> f64 {
        let (y0, y1) = (self.y0, self.y1);
        if !self.log {
            return self.top + self.ph - (v - y0) / (y1 - y0) * self.ph;
        }
        self.top + self.ph - (v.log10() - y0.log10()) / (y1.log10() - y0.log10()) * self.ph
    }

    /// The document's opening, the background and the title and subtitle.
    fn write_heading(&self, out: &mut String, title: &str, subtitle: &str) {
        let (w, h, left) = (self.w, self.h, self.left);
        let _ = writeln!(
            out,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="Ubuntu, DejaVu Sans, Arial, sans-serif" font-size="13">"#
        );
        let _ = writeln!(out, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
        let _ = writeln!(
            out,
            r#"<text x="{left}" y="28" font-size="18" font-weight="bold">{}</text>"#,
            escape(title)
        );
        let _ = writeln!(
            out,
            r##"<text x="{left}" y="50" fill="#444">{}</text>"##,
            escape(subtitle)
        );
    }

    /// The grid with its tick labels, the plot's frame and the axis labels.
    fn write_axes(&self, out: &mut String, axes: &Axes) {
        let (h, left, top, pw, ph) = (self.h, self.left, self.top, self.pw, self.ph);
        let ticks = |lo, hi| {
            if self.log {
                log_ticks(lo, hi)
            } else {
                linear_ticks(lo, hi)
            }
        };
        // Linear ticks: as many decimals as the step needs (0.0005 steps read 0.0005, 0.001).
        let step = linear_step(self.y1 - self.y0).min(linear_step(self.x1 - self.x0));
        let decimals = (-step.log10().floor()).max(0.0) as usize + 1;
        let label = |t: f64| {
            if self.log {
                tick_label(t)
            } else {
                let text = format!("{t:.decimals$}");
                if text.contains('.') {
                    text.trim_end_matches('0').trim_end_matches('.').to_string()
                } else {
                    text
                }
            }
        };
        for t in ticks(self.x0, self.x1) {
            let x = self.sx(t);
            let _ = writeln!(
                out,
                r##"<line x1="{x:.1}" y1="{top}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"##,
                top + ph,
                top + ph + 18.0,
                label(t)
            );
        }
        for t in ticks(self.y0, self.y1) {
            let y = self.sy(t);
            let label = match &axes.y_floor {
                Some((v, floor_label)) if (t - v).abs() < 1e-12 => floor_label.clone(),
                _ => label(t),
            };
            let _ = writeln!(
                out,
                r##"<line x1="{left}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end">{label}</text>"##,
                left + pw,
                left - 6.0,
                y + 4.0
            );
        }
        let _ = writeln!(
            out,
            r#"<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#
        );
        let _ = writeln!(
            out,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
            left + pw / 2.0,
            h - 22.0,
            escape(&axes.x_label)
        );
        let _ = writeln!(
            out,
            r#"<text transform="translate(22 {:.1}) rotate(-90)" text-anchor="middle">{}</text>"#,
            top + ph / 2.0,
            escape(&axes.y_label)
        );
    }

    /// The `k`th series: the points of `family` joined in the order given (coarse to fine),
    /// their labels and the series' legend entry.
    fn write_series(&self, out: &mut String, points: &[ChartPoint], k: usize, family: &str) {
        let colour = PALETTE[k % PALETTE.len()];
        let members: Vec<&ChartPoint> = points.iter().filter(|p| p.family == *family).collect();
        if members.len() > 1 {
            let path: Vec<String> = members
                .iter()
                .map(|p| format!("{:.1},{:.1}", self.sx(p.x), self.sy(self.shown(p))))
                .collect();
            let _ = writeln!(
                out,
                r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="1.5"/>"#,
                path.join(" ")
            );
        }
        for p in &members {
            let (x, y) = (self.sx(p.x), self.sy(self.shown(p)));
            let _ = writeln!(
                out,
                r#"<circle cx="{x:.1}" cy="{y:.1}" r="4.5" fill="{colour}"/>"#
            );
            if !p.label.is_empty() {
                let _ = writeln!(
                    out,
                    r#"<text x="{:.1}" y="{:.1}" font-size="10" fill="{colour}">{}</text>"#,
                    x + 6.0,
                    y - 5.0,
                    escape(&p.label)
                );
            }
        }
        let ly = self.top + 10.0 + 20.0 * k as f64;
        let lx = self.left + self.pw + 20.0;
        let _ = writeln!(
            out,
            r#"<circle cx="{lx:.1}" cy="{ly:.1}" r="4.5" fill="{colour}"/><text x="{:.1}" y="{:.1}">{}</text>"#,
            lx + 10.0,
            ly + 4.0,
            escape(family)
        );
    }

    /// The Pareto front: rings and a dashed staircase, and its legend entry below the
    /// `families` series'.
    fn write_pareto(&self, out: &mut String, points: &[ChartPoint], families: usize) {
        let front = pareto_front(points);
        let mut stairs = Vec::new();
        for (n, &i) in front.iter().enumerate() {
            let (x, y) = (self.sx(points[i].x), self.sy(self.shown(&points[i])));
            if n > 0 {
                let prev_y = self.sy(self.shown(&points[front[n - 1]]));
                stairs.push(format!("{x:.1},{prev_y:.1}"));
            }
            stairs.push(format!("{x:.1},{y:.1}"));
            let _ = writeln!(
                out,
                r#"<circle cx="{x:.1}" cy="{y:.1}" r="8" fill="none" stroke="black" stroke-width="1.5"/>"#
            );
        }
        if stairs.len() > 1 {
            let _ = writeln!(
                out,
                r#"<polyline points="{}" fill="none" stroke="black" stroke-dasharray="5,4"/>"#,
                stairs.join(" ")
            );
        }
        let ly = self.top + 10.0 + 20.0 * families as f64 + 10.0;
        let lx = self.left + self.pw + 20.0;
        let _ = writeln!(
            out,
            r#"<circle cx="{lx:.1}" cy="{ly:.1}" r="8" fill="none" stroke="black" stroke-width="1.5"/><text x="{:.1}" y="{:.1}">Pareto front (nothing faster</text><text x="{:.1}" y="{:.1}">is also more accurate)</text>"#,
            lx + 14.0,
            ly + 4.0,
            lx + 14.0,
            ly + 20.0
        );
    }
}

/// The chart as an SVG document.
pub fn svg(points: &[ChartPoint], axes: &Axes, title: &str, subtitle: &str) -> String {
    let plot = Plot::new(points, axes);
    let mut out = String::new();
    plot.write_heading(&mut out, title, subtitle);
    plot.write_axes(&mut out, axes);
    // Series: points of one family joined in the order given (coarse to fine).
    let mut families: Vec<&str> = Vec::new();
    for p in points {
        if !families.contains(&p.family.as_str()) {
            families.push(&p.family);
        }
    }
    for (k, family) in families.iter().enumerate() {
        plot.write_series(&mut out, points, k, family);
    }
    if axes.pareto {
        plot.write_pareto(&mut out, points, families.len());
    }
    out.push_str("</svg>\n");
    out
}

/// The chart rendered to PNG (the SVG through resvg, text in egui's bundled Ubuntu font).
pub fn png(svg: &str) -> Result<Vec<u8>, String> {
    let mut options = resvg::usvg::Options::default();
    options
        .fontdb_mut()
        .load_font_data(epaint_default_fonts::UBUNTU_LIGHT.to_vec());
    options.fontdb_mut().set_sans_serif_family("Ubuntu");
    let tree = resvg::usvg::Tree::from_str(svg, &options).map_err(|e| e.to_string())?;
    let size = tree.size().to_int_size();
    let mut pixmap = resvg::tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| format!("cannot make a {size:?} image"))?;
    resvg::render(
        &tree,
        resvg::tiny_skia::Transform::default(),
        &mut pixmap.as_mut(),
    );
    pixmap.encode_png().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(family: &str, x: f64, y: f64) -> ChartPoint {
        ChartPoint {
            family: family.into(),
            label: String::new(),
            x,
            y,
        }
    }

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let points = [
            p("a", 10.0, 5.0),
            p("b", 12.0, 6.0), // slower and worse than a
            p("c", 15.0, 0.5),
            p("d", 20.0, 0.5), // slower, not better than c
            p("e", 30.0, 0.0),
        ];
        assert_eq!(pareto_front(&points), vec![0, 2, 4]);
    }

    #[test]
    fn svg_has_axes_units_legend_and_every_point() {
        let points = [
            p("stereo", 10.0, 3.0),
            p("omni", 12.0, 0.0),
            p("omni", 20.0, 0.2),
        ];
        let s = svg(&points, &Axes::speed_against_accuracy(), "title", "sub");
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        assert!(s.contains("frame time of the whole stereo frame, ms (log)"));
        assert!(s.contains("geometric error, px (log)"));
        assert!(s.contains(">stereo</text>") && s.contains(">omni</text>"));
        // Three points and two legend dots (one per family); the front's rings are larger.
        assert!(s.matches("r=\"4.5\"").count() == 5, "{s}");
        assert!(
            s.contains(">≤ 0.001</text>"),
            "the floor's tick is labelled"
        );
        assert_eq!(
            log_ticks(1.0, 100.0),
            vec![1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]
        );
    }

    #[test]
    fn scaling_chart_has_its_axes_thousands_ticks_and_no_front() {
        let points = [
            p("stereo", 7_000.0, 60.0),
            p("stereo", 225_000.0, 400.0),
            p("exact", 7_000.0, 80.0),
            p("exact", 225_000.0, 480.0),
        ];
        let s = svg(&points, &Axes::time_against_triangles(), "t", "s");
        assert!(s.contains(">triangles in the scene (log)</text>"), "{s}");
        assert!(s.contains(">frame time of the whole stereo frame, ms (log)</text>"));
        assert!(
            s.contains(">10k</text>") && s.contains(">100k</text>"),
            "{s}"
        );
        // Four points, two legend dots, one line per series, no Pareto rings.
        assert_eq!(s.matches("r=\"4.5\"").count(), 6, "{s}");
        assert_eq!(s.matches("<polyline").count(), 2, "{s}");
        assert!(!s.contains("r=\"8\"") && !s.contains("Pareto"), "{s}");
    }
}
