//! Headless renders on the real GPU path, checked against the CPU model: where points land, that
//! walls meet without a seam, and that stereo pairs differ only where they should.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod common;

use common::*;
use glam::{Vec2, Vec3};
use image::RgbaImage;
use omnicave::cave::{Eye, Head, RenderMode, eye_positions};
use omnicave::render::RenderSettings;
use omnicave::scene::Scene;
use omnicave::scene::build::grid;

/// Markers around the CAVE: behind each wall, near and far, and inside the CAVE (in front of
/// the screens, negative parallax).
const MARKERS: [Vec3; 7] = [
    Vec3::new(0.3, 1.4, -3.0),
    Vec3::new(-1.0, 2.2, -6.0),
    Vec3::new(-3.5, 1.5, 0.4),
    Vec3::new(3.0, 2.0, 0.5),
    Vec3::new(0.4, 1.1, -1.0),
    Vec3::new(-1.0, 1.6, 0.8),
    Vec3::new(20.0, 5.0, -30.0),
];

#[test]
fn markers_land_where_the_ray_from_the_eye_meets_the_wall() {
    let size = [960, 540];
    let cave = cave_at(size[0], size[1]);
    let heads = [
        ("centred", Head::at(Vec3::new(0.0, 1.7, 0.0))),
        ("off-centre", Head::at(Vec3::new(0.9, 1.2, -1.0))),
        // 0.3 m from the left wall.
        ("near left wall", Head::at(Vec3::new(-1.35, 1.5, 0.3))),
    ];
    let mut checked = 0;
    for (head_name, head) in heads {
        let scene = marker_scene_px(&MARKERS, head.position, &cave, 3.0);
        for (mode, yaw) in [
            (RenderMode::Mono, 0.0),
            (RenderMode::Stereo, 0.0),
            (RenderMode::TrackedStereo, 35.0),
        ] {
            let head = Head {
                orientation: Head::orientation_from_degrees(yaw, 0.0, 0.0),
                ..head
            };
            let images = render(&cave, head, mode, &scene, NO_MSAA);
            let eyes = eye_positions(mode, &head, 0.064, cave.stereo_view_direction);
            for (wall, wall_images) in cave.walls.iter().zip(&images) {
                for eye in Eye::BOTH {
                    let eye_pos = eyes[eye as usize];
                    let found = centroids(wall_images.eye(eye));
                    for (i, marker) in MARKERS.iter().enumerate() {
                        let colour = MARKER_COLOURS[i];
                        let Some(expected) = wall.pixel_of_ray(eye_pos, *marker) else {
                            continue;
                        };
                        let what = format!(
                            "{head_name} {mode} {} {}: marker {i} at {marker}",
                            wall.name,
                            eye.name()
                        );
                        if assert_marker_at(&found, colour, expected, size, &what).is_some() {
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    // 3 heads × 3 modes × both eyes, each marker on at least one wall: far more than 100.
    assert!(
        checked >= 100,
        "only {checked} marker positions were checked"
    );
}

/// A big unlit quad outside the CAVE whose straight, slanted top edge crosses the corner where
/// the left wall meets the front wall.
fn seam_scene() -> (Scene, Vec3, Vec3) {
    let a_top = Vec3::new(-4.0, 2.6, 1.0);
    let b_top = Vec3::new(-1.0, 1.8, -4.0);
    let quad = grid(
        Vec3::new(-4.0, 0.0, 1.0),
        Vec3::new(3.0, -0.8, -5.0),
        Vec3::new(0.0, 2.6, 0.0),
        1,
        1,
        1.0,
    );
    let mut scene = Scene::default();
    add_unlit(&mut scene, &quad, [255, 255, 255]);
    // Seen from inside: make it visible from both sides.
    scene.materials[0].double_sided = true;
    (scene, a_top, b_top)
}

/// Row of the quad's top edge in each column of `columns` (number of non-white rows above the
/// first white pixel; averages to the edge's true position over many columns).
fn edge_rows(img: &RgbaImage, columns: impl Iterator<Item = u32>) -> Vec<(f32, f32)> {
    columns
        .filter_map(|x| {
            (0..img.height())
                .find(|&y| img.get_pixel(x, y)[0] == 255)
                .map(|y| (x as f32 + 0.5, y as f32))
        })
        .collect()
}

#[test]
fn an_edge_crossing_from_left_to_front_wall_has_no_seam() {
    let size = [800, 450];
    let cave = cave_at(size[0], size[1]);
    let (left_i, front_i) = (
        cave.wall_index("left").unwrap(),
        cave.wall_index("front").unwrap(),
    );
    let (scene, a_top, b_top) = seam_scene();
    let corner = cave.walls[front_i].lower_left;
    let cases = [
        (
            "mono centred",
            RenderMode::Mono,
            Head::at(Vec3::new(0.0, 1.7, 0.0)),
        ),
        (
            "mono off-centre",
            RenderMode::Mono,
            Head::at(Vec3::new(0.7, 1.3, -0.8)),
        ),
        (
            "tracked-stereo yaw 30°",
            RenderMode::TrackedStereo,
            Head {
                position: Vec3::new(0.4, 1.6, 0.5),
                orientation: Head::orientation_from_degrees(30.0, 0.0, 0.0),
            },
        ),
        (
            "stereo",
            RenderMode::Stereo,
            Head::at(Vec3::new(-0.3, 1.5, 0.2)),
        ),
    ];
    for (name, mode, head) in cases {
        let images = render(&cave, head, mode, &scene, NO_MSAA);
        let eyes = eye_positions(mode, &head, 0.064, cave.stereo_view_direction);
        for eye in Eye::BOTH {
            let eye_pos = eyes[eye as usize];
            let left = edge_rows(images[left_i].eye(eye), size[0] - 60..size[0]);
            let front = edge_rows(images[front_i].eye(eye), 0..60);
            assert!(
                left.len() > 50 && front.len() > 50,
                "{name}: edge not visible near the seam"
            );
            let (al, bl) = fit_line(&left);
            let (af, _) = fit_line(&front);
            let at_seam_left = al + bl * size[0] as f32;
            let at_seam_front = af;
            // Where the 3D edge crosses the vertical plane through the eye and the corner.
            let d = xz(corner - eye_pos);
            let cross = |p: Vec3| {
                let q = xz(p - eye_pos);
                q.x * d.y - q.y * d.x
            };
            let t = cross(a_top) / (cross(a_top) - cross(b_top));
            let on_edge = a_top + t * (b_top - a_top);
            let expected = cave.walls[front_i].pixel_of_ray(eye_pos, on_edge).unwrap();
            let jump = (at_seam_left - at_seam_front).abs();
            // ≤ 1 px, the acceptance tolerance; the line fits over 60 columns are accurate to a
            // few hundredths of a pixel, so this measures the renderer, not the fit.
            assert!(jump <= 1.0, "{name} {}: seam jump {jump:.2} px", eye.name());
            assert!(
                expected.x.abs() < 0.01,
                "the CPU crossing should be on the corner"
            );
            assert!(
                (at_seam_front - expected.y).abs() <= 1.0,
                "{name}: off the CPU prediction"
            );
        }
    }
}

/// The horizontal (x, z) part of a CAVE-space vector.
fn xz(v: Vec3) -> Vec2 {
    Vec2::new(v.x, v.z)
}

#[test]
fn stereo_images_of_points_ahead_differ_only_horizontally() {
    let size = [960, 540];
    let cave = cave_at(size[0], size[1]);
    let front = cave.wall_index("front").unwrap();
    let head = Head::at(Vec3::new(0.0, 1.7, 0.0));
    // Straight ahead, and further points (far behind the screen, in front of it) moved just
    // enough that they do not hide each other, plus two off-axis points.
    let points = [
        Vec3::new(0.0, 1.7, -3.0),
        Vec3::new(0.0, 2.4, -12.0),
        Vec3::new(-0.2, 1.55, -1.0),
        Vec3::new(0.8, 1.0, -4.0),
        Vec3::new(-0.6, 2.3, -2.5),
    ];
    let scene = marker_scene(&points, head.position, 0.01);
    let images = render(&cave, head, RenderMode::Stereo, &scene, NO_MSAA);
    let eyes = eye_positions(RenderMode::Stereo, &head, 0.064, cave.stereo_view_direction);
    let (l, r) = (
        centroids(&images[front].left),
        centroids(&images[front].right),
    );
    for (i, p) in points.iter().enumerate() {
        let c = MARKER_COLOURS[i];
        let (pl, _) = l[&c];
        let (pr, _) = r[&c];
        let el = cave.walls[front].pixel_of_ray(eyes[0], *p).unwrap();
        let er = cave.walls[front].pixel_of_ray(eyes[1], *p).unwrap();
        let disparity = pr.x - pl.x;
        // The true vertical difference is exactly zero (eyes split parallel to the wall); the
        // rasterised discs differ only in which columns they cover, which moves their vertical
        // centroid by well under half a pixel.
        assert!((pr.y - pl.y).abs() <= 0.5, "vertical parallax for {p}");
        assert!(
            (disparity - (er.x - el.x)).abs() <= 1.0,
            "disparity for {p}"
        );
        // Behind the screen: uncrossed (right image further right); in front: crossed.
        if p.z < -1.65 {
            assert!(disparity > 0.5, "{p} should have uncrossed disparity");
        } else {
            assert!(disparity < -0.5, "{p} should have crossed disparity");
        }
    }
}

#[test]
fn mono_eyes_share_one_image_and_stereo_eyes_do_not() {
    let cave = cave_at(320, 180);
    let head = Head::at(Vec3::new(0.1, 1.6, 0.1));
    let scene = marker_scene(&MARKERS, head.position, 0.02);
    let mono = render(&cave, head, RenderMode::Mono, &scene, NO_MSAA);
    let stereo = render(&cave, head, RenderMode::Stereo, &scene, NO_MSAA);
    for (m, s) in mono.iter().zip(&stereo) {
        assert_eq!(m.left, m.right, "mono {}", m.wall);
        assert_ne!(s.left, s.right, "stereo {}", s.wall);
    }
}

#[test]
fn unlit_colour_is_exact_and_wireframe_draws_edges() {
    let cave = cave_at(320, 180);
    let head = Head::at(Vec3::new(0.0, 1.7, 0.0));
    let quad = grid(
        Vec3::new(-1.0, 0.5, -3.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
        3,
        3,
        1.0,
    );
    let mut scene = Scene::default();
    let m = scene.add_material(omnicave::scene::Material::unlit("half", [0.5, 0.25, 1.0]));
    scene.add_mesh(&quad.vertices, &quad.indices, m);
    let front = cave.wall_index("front").unwrap();

    let plain = render(&cave, head, RenderMode::Mono, &scene, NO_MSAA);
    let centre = plain[front].left.get_pixel(160, 90);
    // Linear 0.5 / 0.25 / 1.0 encoded as sRGB: 188, 137, 255 (±1 for the GPU's rounding).
    let expected = [188u8, 137, 255];
    for k in 0..3 {
        assert!(
            (i32::from(centre[k]) - i32::from(expected[k])).abs() <= 1,
            "unlit colour {centre:?}, expected {expected:?}"
        );
    }

    if !gpu().wireframe_supported {
        println!("adapter has no POLYGON_MODE_LINE; wireframe not checked");
        return;
    }
    let wire = render(
        &cave,
        head,
        RenderMode::Mono,
        &scene,
        RenderSettings {
            msaa: 1,
            wireframe: true,
        },
    );
    // Overlay colour: linear 0.9 → sRGB 243.
    let is_wire = |p: &image::Rgba<u8>| p[0] == p[1] && p[1] == p[2] && p[0] >= 240;
    let count = |img: &RgbaImage| img.pixels().filter(|p| is_wire(p)).count();
    let (before, after) = (count(&plain[front].left), count(&wire[front].left));
    assert_eq!(before, 0);
    // A 3×3 grid of quads drawn as lines: 8 lines across ~100 px plus diagonals.
    assert!(after > 500, "wireframe overlay drew only {after} pixels");
}
