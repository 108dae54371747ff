//! Property-based fuzzing of the config loader and the glTF loader, bounded so it
//! runs on every CI run beside the OSC fuzzers: mutated bundled configs (lines dropped,
//! doubled or cut, numbers replaced by huge, negative, NaN or non-numbers, arrays lengthened,
//! random bytes) and mutated glTF files (bytes flipped in the JSON and the binary chunk,
//! numbers in the JSON rewritten, chunks cut). Nothing may panic or hang, every error is a
//! readable message, and the process's peak memory stays under a stated bound.
//!
//! Deterministic seeds (a CI failure reproduces locally); `OMNICAVE_FUZZ_CASES` raises the
//! number of cases for a longer run.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::cell::Cell;
use std::path::Path;
use std::time::Duration;

use glam::Vec3;
use proptest::collection::vec;
use proptest::prelude::*;

use omnicave::config::Config;
use omnicave::scene::build::grid;
use omnicave::scene::glb_writer::{GlbWriter, MaterialDesc, MeshOptions, NodeDesc};
use omnicave::scene::{SceneBudget, load_gltf_bytes};

use common::fuzz::{cases, runner, within};

/// The process's peak resident memory so far (Linux `VmHWM`), bytes.
fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The peak memory every fuzz test here stays under: the loaders' budgets below allow 64 MiB
/// of textures and 1 M vertices (~150 MB with the scene's copies); the rest is the test
/// binary and its threads. A mutation that made a loader allocate by a lying count would
/// pass it by gigabytes.
const PEAK_RSS_LIMIT: u64 = 1 << 30;

// ---------------------------------------------------------------- config

#[derive(Debug, Clone)]
enum ConfigEdit {
    DropLine(usize),
    DoubleLine(usize),
    CutLine(usize, usize),
    /// Replace the n-th number in the text.
    Number(usize, String),
    /// Add elements to the n-th array.
    LongerArray(usize, String),
    InsertBytes(usize, Vec<u8>),
}

fn number_text() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("1e30".to_owned()),
        Just("-1e30".to_owned()),
        Just("nan".to_owned()),
        Just("-inf".to_owned()),
        Just("0".to_owned()),
        Just("-1".to_owned()),
        Just("4294967296".to_owned()),
        Just("\"text\"".to_owned()),
        Just("[]".to_owned()),
        Just("{}".to_owned()),
        Just("true".to_owned()),
        any::<f32>().prop_map(|f| format!("{f:?}")),
        any::<i64>().prop_map(|i| i.to_string()),
    ]
}

fn config_edit() -> impl Strategy<Value = ConfigEdit> {
    prop_oneof![
        1 => any::<usize>().prop_map(ConfigEdit::DropLine),
        1 => any::<usize>().prop_map(ConfigEdit::DoubleLine),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(l, c)| ConfigEdit::CutLine(l, c)),
        3 => (any::<usize>(), number_text()).prop_map(|(n, t)| ConfigEdit::Number(n, t)),
        1 => (any::<usize>(), number_text()).prop_map(|(n, t)| ConfigEdit::LongerArray(n, t)),
        1 => (any::<usize>(), vec(any::<u8>(), 1..8)).prop_map(|(at, b)| ConfigEdit::InsertBytes(at, b)),
    ]
}

fn apply(text: &str, edit: &ConfigEdit) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let n = lines.len().max(1);
    match edit {
        ConfigEdit::DropLine(l) => {
            lines.remove(l % n);
        }
        ConfigEdit::DoubleLine(l) => {
            let line = lines[l % n].clone();
            lines.insert(l % n, line);
        }
        ConfigEdit::CutLine(l, c) => {
            let line = &mut lines[l % n];
            let keep = line
                .char_indices()
                .nth(c % (line.len() + 1))
                .map_or(line.len(), |(i, _)| i);
            line.truncate(keep);
        }
        ConfigEdit::Number(k, replacement) => {
            let joined = lines.join("\n");
            let numbers: Vec<(usize, usize)> = number_spans(&joined);
            if numbers.is_empty() {
                return joined;
            }
            let (start, end) = numbers[k % numbers.len()];
            return format!("{}{replacement}{}", &joined[..start], &joined[end..]);
        }
        ConfigEdit::LongerArray(k, extra) => {
            let joined = lines.join("\n");
            let closes: Vec<usize> = joined.match_indices(']').map(|(i, _)| i).collect();
            if closes.is_empty() {
                return joined;
            }
            let at = closes[k % closes.len()];
            return format!("{}, {extra}{}", &joined[..at], &joined[at..]);
        }
        ConfigEdit::InsertBytes(at, bytes) => {
            let joined = lines.join("\n");
            let mut raw = joined.into_bytes();
            let at = at % (raw.len() + 1);
            raw.splice(at..at, bytes.iter().copied());
            return String::from_utf8_lossy(&raw).into_owned();
        }
    }
    lines.join("\n")
}

