//! The manual as a newcomer meets it: README.md is a short front door whose links resolve;
//! every page under docs/src is in SUMMARY.md and every link, anchor, image and include in
//! the book resolves; the generated reference pages are what the code gives; every TOML
//! example is a valid config; no commit hash or date appears outside the changelog and the
//! performance page's table headers; and every command on the Getting started and Lab setup
//! pages runs, as written, and succeeds.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::collections::{BTreeSet, HashMap};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::xvfb::{X_SERVER, Xvfb};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn book_src() -> PathBuf {
    repo().join("docs/src")
}

/// Every Markdown page under docs/src, relative to it.
fn pages() -> Vec<PathBuf> {
    fn walk(dir: &Path, base: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                walk(&path, base, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path.strip_prefix(base).unwrap().to_path_buf());
            }
        }
    }
    let mut out = Vec::new();
    walk(&book_src(), &book_src(), &mut out);
    out.sort();
    out
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A fenced code block: its info string, first line number and text.
#[derive(Debug)]
struct Fence {
    info: String,
    line: usize,
    text: String,
}

/// The page's prose (code blocks and inline code blanked) and its fenced blocks.
fn split_code(text: &str) -> (String, Vec<Fence>) {
    let mut prose = String::new();
    let mut fences = Vec::new();
    let mut open: Option<Fence> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if let Some(rest) = trimmed.strip_prefix("```") {
            match open.take() {
                Some(fence) => fences.push(fence),
                None => {
                    open = Some(Fence {
                        info: rest.trim().to_string(),
                        line: i + 1,
                        text: String::new(),
                    })
                }
            }
            prose.push('\n');
            continue;
        }
        match &mut open {
            Some(fence) => {
                fence.text.push_str(line);
                fence.text.push('\n');
                prose.push('\n');
            }
            None => {
                // Inline code spans are not links.
                let mut kept = String::new();
                for (k, part) in line.split('`').enumerate() {
                    if k % 2 == 0 {
                        kept.push_str(part);
                    }
                }
                prose.push_str(&kept);
                prose.push('\n');
            }
        }
    }
    assert!(open.is_none(), "an unclosed code fence");
    (prose, fences)
}

/// Every `](target)` of Markdown links and images in `prose`.
fn link_targets(prose: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = prose;
    while let Some(i) = rest.find("](") {
        let after = &rest[i + 2..];
        let end = after.find(')').unwrap_or(after.len());
        let target = after[..end].split_whitespace().next().unwrap_or("");
        out.push(target.to_string());
        rest = &after[end..];
    }
    out
}

/// The anchor ids mdBook gives a page's headings (its `normalize_id`, with `-1`, `-2` … for
/// repeats).
fn heading_ids(text: &str) -> BTreeSet<String> {
    let (prose, _) = split_code(&text.replace('`', ""));
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut ids = BTreeSet::new();
    for line in prose.lines() {
        let Some(title) = line.strip_prefix('#') else {
            continue;
        };
        let title = title.trim_start_matches('#').trim();
        // Link text stays, its target goes; emphasis marks go.
        let mut plain = String::new();
        let mut chars = title.chars().peekable();
        while let Some(c) = chars.next() {
            if c == ']' && chars.peek() == Some(&'(') {
                for c in chars.by_ref() {
                    if c == ')' {
                        break;
                    }
                }
            } else if !matches!(c, '[' | '*') {
                plain.push(c);
            }
        }
        let id: String = plain
            .chars()
            .filter_map(|ch| {
                if ch.is_alphanumeric() || ch == '_' || ch == '-' {
                    Some(ch.to_ascii_lowercase())
                } else if ch.is_whitespace() {
                    Some('-')
                } else {
                    None
                }
            })
            .collect();
        let n = seen.entry(id.clone()).or_default();
        ids.insert(if *n == 0 {
            id.clone()
        } else {
            format!("{id}-{n}")
        });
        *n += 1;
    }
    ids
}

/// The broken links of the Markdown file `file` (a page, or the README), as messages.
fn broken_links(file: &Path) -> Vec<String> {
    let text = read(file);
    let (prose, _) = split_code(&text);
    let dir = file.parent().unwrap();
    let mut broken = Vec::new();
    let mut targets = link_targets(&prose);
    // mdBook includes: `{{#include PATH}}`.
    for part in text.split("{{#include ").skip(1) {
        let path = part
            .split("}}")
            .next()
            .unwrap_or("")
            .split(':')
            .next()
            .unwrap();
        targets.push(path.trim().to_string());
    }
    for target in targets {
        if target.starts_with("http://") || target.starts_with("https://") {
            continue;
        }
        let (path, anchor) = match target.split_once('#') {
            Some((p, a)) => (p, Some(a)),
            None => (target.as_str(), None),
        };
        let resolved = if path.is_empty() {
            file.to_path_buf()
        } else {
            dir.join(path)
        };
        if !resolved.exists() {
            broken.push(format!("{}: `{target}` does not exist", file.display()));
            continue;
        }
        if let Some(anchor) = anchor
            && resolved.extension().is_some_and(|e| e == "md")
            && !heading_ids(&read(&resolved)).contains(anchor)
        {
            broken.push(format!(
                "{}: `{target}`: no heading with the id `{anchor}`",
                file.display()
            ));
        }
    }
    broken
}

