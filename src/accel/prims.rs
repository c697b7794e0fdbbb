//! Scalar intersection tests for spheres, boxes and planes. Their packet twins are in
//! [`crate::accel::prims_packet`] and follow the same operation order.

use crate::geom::{Aabb, Plane, Sphere};
use crate::ray::Ray;

/// Nearest `t` in `(t_min, t_max)` where `ray` meets the sphere's surface. A ray that
/// starts inside gets the exit point.
///
/// Uses the precise form of Haines et al., "Precision Improvements for Ray/Sphere
/// Intersection" (Ray Tracing Gems, ch. 7): the discriminant comes from the distance of
/// the centre to the ray's line, not from `b * b - a * c`, which cancels catastrophically
/// for far origins; the roots come from `q`, which avoids cancelling `-b + root`.
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
pub fn intersect_sphere(s: &Sphere, ray: &Ray, t_max: f32) -> Option<f32> {
    let oc = ray.org - s.center;
    let a = ray.dir.dot(ray.dir);
    let b = oc.dot(ray.dir);
    let r2 = s.radius * s.radius;
    let c = oc.dot(oc) - r2;
    // Closest point of the line to the centre, relative to the centre.
    let l = oc - ray.dir * (b / a);
    let disc = a * (r2 - l.dot(l));
    if !(disc >= 0.0) {
        return None;
    }
    let root = disc.sqrt();
    let q = -(b + if b < 0.0 { -root } else { root });
    let (t0, t1) = (c / q, q / a);
    let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
    if near > ray.t_min && near < t_max {
        return Some(near);
    }
    (far > ray.t_min && far < t_max).then_some(far)
}

/// Nearest `t` in `(t_min, t_max)` where `ray` meets the box's surface (slab test).
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
pub fn intersect_box(b: &Aabb, ray: &Ray, t_max: f32) -> Option<f32> {
    let inv = ray.dir.recip();
    let t0 = (b.min - ray.org) * inv;
    let t1 = (b.max - ray.org) * inv;
    let t_near = t0.min(t1).max_element();
    let t_far = t0.max(t1).min_element();
    if !(t_near <= t_far) {
        return None;
    }
    if t_near > ray.t_min && t_near < t_max {
        Some(t_near)
    } else if t_far > ray.t_min && t_far < t_max {
        Some(t_far)
    } else {
        None
    }
}

/// `t` in `(t_min, t_max)` where `ray` meets the plane.
#[inline(always)]
pub fn intersect_plane(p: &Plane, ray: &Ray, t_max: f32) -> Option<f32> {
    let t = (p.offset - p.normal.dot(ray.org)) / p.normal.dot(ray.dir);
    (t > ray.t_min && t < t_max).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn far_origins_do_not_invent_sphere_hits() {
        // A glossy ray of scenes/part5.toml 75,000 units from the spheres; the exact
        // discriminant is negative, b * b - a * c in f32 said otherwise.
        let ray = Ray::new(
            Vec3::new(63490.934, 7.3985133, -40061.938),
            Vec3::new(-0.8457027, -5.3081217e-6, 0.5336544),
            0.0,
            75075.4,
        );
        for c in [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-2.0, 1.0, 1.0),
            Vec3::new(2.0, 1.0, -1.0),
        ] {
            let s = Sphere {
                center: c,
                radius: 1.0,
            };
            assert_eq!(intersect_sphere(&s, &ray, ray.t_max), None, "sphere at {c}");
        }
    }

    #[test]
    fn closed_forms() {
        let ray = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, 0.0, f32::INFINITY);
        let s = Sphere {
            center: Vec3::ZERO,
            radius: 2.0,
        };
        assert_eq!(intersect_sphere(&s, &ray, f32::INFINITY), Some(3.0));
        let inside = Ray::new(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(intersect_sphere(&s, &inside, f32::INFINITY), Some(2.0));
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::ONE);
        assert_eq!(intersect_box(&b, &ray, f32::INFINITY), Some(4.0));
        assert_eq!(intersect_box(&b, &inside, f32::INFINITY), Some(1.0));
        let p = Plane {
            normal: Vec3::Z,
            offset: 1.0,
        };
        assert_eq!(intersect_plane(&p, &ray, f32::INFINITY), Some(6.0));
        assert_eq!(intersect_plane(&p, &ray, 5.0), None);
    }
}
