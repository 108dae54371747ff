//! The configuration: the settings model as written in TOML (`file`), its validation
//! (`validate`), where each field stands in the text (`spans`) and its JSON schema (`schema`).
//!
//! Parsing is strict (unknown keys and names are refused) and every semantic check names the
//! file, the line, the field and the offending value, so a lab engineer can fix a config
//! without reading code.

mod bounds;
mod convert;
mod file;
pub mod import;
pub mod schema;
mod spans;
mod strict;
mod validate;
pub mod wall_output;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::cave::Cave;
use crate::gamepad::GamepadSettings;
use crate::output::formats::StereoFormat;
use crate::tracking::{ReceiverSettings, SourceSettings, TrackingSettings};

pub use bounds::{Bounds, bounds};
pub use file::*;

/// Everything that can be wrong with a config file.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config file {path} is not valid{field}: {message}")]
    Parse {
        path: PathBuf,
        /// `": field `x.y`"` where the parser's position names one, else empty.
        field: String,
        message: String,
    },
    #[error("config file {path}{line}: field `{field}` has invalid value {value}: {reason}")]
    Invalid {
        path: PathBuf,
        /// `", line N"` where the text is known, else empty.
        line: String,
        field: String,
        value: String,
        reason: String,
    },
}

/// Where the control panel is drawn in CAVE mode.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PanelPlacement {
    Window,
    /// Over the wall with this index.
    Overlay(usize),
    Hidden,
}

/// Where one wall's window goes.
#[derive(Debug, Clone, PartialEq)]
pub struct WallWindow {
    pub monitor: Option<MonitorRef>,
    pub position: Option<[i32; 2]>,
    pub size: [u32; 2],
    pub output: StereoFormat,
    /// A window per eye instead of the one window (a passive wall with two projectors).
    pub eye_outputs: Vec<EyeWindow>,
}

/// One eye's window of a wall (`[[wall.output]]`).
#[derive(Debug, Clone, PartialEq)]
pub struct EyeWindow {
    pub eye: crate::cave::Eye,
    pub monitor: Option<MonitorRef>,
    pub position: Option<[i32; 2]>,
    pub size: [u32; 2],
    /// x, y, width, height of the eye image shown (wall pixels).
    pub crop: [u32; 4],
    /// The image moves by this many pixels in the window (right, down).
    pub offset: [i32; 2],
}

/// The validated `[app]` section and per-wall window settings.
#[derive(Debug, Clone, PartialEq)]
pub struct AppConfig {
    pub mode: AppMode,
    pub panel: PanelPlacement,
    pub window_position: Option<[i32; 2]>,
    pub window_size: [u32; 2],
    pub preview_output: StereoFormat,
    pub vsync: bool,
    pub navigation_speed: f32,
    /// One per wall, in wall order.
    pub walls: Vec<WallWindow>,
}

/// The validated `[tracking]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingConfig {
    /// Start listening at launch.
    pub enabled: bool,
    /// The OSC receiver's settings (used when the source is OSC).
    pub receiver: ReceiverSettings,
    /// The source to start.
    pub source: SourceSettings,
    /// Button number of the tracked input device → action.
    pub buttons: BTreeMap<usize, crate::tracking::ButtonAction>,
    pub settings: TrackingSettings,
}

/// A validated configuration, ready to use: the settings model as loaded, and what is derived
/// from it once (the walls' geometry, resolved paths, the application's windows, tracking and
/// gamepad set-up). Every other setting is read from `settings` (see `convert.rs`).
#[derive(Debug, Clone)]
pub struct Config {
    /// The file it came from (for messages and relative paths).
    pub source: PathBuf,
    pub cave: Cave,
    /// Scene file, already resolved against the config's folder.
    pub scene_path: Option<PathBuf>,
    /// Sky file, already resolved against the config's folder (`None`: no sky).
    pub sky_path: Option<PathBuf>,
    /// Windows, panel and output formats of the interactive application.
    pub app: AppConfig,
    /// OSC head tracking.
    pub tracking: TrackingConfig,
    pub gamepad: GamepadSettings,
    /// The settings model as validated (what "Save settings" starts from).
    pub settings: ConfigFile,
}

