//! `raypack info SCENE`: builds the kd-tree of a scene (an OBJ file or a TOML scene), or
//! with `--accel bvh8` its 8-wide BVH, and prints its statistics: shape, SAH figures,
//! memory, build time; with `--occupancy`, how many threads worked on the build; with
//! `--primary`, also the one-ray-at-a-time primary-ray rate of the scene's camera on one
//! thread.
//!
//! SCENE is read as `raypack bench` reads it (a TOML scene, an OBJ mesh, or a name from
//! ../shared/scenes/cameras.toml), and the primary rays are RAYS.md's standard set.
//!
//! The build's peak extra memory is the growth of the process's peak resident set
//! during a build, from the resident set just before it (Linux: the peak is reset
//! through `/proc/self/clear_refs`, read from `/proc/self/status`); it includes the
//! finished tree. Elsewhere it is reported as unknown.

use anyhow::Context;
use raypack::accel::Accel;
use raypack::accel::bvh::Bvh;
use raypack::accel::kdtree::{BuildParams, KdTree};
use raypack::accel::occupancy::{Meter, Occupancy};
use raypack::rayset::standard;
use raypack::scene::catalog as scenes;
use serde::Serialize;
use std::path::PathBuf;
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
    /// Also trace the camera's 1024x768 primary rays on one thread, one at a time (the
    /// kd-tree's scalar path, or the BVH's single-ray walk).
    #[arg(long)]
    pub primary: bool,
    /// Also mark how many threads work on each build at each moment and print the
    /// median build's record: its serial part and the speedups it predicts on 16 cores.
    #[arg(long)]
    pub occupancy: bool,
    /// Also write what is printed, and the build's peak extra memory, as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// The accelerator to build: kdtree (the SAH kd-tree) or bvh8 (the 8-wide BVH, whose
    /// build the kd-tree's flags do not change; `--primary` then times its single-ray
    /// walk).
    #[arg(long, default_value = "kdtree", value_parser = ["kdtree", "bvh8"])]
    pub accel: String,
}

#[derive(Serialize, Debug)]
struct Seconds {
    median: f64,
    min: f64,
    all: Vec<f64>,
}

#[derive(Serialize, Debug)]
struct Sah {
    cost: f64,
    traversal_cost: f32,
    intersection_cost: f32,
    empty_bonus: f32,
    /// [`BuildParams::min_saving`] (the fast builder's; the exact one ignores it).
    min_saving: f32,
    /// [`BuildParams::empty_cut`].
    empty_cut: f32,
}

#[derive(Serialize, Debug)]
struct Part {
    bytes: usize,
    bytes_per_primitive: f64,
}

#[derive(Serialize, Debug)]
struct Primary {
    mrays_per_s: f64,
    rays: usize,
    hit_fraction: f64,
    checksum: String,
}

/// The median build's [`Occupancy`] record (`--occupancy`).
#[derive(Serialize, Debug)]
struct OccupancyReport {
    /// Seconds with 0, 1, 2, ... threads working.
    seconds_working: Vec<f64>,
    cores: usize,
    /// With a pool no larger than the cores: the time with fewer threads working than
    /// the pool has, as a fraction of the work, and Amdahl's 16-thread speedup from it.
    serial_fraction: Option<f64>,
    amdahl_16: Option<f64>,
    /// The speedup 16 cores would reach over one, from how many threads worked at a
    /// time ([`Occupancy::predicted_wall`]): telling with a pool of 16 or more.
    profile_16: f64,
}

impl OccupancyReport {
    fn new(o: &Occupancy, threads: usize) -> OccupancyReport {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let (serial_fraction, amdahl_16) = if threads >= 2 && threads <= cores {
            let (f, s) = o.amdahl(threads, 16);
            (Some(f), Some(s))
        } else {
            (None, None)
        };
        OccupancyReport {
            seconds_working: o.seconds(),
            cores,
            serial_fraction,
            amdahl_16,
            profile_16: o.predicted_wall(cores, 1) / o.predicted_wall(cores, 16),
        }
    }
}

/// Everything `info` prints, for scripts (`--json`).
#[derive(Serialize, Debug)]
struct Report {
    scene: String,
    builder: String,
    /// The kernels' instruction set (`RAYPACK_ISA` or the widest the CPU runs).
    isa: String,
    threads: usize,
    build_seconds: Seconds,
    /// Largest growth of the peak resident set over one build (bytes), tree included;
    /// `null` where the operating system does not say.
    build_peak_extra_bytes: Option<u64>,
    triangles: usize,
    spheres: usize,
    boxes: usize,
    planes: usize,
    in_tree: u32,
    nodes: u32,
    leaves: u32,
    empty_leaves: u32,
    max_leaf_depth: u32,
    mean_leaf_depth: f64,
    depth_limit: u32,
    mean_prims_per_leaf: f64,
    refs_per_prim: f64,
    sah: Sah,
    /// With `--occupancy`.
    occupancy: Option<OccupancyReport>,
    memory: std::collections::BTreeMap<&'static str, Part>,
    primary: Option<Primary>,
}

