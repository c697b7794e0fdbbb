//! Numeric edge cases: NaN, infinite and zero-length rays, empty `t` ranges, scenes at
//! 1e-6 and 1e6 scale and far from the origin, and rays starting exactly on triangle
//! edges, corners and split planes. Each must finish (no panic, no endless walk) with
//! the answer documented on [`raypack::accel::Accel`], the same from the kd-tree's
//! scalar and packet paths and from brute force.

mod common;

use common::closed::{leaks_packet, leaks_scalar};
use common::hit_bits;
use common::{adversarial_rays, mixed_primitives, random_rays};
use glam::Vec3;
use rayon::prelude::*;
use raypack::accel::brute::BruteForce;
use raypack::accel::kdtree::KdTree;
use raypack::accel::packet::RayPacket;
use raypack::accel::{Accel, TILE_RAYS};
use raypack::ray::Ray;
use raypack::scene::Geometry;
use raypack::scene::generate::{self, Rng};
use raypack::simd::{W4, W8, W16};

/// Asserts that the kd-tree (scalar and packet) and brute force agree bit for bit on
/// every ray's closest hit and occlusion, on every core; returns the number of hits.
fn assert_agree(g: &Geometry, tree: &KdTree, rays: &[Ray], what: &str) -> usize {
    let brute = BruteForce::new(g);
    rays.par_chunks(8)
        .enumerate()
        .map(|(c, chunk)| {
            let packet = RayPacket::<W8>::from_rays(chunk);
            // The packet answers under each instruction set the CPU runs.
            let by_isa: Vec<_> = common::isas()
                .into_iter()
                .map(|isa| {
                    let answers = isa
                        .scope(|| {
                            (
                                tree.intersect_packet(&packet),
                                tree.occluded_packet(&packet),
                            )
                        })
                        .expect("a supported instruction set");
                    (isa, answers)
                })
                .collect();
            let mut hits = 0;
            for (i, ray) in chunk.iter().enumerate() {
                let want = brute.intersect(ray);
                let occluded = brute.occluded(ray);
                assert_eq!(
                    hit_bits(tree.intersect(ray)),
                    hit_bits(want),
                    "{what}: ray {} {ray:?} kd-tree vs brute",
                    c * 8 + i
                );
                assert_eq!(tree.occluded(ray), occluded, "{what}: ray {ray:?} occluded");
                for (isa, (packet_hits, packet_occluded)) in &by_isa {
                    let lane = packet_hits.lane(i);
                    assert_eq!(
                        hit_bits(lane.is_hit().then_some(lane)),
                        hit_bits(want),
                        "{what}: ray {} {ray:?} packet ({isa}) vs brute",
                        c * 8 + i
                    );
                    assert_eq!(
                        packet_occluded & (1 << i) != 0,
                        occluded,
                        "{what}: ray {ray:?} packet ({isa}) occluded"
                    );
                }
                hits += want.is_some() as usize;
            }
            hits
        })
        .sum()
}

#[test]
fn nan_infinite_and_zero_rays_hit_nothing() {
    let g = mixed_primitives();
    let tree = KdTree::build(&g);
    let brute = BruteForce::new(&g);
    let inside = Vec3::new(0.5, 0.5, 0.5);
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let bad = [
        Ray::new(inside, Vec3::new(nan, 0.0, 1.0), 0.0, inf),
        Ray::new(inside, Vec3::splat(nan), 0.0, inf),
        Ray::new(Vec3::new(0.5, nan, 0.5), Vec3::Y, 0.0, inf),
        Ray::new(inside, Vec3::ZERO, 0.0, inf),
        Ray::new(inside, Vec3::new(-0.0, 0.0, -0.0), 0.0, 10.0),
        Ray::new(inside, Vec3::new(inf, 0.0, 0.0), 0.0, inf),
        Ray::new(Vec3::new(-inf, 0.5, 0.5), Vec3::X, 0.0, inf),
        Ray::new(inside, Vec3::Y, nan, inf),
        Ray::new(inside, Vec3::Y, 0.0, nan),
        Ray::new(inside, Vec3::Y, 2.0, 1.0),
        Ray::new(inside, Vec3::Y, inf, inf),
    ];
    for ray in &bad {
        assert_eq!(brute.intersect(ray), None, "brute {ray:?}");
        assert_eq!(tree.intersect(ray), None, "kd-tree {ray:?}");
        assert!(
            !brute.occluded(ray) && !tree.occluded(ray),
            "occluded {ray:?}"
        );
    }
    // In a packet, beside good lanes: the bad lane misses and the good lanes get their
    // scalar answers.
    let good = Ray::new(Vec3::new(0.5, 2.0, 0.5), -Vec3::Y, 0.0, inf);
    let want = tree.intersect(&good).expect("the good ray hits");
    for (isa, ray) in common::isas()
        .into_iter()
        .flat_map(|i| bad.iter().map(move |r| (i, r)))
    {
        let packet = RayPacket::<W4>::from_rays(&[good, *ray, good, *ray]);
        let (hits, occluded) = isa
            .scope(|| {
                (
                    tree.intersect_packet(&packet),
                    tree.occluded_packet(&packet),
                )
            })
            .expect("a supported instruction set");
        assert_eq!(occluded, 0b0101, "{ray:?}");
        for i in [0, 2] {
            assert_eq!(
                hit_bits(Some(hits.lane(i))),
                hit_bits(Some(want)),
                "{ray:?}"
            );
        }
        assert!(!hits.lane(1).is_hit() && !hits.lane(3).is_hit(), "{ray:?}");
    }
}

