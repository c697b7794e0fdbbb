//! The kd-tree against brute force on arbitrary triangles (plus a sphere, a box and a
//! plane) and arbitrary rays, NaN and infinities included: the same closest primitive
//! with bit-identical `t`, `u`, `v`, the same occlusion, through every entry point that
//! traces them: the scalar path, packets of 4, 8 and 16 lanes, the stream queries, the
//! lane walks at 4, 8 and 16 lanes in one group and in two, and tiles of 8- and 16-lane
//! groups. Coordinates are snapped to a coarse lattice part of the time so shared edges,
//! coplanar triangles and origins on split planes come up often; directions take the
//! first ray's signs part of the time so a tile's groups agree and descend together.

#![no_main]

use arbitrary::Arbitrary;
use glam::Vec3;
use libfuzzer_sys::fuzz_target;
use raypack::accel::brute::BruteForce;
use raypack::accel::kdtree::KdTree;
use raypack::accel::kdtree::traverse_tile::TILE_RAYS;
use raypack::accel::packet::RayPacket;
use raypack::accel::{Accel, PacketWidth};
use raypack::ray::{Hit, Ray};
use raypack::scene::{Aabb, Geometry, Plane, Sphere};
use raypack::simd::{Simd, W4, W8, W16};

#[derive(Arbitrary, Debug)]
struct Input {
    snap: bool,
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u8; 3]>,
    extras: bool,
    same_signs: bool,
    rays: Vec<([f32; 3], [f32; 3], f32, f32)>,
}

/// A hit that is no answer, written into the outputs first so a ray a kernel forgets
/// shows up.
const POISON: Hit = Hit {
    t: -7.0,
    u: 7.0,
    v: 7.0,
    prim: 7,
};

fn v(a: [f32; 3], snap: bool) -> Vec3 {
    let p = Vec3::from(a);
    if snap && p.is_finite() {
        (p * 4.0)
            .round()
            .clamp(Vec3::splat(-64.0), Vec3::splat(64.0))
            * 0.25
    } else {
        p
    }
}

/// A hit's primitive, `t`, `u` and `v` as bits.
fn key(h: Hit) -> (u32, u32, u32, u32) {
    (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits())
}

/// [`key`] of a packet or tile lane, whose miss only has to say so.
fn lane_key(h: Hit) -> (u32, u32, u32, u32) {
    key(if h.is_hit() { h } else { Hit::MISS })
}

/// Brute force's answers for one ray: the closest hit ([`Hit::MISS`] for none) and the
/// occlusion.
#[derive(Clone, Copy)]
struct Want {
    hit: Hit,
    occluded: bool,
}

fuzz_target!(|input: Input| {
    let mut g = Geometry::default();
    // Finite corners only: the loaders reject NaN and infinite vertices.
    g.vertices = input
        .vertices
        .iter()
        .take(64)
        .map(|&a| v(a, input.snap))
        .filter(|p| p.is_finite())
        .collect();
    if g.vertices.is_empty() {
        return;
    }
    let n = g.vertices.len() as u32;
    g.triangles = input
        .triangles
        .iter()
        .take(128)
        .map(|t| t.map(|i| i as u32 % n))
        .collect();
    if input.extras {
        g.spheres.push(Sphere {
            center: g.vertices[0],
            radius: 0.75,
        });
        let b = g.vertices[n as usize / 2];
        g.boxes.push(Aabb::new(b, b + Vec3::new(0.5, 0.0, 1.0)));
        g.planes.push(Plane {
            normal: Vec3::Y,
            offset: g.vertices[n as usize - 1].y,
        });
    }
    let tree = KdTree::build(&g);
    if let Err(e) = tree.validate() {
        panic!("invalid tree: {e}");
    }
    let brute = BruteForce::new(&g);
    let signs = input.rays.first().map(|r| v(r.1, input.snap));
    let rays: Vec<Ray> = input
        .rays
        .iter()
        .take(TILE_RAYS)
        .map(|&(o, d, t_min, t_max)| {
            let d = match signs {
                Some(s) if input.same_signs => v(d, input.snap).copysign(s),
                _ => v(d, input.snap),
            };
            Ray::new(v(o, input.snap), d, t_min, t_max)
        })
        .collect();
    let want: Vec<Want> = rays
        .iter()
        .map(|ray| {
            let hit = brute.intersect(ray).unwrap_or(Hit::MISS);
            let occluded = brute.occluded(ray);
            let scalar = tree.intersect(ray).unwrap_or(Hit::MISS);
            assert_eq!(key(scalar), key(hit), "kd-tree vs brute: {ray:?}");
            assert_eq!(tree.occluded(ray), occluded, "occluded: {ray:?}");
            Want { hit, occluded }
        })
        .collect();
    check_packets::<W4>(&tree, &rays, &want);
    check_packets::<W8>(&tree, &rays, &want);
    check_packets::<W16>(&tree, &rays, &want);
    check_stream(
        &rays,
        &want,
        format_args!("stream"),
        |r, h| Accel::intersect_stream(&tree, r, h),
        |r, o| Accel::occluded_stream(&tree, r, o),
    );
    check_lanes::<W4>(&tree, &rays, &want);
    check_lanes::<W8>(&tree, &rays, &want);
    check_lanes::<W16>(&tree, &rays, &want);
    check_tiles::<W8>(&tree, &rays, &want);
    check_tiles::<W16>(&tree, &rays, &want);
});

