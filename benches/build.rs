//! kd-tree build time (Wald & Havran's O(N log N) SAH build) on the benchmark meshes of
//! ../shared/scenes: `build/{bunny,sponza}` with the default parameters (parallel on
//! the global rayon pool; `RAYON_NUM_THREADS=1` measures one core). Throughput counts
//! triangles. The meshes are read once, outside the timed loop.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use raypack::accel::kdtree::KdTree;
use raypack::scene::catalog;
use std::hint::black_box;

fn build(c: &mut Criterion) {
    let mut group = c.benchmark_group("build");
    group.sample_size(10);
    for name in ["bunny", "sponza"] {
        let scene = catalog::load(name).unwrap_or_else(|e| panic!("{e}"));
        group.throughput(Throughput::Elements(scene.geometry.triangles.len() as u64));
        group.bench_function(name, |b| {
            b.iter(|| black_box(KdTree::build(black_box(&scene.geometry))))
        });
    }
    group.finish();
}

criterion_group!(benches, build);
criterion_main!(benches);
