//! Wald's TriAccel test, scalar against SIMD, per ray-triangle test:
//! `triaccel/{scalar,packet}`.
//!
//! 256 triangles of a tessellated sphere against 1024 coherent rays (256 packets of a
//! 2x2 pixel quad, aimed at the sphere so that about half the tests hit). Every packet
//! meets every triangle: scalar mode runs the 4 lanes' tests one by one, packet mode one
//! 4-wide test. Throughput counts ray-triangle tests. Inputs are built outside `iter`;
//! hits are folded into a checksum through `black_box`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use raypack::accel::RayPacket;
use raypack::accel::triaccel::TriAccel;
use raypack::ray::Ray;
use raypack::simd::{LANES, mask_from_bits, splat};
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
    let packets: Vec<[Ray; LANES]> = (0..256)
        .map(|q| {
            let (qx, qy) = ((q % 16) as f32, (q / 16) as f32);
            std::array::from_fn(|lane| {
                let x = (qx * 2.0 + (lane & 1) as f32) / 32.0 * 2.0 - 1.0;
                let y = (qy * 2.0 + (lane >> 1) as f32) / 32.0 * 2.0 - 1.0;
                let d = Vec3::new(x * 0.4, y * 0.4, 1.0).normalize();
                Ray::new(Vec3::new(0.0, 0.0, -3.0), d, 0.0, f32::INFINITY)
            })
        })
        .collect();
    let tests = (tris.len() * packets.len() * LANES) as u64;

    let mut group = c.benchmark_group("triaccel");
    group.throughput(Throughput::Elements(tests));
    group.bench_function("scalar", |b| {
        b.iter(|| {
            let mut hits = 0u32;
            for quad in &packets {
                for (tri, corners) in &tris {
                    for r in quad {
                        hits += black_box(tri).intersect(r, r.t_max, corners).is_some() as u32;
                    }
                }
            }
            black_box(hits)
        })
    });
    let soa: Vec<RayPacket> = packets.iter().map(|q| RayPacket::from_rays(q)).collect();
    let all = mask_from_bits((1 << LANES) - 1);
    group.bench_function("packet", |b| {
        b.iter(|| {
            let mut hits = 0u32;
            for p in &soa {
                for (tri, corners) in &tris {
                    let h = black_box(tri).intersect_packet(p, all, splat(f32::INFINITY), corners);
                    hits += raypack::simd::bits(h.mask).count_ones();
                }
            }
            black_box(hits)
        })
    });
    group.finish();
}

criterion_group!(benches, triaccel);
criterion_main!(benches);
