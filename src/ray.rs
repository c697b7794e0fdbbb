//! Rays and hits of the scalar path: the record every stage passes on.
//!
//! A hit names its primitive by one `u32` over all the scene's primitives, in the
//! order of [`crate::scene::Geometry`]: triangles (OBJ face order after fan
//! triangulation, as in RAYS.md), then spheres, boxes and planes.

use glam::Vec3;

/// `prim` of a ray that hit nothing (RAYS.md's miss value).
pub const NO_HIT: u32 = u32::MAX;

/// A ray segment: points `org + t * dir` for `t_min < t < t_max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub org: Vec3,
    pub dir: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    pub fn new(org: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Self {
        Ray {
            org,
            dir,
            t_min,
            t_max,
        }
    }

    /// Whether any primitive can be hit: finite origin and direction, a non-zero
    /// direction and `t_min <= t_max`. Every intersector answers "no hit" for other rays
    /// (see [`crate::accel::Accel`]) without testing a primitive.
    #[inline]
    pub fn is_usable(&self) -> bool {
        self.org.is_finite()
            && self.dir.is_finite()
            && self.dir != Vec3::ZERO
            && self.t_min <= self.t_max
    }

    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.org + self.dir * t
    }
}

/// A ray-primitive intersection. `u`, `v` are barycentric weights of a triangle's
/// second and third vertex (zero for other primitives).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub prim: u32,
}

impl Hit {
    /// The value of a miss: `t = +inf`, `prim = NO_HIT`.
    pub const MISS: Hit = Hit {
        t: f32::INFINITY,
        u: 0.0,
        v: 0.0,
        prim: NO_HIT,
    };

    /// True unless this is [`Hit::MISS`].
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.prim != NO_HIT
    }

    /// The closest-hit order every intersector uses: smaller `t` first, and on equal `t`
    /// the smaller primitive id, so the answer does not depend on the visiting order.
    #[inline]
    pub fn is_closer(t: f32, prim: u32, than: &Hit) -> bool {
        t < than.t || (t == than.t && prim < than.prim)
    }
}
