//! Equalizer's `.eqc` configuration: every `wall { bottom_left [x y z] bottom_right [x y z]
//! top_left [x y z] }` (in a canvas segment, or a channel of older files), named after its
//! segment's or channel's name, with the pixel size of the channel's window where given.

use std::collections::HashMap;

use glam::DVec3;

use super::{ImportedWall, clean_name, finite};
use crate::cave::placement::{FileFrame, LengthUnit, UpAxis};

/// Budget: how deep blocks may nest (real files nest about 8 deep).
const MAX_DEPTH: usize = 64;

#[derive(Debug, Clone, PartialEq)]
enum Token<'a> {
    Word(&'a str),
    Text(&'a str),
    Open(char),
    Close(char),
}

fn tokens(text: &str) -> Result<Vec<(Token<'_>, usize)>, String> {
    let mut out = Vec::new();
    let bytes = text.as_bytes();
    let (mut i, mut line) = (0, 1);
    while i < bytes.len() {
        let c = bytes[i];
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b'#' => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' => {
                let start = i + 1;
                let end = text[start..]
                    .find('"')
                    .ok_or(format!("line {line}: a string has no closing '\"'"))?
                    + start;
                out.push((Token::Text(&text[start..end]), line));
                line += text[start..end].matches('\n').count();
                i = end + 1;
            }
            b'{' | b'[' => {
                out.push((Token::Open(c as char), line));
                i += 1;
            }
            b'}' | b']' => {
                out.push((Token::Close(c as char), line));
                i += 1;
            }
            c if c.is_ascii_whitespace() => i += 1,
            _ => {
                let start = i;
                while i < bytes.len()
                    && !bytes[i].is_ascii_whitespace()
                    && !b"{}[]\"#".contains(&bytes[i])
                {
                    i += 1;
                }
                out.push((Token::Word(&text[start..i]), line));
            }
        }
    }
    Ok(out)
}

/// One block being read: its keyword, a name given inside it, a pixel viewport, and the
/// channel a segment refers to.
#[derive(Debug, Default)]
struct Block<'a> {
    keyword: &'a str,
    name: Option<&'a str>,
    channel: Option<&'a str>,
    pixels: Option<[u32; 2]>,
}

/// The walls of an `.eqc` file.
pub fn walls(text: &str, unit: LengthUnit) -> Result<Vec<ImportedWall>, String> {
    let frame = FileFrame {
        unit,
        up: UpAxis::Y,
    };
    let toks = tokens(text)?;
    let mut stack: Vec<Block<'_>> = Vec::new();
    // Walls found, with the names in scope; resolved to windows once the file is read.
    let mut found: Vec<(ImportedWall, Option<String>)> = Vec::new();
    let mut window_pixels: HashMap<String, [u32; 2]> = HashMap::new();
    let mut i = 0;
    while i < toks.len() {
        let (tok, line) = (&toks[i].0, toks[i].1);
        match tok {
            Token::Word(word) if matches!(toks.get(i + 1), Some((Token::Open('{'), _))) => {
                if stack.len() >= MAX_DEPTH {
                    return Err(format!("line {line}: blocks nest deeper than {MAX_DEPTH}"));
                }
                if *word == "wall" {
                    let (wall, next) = wall_block(&toks, i + 2, frame)?;
                    let scope = stack
                        .iter()
                        .rev()
                        .find_map(|b| b.name.or(b.channel))
                        .map(str::to_owned);
                    let channel = stack.iter().rev().find_map(|b| b.channel.or(b.name));
                    found.push((
                        ImportedWall {
                            name: clean_name(
                                scope.as_deref().unwrap_or(""),
                                &format!("wall{}", found.len()),
                            ),
                            ..wall
                        },
                        channel.map(str::to_owned),
                    ));
                    i = next;
                    continue;
                }
                stack.push(Block {
                    keyword: word,
                    ..Block::default()
                });
                i += 2;
                continue;
            }
            Token::Word("name") => {
                if let (Some((Token::Text(n), _)), Some(top)) = (toks.get(i + 1), stack.last_mut())
                {
                    top.name = Some(n);
                    i += 2;
                    continue;
                }
            }
            Token::Word("channel") => {
                if let (Some((Token::Text(n), _)), Some(top)) = (toks.get(i + 1), stack.last_mut())
                {
                    top.channel = Some(n);
                    i += 2;
                    continue;
                }
            }
            Token::Word("viewport") => {
                if let Some(v) = numbers(&toks, i + 1, 4)?
                    && let Some(top) = stack.last_mut()
                    && v[2] > 1.0
                    && v[3] > 1.0
                    && v[2] <= 65535.0
                    && v[3] <= 65535.0
                {
                    top.pixels = Some([v[2] as u32, v[3] as u32]);
                }
            }
            Token::Close('}') => {
                let block = stack
                    .pop()
                    .ok_or(format!("line {line}: '}}' closes no block"))?;
                // A channel inside a window with a pixel viewport: its walls get that size.
                if block.keyword == "channel"
                    && let Some(name) = block.name
                    && let Some(px) = block.pixels.or_else(|| {
                        stack
                            .iter()
                            .rev()
                            .find(|b| b.keyword == "window")
                            .and_then(|w| w.pixels)
                    })
                {
                    window_pixels.insert(name.to_owned(), px);
                }
            }
            _ => {}
        }
        i += 1;
    }
    if let Some(open) = stack.last() {
        return Err(format!("the '{}' block is not closed", open.keyword));
    }
    Ok(found
        .into_iter()
        .map(|(mut wall, channel)| {
            wall.resolution = channel.and_then(|c| window_pixels.get(&c).copied());
            wall
        })
        .collect())
}

