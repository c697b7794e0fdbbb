//! `raypack render SCENE.toml -o OUT.png [--width W --height H --spp N --threads T --seed S]`.
//!
//! Loads a scene file, builds its kd-tree, renders on a local rayon pool with a progress
//! bar on stderr, writes the image (PFM when the name ends in `.pfm`, 8-bit sRGB PNG when
//! it ends in `.png`; whole or not at all) and prints the build and render times, the
//! rays traced by kind and rays per second. `--integrator path|photon` renders with
//! global illumination instead ([`raypack::render::gi`]), and for photons also prints the
//! photon map's build and lookup times.

use super::{BadInput, ImageSide, check_image_size};
use anyhow::Context;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use raypack::accel::kdtree::KdTree;
use raypack::render::film::ImageFormat;
use raypack::render::gi::{GiScene, render_gi};
use raypack::render::path::PathTracer;
use raypack::render::photon::{Photon, PhotonMapper, PhotonSettings};
use raypack::render::{Mode, RayCounts, render, tiles};
use raypack::scene::{AntiAlias, Scene};
use std::collections::BinaryHeap;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (TOML; see scenes/README.md).
    pub scene: PathBuf,
    /// Output image: PFM (32-bit float) when it ends in .pfm, 8-bit sRGB PNG when it ends
    /// in .png (any case); other names are refused.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Image width in pixels (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Camera samples per pixel, a square n*n: 1 turns anti-aliasing off; otherwise an
    /// adaptive scene stays adaptive with n x n samples at edges, any other samples every
    /// pixel n x n. With --integrator path or photon: any count (default 16).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Seed of the area-light and glossy samples (default: the scene's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Trace camera quads and area-light shadow rays as 4-ray packets, or one ray at a
    /// time; both give the same image.
    #[arg(long, value_enum, default_value_t = ModeArg::Packet)]
    pub mode: ModeArg,
    /// Light transport: the tutorial's Whitted tracer, or global illumination by path
    /// tracing or photon mapping (scenes/README.md gives their materials and emitters).
    /// With path and photon, --spp takes any count.
    #[arg(long, value_enum, default_value_t = IntegratorArg::Whitted)]
    pub integrator: IntegratorArg,
    /// Path: most scattering events per path (default: Russian roulette
    /// alone ends paths).
    #[arg(long)]
    pub max_bounces: Option<u32>,
    /// Photon: photons shot from the emitters.
    #[arg(long, default_value_t = PhotonSettings::default().photons)]
    pub photons: u32,
    /// Photon: final-gather rays per camera sample.
    #[arg(long, default_value_t = PhotonSettings::default().gather)]
    pub gather: u32,
    /// Photon: photons per density estimate (k nearest).
    #[arg(long, default_value_t = PhotonSettings::default().k)]
    pub photon_k: usize,
    /// Path and photon: radiance of a uniform sky seen by rays that leave the scene, one
    /// value or R,G,B (default: the scene's background).
    #[arg(long, value_delimiter = ',', num_args = 1..=3)]
    pub sky: Option<Vec<f32>>,
}

/// `--integrator`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorArg {
    Whitted,
    Path,
    Photon,
}

/// `--mode`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeArg {
    Scalar,
    Packet,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::Scalar => Mode::Scalar,
            ModeArg::Packet => Mode::Packet,
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Checked first: a name the film cannot be written under would only fail after the
    // whole render.
    if ImageFormat::from_path(&args.output).is_none() {
        return Err(BadInput(format!(
            "-o {}: unknown image format; the name must end in .png or .pfm",
            args.output.display()
        ))
        .into());
    }
    let (mut scene, warnings) = raypack::scene::file::load_with_warnings(&args.scene)?;
    super::warn(&warnings);
    if args.integrator != IntegratorArg::Whitted {
        return run_gi(scene, &args);
    }
    apply_overrides(&mut scene, &args, args.spp)?;
    let (threads, pool) = worker_pool(args.threads)?;

    let start = Instant::now();
    let accel = pool.install(|| KdTree::build(&scene.geometry));
    let build_seconds = start.elapsed().as_secs_f64();

    let s = &scene.settings;
    let bar = tile_bar(s.width, s.height)?;
    let start = Instant::now();
    let rendered = pool.install(|| render(&scene, &accel, args.mode.into(), &|| bar.inc(1)));
    let render_seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();

    // The film's error names the file and the failure; its source is the OS error.
    rendered.film.write(&args.output)?;
    print!(
        "{}",
        summary(
            &args.scene,
            &args.output,
            &scene,
            threads,
            build_seconds,
            render_seconds,
            &rendered.counts
        )
    );
    Ok(())
}

