//! The panorama view on the GPU against its CPU twins: markers land where the CPU projection
//! puts them in every projection and route (and, in stereo, for each eye); triangles across
//! the rear meridian and over a pole are drawn in pieces inside their true footprint; the two
//! routes agree on the living room; a 360° equirectangular render matches the CPU ray caster.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use glam::{Mat4, Vec2, Vec3};
use image::RgbaImage;

use common::{MARKER_COLOURS, NO_MSAA, cave_at, centroids, gpu, marker_scene, test_frame};
use omnicave::cave::omni::{OmniSettings, omni_eye};
use omnicave::cave::{Cave, Eye, Head, RenderMode};
use omnicave::pano::raycast::{RayCaster, compare, flat_reference};
use omnicave::pano::{PanoRoute, PanoSettings, PanoStereo, Projection, direction};
use omnicave::render::Renderer;
use omnicave::scene::{Material, Scene, Vertex, load_gltf};
use omnicave::tess::{Criterion, TessSettings};

const HEAD: Vec3 = Vec3::new(0.2, 1.6, -0.3);
const IPD: f32 = 0.064;

fn cave() -> Cave {
    cave_at(64, 36)
}

fn settings(projection: Projection, route: PanoRoute, fov_deg: [f32; 2]) -> PanoSettings {
    common::pano_settings(projection, route, fov_deg)
}

/// Renders the panorama of `scene` and reads both eyes back.
fn render(scene: &Scene, pano: &PanoSettings, tess: TessSettings) -> [RgbaImage; 2] {
    render_with(scene, pano, tess, NO_MSAA)
}

fn render_with(
    scene: &Scene,
    pano: &PanoSettings,
    tess: TessSettings,
    settings: omnicave::render::RenderSettings,
) -> [RgbaImage; 2] {
    let cave = cave();
    let mut renderer = Renderer::new(gpu(), &cave, settings).expect("renderer");
    renderer.set_scene(scene).expect("scene upload");
    let mut frame = test_frame(
        &cave,
        Head::at(HEAD),
        RenderMode::Mono,
        OmniSettings::default(),
        tess,
    );
    frame.eye_separation = IPD;
    renderer.render_panorama(&frame, pano).expect("panorama");
    renderer.read_panorama().expect("read back")
}

/// Keeps an image for a person to look at: target/test-out/panorama/<name>.png.
fn keep(name: &str, image: &RgbaImage) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-out/panorama");
    std::fs::create_dir_all(&dir).expect("test output folder");
    image
        .save(dir.join(format!("{name}.png")))
        .expect("write test image");
}

/// A CAVE-space point at a view-space longitude, latitude (degrees) and distance.
fn point_at(pano: &PanoSettings, lon_deg: f32, lat_deg: f32, distance: f32) -> Vec3 {
    let cave_from_view = pano.view_from_cave(HEAD).inverse();
    cave_from_view
        .transform_point3(direction(lon_deg.to_radians(), lat_deg.to_radians()) * distance)
}

/// Pixel (centres at +0.5) of a view-space direction, by the CPU projection.
fn cpu_pixel(pano: &PanoSettings, dir: Vec3) -> Option<Vec2> {
    let ndc = pano.fitted().project(dir)?;
    let [w, h] = pano.size.map(|v| v as f32);
    Some(Vec2::new((ndc.x + 1.0) * 0.5 * w, (1.0 - ndc.y) * 0.5 * h))
}

/// Marker directions (longitude, latitude in degrees) spread over the sphere: ahead, to
/// both sides, high and low, and near the rear meridian (not across it).
const MARKERS: [(f32, f32); 7] = [
    (0.0, 0.0),
    (35.0, 20.0),
    (-70.0, -30.0),
    (110.0, 45.0),
    (-150.0, 10.0),
    (170.0, -50.0),
    (-20.0, 60.0),
];

