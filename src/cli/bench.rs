//! `raypack bench`: rays per second on the standard ray sets of a scene (RAYS.md).
//!
//! The sets are made once, before any timing; the build is timed on its own. Every
//! (set, threads, mode) is traced once to warm up and then `--repeat` times; a pass is
//! the wall time of tracing the whole set on a rayon pool of that many threads, each
//! pinned to a core, taking chunks of 4096 rays (the peers' protocol in ANCHORS.md).
//! Every pass folds its answers into a checksum, printed beside the rates; closest-hit
//! sets must give the same checksum in every mode and thread count.

use super::{BadInput, check_size_flags, load_scene};
use anyhow::Context;
use raypack::accel::Accel;
use raypack::accel::Mode;
use raypack::accel::bvh::Bvh;
use raypack::accel::kdtree::stats::{self, TraversalCounts};
use raypack::accel::kdtree::{BuildParams, KdTree};
use raypack::rayset::trace::{Order, Query, checksum_set, split_packets};
use raypack::rayset::{self, Checksum, RaySet, StandardSets, standard};
use raypack::scene::Geometry;
use raypack::scene::catalog::BenchScene;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Builds the accelerator `bench`, `trace` and `rays` trace through, the kd-tree of
/// `geometry` (on the global rayon pool: every core unless `RAYON_NUM_THREADS` says
/// otherwise); returns it and the build time in seconds.
///
/// This and [`prepare`] are where the commands name the concrete [`KdTree`]: its build
/// takes the tree flags' [`BuildParams`], and `--compare-tree` prints both trees' node
/// counts. Everything they trace goes through [`Accel`] ([`measure`], `checksum_set`,
/// `trace_hits`, `standard_sets` are generic over it), statically dispatched.
pub fn build_accel(geometry: &Geometry, params: &BuildParams) -> (KdTree, f64) {
    let start = Instant::now();
    let accel = KdTree::build_with(geometry, params);
    (accel, start.elapsed().as_secs_f64())
}

/// Builds the accelerator of `scene` and makes its standard sets at `width x height`.
pub fn prepare(
    scene: &BenchScene,
    width: u32,
    height: u32,
    params: &BuildParams,
) -> anyhow::Result<(KdTree, f64, StandardSets)> {
    let (accel, build_seconds) = build_accel(&scene.geometry, params);
    let sets = standard::standard_sets(&accel, &scene.geometry, &scene.view, width, height, None)?;
    Ok((accel, build_seconds, sets))
}

/// Name of the accelerator, for reports.
pub const ACCEL_NAME: &str = "SAH kd-tree";

