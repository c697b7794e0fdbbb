//! The orthonormal basis about a unit vector, once for f32 (rendering) and f64 (the
//! standard ray sets): Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT
//! 2017), listing 3. Branch-free except for the sign of `w.z`, and exact for `w = ±z`.

use glam::{DVec3, Vec3};
use std::ops::{Add, Div, Mul, Neg};

/// The float type of a [`Vector`]: what the basis formula needs of it.
pub trait Real:
    Copy + Add<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// 1.
    const ONE: Self;
    /// `self` with the sign of `sign` (`1.0.copysign(-0.0)` is -1).
    fn copysign(self, sign: Self) -> Self;
}

/// A 3-vector of [`Real`]s: glam's `Vec3` and `DVec3`.
pub trait Vector: Copy + Add<Output = Self> + Mul<Self::Real, Output = Self> {
    /// The component type.
    type Real: Real;
    /// The vector `(x, y, z)`.
    fn new(x: Self::Real, y: Self::Real, z: Self::Real) -> Self;
    /// `(x, y, z)`.
    fn xyz(self) -> [Self::Real; 3];
}

macro_rules! impl_vector {
    ($v:ty, $r:ty) => {
        impl Real for $r {
            const ONE: $r = 1.0;
            #[inline]
            fn copysign(self, sign: $r) -> $r {
                <$r>::copysign(self, sign)
            }
        }
        impl Vector for $v {
            type Real = $r;
            #[inline]
            fn new(x: $r, y: $r, z: $r) -> $v {
                <$v>::new(x, y, z)
            }
            #[inline]
            fn xyz(self) -> [$r; 3] {
                self.to_array()
            }
        }
    };
}
impl_vector!(Vec3, f32);
impl_vector!(DVec3, f64);

/// A right-handed orthonormal basis `(u, v, w)` with `w` the given unit vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Onb<V = Vec3> {
    /// First tangent.
    pub u: V,
    /// Second tangent, `w x u`.
    pub v: V,
    /// The unit vector the basis was made about.
    pub w: V,
}

impl<V: Vector> Onb<V> {
    /// Duff et al. 2017, listing 3. `w` must be unit length.
    #[inline]
    pub fn from_w(w: V) -> Onb<V> {
        let [x, y, z] = w.xyz();
        let one = V::Real::ONE;
        let sign = one.copysign(z);
        let a = -one / (sign + z);
        let b = x * y * a;
        let u = V::new(one + sign * x * x * a, sign * b, -sign * x);
        let v = V::new(b, sign + y * y * a, -y);
        Onb { u, v, w }
    }

    /// `local.x * u + local.y * v + local.z * w`.
    #[inline]
    pub fn to_world(&self, local: V) -> V {
        let [x, y, z] = local.xyz();
        self.u * x + self.v * y + self.w * z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    #[test]
    fn onb_is_orthonormal_and_right_handed() {
        let mut rng = SplitMix64::new(1);
        let mut ws: Vec<Vec3> = (0..2000).map(|_| rng.unit_vector()).collect();
        ws.extend([Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z]);
        ws.push(Vec3::new(1.0, 0.0, -0.0));
        for w in ws {
            let b = Onb::from_w(w);
            for (a, name) in [(b.u, "u"), (b.v, "v"), (b.w, "w")] {
                assert!((a.length() - 1.0).abs() < 1e-5, "{name} of {w} not unit");
            }
            assert!(b.u.dot(b.v).abs() < 1e-5, "u.v for {w}");
            assert!(b.u.dot(b.w).abs() < 1e-5, "u.w for {w}");
            assert!(b.v.dot(b.w).abs() < 1e-5, "v.w for {w}");
            assert!((b.u.cross(b.v) - b.w).length() < 1e-5, "handedness for {w}");
            let p = Vec3::new(0.3, -0.2, 0.9);
            let q = b.to_world(p);
            assert!((Vec3::new(q.dot(b.u), q.dot(b.v), q.dot(b.w)) - p).length() < 1e-5);
            // The f64 basis is the same formula: it agrees to f32 rounding.
            let d = Onb::from_w(w.as_dvec3());
            assert!((d.u.as_vec3() - b.u).length() < 1e-6 && (d.v.as_vec3() - b.v).length() < 1e-6);
        }
    }
}
