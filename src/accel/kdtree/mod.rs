//! SAH kd-tree: build (Wald & Havran 2006), scalar and packet traversal.
//!
//! Layout: `nodes` is one contiguous array of 8-byte [`node::KdNode`]s, children in
//! pairs; a leaf indexes `leaves`, whose `[first, count]` names a contiguous run of
//! `prim_indices`. Primitive records live in `prims` (the same [`Prims`] the brute-force
//! oracle tests). Planes are not in the tree; traversal tests them beside it.

pub mod node;

use super::Prims;
use crate::scene::Aabb;
use node::KdNode;

pub struct KdTree {
    /// Root is `nodes[0]`.
    pub(crate) nodes: Vec<KdNode>,
    /// `[first, count]` into `prim_indices`, one per leaf.
    pub(crate) leaves: Vec<[u32; 2]>,
    pub(crate) prim_indices: Vec<u32>,
    pub(crate) prims: Prims,
    /// Bounds of the bounded primitives; rays are clipped to it before traversal.
    pub(crate) bounds: Aabb,
}
