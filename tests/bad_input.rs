//! Malformed input never panics: a bad config, glTF file or sky is refused with a clear error
//! that names the file, the field or object, and the value; a broken sky is reported and the
//! scene renders without it.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};

use common::gltf_files::write_triangle_gltf;
use common::{repo, run_omnicave};
use omnicave::config::Config;
use omnicave::scene::load_gltf;
use serde_json::json;

fn tmp(name: &str) -> PathBuf {
    common::tmp_dir("bad_input").join(name)
}

// ---------------------------------------------------------------- config

fn config_error(name: &str, text: &str) -> String {
    let path = tmp(name);
    std::fs::write(&path, text).unwrap();
    let err = Config::load(&path)
        .expect_err("config should be refused")
        .to_string();
    assert!(err.contains(name), "error does not name the file: {err}");
    err
}

fn default_cave_text() -> String {
    std::fs::read_to_string(repo("config/cave.toml")).unwrap()
}

#[test]
fn config_errors_name_file_field_and_value() {
    let base = default_cave_text();
    let cases = [
        (
            "unknown-key.toml",
            base.replace("eye_separation = 0.064", "eye_seperation = 0.064"),
            vec!["eye_seperation"],
        ),
        (
            "nan.toml",
            base.replacen(
                "lower_left = [-1.65, 0.0, 1.65]",
                "lower_left = [nan, 0.0, 1.65]",
                1,
            ),
            vec!["wall[0].lower_left", "NaN"],
        ),
        (
            "degenerate.toml",
            base.replacen(
                "upper_left = [-1.65, 2.9, -1.65]",
                "upper_left = [-1.65, 0.0, -1.65]",
                1,
            ),
            vec!["wall[1].upper_left", "no height"],
        ),
        (
            "skewed.toml",
            base.replacen(
                "upper_left = [1.65, 2.9, -1.65]",
                "upper_left = [1.65, 2.9, -1.3]",
                1,
            ),
            vec!["wall[2].upper_left", "not perpendicular", "-1.3"],
        ),
        (
            "zero-size.toml",
            base.replacen("resolution = [1280, 720]", "resolution = [1280, 0]", 1),
            vec!["wall[0].resolution", "[1280, 0]"],
        ),
        // Cluster settings: the wall's rank, the timeouts and the policy.
        (
            "node-range.toml",
            base.replacen("node = 2  ", "node = 5000", 1),
            vec!["wall[2].node", "5000", "between 0 and 1023"],
        ),
        (
            "node-negative.toml",
            base.replacen("node = 1  ", "node = -1 ", 1),
            vec!["wall[0].node", "-1"],
        ),
        (
            "cluster-timeout.toml",
            base.replace("timeout_ms = 2000", "timeout_ms = 0"),
            vec!["cluster.timeout_ms", "0", "between 10 and 600000"],
        ),
        (
            "cluster-policy.toml",
            base.replace("on_node_loss = \"continue\"", "on_node_loss = \"explode\""),
            vec!["on_node_loss", "explode", "continue"],
        ),
        (
            "negative-ipd.toml",
            base.replace("eye_separation = 0.064", "eye_separation = -0.064"),
            vec!["cave.eye_separation", "-0.064"],
        ),
        (
            "bad-mode.toml",
            base.replace("mode = \"stereo\"", "mode = \"omnistereo\""),
            vec!["render.mode", "omnistereo", "mono"],
        ),
        (
            "bad-projection.toml",
            base.replace(
                "projection = \"equirectangular\"",
                "projection = \"mercator\"",
            ),
            vec!["panorama.projection", "mercator", "hammer"],
        ),
        (
            "bad-pano-fov.toml",
            base.replace("v_fov_degrees = 180.0", "v_fov_degrees = 200.0"),
            vec!["panorama.v_fov_degrees", "200", "between 1 and 180"],
        ),
        (
            "bad-pano-stereo.toml",
            base.replace("stereo = \"mono\"", "stereo = \"sbs\""),
            vec!["panorama.stereo", "sbs", "volume"],
        ),
        (
            "bad-volume.toml",
            base.replace("stereo = \"mono\"", "stereo = \"volume\"")
                .replace(
                    "volume_ioid_d_offset = [0.5, 5.0, -0.8]",
                    "volume_ioid_d_offset = [0.5, 0.5, -0.8]",
                ),
            vec!["panorama.volume_ioid_d_offset", "d > 1"],
        ),
        (
            "bad-app-mode.toml",
            base.replace("mode = \"cave\"", "mode = \"wall\""),
            vec!["app.mode", "wall", "preview"],
        ),
        (
            "bad-panel.toml",
            base.replace("panel = \"window\"", "panel = \"overlay:ceiling\""),
            vec!["app.panel", "overlay:ceiling", "names no wall"],
        ),
        (
            "bad-output.toml",
            base.replace(
                "wall_output = \"frame-sequential\"",
                "wall_output = \"quad-buffer\"",
            ),
            vec!["app.wall_output", "quad-buffer", "side-by-side"],
        ),
        (
            "bad-window.toml",
            base.replace("window_size = [1280, 720]", "window_size = [0, 720]"),
            vec!["app.window_size", "[0, 720]"],
        ),
        (
            "bad-wall-window.toml",
            base.replace("monitor = 1 ", "window_size = [0, 100000]\nmonitor = 1 "),
            vec!["wall[0].window_size", "[0, 100000]", "1..=8192"],
        ),
        (
            "bad-monitor.toml",
            base.replace("monitor = 1 ", "monitor = -1 "),
            vec!["monitor"],
        ),
        (
            "no-walls.toml",
            "[cave]\neye_separation = 0.06\n".to_owned(),
            vec!["wall"],
        ),
        (
            "duplicate-wall.toml",
            base.replace("name = \"right\"", "name = \"left\""),
            vec!["wall[2].name", "another wall"],
        ),
        (
            "bad-sky-mode.toml",
            base.replace("mode = \"auto\"", "mode = \"omni\""),
            vec!["skybox.mode", "omni", "omni-exact"],
        ),
        (
            "bad-sky-slices.toml",
            base.replace("pixels_per_slice = 8.0", "pixels_per_slice = 0.0"),
            vec!["skybox.pixels_per_slice", "0.0"],
        ),
        (
            "not-toml.toml",
            "this is [not toml".to_owned(),
            vec!["not valid"],
        ),
    ];
    for (name, text, needles) in cases {
        let err = config_error(name, &text);
        for n in needles {
            assert!(err.contains(n), "{name}: '{n}' missing from: {err}");
        }
    }
    let missing = Config::load(&tmp("does-not-exist.toml"))
        .unwrap_err()
        .to_string();
    assert!(missing.contains("does-not-exist.toml"), "{missing}");
}

