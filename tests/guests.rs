//! Where guests may stand: `omnicave guests` end to end (maps, grid, summary, bad input), and
//! `render --viewer`: what a guest sees of walls rendered for the head, re-projected to the
//! guest's eyes, against the ray-intersection model.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod common;

use std::collections::HashMap;

use common::{MARKER_COLOURS, gpu, repo, run_omnicave, tmp_dir};
use glam::{DVec2, Vec3};
use image::RgbaImage;
use omnicave::cave::{Head, RenderMode};
use omnicave::config::Config;
use omnicave::guests::reproject::EyeCamera;
use omnicave::guests::{Assumed, Gaze, Method, Setup, closest_midpoint, judge};
use omnicave::headless::{ViewerRequest, viewer_images};
use omnicave::scene::Scene;

/// The bundled config with `mode`, the head at `head`, walls of `size` pixels, no sky, and
/// `msaa` samples (4: marker edges blend linearly with the background, so a weighted centroid
/// resolves a fraction of a pixel).
fn config(mode: RenderMode, head: Vec3, size: [u32; 2], msaa: u32) -> Config {
    let path = repo("config/cave.toml");
    let mut settings = Config::load(&path).expect("bundled config").settings;
    settings.render.mode = mode;
    settings.render.msaa = msaa;
    // Black, so that a marker's weight (below) is its coverage alone.
    settings.render.background = [0.0; 3];
    settings.head.position = head.to_array();
    for wall in &mut settings.walls {
        wall.resolution = size;
    }
    let mut config = settings.validate(&path).expect("valid");
    config.sky_path = None;
    config
}

/// An unlit sphere at each point, about 4 wall pixels in radius seen from `head` (the thesis
/// walls at 960 px: 2.1 mrad a pixel from the centre), finely tessellated (see
/// `common::markers_tessellated`).
fn fine_markers(points: &[Vec3], head: Vec3) -> Scene {
    common::markers_tessellated(points, |p| 4.0 * 2.1e-3 * (p - head).length(), 48, 64)
}

/// Each marker colour's centroid near `expected` (within `window` px), weighted by how much
/// of the colour each pixel holds: the re-projection blends a marker's rim with the black
/// background linearly, so the weighted centroid is unbiased where an exact-colour one is not.
fn weighted_centroid(
    img: &RgbaImage,
    colour: [u8; 3],
    expected: DVec2,
    window: f64,
) -> Option<DVec2> {
    let c = colour.map(f64::from);
    let norm = c.iter().map(|v| v * v).sum::<f64>();
    let (mut sum, mut weight) = (DVec2::ZERO, 0.0);
    let (x0, x1) = (
        (expected.x - window).max(0.0) as u32,
        (expected.x + window).min(f64::from(img.width())) as u32,
    );
    let (y0, y1) = (
        (expected.y - window).max(0.0) as u32,
        (expected.y + window).min(f64::from(img.height())) as u32,
    );
    for y in y0..y1 {
        for x in x0..x1 {
            let p = img.get_pixel(x, y).0;
            // A pixel of another marker colour does not count (channels it lacks are lit).
            let off: f64 = (0..3)
                .filter(|k| c[*k] == 0.0)
                .map(|k| f64::from(p[k]))
                .sum();
            if off > 8.0 {
                continue;
            }
            let w = (0..3).map(|k| f64::from(p[k]) * c[k]).sum::<f64>() / norm;
            if w > 0.02 {
                sum += w * DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                weight += w;
            }
        }
    }
    (weight > 1.0).then(|| sum / weight)
}

