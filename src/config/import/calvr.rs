//! CalVR's XML screen list: every `<Screen originX= originY= originZ= h= p= r= width= height=
//! name= comment= />` (the screen's centre and heading, pitch, roll in degrees; CalVR's frame is
//! z-up with y to the front, in millimetres), with the pixel size of its `<Window>` where given.
//! Read as CalVR reads it: a fragment of several top-level elements (a screens file, after its
//! `<?xml?>` line), the files its `<INCLUDE>`s name, every `<LOCAL host=…>` block (the screens
//! of every host), and comments with `--` inside.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::lines::LineIndex;
use super::{ImportedWall, Reading, clean_name, excerpt, finite};
use crate::cave::placement::{FileFrame, LengthUnit, UpAxis, corners_from_centre, wall_rotation};
use crate::read_capped::{MAX_CONFIG_BYTES, read_capped_text};

/// Budget: how deep `<INCLUDE>`s nest, and how many files one import reads.
const MAX_INCLUDE_DEPTH: usize = 8;
const MAX_FILES: usize = 64;

/// The text as a strict XML parser takes it, on the same lines: comments emptied (CalVR's and
/// MinVR's parsers end a comment at the first `-->`, `--` inside included), an `<?xml?>`
/// declaration blanked, element names that XML refuses and CalVR's Mini-XML reads (`<0
/// value=…/>`, `<Raisa(slow) …/>`) made names (a `_` before a digit, `_` for other
/// characters), everything wrapped in one root element (a fragment has
/// several). A document type declaration is refused (no entity expansion). Linear in the text.
pub(super) fn strict_xml(text: &str) -> Result<String, String> {
    let text = text.trim_start_matches('\u{feff}');
    if text.contains("<!DOCTYPE") || text.contains("<!doctype") {
        return Err("a document type declaration (DTD, <!DOCTYPE …>) is refused".into());
    }
    let mut body = String::with_capacity(text.len() + 64);
    let mut rest = text;
    while let Some(start) = rest.find("<!--") {
        body.push_str(&rest[..start + 4]);
        let after = &rest[start + 4..];
        let end = after
            .find("-->")
            .ok_or("a comment '<!--' is not closed by '-->'")?;
        body.extend(
            after[..end]
                .chars()
                .map(|c| if c == '\n' { '\n' } else { ' ' }),
        );
        body.push_str("-->");
        rest = &after[end + 3..];
    }
    body.push_str(rest);
    let trimmed = body.trim_start();
    if trimmed.starts_with("<?xml")
        && let Some(end) = trimmed.find("?>")
    {
        let from = body.len() - trimmed.len();
        let blank: String = body[from..from + end + 2]
            .chars()
            .map(|c| if c == '\n' { '\n' } else { ' ' })
            .collect();
        body.replace_range(from..from + end + 2, &blank);
    }
    let mut out = String::with_capacity(body.len() + 64);
    out.push_str("<omnicave-import>");
    let mut chars = body.chars().peekable();
    while let Some(c) = chars.next() {
        out.push(c);
        if c != '<' {
            continue;
        }
        if chars.peek() == Some(&'/') {
            out.push('/');
            chars.next();
        }
        // A tag name as Mini-XML reads one (up to a space, '/' or '>'), made an XML name.
        if chars
            .peek()
            .is_some_and(|c| c.is_ascii_digit() || *c == '-' || *c == '.')
        {
            out.push('_');
        }
        if !chars
            .peek()
            .is_some_and(|c| c.is_alphanumeric() || *c == '_')
        {
            continue; // `<!--`, `<?`, `<!DOCTYPE`, or text
        }
        while let Some(&n) = chars.peek() {
            if n.is_whitespace() || n == '/' || n == '>' {
                break;
            }
            let ok = n.is_alphanumeric() || matches!(n, '_' | '-' | '.' | ':');
            out.push(if ok { n } else { '_' });
            chars.next();
        }
    }
    out.push_str("</omnicave-import>");
    Ok(out)
}

/// Parses [`strict_xml`] text: no DTD, a node budget well above any screen list.
pub(super) fn parse_xml(text: &str) -> Result<roxmltree::Document<'_>, String> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: false,
        nodes_limit: 1_000_000,
        ..roxmltree::ParsingOptions::default()
    };
    roxmltree::Document::parse_with_options(text, options).map_err(|e| e.to_string())
}

