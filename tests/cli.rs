//! The command line and the settings model's conventions: bad arguments exit non-zero with a
//! message naming the flag and the value, never a panic, and a negative or 100 KB value is
//! read as a value and shown cut; enum flags list their values and suggest the nearest one;
//! shell completions and the config's JSON schema are printed; the bundled configs load and
//! validate against the committed schema; names round-trip; config errors name the line;
//! `render` writes every wall and eye in each format asked for; a GPU validation error or a
//! lost device ends a render with a message, not a panic; and a batch command stopped by
//! SIGTERM exits with 143.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use common::{repo, run_omnicave as omnicave};
use omnicave::cave::RenderMode;
use omnicave::cave::omni::WarpVariant;
use omnicave::config::{AppMode, Config};
use omnicave::gamepad::{GamepadAction, GamepadMode};
use omnicave::output::formats::StereoFormat;
use omnicave::pano::{PanoRoute, PanoStereoKind, Projection};
use omnicave::sky::SkyMode;
use omnicave::tracking::QuaternionOrder;
use omnicave::tracking::sim::SimForm;

/// A path in this test binary's scratch folder.
fn tmp(name: &str) -> PathBuf {
    common::tmp_dir("cli").join(name)
}

#[test]
fn help_lists_every_enum_flags_values() {
    let (code, help, _) = omnicave(&["render", "--help"]);
    assert_eq!(code, 0);
    let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let expect = |names: &[&str]| {
        let listed = format!("[possible values: {}]", names.join(", "));
        assert!(flat.contains(&listed), "{listed} missing from:\n{help}");
    };
    expect(RenderMode::NAMES);
    expect(WarpVariant::NAMES);
    expect(SkyMode::NAMES);
    expect(StereoFormat::NAMES);
    expect(Projection::NAMES);
    expect(PanoRoute::NAMES);
    expect(PanoStereoKind::NAMES);
    expect(&["walls", "panorama"]);

    let (code, help, _) = omnicave(&["track-sim", "--help"]);
    assert_eq!(code, 0);
    let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    for names in [
        SimForm::NAMES,
        QuaternionOrder::NAMES,
        &["circle", "figure-eight", "still"],
    ] {
        let listed = format!("[possible values: {}]", names.join(", "));
        assert!(flat.contains(&listed), "{listed} missing from:\n{help}");
    }

    let (code, help, _) = omnicave(&["--help"]);
    assert!(
        code == 0 && help.contains("completions") && help.contains("config"),
        "{help}"
    );
}

#[test]
fn a_typo_gets_a_suggestion() {
    let (code, _, err) = omnicave(&["render", "--mode", "stero", "--out", "out/x"]);
    assert_ne!(code, 0);
    assert!(err.contains("invalid value 'stero' for '--mode"), "{err}");
    assert!(err.contains("a similar value exists: 'stereo'"), "{err}");
    let (code, _, err) = omnicave(&["render", "--format", "anaglyf", "--out", "out/x"]);
    assert!(code != 0 && err.contains("'anaglyph'"), "{err}");
}

#[test]
fn completions_are_printed() {
    let (code, script, _) = omnicave(&["completions", "bash"]);
    assert_eq!(code, 0);
    assert!(
        script.contains("_omnicave()") && script.contains("complete -F"),
        "{script}"
    );
    // The enum values are completed too.
    assert!(script.contains("omni-offaxis") && script.contains("side-by-side-half"));
    for shell in ["zsh", "fish", "elvish", "powershell"] {
        let (code, script, _) = omnicave(&["completions", shell]);
        assert!(code == 0 && script.contains("omnicave"), "{shell}");
    }
    let (code, _, err) = omnicave(&["completions", "tcsh"]);
    assert!(code != 0 && err.contains("possible values"), "{err}");
}