/// Byte ranges of the numbers in `text` (outside comments is not needed: a number in a
/// comment changed is a harmless case too).
fn number_spans(text: &str) -> Vec<(usize, usize)> {
    let bytes = text.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit()
            && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_'));
        if starts {
            let start = if i > 0 && bytes[i - 1] == b'-' {
                i - 1
            } else {
                i
            };
            let mut end = i;
            while end < bytes.len()
                && (bytes[end].is_ascii_digit()
                    || matches!(bytes[end], b'.' | b'e' | b'E' | b'-' | b'+'))
            {
                end += 1;
            }
            spans.push((start, end));
            i = end;
        } else {
            i += 1;
        }
    }
    spans
}

#[test]
fn the_config_loader_never_panics_or_hangs_on_mutated_configs() {
    let n = cases(3000);
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bases: Vec<String> = ["config/cave.toml", "config/desktop.toml"]
        .iter()
        .map(|f| std::fs::read_to_string(repo.join(f)).unwrap())
        .collect();
    let refused = within(Duration::from_secs(600), move || {
        let refused = Cell::new(0u32);
        runner(n)
            .run(
                &(0..bases.len(), vec(config_edit(), 1..4)),
                |(base, edits)| {
                    let mut text = bases[base].clone();
                    for e in &edits {
                        text = apply(&text, e);
                    }
                    match Config::from_toml(&text, Path::new("fuzz.toml")) {
                        Ok(_) => {}
                        Err(e) => {
                            let message = e.to_string();
                            prop_assert!(message.contains("fuzz.toml"), "{}", message);
                            prop_assert!(message.len() < 4096, "{} bytes", message.len());
                            refused.set(refused.get() + 1);
                        }
                    }
                    Ok(())
                },
            )
            .map_err(|e| e.to_string())
            .unwrap();
        refused.get()
    });
    assert!(refused > n / 4, "the mutations should break most configs");
    if let Some(peak) = peak_rss() {
        assert!(peak < PEAK_RSS_LIMIT, "peak memory {peak} bytes");
    }
}

// ---------------------------------------------------------------- glTF

/// A small GLB with what the loader reads: indices, normals, UVs, a PNG texture, a node
/// hierarchy with a transform.
fn seed_glb() -> Vec<u8> {
    let mut w = GlbWriter::new();
    let mut img = image::RgbaImage::new(8, 8);
    for (x, y, p) in img.enumerate_pixels_mut() {
        *p = image::Rgba([(x * 32) as u8, (y * 32) as u8, 128, 255]);
    }
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let texture = w.add_png_texture("t", &png);
    let material = w.add_material(&MaterialDesc {
        texture: Some(texture),
        ..MaterialDesc::plain("m", [1.0; 3], 0.5)
    });
    let quad = grid(Vec3::new(-0.5, 1.0, -2.0), Vec3::X, Vec3::Y, 2, 2, 1.0);
    let mesh = w.add_mesh_with("q", &[(&quad, material)], &MeshOptions::default());
    let leaf = w.add_node(
        NodeDesc::new("leaf")
            .with_mesh(mesh)
            .at(Vec3::new(0.1, 0.0, 0.0)),
    );
    let root = w.add_node(
        NodeDesc::new("root")
            .with_children(vec![leaf])
            .rotated_y_degrees(20.0),
    );
    w.to_glb(&[root])
}

#[derive(Debug, Clone)]
enum GlbEdit {
    /// Flip bits of the byte at this position (anywhere: headers, JSON, BIN).
    Flip(usize, u8),
    /// Replace the n-th number of the JSON chunk.
    JsonNumber(usize, i64),
    Truncate(usize),
}

fn glb_edit() -> impl Strategy<Value = GlbEdit> {
    let interesting = prop_oneof![
        Just(0i64),
        Just(-1),
        Just(1),
        Just(3),
        Just(5126),
        Just(5123),
        Just(65_536),
        Just(u32::MAX as i64),
        Just(i64::from(i32::MAX)),
        Just(1 << 40),
        any::<i64>(),
    ];
    prop_oneof![
        3 => (any::<usize>(), 1u8..=255).prop_map(|(at, bits)| GlbEdit::Flip(at, bits)),
        3 => (any::<usize>(), interesting).prop_map(|(n, v)| GlbEdit::JsonNumber(n, v)),
        1 => any::<usize>().prop_map(GlbEdit::Truncate),
    ]
}