#[test]
fn a_guest_at_the_tracked_head_sees_the_normal_render() {
    // Fixed-direction stereo facing the front wall, and tracked stereo for a guest standing at
    // the head facing the same way, put the eyes in the same places: the two renders, re-
    // projected to the guest's eyes, must agree within one level (the GPU renders the same
    // eyes twice; nothing else differs).
    let head = Vec3::new(0.2, 1.6, 0.3);
    let config = config(RenderMode::Stereo, head, [480, 270], 1);
    let scene = omnicave::setup::load_scene(&config.settings, &repo("assets/living-room.glb"))
        .expect("bundled living room");
    let viewer = ViewerRequest {
        position: head,
        yaw_degrees: Some(0.0),
        fov_degrees: [120.0, 80.0],
        size: [480, 320],
    };
    let images = viewer_images(gpu(), &config, &scene, None, &viewer).expect("rendered");
    for eye in 0..2 {
        let (seen, correct) = (&images.seen[eye], &images.correct[eye]);
        let worst = seen
            .pixels()
            .zip(correct.pixels())
            .flat_map(|(a, b)| (0..3).map(move |k| a[k].abs_diff(b[k])))
            .max()
            .unwrap();
        assert!(worst <= 1, "eye {eye}: differs by {worst} levels");
        // Not a blank image agreeing with itself: most of the view shows the room.
        let lit = seen
            .pixels()
            .filter(|p| p[0] as u32 + p[1] as u32 + p[2] as u32 > 30)
            .count();
        assert!(lit > seen.len() / 4 / 2, "eye {eye}: only {lit} lit pixels");
    }
}

#[test]
fn re_projected_markers_land_where_the_model_says() {
    let head = Vec3::new(0.0, 1.7, 0.0);
    let size = [960, 540];
    // Markers in front of the walls, on them and behind them, ahead and to the sides.
    let markers = [
        Vec3::new(-0.3, 1.5, -1.0),
        Vec3::new(0.4, 1.9, -2.5),
        Vec3::new(-0.9, 1.3, -4.0),
        Vec3::new(0.7, 1.7, -1.65),
        Vec3::new(1.2, 1.2, -3.0),
        Vec3::new(-0.2, 2.1, -6.0),
        Vec3::new(0.15, 1.45, -0.7),
    ];
    let guests = [
        (Vec3::new(0.5, 1.7, 0.6), 0.0f32),
        (Vec3::new(-0.7, 1.5, 0.2), 10.0),
        (Vec3::new(0.3, 1.8, -0.8), -5.0),
    ];
    let mut checked = 0;
    let mut worst_eye = 0.0f64;
    let mut worst_perceived = 0.0f64;
    for mode in [RenderMode::Stereo, RenderMode::OmniOnAxis] {
        let config = config(mode, head, size, 4);
        let scene = fine_markers(&markers, head);
        let ipd = f64::from(config.settings.cave.eye_separation);
        let setup = Setup::new(
            &config.cave,
            Head::at(head),
            ipd,
            config.settings.omni().pole_merge,
        );
        let method = Method {
            mode,
            assumed: Assumed::Head,
        };
        for (guest, yaw) in guests {
            let viewer = ViewerRequest {
                position: guest,
                yaw_degrees: Some(yaw),
                fov_degrees: [100.0, 75.0],
                size: [800, 600],
            };
            let images = viewer_images(gpu(), &config, &scene, None, &viewer).expect("rendered");
            let [left_cam, right_cam]: [EyeCamera; 2] = images.cameras;
            let forward = (Head::orientation_from_degrees(yaw, 0.0, 0.0) * Vec3::NEG_Z).as_dvec3();
            // The cyclopean eye's camera: where the guest perceives each marker.
            let cyclops =
                EyeCamera::new(guest.as_dvec3(), forward, [100.0, 75.0], [800, 600]).unwrap();
            for (i, marker) in markers.iter().enumerate() {
                let p = marker.as_dvec3();
                let colour = MARKER_COLOURS[i % MARKER_COLOURS.len()];
                let Some(shown) = setup.shown_at(method, p) else {
                    continue;
                };
                let expected = [left_cam.pixel_of(shown[0]), right_cam.pixel_of(shown[1])];
                let [Some(el), Some(er)] = expected else {
                    continue;
                };
                // Away from the image's border, where a cut marker's centroid is biased.
                let inside = |q: DVec2| q.x > 12.0 && q.y > 12.0 && q.x < 788.0 && q.y < 588.0;
                if !inside(el) || !inside(er) {
                    continue;
                }
                let what = format!("{} guest {guest} marker {i} at {marker}", mode.name());
                let gl = weighted_centroid(&images.seen[0], colour, el, 12.0)
                    .unwrap_or_else(|| panic!("{what}: left marker not seen near {el}"));
                let gr = weighted_centroid(&images.seen[1], colour, er, 12.0)
                    .unwrap_or_else(|| panic!("{what}: right marker not seen near {er}"));
                // 0.5 px: the acceptance tolerance. A fine sphere's image centroid is within
                // (r/d)² × its offset from the principal point of its centre's image (< 0.01 px
                // here); with 4× MSAA and bilinear re-projection its rim blends linearly, so
                // what remains is the rasteriser's coverage noise (about 0.1 px).
                let (dl, dr) = (gl.distance(el), gr.distance(er));
                assert!(
                    dl <= 0.5 && dr <= 0.5,
                    "{what}: left {gl} vs {el} ({dl:.2} px), right {gr} vs {er} ({dr:.2} px)"
                );
                worst_eye = worst_eye.max(dl).max(dr);
                // The perceived point from the measured images against the model's P′.
                let judged = judge(guest.as_dvec3(), ipd, Gaze::Along(forward), p, shown)
                    .expect("in front of the guest");
                let measured = closest_midpoint(
                    left_cam.eye,
                    left_cam.ray(gl),
                    right_cam.eye,
                    right_cam.ray(gr),
                );
                if let (Some(model), Some(measured)) = (judged.perceived, measured) {
                    let (a, b) = (
                        cyclops.pixel_of(model).unwrap(),
                        cyclops.pixel_of(measured).unwrap(),
                    );
                    let d = a.distance(b);
                    assert!(d <= 0.5, "{what}: P′ seen at {b}, model {a} ({d:.2} px)");
                    worst_perceived = worst_perceived.max(d);
                }
                checked += 1;
            }
        }
    }
    println!(
        "{checked} markers: worst eye {worst_eye:.3} px, worst perceived point {worst_perceived:.3} px"
    );
    // 2 modes × 3 guests × 7 markers, a few outside a guest's view.
    assert!(checked >= 25, "only {checked} markers checked");
}

