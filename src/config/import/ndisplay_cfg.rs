//! Unreal nDisplay's legacy text format (`.cfg`, UE 4.20–4.26, read by UE 4.27's importer):
//! one component per line,
//! `[screen] id="scr_front" loc="X=1.5,Y=0,Z=1" rot="P=0,Y=0,R=0" size="X=3,Y=2.25"
//! parent="cave_origin"`, with `[scene_node]`, `[camera]`, `[viewport]`, `[projection]` and
//! `[window]` lines around it. Lengths are metres in Unreal's frame (x forward, y right, z up).
//! Read as UE 4.27's importer reads it: ids and references compared ignoring case, an id
//! defined twice keeps its last line (with a note naming both; UE 4.22–4.26 took the first); a
//! number that is not one (`X=0.40.0`) is refused naming the line and the field.

use std::collections::HashMap;

use glam::DVec3;

use super::unreal::{Component, Graph, MAX_SCREENS, Placer, conversion, wall};
use super::{ImportedWall, Reading, clean_name, excerpt, finite};
use crate::cave::placement::LengthUnit;

/// Budget: lines with an id (a 4 MiB file holds about 50 000).
const MAX_COMPONENTS: usize = 100_000;

/// One `[kind] key=value …` line.
#[derive(Debug)]
struct Line<'a> {
    number: usize,
    kind: String,
    values: HashMap<String, &'a str>,
}

impl<'a> Line<'a> {
    fn get(&self, key: &str) -> Option<&'a str> {
        self.values.get(key).copied()
    }

    fn id(&self) -> Option<&'a str> {
        self.get("id").filter(|id| !id.is_empty())
    }

    /// `key="X=1,Y=2,Z=3"` with `names` in order (`P`, `Y`, `R` for a rotation); missing
    /// components are 0 (as nDisplay's parser leaves them).
    fn vector<const N: usize>(&self, key: &str, names: [&str; N]) -> Result<[f64; N], String> {
        let mut out = [0.0; N];
        let Some(text) = self.get(key) else {
            return Ok(out);
        };
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (name, value) = part.split_once('=').ok_or_else(|| {
                format!(
                    "line {}: [{}] {key}=\"{}\": '{}' is not NAME=NUMBER",
                    self.number,
                    self.kind,
                    excerpt(text),
                    excerpt(part)
                )
            })?;
            let Some(i) = names
                .iter()
                .position(|n| n.eq_ignore_ascii_case(name.trim()))
            else {
                continue;
            };
            out[i] = finite(value).ok_or_else(|| {
                format!(
                    "line {}: [{}] {key} {}: '{}' is not a number",
                    self.number,
                    self.kind,
                    names[i],
                    excerpt(value.trim())
                )
            })?;
        }
        Ok(out)
    }

    /// A plain number (`width="1920"`), `None` where absent.
    fn number(&self, key: &str) -> Result<Option<f64>, String> {
        self.get(key)
            .map(|text| {
                finite(text).ok_or_else(|| {
                    format!(
                        "line {}: [{}] {key}=\"{}\" is not a number",
                        self.number,
                        self.kind,
                        excerpt(text)
                    )
                })
            })
            .transpose()
    }
}

/// Splits `[kind] a=1 b="two words" c=X=1,Y=2` into its kind and values (keys lower-cased).
fn parse_line(text: &str, number: usize) -> Result<Option<Line<'_>>, String> {
    let t = text.trim();
    if t.is_empty() || t.starts_with('#') || t.starts_with("//") || t.starts_with(';') {
        return Ok(None);
    }
    let Some(rest) = t.strip_prefix('[') else {
        return Err(format!(
            "line {number}: expected a '[kind]' line, found '{}'",
            t.chars().take(40).collect::<String>()
        ));
    };
    let (kind, mut rest) = rest
        .split_once(']')
        .ok_or(format!("line {number}: '[' has no closing ']'"))?;
    let mut values = HashMap::new();
    loop {
        rest = rest.trim_start();
        if rest.is_empty() || rest.starts_with('#') {
            break;
        }
        let (key, after) = rest
            .split_once('=')
            .ok_or_else(|| format!("line {number}: '{}' is not key=value", excerpt(rest)))?;
        let key = key.trim();
        if key.is_empty() || key.contains(char::is_whitespace) {
            return Err(format!("line {number}: '{}' is not a key", excerpt(key)));
        }
        let (value, next) = if let Some(quoted) = after.strip_prefix('"') {
            let end = quoted
                .find('"')
                .ok_or(format!("line {number}: {key}=\" has no closing '\"'"))?;
            (&quoted[..end], &quoted[end + 1..])
        } else {
            let end = after.find(char::is_whitespace).unwrap_or(after.len());
            (&after[..end], &after[end..])
        };
        values.insert(key.to_ascii_lowercase(), value);
        rest = next;
    }
    Ok(Some(Line {
        number,
        kind: kind.trim().to_ascii_lowercase(),
        values,
    }))
}

