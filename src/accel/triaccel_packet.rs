//! Packet twin of [`crate::accel::triaccel`]: one TriAccel record against `LANES` rays
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

use super::packet::{LaneHits, RayPacket};
use super::triaccel::{C1, C2, MOD3, T_SLACK, TriAccel, exact_rule};
use crate::simd::{LANES, Mask, Vf, bits, mask_from_bits, max_abs, min_lt, none, splat};
use glam::Vec3;

impl TriAccel {
    /// Intersects the lanes of `rays` set in `active` with the triangle for
    /// `t_min < t < t_max` (per lane); `corners` as in [`TriAccel::intersect`].
    #[inline]
    pub fn intersect_packet(
        &self,
        rays: &RayPacket,
        active: Mask,
        t_max: Vf,
        corners: &[Vec3; 3],
    ) -> LaneHits {
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
            active & ((t - t_max) * ad).simd_lt(slack) & ((rays.t_min - t) * ad).simd_lt(slack);
        if none(mask) {
            return LaneHits::none();
        }
        let hu = o[ku] + t * d[ku];
        let hv = o[kv] + t * d[kv];
        let u = hu * splat(self.b_nu) + hv * splat(self.b_nv) + splat(self.b_d);
        let v = hu * splat(self.c_nu) + hv * splat(self.c_nv) + splat(self.c_d);
        let w = Vf::ONE - u - v;
        let bound = splat(self.err) * reach * (splat(C1) * d_max + splat(C2) * ad);
        let edge = min_lt(min_lt(u, v), w) * ad;
        let inside = edge.simd_ge(bound);
        let sure = mask & inside & t.simd_gt(rays.t_min) & t.simd_lt(t_max);
        let unsure = bits(mask & !inside & edge.simd_ge(-bound));
        if unsure == 0 {
            return LaneHits {
                mask: sure,
                t,
                u,
                v,
            };
        }
        let (mut tt, mut uu, mut vv) = (t.to_array(), u.to_array(), v.to_array());
        let mut hit = bits(sure);
        let t_max = t_max.to_array();
        for i in 0..LANES {
            if unsure & (1 << i) != 0
                && let Some(ray) = rays.lane(i)
                && let Some((ti, ui, vi)) = exact_rule(&ray, t_max[i], corners)
            {
                (tt[i], uu[i], vv[i]) = (ti, ui, vi);
                hit |= 1 << i;
            }
        }
        LaneHits {
            mask: mask_from_bits(hit),
            t: Vf::from(tt),
            u: Vf::from(uu),
            v: Vf::from(vv),
        }
    }
}
