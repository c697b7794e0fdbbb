//! Stage: accel. The exact edge rule behind the triangle tests: Woop, Benthin and Wald,
//! "Watertight ray/triangle intersection" (JCGT 2(1), 2013).
//!
//! The ray is made the z axis of its own frame: corners are translated by the origin
//! and sheared along the direction's largest axis. Each edge function is then a 2D
//! cross product of two transformed corners. Two facts make the rule watertight:
//! - A corner's transformed position depends only on the corner and the ray, so every
//!   triangle sharing it sees the same bits; the edge function of a shared edge is
//!   evaluated from the same two points in the opposite order, which gives exactly the
//!   negated value (products commute and `a - b == -(b - a)` in IEEE arithmetic).
//! - Rounding is monotonic, so a 2D cross product computed in f32 has the sign of the
//!   exact product of its (rounded) inputs, or is zero. Zeros are recomputed in f64,
//!   where the products of f32 values are exact, so every sign is exact with respect to
//!   the transformed corners, and the triangles around a shared vertex tile the ray's
//!   neighbourhood without gaps.
//!
//! Ties (a zero edge function: the ray passes exactly through an edge or a corner)
//! count as inside, so both neighbours report the hit (an f32 product that overflows is
//! recomputed in f64 as a zero is); a triangle seen exactly edge-on
//! (all three zero) is missed. Both orientations are accepted, as TriAccel does.
//!
//! [`crate::accel::triaccel`] calls this only for rays whose fast answer lies within its
//! rounding bound of an edge, and then reports this test's `t`, `u`, `v`. The packet
//! test decides all such lanes at once with [`intersect_lanes`], the same operations
//! in lanes, and leaves the rare lanes that need f64 (an edge function or a term of
//! `t` that is zero, subnormal or infinite in f32) to [`intersect`] itself, so the
//! paths agree bit for bit.

use super::axis::MOD3;
use crate::ray::Ray;
use crate::simd::{AMap, Float, inl};
use glam::Vec3;

/// Where the line of `ray` passes through the closed triangle `corners` under the
/// watertight edge rule: `(t, u, v)` with `u`, `v` the weights of the second and third
/// corner, or `None` when it misses (or meets the triangle edge-on, or has NaNs). The
/// ray's `t` range is not checked here.
///
/// `t` is interpolated from the corners' distances along the ray, as in the paper, so
/// the point at `t` lies within rounding of the triangle even for grazing rays, where a
/// plane's `t` does not (a kd-tree finds the hit in the triangle's own cells). Where an
/// edge function or a term of that interpolation leaves f32's normal range, all of it
/// is computed in f64: an underflow would round a tiny `t` to zero and put the hit
/// outside those cells.
#[inline(always)]
pub fn intersect(ray: &Ray, corners: &[Vec3; 3]) -> Option<(f32, f32, f32)> {
    let (org, dir) = (ray.org, ray.dir);
    let ad = dir.abs();
    let kz = if ad.x >= ad.y && ad.x >= ad.z {
        0
    } else if ad.y >= ad.z {
        1
    } else {
        2
    };
    let (kx, ky) = (MOD3[kz + 1], MOD3[kz + 2]);
    let sx = dir[kx] / dir[kz];
    let sy = dir[ky] / dir[kz];
    let sz = 1.0 / dir[kz];
    let project = inl(
        #[inline(always)]
        |p: Vec3| {
            let q = p - org;
            [q[kx] - sx * q[kz], q[ky] - sy * q[kz], sz * q[kz]]
        },
    );
    let [a, b, c] = corners.map(project);
    let edge = inl(
        #[inline(always)]
        |p: [f32; 3], q: [f32; 3]| p[0] * q[1] - p[1] * q[0],
    );
    let (eu, ev, ew) = (edge(b, c), edge(c, a), edge(a, b));
    let (tu, tv, tw) = (eu * a[2], ev * b[2], ew * c[2]);
    if [eu, ev, ew, tu, tv, tw].into_iter().all(f32::is_normal) {
        let signs = [eu, ev, ew].map(
            #[inline(always)]
            |e| sign(e as f64),
        );
        if signs.contains(&-1) == signs.contains(&1) {
            return None;
        }
        let det = eu + ev + ew;
        let t = (tu + tv + tw) / det;
        return Some((t, ev / det, ew / det));
    }
    // An edge function or a term of `t` that is zero, subnormal or infinite in f32:
    // the products of f32 values are exact in f64, and neither underflows nor
    // overflows there.
    let f = inl(
        #[inline(always)]
        |x: f32| x as f64,
    );
    let edge64 = inl(
        #[inline(always)]
        |p: [f32; 3], q: [f32; 3]| f(p[0]) * f(q[1]) - f(p[1]) * f(q[0]),
    );
    let e = [edge64(b, c), edge64(c, a), edge64(a, b)];
    let signs = e.map(sign);
    if signs.contains(&-1) == signs.contains(&1) {
        return None;
    }
    let det = e[0] + e[1] + e[2];
    let t = (e[0] * f(a[2]) + e[1] * f(b[2]) + e[2] * f(c[2])) / det;
    Some((t as f32, (e[1] / det) as f32, (e[2] / det) as f32))
}

