//! Accuracy of a bench method, from the CPU twin: the geometric error of what the method draws
//! against the exact omnistereo image (every point seen from its own eye), and the triangles it
//! draws after culling and tessellation.

use glam::{Mat4, Vec2, Vec3};

use super::methods::Method;
use crate::cave::{Head, RenderMode, view_setups};
use crate::config::Config;
use crate::scene::Scene;
use crate::tess::error::{ErrorStats, border_crossings, edge_error_samples, source_positions};
use crate::tess::{
    TessOutput, TessView, double_sided_flags, point_position, project, shared_partner, tess_view,
    tessellate,
};

/// Output budget of the CPU twin per view (the GPU's default is 1 M; the CPU twin needs no
/// more than the largest setting the bench uses).
const CAPACITY: usize = 1 << 21;
/// Spacing of error samples along drawn edges, pixels.
const SAMPLE_SPACING_PX: f32 = 4.0;

/// What a method draws and how far it is from the omnistereo ideal.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Accuracy {
    pub error: ErrorStats,
    /// How far scene edges jump where they cross from one wall to the next (pixels along the
    /// shared edge, one sample per crossing edge, seam and eye); 0 for an exact image.
    pub seam: ErrorStats,
    /// Source triangles over all views, before culling.
    pub input: u64,
    /// Culled before drawing (back faces, warp-aware frustum) over all views.
    pub culled: u64,
    /// Triangles drawn over all views.
    pub emitted: u64,
    /// Length on screen of the drawn triangles' edges over all views, pixels, each edge once
    /// for every triangle that has it (triangles reaching behind the near plane left out):
    /// along every edge the rasteriser shades the pixels it crosses for the triangles on
    /// both sides, so on a software rasteriser, which shades whole blocks there, the scene
    /// pass grows with this length more than with the triangles' count.
    pub edge_px: f64,
}

/// The accuracy of `method` for `scene` seen from `head`, every wall and eye of the config.
///
/// The ideal is the omnistereo image: each point where the ray from its own eye meets the wall
/// (the off-axis warp's projection, which puts vertices exactly there). Off-axis stereo and
/// mono are measured against it too, so their error is the wrong parallax of directions away
/// from the assumed view direction; mono against both eyes.
pub fn accuracy(
    config: &Config,
    scene: &Scene,
    head: Vec3,
    world_from_cave: Mat4,
    method: &Method,
) -> Accuracy {
    accuracy_within(config, scene, head, world_from_cave, method, CAPACITY)
}

/// [`accuracy`] with the twin's output budget per view `capacity`, which binds only a method
/// that refines: one without a criterion draws every source triangle directly, on the GPU as
/// here, with no output budget (a cap would leave triangles out of its error and count).
fn accuracy_within(
    config: &Config,
    scene: &Scene,
    head: Vec3,
    world_from_cave: Mat4,
    method: &Method,
    capacity: usize,
) -> Accuracy {
    let cave = &config.cave;
    let head = Head::at(head);
    let ipd = config.settings.cave.eye_separation;
    let omni = config.settings.omni();
    let ideal_views = view_setups(cave, &head, RenderMode::OmniOffAxis, ipd);
    let flags = double_sided_flags(scene);
    // As the renderer: tessellated wherever a criterion is set, with or without the warp
    // (the triangle control is stereo through the tessellator).
    let settings = method.tess;
    let capacity = if settings.criterion.is_some() {
        capacity
    } else {
        usize::MAX
    };
    let mut samples = Vec::new();
    let mut result = Accuracy::default();
    let views = view_setups(cave, &head, method.mode, ipd);
    let mut outputs = Vec::with_capacity(views.len());
    for (index, view) in views.iter().enumerate() {
        let wall = &cave.walls[view.wall];
        let drawn = tess_view(view, wall, world_from_cave, Some(omni));
        // Both eyes of a wall share one refinement, as the renderer draws them.
        let drawn = match shared_partner(&views, index, &settings) {
            Some(other) => drawn.paired_with(other),
            None => drawn,
        };
        let out = tessellate(scene, &flags, &drawn, &settings, capacity);
        result.input += u64::from(out.stats.input);
        result.culled += u64::from(out.stats.culled_backface + out.stats.culled_frustum);
        // Drawn: what the tessellator emits and the clusters drawn directly.
        result.emitted += u64::from(out.stats.emitted) + out.fine.len() as u64;
        result.edge_px += drawn_edge_length(scene, &drawn, &out);
        for ideal in ideal_views
            .iter()
            .filter(|i| i.wall == view.wall && (view.eye.is_none() || i.eye == view.eye))
        {
            let ideal = tess_view(ideal, wall, world_from_cave, Some(omni));
            samples.extend(edge_error_samples(
                scene,
                &drawn,
                &out,
                &ideal,
                SAMPLE_SPACING_PX,
            ));
        }
        outputs.push((drawn, out));
    }
    result.error = ErrorStats::from_samples(samples);
    // Seams: each scene edge crossing a shared wall edge, where each wall draws it (same eye).
    let mut jumps = Vec::new();
    for seam in cave.seams() {
        let [a, b] = seam.walls;
        let (wa, wb) = (&cave.walls[a], &cave.walls[b]);
        let seam_px = (wa.pixel_of_wall_point(seam.to) - wa.pixel_of_wall_point(seam.from))
            .length()
            .max((wb.pixel_of_wall_point(seam.to) - wb.pixel_of_wall_point(seam.from)).length());
        for (va, (ta, oa)) in views.iter().zip(&outputs).filter(|(v, _)| v.wall == a) {
            let Some((tb, ob)) = views
                .iter()
                .zip(&outputs)
                .find(|(v, _)| v.wall == b && v.eye == va.eye)
                .map(|(_, o)| o)
            else {
                continue;
            };
            let on = |wall: &crate::cave::Wall, tv, out| {
                let ends = [seam.from, seam.to].map(|p| wall.pixel_of_wall_point(p));
                border_crossings(scene, tv, out, ends[0], ends[1])
            };
            let (on_a, on_b) = (on(wa, ta, oa), on(wb, tb, ob));
            // Each crossing on one wall against the nearest crossing of the same edge on the
            // other (a warped edge may cross the border more than once).
            for (key, us) in &on_a {
                let Some(others) = on_b.get(key) else {
                    continue;
                };
                for ua in us {
                    let nearest = others
                        .iter()
                        .map(|ub| (ua - ub).abs())
                        .fold(f32::INFINITY, f32::min);
                    if nearest.is_finite() {
                        jumps.push(nearest * seam_px);
                    }
                }
            }
        }
    }
    result.seam = ErrorStats::from_samples(jumps);
    result
}