#[test]
fn guests_writes_maps_grid_and_summary_for_shells() {
    let out = tmp_dir("guests-shells");
    let _ = std::fs::remove_dir_all(&out);
    let out_s = out.to_str().unwrap();
    let (code, _, stderr) = run_omnicave(&[
        "guests",
        "--shells",
        "1,2,4",
        "--points",
        "1500",
        "--step",
        "0.2",
        "--methods",
        "tracked-stereo,omni-onaxis,omni-offaxis@centre",
        "--out",
        out_s,
    ]);
    assert_eq!(code, 0, "{stderr}");
    for metric in [
        "vertical-disparity",
        "direction-error",
        "horizontal-disparity-error",
        "depth-ratio",
    ] {
        for method in [
            "tracked-stereo-at-head",
            "omni-onaxis-at-head",
            "omni-offaxis-at-centre",
        ] {
            let path = out.join(format!("map-{method}-{metric}.png"));
            let img = image::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(img.width() > 300 && img.height() > 300);
        }
    }
    // grid.csv: one row per method and cell inside the CAVE; the cell at the head (the
    // bundled config's 0, 1.7, 0 is a cell centre on a 0.2 m grid) sees omnistereo exactly.
    let mut reader = csv::Reader::from_path(out.join("grid.csv")).unwrap();
    let headers = reader.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    let per_method: HashMap<String, usize> = rows.iter().fold(HashMap::new(), |mut m, r| {
        *m.entry(r[col("method")].to_string()).or_default() += 1;
        m
    });
    // 3.2 m of floor at 0.2 m: 17 × 17 cells.
    assert_eq!(per_method.len(), 3);
    assert!(per_method.values().all(|n| *n == 17 * 17), "{per_method:?}");
    let at_head = |method: &str| {
        rows.iter()
            .find(|r| {
                &r[col("method")] == method
                    && r[col("x_m")].parse::<f64>().unwrap().abs() < 1e-9
                    && r[col("z_m")].parse::<f64>().unwrap().abs() < 1e-9
            })
            .unwrap_or_else(|| panic!("{method}: no cell at the head"))
            .clone()
    };
    let omni = at_head("omni-onaxis@head");
    for name in [
        "vertical_p95_arcmin",
        "direction_p95_arcmin",
        "horizontal_p95_arcmin",
    ] {
        let v: f64 = omni[col(name)].parse().unwrap();
        assert!(v.abs() < 1e-3, "omni-onaxis at the head: {name} {v}");
    }
    // Fixed tracked stereo for a guest at the head turning to the side: a whole vergence
    // angle wrong at the 95th percentile.
    let tracked = at_head("tracked-stereo@head");
    let v: f64 = tracked[col("horizontal_p95_arcmin")].parse().unwrap();
    assert!(v > 20.0, "tracked stereo at the head turning: {v} arcmin");
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    for method in [
        "tracked-stereo@head",
        "omni-onaxis@head",
        "omni-offaxis@centre",
    ] {
        assert!(summary.contains(&format!("| {method} |")), "{summary}");
    }
    let mut summary_csv = csv::Reader::from_path(out.join("summary.csv")).unwrap();
    assert_eq!(summary_csv.records().count(), 3);
}

