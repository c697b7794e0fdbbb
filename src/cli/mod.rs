//! Subcommands, one file each.
//!
//! What a subcommand prints on stdout goes through `outln!` and `out!`: a closed
//! stdout (`raypack render ... | head`) must not stop the work, so a render whose summary
//! nobody reads still writes its image.

/// `println!` that a closed stdout does not stop (see `write_stdout`).
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` that a closed stdout does not stop (see `write_stdout`).
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!($($arg)*))
    };
}

pub mod bench;
pub mod huge_pages;
pub mod info;
pub mod rays;
pub mod render;
pub mod trace;

use anyhow::Context;
use clap::{Parser, Subcommand};
use raypack::accel::kdtree::{BuildParams, BuilderKind};
use raypack::scene::file::{MAX_PIXELS, MAX_SIDE};
use std::path::{Path, PathBuf};

#[cfg(test)]
mod tests {
    use super::count;

    #[test]
    fn counts_are_singular_for_one() {
        assert_eq!(count(1, "triangle"), "1 triangle");
        assert_eq!(count(0, "triangle"), "0 triangles");
        assert_eq!(count(1, "box"), "1 box");
        assert_eq!(count(2, "box"), "2 boxes");
    }
}

#[derive(Parser, Debug)]
#[command(
    name = "raypack",
    version,
    about = "A packet ray tracer: SAH kd-tree, SIMD packets of 4, 8 or 16 rays"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene file to an image.
    Render(render::Args),
    /// Measure rays per second on a scene.
    Bench(bench::Args),
    /// Build the kd-tree (or with --accel bvh8 the BVH) of a scene and print its statistics.
    Info(info::Args),
    /// Trace a ray file and write the hits file.
    Trace(trace::Args),
    /// Write a standard ray set.
    Rays(rays::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    // A bad `RAYPACK_ISA` is an error before any work, not a silent fallback.
    raypack::simd::Isa::from_env().map_err(|e| BadInput(e.to_string()))?;
    match cli.command {
        Command::Render(a) => render::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Info(a) => info::run(a),
        Command::Trace(a) => trace::run(a),
        Command::Rays(a) => rays::run(a),
    }
}

/// The SAH cost model of the kd-tree build, shared by `info` and `bench` so a tree's
/// shape and its rays per second can be compared for the same costs.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct TreeArgs {
    /// Cost of a traversal step in the SAH (K_T).
    #[arg(long, default_value_t = BuildParams::default().traversal_cost)]
    pub traversal_cost: f32,
    /// Cost of a primitive test in the SAH (K_I).
    #[arg(long, default_value_t = BuildParams::default().intersection_cost)]
    pub intersection_cost: f32,
    /// Share of the cost forgiven for cutting off empty space.
    #[arg(long, default_value_t = BuildParams::default().empty_bonus)]
    pub empty_bonus: f32,
    /// The kd-tree builder: exact (Wald & Havran's sweep at every node, the reference)
    /// or fast (binned SAH down to --sweep-below primitives, then vectorised exact
    /// pricing of small nodes; the default).
    #[arg(long, default_value_t = BuilderKind::default(), value_parser = parse_builder)]
    pub builder: BuilderKind,
    /// The fast builder's switch from binning to exact pricing, in primitives per node.
    #[arg(long, default_value_t = BuildParams::default().sweep_below)]
    pub sweep_below: u32,
    /// The fast builder's smallest saving worth a subtree, in SAH cost units: a node
    /// that no subtree could save this much of the tree's cost from becomes a leaf (0:
    /// split wherever the SAH gains at all).
    #[arg(long, default_value_t = BuildParams::default().min_saving)]
    pub min_saving: f32,
    /// Cut the empty margins of a leaf of one or two primitives off with splits at their
    /// bounds while a cut keeps at most 1 - this share of the cell's area (0: no cuts).
    #[arg(long, default_value_t = BuildParams::default().empty_cut)]
    pub empty_cut: f32,
}

fn parse_builder(s: &str) -> Result<BuilderKind, String> {
    s.parse()
}

impl TreeArgs {
    /// Build parameters with these costs; the rest are the defaults.
    pub fn params(&self) -> anyhow::Result<BuildParams> {
        let ok = |x: f32| x.is_finite() && x >= 0.0;
        if !(ok(self.traversal_cost) && ok(self.intersection_cost) && self.intersection_cost > 0.0)
        {
            return Err(BadInput(
                "--traversal-cost and --intersection-cost must be finite, >= 0 and K_I > 0".into(),
            )
            .into());
        }
        if !(0.0..1.0).contains(&self.empty_bonus) {
            return Err(BadInput("--empty-bonus must be in [0, 1)".into()).into());
        }
        if !ok(self.min_saving) {
            return Err(BadInput("--min-saving must be finite and >= 0".into()).into());
        }
        if !(0.0..1.0).contains(&self.empty_cut) {
            return Err(BadInput("--empty-cut must be in [0, 1)".into()).into());
        }
        Ok(BuildParams {
            traversal_cost: self.traversal_cost,
            intersection_cost: self.intersection_cost,
            empty_bonus: self.empty_bonus,
            builder: self.builder,
            sweep_below: self.sweep_below,
            min_saving: self.min_saving,
            empty_cut: self.empty_cut,
            ..BuildParams::default()
        })
    }
}

/// An error in what the user gave us (arguments, files); exits with code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// One side of an image size to check, and where it came from, for the message.
#[derive(Clone, Copy, Debug)]
pub enum ImageSide {
    /// Given on the command line as `flag` (`--width`, `--height`).
    Flag { flag: &'static str, value: u32 },
    /// The scene file's.
    Scene { value: u32 },
}

impl ImageSide {
    fn value(self) -> u32 {
        match self {
            ImageSide::Flag { value, .. } | ImageSide::Scene { value } => value,
        }
    }

    /// `--width 640`, or `the scene's width 640` (`dimension` names the side).
    fn describe(self, dimension: &str) -> String {
        match self {
            ImageSide::Flag { flag, value } => format!("{flag} {value}"),
            ImageSide::Scene { value } => format!("the scene's {dimension} {value}"),
        }
    }
}

