//! Keeps `ARCHITECTURE.md` in step with the code it maps. The document names things in code
//! spans (text between backticks, outside fenced code blocks), and these tests hold it to
//! four rules:
//!
//! 1. every member of `[workspace] members` in `Cargo.toml` other than `.` is named by its
//!    directory, e.g. `crates/mesobake-render`;
//! 2. every top-level module of a crate (a line `mod x;` or `pub mod x;` at the start of a
//!    line of its `src/lib.rs`, and for the root package of `src/main.rs` too) is named in
//!    that crate's part of the document by a code span whose last component is `x`: `x`,
//!    `x.rs`, `x/`, `src/x/` or `mesobake_render::x`. A crate's part is the section under
//!    the heading that names its directory; the root package's part is every section whose
//!    heading names a path under `src/`;
//! 3. the document is at most 16,000 bytes;
//! 4. every code span that looks like a repository path (it contains `/` and starts with
//!    `src/`, `crates/`, `shaders/`, `tests/`, `docs/`, `scenes/`, `migrations/` or
//!    `config/`) names a file or directory that exists.

use std::path::Path;

const DOCUMENT: &str = "ARCHITECTURE.md";
const MAX_BYTES: usize = 16_000;
const PATH_PREFIXES: [&str; 8] = [
    "src/",
    "crates/",
    "shaders/",
    "tests/",
    "docs/",
    "scenes/",
    "migrations/",
    "config/",
];

/// The repository root (the root package's directory).
fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The text of `relative` under the repository root.
fn read(relative: &str) -> String {
    std::fs::read_to_string(root().join(relative))
        .unwrap_or_else(|e| panic!("cannot read {relative}: {e}"))
}

