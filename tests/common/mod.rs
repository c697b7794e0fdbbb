//! Utilities shared by the integration tests: the benchmark scenes of ../shared/scenes
//! (found or reported missing, a minimal OBJ reader for positions and faces, and the
//! cameras), and ray sets.
//!
//! A clone without the scenes still passes: each test that needs them starts with
//! [`require_scenes!`], which returns from it when they are missing, and the binary
//! prints at exit how many of its tests did not run. CI sets `RAYPACK_REQUIRE_SCENES=1`,
//! which turns a missing folder into a failure.

#![allow(dead_code)]

pub mod cli;
pub mod closed;

use glam::Vec3;
use raypack::accel::RayPacket;
use raypack::accel::kdtree::KdTree;
use raypack::ray::{Hit, Ray};
use raypack::scene::catalog;
use raypack::scene::generate::{self, Rng};
use raypack::scene::{Aabb, Camera, Geometry, Plane, Sphere};
use raypack::simd::{Float, Isa, LaneMask, Mask, Simd, Vf};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, Once};

/// A hit as the bits the scalar/packet and kd-tree/brute-force comparisons demand equal:
/// primitive, then `t`, `u`, `v` as `to_bits`.
pub fn hit_bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
}

/// A packet whose lane `i` is `rays[i]`, or inactive and full of NaN (also past the
/// end of `rays`).
pub fn packet<W: Simd>(rays: &[Option<Ray>]) -> RayPacket<W> {
    assert!(rays.len() <= W::LANES);
    let get = |f: &dyn Fn(&Ray) -> f32| {
        Vf::<W>::from_fn(|i| rays.get(i).copied().flatten().as_ref().map_or(f32::NAN, f))
    };
    let org = [0, 1, 2].map(|a| get(&|r| r.org[a]));
    let dir = [0, 1, 2].map(|a| get(&|r| r.dir[a]));
    let mut active = 0;
    for (i, r) in rays.iter().enumerate() {
        if r.is_some() {
            active |= 1 << i;
        }
    }
    RayPacket {
        org,
        dir,
        inv_dir: dir.map(|d| Vf::<W>::ONE / d),
        t_min: get(&|r| r.t_min),
        t_max: get(&|r| r.t_max),
        active: Mask::<W>::from_bits(active),
    }
}

/// Set to 1 (CI does), missing benchmark scenes fail the tests that need them instead of
/// skipping them.
pub const REQUIRE_SCENES_ENV: &str = "RAYPACK_REQUIRE_SCENES";

/// Set to 1 (CI does), the leak tests trace their full ray counts (see [`ray_count`]).
pub const EXHAUSTIVE_ENV: &str = "RAYPACK_EXHAUSTIVE";

/// Whether the environment variable `name` is set to something other than empty or 0.
pub fn env_flag(name: &str) -> bool {
    std::env::var_os(name).is_some_and(|v| !v.is_empty() && v != "0")
}

/// `quick` rays, or `exhaustive` ones with `RAYPACK_EXHAUSTIVE=1`: for the tests that look
/// for rare events (a ray leaking through a closed mesh) where only the count decides how
/// rare an event can still be seen.
pub fn ray_count(quick: usize, exhaustive: usize) -> usize {
    if env_flag(EXHAUSTIVE_ENV) {
        exhaustive
    } else {
        quick
    }
}

/// Tests of this binary that returned early for want of the benchmark scenes.
static SKIPPED_COUNT: AtomicUsize = AtomicUsize::new(0);
/// Where those tests looked, each folder list once.
static LOOKED: Mutex<Vec<String>> = Mutex::new(Vec::new());
/// Registers [`report_skipped`] on the first skip.
static REPORT_AT_EXIT: Once = Once::new();

/// The benchmark scenes folder, found as `raypack` finds it
/// ([`catalog::shared_scenes_dir`]: `$RAYPACK_SCENES` when it is set, else
/// `../shared/scenes`). `None` when it is missing: the test is counted as not run, and
/// the binary says so once at exit ([`require_scenes!`] returns from the test). With
/// `RAYPACK_REQUIRE_SCENES=1` a missing folder fails the test instead, naming where it
/// looked.
pub fn scenes() -> Option<PathBuf> {
    let dir = catalog::shared_scenes_dir();
    if dir.is_none() {
        let mut looked: Vec<String> = catalog::shared_scenes_candidates()
            .iter()
            .map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone()))
            .map(|p| p.display().to_string())
            .collect();
        looked.dedup();
        not_found(looked.join(", "));
    }
    dir
}

