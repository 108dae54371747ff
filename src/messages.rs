//! Error messages kept readable whatever the input: a line longer than a screen (a 200 KB
//! value pasted into a config or a flag) is cut, saying how much was left out.

/// Longest line kept whole, in characters.
pub const MAX_LINE_CHARS: usize = 240;

/// `text` with every line longer than [`MAX_LINE_CHARS`] cut, ending "… (N more characters)".
pub fn cut_long_lines(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(64 * 1024));
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push('\n');
        }
        out.push_str(&cut(line, MAX_LINE_CHARS));
    }
    out
}

/// `text` cut to `max` characters, saying how many more there were.
pub fn cut(text: &str, max: usize) -> String {
    match text.char_indices().nth(max) {
        None => text.to_owned(),
        Some((at, _)) => {
            let more = text[at..].chars().count();
            format!("{}… ({more} more characters)", &text[..at])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_lines_are_cut_and_short_ones_kept() {
        let long = "é".repeat(200_000);
        let cut_text = cut_long_lines(&format!("short\n{long}\nend"));
        assert!(cut_text.starts_with("short\n"));
        assert!(
            cut_text.ends_with("… (199760 more characters)\nend"),
            "{}",
            &cut_text[..50]
        );
        assert!(cut_text.len() < 1000);
        assert_eq!(cut("abc", 3), "abc");
    }
}