/// Name of `--accel bvh8`'s accelerator, for reports.
pub const BVH_NAME: &str = "8-wide BVH";

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A TOML scene, an OBJ mesh, a scene name of ../shared/scenes/cameras.toml, or spd:NAME[:SIZE].
    pub scene: String,
    /// Ray sets to trace (primary, shadow, diffuse).
    #[arg(long, value_delimiter = ',', default_value = "primary,shadow,diffuse")]
    pub sets: Vec<String>,
    /// Modes: scalar (one ray at a time), packet4, packet8, packet16 (4, 8 or 16 rays,
    /// one SIMD lane each: in an image set a 2x2, 4x2 or 4x4 pixel block, elsewhere
    /// consecutive rays), packet (the widest this CPU runs natively), tile64 (64 rays
    /// as SIMD groups sharing one walk), stream (one ray per lane, each on its own walk)
    /// or all. Rates are Mrays/s; the fastest mode of each set is named after the table.
    #[arg(long, default_value = "packet,tile64,stream", value_parser = |s: &str| Mode::parse_list(s).map(Modes))]
    pub modes: Modes,
    /// Thread counts (default: 1 and every core; 0 means every core).
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<usize>,
    /// Timed passes per measurement (after one warm-up pass).
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Image width of the primary set (a multiple of 16).
    #[arg(long, default_value_t = standard::WIDTH)]
    pub width: u32,
    /// Image height of the primary set (a multiple of 16).
    #[arg(long, default_value_t = standard::HEIGHT)]
    pub height: u32,
    /// Trace DIR/<set>.rays (e.g. the Embree harness's `gen` output) instead of the sets
    /// raypack makes, so two tracers are timed on the same rays.
    #[arg(long, value_name = "DIR")]
    pub rays: Option<PathBuf>,
    /// Also write the results as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The accelerator to time: kdtree (the SAH kd-tree, every mode) or bvh8 (the 8-wide
    /// BVH: its stream mode walks one ray at a time, eight boxes per step; its packet
    /// modes walk a packet's rays together, one box against every ray per step; the
    /// tile mode traces its rays one by one). The ray sets are made with the kd-tree
    /// either way.
    #[arg(long, default_value = "kdtree", value_parser = ["kdtree", "bvh8"])]
    pub accel: String,
    #[command(flatten)]
    pub tree: super::TreeArgs,
    /// Time a second tree against the first, built with these tree flags (e.g.
    /// "--empty-cut 0.5 --intersection-cost 60"; flags not given take their defaults).
    /// Each measurement alternates the two trees pass by pass (A B B A ...), so both meet
    /// the same drift of a shared machine, and a row for the second tree follows with the
    /// median ratio of its passes to the first tree's neighbouring ones.
    #[arg(long, value_name = "FLAGS", allow_hyphen_values = true)]
    pub compare_tree: Option<String>,
}

/// The flags of `--compare-tree`, read as `bench` reads its own tree flags.
#[derive(clap::Parser, Debug)]
#[command(no_binary_name = true)]
struct CompareTree {
    #[command(flatten)]
    tree: super::TreeArgs,
}

/// The build parameters that `--compare-tree FLAGS` names.
fn compare_params(flags: &str) -> anyhow::Result<BuildParams> {
    use clap::Parser;
    let bad = |why: &str| BadInput(format!("--compare-tree \"{flags}\": {why}"));
    let parsed = CompareTree::try_parse_from(flags.split_whitespace()).map_err(|e| {
        let message = e.to_string();
        bad(message
            .lines()
            .next()
            .unwrap_or_default()
            .trim_start_matches("error: "))
    })?;
    parsed.tree.params().map_err(|e| bad(&e.to_string()).into())
}

/// `--modes`: a comma-separated list, `all` standing for every mode.
#[derive(Clone, Debug)]
pub struct Modes(pub Vec<Mode>);

#[derive(Serialize, Debug)]
pub struct Machine {
    pub cpu: String,
    pub cores: usize,
    pub simd: String,
}

#[derive(Serialize, Debug)]
pub struct Row {
    pub set: String,
    pub mode: String,
    /// SIMD lanes of the kernels (1 for scalar).
    pub width: usize,
    /// Rays traced together.
    pub packet_size: usize,
    pub threads: usize,
    pub rays: usize,
    pub mrays_median: f64,
    pub mrays_min: f64,
    pub mrays_max: f64,
    pub checksum: String,
    /// The second tree's rates (`--compare-tree`), from passes alternating with these.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub second_tree: Option<SecondTree>,
}

/// The second tree's side of a row (`--compare-tree`).
#[derive(Serialize, Debug)]
pub struct SecondTree {
    pub mrays_median: f64,
    pub mrays_min: f64,
    pub mrays_max: f64,
    /// Median over the passes of the second tree's rate over the first tree's in the
    /// neighbouring pass.
    pub ratio_median: f64,
}