// ---------------------------------------------------------------- glTF

/// A change to a glTF document and its binary buffer.
type GltfEdit = dyn FnOnce(&mut serde_json::Value, &mut Vec<u8>);

/// The one-triangle glTF of [`write_triangle_gltf`] in this binary's scratch folder.
fn triangle_gltf(name: &str, edit: impl FnOnce(&mut serde_json::Value, &mut Vec<u8>)) -> PathBuf {
    write_triangle_gltf(&common::tmp_dir("bad_input"), name, edit)
}

fn gltf_error(path: &Path) -> String {
    let err = load_gltf(path)
        .expect_err("file should be refused")
        .to_string();
    let file = path.file_name().unwrap().to_str().unwrap();
    assert!(err.contains(file), "error does not name {file}: {err}");
    err
}

#[test]
fn truncated_glb_is_refused() {
    let bytes = std::fs::read(repo("assets/living-room.glb")).unwrap();
    for (name, cut) in [
        ("truncated-half.glb", bytes.len() / 2),
        ("truncated-header.glb", 10),
        ("truncated-json.glb", 100),
    ] {
        let path = tmp(name);
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let err = gltf_error(&path);
        assert!(
            err.contains("truncated") || err.contains("not valid glTF"),
            "{err}"
        );
    }
}

#[test]
fn missing_buffer_is_named() {
    let path = triangle_gltf("missing-buffer", |doc, _| {
        doc["buffers"][0]["uri"] = json!("nowhere.bin");
    });
    let err = gltf_error(&path);
    assert!(
        err.contains("nowhere.bin") && err.contains("does not exist"),
        "{err}"
    );
}