/// Holds an image size from the command line (`render`'s overrides, the primary set of
/// `bench` and `rays`) to the limits of scene files, [`MAX_SIDE`] per side and
/// [`MAX_PIXELS`] in all, so no flag can ask for an image a scene file may not: past
/// them the buffers would not fit in memory and the allocation would abort the process.
pub fn check_image_size(width: ImageSide, height: ImageSide) -> Result<(), BadInput> {
    for (side, dimension) in [(width, "width"), (height, "height")] {
        let v = side.value();
        if v == 0 || v > MAX_SIDE {
            return Err(BadInput(format!(
                "{} must be between 1 and {MAX_SIDE}",
                side.describe(dimension)
            )));
        }
    }
    let pixels = width.value() as u64 * height.value() as u64;
    if pixels > MAX_PIXELS {
        return Err(BadInput(format!(
            "{} and {} make {pixels} pixels, more than the limit of {MAX_PIXELS}",
            width.describe("width"),
            height.describe("height")
        )));
    }
    Ok(())
}

/// [`check_image_size`] of `--width` and `--height` (the primary set of `bench`, `rays`).
pub fn check_size_flags(width: u32, height: u32) -> Result<(), BadInput> {
    check_image_size(
        ImageSide::Flag {
            flag: "--width",
            value: width,
        },
        ImageSide::Flag {
            flag: "--height",
            value: height,
        },
    )
}

/// Loads a scene argument of `bench`, `trace` or `rays` and says what was loaded.
pub fn load_scene(arg: &str) -> anyhow::Result<raypack::scene::catalog::BenchScene> {
    let scene = raypack::scene::catalog::load(arg)?;
    eprintln!(
        "{}: {} (loaded in {:.2} s)",
        scene.name,
        primitive_counts(&scene.geometry),
        scene.load_seconds
    );
    warn(&scene.warnings);
    Ok(scene)
}