/// [`intersect`] in lanes: lane `i` holds one ray (`org`, `dir`) and one triangle
/// (`corners`); either may be the same in every lane (a packet against one triangle,
/// or one ray against a leaf's triangles). Every operation is the scalar one, lane by
/// lane, so where `decided` is set the answer (`hit`, and `t`, `u`, `v` where it hit)
/// is [`intersect`]'s bit for bit. The other lanes have an edge function or a term of
/// `t` that is zero, subnormal or not finite in f32 (a ray exactly through an edge or a
/// corner, an underflow, NaNs): only the scalar test's f64 recomputation decides them.
#[derive(Clone, Copy, Debug)]
pub struct LaneAnswer<F: Float> {
    /// Lanes the f32 edge functions decide.
    pub decided: F::Mask,
    /// Decided lanes whose ray's line passes through the triangle.
    pub hit: F::Mask,
    /// Distance along the ray (meaningful where `hit`).
    pub t: F,
    /// Weight of the second corner.
    pub u: F,
    /// Weight of the third corner.
    pub v: F,
}

/// [`intersect`] for every lane at once (see [`LaneAnswer`]): one pass instead of one
/// call per lane where several lanes of a packet lie within the edge bound.
#[inline(always)]
pub fn intersect_lanes<F: Float>(
    org: &[F; 3],
    dir: &[F; 3],
    corners: &[[F; 3]; 3],
) -> LaneAnswer<F> {
    let ad = (*dir).amap(F::abs);
    // The scalar choice of `kz`, `kx = kz + 1`, `ky = kz + 2` (mod 3) per lane.
    let x_wins = ad[0].cmp_ge(ad[1]) & ad[0].cmp_ge(ad[2]);
    let y_wins = !x_wins & ad[1].cmp_ge(ad[2]);
    let sel = F::select;
    let kz = inl(
        #[inline(always)]
        |v: &[F; 3]| sel(x_wins, v[0], sel(y_wins, v[1], v[2])),
    );
    let kx = inl(
        #[inline(always)]
        |v: &[F; 3]| sel(x_wins, v[1], sel(y_wins, v[2], v[0])),
    );
    let ky = inl(
        #[inline(always)]
        |v: &[F; 3]| sel(x_wins, v[2], sel(y_wins, v[0], v[1])),
    );
    let dz = kz(dir);
    let sx = kx(dir) / dz;
    let sy = ky(dir) / dz;
    let sz = F::ONE / dz;
    let project = inl(
        #[inline(always)]
        |p: &[F; 3]| {
            let q = [p[0] - org[0], p[1] - org[1], p[2] - org[2]];
            let qz = kz(&q);
            [kx(&q) - sx * qz, ky(&q) - sy * qz, sz * qz]
        },
    );
    let [a, b, c] = (*corners).amap(
        #[inline(always)]
        |p| project(&p),
    );
    let edge = inl(
        #[inline(always)]
        |p: &[F; 3], q: &[F; 3]| p[0] * q[1] - p[1] * q[0],
    );
    let (eu, ev, ew) = (edge(&b, &c), edge(&c, &a), edge(&a, &b));
    let (tu, tv, tw) = (eu * a[2], ev * b[2], ew * c[2]);
    // `f32::is_normal`: NaN fails the comparison.
    let normal = inl(
        #[inline(always)]
        |x: F| x.abs().cmp_ge(F::splat(f32::MIN_POSITIVE)) & x.finite(),
    );
    let decided = normal(eu) & normal(ev) & normal(ew) & normal(tu) & normal(tv) & normal(tw);
    let z = F::ZERO;
    let same_sign =
        (eu.cmp_gt(z) & ev.cmp_gt(z) & ew.cmp_gt(z)) | (eu.cmp_lt(z) & ev.cmp_lt(z) & ew.cmp_lt(z));
    let det = eu + ev + ew;
    let t = (tu + tv + tw) / det;
    LaneAnswer {
        decided,
        hit: decided & same_sign,
        t,
        u: ev / det,
        v: ew / det,
    }
}

