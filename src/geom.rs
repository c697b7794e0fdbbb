//! geom: primitives as the accelerators see them, flat arrays with one `u32` id per
//! primitive, below both the accelerators and the scene loaders (which fill them).
//!
//! Ids run over triangles first, then spheres, boxes and planes, so a triangle's id is
//! its index in OBJ face order (RAYS.md) and a kd-tree leaf can hold any of the first
//! three kinds. Planes are unbounded and are tested beside the tree, never in it.

use glam::{DVec3, Vec3};

/// An axis-aligned box. An empty box has `min > max` on every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// The corner with the smallest coordinate on every axis (inclusive).
    pub min: Vec3,
    /// The corner with the largest coordinate on every axis (inclusive).
    pub max: Vec3,
}

impl Aabb {
    /// The box that contains nothing; growing it by a point gives that point.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box between two corners, taken as given (`min > max` on an axis makes it
    /// empty).
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Aabb { min, max }
    }

    /// Extends the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box containing both; [`Aabb::EMPTY`] is its identity.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// True when no point is inside: `min > max` on some axis. A single point, or a flat
    /// box of zero width, is not empty.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Side lengths, zero for an empty box (rather than the negative infinities of
    /// [`Aabb::EMPTY`]).
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Length of the diagonal; scales the offsets that keep secondary rays off surfaces.
    pub fn diagonal(&self) -> f32 {
        self.extent().length()
    }

    /// Surface area, the SAH's measure of how likely a ray is to cross the box; zero for
    /// an empty box.
    pub fn surface_area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// True when `p` is inside or on the boundary.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// A sphere, intersected analytically (not tessellated).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre; texture coordinates turn about the +y axis through it.
    pub center: Vec3,
    /// Radius, greater than 0 (scene files reject others).
    pub radius: f32,
}

impl Sphere {
    /// The tight axis-aligned box around the sphere.
    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.center - Vec3::splat(self.radius),
            self.center + Vec3::splat(self.radius),
        )
    }
}

/// The infinite plane of points `p` with `dot(normal, p) == offset`; `normal` is unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal; the side it points to is the front.
    pub normal: Vec3,
    /// Signed distance of the plane from the origin along `normal`.
    pub offset: f32,
}

/// Which array a primitive id points into, with the index inside that array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimRef {
    /// Index into [`Geometry::triangles`].
    Triangle(u32),
    /// Index into [`Geometry::spheres`].
    Sphere(u32),
    /// Index into [`Geometry::boxes`].
    Box(u32),
    /// Index into [`Geometry::planes`].
    Plane(u32),
}

/// All primitives of a scene. Triangles index `vertices`.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// Triangle corners, shared between triangles (OBJ's `v` lines, in order).
    pub vertices: Vec<Vec3>,
    /// Three indices into `vertices` per triangle; a triangle's position here is its id.
    pub triangles: Vec<[u32; 3]>,
    /// Spheres, with ids after the triangles.
    pub spheres: Vec<Sphere>,
    /// Axis-aligned boxes as solid primitives, with ids after the spheres.
    pub boxes: Vec<Aabb>,
    /// Infinite planes, with the last ids; tested beside the tree, never in it.
    pub planes: Vec<Plane>,
}

/// Bounds of the bounded primitives in f64 and their diagonal (planes excluded; all zero
/// when there are none): the scale the ray sets and the default views are made at.
pub fn scene_box(geometry: &Geometry) -> (DVec3, DVec3, f64) {
    let b = geometry.bounds();
    if b.is_empty() {
        return (DVec3::ZERO, DVec3::ZERO, 0.0);
    }
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    (lo, hi, (hi - lo).length())
}

impl Geometry {
    /// Primitives that go into an accelerator's tree: triangles, spheres and boxes.
    pub fn bounded_count(&self) -> u32 {
        (self.triangles.len() + self.spheres.len() + self.boxes.len()) as u32
    }

    /// All primitives, planes included.
    pub fn prim_count(&self) -> u32 {
        self.bounded_count() + self.planes.len() as u32
    }

