//! Where a setting stands in a config's text: the field path at a parser error's offset, and
//! the line of a field named by its path, so every error points into the file.

use toml::de::{DeTable, DeValue};

/// The dotted path (`render.mode`, `wall[2].upper_left`) of the innermost key or value that
/// covers byte `offset` of `text`, if the text parses as TOML and one does.
pub fn field_at(text: &str, offset: usize) -> Option<String> {
    let table = DeTable::parse(text).ok()?;
    let mut best: Option<(usize, String)> = None;
    visit_table(table.get_ref(), "", &mut |path, span| {
        if span.contains(&offset) || (span.is_empty() && span.start == offset) {
            let width = span.len();
            if best.as_ref().is_none_or(|(w, _)| width <= *w) {
                best = Some((width, path.to_owned()));
            }
        }
    });
    best.map(|(_, path)| path)
}

/// The 1-based line of the key (or array element) at `path` in `text`.
pub fn line_of(text: &str, path: &str) -> Option<usize> {
    let table = DeTable::parse(text).ok()?;
    let mut found = None;
    visit_table(table.get_ref(), "", &mut |p, span| {
        if found.is_none() && p == path {
            found = Some(span.start);
        }
    });
    found.map(|offset| 1 + text[..offset.min(text.len())].matches('\n').count())
}

/// Calls `f` with the path and span of every key and array element, depth first.
fn visit_table(table: &DeTable<'_>, prefix: &str, f: &mut dyn FnMut(&str, std::ops::Range<usize>)) {
    for (key, value) in table.iter() {
        let path = if prefix.is_empty() {
            key.get_ref().to_string()
        } else {
            format!("{prefix}.{}", key.get_ref())
        };
        f(&path, key.span());
        f(&path, value.span());
        visit_value(value.get_ref(), &path, f);
    }
}

fn visit_value(value: &DeValue<'_>, path: &str, f: &mut dyn FnMut(&str, std::ops::Range<usize>)) {
    match value {
        DeValue::Table(table) => visit_table(table, path, f),
        DeValue::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let item_path = format!("{path}[{i}]");
                f(&item_path, item.span());
                visit_value(item.get_ref(), &item_path, f);
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "[render]\nmode = \"omni\"\n\n[[wall]]\nname = \"a\"\n\n[[wall]]\nname = \"b\"\nresolution = [1, 0]\n";

    #[test]
    fn finds_the_field_at_an_offset() {
        let at = |needle: &str| field_at(TEXT, TEXT.find(needle).expect("in text"));
        assert_eq!(at("\"omni\"").as_deref(), Some("render.mode"));
        assert_eq!(at("\"b\"").as_deref(), Some("wall[1].name"));
        assert_eq!(at("0]").as_deref(), Some("wall[1].resolution[1]"));
    }

    #[test]
    fn finds_the_line_of_a_field() {
        assert_eq!(line_of(TEXT, "render.mode"), Some(2));
        assert_eq!(line_of(TEXT, "wall[1].resolution"), Some(9));
        assert_eq!(line_of(TEXT, "wall[1].resolution[1]"), Some(9));
        assert_eq!(line_of(TEXT, "head.position"), None);
    }
}