/// Every marker of `pano` within 1 px of the CPU projection (those in view and at least
/// 8 px inside the image, where a cut-off marker's centroid would be biased). Returns how
/// many markers were checked.
fn check_markers(pano: &PanoSettings, tess: TessSettings, what: &str) -> usize {
    let points: Vec<Vec3> = MARKERS
        .iter()
        .map(|&(lon, lat)| point_at(pano, lon, lat, 3.0))
        .collect();
    // 0.02 m per metre: about 1.15° of radius, 2.3 px at 720 px per 360°.
    let scene = marker_scene(&points, HEAD, 0.02);
    let [image, _] = render(&scene, pano, tess);
    let found = centroids(&image);
    let mut checked = 0;
    for (i, &(lon, lat)) in MARKERS.iter().enumerate() {
        let dir = direction(lon.to_radians(), lat.to_radians());
        let Some(expected) = cpu_pixel(pano, dir) else {
            continue;
        };
        if !common::inside(expected, pano.size, 8.0) {
            continue;
        }
        let colour = MARKER_COLOURS[i % MARKER_COLOURS.len()];
        let (got, _) = *found
            .get(&colour)
            .unwrap_or_else(|| panic!("{what}: marker {i} expected at {expected}, not drawn"));
        let err = (got - expected).length();
        // 1 px: the acceptance tolerance. A 2.3 px marker's centroid differs from its
        // centre's image by the projection's change of scale across it, < 0.2 px where the
        // markers are (|latitude| ≤ 60°).
        assert!(
            err <= 1.0,
            "{what}: marker {i} ({lon}°, {lat}°) drawn at {got}, expected {expected} ({err:.2} px)"
        );
        checked += 1;
    }
    checked
}

#[test]
fn markers_land_where_the_cpu_projection_puts_them_in_every_projection_and_route() {
    let cases = [
        (
            Projection::Equirectangular,
            PanoRoute::Geometric,
            [360.0, 180.0],
        ),
        (Projection::Hammer, PanoRoute::Geometric, [360.0, 180.0]),
        (
            Projection::Equirectangular,
            PanoRoute::Image,
            [360.0, 180.0],
        ),
        (Projection::Hammer, PanoRoute::Image, [360.0, 180.0]),
        (Projection::Perspective, PanoRoute::Image, [150.0, 120.0]),
        (Projection::AlbersConic, PanoRoute::Image, [360.0, 170.0]),
        (
            Projection::AzimuthalEquidistant,
            PanoRoute::Image,
            [360.0, 360.0],
        ),
        // A narrower field of view: the map window, not only the projection, must match.
        (
            Projection::Equirectangular,
            PanoRoute::Geometric,
            [200.0, 100.0],
        ),
    ];
    let tess = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
    for (projection, route, fov) in cases {
        let pano = settings(projection, route, fov);
        let what = format!(
            "{} {} {}×{}°",
            projection.name(),
            route.name(),
            fov[0],
            fov[1]
        );
        let checked = check_markers(&pano, tess, &what);
        // All seven around the full sphere; the narrower views see at least the two ahead.
        let needed = if fov[0] >= 360.0 { MARKERS.len() } else { 2 };
        assert!(checked >= needed, "{what}: only {checked} markers checked");
    }
}

/// One double-sided unlit triangle.
fn triangle_scene(triangles: &[([Vec3; 3], [u8; 3])]) -> Scene {
    let mut scene = Scene::default();
    for (corners, rgb) in triangles {
        let mut material = Material::unlit("triangle", rgb.map(|v| f32::from(v) / 255.0));
        material.double_sided = true;
        let m = scene.add_material(material);
        let n = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        let vertices: Vec<Vertex> = corners
            .iter()
            .map(|p| Vertex {
                position: p.to_array(),
                normal: n.to_array(),
                uv: [0.0, 0.0],
                ..Default::default()
            })
            .collect();
        scene.add_mesh(&vertices, &[0, 1, 2], m);
    }
    scene
}

/// Per pixel, whether the CPU ray through its centre meets triangle `t` of `scene` first.
fn cpu_footprint(scene: &Scene, pano: &PanoSettings, t: usize) -> Vec<bool> {
    RayCaster::new(scene, Mat4::IDENTITY)
        .panorama(pano, HEAD, 0.01, 1000.0)
        .into_iter()
        .map(|h| h.is_some_and(|h| h.triangle == t))
        .collect()
}