#[test]
fn every_page_is_in_the_summary_and_every_summary_entry_exists() {
    let summary = read(&book_src().join("SUMMARY.md"));
    let listed: BTreeSet<PathBuf> = link_targets(&summary)
        .into_iter()
        .map(PathBuf::from)
        .collect();
    for page in &listed {
        assert!(
            book_src().join(page).is_file(),
            "SUMMARY.md lists {} which does not exist",
            page.display()
        );
    }
    let missing: Vec<_> = pages()
        .into_iter()
        .filter(|p| p != Path::new("SUMMARY.md") && !listed.contains(p))
        .collect();
    assert!(missing.is_empty(), "pages not in SUMMARY.md: {missing:?}");
    let toml = read(&repo().join("docs/book.toml"));
    assert!(
        toml.contains("src = \"src\""),
        "docs/book.toml must keep src = \"src\""
    );
}

#[test]
fn every_link_image_anchor_and_include_resolves() {
    let mut broken = broken_links(&repo().join("README.md"));
    for page in pages() {
        broken.extend(broken_links(&book_src().join(page)));
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

/// The checker itself finds what it should: a missing file, a missing anchor, an include.
#[test]
fn the_link_checker_finds_broken_links() {
    let dir = std::env::temp_dir().join(format!("omnicave-book-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.md"), "# A title\n\n## Second `one`\n").unwrap();
    let page = dir.join("b.md");
    std::fs::write(
        &page,
        "[ok](a.md) [ok](a.md#second-one) [no](c.md) [no](a.md#third) ![no](x.png)\n\
         `[code](not-a-link.md)`\n{{#include missing.md}}\n",
    )
    .unwrap();
    let broken = broken_links(&page);
    assert_eq!(broken.len(), 4, "{broken:#?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_generated_reference_pages_are_what_the_code_gives() {
    let out = Command::new(env!("CARGO_BIN_EXE_omnicave"))
        .args(["docs", "--check", "--repo"])
        .arg(repo())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Drift is caught and named: a committed page changed by hand (as a default changed in the
/// code would leave it) fails the check, naming the page and the command that regenerates it.
#[test]
fn a_stale_reference_page_is_named_with_the_command_that_fixes_it() {
    let copy = std::env::temp_dir().join(format!("omnicave-docs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&copy);
    std::fs::create_dir_all(copy.join("docs/src/reference")).unwrap();
    std::fs::create_dir_all(copy.join("docs/src/contributing")).unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_omnicave"))
            .args(args)
            .arg("--repo")
            .arg(&copy)
            .output()
            .unwrap()
    };
    std::fs::create_dir_all(copy.join("tests")).unwrap();
    std::fs::copy(repo().join("tests/book.rs"), copy.join("tests/book.rs")).unwrap();
    assert!(run(&["docs"]).status.success());
    assert!(run(&["docs", "--check"]).status.success());
    let page = copy.join("docs/src/reference/config.md");
    let text = read(&page).replace(
        "| `max_depth` | integer | `12` |",
        "| `max_depth` | integer | `10` |",
    );
    assert!(
        text.contains("`10`"),
        "the tessellation depth row was not found"
    );
    std::fs::write(&page, text).unwrap();
    let out = run(&["docs", "--check"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("docs/src/reference/config.md") && err.contains("cargo run -- docs"),
        "{err}"
    );
    std::fs::remove_dir_all(&copy).unwrap();
}

#[test]
fn every_toml_example_is_a_valid_config() {
    let schema: serde_json::Value =
        serde_json::from_str(&read(&repo().join("config/omnicave.schema.json"))).unwrap();
    let mut schemas = boon::Schemas::new();
    let mut compiler = boon::Compiler::new();
    compiler
        .add_resource("omnicave.schema.json", schema)
        .unwrap();
    let index = compiler
        .compile("omnicave.schema.json", &mut schemas)
        .unwrap();
    let mut checked = 0;
    let mut bad = Vec::new();
    for page in pages() {
        let (_, fences) = split_code(&read(&book_src().join(&page)));
        for fence in fences.iter().filter(|f| f.info == "toml") {
            checked += 1;
            let at = format!("{}:{}", page.display(), fence.line);
            let value: toml::Value = match toml::from_str(&fence.text) {
                Ok(v) => v,
                Err(e) => {
                    bad.push(format!("{at}: not TOML: {e}"));
                    continue;
                }
            };
            let json = serde_json::to_value(value).unwrap();
            if let Err(e) = schemas.validate(&json, index) {
                bad.push(format!("{at}: not a valid config: {e}"));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    assert!(checked > 5, "only {checked} TOML examples in the book");
}

/// A word that looks like a commit hash: 7 to 40 hexadecimal digits with both a digit and a
/// letter (not a colour `#rrggbb`).
fn hashes(line: &str) -> Vec<&str> {
    line.split(|c: char| !c.is_ascii_alphanumeric() && c != '#')
        .filter(|w| {
            (7..=40).contains(&w.len())
                && w.chars()
                    .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())
                && w.chars().any(|c| c.is_ascii_digit())
                && w.chars().any(|c| c.is_ascii_alphabetic())
        })
        .collect()
}

/// A date written as YYYY-MM-DD.
fn has_date(line: &str) -> bool {
    let b = line.as_bytes();
    b.windows(10).any(|w| {
        w.iter().enumerate().all(|(i, c)| match i {
            4 | 7 => *c == b'-',
            _ => c.is_ascii_digit(),
        }) && w.starts_with(b"20")
    })
}

#[test]
fn no_commit_hash_or_date_outside_the_changelog_and_the_performance_tables() {
    let mut found = Vec::new();
    let mut check = |name: String, text: &str, tables_may_date: bool| {
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            // A table's header row: the line above its `|---|` separator.
            let header = line.trim_start().starts_with('|')
                && lines
                    .get(i + 1)
                    .is_some_and(|next| next.trim_start().starts_with("|--"));
            if let Some(h) = hashes(line).first()
                && !(tables_may_date && header)
            {
                found.push(format!("{name}:{}: `{h}` looks like a commit hash", i + 1));
            }
            if has_date(line) && !(tables_may_date && header) {
                found.push(format!("{name}:{}: a date", i + 1));
            }
        }
    };
    check("README.md".into(), &read(&repo().join("README.md")), false);
    for page in pages() {
        if page == Path::new("changelog.md") {
            continue;
        }
        let performance = page == Path::new("performance.md");
        check(
            format!("docs/src/{}", page.display()),
            &read(&book_src().join(&page)),
            performance,
        );
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
    assert!(hashes("the run before c886cb6 was slower").len() == 1);
    assert!(has_date("measured 2026-12-04") && !has_date("1920x1200"));
}

#[test]
fn the_readme_is_a_short_front_door() {
    let readme = read(&repo().join("README.md"));
    let lines = readme.lines().count();
    assert!(lines <= 150, "README.md has {lines} lines (at most 150)");
    for needed in ["bash scripts/setup.sh", "bash scripts/test.sh", "docs/src/"] {
        assert!(readme.contains(needed), "README.md lacks `{needed}`");
    }
    // CI runs the README's test command: it must be the one .ci/run runs.
    let ci = read(&repo().join(".ci/run"));
    assert!(ci.contains("bash scripts/test.sh"));
}

/// How long one command of a page may take (building the VRPN server the first time is the
/// slowest).
const COMMAND_LIMIT: Duration = Duration::from_secs(300);

/// The README's test command: CI runs it, and it runs this test, so the runner does not.
const TEST_COMMAND: &str = "bash scripts/test.sh";

/// Seconds the application runs for when a page starts it (`--quit-after` is appended).
const APP_SECONDS: &str = "4";

/// A page's command as the runner executes it: `omnicave` is the built binary (on PATH);
/// `cargo run --release --` is the same binary; the application quits by itself.
fn runnable(command: &str) -> String {
    let mut command = command.trim().to_string();
    for cargo in ["cargo run --release -- ", "cargo run -- "] {
        if let Some(rest) = command.strip_prefix(cargo) {
            command = format!("omnicave {rest}");
        }
    }
    if command == "cargo run --release" || command == "omnicave" {
        command = "omnicave run --config config/desktop.toml --preview".into();
    }
    let starts_app = command.starts_with("omnicave run") || command.contains("&& omnicave run");
    if starts_app && !command.contains("--quit-after") {
        let background = command.ends_with('&');
        command = command.trim_end_matches('&').trim_end().to_string();
        command = format!("{command} --quit-after {APP_SECONDS}");
        if background {
            command.push_str(" &");
        }
    }
    command
}

/// The commands of a `sh` block: comments dropped, `\` continuations joined.
fn commands(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut current = String::new();
    for line in text.lines() {
        let line = line.trim();
        if current.is_empty() && (line.is_empty() || line.starts_with('#')) {
            continue;
        }
        match line.strip_suffix('\\') {
            Some(part) => {
                current.push_str(part);
                current.push(' ');
            }
            None => {
                current.push_str(line);
                out.push(std::mem::take(&mut current));
            }
        }
    }
    out
}

/// Runs `command` with bash in the repository, the binary first on PATH, on `display`;
/// waits at most [`COMMAND_LIMIT`].
fn run_command(command: &str, display: &str, path: &str) -> Result<(), String> {
    let mut child = Command::new("bash")
        .args(["-c", command])
        .current_dir(repo())
        .env("PATH", path)
        .env("DISPLAY", display)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            let out = child.wait_with_output().map_err(|e| e.to_string())?;
            return if status.success() {
                Ok(())
            } else {
                Err(format!(
                    "exit {status}\nstdout:\n{}\nstderr:\n{}",
                    String::from_utf8_lossy(&out.stdout),
                    String::from_utf8_lossy(&out.stderr)
                ))
            };
        }
        if start.elapsed() > COMMAND_LIMIT {
            let _ = child.kill();
            return Err(format!("still running after {COMMAND_LIMIT:?}"));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Every command on the pages a newcomer follows (Getting started, Lab setup) runs as
/// written and succeeds; a block that needs `../shared` says so when it skips (CI must not).
#[test]
fn every_command_on_the_getting_started_and_lab_setup_pages_runs() {
    let _x = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let xvfb = Xvfb::start([1920, 1080]);
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_omnicave")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let shared = repo().join("../shared").exists();
    let mut ran = 0;
    let mut failures = Vec::new();
    let newcomer_pages: Vec<PathBuf> = pages()
        .into_iter()
        .filter(|p| p == Path::new("getting-started.md") || p.starts_with("lab-setup"))
        .collect();
    assert!(newcomer_pages.len() > 5, "{newcomer_pages:?}");
    for page in newcomer_pages {
        let (_, fences) = split_code(&read(&book_src().join(&page)));
        for fence in &fences {
            let at = format!("docs/src/{}:{}", page.display(), fence.line);
            let language = fence.info.split([',', ' ']).next().unwrap_or("");
            assert!(
                !matches!(
                    language,
                    "bash" | "shell" | "console" | "shellsession" | "zsh"
                ),
                "{at}: commands on this page go in ```sh blocks (run by this test)"
            );
            if language != "sh" {
                continue;
            }
            if fence.text.contains("../shared") && !shared {
                assert!(
                    std::env::var_os("CI").is_none(),
                    "{at} needs ../shared, and CI must not skip"
                );
                eprintln!("SKIPPED: {at} needs ../shared, which is absent");
                continue;
            }
            let mut background: Vec<Child> = Vec::new();
            for command in commands(&fence.text) {
                let command = runnable(&command);
                ran += 1;
                if command == TEST_COMMAND {
                    // The command that runs this very test (CI runs exactly it).
                    continue;
                }
                if let Some(cmd) = command.strip_suffix('&') {
                    // Its own process group, so that the whole of it (a loop, a pipeline) is
                    // stopped when the block ends.
                    let child = Command::new("bash")
                        .args(["-c", cmd])
                        .process_group(0)
                        .current_dir(repo())
                        .env("PATH", &path)
                        .env("DISPLAY", &xvfb.display)
                        .stdin(Stdio::null())
                        .stdout(Stdio::null())
                        .stderr(Stdio::null())
                        .spawn()
                        .unwrap();
                    background.push(child);
                    continue;
                }
                eprintln!("{at}: {command}");
                if let Err(why) = run_command(&command, &xvfb.display, &path) {
                    failures.push(format!("{at}: `{command}`: {why}"));
                }
            }
            for mut child in background {
                let _ = Command::new("kill")
                    .args(["-TERM", "--", &format!("-{}", child.id())])
                    .status();
                let _ = child.wait();
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    assert!(ran >= 10, "only {ran} commands on the newcomer's pages");
}

#[test]
fn the_runner_rewrites_only_what_it_says() {
    assert_eq!(
        runnable("cargo run --release -- render --config config/cave.toml"),
        "omnicave render --config config/cave.toml"
    );
    assert_eq!(
        runnable("omnicave run --config config/cave.toml &"),
        "omnicave run --config config/cave.toml --quit-after 4 &"
    );
    assert_eq!(runnable("omnicave monitors"), "omnicave monitors");
    assert_eq!(
        commands("# a comment\nomnicave render \\\n  --mode stereo\n\nls out\n"),
        vec!["omnicave render  --mode stereo", "ls out"]
    );
}