#[derive(Serialize, Debug)]
pub struct Report {
    pub machine: Machine,
    pub scene: String,
    pub accel: String,
    pub triangles: usize,
    pub spheres: usize,
    pub primitives: u32,
    pub build_seconds: f64,
    /// `exact` or `fast` (`--builder`).
    pub builder: String,
    /// The SAH costs the tree was built with: `[K_T, K_I, empty bonus]`.
    pub sah_costs: [f32; 3],
    pub width: u32,
    pub height: u32,
    pub light: [f64; 3],
    pub light_source: String,
    /// Per set and packet mode: packets whose lanes disagree on a direction sign (the
    /// packet path traces them as one group per sign octant), and all packets.
    pub split_packets:
        std::collections::BTreeMap<String, std::collections::BTreeMap<String, [usize; 2]>>,
    /// The flags of `--compare-tree`, when a second tree was timed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare_tree: Option<String>,
    /// The second tree's build time in seconds (`--compare-tree`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub second_build_seconds: Option<f64>,
    /// 1-minute load average before and after the timed passes.
    pub load_average: [f64; 2],
    pub results: Vec<Row>,
}

/// The standard set called `name` (`primary`, `shadow`, `diffuse`; names are checked
/// before).
fn set_named<'s>(sets: &'s StandardSets, name: &str) -> &'s RaySet {
    match name {
        "primary" => &sets.primary,
        "shadow" => &sets.shadow,
        _ => &sets.diffuse,
    }
}

/// CPU model, logical cores and the instruction set of the kernels in use.
pub fn machine() -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let simd = super::isa_label();
    Machine { cpu, cores, simd }
}

/// The 1-minute load average (runnable processes), or NaN where the system does not
/// say; a figure above the thread count means other processes shared the cores.
pub fn load_average() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(f64::NAN)
}

/// True when the 1-minute load average left after the passes is more than raypack's own
/// threads account for by over 0.5 per core: other processes then ran during the timed
/// passes and took cycles from them.
pub fn machine_was_busy(load: f64, threads: usize, cores: usize) -> bool {
    load - threads as f64 > 0.5 * cores as f64
}

/// A rayon pool of `threads` threads, thread `i` pinned to core `i % cores`.
fn pinned_pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
    let cores = core_affinity::get_core_ids().unwrap_or_default();
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .start_handler(move |i| {
            if !cores.is_empty() {
                core_affinity::set_for_current(cores[i % cores.len()]);
            }
        })
        .build()
        .context("starting the tracing threads")
}

/// The traversal counters of every thread of `pool`, summed (zero without the `stats`
/// feature).
fn pool_traversal_counts(pool: &rayon::ThreadPool) -> TraversalCounts {
    pool.broadcast(|_| stats::counts())
        .into_iter()
        .fold(TraversalCounts::default(), TraversalCounts::plus)
}

/// Median of a non-empty list.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// One tree's side of a measurement ([`measure`]).
#[derive(Default)]
pub struct Measured {
    /// Mrays/s, in pass order.
    pub rates: Vec<f64>,
    pub checksum: Checksum,
    /// The traversal counters (`stats` feature) of this tree's passes alone, the
    /// warm-up pass included.
    pub work: TraversalCounts,
}

/// One measurement of each of `accels` (one tree, or two with `--compare-tree`): a
/// warm-up pass each, then `repeat` timed passes each, the trees taking turns in the
/// order A B, B A, A B ... so that pass `j` of each lies next to pass `j` of the other.
/// The counters are read between passes, outside the timed part, so each tree gets its
/// own.
pub fn measure<A: Accel>(
    pool: &rayon::ThreadPool,
    accels: &[&A],
    set: &RaySet,
    mode: Mode,
    query: Query,
    repeat: usize,
) -> Vec<Measured> {
    // One pass of `accel`, its time, and the counts it added to `m`.
    let pass = |accel: &A, m: &mut Measured| {
        let work = pool_traversal_counts(pool);
        let start = Instant::now();
        let c = std::hint::black_box(pool.install(|| checksum_set(accel, set, mode, query)));
        let seconds = start.elapsed().as_secs_f64();
        m.work = m.work.plus(pool_traversal_counts(pool).since(work));
        (c, seconds)
    };
    let mut out: Vec<Measured> = accels
        .iter()
        .map(|a| {
            let mut m = Measured::default();
            m.checksum = pass(a, &mut m).0;
            m
        })
        .collect();
    for j in 0..repeat {
        for k in 0..accels.len() {
            let k = if j % 2 == 0 { k } else { accels.len() - 1 - k };
            let (c, seconds) = pass(accels[k], &mut out[k]);
            assert_eq!(c, out[k].checksum, "a pass gave a different answer");
            out[k].rates.push(set.len() as f64 / seconds / 1e6);
        }
    }
    out
}