/// A field of `/proc/self/status` in bytes (`VmRSS`, `VmHWM`).
fn proc_status_bytes(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kib: u64 = line[field.len()..]
        .trim_start_matches(':')
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kib * 1024)
}

/// Resets the peak resident set to the current one; returns the current one.
fn reset_peak() -> Option<u64> {
    std::fs::write("/proc/self/clear_refs", "5").ok()?;
    proc_status_bytes("VmRSS")
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.repeat == 0 {
        return Err(super::BadInput("--repeat must be at least 1".into()).into());
    }
    super::check_outputs([("--json", args.json.as_ref())])?;
    let threads = super::thread_count(args.threads);
    let params = BuildParams {
        parallel: threads > 1,
        ..args.tree.params()?
    };
    let scene = scenes::load(&args.scene)?;
    super::warn(&scene.warnings);
    let geometry = &scene.geometry;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the build threads")?;
    if args.accel == "bvh8" {
        return run_bvh(&args, &scene, &pool, threads);
    }
    let Builds {
        tree,
        seconds,
        occupancies,
        peak_extra,
    } = timed_builds(&pool, args.repeat, args.occupancy, |meter| {
        KdTree::build_metered(geometry, &params, meter)
    });
    let s = tree.stats(&params);
    let tris = geometry.triangles.len();
    let bounded = tris + geometry.spheres.len() + geometry.boxes.len();
    // Per primitive the tree holds or left out, so a scene of spheres does not divide by
    // its (zero) triangles.
    let per_prim = |bytes: usize| bytes as f64 / bounded.max(1) as f64;
    outln!("scene            {}", args.scene);
    outln!("kernels          {}", super::isa_label());
    outln!("primitives       {}", super::primitive_counts(geometry));
    let bounds = geometry.bounds();
    if bounds.is_empty() {
        outln!("bounds           empty (planes only)");
    } else {
        outln!("bounds           min {} max {}", bounds.min, bounds.max);
    }
    let degenerate = bounded - s.build.tree_prims as usize;
    outln!(
        "in tree          {} of {} bounded ({} left out; planes are tested beside the tree)",
        s.build.tree_prims,
        bounded,
        super::count(degenerate, "degenerate triangle"),
    );
    print_build(&seconds, threads, &format!("{} builder", params.builder));
    let occupancy = args
        .occupancy
        .then(|| print_occupancy(occupancies, threads));
    print_peak_extra(peak_extra);
    outln!("nodes            {}", s.nodes);
    outln!("leaves           {} ({} empty)", s.leaves, s.empty_leaves);
    outln!(
        "leaf depth       max {}, mean {:.2} (SAH splits stop at depth {}; the cuts of empty margins go on below them)",
        s.max_leaf_depth,
        s.mean_leaf_depth,
        s.build.max_depth_limit
    );
    outln!(
        "prims per leaf   {:.2} (non-empty leaves); {:.2} references per primitive",
        s.mean_prims_per_leaf,
        s.refs_per_prim
    );
    outln!(
        "SAH cost         {:.2} (K_T {}, K_I {}, empty margins cut at {})",
        s.sah_cost,
        params.traversal_cost,
        params.intersection_cost,
        params.empty_cut
    );
    outln!(
        "stream queries   {}",
        if tree.is_flat() {
            "flat: every primitive tested against packets of rays (cheaper than the tree by the SAH)"
        } else {
            "kd-tree walks"
        }
    );
    let total = s.node_bytes + s.leaf_bytes + s.index_bytes + s.triaccel_bytes + s.flat_bytes;
    let mut memory = std::collections::BTreeMap::new();
    for (name, key, bytes) in [
        ("nodes", "nodes", s.node_bytes),
        ("leaf table", "leaf_table", s.leaf_bytes),
        ("index lists", "index_lists", s.index_bytes),
        ("TriAccel", "triaccel", s.triaccel_bytes),
        ("flat slots", "flat_slots", s.flat_bytes),
        ("total", "total", total),
    ] {
        outln!(
            "memory {name:<11} {:>10.2} MiB  {:>6.1} bytes/primitive",
            bytes as f64 / (1 << 20) as f64,
            per_prim(bytes)
        );
        memory.insert(
            key,
            Part {
                bytes,
                bytes_per_primitive: per_prim(bytes),
            },
        );
    }
    let primary = (args.primary)
        .then(|| time_primary(&tree, &scene.view, "scalar"))
        .transpose()?;
    if let Some(path) = &args.json {
        let report = Report {
            scene: args.scene.clone(),
            builder: params.builder.to_string(),
            isa: super::isa_label(),
            threads,
            build_seconds: seconds,
            build_peak_extra_bytes: peak_extra,
            triangles: tris,
            spheres: geometry.spheres.len(),
            boxes: geometry.boxes.len(),
            planes: geometry.planes.len(),
            in_tree: s.build.tree_prims,
            nodes: s.nodes,
            leaves: s.leaves,
            empty_leaves: s.empty_leaves,
            max_leaf_depth: s.max_leaf_depth,
            mean_leaf_depth: s.mean_leaf_depth,
            depth_limit: s.build.max_depth_limit,
            mean_prims_per_leaf: s.mean_prims_per_leaf,
            refs_per_prim: s.refs_per_prim,
            sah: Sah {
                cost: s.sah_cost,
                traversal_cost: params.traversal_cost,
                intersection_cost: params.intersection_cost,
                empty_bonus: params.empty_bonus,
                min_saving: params.min_saving,
                empty_cut: params.empty_cut,
            },
            occupancy,
            memory,
            primary,
        };
        super::write_json(path, &report)?;
    }
    Ok(())
}

