//! `omnicave config import`: walls from the configuration files of the software a lab uses
//! today (Equalizer, CalVR, Unreal nDisplay in both its formats, Vrui, MinVR), converted into
//! omnicave's `[[wall]]` tables in CAVE space, with what was converted and repaired stated.

mod calvr;
mod check;
mod equalizer;
mod lines;
mod minvr;
mod ndisplay;
mod ndisplay_cfg;
mod unreal;
mod vrui;

pub use check::{EdgeJoin, WallCheck, check_report, check_walls};
pub use lines::LineIndex;

use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::cave::placement::{LengthUnit, UpAxis};
use crate::read_capped::{MAX_CONFIG_BYTES, read_capped_text};

/// Budget: the most walls one file may describe (omnicave's own `budgets.max_walls` default).
pub const MAX_IMPORTED_WALLS: usize = 64;

/// Budget: notes kept from one file (repairs, skipped screens).
const MAX_NOTES: usize = 50;

/// Budget: how far from the CAVE's origin an imported corner may lie, metres (the largest
/// domes and LED volumes are tens of metres; a corner beyond this is a unit or parse error).
pub const MAX_CORNER_M: f64 = 1000.0;

/// The formats `config import` reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImportFormat {
    /// Equalizer's `.eqc`: `wall { bottom_left [...] bottom_right [...] top_left [...] }`, metres,
    /// y up.
    Equalizer,
    /// CalVR's XML `<Screen originX= originY= originZ= h= p= r= width= height= />`, mm, z up
    /// (a whole config or a fragment of several top-level elements, with its `<include>`s).
    CalVr,
    /// Unreal nDisplay's JSON `scene.screens` (with `scene.xforms` parents), cm, z up, x forward.
    NDisplay,
    /// Unreal nDisplay's legacy text `.cfg` (before UE 4.27): `[screen] id= loc= rot= size=
    /// parent=` lines, metres, z up, x forward.
    NDisplayCfg,
    /// Vrui's `.cfg`: `section` blocks whose screens give `origin`, `horizontalAxis`,
    /// `verticalAxis`, `width`, `height`, in the units of `inchScale` or `meterScale`, up along
    /// `upDirection`.
    Vrui,
    /// MinVR's XML (`TopLeft`, `TopRight`, `BottomLeft`, `BottomRight` of each tile) and MinVR
    /// 1's `.vrsetup` text form.
    MinVr,
}

crate::named_enum!(ImportFormat {
    Self::Equalizer => "equalizer",
    Self::CalVr => "calvr",
    Self::NDisplay => "ndisplay",
    Self::NDisplayCfg => "ndisplay-cfg",
    Self::Vrui => "vrui",
    Self::MinVr => "minvr",
});

impl ImportFormat {
    /// The format a file name suggests, where its content does not say (`.cfg` is nDisplay's
    /// or Vrui's: the content decides).
    pub fn from_extension(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "eqc" => Some(Self::Equalizer),
            "xml" => Some(Self::CalVr),
            "ndisplay" | "json" => Some(Self::NDisplay),
            "minvr" | "vrsetup" => Some(Self::MinVr),
            _ => None,
        }
    }

    /// The format a file's content shows, where it shows one: nDisplay's `[cluster_node]`
    /// lines, Vrui's `section` lines, MinVR's and CalVR's XML, Equalizer's `wall {`.
    pub fn from_content(text: &str) -> Option<Self> {
        let first = text.trim_start_matches('\u{feff}').trim_start();
        if first.starts_with('{') {
            return Some(Self::NDisplay);
        }
        let lower_head: String = text
            .chars()
            .take(64 * 1024)
            .collect::<String>()
            .to_ascii_lowercase();
        let line_starts = |prefix: &str| {
            lower_head
                .lines()
                .any(|l| l.trim_start().starts_with(prefix))
        };
        if [
            "[cluster_node]",
            "[screen]",
            "[scene_node]",
            "[viewport]",
            "[info]",
        ]
        .iter()
        .any(|p| line_starts(p))
        {
            return Some(Self::NDisplayCfg);
        }
        if line_starts("section ") {
            return Some(Self::Vrui);
        }
        if lower_head.contains("<minvr") || lower_head.contains("<vrsetup") {
            return Some(Self::MinVr);
        }
        if lower_head.contains("<screen") || lower_head.contains("<calvr") {
            return Some(Self::CalVr);
        }
        if minvr::is_vrsetup_text(&lower_head) {
            return Some(Self::MinVr);
        }
        if lower_head.contains("bottom_left") && lower_head.contains("wall") {
            return Some(Self::Equalizer);
        }
        None
    }

    /// The length unit the format's documentation uses.
    pub fn default_unit(self) -> LengthUnit {
        match self {
            Self::Equalizer | Self::NDisplayCfg | Self::MinVr => LengthUnit::Metre,
            Self::CalVr => LengthUnit::Millimetre,
            Self::NDisplay => LengthUnit::Centimetre,
            Self::Vrui => LengthUnit::Inch,
        }
    }
}