#[test]
fn bad_accessors_are_refused() {
    let cases: Vec<(&str, Box<GltfEdit>, &str)> = vec![
        (
            "accessor-past-view",
            Box::new(|doc, _| doc["accessors"][0]["count"] = json!(30)),
            "read past the end of buffer view",
        ),
        (
            "view-past-buffer",
            Box::new(|doc, bin| {
                bin.truncate(40);
                doc["buffers"][0]["byteLength"] = json!(40);
            }),
            "outside buffer",
        ),
        (
            "index-out-of-range",
            Box::new(|_, bin| bin[38..40].copy_from_slice(&7u16.to_le_bytes())),
            "index 7 is out of range for 3 vertices",
        ),
        (
            "nan-position",
            Box::new(|_, bin| bin[0..4].copy_from_slice(&f32::NAN.to_le_bytes())),
            "NaN",
        ),
        (
            "huge-count",
            Box::new(|doc, _| doc["accessors"][0]["count"] = json!(u32::MAX)),
            // Counted against the vertex budget before any accessor is read.
            "4294967295 vertices here, over budgets.max_vertices",
        ),
        (
            // Under the budget but still past its data: the accessor check names it.
            "large-count",
            Box::new(|doc, _| doc["accessors"][0]["count"] = json!(1_000_000)),
            "accessor 0",
        ),
        (
            "wrong-type",
            Box::new(|doc, _| doc["accessors"][0]["type"] = json!("VEC2")),
            "",
        ),
        (
            "bad-material",
            Box::new(|doc, _| doc["meshes"][0]["primitives"][0]["material"] = json!(5)),
            "",
        ),
    ];
    for (name, edit, needle) in cases {
        let path = triangle_gltf(name, edit);
        let err = gltf_error(&path);
        assert!(
            err.contains(needle),
            "{name}: '{needle}' missing from: {err}"
        );
    }
}

#[test]
fn garbage_empty_and_missing_files_are_refused() {
    for (name, bytes) in [
        ("empty.glb", Vec::new()),
        ("garbage.gltf", b"\x00\x01\x02 not json".to_vec()),
        ("wrong-json.gltf", br#"{"asset": 3}"#.to_vec()),
        ("glb-magic-only.glb", b"glTF".to_vec()),
    ] {
        let path = tmp(name);
        std::fs::write(&path, bytes).unwrap();
        gltf_error(&path);
    }
    let err = load_gltf(&tmp("no-such-scene.glb"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("no-such-scene.glb"), "{err}");
}

// ---------------------------------------------------------------- sky

fn sky_error(path: &Path) -> String {
    omnicave::sky::load_sky(path)
        .expect_err("sky should be refused")
        .to_string()
}

#[test]
fn bad_sky_files_are_refused_naming_the_file() {
    let garbage = tmp("garbage-sky.png");
    std::fs::write(&garbage, b"not an image at all").unwrap();
    let err = sky_error(&garbage);
    assert!(
        err.contains("garbage-sky.png") && err.contains("not a readable"),
        "{err}"
    );

    let square = tmp("square-sky.png");
    image::RgbaImage::new(64, 64).save(&square).unwrap();
    let err = sky_error(&square);
    assert!(
        err.contains("square-sky.png") && err.contains("twice as wide"),
        "{err}"
    );

    let missing = tmp("no-such-sky.hdr");
    let err = sky_error(&missing);
    assert!(
        err.contains("no-such-sky.hdr") && err.contains("cannot read"),
        "{err}"
    );

    // A folder of faces missing one, and one with a face of the wrong size.
    let dir = tmp("five-faces");
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["right", "left", "top", "bottom", "front"] {
        image::RgbaImage::new(8, 8)
            .save(dir.join(format!("{name}.png")))
            .unwrap();
    }
    let _ = std::fs::remove_file(dir.join("back.png"));
    let err = sky_error(&dir);
    assert!(
        err.contains("five-faces") && err.contains("no back face"),
        "{err}"
    );
    image::RgbaImage::new(8, 4)
        .save(dir.join("back.png"))
        .unwrap();
    let err = sky_error(&dir);
    assert!(err.contains("back.png") && err.contains("8×4"), "{err}");
}

#[test]
fn a_broken_sky_is_reported_and_the_scene_still_renders() {
    let out = tmp("cli-bad-sky");
    let _ = std::fs::remove_dir_all(&out);
    let garbage = tmp("cli-garbage-sky.jpg");
    std::fs::write(&garbage, b"\xff\xd8 broken jpeg").unwrap();
    let (code, _, stderr) = run_omnicave(&[
        "render",
        "--config",
        "config/cave.toml",
        "--skybox",
        garbage.to_str().unwrap(),
        "--size",
        "64x36",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "render should go on without the sky:\n{stderr}");
    assert!(
        stderr.contains("cli-garbage-sky.jpg") && stderr.contains("rendering without a sky"),
        "{stderr}"
    );
    assert!(out.join("front-left.png").is_file());
}
