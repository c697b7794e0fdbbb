//! Helpers shared by the integration tests: the benchmark scenes of ../shared/scenes
//! (a minimal OBJ reader for positions and faces, and the cameras), and ray sets.

#![allow(dead_code)]

use glam::Vec3;
use raypack::ray::Ray;
use raypack::scene::generate::Rng;
use raypack::scene::{Camera, Geometry};
use std::path::{Path, PathBuf};

/// `../shared/scenes`, relative to the crate root. Panics, naming the path, when absent:
/// tests that need the benchmark scenes never skip quietly.
pub fn shared_scenes() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    assert!(
        dir.join("cameras.toml").is_file(),
        "benchmark scenes missing: expected {} (with cameras.toml)",
        dir.display()
    );
    dir
}

/// The geometry (positions and fan-triangulated faces, in RAYS.md order) and camera of
/// benchmark scene `name` from cameras.toml.
pub fn shared_scene(name: &str) -> (Geometry, Camera) {
    let dir = shared_scenes();
    let cameras_path = dir.join("cameras.toml");
    let text = std::fs::read_to_string(&cameras_path).expect("read cameras.toml");
    let table: toml::Table = text.parse().expect("parse cameras.toml");
    let entry = table[name].as_table().expect("scene table");
    let vec3 = |key: &str| {
        let a = entry[key].as_array().expect(key);
        let f = |i: usize| a[i].as_float().expect(key) as f32;
        Vec3::new(f(0), f(1), f(2))
    };
    let camera = Camera {
        eye: vec3("eye"),
        target: vec3("target"),
        up: vec3("up"),
        vfov_deg: entry["vfov_deg"].as_float().expect("vfov_deg") as f32,
    };
    let obj = dir.join(entry["obj"].as_str().expect("obj"));
    let g = read_obj(&obj);
    let expected = entry["triangles"].as_integer().expect("triangles") as usize;
    assert_eq!(g.triangles.len(), expected, "{}", obj.display());
    (g, camera)
}

/// Positions and faces of an OBJ file (positive indices, fan triangulation).
pub fn read_obj(path: &Path) -> Geometry {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut g = Geometry::default();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f32> = words
                    .take(3)
                    .map(|w| w.parse().expect("coordinate"))
                    .collect();
                g.vertices.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let idx: Vec<u32> = words
                    .map(|w| w.split('/').next().unwrap().parse::<u32>().expect("index") - 1)
                    .collect();
                for i in 1..idx.len() - 1 {
                    g.triangles.push([idx[0], idx[i], idx[i + 1]]);
                }
            }
            _ => {}
        }
    }
    g
}

/// Camera rays of a `width` x `height` image, every `stride`-th pixel in raster order.
pub fn camera_rays(camera: &Camera, width: u32, height: u32, stride: usize) -> Vec<Ray> {
    let frame = camera.frame(width, height);
    (0..width * height)
        .step_by(stride)
        .map(|i| frame.ray((i % width) as f32 + 0.5, (i / width) as f32 + 0.5))
        .collect()
}

/// Random rays about the box `[lo, hi]`: origins inside it and outside it, uniform
/// directions, and a share of axis-parallel directions with +0.0 and -0.0 components.
pub fn random_rays(lo: Vec3, hi: Vec3, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let margin = (hi - lo) * 0.5;
    (0..count)
        .map(|i| {
            let org = if i % 2 == 0 {
                rng.point(lo, hi)
            } else {
                rng.point(lo - margin, hi + margin)
            };
            let mut dir = rng.unit_vector();
            if i % 5 == 0 {
                // Axis-parallel, or parallel to one coordinate plane, with signed zeros.
                let keep = rng.below(3) as usize;
                for a in 0..3 {
                    if a != keep && (i % 3 == 0 || a == (keep + 1) % 3) {
                        dir[a] = if rng.below(2) == 0 { 0.0 } else { -0.0 };
                    }
                }
                dir = dir.normalize();
            }
            Ray::new(org, dir, 0.0, f32::INFINITY)
        })
        .collect()
}