#[test]
fn gen_assets_has_help() {
    let out = Command::new(env!("CARGO_BIN_EXE_gen-assets"))
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{help}");
    assert!(help.contains("--out") && help.contains("--check"), "{help}");
}

#[test]
fn the_committed_schema_is_current_and_the_bundled_configs_load_and_validate() {
    let (code, printed, err) = omnicave(&["config", "schema"]);
    assert_eq!(code, 0, "{err}");
    let committed = std::fs::read_to_string(repo("config/omnicave.schema.json")).unwrap();
    assert_eq!(
        printed, committed,
        "config/omnicave.schema.json is stale: run `omnicave config schema > config/omnicave.schema.json`"
    );

    let schema: serde_json::Value = serde_json::from_str(&committed).unwrap();
    let mut schemas = boon::Schemas::new();
    let mut compiler = boon::Compiler::new();
    compiler
        .add_resource("omnicave.schema.json", schema)
        .unwrap();
    let index = compiler
        .compile("omnicave.schema.json", &mut schemas)
        .unwrap();
    let as_json = |text: &str| -> serde_json::Value {
        serde_json::to_value(toml::from_str::<toml::Value>(text).unwrap()).unwrap()
    };
    for name in ["config/cave.toml", "config/desktop.toml"] {
        let text = std::fs::read_to_string(repo(name)).unwrap();
        assert!(
            text.starts_with("#:schema ./omnicave.schema.json"),
            "{name} does not point editors at the schema"
        );
        if let Err(e) = schemas.validate(&as_json(&text), index) {
            panic!("{name} does not validate against the schema: {e:#}");
        }
        // And each loads: the three walls of the thesis CAVE, with a scene that exists.
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
    // The schema is not vacuous: it refuses an unknown key, an unknown name and a wrong type.
    let base = std::fs::read_to_string(repo("config/cave.toml")).unwrap();
    for bad in [
        base.replace("eye_separation = 0.064", "eye_seperation = 0.064"),
        base.replace("mode = \"stereo\"", "mode = \"omnistereo\""),
        base.replace("msaa = 4", "msaa = \"four\""),
    ] {
        assert!(
            schemas.validate(&as_json(&bad), index).is_err(),
            "schema accepted a bad config"
        );
    }
}

#[test]
fn every_name_round_trips() {
    fn check<T>(
        all: &[T],
        names: &[&str],
        name: impl Fn(&T) -> &'static str,
        parse: impl Fn(&str) -> Option<T>,
    ) where
        T: PartialEq + std::fmt::Debug + serde::Serialize + serde::de::DeserializeOwned,
    {
        assert_eq!(all.len(), names.len());
        let mut seen = std::collections::HashSet::new();
        for (value, expected) in all.iter().zip(names) {
            assert_eq!(name(value), *expected);
            assert!(seen.insert(*expected), "{expected} named twice");
            assert_eq!(parse(expected).as_ref(), Some(value));
            let json = serde_json::to_string(value).unwrap();
            assert_eq!(json, format!("\"{expected}\""));
            assert_eq!(&serde_json::from_str::<T>(&json).unwrap(), value);
        }
        assert!(parse("no-such-name").is_none());
    }
    check(
        &RenderMode::ALL,
        RenderMode::NAMES,
        |v| v.name(),
        RenderMode::from_name,
    );
    check(
        &WarpVariant::ALL,
        WarpVariant::NAMES,
        |v| v.name(),
        WarpVariant::from_name,
    );
    check(
        &SkyMode::ALL,
        SkyMode::NAMES,
        |v| v.name(),
        SkyMode::from_name,
    );
    check(
        &StereoFormat::ALL,
        StereoFormat::NAMES,
        |v| v.name(),
        StereoFormat::from_name,
    );
    check(
        &Projection::ALL,
        Projection::NAMES,
        |v| v.name(),
        Projection::from_name,
    );
    check(
        &PanoRoute::ALL,
        PanoRoute::NAMES,
        |v| v.name(),
        PanoRoute::from_name,
    );
    check(
        &PanoStereoKind::ALL,
        PanoStereoKind::NAMES,
        |v| v.name(),
        PanoStereoKind::from_name,
    );
    check(
        &GamepadMode::ALL,
        GamepadMode::NAMES,
        |v| v.name(),
        GamepadMode::from_name,
    );
    check(
        &GamepadAction::ALL,
        GamepadAction::NAMES,
        |v| v.name(),
        GamepadAction::from_name,
    );
    check(
        &QuaternionOrder::ALL,
        QuaternionOrder::NAMES,
        |v| v.name(),
        QuaternionOrder::from_name,
    );
    check(
        &SimForm::ALL,
        SimForm::NAMES,
        |v| v.name(),
        SimForm::from_name,
    );
    check(
        &AppMode::ALL,
        AppMode::NAMES,
        |v| v.name(),
        AppMode::from_name,
    );
}

#[test]
fn config_errors_name_the_line() {
    let base = std::fs::read_to_string(repo("config/cave.toml")).unwrap();
    let line_of =
        |text: &str, needle: &str| 1 + text[..text.find(needle).unwrap()].matches('\n').count();
    // A semantic error (found by validation) and a type error (found by the parser) both
    // point at the line of the offending value.
    let skewed = base.replacen(
        "upper_left = [1.65, 2.9, -1.65]",
        "upper_left = [1.65, 2.9, -1.3]",
        1,
    );
    let err = Config::from_toml(&skewed, Path::new("skewed.toml"))
        .unwrap_err()
        .to_string();
    let line = line_of(&skewed, "upper_left = [1.65, 2.9, -1.3]");
    assert!(
        err.contains(&format!(
            "skewed.toml, line {line}: field `wall[2].upper_left`"
        )),
        "{err}"
    );

    let bad_mode = base.replace("mode = \"stereo\"", "mode = \"stero\"");
    let err = Config::from_toml(&bad_mode, Path::new("mode.toml"))
        .unwrap_err()
        .to_string();
    let line = line_of(&bad_mode, "mode = \"stero\"");
    assert!(err.contains("field `render.mode`"), "{err}");
    assert!(err.contains(&format!("line {line}")), "{err}");
}

#[test]
fn a_narrower_projection_takes_as_much_of_the_configs_field_of_view_as_it_shows() {
    // config/cave.toml asks for 360° × 180°; perspective shows at most 170° × 170° and Albers
    // 360° × 170°: without --fov the render clamps to that instead of refusing.
    for projection in ["perspective", "albers"] {
        let out = tmp(&format!("narrow-{projection}"));
        let (code, _, err) = omnicave(&[
            "render",
            "--view",
            "panorama",
            "--projection",
            projection,
            "--pano-size",
            "64x32",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{projection}: {err}");
        assert!(out.join("panorama.png").is_file(), "{projection}");
    }
    // An explicit field of view beyond the projection is still refused.
    let (code, _, err) = omnicave(&[
        "render",
        "--view",
        "panorama",
        "--projection",
        "perspective",
        "--fov",
        "200,90",
        "--out",
        "out/never",
    ]);
    assert!(code != 0 && err.contains("panorama.h_fov_degrees"), "{err}");
}

#[test]
fn a_reader_closing_the_pipe_early_is_no_panic() {
    // `omnicave completions bash | head -1`: the reader goes away before the writer is done.
    // The read end is closed right after the start, long before the program has parsed its
    // arguments, so its write meets a broken pipe.
    for args in [["completions", "bash"], ["config", "schema"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_omnicave"))
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert_ne!(out.status.code(), Some(101), "{args:?}: {stderr}");
    }
}

#[test]
fn bad_cli_arguments_exit_nonzero_with_a_message() {
    let out = tmp("cli-out");
    let out = out.to_str().unwrap();
    let bad_config = tmp("cli-bad.toml");
    std::fs::write(
        &bad_config,
        std::fs::read_to_string(repo("config/cave.toml"))
            .unwrap()
            .replace("msaa = 4", "msaa = 3"),
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
        let (code, _, stderr) = omnicave(&args);
        assert_ne!(code, 0, "{args:?} should fail");
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
    let (code, _, stderr) = omnicave(&[
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
    assert_eq!(code, 0, "render failed:\n{stderr}");
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

/// The test hook `OMNICAVE_TEST_GPU_FAULT` makes the device report a real validation error,
/// or destroys it as a driver reset would: the render ends with exit status 1 and a message
/// saying so, not a panic (101).
#[test]
fn a_gpu_fault_ends_a_render_with_a_message_not_a_panic() {
    for (fault, says) in [
        ("validation", "GPU validation error"),
        ("lost", "the GPU device was lost"),
    ] {
        let out = tmp(&format!("gpu-fault-{fault}"));
        let result = Command::new(env!("CARGO_BIN_EXE_omnicave"))
            .args(["render", "--config", "config/cave.toml", "--mode", "stereo"])
            .args(["--size", "32x18", "--out", out.to_str().unwrap()])
            .current_dir(repo("."))
            .env("OMNICAVE_TEST_GPU_FAULT", fault)
            .env("NO_COLOR", "1")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{fault}:\n{stderr}");
        assert!(
            stderr.contains("the GPU stopped working") && stderr.contains(says),
            "{fault}:\n{stderr}"
        );
    }
}

/// `--ipd -1` is a value (not an unknown flag `-1`), refused with its range; a 100 KB value is
/// cut in the message, on the command line and in a config.
#[test]
fn negative_and_huge_values_get_readable_errors() {
    let (code, _, stderr) = omnicave(&["render", "--out", "/tmp/x", "--ipd", "-1"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("'-1' for '--ipd") && stderr.contains("outside 0..0.5 m"),
        "{stderr}"
    );
    assert!(!stderr.contains("unexpected argument"), "{stderr}");
    let (code, _, stderr) = omnicave(&[
        "render",
        "--out",
        "/tmp/x",
        "--head-yaw",
        "-30",
        "--ipd",
        "-0.5",
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("'-0.5' for '--ipd"), "{stderr}");

    let long = "9".repeat(100_000);
    let (code, _, stderr) = omnicave(&["render", "--out", "/tmp/x", "--ipd", &long]);
    assert_eq!(code, 2);
    assert!(
        stderr.len() < 2000 && stderr.contains("more characters"),
        "{} bytes",
        stderr.len()
    );

    // A 200 KB value in a config: the error names the field and cuts the value.
    let cave = std::fs::read_to_string(repo("config/cave.toml")).unwrap();
    let text = cave.replacen(
        "name = \"left\"",
        &format!("name = \"{}\"", "x".repeat(200_000)),
        1,
    );
    let file = tmp("long-name.toml");
    std::fs::write(&file, text).unwrap();
    let (code, _, stderr) = omnicave(&[
        "render",
        "--config",
        file.to_str().unwrap(),
        "--out",
        "/tmp/x",
    ]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("wall[0].name") && stderr.len() < 2000,
        "{}",
        &stderr[..stderr.len().min(3000)]
    );
}

/// A batch command stopped by SIGTERM exits with 143 (as the shell reports a process
/// terminated by SIGTERM), not by the signal itself, and the handler is in place from the
/// first instruction.
#[test]
fn a_batch_command_stopped_by_a_signal_exits_with_143() {
    let out = tmp("sigterm-render");
    let config = repo("config/cave.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_omnicave"))
        .args([
            "render",
            "--config",
            config.to_str().unwrap(),
            "--size",
            "1024x768",
            "--mode",
            "omni-offaxis",
            "--tess",
            "error:0.5",
            "--out",
            out.to_str().unwrap(),
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(150));
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(143), "{status:?}");
}