/// [`scenes`] for tests that read the scene files of scenes/gi: those name their meshes by
/// a path relative to the file (`../../../shared/scenes/...`), so the folder must also be
/// there, beside the crate, whatever `$RAYPACK_SCENES` says.
pub fn scenes_beside_crate() -> Option<PathBuf> {
    scenes()?;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if dir.join("cameras.toml").is_file() {
        Some(dir)
    } else {
        not_found(dir.display().to_string());
        None
    }
}

/// Fails the test when [`REQUIRE_SCENES_ENV`] is set; else counts it as not run.
fn not_found(looked: String) {
    assert!(
        !env_flag(REQUIRE_SCENES_ENV),
        "benchmark scenes not found (looked in {looked}, with cameras.toml) and \
         {REQUIRE_SCENES_ENV} is set; see README.md, \"Benchmark scenes\", or set RAYPACK_SCENES"
    );
    SKIPPED_COUNT.fetch_add(1, Ordering::Relaxed);
    let mut list = LOOKED.lock().unwrap_or_else(|e| e.into_inner());
    if !list.contains(&looked) {
        list.push(looked);
    }
    drop(list);
    REPORT_AT_EXIT.call_once(|| {
        unsafe extern "C" {
            /// C's `atexit`, in every C library the standard library links.
            fn atexit(f: extern "C" fn()) -> std::ffi::c_int;
        }
        // SAFETY: `report_skipped` is a plain `extern "C" fn()` that neither unwinds nor
        // calls `exit`, as `atexit` requires.
        unsafe { atexit(report_skipped) };
    });
}

/// Runs at process exit, after the test harness's summary: one line for the binary.
extern "C" fn report_skipped() {
    let count = SKIPPED_COUNT.load(Ordering::Relaxed);
    let looked = LOOKED.lock().map(|l| l.join("; ")).unwrap_or_default();
    let tests = if count == 1 {
        "1 test".to_string()
    } else {
        format!("{count} tests")
    };
    let _ = writeln!(
        std::io::stderr(),
        "raypack: {tests} in this binary did not run: benchmark scenes not found (looked in \
         {looked}). See README.md, \"Benchmark scenes\", or set RAYPACK_SCENES."
    );
}

/// The benchmark scenes folder, or a `return` from the calling test when it is missing
/// (see [`scenes`]). Call it first thing in every test that needs the scenes; pass
/// `common::scenes_beside_crate()` for the scene files of scenes/gi.
#[macro_export]
macro_rules! require_scenes {
    () => {
        $crate::require_scenes!($crate::common::scenes())
    };
    ($found:expr) => {
        match $found {
            Some(dir) => dir,
            None => return,
        }
    };
}

/// Runs a test body generic over the packet width at every width (4, 8 and 16 lanes),
/// each on its own thread, so the three share both cores, and on each thread once per
/// instruction set the CPU runs ([`isas`]). Each width stays on one thread: the
/// traversal counters the bodies read are per thread, and so is [`Isa::scope`].
#[macro_export]
macro_rules! at_every_width {
    ($f:ident $(, $arg:expr)*) => {
        std::thread::scope(|s| {
            s.spawn(|| $crate::common::each_isa(|| $f::<raypack::simd::W4>($($arg),*)));
            s.spawn(|| $crate::common::each_isa(|| $f::<raypack::simd::W8>($($arg),*)));
            $crate::common::each_isa(|| $f::<raypack::simd::W16>($($arg),*));
        })
    };
}

/// The instruction sets whose kernels the tests run: every one the CPU runs. Those it
/// lacks are named once per binary at exit, so a run on an AVX2-only machine says
/// that its AVX-512 kernels went untested.
pub fn isas() -> Vec<Isa> {
    static REPORT: Once = Once::new();
    let (run, lacking): (Vec<Isa>, Vec<Isa>) = Isa::ALL.into_iter().partition(|i| i.supported());
    if !lacking.is_empty() {
        REPORT.call_once(|| {
            unsafe extern "C" {
                fn atexit(f: extern "C" fn()) -> std::ffi::c_int;
            }
            // SAFETY: as in `not_found`.
            unsafe { atexit(report_isas) };
        });
    }
    run
}

/// `f` once under each of [`isas`], on the calling thread.
pub fn each_isa(mut f: impl FnMut()) {
    for isa in isas() {
        isa.scope(&mut f).expect("a supported instruction set");
    }
}

