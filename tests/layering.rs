//! The layering that src/lib.rs states, checked on the source text: every `crate::` and
//! `super::` path outside comments and `#[cfg(test)]` modules is resolved to the file
//! that defines it, and
//! - a file imports nothing from a top-level module above its own (the order is
//!   [`LAYERS`]; modules on one rank, such as `render` and `rayset`, do not import each
//!   other);
//! - no files import each other, directly or round a longer cycle.
//!
//! Test modules may use anything: a test of a low module can build its inputs with a
//! higher one. `src/cli` reaches the library only as `raypack::`, which is always down,
//! so only its files' imports of each other are checked.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level modules from the bottom up, with their rank: a module may import modules
/// of a lower rank and its own files only.
const LAYERS: &[(&str, u32)] = &[
    ("output", 0),
    ("rng", 0),
    ("onb", 0),
    ("simd", 0),
    ("ray", 1),
    ("geom", 2),
    // Siblings: the accelerators know geometry, never materials, cameras or loaders.
    ("scene", 3),
    ("accel", 3),
    ("render", 4),
    ("rayset", 4),
    ("prelude", 5),
    // A render set up as the command line and the Python package set it up.
    ("studio", 5),
    ("cli", 6),
];

/// Imports that break the rules today, `(from, to)` with paths relative to src/; the
/// test fails when a listed import no longer exists, so the list cannot go stale. None
/// are left.
const KNOWN: &[(&str, &str)] = &[];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
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

/// The module path of a file relative to src/ (`accel/kdtree/mod.rs` is
/// `["accel", "kdtree"]`; lib.rs and main.rs are the root).
fn module_of(rel: &str) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .trim_end_matches(".rs")
        .split('/')
        .map(String::from)
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The file (relative to src/) that defines the longest prefix of `path` that is a
/// module, or None for paths outside the crate.
fn file_of(path: &[String], files: &BTreeSet<String>) -> Option<String> {
    for n in (0..=path.len()).rev() {
        let stem = path[..n].join("/");
        if n == 0 {
            return Some("lib.rs".into());
        }
        for candidate in [format!("{stem}.rs"), format!("{stem}/mod.rs")] {
            if files.contains(&candidate) {
                return Some(candidate);
            }
        }
    }
    None
}