/// `-1`, `0` or `1` by the sign of `x`; NaN gives 0.
#[inline(always)]
fn sign(x: f64) -> i8 {
    (x > 0.0) as i8 - (x < 0.0) as i8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generate::{Rng, random_soup};
    use crate::simd::{LaneMask, Simd, Vf, W4, W8, W16};

    #[test]
    fn shared_edges_and_vertices_are_hit_from_both_sides() {
        let (a, b, c, d) = (
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
        );
        let through = |p: Vec3| Ray::new(Vec3::new(p.x, p.y, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        // The diagonal b-c is shared by (a, b, c) and (b, d, c): a ray through its
        // midpoint hits both, and so does a ray through the shared corner b.
        for p in [(b + c) * 0.5, b] {
            let (t, u, v) = intersect(&through(p), &[a, b, c]).expect("first triangle");
            assert_eq!(t, 1.0);
            assert!(u + v == 1.0 && u >= 0.0 && v >= 0.0, "{u} {v}");
            assert!(intersect(&through(p), &[b, d, c]).is_some());
        }
        let inner = intersect(&through(Vec3::new(0.25, 0.5, 1.0)), &[a, b, c]);
        assert_eq!(inner, Some((1.0, 0.25, 0.5)));
        assert!(intersect(&through(Vec3::new(1.5, 0.5, 1.0)), &[a, b, c]).is_none());
        // Seen edge-on: missed.
        let side = Ray::new(Vec3::new(-1.0, 0.25, 1.0), Vec3::X, 0.0, f32::INFINITY);
        assert!(intersect(&side, &[a, b, c]).is_none());
        let nan = Ray::new(Vec3::NAN, Vec3::Z, 0.0, f32::INFINITY);
        assert!(intersect(&nan, &[a, b, c]).is_none());
    }

    /// One lane's ray and triangle.
    type Case = (Ray, [Vec3; 3]);

    /// Each lane its own ray and triangle: random triangles, a fan sharing edges,
    /// axis-aligned and degenerate triangles and one far from the origin; rays aimed at
    /// corners, edge midpoints and interiors (those through corners and shared edges
    /// leave lanes undecided), axis-parallel rays with signed zeros, directions whose
    /// largest components tie, zero and NaN directions, NaN origins.
    fn cases() -> Vec<Case> {
        let mut rng = Rng::new(23);
        let mut g = random_soup(48, 0.6, 5);
        let hub = Vec3::new(0.5, 0.5, 0.5);
        let rim = |a: f32| hub + Vec3::new(a.cos(), a.sin(), 0.3 * a.sin()) * 0.4;
        let mut tris: Vec<[Vec3; 3]> = (0..g.triangles.len() as u32)
            .map(|i| g.triangle(i))
            .collect();
        for s in 0..6 {
            let (a0, a1) = (s as f32, (s + 1) as f32);
            tris.push([hub, rim(a0), rim(a1)]);
        }
        for k in 0..3 {
            let e = |i: usize| Vec3::AXES[(k + i) % 3];
            tris.push([e(1) * 0.1, e(1) * 0.9, e(2) * 0.9 + e(0) * 0.5]);
        }
        tris.push([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
        let far = Vec3::new(3.0e4, -2.0e4, 1.0e4);
        tris.push([far, far + Vec3::X, far + Vec3::Y]);
        g.triangles.clear();
        let mut out = Vec::new();
        for &[a, b, c] in &tris {
            let o = rng.point(a - Vec3::ONE, a + Vec3::ONE);
            for target in [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5] {
                out.push((Ray::new(o, target - o, 0.0, f32::INFINITY), [a, b, c]));
            }
            // Just outside and just inside each edge, and random directions.
            for (p, q, r) in [(a, b, c), (b, c, a), (c, a, b)] {
                let mid = (p + q) * 0.5;
                for step in [1e-6f32, -1e-6, 1e-3] {
                    let target = mid + (mid - r) * step;
                    out.push((Ray::new(o, target - o, 0.0, f32::INFINITY), [a, b, c]));
                }
                out.push((
                    Ray::new(o, rng.unit_vector(), 0.0, f32::INFINITY),
                    [a, b, c],
                ));
            }
            let inside = a * 0.25 + b * 0.25 + c * 0.5;
            out.push((Ray::new(o, inside - o, 0.0, f32::INFINITY), [a, b, c]));
            out.push((Ray::new(inside, rng.unit_vector(), 0.0, 1.0), [a, b, c]));
            for axis in Vec3::AXES {
                for s in [1.0f32, -1.0] {
                    let d = Vec3::select((axis * s).cmpeq(Vec3::ZERO), Vec3::splat(-0.0), axis * s);
                    out.push((Ray::new(inside - d, d, 0.0, f32::INFINITY), [a, b, c]));
                }
            }
            for d in [
                Vec3::new(1.0, 1.0, 0.5),
                Vec3::new(-1.0, 0.5, 1.0),
                Vec3::new(0.5, -1.0, -1.0),
                Vec3::ONE,
                Vec3::ZERO,
                Vec3::new(f32::NAN, 1.0, 0.0),
            ] {
                out.push((Ray::new(inside - d, d, 0.0, f32::INFINITY), [a, b, c]));
            }
            out.push((
                Ray::new(Vec3::splat(f32::NAN), Vec3::Z, 0.0, 1.0),
                [a, b, c],
            ));
        }
        // Neighbouring lanes see different triangles and rays.
        for i in (1..out.len()).step_by(3) {
            let j = rng.below(out.len() as u32) as usize;
            out.swap(i, j);
        }
        out
    }

    #[inline(always)]
    fn lanes_match_scalar<W: Simd>() {
        let cases = cases();
        let (mut hits, mut misses, mut undecided) = (0, 0, 0);
        for chunk in cases.chunks(W::LANES) {
            let lane = |i: usize| &chunk[i % chunk.len()];
            let v = |f: &dyn Fn(&Case) -> f32| Vf::<W>::from_fn(|i| f(lane(i)));
            let org = [v(&|c| c.0.org.x), v(&|c| c.0.org.y), v(&|c| c.0.org.z)];
            let dir = [v(&|c| c.0.dir.x), v(&|c| c.0.dir.y), v(&|c| c.0.dir.z)];
            let corners: [[Vf<W>; 3]; 3] =
                std::array::from_fn(|k| [v(&|c| c.1[k].x), v(&|c| c.1[k].y), v(&|c| c.1[k].z)]);
            let got = intersect_lanes(&org, &dir, &corners);
            let (decided, hit) = (got.decided.bits(), got.hit.bits());
            assert_eq!(hit & !decided, 0);
            for (i, (ray, tri)) in chunk.iter().enumerate() {
                let want = intersect(ray, tri);
                if decided & (1 << i) == 0 {
                    undecided += 1;
                    continue;
                }
                let lanes =
                    (hit & (1 << i) != 0).then(|| (got.t.lane(i), got.u.lane(i), got.v.lane(i)));
                let bits =
                    |h: Option<(f32, f32, f32)>| h.map(|(t, u, v)| [t, u, v].map(f32::to_bits));
                assert_eq!(
                    bits(lanes),
                    bits(want),
                    "{} lanes: {ray:?} against {tri:?}",
                    W::LANES
                );
                if want.is_some() {
                    hits += 1
                } else {
                    misses += 1
                }
            }
        }
        assert!(
            hits > 300 && misses > 300 && undecided > 30,
            "{hits} hits, {misses} misses, {undecided} undecided"
        );
    }

    #[test]
    fn lanes_match_scalar_at_every_width() {
        lanes_match_scalar::<W4>();
        lanes_match_scalar::<W8>();
        lanes_match_scalar::<W16>();
    }
}