/// Packets of `W`'s width against brute force, lane by lane.
fn check_packets<W: PacketWidth>(tree: &KdTree, rays: &[Ray], want: &[Want]) {
    for (chunk, want) in rays.chunks(W::LANES).zip(want.chunks(W::LANES)) {
        let packet = RayPacket::<W>::from_rays(chunk);
        let hits = tree.intersect_packet(&packet);
        let occluded = tree.occluded_packet(&packet);
        for (i, (ray, w)) in chunk.iter().zip(want).enumerate() {
            assert_eq!(
                lane_key(hits.lane(i)),
                key(w.hit),
                "packet of {} vs brute: {ray:?}",
                W::LANES
            );
            assert_eq!(
                occluded & (1 << i) != 0,
                w.occluded,
                "packet of {} occluded: {ray:?}",
                W::LANES
            );
        }
        assert_eq!(
            occluded >> chunk.len(),
            0,
            "packet of {}: bits past the rays",
            W::LANES
        );
    }
}

/// One stream query pair (`intersect` into hits, `occluded` into answers) against brute
/// force, ray by ray: a miss must be written as [`Hit::MISS`], and every output is
/// overwritten (hits start as [`POISON`], answers as alternating garbage).
fn check_stream(
    rays: &[Ray],
    want: &[Want],
    what: std::fmt::Arguments,
    intersect: impl FnOnce(&[Ray], &mut [Hit]),
    occluded: impl FnOnce(&[Ray], &mut [bool]),
) {
    let mut hits = vec![POISON; rays.len()];
    intersect(rays, &mut hits);
    let mut blocked: Vec<bool> = (0..rays.len()).map(|i| i % 2 == 0).collect();
    occluded(rays, &mut blocked);
    for (i, ray) in rays.iter().enumerate() {
        assert_eq!(
            key(hits[i]),
            key(want[i].hit),
            "{what} vs brute, ray {i}: {ray:?}"
        );
        assert_eq!(
            blocked[i], want[i].occluded,
            "{what} occluded, ray {i}: {ray:?}"
        );
    }
}

/// The lane walks at `W`'s width in one group of lanes and in two, whatever the tree's
/// size (the tree's own stream queries walk a tree this small ray by ray).
fn check_lanes<W: Simd>(tree: &KdTree, rays: &[Ray], want: &[Want]) {
    for groups in [1, 2] {
        check_stream(
            rays,
            want,
            format_args!("lane walk ({} lanes, {groups} groups)", W::LANES),
            |r, h| tree.intersect_lanes_in::<W>(r, h, groups),
            |r, o| tree.occluded_lanes_in::<W>(r, o, groups),
        );
    }
}

/// The rays as one tile of `W`-lane groups against brute force, ray by ray.
fn check_tiles<W: Simd>(tree: &KdTree, rays: &[Ray], want: &[Want]) {
    let mut hits = vec![POISON; rays.len()];
    tree.intersect_tile::<W>(rays, &mut hits);
    let occluded = tree.occluded_tile::<W>(rays);
    for (i, ray) in rays.iter().enumerate() {
        assert_eq!(
            lane_key(hits[i]),
            key(want[i].hit),
            "tile of {}-lane groups vs brute, ray {i}: {ray:?}",
            W::LANES
        );
        assert_eq!(
            occluded & (1 << i) != 0,
            want[i].occluded,
            "tile of {}-lane groups occluded, ray {i}: {ray:?}",
            W::LANES
        );
    }
    assert_eq!(
        occluded.checked_shr(rays.len() as u32).unwrap_or(0),
        0,
        "tile of {}-lane groups: bits past the rays",
        W::LANES
    );
}