/// What a reader is given beside the text, and what it says beside the walls.
#[derive(Debug)]
pub struct Reading<'a> {
    /// The file (includes are relative to it; messages name it).
    pub path: &'a Path,
    /// `--units`, overriding the file's own.
    pub unit: Option<LengthUnit>,
    /// `--section` (Vrui: the root section whose screens to read).
    pub section: Option<&'a str>,
    /// How the file's frame and units became CAVE space.
    pub conversion: String,
    /// What was repaired, skipped or assumed, each naming its line or id.
    pub notes: Vec<String>,
}

/// Walls imported from a file, with how they were converted.
#[derive(Debug, Clone)]
pub struct Import {
    pub format: ImportFormat,
    pub walls: Vec<ImportedWall>,
    /// Which axis became which and the scale applied.
    pub conversion: String,
    /// Repairs, skipped screens and assumptions, each naming its line or id.
    pub notes: Vec<String>,
}

/// A wall read from another program's file, in CAVE space (metres, y up).
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedWall {
    pub name: String,
    pub lower_left: DVec3,
    pub lower_right: DVec3,
    pub upper_left: DVec3,
    /// Pixels, where the file says (a window or viewport of this wall).
    pub resolution: Option<[u32; 2]>,
}

/// What can go wrong importing, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {why}")]
    Invalid { path: PathBuf, why: String },
    #[error("{path}: no walls found ({what})")]
    NoWalls { path: PathBuf, what: &'static str },
    #[error("{path}: more than {MAX_IMPORTED_WALLS} walls")]
    TooMany { path: PathBuf },
    #[error(
        "cannot tell the format of {path} from its name or content: give --format (equalizer, \
         calvr, ndisplay, ndisplay-cfg, vrui or minvr)"
    )]
    Format { path: PathBuf },
    #[error("{path}: wall {wall}: a corner at {corner} m is {why}")]
    Corner {
        path: PathBuf,
        wall: String,
        corner: String,
        why: &'static str,
    },
}

/// Reads `path` (at most [`MAX_CONFIG_BYTES`]) and returns its walls in CAVE space. `format`:
/// else the content's, else the extension's; `unit` overrides the file's; `section` picks a
/// Vrui root section.
pub fn import_walls(
    path: &Path,
    format: Option<ImportFormat>,
    unit: Option<LengthUnit>,
    section: Option<&str>,
) -> Result<Import, ImportError> {
    let text = read_capped_text(path, MAX_CONFIG_BYTES, "config files").map_err(|source| {
        ImportError::Read {
            path: path.to_owned(),
            source,
        }
    })?;
    import_text(&text, path, format, unit, section)
}

