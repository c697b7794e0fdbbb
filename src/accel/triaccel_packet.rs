//! Packet twin of [`crate::accel::triaccel`]: one TriAccel record against a packet's rays
//! (Wald 2004, PhD thesis, section 7.2: the SIMD form of the projected test).
//!
//! The projection axis `k` belongs to the triangle, so it is one scalar for the whole
//! packet: the lanes differ only in their rays. Every expression repeats the scalar
//! [`TriAccel::intersect`] operation by operation (`a * b + c` as a multiply then an
//! add, a true division, the same min/max order), so `t`, `u`, `v` and the edge bound are
//! bit-identical to it in every lane. Lanes whose answer lies within the bound of an
//! edge are decided by the exact rule in lanes ([`super::watertight::intersect_lanes`],
//! the scalar rule's operations), all such lanes in one pass; a lane it leaves
//! undecided (an edge function exactly zero) takes the scalar rule itself
//! ([`super::triaccel::exact_rule`]). Either gives the scalar `t`, `u`, `v`. Inactive lanes are masked out of the result; their
//! values (NaN included) reach no other lane because every operation is lane-wise.

use super::axis::MOD3;
use super::packet::{LaneHits, RayPacket};
use super::triaccel::{C1, C2, T_SLACK, TriAccel, exact_rule};
use super::watertight;
use crate::simd::{AMap, Float, LaneMask, Mask, Simd, Vf, max_abs};
use glam::Vec3;

/// The projected test's arithmetic in lanes, shared by the packet test (lanes are rays,
/// one record broadcast) and the leaf test (lanes are records, one ray broadcast,
/// [`super::triaccel_leaf`]): the ray in the triangle's axes, `o = [o_k, o_u, o_v]` and
/// `d` likewise, and the largest components of the ray's origin and direction. Both
/// steps repeat [`TriAccel::intersect`] operation by operation.
pub(super) struct Projected<W: Simd> {
    pub o: [Vf<W>; 3],
    pub d: [Vf<W>; 3],
    pub o_max: Vf<W>,
    pub d_max: Vf<W>,
}

impl<W: Simd> Projected<W> {
    /// The distance `t` to the plane of a record with `n = [n_u, n_v, n_d]` and `mag`,
    /// with `|denom|`, the `reach` of the error bounds and the range tolerance `slack`.
    #[inline(always)]
    pub fn distance(&self, n: [Vf<W>; 3], mag: Vf<W>) -> (Vf<W>, Vf<W>, Vf<W>, Vf<W>) {
        let (o, d) = (&self.o, &self.d);
        let [n_u, n_v, n_d] = n;
        let denom = d[0] + n_u * d[1] + n_v * d[2];
        let numer = n_d - o[0] - n_u * o[1] - n_v * o[2];
        let t = numer / denom;
        let ad = denom.abs();
        let reach = mag + self.o_max + t.abs() * self.d_max;
        (t, ad, reach, reach * Vf::<W>::splat(T_SLACK))
    }

    /// The barycentrics `u`, `v` at `t` of a record with `b = [b_nu, b_nv, b_d]`, `c`
    /// likewise and `err`, with the distance `edge` to the nearest edge (times
    /// `|denom|`) and its rounding `bound`.
    #[inline(always)]
    pub fn barycentrics(
        &self,
        t: Vf<W>,
        ad: Vf<W>,
        reach: Vf<W>,
        b: [Vf<W>; 3],
        c: [Vf<W>; 3],
        err: Vf<W>,
    ) -> (Vf<W>, Vf<W>, Vf<W>, Vf<W>) {
        let splat = Vf::<W>::splat;
        let (o, d) = (&self.o, &self.d);
        let hu = o[1] + t * d[1];
        let hv = o[2] + t * d[2];
        let u = hu * b[0] + hv * b[1] + b[2];
        let v = hu * c[0] + hv * c[1] + c[2];
        let w = Vf::<W>::ONE - u - v;
        let bound = err * reach * (splat(C1) * self.d_max + splat(C2) * ad);
        let edge = u.min_lt(v).min_lt(w) * ad;
        (u, v, edge, bound)
    }
}

