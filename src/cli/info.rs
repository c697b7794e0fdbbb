//! `raypack info SCENE`: builds the kd-tree of a scene (an OBJ file or a TOML scene) and
//! prints its statistics: shape, SAH cost, memory, build time; with `--primary`, also
//! the scalar primary-ray rate of the scene's camera on one thread.
//!
//! SCENE is read as `raypack bench` reads it (a TOML scene, an OBJ mesh, or a name from
//! ../shared/scenes/cameras.toml), and the primary rays are RAYS.md's standard set.

use anyhow::Context;
use raypack::accel::Accel;
use raypack::accel::kdtree::{BuildParams, KdTree};
use raypack::rayset::{scenes, standard};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A TOML scene, an OBJ mesh, or a scene name from ../shared/scenes/cameras.toml.
    pub scene: String,
    /// Build threads (0: all cores). With 1 the build is serial.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Builds to time; the median is reported.
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    #[command(flatten)]
    pub tree: super::TreeArgs,
    /// Also trace the camera's 1024x768 primary rays on one thread (scalar path).
    #[arg(long)]
    pub primary: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = scenes::load(&args.scene)?;
    super::warn(&scene.warnings);
    let geometry = &scene.geometry;
    let threads = super::thread_count(args.threads);
    let params = BuildParams {
        parallel: threads > 1,
        ..args.tree.params()?
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the build threads")?;
    let mut seconds = Vec::new();
    let mut tree = None;
    for _ in 0..args.repeat.max(1) {
        let start = Instant::now();
        tree = Some(pool.install(|| KdTree::build_with(geometry, &params)));
        seconds.push(start.elapsed().as_secs_f64());
    }
    let tree = tree.expect("at least one build");
    seconds.sort_by(f64::total_cmp);
    let s = tree.stats(&params);
    let tris = geometry.triangles.len();
    let per_tri = |bytes: usize| bytes as f64 / tris.max(1) as f64;
    println!("scene            {}", args.scene);
    println!("primitives       {}", super::primitive_counts(geometry));
    let bounds = geometry.bounds();
    if bounds.is_empty() {
        println!("bounds           empty (planes only)");
    } else {
        println!("bounds           min {} max {}", bounds.min, bounds.max);
    }
    let bounded = tris + geometry.spheres.len() + geometry.boxes.len();
    let degenerate = bounded - s.build.tree_prims as usize;
    println!(
        "in tree          {} of {} bounded ({} left out; planes are tested beside the tree)",
        s.build.tree_prims,
        bounded,
        super::count(degenerate, "degenerate triangle"),
    );
    println!(
        "build            {:.3} s median of {} on {} (min {:.3} s)",
        seconds[seconds.len() / 2],
        super::count(seconds.len(), "build"),
        super::count(threads, "thread"),
        seconds[0]
    );
    println!("nodes            {}", s.nodes);
    println!("leaves           {} ({} empty)", s.leaves, s.empty_leaves);
    println!(
        "leaf depth       max {}, mean {:.2} (limit {})",
        s.max_leaf_depth, s.mean_leaf_depth, s.build.max_depth_limit
    );
    println!(
        "prims per leaf   {:.2} (non-empty leaves); {:.2} references per primitive",
        s.mean_prims_per_leaf, s.refs_per_prim
    );
    println!(
        "SAH cost         {:.2} (K_T {}, K_I {})",
        s.sah_cost, params.traversal_cost, params.intersection_cost
    );
    let total = s.node_bytes + s.leaf_bytes + s.index_bytes + s.triaccel_bytes;
    for (name, bytes) in [
        ("nodes", s.node_bytes),
        ("leaf table", s.leaf_bytes),
        ("index lists", s.index_bytes),
        ("TriAccel", s.triaccel_bytes),
        ("total", total),
    ] {
        println!(
            "memory {name:<11} {:>10.2} MiB  {:>6.1} bytes/triangle",
            bytes as f64 / (1 << 20) as f64,
            per_tri(bytes)
        );
    }
    if args.primary {
        let (w, h) = (standard::WIDTH, standard::HEIGHT);
        let rays = standard::primary(&scene.view, w, h)?.rays;
        let mut best = f64::INFINITY;
        let mut checksum = 0u64;
        let mut hits = 0;
        for _ in 0..3 {
            let start = Instant::now();
            (checksum, hits) =
                rays.iter()
                    .fold((0u64, 0usize), |(sum, n), r| match tree.intersect(r) {
                        Some(hit) => (
                            sum.wrapping_add(hit.prim as u64 ^ hit.t.to_bits() as u64),
                            n + 1,
                        ),
                        None => (sum, n),
                    });
            best = best.min(start.elapsed().as_secs_f64());
        }
        println!(
            "primary rays     {:.2} Mrays/s scalar, 1 thread, best of 3 ({}x{}, {:.1}% hit, checksum {checksum:016x})",
            rays.len() as f64 / best / 1e6,
            w,
            h,
            100.0 * hits as f64 / rays.len() as f64
        );
    }
    Ok(())
}
