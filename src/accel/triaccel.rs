//! Wald's precomputed triangle test ("TriAccel", Wald 2004, PhD thesis, section 7.1),
//! made watertight.
//!
//! Each triangle is stored as its plane and two edge equations, all projected onto the
//! coordinate plane where the triangle is largest (dropping axis `k`). The test then
//! costs one division and a handful of multiply-adds, and needs no vertex fetch.
//!
//! The packet twin lives in [`crate::accel::triaccel_packet`] and performs the same
//! operations in the same order, so both return bit-identical `t`, `u`, `v`.
//!
//! Watertightness. As published, the test lets rays slip between triangles that share
//! an edge: each triangle computes its own hit point from its own rounded plane (its own
//! `t`) and its own projection, so two neighbours can both place a ray just outside
//! themselves. Measured on this machine with `tests/watertight.rs` before this rule: 3 of
//! 1,048,576 random interior rays escaped a closed oblique 132K-triangle grid, and 6.9%
//! of rays aimed exactly at its shared edges and vertices (8.6% on a tessellated sphere,
//! 0.33% on an axis-aligned box with rounded coordinates). The error is not a property
//! of the triangle alone: to first order (`eps = 2^-24`, `beta` the size of the edge
//! coefficients, `|d|` the direction's largest component, `denom` the test's
//! denominator)
//!
//! ```text
//! |u - u_exact| <= eps * beta * (mag + |o| + |t| |d|) * (c1 |d| / |denom| + c2)
//! ```
//!
//! It grows with the ray origin's magnitude and without limit for grazing rays, so a
//! fixed per-triangle slack folded into `b_d`/`c_d` (the cheapest candidate: no extra
//! instruction) cannot close every crack; a slack wide enough for typical rays (about
//! 1e-4 of the triangle on the 132K grid) still leaks grazing ones and fattens every
//! silhouette. An exact rule for every test (Woop, Benthin & Wald 2013) needs the
//! corners and a per-lane permutation of axes in the packet test, about three times the
//! arithmetic.
//!
//! So the test is a hybrid. A lane whose `t` lies outside `(t_min, t_max)` by more than
//! it can differ from the exact rule's `t` ([`T_SLACK`]) leaves at once, as in Wald's
//! test. Otherwise the fast TriAccel answer stands when the smallest of `u`,
//! `v`, `w = 1 - u - v` is farther from zero than the bound above (with `c1 = 128`,
//! `c2 = 64`: four times the first-order constants of TriAccel's own rounding plus the
//! exact rule's). Then the exact rule of [`crate::accel::watertight`] gives the same
//! answer, so every answer is the exact rule's answer, which is watertight. Only rays
//! within the bound of an edge (rare: the bound is a few ulps of the coordinates, seen
//! through the triangle's size) run the exact rule on the triangle's corners; both paths
//! call the same scalar function, so they stay bit-identical. The bound's per-triangle
//! factors fill the record's two spare words (`err = eps * beta` and `mag`, the largest
//! corner coordinate, raised to cover the rounding of the stored coefficients, measured
//! in f64 at build time), so the record stays 48 bytes. A hit decided by the exact rule
//! reports that rule's `t`, `u`, `v`: for a grazing ray the plane's `t` can put the hit
//! point well outside the triangle (and outside its kd-tree cells), the rule's cannot.
//!
//! The cost in Mrays/s is recorded in perf/log/overview.md, section "Watertightness".

// The packet twin names the axes through this module too.
use super::axis::MOD3;
use super::watertight;
use crate::geom::Geometry;
use crate::ray::Ray;
use glam::{DVec3, Vec3};

/// Unit roundoff of f32.
const EPS: f32 = f32::EPSILON * 0.5;

/// Weight of the grazing term `|d| / |denom|` in the edge bound (see the module doc).
pub const C1: f32 = 128.0;

/// Weight of the constant term in the edge bound.
pub const C2: f32 = 64.0;