/// Whether pixel `i` of a `w`-wide mask has a neighbour (8-connected) with the other value.
fn at_boundary(mask: &[bool], w: usize, i: usize) -> bool {
    let (x, y) = ((i % w) as i64, (i / w) as i64);
    let h = (mask.len() / w) as i64;
    (-1..=1).any(|dy| {
        (-1..=1).any(|dx| {
            let (nx, ny) = (x + dx, y + dy);
            (0..w as i64).contains(&nx)
                && (0..h).contains(&ny)
                && mask[(ny as usize) * w + nx as usize] != mask[i]
        })
    })
}

/// A triangle behind the viewer, across the rear meridian (longitudes 150°, −140°, 175°).
fn rear_triangle() -> [Vec3; 3] {
    let pano = settings(
        Projection::Equirectangular,
        PanoRoute::Geometric,
        [360.0, 180.0],
    );
    [
        point_at(&pano, 150.0, -20.0, 3.0),
        point_at(&pano, -140.0, -10.0, 3.0),
        point_at(&pano, 175.0, 35.0, 3.0),
    ]
}

#[test]
fn triangles_across_the_rear_meridian_and_over_a_pole_are_drawn_in_pieces_in_their_footprint() {
    // Behind the viewer, across the rear meridian; overhead, around the north pole; below,
    // around the south pole. Untessellated, so the pre-clip alone must handle them.
    let behind = rear_triangle();
    let overhead = [
        HEAD + Vec3::new(-1.0, 0.9, -0.8),
        HEAD + Vec3::new(1.2, 0.9, -0.5),
        HEAD + Vec3::new(0.1, 0.9, 1.3),
    ];
    let below = [
        HEAD + Vec3::new(0.6, -1.2, 0.7),
        HEAD + Vec3::new(-0.9, -1.2, 0.4),
        HEAD + Vec3::new(0.2, -1.2, -1.0),
    ];
    let colours = [[255, 0, 0], [0, 255, 0], [0, 0, 255]];
    let scene = triangle_scene(&[
        (behind, colours[0]),
        (overhead, colours[1]),
        (below, colours[2]),
    ]);
    for projection in [Projection::Equirectangular, Projection::Hammer] {
        let pano = settings(projection, PanoRoute::Geometric, [360.0, 180.0]);
        let [image, _] = render(&scene, &pano, TessSettings::default());
        keep(&format!("preclip-{}", projection.name()), &image);
        let w = pano.size[0] as usize;
        for (t, rgb) in colours.iter().enumerate() {
            let truth = cpu_footprint(&scene, &pano, t);
            let drawn: Vec<bool> = image.pixels().map(|p| [p[0], p[1], p[2]] == *rgb).collect();
            let area = truth.iter().filter(|&&b| b).count();
            assert!(
                area > 1000,
                "{}: triangle {t} has {area} px",
                projection.name()
            );
            let mut outside = 0;
            let mut missing = 0;
            for i in 0..truth.len() {
                if drawn[i] == truth[i] {
                    continue;
                }
                // The GPU and the CPU decide pixels on the triangle's outline alike up to
                // rounding: a difference is allowed only next to the outline.
                assert!(
                    at_boundary(&truth, w, i),
                    "{}: triangle {t} pixel ({}, {}) is {} but the CPU ray {}",
                    projection.name(),
                    i % w,
                    i / w,
                    if drawn[i] { "lit" } else { "empty" },
                    if truth[i] { "meets it" } else { "misses it" },
                );
                if drawn[i] {
                    outside += 1;
                } else {
                    missing += 1;
                }
            }
            // Pieces: the rear triangle reaches both side edges of the image (in Hammer,
            // the outline's left and right ends); the polar ones span every column.
            let columns: Vec<usize> = (0..truth.len())
                .filter(|&i| drawn[i])
                .map(|i| i % w)
                .collect();
            let (min_x, max_x) = (
                *columns.iter().min().expect("drawn"),
                *columns.iter().max().expect("drawn"),
            );
            let spread: std::collections::BTreeSet<usize> = columns.iter().copied().collect();
            let name = projection.name();
            if t == 0 {
                // Two pieces, at the left and right ends of the image; the middle stays
                // empty.
                assert!(
                    min_x <= 2 && max_x >= w - 3,
                    "{name}: rear triangle not at both edges"
                );
                assert!(
                    !spread.contains(&(w / 2)),
                    "{name}: rear triangle smeared over the centre"
                );
            } else if projection == Projection::Equirectangular {
                // The pole is the whole top (bottom) row: the polar triangles span every
                // column.
                assert!(
                    spread.len() >= w - 2,
                    "{name}: polar triangle {t} misses columns"
                );
            } else {
                // Hammer: the pole is a point at the top (bottom) centre; the cap around it
                // reaches far to both sides.
                assert!(
                    min_x * 10 < w * 3 && max_x * 10 > w * 7,
                    "{name}: polar triangle {t} too narrow"
                );
            }
            // Rounding on the outline only: well under 1 % of the area either way.
            assert!(
                outside + missing <= area / 100 + 8,
                "{}: triangle {t}: {outside} + {missing} px differ",
                projection.name()
            );
        }
    }
}

