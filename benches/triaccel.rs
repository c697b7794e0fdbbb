//! Wald's TriAccel test, scalar against SIMD, per ray-triangle test:
//! `triaccel/{scalar,packet4,packet8,packet16}`.
//!
//! 256 triangles of a tessellated sphere against 1024 coherent rays (a 64x16 pixel
//! grid aimed at the sphere so that about half the tests hit). Every ray meets every
//! triangle: scalar mode runs the tests one by one, packet mode one test per packet of
//! 4, 8 or 16 consecutive rays. Throughput counts ray-triangle tests. Inputs are built outside `iter`;
//! hits are folded into a checksum through `black_box`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use raypack::accel::RayPacket;
use raypack::accel::triaccel::TriAccel;
use raypack::ray::Ray;
use raypack::simd::{Float, LaneMask, Mask, Simd, Vf, W4, W8, W16};
use std::hint::black_box;

/// The triangles of a UV sphere of radius 1 at the origin (`rings` x `2 rings` cells),
/// with their corners (read by the test only for rays within rounding of an edge).
fn sphere_triangles(rings: u32) -> Vec<(TriAccel, [Vec3; 3])> {
    let p = |r: u32, s: u32| {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        let phi = std::f32::consts::PI * s as f32 / rings as f32;
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    };
    let mut tris = Vec::new();
    for r in 0..rings {
        for s in 0..2 * rings {
            let (a, b, c, d) = (p(r, s), p(r + 1, s), p(r + 1, s + 1), p(r, s + 1));
            tris.push((TriAccel::new(a, b, c), [a, b, c]));
            tris.push((TriAccel::new(a, c, d), [a, c, d]));
        }
    }
    tris
}

fn triaccel(c: &mut Criterion) {
    let tris = sphere_triangles(8);
    let rays: Vec<Ray> = (0..1024)
        .map(|i| {
            let (px, py) = ((i % 64) as f32, (i / 64) as f32);
            let x = px / 64.0 * 2.0 - 1.0;
            let y = py / 16.0 * 2.0 - 1.0;
            let d = Vec3::new(x * 0.4, y * 0.4, 1.0).normalize();
            Ray::new(Vec3::new(0.0, 0.0, -3.0), d, 0.0, f32::INFINITY)
        })
        .collect();
    let tests = (tris.len() * rays.len()) as u64;

    let mut group = c.benchmark_group("triaccel");
    group.throughput(Throughput::Elements(tests));
    group.bench_function("scalar", |b| {
        b.iter(|| {
            let mut hits = 0u32;
            for r in &rays {
                for (tri, corners) in &tris {
                    hits += black_box(tri).intersect(r, r.t_max, corners).is_some() as u32;
                }
            }
            black_box(hits)
        })
    });
    packet::<W4>(&mut group, &tris, &rays);
    packet::<W8>(&mut group, &tris, &rays);
    packet::<W16>(&mut group, &tris, &rays);
    group.finish();
}

/// `triaccel/packetN`: every packet of `W::LANES` consecutive rays against every
/// triangle.
fn packet<W: Simd>(
    group: &mut criterion::BenchmarkGroup<criterion::measurement::WallTime>,
    tris: &[(TriAccel, [Vec3; 3])],
    rays: &[Ray],
) {
    let soa: Vec<RayPacket<W>> = rays.chunks(W::LANES).map(RayPacket::from_rays).collect();
    let all = Mask::<W>::from_bits(W::all_bits());
    group.bench_function(format!("packet{}", W::LANES), |b| {
        b.iter(|| {
            let mut hits = 0u32;
            for p in &soa {
                for (tri, corners) in tris {
                    let t_max = Vf::<W>::splat(f32::INFINITY);
                    let h = black_box(tri).intersect_packet(p, all, t_max, corners);
                    hits += h.mask.bits().count_ones();
                }
            }
            black_box(hits)
        })
    });
}

criterion_group!(benches, triaccel);
criterion_main!(benches);