/// The screens of a legacy nDisplay config.
pub fn walls(text: &str, reading: &mut Reading<'_>) -> Result<Vec<ImportedWall>, String> {
    let unit = reading.unit.unwrap_or(LengthUnit::Metre);
    reading.conversion = conversion(unit.name(), unit.metres());
    // Each kind's lines by id (any case), the last definition kept (UE 4.27's maps keep the
    // last).
    let mut by_id: ById<'_> = HashMap::new();
    let mut order: Vec<(String, String)> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let Some(line) = parse_line(raw, i + 1)? else {
            continue;
        };
        let Some(id) = line.id() else {
            continue;
        };
        if by_id.len() >= MAX_COMPONENTS {
            return Err(format!("more than {MAX_COMPONENTS} components"));
        }
        let key = (line.kind.clone(), id.to_ascii_lowercase());
        if let Some(old) = by_id.get(&key) {
            reading.notes.push(format!(
                "[{}] id=\"{}\" is defined on line {} and again on line {}: line {} is used, \
                 as UE 4.27's nDisplay importer does",
                line.kind,
                excerpt(id),
                old.number,
                line.number,
                line.number
            ));
        } else {
            order.push(key.clone());
        }
        by_id.insert(key, line);
    }
    let mut graph = Graph::default();
    let mut screens = Vec::new();
    for key in &order {
        let line = &by_id[key];
        let (kind, id) = (key.0.as_str(), key.1.as_str());
        if !matches!(kind, "scene_node" | "screen" | "camera") {
            continue;
        }
        let [x, y, z] = line.vector("loc", ["X", "Y", "Z"])?;
        let rotation = line.vector("rot", ["P", "Y", "R"])?;
        let tracker = line.get("tracker_id").filter(|t| !t.is_empty());
        let follows = if kind == "camera" {
            Some(format!(
                "it is under the camera '{id}', which moves with the viewer"
            ))
        } else {
            tracker.map(|t| format!("it is under '{id}', which follows the tracker '{t}'"))
        };
        graph.components.insert(
            id.to_owned(),
            Component {
                parent: line.get("parent").map(str::to_ascii_lowercase),
                location: DVec3::new(x, y, z),
                rotation,
                scale: DVec3::ONE,
                follows,
                at: format!("line {}", line.number),
            },
        );
        if kind == "screen" {
            if screens.len() >= MAX_SCREENS {
                return Err(format!("more than {MAX_SCREENS} screens"));
            }
            screens.push(line);
        }
    }
    let cameras: Vec<&str> = order
        .iter()
        .filter(|(kind, _)| kind == "camera")
        .map(|(_, id)| id.as_str())
        .collect();
    let screen_ids: Vec<String> = screens
        .iter()
        .filter_map(|l| l.id())
        .map(str::to_ascii_lowercase)
        .collect();
    let screen_refs: Vec<&str> = screen_ids.iter().map(String::as_str).collect();
    graph.mark_viewer_nodes(&cameras, &screen_refs);
    let places = viewport_places(&by_id, &order)?;
    let mut placer = Placer::new(&graph);
    let mut out = Vec::new();
    for (line, key) in screens.into_iter().zip(&screen_ids) {
        let Some(id) = line.id() else { continue };
        let at = format!("line {}: [screen] id=\"{}\"", line.number, excerpt(id));
        if line.get("size").is_none() {
            return Err(format!("{at} has no size"));
        }
        let size = line.vector("size", ["X", "Y"])?;
        if !size.iter().all(|v| *v > 0.0) {
            return Err(format!("{at}: size must be positive"));
        }
        match placer
            .screen(key, size, unit.metres())
            .map_err(|e| format!("{at}: {e}"))?
        {
            Ok(corners) => {
                let place = places.get(key.as_str()).copied();
                out.push((
                    place.map(|p| p.0),
                    wall(
                        clean_name(id, &format!("screen{}", out.len())),
                        corners,
                        place.map(|p| p.1),
                    ),
                ));
            }
            Err(why) => reading
                .notes
                .push(format!("{at} skipped, not a wall: {why}")),
        }
    }
    // By their viewports' places on the windows (top, then left), as the JSON form is read;
    // screens without a viewport after, in file order.
    out.sort_by_key(|(place, _)| place.unwrap_or((u64::MAX, u64::MAX)));
    Ok(out.into_iter().map(|(_, w)| w).collect())
}

