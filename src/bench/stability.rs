//! The stability sweep (`omnicave bench --stability`): head positions over the whole CAVE
//! volume, down to 5 cm from walls and corners, and triangles in every direction (0.1° from the
//! poles, behind the viewer, across the wall seams, near and far), warped for every wall and
//! eye with the CPU twin; counted are the failures the thesis describes (chapter 5.1) and the
//! eye flips pole merging prevents.

use std::fmt::Write as _;

use glam::{Mat4, Vec2, Vec3};

use crate::cave::omni::{OmniSettings, PoleMerge, WarpVariant, omni_eye, wall_plane, warp};
use crate::cave::{Cave, Eye, Wall, off_axis_projection};

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
    if !clip.is_finite() || clip.w <= near {
        return None;
    }
    Some(Vec2::new(
        (clip.x / clip.w * 0.5 + 0.5) * wall.resolution[0] as f32,
        (0.5 - clip.y / clip.w * 0.5) * wall.resolution[1] as f32,
    ))
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
    let projections: Vec<(Mat4, glam::Vec4)> = cave
        .walls
        .iter()
        .map(|w| {
            (
                off_axis_projection(w, c, cave.near, cave.far).clip_from_cave,
                wall_plane(w),
            )
        })
        .collect();
    let heads = sweep_heads(cave);
    f.heads = heads.len();
    for head in heads {
        for (tri, small) in sweep_triangles(head) {
            for (wall, (m, plane)) in cave.walls.iter().zip(&projections) {
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
                        drawn[i] = project(*m, wall, cave.near, warped);
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
