//! Packet twin of [`crate::accel::triaccel`]: one TriAccel record against `LANES` rays
//! (Wald 2004, PhD thesis, section 7.2: the SIMD form of the projected test).
//!
//! The projection axis `k` belongs to the triangle, so it is one scalar for the whole
//! packet: the lanes differ only in their rays. Every expression repeats the scalar
//! [`TriAccel::intersect`] operation by operation (`a * b + c` as a multiply then an
//! add, a true division), so `t`, `u` and `v` are bit-identical to it in every lane.
//! Inactive lanes are masked out of the result; their values (NaN included) reach no
//! other lane because every operation is lane-wise.

use super::packet::{LaneHits, RayPacket};
use super::triaccel::{MOD3, TriAccel};
use crate::simd::{Mask, Vf, none, splat};

impl TriAccel {
    /// Intersects the lanes of `rays` set in `active` with the triangle for
    /// `t_min < t < t_max` (per lane). Leaves early once no lane can still hit.
    #[inline]
    pub fn intersect_packet(&self, rays: &RayPacket, active: Mask, t_max: Vf) -> LaneHits {
        let k = self.k as usize;
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let (o, d) = (&rays.org, &rays.dir);
        let (n_u, n_v) = (splat(self.n_u), splat(self.n_v));
        let denom = d[k] + n_u * d[ku] + n_v * d[kv];
        let numer = splat(self.n_d) - o[k] - n_u * o[ku] - n_v * o[kv];
        let t = numer / denom;
        let mut mask = active & t.simd_gt(rays.t_min) & t.simd_lt(t_max);
        if none(mask) {
            return LaneHits::none();
        }
        let hu = o[ku] + t * d[ku];
        let hv = o[kv] + t * d[kv];
        let u = hu * splat(self.b_nu) + hv * splat(self.b_nv) + splat(self.b_d);
        let v = hu * splat(self.c_nu) + hv * splat(self.c_nv) + splat(self.c_d);
        mask = mask & u.simd_ge(Vf::ZERO) & v.simd_ge(Vf::ZERO) & (u + v).simd_le(Vf::ONE);
        LaneHits { mask, t, u, v }
    }
}