/// What [`timed_builds`] returns: the last tree, the builds' seconds, every build's
/// occupancy record with its seconds, and the largest peak extra memory.
struct Builds<T> {
    tree: T,
    seconds: Seconds,
    occupancies: Vec<(f64, Occupancy)>,
    peak_extra: Option<u64>,
}

/// Runs `build` `repeat` times on `pool`, each with a meter when `occupancy`.
fn timed_builds<T: Send>(
    pool: &rayon::ThreadPool,
    repeat: usize,
    occupancy: bool,
    build: impl Fn(Meter) -> T + Sync,
) -> Builds<T> {
    let mut seconds = Vec::new();
    let mut occupancies = Vec::new();
    let mut tree = None;
    let mut peak_extra: Option<u64> = None;
    for _ in 0..repeat {
        drop(tree.take());
        let record = Occupancy::new();
        let meter = if occupancy {
            record.meter()
        } else {
            Meter::OFF
        };
        let before = reset_peak();
        let start = Instant::now();
        tree = Some(pool.install(|| build(meter)));
        let elapsed = start.elapsed().as_secs_f64();
        seconds.push(elapsed);
        occupancies.push((elapsed, record));
        let extra = before
            .zip(proc_status_bytes("VmHWM"))
            .map(|(before, peak)| peak.saturating_sub(before));
        peak_extra = peak_extra.max(extra);
    }
    let mut sorted = seconds.clone();
    sorted.sort_by(f64::total_cmp);
    Builds {
        tree: tree.expect("at least one build"),
        seconds: Seconds {
            median: sorted[sorted.len() / 2],
            min: sorted[0],
            all: seconds,
        },
        occupancies,
        peak_extra,
    }
}

/// Times the standard primary set of `view` through `accel` one ray at a time on this
/// thread (best of 3), prints the rate, the hit share and a checksum of the hits (the
/// same for every accelerator: they answer bit for bit alike), and returns them.
fn time_primary(
    accel: &dyn Accel,
    view: &raypack::scene::View,
    walk: &str,
) -> anyhow::Result<Primary> {
    let (w, h) = (standard::WIDTH, standard::HEIGHT);
    let rays = standard::primary(view, w, h)?.rays;
    let mut best = f64::INFINITY;
    let mut checksum = 0u64;
    let mut hits = 0;
    for _ in 0..3 {
        let start = Instant::now();
        (checksum, hits) =
            rays.iter()
                .fold((0u64, 0usize), |(sum, n), r| match accel.intersect(r) {
                    Some(hit) => (
                        sum.wrapping_add(hit.prim as u64 ^ hit.t.to_bits() as u64),
                        n + 1,
                    ),
                    None => (sum, n),
                });
        best = best.min(start.elapsed().as_secs_f64());
    }
    let rate = rays.len() as f64 / best / 1e6;
    let hit_fraction = hits as f64 / rays.len() as f64;
    outln!(
        "primary rays     {rate:.2} Mrays/s {walk}, 1 thread, best of 3 ({w}x{h}, {:.1}% hit, checksum {checksum:016x})",
        100.0 * hit_fraction
    );
    Ok(Primary {
        mrays_per_s: rate,
        rays: rays.len(),
        hit_fraction,
        checksum: format!("{checksum:016x}"),
    })
}