/// The code of a file without comments and without `#[cfg(test)]` modules (a test
/// module ends at the first `}` line at its own indentation, as rustfmt writes it).
fn code_of(text: &str) -> String {
    let mut out = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_start();
        if t.starts_with("#[cfg(test)]")
            && lines
                .peek()
                .is_some_and(|l| l.trim_start().starts_with("mod "))
        {
            let indent = line.len() - t.len();
            let close = format!("{}}}", " ".repeat(indent));
            for l in lines.by_ref() {
                if l == close {
                    break;
                }
            }
            continue;
        }
        if t.starts_with("//") {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Every `crate::a::b` and `super::a` path in `code`, with `{a::b, c}` groups expanded,
/// as segments after the keyword (`super` kept as a segment).
fn paths_in(code: &str) -> Vec<Vec<String>> {
    let bytes = code.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let rest = &code[i..];
        let starts = (rest.starts_with("crate::") || rest.starts_with("super::"))
            && (i == 0
                || !(bytes[i - 1].is_ascii_alphanumeric()
                    || bytes[i - 1] == b'_'
                    || bytes[i - 1] == b':'));
        if !starts {
            i += 1;
            continue;
        }
        // Read `seg::seg::...`.
        let mut segs = Vec::new();
        let mut j = i;
        loop {
            let k = j + code[j..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(code.len() - j);
            segs.push(code[j..k].to_string());
            j = k;
            if code[j..].starts_with("::")
                && code[j + 2..].starts_with(|c: char| c.is_alphanumeric() || c == '_')
            {
                j += 2;
            } else {
                break;
            }
        }
        if code[j..].starts_with("::{") {
            let end = j + code[j..].find('}').unwrap();
            for item in code[j + 3..end].split(',') {
                let item = item.trim();
                if item.is_empty() {
                    continue;
                }
                let mut p = segs.clone();
                p.extend(item.split("::").map(|s| s.trim().to_string()));
                out.push(p);
            }
            j = end;
        } else {
            out.push(segs);
        }
        i = j.max(i + 1);
    }
    out
}

/// Resolves a path found in the file of module `module` to absolute module segments.
fn absolute(module: &[String], path: &[String]) -> Vec<String> {
    let mut base: Vec<String>;
    let mut rest = path;
    if rest[0] == "crate" {
        base = Vec::new();
        rest = &rest[1..];
    } else {
        // `super` in a/b.rs and in a/b/mod.rs (both module a::b) is `a`.
        base = module.to_vec();
        while rest.first().is_some_and(|s| s == "super") {
            base.pop();
            rest = &rest[1..];
        }
    }
    base.extend(rest.iter().cloned());
    base
}

fn rank(top: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == top).map(|&(_, r)| r)
}

/// Each file's imports of other files, relative to src/.
fn import_graph() -> BTreeMap<String, BTreeSet<String>> {
    let root = src();
    let mut paths = Vec::new();
    rust_files(&root, &mut paths);
    let rel = |p: &Path| {
        p.strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/")
    };
    let files: BTreeSet<String> = paths.iter().map(|p| rel(p)).collect();
    let mut graph = BTreeMap::new();
    for path in &paths {
        let from = rel(path);
        let module = module_of(&from);
        let code = code_of(&std::fs::read_to_string(path).unwrap());
        let mut to = BTreeSet::new();
        for p in paths_in(&code) {
            let abs = absolute(&module, &p);
            if let Some(file) = file_of(&abs, &files)
                && file != from
            {
                to.insert(file);
            }
        }
        graph.insert(from, to);
    }
    graph
}

fn top(file: &str) -> &str {
    file.split('/').next().unwrap().trim_end_matches(".rs")
}

#[test]
fn imports_point_down_the_pipeline() {
    let graph = import_graph();
    assert!(
        graph.contains_key("scene/camera.rs"),
        "src/ not found: {:?}",
        graph.keys()
    );
    let mut bad = Vec::new();
    for (from, tos) in &graph {
        let Some(r_from) = rank(top(from)) else {
            continue; // lib.rs, main.rs
        };
        for to in tos {
            if top(to) == top(from) || to == "lib.rs" {
                continue;
            }
            let r_to = rank(top(to))
                .unwrap_or_else(|| panic!("{to}: top-level module missing from LAYERS"));
            if r_to >= r_from && !KNOWN.contains(&(from.as_str(), to.as_str())) {
                bad.push(format!("{from} imports {to}"));
            }
        }
    }
    for (m, _) in LAYERS {
        assert!(
            graph.keys().any(|f| top(f) == *m),
            "LAYERS names `{m}`, which has no file in src/"
        );
    }
    assert!(
        bad.is_empty(),
        "imports that point up or sideways:\n{}",
        bad.join("\n")
    );
}

#[test]
fn no_files_import_each_other() {
    let graph = import_graph();
    // Strongly connected components (Tarjan), known edges left out.
    let nodes: Vec<&String> = graph.keys().collect();
    let index_of: BTreeMap<&str, usize> = nodes
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let edges: Vec<Vec<usize>> = nodes
        .iter()
        .map(|from| {
            graph[*from]
                .iter()
                .filter(|to| !KNOWN.contains(&(from.as_str(), to.as_str())))
                .filter_map(|to| index_of.get(to.as_str()).copied())
                .collect()
        })
        .collect();
    let cycles = strongly_connected(&edges);
    let named: Vec<String> = cycles
        .iter()
        .filter(|c| c.len() > 1)
        .map(|c| {
            c.iter()
                .map(|&i| nodes[i].as_str())
                .collect::<Vec<_>>()
                .join(" <-> ")
        })
        .collect();
    assert!(
        named.is_empty(),
        "files that import each other:\n{}",
        named.join("\n")
    );
    // Every known exception is still there: a fixed one is taken off the list.
    for (from, to) in KNOWN {
        assert!(
            graph.get(*from).is_some_and(|t| t.contains(*to)),
            "{from} no longer imports {to}: remove the entry from KNOWN"
        );
    }
}

/// Tarjan's algorithm, iteration order fixed by node index.
fn strongly_connected(edges: &[Vec<usize>]) -> Vec<Vec<usize>> {
    struct State<'a> {
        edges: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on_stack: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(s: &mut State, v: usize) {
        s.index[v] = Some(s.next);
        s.low[v] = s.next;
        s.next += 1;
        s.stack.push(v);
        s.on_stack[v] = true;
        for &w in &s.edges[v] {
            match s.index[w] {
                None => {
                    visit(s, w);
                    s.low[v] = s.low[v].min(s.low[w]);
                }
                Some(i) if s.on_stack[w] => s.low[v] = s.low[v].min(i),
                Some(_) => {}
            }
        }
        if Some(s.low[v]) == s.index[v] {
            let mut c = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on_stack[w] = false;
                c.push(w);
                if w == v {
                    break;
                }
            }
            c.sort();
            s.out.push(c);
        }
    }
    let n = edges.len();
    let mut s = State {
        edges,
        index: vec![None; n],
        low: vec![0; n],
        on_stack: vec![false; n],
        stack: Vec::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in 0..n {
        if s.index[v].is_none() {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn the_checker_sees_paths_groups_and_skips_tests() {
    let code = code_of(
        "use crate::scene::{Geometry, file::MAX};\nuse super::x::Y;\n// crate::cli::no\n\
         fn f() { crate::accel::Accel::f(); }\n#[cfg(test)]\nmod tests {\n    use crate::render::x;\n}\n\
         fn g() {}\n",
    );
    let got = paths_in(&code);
    let want: Vec<Vec<String>> = [
        &["crate", "scene", "Geometry"][..],
        &["crate", "scene", "file", "MAX"],
        &["super", "x", "Y"],
        &["crate", "accel", "Accel", "f"],
    ]
    .iter()
    .map(|p| p.iter().map(|s| s.to_string()).collect())
    .collect();
    assert_eq!(got, want);
    assert!(code.contains("fn g()"), "code after a test module is kept");
    let module = module_of("accel/kdtree/traverse.rs");
    let abs = absolute(
        &module,
        &["super".into(), "build".into(), "MAX_DEPTH".into()],
    );
    assert_eq!(abs, ["accel", "kdtree", "build", "MAX_DEPTH"]);
    let module = module_of("accel/kdtree/mod.rs");
    let abs = absolute(&module, &["super".into(), "Prims".into()]);
    assert_eq!(abs, ["accel", "Prims"]);
    assert_eq!(
        strongly_connected(&[vec![1], vec![0], vec![0]])
            .iter()
            .filter(|c| c.len() > 1)
            .count(),
        1
    );
}
