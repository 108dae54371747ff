//! MinVR's display corners. MinVR 2's XML (`.minvr`): every element with `TopLeft`,
//! `BottomLeft` and `BottomRight` children (`-4,4,4`, a float array; `TopRight` checked), named
//! after the element, its pixels from the `Width` and `Height` in it or the nearest enclosing
//! element (MinVR looks names up outwards). MinVR 1's text (`.vrsetup`): `WindowN_ViewportM_TopLeft
//! (x, y, z)`, `…_BotLeft`, `…_BotRight`, `…_Width`, `…_Height`. Both in feet by MinVR's
//! documentation ("from the centre of the display or CAVE"), y up, right-handed: CAVE space
//! scaled. Comments with `--` inside (`<!---- … ---->`), which MinVR's own XML reader accepts,
//! are read too.

use std::collections::HashMap;

use glam::DVec3;

use super::calvr::{parse_xml, strict_xml};
use super::lines::LineIndex;
use super::{ImportedWall, Reading, clean_name, excerpt, finite};
use crate::cave::placement::LengthUnit;

/// How far a tile's fourth corner may be from the rectangle the other three make, metres,
/// before it is said (omnicave walls are rectangles, and the fourth corner follows).
const TOP_RIGHT_TOLERANCE_M: f64 = 1e-3;

/// Whether lower-cased text looks like MinVR 1's `.vrsetup`.
pub(super) fn is_vrsetup_text(lower: &str) -> bool {
    lower.contains("_viewport") && lower.contains("_botleft")
}

/// "-4, 4,4" or "(-4, 4, 4)" as three numbers (MinVR splits on commas; MinVR 1 takes any one
/// character between numbers in parentheses).
fn three(text: &str) -> Option<DVec3> {
    let inner = text.trim().trim_start_matches('(').trim_end_matches(')');
    let v: Vec<f64> = inner.split(',').map(finite).collect::<Option<_>>()?;
    (v.len() == 3).then(|| DVec3::new(v[0], v[1], v[2]))
}

/// The walls of a MinVR file (either form).
pub fn walls(text: &str, reading: &mut Reading<'_>) -> Result<Vec<ImportedWall>, String> {
    let unit = reading.unit.unwrap_or(LengthUnit::Foot);
    reading.conversion = format!(
        "MinVR's frame (y up, right-handed, as CAVE space) in {} (× {}){}",
        unit.name(),
        unit.metres(),
        if reading.unit.is_none() {
            ": MinVR's documented unit; give --units if the file is in another"
        } else {
            ""
        }
    );
    let walls =
        if text.to_ascii_lowercase().contains("<minvr") || text.trim_start().starts_with('<') {
            xml_walls(text, unit.metres(), reading)?
        } else {
            vrsetup_walls(text, unit.metres(), reading)?
        };
    Ok(walls)
}

/// A tile by its corners: lower left, lower right, upper left; the upper right checked.
fn tile(
    name: String,
    [top_left, top_right, bottom_left, bottom_right]: [Option<DVec3>; 4],
    metres: f64,
    resolution: Option<[u32; 2]>,
    at: &str,
    reading: &mut Reading<'_>,
) -> Option<ImportedWall> {
    let (Some(tl), Some(bl), Some(br)) = (top_left, bottom_left, bottom_right) else {
        return None;
    };
    if let Some(tr) = top_right {
        let off = (tr - (tl + br - bl)).length() * metres;
        if off > TOP_RIGHT_TOLERANCE_M {
            reading.notes.push(format!(
                "{at}: {name}'s TopRight is {:.1} mm off the rectangle of its other corners; the \
                 wall is that rectangle",
                off * 1000.0
            ));
        }
    }
    Some(ImportedWall {
        name,
        lower_left: bl * metres,
        lower_right: br * metres,
        upper_left: tl * metres,
        resolution,
    })
}

