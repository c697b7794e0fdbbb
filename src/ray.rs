//! Rays and hits of the scalar path: the record every stage passes on.
//!
//! A hit names its primitive by one `u32` over all the scene's primitives, in the
//! order of [`crate::scene::Geometry`]: triangles (OBJ face order after fan
//! triangulation, as in RAYS.md), then spheres, boxes and planes.

#![warn(missing_docs)]

use glam::Vec3;

/// `prim` of a ray that hit nothing (RAYS.md's miss value).
pub const NO_HIT: u32 = u32::MAX;

/// A ray segment: points `org + t * dir` for `t_min < t < t_max`. `repr(C)`: eight
/// f32 in the order of [`Ray::as_records`], so packets load rays as whole records.
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Ray {
    /// Origin, the point at `t = 0`.
    pub org: Vec3,
    /// Direction, not necessarily unit length: `t` is measured in multiples of it.
    pub dir: Vec3,
    /// Exclusive lower bound of `t`; a positive value keeps secondary rays off the
    /// surface they leave.
    pub t_min: f32,
    /// Exclusive upper bound of `t`: the distance to a light for shadow rays, and the
    /// closest hit so far while tracing.
    pub t_max: f32,
}

const _: () = assert!(
    size_of::<Ray>() == 32
        && std::mem::offset_of!(Ray, dir) == 12
        && std::mem::offset_of!(Ray, t_min) == 24
        && std::mem::offset_of!(Ray, t_max) == 28
);

impl Ray {
    /// The rays as records of eight f32, `ox oy oz dx dy dz t_min t_max`, without a
    /// copy: the input of [`crate::simd::Float::transpose8`].
    #[inline]
    pub fn as_records(rays: &[Ray]) -> &[[f32; 8]] {
        // `Ray` is `Pod`: eight f32 at the offsets asserted above, no padding.
        bytemuck::cast_slice(rays)
    }

    /// The segment `org + t * dir`, `t_min < t < t_max`; nothing is checked (see
    /// [`Ray::is_usable`]).
    pub fn new(org: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Self {
        Ray {
            org,
            dir,
            t_min,
            t_max,
        }
    }

    /// Whether any primitive can be hit: finite origin and direction, a direction whose
    /// largest component lies in [`DIR_MIN`, `DIR_MAX`] (a zero direction does not) and
    /// `t_min <= t_max`. Every intersector answers "no hit" for other rays (see
    /// [`crate::accel::Accel`]) without testing a primitive.
    #[inline(always)]
    pub fn is_usable(&self) -> bool {
        let d_max = self.dir.abs().max_element();
        self.org.is_finite()
            && self.dir.is_finite()
            && (DIR_MIN..=DIR_MAX).contains(&d_max)
            && self.t_min <= self.t_max
    }

    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.org + self.dir * t
    }
}

/// Smallest largest-component a usable direction may have (2^-64).
///
/// Directions far from unit length make `t * d` overflow or underflow in f32 long before
/// `t` does, and the triangle test's shear (`d_u / d_k`) underflow: the tests' answers
/// then stop being consistent with any bounds a traversal can widen. Normalised
/// directions are always inside [`DIR_MIN`, `DIR_MAX`]; rays outside hit nothing.
pub const DIR_MIN: f32 = 1.0 / (1u64 << 63) as f32 / 2.0;

/// Largest largest-component a usable direction may have (2^64); see [`DIR_MIN`].
pub const DIR_MAX: f32 = (1u64 << 63) as f32 * 2.0;

/// A ray-primitive intersection. `u`, `v` are barycentric weights of a triangle's
/// second and third vertex (zero for other primitives). `repr(C)`: four 4-byte words, so
/// packets store their hits as whole records ([`Hit::as_records_mut`]).
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Hit {
    /// Ray parameter of the hit point, in multiples of the ray's `dir`; `+inf` on a miss.
    pub t: f32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
    /// Primitive id in [`crate::scene::Geometry`] order, or [`NO_HIT`].
    pub prim: u32,
}

const _: () = assert!(
    size_of::<Hit>() == 16
        && std::mem::offset_of!(Hit, u) == 4
        && std::mem::offset_of!(Hit, v) == 8
        && std::mem::offset_of!(Hit, prim) == 12
);

impl Hit {
    /// The hits as records of four f32 words, `t u v prim` (`prim`'s bits as an f32),
    /// without a copy: the output of [`crate::simd::Float::transpose4_into`].
    #[inline]
    pub fn as_records_mut(hits: &mut [Hit]) -> &mut [[f32; 4]] {
        // `Hit` is `Pod`: four 4-byte words at the offsets asserted above, no padding.
        bytemuck::cast_slice_mut(hits)
    }

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