/// `text` without its fenced code blocks (the fences included).
fn prose(text: &str) -> String {
    let mut out = String::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// The code spans of `text` outside fenced code blocks, trimmed.
fn code_spans(text: &str) -> Vec<String> {
    prose(text)
        .split('`')
        .skip(1)
        .step_by(2)
        .map(|s| s.trim().to_string())
        .collect()
}

/// The document's sections outside fenced code blocks: (heading line, the text from the
/// heading to the next heading); the text before the first heading has an empty heading.
fn sections(doc: &str) -> Vec<(String, String)> {
    let mut out = vec![(String::new(), String::new())];
    for line in prose(doc).lines() {
        if line.starts_with('#') {
            out.push((line.to_string(), String::new()));
        }
        let body = &mut out.last_mut().expect("one section at least").1;
        body.push_str(line);
        body.push('\n');
    }
    out
}

/// `span` without a trailing `/`.
fn directory(span: &str) -> &str {
    span.trim_end_matches('/')
}

/// The last component of a code span: `x` for `x`, `x.rs`, `x/`, `src/x/` or `a::x`.
fn last_component(span: &str) -> &str {
    let s = directory(span);
    let s = s.strip_suffix(".rs").unwrap_or(s);
    let s = s.rsplit("::").next().unwrap_or(s);
    s.rsplit('/').next().unwrap_or(s)
}

/// The members of `[workspace] members` in `Cargo.toml`, as written (`.` included).
fn workspace_members() -> Vec<String> {
    let manifest = read("Cargo.toml");
    let table = manifest
        .find("[workspace]")
        .map(|i| &manifest[i..])
        .expect("Cargo.toml has a [workspace] table");
    let key = table.find("members").expect("[workspace] has members");
    let open = key + table[key..].find('[').expect("members is an array");
    let close = open + table[open..].find(']').expect("members' array is closed");
    table[open + 1..close]
        .lines()
        .map(|line| line.split('#').next().unwrap_or(""))
        .flat_map(|line| line.split(','))
        .map(|m| m.trim().trim_matches('"').to_string())
        .filter(|m| !m.is_empty())
        .collect()
}

/// The top-level modules `source` declares: its lines `mod x;`, `pub mod x;` and
/// `pub(crate) mod x;` that start at the beginning of the line.
fn declared_modules(source: &str) -> Vec<String> {
    source
        .lines()
        .filter(|line| !line.starts_with(char::is_whitespace))
        .filter_map(|line| {
            let line = line.split("//").next().unwrap_or("").trim_end();
            let rest = line
                .strip_prefix("pub ")
                .or_else(|| line.strip_prefix("pub(crate) "))
                .unwrap_or(line);
            let name = rest.strip_prefix("mod ")?.strip_suffix(';')?.trim();
            let ident =
                !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            ident.then(|| name.to_string())
        })
        .collect()
}

/// The Rust files of member `member` whose top-level modules the document must name: its
/// `src/lib.rs`, and the root package's `src/main.rs` too (where they exist).
fn module_roots(member: &str) -> Vec<String> {
    let prefix = if member == "." {
        String::new()
    } else {
        format!("{member}/")
    };
    let mut files = vec![format!("{prefix}src/lib.rs")];
    if member == "." {
        files.push("src/main.rs".to_string());
    }
    files.retain(|f| root().join(f).is_file());
    files
}

/// Every workspace member under `crates/` (all but the root package) is named by its directory.
#[test]
fn every_workspace_member_is_named() {
    let doc = read(DOCUMENT);
    let spans = code_spans(&doc);
    let missing: Vec<String> = workspace_members()
        .into_iter()
        .filter(|m| m != ".")
        .filter(|m| !spans.iter().any(|s| directory(s) == directory(m)))
        .collect();
    assert!(
        missing.is_empty(),
        "{DOCUMENT} does not name these workspace members (as `crates/...` in backticks): {}",
        missing.join(", ")
    );
}

/// Every top-level module of every crate is named in its crate's part of the document.
#[test]
fn every_top_level_module_is_named_in_its_crates_section() {
    let doc = read(DOCUMENT);
    let sections = sections(&doc);
    let mut failures = Vec::new();
    for member in workspace_members() {
        let part: Vec<&(String, String)> = sections
            .iter()
            .filter(|(heading, _)| {
                code_spans(heading).iter().any(|s| {
                    if member == "." {
                        s.starts_with("src/")
                    } else {
                        directory(s) == directory(&member)
                    }
                })
            })
            .collect();
        let spans: Vec<String> = part.iter().flat_map(|(_, body)| code_spans(body)).collect();
        for file in module_roots(&member) {
            let modules = declared_modules(&read(&file));
            if part.is_empty() && !modules.is_empty() {
                failures.push(if member == "." {
                    format!("no heading of {DOCUMENT} names a path under `src/` (the root package)")
                } else {
                    format!("no heading of {DOCUMENT} names `{member}`, whose modules it must name")
                });
                break;
            }
            for module in modules {
                if !spans.iter().any(|s| last_component(s) == module) {
                    failures.push(format!(
                        "module `{module}` of {file} is not named in its crate's section"
                    ));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{DOCUMENT} is stale:\n{}",
        failures.join("\n")
    );
}

/// The document stays short enough to read: at most 16,000 bytes.
#[test]
fn the_document_is_at_most_16000_bytes() {
    let len = read(DOCUMENT).len();
    assert!(
        len <= MAX_BYTES,
        "{DOCUMENT} is {len} bytes, over the limit of {MAX_BYTES}: shorten it"
    );
}

/// Every repository path the document writes in backticks exists.
#[test]
fn every_path_in_backticks_exists() {
    let doc = read(DOCUMENT);
    let mut missing: Vec<String> = code_spans(&doc)
        .into_iter()
        .filter(|s| s.contains('/') && PATH_PREFIXES.iter().any(|p| s.starts_with(p)))
        .filter(|s| !root().join(s).exists())
        .collect();
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "{DOCUMENT} names paths that do not exist: {}",
        missing.join(", ")
    );
}
