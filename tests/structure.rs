//! The layout rules of docs/architecture.md, checked on the sources of every crate: no
//! import circle between the modules of a crate, no function over 120 lines, no library
//! struct with more than 15 public fields. The check reads the source text (a module's
//! `crate::` and `super::` paths, item boundaries at their indentation), so it needs no
//! compiler support and fails with the module, file and line it objects to.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The longest function body a library may have, in lines (signature and braces included).
const MAX_FUNCTION_LINES: usize = 120;
/// The most public fields a library struct may have.
const MAX_PUBLIC_FIELDS: usize = 15;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `src/` directory of the workspace's libraries and binaries, the facade's included.
fn source_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path().join("src"))
        .filter(|p| p.is_dir())
        .collect();
    dirs.push(root().join("src"));
    dirs.sort();
    dirs
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a source file (`crate::simulate::setup`), `crate` for a root.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    if parts == ["lib"] || parts == ["main"] || parts.is_empty() {
        return "crate".into();
    }
    format!("crate::{}", parts.join("::"))
}

/// Source text without `//` comments (doc links are not imports).
fn code_of(text: &str) -> String {
    text.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
}

/// The modules of the crate that `module`'s code names through `crate::` or `super::`
/// paths (the longest path prefix that is a module; its own ancestors left out).
fn uses(module: &str, code: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let parent: Option<Vec<&str>> =
        (module != "crate").then(|| module.rsplit_once("::").unwrap().0.split("::").collect());
    let bytes = code.as_bytes();
    let mut out = BTreeSet::new();
    for base in ["crate::", "super::"] {
        for (at, _) in code.match_indices(base) {
            if at > 0 && (bytes[at - 1].is_ascii_alphanumeric() || bytes[at - 1] == b'_') {
                continue;
            }
            let tail: String = code[at + base.len()..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let mut full: Vec<&str> = match (base, &parent) {
                ("crate::", _) => vec!["crate"],
                (_, Some(p)) => p.clone(),
                (_, None) => continue,
            };
            full.extend(tail.split("::").filter(|s| !s.is_empty()));
            for k in (1..=full.len()).rev() {
                let candidate = full[..k].join("::");
                if modules.contains(&candidate) {
                    if candidate != module
                        && !module.starts_with(&format!("{candidate}::"))
                        && candidate != "crate"
                    {
                        out.insert(candidate);
                    }
                    break;
                }
            }
        }
    }
    out
}

/// The circles of a graph: its strongly connected components of more than one module.
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let reach = |from: &String| -> BTreeSet<String> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.clone()];
        while let Some(m) = stack.pop() {
            for n in graph.get(&m).into_iter().flatten() {
                if seen.insert(n.clone()) {
                    stack.push(n.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> = graph.keys().map(|m| (m, reach(m))).collect();
    let mut found: BTreeSet<Vec<String>> = BTreeSet::new();
    for (m, r) in &reached {
        if !r.contains(*m) {
            continue;
        }
        let comp: Vec<String> =
            r.iter().filter(|n| reached.get(n).is_some_and(|back| back.contains(*m))).cloned().collect();
        if comp.len() > 1 {
            found.insert(comp);
        }
    }
    found.into_iter().collect()
}

#[test]
fn no_module_imports_in_a_circle() {
    let mut problems = vec![];
    for src in source_dirs() {
        let mut files = vec![];
        rust_files(&src, &mut files);
        let texts: BTreeMap<String, String> = files
            .iter()
            .map(|f| (module_of(&src, f), code_of(&std::fs::read_to_string(f).unwrap())))
            .collect();
        let modules: BTreeSet<String> = texts.keys().cloned().collect();
        let graph: BTreeMap<String, BTreeSet<String>> = texts
            .iter()
            .filter(|(m, _)| *m != "crate")
            .map(|(m, code)| (m.clone(), uses(m, code, &modules)))
            .collect();
        for circle in circles(&graph) {
            problems.push(format!("{}: {}", src.display(), circle.join(" <-> ")));
        }
    }
    assert!(problems.is_empty(), "module import circles:\n{}", problems.join("\n"));
}

/// The checker itself finds a circle where there is one.
#[test]
fn the_circle_check_finds_a_circle() {
    let modules: BTreeSet<String> = ["crate", "crate::a", "crate::b", "crate::c"].map(String::from).into();
    let graph: BTreeMap<String, BTreeSet<String>> = [
        ("crate::a", "use crate::b::X;"),
        ("crate::b", "fn f() { crate::c::g() }"),
        ("crate::c", "// crate::a::Y is a comment\nuse super::a::Z;"),
    ]
    .into_iter()
    .map(|(m, code)| (m.to_string(), uses(m, &code_of(code), &modules)))
    .collect();
    assert_eq!(circles(&graph), vec![vec!["crate::a".to_string(), "crate::b".into(), "crate::c".into()]]);
    let mut broken = graph.clone();
    broken.get_mut("crate::c").unwrap().clear();
    assert!(circles(&broken).is_empty());
}

/// Items of a file that break the size rules: functions over [`MAX_FUNCTION_LINES`], public
/// structs with more than [`MAX_PUBLIC_FIELDS`] public fields. An item ends at the first
/// line that is its indentation followed by `}`.
fn oversized(text: &str) -> Vec<String> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = vec![];
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let end = || (i + 1..lines.len()).find(|&j| lines[j] == format!("{indent}}}"));
        let after_vis = trimmed
            .strip_prefix("pub(crate) ")
            .or_else(|| trimmed.strip_prefix("pub(super) "))
            .or_else(|| trimmed.strip_prefix("pub "))
            .unwrap_or(trimmed);
        if after_vis.starts_with("fn ") && !line.trim_end().ends_with(';') {
            if let Some(j) = end()
                && j - i + 1 > MAX_FUNCTION_LINES
            {
                out.push(format!("line {}: a function of {} lines", i + 1, j - i + 1));
            }
        } else if trimmed.starts_with("pub struct ") && line.trim_end().ends_with('{') {
            let field = format!("{indent}    pub ");
            if let Some(j) = end() {
                let count =
                    lines[i + 1..j].iter().filter(|l| l.starts_with(&field) && l.contains(':')).count();
                if count > MAX_PUBLIC_FIELDS {
                    out.push(format!("line {}: a struct with {count} public fields", i + 1));
                }
            }
        }
    }
    out
}

#[test]
fn no_function_or_struct_too_large() {
    let mut problems = vec![];
    for src in source_dirs() {
        let mut files = vec![];
        rust_files(&src, &mut files);
        for file in files {
            for p in oversized(&std::fs::read_to_string(&file).unwrap()) {
                problems.push(format!("{}: {p}", file.display()));
            }
        }
    }
    assert!(problems.is_empty(), "over the size rules:\n{}", problems.join("\n"));
}

/// The size check finds an oversized function and struct.
#[test]
fn the_size_check_finds_large_items() {
    let long_fn = format!("fn f() {{\n{}}}\n", "    let x = 1;\n".repeat(MAX_FUNCTION_LINES));
    assert_eq!(oversized(&long_fn).len(), 1);
    let wide = format!(
        "pub struct S {{\n{}}}\n",
        (0..16).map(|k| format!("    pub f{k}: u8,\n")).collect::<String>()
    );
    assert_eq!(oversized(&wide).len(), 1);
    let fine = format!(
        "pub struct S {{\n{}}}\n",
        (0..15).map(|k| format!("    pub f{k}: u8,\n")).collect::<String>()
    );
    assert!(oversized(&fine).is_empty());
}