/// `|t - t_exact| <= T_SLACK * reach / |denom|` with `reach = mag + |o| + |t| |d|`: the
/// first-order bound on how far TriAccel's `t` lies from the exact rule's (`28 eps`),
/// times four. Lanes farther than this outside `(t_min, t_max)` leave at once.
pub const T_SLACK: f32 = 1.0 / (1u32 << 17) as f32;

/// `if a < b { a } else { b }`: the order of [`crate::simd::Float::min_lt`].
#[inline(always)]
pub fn min_lt(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// `if a > b { a } else { b }`: the order of [`crate::simd::Float::max_gt`].
#[inline(always)]
pub fn max_gt(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// The largest absolute component, `max_gt(max_gt(|x|, |y|), |z|)`: the order of
/// [`crate::simd::max_abs`]. The triangle test's error bound grows with it (of the
/// origin and of the direction), and so do the kd-tree's plane margins.
#[inline(always)]
pub fn max_abs(v: Vec3) -> f32 {
    max_gt(max_gt(v.x.abs(), v.y.abs()), v.z.abs())
}

/// The answer of the exact edge rule for a ray within the bound of an edge: its hit
/// (`t`, `u`, `v` from [`watertight::intersect`]) when `t_min < t < t_max`. The scalar
/// and packet tests both call this one function.
#[inline(never)]
pub fn exact_rule(ray: &Ray, t_max: f32, corners: &[Vec3; 3]) -> Option<(f32, f32, f32)> {
    let (t, u, v) = watertight::intersect(ray, corners)?;
    (t > ray.t_min && t < t_max).then_some((t, u, v))
}

/// One precomputed triangle: 48 bytes, three 16-byte rows, laid out as in Wald's thesis
/// so the packet test loads each row with one aligned load.
///
/// For a hit point `h` projected to `(h_u, h_v)`:
/// - plane: `t = (n_d - o_k - n_u o_u - n_v o_v) / (d_k + n_u d_u + n_v d_v)`;
/// - `u = h_u b_nu + h_v b_nv + b_d` is the weight of the second vertex;
/// - `v = h_u c_nu + h_v c_nv + c_d` is the weight of the third vertex.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TriAccel {
    /// Normal's `u` component over its `k` component.
    pub n_u: f32,
    /// Normal's `v` component over its `k` component.
    pub n_v: f32,
    /// Plane offset over the normal's `k` component: `dot(n, v0) / n_k`.
    pub n_d: f32,
    /// Projection axis `k` (the largest component of the normal) in bits 0 and 1, the
    /// triangle's id above them ([`TriAccel::axis`], [`TriAccel::id`]): a hit names its
    /// triangle from the record it was tested with, with no other load.
    pub k_id: u32,
    /// `u`'s gradient along the projected `u` axis.
    pub b_nu: f32,
    /// `u`'s gradient along the projected `v` axis.
    pub b_nv: f32,
    /// `u`'s constant term.
    pub b_d: f32,
    /// `eps * beta`: the edge bound's scale, with `beta = |b_nu| + |b_nv| + |c_nu| +
    /// |c_nv|` bounding the gradient of `u`, `v` and `1 - u - v` (Wald's padding word).
    pub err: f32,
    /// `v`'s gradient along the projected `u` axis.
    pub c_nu: f32,
    /// `v`'s gradient along the projected `v` axis.
    pub c_nv: f32,
    /// `v`'s constant term.
    pub c_d: f32,
    /// The largest corner coordinate, raised to cover the stored coefficients' own
    /// rounding (Wald's second padding word).
    pub mag: f32,
}

const _: () = assert!(std::mem::size_of::<TriAccel>() == 48);

/// Largest triangle id a record holds (30 bits, as the kd-tree's indices).
pub const MAX_ID: u32 = (1 << 30) - 1;

impl TriAccel {
    /// The projection axis `k`.
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.k_id & 3) as usize
    }

    /// The record as its three 16-byte rows (`n_u n_v n_d k_id`, `b_nu b_nv b_d err`,
    /// `c_nu c_nv c_d mag`; `k_id` as float bits), for loads of a whole row at a time.
    #[inline(always)]
    pub fn rows(&self) -> &[[f32; 4]; 3] {
        // `TriAccel` is `Pod`: twelve 4-byte fields, no padding (the derive checks it).
        bytemuck::cast_ref(self)
    }

    /// The id of the triangle.
    #[inline(always)]
    pub fn id(&self) -> u32 {
        self.k_id >> 2
    }

    /// The record naming triangle `id` (at most [`MAX_ID`]).
    #[inline(always)]
    pub fn with_id(self, id: u32) -> TriAccel {
        debug_assert!(id <= MAX_ID);
        TriAccel {
            k_id: (self.k_id & 3) | id << 2,
            ..self
        }
    }

    /// Precomputes the record of the triangle with corners `a`, `b`, `c` (id 0). A degenerate
    /// triangle gets a record that no ray hits (its edge equations are all zero with
    /// `b_d = -1`).
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> TriAccel {
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
                k_id: k as u32,
                b_nu: 0.0,
                b_nv: 0.0,
                b_d: -1.0,
                err: 0.0,
                c_nu: 0.0,
                c_nv: 0.0,
                c_d: -1.0,
                mag: 0.0,
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
        let mut acc = TriAccel {
            n_u,
            n_v,
            n_d,
            k_id: k as u32,
            b_nu,
            b_nv,
            b_d,
            err: 0.0,
            c_nu,
            c_nv,
            c_d,
            mag: 0.0,
        };
        (acc.err, acc.mag) = acc.bound_factors([a, b, c]);
        acc
    }

    /// `err` and `mag` for corners `p` (see the module doc). The stored coefficients'
    /// rounding is measured in f64 at the corners: `s_e`, the largest error of `u`, `v`
    /// or `u + v`, and `r_p`, the largest distance along `k` from a corner to the stored
    /// plane. Being affine, these errors grow at most fourfold (eightfold for the plane)
    /// over the region where the bound decides anything, and `mag` is raised until the
    /// bound's constant and grazing terms cover them. Rounded up, never down.
    fn bound_factors(&self, p: [Vec3; 3]) -> (f32, f32) {
        let k = self.axis();
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let f = |x: f32| x as f64;
        let beta =
            f(self.b_nu).abs() + f(self.b_nv).abs() + f(self.c_nu).abs() + f(self.c_nv).abs();
        let mut m = 0.0f64;
        let mut s_e = 0.0f64;
        let mut r_p = 0.0f64;
        for (i, q) in p.iter().enumerate() {
            let q = DVec3::new(f(q.x), f(q.y), f(q.z));
            m = m.max(q.abs().max_element());
            let u = q[ku] * f(self.b_nu) + q[kv] * f(self.b_nv) + f(self.b_d);
            let v = q[ku] * f(self.c_nu) + q[kv] * f(self.c_nv) + f(self.c_d);
            let (u0, v0) = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)][i];
            s_e = s_e
                .max((u - u0).abs())
                .max((v - v0).abs())
                .max((u + v - u0 - v0).abs());
            let plane = f(self.n_d) - f(self.n_u) * q[ku] - f(self.n_v) * q[kv];
            r_p = r_p.max((q[k] - plane).abs());
        }
        let eps = EPS as f64;
        let err = (eps * beta * (1.0 + 1e-6)).max(f32::MIN_POSITIVE as f64);
        let mag = m
            .max(4.0 * s_e / (err * C2 as f64))
            .max(8.0 * r_p / (eps * C1 as f64))
            * (1.0 + 1e-6);
        let up = |x: f64| {
            let y = x as f32;
            if (y as f64) < x { y.next_up() } else { y }
        };
        (up(err), up(mag))
    }

    /// True for the record of a degenerate triangle (zero area, or corners too large
    /// for its plane to be finite): [`TriAccel::new`] zeroes its edge equations, so no
    /// ray hits it and the kd-tree leaves it out.
    #[inline(always)]
    pub fn is_degenerate(&self) -> bool {
        self.b_nu == 0.0 && self.b_nv == 0.0 && self.c_nu == 0.0 && self.c_nv == 0.0
    }

    /// The record of `geometry`'s triangle `tri`, naming it.
    #[inline(always)]
    pub fn of(geometry: &Geometry, tri: u32) -> TriAccel {
        let [a, b, c] = geometry.triangle(tri);
        TriAccel::new(a, b, c).with_id(tri)
    }

    /// Intersects `ray` with the triangle for `t_min < t < t_max`; returns `(t, u, v)`.
    /// `corners` are the triangle's corners, read only when the exact edge rule decides.
    ///
    /// Operation order is part of the contract: the packet test repeats it exactly.
    #[inline(always)]
    #[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
    pub fn intersect(&self, ray: &Ray, t_max: f32, corners: &[Vec3; 3]) -> Option<(f32, f32, f32)> {
        let k = self.axis();
        let (ku, kv) = (MOD3[k + 1], MOD3[k + 2]);
        let (o, d) = (ray.org, ray.dir);
        let denom = d[k] + self.n_u * d[ku] + self.n_v * d[kv];
        let numer = self.n_d - o[k] - self.n_u * o[ku] - self.n_v * o[kv];
        let t = numer / denom;
        let ad = denom.abs();
        let (o_max, d_max) = (max_abs(o), max_abs(d));
        let reach = self.mag + o_max + t.abs() * d_max;
        // Early out, written so that NaN fails: `t` is outside the ray's range by more
        // than it can differ from the exact rule's `t` (`T_SLACK * reach / |denom|`).
        let slack = reach * T_SLACK;
        if !((t - t_max) * ad < slack && (ray.t_min - t) * ad < slack) {
            return None;
        }
        let hu = o[ku] + t * d[ku];
        let hv = o[kv] + t * d[kv];
        let u = hu * self.b_nu + hv * self.b_nv + self.b_d;
        let v = hu * self.c_nu + hv * self.c_nv + self.c_d;
        let w = 1.0 - u - v;
        let bound = self.err * reach * (C1 * d_max + C2 * ad);
        let edge = min_lt(min_lt(u, v), w) * ad;
        // Written so that NaN (denominator 0) fails. The `t` range is checked on the
        // `t` that is reported, so the answer does not depend on the `t_max` a caller
        // passes beyond cutting at it (a kd-tree's answer equals brute force's).
        if edge >= bound {
            return (t > ray.t_min && t < t_max).then_some((t, u, v));
        }
        if !(edge >= -bound) {
            return None;
        }
        exact_rule(ray, t_max, corners)
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
        let acc = TriAccel::new(a, b, c);
        let corners = [a, b, c];
        let p = a * 0.5 + b * 0.25 + c * 0.25;
        let ray = Ray::new(Vec3::new(p.x, p.y, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        let (t, u, v) = acc.intersect(&ray, ray.t_max, &corners).expect("hit");
        assert!((t - 2.0).abs() < 1e-6);
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.25).abs() < 1e-6);
        // Outside the u >= 0 edge, and beyond t_max.
        let miss = Ray::new(Vec3::new(-0.1, 1.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(acc.intersect(&miss, miss.t_max, &corners).is_none());
        assert!(acc.intersect(&ray, 1.5, &corners).is_none());
    }

    #[test]
    fn degenerate_triangles_are_never_hit() {
        let corners = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let acc = TriAccel::new(corners[0], corners[1], corners[2]);
        assert!(acc.is_degenerate());
        let ray = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(acc.intersect(&ray, ray.t_max, &corners).is_none());
        assert!(!TriAccel::new(Vec3::ZERO, Vec3::X, Vec3::Y).is_degenerate());
    }
}