/// One file being read: where it is, its lines, and how messages name it.
struct Source<'a> {
    lines: LineIndex,
    /// "" for the file imported, "NAME.xml " for an included one.
    label: String,
    dir: &'a Path,
}

impl Source<'_> {
    fn at(&self, node: &roxmltree::Node<'_, '_>) -> String {
        format!("{}line {}", self.label, self.lines.line(node.range().start))
    }

    fn number(
        &self,
        node: &roxmltree::Node<'_, '_>,
        name: &str,
        default: Option<f64>,
    ) -> Result<f64, String> {
        let tag = node.tag_name().name();
        match node.attribute(name) {
            Some(text) => finite(text).ok_or_else(|| {
                format!(
                    "{}: <{tag}> {name}=\"{}\" is not a number",
                    self.at(node),
                    excerpt(text)
                )
            }),
            None => default.ok_or_else(|| format!("{}: <{tag}> has no {name}", self.at(node))),
        }
    }
}

/// What the files read so far share, and the walls found.
struct Includes {
    unit: LengthUnit,
    out: Vec<ImportedWall>,
    read: HashSet<PathBuf>,
    files: usize,
    /// Screens by host and name, and where each was read: CalVR takes the first (the main
    /// file's before an included one's).
    screens: HashMap<(String, String), String>,
}

/// The screens of a CalVR config.
pub fn walls(text: &str, reading: &mut Reading<'_>) -> Result<Vec<ImportedWall>, String> {
    let unit = reading.unit.unwrap_or(LengthUnit::Millimetre);
    let mut includes = Includes {
        read: HashSet::from([reading
            .path
            .canonicalize()
            .unwrap_or(reading.path.to_owned())]),
        files: 1,
        screens: HashMap::new(),
        unit,
        out: Vec::new(),
    };
    let dir = reading.path.parent().unwrap_or(Path::new("."));
    read(text, dir, String::new(), 0, reading, &mut includes)?;
    Ok(includes.out)
}

/// The `<LOCAL>` block each element is in (its start offset; 0 for none), found in one pass
/// down the document: windows and channels are looked up within it, as each host reads only
/// its own.
fn scopes(doc: &roxmltree::Document<'_>) -> HashMap<roxmltree::NodeId, usize> {
    let mut out: HashMap<roxmltree::NodeId, usize> = HashMap::new();
    for node in doc.descendants().filter(roxmltree::Node::is_element) {
        let scope = if node.has_tag_name("LOCAL") {
            node.range().start
        } else {
            node.parent()
                .and_then(|p| out.get(&p.id()).copied())
                .unwrap_or(0)
        };
        out.insert(node.id(), scope);
    }
    out
}

