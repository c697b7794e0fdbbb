//! Subcommands, one file each.

pub mod bench;
pub mod info;
pub mod rays;
pub mod render;
pub mod trace;

use clap::{Parser, Subcommand};

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
