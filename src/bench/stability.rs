//! The stability sweep (`omnicave bench --stability`): head positions over the whole CAVE
//! volume, down to 5 cm from walls and corners, and triangles in every direction (0.1° from the
//! poles, behind the viewer, across the wall seams, near and far), warped for every wall and
//! eye with the CPU twin; counted are the failures the thesis describes (chapter 5.1) and the
//! eye flips pole merging prevents. A second part renders a closed room with closed boxes at
//! the poles, behind the viewer and across the seams: holes (background seen inside the closed
//! room, counted on the GPU's images) and popping (how much the drawn error changes between
//! head positions 2 mm apart, CPU twin) for each render method.

use std::collections::HashMap;
use std::fmt::Write as _;

use glam::{Mat4, Vec2, Vec3};

use crate::cave::omni::{OmniSettings, PoleMerge, WarpVariant, omni_eye, wall_plane, warp};
use crate::cave::{Cave, Eye, Head, RenderMode, Wall, off_axis_projection, view_near, view_setups};
use crate::scene::build::cuboid;
use crate::scene::{Material, Scene};
use crate::tess::error::{drawn_edge_points, edge_point_position, exact_pixel};
use crate::tess::{
    Criterion, TessSettings, clip_to_pixel, double_sided_flags, shared_partner, tess_view,
    tessellate,
};

/// Failure counts of one warp configuration over the sweep.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Failures {
    pub heads: usize,
    pub vertices: usize,
    pub triangles: usize,
    /// Warped to NaN or infinity.
    pub non_finite: usize,
    /// Drawn on a wall through which their own eye cannot see them.
    pub ghost_vertices: usize,
    /// Drawn more than 1 px from where their own eye sees them.
    pub misplaced_vertices: usize,
    /// Drawn more than twice (+10 px) the size of the triangle's exact image.
    pub exploded_triangles: usize,
    /// Small triangles whose corners' eyes jumped by more than half the eye separation (eyes
    /// flipping across the pole).
    pub torn_triangles: usize,
}

impl Failures {
    /// Every count, in the order of the tables: heads, vertices, triangles, non-finite, ghost,
    /// misplaced, exploded, torn.
    pub fn counts(&self) -> [usize; 8] {
        [
            self.heads,
            self.vertices,
            self.triangles,
            self.non_finite,
            self.ghost_vertices,
            self.misplaced_vertices,
            self.exploded_triangles,
            self.torn_triangles,
        ]
    }

    pub fn total(&self) -> usize {
        self.non_finite
            + self.ghost_vertices
            + self.misplaced_vertices
            + self.exploded_triangles
            + self.torn_triangles
    }
}

fn project(m: Mat4, wall: &Wall, near: f32, p: Vec3) -> Option<Vec2> {
    let clip = m * p.extend(1.0);
    (clip.is_finite() && clip.w > near).then(|| clip_to_pixel(clip, wall.resolution))
}

fn diag(points: &[Vec2]) -> f32 {
    let lo = points
        .iter()
        .fold(Vec2::splat(f32::INFINITY), |a, p| a.min(*p));
    let hi = points
        .iter()
        .fold(Vec2::splat(f32::NEG_INFINITY), |a, p| a.max(*p));
    (hi - lo).length()
}

/// Triangles around `head`: small ones (flag `true`) in every direction including 0.1° from
/// the poles, behind the viewer and along the seams, near and far, plus large ones spanning
/// walls and the pole (whose corners rightly have different eyes).
pub fn sweep_triangles(head: Vec3) -> Vec<([Vec3; 3], bool)> {
    let mut tris = Vec::new();
    for az in (0..360).step_by(30) {
        for el in [-89.9f32, -80.0, -45.0, 0.0, 30.0, 70.0, 85.0, 89.9] {
            for dist in [0.4f32, 2.0, 12.0] {
                let (a, e) = ((az as f32 + 7.0).to_radians(), el.to_radians());
                let dir = Vec3::new(-a.sin() * e.cos(), e.sin(), -a.cos() * e.cos());
                let centre = head + dist * dir;
                let side = dir.cross(Vec3::Y).normalize_or(Vec3::X);
                let up = side.cross(dir).normalize();
                let s = 0.08 * dist;
                tris.push((
                    [centre - s * side, centre + s * side, centre + s * up],
                    true,
                ));
            }
        }
    }
    // Large triangles crossing the wall seams and the pole.
    for k in 0..8 {
        let a = (k as f32 * 45.0 + 10.0).to_radians();
        let b = a + 70f32.to_radians();
        let p = |ang: f32, d: f32, y: f32| head + Vec3::new(-ang.sin() * d, y, -ang.cos() * d);
        tris.push((
            [p(a, 4.0, -1.0), p(b, 4.0, -1.0), p(0.5 * (a + b), 4.0, 1.5)],
            false,
        ));
        tris.push((
            [
                p(a, 0.6, 1.0),
                p(b, 0.6, 1.0),
                p(a + std::f32::consts::PI, 0.6, 1.2),
            ],
            false,
        ));
    }
    tris
}

