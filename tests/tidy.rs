//! The house rules as a test (after rust-analyzer's `tidy`): what ARCHITECTURE.md and
//! DESIGN's house style promise is checked here, so it cannot drift.
//!
//! - every `src/**/*.rs` opens with a `//!` module doc;
//! - every module's `crate::…` paths stay inside the dependency table of ARCHITECTURE.md
//!   ("## Dependency rules"; the table is parsed from there, so it is kept in one place);
//! - nothing under `src/cli` or `benches/` reaches into `api`, and `jobs` knows nothing of it;
//! - no source file is over 600 lines before its tests;
//! - one module style: a module with submodules is a folder whose `mod.rs` declares them, a
//!   leaf module is `foo.rs`, and unit tests live in `foo/tests.rs` (no inline `mod tests {`);
//! - no test or build step reads outside the repository (the sibling folder of shared docs);
//! - the Dockerfile's build stage copies every file the binary compiles in (`include_str!`).
//!
//! Each failure names the file, the line and the rule, and says how to fix it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file below `dir`, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn rel(p: &Path) -> String {
    p.strip_prefix(root()).unwrap_or(p).display().to_string()
}

/// The top-level module a file under `src/` belongs to (`src/signal/vmd/admm.rs` → `signal`).
fn module_of(p: &Path) -> String {
    let r = p.strip_prefix(root().join("src")).expect("under src");
    let first = r.components().next().unwrap().as_os_str().to_string_lossy();
    first.trim_end_matches(".rs").to_string()
}

/// The code part of a line: no `//` comment (doc comments included), no string contents.
fn code_part(line: &str) -> String {
    let mut out = String::new();
    let mut in_str = false;
    let mut prev = ' ';
    let chars: Vec<char> = line.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if in_str {
            if c == '"' && prev != '\\' {
                in_str = false;
            }
        } else if c == '"' {
            in_str = true;
        } else if c == '/' && chars.get(i + 1) == Some(&'/') {
            break;
        } else {
            out.push(c);
        }
        prev = if prev == '\\' && c == '\\' { ' ' } else { c };
        i += 1;
    }
    out
}

/// Top-level modules named by `crate::` paths in `text` (`crate::a::b`, `crate::{a, b::c}`),
/// with the 1-based line of each use.
fn crate_uses(text: &str) -> Vec<(String, usize)> {
    let mut out = Vec::new();
    let mut pending_brace: Option<(String, usize, i32)> = None; // text so far, line, depth
    for (no, raw) in text.lines().enumerate() {
        let line = code_part(raw);
        if let Some((mut acc, at, mut depth)) = pending_brace.take() {
            for c in line.chars() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    _ => {}
                }
                acc.push(c);
                if depth == 0 {
                    break;
                }
            }
            if depth == 0 {
                out.extend(top_level_names(&acc).into_iter().map(|m| (m, at)));
            } else {
                pending_brace = Some((acc, at, depth));
            }
            continue;
        }
        let mut rest = line.as_str();
        while let Some(i) = rest.find("crate::") {
            let after = &rest[i + "crate::".len()..];
            let before_ok = i == 0
                || !rest[..i]
                    .chars()
                    .last()
                    .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$');
            if before_ok {
                if let Some(inner) = after.strip_prefix('{') {
                    let mut depth = 1;
                    let mut acc = String::new();
                    for c in inner.chars() {
                        match c {
                            '{' => depth += 1,
                            '}' => depth -= 1,
                            _ => {}
                        }
                        if depth == 0 {
                            break;
                        }
                        acc.push(c);
                    }
                    if depth == 0 {
                        out.extend(top_level_names(&acc).into_iter().map(|m| (m, no + 1)));
                    } else {
                        pending_brace = Some((acc, no + 1, depth));
                    }
                } else {
                    let name: String = after
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        out.push((name, no + 1));
                    }
                }
            }
            rest = &rest[i + "crate::".len()..];
        }
    }
    out
}

/// The first path segment of each comma-separated item at brace depth 0 of `group`.
fn top_level_names(group: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut depth = 0;
    let mut item = String::new();
    for c in group.chars().chain(std::iter::once(',')) {
        match c {
            '{' => {
                depth += 1;
                item.push(c);
            }
            '}' => {
                depth -= 1;
                item.push(c);
            }
            ',' if depth == 0 => {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() && name != "self" {
                    names.push(name);
                }
                item.clear();
            }
            _ => item.push(c),
        }
    }
    names
}

