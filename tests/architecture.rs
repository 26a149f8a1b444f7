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
//!
//! And two rules of the code that the document states: no module cycle inside any crate,
//! and no server, database, async-runtime or GPU crate below the layers that need one.

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

/// A module of a crate: its path below the crate root (empty for `lib.rs` and `main.rs`).
type ModulePath = Vec<String>;

/// The Rust files under `dir` (recursively), as paths relative to `dir`.
fn rust_files(dir: &Path, below: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir.join(below)) else {
        return;
    };
    for entry in entries.flatten() {
        let relative = below.join(entry.file_name());
        if entry.path().is_dir() {
            rust_files(dir, &relative, out);
        } else if relative.extension().is_some_and(|e| e == "rs") {
            out.push(relative);
        }
    }
}

/// The module a source file (relative to `src/`) defines: `a/b.rs` and `a/b/mod.rs` are
/// `a::b`; `lib.rs` and `main.rs` the crate root.
fn module_of(file: &Path) -> ModulePath {
    let mut parts: Vec<String> = file
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if !(stem == "mod" || (parts.is_empty() && (stem == "lib" || stem == "main"))) {
        parts.push(stem.to_string());
    }
    parts
}

/// The modules that the code lines of `source` (module `at` of a crate whose modules are
/// `known`) name through `crate::`, `super::` or a child module's name: each resolved to the
/// longest known module its path starts with.
fn imported_modules(source: &str, at: &ModulePath, known: &[ModulePath]) -> Vec<ModulePath> {
    let mut out = Vec::new();
    for line in source.lines() {
        let code = line.split("//").next().unwrap_or("");
        let words = code.split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'));
        for word in words.filter(|w| w.contains("::")) {
            let mut segments: Vec<&str> = word.split("::").filter(|s| !s.is_empty()).collect();
            let mut path: ModulePath = match segments.first() {
                Some(&"crate") => {
                    segments.remove(0);
                    Vec::new()
                }
                Some(&"super") => {
                    let mut base = at.clone();
                    while segments.first() == Some(&"super") {
                        segments.remove(0);
                        base.pop();
                    }
                    base
                }
                Some(&"self") => {
                    segments.remove(0);
                    at.clone()
                }
                Some(first) => {
                    let mut child = at.clone();
                    child.push(first.to_string());
                    if !known.contains(&child) {
                        continue;
                    }
                    at.clone()
                }
                None => continue,
            };
            let mut best = path.clone();
            for segment in segments {
                path.push(segment.to_string());
                if known.contains(&path) {
                    best = path.clone();
                }
            }
            out.push(best);
        }
    }
    out
}

/// No module of any crate imports a module that imports it back, directly or around a
/// loop (imports between a module and the modules inside it do not count: a parent hands
/// on its children's names, and a child uses its parent's).
#[test]
fn no_module_imports_one_that_imports_it_back() {
    let mut cycles = Vec::new();
    for member in workspace_members() {
        let src = root().join(member.as_str()).join("src");
        let mut files = Vec::new();
        rust_files(&src, Path::new(""), &mut files);
        files.sort();
        let modules: Vec<ModulePath> = files.iter().map(|f| module_of(f)).collect();
        let nested = |a: &ModulePath, b: &ModulePath| a.starts_with(b) || b.starts_with(a);
        let edges: Vec<Vec<usize>> = files
            .iter()
            .zip(&modules)
            .map(|(file, at)| {
                let source = std::fs::read_to_string(src.join(file)).unwrap();
                let mut to: Vec<usize> = imported_modules(&source, at, &modules)
                    .iter()
                    .filter(|m| !nested(m, at))
                    .filter_map(|m| modules.iter().position(|k| k == m))
                    .collect();
                to.sort_unstable();
                to.dedup();
                to
            })
            .collect();
        // A module is on a cycle when it can reach itself.
        for start in 0..modules.len() {
            let mut seen = vec![false; modules.len()];
            let mut stack: Vec<(usize, Vec<usize>)> = vec![(start, vec![start])];
            while let Some((node, trail)) = stack.pop() {
                for &next in &edges[node] {
                    if next == start {
                        let names: Vec<String> = trail
                            .iter()
                            .chain([&start])
                            .map(|&i| files[i].display().to_string())
                            .collect();
                        cycles.push(format!("{member}: {}", names.join(" -> ")));
                    } else if !seen[next] {
                        seen[next] = true;
                        stack.push((next, [trail.clone(), vec![next]].concat()));
                    }
                }
            }
        }
    }
    cycles.sort();
    cycles.dedup();
    assert!(cycles.is_empty(), "module cycles:\n{}", cycles.join("\n"));
}

/// The names of the `[dependencies]` of the member at `member` (not its dev-dependencies).
fn normal_dependencies(member: &str) -> Vec<String> {
    let manifest = read(&format!("{member}/Cargo.toml"));
    let mut in_table = false;
    let mut names = Vec::new();
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            in_table = line == "[dependencies]";
        } else if in_table && let Some((name, _)) = line.split_once('=') {
            names.push(name.trim().to_string());
        }
    }
    names
}

/// The layers' dependency rules that Cargo does not check by itself: the format, core,
/// bake and render crates take no server, database, async-runtime or GPU crate, and the
/// GPU and scene crates no server, database or async-runtime crate.
#[test]
fn the_lower_layers_depend_on_no_server_database_async_or_gpu_crate() {
    const SERVICE: [&str; 8] = [
        "axum",
        "hyper",
        "hyper-util",
        "object_store",
        "reqwest",
        "sqlx",
        "tokio",
        "tower-http",
    ];
    const GPU: [&str; 3] = ["wgpu", "naga", "pollster"];
    let rules: [(&str, Vec<&str>); 6] = [
        ("crates/mesobake-package", [&SERVICE[..], &GPU[..]].concat()),
        ("crates/mesobake-core", [&SERVICE[..], &GPU[..]].concat()),
        ("crates/mesobake-bake", [&SERVICE[..], &GPU[..]].concat()),
        ("crates/mesobake-render", [&SERVICE[..], &GPU[..]].concat()),
        ("crates/mesobake-gpu", SERVICE.to_vec()),
        ("crates/mesobake-scene", SERVICE.to_vec()),
    ];
    let mut failures = Vec::new();
    for (member, forbidden) in rules {
        for name in normal_dependencies(member) {
            if forbidden.contains(&name.as_str()) {
                failures.push(format!("{member} depends on {name}"));
            }
        }
    }
    assert!(failures.is_empty(), "layering: {}", failures.join("; "));
}