extern "C" fn report_isas() {
    let lacking: Vec<&str> = Isa::ALL
        .into_iter()
        .filter(|i| !i.supported())
        .map(Isa::name)
        .collect();
    let _ = writeln!(
        std::io::stderr(),
        "raypack: the {} kernels did not run in this binary: this CPU lacks them",
        lacking.join(" and ")
    );
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
/// benchmark scene `name` from cameras.toml. The test must have called
/// [`require_scenes!`] first.
pub fn shared_scene(name: &str) -> (Geometry, Camera) {
    let (entry, obj) = catalog::shared_scene(name).unwrap_or_else(|e| panic!("{e}"));
    let camera = Camera::from(&entry.view());
    let g = read_obj(&obj);
    let expected = entry.triangles.expect("triangles in cameras.toml") as usize;
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

/// A stress scene of the accelerator tests: its name, geometry, camera, a seed and
/// how many random and adversarial rays to trace.
pub struct Stress {
    pub what: String,
    pub geometry: Geometry,
    pub camera: Camera,
    pub seed: u64,
    pub rays: usize,
}

/// The stress scenes every accelerator is checked against brute force on: random
/// soups of 1 to 12,000 triangles, a tessellated sphere, an axis-aligned grid (whose
/// triangles lie in lattice planes, seen obliquely and straight on), a closed box and
/// mixed primitives. `kind` is `soups`, `sphere`, `grid`, `closed box` or `mixed`.
pub fn stress_scenes(kind: &str) -> Vec<Stress> {
    let scene = |what: String, geometry: Geometry, from: Vec3, seed: u64, rays: usize| {
        let camera = looking_at(&geometry, from);
        Stress {
            what,
            geometry,
            camera,
            seed,
            rays,
        }
    };
    match kind {
        "soups" => [
            (1, 0.5, 1),
            (40, 0.5, 2),
            (2_000, 0.1, 3),
            (12_000, 0.03, 4),
        ]
        .into_iter()
        .map(|(count, size, seed)| {
            let g = generate::random_soup(count, size, seed);
            scene(
                format!("soup {count}"),
                g,
                Vec3::new(0.3, 0.4, -1.0),
                seed,
                1_500,
            )
        })
        .collect(),
        "sphere" => {
            let g = generate::tessellated_sphere(Vec3::new(1.0, 2.0, 3.0), 2.0, 48, 64);
            vec![scene(
                "sphere".into(),
                g,
                Vec3::new(0.0, 0.2, -1.0),
                11,
                3_000,
            )]
        }
        "grid" => {
            let g = generate::axis_aligned_grid(6);
            let oblique = scene(
                "grid".into(),
                g.clone(),
                Vec3::new(0.7, 0.5, -1.0),
                21,
                4_000,
            );
            // Axis-aligned cameras: rays in lattice planes, along the triangles' edges.
            let straight = Stress {
                what: "grid, straight camera".into(),
                geometry: g,
                camera: Camera {
                    eye: Vec3::new(3.0, 3.0, -10.0),
                    target: Vec3::new(3.0, 3.0, 0.0),
                    up: Vec3::Y,
                    vfov_deg: 40.0,
                },
                seed: 22,
                rays: 500,
            };
            vec![oblique, straight]
        }
        "closed box" => {
            let g = generate::closed_box(8);
            vec![scene(
                "closed box".into(),
                g,
                Vec3::new(0.1, 0.1, -0.2),
                31,
                3_000,
            )]
        }
        "mixed" => {
            let g = mixed_primitives();
            vec![scene(
                "mixed primitives".into(),
                g,
                Vec3::new(0.2, 0.5, -1.0),
                43,
                3_000,
            )]
        }
        _ => panic!("no stress scene `{kind}`"),
    }
}

/// One `#[test]` per kind of [`stress_scenes`], each calling the test file's own
/// `check_stress(kind)`.
#[macro_export]
macro_rules! stress_tests {
    () => {
        #[test]
        fn random_soups_match_brute_force() {
            check_stress("soups");
        }

        #[test]
        fn tessellated_sphere_matches_brute_force() {
            check_stress("sphere");
        }

        #[test]
        fn axis_aligned_grid_on_split_planes_matches_brute_force() {
            check_stress("grid");
        }

        #[test]
        fn closed_box_matches_brute_force() {
            check_stress("closed box");
        }

        #[test]
        fn spheres_boxes_planes_and_triangles_match_brute_force() {
            check_stress("mixed");
        }
    };
}
