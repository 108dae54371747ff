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

/// One imported wall's corners (lower left, lower right, upper left), to 0.1 mm: the
/// acceptance's precision, far above the files' own rounding (a micrometre in the worst).
fn assert_corners(import: &omnicave::config::import::Import, name: &str, want: [[f64; 3]; 3]) {
    let w = import
        .walls
        .iter()
        .find(|w| w.name == name)
        .unwrap_or_else(|| panic!("no wall {name} in {:?}", names(import)));
    for (got, want) in [w.lower_left, w.lower_right, w.upper_left].iter().zip(want) {
        let d = (*got - glam::DVec3::from(want)).length();
        assert!(d < 1e-4, "{name}: {got} is {:.3} mm from {want:?}", d * 1e3);
    }
}

fn names(import: &omnicave::config::import::Import) -> Vec<&str> {
    import.walls.iter().map(|w| w.name.as_str()).collect()
}

fn import(file: &str, section: Option<&str>) -> omnicave::config::import::Import {
    omnicave::config::import::import_walls(
        &root().join("tests/data/import").join(file),
        None,
        None,
        section,
    )
    .unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// Every wall pair that shares an edge meets there (within 0.1 mm), and there are `joins`.
fn assert_all_meet(import: &omnicave::config::import::Import, joins: usize) {
    let (_, found) = omnicave::config::import::check_walls(&import.walls);
    for j in &found {
        assert!(j.distance <= 1e-4, "{}", j.describe());
    }
    assert_eq!(
        found.len(),
        joins,
        "{:?}",
        found.iter().map(|j| j.describe()).collect::<Vec<_>>()
    );
}

/// Real installations' own files (tests/data/import/README.md names their sources and
/// licences), each format detected by its content, corners worked by hand from each format's
/// documented conventions.
#[test]
fn real_installations_files_import_to_hand_worked_corners() {
    // Equalizer's own three-sided CAVE example: metres, y up, as omnicave.
    let eq = import("3-channel.cave.eqc", None);
    assert_eq!(
        names(&eq),
        ["channel-left", "channel-middle", "channel-right"]
    );
    assert_corners(
        &eq,
        "channel-left",
        [[-1.0, -1.0, 1.0], [-1.0, -1.0, -1.0], [-1.0, 1.0, 1.0]],
    );
    assert_all_meet(&eq, 2);

    // RWTH Aachen's aixCAVE, nDisplay JSON (UE 5): cm, Unreal axes, 5.25 m wide walls of 2×2
    // overlapping projector tiles. The front wall's lower-left tile: centre (262.5,
    // −105.3575, 98.214249) cm, 314.285 × 196.428497 cm → CAVE (−1.053575, 0.982142, −2.625).
    let aix = import("aixcave.ndisplay", None);
    assert_eq!(aix.walls.len(), 24, "{:?}", names(&aix));
    assert_corners(
        &aix,
        "screen_front_lower_left",
        [
            [-2.625, 0.0, -2.625],
            [0.51785, 0.0, -2.625],
            [-2.625, 1.964285, -2.625],
        ],
    );
    // The left wall turned −90° about up: its lower-left tile runs from the back corner.
    assert_corners(
        &aix,
        "screen_left_lower_left",
        [
            [-2.625, 0.0, 2.625],
            [-2.625, 0.0, -0.51785],
            [-2.625, 1.964285, 2.625],
        ],
    );
    // screen_main hangs off the glasses that carry the cameras: it follows the viewer.
    assert!(!names(&aix).contains(&"screen_main"));
    assert!(
        aix.notes
            .iter()
            .any(|n| n.contains("screen_main") && n.contains("shutter_glasses")),
        "{:?}",
        aix.notes
    );

    // University of Minnesota's IV/LAB CAVE, MinVR 2 XML (feet, y up), with its `<!---- ---->`.
    let ivlab = import("ivlabcave.minvr", None);
    assert_eq!(
        names(&ivlab),
        [
            "IVLABCave_LeftWall",
            "IVLABCave_FrontWall",
            "IVLABCave_RightWall",
            "IVLABCave_Floor"
        ]
    );
    let ft = 0.3048;
    assert_corners(
        &ivlab,
        "IVLABCave_LeftWall",
        [
            [-4.0 * ft, -4.0 * ft, 4.0 * ft],
            [-4.0 * ft, -4.0 * ft, -4.0 * ft],
            [-4.0 * ft, 4.0 * ft, 4.0 * ft],
        ],
    );
    assert_eq!(
        ivlab.walls[3].resolution,
        Some([1280, 720]),
        "the floor's own Height"
    );
    assert_eq!(
        ivlab.walls[0].resolution,
        Some([1280, 1300]),
        "the clients' Width, Height"
    );
    assert_all_meet(&ivlab, 5);

    // The same CAVE in MinVR 1's text form: Window2_Viewport1 is the front wall.
    let umn = import("umn-cave.vrsetup", None);
    assert_eq!(umn.walls.len(), 4);
    assert_corners(
        &umn,
        "window2_viewport1",
        [
            [-4.0 * ft, -4.0 * ft, -4.0 * ft],
            [4.0 * ft, -4.0 * ft, -4.0 * ft],
            [-4.0 * ft, 4.0 * ft, -4.0 * ft],
        ],
    );
    assert_all_meet(&umn, 5);

    // Vrui's own Vrui.cfg: several installations; KeckCAVES (UC Davis) is picked by name.
    let path = root().join("tests/data/import/Vrui.cfg");
    let e = omnicave::config::import::import_walls(&path, None, None, None).unwrap_err();
    assert!(
        e.to_string().contains("--section")
            && e.to_string()
                .contains("caveman.geology.ucdavis.edu (5 fixed screens)"),
        "{e}"
    );
    let keck = import("Vrui.cfg", Some("caveman.geology.ucdavis.edu"));
    // Wall2, the front wall: origin (−60, 60, 0) in, horizontal +x, vertical +z, 120 × 96 in;
    // z up, y forward → CAVE (x, z, −y).
    let inch = 0.0254;
    assert_corners(
        &keck,
        "Wall2",
        [
            [-60.0 * inch, 0.0, -60.0 * inch],
            [60.0 * inch, 0.0, -60.0 * inch],
            [-60.0 * inch, 96.0 * inch, -60.0 * inch],
        ],
    );
    assert!(
        keck.conversion.contains("inchScale 1"),
        "{}",
        keck.conversion
    );

    // Brown's YURT in Vrui: feet (inchScale 1/12), y up, −z forward, axes not of unit length.
    let yurt = import("yurt-Vrui.cfg", Some("cave001"));
    assert_eq!(yurt.walls.len(), 38);
    assert_corners(
        &yurt,
        "screen37",
        [
            [1.279507728, 0.071229931, -0.000001687],
            [1.214844408, 0.071229931, -0.390366504],
            [1.140174504, -0.586294992, 0.023077871],
        ],
    );
}

/// Files written here in the forms real installations publish (their own can not be shipped):
/// nDisplay's legacy `.cfg` with its defects, a looped LED ribbon as nDisplay JSON, and a CalVR
/// main file including a screens fragment.
#[test]
fn legacy_ndisplay_ribbon_and_calvr_fragments_import_as_their_software_reads_them() {
    let legacy = import("legacy-cave.cfg", None);
    assert_eq!(legacy.format.name(), "ndisplay-cfg");
    assert_eq!(legacy.walls.len(), 7, "{:?}", names(&legacy));
    // Metres, Unreal axes. The front's right tile as its second (last) definition says.
    assert_corners(
        &legacy,
        "screen_front_right",
        [[0.0, 0.0, -2.625], [2.625, 0.0, -2.625], [0.0, 3.3, -2.625]],
    );
    // Left wall, yaw −90: from the back corner forward. Right wall, yaw +90: from the front.
    assert_corners(
        &legacy,
        "screen_left_back",
        [
            [-2.625, 0.0, 2.625],
            [-2.625, 0.0, 0.0],
            [-2.625, 3.3, 2.625],
        ],
    );
    assert_corners(
        &legacy,
        "screen_right_front",
        [
            [2.625, 0.0, -2.625],
            [2.625, 0.0, 0.0],
            [2.625, 3.3, -2.625],
        ],
    );
    // Floor, pitch −90: its height runs forward (−z).
    assert_corners(
        &legacy,
        "screen_floor_left",
        [
            [-2.625, 0.0, 2.625],
            [0.0, 0.0, 2.625],
            [-2.625, 0.0, -2.625],
        ],
    );
    let front = legacy
        .walls
        .iter()
        .find(|w| w.name == "screen_front_left")
        .unwrap();
    assert_eq!(front.resolution, Some([1920, 1200]));
    assert!(
        legacy
            .notes
            .iter()
            .any(|n| n.contains("line 23") && n.contains("line 24")),
        "the duplicate names both lines: {:?}",
        legacy.notes
    );
    assert!(
        legacy
            .notes
            .iter()
            .any(|n| n.contains("screen_main") && n.contains("tracker"))
    );
    // The missing tile leaves the right wall's back half open: every edge there is, meets.
    assert_all_meet(&legacy, 10);
    // A malformed number is refused naming its line and field.
    let dir = scratch("legacy");
    let text = std::fs::read_to_string(root().join("tests/data/import/legacy-cave.cfg")).unwrap();
    let bad = dir.join("bad.cfg");
    std::fs::write(&bad, text.replace("X=0.40,Y=0,Z=0", "X=0.40.0,Y=0,Z=0")).unwrap();
    let e = omnicave::config::import::import_walls(&bad, None, None, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.cfg")
            && e.contains("line 40")
            && e.contains("loc X")
            && e.contains("0.40.0"),
        "{e}"
    );

    // The ribbon: 20 strips, each off the previous one's edge, turned 15° further, sized by
    // their scale: every neighbour meets edge to edge.
    let ribbon = import("ribbon.ndisplay", None);
    assert_eq!(ribbon.walls.len(), 21);
    assert_all_meet(&ribbon, 19);
    // strip_01: its hinge (190, 25, 0) cm, turned 15°; 50 cm wide along (−sin 15°, cos 15°, 0).
    assert_corners(
        &ribbon,
        "strip_01",
        [
            [0.25, 0.0, -1.9],
            [0.732962913, 0.0, -1.770590477],
            [0.25, 3.0, -1.9],
        ],
    );

    // CalVR: the main file includes the screens fragment (several top-level elements, a
    // `<!---- ---->` comment, two hosts' windows both named "0").
    let calvr = import("calvr-main.xml", None);
    assert_eq!(names(&calvr), ["LEFT", "FRONT", "RIGHT"]);
    assert_corners(
        &calvr,
        "LEFT",
        [[-1.65, 0.0, 1.65], [-1.65, 0.0, -1.65], [-1.65, 2.9, 1.65]],
    );
    assert_eq!(calvr.walls[0].resolution, Some([1280, 720]));
    assert_eq!(
        calvr.walls[2].resolution,
        Some([1920, 1080]),
        "cave-1's own window 0"
    );
    assert_all_meet(&calvr, 2);

    // Vrui as Vrui reads it: metres, y up, −z forward; `height 4.5.0` is 4.5 (with a note); a
    // comment stuck to a value; a screen on a tracked device skipped.
    let vrui = "section Vrui\n section Lab\n  meterScale 1.0\n  upDirection (0.0, 1.0, 0.0)\n  \
                forwardDirection (0.0, 0.0, -1.0)\n  section Front\n   origin (-1.0, 0.0, -1.0)#x\n   \
                horizontalAxis (1.0, 0.0, 0.0)\n   verticalAxis (0.0, 2.0, 0.0)\n   width 2.0\n   \
                height 4.5.0\n  endsection\n  section Hmd\n   deviceMounted true\n   \
                origin (0, 0, 0)\n   horizontalAxis (1, 0, 0)\n   verticalAxis (0, 1, 0)\n   \
                width 1\n   height 1\n  endsection\n endsection\nendsection\n";
    let lab = omnicave::config::import::import_text(vrui, Path::new("lab.cfg"), None, None, None)
        .unwrap();
    assert_eq!(lab.format.name(), "vrui");
    assert_corners(
        &lab,
        "Front",
        [[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [-1.0, 4.5, -1.0]],
    );
    assert_eq!(lab.walls.len(), 1);
    assert!(
        lab.notes
            .iter()
            .any(|n| n.contains("line 11") && n.contains("read as 4.5")),
        "{:?}",
        lab.notes
    );
    assert!(
        lab.notes
            .iter()
            .any(|n| n.contains("Hmd") && n.contains("deviceMounted")),
        "{:?}",
        lab.notes
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Nearly 4 MiB (the import's file budget) of `unit` repeated after `head` and before `tail`.
fn four_mib(head: &str, unit: &dyn Fn(usize) -> String, tail: &str) -> String {
    let budget = (4 << 20) - 16 * 1024;
    let mut text = head.to_owned();
    let mut i = 0;
    while text.len() + tail.len() < budget {
        text.push_str(&unit(i));
        i += 1;
    }
    text.push_str(tail);
    text
}

/// Hostile inputs of every format: each read or refused with a clear message in under a
/// second (the parsers are linear; CalVR's was quadratic, and a 4 MiB file hung it), never
/// a corner that is not finite in the output.
#[test]
fn four_mib_and_hostile_inputs_of_every_format_are_read_or_refused_quickly() {
    use omnicave::config::import::{ImportFormat, import_text};
    let screen_json = |i: usize, parent: &str| {
        format!(
            "\"s{i}\":{{\"size\":{{\"width\":100,\"height\":100}},\"parentId\":\"{parent}\",\
             \"location\":{{\"x\":100}}}}"
        )
    };
    let deep_xforms = four_mib(
        "{\"nDisplay\":{\"scene\":{\"xforms\":{\"x0\":{}",
        &|i| {
            format!(
                ",\"x{}\":{{\"parentId\":\"x{i}\",\"location\":{{\"z\":0.001}}}}",
                i + 1
            )
        },
        "},\"screens\":{PLACEHOLDER}}}}",
    );
    // Every screen at the bottom of the deepest chain: placed once, not once per screen.
    let last = deep_xforms.matches("\"parentId\"").count();
    let screens: Vec<String> = (0..64)
        .map(|i| screen_json(i, &format!("x{last}")))
        .collect();
    let deep_xforms = deep_xforms.replace("PLACEHOLDER", &screens.join(","));
    let cfg_chain = four_mib(
        "[scene_node] id=n0 loc=\"X=0,Y=0,Z=0\"\n",
        &|i| {
            format!(
                "[scene_node] id=n{} loc=\"X=0,Y=0,Z=+0.0001\" parent=n{i}\n",
                i + 1
            )
        },
        "[screen] id=s loc=\"X=1\" size=\"X=1,Y=1\" parent=n1000\n",
    );
    let calvr = four_mib(
        "<?xml version=\"1.0\"?>\n<!-- -- -->\n",
        &|i| {
            format!(
                "<LOCAL host=\"h{i}\"><Window name=\"0\" width=\"10\" height=\"10\"/></LOCAL>\n"
            )
        },
        "<Screen width=\"1\" height=\"1\" window=\"0\"/>",
    );
    let vrui = four_mib(
        "section Vrui\nsection Cave\n",
        &|i| {
            format!(
                "section s{i}\norigin (0, 0, 0)\nhorizontalAxis (1, 0, 0)\nverticalAxis (0, 0, 1)\nwidth 1\nheight 1\nendsection\n"
            )
        },
        "endsection\nendsection\n",
    );
    let minvr = four_mib(
        "<MinVR>",
        &|i| {
            format!(
                "<T{i}><TopLeft>-1,1,0</TopLeft><BottomLeft>-1,-1,0</BottomLeft><BottomRight>1,-1,0</BottomRight></T{i}>"
            )
        },
        "</MinVR>",
    );
    let vrsetup = four_mib(
        "",
        &|i| {
            format!(
                "Window1_Viewport{i}_TopLeft (-1, 1, 0)\nWindow1_Viewport{i}_BotLeft (-1,-1,0)\nWindow1_Viewport{i}_BotRight (1,-1,0)\n"
            )
        },
        "",
    );
    let eqc = four_mib(
        "canvas {",
        &|_| {
            "segment { wall { bottom_left [ -1 -1 -1 ] bottom_right [ 1 -1 -1 ] top_left [ -1 1 -1 ] } }\n".into()
        },
        "}",
    );
    let nested_vrui = "section a\n".repeat(200_000);
    let cases: Vec<(&str, String, Option<&str>)> = vec![
        ("deep.ndisplay", deep_xforms, None),
        ("chain.cfg", cfg_chain, None),
        ("hosts.xml", calvr, None),
        ("many.cfg", vrui, Some("more than 64 walls")),
        ("tiles.minvr", minvr, Some("more than 64 walls")),
        ("tiles.vrsetup", vrsetup, Some("more than 64 walls")),
        ("walls.eqc", eqc, Some("more than 64 walls")),
        ("nested.cfg", nested_vrui, Some("nest deeper than 64")),
    ];
    for (name, text, refusal) in cases {
        assert!(text.len() <= 4 << 20, "{name}: {} bytes", text.len());
        // The better of two runs: a scheduler hiccup on a loaded 2-core machine is not the
        // reader's time.
        let mut took = std::time::Duration::MAX;
        let mut result = None;
        for _ in 0..2 {
            let start = std::time::Instant::now();
            result = Some(import_text(&text, Path::new(name), None, None, None));
            took = took.min(start.elapsed());
        }
        let result = result.expect("ran");
        eprintln!("{name}: {} bytes, {took:?}", text.len());
        // One second, the acceptance's bound; the worst here, 70 000 nested nDisplay parents,
        // takes about half a second in the test build.
        assert!(took.as_secs_f64() < 1.0, "{name}: {took:?}");
        match (result, refusal) {
            (Ok(import), None) => {
                for w in &import.walls {
                    assert!(
                        w.lower_left.is_finite() && w.upper_left.is_finite(),
                        "{name}"
                    );
                }
            }
            (Err(e), Some(says)) => {
                let e = e.to_string();
                assert!(e.contains(name) && e.contains(says), "{name}: {e}");
            }
            (Ok(i), Some(says)) => panic!(
                "{name}: imported {} walls, expected '{says}'",
                i.walls.len()
            ),
            (Err(e), None) => panic!("{name}: {e}"),
        }
    }

    // Numbers that overflow, or place a wall kilometres away, are refused, never written.
    for (name, text, says) in [
        (
            "huge.xml",
            "<Screen width=\"1e308\" height=\"1\" originX=\"1e308\"/>",
            "farther than 1000 m",
        ),
        (
            "far.xml",
            "<Screen width=\"1\" height=\"1\" originX=\"1e7\"/>",
            "farther than 1000 m",
        ),
        (
            "inf.ndisplay",
            r#"{"nDisplay":{"scene":{"xforms":{"a":{"location":{"x":1e308}}},"screens":{"s":{"size":{"width":1,"height":1},"parentId":"a","location":{"x":1e308}}}}}}"#,
            "not finite",
        ),
    ] {
        let e = import_text(text, Path::new(name), None, None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name) && e.contains(says), "{name}: {e}");
    }
    // Cycles are named as cycles; a chain of 500 acyclic parents is followed.
    let cycle = r#"{"nDisplay":{"scene":{"xforms":{"a":{"parentId":"b"},"b":{"parentId":"c"},"c":{"parentId":"a"}},"screens":{"s":{"size":{"width":1,"height":1},"parentId":"a"}}}}}"#;
    let e = import_text(cycle, Path::new("c.ndisplay"), None, None, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cycle: a → b → c → a"), "{e}");
    // A legacy nDisplay file read with `--format ndisplay`, and a CalVR include that is not
    // there (noted, as CalVR goes on), or includes itself (read once).
    let legacy = std::fs::read_to_string(root().join("tests/data/import/legacy-cave.cfg")).unwrap();
    let i = import_text(
        &legacy,
        Path::new("l.cfg"),
        Some(ImportFormat::NDisplay),
        None,
        None,
    )
    .unwrap();
    assert_eq!(i.walls.len(), 7);
    let dir = scratch("include");
    let me = dir.join("me.xml");
    std::fs::write(
        &me,
        "<INCLUDE>me.xml</INCLUDE><INCLUDE>gone.xml</INCLUDE><Screen width=\"1\" height=\"1\"/>",
    )
    .unwrap();
    let i = omnicave::config::import::import_walls(&me, None, None, None).unwrap();
    assert_eq!(i.walls.len(), 1);
    assert!(
        i.notes.iter().any(|n| n.contains("included again")),
        "{:?}",
        i.notes
    );
    assert!(
        i.notes
            .iter()
            .any(|n| n.contains("gone.xml") && n.contains("skipped")),
        "{:?}",
        i.notes
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `config import --check` prints each wall and how the walls meet, and writes nothing.
#[test]
fn import_check_prints_walls_and_their_edges() {
    let file = root().join("tests/data/import/legacy-cave.cfg");
    let (code, out, err) = run_omnicave(&["config", "import", "--check", file.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("screen_front_left: 2.6250 × 3.3000 m, centre (-1.3125, 1.6500, -2.6250), normal (0.0000, 0.0000, 1.0000)"), "{out}");
    assert!(
        out.contains("7 walls, 10 shared edges, 10 meeting within 0.1 mm, 0 apart"),
        "{out}"
    );
    assert!(
        err.contains("line 23") && err.contains("screen_main"),
        "the notes: {err}"
    );
    // The written walls say how they were converted and repaired.
    let (code, out, err) = run_omnicave(&["config", "import", file.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("# Converted from Unreal's frame"), "{out}");
    assert!(
        out.contains("# Note: [screen] id=\"screen_front_right\" is defined on line 23"),
        "{out}"
    );
}
