//! Packet twins of [`crate::accel::prims`]: spheres, boxes and planes against a whole
//! packet, in the scalar tests' operation order, so each lane's `t` is bit-identical to
//! the scalar test's. Inactive lanes never hit and influence no other lane.
//!
//! [`Prims`]' packet methods dispatch a primitive id to its test, as the scalar
//! [`Prims::intersect_prim`] does, and fold the unbounded planes into a packet's hits.

use super::Prims;
use super::packet::{HitPacket, LaneHits, RayPacket};
use crate::geom::{Aabb, Plane, Sphere};
use crate::simd::{AMap, Float, LaneMask, Mask, Simd, Uint, Vf, array_fn, prefetch};

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

    /// The primitives `prims` of a leaf against the lanes `lanes[g]` of each group
    /// `rays(g)`: one group for a packet, several for a tile (traverse_tile.rs). It goes
    /// primitive by primitive, so each record is loaded once for all groups and the
    /// groups' tests, independent of one another, overlap; each group sees the
    /// primitives in the leaf's order, so its answers do not depend on the others.
    /// Closest hit: folds group `g`'s hits into `best[g]` (in [`Hit::is_closer`]
    /// order). With `ANY_HIT`: adds to `occluded[g]` the lanes that hit anything in
    /// `(t_min, t_max)`, each lane leaving at its first hit. `count(n)` is told of
    /// every `n` primitive tests (the kd-tree's statistics).
    #[inline(always)]
    pub(crate) fn leaf_groups<'r, W: Simd, const G: usize, const ANY_HIT: bool>(
        &self,
        prims: &[u32],
        rays: impl Fn(usize) -> &'r RayPacket<W>,
        lanes: &[Mask<W>; G],
        best: &mut [HitPacket<W>],
        occluded: &mut [Mask<W>],
        count: impl Fn(u64),
    ) {
        let (best, occluded) = (&mut best[..G], &mut occluded[..G]);
        if ANY_HIT {
            let mut live = *lanes;
            for &p in prims {
                let mut any = Mask::<W>::NONE;
                for g in 0..G {
                    if live[g].any() {
                        count(1);
                        let hits = self.intersect_prim_packet(p, rays(g), live[g], rays(g).t_max);
                        occluded[g] |= hits.mask;
                        live[g] &= !hits.mask;
                        any |= live[g];
                    }
                }
                if any.none() {
                    break;
                }
            }
        } else {
            // Lanes near an edge need the triangle's corners (the exact rule,
            // triaccel.rs), which sit apart from its record: ask for them now, while
            // the leaf's tests run.
            for &p in prims {
                if let Some(c) = self.corners.get(p as usize) {
                    prefetch(c);
                }
            }
            let mut limit: [Vf<W>; G] = array_fn(
                #[inline(always)]
                |g| next_up(best[g].t).min(rays(g).t_max),
            );
            let groups = lanes
                .iter()
                .filter(
                    #[inline(always)]
                    |l| l.any(),
                )
                .count() as u64;
            count(groups * prims.len() as u64);
            for &p in prims {
                let id = self.id(p);
                for g in 0..G {
                    if lanes[g].any() {
                        let hits = self.intersect_prim_packet(p, rays(g), lanes[g], limit[g]);
                        if best[g].merge(&hits, id).any() {
                            limit[g] = next_up(best[g].t).min(rays(g).t_max);
                        }
                    }
                }
            }
        }
    }
}

/// The smallest float above each lane (`f32::next_up`), used for the scalar path's
/// leaf limit `next_up(best.t)`.
#[inline(always)]
fn next_up<F: Float>(v: F) -> F {
    let b = v.to_bits();
    let one = F::U::splat(1);
    let up = F::from_bits(b + one);
    let down = F::from_bits(b - one);
    let pos = v.cmp_gt(F::ZERO) & v.cmp_lt(F::splat(f32::INFINITY));
    let r = F::select(pos, up, F::select(v.cmp_lt(F::ZERO), down, v));
    F::select(v.cmp_eq(F::ZERO), F::from_bits(one), r)
}
