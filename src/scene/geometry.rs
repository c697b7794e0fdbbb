//! Primitives as the accelerators see them: flat arrays, one `u32` id per primitive.
//!
//! Ids run over triangles first, then spheres, boxes and planes, so a triangle's id is
//! its index in OBJ face order (RAYS.md) and a kd-tree leaf can hold any of the first
//! three kinds. Planes are unbounded and are tested beside the tree, never in it.

use glam::Vec3;

/// An axis-aligned box. An empty box has `min > max` on every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The box that contains nothing; growing it by a point gives that point.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Aabb { min, max }
    }

    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

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

    pub fn surface_area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

impl Sphere {
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
    pub normal: Vec3,
    pub offset: f32,
}

/// Which array a primitive id points into, with the index inside that array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimRef {
    Triangle(u32),
    Sphere(u32),
    Box(u32),
    Plane(u32),
}

/// All primitives of a scene. Triangles index `vertices`.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub spheres: Vec<Sphere>,
    pub boxes: Vec<Aabb>,
    pub planes: Vec<Plane>,
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
