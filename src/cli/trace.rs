//! `raypack trace`: traces a rays file and writes the hits file (RAYS.md), so that the
//! answers can be compared ray by ray with another tracer's.

use super::{bench::build_accel, load_scene};
use raypack::accel::Mode;
use raypack::rayset::{self, Checksum};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A TOML scene, an OBJ mesh, a scene name of ../shared/scenes/cameras.toml, or spd:NAME[:SIZE].
    pub scene: String,
    /// The rays file to trace.
    #[arg(long)]
    pub rays: PathBuf,
    /// The hits file to write (closest hits, whatever the set).
    #[arg(short, long, value_name = "OUT", alias = "out")]
    pub output: PathBuf,
    /// scalar: one ray at a time; packet4, packet8, packet16: 4, 8 or 16 rays per packet
    /// (in an image set a 2x2, 4x2 or 4x4 pixel block, elsewhere consecutive rays;
    /// packet, the default as in `render`: the widest this CPU runs);
    /// tile64: 64 rays per tile as SIMD groups sharing one walk; stream: one ray per SIMD
    /// lane, each on its own walk (for incoherent rays). Every mode writes the same hits.
    #[arg(long, default_value = "packet")]
    pub mode: Mode,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    super::check_extension("-o", &args.output, "hits")?;
    super::check_output("-o", &args.output)?;
    let rays = rayset::read_rays(&args.rays)?;
    let scene = load_scene(&args.scene)?;
    let (accel, build_seconds) = build_accel(&scene.geometry, &Default::default());
    let start = std::time::Instant::now();
    let hits = rayset::trace::trace_hits(&accel, &rays, args.mode);
    let seconds = start.elapsed().as_secs_f64();
    rayset::write_hits(&args.output, &hits)?;
    outln!(
        "{}: {} rays, {} hits ({} mode, build {:.3} s, trace {:.3} s), checksum {}",
        args.output.display(),
        rays.len(),
        Checksum::of_hits(&hits).hits,
        args.mode,
        build_seconds,
        seconds,
        Checksum::of_hits(&hits)
    );
    Ok(())
}