/// [`import_walls`] of a file's text already read (`path` names it in messages; a CalVR
/// `<INCLUDE>` is relative to its folder).
pub fn import_text(
    text: &str,
    path: &Path,
    format: Option<ImportFormat>,
    unit: Option<LengthUnit>,
    section: Option<&str>,
) -> Result<Import, ImportError> {
    let format = format
        .or_else(|| ImportFormat::from_content(text))
        .or_else(|| ImportFormat::from_extension(path))
        .ok_or_else(|| ImportError::Format {
            path: path.to_owned(),
        })?;
    let mut reading = Reading {
        path,
        unit,
        section,
        conversion: String::new(),
        notes: Vec::new(),
    };
    let invalid = |why: String| ImportError::Invalid {
        path: path.to_owned(),
        why,
    };
    let frame = |up: UpAxis| {
        let unit = unit.unwrap_or(format.default_unit());
        match up {
            UpAxis::Y => format!(
                "y up, as CAVE space; lengths in {} (× {})",
                unit.name(),
                unit.metres()
            ),
            UpAxis::Z => format!(
                "right-handed z up, y to the front: CAVE x = x, CAVE y = z, CAVE z = -y; lengths \
                 in {} (× {})",
                unit.name(),
                unit.metres()
            ),
        }
    };
    let walls = match format {
        ImportFormat::Equalizer => {
            reading.conversion = frame(UpAxis::Y);
            equalizer::walls(text, unit.unwrap_or(format.default_unit())).map_err(invalid)?
        }
        ImportFormat::CalVr => {
            reading.conversion = frame(UpAxis::Z);
            calvr::walls(text, &mut reading).map_err(invalid)?
        }
        ImportFormat::NDisplay | ImportFormat::NDisplayCfg => {
            // Either nDisplay name reads either of its formats: the content decides.
            if text
                .trim_start_matches('\u{feff}')
                .trim_start()
                .starts_with('{')
            {
                ndisplay::walls(text, &mut reading).map_err(invalid)?
            } else {
                ndisplay_cfg::walls(text, &mut reading).map_err(invalid)?
            }
        }
        ImportFormat::Vrui => vrui::walls(text, &mut reading).map_err(invalid)?,
        ImportFormat::MinVr => minvr::walls(text, &mut reading).map_err(invalid)?,
    };
    if walls.is_empty() {
        return Err(ImportError::NoWalls {
            path: path.to_owned(),
            what: match format {
                ImportFormat::Equalizer => "no wall { } blocks",
                ImportFormat::CalVr => "no <Screen> elements",
                ImportFormat::NDisplay | ImportFormat::NDisplayCfg => {
                    "no screens fixed in the room"
                }
                ImportFormat::Vrui => "no screen sections fixed in the room",
                ImportFormat::MinVr => "no tiles with four corners",
            },
        });
    }
    if walls.len() > MAX_IMPORTED_WALLS {
        return Err(ImportError::TooMany {
            path: path.to_owned(),
        });
    }
    for w in &walls {
        for c in [w.lower_left, w.lower_right, w.upper_left] {
            let why = if !c.is_finite() {
                Some("not finite")
            } else if c.abs().max_element() > MAX_CORNER_M {
                Some("farther than 1000 m from the origin (a unit or parse error?)")
            } else {
                None
            };
            if let Some(why) = why {
                return Err(ImportError::Corner {
                    path: path.to_owned(),
                    wall: w.name.clone(),
                    corner: format!("({:.6e}, {:.6e}, {:.6e})", c.x, c.y, c.z),
                    why,
                });
            }
        }
    }
    // Budget: notes said (a hostile file could repeat one repair a million times).
    let mut notes = reading.notes;
    if notes.len() > MAX_NOTES {
        let more = notes.len() - MAX_NOTES;
        notes.truncate(MAX_NOTES);
        notes.push(format!("{more} more notes like these"));
    }
    Ok(Import {
        format,
        walls: unique_names(walls),
        conversion: reading.conversion,
        notes,
    })
}

/// A wall name omnicave accepts (1–64 of a-z, A-Z, 0-9, '-', '_'), from any text.
pub fn clean_name(raw: &str, fallback: &str) -> String {
    let name: String = raw
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .take(64)
        .collect();
    if name.trim_matches('_').is_empty() {
        fallback.to_owned()
    } else {
        name
    }
}

fn unique_names(mut walls: Vec<ImportedWall>) -> Vec<ImportedWall> {
    let mut seen = std::collections::HashSet::new();
    for (i, w) in walls.iter_mut().enumerate() {
        if seen.insert(w.name.clone()) {
            continue;
        }
        // The first free suffix from the wall's place on (a name may already end in one).
        let stem: String = w.name.chars().take(56).collect();
        let mut n = i;
        while !seen.insert(format!("{stem}_{n}")) {
            n += 1;
        }
        w.name = format!("{stem}_{n}");
    }
    walls
}

