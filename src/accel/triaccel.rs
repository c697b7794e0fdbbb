//! Wald's precomputed triangle test ("TriAccel", Wald 2004, PhD thesis, section 7.1).
//!
//! Each triangle is stored as its plane and two edge equations, all projected onto the
//! coordinate plane where the triangle is largest (dropping axis `k`). The test then
//! costs one division and a handful of multiply-adds, and needs no vertex fetch.
//!
//! The packet twin lives in [`crate::accel::triaccel_packet`] and performs the same
//! operations in the same order, so both return bit-identical `t`, `u`, `v`.

use crate::ray::Ray;
use crate::scene::Geometry;
use glam::Vec3;

/// `(k + 1) % 3` and `(k + 2) % 3` without a division: `MOD3[k + 1]`, `MOD3[k + 2]`.
pub const MOD3: [usize; 5] = [0, 1, 2, 0, 1];

/// One precomputed triangle: 48 bytes, three 16-byte rows, laid out as in Wald's thesis
/// so the packet test loads each row with one aligned load.
///
/// For a hit point `h` projected to `(h_u, h_v)`:
/// - plane: `t = (n_d - o_k - n_u o_u - n_v o_v) / (d_k + n_u d_u + n_v d_v)`;
/// - `u = h_u b_nu + h_v b_nv + b_d` is the weight of the second vertex;
/// - `v = h_u c_nu + h_v c_nv + c_d` is the weight of the third vertex.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriAccel {
    pub n_u: f32,
    pub n_v: f32,
    pub n_d: f32,
    /// Projection axis: the largest component of the normal.
    pub k: u32,
    pub b_nu: f32,
    pub b_nv: f32,
    pub b_d: f32,
    /// The triangle's id (its index in [`Geometry::triangles`]).
    pub tri: u32,
    pub c_nu: f32,
    pub c_nv: f32,
    pub c_d: f32,
    /// Unused; keeps rows 16-byte aligned.
    pub pad: u32,
}

const _: () = assert!(std::mem::size_of::<TriAccel>() == 48);

impl TriAccel {
    /// Precomputes the record of triangle `tri` with corners `a`, `b`, `c`. A degenerate
    /// triangle gets a record that no ray hits (its edge equations are all zero with
    /// `b_d = -1`).
    pub fn new(a: Vec3, b: Vec3, c: Vec3, tri: u32) -> TriAccel {
        let e1 = b - a; // toward the second vertex (weight u)
        let e2 = c - a; // toward the third vertex (weight v)
        let n = e1.cross(e2);
        let an = n.abs();
        let k = if an.x >= an.y && an.x >= an.z {
            0
        } else if an.y >= an.z {
            1
        } else {
            2
        };
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let nk = n[k];
        // det of [e1 e2] in the (u, v) projection equals n[k].
        let det = e1[ku] * e2[kv] - e1[kv] * e2[ku];
        if nk == 0.0 || det == 0.0 || !nk.is_finite() || !det.is_finite() {
            return TriAccel {
                n_u: 0.0,
                n_v: 0.0,
                n_d: 0.0,
                k: k as u32,
                b_nu: 0.0,
                b_nv: 0.0,
                b_d: -1.0,
                tri,
                c_nu: 0.0,
                c_nv: 0.0,
                c_d: -1.0,
                pad: 0,
            };
        }
        let n_u = n[ku] / nk;
        let n_v = n[kv] / nk;
        let n_d = a[k] + n_u * a[ku] + n_v * a[kv];
        // Solve h - a = u e1 + v e2 in 2D (Cramer's rule).
        let b_nu = e2[kv] / det;
        let b_nv = -e2[ku] / det;
        let b_d = -(a[ku] * b_nu + a[kv] * b_nv);
        let c_nu = -e1[kv] / det;
        let c_nv = e1[ku] / det;
        let c_d = -(a[ku] * c_nu + a[kv] * c_nv);
        TriAccel {
            n_u,
            n_v,
            n_d,
            k: k as u32,
            b_nu,
            b_nv,
            b_d,
            tri,
            c_nu,
            c_nv,
            c_d,
            pad: 0,
        }
    }

    /// Records for every triangle of `geometry`, in id order.
    pub fn build_all(geometry: &Geometry) -> Vec<TriAccel> {
        (0..geometry.triangles.len() as u32)
            .map(|i| {
                let [a, b, c] = geometry.triangle(i);
                TriAccel::new(a, b, c, i)
            })
            .collect()
    }

    /// Intersects `ray` with the triangle for `t_min < t < t_max`; returns `(t, u, v)`.
    ///
    /// Operation order is part of the contract: the packet test repeats it exactly.
    #[inline]
    #[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<(f32, f32, f32)> {
        let k = self.k as usize;
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let (o, d) = (ray.org, ray.dir);
        let denom = d[k] + self.n_u * d[ku] + self.n_v * d[kv];
        let numer = self.n_d - o[k] - self.n_u * o[ku] - self.n_v * o[kv];
        let t = numer / denom;
        // Written so that NaN (denominator 0) fails.
        if !(t > ray.t_min && t < t_max) {
            return None;
        }
        let hu = o[ku] + t * d[ku];
        let hv = o[kv] + t * d[kv];
        let u = hu * self.b_nu + hv * self.b_nv + self.b_d;
        if !(u >= 0.0) {
            return None;
        }
        let v = hu * self.c_nu + hv * self.c_nv + self.c_d;
        if !(v >= 0.0) || !(u + v <= 1.0) {
            return None;
        }
        Some((t, u, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentrics_weight_second_and_third_vertex() {
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(2.0, 0.0, 1.0),
            Vec3::new(0.0, 4.0, 1.0),
        );
        let acc = TriAccel::new(a, b, c, 7);
        let p = a * 0.5 + b * 0.25 + c * 0.25;
        let ray = Ray::new(Vec3::new(p.x, p.y, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        let (t, u, v) = acc.intersect(&ray, ray.t_max).expect("hit");
        assert!((t - 2.0).abs() < 1e-6);
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.25).abs() < 1e-6);
        // Outside the u >= 0 edge, and beyond t_max.
        let miss = Ray::new(Vec3::new(-0.1, 1.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(acc.intersect(&miss, miss.t_max).is_none());
        assert!(acc.intersect(&ray, 1.5).is_none());
    }

    #[test]
    fn degenerate_triangles_are_never_hit() {
        let acc = TriAccel::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0, 0);
        let ray = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(acc.intersect(&ray, ray.t_max).is_none());
    }
}
