//! Closed meshes, rays from strictly inside them, and the leak count of an accelerator:
//! every such ray must hit the surface, so a miss is a ray that leaked through a crack.

use glam::Vec3;
use rayon::prelude::*;
use raypack::accel::Accel;
use raypack::accel::packet::RayPacket;
use raypack::accel::{PacketTrace, PacketWidth};
use raypack::ray::Ray;
use raypack::scene::Geometry;
use raypack::scene::generate::{self, Rng};
use raypack::simd::Isa;

/// A closed mesh and a sampler of points strictly inside it.
pub struct ClosedMesh {
    pub name: &'static str,
    pub geometry: Geometry,
    interior: Box<dyn Fn(&mut Rng) -> Vec3 + Sync>,
}

impl ClosedMesh {
    pub fn interior_point(&self, rng: &mut Rng) -> Vec3 {
        (self.interior)(rng)
    }
}

/// The closed meshes of the watertightness suite:
/// - `sphere`: a tessellated sphere (96 x 128, 24,320 triangles) off the origin;
/// - `box_lattice`: [`generate::closed_box`] of 16 x 16 squares per face on the integer
///   lattice: axis-aligned, coplanar neighbours, every vertex on likely split planes;
/// - `box_tenths`: the same box scaled by 0.1 and moved, so its coordinates round;
/// - `warped_grid`: [`generate::warped_closed_grid`] with 105 x 105 squares per face,
///   132,300 oblique triangles.
///
/// None of the meshes of ../shared/scenes is closed (bunny: 223 boundary edges; sponza,
/// conference and cornell_box are open scenes), so none is used here.
pub fn closed_meshes() -> Vec<ClosedMesh> {
    let centre = Vec3::new(0.31, -0.17, 0.05);
    let radius = 1.7;
    let sphere = generate::tessellated_sphere(centre, radius, 96, 128);
    let box16 = generate::closed_box(16);
    let mut tenths = generate::closed_box(16);
    let offset = Vec3::new(-0.35, 0.7, 0.15);
    for v in &mut tenths.vertices {
        *v = *v * 0.1 + offset;
    }
    let n = 105;
    vec![
        ClosedMesh {
            name: "sphere",
            geometry: sphere,
            interior: Box::new(move |rng| {
                // Inside the ball of 0.95 radius: the inscribed polyhedron reaches
                // past 0.999 radius for this tessellation.
                loop {
                    let p = rng.point(Vec3::splat(-1.0), Vec3::ONE);
                    if p.length_squared() < 1.0 {
                        return centre + p * (0.95 * radius);
                    }
                }
            }),
        },
        ClosedMesh {
            name: "box_lattice",
            geometry: box16,
            interior: Box::new(|rng| rng.point(Vec3::splat(0.01), Vec3::splat(15.99))),
        },
        ClosedMesh {
            name: "box_tenths",
            geometry: tenths,
            interior: Box::new(move |rng| {
                rng.point(Vec3::splat(0.001), Vec3::splat(1.599)) + offset
            }),
        },
        ClosedMesh {
            name: "warped_grid",
            geometry: generate::warped_closed_grid(n),
            interior: Box::new(move |rng| {
                let p = rng.point(Vec3::splat(0.5), Vec3::splat(n as f32 - 0.5));
                generate::warp_point(p, n)
            }),
        },
    ]
}

/// `count` rays from random interior points in uniformly random directions.
pub fn interior_rays(mesh: &ClosedMesh, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| {
            let org = mesh.interior_point(&mut rng);
            Ray::new(org, rng.unit_vector(), 0.0, f32::INFINITY)
        })
        .collect()
}

/// `count` rays from random interior points aimed exactly at shared features: in turn a
/// triangle corner (a shared vertex), an edge midpoint and a random point of an edge.
/// The direction is `target - origin`, unnormalized, so the line passes through the
/// target up to one rounding.
pub fn aimed_rays(mesh: &ClosedMesh, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let g = &mesh.geometry;
    let mut rays = Vec::with_capacity(count);
    while rays.len() < count {
        let org = mesh.interior_point(&mut rng);
        let [a, b, c] = g.triangle(rng.below(g.triangles.len() as u32));
        let (p, q) = match rng.below(3) {
            0 => (a, b),
            1 => (b, c),
            _ => (c, a),
        };
        let target = match rays.len() % 3 {
            0 => p,
            1 => (p + q) * 0.5,
            _ => p + (q - p) * rng.f32(),
        };
        let dir = target - org;
        if dir != Vec3::ZERO {
            rays.push(Ray::new(org, dir, 0.0, f32::INFINITY));
        }
    }
    rays
}

/// Indices of the rays that miss, traced one by one.
pub fn leaks_scalar(accel: &dyn Accel, rays: &[Ray]) -> Vec<usize> {
    (0..rays.len())
        .into_par_iter()
        .filter(|&i| accel.intersect(&rays[i]).is_none())
        .collect()
}

/// Indices of the rays that miss, traced `W::LANES` at a time as packets with the
/// kernels of `isa` (consecutive rays share a packet; they are incoherent, so this also
/// exercises packet splitting).
pub fn leaks_packet<W: PacketWidth>(isa: Isa, accel: &dyn Accel, rays: &[Ray]) -> Vec<usize> {
    rays.par_chunks(W::LANES)
        .enumerate()
        .flat_map_iter(|(c, chunk)| {
            let hits = isa
                .scope(|| accel.intersect_packet(&RayPacket::<W>::from_rays(chunk)))
                .expect("a supported instruction set");
            (0..chunk.len())
                .filter(move |&i| !hits.lane(i).is_hit())
                .map(move |i| c * W::LANES + i)
        })
        .collect()
}
