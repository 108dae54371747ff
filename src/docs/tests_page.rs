//! The test table (`contributing/testing.md`), from each test file's opening comment.

use std::fmt::Write as _;
use std::path::Path;

use super::{DocsError, cell, generated_header};

/// The first paragraph of a file's `//!` comment.
fn opening_comment(text: &str) -> String {
    text.lines()
        .map_while(|l| l.trim_start().strip_prefix("//!"))
        .map(str::trim)
        .take_while(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// `contributing/testing.md`: one row per test file in `tests_dir`, what it proves.
pub fn tests_page(tests_dir: &Path) -> Result<String, DocsError> {
    let read_dir = |path: &Path| {
        std::fs::read_dir(path).map_err(|source| DocsError::Read {
            path: path.to_path_buf(),
            source,
        })
    };
    let mut files: Vec<_> = read_dir(tests_dir)?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .collect();
    files.sort();
    let mut out = generated_header("each test file's opening comment (`tests/*.rs`)");
    out.push_str(
        "# Testing\n\n\
         `bash scripts/test.sh` runs everything CI runs: formatting, clippy (with and without \
         cluster mode), the Khronos glTF validator on the bundled scenes, and every test. The \
         tests render for real, headless, on whatever Vulkan adapter is present (lavapipe on a \
         machine without a GPU), and check pictures against the CPU twins of the GPU maths. \
         One test file: `cargo test --test NAME`; unit tests: `cargo test --lib`.\n\n\
         Tests that use `../shared/corpus` (third-party glTF models) or `../shared/peers` \
         (the real VRPN server) say so when they skip because it is absent; CI always has it.\n\n\
         | file | what it proves |\n|---|---|\n",
    );
    for path in files {
        let text = std::fs::read_to_string(&path).map_err(|source| DocsError::Read {
            path: path.clone(),
            source,
        })?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy())
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "| `tests/{name}` | {} |",
            cell(&opening_comment(&text))
        );
    }
    Ok(out)
}
