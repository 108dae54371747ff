//! The tracked wand's ray on the walls: in every render mode (omnistereo and tessellated
//! omnistereo included) its tip lands within 1 px of where the CPU model puts it (the ray
//! from the eye that sees it, through the wall) and the beam runs along the projected ray.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{NO_MSAA, cave_at, gpu, inside, test_frame};
use glam::{Quat, Vec2, Vec3};
use image::RgbaImage;
use omnicave::cave::omni::{OmniSettings, PoleMerge, omni_eye};
use omnicave::cave::wand::WandRay;
use omnicave::cave::{Eye, Head, RenderMode, eye_positions};
use omnicave::render::Renderer;
use omnicave::scene::Scene;
use omnicave::tess::{Criterion, TessSettings};

const IPD: f32 = 0.064;

/// The tip's pixels (magenta) and the beam's (green), as the unlit colours come out.
fn is_tip(p: &image::Rgba<u8>) -> bool {
    p[0] > 200 && p[1] < 100 && p[2] > 180
}
fn is_beam(p: &image::Rgba<u8>) -> bool {
    p[1] > 200 && p[0] < 120 && p[2] < 160
}

fn centroid(img: &RgbaImage, pick: impl Fn(&image::Rgba<u8>) -> bool) -> Option<(Vec2, usize)> {
    let mut sum = Vec2::ZERO;
    let mut n = 0;
    for (x, y, p) in img.enumerate_pixels() {
        if pick(p) {
            sum += Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f32, n))
}

/// Distance from `p` to the segment `a`–`b`.
fn to_segment(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    (a + t * ab - p).length()
}

/// The convex hull of `points` (counter-clockwise, Andrew's monotone chain).
fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<Vec2> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Vec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Distance from `q` to a convex polygon (0 inside).
fn to_polygon(q: Vec2, hull: &[Vec2]) -> f32 {
    if hull.len() < 3 {
        return hull
            .windows(2)
            .map(|s| to_segment(q, s[0], s[1]))
            .fold(f32::MAX, f32::min);
    }
    let n = hull.len();
    let inside = (0..n).all(|i| (hull[(i + 1) % n] - hull[i]).perp_dot(q - hull[i]) >= 0.0);
    if inside {
        return 0.0;
    }
    (0..n)
        .map(|i| to_segment(q, hull[i], hull[(i + 1) % n]))
        .fold(f32::MAX, f32::min)
}

/// Where the CPU model sees point `p` from, for `eye` in `mode`.
fn eye_for(mode: RenderMode, head: &Head, p: Vec3, eye: Eye) -> Vec3 {
    if mode.is_omni() {
        omni_eye(head.position, p, IPD, eye, Some(PoleMerge::default()))
    } else {
        eye_positions(mode, head, IPD, Vec3::NEG_Z)[eye as usize]
    }
}