/// Renders with the path tracer or the photon mapper: any `--spp`, the sky, and a
/// summary with rays by kind, rays/s and, for photons, the map's build and lookup times.
fn run_gi(mut scene: Scene, args: &Args) -> anyhow::Result<()> {
    let spp = args.spp.unwrap_or(16);
    if spp == 0 {
        return Err(BadInput("--spp must be at least 1".into()).into());
    }
    let environment = match args.sky.as_deref() {
        None => scene.settings.background,
        Some([v]) => Vec3::splat(*v),
        Some([r, g, b]) => Vec3::new(*r, *g, *b),
        Some(_) => return Err(BadInput("--sky takes one value or R,G,B".into()).into()),
    };
    if !environment.is_finite() || environment.min_element() < 0.0 {
        return Err(BadInput("--sky values must be finite and >= 0".into()).into());
    }
    if args.photon_k < 2 {
        return Err(BadInput("--photon-k must be at least 2".into()).into());
    }
    apply_overrides(&mut scene, args, None)?;
    let (threads, pool) = worker_pool(args.threads)?;
    let start = Instant::now();
    let accel = pool.install(|| KdTree::build(&scene.geometry));
    let build_seconds = start.elapsed().as_secs_f64();
    let gi = GiScene::new(&scene, &accel, environment, args.max_bounces);
    if gi.lights.photon_power() <= 0.0 && gi.lights.is_empty() {
        eprintln!(
            "warning: {}: nothing emits light (no emissive material, light or sky): the image is black",
            args.scene.display()
        );
    }
    let s = &scene.settings;
    let bar = tile_bar(s.width, s.height)?;
    let mut photon_lines = String::new();
    let mut excluded = 0.0;
    let start = Instant::now();
    let rendered = match args.integrator {
        IntegratorArg::Path => {
            let tracer = PathTracer { scene: gi };
            pool.install(|| render_gi(&scene, &tracer, spp, args.mode.into(), &|| bar.inc(1)))
        }
        _ => {
            let settings = PhotonSettings {
                photons: args.photons,
                gather: args.gather,
                k: args.photon_k,
                seed: scene.settings.seed,
                ..PhotonSettings::default()
            };
            let mapper = pool.install(|| PhotonMapper::new(gi, settings));
            // Timed apart: the lookup benchmark is not part of the render.
            let lookup_start = Instant::now();
            let lookup = pool.install(|| lookup_seconds(&mapper));
            excluded = lookup_start.elapsed().as_secs_f64();
            let st = &mapper.stats;
            photon_lines = format!(
                "photons    {} shot ({} rays) in {:.3} s: {} global, {} caustic stored\n\
                 photon map kd-trees balanced in {:.3} s; irradiance precomputed at {} points \
                 in {:.3} s; {:.2} us per {}-nearest lookup\n",
                args.photons,
                st.rays,
                st.trace_seconds,
                st.global,
                st.caustic,
                st.build_seconds,
                mapper.irradiance.len(),
                st.precompute_seconds,
                lookup * 1e6,
                settings.k,
            );
            let mut r =
                pool.install(|| render_gi(&scene, &mapper, spp, args.mode.into(), &|| bar.inc(1)));
            r.counts.photon = st.rays;
            r
        }
    };
    let render_seconds = start.elapsed().as_secs_f64() - excluded;
    bar.finish_and_clear();
    rendered.film.write(&args.output)?;
    let c = &rendered.counts;
    let name = match args.integrator {
        IntegratorArg::Path => "path tracing",
        _ => "photon mapping",
    };
    print!(
        "scene      {}: {}x{}, {name}, {spp} samples per pixel, {threads} threads\n\
         primitives {}\n\
         build      {build_seconds:.3} s (kd-tree)\n\
         {photon_lines}\
         render     {render_seconds:.3} s\n\
         rays       {} total: {} camera, {} bounce, {} shadow, {} gather, {} photon\n\
         rays/s     {:.2} M\n\
         {}\
         wrote      {}\n",
        args.scene.display(),
        s.width,
        s.height,
        scene.geometry.prim_count(),
        c.total(),
        c.camera,
        c.bounce,
        c.shadow,
        c.gather,
        c.photon,
        c.total() as f64 / render_seconds.max(1e-9) / 1e6,
        if c.camera_packets > 0 {
            format!(
                "packets    camera rays in {} packets; other rays one by one\n",
                c.camera_packets
            )
        } else {
            String::new()
        },
        args.output.display(),
    );
    Ok(())
}