/// Head positions over the walls' bounding box: six across each horizontal axis (the outer
/// ones 5 cm from the walls) and four heights (the top one 5 cm under the walls' top edge);
/// positions behind a wall (a CAVE that is not a box) are left out.
pub fn sweep_heads(cave: &Cave) -> Vec<Vec3> {
    let (min, max) = Cave::bounding_box(&cave.walls);
    const EDGE: f32 = 0.05;
    let across = |lo: f32, hi: f32| {
        [0.0f32, 0.2, 0.4, 0.6, 0.8, 1.0].map(|t| (lo + EDGE) + t * (hi - lo - 2.0 * EDGE))
    };
    let top = (max.y - EDGE).max(min.y + 0.3);
    let heights = [min.y + 0.3, min.y + 1.2, min.y + 1.8, top];
    let mut heads = Vec::new();
    for x in across(min.x, max.x) {
        for z in across(min.z, max.z) {
            for y in heights {
                let h = Vec3::new(x, y, z);
                if cave.head_problem(h).is_none() {
                    heads.push(h);
                }
            }
        }
    }
    heads
}

/// Runs the sweep for one warp configuration, eyes `ipd` apart.
pub fn sweep(cave: &Cave, ipd: f32, settings: OmniSettings) -> Failures {
    let mut f = Failures::default();
    let c = cave.projection_centre;
    // Each wall's projection from the centre, with the near plane `view_setups` gives it.
    let projections: Vec<(Mat4, glam::Vec4, f32)> = cave
        .walls
        .iter()
        .map(|w| {
            let near = view_near(cave.near, w.signed_distance(c));
            (
                off_axis_projection(w, c, near, cave.far).clip_from_cave,
                wall_plane(w),
                near,
            )
        })
        .collect();
    let heads = sweep_heads(cave);
    f.heads = heads.len();
    for head in heads {
        for (tri, small) in sweep_triangles(head) {
            for (wall, (m, plane, near)) in cave.walls.iter().zip(&projections) {
                for eye in Eye::BOTH {
                    f.triangles += 1;
                    let eyes = tri.map(|v| omni_eye(head, v, ipd, eye, settings.pole_merge));
                    // Torn: two corners of one small triangle whose eyes jumped by more
                    // than half the ipd (eyes flipping across the pole).
                    let torn =
                        small && (0..3).any(|i| (eyes[i] - eyes[(i + 1) % 3]).length() > 0.5 * ipd);
                    let mut drawn = [None; 3];
                    let mut exact = [None; 3];
                    for i in 0..3 {
                        f.vertices += 1;
                        let warped = warp(settings.warp, tri[i], eyes[i], c, *plane);
                        if !warped.is_finite() {
                            f.non_finite += 1;
                            continue;
                        }
                        drawn[i] = project(*m, wall, *near, warped);
                        exact[i] = wall.pixel_of_ray(eyes[i], tri[i]);
                        match (drawn[i], exact[i]) {
                            (Some(_), None) => f.ghost_vertices += 1,
                            (Some(d), Some(e)) if (d - e).length() > 1.0 => {
                                f.misplaced_vertices += 1;
                            }
                            _ => {}
                        }
                    }
                    if torn && drawn.iter().any(Option::is_some) {
                        f.torn_triangles += 1;
                    }
                    // Exploded: drawn far larger than the exact image of the triangle
                    // (its edges sampled and seen each from its own eye) says.
                    if let [Some(a), Some(b), Some(cc)] = drawn {
                        let mut samples = Vec::with_capacity(24);
                        let mut complete = exact.iter().all(Option::is_some);
                        for i in 0..3 {
                            for s in 0..8 {
                                let p = tri[i].lerp(tri[(i + 1) % 3], s as f32 / 8.0);
                                let e = omni_eye(head, p, ipd, eye, settings.pole_merge);
                                match wall.pixel_of_ray(e, p) {
                                    Some(px) => samples.push(px),
                                    None => complete = false,
                                }
                            }
                        }
                        let drawn_size = diag(&[a, b, cc]);
                        let exact_size = if samples.is_empty() {
                            0.0
                        } else {
                            diag(&samples)
                        };
                        if (complete && drawn_size > 2.0 * exact_size + 10.0)
                            || (!complete && samples.is_empty() && drawn_size > 10.0)
                        {
                            f.exploded_triangles += 1;
                        }
                    }
                }
            }
        }
    }
    f
}