/// The dependency table of ARCHITECTURE.md: rows `| `module` | `a`, `b` |` under the
/// heading "## Dependency rules" (a row's second cell may say "anything except `x`, `y`").
#[derive(Debug)]
enum Allowed {
    Only(BTreeSet<String>),
    AllExcept(BTreeSet<String>),
}

fn dependency_table() -> BTreeMap<String, Allowed> {
    let text = std::fs::read_to_string(root().join("ARCHITECTURE.md"))
        .expect("ARCHITECTURE.md at the repository root");
    let start = text
        .find("## Dependency rules")
        .expect("ARCHITECTURE.md has a '## Dependency rules' section");
    let mut table = BTreeMap::new();
    for line in text[start..].lines().skip(1) {
        if line.starts_with("## ") {
            break;
        }
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 4 || !cells[1].starts_with('`') {
            continue;
        }
        let names = |s: &str| -> BTreeSet<String> {
            s.split('`')
                .skip(1)
                .step_by(2)
                .map(str::to_string)
                .collect()
        };
        let module = cells[1].trim_matches('`').to_string();
        let allowed = if cells[2].starts_with("anything") {
            Allowed::AllExcept(names(cells[2]))
        } else {
            Allowed::Only(names(cells[2]))
        };
        table.insert(module, allowed);
    }
    assert!(
        table.len() >= 10,
        "ARCHITECTURE.md's dependency table has {} rows; expected one per module",
        table.len()
    );
    table
}

