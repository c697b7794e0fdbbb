//! `raypack rays`: writes a standard ray set of a scene (RAYS.md), or the scene itself
//! as OBJ (procedural scenes, for other tracers).

use super::{BadInput, bench::prepare, check_size_flags, load_scene};
use anyhow::Context;
use raypack::rayset::{self, standard};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A TOML scene, an OBJ mesh, a scene name of ../shared/scenes/cameras.toml, or spd:NAME[:SIZE].
    pub scene: String,
    /// Which set: primary, shadow or diffuse.
    #[arg(long, default_value = "primary")]
    pub set: String,
    /// The rays file to write.
    #[arg(short, long, value_name = "OUT", alias = "out")]
    pub output: Option<PathBuf>,
    /// Also write the closest hits of the set (scalar path) to this hits file.
    #[arg(long)]
    pub hits: Option<PathBuf>,
    /// Image width of the primary set (a multiple of 16).
    #[arg(long, default_value_t = standard::WIDTH)]
    pub width: u32,
    /// Image height of the primary set (a multiple of 16).
    #[arg(long, default_value_t = standard::HEIGHT)]
    pub height: u32,
    /// Write the scene's geometry as OBJ (spheres as UV spheres) to this file.
    #[arg(long)]
    pub obj: Option<PathBuf>,
    /// Rings of the UV spheres that --obj writes.
    #[arg(long, default_value_t = 8)]
    pub sphere_rings: u32,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.output.is_none() && args.obj.is_none() {
        return Err(BadInput("nothing to write: give -o F.rays and/or --obj F.obj".into()).into());
    }
    if !matches!(args.set.as_str(), "primary" | "shadow" | "diffuse") {
        return Err(BadInput(format!(
            "--set {}: expected primary, shadow or diffuse",
            args.set
        ))
        .into());
    }
    if args.output.is_some() {
        check_size_flags(args.width, args.height)?;
    }
    for (flag, path, extension) in [("-o", &args.output, "rays"), ("--hits", &args.hits, "hits")] {
        if let Some(path) = path {
            super::check_extension(flag, path, extension)?;
        }
    }
    super::check_outputs([
        ("-o", args.output.as_ref()),
        ("--hits", args.hits.as_ref()),
        ("--obj", args.obj.as_ref()),
    ])?;
    let scene = load_scene(&args.scene)?;
    if let Some(obj) = &args.obj {
        raypack::scene::spd::write_obj(obj, &scene.geometry, args.sphere_rings)
            .with_context(|| format!("writing the OBJ of {}", args.scene))?;
        outln!("wrote {}", obj.display());
    }
    let Some(out) = &args.output else {
        return Ok(());
    };
    let (accel, build_seconds, sets) =
        prepare(&scene, args.width, args.height, &Default::default())?;
    let (set, hits) = match args.set.as_str() {
        "primary" => (&sets.primary, Some(&sets.primary_hits)),
        "shadow" => (&sets.shadow, None),
        _ => (&sets.diffuse, None),
    };
    rayset::write_rays(out, set)?;
    outln!(
        "{}: {} {} rays of {} (build {:.3} s); light [{}, {}, {}] ({}), offset {:.6}",
        out.display(),
        set.len(),
        args.set,
        args.scene,
        build_seconds,
        sets.light.x,
        sets.light.y,
        sets.light.z,
        sets.light_source.describe(),
        sets.offset
    );
    if let Some(path) = &args.hits {
        let hits = match hits {
            Some(h) => h.clone(),
            None => standard::closest_hits(&accel, &set.rays),
        };
        rayset::write_hits(path, &hits)?;
        outln!(
            "{}: {} hits",
            path.display(),
            rayset::Checksum::of_hits(&hits).hits
        );
    }
    Ok(())
}