/// The worker threads `--threads N` asks for: `0` means one per core, in every command.
pub fn thread_count(threads: usize) -> usize {
    if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
}

/// `1 triangle`, `2 triangles`: a count with its noun in the singular where it is 1.
/// `noun` is the singular; the plural adds `s`, or `es` after `x` (`boxes`).
pub fn count(n: usize, noun: &str) -> String {
    let plural = if noun.ends_with('x') { "es" } else { "s" };
    format!("{n} {noun}{}", if n == 1 { "" } else { plural })
}

/// The primitives of `geometry`, each kind named, e.g. `1 triangle, 0 spheres, 2 boxes,
/// 1 plane`.
pub fn primitive_counts(geometry: &raypack::scene::Geometry) -> String {
    [
        count(geometry.triangles.len(), "triangle"),
        count(geometry.spheres.len(), "sphere"),
        count(geometry.boxes.len(), "box"),
        count(geometry.planes.len(), "plane"),
    ]
    .join(", ")
}

/// Prints each loader warning once on stderr.
pub fn warn(warnings: &[raypack::scene::Warning]) {
    for w in warnings {
        eprintln!("raypack: warning: {w}");
    }
}

/// Refuses an output that cannot be written (its folder is missing or read-only, or it
/// names a folder) before any work is done, so a long render or build does not end in a
/// failed write. Not bad input: exit code 1 with the OS error, as a failed write.
pub fn check_output(flag: &str, path: &Path) -> anyhow::Result<()> {
    raypack::output::check_writable(path)
        .with_context(|| format!("{flag} {}: cannot write there", path.display()))
}

/// Refuses an output name that does not end in `.{extension}` (any case): a hits file
/// named `j.png` would be taken for an image by every other tool.
pub fn check_extension(flag: &str, path: &Path, extension: &str) -> Result<(), BadInput> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(extension))
    {
        return Ok(());
    }
    Err(BadInput(format!(
        "{flag} {}: this file is written in the .{extension} format of ../shared/RAYS.md; its name must end in .{extension}",
        path.display()
    )))
}

/// [`check_output`] of each path that is given.
pub fn check_outputs<'a>(
    outputs: impl IntoIterator<Item = (&'static str, Option<&'a PathBuf>)>,
) -> anyhow::Result<()> {
    for (flag, path) in outputs {
        if let Some(path) = path {
            check_output(flag, path)?;
        }
    }
    Ok(())
}

/// Writes to stdout. A reader that went away (`EPIPE`, as after `| head`) is not an
/// error, and any other failure is reported once on stderr: what the command writes to
/// files matters more than its summary.
pub fn write_stdout(args: std::fmt::Arguments) {
    use std::io::Write;
    use std::sync::atomic::{AtomicBool, Ordering};
    static REPORTED: AtomicBool = AtomicBool::new(false);
    let result = std::io::stdout().lock().write_fmt(args);
    if let Err(e) = result
        && e.kind() != std::io::ErrorKind::BrokenPipe
        && !REPORTED.swap(true, Ordering::Relaxed)
    {
        eprintln!("raypack: warning: cannot write to stdout: {e}");
    }
}

/// Writes `value` as pretty JSON to `path`, whole or not at all, and says so.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    raypack::output::write_bytes_atomic(path, text.as_bytes(), |e| e)
        .with_context(|| format!("{}: cannot write the report", path.display()))?;
    outln!("wrote {}", path.display());
    Ok(())
}

/// 2 when the error was caused by bad input, 1 otherwise.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    let bad_input = e
        .chain()
        .any(|c| c.is::<BadInput>() || raypack::is_input_error(c));
    if bad_input { 2 } else { 1 }
}

/// The kernels' instruction set for reports: the one in use, and the widest this CPU
/// runs when `RAYPACK_ISA` forced a lower one (`avx2 (cpu: avx512)`).
pub fn isa_label() -> String {
    use raypack::simd::Isa;
    let (used, best) = (Isa::in_use(), Isa::best());
    if used == best {
        used.name().to_string()
    } else {
        format!("{used} (cpu: {best})")
    }
}
