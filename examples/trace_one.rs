//! raypack as a library: load an OBJ mesh, build the kd-tree, trace one ray, one packet
//! and a stream, and print the hits.
//!
//!     cargo run --release --example trace_one ../shared/scenes/bunny/bunny.obj

use glam::Vec3;
use raypack::accel::kdtree::KdTree;
use raypack::accel::{Accel, RayPacket};
use raypack::ray::{Hit, Ray};
use raypack::scene::{Geometry, obj};
use raypack::simd::{Simd, W8};

fn main() -> anyhow::Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "../shared/scenes/bunny/bunny.obj".into());
    let mesh = obj::load(path.as_ref())?;
    let geometry = Geometry {
        vertices: mesh.positions,
        triangles: mesh.triangles,
        ..Geometry::default()
    };
    let tree = KdTree::build(&geometry);
    let bounds = tree.bounds();
    let centre = (bounds.min + bounds.max) * 0.5;
    let eye = centre + Vec3::new(0.0, 0.0, 2.0 * (bounds.max - bounds.min).length());
    println!("{path}: {} triangles", geometry.triangles.len());

    // One ray from in front of the mesh towards its centre.
    let ray = Ray::new(eye, (centre - eye).normalize(), 0.0, f32::INFINITY);
    match tree.intersect(&ray) {
        Some(hit) => println!("ray:    triangle {} at t = {}", hit.prim, hit.t),
        None => println!("ray:    miss"),
    }

    // A packet of 8 rays (one AVX2 register per coordinate; `W4` and `W16` are the other
    // widths) fanning out around it: each lane's answer equals the single ray's.
    let rays: Vec<Ray> = (0..W8::LANES)
        .map(|i| {
            let offset = Vec3::new(i as f32 * 0.05, 0.0, 0.0) * (bounds.max - bounds.min);
            Ray::new(eye, (centre + offset - eye).normalize(), 0.0, f32::INFINITY)
        })
        .collect();
    let hits = tree.intersect_packet(&RayPacket::<W8>::from_rays(&rays));
    for (i, ray) in rays.iter().enumerate() {
        let hit = hits.lane(i);
        assert_eq!(Some(hit).filter(|h| h.is_hit()), tree.intersect(ray));
        if hit.is_hit() {
            println!("lane {i}: triangle {} at t = {}", hit.prim, hit.t);
        } else {
            println!("lane {i}: miss");
        }
    }

    // A stream of unrelated rays (Embree's rtcIntersect1M): many rays in flight at once,
    // answers in input order, each equal to the single ray's.
    let stream: Vec<Ray> = (0..1000)
        .map(|i| {
            let a = i as f32 * 2.399_963; // golden angle: directions spread evenly
            let d = Vec3::new(a.cos(), (i as f32 / 500.0) - 1.0, a.sin()).normalize();
            Ray::new(centre, d, 0.0, f32::INFINITY)
        })
        .collect();
    let mut hits = vec![Hit::MISS; stream.len()];
    tree.intersect_stream(&stream, &mut hits);
    let found = hits.iter().filter(|h| h.is_hit()).count();
    for (ray, hit) in stream.iter().zip(&hits) {
        assert_eq!(Some(*hit).filter(|h| h.is_hit()), tree.intersect(ray));
    }
    println!(
        "stream: {found} of {} rays from the centre hit",
        stream.len()
    );
    Ok(())
}
