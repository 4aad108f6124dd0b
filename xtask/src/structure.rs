//! Structure rules `cargo xtask test` checks on every library and binary source (`src/` of each
//! crate; tests, benches and examples are test code):
//!
//! - no file holds more than [`MAX_LINES`] lines before its `#[cfg(test)]` module (one idea per
//!   file: split by concept);
//! - no `clippy::too_many_arguments` allowance (group what travels together in a struct);
//! - no import cycle between modules. A crate's modules form a tree; an import from module A to
//!   module B (`use crate::…`, `use super::…`, or a path written inline) ties the two children
//!   of their nearest common ancestor that hold them, and those ties must not form a cycle
//!   among any module's children. A module and its own submodules may use each other (a
//!   submodule sees its parent's items), as a folder is one unit seen from outside.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Lines a source file may hold before its tests.
pub const MAX_LINES: usize = 800;

/// A module's path from the crate root (`[]` is the root).
type ModPath = Vec<String>;

/// Every rule broken under `root` (the workspace), as messages naming the file.
pub fn check(root: &Path) -> Result<Vec<String>, String> {
    let mut problems = Vec::new();
    for src in source_roots(root)? {
        let files = rust_files(&src)?;
        for f in &files {
            let text = std::fs::read_to_string(f).map_err(|e| format!("{}: {e}", f.display()))?;
            let rel = f.strip_prefix(root).unwrap_or(f).display().to_string();
            let lines = code_before_tests(&text).lines().count();
            if lines > MAX_LINES {
                problems.push(format!(
                    "{rel}: {lines} lines before its tests (at most {MAX_LINES}): split it by concept"
                ));
            }
            let allowance = ["clippy::", "too_many_arguments"].concat();
            if text
                .lines()
                .any(|l| l.contains("allow(") && l.contains(&allowance))
            {
                problems.push(format!(
                    "{rel}: a too_many_arguments allowance: group the arguments that travel together"
                ));
            }
        }
        let rel = src.strip_prefix(root).unwrap_or(&src).to_path_buf();
        problems.extend(
            cycles(&src, &files)?
                .into_iter()
                .map(|m| format!("{}: {m}", rel.display())),
        );
    }
    Ok(problems)
}

/// `src/` of every crate of the workspace (crates/*, xtask, tests, android when present).
fn source_roots(root: &Path) -> Result<Vec<PathBuf>, String> {
    let mut roots = Vec::new();
    let crates = root.join("crates");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&crates)
        .map_err(|e| format!("{}: {e}", crates.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    dirs.extend(["xtask", "tests", "android"].iter().map(|d| root.join(d)));
    dirs.sort();
    for d in dirs {
        let src = d.join("src");
        if src.join("lib.rs").is_file() || src.join("main.rs").is_file() {
            roots.push(src);
        }
    }
    Ok(roots)
}

fn rust_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).map_err(|e| format!("{}: {e}", d.display()))? {
            let p = e.map_err(|e| e.to_string())?.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// The text before the first `#[cfg(test)]` at the start of a line.
fn code_before_tests(text: &str) -> &str {
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        if line.starts_with("#[cfg(test)]") {
            return &text[..at];
        }
        at += line.len();
    }
    text
}

/// The module a file under `src` is: `lib.rs`/`main.rs` the root, `a/mod.rs` and `a.rs` module
/// `a`, `a/b.rs` module `a::b`.
fn module_of(src: &Path, file: &Path) -> ModPath {
    let rel = file.strip_prefix(src).unwrap_or(file);
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    if let Some(last) = parts.pop() {
        let stem = last.trim_end_matches(".rs");
        let is_root = parts.is_empty() && (stem == "lib" || stem == "main");
        if stem != "mod" && !is_root {
            parts.push(stem.to_string());
        }
    }
    parts
}

