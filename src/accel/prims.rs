//! Scalar intersection tests for spheres, boxes and planes. Their packet twins are in
//! [`crate::accel::prims_packet`] and follow the same operation order.

use crate::ray::Ray;
use crate::scene::{Aabb, Plane, Sphere};

/// Nearest `t` in `(t_min, t_max)` where `ray` meets the sphere's surface. A ray that
/// starts inside gets the exit point.
#[inline]
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "NaN must fail the test")]
pub fn intersect_sphere(s: &Sphere, ray: &Ray, t_max: f32) -> Option<f32> {
    let oc = ray.org - s.center;
    let a = ray.dir.dot(ray.dir);
    let b = oc.dot(ray.dir);
    let c = oc.dot(oc) - s.radius * s.radius;
    let disc = b * b - a * c;
    if !(disc >= 0.0) {
        return None;
    }
    let root = disc.sqrt();
    let t0 = (-b - root) / a;
    if t0 > ray.t_min && t0 < t_max {
        return Some(t0);
    }
    let t1 = (-b + root) / a;
    (t1 > ray.t_min && t1 < t_max).then_some(t1)
}

/// Nearest `t` in `(t_min, t_max)` where `ray` meets the box's surface (slab test).
#[inline]
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
#[inline]
pub fn intersect_plane(p: &Plane, ray: &Ray, t_max: f32) -> Option<f32> {
    let t = (p.offset - p.normal.dot(ray.org)) / p.normal.dot(ray.dir);
    (t > ray.t_min && t < t_max).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

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
