//! `raypack render SCENE -o OUT [--width W --height H --spp N --threads T --seed S]`.
//!
//! SCENE is a TOML scene file (see scenes/README.md), an OBJ mesh, or the name of a
//! benchmark scene in ../shared/scenes/cameras.toml (`sponza`, `bunny`, `conference`,
//! `cornell_box`). A mesh is shaded with its MTL colours and lit as
//! [`raypack::studio::light_mesh`] lights it; its camera is the one cameras.toml gives it, or one that frames its
//! bounds. `--eye`, `--target`, `--up` and `--vfov` override the camera of any scene.
//!
//! The output is checked before any work (its folder must exist and be writable), the
//! kd-tree is built and the image rendered on a local rayon pool with its progress on
//! stderr (a bar, or a line every few seconds when stderr is not a terminal); the
//! summary (build and render times, rays by kind, rays per second) is printed before the
//! image is written (PNG, PFM or EXR by the name; whole or not at all), so a failed write
//! still reports the render.
//!
//! `--integrator path|photon` renders with global illumination instead
//! ([`raypack::render::gi`]): a mesh scene is then lit by its emissive materials (MTL
//! `Ke`, or `Ka` above 1) and `--sky`, not by the light rig; photon mapping also prints
//! the photon map's build and lookup times.

use super::{BadInput, ImageSide, check_image_size};
use anyhow::Context;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use raypack::accel::Mode;
use raypack::accel::kdtree::KdTree;
use raypack::render::film::{ImageFormat, WriteOptions};
use raypack::render::gi::{self, GiCounts, GiScene, render_gi};
use raypack::render::path::PathTracer;
use raypack::render::photon::{Photon, PhotonMapper, PhotonSettings};
use raypack::render::sample::SamplerKind;
use raypack::render::{Film, RayCounts, render, tiles};
use raypack::scene::{AntiAlias, Camera, Scene};
use raypack::studio::{self, MAX_GI_SPP, Source, Staged};
use serde::Serialize;
use std::collections::{BTreeMap, BinaryHeap};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A TOML scene file (see scenes/README.md), an OBJ mesh, or a scene name of
    /// ../shared/scenes/cameras.toml (sponza, bunny, conference, cornell_box).
    pub scene: String,
    /// Output image: 8-bit sRGB PNG (.png), 32-bit float PFM (.pfm) or OpenEXR (.exr),
    /// by the name's ending (any case); other names are refused.
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
    /// pixel n x n. With --integrator path or photon: any count from 1 to 65536
    /// (default 16).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (0, the default: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Seed of the area-light and glossy samples (default: the scene's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// How rays are traced: scalar (one ray at a time), packet4, packet8, packet16
    /// (camera blocks and shadow rays as packets of 4, 8 or 16 rays; packet, the
    /// default: the widest this CPU runs natively), tile64 (64 camera rays as SIMD groups
    /// sharing one walk) or stream (one ray per SIMD lane, each on its own walk). Every
    /// mode gives the same image.
    #[arg(long, default_value = "packet")]
    pub mode: Mode,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// PNG only: scale the linear image by 2^EV before the clamp to [0, 1] and the sRGB
    /// encoding (PFM and EXR keep linear radiance).
    #[arg(long, value_name = "EV", allow_negative_numbers = true)]
    pub exposure: Option<f32>,
    /// EXR only: write 16-bit half floats instead of 32-bit floats.
    #[arg(long)]
    pub half: bool,
    /// Also write the render's figures (times, rays by kind, rays/s, size, threads) as
    /// JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Light transport: the tutorial's Whitted tracer, or global illumination by path
    /// tracing or photon mapping (scenes/README.md gives their materials and emitters).
    /// With path and photon, --spp takes any count.
    #[arg(long, value_enum, default_value_t = IntegratorArg::Whitted)]
    pub integrator: IntegratorArg,
    /// Path and photon: how each camera sample draws its random numbers (Owen-scrambled
    /// Sobol points, or independent uniforms). Refused with the Whitted tracer.
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerArg>,
    /// Path: most scattering events per path (default: Russian roulette
    /// alone ends paths). Refused with the other integrators.
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