/// Mean time of a k-nearest query on the global map, at up to 100,000 stored photons'
/// positions spread over the map (on the current pool).
fn lookup_seconds(mapper: &PhotonMapper) -> f64 {
    let photons = mapper.global.photons();
    if photons.is_empty() {
        return 0.0;
    }
    let step = photons.len().div_ceil(100_000);
    let queries: Vec<&Photon> = photons.iter().step_by(step).collect();
    let start = Instant::now();
    let found: usize = queries
        .par_iter()
        .map_init(BinaryHeap::new, |heap, ph| {
            mapper
                .global
                .nearest(ph.p, mapper.settings.k, mapper.radius, &|_| true, heap)
                .len()
        })
        .sum();
    std::hint::black_box(found);
    start.elapsed().as_secs_f64() / queries.len() as f64
}

/// The local rayon pool of `--threads` (default: one per core) and its size.
fn worker_pool(threads: Option<usize>) -> anyhow::Result<(usize, rayon::ThreadPool)> {
    let threads = match threads {
        Some(0) => return Err(BadInput("--threads must be at least 1".into()).into()),
        Some(t) => t,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;
    Ok((threads, pool))
}

/// The progress bar on stderr, one step per tile of a `width x height` image.
fn tile_bar(width: u32, height: u32) -> anyhow::Result<ProgressBar> {
    let bar = ProgressBar::new(tiles::tiles(width, height).len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} tiles, eta {eta}")
            .context("progress bar template")?
            .progress_chars("=> "),
    );
    Ok(bar)
}

/// Applies the command line's size, sampling and seed to the scene's settings. The size
/// that results is held to the limits of scene files ([`check_image_size`]).
/// `spp` is the square sample count of the Whitted tracer (`None` for the GI
/// integrators, which take `--spp` as it is).
fn apply_overrides(scene: &mut Scene, args: &Args, spp: Option<u32>) -> Result<(), BadInput> {
    let s = &mut scene.settings;
    let side = |flag: &'static str, given: Option<u32>, scene: u32| match given {
        Some(value) => ImageSide::Flag { flag, value },
        None => ImageSide::Scene { value: scene },
    };
    check_image_size(
        side("--width", args.width, s.width),
        side("--height", args.height, s.height),
    )?;
    s.width = args.width.unwrap_or(s.width);
    s.height = args.height.unwrap_or(s.height);
    if let Some(spp) = spp {
        let n = (spp as f64).sqrt().round() as u32;
        if spp == 0 || n * n != spp || n > 16 {
            return Err(BadInput(format!(
                "--spp must be a square between 1 and 256 (1, 4, 9, 16, ...), not {spp}"
            )));
        }
        s.antialias = match (n, s.antialias) {
            (1, _) => AntiAlias::None,
            (n, AntiAlias::Adaptive(_)) => AntiAlias::Adaptive(n),
            (n, _) => AntiAlias::Full(n),
        };
    }
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    Ok(())
}

fn summary(
    scene_path: &Path,
    output: &Path,
    scene: &Scene,
    threads: usize,
    build_seconds: f64,
    render_seconds: f64,
    c: &RayCounts,
) -> String {
    let s = &scene.settings;
    let sampling = match s.antialias {
        AntiAlias::None => "1 sample per pixel".to_string(),
        AntiAlias::Full(n) => format!("{} samples per pixel", n * n),
        AntiAlias::Adaptive(n) => format!("adaptive, {} samples at edges", n * n),
    };
    let rays_per_second = c.total() as f64 / render_seconds.max(1e-9);
    format!(
        "scene      {}: {}x{}, {sampling}, {threads} threads\n\
         primitives {}\n\
         build      {build_seconds:.3} s (kd-tree)\n\
         render     {render_seconds:.3} s\n\
         rays       {} total: {} primary, {} shadow, {} reflection, {} refraction, {} glossy\n\
         rays/s     {:.2} M\n\
         {}\
         wrote      {}\n",
        scene_path.display(),
        s.width,
        s.height,
        scene.geometry.prim_count(),
        c.total(),
        c.primary,
        c.shadow,
        c.reflection,
        c.refraction,
        c.glossy,
        rays_per_second / 1e6,
        packet_summary(c),
        output.display(),
    )
}

/// In packet mode, how many rays of each kind were traced in packets and how many alone.
fn packet_summary(c: &RayCounts) -> String {
    let p = &c.packets;
    if *p == Default::default() {
        return String::new();
    }
    let kinds = [
        ("primary", &p.primary),
        ("shadow", &p.shadow),
        ("secondary", &p.secondary),
        ("glossy", &p.glossy),
    ];
    let parts: Vec<String> = kinds
        .iter()
        .map(|(name, b)| {
            format!(
                "{name} {} in {} packets + {} single",
                b.packet_rays, b.packets, b.single_rays
            )
        })
        .collect();
    format!("packets    {}\n", parts.join(", "))
}
