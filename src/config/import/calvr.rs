//! CalVR's XML screen list: every `<Screen originX= originY= originZ= h= p= r= width= height=
//! name= comment= />` (the screen's centre and heading, pitch, roll in degrees; CalVR's frame is
//! z-up with y to the front, in millimetres), with the pixel size of its `<Window>` where given.

use std::collections::HashMap;

use glam::DVec3;

use super::{ImportedWall, clean_name};
use crate::cave::placement::{FileFrame, LengthUnit, UpAxis, corners_from_centre, wall_rotation};

fn number(node: &roxmltree::Node<'_, '_>, name: &str, default: Option<f64>) -> Result<f64, String> {
    let line = node.document().text_pos_at(node.range().start).row;
    match node.attribute(name) {
        Some(text) => text
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or(format!(
                "line {line}: <{}> {name}=\"{text}\" is not a number",
                node.tag_name().name()
            )),
        None => default.ok_or(format!(
            "line {line}: <{}> has no {name}",
            node.tag_name().name()
        )),
    }
}

/// The screens of a CalVR config.
pub fn walls(text: &str, unit: LengthUnit) -> Result<Vec<ImportedWall>, String> {
    // No DTD (no entity expansion); a node budget well above any screen list.
    let options = roxmltree::ParsingOptions {
        allow_dtd: false,
        nodes_limit: 1_000_000,
        ..roxmltree::ParsingOptions::default()
    };
    let doc = roxmltree::Document::parse_with_options(text, options).map_err(|e| e.to_string())?;
    let frame = FileFrame {
        unit,
        up: UpAxis::Z,
    };
    // Windows by name (CalVR numbers them "0", "1", …) → their pixel size.
    let mut windows: HashMap<String, [u32; 2]> = HashMap::new();
    for w in doc.descendants().filter(|n| n.has_tag_name("Window")) {
        let (Some(name), Ok(width), Ok(height)) = (
            w.attribute("name"),
            number(&w, "width", None),
            number(&w, "height", None),
        ) else {
            continue;
        };
        if (1.0..=65535.0).contains(&width) && (1.0..=65535.0).contains(&height) {
            windows.insert(name.to_owned(), [width as u32, height as u32]);
        }
    }
    let mut out = Vec::new();
    for (i, s) in doc
        .descendants()
        .filter(|n| n.has_tag_name("Screen"))
        .enumerate()
    {
        let centre = DVec3::new(
            number(&s, "originX", Some(0.0))?,
            number(&s, "originY", Some(0.0))?,
            number(&s, "originZ", Some(0.0))?,
        );
        let size = [number(&s, "width", None)?, number(&s, "height", None)?];
        if !size.iter().all(|v| *v > 0.0) {
            let line = doc.text_pos_at(s.range().start).row;
            return Err(format!(
                "line {line}: <Screen> width and height must be positive"
            ));
        }
        let [h, p, r] = [
            number(&s, "h", Some(0.0))?,
            number(&s, "p", Some(0.0))?,
            number(&s, "r", Some(0.0))?,
        ];
        // CalVR turns a screen by roll about its y (forward), pitch about x, heading about z
        // (up); in CAVE axes z-up's forward +y is −z, so roll changes sign.
        let corners = corners_from_centre(
            frame.to_cave(centre),
            wall_rotation([h, p, -r]),
            size.map(|v| v * unit.metres()),
        );
        let label = s.attribute("comment").or(s.attribute("name")).unwrap_or("");
        out.push(ImportedWall {
            name: clean_name(label, &format!("screen{i}")),
            lower_left: corners[0],
            lower_right: corners[1],
            upper_left: corners[2],
            resolution: s.attribute("window").and_then(|w| windows.get(w).copied()),
        });
    }
    Ok(out)
}
