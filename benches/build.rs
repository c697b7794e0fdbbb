//! kd-tree build time on the benchmark meshes of ../shared/scenes: `build/{bunny,sponza}`
//! with the default parameters (the fast builder: binned SAH for large nodes, the exact
//! sweep below), `build/exact/{bunny,sponza}` with Wald & Havran's sweep at every node.
//! Both run parallel on the global rayon pool; `RAYON_NUM_THREADS=1` measures one core.
//! Throughput counts triangles. The meshes are read once, outside the timed loop.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use raypack::accel::kdtree::{BuildParams, BuilderKind, KdTree};
use raypack::scene::catalog;
use std::hint::black_box;

fn build(c: &mut Criterion) {
    let mut group = c.benchmark_group("build");
    group.sample_size(10);
    let exact = BuildParams {
        builder: BuilderKind::Exact,
        ..BuildParams::default()
    };
    for name in ["bunny", "sponza"] {
        let scene = catalog::load(name).unwrap_or_else(|e| panic!("{e}"));
        group.throughput(Throughput::Elements(scene.geometry.triangles.len() as u64));
        group.bench_function(name, |b| {
            b.iter(|| black_box(KdTree::build(black_box(&scene.geometry))))
        });
        group.bench_function(format!("exact/{name}"), |b| {
            b.iter(|| black_box(KdTree::build_with(black_box(&scene.geometry), &exact)))
        });
    }
    group.finish();
}

criterion_group!(benches, build);
criterion_main!(benches);