/// The configurations the sweep compares: the recommended one first, then the two the thesis
/// (and the ODS literature) say fail.
pub fn configurations() -> Vec<(&'static str, OmniSettings)> {
    let pole = Some(PoleMerge::default());
    vec![
        (
            "similar triangles, pole merge 60–75° (recommended)",
            OmniSettings {
                warp: WarpVariant::SimilarTriangles,
                pole_merge: pole,
            },
        ),
        (
            "intersection point, pole merge 60–75°",
            OmniSettings {
                warp: WarpVariant::IntersectionPoint,
                pole_merge: pole,
            },
        ),
        (
            "similar triangles, pole merge off",
            OmniSettings {
                warp: WarpVariant::SimilarTriangles,
                pole_merge: None,
            },
        ),
    ]
}

/// The sweep's results as a Markdown table.
pub fn markdown(results: &[(&str, Failures)]) -> String {
    let mut md = String::from(
        "| warp | heads | vertices | triangles | non-finite | ghost | misplaced | exploded | torn |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for (name, f) in results {
        let cells: Vec<String> = f.counts().iter().map(usize::to_string).collect();
        let _ = writeln!(md, "| {name} | {} |", cells.join(" | "));
    }
    md
}

/// A render method of the rendered part of the sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepMethod {
    pub name: &'static str,
    pub mode: RenderMode,
    pub omni: OmniSettings,
    pub tess: TessSettings,
}

/// The rendered methods: the recommended configuration first, then the ones the thesis says
/// fail (no tessellation, the intersection-point warp, pole merge off), the on-axis warp, and
/// off-axis stereo (no warp at all) as the baseline.
pub fn sweep_methods() -> Vec<SweepMethod> {
    let error = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
    let recommended = OmniSettings::default();
    vec![
        SweepMethod {
            name: "omni-offaxis + error:0.5, similar triangles, pole merge (recommended)",
            mode: RenderMode::OmniOffAxis,
            omni: recommended,
            tess: error,
        },
        SweepMethod {
            name: "omni-offaxis, no tessellation",
            mode: RenderMode::OmniOffAxis,
            omni: recommended,
            tess: TessSettings::default(),
        },
        SweepMethod {
            name: "omni-offaxis + error:0.5, intersection point",
            mode: RenderMode::OmniOffAxis,
            omni: OmniSettings {
                warp: WarpVariant::IntersectionPoint,
                ..recommended
            },
            tess: error,
        },
        SweepMethod {
            name: "omni-offaxis + error:0.5, pole merge off",
            mode: RenderMode::OmniOffAxis,
            omni: OmniSettings {
                pole_merge: None,
                ..recommended
            },
            tess: error,
        },
        SweepMethod {
            name: "omni-onaxis + error:0.5",
            mode: RenderMode::OmniOnAxis,
            omni: recommended,
            tess: error,
        },
        SweepMethod {
            name: "off-axis stereo (no warp)",
            mode: RenderMode::Stereo,
            omni: recommended,
            tess: TessSettings::default(),
        },
    ]
}

/// Clear colour of the rendered sweep (sRGB): no surface of [`sweep_scene`] has it, so every
/// pixel showing it is a hole.
pub const HOLE_COLOUR: [f32; 3] = [1.0, 0.0, 1.0];

/// Whether an 8-bit sRGB pixel shows [`HOLE_COLOUR`] (unlit surfaces are far from it).
pub fn is_hole(rgb: [u8; 3]) -> bool {
    rgb[0] > 230 && rgb[1] < 25 && rgb[2] > 230
}

