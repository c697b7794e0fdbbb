//! Degenerate (zero-area) OBJ triangles are skipped and counted: every subcommand that
//! loads a scene (render, info, bench, trace, rays) prints one warning on stderr naming
//! the mesh file and the count, and a clean mesh gives none.

mod common;

use common::cli::{check, raypack, s};
use std::path::PathBuf;

/// Four triangles: the first and last are proper, the second repeats a corner and the
/// third has collinear corners.
const DEGENERATE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 1\n\
                              f 1 2 3\nf 1 2 2\nf 1 2 4\nf 1 3 5\n";
const CLEAN_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const WARNING: &str = "degenerate.obj: 2 degenerate (zero-area) triangles skipped";

/// A scratch folder holding both meshes and a scene file for each.
fn scratch(name: &str) -> PathBuf {
    let dir = common::cli::scratch(name);
    std::fs::write(dir.join("degenerate.obj"), DEGENERATE_OBJ).unwrap();
    std::fs::write(dir.join("clean.obj"), CLEAN_OBJ).unwrap();
    let scene = |mesh: &str| {
        format!(
            "[camera]\neye = [0.3, 0.3, -3]\ntarget = [0.3, 0.3, 0]\n\
             [render]\nwidth = 16\nheight = 12\n\
             [[meshes]]\nfile = \"{mesh}\"\n\
             [[lights]]\nkind = \"point\"\nposition = [0, 0, -3]\n"
        )
    };
    std::fs::write(dir.join("degenerate.toml"), scene("degenerate.obj")).unwrap();
    std::fs::write(dir.join("clean.toml"), scene("clean.obj")).unwrap();
    dir
}

/// Runs raypack, requires success, and returns its stderr.
fn stderr_of(args: &[&str]) -> String {
    let out = raypack(args);
    check(&out, &format!("raypack {args:?}"));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The warnings in `stderr` about the input. bench's warning that other processes
/// loaded the machine during its timed passes says nothing about the mesh and comes and
/// goes with the machine, so it is not counted.
fn warnings(stderr: &str) -> usize {
    stderr
        .lines()
        .filter(|l| l.contains("warning:") && !l.contains("the machine was busy"))
        .count()
}

fn assert_one_warning(args: &[&str]) {
    let stderr = stderr_of(args);
    assert_eq!(
        stderr.matches(WARNING).count(),
        1,
        "raypack {args:?}: want `{WARNING}` once in:\n{stderr}"
    );
    assert_eq!(warnings(&stderr), 1, "{stderr}");
}

fn assert_no_warning(args: &[&str]) {
    let stderr = stderr_of(args);
    assert_eq!(warnings(&stderr), 0, "raypack {args:?}:\n{stderr}");
}

#[test]
fn every_subcommand_warns_once_about_degenerate_triangles() {
    let dir = scratch("all");
    let (obj, toml) = (dir.join("degenerate.obj"), dir.join("degenerate.toml"));
    let png = dir.join("out.png");
    assert_one_warning(&["render", s(&toml), "-o", s(&png)]);
    assert!(png.is_file(), "the image is still rendered");
    assert_one_warning(&["info", s(&obj)]);
    assert_one_warning(&["info", s(&toml)]);
    let rays = dir.join("primary.rays");
    assert_one_warning(&[
        "rays",
        s(&obj),
        "--set",
        "primary",
        "-o",
        s(&rays),
        "--width",
        "16",
        "--height",
        "16",
    ]);
    let hits = dir.join("primary.hits");
    assert_one_warning(&["trace", s(&toml), "--rays", s(&rays), "-o", s(&hits)]);
    assert_one_warning(&[
        "bench",
        s(&obj),
        "--sets",
        "primary",
        "--modes",
        "scalar",
        "--threads",
        "1",
        "--repeat",
        "1",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_clean_mesh_gives_no_warning() {
    let dir = scratch("clean");
    let png = dir.join("out.png");
    assert_no_warning(&["render", s(&dir.join("clean.toml")), "-o", s(&png)]);
    assert_no_warning(&["info", s(&dir.join("clean.obj"))]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_library_reports_one_warning_per_mesh_file() {
    let dir = scratch("lib");
    let text = format!(
        "{}[[meshes]]\nfile = \"degenerate.obj\"\ntranslate = [0, 0, 5]\n",
        std::fs::read_to_string(dir.join("degenerate.toml")).unwrap()
    );
    let path = dir.join("twice.toml");
    let (scene, warnings) = raypack::scene::file::parse_with_warnings(&path, &text).unwrap();
    assert_eq!(scene.geometry.triangles.len(), 8);
    let want = raypack::scene::Warning::DegenerateTriangles {
        path: dir.join("degenerate.obj"),
        count: 2,
        overflow: 0,
    };
    assert_eq!(warnings, vec![want.clone(), want]);
    let (_, warnings) = raypack::scene::file::load_with_warnings(&dir.join("clean.toml")).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