/// Prints the builds' times.
fn print_build(seconds: &Seconds, threads: usize, what: &str) {
    outln!(
        "build            {:.3} s median of {} on {} (min {:.3} s), {what}",
        seconds.median,
        super::count(seconds.all.len(), "build"),
        super::count(threads, "thread"),
        seconds.min,
    );
}

/// Prints the median build's occupancy record and returns it.
fn print_occupancy(mut occupancies: Vec<(f64, Occupancy)>, threads: usize) -> OccupancyReport {
    occupancies.sort_by(|a, b| a.0.total_cmp(&b.0));
    let report = OccupancyReport::new(&occupancies[occupancies.len() / 2].1, threads);
    let at: Vec<String> = (report.seconds_working.iter())
        .map(|t| format!("{t:.4}"))
        .collect();
    outln!(
        "occupancy        seconds with 0, 1, 2, ... threads working: {} (median build)",
        at.join(" / ")
    );
    if let (Some(f), Some(s)) = (report.serial_fraction, report.amdahl_16) {
        outln!(
            "serial part      {:.1}% of the work ran with fewer than {threads} threads working: Amdahl predicts {s:.1}x on 16 threads",
            100.0 * f
        );
    }
    outln!(
        "parallelism      {:.1}x on 16 cores over one, from the threads working at a time ({} on {})",
        report.profile_16,
        super::count(threads, "thread"),
        super::count(report.cores, "core"),
    );
    report
}

/// Prints the build's peak extra memory.
fn print_peak_extra(peak_extra: Option<u64>) {
    match peak_extra {
        Some(bytes) => outln!(
            "build peak extra {:.2} MiB (peak resident set over the build, tree included)",
            bytes as f64 / (1 << 20) as f64
        ),
        None => outln!("build peak extra unknown"),
    }
}

/// What `info --accel bvh8` prints, for scripts (`--json`).
#[derive(Serialize, Debug)]
struct BvhReport {
    scene: String,
    isa: String,
    threads: usize,
    build_seconds: Seconds,
    build_peak_extra_bytes: Option<u64>,
    triangles: usize,
    nodes: usize,
    leaves: usize,
    fill: f64,
    mean_leaf: f64,
    depth: u32,
    sah_nodes: f64,
    sah_leaves: f64,
    bytes: usize,
    bytes_per_primitive: f64,
    occupancy: Option<OccupancyReport>,
    primary: Option<Primary>,
}

/// `info --accel bvh8`: the BVH's builds, shape and memory.
fn run_bvh(
    args: &Args,
    scene: &scenes::BenchScene,
    pool: &rayon::ThreadPool,
    threads: usize,
) -> anyhow::Result<()> {
    let geometry = &scene.geometry;
    let Builds {
        tree,
        seconds,
        occupancies,
        peak_extra,
    } = timed_builds(pool, args.repeat, args.occupancy, |meter| {
        Bvh::build_metered(geometry, threads > 1, meter)
    });
    let bounded = geometry.bounded_count();
    outln!("scene            {}", args.scene);
    outln!("kernels          {}", super::isa_label());
    outln!("primitives       {}", super::primitive_counts(geometry));
    print_build(&seconds, threads, "8-wide BVH");
    let occupancy = args
        .occupancy
        .then(|| print_occupancy(occupancies, threads));
    print_peak_extra(peak_extra);
    let s = tree.stats();
    outln!(
        "nodes            {} 8-wide ({:.0}% of child slots used), depth {}",
        s.nodes,
        100.0 * s.fill,
        s.depth
    );
    outln!(
        "leaves           {} of {:.2} primitives",
        s.leaves,
        s.mean_leaf
    );
    outln!(
        "SAH              {:.2} node steps + {:.2} leaves per ray through the root box",
        s.sah_nodes,
        s.sah_leaves
    );
    let per_prim = tree.bytes() as f64 / bounded.max(1) as f64;
    outln!(
        "memory total     {:>10.2} MiB  {per_prim:>6.1} bytes/primitive",
        tree.bytes() as f64 / (1 << 20) as f64
    );
    let primary = (args.primary)
        .then(|| time_primary(&tree, &scene.view, "single-ray walk"))
        .transpose()?;
    if let Some(path) = &args.json {
        let report = BvhReport {
            scene: args.scene.clone(),
            isa: super::isa_label(),
            threads,
            build_seconds: seconds,
            build_peak_extra_bytes: peak_extra,
            triangles: geometry.triangles.len(),
            nodes: s.nodes,
            leaves: s.leaves,
            fill: s.fill,
            mean_leaf: s.mean_leaf,
            depth: s.depth,
            sah_nodes: s.sah_nodes,
            sah_leaves: s.sah_leaves,
            bytes: tree.bytes(),
            bytes_per_primitive: per_prim,
            occupancy,
            primary,
        };
        super::write_json(path, &report)?;
    }
    Ok(())
}