/// Length of the segment `a`–`b` inside the rectangle 0..`w` × 0..`h` (Liang–Barsky).
fn length_inside(a: Vec2, b: Vec2, w: f32, h: f32) -> f32 {
    let d = b - a;
    let (mut enter, mut leave) = (0.0f32, 1.0f32);
    for (p, q) in [(-d.x, a.x), (d.x, w - a.x), (-d.y, a.y), (d.y, h - a.y)] {
        if p == 0.0 {
            if q < 0.0 {
                return 0.0;
            }
            continue;
        }
        let r = q / p;
        if p < 0.0 {
            enter = enter.max(r);
        } else {
            leave = leave.min(r);
        }
    }
    (leave - enter).max(0.0) * d.length()
}

/// Length on screen of the edges of every triangle drawn in view `tv` (see
/// [`Accuracy::edge_px`]).
fn drawn_edge_length(scene: &Scene, tv: &TessView<'_>, out: &TessOutput) -> f64 {
    let [w, h] = tv.wall.resolution.map(|v| v as f32);
    let mut total = 0.0f64;
    for tri in out.drawn() {
        let corners = source_positions(scene, tri.source);
        let drawn = tri.corners.map(|c| project(tv, point_position(corners, c)));
        if drawn.iter().any(|d| d.clip.w <= tv.near) {
            continue;
        }
        for k in 0..3 {
            let length = length_inside(drawn[k].pixel, drawn[(k + 1) % 3].pixel, w, h);
            if length.is_finite() {
                total += f64::from(length);
            }
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stereo and the plain warp draw the whole scene directly: the twin measures every
    /// triangle of theirs however small its budget (a scene past it once had its stereo count
    /// and errors measured on the first 2^21 triangles of a view only).
    #[test]
    fn a_method_without_a_criterion_is_measured_whole_past_the_twins_budget() {
        use crate::scene::build::grid;
        let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/cave.toml"));
        let config = Config::load(path).expect("the bundled config loads");
        let head = config.settings.head().position;
        // 800 triangles 1 m ahead of the head, facing it: most of them in the front wall's
        // views.
        let mesh = grid(
            head + Vec3::new(-0.5, -0.5, -1.0),
            Vec3::X,
            Vec3::Y,
            20,
            20,
            1.0,
        );
        let mut scene = Scene::default();
        let material = scene.add_material(crate::scene::Material::unlit("grid", [0.5; 3]));
        scene.add_mesh(&mesh.vertices, &mesh.indices, material);
        let world_from_cave = config.settings.world_from_cave();
        let all = super::super::methods::methods(true, config.settings.tess());
        for name in ["stereo", "omni-offaxis"] {
            let method = all
                .iter()
                .find(|m| m.name == name)
                .expect("the quick methods hold it");
            let whole = accuracy_within(&config, &scene, head, world_from_cave, method, usize::MAX);
            let small = accuracy_within(&config, &scene, head, world_from_cave, method, 16);
            // More than the budget in every view on average: the old cap would bind.
            let views = 2 * config.cave.walls.len() as u64;
            assert!(
                whole.emitted > 16 * views,
                "{name}: {} drawn",
                whole.emitted
            );
            assert_eq!(small, whole, "{name}");
        }
    }

    #[test]
    fn only_the_part_of_an_edge_inside_the_image_counts() {
        let (w, h) = (100.0, 50.0);
        let inside = length_inside(Vec2::new(10.0, 10.0), Vec2::new(40.0, 50.0), w, h);
        assert!((inside - 50.0).abs() < 1e-4, "{inside}");
        // Half in: from x = −50 to 50 along y = 25.
        let half = length_inside(Vec2::new(-50.0, 25.0), Vec2::new(50.0, 25.0), w, h);
        assert!((half - 50.0).abs() < 1e-4, "{half}");
        // Across the whole image, corner to corner beyond it.
        let across = length_inside(Vec2::new(-100.0, -50.0), Vec2::new(200.0, 100.0), w, h);
        assert!((across - 100.0f32.hypot(50.0)).abs() < 1e-3, "{across}");
        assert_eq!(
            length_inside(Vec2::new(-10.0, -10.0), Vec2::new(-1.0, 60.0), w, h),
            0.0
        );
        assert_eq!(
            length_inside(Vec2::new(120.0, 10.0), Vec2::new(150.0, 20.0), w, h),
            0.0
        );
    }
}
