//! Line numbers of byte offsets, found in logarithmic time from one linear pass (a reader that
//! counted newlines from the start for every message was quadratic in the file).

/// The byte offset where each line starts.
#[derive(Debug, Clone)]
pub struct LineIndex {
    starts: Vec<usize>,
}

impl LineIndex {
    pub fn new(text: &str) -> Self {
        let mut starts = vec![0];
        starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Self { starts }
    }

    /// The 1-based line holding byte `offset`.
    pub fn line(&self, offset: usize) -> usize {
        match self.starts.binary_search(&offset) {
            Ok(i) => i + 1,
            Err(i) => i,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_fall_on_their_lines() {
        let text = "ab\ncd\n\nef";
        let lines = LineIndex::new(text);
        let at = |s: &str| lines.line(text.find(s).unwrap());
        assert_eq!((lines.line(0), at("b"), at("c"), at("d")), (1, 1, 2, 2));
        assert_eq!((lines.line(6), at("e"), lines.line(text.len())), (3, 4, 4));
    }
}
