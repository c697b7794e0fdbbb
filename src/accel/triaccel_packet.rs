//! Packet twin of [`crate::accel::triaccel`]: one TriAccel record against a packet's rays
//! (Wald 2004, PhD thesis, section 7.2: the SIMD form of the projected test).
//!
//! The projection axis `k` belongs to the triangle, so it is one scalar for the whole
//! packet: the lanes differ only in their rays. Every expression repeats the scalar
//! [`TriAccel::intersect`] operation by operation (`a * b + c` as a multiply then an
//! add, a true division, the same min/max order), so `t`, `u`, `v` and the edge bound are
//! bit-identical to it in every lane. Lanes whose answer lies within the bound of an
//! edge are decided one by one by the same scalar exact rule
//! ([`super::triaccel::exact_rule`]), which also gives their `t`, `u`, `v`. Inactive lanes are masked out of the result; their
//! values (NaN included) reach no other lane because every operation is lane-wise.

use super::axis::MOD3;
use super::packet::{LaneHits, RayPacket};
use super::triaccel::{C1, C2, T_SLACK, TriAccel, exact_rule};
use crate::simd::{Float, LaneMask, Mask, Simd, Vf, max_abs};
use glam::Vec3;

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
        let k = self.k as usize;
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let (o, d) = (&rays.org, &rays.dir);
        let (n_u, n_v) = (splat(self.n_u), splat(self.n_v));
        let denom = d[k] + n_u * d[ku] + n_v * d[kv];
        let numer = splat(self.n_d) - o[k] - n_u * o[ku] - n_v * o[kv];
        let t = numer / denom;
        let ad = denom.abs();
        let (o_max, d_max) = (max_abs(o), max_abs(d));
        let reach = splat(self.mag) + o_max + t.abs() * d_max;
        let slack = reach * splat(T_SLACK);
        let mask =
            active & ((t - t_max) * ad).cmp_lt(slack) & ((rays.t_min - t) * ad).cmp_lt(slack);
        if mask.none() {
            return LaneHits::none();
        }
        let hu = o[ku] + t * d[ku];
        let hv = o[kv] + t * d[kv];
        let u = hu * splat(self.b_nu) + hv * splat(self.b_nv) + splat(self.b_d);
        let v = hu * splat(self.c_nu) + hv * splat(self.c_nv) + splat(self.c_d);
        let w = Vf::<W>::ONE - u - v;
        let bound = splat(self.err) * reach * (splat(C1) * d_max + splat(C2) * ad);
        let edge = u.min_lt(v).min_lt(w) * ad;
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
        let (mut tt, mut uu, mut vv) = (t, u, v);
        let mut hit = sure.bits();
        let mut left = unsure;
        while left != 0 {
            let i = left.trailing_zeros() as usize;
            left &= left - 1;
            if let Some(ray) = rays.lane(i)
                && let Some((ti, ui, vi)) = exact_rule(&ray, t_max.lane(i), corners)
            {
                let lane = Mask::<W>::from_bits(1 << i);
                tt = Vf::<W>::select(lane, splat(ti), tt);
                uu = Vf::<W>::select(lane, splat(ui), uu);
                vv = Vf::<W>::select(lane, splat(vi), vv);
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
}
