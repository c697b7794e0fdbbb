//! The primitive records an accelerator tests ([`Prims`]): their construction, the
//! scalar test of one primitive, of a leaf's and of the planes, and the scalar tests of
//! spheres, boxes and planes they dispatch to (triangles: [`crate::accel::triaccel`]).
//!
//! The packet twins, in the same operation order, are in [`crate::accel::prims_packet`]
//! (the shapes' tests and [`Prims`]' packet methods); the lane test of a leaf's
//! triangles, for the kd-tree's lane walks, is [`Prims::intersect_tris_lanes`] in
//! [`crate::accel::triaccel_leaf`].

use crate::accel::occupancy::Meter;
use crate::accel::triaccel::TriAccel;
use crate::geom::{Aabb, Geometry, Plane, Sphere};
use crate::ray::{Hit, Ray};
use glam::Vec3;

/// The primitive records an accelerator tests: TriAccel triangles, spheres and boxes
/// and the unbounded planes, tested beside any tree.
///
/// Records are indexed by *slot*. Spheres, boxes and planes sit at their primitive id;
/// a triangle's slot is its id until [`Prims::reorder_triangles`] places the records
/// in the order a tree's leaves name them, so a leaf's triangles share cache lines
/// (perf/log/wide.md, "Triangle records in leaf order"). Each record carries its
/// triangle's id ([`TriAccel::id`]); hits report ids ([`Prims::id`]) and ties between
/// equal distances go to the smaller id, so the answers do not depend on the order.
#[derive(Clone, Debug, Default)]
pub struct Prims {
    /// The triangles' precomputed records, by slot.
    pub tris: Vec<TriAccel>,
    /// Each triangle's corners, by slot, read only when the exact edge rule decides a
    /// test.
    pub corners: Vec<[Vec3; 3]>,
    /// Spheres; sphere `i` has primitive id `sphere_base + i`.
    pub spheres: Vec<Sphere>,
    /// Axis-aligned boxes; box `i` has primitive id `box_base + i`.
    pub boxes: Vec<Aabb>,
    /// Unbounded planes, tested beside the tree; plane `i` has id `plane_base + i`.
    pub planes: Vec<Plane>,
    /// Id of the first sphere (= triangle count).
    pub sphere_base: u32,
    /// Id of the first box.
    pub box_base: u32,
    /// Id of the first plane (= number of bounded primitives).
    pub plane_base: u32,
}

impl Prims {
    /// The records of `g`'s primitives, ids in `g`'s order (RAYS.md's for triangles).
    pub fn new(g: &Geometry) -> Prims {
        Prims::with(g, false, Meter::OFF)
    }

    /// [`Prims::new`], the triangles' records made on the current rayon pool when
    /// `parallel` (the same records: each depends on its triangle alone), the pool's
    /// work marked on `meter`.
    pub fn with(g: &Geometry, parallel: bool, meter: Meter) -> Prims {
        use rayon::prelude::*;
        let sphere_base = g.triangles.len() as u32;
        let box_base = sphere_base + g.spheres.len() as u32;
        let plane_base = box_base + g.boxes.len() as u32;
        // The corners are gathered from the mesh once; the records read them in order.
        let ids = 0..g.triangles.len() as u32;
        let record =
            |(id, &[a, b, c]): (usize, &[Vec3; 3])| TriAccel::new(a, b, c).with_id(id as u32);
        let (corners, tris): (Vec<[Vec3; 3]>, Vec<TriAccel>) = if parallel {
            meter.hand_off(|| {
                let corners: Vec<_> = (meter.jobs(ids.into_par_iter()))
                    .map(|i| g.triangle(i))
                    .collect();
                let tris = (meter.jobs(corners.par_iter().enumerate()))
                    .map(record)
                    .collect();
                (corners, tris)
            })
        } else {
            let corners: Vec<_> = ids.map(|i| g.triangle(i)).collect();
            let tris = corners.iter().enumerate().map(record).collect();
            (corners, tris)
        };
        Prims {
            tris,
            corners,
            spheres: g.spheres.clone(),
            boxes: g.boxes.clone(),
            planes: g.planes.clone(),
            sphere_base,
            box_base,
            plane_base,
        }
    }