/// `g` scaled by `scale` about the origin and moved by `offset`.
fn transformed(g: &Geometry, scale: f32, offset: Vec3) -> Geometry {
    let mut g = g.clone();
    for v in &mut g.vertices {
        *v = *v * scale + offset;
    }
    g
}

#[test]
fn tiny_huge_and_far_scenes_agree_with_brute_force_and_stay_watertight() {
    let sphere = generate::tessellated_sphere(Vec3::new(0.2, -0.1, 0.3), 1.0, 24, 32);
    let soup = generate::random_soup(2_000, 0.2, 5);
    for (scale, offset) in [
        (1e-6, Vec3::ZERO),
        (1e6, Vec3::ZERO),
        (1.0, Vec3::new(1e4, -2e4, 3e3)),
        (1e-3, Vec3::new(0.0, 1e3, 0.0)),
    ] {
        let what = format!("scale {scale:e}, offset {offset}");
        let closed = transformed(&sphere, scale, offset);
        let g = generate::merge(&[closed.clone(), transformed(&soup, scale, offset)]);
        let tree = KdTree::build(&g);
        let b = g.bounds();
        let mut rays = random_rays(b.min, b.max, 4_000, 7);
        rays.extend(adversarial_rays(&tree, &g, 4_000, 8));
        let hits = assert_agree(&g, &tree, &rays, &what);
        assert!(hits > 2_000, "{what}: only {hits} hits");

        let closed_tree = KdTree::build(&closed);
        let mut rng = Rng::new(9);
        let centre = Vec3::new(0.2, -0.1, 0.3) * scale + offset;
        let interior: Vec<Ray> = (0..common::ray_count(1 << 14, 100_000))
            .map(|_| {
                let p = rng.point(Vec3::splat(-0.5), Vec3::splat(0.5)) * scale + centre;
                Ray::new(p, rng.unit_vector(), 0.0, f32::INFINITY)
            })
            .collect();
        assert_eq!(
            leaks_scalar(&closed_tree, &interior).len(),
            0,
            "{what}: scalar leaks"
        );
        for isa in common::isas() {
            assert_eq!(
                leaks_packet::<W4>(isa, &closed_tree, &interior).len(),
                0,
                "{what}: packet leaks (4 lanes, {isa})"
            );
            assert_eq!(
                leaks_packet::<W16>(isa, &closed_tree, &interior).len(),
                0,
                "{what}: packet leaks (16 lanes, {isa})"
            );
        }
    }
}

#[test]
fn rays_starting_on_edges_corners_and_split_planes_are_defined() {
    for (name, g) in [
        ("box", generate::closed_box(6)),
        ("warped grid", generate::warped_closed_grid(12)),
        ("grid", generate::axis_aligned_grid(4)),
    ] {
        let tree = KdTree::build(&g);
        let mut rng = Rng::new(77);
        let mut rays = Vec::new();
        for _ in 0..3_000 {
            let [a, b, c] = g.triangle(rng.below(g.triangles.len() as u32));
            let org = match rng.below(4) {
                0 => a,
                1 => (a + b) * 0.5,
                2 => b + (c - b) * rng.f32(),
                _ => (a + b + c) / 3.0,
            };
            let mut dir = rng.unit_vector();
            if rng.below(4) == 0 {
                // Along an edge, or an axis with signed zeros.
                dir = if rng.below(2) == 0 {
                    c - a
                } else {
                    Vec3::new(0.0, -0.0, 1.0)
                };
            }
            rays.push(Ray::new(org, dir, 0.0, f32::INFINITY));
        }
        rays.extend(adversarial_rays(&tree, &g, 3_000, 78));
        assert_agree(&g, &tree, &rays, name);
    }
}

