//! Walls as other CAVE software describes them: `omnicave config import` of an Equalizer
//! `.eqc`, a CalVR XML and an nDisplay `.ndisplay` description of the default CAVE (written as
//! those projects' documentation shows) renders exactly as `config/cave.toml`; walls given by
//! centre + yaw/pitch/roll + size and by origin + axes + size, in other units and z up, are the
//! same walls; broken files are refused with the file named.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};

use common::run_omnicave;
use omnicave::cave::Cave;
use omnicave::config::Config;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn cave_toml() -> String {
    std::fs::read_to_string(root().join("config/cave.toml")).expect("cave.toml")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("omnicave-import-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch");
    dir
}

/// Corners equal to a micrometre (the importer writes six decimals), resolutions equal.
fn assert_same_walls(got: &Cave, want: &Cave, what: &str) {
    assert_eq!(got.walls.len(), want.walls.len(), "{what}");
    for (g, w) in got.walls.iter().zip(&want.walls) {
        for (a, b) in [
            (g.lower_left, w.lower_left),
            (g.lower_right, w.lower_right),
            (g.upper_left, w.upper_left),
        ] {
            assert!(
                (a - b).length() < 1e-6,
                "{what}, wall {}: {a} vs {b}",
                g.name
            );
        }
        assert_eq!(g.resolution, w.resolution, "{what}, wall {}", g.name);
    }
}

/// Renders `config` (stereo, the living room, 192×108) and returns every wall image's pixels.
fn render(config: &Path, out: &Path) -> Vec<(String, image::RgbaImage)> {
    let (code, _, err) = run_omnicave(&[
        "render",
        "--config",
        config.to_str().expect("path"),
        "--scene",
        "assets/living-room.glb",
        "--mode",
        "stereo",
        "--size",
        "192x108",
        "--out",
        out.to_str().expect("path"),
    ]);
    assert_eq!(code, 0, "render {}: {err}", config.display());
    let mut files: Vec<_> = std::fs::read_dir(out)
        .expect("out")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    assert!(files.len() >= 6, "{} images", files.len());
    files
        .into_iter()
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().to_lowercase();
            (name, image::open(&p).expect("png").to_rgba8())
        })
        .collect()
}