impl Config {
    /// Reads and validates a config file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = crate::read_capped::read_capped_text(
            path,
            crate::read_capped::MAX_CONFIG_BYTES,
            "config files",
        )
        .map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::from_toml(&text, path)
    }

    /// Parses and validates config text; `path` is used for messages and relative paths.
    /// Every error names the field and, where the text has it, its line.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let file: ConfigFile = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            field: e
                .span()
                .and_then(|span| spans::field_at(text, span.start))
                .map(|field| format!(": field `{field}`"))
                .unwrap_or_default(),
            message: crate::messages::cut_long_lines(e.to_string().trim_end()),
        })?;
        let model = toml::Value::try_from(&file).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            field: String::new(),
            message: e.to_string(),
        })?;
        strict::check_lengths(text, &model).map_err(|wrong| ConfigError::Invalid {
            path: path.to_owned(),
            line: spans::line_of(text, &wrong.path)
                .map(|line| format!(", line {line}"))
                .unwrap_or_default(),
            value: format!("({} elements)", wrong.got),
            reason: format!("takes exactly {} elements", wrong.expected),
            field: wrong.path,
        })?;
        file.validate_text(path, Some(text))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::RenderMode;
    use crate::cave::omni::OmniSettings;

    const GOOD: &str = r#"
[[wall]]
name = "front"
lower_left = [-1.65, 0.0, -1.65]
lower_right = [1.65, 0.0, -1.65]
upper_left = [-1.65, 2.9, -1.65]
resolution = [1280, 720]
"#;

    fn err(text: &str) -> String {
        match Config::from_toml(text, Path::new("test.toml")) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn minimal_config_gets_defaults() {
        let cfg = Config::from_toml(GOOD, Path::new("x/test.toml")).expect("valid");
        assert_eq!(cfg.cave.walls.len(), 1);
        assert_eq!(cfg.settings.render.mode, RenderMode::Stereo);
        assert!((cfg.settings.cave.eye_separation - 0.064).abs() < 1e-7);
    }

    #[test]
    fn omnistereo_defaults_match_the_library_defaults() {
        let cfg = Config::from_toml(GOOD, Path::new("test.toml")).expect("valid");
        assert_eq!(cfg.settings.omni(), OmniSettings::default());
    }

    #[test]
    fn unknown_key_is_named() {
        let e = err(&format!("{GOOD}\n[head]\nposition = [0,1,0]\nheigth = 3\n"));
        assert!(e.contains("test.toml") && e.contains("heigth"), "{e}");
    }

    #[test]
    fn nan_is_refused_with_field_and_value() {
        let e = err(&GOOD.replace("[-1.65, 2.9, -1.65]", "[-1.65, nan, -1.65]"));
        assert!(e.contains("wall[0].upper_left") && e.contains("NaN"), "{e}");
    }

    #[test]
    fn skewed_wall_is_refused() {
        let e = err(&GOOD.replace("[-1.65, 2.9, -1.65]", "[-1.0, 2.9, -1.65]"));
        assert!(e.contains("not perpendicular"), "{e}");
    }

    #[test]
    fn degenerate_and_zero_size_walls_are_refused() {
        let e = err(&GOOD.replace("[1.65, 0.0, -1.65]", "[-1.65, 0.0, -1.65]"));
        assert!(
            e.contains("wall[0].lower_right") && e.contains("no width"),
            "{e}"
        );
        let e = err(&GOOD.replace("[1280, 720]", "[0, 720]"));
        assert!(
            e.contains("wall[0].resolution") && e.contains("[0, 720]"),
            "{e}"
        );
    }

    #[test]
    fn bad_mode_lists_the_choices() {
        let e = err(&format!("{GOOD}\n[render]\nmode = \"omni\"\n"));
        assert!(
            e.contains("render.mode") && e.contains("tracked-stereo"),
            "{e}"
        );
    }
}