/// A direction component so small that `org * (1 / d)` overflows (|d| below
/// |org| / f32::MAX, a normal or subnormal float): the node step's band ends become
/// infinite or NaN, and every path must still find brute force's hit. A fused
/// multiply-add in the node step got this wrong (an exact product plus an overflowed
/// offset gave -inf where the plane lay ahead, and the walk skipped the hit's cell), so
/// the walks that fuse it (packet, tile and lane walks) send such rays to the scalar walk
/// (src/accel/kdtree/traverse.rs).
#[test]
fn overflowing_inverse_directions_agree_with_brute_force() {
    let g = transformed(&mixed_primitives(), 20.0, Vec3::new(8.0, -12.0, 15.0));
    let tree = KdTree::build(&g);
    let bounds = tree.bounds();
    let mut rng = Rng::new(17);
    let tiny = [1.5e-38, -1.2e-38, 3e-39, -1e-45, 1e-37, -2e-36];
    let rays: Vec<Ray> = (0..common::ray_count(1 << 13, 1 << 16))
        .map(|i| {
            let org = rng.point(bounds.min, bounds.max);
            let mut d = rng.unit_vector();
            d[i % 3] = tiny[(i / 3) % tiny.len()];
            Ray::new(org, d.normalize(), 0.0, f32::INFINITY)
        })
        .collect();
    let hits = assert_agree(&g, &tree, &rays, "tiny direction components");
    assert!(hits > rays.len() / 4, "only {hits} hits");
    // The lane walks (streams), under every instruction set.
    let brute = BruteForce::new(&g);
    let want: Vec<_> = rays.iter().map(|r| hit_bits(brute.intersect(r))).collect();
    common::each_isa(|| {
        let mut got = vec![raypack::ray::Hit::MISS; rays.len()];
        tree.intersect_lanes_in::<W8>(&rays, &mut got, 1);
        for (i, (h, w)) in got.iter().zip(&want).enumerate() {
            let h = hit_bits(h.is_hit().then_some(*h));
            assert_eq!(
                h,
                *w,
                "stream ({}): ray {i} {:?}",
                raypack::simd::Isa::in_use(),
                rays[i]
            );
        }
    });
    // Tiles of 64 coherent rays (one origin, directions a little apart, the tiny
    // component on the same axis with the same sign in every lane), so the tile and
    // packet walks take them rather than splitting them into small groups.
    let mut tiles = Vec::new();
    for t in 0..64 {
        let org = rng.point(bounds.min, bounds.max);
        let centre = (rng.point(bounds.min, bounds.max) - org).normalize();
        let tiny = tiny[t % tiny.len()];
        for _ in 0..TILE_RAYS {
            let mut d = centre + rng.unit_vector() * 0.05;
            d[t % 3] = tiny;
            tiles.push(Ray::new(org, d.normalize(), 0.0, f32::INFINITY));
        }
    }
    let want: Vec<_> = tiles.iter().map(|r| hit_bits(brute.intersect(r))).collect();
    let hits = want.iter().filter(|h| h.is_some()).count();
    assert!(hits > tiles.len() / 4, "only {hits} tile hits");
    common::each_isa(|| {
        for (tile, want) in tiles.chunks(TILE_RAYS).zip(want.chunks(TILE_RAYS)) {
            let mut got = [raypack::ray::Hit::MISS; TILE_RAYS];
            tree.intersect_tile::<W16>(tile, &mut got);
            let mut also = [raypack::ray::Hit::MISS; TILE_RAYS];
            tree.intersect_tile::<W8>(tile, &mut also);
            for (i, w) in want.iter().enumerate() {
                let isa = raypack::simd::Isa::in_use();
                let (a, b) = (&got[i], &also[i]);
                assert_eq!(
                    hit_bits(a.is_hit().then_some(*a)),
                    *w,
                    "tile16 ({isa}): {:?}",
                    tile[i]
                );
                assert_eq!(
                    hit_bits(b.is_hit().then_some(*b)),
                    *w,
                    "tile8 ({isa}): {:?}",
                    tile[i]
                );
            }
        }
    });
}