/// `--sampler`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerArg {
    /// Owen-scrambled Sobol points (the default).
    Sobol,
    /// Independent uniforms.
    Independent,
}

impl SamplerArg {
    fn kind(self) -> SamplerKind {
        match self {
            SamplerArg::Sobol => SamplerKind::Sobol,
            SamplerArg::Independent => SamplerKind::Independent,
        }
    }
}

/// `--integrator`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorArg {
    /// The tutorial's recursive ray tracer (the default).
    Whitted,
    /// Unidirectional path tracing.
    Path,
    /// Photon mapping with final gathering.
    Photon,
}

/// Camera overrides, each replacing one value of the scene's camera.
#[derive(clap::Args, Debug, Default)]
pub struct CameraArgs {
    /// Camera position, `x,y,z`.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// Point the camera looks at, `x,y,z`.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Camera up direction, `x,y,z`.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees, in (0, 180).
    #[arg(long, value_name = "DEG")]
    pub vfov: Option<f32>,
}

/// `x,y,z` with three finite numbers.
fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    let [x, y, z] = parts[..] else {
        return Err(format!("expected three numbers x,y,z, not `{s}`"));
    };
    let num = |t: &str| match t.trim().parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("`{t}` is not a finite number")),
    };
    Ok(Vec3::new(num(x)?, num(y)?, num(z)?))
}

impl CameraArgs {
    /// Applies the overrides to `camera`, refusing a camera that cannot form an image
    /// (eye on the target, up along the view, a field of view outside (0, 180)).
    pub fn apply(&self, camera: &mut Camera) -> Result<(), BadInput> {
        camera.eye = self.eye.unwrap_or(camera.eye);
        camera.target = self.target.unwrap_or(camera.target);
        camera.up = self.up.unwrap_or(camera.up);
        camera.vfov_deg = self.vfov.unwrap_or(camera.vfov_deg);
        if !(camera.vfov_deg > 0.0 && camera.vfov_deg < 180.0) {
            return Err(BadInput(format!(
                "--vfov {}: the field of view must be in (0, 180) degrees",
                camera.vfov_deg
            )));
        }
        let forward = camera.target - camera.eye;
        if forward.cross(camera.up).length_squared() <= 0.0 || !forward.is_finite() {
            return Err(BadInput(format!(
                "camera: eye {} and target {} must differ and up {} must not lie along the view",
                camera.eye, camera.target, camera.up
            )));
        }
        Ok(())
    }
}

/// What `--json` writes.
#[derive(Serialize, Debug)]
struct Report<'a> {
    scene: &'a str,
    output: &'a Path,
    width: u32,
    height: u32,
    threads: usize,
    mode: &'a str,
    /// The kernels' instruction set (`RAYPACK_ISA` or the widest the CPU runs).
    isa: String,
    primitives: u32,
    build_seconds: f64,
    render_seconds: f64,
    integrator: &'a str,
    /// The global-illumination integrators' sampler (`sobol` or `independent`).
    #[serde(skip_serializing_if = "Option::is_none")]
    sampler: Option<&'static str>,
    /// Rays by kind (the kinds of the integrator), and `total`.
    rays: BTreeMap<&'static str, u64>,
    mrays_per_second: f64,
}