fn read(
    text: &str,
    dir: &Path,
    label: String,
    depth: usize,
    reading: &mut Reading<'_>,
    includes: &mut Includes,
) -> Result<(), String> {
    let unit = includes.unit;
    let strict = strict_xml(text).map_err(|e| format!("{label}{e}"))?;
    let doc = parse_xml(&strict).map_err(|e| format!("{label}{e}"))?;
    let source = Source {
        lines: LineIndex::new(&strict),
        label,
        dir,
    };
    let frame = FileFrame {
        unit,
        up: UpAxis::Z,
    };
    let scope = scopes(&doc);
    let scope_of = |n: &roxmltree::Node<'_, '_>| scope.get(&n.id()).copied().unwrap_or(0);
    // Windows and channels by host block and name (CalVR numbers them "0", "1", …) → their
    // pixel size; the first of a name kept.
    let mut windows: HashMap<(usize, &str), [u32; 2]> = HashMap::new();
    let mut channels: HashMap<(usize, &str), [u32; 2]> = HashMap::new();
    for w in doc
        .descendants()
        .filter(|n| n.has_tag_name("Window") || n.has_tag_name("Channel"))
    {
        let (Some(name), Ok(width), Ok(height)) = (
            w.attribute("name"),
            source.number(&w, "width", None),
            source.number(&w, "height", None),
        ) else {
            continue;
        };
        if (1.0..=65535.0).contains(&width) && (1.0..=65535.0).contains(&height) {
            let map = if w.has_tag_name("Window") {
                &mut windows
            } else {
                &mut channels
            };
            map.entry((scope_of(&w), name))
                .or_insert([width as u32, height as u32]);
        }
    }
    for node in doc.descendants().filter(roxmltree::Node::is_element) {
        // CalVR's Mini-XML compares names with case: `<INCLUDE>` only.
        if node.has_tag_name("INCLUDE") {
            include(&node, &source, depth, reading, includes)?;
            continue;
        }
        if !node.has_tag_name("Screen") {
            continue;
        }
        let s = node;
        // A screen of a host and name read before is that screen (CalVR looks names up in
        // the main file first).
        if let Some(name) = s.attribute("name") {
            let host = s
                .ancestors()
                .find(|a| a.has_tag_name("LOCAL"))
                .and_then(|l| l.attribute("host"))
                .unwrap_or("")
                .to_owned();
            let here = source.at(&s);
            if let Some(first) = includes.screens.get(&(host.clone(), name.to_owned())) {
                reading.notes.push(format!(
                    "{here}: <Screen name=\"{}\"> is defined before, at {first}: that one is \
                     used, as CalVR does",
                    excerpt(name)
                ));
                continue;
            }
            includes.screens.insert((host, name.to_owned()), here);
        }
        let centre = DVec3::new(
            source.number(&s, "originX", Some(0.0))?,
            source.number(&s, "originY", Some(0.0))?,
            source.number(&s, "originZ", Some(0.0))?,
        );
        let size = [
            source.number(&s, "width", None)?,
            source.number(&s, "height", None)?,
        ];
        if !size.iter().all(|v| *v > 0.0) {
            return Err(format!(
                "{}: <Screen> width and height must be positive",
                source.at(&s)
            ));
        }
        let [h, p, r] = [
            source.number(&s, "h", Some(0.0))?,
            source.number(&s, "p", Some(0.0))?,
            source.number(&s, "r", Some(0.0))?,
        ];
        // CalVR turns a screen by roll about its y (forward), pitch about x, heading about z
        // (up); in CAVE axes z-up's forward +y is −z, so roll changes sign.
        let corners = corners_from_centre(
            frame.to_cave(centre),
            wall_rotation([h, p, -r]),
            size.map(|v| v * unit.metres()),
        );
        let label = s.attribute("comment").or(s.attribute("name")).unwrap_or("");
        let out = &mut includes.out;
        out.push(ImportedWall {
            name: clean_name(label, &format!("screen{}", out.len())),
            lower_left: corners[0],
            lower_right: corners[1],
            upper_left: corners[2],
            // The window the screen names, else the channel of its name (real CalVR files link
            // a screen to the channel of the same name, which has the pixels).
            resolution: s
                .attribute("window")
                .and_then(|w| windows.get(&(scope_of(&s), w)).copied())
                .or_else(|| {
                    let name = s.attribute("channel").or(s.attribute("name"))?;
                    channels.get(&(scope_of(&s), name)).copied()
                }),
        });
    }
    Ok(())
}

/// Reads the file an `<INCLUDE>` names (its first word, relative to the including file's
/// folder), once; a file that is not there is noted and skipped, as CalVR does.
fn include(
    node: &roxmltree::Node<'_, '_>,
    source: &Source<'_>,
    depth: usize,
    reading: &mut Reading<'_>,
    includes: &mut Includes,
) -> Result<(), String> {
    let at = source.at(node);
    let Some(name) = node.text().and_then(|t| t.split_whitespace().next()) else {
        return Err(format!("{at}: <INCLUDE> names no file"));
    };
    if depth + 1 > MAX_INCLUDE_DEPTH {
        return Err(format!(
            "{at}: <INCLUDE>{name}</INCLUDE> nests deeper than {MAX_INCLUDE_DEPTH} files"
        ));
    }
    let path = source.dir.join(name);
    let key = path.canonicalize().unwrap_or(path.clone());
    if !includes.read.insert(key) {
        reading.notes.push(format!(
            "{at}: {} is included again; read once",
            path.display()
        ));
        return Ok(());
    }
    includes.files += 1;
    if includes.files > MAX_FILES {
        return Err(format!("{at}: more than {MAX_FILES} files included"));
    }
    let text = match read_capped_text(&path, MAX_CONFIG_BYTES, "config files") {
        Ok(text) => text,
        Err(e) => {
            reading.notes.push(format!(
                "{at}: <INCLUDE>{name}</INCLUDE> skipped: cannot read {}: {e}",
                path.display()
            ));
            return Ok(());
        }
    };
    let dir = path.parent().unwrap_or(Path::new(".")).to_owned();
    let label = format!("{} ", path.display());
    read(&text, &dir, label, depth + 1, reading, includes)
}