#[test]
fn imported_equalizer_calvr_and_ndisplay_caves_render_as_cave_toml() {
    let base = root().join("config/cave.toml");
    let want = Config::load(&base).expect("cave.toml");
    let dir = scratch("render");
    let reference = render(&base, &dir.join("reference"));
    for file in ["cave.eqc", "cave-calvr.xml", "cave.ndisplay"] {
        let input = root().join("tests/data/import").join(file);
        let output = dir.join(format!("{file}.toml"));
        let (code, _, err) = run_omnicave(&[
            "config",
            "import",
            input.to_str().unwrap(),
            "--base",
            "config/cave.toml",
            "--output",
            output.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "import {file}: {err}");
        let text = std::fs::read_to_string(&output).expect("imported");
        // The base's other settings and comments survive, and each wall keeps its monitor.
        assert!(text.contains("# The three-wall CAVE of the VRVis research centre"));
        assert_eq!(
            text.matches("monitor = ").count(),
            3,
            "{file}: monitors kept"
        );
        let got = Config::from_toml(&text, &base).expect("imported config loads");
        assert_same_walls(&got.cave, &want.cave, file);
        let images = render(&output, &dir.join(file));
        assert_eq!(images.len(), reference.len());
        for ((name, a), (ref_name, b)) in images.iter().zip(&reference) {
            // Same walls to a micrometre: the same pixels, exactly.
            assert_eq!(name, ref_name, "{file}: wall order");
            let differing = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
            assert_eq!(
                differing, 0,
                "{file}: {name} differs from cave.toml in {differing} px"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// cave.toml with its `[[wall]]` tables replaced by `walls`.
fn with_walls(cave_section_extra: &str, walls: &str) -> String {
    let text = cave_toml();
    let at = text.find("[[wall]]").expect("walls");
    let head = text[..at].replacen("[cave]\n", &format!("[cave]\n{cave_section_extra}\n"), 1);
    format!("{head}{walls}")
}

#[test]
fn walls_by_centre_and_by_axes_in_other_units_and_z_up_are_the_same_walls() {
    let want = Config::load(&root().join("config/cave.toml"))
        .expect("cave.toml")
        .cave;
    let path = root().join("config/cave.toml");
    // nDisplay/CalVR style: centres, yaw about up, sizes; millimetres, z up (y to the front).
    let centre_mm_z_up = with_walls(
        "wall_units = \"mm\"\nwall_up_axis = \"z\"",
        r#"
[[wall]]
name = "left"
centre = [-1650.0, 0.0, 1450.0]
yaw_pitch_roll_degrees = [90.0, 0.0, 0.0]
size = [3300.0, 2900.0]
resolution = [1280, 720]

[[wall]]
name = "front"
centre = [0.0, 1650.0, 1450.0]
size = [3300.0, 2900.0]
resolution = [1280, 720]

[[wall]]
name = "right"
centre = [1650.0, 0.0, 1450.0]
yaw_pitch_roll_degrees = [-90.0, 0.0, 0.0]
size = [3300.0, 2900.0]
resolution = [1280, 720]
"#,
    );
    let got = Config::from_toml(&centre_mm_z_up, &path)
        .expect("centre form")
        .cave;
    assert_same_walls(&got, &want, "centre + yaw/pitch/roll, mm, z up");
    // Vrui style: lower-left origin, edge directions (any length), size; in centimetres, y up.
    let axes_cm = with_walls(
        "wall_units = \"cm\"",
        r#"
[[wall]]
name = "left"
origin = [-165.0, 0.0, 165.0]
horizontal_axis = [0.0, 0.0, -1.0]
vertical_axis = [0.0, 5.0, 0.0]
size = [330.0, 290.0]
resolution = [1280, 720]

[[wall]]
name = "front"
origin = [-165.0, 0.0, -165.0]
horizontal_axis = [2.0, 0.0, 0.0]
vertical_axis = [0.0, 1.0, 0.0]
size = [330.0, 290.0]
resolution = [1280, 720]

[[wall]]
name = "right"
lower_left = [165.0, 0.0, -165.0]
lower_right = [165.0, 0.0, 165.0]
upper_left = [165.0, 290.0, -165.0]
resolution = [1280, 720]
"#,
    );
    let got = Config::from_toml(&axes_cm, &path).expect("axes form").cave;
    assert_same_walls(&got, &want, "origin + axes, cm (and corners in cm)");
    // A foot is 0.3048 m exactly: a 10 × 8 ft front wall.
    let feet = with_walls(
        "wall_units = \"foot\"",
        "[[wall]]\nname = \"f\"\ncentre = [0.0, 4.0, -5.0]\nsize = [10.0, 8.0]\nresolution = [64, 64]\n",
    );
    let got = Config::from_toml(&feet, &path).expect("feet").cave;
    let w = &got.walls[0];
    assert!((w.lower_right - w.lower_left).length() - 3.048 < 1e-6);
    assert!((w.upper_left.y - 2.4384).abs() < 1e-6, "{}", w.upper_left);
}

#[test]
fn incomplete_or_mixed_wall_forms_are_refused_by_field() {
    let path = root().join("config/cave.toml");
    for (walls, field) in [
        ("centre = [0.0, 1.0, -1.0]\n", "wall[0].size"),
        (
            "centre = [0.0, 1.0, -1.0]\nsize = [1.0, -1.0]\n",
            "wall[0].size",
        ),
        (
            "centre = [0.0, 1.0, -1.0]\nsize = [1.0, 1.0]\nlower_left = [0.0, 0.0, 0.0]\n",
            "wall[0].lower_left",
        ),
        (
            "origin = [0.0, 0.0, -1.0]\nhorizontal_axis = [0.0, 0.0, 0.0]\nvertical_axis = \
             [0.0, 1.0, 0.0]\nsize = [1.0, 1.0]\n",
            "wall[0].horizontal_axis",
        ),
        (
            "origin = [0.0, 0.0, -1.0]\nsize = [1.0, 1.0]\n",
            "wall[0].horizontal_axis",
        ),
        (
            "centre = [0.0, 1.0, -1.0]\nsize = [1.0, 1.0]\nyaw_pitch_roll_degrees = [1e9, 0.0, \
             0.0]\n",
            "wall[0].yaw_pitch_roll_degrees",
        ),
        ("", "wall[0].lower_left"),
    ] {
        let text = with_walls(
            "",
            &format!("[[wall]]\nname = \"w\"\n{walls}resolution = [64, 64]\n"),
        );
        let e = Config::from_toml(&text, &path)
            .expect_err(walls)
            .to_string();
        assert!(e.contains(field), "{walls:?}: {e}");
    }
}

#[test]
fn broken_peer_files_are_refused_with_the_file_named() {
    let dir = scratch("broken");
    for (name, text, says) in [
        (
            "open.eqc",
            "server { config { canvas { segment { wall {",
            "not closed",
        ),
        (
            "nan.eqc",
            "canvas { wall { bottom_left [ nan 0 0 ] bottom_right [ 1 0 0 ] top_left [ 0 1 0 ] } }",
            "not a number",
        ),
        ("none.eqc", "server { config { } }", "no walls"),
        ("deep.eqc", &"a { ".repeat(100_000), "nest deeper"),
        (
            "bad.xml",
            "<CalVR><Screen width=\"3300\" /></CalVR>",
            "height",
        ),
        (
            "entities.xml",
            "<!DOCTYPE a [<!ENTITY x \"y\">]><a>&x;</a>",
            "DTD",
        ),
        (
            "cycle.ndisplay",
            r#"{"nDisplay":{"scene":{"xforms":{"a":{"parentId":"b"},"b":{"parentId":"a"}},
               "screens":{"s":{"size":{"width":1,"height":1},"parentId":"a"}}}}}"#,
            "cycle",
        ),
        ("notjson.ndisplay", "{ nDisplay: ", "key must be a string"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write");
        let (code, _, err) = run_omnicave(&["config", "import", path.to_str().unwrap()]);
        assert_ne!(code, 0, "{name} imported");
        assert!(
            err.contains(name),
            "{name}: the message names the file: {err}"
        );
        assert!(err.contains(says), "{name}: {err}");
    }
    // An unknown extension asks for --format.
    let path = dir.join("walls.cfg");
    std::fs::write(&path, "x").expect("write");
    let (code, _, err) = run_omnicave(&["config", "import", path.to_str().unwrap()]);
    assert!(code != 0 && err.contains("--format"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
