//! The kd-tree against brute force on arbitrary triangles (plus a sphere, a box and a
//! plane) and arbitrary rays, NaN and infinities included: the same closest primitive
//! with bit-identical `t`, `u`, `v`, the same occlusion, and the packet path equal to the
//! scalar one lane by lane. Coordinates are snapped to a coarse lattice part of the time
//! so shared edges, coplanar triangles and origins on split planes come up often.

#![no_main]

use arbitrary::Arbitrary;
use glam::Vec3;
use libfuzzer_sys::fuzz_target;
use raypack::accel::brute::BruteForce;
use raypack::accel::kdtree::KdTree;
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
    rays: Vec<([f32; 3], [f32; 3], f32, f32)>,
}

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

fn key(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
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
    let rays: Vec<Ray> = input
        .rays
        .iter()
        .take(64)
        .map(|&(o, d, t_min, t_max)| Ray::new(v(o, input.snap), v(d, input.snap), t_min, t_max))
        .collect();
    check_packets::<W4>(&tree, &brute, &rays);
    check_packets::<W8>(&tree, &brute, &rays);
    check_packets::<W16>(&tree, &brute, &rays);
    check_lanes::<W4>(&tree, &brute, &rays);
    check_lanes::<W8>(&tree, &brute, &rays);
    check_lanes::<W16>(&tree, &brute, &rays);
});

/// Every ray against brute force, scalar and in packets of `W`'s width.
fn check_packets<W: PacketWidth>(tree: &KdTree, brute: &BruteForce, rays: &[Ray]) {
    for chunk in rays.chunks(W::LANES) {
        let packet = RayPacket::<W>::from_rays(chunk);
        let hits = tree.intersect_packet(&packet);
        let occluded = tree.occluded_packet(&packet);
        for (i, ray) in chunk.iter().enumerate() {
            let want = brute.intersect(ray);
            assert_eq!(
                key(tree.intersect(ray)),
                key(want),
                "kd-tree vs brute: {ray:?}"
            );
            let lane = hits.lane(i);
            assert_eq!(
                key(lane.is_hit().then_some(lane)),
                key(want),
                "packet of {} vs brute: {ray:?}",
                W::LANES
            );
            let blocked = brute.occluded(ray);
            assert_eq!(tree.occluded(ray), blocked, "occluded: {ray:?}");
            assert_eq!(
                occluded & (1 << i) != 0,
                blocked,
                "packet occluded: {ray:?}"
            );
        }
    }
}

/// The stream kernel itself (the lane walks at `W`'s width; the stream queries of a
/// tree this small walk ray by ray) against brute force.
fn check_lanes<W: Simd>(tree: &KdTree, brute: &BruteForce, rays: &[Ray]) {
    let mut hits = vec![Hit::MISS; rays.len()];
    tree.intersect_lanes::<W>(rays, &mut hits);
    let mut occluded = vec![false; rays.len()];
    tree.occluded_lanes::<W>(rays, &mut occluded);
    for ((ray, hit), blocked) in rays.iter().zip(&hits).zip(&occluded) {
        let want = brute.intersect(ray);
        assert_eq!(
            key(hit.is_hit().then_some(*hit)),
            key(want),
            "stream ({} lanes) vs brute: {ray:?}",
            W::LANES
        );
        assert_eq!(
            *blocked,
            brute.occluded(ray),
            "stream ({} lanes) occluded: {ray:?}",
            W::LANES
        );
    }
}