fn apply_glb(glb: &[u8], edit: &GlbEdit) -> Vec<u8> {
    let mut out = glb.to_vec();
    match edit {
        GlbEdit::Flip(at, bits) => {
            if let Some(len) = std::num::NonZeroUsize::new(out.len()) {
                out[*at % len] ^= bits;
            }
        }
        GlbEdit::Truncate(at) => out.truncate(at % (out.len() + 1)),
        GlbEdit::JsonNumber(k, value) => {
            if out.len() < 20 {
                return out;
            }
            let json_len = u32::from_le_bytes(out[12..16].try_into().unwrap()) as usize;
            let Some(json) = out.get(20..20 + json_len) else {
                return out;
            };
            let text = String::from_utf8_lossy(json).into_owned();
            let spans = number_spans(&text);
            if spans.is_empty() {
                return out;
            }
            let (start, end) = spans[k % spans.len()];
            let mut text = format!("{}{value}{}", &text[..start], &text[end..]).into_bytes();
            while !text.len().is_multiple_of(4) {
                text.push(b' ');
            }
            let bin = out[20 + json_len..].to_vec();
            let mut rebuilt = Vec::new();
            rebuilt.extend_from_slice(b"glTF");
            rebuilt.extend_from_slice(&2u32.to_le_bytes());
            rebuilt.extend_from_slice(&((20 + text.len() + bin.len()) as u32).to_le_bytes());
            rebuilt.extend_from_slice(&(text.len() as u32).to_le_bytes());
            rebuilt.extend_from_slice(b"JSON");
            rebuilt.extend_from_slice(&text);
            rebuilt.extend_from_slice(&bin);
            return rebuilt;
        }
    }
    out
}

#[test]
fn the_gltf_loader_never_panics_or_hangs_on_mutated_files() {
    fuzz_gltf(seed_glb(), cases(3000));
}

/// The same on the bundled animated sample: animations (every interpolation), a skin and
/// morph targets, mutated.
#[test]
fn the_gltf_loader_never_panics_or_hangs_on_mutated_animated_files() {
    fuzz_gltf(
        omnicave::scene::animated_sample::animated_sample_glb(),
        cases(1500),
    );
}

/// Loads `n` mutations of `seed`: each loads within the budget or is refused naming the
/// file, without a panic (even one caught), a hang or runaway memory.
fn fuzz_gltf(seed: Vec<u8>, n: u32) {
    // The seed itself loads.
    let budget = SceneBudget {
        max_file_bytes: 1 << 20,
        max_instances: 10_000,
        max_vertices: 1 << 20,
        max_triangles: 1 << 20,
        max_texture_side: 1024,
        max_texture_bytes: 64 << 20,
        max_pose_bytes: 64 << 20,
        ..SceneBudget::default()
    };
    load_gltf_bytes(&seed, Path::new("seed.glb"), &budget).expect("seed loads");
    let (refused, caught) = within(Duration::from_secs(600), move || {
        let (refused, caught) = (Cell::new(0u32), Cell::new(0u32));
        runner(n)
            .run(&vec(glb_edit(), 1..4), |edits| {
                let mut bytes = seed.clone();
                for e in &edits {
                    bytes = apply_glb(&bytes, e);
                }
                match load_gltf_bytes(&bytes, Path::new("fuzz.glb"), &budget) {
                    Ok(scene) => {
                        prop_assert!(scene.vertices.len() <= 1 << 20);
                    }
                    Err(e) => {
                        let message = e.to_string();
                        prop_assert!(message.contains("fuzz.glb"), "{}", message);
                        prop_assert!(message.len() < 8192, "{} bytes", message.len());
                        // The loader's last net: a panic inside a dependency turned into an
                        // error. Counted so that a new one is seen.
                        if message.contains("the glTF parser failed") {
                            caught.set(caught.get() + 1);
                        }
                        refused.set(refused.get() + 1);
                    }
                }
                Ok(())
            })
            .map_err(|e| e.to_string())
            .unwrap();
        (refused.get(), caught.get())
    });
    assert!(refused > n / 4, "the mutations should break most files");
    // Every panic of the gltf crate the fuzzer found is checked for before it is reached.
    assert_eq!(
        caught, 0,
        "a mutation reached a panic inside the gltf crate"
    );
    if let Some(peak) = peak_rss() {
        assert!(peak < PEAK_RSS_LIMIT, "peak memory {peak} bytes");
    }
}