    /// Places the triangles' records in `order`: slot `s` gets the triangle that was in
    /// slot `order[s]` (`order` a permutation of the slots).
    /// On the current rayon pool when `parallel`, marked on `meter`.
    pub fn reorder_triangles(&mut self, order: &[u32], parallel: bool, meter: Meter) {
        use rayon::prelude::*;
        debug_assert_eq!(order.len(), self.tris.len());
        if parallel {
            meter.hand_off(|| {
                let tris = (meter.jobs(order.par_iter()))
                    .map(|&s| self.tris[s as usize])
                    .collect();
                let corners = (meter.jobs(order.par_iter()))
                    .map(|&s| self.corners[s as usize])
                    .collect();
                (self.tris, self.corners) = (tris, corners);
            })
        } else {
            self.tris = order.iter().map(|&s| self.tris[s as usize]).collect();
            self.corners = order.iter().map(|&s| self.corners[s as usize]).collect();
        }
    }

    /// True when every bounded primitive is a triangle (no spheres or boxes): a leaf's
    /// slots then need no check before the triangle-only lane kernels.
    #[inline(always)]
    pub fn triangles_only(&self) -> bool {
        self.sphere_base == self.plane_base
    }

    /// The primitive id of the record in `slot` (see [`Prims`]).
    #[inline(always)]
    pub fn id(&self, slot: u32) -> u32 {
        if slot < self.sphere_base {
            self.tris[slot as usize].id()
        } else {
            slot
        }
    }