impl TriAccel {
    /// Intersects the lanes of `rays` set in `active` with the triangle for
    /// `t_min < t < t_max` (per lane); `corners` as in [`TriAccel::intersect`].
    #[inline(always)]
    pub fn intersect_packet<W: Simd>(
        &self,
        rays: &RayPacket<W>,
        active: Mask<W>,
        t_max: Vf<W>,
        corners: &[Vec3; 3],
    ) -> LaneHits<W> {
        let splat = Vf::<W>::splat;
        let k = self.axis();
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let (o, d) = (&rays.org, &rays.dir);
        let ray = Projected::<W> {
            o: [o[k], o[ku], o[kv]],
            d: [d[k], d[ku], d[kv]],
            o_max: max_abs(o),
            d_max: max_abs(d),
        };
        let (t, ad, reach, slack) =
            ray.distance([self.n_u, self.n_v, self.n_d].amap(splat), splat(self.mag));
        let mask =
            active & ((t - t_max) * ad).cmp_lt(slack) & ((rays.t_min - t) * ad).cmp_lt(slack);
        if mask.none() {
            return LaneHits::none();
        }
        let (u, v, edge, bound) = ray.barycentrics(
            t,
            ad,
            reach,
            [self.b_nu, self.b_nv, self.b_d].amap(splat),
            [self.c_nu, self.c_nv, self.c_d].amap(splat),
            splat(self.err),
        );
        let inside = edge.cmp_ge(bound);
        let sure = mask & inside & t.cmp_gt(rays.t_min) & t.cmp_lt(t_max);
        let unsure = (mask & !inside & edge.cmp_ge(-bound)).bits();
        if unsure == 0 {
            return LaneHits {
                mask: sure,
                t,
                u,
                v,
            };
        }
        near_edges(
            rays,
            t_max,
            corners,
            LaneHits {
                mask: sure,
                t,
                u,
                v,
            },
            Mask::<W>::from_bits(unsure),
        )
    }
}

/// `fast` (the lanes the fast test decided) with the lanes of `unsure`, those within
/// the edge bound, decided by the exact rule. Out of line: most tests have no such
/// lane, and the traversal loops that inline the test stay small.
#[inline(always)]
fn near_edges<W: Simd>(
    rays: &RayPacket<W>,
    t_max: Vf<W>,
    corners: &[Vec3; 3],
    fast: LaneHits<W>,
    unsure: Mask<W>,
) -> LaneHits<W> {
    W::enter(
        #[inline(always)]
        || near_edges_in(rays, t_max, corners, fast, unsure),
    )
}

/// [`near_edges`]' body, compiled for `W`'s instruction set ([`Simd::enter`]).
#[inline(always)]
fn near_edges_in<W: Simd>(
    rays: &RayPacket<W>,
    t_max: Vf<W>,
    corners: &[Vec3; 3],
    fast: LaneHits<W>,
    unsure: Mask<W>,
) -> LaneHits<W> {
    let splat = Vf::<W>::splat;
    // The exact rule for every unsure lane in one pass; lanes it leaves undecided
    // (an edge function exactly zero) take the scalar rule one by one.
    let exact = watertight::intersect_lanes(
        &rays.org,
        &rays.dir,
        &corners.amap(
            #[inline(always)]
            |c| [splat(c.x), splat(c.y), splat(c.z)],
        ),
    );
    let in_range = exact.t.cmp_gt(rays.t_min) & exact.t.cmp_lt(t_max);
    let mut hit = (fast.mask | (unsure & exact.hit & in_range)).bits();
    let select = Vf::<W>::select;
    let (mut tt, mut uu, mut vv) = (
        select(unsure, exact.t, fast.t),
        select(unsure, exact.u, fast.u),
        select(unsure, exact.v, fast.v),
    );
    let mut left = (unsure & !exact.decided).bits();
    while left != 0 {
        let i = left.trailing_zeros() as usize;
        left &= left - 1;
        if let Some(ray) = rays.lane(i)
            && let Some((ti, ui, vi)) = exact_rule(&ray, t_max.lane(i), corners)
        {
            let lane = Mask::<W>::from_bits(1 << i);
            tt = select(lane, splat(ti), tt);
            uu = select(lane, splat(ui), uu);
            vv = select(lane, splat(vi), vv);
            hit |= 1 << i;
        }
    }
    LaneHits {
        mask: Mask::<W>::from_bits(hit),
        t: tt,
        u: uu,
        v: vv,
    }
}
