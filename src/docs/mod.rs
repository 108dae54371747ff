//! The book's reference pages, generated from the code they describe (`omnicave docs`).
//!
//! Each page is built from the definition the program itself uses: the config keys from the
//! settings model's JSON Schema, the command line from clap, the key and gamepad maps from
//! their tables, the OSC forms from the decoder's table, the budgets from the settings model
//! and the fixed limits' constants, and the test table from each test file's opening comment.
//! `omnicave docs --check` (run by `tests/book.rs`) fails, naming the page, when a committed
//! page differs from what the code gives.

mod cli_page;
mod config_page;
mod tables;
mod tests_page;

use std::path::{Path, PathBuf};

pub use cli_page::cli_page;
pub use config_page::{budgets_page, config_page};
pub use tables::{keys_page, osc_page};
pub use tests_page::tests_page;

/// The command that regenerates every page, as the pages and the drift check name it.
pub const REGENERATE: &str = "cargo run -- docs";

/// One generated page: where it goes under the book's `src/` and its text.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    /// Path relative to `docs/src`.
    pub path: &'static str,
    /// The whole Markdown text.
    pub text: String,
}

/// Why the pages could not be generated, written or checked.
#[derive(Debug, thiserror::Error)]
pub enum DocsError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("the config schema is not what the page generator expects: {0}")]
    Schema(String),
}

/// The line every generated page starts with, naming its source and how to regenerate it.
pub fn generated_header(source: &str) -> String {
    format!(
        "<!-- Generated from {source} by `{REGENERATE}`; edit the source, not this page. -->\n\n"
    )
}

/// Every generated page: `cli` is the program's clap definition, `repo` the repository root
/// (the test table reads `tests/`).
pub fn all_pages(cli: &clap::Command, repo: &Path) -> Result<Vec<Page>, DocsError> {
    Ok(vec![
        Page {
            path: "reference/config.md",
            text: config_page()?,
        },
        Page {
            path: "reference/cli.md",
            text: cli_page(cli),
        },
        Page {
            path: "reference/keys.md",
            text: keys_page(),
        },
        Page {
            path: "reference/osc.md",
            text: osc_page(),
        },
        Page {
            path: "reference/budgets.md",
            text: budgets_page()?,
        },
        Page {
            path: "contributing/testing.md",
            text: tests_page(&repo.join("tests"))?,
        },
    ])
}

/// Writes every page under `book_src` (`docs/src`).
pub fn write_pages(pages: &[Page], book_src: &Path) -> Result<(), DocsError> {
    for page in pages {
        let path = book_src.join(page.path);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|source| DocsError::Write {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        std::fs::write(&path, &page.text).map_err(|source| DocsError::Write { path, source })?;
    }
    Ok(())
}

/// The pages whose committed text under `book_src` differs from `pages` (missing ones too),
/// as paths relative to the repository (`docs/src/...`).
pub fn stale_pages(pages: &[Page], book_src: &Path) -> Vec<String> {
    pages
        .iter()
        .filter(|page| {
            std::fs::read_to_string(book_src.join(page.path))
                .ok()
                .as_deref()
                != Some(page.text.as_str())
        })
        .map(|page| format!("docs/src/{}", page.path))
        .collect()
}

/// Escapes text for a Markdown table cell: pipes escaped, line breaks joined.
pub(crate) fn cell(text: &str) -> String {
    let joined = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    // `<` outside code spans would open an HTML tag in mdBook (overlay:<wall>).
    let escaped: Vec<String> = joined
        .split('`')
        .enumerate()
        .map(|(i, part)| {
            if i % 2 == 0 {
                part.replace('<', "&lt;")
            } else {
                part.to_string()
            }
        })
        .collect();
    escaped.join("`").replace('|', "\\|")
}