#[test]
fn guests_refuses_bad_requests_with_the_value_named() {
    let out = tmp_dir("guests-bad");
    let out_s = out.to_str().unwrap();
    let cases: [(&[&str], &str); 8] = [
        // 410 881 cells × 200 000 points: over the judgement budget, refused before any map.
        (
            &["--shells", "1", "--step", "0.005", "--points", "200000"],
            "judgements",
        ),
        (&["--shells", "1", "--points", "200001"], "200001 points"),
        (&["--shells", "1", "--points", "0"], "0 points"),
        (&["--shells", "1", "--eye-heights", "7.5"], "eye height 7.5"),
        (&["--shells", "1", "--step", "0.001"], "grid step 0.001"),
        (&["--shells", "-1"], "shell radii"),
        (
            &["--shells", "1", "--methods", "omni@head"],
            "unknown render mode 'omni'",
        ),
        (
            &["--shells", "1", "--vertical-arcmin", "0"],
            "must be positive",
        ),
    ];
    for (args, expected) in cases {
        let mut all = vec!["guests", "--out", out_s];
        all.extend_from_slice(args);
        let (code, _, stderr) = run_omnicave(&all);
        assert_ne!(code, 0, "{args:?} was accepted");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
    }
}

#[test]
fn render_viewer_writes_both_views_and_refuses_a_guest_outside() {
    let out = tmp_dir("render-viewer");
    let _ = std::fs::remove_dir_all(&out);
    let out_s = out.to_str().unwrap();
    let (code, _, stderr) = run_omnicave(&[
        "render",
        "--size",
        "240x135",
        "--viewer",
        "0.5,1.7,0.6",
        "--viewer-size",
        "320x240",
        "--out",
        out_s,
    ]);
    assert_eq!(code, 0, "{stderr}");
    for name in [
        "seen-left",
        "seen-right",
        "correct-left",
        "correct-right",
        "compare",
    ] {
        let img = image::open(out.join(format!("{name}.png"))).unwrap();
        assert_eq!(img.height(), 240, "{name}");
    }
    let figures = std::fs::read_to_string(out.join("viewer.md")).unwrap();
    assert!(figures.contains("vertical disparity"), "{figures}");
    let (code, _, stderr) = run_omnicave(&["render", "--viewer", "0,1.7,9", "--out", out_s]);
    assert_ne!(code, 0);
    assert!(stderr.contains("--viewer"), "{stderr}");
}