#[test]
fn msaa_antialiases_the_geometric_route_along_the_exact_outline_only() {
    // A red triangle across the rear meridian on black, at 4× MSAA.
    let pano = settings(
        Projection::Equirectangular,
        PanoRoute::Geometric,
        [360.0, 180.0],
    );
    let scene = triangle_scene(&[(rear_triangle(), [255, 0, 0])]);
    let msaa = omnicave::render::RenderSettings {
        msaa: 4,
        wireframe: false,
    };
    let [image, _] = render_with(&scene, &pano, TessSettings::default(), msaa);
    keep("msaa-rear-triangle", &image);
    let truth = cpu_footprint(&scene, &pano, 0);
    let w = pano.size[0] as usize;
    let mut partial = 0;
    for (i, p) in image.pixels().enumerate() {
        let red = p[0];
        // Nothing but red on black.
        assert!(p[1] == 0 && p[2] == 0, "pixel {i}: {p:?}");
        if red == 0 || red == 255 {
            // Whole pixels agree with the CPU footprint, or lie on its outline.
            assert!(
                (red == 255) == truth[i] || at_boundary(&truth, w, i),
                "pixel ({}, {}) is {red} against the CPU footprint {}",
                i % w,
                i / w,
                truth[i]
            );
        } else {
            // Blended pixels only on the outline.
            assert!(
                at_boundary(&truth, w, i),
                "pixel ({}, {}) blended inside",
                i % w,
                i / w
            );
            partial += 1;
        }
    }
    // The outline is ~500 px long: most of its pixels are partly covered.
    assert!(
        partial > 200,
        "only {partial} blended pixels: not antialiased"
    );
}

/// Largest channel difference between two pixels.
fn channel_diff(a: [u8; 3], b: [u8; 3]) -> u8 {
    (0..3).map(|k| a[k].abs_diff(b[k])).max().unwrap_or(0)
}

#[test]
fn a_360_equirectangular_render_matches_the_cpu_ray_caster() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/living-room.glb");
    let mut pano = settings(
        Projection::Equirectangular,
        PanoRoute::Geometric,
        [360.0, 180.0],
    );
    pano.size = [512, 256];
    let cave = cave();
    let (scene, reference) = flat_reference(
        &load_gltf(&path).expect("living room"),
        Mat4::IDENTITY,
        &pano,
        HEAD,
        cave.near,
        cave.far,
    );
    let tess = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
    for route in [PanoRoute::Geometric, PanoRoute::Image] {
        pano.route = route;
        let [image, _] = render(&scene, &pano, tess);
        keep(&format!("raycaster-check-{}", route.name()), &image);
        let pixels: Vec<[u8; 3]> = image.pixels().map(|p| [p[0], p[1], p[2]]).collect();
        let c = compare(&pixels, &reference, pano.size[0] as usize, [0, 0, 0]);
        // Away from edges the two must show the same surface. 0.01 % (13 pixels here): the
        // geometric route decides coverage by the same ray as the reference, so only a ray
        // that passes exactly between two triangles (rounding on a shared edge) can differ.
        assert!(
            c.away_from_edges * 10_000 <= c.pixels,
            "{}: {} pixels away from edges differ",
            route.name(),
            c.away_from_edges
        );
        // At edges: the geometric route samples the same pixel centres (a handful differ by
        // rounding); the image route's bilinear lookup blurs about one pixel per edge pixel.
        let edge_budget = match route {
            PanoRoute::Geometric => c.pixels / 1000,
            PanoRoute::Image => c.pixels / 50,
        };
        assert!(
            c.differ <= edge_budget,
            "{}: {} pixels differ",
            route.name(),
            c.differ
        );
    }
}

