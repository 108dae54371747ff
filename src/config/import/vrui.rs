//! Vrui's configuration files (`Vrui.cfg`): `section NAME` … `endsection` blocks of `tag value`
//! lines, one root section per installation under `section Vrui`. A screen is a section with
//! `origin` (its lower-left corner), `horizontalAxis`, `verticalAxis`, `width` and `height`, in
//! the root's units (`meterScale` or `inchScale`: the length of a metre or an inch in file
//! units; inches by default) and axes (`upDirection`, `forwardDirection`; z up, y forward by
//! default). Read as Vrui reads it: `#` starts a comment anywhere, a trailing `\` joins lines,
//! a section opened again is merged, a repeated tag keeps its last value, and a number is read
//! up to the first character that is not part of one (`height 4.5.0` is 4.5, with a note).
//! Screens with `deviceMounted true` move with a tracked device: reported and skipped.

use std::collections::HashMap;

use glam::{DQuat, DVec3};

use super::{ImportedWall, Reading, clean_name, excerpt, finite};
use crate::cave::placement::corners_from_axes;

/// Budget: how deep sections nest (the file itself is at most 4 MiB).
const MAX_DEPTH: usize = 64;

/// One section: its name, parent, tags (value, line) and subsections in file order.
#[derive(Debug, Default)]
struct Section {
    name: String,
    parent: Option<usize>,
    line: usize,
    tags: HashMap<String, (String, usize)>,
    children: Vec<usize>,
}

/// The section tree; section 0 is the file itself.
#[derive(Debug)]
struct Tree {
    sections: Vec<Section>,
}

