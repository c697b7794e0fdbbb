//! The benchmark meshes of ../shared/scenes load with the triangle counts and bounds that
//! ../shared/scenes/README.md lists. Without the folder the tests do not run (see
//! `common::scenes`); a file missing from it fails the test, naming its path.

mod common;

use glam::Vec3;
use raypack::scene::{Aabb, Camera, Scene, obj};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn shared(scenes: &Path, rel: &str) -> PathBuf {
    let p = scenes.join(rel);
    assert!(p.is_file(), "benchmark mesh {} is missing", p.display());
    p
}

/// Loads `rel`, checks its triangle count and bounds (over used vertices), and prints the
/// load time for the record (not asserted).
fn check(
    scenes: &Path,
    rel: &str,
    triangles: usize,
    min: [f32; 3],
    max: [f32; 3],
    tol: f32,
) -> obj::ObjMesh {
    let path = shared(scenes, rel);
    let start = Instant::now();
    let m = obj::load(&path).unwrap_or_else(|e| panic!("{e}"));
    eprintln!(
        "{rel}: {} triangles, {} vertices, {} degenerate, loaded in {:.3} s",
        m.triangles.len(),
        m.positions.len(),
        m.degenerate_count,
        start.elapsed().as_secs_f64()
    );
    assert_eq!(m.triangles.len(), triangles, "{rel}");
    assert_eq!(m.normals.len(), m.positions.len());
    let mut b = Aabb::EMPTY;
    for t in &m.triangles {
        for &i in t {
            b.grow(m.positions[i as usize]);
        }
    }
    let close = |a: Vec3, e: [f32; 3]| (a - Vec3::from_array(e)).abs().max_element() <= tol;
    assert!(
        close(b.min, min) && close(b.max, max),
        "{rel}: bounds {b:?}"
    );
    m
}

#[test]
fn bunny_loads() {
    let scenes = require_scenes!();
    let m = check(
        &scenes,
        "bunny/bunny.obj",
        69_451,
        [-0.09469, 0.032987, -0.061874],
        [0.061009, 0.187321, 0.0588],
        1e-5,
    );
    assert!(m.uvs.is_empty() && m.materials.is_empty());
}

#[test]
fn sponza_loads() {
    let scenes = require_scenes!();
    check(
        &scenes,
        "sponza/sponza.obj",
        262_267,
        [-1920.9459, -126.4425, -1182.8071],
        [1799.8307, 1429.5156, 1105.4912],
        1e-3,
    );
}

#[test]
fn conference_loads() {
    let scenes = require_scenes!();
    check(
        &scenes,
        "conference/conference.obj",
        331_179,
        [-1020.13, -2.7924, -1055.66],
        [1685.81, 650.293, 668.489],
        1e-3,
    );
}

#[test]
fn cornell_box_loads_with_its_materials() {
    let scenes = require_scenes!();
    let m = check(
        &scenes,
        "cornell_box/cornell_box.obj",
        36,
        [0.0, 0.0, 0.0],
        [556.0, 548.8, 559.2],
        1e-3,
    );
    let names: Vec<&str> = m.materials.iter().map(|m| m.name.as_str()).collect();
    for n in ["white", "red", "green", "blue", "light"] {
        assert!(names.contains(&n), "material {n} missing from {names:?}");
    }
    assert!(m.tri_material.iter().all(Option::is_some));
    let red = names.iter().position(|&n| n == "red").unwrap() as u32;
    let red_count = m.tri_material.iter().filter(|&&t| t == Some(red)).count();
    assert!(red_count > 0 && red_count < 36);
    assert!(m.materials[red as usize].diffuse.x > m.materials[red as usize].diffuse.y);
}

#[test]
fn scene_from_obj_maps_mtl_colours_and_keeps_geometric_normals() {
    let scenes = require_scenes!();
    let cam = Camera {
        eye: Vec3::new(278.0, 273.0, -800.0),
        target: Vec3::new(278.0, 273.0, -799.0),
        up: Vec3::Y,
        vfov_deg: 39.3077,
    };
    let path = shared(&scenes, "cornell_box/cornell_box.obj");
    let (s, warnings) = Scene::from_obj(&path, cam.clone()).unwrap();
    let mesh = raypack::scene::obj::load(&path).unwrap();
    assert!(warnings.is_empty());
    assert_eq!(s.geometry.triangles.len(), 36);
    assert_eq!(s.prim_material.len(), 36);
    // One material per MTL material, plus the grey of triangles before any `usemtl`.
    assert_eq!(s.materials.len(), mesh.materials.len() + 1);
    for (tri, m) in mesh.tri_material.iter().enumerate() {
        let want = m.map_or(Vec3::splat(0.8), |k| mesh.materials[k as usize].diffuse);
        assert_eq!(s.material(tri as u32).color, want, "triangle {tri}");
    }
    assert!(
        s.normals.is_empty(),
        "the file has no normals: shade with geometric ones"
    );
    assert!(s.lights.is_empty());
    assert_eq!(s.camera, cam);
}