#[test]
fn the_geometric_and_image_routes_agree_on_the_living_room_except_for_sampling_blur() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/living-room.glb");
    let scene = load_gltf(&path).expect("living room");
    let tess = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
    let mut pano = settings(
        Projection::Equirectangular,
        PanoRoute::Geometric,
        [360.0, 180.0],
    );
    pano.size = [720, 360];
    let [geometric, _] = render(&scene, &pano, tess);
    pano.route = PanoRoute::Image;
    // Faces of 512 px: 90° each, 5.7 px per degree against the panorama's 2 px per degree,
    // so the cube map is sampled finer than the panorama needs.
    let [image, _] = render(&scene, &pano, tess);
    let total = geometric.pixels().len();
    let mut sum = 0u64;
    let mut large = 0;
    for (a, b) in geometric.pixels().zip(image.pixels()) {
        let d = channel_diff([a[0], a[1], a[2]], [b[0], b[1], b[2]]);
        sum += u64::from(d);
        if d > 48 {
            large += 1;
        }
    }
    let mean = sum as f64 / total as f64;
    // Sampling blur: the image route filters the cube faces bilinearly and the geometric
    // route samples textures with mipmaps at the panorama's own density, so textures and
    // edges differ slightly everywhere (a mean of a few levels) and strongly only along
    // edges (a few per cent of the pixels). A misplaced wall or a missing object would move
    // thousands of pixels by far more than 48 levels.
    assert!(mean < 6.0, "mean difference {mean:.2}");
    assert!(
        large * 100 < total * 3,
        "{large} pixels differ by more than 48 levels"
    );
}

/// The CPU eye model of the omnistereo panorama: the direction from `eye`'s own eye.
fn ods_direction(pano: &PanoSettings, p: Vec3, eye: Eye) -> Vec3 {
    let e = omni_eye(HEAD, p, IPD, eye, OmniSettings::default().pole_merge);
    pano.view_from_cave(HEAD)
        .transform_vector3(p - e)
        .normalize()
}

#[test]
fn omnistereo_and_volume_stereo_put_each_eye_where_their_models_say() {
    let mut pano = settings(
        Projection::Equirectangular,
        PanoRoute::Geometric,
        [360.0, 180.0],
    );
    pano.size = [1440, 720];
    // Near markers (1 m) for a disparity of several pixels.
    let points: Vec<Vec3> = MARKERS
        .iter()
        .take(6)
        .map(|&(lon, lat)| point_at(&pano, lon, lat, 1.0))
        .collect();
    let scene = marker_scene(&points, HEAD, 0.012);
    let tess = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
    for stereo in [PanoStereo::Omni, PanoStereo::VOLUME_DEFAULT] {
        pano.stereo = stereo;
        let images = render(&scene, &pano, tess);
        let mut disparity = Vec::new();
        for (e, eye) in Eye::BOTH.into_iter().enumerate() {
            let found = centroids(&images[e]);
            for (i, p) in points.iter().enumerate() {
                let expected = match stereo {
                    PanoStereo::Omni => cpu_pixel(&pano, ods_direction(&pano, *p, eye)),
                    _ => {
                        // VR'14: mono position plus the parallax of the depth in the unit cube.
                        let PanoStereo::Volume { ioid, d, offset } = stereo else {
                            unreachable!()
                        };
                        let mono = cpu_pixel(
                            &pano,
                            pano.view_from_cave(HEAD).transform_vector3(*p - HEAD),
                        );
                        let cave = cave();
                        let depth = ((*p - HEAD).length() - cave.near) / (cave.far - cave.near);
                        let z = 2.0 * depth - 1.0;
                        let shift = eye.sign() * 0.5 * ioid * (1.0 - (offset + d) / (z + d));
                        mono.map(|m| m + Vec2::new(shift * 0.5 * pano.size[0] as f32, 0.0))
                    }
                };
                let Some(expected) = expected.filter(|x| common::inside(*x, pano.size, 10.0))
                else {
                    continue;
                };
                let colour = MARKER_COLOURS[i % MARKER_COLOURS.len()];
                let (got, _) = found[&colour];
                let err = (got - expected).length();
                assert!(
                    err <= 1.0,
                    "{} {}: marker {i} at {got}, expected {expected} ({err:.2} px)",
                    stereo.name(),
                    eye.name()
                );
                disparity.push((i, eye, got));
            }
        }
        // The two eyes differ horizontally only.
        for (i, _, left) in disparity.iter().filter(|d| d.1 == Eye::Left) {
            if let Some((_, _, right)) = disparity.iter().find(|d| d.0 == *i && d.1 == Eye::Right) {
                assert!(
                    (left.y - right.y).abs() <= 1.0,
                    "{}: marker {i} rows differ",
                    stereo.name()
                );
            }
        }
    }
}

