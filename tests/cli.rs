//! The command line and the settings model's conventions: enum flags list their values and
//! suggest the nearest one, shell completions and the config's JSON schema are printed, the
//! bundled configs validate against the committed schema, names round-trip, and config
//! errors name the line.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;
use std::process::Command;

use omnicave::cave::RenderMode;
use omnicave::cave::omni::WarpVariant;
use omnicave::config::{AppMode, Config};
use omnicave::gamepad::{GamepadAction, GamepadMode};
use omnicave::output::formats::StereoFormat;
use omnicave::pano::{PanoRoute, PanoStereoKind, Projection};
use omnicave::sky::SkyMode;
use omnicave::tracking::QuaternionOrder;
use omnicave::tracking::sim::SimForm;

fn omnicave(args: &[&str]) -> (bool, String, String) {
    common::run_omnicave(args)
}

fn repo(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

#[test]
fn help_lists_every_enum_flags_values() {
    let (ok, help, _) = omnicave(&["render", "--help"]);
    assert!(ok);
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

    let (ok, help, _) = omnicave(&["track-sim", "--help"]);
    assert!(ok);
    let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    for names in [
        SimForm::NAMES,
        QuaternionOrder::NAMES,
        &["circle", "figure-eight", "still"],
    ] {
        let listed = format!("[possible values: {}]", names.join(", "));
        assert!(flat.contains(&listed), "{listed} missing from:\n{help}");
    }

    let (ok, help, _) = omnicave(&["--help"]);
    assert!(
        ok && help.contains("completions") && help.contains("config"),
        "{help}"
    );
}

#[test]
fn a_typo_gets_a_suggestion() {
    let (ok, _, err) = omnicave(&["render", "--mode", "stero", "--out", "out/x"]);
    assert!(!ok);
    assert!(err.contains("invalid value 'stero' for '--mode"), "{err}");
    assert!(err.contains("a similar value exists: 'stereo'"), "{err}");
    let (ok, _, err) = omnicave(&["render", "--format", "anaglyf", "--out", "out/x"]);
    assert!(!ok && err.contains("'anaglyph'"), "{err}");
}

#[test]
fn completions_are_printed() {
    let (ok, script, _) = omnicave(&["completions", "bash"]);
    assert!(ok);
    assert!(
        script.contains("_omnicave()") && script.contains("complete -F"),
        "{script}"
    );
    // The enum values are completed too.
    assert!(script.contains("omni-offaxis") && script.contains("side-by-side-half"));
    for shell in ["zsh", "fish", "elvish", "powershell"] {
        let (ok, script, _) = omnicave(&["completions", shell]);
        assert!(ok && script.contains("omnicave"), "{shell}");
    }
    let (ok, _, err) = omnicave(&["completions", "tcsh"]);
    assert!(!ok && err.contains("possible values"), "{err}");
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
fn the_committed_schema_is_current_and_the_bundled_configs_validate() {
    let (ok, printed, err) = omnicave(&["config", "schema"]);
    assert!(ok, "{err}");
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
    }
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
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("narrow-{projection}"));
        let (ok, _, err) = omnicave(&[
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
        assert!(ok, "{projection}: {err}");
        assert!(out.join("panorama.png").is_file(), "{projection}");
    }
    // An explicit field of view beyond the projection is still refused.
    let (ok, _, err) = omnicave(&[
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
    assert!(!ok && err.contains("panorama.h_fov_degrees"), "{err}");
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