impl Tree {
    fn parse(text: &str) -> Result<Self, String> {
        let mut sections = vec![Section::default()];
        // (parent, name) → section: a section opened again is found in constant time.
        let mut by_name: HashMap<(usize, String), usize> = HashMap::new();
        let mut open = vec![0usize];
        let mut pending = String::new();
        let mut pending_line = 0;
        for (i, raw) in text.lines().enumerate() {
            let uncommented = raw.split('#').next().unwrap_or("");
            if pending.is_empty() {
                pending_line = i + 1;
            }
            // A trailing backslash joins the next line.
            if let Some(joined) = uncommented.trim_end().strip_suffix('\\') {
                pending.push_str(joined);
                pending.push(' ');
                continue;
            }
            pending.push_str(uncommented);
            let line = std::mem::take(&mut pending);
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            let (word, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
            let rest = rest.trim();
            let current = *open.last().unwrap_or(&0);
            if word.eq_ignore_ascii_case("section") {
                let name = rest.trim_matches('"').to_owned();
                if name.is_empty() {
                    return Err(format!("line {pending_line}: 'section' has no name"));
                }
                if open.len() > MAX_DEPTH {
                    return Err(format!(
                        "line {pending_line}: sections nest deeper than {MAX_DEPTH}"
                    ));
                }
                // A section opened again is the same section.
                let index = *by_name.entry((current, name.clone())).or_insert_with(|| {
                    sections.push(Section {
                        name,
                        parent: Some(current),
                        line: pending_line,
                        ..Section::default()
                    });
                    let index = sections.len() - 1;
                    sections[current].children.push(index);
                    index
                });
                open.push(index);
            } else if word.eq_ignore_ascii_case("endsection") {
                if open.len() == 1 {
                    return Err(format!(
                        "line {pending_line}: 'endsection' with no section open"
                    ));
                }
                open.pop();
            } else if rest.is_empty() {
                // A tag without a value removes it.
                sections[current].tags.remove(word);
            } else {
                let value = rest.strip_prefix("+=").map_or(rest, str::trim);
                sections[current]
                    .tags
                    .insert(word.to_owned(), (value.to_owned(), pending_line));
            }
        }
        if open.len() > 1 {
            let s = &sections[open[open.len() - 1]];
            return Err(format!(
                "section {} (line {}) has no endsection",
                s.name, s.line
            ));
        }
        Ok(Self { sections })
    }

    /// A tag of section `s` or the nearest enclosing section that has it.
    fn inherited(&self, mut s: usize, tag: &str) -> Option<&(String, usize)> {
        loop {
            if let Some(v) = self.sections[s].tags.get(tag) {
                return Some(v);
            }
            s = self.sections[s].parent?;
        }
    }

    /// Whether a section describes a screen.
    fn is_screen(&self, s: usize) -> bool {
        let tags = &self.sections[s].tags;
        [
            "origin",
            "horizontalAxis",
            "verticalAxis",
            "width",
            "height",
        ]
        .iter()
        .all(|t| tags.contains_key(*t))
            || tags.contains_key("transform") && tags.contains_key("width")
    }

    /// Every screen section under `s`, in file order.
    fn screens_under(&self, s: usize, out: &mut Vec<usize>) {
        for &c in &self.sections[s].children {
            if self.is_screen(c) {
                out.push(c);
            }
            self.screens_under(c, out);
        }
    }

    /// The sections that hold screens: the children of `section Vrui` (or of the file when
    /// there is none).
    fn roots(&self) -> Vec<usize> {
        let top = self.sections[0]
            .children
            .iter()
            .copied()
            .find(|&c| self.sections[c].name == "Vrui");
        match top {
            Some(vrui) => self.sections[vrui].children.clone(),
            None => self.sections[0].children.clone(),
        }
    }
}

/// A number as Vrui's parser reads one: the longest prefix that is a number; the rest is
/// ignored (`4.5.0` is 4.5).
fn number_prefix(text: &str) -> Option<(f64, bool)> {
    let t = text.trim();
    let b = t.as_bytes();
    let mut end = 0;
    if end < b.len() && (b[end] == b'+' || b[end] == b'-') {
        end += 1;
    }
    let digits = |mut i: usize| {
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        i
    };
    let int_end = digits(end);
    end = int_end;
    if end < b.len() && b[end] == b'.' {
        end = digits(end + 1);
    }
    if end < b.len() && (b[end] == b'e' || b[end] == b'E') {
        let mut e = end + 1;
        if e < b.len() && (b[e] == b'+' || b[e] == b'-') {
            e += 1;
        }
        let e_end = digits(e);
        if e_end > e {
            end = e_end;
        }
    }
    let value = t[..end].parse::<f64>().ok().filter(|v| v.is_finite())?;
    Some((value, end < t.len()))
}

/// `(x, y, z)`: each element a whole number (Vrui refuses `(4.5.0, 1, 2)`).
fn vector(text: &str) -> Option<DVec3> {
    let inner = text.trim().strip_prefix('(')?.strip_suffix(')')?;
    let v: Vec<f64> = inner.split(',').map(finite).collect::<Option<_>>()?;
    (v.len() == 3).then(|| DVec3::new(v[0], v[1], v[2]))
}

/// A root section's frame: metres per file unit and the CAVE axes in file coordinates.
struct Frame {
    metres: f64,
    right: DVec3,
    up: DVec3,
    back: DVec3,
}

impl Frame {
    fn to_cave(&self, p: DVec3) -> DVec3 {
        DVec3::new(p.dot(self.right), p.dot(self.up), p.dot(self.back)) * self.metres
    }
}

/// The screens of a Vrui config's root section (`--section`, or the only one with fixed
/// screens).
pub fn walls(text: &str, reading: &mut Reading<'_>) -> Result<Vec<ImportedWall>, String> {
    let tree = Tree::parse(text)?;
    let roots = tree.roots();
    let fixed = |root: usize| -> Vec<usize> {
        let mut screens = Vec::new();
        if tree.is_screen(root) {
            screens.push(root);
        }
        tree.screens_under(root, &mut screens);
        screens
            .into_iter()
            .filter(|&s| {
                !tree.sections[s]
                    .tags
                    .get("deviceMounted")
                    .is_some_and(|(v, _)| v.trim().eq_ignore_ascii_case("true"))
            })
            .collect()
    };
    let root = match reading.section {
        Some(name) => *roots
            .iter()
            .find(|&&r| tree.sections[r].name == name)
            .ok_or_else(|| {
                format!(
                    "no root section '{name}'; the root sections are {}",
                    list_roots(&tree, &roots, &fixed)
                )
            })?,
        None => {
            let with_screens: Vec<usize> = roots
                .iter()
                .copied()
                .filter(|&r| !fixed(r).is_empty())
                .collect();
            match with_screens[..] {
                [one] => one,
                [] => return Ok(Vec::new()),
                _ => {
                    return Err(format!(
                        "several root sections have screens: {}; give --section NAME (Vrui \
                         picks one by VRUI_ROOTSECTION or the host name)",
                        list_roots(&tree, &with_screens, &fixed)
                    ));
                }
            }
        }
    };
    let frame = frame(&tree, root, reading)?;
    let mut out = Vec::new();
    let mut all = Vec::new();
    if tree.is_screen(root) {
        all.push(root);
    }
    tree.screens_under(root, &mut all);
    for s in all {
        let section = &tree.sections[s];
        let at = format!("section {} (line {})", section.name, section.line);
        let tag = |name: &str| section.tags.get(name);
        if tag("deviceMounted").is_some_and(|(v, _)| v.trim().eq_ignore_ascii_case("true")) {
            reading.notes.push(format!(
                "{at} skipped, not a wall: deviceMounted true (it moves with a tracked device)"
            ));
            continue;
        }
        if tag("transform").is_some() || tag("preTransform").is_some() {
            reading.notes.push(format!(
                "{at} skipped: a screen placed by 'transform' or 'preTransform' is not read; \
                 give it origin, horizontalAxis and verticalAxis"
            ));
            continue;
        }
        let vec = |name: &str| -> Result<DVec3, String> {
            let (v, line) = tag(name).ok_or(format!("{at} has no {name}"))?;
            vector(v)
                .ok_or_else(|| format!("line {line}: {name} '{}' is not (x, y, z)", excerpt(v)))
        };
        let mut scalar = |name: &str| -> Result<f64, String> {
            let (v, line) = tag(name).ok_or(format!("{at} has no {name}"))?;
            let (value, trailing) = number_prefix(v)
                .ok_or_else(|| format!("line {line}: {name} '{}' is not a number", excerpt(v)))?;
            if trailing {
                reading.notes.push(format!(
                    "line {line}: {name} '{}' read as {value}, as Vrui reads it",
                    excerpt(v)
                ));
            }
            Ok(value)
        };
        let size = [scalar("width")?, scalar("height")?];
        if !size.iter().all(|v| *v > 0.0) {
            return Err(format!("{at}: width and height must be positive"));
        }
        let (mut origin, mut h, mut v) =
            (vec("origin")?, vec("horizontalAxis")?, vec("verticalAxis")?);
        // An optional rotation of the screen about a centre.
        if let Some((angle, _)) = tag("rotateAngle") {
            let degrees = number_prefix(angle).map_or(0.0, |(a, _)| a);
            let centre = vec("rotateCenter").unwrap_or(DVec3::ZERO);
            // Vrui's default axis is x.
            let axis = vec("rotateAxis")
                .ok()
                .and_then(DVec3::try_normalize)
                .unwrap_or(DVec3::X);
            let q = DQuat::from_axis_angle(axis, degrees.to_radians());
            origin = centre + q * (origin - centre);
            h = q * h;
            v = q * v;
        }
        // Vrui builds the screen's frame from the horizontal axis and the vertical one made
        // square to it (Rotation::fromBaseVectors): measured axes a little off square still give
        // a rectangle.
        let v = v - v.dot(h) / h.length_squared().max(f64::MIN_POSITIVE) * h;
        let corners = corners_from_axes(
            frame.to_cave(origin),
            frame.to_cave(h),
            frame.to_cave(v),
            size.map(|x| x * frame.metres),
        )
        .ok_or(format!("{at}: an axis has no length"))?;
        out.push(ImportedWall {
            name: clean_name(&section.name, &format!("screen{}", out.len())),
            lower_left: corners[0],
            lower_right: corners[1],
            upper_left: corners[2],
            resolution: None,
        });
    }
    Ok(out)
}

fn list_roots(tree: &Tree, roots: &[usize], fixed: &dyn Fn(usize) -> Vec<usize>) -> String {
    roots
        .iter()
        .map(|&r| {
            format!(
                "{} ({} fixed screens)",
                tree.sections[r].name,
                fixed(r).len()
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The root section's units and axes, stated in the conversion.
fn frame(tree: &Tree, root: usize, reading: &mut Reading<'_>) -> Result<Frame, String> {
    // Vrui 8 keeps `unit`, `up` and `forward` in the root's `section Environment`; older files
    // give `meterScale` or `inchScale`, `upDirection`, `forwardDirection` in the root.
    let environment = tree.sections[root]
        .children
        .iter()
        .copied()
        .find(|&c| tree.sections[c].name == "Environment");
    let tag = |new: &str, old: &str| {
        environment
            .and_then(|e| tree.sections[e].tags.get(new))
            .or_else(|| tree.inherited(root, old))
    };
    let scale = |name: &str| -> Result<Option<f64>, String> {
        tree.inherited(root, name)
            .map(|(v, line)| {
                number_prefix(v)
                    .map(|(x, _)| x)
                    .filter(|x| *x > 0.0)
                    .ok_or_else(|| {
                        format!(
                            "line {line}: {name} '{}' is not a positive number",
                            excerpt(v)
                        )
                    })
            })
            .transpose()
    };
    let unit = environment
        .and_then(|e| tree.sections[e].tags.get("unit"))
        .map(|(v, line)| {
            environment_unit(v).ok_or_else(|| {
                format!(
                    "line {line}: unit '{}' is not a unit Vrui names (Inch, Foot, Meter, …)",
                    excerpt(v)
                )
            })
        })
        .transpose()?;
    let (metres, unit_said) = match (
        reading.unit,
        unit,
        scale("meterScale")?,
        scale("inchScale")?,
    ) {
        (Some(unit), ..) => (unit.metres(), format!("{} (--units)", unit.name())),
        (None, Some((m, said)), ..) => (m, format!("unit {said}: 1 unit = {m} m")),
        (None, None, Some(m), _) => (1.0 / m, format!("meterScale {m}: 1 unit = {} m", 1.0 / m)),
        (None, None, None, Some(i)) => (
            0.0254 / i,
            format!("inchScale {i}: 1 unit = {} m", 0.0254 / i),
        ),
        (None, None, None, None) => (0.0254, "inches (Vrui's default)".to_owned()),
    };
    let direction = |new: &str, old: &str, default: DVec3| -> Result<DVec3, String> {
        match tag(new, old) {
            None => Ok(default),
            Some((v, line)) => vector(v)
                .and_then(DVec3::try_normalize)
                .ok_or_else(|| format!("line {line}: {old} '{}' is not a direction", excerpt(v))),
        }
    };
    let up = direction("up", "upDirection", DVec3::Z)?;
    let forward = direction("forward", "forwardDirection", DVec3::Y)?;
    // Forward made square to up; right = forward × up; CAVE's +z (back) = −forward.
    let forward = (forward - forward.dot(up) * up)
        .try_normalize()
        .ok_or("forwardDirection is along upDirection")?;
    let right = forward.cross(up);
    reading.conversion = format!(
        "Vrui's frame (right-handed; up {up}, forward {forward}) in {unit_said}: CAVE x = \
         {right}, CAVE y = up, CAVE z = -forward; the origin kept"
    );
    Ok(Frame {
        metres,
        right,
        up,
        back: -forward,
    })
}

/// Vrui 8's `unit (Name)` or `unit (Name, factor)`: metres per file unit (the factor times the
/// named unit), and the unit as written.
fn environment_unit(text: &str) -> Option<(f64, String)> {
    let inner = text.trim().strip_prefix('(')?.strip_suffix(')')?;
    let mut parts = inner.split(',').map(str::trim);
    let name = parts.next()?;
    let factor = match parts.next() {
        Some(f) => finite(f).filter(|f| *f > 0.0)?,
        None => 1.0,
    };
    let metres = match name.to_ascii_lowercase().as_str() {
        "meter" | "metre" => 1.0,
        "centimeter" | "centimetre" => 0.01,
        "millimeter" | "millimetre" => 0.001,
        "kilometer" | "kilometre" => 1000.0,
        "inch" => 0.0254,
        "foot" => 0.3048,
        "yard" => 0.9144,
        "mile" => 1609.344,
        _ => return None,
    };
    Some((metres * factor, excerpt(inner)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_as_vrui_reads_them() {
        assert_eq!(number_prefix("4.5.0"), Some((4.5, true)));
        assert_eq!(number_prefix(" -5.53578e-06 "), Some((-5.53578e-06, false)));
        assert_eq!(number_prefix("+2"), Some((2.0, false)));
        assert_eq!(number_prefix("abc"), None);
        assert_eq!(
            vector("(4.19786 , 0.233694, -5.53578e-06)"),
            Some(DVec3::new(4.19786, 0.233694, -5.53578e-06))
        );
        assert_eq!(vector("(4.5.0, 1, 2)"), None);
    }

    #[test]
    fn sections_merge_and_tags_keep_the_last_value() {
        let tree = Tree::parse(
            "section Vrui\n section \"a b\"\n  width 1 # comment\n width 2\n endsection\n \
             section a b\n  height 3\\\n.5\n endsection\nendsection\n",
        )
        .unwrap();
        let ab = tree.roots()[0];
        assert_eq!(tree.sections[ab].name, "a b");
        assert_eq!(tree.sections[ab].tags["width"].0, "2");
        assert_eq!(tree.sections[ab].tags["height"].0, "3 .5");
        assert!(Tree::parse("endsection\n").unwrap_err().contains("line 1"));
        assert!(
            Tree::parse("section x\n")
                .unwrap_err()
                .contains("no endsection")
        );
    }
}