#[test]
fn a_panorama_needs_no_new_pipelines_and_bad_sizes_are_refused() {
    let cave = cave();
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    let built = renderer.pipelines_built();
    let scene = marker_scene(&[HEAD + Vec3::new(0.0, 0.0, -2.0)], HEAD, 0.02);
    renderer.set_scene(&scene).expect("scene upload");
    let frame = test_frame(
        &cave,
        Head::at(HEAD),
        RenderMode::Mono,
        OmniSettings::default(),
        TessSettings::default(),
    );
    for route in PanoRoute::ALL {
        for projection in Projection::ALL {
            let mut pano = settings(projection, route, [120.0, 90.0]);
            pano.size = [64, 32];
            renderer.render_panorama(&frame, &pano).expect("panorama");
        }
    }
    assert_eq!(
        renderer.pipelines_built(),
        built,
        "switching built pipelines"
    );
    let mut pano = settings(Projection::Hammer, PanoRoute::Geometric, [360.0, 180.0]);
    pano.size = [0, 10];
    let err = renderer
        .render_panorama(&frame, &pano)
        .expect_err("empty image");
    assert!(err.to_string().contains("0×10"), "{err}");
    // The renderer keeps working after the refusal.
    pano.size = [64, 32];
    renderer
        .render_panorama(&frame, &pano)
        .expect("panorama after a refusal");
}

