//! Scalar against packet kd-tree traversal on Crytek Sponza from ../shared/scenes, one
//! thread: `traverse/{scalar,packet}/{primary,shadow}`.
//!
//! - primary: the 1024x768 camera rays of cameras.toml, in RAYS.md's packet order (2x2
//!   quads in 16x16 tiles); the scalar path traces the same rays one at a time.
//! - shadow: from each primary hit, offset along the geometric normal facing the ray by
//!   1e-4 of the scene diagonal, toward a point light in the atrium (any-hit, `t_max` =
//!   distance to the light); a packet holds the shadow rays of one quad, lanes whose
//!   primary ray missed are inactive.
//!
//! Rays are built once, outside the timed loop; hits go through `black_box` into a
//! checksum. Throughput is in rays, so reports read in rays/s.

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use raypack::accel::Accel;
use raypack::accel::kdtree::KdTree;
use raypack::accel::packet::{RayPacket, quad_order};
use raypack::ray::Ray;
use raypack::scene::{Camera, Geometry};
use raypack::simd::LANES;
use std::hint::black_box;

const WIDTH: u32 = 1024;
const HEIGHT: u32 = 768;

/// Primary quads and, per quad, its shadow rays (`None` where the primary ray missed).
fn ray_sets(
    tree: &KdTree,
    g: &Geometry,
    camera: &Camera,
) -> (Vec<[Ray; LANES]>, Vec<[Option<Ray>; LANES]>) {
    let frame = camera.frame(WIDTH, HEIGHT);
    let quads: Vec<_> = quad_order(WIDTH, HEIGHT)
        .into_iter()
        .map(|(x, y)| RayPacket::camera_quad(&frame, x, y))
        .collect();
    let b = g.bounds();
    let eps = 1e-4 * b.diagonal();
    let light = Vec3::new(0.0, b.min.y + (b.max.y - b.min.y) * 0.8, 0.0);
    let shadows = quads
        .iter()
        .map(|q| {
            q.map(|r| {
                let h = tree.intersect(&r)?;
                let n = g.geometric_normal(h.prim, r.at(h.t));
                let n = if n.dot(r.dir) > 0.0 { -n } else { n };
                let p = r.at(h.t) + n * eps;
                let to = light - p;
                Some(Ray::new(p, to.normalize(), 0.0, to.length()))
            })
        })
        .collect();
    (quads, shadows)
}

fn traverse(c: &mut Criterion) {
    let (g, camera) = common::shared_scene("sponza");
    let tree = KdTree::build(&g);
    let (quads, shadows) = ray_sets(&tree, &g, &camera);
    let primary_rays: Vec<Ray> = quads.iter().flatten().copied().collect();
    let primary_packets: Vec<RayPacket> = quads.iter().map(|q| RayPacket::from_rays(q)).collect();
    let shadow_rays: Vec<Ray> = shadows.iter().flatten().flatten().copied().collect();
    let shadow_packets: Vec<RayPacket> = shadows.iter().map(RayPacket::from_lanes).collect();

    let mut group = c.benchmark_group("traverse/scalar");
    group.sample_size(10);
    group.throughput(Throughput::Elements(primary_rays.len() as u64));
    group.bench_function("primary", |b| {
        b.iter(|| {
            let mut sum = 0u64;
            for r in &primary_rays {
                sum += tree
                    .intersect(black_box(r))
                    .map_or(0, |h| h.prim as u64 + 1);
            }
            black_box(sum)
        })
    });
    group.throughput(Throughput::Elements(shadow_rays.len() as u64));
    group.bench_function("shadow", |b| {
        b.iter(|| {
            let occluded = shadow_rays
                .iter()
                .filter(|r| tree.occluded(black_box(r)))
                .count();
            black_box(occluded)
        })
    });
    group.finish();

    let mut group = c.benchmark_group("traverse/packet");
    group.sample_size(10);
    group.throughput(Throughput::Elements(primary_rays.len() as u64));
    group.bench_function("primary", |b| {
        b.iter(|| {
            let mut sum = 0u64;
            for p in &primary_packets {
                let h = tree.intersect_packet(black_box(p));
                sum += h
                    .prim
                    .to_array()
                    .iter()
                    .map(|&p| p.wrapping_add(1) as u64)
                    .sum::<u64>();
            }
            black_box(sum)
        })
    });
    group.throughput(Throughput::Elements(shadow_rays.len() as u64));
    group.bench_function("shadow", |b| {
        b.iter(|| {
            let occluded: u32 = shadow_packets
                .iter()
                .map(|p| tree.occluded_packet(black_box(p)).count_ones())
                .sum();
            black_box(occluded)
        })
    });
    group.finish();
}

criterion_group!(benches, traverse);
criterion_main!(benches);
