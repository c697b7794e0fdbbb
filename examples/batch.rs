//! Tracing many rays from a program: a million incoherent rays (from random points on a
//! sphere around the mesh to random points in its bounds, like the bounces of a path
//! tracer) through `Accel::intersect_batch` and `occluded_batch` on every core, with the
//! rate in Mrays/s.
//!
//!     cargo run --release --example batch [MESH.obj] [RAYS]
//!
//! The mesh defaults to the repository's `scenes/knot.obj`; RAYS to 1,000,000. RAYS may
//! also be a `.rays` file (`raypack rays`, ../shared/RAYS.md): then those rays are traced,
//! the same rays `raypack bench --rays` times (perf/isa.md compares the two).

use raypack::prelude::*;
use raypack::rng::Pcg32;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "scenes/knot.obj".into());
    let rays_arg = args.next();
    let from_file = rays_arg.as_deref().filter(|a| a.ends_with(".rays"));
    let count: usize = match (&rays_arg, from_file) {
        (_, Some(_)) => 0,
        (Some(n), None) => n
            .parse()
            .map_err(|_| format!("RAYS: `{n}` is neither a count nor a .rays file"))?,
        (None, None) => 1_000_000,
    };
    let start = Instant::now();
    let tree = KdTree::build(&Geometry::from(obj::load(path.as_ref())?));
    println!(
        "{path}: kd-tree built in {:.3} s",
        start.elapsed().as_secs_f64()
    );

    let bounds = tree.bounds();
    let centre = (bounds.min + bounds.max) * 0.5;
    let radius = bounds.diagonal();
    let mut rng = Pcg32::new(7, 1);
    let mut unit = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    let rays: Vec<Ray> = match from_file {
        Some(file) => raypack::rayset::read_rays(file.as_ref())?.rays,
        None => (0..count)
            .map(|_| {
                let org = centre + (unit() * 2.0 - Vec3::ONE).normalize_or(Vec3::X) * radius;
                let target = bounds.min + unit() * (bounds.max - bounds.min);
                Ray::new(org, (target - org).normalize(), 0.0, f32::INFINITY)
            })
            .collect(),
    };

    let threads = rayon::current_num_threads();
    // The kernels' instruction set: the widest this CPU runs, whatever flags built this.
    println!("kernels: {}", raypack::simd::Isa::in_use());
    let mut hits = vec![Hit::MISS; rays.len()];
    let mut blocked = vec![false; rays.len()];
    let closest = median_rate(rays.len(), || tree.intersect_batch(&rays, &mut hits));
    let any = median_rate(rays.len(), || tree.occluded_batch(&rays, &mut blocked));
    for (name, rate) in [("intersect_batch", closest), ("occluded_batch", any)] {
        println!(
            "{name:<16} {} rays on {threads} threads: {rate:.2} Mrays/s (median of 5)",
            rays.len()
        );
    }
    let hit_count = hits.iter().filter(|h| h.is_hit()).count();
    assert!(hits.iter().zip(&blocked).all(|(h, b)| h.is_hit() == *b));
    println!("{hit_count} of {} rays hit", rays.len());
    Ok(())
}

/// Mrays/s of `trace` over `rays` rays: the median of 5 timed calls after one warm-up.
fn median_rate(rays: usize, mut trace: impl FnMut()) -> f64 {
    trace();
    let mut rates: Vec<f64> = (0..5)
        .map(|_| {
            let start = Instant::now();
            trace();
            rays as f64 / start.elapsed().as_secs_f64() / 1e6
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    rates[2]
}