fn xml_walls(
    text: &str,
    metres: f64,
    reading: &mut Reading<'_>,
) -> Result<Vec<ImportedWall>, String> {
    let strict = strict_xml(text)?;
    let doc = parse_xml(&strict)?;
    let lines = LineIndex::new(&strict);
    let child_text = |node: roxmltree::Node<'_, '_>, name: &str| {
        node.children()
            .find(|c| c.has_tag_name(name))
            .map(|c| c.text().unwrap_or("").to_owned())
    };
    // Each element's own Width and Height children, found in one pass.
    let mut own: HashMap<(roxmltree::NodeId, &str), u32> = HashMap::new();
    for node in doc.descendants().filter(roxmltree::Node::is_element) {
        let name = node.tag_name().name();
        if let ("Width" | "Height", Some(parent)) = (name, node.parent()) {
            let pixels = node
                .text()
                .and_then(|t| t.trim().parse::<f64>().ok())
                .filter(|v| (1.0..=65535.0).contains(v));
            if let Some(v) = pixels {
                own.insert(
                    (
                        parent.id(),
                        if name == "Width" { "Width" } else { "Height" },
                    ),
                    v as u32,
                );
            }
        }
    }
    // A pixel count looked up outwards from a node, as MinVR looks names up.
    let scoped = |node: roxmltree::Node<'_, '_>, name: &str| -> Option<u32> {
        node.ancestors()
            .find_map(|a| own.get(&(a.id(), name)).copied())
    };
    let mut out = Vec::new();
    for node in doc.descendants().filter(roxmltree::Node::is_element) {
        if child_text(node, "BottomLeft").is_none() {
            continue;
        }
        let at = format!("line {}", lines.line(node.range().start));
        let corners = ["TopLeft", "TopRight", "BottomLeft", "BottomRight"]
            .map(|c| child_text(node, c).map(|t| three(&t).ok_or((c, t))));
        let mut parsed = [None; 4];
        for (slot, corner) in parsed.iter_mut().zip(corners) {
            match corner {
                None => {}
                Some(Ok(v)) => *slot = Some(v),
                Some(Err((c, t))) => {
                    return Err(format!(
                        "{at}: <{}> {c} '{}' is not three numbers",
                        node.tag_name().name(),
                        excerpt(t.trim())
                    ));
                }
            }
        }
        let resolution = scoped(node, "Width")
            .zip(scoped(node, "Height"))
            .map(|(w, h)| [w, h]);
        let name = clean_name(node.tag_name().name(), &format!("tile{}", out.len()));
        match tile(name, parsed, metres, resolution, &at, reading) {
            Some(w) => out.push(w),
            None => reading.notes.push(format!(
                "{at}: <{}> has a BottomLeft but not TopLeft and BottomRight: skipped",
                node.tag_name().name()
            )),
        }
    }
    Ok(out)
}

fn vrsetup_walls(
    text: &str,
    metres: f64,
    reading: &mut Reading<'_>,
) -> Result<Vec<ImportedWall>, String> {
    // name → (value, line); a repeated name keeps the last, as MinVR 1 does.
    let mut values: HashMap<String, (&str, usize)> = HashMap::new();
    let mut viewports: Vec<String> = Vec::new();
    let mut seen: std::collections::HashSet<String> = std::collections::HashSet::new();
    for (i, line) in text.lines().enumerate() {
        // `#` is a comment only as a line's first character.
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let line_text = line.trim();
        let (name, value) = line_text
            .split_once(char::is_whitespace)
            .unwrap_or((line_text, ""));
        let lower = name.to_ascii_lowercase();
        if let Some(prefix) = lower.strip_suffix("_botleft")
            && seen.insert(prefix.to_owned())
        {
            viewports.push(prefix.to_owned());
        }
        values.insert(lower, (value.trim(), i + 1));
    }
    let mut out = Vec::new();
    for prefix in viewports {
        let corner = |c: &str| -> Result<Option<DVec3>, String> {
            match values.get(&format!("{prefix}_{c}")) {
                None => Ok(None),
                Some((text, line)) => three(text).map(Some).ok_or_else(|| {
                    format!(
                        "line {line}: {}_{c} '{}' is not (x, y, z)",
                        excerpt(&prefix),
                        excerpt(text)
                    )
                }),
            }
        };
        let corners = [
            corner("topleft")?,
            corner("topright")?,
            corner("botleft")?,
            corner("botright")?,
        ];
        let pixels = |c: &str| {
            values
                .get(&format!("{prefix}_{c}"))
                .and_then(|(t, _)| t.parse::<f64>().ok())
                .filter(|v| (1.0..=65535.0).contains(v))
                .map(|v| v as u32)
        };
        let resolution = pixels("width").zip(pixels("height")).map(|(w, h)| [w, h]);
        let line = values
            .get(&format!("{prefix}_botleft"))
            .map_or(0, |(_, l)| *l);
        let at = format!("line {line}");
        let name = clean_name(&prefix, &format!("tile{}", out.len()));
        match tile(name, corners, metres, resolution, &at, reading) {
            Some(w) => out.push(w),
            None => reading.notes.push(format!(
                "{at}: {prefix} has a BotLeft but not TopLeft and BotRight: skipped"
            )),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_as_both_forms_write_them() {
        assert_eq!(three("-4, 4,4"), Some(DVec3::new(-4.0, 4.0, 4.0)));
        assert_eq!(three(" (4,-4, -4) "), Some(DVec3::new(4.0, -4.0, -4.0)));
        assert_eq!(three("(1, 2)"), None);
        assert_eq!(three("1, nan, 2"), None);
    }
}