/// The rendered sweep's scene, in CAVE space: a closed room around the CAVE (2 m beyond the
/// walls, 1 m under the floor and 1.5 m over the top), one quad per face, seen from inside, so
/// that every pixel of every wall must show it; and closed boxes where the methods fail: over
/// the CAVE's centre (the pole overhead), on the floor under it (the pole underfoot), behind
/// the viewer, and outside every seam (across it). Unlit and single-sided, so back-face
/// culling is exercised too.
pub fn sweep_scene(cave: &Cave) -> Scene {
    let (min, max) = Cave::bounding_box(&cave.walls);
    let centre = 0.5 * (min + max);
    let mut scene = Scene::default();
    // A box from `cuboid`, snapped to its exact bounds (watertight: a crack could otherwise
    // be the scene's own).
    let mut add = |at: Vec3, size: Vec3, inward: bool, rgb: [f32; 3], name: &str| {
        let mesh = cuboid(size, 1.0);
        let mesh = if inward { mesh.flipped() } else { mesh }
            .transformed(Mat4::from_translation(at))
            .snapped_to_box(at - 0.5 * size, at + 0.5 * size);
        let material = scene.add_material(Material {
            double_sided: false,
            ..Material::unlit(name, rgb)
        });
        scene.add_mesh(&mesh.vertices, &mesh.indices, material);
    };
    let room_size = (max - min) + Vec3::new(4.0, 2.5, 4.0);
    let room_centre = Vec3::new(centre.x, min.y - 1.0 + 0.5 * room_size.y, centre.z);
    add(room_centre, room_size, true, [0.55, 0.55, 0.6], "room");
    let mut boxes = vec![
        (Vec3::new(centre.x, max.y + 0.5, centre.z), Vec3::splat(0.6)),
        (
            Vec3::new(centre.x, min.y + 0.125, centre.z),
            Vec3::new(0.5, 0.25, 0.5),
        ),
        (Vec3::new(centre.x, centre.y, max.z + 1.0), Vec3::splat(1.0)),
    ];
    for seam in cave.seams() {
        let [a, b] = seam.walls;
        let outward = -(cave.walls[a].normal() + cave.walls[b].normal()).normalize_or_zero();
        boxes.push((
            0.5 * (seam.from + seam.to) + 0.8 * outward,
            Vec3::splat(0.8),
        ));
    }
    let colours = [
        [0.9, 0.6, 0.2],
        [0.2, 0.7, 0.3],
        [0.2, 0.4, 0.9],
        [0.9, 0.9, 0.2],
        [0.1, 0.8, 0.8],
    ];
    for (i, (at, size)) in boxes.into_iter().enumerate() {
        add(at, size, false, colours[i % colours.len()], "box");
    }
    scene
}

/// Drawn error and its change between neighbouring head positions (CPU twin).
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Edge points compared (drawn at all three head positions).
    pub samples: usize,
    /// Largest distance between where a point is drawn and where the recommended omnistereo
    /// ideal puts it, px.
    pub max_error_px: f32,
    /// The head position where that error was drawn.
    pub worst_head: Vec3,
    /// Largest jump of that error between neighbouring head positions (second difference),
    /// px.
    pub max_pop_px: f32,
    /// Points whose error jumped by more than [`POP_THRESHOLD_PX`].
    pub popping: usize,
}

impl Motion {
    /// The worse of two.
    pub fn merge(self, other: Motion) -> Motion {
        let worse = if other.max_error_px > self.max_error_px {
            other
        } else {
            self
        };
        Motion {
            samples: self.samples + other.samples,
            max_error_px: worse.max_error_px,
            worst_head: worse.worst_head,
            max_pop_px: self.max_pop_px.max(other.max_pop_px),
            popping: self.popping + other.popping,
        }
    }
}

/// A point pops when its error jumps by more than this as the head moves 2 mm (the second
/// difference over three positions, see [`motion`]). Chosen from what smooth motion gives:
/// off-axis stereo, which has no discontinuity at all, reaches 0.95 px near the walls from the
/// curvature of its (large) error alone, and the recommended method 0.64 px; a tessellation
/// level switching or an eye flipping across the pole shows as a jump of about its own size.
pub const POP_THRESHOLD_PX: f32 = 1.0;

/// Distance between the neighbouring head positions of the popping test (three positions in
/// a row).
pub const POP_STEP_M: f32 = 0.002;

/// Samples per scene edge for the popping test.
pub const POP_SAMPLES_PER_EDGE: u32 = 64;

/// Margin of the image left out of the drawn error (px); see `drawn_errors`.
const BORDER_PX: f32 = 1.0;

/// Output budget of the CPU twin per view.
const POP_CAPACITY: usize = 1 << 21;