/// The crate-relative paths a file's code names: `use` trees expanded, and `crate::…`,
/// `super::…`, `self::…` paths written inline, resolved against the file's module `at`.
fn referenced_paths(code: &str, at: &ModPath) -> Vec<ModPath> {
    // Comments (docs included) name paths too; only code counts.
    let code: String = code
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let code = code.as_str();
    let mut out = Vec::new();
    let bytes = code.as_bytes();
    // `use` statements: the tree up to the `;`.
    let mut i = 0;
    while let Some(pos) = code[i..].find("use ") {
        let start = i + pos;
        i = start + 4;
        let before = start.checked_sub(1).map(|b| bytes[b]);
        if before.is_some_and(|b| b.is_ascii_alphanumeric() || b == b'_') {
            continue;
        }
        let Some(end) = code[i..].find(';') else {
            break;
        };
        let tree: String = code[i..i + end]
            .replace(" as ", "@")
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect();
        for p in expand_use(&tree) {
            out.extend(resolve(&p, at));
        }
        i += end;
    }
    // Inline paths.
    for prefix in ["crate::", "super::", "self::"] {
        let mut j = 0;
        while let Some(pos) = code[j..].find(prefix) {
            let start = j + pos;
            j = start + prefix.len();
            let before = start.checked_sub(1).map(|b| bytes[b]);
            if before.is_some_and(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b':') {
                continue;
            }
            let path: String = code[start..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let segments: Vec<String> = path
                .split("::")
                .filter(|s| !s.is_empty())
                .map(String::from)
                .collect();
            out.extend(resolve(&segments, at));
        }
    }
    out.sort();
    out.dedup();
    out
}

/// `a::{b, c::{d, e}}` -> `a::b`, `a::c::d`, `a::c::e` (whitespace already removed, `x as y`
/// written `x@y`).
fn expand_use(tree: &str) -> Vec<Vec<String>> {
    let tree = tree.trim_start_matches("::");
    let Some(open) = tree.find('{') else {
        // `path as name` arrives as `path@name`.
        let path = tree.split('@').next().unwrap_or(tree);
        return vec![path
            .split("::")
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect()];
    };
    let prefix: Vec<String> = tree[..open]
        .split("::")
        .filter(|s| !s.is_empty())
        .map(String::from)
        .collect();
    let inner = tree[open + 1..]
        .strip_suffix('}')
        .unwrap_or(&tree[open + 1..]);
    let mut out = Vec::new();
    let mut depth = 0;
    let mut item = String::new();
    for c in inner.chars().chain(std::iter::once(',')) {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                for mut p in expand_use(&item) {
                    let mut full = prefix.clone();
                    full.append(&mut p);
                    out.push(full);
                }
                item.clear();
                continue;
            }
            _ => {}
        }
        item.push(c);
    }
    out
}

