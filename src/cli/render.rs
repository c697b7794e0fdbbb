//! `raypack render SCENE.toml -o OUT.png [--width W --height H --spp N --threads T --seed S]`.
//!
//! Loads a scene file, builds its kd-tree, renders on a local rayon pool with a progress
//! bar on stderr, writes the image (PFM when the name ends in `.pfm`, 8-bit sRGB PNG when
//! it ends in `.png`; whole or not at all) and prints the build and render times, the
//! rays traced by kind and rays per second.

use super::{BadInput, ImageSide, check_image_size};
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use raypack::accel::kdtree::KdTree;
use raypack::render::film::ImageFormat;
use raypack::render::{Mode, RayCounts, render, tiles};
use raypack::scene::{AntiAlias, Scene};
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
    /// pixel n x n.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Seed of the area-light and glossy samples (default: the scene's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Trace camera blocks and shadow rays as packets of 4, 8 or 16 rays (packet4,
    /// packet8, packet16; packet: the widest this CPU runs natively), or one ray at a
    /// time (scalar); every mode gives the same image.
    #[arg(long, default_value = "packet")]
    pub mode: Mode,
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
    apply_overrides(&mut scene, &args)?;
    let threads = match args.threads {
        Some(0) => return Err(BadInput("--threads must be at least 1".into()).into()),
        Some(t) => t,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;

    let start = Instant::now();
    let accel = pool.install(|| KdTree::build(&scene.geometry));
    let build_seconds = start.elapsed().as_secs_f64();

    let s = &scene.settings;
    let bar = ProgressBar::new(tiles::tiles(s.width, s.height).len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} tiles, eta {eta}")
            .context("progress bar template")?
            .progress_chars("=> "),
    );
    let start = Instant::now();
    let rendered = pool.install(|| render(&scene, &accel, args.mode, &|| bar.inc(1)));
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

/// Applies the command line's size, sampling and seed to the scene's settings. The size
/// that results is held to the limits of scene files ([`check_image_size`]).
fn apply_overrides(scene: &mut Scene, args: &Args) -> Result<(), BadInput> {
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
    if let Some(spp) = args.spp {
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