#[test]
fn the_wand_ray_lands_where_the_cpu_model_says_in_every_mode() {
    let size = [480, 270];
    let cave = cave_at(size[0], size[1]);
    // A head turned 20° left (for tracked stereo) and three wands: one pointing at each wall.
    let head = Head {
        position: Vec3::new(0.2, 1.6, 0.3),
        orientation: Quat::from_rotation_y(20f32.to_radians()),
    };
    let rays = [
        WandRay::from_pose(
            Vec3::new(0.3, 1.2, -0.2),
            Quat::from_rotation_y(15f32.to_radians()) * Quat::from_rotation_x(0.15),
            1.0,
        ),
        WandRay::from_pose(
            Vec3::new(0.0, 1.3, 0.0),
            Quat::from_rotation_y(80f32.to_radians()),
            1.1,
        ),
        WandRay::from_pose(
            Vec3::new(0.4, 1.1, 0.2),
            Quat::from_rotation_y(-75f32.to_radians()) * Quat::from_rotation_x(-0.1),
            0.9,
        ),
    ]
    .map(|r| r.expect("ray"));
    let modes = [
        (RenderMode::Mono, None),
        (RenderMode::Stereo, None),
        (RenderMode::TrackedStereo, None),
        (RenderMode::OmniOnAxis, None),
        (RenderMode::OmniOffAxis, None),
        (RenderMode::OmniOffAxis, Some(Criterion::Edge(8.0))),
    ];
    let (mut tips, mut beams) = (0, 0);
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(&Scene::default()).expect("empty scene");
    for (mode, criterion) in modes {
        for ray in &rays {
            let tess = TessSettings {
                criterion,
                ..TessSettings::default()
            };
            let mut frame = test_frame(&cave, head, mode, OmniSettings::default(), tess);
            frame.wand_ray = Some(*ray);
            renderer.render(&frame).expect("render");
            let images = renderer.read_images().expect("read back");
            for (wall, wall_images) in cave.walls.iter().zip(&images) {
                for eye in Eye::BOTH {
                    let img = wall_images.eye(eye);
                    let what = format!("{mode} {criterion:?} {} {}", wall.name, eye.name());
                    // The tip: a 6 cm cube, a marker.
                    let tip = ray.tip();
                    let expected = wall.pixel_of_ray(eye_for(mode, &head, tip, eye), tip);
                    if let Some(expected) = expected.filter(|e| inside(*e, size, 10.0)) {
                        let (got, n) = centroid(img, is_tip)
                            .unwrap_or_else(|| panic!("{what}: no tip, expected at {expected}"));
                        let err = (got - expected).length();
                        // 1 px: the acceptance tolerance. The cube is ~15 px across here; its
                        // image centroid is off its centre's image by far less than that.
                        assert!(
                            err <= 1.0,
                            "{what}: tip at {got}, expected {expected} ({n} px)"
                        );
                        tips += 1;
                    }
                    // The beam: every beam pixel lies within 1 px of the image of one of the
                    // beam's segments as the CPU model projects its corners (each vertex seen
                    // by its own eye in omnistereo, as the shader does): the convex hull of a
                    // segment's eight projected corners holds all of its triangles.
                    let mut corners = vec![Vec3::ZERO; omnicave::scene::wand_mesh::VERTICES];
                    omnicave::scene::wand_mesh::positions(ray, glam::Mat4::IDENTITY, &mut corners);
                    let hulls: Vec<Vec<Vec2>> = (0..omnicave::scene::wand_mesh::SEGMENTS)
                        .filter_map(|s| {
                            let pts: Option<Vec<Vec2>> = corners[4 * s..4 * s + 8]
                                .iter()
                                .map(|c| wall.pixel_of_ray(eye_for(mode, &head, *c, eye), *c))
                                .collect();
                            pts.map(|p| convex_hull(&p))
                        })
                        .collect();
                    let beam = omnicave::scene::wand_mesh::beam_length(ray);
                    let line: Vec<Vec2> = (0..=40)
                        .map(|i| ray.at(beam * i as f32 / 40.0))
                        .filter_map(|p| wall.pixel_of_ray(eye_for(mode, &head, p, eye), p))
                        .collect();
                    for (x, y, p) in img.enumerate_pixels() {
                        if !is_beam(p) {
                            continue;
                        }
                        let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                        let d = hulls
                            .iter()
                            .map(|h| to_polygon(q, h))
                            .fold(f32::MAX, f32::min);
                        // 1 px: a pixel whose centre is outside a triangle but within a pixel
                        // of it can be covered by the rasteriser's rounding of the vertices.
                        assert!(
                            d <= 1.0,
                            "{what}: a beam pixel at {q} is {d:.2} px off the beam"
                        );
                        beams += 1;
                    }
                    for p in line.iter().filter(|p| inside(**p, size, 12.0)) {
                        let near = (-2..=2).any(|dy: i32| {
                            (-2..=2).any(|dx: i32| {
                                let (x, y) = (p.x as i32 + dx, p.y as i32 + dy);
                                x >= 0
                                    && y >= 0
                                    && img
                                        .get_pixel_checked(x as u32, y as u32)
                                        .is_some_and(|c| is_beam(c) || is_tip(c))
                            })
                        });
                        assert!(near, "{what}: the ray's point {p} has no beam within 2 px");
                    }
                }
            }
        }
    }
    assert!(tips >= 30, "only {tips} tips checked");
    // The check of every beam pixel above is not vacuous: beams were drawn.
    assert!(beams > 0, "no beam pixel drawn");
}
