//! Utilities shared by the integration tests: the benchmark scenes of ../shared/scenes
//! (a minimal OBJ reader for positions and faces, and the cameras), and ray sets.

#![allow(dead_code)]

pub mod cli;
pub mod closed;

use glam::Vec3;
use raypack::accel::kdtree::KdTree;
use raypack::ray::{Hit, Ray};
use raypack::scene::generate::{self, Rng};
use raypack::scene::{Aabb, Camera, Geometry, Plane, Sphere};
use std::path::{Path, PathBuf};

/// A hit as the bits the scalar/packet and kd-tree/brute-force comparisons demand equal:
/// primitive, then `t`, `u`, `v` as `to_bits`.
pub fn hit_bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
}

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

/// The tutorial scene files of scenes/ (all seven or more), sorted. Panics, naming the
/// folder, when they are missing.
pub fn shipped_scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    assert!(
        paths.len() >= 7,
        "expected the tutorial scenes in {}",
        dir.display()
    );
    paths
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

/// Rays built to hit the tree's weak spots: origins exactly on split planes (some lying
/// in the plane, with +0.0 or -0.0 there), axis-parallel rays through lattice points,
/// and rays aimed exactly at triangle corners and edge midpoints.
pub fn adversarial_rays(tree: &KdTree, g: &Geometry, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let b = g.bounds();
    let splits: Vec<(usize, f32)> = tree
        .nodes()
        .iter()
        .filter(|n| !n.is_leaf())
        .map(|n| (n.axis(), n.split))
        .collect();
    let mut rays = Vec::with_capacity(count);
    while rays.len() < count {
        let kind = rays.len() % 4;
        let mut org = rng.point(b.min, b.max);
        let mut dir = rng.unit_vector();
        match kind {
            0 if !splits.is_empty() => {
                let (axis, split) = splits[rng.below(splits.len() as u32) as usize];
                org[axis] = split;
                if rng.below(2) == 0 {
                    dir[axis] = if rng.below(2) == 0 { 0.0 } else { -0.0 };
                }
            }
            1 => {
                // Lattice origin (the grid generators' planes), axis-parallel direction.
                org = org.round();
                dir = Vec3::ZERO;
                for a in 0..3 {
                    dir[a] = if rng.below(2) == 0 { 0.0 } else { -0.0 };
                }
                let a = rng.below(3) as usize;
                dir[a] = if rng.below(2) == 0 { 1.0 } else { -1.0 };
                if rng.below(3) == 0 {
                    org[(a + 1) % 3] += 0.5;
                }
            }
            _ if !g.triangles.is_empty() => {
                let [p, q, r] = g.triangle(rng.below(g.triangles.len() as u32));
                let target = if kind == 2 { p } else { (q + r) * 0.5 };
                let from = target - rng.unit_vector() * (b.diagonal() * rng.range(0.1, 1.0));
                org = from;
                dir = target - from;
            }
            _ => {}
        }
        let len = dir.length();
        if len > 0.0 {
            rays.push(Ray::new(org, dir / len, 0.0, f32::INFINITY));
        }
    }
    rays
}

/// A camera at `from` (in scene diagonals) from the centre of `g`, looking at it.
pub fn looking_at(g: &Geometry, from: Vec3) -> Camera {
    let b = g.bounds();
    let centre = (b.min + b.max) * 0.5;
    Camera {
        eye: centre + from * b.diagonal(),
        target: centre,
        up: Vec3::Y,
        vfov_deg: 50.0,
    }
}

/// Triangles (a soup and a small sphere) with 300 spheres, 300 boxes (some flat) and
/// a ground plane.
pub fn mixed_primitives() -> Geometry {
    let mut g = generate::merge(&[
        generate::random_soup(3_000, 0.1, 41),
        generate::tessellated_sphere(Vec3::new(0.5, 0.5, 0.5), 0.3, 12, 16),
    ]);
    let mut rng = Rng::new(42);
    for _ in 0..300 {
        g.spheres.push(Sphere {
            center: rng.point(Vec3::ZERO, Vec3::ONE),
            radius: rng.range(0.001, 0.05),
        });
        let lo = rng.point(Vec3::ZERO, Vec3::ONE);
        let mut hi = lo + rng.point(Vec3::ZERO, Vec3::splat(0.05));
        if rng.below(4) == 0 {
            hi.y = lo.y; // a flat box
        }
        g.boxes.push(Aabb::new(lo, hi));
    }
    g.planes.push(Plane {
        normal: Vec3::Y,
        offset: -0.25,
    });
    g
}

/// Top-left pixels of the 2x2 quads of a `width x height` image set in RAYS.md's packet
/// order (both multiples of 16), read off the library's own ray order.
pub fn quad_corners(width: u32, height: u32) -> Vec<(u32, u32)> {
    (0..(width * height) as usize)
        .step_by(4)
        .map(|i| raypack::rayset::packet_pixel(i, width))
        .collect()
}