/// `[ a b c ... ]` of `n` numbers starting at token `at`; `None` if no '[' is there.
fn numbers(toks: &[(Token<'_>, usize)], at: usize, n: usize) -> Result<Option<Vec<f64>>, String> {
    if !matches!(toks.get(at), Some((Token::Open('['), _))) {
        return Ok(None);
    }
    let line = toks[at].1;
    let mut v = Vec::with_capacity(n);
    for k in 0..n {
        match toks.get(at + 1 + k) {
            Some((Token::Word(w), _)) => {
                v.push(finite(w).ok_or(format!("line {line}: '{w}' is not a number"))?)
            }
            _ => return Err(format!("line {line}: expected {n} numbers in [ ]")),
        }
    }
    if !matches!(toks.get(at + 1 + n), Some((Token::Close(']'), _))) {
        return Err(format!("line {line}: expected ']' after {n} numbers"));
    }
    Ok(Some(v))
}

/// Reads a wall block's corners from token `at` (after its '{'); returns it and the index after
/// its '}'.
fn wall_block(
    toks: &[(Token<'_>, usize)],
    mut at: usize,
    frame: FileFrame,
) -> Result<(ImportedWall, usize), String> {
    let start_line = toks.get(at).map_or(0, |t| t.1);
    let corner = |at: usize| -> Result<DVec3, String> {
        let v =
            numbers(toks, at, 3)?.ok_or(format!("line {start_line}: a corner needs [x y z]"))?;
        Ok(frame.to_cave(DVec3::new(v[0], v[1], v[2])))
    };
    let (mut bl, mut br, mut tl) = (None, None, None);
    while let Some((tok, line)) = toks.get(at) {
        match tok {
            Token::Close('}') => {
                let missing = |what: &str| format!("line {start_line}: the wall has no {what}");
                let wall = ImportedWall {
                    name: String::new(),
                    lower_left: bl.ok_or_else(|| missing("bottom_left"))?,
                    lower_right: br.ok_or_else(|| missing("bottom_right"))?,
                    upper_left: tl.ok_or_else(|| missing("top_left"))?,
                    resolution: None,
                };
                return Ok((wall, at + 1));
            }
            Token::Word("bottom_left") => bl = Some(corner(at + 1)?),
            Token::Word("bottom_right") => br = Some(corner(at + 1)?),
            Token::Word("top_left") => tl = Some(corner(at + 1)?),
            Token::Open('{') => return Err(format!("line {line}: unexpected block in a wall")),
            _ => {}
        }
        at += 1;
    }
    Err(format!("line {start_line}: the wall block is not closed"))
}
