//! Property test, seeded: on random scenes (random triangle soups, spheres, boxes, some
//! flat, and planes, at random scales and offsets), random rays grouped into packets with
//! adversarial lanes — active NaN and zero-direction lanes, ±0.0 components, rays starting
//! on a surface, mixed direction signs, inactive lanes full of NaN — the kd-tree's packet
//! path equals its scalar path lane by lane (same primitive, `t`, `u`, `v` bits, same
//! occlusion), and the scalar path equals brute force. A failure names the scene seed.

mod common;

use common::hit_bits;
use glam::Vec3;
use raypack::accel::Accel;
use raypack::accel::brute::BruteForce;
use raypack::accel::kdtree::KdTree;
use raypack::accel::packet::RayPacket;
use raypack::ray::Ray;
use raypack::scene::generate::{self, Rng};
use raypack::scene::{Aabb, Geometry, Plane, Sphere};
use raypack::simd::{Float, LaneMask, Mask, Simd, Vf};

const SCENES: u64 = 64;
const PACKETS: usize = 600;

/// Scene number `seed`: everything placed in `[0, 1]^3`, then scaled and moved.
fn random_scene(seed: u64) -> Geometry {
    let mut rng = Rng::new(seed);
    let tris = rng.below(400);
    let mut g = generate::random_soup(tris, rng.range(0.02, 0.5), seed);
    if rng.below(3) == 0 {
        g = generate::merge(&[g, generate::closed_box(1 + rng.below(4))]);
        let s = 1.0 / 4.0;
        for v in &mut g.vertices {
            *v *= s;
        }
    }
    for _ in 0..rng.below(40) {
        g.spheres.push(Sphere {
            center: rng.point(Vec3::ZERO, Vec3::ONE),
            radius: rng.range(0.001, 0.2),
        });
    }
    for _ in 0..rng.below(40) {
        let lo = rng.point(Vec3::ZERO, Vec3::ONE);
        let mut hi = lo + rng.point(Vec3::ZERO, Vec3::splat(0.2));
        if rng.below(3) == 0 {
            hi[rng.below(3) as usize] = lo[rng.below(3) as usize].min(hi.x);
            hi = hi.max(lo);
        }
        g.boxes.push(Aabb::new(lo, hi));
    }
    for _ in 0..rng.below(3) {
        g.planes.push(Plane {
            normal: rng.unit_vector(),
            offset: rng.range(-0.5, 0.5),
        });
    }
    let scale = [1.0, 1e-3, 1e3, 37.5][rng.below(4) as usize];
    let offset = rng.point(Vec3::splat(-2.0), Vec3::splat(2.0)) * scale;
    for v in &mut g.vertices {
        *v = *v * scale + offset;
    }
    for s in &mut g.spheres {
        s.center = s.center * scale + offset;
        s.radius *= scale;
    }
    for b in &mut g.boxes {
        *b = Aabb::new(b.min * scale + offset, b.max * scale + offset);
    }
    for p in &mut g.planes {
        p.offset = p.offset * scale + p.normal.dot(offset);
    }
    g
}

/// One lane: mostly ordinary rays about the scene, some adversarial.
fn random_lane(rng: &mut Rng, g: &Geometry, accel: &BruteForce) -> Ray {
    let b = accel.bounds();
    let (lo, hi) = if b.is_empty() {
        (Vec3::splat(-1.0), Vec3::ONE)
    } else {
        (b.min - b.extent() * 0.2, b.max + b.extent() * 0.2)
    };
    let mut org = rng.point(lo, hi);
    let mut dir = rng.unit_vector();
    match rng.below(10) {
        0 => dir = Vec3::new(f32::NAN, dir.y, dir.z),
        1 => dir = Vec3::ZERO,
        2 => {
            for a in 0..3 {
                if rng.below(2) == 0 {
                    dir[a] = if rng.below(2) == 0 { 0.0 } else { -0.0 };
                }
            }
        }
        3 if !g.triangles.is_empty() => {
            // From a point of a triangle (on its surface, an edge or a corner).
            let [p, q, r] = g.triangle(rng.below(g.triangles.len() as u32));
            org = match rng.below(3) {
                0 => p,
                1 => (p + q) * 0.5,
                _ => (p + q + r) / 3.0,
            };
        }
        4 => {
            if let Some(h) = accel.intersect(&Ray::new(org, dir, 0.0, f32::INFINITY)) {
                org += dir * h.t;
                dir = rng.unit_vector();
            }
        }
        _ => {}
    }
    let t_max = if rng.below(4) == 0 {
        rng.range(0.0, 2.0) * (hi - lo).length()
    } else {
        f32::INFINITY
    };
    Ray::new(org, dir, 0.0, t_max)
}

#[test]
fn packet_equals_scalar_equals_brute_force_on_random_scenes() {
    at_every_width!(packet_equals_scalar_at);
}

fn packet_equals_scalar_at<W: Simd>() {
    let mut hits = 0usize;
    for seed in 0..SCENES {
        let g = random_scene(1000 + seed);
        let tree = KdTree::build(&g);
        tree.validate()
            .unwrap_or_else(|e| panic!("scene {seed}: {e}"));
        let brute = BruteForce::new(&g);
        let mut rng = Rng::new(seed);
        for n in 0..PACKETS {
            let rays: Vec<Ray> = (0..W::LANES)
                .map(|_| random_lane(&mut rng, &g, &brute))
                .collect();
            let mut packet = RayPacket::<W>::from_rays(&rays);
            let live = if rng.below(4) == 0 {
                rng.below(W::all_bits())
            } else {
                W::all_bits()
            };
            packet.active = Mask::<W>::from_bits(live);
            // Inactive lanes hold NaN: they must not change anything.
            for a in 0..3 {
                let o = packet.org[a];
                packet.org[a] = Vf::<W>::from_fn(|i| {
                    if live & (1 << i) == 0 {
                        f32::NAN
                    } else {
                        o.lane(i)
                    }
                });
            }
            let got = tree.intersect_packet(&packet);
            let occluded = tree.occluded_packet(&packet);
            for (i, ray) in rays.iter().enumerate() {
                let what = || format!("scene {seed}, packet {n}, lane {i}: {ray:?}");
                let lane = got.lane(i);
                if live & (1 << i) == 0 {
                    assert!(
                        !lane.is_hit() && occluded & (1 << i) == 0,
                        "{} (inactive)",
                        what()
                    );
                    continue;
                }
                let scalar = tree.intersect(ray);
                assert_eq!(
                    hit_bits(scalar),
                    hit_bits(brute.intersect(ray)),
                    "{}: kd-tree vs brute",
                    what()
                );
                assert_eq!(
                    hit_bits(lane.is_hit().then_some(lane)),
                    hit_bits(scalar),
                    "{}: packet vs scalar",
                    what()
                );
                let blocked = tree.occluded(ray);
                assert_eq!(
                    blocked,
                    brute.occluded(ray),
                    "{}: occluded vs brute",
                    what()
                );
                assert_eq!(
                    occluded & (1 << i) != 0,
                    blocked,
                    "{}: packet occluded",
                    what()
                );
                hits += scalar.is_some() as usize;
            }
        }
    }
    assert!(hits > (SCENES as usize * PACKETS), "only {hits} hits");
}