#[test]
fn the_render_command_writes_a_stereo_panorama_in_its_formats() {
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-out/pano-cli");
    let _ = std::fs::remove_dir_all(&out);
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_omnicave"))
        .args([
            "render",
            "--view",
            "panorama",
            "--config",
            "config/cave.toml",
            "--scene",
            "assets/living-room.glb",
            "--projection",
            "hammer",
            "--pano-stereo",
            "omni",
            "--pano-size",
            "160x80",
            "--format",
            "side-by-side",
            "--out",
        ])
        .arg(&out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run omnicave");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "render failed:\n{stderr}");
    for (name, size) in [
        ("panorama-left.png", (160, 80)),
        ("panorama-right.png", (160, 80)),
        ("panorama-anaglyph.png", (160, 80)),
        ("panorama-side-by-side.png", (320, 80)),
    ] {
        let img = image::open(out.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((img.width(), img.height()), size, "{name}");
    }
    // Omnistereo: the eyes differ (near furniture has disparity).
    let left = image::open(out.join("panorama-left.png"))
        .unwrap()
        .to_rgb8();
    let right = image::open(out.join("panorama-right.png"))
        .unwrap()
        .to_rgb8();
    let differ = left
        .pixels()
        .zip(right.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(differ > 100, "only {differ} pixels differ between the eyes");
    assert!(
        stderr.contains("panorama: hammer 360°×180°, geometric route, omni"),
        "{stderr}"
    );
}

#[test]
fn the_sky_shows_behind_the_panorama_where_its_beacons_are() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sky.png");
    let sky = omnicave::sky::load_sky(&path).expect("bundled sky");
    let cave = cave();
    // A box in front of the red beacon (azimuth 0°, 15° up): the scene hides the sky there.
    let hider = marker_scene(
        &[HEAD + omnicave::sky::bundled::BEACONS[0].direction() * 2.0],
        HEAD,
        0.1,
    );
    for route in PanoRoute::ALL {
        let mut pano = settings(Projection::Equirectangular, route, [360.0, 180.0]);
        pano.size = [1440, 720];
        pano.cube_size = 1024;
        let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
        renderer.set_sky(Some(&sky)).expect("sky");
        renderer.set_scene(&hider).expect("scene upload");
        let frame = test_frame(
            &cave,
            Head::at(HEAD),
            RenderMode::Mono,
            OmniSettings::default(),
            TessSettings::default(),
        );
        renderer.render_panorama(&frame, &pano).expect("panorama");
        let [image, _] = renderer.read_panorama().expect("read back");
        keep(&format!("sky-{}", route.name()), &image);
        for (i, beacon) in omnicave::sky::bundled::BEACONS.iter().enumerate() {
            let dir = pano
                .view_from_cave(HEAD)
                .transform_vector3(beacon.direction());
            let at = cpu_pixel(&pano, dir).expect("every direction has a pixel");
            let p = image.get_pixel(at.x as u32, at.y as u32);
            let got = [p[0], p[1], p[2]];
            // The marker hiding the first beacon is red too ([255, 0, 0], unlit); the others
            // show the beacon's own colour at its centre (a 1.5° cap is 6 px across here:
            // its centre is unfiltered) within the sky's 8-bit rounding and the lookup's
            // bilinear filtering, 24 levels.
            let expected = if i == 0 { [255, 0, 0] } else { beacon.rgb };
            assert!(
                channel_diff(got, expected) <= 24,
                "{} route: beacon {} at {at} shows {got:?}, expected {expected:?}",
                route.name(),
                beacon.name
            );
        }
    }
}

#[test]
fn image_and_geometric_routes_agree_on_back_faces() {
    // Single-sided squares all around the head, half facing it and half facing away: both
    // routes draw exactly the facing ones (the image route's rasteriser culls by winding in
    // each cube face, the geometric route in its vertex shader), and a double-sided square
    // facing away is drawn by both.
    let mut pano = settings(
        Projection::Equirectangular,
        PanoRoute::Image,
        [360.0, 180.0],
    );
    pano.size = [360, 180];
    let mut scene = Scene::default();
    let mut expected = Vec::new();
    for (k, (lon, lat)) in [
        (0.0, 0.0),
        (70.0, 10.0),
        (-120.0, -20.0),
        (160.0, 30.0),
        (20.0, 60.0),
    ]
    .into_iter()
    .enumerate()
    {
        for (facing, double_sided, dlon) in [
            (true, false, 0.0),
            (false, false, 12.0),
            (false, true, -12.0),
        ] {
            let centre = point_at(&pano, lon + dlon, lat, 2.0);
            let to_head = (HEAD - centre).normalize();
            let normal = if facing { to_head } else { -to_head };
            let right = Vec3::Y.cross(normal).normalize_or(Vec3::X) * 0.15;
            let up = normal.cross(right).normalize() * 0.15;
            let corners = [
                centre - right - up,
                centre + right - up,
                centre + right + up,
                centre - right + up,
            ];
            let rgb = [200, 40 * k as u8, if double_sided { 250 } else { 0 }];
            let mut material = Material::unlit("square", rgb.map(|v| f32::from(v) / 255.0));
            material.double_sided = double_sided;
            let m = scene.add_material(material);
            let vertices: Vec<Vertex> = corners
                .iter()
                .map(|p| Vertex::new(p.to_array(), normal.to_array(), [0.0, 0.0]))
                .collect();
            scene.add_mesh(&vertices, &[0, 1, 2, 0, 2, 3], m);
            expected.push((lon + dlon, lat, facing || double_sided));
        }
    }
    let mut images = Vec::new();
    for route in [PanoRoute::Image, PanoRoute::Geometric] {
        pano.route = route;
        let [image, _] = render(&scene, &pano, TessSettings::default());
        keep(&format!("back-faces-{}", route.name()), &image);
        images.push(image);
    }
    for (lon, lat, drawn) in expected {
        let dir = direction(lon.to_radians(), lat.to_radians());
        let at = cpu_pixel(&pano, dir).unwrap();
        let seen: Vec<bool> = images
            .iter()
            .map(|img| img.get_pixel(at.x as u32, at.y as u32)[0] > 100)
            .collect();
        assert_eq!(
            seen,
            vec![drawn, drawn],
            "square at longitude {lon}, latitude {lat}: image and geometric routes"
        );
    }
}
