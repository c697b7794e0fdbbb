//! The README's library example is the crate docs' quick start (a doc test that
//! `cargo test` runs), line for line: the README cannot show code that does not build.

use std::path::Path;

/// The visible lines of the first code block of src/lib.rs's crate docs (lines hidden
/// with `# ` left out).
fn quick_start() -> Vec<String> {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    let doc: Vec<&str> = lib
        .lines()
        .take_while(|l| l.starts_with("//!"))
        .map(|l| {
            l.strip_prefix("//! ")
                .unwrap_or(l.trim_start_matches("//!"))
        })
        .collect();
    let open = doc.iter().position(|l| *l == "```").expect("a code block");
    let close = open + 1 + doc[open + 1..].iter().position(|l| *l == "```").unwrap();
    doc[open + 1..close]
        .iter()
        .filter(|l| !(l.starts_with("# ") || **l == "#"))
        .map(|l| l.to_string())
        .collect()
}

/// The indented code block of the README's "raypack as a library" section.
fn readme_example() -> Vec<String> {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let section = readme
        .split("\n## ")
        .find(|s| s.starts_with("raypack as a library"))
        .expect("a section \"raypack as a library\"");
    let lines: Vec<&str> = section.lines().collect();
    let first = lines.iter().position(|l| l.starts_with("    ")).unwrap();
    let mut block: Vec<String> = lines[first..]
        .iter()
        .take_while(|l| l.is_empty() || l.starts_with("    "))
        .map(|l| l.strip_prefix("    ").unwrap_or("").to_string())
        .collect();
    while block.last().is_some_and(String::is_empty) {
        block.pop();
    }
    block
}

#[test]
fn the_readme_library_example_is_the_tested_quick_start() {
    let (readme, docs) = (readme_example(), quick_start());
    assert!(readme.len() > 10, "{readme:?}");
    assert_eq!(
        readme, docs,
        "README.md's example and src/lib.rs's quick start differ"
    );
}