/// Per view (wall, eye) and edge point: drawn minus ideal, px.
fn drawn_errors(
    cave: &Cave,
    scene: &Scene,
    flags: &[Option<bool>],
    ipd: f32,
    method: &SweepMethod,
    head: Vec3,
) -> HashMap<(usize, Option<Eye>, crate::tess::error::EdgePoint), Vec2> {
    let head = Head::at(head);
    let ideal_views = view_setups(cave, &head, RenderMode::OmniOffAxis, ipd);
    let mut errors = HashMap::new();
    let views = view_setups(cave, &head, method.mode, ipd);
    for (index, view) in views.iter().enumerate() {
        let wall = &cave.walls[view.wall];
        let tv = tess_view(view, wall, Mat4::IDENTITY, Some(method.omni));
        // Both eyes of a wall share one refinement, as the renderer draws them.
        let tv = match shared_partner(&views, index, &method.tess) {
            Some(other) => tv.paired_with(other),
            None => tv,
        };
        let out = tessellate(scene, flags, &tv, &method.tess, POP_CAPACITY);
        let Some(ideal) = ideal_views
            .iter()
            .find(|i| i.wall == view.wall && i.eye == view.eye)
        else {
            continue;
        };
        let ideal = tess_view(ideal, wall, Mat4::IDENTITY, Some(OmniSettings::default()));
        let size = Vec2::new(wall.resolution[0] as f32, wall.resolution[1] as f32);
        for (key, drawn) in drawn_edge_points(scene, &tv, &out, POP_SAMPLES_PER_EDGE) {
            let world = edge_point_position(scene, key, POP_SAMPLES_PER_EDGE);
            // Points the ideal puts within BORDER_PX of the image's edge are left to the seam
            // error: there the wall hands the point over to its neighbour, and seen at a
            // grazing angle (an eye 2 cm from the next wall) a point sliding along its own
            // edge past the border would count as tens of pixels off without anything
            // visible being wrong.
            if let Some(exact) = exact_pixel(&ideal, world)
                && exact.cmpge(Vec2::splat(BORDER_PX)).all()
                && exact.cmple(size - BORDER_PX).all()
            {
                errors.insert((view.wall, view.eye, key), drawn - exact);
            }
        }
    }
    errors
}

/// The drawn error of `method` at `head` − `step`, `head` and `head` + `step`, and how much it
/// jumped: points of every scene edge, every wall and eye, against the recommended omnistereo
/// ideal (each point seen from its own eye). A jump is the second difference of the error
/// over the three positions: a smoothly changing error (a wrong parallax that grows as the
/// head nears a wall) leaves it near zero, a sudden change in one of the two steps (a
/// tessellation level switching, eyes flipping across the pole) shows in full.
pub fn motion(
    cave: &Cave,
    scene: &Scene,
    ipd: f32,
    method: &SweepMethod,
    head: Vec3,
    step: Vec3,
) -> Motion {
    let flags = double_sided_flags(scene);
    let [before, at, after] =
        [head - step, head, head + step].map(|h| drawn_errors(cave, scene, &flags, ipd, method, h));
    let mut m = Motion {
        worst_head: head,
        ..Motion::default()
    };
    for (key, e0) in &at {
        m.max_error_px = m.max_error_px.max(e0.length());
        let (Some(e_before), Some(e_after)) = (before.get(key), after.get(key)) else {
            continue;
        };
        let jump = (*e_after - 2.0 * *e0 + *e_before).length();
        if !jump.is_finite() {
            continue;
        }
        m.samples += 1;
        m.max_pop_px = m.max_pop_px.max(jump);
        if jump > POP_THRESHOLD_PX {
            m.popping += 1;
        }
    }
    m
}

/// Results of one rendered method over the sweep.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct Rendered {
    pub motion: Motion,
    /// Frames (head positions) rendered, each all walls and eyes.
    pub frames: usize,
    /// Pixels over all frames, walls and eyes showing the background inside the closed room.
    pub hole_pixels: u64,
    /// Frames with at least one hole pixel.
    pub frames_with_holes: usize,
    /// The worst frame's share of hole pixels, %.
    pub worst_frame_pct: f64,
}

/// The rendered part's results as a Markdown table.
pub fn rendered_markdown(results: &[(SweepMethod, Rendered)], size: [u32; 2]) -> String {
    let mut md = format!(
        "| method | edge points | max error px | at head (m) | max pop px | points popping > {POP_THRESHOLD_PX} \
         px | frames | frames with holes | hole pixels | worst frame holes % |\n\
         |---|---:|---:|---|---:|---:|---:|---:|---:|---:|\n"
    );
    for (m, r) in results {
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {:.2}, {:.2}, {:.2} | {:.2} | {} | {} | {} | {} | {:.3} |",
            m.name,
            r.motion.samples,
            r.motion.max_error_px,
            r.motion.worst_head.x,
            r.motion.worst_head.y,
            r.motion.worst_head.z,
            r.motion.max_pop_px,
            r.motion.popping,
            r.frames,
            r.frames_with_holes,
            r.hole_pixels,
            r.worst_frame_pct
        );
    }
    let _ = writeln!(
        md,
        "\nHoles are counted on the GPU's images at {}×{} per wall without MSAA (a pixel is a \
         hole when its centre is not covered); errors and pops with the CPU twin at the \
         config's wall size.",
        size[0], size[1]
    );
    md
}