impl<'a> Report<'a> {
    /// The report of a render of `scene` (after the overrides) that took `times` =
    /// `[build, render]` seconds and traced `rays` (by kind, and `total`).
    fn new(
        args: &'a Args,
        scene: &Scene,
        threads: usize,
        [build_seconds, render_seconds]: [f64; 2],
        integrator: &'a str,
        rays: BTreeMap<&'static str, u64>,
    ) -> Report<'a> {
        let total = rays.get("total").copied().unwrap_or(0);
        Report {
            scene: &args.scene,
            output: &args.output,
            width: scene.settings.width,
            height: scene.settings.height,
            threads,
            mode: args.mode.name(),
            isa: super::isa_label(),
            primitives: scene.geometry.prim_count(),
            build_seconds,
            render_seconds,
            integrator,
            sampler: (args.integrator != IntegratorArg::Whitted).then(|| {
                args.sampler
                    .map_or(SamplerKind::default(), SamplerArg::kind)
                    .name()
            }),
            rays,
            mrays_per_second: total as f64 / render_seconds.max(1e-9) / 1e6,
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Checked first: a name the film cannot be written under, or a folder it cannot be
    // written in, would only fail after the whole render.
    let Some(format) = ImageFormat::from_path(&args.output) else {
        return Err(BadInput(format!(
            "-o {}: unknown image format; the name must end in .png, .pfm or .exr",
            args.output.display()
        ))
        .into());
    };
    if args.exposure.is_some() && format != ImageFormat::Png {
        return Err(BadInput("--exposure applies to PNG output only".into()).into());
    }
    if args.half && format != ImageFormat::Exr {
        return Err(BadInput("--half applies to EXR output only".into()).into());
    }
    if args.max_bounces.is_some() && args.integrator != IntegratorArg::Path {
        return Err(BadInput(
            "--max-bounces applies to --integrator path only (photon paths end by Russian \
             roulette, the Whitted tracer by the scene's depth)"
                .into(),
        )
        .into());
    }
    if args.sampler.is_some() && args.integrator == IntegratorArg::Whitted {
        return Err(BadInput(
            "--sampler applies to --integrator path and photon (the Whitted tracer keeps its \
             stratified samples)"
                .into(),
        )
        .into());
    }
    let exposure = args.exposure.unwrap_or(0.0);
    if !exposure.is_finite() {
        return Err(BadInput("--exposure must be a finite number".into()).into());
    }
    let options = WriteOptions {
        exposure,
        exr_half: args.half,
    };
    super::check_outputs([("-o", Some(&args.output)), ("--json", args.json.as_ref())])?;

    let mut staged = studio::load(&args.scene)?;
    super::warn(&staged.warnings);
    args.camera.apply(&mut staged.scene.camera)?;
    if args.integrator != IntegratorArg::Whitted {
        return run_gi(staged, &args, &options);
    }
    let Staged {
        mut scene, source, ..
    } = staged;
    apply_overrides(&mut scene, &args, args.spp)?;
    let (threads, pool) = worker_pool(args.threads)?;

    let start = Instant::now();
    let accel = pool.install(|| KdTree::build(&scene.geometry));
    let build_seconds = start.elapsed().as_secs_f64();
    if let Source::Mesh = source {
        let left_out = studio::light_mesh(&mut scene, &accel).context("placing the key light")?;
        if left_out > 0 {
            eprintln!(
                "raypack: warning: {}: lit by its {} brightest emissive triangles; the {} dimmer ones are left out of the Whitted tracer's lights (--integrator path takes them all)",
                args.scene,
                scene.lights.len(),
                left_out
            );
        }
    }
    if scene.lights.is_empty() && scene.settings.ambient == 0.0 {
        eprintln!(
            "raypack: warning: {}: the scene has no lights and no ambient term; it renders black but for its background",
            args.scene
        );
    }

    let s = &scene.settings;
    let bar = Progress::new(tiles::tiles(s.width, s.height).len() as u64, "tiles")?;
    let start = Instant::now();
    let rendered = pool.install(|| render(&scene, &accel, args.mode, &|| bar.inc()));
    let render_seconds = start.elapsed().as_secs_f64();
    bar.finish();

    let c = &rendered.counts;
    out!(
        "{}",
        summary(
            &args.scene,
            &scene,
            threads,
            build_seconds,
            render_seconds,
            c
        )
    );
    let rays = BTreeMap::from([
        ("total", c.total()),
        ("primary", c.primary),
        ("shadow", c.shadow),
        ("reflection", c.reflection),
        ("refraction", c.refraction),
        ("glossy", c.glossy),
    ]);
    let times = [build_seconds, render_seconds];
    let report = Report::new(&args, &scene, threads, times, "whitted", rays);
    finish(&args, &report, &rendered.film, &options)
}

/// Writes the `--json` report, then the image (whose error names the file, with the OS
/// error as its source), once the summary is printed.
fn finish(args: &Args, report: &Report, film: &Film, options: &WriteOptions) -> anyhow::Result<()> {
    if let Some(path) = &args.json {
        super::write_json(path, report)?;
    }
    if ImageFormat::from_path(&args.output) == Some(ImageFormat::Png)
        && args.exposure.is_none()
        && let Some((ev, bright)) = film.exposure_hint()
    {
        eprintln!(
            "raypack: warning: {} is dark: its brightest pixels reach {bright:.3} of white; render it with --exposure {ev} to brighten it (or write .pfm or .exr to keep linear radiance)",
            args.output.display(),
        );
    }
    film.write_with(&args.output, options)?;
    outln!("wrote      {}", args.output.display());
    Ok(())
}

/// How a global-illumination render traced its rays in `mode`, for the summary.
fn routing(integrator: IntegratorArg, mode: Mode, c: &GiCounts) -> String {
    let path = integrator == IntegratorArg::Path;
    match mode {
        Mode::Scalar => "every ray alone (the reference mode)".into(),
        Mode::Stream if path => "camera, bounce and shadow rays as streams".into(),
        Mode::Stream => "camera rays as streams; photon, gather and shadow rays alone".into(),
        _ if path => format!(
            "camera rays in {} packets, the camera hits' shadow rays toward point lights in {} \
             packets, bounce and other shadow rays as streams",
            c.camera_packets, c.shadow_packets
        ),
        _ => format!(
            "camera rays in {} packets; photon, gather and shadow rays alone",
            c.camera_packets
        ),
    }
}

/// Renders with the path tracer or the photon mapper: any `--spp`, the sky, and a
/// summary with rays by kind, rays/s and, for photons, the map's build and lookup times.
fn run_gi(staged: Staged, args: &Args, options: &WriteOptions) -> anyhow::Result<()> {
    let spp = args.spp.unwrap_or(16);
    if !(1..=MAX_GI_SPP).contains(&spp) {
        return Err(BadInput(format!(
            "--spp {spp}: the path and photon integrators take 1 to {MAX_GI_SPP} samples per pixel"
        ))
        .into());
    }
    let sky = match args.sky.as_deref() {
        None => None,
        Some([v]) => Some(Vec3::splat(*v)),
        Some([r, g, b]) => Some(Vec3::new(*r, *g, *b)),
        Some(_) => return Err(BadInput("--sky takes one value or R,G,B".into()).into()),
    };
    let (environment, white_sky) = studio::gi_environment(&staged, sky);
    if white_sky {
        // A bare mesh has no light of its own: a uniform white sky shows its shape.
        eprintln!(
            "raypack: note: {} has no emissive material; it is lit by a uniform sky of radiance 1 (--sky R,G,B sets another)",
            args.scene
        );
    }
    let mut scene = staged.scene;
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
    let mut gi = GiScene::new(&scene, &accel, environment, args.max_bounces);
    if let Some(sampler) = args.sampler {
        gi.sampler = sampler.kind();
    }
    if gi.lights.photon_power() <= 0.0 && gi.lights.is_empty() {
        eprintln!(
            "raypack: warning: {}: nothing emits light (no emissive material, light or sky): the image is black; --sky 1 lights it by a uniform white sky",
            args.scene
        );
    }
    let s = &scene.settings;
    let bar = Progress::new(gi::pieces(s.width, s.height, spp) as u64, "pieces")?;
    let mut photon_lines = String::new();
    let mut excluded = 0.0;
    let start = Instant::now();
    let rendered = match args.integrator {
        IntegratorArg::Path => {
            let tracer = PathTracer::new(gi);
            pool.install(|| render_gi(&scene, &tracer, spp, args.mode, &|| bar.inc()))
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
            let mut r = pool.install(|| render_gi(&scene, &mapper, spp, args.mode, &|| bar.inc()));
            r.counts.photon = st.rays;
            r
        }
    };
    let render_seconds = start.elapsed().as_secs_f64() - excluded;
    bar.finish();
    let c = &rendered.counts;
    let name = match args.integrator {
        IntegratorArg::Path => "path tracing",
        _ => "photon mapping",
    };
    out!(
        "scene      {}: {}x{}, {name}, {} per pixel, {}\n\
         primitives {}\n\
         build      {build_seconds:.3} s (kd-tree)\n\
         {photon_lines}\
         render     {render_seconds:.3} s\n\
         rays       {} total: {} camera, {} bounce, {} shadow, {} gather, {} photon, {} light\n\
         rays/s     {:.2} M\n\
         tracing    {}\n",
        args.scene,
        s.width,
        s.height,
        super::count(spp as usize, "sample"),
        super::count(threads, "thread"),
        scene.geometry.prim_count(),
        c.total(),
        c.camera,
        c.bounce,
        c.shadow,
        c.gather,
        c.photon,
        c.light,
        c.total() as f64 / render_seconds.max(1e-9) / 1e6,
        routing(args.integrator, args.mode, c),
    );
    let rays = BTreeMap::from([
        ("total", c.total()),
        ("camera", c.camera),
        ("bounce", c.bounce),
        ("shadow", c.shadow),
        ("gather", c.gather),
        ("photon", c.photon),
        ("light", c.light),
    ]);
    let integrator = match args.integrator {
        IntegratorArg::Path => "path",
        _ => "photon",
    };
    let times = [build_seconds, render_seconds];
    let report = Report::new(args, &scene, threads, times, integrator, rays);
    finish(args, &report, &rendered.film, options)
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

/// The local rayon pool of `--threads` (0: one per core) and its size.
fn worker_pool(threads: usize) -> anyhow::Result<(usize, rayon::ThreadPool)> {
    let threads = super::thread_count(threads);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;
    Ok((threads, pool))
}

/// The render's progress on stderr, one step per tile: a bar in a terminal, and
/// otherwise (a log file, a CI job) a line every [`PROGRESS_LINE_SECONDS`], so a long
/// render is never silent.
struct Progress {
    bar: ProgressBar,
    /// Set when stderr is not a terminal: when the render started, and when the last
    /// line was printed (milliseconds since the start).
    lines: Option<(Instant, AtomicU64)>,
    unit: &'static str,
}

/// Seconds between the progress lines of a render whose stderr is not a terminal.
const PROGRESS_LINE_SECONDS: u64 = 5;

impl Progress {
    /// A bar of `steps` steps, each one of `unit` (tiles, pieces).
    fn new(steps: u64, unit: &'static str) -> anyhow::Result<Progress> {
        let bar = ProgressBar::new(steps);
        bar.set_style(
            ProgressStyle::with_template(&format!(
                "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit}, eta {{eta}}"
            ))
            .context("progress bar template")?
            .progress_chars("=> "),
        );
        let lines = (!std::io::stderr().is_terminal()).then(|| (Instant::now(), AtomicU64::new(0)));
        Ok(Progress { bar, lines, unit })
    }

    /// One more step done.
    fn inc(&self) {
        self.bar.inc(1);
        let Some((start, last)) = &self.lines else {
            return;
        };
        let now = start.elapsed().as_millis() as u64;
        let prev = last.load(Ordering::Relaxed);
        // One thread of the pool prints; the others see the new time and go on.
        if now >= prev + PROGRESS_LINE_SECONDS * 1000
            && last
                .compare_exchange(prev, now, Ordering::Relaxed, Ordering::Relaxed)
                .is_ok()
        {
            let (done, all) = (self.bar.position(), self.bar.length().unwrap_or(0));
            eprintln!(
                "raypack: {done}/{all} {} ({:.0}%) in {:.0} s",
                self.unit,
                100.0 * done as f64 / all.max(1) as f64,
                now as f64 / 1000.0
            );
        }
    }

    fn finish(&self) {
        self.bar.finish();
    }
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
        s.antialias = studio::whitted_antialias(s.antialias, spp).ok_or_else(|| {
            BadInput(format!(
                "--spp must be a square between 1 and 256 (1, 4, 9, 16, ...), not {spp}"
            ))
        })?;
    }
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    Ok(())
}

fn summary(
    scene_name: &str,
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
        "scene      {}: {}x{}, {sampling}, {}\n\
         primitives {}\n\
         build      {build_seconds:.3} s (kd-tree)\n\
         render     {render_seconds:.3} s\n\
         rays       {} total: {} primary, {} shadow, {} reflection, {} refraction, {} glossy\n\
         rays/s     {:.2} M\n\
         {}",
        scene_name,
        s.width,
        s.height,
        super::count(threads, "thread"),
        scene.geometry.prim_count(),
        c.total(),
        c.primary,
        c.shadow,
        c.reflection,
        c.refraction,
        c.glossy,
        rays_per_second / 1e6,
        packet_summary(c),
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
