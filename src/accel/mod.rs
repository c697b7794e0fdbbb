//! Acceleration structures: the narrow interface the renderer traces through.
//!
//! As in pbrt-v4, an accelerator answers `bounds`, closest-hit `intersect` and any-hit
//! `occluded`, for single rays and for packets. [`brute::BruteForce`] tests every
//! primitive and is the oracle; [`kdtree::KdTree`] is the fast path. Both hold the same
//! [`Prims`] records, so a disagreement points at traversal, not at a primitive test.

pub mod axis;
pub mod brute;
pub mod kdtree;
pub mod packet;
pub mod prims;
pub mod prims_packet;
pub mod triaccel;
pub mod triaccel_packet;
pub mod watertight;

use crate::ray::{Hit, Ray};
use crate::scene::{Aabb, Geometry, Plane, Sphere};
use glam::Vec3;
pub use packet::{HitPacket, RayPacket};
use triaccel::TriAccel;

/// An intersector over one scene's primitives.
///
/// Numeric edge cases have one defined answer in every intersector and both paths: a
/// ray with a NaN or infinite origin or direction component, a zero direction, a
/// direction whose largest component lies outside [2^-64, 2^64] ([`crate::ray::DIR_MIN`]),
/// or `!(t_min <= t_max)` hits nothing (`intersect` is `None`, `occluded` false); a ray
/// starting exactly on a surface, an edge or a split plane gets the closest hit with
/// `t > t_min` strictly, the same as brute force's, bit for bit.
pub trait Accel: Sync {
    /// Bounds of the bounded primitives (planes excluded).
    fn bounds(&self) -> Aabb;

    /// The closest hit with `ray.t_min < t < ray.t_max`; ties go to the smaller id.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// True when anything lies between `ray.t_min` and `ray.t_max`.
    fn occluded(&self, ray: &Ray) -> bool;

    /// Closest hits of the active lanes of `rays`; inactive lanes get [`Hit::MISS`].
    fn intersect_packet(&self, rays: &RayPacket) -> HitPacket {
        HitPacket::from_lanes(|i| match rays.lane(i) {
            Some(r) => self.intersect(&r).unwrap_or(Hit::MISS),
            None => Hit::MISS,
        })
    }

    /// Bit `i` set when active lane `i` is occluded.
    fn occluded_packet(&self, rays: &RayPacket) -> u32 {
        let mut bits = 0;
        for i in 0..crate::simd::LANES {
            if rays.lane(i).is_some_and(|r| self.occluded(&r)) {
                bits |= 1 << i;
            }
        }
        bits
    }
}

/// The primitive records an accelerator tests: TriAccel triangles, spheres and boxes
/// (indexed by primitive id) and the unbounded planes, tested beside any tree.
#[derive(Clone, Debug, Default)]
pub struct Prims {
    pub tris: Vec<TriAccel>,
    /// Each triangle's corners, read only when the exact edge rule decides a test.
    pub corners: Vec<[Vec3; 3]>,
    pub spheres: Vec<Sphere>,
    pub boxes: Vec<Aabb>,
    pub planes: Vec<Plane>,
    /// Id of the first sphere (= triangle count).
    pub sphere_base: u32,
    /// Id of the first box.
    pub box_base: u32,
    /// Id of the first plane (= number of bounded primitives).
    pub plane_base: u32,
}

impl Prims {
    pub fn new(g: &Geometry) -> Prims {
        let sphere_base = g.triangles.len() as u32;
        let box_base = sphere_base + g.spheres.len() as u32;
        let plane_base = box_base + g.boxes.len() as u32;
        Prims {
            tris: TriAccel::build_all(g),
            corners: (0..g.triangles.len() as u32)
                .map(|i| g.triangle(i))
                .collect(),
            spheres: g.spheres.clone(),
            boxes: g.boxes.clone(),
            planes: g.planes.clone(),
            sphere_base,
            box_base,
            plane_base,
        }
    }

    /// Tests bounded primitive `prim` for `ray.t_min < t < t_max`.
    #[inline]
    pub fn intersect_prim(&self, prim: u32, ray: &Ray, t_max: f32) -> Option<Hit> {
        if prim < self.sphere_base {
            let i = prim as usize;
            let (t, u, v) = self.tris[i].intersect(ray, t_max, &self.corners[i])?;
            Some(Hit { t, u, v, prim })
        } else if prim < self.box_base {
            let t = prims::intersect_sphere(
                &self.spheres[(prim - self.sphere_base) as usize],
                ray,
                t_max,
            )?;
            Some(Hit {
                t,
                u: 0.0,
                v: 0.0,
                prim,
            })
        } else {
            let t = prims::intersect_box(&self.boxes[(prim - self.box_base) as usize], ray, t_max)?;
            Some(Hit {
                t,
                u: 0.0,
                v: 0.0,
                prim,
            })
        }
    }

    /// Folds the planes into `best` (closest-hit order of [`Hit::is_closer`]). A ray
    /// that is not [`Ray::is_usable`] hits no plane: `best.t.min(NaN)` would otherwise
    /// drop a NaN `t_max` and let the plane through (the packet twin's `min` keeps it).
    #[inline]
    pub fn intersect_planes(&self, ray: &Ray, best: &mut Hit) {
        if !ray.is_usable() {
            return;
        }
        for (i, p) in self.planes.iter().enumerate() {
            if let Some(t) = prims::intersect_plane(p, ray, best.t.min(ray.t_max)) {
                let prim = self.plane_base + i as u32;
                if Hit::is_closer(t, prim, best) {
                    *best = Hit {
                        t,
                        u: 0.0,
                        v: 0.0,
                        prim,
                    };
                }
            }
        }
    }

    /// True when any plane lies in `(t_min, t_max)`; never for a ray that is not
    /// [`Ray::is_usable`] (an infinite direction component gives `t = 0` on a plane
    /// along it).
    #[inline]
    pub fn planes_occlude(&self, ray: &Ray) -> bool {
        ray.is_usable()
            && self
                .planes
                .iter()
                .any(|p| prims::intersect_plane(p, ray, ray.t_max).is_some())
    }
}
