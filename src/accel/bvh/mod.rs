//! An 8-wide BVH: each step of a single ray tests it against eight child boxes in one
//! SIMD register (Embree's BVH8, Wald et al. 2008; Áfra et al. 2016), each step of a
//! coherent packet one child box against all its rays ([`traverse_packet`]); and a box
//! ends at its primitives, so a ray that misses an isolated model or leaves it stops
//! after a few steps where a kd-tree walks every empty cell on its way.
//!
//! Layout: `nodes` holds [`Node8`]s, root first; a child word is an inner node's index,
//! a leaf (`LEAF_BIT`, count - 1 in bits 27-29, first reference below) or `EMPTY`.
//! A leaf names `slots[first..first + count]`, slots of `prims` (the same [`Prims`] the
//! kd-tree and the brute-force oracle test, the triangles' records placed in leaf
//! order, so in a scene of triangles only a leaf's slots are `first..first + count`
//! themselves: the single walk reads its records without the list, one dependent load
//! fewer per leaf). The leaves' triangles are tested in lanes by the kd-tree's own leaf
//! kernel ([`Prims::intersect_tris_lanes`]), so hits are the brute-force ones bit for
//! bit; the box test only has to be conservative ([`traverse`]).

mod build;
pub mod traverse;
pub mod traverse_packet;

use super::{Accel, HitPacket, Prims, RayPacket};
use crate::geom::Aabb;
use crate::ray::{Hit, Ray};
use crate::simd::{LaneBits, W4, W8, W16};

/// Most primitives in a leaf: one lane test of eight.
pub const MAX_LEAF: usize = 8;

/// Marks a leaf's child word.
pub(crate) const LEAF_BIT: u32 = 1 << 31;

/// The child word of an unused slot (its box is empty and never hit).
pub(crate) const EMPTY: u32 = u32::MAX;

/// Eight children's boxes, one array of eight per plane (min x, max x, min y, max y,
/// min z, max z: a ray loads its near and far plane of each axis as one vector), and
/// their child words.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node8 {
    /// `planes[2 * axis]` the minima, `planes[2 * axis + 1]` the maxima.
    pub planes: [[f32; 8]; 6],
    /// Child words (see the module docs).
    pub child: [u32; 8],
}

impl Node8 {
    /// No children: every box empty (min +inf, max -inf), so every test fails.
    pub const EMPTY: Node8 = Node8 {
        planes: [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ],
        child: [EMPTY; 8],
    };

    fn set_child(&mut self, slot: usize, b: &Aabb, word: u32) {
        for axis in 0..3 {
            self.planes[2 * axis][slot] = b.min[axis];
            self.planes[2 * axis + 1][slot] = b.max[axis];
        }
        self.child[slot] = word;
    }

    /// The box of child `slot`, as the build wrote it (empty for an unused
    /// slot).
    pub fn child_box(&self, slot: usize) -> Aabb {
        let p = &self.planes;
        Aabb {
            min: glam::Vec3::new(p[0][slot], p[2][slot], p[4][slot]),
            max: glam::Vec3::new(p[1][slot], p[3][slot], p[5][slot]),
        }
    }
}

/// Shape and cost figures of a built BVH (`raypack bench --accel bvh8`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// 8-wide inner nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Used child slots over all slots of the inner nodes.
    pub fill: f64,
    /// Mean primitives per leaf.
    pub mean_leaf: f64,
    /// Depth of the deepest leaf (children of the root at depth 1).
    pub depth: u32,
    /// Expected inner-node steps of a ray through the root's box: the inner nodes'
    /// areas over the root's (the surface area heuristic).
    pub sah_nodes: f64,
    /// Expected leaf tests of such a ray: the leaves' areas over the root's.
    pub sah_leaves: f64,
}