    /// Tests the bounded primitive in `slot` for `ray.t_min < t < t_max`; the hit
    /// reports its id.
    #[inline(always)]
    pub fn intersect_prim(&self, slot: u32, ray: &Ray, t_max: f32) -> Option<Hit> {
        // Spheres and boxes sit at their id; a triangle's record names its own.
        let prim = slot;
        if prim < self.sphere_base {
            let i = slot as usize;
            let (t, u, v) = self.tris[i].intersect(ray, t_max, &self.corners[i])?;
            Some(Hit {
                t,
                u,
                v,
                prim: self.tris[i].id(),
            })
        } else if prim < self.box_base {
            let t = intersect_sphere(
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
            let t = intersect_box(&self.boxes[(prim - self.box_base) as usize], ray, t_max)?;
            Some(Hit {
                t,
                u: 0.0,
                v: 0.0,
                prim,
            })
        }
    }

    /// Folds the primitives in slots `prims` of a leaf into `best` in order: each is tested with
    /// `t_max = next_up(best.t)` (capped at the ray's) so an equal `t` reaches
    /// [`Hit::is_closer`] and a smaller id wins the tie.
    #[inline(always)]
    pub fn intersect_leaf(&self, prims: &[u32], ray: &Ray, best: &mut Hit) {
        for &p in prims {
            let limit = best.t.next_up().min(ray.t_max);
            if let Some(h) = self.intersect_prim(p, ray, limit)
                && Hit::is_closer(h.t, h.prim, best)
            {
                *best = h;
            }
        }
    }

    /// Whether any primitive in slots `prims` is hit in `(t_min, t_max)`: the any-hit
    /// twin of [`Prims::intersect_leaf`]. A loop, not `Iterator::any`, which LLVM may
    /// keep out of line (see [`crate::simd::inl`]).
    #[inline(always)]
    pub fn occludes_leaf(&self, prims: &[u32], ray: &Ray) -> bool {
        for &p in prims {
            if self.intersect_prim(p, ray, ray.t_max).is_some() {
                return true;
            }
        }
        false
    }

    /// Folds the planes into `best` (closest-hit order of [`Hit::is_closer`]). A ray
    /// that is not [`Ray::is_usable`] hits no plane: `best.t.min(NaN)` would otherwise
    /// drop a NaN `t_max` and let the plane through (the packet twin's `min` keeps it).
    #[inline(always)]
    pub fn intersect_planes(&self, ray: &Ray, best: &mut Hit) {
        if !ray.is_usable() {
            return;
        }
        for (i, p) in self.planes.iter().enumerate() {
            if let Some(t) = intersect_plane(p, ray, best.t.min(ray.t_max)) {
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
    #[inline(always)]
    pub fn planes_occlude(&self, ray: &Ray) -> bool {
        ray.is_usable()
            && self
                .planes
                .iter()
                .any(|p| intersect_plane(p, ray, ray.t_max).is_some())
    }
}

/// Nearest `t` in `(t_min, t_max)` where `ray` meets the sphere's surface. A ray that
/// starts inside gets the exit point.
///
/// Uses the precise form of Haines et al., "Precision Improvements for Ray/Sphere
/// Intersection" (Ray Tracing Gems, ch. 7): the discriminant comes from the distance of
/// the centre to the ray's line, not from `b * b - a * c`, which cancels catastrophically
/// for far origins; the roots come from `q`, which avoids cancelling `-b + root`.
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
pub fn intersect_sphere(s: &Sphere, ray: &Ray, t_max: f32) -> Option<f32> {
    let oc = ray.org - s.center;
    let a = ray.dir.dot(ray.dir);
    let b = oc.dot(ray.dir);
    let r2 = s.radius * s.radius;
    let c = oc.dot(oc) - r2;
    // Closest point of the line to the centre, relative to the centre.
    let l = oc - ray.dir * (b / a);
    let disc = a * (r2 - l.dot(l));
    if !(disc >= 0.0) {
        return None;
    }
    let root = disc.sqrt();
    let q = -(b + if b < 0.0 { -root } else { root });
    let (t0, t1) = (c / q, q / a);
    let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
    if near > ray.t_min && near < t_max {
        return Some(near);
    }
    (far > ray.t_min && far < t_max).then_some(far)
}

/// Nearest `t` in `(t_min, t_max)` where `ray` meets the box's surface (slab test).
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
pub fn intersect_box(b: &Aabb, ray: &Ray, t_max: f32) -> Option<f32> {
    let inv = ray.dir.recip();
    let t0 = (b.min - ray.org) * inv;
    let t1 = (b.max - ray.org) * inv;
    let t_near = t0.min(t1).max_element();
    let t_far = t0.max(t1).min_element();
    if !(t_near <= t_far) {
        return None;
    }
    if t_near > ray.t_min && t_near < t_max {
        Some(t_near)
    } else if t_far > ray.t_min && t_far < t_max {
        Some(t_far)
    } else {
        None
    }
}

/// `t` in `(t_min, t_max)` where `ray` meets the plane.
#[inline(always)]
pub fn intersect_plane(p: &Plane, ray: &Ray, t_max: f32) -> Option<f32> {
    let t = (p.offset - p.normal.dot(ray.org)) / p.normal.dot(ray.dir);
    (t > ray.t_min && t < t_max).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn far_origins_do_not_invent_sphere_hits() {
        // A glossy ray of scenes/part5.toml 75,000 units from the spheres; the exact
        // discriminant is negative, b * b - a * c in f32 said otherwise.
        let ray = Ray::new(
            Vec3::new(63490.934, 7.3985133, -40061.938),
            Vec3::new(-0.8457027, -5.3081217e-6, 0.5336544),
            0.0,
            75075.4,
        );
        for c in [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-2.0, 1.0, 1.0),
            Vec3::new(2.0, 1.0, -1.0),
        ] {
            let s = Sphere {
                center: c,
                radius: 1.0,
            };
            assert_eq!(intersect_sphere(&s, &ray, ray.t_max), None, "sphere at {c}");
        }
    }

    #[test]
    fn closed_forms() {
        let ray = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, 0.0, f32::INFINITY);
        let s = Sphere {
            center: Vec3::ZERO,
            radius: 2.0,
        };
        assert_eq!(intersect_sphere(&s, &ray, f32::INFINITY), Some(3.0));
        let inside = Ray::new(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(intersect_sphere(&s, &inside, f32::INFINITY), Some(2.0));
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::ONE);
        assert_eq!(intersect_box(&b, &ray, f32::INFINITY), Some(4.0));
        assert_eq!(intersect_box(&b, &inside, f32::INFINITY), Some(1.0));
        let p = Plane {
            normal: Vec3::Z,
            offset: 1.0,
        };
        assert_eq!(intersect_plane(&p, &ray, f32::INFINITY), Some(6.0));
        assert_eq!(intersect_plane(&p, &ray, 5.0), None);
    }

    /// [`Prims::triangles_only`] (which lets the lane walks skip checking a leaf's
    /// slots) holds for triangles and planes, and not once a sphere or a box is added.
    #[test]
    fn triangles_only_means_no_sphere_or_box() {
        let mut g = crate::scene::generate::random_soup(20, 0.5, 1);
        g.planes.push(crate::geom::Plane {
            normal: Vec3::Y,
            offset: 0.0,
        });
        assert!(Prims::new(&g).triangles_only());
        let mut with_sphere = g.clone();
        with_sphere.spheres.push(crate::geom::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        });
        assert!(!Prims::new(&with_sphere).triangles_only());
        g.boxes.push(crate::geom::Aabb::new(Vec3::ZERO, Vec3::ONE));
        assert!(!Prims::new(&g).triangles_only());
    }
}
