//! Bad input never panics: malformed configs, glTF files and CLI arguments give clear errors
//! that name the file, the field or object, and the value.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};

use omnicave::config::Config;
use omnicave::scene::load_gltf;
use serde_json::json;

fn tmp(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad_input");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
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
fn bundled_configs_are_valid() {
    for name in ["config/cave.toml", "config/desktop.toml"] {
        let cfg = Config::load(&repo(name)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(cfg.cave.walls.len(), 3);
        let names: Vec<_> = cfg.cave.walls.iter().map(|w| w.name.as_str()).collect();
        assert_eq!(names, ["left", "front", "right"]);
        assert!(
            cfg.scene_path.as_ref().is_some_and(|p| p.is_file()),
            "{name}: scene missing"
        );
    }
    let cave = Config::load(&repo("config/cave.toml")).unwrap().cave;
    assert_eq!(
        cave,
        omnicave::cave::Cave {
            ..omnicave::cave::thesis_cave()
        }
    );
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
        // Cluster settings (issue 21): the wall's rank, the timeouts and the policy.
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

/// A one-triangle glTF with an external buffer; `edit` may break the JSON or the binary.
fn write_triangle_gltf(
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value, &mut Vec<u8>),
) -> PathBuf {
    let mut bin = Vec::new();
    for v in [[0.0f32, 0.0, -2.0], [1.0, 0.0, -2.0], [0.0, 1.0, -2.0]] {
        for c in v {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0] {
        bin.extend_from_slice(&i.to_le_bytes()); // last one is padding
    }
    let bin_name = format!("{name}.bin");
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": bin_name, "byteLength": 44}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, -2.0], "max": [1.0, 1.0, -2.0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ]
    });
    edit(&mut doc, &mut bin);
    let path = tmp(&format!("{name}.gltf"));
    std::fs::write(&path, doc.to_string()).unwrap();
    std::fs::write(tmp(&bin_name), &bin).unwrap();
    path
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
fn a_well_formed_triangle_loads_with_generated_normals() {
    let scene = load_gltf(&write_triangle_gltf("good", |_, _| {})).unwrap();
    assert_eq!(scene.triangle_count(), 1);
    // No NORMAL attribute: generated from the winding (counter-clockwise seen from +z).
    for v in &scene.vertices {
        assert!((v.normal[2] - 1.0).abs() < 1e-6, "{:?}", v.normal);
    }
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
    let path = write_triangle_gltf("missing-buffer", |doc, _| {
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
            // Counted against the vertex budget before any accessor is read (issue 18).
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
        let path = write_triangle_gltf(name, edit);
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

// ---------------------------------------------------------------- CLI

fn omnicave(args: &[&str]) -> (bool, String) {
    let (ok, _, stderr) = common::run_omnicave(args);
    (ok, stderr)
}

#[test]
fn bad_cli_arguments_exit_nonzero_with_a_message() {
    let out = tmp("cli-out");
    let out = out.to_str().unwrap();
    let bad_config = tmp("cli-bad.toml");
    std::fs::write(
        &bad_config,
        default_cave_text().replace("msaa = 4", "msaa = 3"),
    )
    .unwrap();
    let bad_scene = tmp("cli-bad.glb");
    std::fs::write(&bad_scene, b"glTF\x02\x00\x00\x00\xff\xff\xff\xff").unwrap();
    let bad_path = tmp("cli-bad-path.csv");
    std::fs::write(&bad_path, "t,x,y,z\n0,0,1.7,0\n0.5,0.1,1.7\n").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["render", "--mode", "bogus", "--out", out],
            "invalid value 'bogus' for '--mode",
        ),
        (
            vec!["render", "--view", "dome", "--out", out],
            "invalid value 'dome' for '--view",
        ),
        (
            vec![
                "render",
                "--view",
                "panorama",
                "--projection",
                "mercator",
                "--out",
                out,
            ],
            "invalid value 'mercator' for '--projection",
        ),
        (
            vec![
                "render", "--view", "panorama", "--fov", "400,90", "--out", out,
            ],
            "horizontal field of view 400° must be 1 to 360 degrees",
        ),
        (
            vec!["render", "--view", "panorama", "--fov", "360", "--out", out],
            "expected H,V in degrees",
        ),
        (
            vec![
                "render",
                "--view",
                "panorama",
                "--pano-route",
                "ray",
                "--out",
                out,
            ],
            "invalid value 'ray' for '--pano-route",
        ),
        // The application refuses a bad config or scene before opening any window.
        (
            vec!["run", "--config", bad_config.to_str().unwrap()],
            "render.msaa",
        ),
        (
            vec!["run", "--scene", bad_scene.to_str().unwrap()],
            "cli-bad.glb",
        ),
        (vec!["run", "--stats-every", "0"], "outside 0..1e6"),
        (
            vec!["run", "--quit-after", "soon"],
            "not a number of seconds",
        ),
        (vec!["run", "--preview", "--cave"], "cannot be used with"),
        (
            vec!["render", "--head", "1,2", "--out", out],
            "expected X,Y,Z",
        ),
        (
            vec!["render", "--head", "1,2,abc", "--out", out],
            "'abc' is not a number",
        ),
        (
            vec!["render", "--head", "1,inf,2", "--out", out],
            "not a finite number",
        ),
        (
            vec!["render", "--size", "0x10", "--out", out],
            "outside 1..=8192",
        ),
        (
            vec!["render", "--size", "640", "--out", out],
            "expected WxH",
        ),
        (vec!["render", "--ipd", "2", "--out", out], "outside 0..0.5"),
        (
            vec!["render", "--msaa", "2", "--out", out],
            "MSAA must be 1 or 4",
        ),
        (
            vec!["render", "--head-yaw", "720", "--out", out],
            "outside -360..360",
        ),
        (
            vec!["render", "--warp", "fast", "--out", out],
            "invalid value 'fast' for '--warp",
        ),
        (
            vec!["render", "--pole-merge", "75,60", "--out", out],
            "0 <= START <= END <= 90",
        ),
        (
            vec!["render", "--pole-merge", "on", "--out", out],
            "expected START,END",
        ),
        (
            vec!["render", "--head", "0,1.7,-2", "--out", out],
            "behind or on wall 'front'",
        ),
        (
            vec!["render", "--tess", "error", "--out", out],
            "expected none, uniform:N",
        ),
        (
            vec!["render", "--tess", "edge:-3", "--out", out],
            "outside 0.01..=10000",
        ),
        (
            vec!["render", "--tess-max-depth", "40", "--out", out],
            "exceeds the limit of 16",
        ),
        (
            vec!["render", "--skybox-mode", "exact", "--out", out],
            "invalid value 'exact' for '--skybox-mode",
        ),
        (
            vec!["render", "--format", "checkerboard", "--out", out],
            "invalid value 'checkerboard' for '--format",
        ),
        (vec!["render"], "--out"),
        (vec!["fly"], "unrecognized subcommand"),
        (
            vec!["run", "--osc-listen", "everywhere"],
            "'everywhere' is not an address:port",
        ),
        (
            vec!["track-sim", "--target", "nohost"],
            "'nohost' is not a host:port",
        ),
        (
            vec!["track-sim", "--pattern", "spiral"],
            "invalid value 'spiral' for '--pattern",
        ),
        (
            vec!["track-sim", "--form", "smoke"],
            "invalid value 'smoke' for '--form",
        ),
        (vec!["track-sim", "--rate", "0"], "outside 0.1..10000 Hz"),
        (
            vec!["track-sim", "--quaternion-order", "zwxy"],
            "invalid value 'zwxy' for '--quaternion-order",
        ),
        (
            vec!["track-sim", "--replay", "no-such-path.csv"],
            "cannot read path file no-such-path.csv",
        ),
        (
            vec!["track-sim", "--replay", bad_path.to_str().unwrap()],
            "cli-bad-path.csv, line 3: 3 fields",
        ),
        (
            vec!["track-sim", "--config", bad_config.to_str().unwrap()],
            "render.msaa",
        ),
        (
            vec!["render", "--config", "nope.toml", "--out", out],
            "nope.toml",
        ),
        (
            vec![
                "render",
                "--config",
                bad_config.to_str().unwrap(),
                "--out",
                out,
            ],
            "render.msaa",
        ),
        (
            vec![
                "render",
                "--scene",
                bad_scene.to_str().unwrap(),
                "--out",
                out,
            ],
            "cli-bad.glb",
        ),
    ];
    for (args, needle) in cases {
        let (ok, stderr) = omnicave(&args);
        assert!(!ok, "{args:?} should fail");
        assert!(
            stderr.contains(needle),
            "{args:?}: '{needle}' missing from:\n{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?} panicked:\n{stderr}");
    }
}

#[test]
fn render_command_writes_every_wall_and_eye() {
    let out = tmp("cli-render");
    let _ = std::fs::remove_dir_all(&out);
    let (ok, stderr) = omnicave(&[
        "render",
        "--config",
        "config/cave.toml",
        "--mode",
        "omni-offaxis",
        "--pole-merge",
        "55,70",
        "--tess",
        "error:1",
        "--head",
        "0.2,1.6,-0.3",
        "--head-yaw",
        "-20",
        "--size",
        "128x72",
        "--format",
        "side-by-side",
        "--format",
        "frame-packing",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "render failed:\n{stderr}");
    for wall in ["left", "front", "right"] {
        let sbs = image::open(out.join(format!("{wall}-side-by-side.png"))).unwrap();
        assert_eq!((sbs.width(), sbs.height()), (256, 72));
        let packed = image::open(out.join(format!("{wall}-frame-packing.png"))).unwrap();
        assert_eq!((packed.width(), packed.height()), (128, 147));
    }
    for wall in ["left", "front", "right"] {
        for eye in ["left", "right"] {
            let img = image::open(out.join(format!("{wall}-{eye}.png"))).unwrap();
            assert_eq!((img.width(), img.height()), (128, 72));
        }
    }
    let unfolded = image::open(out.join("unfolded-anaglyph.png")).unwrap();
    assert_eq!((unfolded.width(), unfolded.height()), (384, 72));
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
fn six_faces_load_in_place_and_hdr_keeps_its_range() {
    use glam::Vec3;
    // Faces of distinct colours, given by their px…nz aliases, each with a white top-left
    // quadrant (as the image is viewed from inside the cube): a face loaded into the wrong
    // layer, mirrored or rotated would show its colour or its white in the wrong direction.
    let dir = tmp("six-faces");
    std::fs::create_dir_all(&dir).unwrap();
    let colours = [
        [255u8, 0, 0],
        [0, 255, 0],
        [0, 0, 255],
        [255, 255, 0],
        [255, 0, 255],
        [0, 255, 255],
    ];
    for (alias, c) in ["px", "nx", "py", "ny", "pz", "nz"].iter().zip(colours) {
        image::RgbaImage::from_fn(16, 16, |x, y| {
            if x < 8 && y < 8 {
                image::Rgba([255, 255, 255, 255])
            } else {
                image::Rgba([c[0], c[1], c[2], 255])
            }
        })
        .save(dir.join(format!("{alias}.png")))
        .unwrap();
    }
    let cube = omnicave::sky::load_sky(&dir).unwrap();
    assert_eq!(cube.size(), 16);
    assert_eq!(cube.levels.len(), 5);
    // For each face: its centre direction, and the direction of its image's top-left quadrant
    // as a viewer inside sees it (CAVE space: +x right, +y up, −z front). The top face is seen
    // with the front at its lower edge, the bottom face with the front at its upper edge.
    let faces = [
        ("right (px)", Vec3::X, Vec3::new(1.0, 0.5, -0.5)),
        ("left (nx)", Vec3::NEG_X, Vec3::new(-1.0, 0.5, 0.5)),
        ("top (py)", Vec3::Y, Vec3::new(-0.5, 1.0, 0.5)),
        ("bottom (ny)", Vec3::NEG_Y, Vec3::new(-0.5, -1.0, -0.5)),
        ("front (pz)", Vec3::NEG_Z, Vec3::new(-0.5, 0.5, -1.0)),
        ("back (nz)", Vec3::Z, Vec3::new(0.5, 0.5, 1.0)),
    ];
    for ((name, centre, top_left), c) in faces.into_iter().zip(colours) {
        let want = c.map(|v| f32::from(v) / 255.0);
        // Just off the centre, into the coloured quadrants.
        let off_centre =
            centre + 0.2 * (centre.cross(Vec3::Y).normalize_or(Vec3::X)) - 0.1 * Vec3::Y;
        assert_eq!(cube.sample_nearest(off_centre), want, "{name}: colour");
        assert_eq!(
            cube.sample_nearest(top_left),
            [1.0; 3],
            "{name}: top-left quadrant"
        );
    }

    // An HDR equirectangular sky: values above 1 survive (RGBA16F), and are where they belong.
    let hdr = tmp("bright.hdr");
    let (w, h) = (64u32, 32u32);
    let pixels: Vec<image::Rgb<f32>> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            // The upper half is bright (4.0), the lower dim (0.25).
            let v = if y < h / 2 { 4.0 } else { 0.25 };
            image::Rgb([v, v * 0.5, if x < w / 2 { 1.0 } else { 2.0 }])
        })
        .collect();
    let file = std::fs::File::create(&hdr).unwrap();
    image::codecs::hdr::HdrEncoder::new(file)
        .encode(&pixels, w as usize, h as usize)
        .unwrap();
    let cube = omnicave::sky::load_sky(&hdr).unwrap();
    assert!(cube.is_hdr());
    let up = cube.sample_nearest(Vec3::new(0.0, 1.0, -0.2));
    assert!((up[0] - 4.0).abs() < 0.05, "{up:?}");
    let down = cube.sample_nearest(Vec3::new(0.3, -1.0, 0.0));
    assert!((down[0] - 0.25).abs() < 0.01, "{down:?}");
}

#[test]
fn a_broken_sky_is_reported_and_the_scene_still_renders() {
    let out = tmp("cli-bad-sky");
    let _ = std::fs::remove_dir_all(&out);
    let garbage = tmp("cli-garbage-sky.jpg");
    std::fs::write(&garbage, b"\xff\xd8 broken jpeg").unwrap();
    let (ok, stderr) = omnicave(&[
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
    assert!(ok, "render should go on without the sky:\n{stderr}");
    assert!(
        stderr.contains("cli-garbage-sky.jpg") && stderr.contains("rendering without a sky"),
        "{stderr}"
    );
    assert!(out.join("front-left.png").is_file());
}