/// Fastest, slowest and median of `rates`.
fn spread(rates: &[f64]) -> (f64, f64, f64) {
    let lo = rates.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = rates.iter().copied().fold(0.0, f64::max);
    (lo, hi, median(&mut rates.to_vec()))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    for s in &args.sets {
        if !matches!(s.as_str(), "primary" | "shadow" | "diffuse") {
            return Err(BadInput(format!(
                "--sets: unknown set `{s}` (expected primary, shadow, diffuse)"
            ))
            .into());
        }
    }
    if args.repeat == 0 {
        return Err(BadInput("--repeat must be at least 1".into()).into());
    }
    super::check_outputs([("--json", args.json.as_ref())])?;
    let machine = machine();
    let mut threads: Vec<usize> = if args.threads.is_empty() {
        vec![1, machine.cores]
    } else {
        args.threads
            .iter()
            .map(|&t| super::thread_count(t))
            .collect()
    };
    threads.dedup();

    check_size_flags(args.width, args.height)?;
    let params = args.tree.params()?;
    let second_params = args
        .compare_tree
        .as_deref()
        .map(compare_params)
        .transpose()?;

    if args.accel == "bvh8" && args.compare_tree.is_some() {
        return Err(
            BadInput("--compare-tree compares kd-trees: it needs --accel kdtree".into()).into(),
        );
    }
    let scene = load_scene(&args.scene)?;
    let (accel, build_seconds, mut sets) = prepare(&scene, args.width, args.height, &params)?;
    let bvh = (args.accel == "bvh8").then(|| Bvh::build(&scene.geometry));
    if let Some(dir) = &args.rays {
        for name in &args.sets {
            let set = rayset::read_rays(&dir.join(format!("{name}.rays")))?;
            match name.as_str() {
                "primary" => sets.primary = set,
                "shadow" => sets.shadow = set,
                _ => sets.diffuse = set,
            }
        }
        outln!("ray sets read from {}", dir.display());
    }
    outln!(
        "raypack bench {}: {}; {} ({} builder, K_T {}, K_I {}, empty bonus {}) built in {:.3} s",
        args.scene,
        super::primitive_counts(&scene.geometry),
        ACCEL_NAME,
        args.tree.builder,
        args.tree.traversal_cost,
        args.tree.intersection_cost,
        args.tree.empty_bonus,
        build_seconds
    );
    if let Some(bvh) = &bvh {
        let s = bvh.stats();
        outln!(
            "timed: {BVH_NAME} ({} nodes {:.0}% filled, {} leaves of {:.2} primitives, depth {}, \
             SAH steps {:.2} + leaves {:.2}; {:.1} bytes per triangle) built in {:.3} s",
            s.nodes,
            100.0 * s.fill,
            s.leaves,
            s.mean_leaf,
            s.depth,
            s.sah_nodes,
            s.sah_leaves,
            bvh.bytes() as f64 / scene.geometry.triangles.len().max(1) as f64,
            bvh.build_seconds()
        );
    }
    let second = second_params.map(|p| build_accel(&scene.geometry, &p));
    if let (Some((tree, seconds)), Some(flags)) = (&second, &args.compare_tree) {
        outln!(
            "second tree (--compare-tree \"{flags}\"): {} nodes, built in {seconds:.3} s; the first has {} nodes",
            tree.nodes().len(),
            accel.nodes().len()
        );
    }
    let trees: Vec<&KdTree> = std::iter::once(&accel)
        .chain(second.as_ref().map(|(tree, _)| tree))
        .collect();
    outln!(
        "machine: {}, {} cores, kernels {}",
        machine.cpu,
        machine.cores,
        machine.simd
    );
    outln!(
        "sets: primary {} rays ({}x{}), shadow {}, diffuse {}; light [{:.6}, {:.6}, {:.6}] ({}), offset {:.6}",
        sets.primary.len(),
        sets.primary.width,
        sets.primary.height,
        sets.shadow.len(),
        sets.diffuse.len(),
        sets.light.x,
        sets.light.y,
        sets.light.z,
        sets.light_source.describe(),
        sets.offset
    );
    let packet_modes: Vec<Mode> = args
        .modes
        .0
        .iter()
        .copied()
        .filter(|&m| m.packet_size() > 1)
        .collect();
    let split_packets: std::collections::BTreeMap<
        String,
        std::collections::BTreeMap<String, [usize; 2]>,
    > = args
        .sets
        .iter()
        .map(|name| {
            let set = set_named(&sets, name);
            let per_mode = packet_modes
                .iter()
                .map(|&m| (m.to_string(), split_packets(&set.rays, Order::of(set), m)))
                .collect();
            (name.clone(), per_mode)
        })
        .collect();
    for mode in &packet_modes {
        let shares: Vec<String> = split_packets
            .iter()
            .map(|(name, per_mode)| {
                let [split, total] = per_mode[&mode.to_string()];
                let share = 100.0 * split as f64 / total.max(1) as f64;
                format!("{name} {split} of {total} ({share:.1}%)")
            })
            .collect();
        outln!(
            "{mode}: packets split by direction signs (traced as one group per sign octant): {}",
            shares.join(", ")
        );
    }
    outln!(
        "{:<8} {:<8} {:>5} {:>6} {:>7} {:>9} {:>9} {:>9} {:>9}  checksum (hits:sum of prim ids)",
        "set",
        "mode",
        "width",
        "packet",
        "threads",
        "rays",
        "Mrays/s",
        "min",
        "max"
    );

    let pools = threads
        .iter()
        .map(|&t| pinned_pool(t).map(|p| (t, p)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let load_before = load_average();
    let timing = Timing {
        sets: &sets,
        names: &args.sets,
        modes: &args.modes.0,
        pools: &pools,
        repeat: args.repeat,
    };
    let Timed {
        rows,
        disagreements,
        tile_notes,
        work_notes,
    } = match &bvh {
        Some(bvh) => time_sets(&[bvh], &timing),
        None => time_sets(&trees, &timing),
    };
    let load_after = load_average();
    if args.modes.0.len() > 1 {
        for line in fastest(&rows) {
            outln!("{line}");
        }
    }
    for note in &tile_notes {
        outln!("tile64, {note}");
    }
    if stats::ENABLED {
        outln!("traversal work (a packet step counts once, whatever its active lanes):");
    }
    for note in &work_notes {
        outln!("  {note}");
    }
    outln!("load average (1 min) before / after the passes: {load_before:.2} / {load_after:.2}");
    let busiest = threads.iter().copied().max().unwrap_or(1);
    if machine_was_busy(load_after, busiest, machine.cores) {
        eprintln!(
            "raypack: warning: the machine was busy: load average {load_after:.2} with at most {} of raypack on {}; other processes shared the cores and these figures are unreliable",
            super::count(busiest, "thread"),
            super::count(machine.cores, "core"),
        );
    }
    if let Some(path) = &args.json {
        let report = Report {
            machine,
            scene: args.scene.clone(),
            accel: if bvh.is_some() { BVH_NAME } else { ACCEL_NAME }.to_string(),
            triangles: scene.geometry.triangles.len(),
            spheres: scene.geometry.spheres.len(),
            primitives: scene.geometry.prim_count(),
            build_seconds: bvh.as_ref().map_or(build_seconds, |b| b.build_seconds()),
            builder: args.tree.builder.to_string(),
            sah_costs: [
                args.tree.traversal_cost,
                args.tree.intersection_cost,
                args.tree.empty_bonus,
            ],
            width: sets.primary.width,
            height: sets.primary.height,
            light: sets.light.to_array(),
            light_source: sets.light_source.describe().to_string(),
            split_packets,
            compare_tree: args.compare_tree.clone(),
            second_build_seconds: second.as_ref().map(|(_, seconds)| *seconds),
            load_average: [load_before, load_after],
            results: rows,
        };
        super::write_json(path, &report)?;
    }
    if !disagreements.is_empty() {
        anyhow::bail!(
            "checksums differ between modes or thread counts: {}",
            disagreements.join(", ")
        );
    }
    Ok(())
}

/// What [`time_sets`] needs besides the accelerators.
struct Timing<'a> {
    sets: &'a StandardSets,
    names: &'a [String],
    modes: &'a [Mode],
    pools: &'a [(usize, rayon::ThreadPool)],
    repeat: usize,
}

/// The rows and notes of [`time_sets`].
struct Timed {
    rows: Vec<Row>,
    disagreements: Vec<String>,
    tile_notes: Vec<String>,
    work_notes: Vec<String>,
}

/// Times every set, thread count and mode on `trees` (one accelerator, or two with
/// `--compare-tree`), printing a row for each.
fn time_sets<A: Accel>(trees: &[&A], timing: &Timing) -> Timed {
    let mut rows = Vec::new();
    let mut disagreements = Vec::new();
    let mut tile_notes = Vec::new();
    let mut work_notes = Vec::new();
    for name in timing.names {
        let set = set_named(timing.sets, name);
        let query = match name.as_str() {
            "shadow" => Query::Occluded,
            _ => Query::Closest,
        };
        let mut first: Option<Checksum> = None;
        for (t, pool) in timing.pools {
            for &mode in timing.modes {
                let results = measure(pool, trees, set, mode, query, timing.repeat);
                let (rates, checksum) = (&results[0].rates, results[0].checksum);
                for (k, m) in results.iter().enumerate() {
                    let which = if k == 0 { "" } else { ", second tree" };
                    if stats::ENABLED {
                        let w = m.work;
                        // One warm-up pass and `repeat` timed ones.
                        let rays = (set.len() * (timing.repeat + 1)).max(1) as f64;
                        work_notes.push(format!(
                            "{name} {mode:<8} {}{which}: {:.2} node steps, {:.2} leaf visits, {:.2} primitive tests per ray",
                            super::count(*t, "thread"),
                            w.node_steps as f64 / rays,
                            w.leaf_visits as f64 / rays,
                            w.prim_tests as f64 / rays
                        ));
                    }
                    if stats::ENABLED && mode == Mode::Tile64 {
                        let tiles = m.work.tiles.max(1) as f64;
                        tile_notes.push(format!(
                            "{name} {}{which}: {:.1}% of tiles traced per group (mixed signs or one group), mean entry depth {:.1} nodes",
                            super::count(*t, "thread"),
                            100.0 * m.work.tile_fallbacks as f64 / tiles,
                            m.work.tile_entry_depth as f64 / tiles
                        ));
                    }
                }
                let agrees = *first.get_or_insert(checksum) == checksum;
                if !agrees {
                    disagreements.push(format!("{name} {mode} {}", super::count(*t, "thread")));
                }
                let (lo, hi, med) = spread(rates);
                outln!(
                    "{:<8} {:<8} {:>5} {:>6} {:>7} {:>9} {:>9.3} {:>9.3} {:>9.3}  {}{}",
                    name,
                    mode,
                    mode.width(),
                    mode.packet_size(),
                    t,
                    set.len(),
                    med,
                    lo,
                    hi,
                    checksum,
                    if agrees { "" } else { "  (differs)" }
                );
                // The second tree's row (`--compare-tree`), printed under the first's.
                let second_tree = results.get(1).map(|m| {
                    let (second, same) = (&m.rates, m.checksum == checksum);
                    if !same {
                        disagreements.push(format!(
                            "{name} {mode} {}, second tree",
                            super::count(*t, "thread")
                        ));
                    }
                    let (lo, hi, med) = spread(second);
                    let mut ratios: Vec<f64> =
                        second.iter().zip(rates).map(|(b, a)| b / a).collect();
                    let ratio = median(&mut ratios);
                    outln!(
                        "{:<8} {:<8} {:>5} {:>6} {:>7} {:>9} {:>9.3} {:>9.3} {:>9.3}  second tree: {ratio:.3}x the first (median of paired passes){}",
                        "",
                        "",
                        "",
                        "",
                        "",
                        "",
                        med,
                        lo,
                        hi,
                        if same { "" } else { ", checksum differs" }
                    );
                    SecondTree {
                        mrays_median: med,
                        mrays_min: lo,
                        mrays_max: hi,
                        ratio_median: ratio,
                    }
                });
                rows.push(Row {
                    set: name.clone(),
                    mode: mode.to_string(),
                    width: mode.width(),
                    packet_size: mode.packet_size(),
                    threads: *t,
                    rays: set.len(),
                    mrays_median: med,
                    mrays_min: lo,
                    mrays_max: hi,
                    checksum: checksum.to_string(),
                    second_tree,
                });
            }
        }
    }
    Timed {
        rows,
        disagreements,
        tile_notes,
        work_notes,
    }
}

/// One line per set and thread count naming the mode with the highest median rate, in
/// the order the rows were measured.
fn fastest(rows: &[Row]) -> Vec<String> {
    let mut lines = Vec::new();
    let mut seen = Vec::new();
    for row in rows {
        let key = (row.set.as_str(), row.threads);
        if seen.contains(&key) {
            continue;
        }
        seen.push(key);
        let best = rows
            .iter()
            .filter(|r| (r.set.as_str(), r.threads) == key)
            .max_by(|a, b| a.mrays_median.total_cmp(&b.mrays_median))
            .unwrap_or(row);
        lines.push(format!(
            "fastest  {} on {}: {} at {:.3} Mrays/s",
            row.set,
            super::count(row.threads, "thread"),
            best.mode,
            best.mrays_median
        ));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::{Row, fastest, machine_was_busy};

    #[test]
    fn fastest_names_the_best_mode_of_each_set_and_thread_count() {
        let row = |set: &str, mode: &str, threads: usize, mrays: f64| Row {
            set: set.into(),
            mode: mode.into(),
            width: 8,
            packet_size: 8,
            threads,
            rays: 10,
            mrays_median: mrays,
            mrays_min: mrays,
            mrays_max: mrays,
            checksum: String::new(),
            second_tree: None,
        };
        let rows = [
            row("primary", "packet8", 1, 9.0),
            row("primary", "stream", 1, 4.0),
            row("primary", "packet8", 2, 17.0),
            row("primary", "stream", 2, 18.0),
            row("diffuse", "packet8", 1, 2.0),
            row("diffuse", "stream", 1, 5.5),
        ];
        assert_eq!(
            fastest(&rows),
            [
                "fastest  primary on 1 thread: packet8 at 9.000 Mrays/s",
                "fastest  primary on 2 threads: stream at 18.000 Mrays/s",
                "fastest  diffuse on 1 thread: stream at 5.500 Mrays/s",
            ]
        );
    }

    #[test]
    fn busy_means_load_beyond_raypacks_own_threads() {
        // Two raypack threads on two cores account for a load of 2.
        assert!(!machine_was_busy(2.4, 2, 2));
        assert!(machine_was_busy(3.2, 2, 2));
        // One thread on eight cores: 4 more runnable processes is a busy machine.
        assert!(!machine_was_busy(4.9, 1, 8));
        assert!(machine_was_busy(5.1, 1, 8));
    }
}