// ---------------------------------------------------------------- wall imports

/// Tokens that matter to the importers' grammars, spliced into their files.
const IMPORT_TOKENS: &[&str] = &[
    "<",
    ">",
    "/>",
    "</",
    "<!--",
    "-->",
    "<INCLUDE>x.xml</INCLUDE>",
    "<Screen",
    "\"",
    "=",
    "{",
    "}",
    "[",
    "]",
    "(",
    ")",
    ",",
    "\n",
    "section ",
    "endsection\n",
    "parentId",
    "\"parentId\":\"",
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "0.40.0",
    "+",
    "X=",
    "[screen] id=s size=\"X=1,Y=1\" ",
    "#",
    "\\\n",
    "TopLeft",
    "_BotLeft (",
    "deviceMounted true\n",
    "wall {",
];

/// One edit of an import file: splice a token in, cut a range, or double one.
#[derive(Debug, Clone)]
enum ImportEdit {
    Splice(usize, usize),
    Cut(usize, usize),
    Double(usize, usize),
}

fn import_edit() -> impl Strategy<Value = ImportEdit> {
    prop_oneof![
        3 => (any::<usize>(), 0..IMPORT_TOKENS.len()).prop_map(|(at, t)| ImportEdit::Splice(at, t)),
        1 => (any::<usize>(), 1usize..400).prop_map(|(at, n)| ImportEdit::Cut(at, n)),
        1 => (any::<usize>(), 1usize..400).prop_map(|(at, n)| ImportEdit::Double(at, n)),
    ]
}

fn apply_import(text: &str, edit: &ImportEdit) -> String {
    let mut bytes = text.as_bytes().to_vec();
    let len = bytes.len().max(1);
    match *edit {
        ImportEdit::Splice(at, t) => {
            let at = at % len;
            bytes.splice(at..at, IMPORT_TOKENS[t].bytes());
        }
        ImportEdit::Cut(at, n) => {
            let at = at % len;
            let end = (at + n).min(bytes.len());
            bytes.drain(at..end);
        }
        ImportEdit::Double(at, n) => {
            let at = at % len;
            let end = (at + n).min(bytes.len());
            let copy = bytes[at..end].to_vec();
            bytes.splice(end..end, copy);
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

#[test]
fn the_wall_importers_never_panic_or_hang_on_mutated_files() {
    use omnicave::config::import::import_text;
    let n = cases(1500);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/import");
    // Every format's files as their owners publish them (the licences aside).
    let seeds: Vec<(String, String)> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            !name.starts_with("LICENSE") && !name.starts_with("COPYING") && !name.ends_with(".md")
        })
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read_to_string(&p).unwrap())
        })
        .collect();
    assert!(seeds.len() >= 10, "{} seed files", seeds.len());
    let refused = within(Duration::from_secs(600), move || {
        let refused = Cell::new(0u32);
        runner(n)
            .run(
                &(0..seeds.len(), vec(import_edit(), 1..4)),
                |(seed, edits)| {
                    let (name, text) = &seeds[seed];
                    let mut text = text.clone();
                    for e in &edits {
                        text = apply_import(&text, e);
                    }
                    // A Vrui file with several installations is read as one (the first).
                    let section = name
                        .contains("Vrui")
                        .then_some("caveman.geology.ucdavis.edu");
                    match import_text(&text, &dir.join(name), None, None, section) {
                        Ok(import) => {
                            for w in &import.walls {
                                for c in [w.lower_left, w.lower_right, w.upper_left] {
                                    prop_assert!(c.is_finite() && c.abs().max_element() <= 1000.0);
                                }
                            }
                        }
                        Err(e) => {
                            let message = e.to_string();
                            prop_assert!(message.contains(name.as_str()), "{}", message);
                            prop_assert!(message.len() < 4096, "{} bytes", message.len());
                            refused.set(refused.get() + 1);
                        }
                    }
                    Ok(())
                },
            )
            .map_err(|e| e.to_string())
            .unwrap();
        refused.get()
    });
    // Most single edits leave a file readable (a token inside a comment or a name); some break
    // it. Both happen, or the mutations miss the grammar.
    assert!(refused > n / 20 && refused < n, "{refused} of {n} refused");
}
