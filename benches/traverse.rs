//! Scalar against packet kd-tree traversal on Crytek Sponza from ../shared/scenes, one
//! thread, on the standard ray sets of RAYS.md (`raypack::rayset::standard`, the sets
//! `raypack bench` and the Embree harness trace):
//! `traverse/{scalar,packet}/{primary,shadow,diffuse}`.
//!
//! - primary: the 1024x768 camera rays of cameras.toml in packet order (2x2 quads in
//!   16x16 tiles); packet mode traces each quad as one packet;
//! - shadow: one ray per primary hit toward the point light, any-hit;
//! - diffuse: one cosine-weighted bounce per primary hit, closest hit.
//!
//! Packet mode takes 4 consecutive rays per packet, as the Embree harness's packet4.
//! Sets are made once, outside the timed loop; every answer is folded into a checksum
//! through `black_box`. Throughput is in rays, so reports read in rays/s.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use raypack::accel::Mode;
use raypack::accel::kdtree::KdTree;
use raypack::rayset::standard;
use raypack::rayset::trace::{Order, Query, checksum_chunk};
use raypack::scene::catalog;
use std::hint::black_box;

fn traverse(c: &mut Criterion) {
    let scene = catalog::load("sponza").unwrap_or_else(|e| panic!("{e}"));
    let tree = KdTree::build(&scene.geometry);
    let sets = standard::standard_sets(
        &tree,
        &scene.geometry,
        &scene.view,
        standard::WIDTH,
        standard::HEIGHT,
        None,
    )
    .expect("standard sets");
    for mode in Mode::ALL {
        let mut group = c.benchmark_group(format!("traverse/{mode}"));
        group.sample_size(10);
        for (name, set, query) in [
            ("primary", &sets.primary, Query::Closest),
            ("shadow", &sets.shadow, Query::Occluded),
            ("diffuse", &sets.diffuse, Query::Closest),
        ] {
            group.throughput(Throughput::Elements(set.len() as u64));
            group.bench_function(name, |b| {
                b.iter(|| {
                    black_box(checksum_chunk(
                        &tree,
                        black_box(&set.rays),
                        Order::of(set),
                        mode,
                        query,
                    ))
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, traverse);
criterion_main!(benches);