/// Lines by kind and lower-cased id.
type ById<'a> = HashMap<(String, String), Line<'a>>;

/// Screen id (lower case) → (its viewport's place on the windows: top, left; its pixels).
type Places = HashMap<String, ((u64, u64), [u32; 2])>;

/// Where each screen's viewport is and how many pixels it has: `[viewport] projection=` →
/// `[projection] screen=` (or the older `[viewport] screen=`), offset by the first `[window]`
/// that lists it; in file order, the first viewport of a screen kept.
fn viewport_places(by_id: &ById<'_>, order: &[(String, String)]) -> Result<Places, String> {
    let of_kind = |kind: &'static str| {
        order
            .iter()
            .filter(move |(k, _)| k == kind)
            .map(|key| (key.1.as_str(), &by_id[key]))
    };
    // Viewport id → the window's corner.
    let mut window_of: HashMap<String, (f64, f64)> = HashMap::new();
    for (_, w) in of_kind("window") {
        let corner = (
            w.number("winx")?.unwrap_or(0.0),
            w.number("winy")?.unwrap_or(0.0),
        );
        for vp in w.get("viewports").unwrap_or("").split(',') {
            window_of
                .entry(vp.trim().to_ascii_lowercase())
                .or_insert(corner);
        }
    }
    let mut out = HashMap::new();
    for (id, vp) in of_kind("viewport") {
        let screen = match vp.get("projection") {
            Some(p) => by_id
                .get(&("projection".to_owned(), p.to_ascii_lowercase()))
                .and_then(|p| p.get("screen")),
            None => vp.get("screen"),
        };
        let (Some(screen), Some(w), Some(h)) = (screen, vp.number("width")?, vp.number("height")?)
        else {
            continue;
        };
        if !((1.0..=65535.0).contains(&w) && (1.0..=65535.0).contains(&h)) {
            continue;
        }
        let (wx, wy) = window_of.get(id).copied().unwrap_or((0.0, 0.0));
        let x = wx + vp.number("x")?.unwrap_or(0.0);
        let y = wy + vp.number("y")?.unwrap_or(0.0);
        let place = (y.clamp(0.0, 1e9) as u64, x.clamp(0.0, 1e9) as u64);
        out.entry(screen.to_ascii_lowercase())
            .or_insert((place, [w as u32, h as u32]));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_split_as_ndisplay_splits_them() {
        let l = parse_line(
            r#"[screen] id="scr front" loc="X=1.5,Y=+0.25,Z=1" size=X=3,Y=2.25 parent=origin"#,
            7,
        )
        .unwrap()
        .unwrap();
        assert_eq!(l.kind, "screen");
        assert_eq!(l.id(), Some("scr front"));
        assert_eq!(l.vector("loc", ["X", "Y", "Z"]).unwrap(), [1.5, 0.25, 1.0]);
        assert_eq!(l.vector("size", ["X", "Y"]).unwrap(), [3.0, 2.25]);
        assert_eq!(l.get("parent"), Some("origin"));
        let bad = parse_line(r#"[screen] id=s loc="X=0.40.0,Y=0,Z=0""#, 9)
            .unwrap()
            .unwrap();
        let e = bad.vector("loc", ["X", "Y", "Z"]).unwrap_err();
        assert!(
            e.contains("line 9") && e.contains("loc X") && e.contains("0.40.0"),
            "{e}"
        );
        assert!(parse_line("# a comment", 1).unwrap().is_none());
        assert!(parse_line("id=x", 2).unwrap_err().contains("line 2"));
    }
}