/// A path as written, from module `at`, to a crate-relative path; `None` for paths outside the
/// crate (another crate, std).
fn resolve(path: &[String], at: &ModPath) -> Option<ModPath> {
    let mut base: ModPath;
    let mut rest = path;
    match path.first().map(String::as_str) {
        Some("crate") => {
            base = Vec::new();
            rest = &path[1..];
        }
        Some("super") | Some("self") => {
            base = at.clone();
            while let Some(s) = rest.first() {
                match s.as_str() {
                    "super" => {
                        base.pop()?;
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        _ => return None,
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The longest prefix of `path` that is a module of the crate.
fn deepest_module(path: &ModPath, modules: &BTreeSet<ModPath>) -> ModPath {
    let mut best = Vec::new();
    for k in 1..=path.len() {
        if modules.contains(&path[..k].to_vec()) {
            best = path[..k].to_vec();
        }
    }
    best
}

/// The import cycles among sibling modules of the crate whose sources are `files` under `src`.
fn cycles(src: &Path, files: &[PathBuf]) -> Result<Vec<String>, String> {
    let modules: BTreeSet<ModPath> = files.iter().map(|f| module_of(src, f)).collect();
    // (parent, child a, child b) -> one file-level import that ties them, for the message.
    let mut ties: BTreeMap<(ModPath, String, String), String> = BTreeMap::new();
    for f in files {
        let text = std::fs::read_to_string(f).map_err(|e| format!("{}: {e}", f.display()))?;
        let from = module_of(src, f);
        for path in referenced_paths(code_before_tests(&text), &from) {
            let to = deepest_module(&path, &modules);
            let common = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
            if common == from.len() || common == to.len() {
                continue; // an ancestor or a descendant: one unit seen from outside
            }
            let parent = from[..common].to_vec();
            let key = (parent, from[common].clone(), to[common].clone());
            ties.entry(key)
                .or_insert_with(|| format!("{} uses {}", from.join("::"), path.join("::")));
        }
    }
    let mut by_parent: BTreeMap<ModPath, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (parent, a, b) in ties.keys() {
        by_parent
            .entry(parent.clone())
            .or_default()
            .entry(a.clone())
            .or_default()
            .insert(b.clone());
    }
    let mut out = Vec::new();
    for (parent, edges) in by_parent {
        for scc in strongly_connected(&edges) {
            let evidence: Vec<String> = scc
                .iter()
                .flat_map(|a| {
                    scc.iter()
                        .filter_map(|b| ties.get(&(parent.clone(), a.clone(), b.clone())).cloned())
                })
                .collect();
            out.push(format!(
                "an import cycle among the modules {{{}}} of `{}`: {}",
                scc.join(", "),
                if parent.is_empty() {
                    "crate".to_string()
                } else {
                    parent.join("::")
                },
                evidence.join("; ")
            ));
        }
    }
    Ok(out)
}

/// Strongly connected components of more than one node (Tarjan).
fn strongly_connected(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'e> {
        edges: &'e BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'e str, usize>,
        low: BTreeMap<&'e str, usize>,
        stack: Vec<&'e str>,
        on_stack: BTreeSet<&'e str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'e>(s: &mut State<'e>, v: &'e str) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        s.on_stack.insert(v);
        let targets: Vec<&'e str> = s
            .edges
            .get(v)
            .map(|t| t.iter().map(String::as_str).collect())
            .unwrap_or_default();
        for w in targets {
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low[v];
                s.low.insert(v, lv.min(lw));
            } else if s.on_stack.contains(w) {
                let iw = s.index[w];
                let lv = s.low[v];
                s.low.insert(v, lv.min(iw));
            }
        }
        if s.low[v] == s.index[v] {
            let mut scc = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                scc.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if scc.len() > 1 {
                scc.sort();
                s.out.push(scc);
            }
        }
    }
    let mut s = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Vec<String> {
        s.split("::")
            .filter(|x| !x.is_empty())
            .map(String::from)
            .collect()
    }

    #[test]
    fn use_trees_expand_to_every_path() {
        assert_eq!(
            expand_use("crate::plan::{Plan,memory::{AliasAssignment,MemorySlot},Step}"),
            [
                p("crate::plan::Plan"),
                p("crate::plan::memory::AliasAssignment"),
                p("crate::plan::memory::MemorySlot"),
                p("crate::plan::Step")
            ]
        );
        assert_eq!(
            expand_use("super::access::Access"),
            [p("super::access::Access")]
        );
    }

    #[test]
    fn paths_resolve_from_the_file_module() {
        let at = p("compile::barriers");
        assert_eq!(
            resolve(&p("super::access::Access"), &at),
            Some(p("compile::access::Access"))
        );
        assert_eq!(resolve(&p("crate::plan::Step"), &at), Some(p("plan::Step")));
        assert_eq!(resolve(&p("self::x"), &at), Some(p("compile::barriers::x")));
        assert_eq!(resolve(&p("std::sync::Arc"), &at), None);
    }

    #[test]
    fn a_cycle_between_siblings_is_found_and_parents_and_children_are_one_unit() {
        let dir = std::env::temp_dir().join(format!("xtask-structure-{}", std::process::id()));
        let src = dir.join("src");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(src.join("a")).unwrap();
        let write = |rel: &str, text: &str| std::fs::write(src.join(rel), text).unwrap();
        write("lib.rs", "mod a;\nmod b;\nmod c;\n");
        // a/mod.rs and its child use each other: allowed.
        write("a/mod.rs", "mod inner;\nuse inner::X;\npub struct Y;\n");
        write(
            "a/inner.rs",
            "use super::Y;\npub struct X;\nfn f() { crate::b::g(); }\n",
        );
        // b -> c inline, c -> a::inner through a use tree: a -> b -> c -> a.
        write("b.rs", "pub fn g() { crate::c::h(); }\n");
        write("c.rs", "use crate::{a::inner::X, b};\npub fn h() {}\n#[cfg(test)]\nmod tests { use crate::a::Y; }\n");
        let files = rust_files(&src).unwrap();
        let found = cycles(&src, &files).unwrap();
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(
            found[0].contains("{a, b, c}") && found[0].contains("`crate`"),
            "{found:?}"
        );
        // Without c -> a the cycle is gone (the tests module does not count).
        write(
            "c.rs",
            "pub fn h() {}\n#[cfg(test)]\nmod tests { use crate::a::Y; }\n",
        );
        assert!(cycles(&src, &files).unwrap().is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn renamed_imports_keep_their_path() {
        let at = p("renderer");
        let code = "use crate::cull::Culling as C;\nuse tilegraph_graph::Plan;\n";
        assert_eq!(referenced_paths(code, &at), [p("cull::Culling")]);
        // Comments do not count.
        assert!(referenced_paths("// see crate::cull::add_cull\n", &at).is_empty());
    }
}
