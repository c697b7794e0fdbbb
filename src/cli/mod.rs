//! Subcommands, one file each.

pub mod bench;
pub mod info;
pub mod rays;
pub mod render;
pub mod trace;

use clap::{Parser, Subcommand};
use raypack::accel::kdtree::BuildParams;

#[derive(Parser, Debug)]
#[command(
    name = "raypack",
    version,
    about = "A packet ray tracer: SAH kd-tree, 4-ray SIMD packets"
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
    /// Build the kd-tree of a scene and print its statistics.
    Info(info::Args),
    /// Trace a ray file and write the hits file.
    Trace(trace::Args),
    /// Write a standard ray set.
    Rays(rays::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
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
        Ok(BuildParams {
            traversal_cost: self.traversal_cost,
            intersection_cost: self.intersection_cost,
            empty_bonus: self.empty_bonus,
            ..BuildParams::default()
        })
    }
}

/// An error in what the user gave us (arguments, files); exits with code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Loads a scene argument of `bench`, `trace` or `rays` and says what was loaded.
pub fn load_scene(arg: &str) -> anyhow::Result<raypack::rayset::scenes::BenchScene> {
    let scene = raypack::rayset::scenes::load(arg)?;
    eprintln!(
        "{}: {} triangles, {} spheres, {} boxes, {} planes (loaded in {:.2} s)",
        scene.name,
        scene.geometry.triangles.len(),
        scene.geometry.spheres.len(),
        scene.geometry.boxes.len(),
        scene.geometry.planes.len(),
        scene.load_seconds
    );
    warn(&scene.warnings);
    Ok(scene)
}

/// Prints each loader warning once on stderr.
pub fn warn(warnings: &[raypack::scene::Warning]) {
    for w in warnings {
        eprintln!("raypack: warning: {w}");
    }
}

/// 2 when the error was caused by bad input, 1 otherwise.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    let bad_input = e
        .chain()
        .any(|c| c.is::<BadInput>() || raypack::is_input_error(c));
    if bad_input { 2 } else { 1 }
}