    /// Splits a primitive id into its kind and index. Ids past the end map to a plane
    /// index past `planes`, which callers never produce.
    #[inline]
    pub fn prim_ref(&self, prim: u32) -> PrimRef {
        let t = self.triangles.len() as u32;
        let s = t + self.spheres.len() as u32;
        let b = s + self.boxes.len() as u32;
        if prim < t {
            PrimRef::Triangle(prim)
        } else if prim < s {
            PrimRef::Sphere(prim - t)
        } else if prim < b {
            PrimRef::Box(prim - s)
        } else {
            PrimRef::Plane(prim - b)
        }
    }

    /// The id of plane `i`.
    pub fn plane_prim(&self, i: u32) -> u32 {
        self.bounded_count() + i
    }

    /// The three corners of triangle `tri`.
    #[inline]
    pub fn triangle(&self, tri: u32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[tri as usize];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Bounds of a bounded primitive (empty for a plane).
    pub fn prim_bounds(&self, prim: u32) -> Aabb {
        match self.prim_ref(prim) {
            PrimRef::Triangle(i) => {
                let mut b = Aabb::EMPTY;
                for p in self.triangle(i) {
                    b.grow(p);
                }
                b
            }
            PrimRef::Sphere(i) => self.spheres[i as usize].bounds(),
            PrimRef::Box(i) => self.boxes[i as usize],
            PrimRef::Plane(_) => Aabb::EMPTY,
        }
    }

    /// Bounds of every bounded primitive (planes excluded).
    pub fn bounds(&self) -> Aabb {
        (0..self.bounded_count()).fold(Aabb::EMPTY, |b, p| b.union(&self.prim_bounds(p)))
    }

    /// Geometric normal at a hit, not yet flipped toward the ray. For triangles this is
    /// `normalize(cross(v1 - v0, v2 - v0))`, the RAYS.md convention.
    pub fn geometric_normal(&self, prim: u32, p: Vec3) -> Vec3 {
        match self.prim_ref(prim) {
            PrimRef::Triangle(i) => {
                let [a, b, c] = self.triangle(i);
                (b - a).cross(c - a).normalize_or_zero()
            }
            PrimRef::Sphere(i) => {
                let s = &self.spheres[i as usize];
                ((p - s.center) / s.radius).normalize_or_zero()
            }
            PrimRef::Box(i) => box_normal(&self.boxes[i as usize], p),
            PrimRef::Plane(i) => self.planes[i as usize].normal,
        }
    }
}

/// The outward normal of the box face nearest to `p`.
fn box_normal(b: &Aabb, p: Vec3) -> Vec3 {
    let c = (b.min + b.max) * 0.5;
    let h = ((b.max - b.min) * 0.5).max(Vec3::splat(f32::MIN_POSITIVE));
    let d = (p - c) / h;
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        Vec3::new(d.x.signum(), 0.0, 0.0)
    } else if a.y >= a.z {
        Vec3::new(0.0, d.y.signum(), 0.0)
    } else {
        Vec3::new(0.0, 0.0, d.z.signum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_ids_run_over_triangles_spheres_boxes_planes() {
        let g = Geometry {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![[0, 1, 2], [0, 2, 1]],
            spheres: vec![Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            }],
            boxes: vec![Aabb::new(Vec3::ZERO, Vec3::ONE)],
            planes: vec![Plane {
                normal: Vec3::Y,
                offset: 0.0,
            }],
        };
        assert_eq!(g.prim_ref(1), PrimRef::Triangle(1));
        assert_eq!(g.prim_ref(2), PrimRef::Sphere(0));
        assert_eq!(g.prim_ref(3), PrimRef::Box(0));
        assert_eq!(g.prim_ref(g.plane_prim(0)), PrimRef::Plane(0));
        assert_eq!(g.bounds(), Aabb::new(Vec3::splat(-1.0), Vec3::ONE));
        assert_eq!(g.geometric_normal(3, Vec3::new(0.5, 1.0, 0.5)), Vec3::Y);
    }
}
