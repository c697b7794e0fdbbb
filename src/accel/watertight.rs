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
//! rounding bound of an edge, and then reports this test's `t`, `u`, `v`; the scalar and
//! packet paths call the same function, so they agree bit for bit.

use super::axis::MOD3;
use crate::ray::Ray;
use glam::Vec3;

/// Where the line of `ray` passes through the closed triangle `corners` under the
/// watertight edge rule: `(t, u, v)` with `u`, `v` the weights of the second and third
/// corner, or `None` when it misses (or meets the triangle edge-on, or has NaNs). The
/// ray's `t` range is not checked here.
///
/// `t` is interpolated from the corners' distances along the ray, as in the paper, so
/// the point at `t` lies within rounding of the triangle even for grazing rays, where a
/// plane's `t` does not (a kd-tree finds the hit in the triangle's own cells).
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
    let project = |p: Vec3| {
        let q = p - org;
        [q[kx] - sx * q[kz], q[ky] - sy * q[kz], sz * q[kz]]
    };
    let [a, b, c] = corners.map(project);
    let edge = |p: [f32; 3], q: [f32; 3]| p[0] * q[1] - p[1] * q[0];
    let (eu, ev, ew) = (edge(b, c), edge(c, a), edge(a, b));
    let exact = |e: f32| e != 0.0 && e.is_finite();
    let signs = if !(exact(eu) && exact(ev) && exact(ew)) {
        let edge64 =
            |p: [f32; 3], q: [f32; 3]| p[0] as f64 * q[1] as f64 - p[1] as f64 * q[0] as f64;
        [edge64(b, c), edge64(c, a), edge64(a, b)].map(sign)
    } else {
        [eu, ev, ew].map(|e| sign(e as f64))
    };
    if signs.contains(&-1) == signs.contains(&1) {
        return None;
    }
    let det = eu + ev + ew;
    let t = (eu * a[2] + ev * b[2] + ew * c[2]) / det;
    Some((t, ev / det, ew / det))
}

/// `-1`, `0` or `1` by the sign of `x`; NaN gives 0.
#[inline]
fn sign(x: f64) -> i8 {
    (x > 0.0) as i8 - (x < 0.0) as i8
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
