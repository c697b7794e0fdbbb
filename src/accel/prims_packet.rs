//! Packet twins of [`crate::accel::prims`]: spheres, boxes and planes against a whole
//! packet, in the scalar tests' operation order, so each lane's `t` is bit-identical to
//! the scalar test's. Inactive lanes never hit and influence no other lane.
//!
//! [`Prims`]' packet methods dispatch a primitive id to its test, as the scalar
//! [`Prims::intersect_prim`] does, and fold the unbounded planes into a packet's hits.

use super::Prims;
use super::packet::{HitPacket, LaneHits, RayPacket};
use crate::geom::{Aabb, Plane, Sphere};
use crate::simd::{AMap, Float, LaneMask, Mask, Simd, Vf};

/// `a . b` in glam's order: `(x + y) + z`.
#[inline(always)]
fn dot<F: Float>(a: [F; 3], b: [F; 3]) -> F {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn in_range<W: Simd>(t: Vf<W>, rays: &RayPacket<W>, t_max: Vf<W>) -> Mask<W> {
    t.cmp_gt(rays.t_min) & t.cmp_lt(t_max)
}

/// Nearest `t` in `(t_min, t_max)` per lane where the ray meets the sphere's surface;
/// twin of [`super::prims::intersect_sphere`].
#[inline(always)]
pub fn intersect_sphere_packet<W: Simd>(
    s: &Sphere,
    rays: &RayPacket<W>,
    active: Mask<W>,
    t_max: Vf<W>,
) -> LaneHits<W> {
    let splat = Vf::<W>::splat;
    let select = Vf::<W>::select;
    let oc = [0, 1, 2].amap(
        #[inline(always)]
        |a| rays.org[a] - splat(s.center[a]),
    );
    let a = dot(rays.dir, rays.dir);
    let b = dot(oc, rays.dir);
    let r2 = splat(s.radius * s.radius);
    let c = dot(oc, oc) - r2;
    let s_line = b / a;
    let l = [0, 1, 2].amap(
        #[inline(always)]
        |k| oc[k] - rays.dir[k] * s_line,
    );
    let disc = a * (r2 - dot(l, l));
    let mask = active & disc.cmp_ge(Vf::<W>::ZERO);
    if mask.none() {
        return LaneHits::none();
    }
    let root = disc.sqrt();
    let q = -(b + select(b.cmp_lt(Vf::<W>::ZERO), -root, root));
    let (t0, t1) = (c / q, q / a);
    let order = t0.cmp_lt(t1);
    nearer_in_range(
        mask,
        select(order, t0, t1),
        select(order, t1, t0),
        rays,
        t_max,
    )
}

/// In the lanes of `mask`, `t0` if it lies in `(t_min, t_max)`, else `t1` if it does:
/// the scalar tests' "nearer root first".
#[inline(always)]
fn nearer_in_range<W: Simd>(
    mask: Mask<W>,
    t0: Vf<W>,
    t1: Vf<W>,
    rays: &RayPacket<W>,
    t_max: Vf<W>,
) -> LaneHits<W> {
    let near = in_range(t0, rays, t_max);
    let far = in_range(t1, rays, t_max);
    LaneHits {
        mask: mask & (near | far),
        t: Vf::<W>::select(near, t0, t1),
        u: Vf::<W>::ZERO,
        v: Vf::<W>::ZERO,
    }
}

/// Nearest `t` in `(t_min, t_max)` per lane where the ray meets the box's surface (slab
/// test); twin of [`super::prims::intersect_box`]. `rays.inv_dir` is `1 / dir` by true
/// division, as the scalar `recip`.
#[inline(always)]
pub fn intersect_box_packet<W: Simd>(
    b: &Aabb,
    rays: &RayPacket<W>,
    active: Mask<W>,
    t_max: Vf<W>,
) -> LaneHits<W> {
    let splat = Vf::<W>::splat;
    let t0 = [0, 1, 2].amap(
        #[inline(always)]
        |a| (splat(b.min[a]) - rays.org[a]) * rays.inv_dir[a],
    );
    let t1 = [0, 1, 2].amap(
        #[inline(always)]
        |a| (splat(b.max[a]) - rays.org[a]) * rays.inv_dir[a],
    );
    let lo = [0, 1, 2].amap(
        #[inline(always)]
        |a| t0[a].min_lt(t1[a]),
    );
    let hi = [0, 1, 2].amap(
        #[inline(always)]
        |a| t0[a].max_gt(t1[a]),
    );
    let t_near = lo[0].max_gt(lo[1].max_gt(lo[2]));
    let t_far = hi[0].min_lt(hi[1].min_lt(hi[2]));
    let mask = active & t_near.cmp_le(t_far);
    nearer_in_range(mask, t_near, t_far, rays, t_max)
}

/// `t` in `(t_min, t_max)` per lane where the ray meets the plane; twin of
/// [`super::prims::intersect_plane`].
#[inline(always)]
pub fn intersect_plane_packet<W: Simd>(
    p: &Plane,
    rays: &RayPacket<W>,
    active: Mask<W>,
    t_max: Vf<W>,
) -> LaneHits<W> {
    let n = [0, 1, 2].amap(
        #[inline(always)]
        |a| Vf::<W>::splat(p.normal[a]),
    );
    let t = (Vf::<W>::splat(p.offset) - dot(n, rays.org)) / dot(n, rays.dir);
    LaneHits {
        mask: active & in_range(t, rays, t_max),
        t,
        u: Vf::<W>::ZERO,
        v: Vf::<W>::ZERO,
    }
}

impl Prims {
    /// Tests bounded primitive `prim` against the `active` lanes; twin of
    /// [`Prims::intersect_prim`].
    #[inline(always)]
    pub fn intersect_prim_packet<W: Simd>(
        &self,
        prim: u32,
        rays: &RayPacket<W>,
        active: Mask<W>,
        t_max: Vf<W>,
    ) -> LaneHits<W> {
        if prim < self.sphere_base {
            let i = prim as usize;
            self.tris[i].intersect_packet(rays, active, t_max, &self.corners[i])
        } else if prim < self.box_base {
            let s = &self.spheres[(prim - self.sphere_base) as usize];
            intersect_sphere_packet(s, rays, active, t_max)
        } else {
            let b = &self.boxes[(prim - self.box_base) as usize];
            intersect_box_packet(b, rays, active, t_max)
        }
    }

    /// Folds the planes into the `active` lanes of `best`; twin of
    /// [`Prims::intersect_planes`].
    #[inline(always)]
    pub fn intersect_planes_packet<W: Simd>(
        &self,
        rays: &RayPacket<W>,
        active: Mask<W>,
        best: &mut HitPacket<W>,
    ) {
        if self.planes.is_empty() {
            return;
        }
        let active = active & rays.usable();
        for (i, p) in self.planes.iter().enumerate() {
            let hits = intersect_plane_packet(p, rays, active, best.t.min(rays.t_max));
            best.merge(&hits, self.plane_base + i as u32);
        }
    }

    /// Lanes of `active` that a plane occludes; twin of [`Prims::planes_occlude`].
    #[inline(always)]
    pub fn planes_occlude_packet<W: Simd>(&self, rays: &RayPacket<W>, active: Mask<W>) -> Mask<W> {
        let active = active & rays.usable();
        let mut hit = Mask::<W>::NONE;
        for p in &self.planes {
            hit = hit | intersect_plane_packet(p, rays, active & !hit, rays.t_max).mask;
            if (active & !hit).none() {
                break;
            }
        }
        hit
    }
}