/// An 8-wide BVH over one scene's bounded primitives, the planes tested beside it.
pub struct Bvh {
    pub(crate) nodes: Vec<Node8>,
    pub(crate) slots: Vec<u32>,
    pub(crate) prims: Prims,
    bounds: Aabb,
    /// The largest absolute coordinate of `bounds`: the walks' margin grows with it.
    pub(crate) coord_max: f32,
    build_seconds: f64,
}

impl Bvh {
    /// The BVH of `g`, built on the current rayon pool.
    pub fn build(g: &crate::geom::Geometry) -> Bvh {
        Bvh::build_with(g, true)
    }

    /// The nodes, root first.
    pub fn nodes(&self) -> &[Node8] {
        &self.nodes
    }

    /// Wall time of the build.
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Bytes of the nodes, the leaves' slot lists and the TriAccel records.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.slots.as_slice())
            + std::mem::size_of_val(self.prims.tris.as_slice())
    }

    /// Walks the tree for its [`BvhStats`].
    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats {
            nodes: self.nodes.len(),
            ..BvhStats::default()
        };
        if self.nodes.is_empty() {
            return s;
        }
        let area = |b: &Aabb| b.surface_area() as f64;
        let root = area(&self.bounds).max(f64::MIN_POSITIVE);
        let (mut used, mut prims) = (0usize, 0usize);
        let mut todo = vec![(0u32, 1u32, self.bounds)];
        while let Some((w, depth, b)) = todo.pop() {
            if w & LEAF_BIT != 0 {
                s.leaves += 1;
                prims += self.leaf(w).len();
                s.depth = s.depth.max(depth);
                s.sah_leaves += area(&b) / root;
                continue;
            }
            s.sah_nodes += area(&b) / root;
            let node = &self.nodes[w as usize];
            for (slot, &c) in node.child.iter().enumerate() {
                if c != EMPTY {
                    used += 1;
                    todo.push((c, depth + 1, node.child_box(slot)));
                }
            }
        }
        s.fill = used as f64 / (8 * s.nodes) as f64;
        s.mean_leaf = prims as f64 / s.leaves.max(1) as f64;
        s
    }

    /// The first slot and the count of leaf word `w`.
    #[inline(always)]
    pub(crate) fn leaf_run(w: u32) -> (usize, usize) {
        ((w & ((1 << 27) - 1)) as usize, ((w >> 27) & 7) as usize + 1)
    }

    /// The slots of leaf word `w`.
    #[inline(always)]
    pub(crate) fn leaf(&self, w: u32) -> &[u32] {
        let (first, count) = Bvh::leaf_run(w);
        &self.slots[first..first + count]
    }
}

impl Accel for Bvh {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut hit = [Hit::MISS];
        self.intersect_stream(std::slice::from_ref(ray), &mut hit);
        hit[0].is_hit().then_some(hit[0])
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let mut o = [false];
        self.occluded_stream(std::slice::from_ref(ray), &mut o);
        o[0]
    }

    fn intersect_packet4(&self, rays: &RayPacket<W4>) -> HitPacket<W4> {
        self.intersect_packet(rays)
    }

    fn intersect_packet8(&self, rays: &RayPacket<W8>) -> HitPacket<W8> {
        self.intersect_packet(rays)
    }

    fn intersect_packet16(&self, rays: &RayPacket<W16>) -> HitPacket<W16> {
        self.intersect_packet(rays)
    }

    fn occluded_packet4(&self, rays: &RayPacket<W4>) -> LaneBits {
        self.occluded_packet(rays)
    }

    fn occluded_packet8(&self, rays: &RayPacket<W8>) -> LaneBits {
        self.occluded_packet(rays)
    }

    fn occluded_packet16(&self, rays: &RayPacket<W16>) -> LaneBits {
        self.occluded_packet(rays)
    }

    fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "intersect_stream: one hit per ray");
        crate::simd::dispatch!(8; self.intersect_rays::<@>(rays, hits))
    }

    fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_stream: one answer per ray"
        );
        crate::simd::dispatch!(8; self.occluded_rays::<@>(rays, occluded))
    }
}