/// A number as the files write one (surrounding blanks allowed), if it is finite.
pub(crate) fn finite(text: &str) -> Option<f64> {
    text.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

/// A value quoted in a message: at most 80 characters (a hostile file's 4 MiB line is not
/// echoed).
pub(crate) fn excerpt(text: &str) -> String {
    let mut out: String = text.chars().take(80).collect();
    if out.len() < text.len() {
        out.push('…');
    }
    out
}

/// A number as TOML writes it: six decimals (a micrometre), no trailing zeros, no "-0".
fn number(v: f64) -> String {
    let rounded = (v * 1e6).round() / 1e6;
    let rounded = if rounded == 0.0 { 0.0 } else { rounded };
    let mut s = format!("{rounded:.6}");
    while s.ends_with('0') {
        s.pop();
    }
    if s.ends_with('.') {
        s.push('0');
    }
    s
}

/// The comment lines that say where the walls came from, how they were converted and what
/// was repaired or skipped.
pub fn provenance(import: &Import, source: &Path) -> String {
    let mut out = format!(
        "# Walls imported from {} ({}) by `omnicave config import`, in CAVE space: metres, +y up.\n\
         # Converted from {}.\n",
        source.display(),
        import.format.name(),
        import.conversion
    );
    for note in &import.notes {
        out.push_str(&format!("# Note: {}\n", note.replace('\n', " ")));
    }
    out
}

/// The walls as `[[wall]]` tables (`resolution` where the file gives none), after the
/// [`provenance`] comments.
pub fn walls_toml(import: &Import, resolution: [u32; 2], source: &Path) -> String {
    let mut out = provenance(import, source);
    for w in &import.walls {
        let p = |v: DVec3| format!("[{}, {}, {}]", number(v.x), number(v.y), number(v.z));
        let [rw, rh] = w.resolution.unwrap_or(resolution);
        out.push_str(&format!(
            "\n[[wall]]\nname = \"{}\"\nlower_left = {}\nlower_right = {}\nupper_left = {}\n\
             resolution = [{rw}, {rh}]\n",
            w.name,
            p(w.lower_left),
            p(w.lower_right),
            p(w.upper_left)
        ));
    }
    out
}

/// The keys that place a wall (replaced on import).
const GEOMETRY_KEYS: [&str; 10] = [
    "lower_left",
    "lower_right",
    "upper_left",
    "centre",
    "yaw_pitch_roll_degrees",
    "origin",
    "horizontal_axis",
    "vertical_axis",
    "size",
    "resolution",
];

/// `base` (a config's text) with its `[[wall]]` tables replaced by the imported walls (its
/// comments and every other setting kept), the [`provenance`] comments above the first.
pub fn replace_walls(
    base: &str,
    import: &Import,
    resolution: [u32; 2],
    source: &Path,
) -> Result<String, String> {
    let walls = &import.walls;
    let mut doc: toml_edit::DocumentMut = base.parse().map_err(|e| format!("{e}"))?;
    // The base's walls by name (any case): a wall of the same name keeps its monitor, window
    // and output settings.
    let base_walls: Vec<toml_edit::Table> = doc
        .get("wall")
        .and_then(toml_edit::Item::as_array_of_tables)
        .map(|a| a.iter().cloned().collect())
        .unwrap_or_default();
    let mut tables = toml_edit::ArrayOfTables::new();
    for w in walls {
        let mut t = base_walls
            .iter()
            .find(|b| {
                b.get("name")
                    .and_then(toml_edit::Item::as_str)
                    .is_some_and(|n| n.eq_ignore_ascii_case(&w.name))
            })
            .cloned()
            .unwrap_or_default();
        for geometry in GEOMETRY_KEYS {
            t.remove(geometry);
        }
        let p = |v: DVec3| {
            let mut a = toml_edit::Array::new();
            for c in [v.x, v.y, v.z] {
                a.push(number(c).parse::<f64>().unwrap_or(c));
            }
            toml_edit::value(a)
        };
        t["name"] = toml_edit::value(w.name.clone());
        t["lower_left"] = p(w.lower_left);
        t["lower_right"] = p(w.lower_right);
        t["upper_left"] = p(w.upper_left);
        let [rw, rh] = w.resolution.unwrap_or(resolution);
        let mut r = toml_edit::Array::new();
        r.push(i64::from(rw));
        r.push(i64::from(rh));
        t["resolution"] = toml_edit::value(r);
        tables.push(t);
    }
    // The walls are in CAVE metres, y up, whatever the base said.
    if let Some(cave) = doc.get_mut("cave").and_then(toml_edit::Item::as_table_mut) {
        cave.remove("wall_units");
        cave.remove("wall_up_axis");
    }
    if let Some(first) = tables.get_mut(0) {
        first
            .decor_mut()
            .set_prefix(format!("\n{}", provenance(import, source)));
    }
    doc["wall"] = toml_edit::Item::ArrayOfTables(tables);
    Ok(doc.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_exact_to_a_micrometre() {
        assert_eq!(number(-1.65), "-1.65");
        assert_eq!(number(2.9000000000000004), "2.9");
        assert_eq!(number(-1e-17), "0.0");
        assert_eq!(number(3.0), "3.0");
    }

    #[test]
    fn names_are_made_acceptable() {
        assert_eq!(clean_name("screen front", "w"), "screen_front");
        assert_eq!(clean_name("  ", "wall3"), "wall3");
        let walls = ["a", "a", "a"]
            .map(|n| ImportedWall {
                name: n.into(),
                lower_left: DVec3::ZERO,
                lower_right: DVec3::X,
                upper_left: DVec3::Y,
                resolution: None,
            })
            .to_vec();
        let names: Vec<_> = unique_names(walls.clone())
            .into_iter()
            .map(|w| w.name)
            .collect();
        assert_eq!(names, ["a", "a_1", "a_2"]);
        let mut clash = walls;
        clash[0].name = "a_2".into();
        let names: Vec<_> = unique_names(clash).into_iter().map(|w| w.name).collect();
        assert_eq!(names, ["a_2", "a", "a_3"]);
        assert_eq!(excerpt(&"x".repeat(100)).chars().count(), 81);
    }
}
