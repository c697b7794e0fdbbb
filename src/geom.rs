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

/// Why vertex and index arrays handed to [`Geometry::from_arrays`] make no mesh; each
/// names the first bad entry.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// No triangles, or no vertices.
    #[error("the mesh is empty: {vertices} vertices, {triangles} triangles")]
    Empty {
        /// How many vertices were given.
        vertices: usize,
        /// How many triangles were given.
        triangles: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex}: {axis} is {value}, not a finite number")]
    NotFinite {
        /// The vertex's index.
        vertex: usize,
        /// `x`, `y` or `z`.
        axis: char,
        /// The value found.
        value: f32,
    },
    /// A triangle names a vertex that is not there.
    #[error("triangle {triangle}: corner {corner} is vertex {index}, outside 0..{vertices}")]
    BadIndex {
        /// The triangle's index.
        triangle: usize,
        /// 0, 1 or 2.
        corner: usize,
        /// The index found (negative ones included).
        index: i128,
        /// How many vertices there are.
        vertices: usize,
    },
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
    /// A triangle mesh from flat arrays, as a program that made its own mesh holds them:
    /// `vertices[i]` is vertex `i`, `triangles[j]` the three vertex indices of triangle
    /// `j` (its primitive id). Every coordinate must be finite and every index in range;
    /// the error names the first that is not.
    pub fn from_arrays<I>(
        vertices: &[[f32; 3]],
        triangles: &[[I; 3]],
    ) -> Result<Geometry, MeshError>
    where
        I: Copy + Into<i128>,
    {
        if vertices.is_empty() || triangles.is_empty() {
            return Err(MeshError::Empty {
                vertices: vertices.len(),
                triangles: triangles.len(),
            });
        }
        for (vertex, v) in vertices.iter().enumerate() {
            if let Some(k) = (0..3).find(|&k| !v[k].is_finite()) {
                return Err(MeshError::NotFinite {
                    vertex,
                    axis: ['x', 'y', 'z'][k],
                    value: v[k],
                });
            }
        }
        // Indices past u32 cannot be stored: the vertex count bounds them first.
        let n = vertices.len().min(u32::MAX as usize);
        let mut tris = Vec::with_capacity(triangles.len());
        for (triangle, t) in triangles.iter().enumerate() {
            let mut corners = [0u32; 3];
            for corner in 0..3 {
                let index: i128 = t[corner].into();
                if !(0..n as i128).contains(&index) {
                    return Err(MeshError::BadIndex {
                        triangle,
                        corner,
                        index,
                        vertices: vertices.len(),
                    });
                }
                corners[corner] = index as u32;
            }
            tris.push(corners);
        }
        Ok(Geometry {
            vertices: vertices.iter().map(|&v| Vec3::from_array(v)).collect(),
            triangles: tris,
            ..Geometry::default()
        })
    }

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

    /// Each triangle's unit normal, [`Geometry::geometric_normal`]'s bit for bit,
    /// computed on the current rayon pool: a table where a hit's normal costs one read
    /// instead of an index and three vertex loads.
    pub fn triangle_normals(&self) -> Vec<Vec3> {
        use rayon::prelude::*;
        (0..self.triangles.len() as u32)
            .into_par_iter()
            .map(|t| self.geometric_normal(t, Vec3::ZERO))
            .collect()
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

    #[test]
    fn meshes_from_arrays_are_checked_entry_by_entry() {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let g = Geometry::from_arrays(&v, &[[0i64, 1, 2]]).unwrap();
        assert_eq!(g.triangle(0), [Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(g.prim_count(), 1);
        let empty: [[i64; 3]; 0] = [];
        assert!(matches!(
            Geometry::from_arrays(&v, &empty),
            Err(MeshError::Empty {
                vertices: 3,
                triangles: 0
            })
        ));
        let mut nan = v;
        nan[2][1] = f32::NAN;
        let e = Geometry::from_arrays(&nan, &[[0u32, 1, 2]]).unwrap_err();
        assert_eq!(e.to_string(), "vertex 2: y is NaN, not a finite number");
        for (bad, index) in [([0i64, -1, 2], -1i128), ([0, 1, 3], 3)] {
            let e = Geometry::from_arrays(&v, &[[0, 1, 2], bad]).unwrap_err();
            assert_eq!(
                e,
                MeshError::BadIndex {
                    triangle: 1,
                    corner: if index < 0 { 1 } else { 2 },
                    index,
                    vertices: 3
                }
            );
        }
    }
}