#[test]
fn every_source_file_opens_with_a_module_doc() {
    let mut bad = Vec::new();
    for f in rust_files(&root().join("src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
        if !first.starts_with("//!") {
            bad.push(rel(&f));
        }
    }
    assert!(
        bad.is_empty(),
        "these files do not open with a `//!` module doc (say what the file is and, for \
         hand-written numerics, why no crate does it): {bad:#?}"
    );
}

#[test]
fn modules_use_only_what_the_dependency_table_allows() {
    let table = dependency_table();
    let modules: BTreeSet<String> = rust_files(&root().join("src"))
        .iter()
        .map(|f| module_of(f))
        .filter(|m| m != "lib" && m != "main")
        .collect();
    let unlisted: Vec<&String> = modules.iter().filter(|m| !table.contains_key(*m)).collect();
    assert!(
        unlisted.is_empty(),
        "modules missing from ARCHITECTURE.md's dependency table: {unlisted:?}; add a row \
         saying what each may use"
    );
    let mut bad = Vec::new();
    for f in rust_files(&root().join("src")) {
        let m = module_of(&f);
        let Some(allowed) = table.get(&m) else {
            continue;
        };
        let text = std::fs::read_to_string(&f).unwrap();
        for (used, line) in crate_uses(&text) {
            if used == m || !modules.contains(&used) {
                continue; // itself, or a macro/`crate::` item that is not a module
            }
            let ok = match allowed {
                Allowed::Only(set) => set.contains(&used),
                Allowed::AllExcept(set) => !set.contains(&used),
            };
            if !ok {
                bad.push(format!(
                    "{}:{line}: `{m}` uses `crate::{used}`, which ARCHITECTURE.md's \
                     dependency table does not allow",
                    rel(&f)
                ));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "dependency rule broken (move the code to the module that may use it, or pass the \
         value in):\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_cli_and_benches_do_not_reach_into_api() {
    let mut bad = Vec::new();
    let mut files = rust_files(&root().join("src/cli"));
    files.extend(rust_files(&root().join("benches")));
    files.push(root().join("src/jobs.rs"));
    files.extend(rust_files(&root().join("src/jobs")));
    for f in files.into_iter().filter(|f| f.exists()) {
        let text = std::fs::read_to_string(&f).unwrap();
        for (no, line) in text.lines().enumerate() {
            let code = code_part(line);
            if code.contains("truecut::api") || code.contains("crate::api") {
                bad.push(format!("{}:{}: {}", rel(&f), no + 1, line.trim()));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "the CLI, the benches and jobs call cores, never HTTP handlers (shared body types \
         live in `wire`):\n{}",
        bad.join("\n")
    );
}

#[test]
fn no_source_file_is_over_600_lines_before_its_tests() {
    let mut bad = Vec::new();
    for f in rust_files(&root().join("src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        let n = text
            .lines()
            .position(|l| l.trim_start().starts_with("#[cfg(test)]"))
            .unwrap_or_else(|| text.lines().count());
        if n > 600 {
            bad.push(format!("{}: {n} lines", rel(&f)));
        }
    }
    assert!(
        bad.is_empty(),
        "split these along their own seams (one concept per file, aim 400): {bad:#?}"
    );
}

#[test]
fn one_module_style_with_tests_in_their_own_file() {
    let mut bad = Vec::new();
    for f in rust_files(&root().join("src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        if text
            .lines()
            .any(|l| l.trim_start().starts_with("mod tests {"))
        {
            bad.push(format!(
                "{}: inline `mod tests {{`; move it to tests.rs",
                rel(&f)
            ));
        }
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        if name != "mod.rs" && name != "tests.rs" {
            let folder = f.with_extension("");
            if let Ok(entries) = std::fs::read_dir(&folder) {
                let others: Vec<String> = entries
                    .flatten()
                    .map(|e| e.file_name().to_string_lossy().to_string())
                    .filter(|n| n != "tests.rs")
                    .collect();
                if !others.is_empty() {
                    bad.push(format!(
                        "{}: has submodules {others:?} beside it; make it {}/mod.rs",
                        rel(&f),
                        rel(&folder)
                    ));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "one module style (folders with mod.rs, tests in foo/tests.rs):\n{}",
        bad.join("\n")
    );
}

#[test]
fn nothing_reads_outside_the_repository() {
    let mut bad = Vec::new();
    let mut files = rust_files(&root().join("src"));
    files.extend(rust_files(&root().join("tests")));
    files.extend(rust_files(&root().join("benches")));
    files.push(root().join("build.rs"));
    for f in files.into_iter().filter(|f| f.exists()) {
        let text = std::fs::read_to_string(&f).unwrap();
        for (no, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            // The patterns are built, not written, so that this file does not match itself.
            let sibling = ["..", "shared"].join("/");
            let reference = ["", "shared", "reference"].join("/");
            if code.contains(&sibling) || code.contains(&reference) {
                bad.push(format!("{}:{}: {}", rel(&f), no + 1, line.trim()));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "a clone stands alone: vendor what these read under tests/data/ (with its origin in \
         tests/data/README.md):\n{}",
        bad.join("\n")
    );
}

/// The container build copies only what the Dockerfile names: a file compiled in with
/// `include_str!`/`include_bytes!` from outside `src/` must lie under a copied path (the
/// dashboard's assets were once missing, and the image did not build).
#[test]
fn the_dockerfile_copies_what_the_binary_compiles_in() {
    let docker = std::fs::read_to_string(root().join("Dockerfile")).unwrap();
    // the text between the first and the second FROM (the comments above the first are skipped)
    let build_stage = docker.split("\nFROM ").nth(1).unwrap_or("");
    let copied: Vec<String> = build_stage
        .lines()
        .filter_map(|l| l.trim().strip_prefix("COPY "))
        .filter(|l| !l.starts_with("--from"))
        .flat_map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            let sources = &words[..words.len().saturating_sub(1)];
            sources
                .iter()
                .map(|w| w.trim_end_matches('/').to_string())
                .collect::<Vec<_>>()
        })
        .collect();
    let mut bad = Vec::new();
    for f in rust_files(&root().join("src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        for (no, line) in text.lines().enumerate() {
            for mac in ["include_str!(\"", "include_bytes!(\""] {
                let Some(at) = line.find(mac) else { continue };
                let arg = &line[at + mac.len()..];
                let Some(end) = arg.find('"') else { continue };
                let target = f.parent().unwrap().join(&arg[..end]);
                let Ok(target) = target.canonicalize() else {
                    bad.push(format!(
                        "{}:{}: {} does not exist",
                        rel(&f),
                        no + 1,
                        &arg[..end]
                    ));
                    continue;
                };
                let inside = rel(&target);
                if !copied
                    .iter()
                    .any(|c| inside == *c || inside.starts_with(&format!("{c}/")))
                {
                    bad.push(format!("{}:{}: {inside}", rel(&f), no + 1));
                }
            }
        }
    }
    assert!(
        !copied.is_empty(),
        "no COPY lines found in the Dockerfile's build stage"
    );
    assert!(
        bad.is_empty(),
        "the Dockerfile's build stage copies {copied:?} but the binary compiles in files \
         outside them; add a COPY line:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_use_scanner_reads_grouped_and_nested_paths() {
    let text = "use crate::{signal::x, geometry::{a, b}, self};\nlet v = crate::nn::f();\n\
                // crate::api in a comment\nuse crate::{\n    motion,\n    gap::y,\n};\n";
    let got: Vec<(String, usize)> = crate_uses(text);
    let names: Vec<&str> = got.iter().map(|(m, _)| m.as_str()).collect();
    assert_eq!(names, ["signal", "geometry", "nn", "motion", "gap"]);
    assert_eq!(got[3].1, 4);
}
