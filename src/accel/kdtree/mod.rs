//! SAH kd-tree: build (binned SAH for large nodes, Wald & Havran 2006's sweep below;
//! the sweep alone as the reference), scalar, packet and stream traversal.
//!
//! Layout: `nodes` is one contiguous array of 8-byte [`node::KdNode`]s, children in
//! pairs; a leaf holds its `[first, count]`, a contiguous run of `prim_indices`
//! (the same ranges, in build order, stay in `leaves` for statistics and tests). Primitive records live in `prims` (the same [`Prims`] the brute-force
//! oracle tests), where the build may place the triangles' records in the order the
//! leaves first name them (the indices then name those slots; hits still report ids).
//! Planes are not in the tree; traversal tests them beside it.
//!
//! Three kinds of walk, each written once:
//! - the scalar walk ([`traverse`], the oracle): one ray, `KdTree::step` per node;
//! - the group walk ([`traverse_packet`]): SIMD packets that decide together, one
//!   group for a packet, several sharing one stack for a tile ([`traverse_tile`]);
//! - the lane walk ([`traverse_lanes`]): one ray per SIMD lane, each on its own walk,
//!   for streams ([`traverse_stream`]).
//!
//! All three start from one set-up (`traverse::start`: the plane bands,
//! `traverse::Bands`, and the box clip), written against [`crate::simd::Float`] for
//! one ray or one per lane, and the SIMD walks hand the same rays to the scalar walk: those
//! with a zero direction component, or one so small that a node step may overflow.
//!
//! Invariants, checked by [`KdTree::validate`]: every child pair lies inside `nodes` and
//! has exactly one parent, depth never exceeds [`build::MAX_DEPTH`], the leaves' ranges
//! are exactly those of `leaves`, every leaf range lies inside `prim_indices`, every
//! index names a bounded primitive, and every inner node's empty-child bits say which of
//! its children are empty leaves.

pub mod build;
pub mod node;
pub mod stats;
pub mod traverse;
pub mod traverse_lanes;
pub mod traverse_packet;
pub mod traverse_stream;
pub mod traverse_tile;

use super::Prims;
use crate::geom::Aabb;
pub use build::{BuildParams, BuildStats, BuilderKind};
use node::{AlignedNodes, KdNode};

/// A SAH kd-tree over one scene's bounded primitives, with the planes beside it. Built
/// once ([`KdTree::build`]), then read-only and shared by every tracing thread.
pub struct KdTree {
    /// Root is `nodes[0]`; the array starts on a 64-byte boundary.
    pub(crate) nodes: AlignedNodes,
    /// `[first, count]` into `prim_indices`, one per leaf in build order (the nodes
    /// carry the same ranges).
    pub(crate) leaves: Vec<[u32; 2]>,
    pub(crate) prim_indices: Vec<u32>,
    pub(crate) prims: Prims,
    /// Bounds of the bounded primitives; rays are clipped to it before traversal.
    pub(crate) bounds: Aabb,
    pub(crate) build_stats: BuildStats,
    /// The slots the flat stream queries test, in order: every bounded primitive but
    /// the degenerate triangles no ray hits. Empty unless the tree chose them
    /// ([`KdTree::is_flat`]).
    pub(crate) flat: Vec<u32>,
}

/// Shape and cost figures of a built tree (`raypack info`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeStats {
    /// What the build recorded (time, depth limit, primitives in the tree).
    pub build: BuildStats,
    /// Inner nodes and leaves.
    pub nodes: u32,
    /// Leaves, empty ones included.
    pub leaves: u32,
    /// Leaves without primitives: the empty space the SAH cut off.
    pub empty_leaves: u32,
    /// Depth of the deepest leaf (the root is at depth 0).
    pub max_leaf_depth: u32,
    /// Mean depth over all leaves.
    pub mean_leaf_depth: f64,
    /// Over non-empty leaves.
    pub mean_prims_per_leaf: f64,
    /// Primitive references over primitives in the tree (duplication by straddling).
    pub refs_per_prim: f64,
    /// Expected cost of a random ray under the build's cost model:
    /// `sum K_T SA(inner) / SA(root) + sum K_I n SA(leaf) / SA(root)`.
    pub sah_cost: f64,
    /// Bytes of the node array.
    pub node_bytes: usize,
    /// Bytes of the leaf table.
    pub leaf_bytes: usize,
    /// Bytes of the leaves' primitive index lists.
    pub index_bytes: usize,
    /// Bytes of the TriAccel records.
    pub triaccel_bytes: usize,
    /// The flat stream queries' slot list (none unless the tree chose them).
    pub flat_bytes: usize,
}

impl KdTree {
    /// The node array (root first).
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The `[first, count]` ranges of the leaves.
    pub fn leaves(&self) -> &[[u32; 2]] {
        &self.leaves
    }

    /// The slots of [`KdTree::prims`] the leaves point into ([`Prims::id`] gives each
    /// one's primitive id; a triangle's slot differs from its id where the build placed
    /// the records in leaf order).
    pub fn prim_indices(&self) -> &[u32] {
        &self.prim_indices
    }

    /// The primitive records the leaves' slots refer to.
    pub fn prims(&self) -> &Prims {
        &self.prims
    }

    /// What the build recorded.
    pub fn build_stats(&self) -> &BuildStats {
        &self.build_stats
    }

    /// The primitive ids of the ranged leaf `n`.
    #[inline(always)]
    pub(super) fn leaf_prims(&self, n: &KdNode) -> &[u32] {
        let first = n.leaf_first() as usize;
        &self.prim_indices[first..first + n.leaf_count() as usize]
    }

    /// Walks the tree for its statistics, priced with `params`' costs.
    pub fn stats(&self, params: &BuildParams) -> TreeStats {
        let mut s = TreeStats {
            build: self.build_stats.clone(),
            nodes: self.nodes.len() as u32,
            leaves: self.leaves.len() as u32,
            node_bytes: std::mem::size_of_val(&self.nodes[..]),
            leaf_bytes: std::mem::size_of_val(self.leaves.as_slice()),
            index_bytes: std::mem::size_of_val(self.prim_indices.as_slice()),
            triaccel_bytes: std::mem::size_of_val(self.prims.tris.as_slice()),
            flat_bytes: std::mem::size_of_val(self.flat.as_slice()),
            ..TreeStats::default()
        };
        let root_area = self.bounds.surface_area() as f64;
        let mut depth_sum = 0u64;
        let mut full_leaves = 0u64;
        let mut sah = 0.0f64;
        let mut stack = vec![(0u32, self.bounds, 0u32)];
        while let Some((n, cell, depth)) = stack.pop() {
            let node = &self.nodes[n as usize];
            let area = if root_area > 0.0 {
                cell.surface_area() as f64 / root_area
            } else {
                1.0
            };
            if node.is_leaf() {
                let count = node.leaf_count();
                if count == 0 {
                    s.empty_leaves += 1;
                } else {
                    full_leaves += 1;
                }
                depth_sum += depth as u64;
                s.max_leaf_depth = s.max_leaf_depth.max(depth);
                sah += params.intersection_cost as f64 * count as f64 * area;
            } else {
                sah += params.traversal_cost as f64 * area;
                let (a, c) = (node.axis(), node.children());
                let (mut left, mut right) = (cell, cell);
                left.max[a] = node.split;
                right.min[a] = node.split;
                stack.push((c, left, depth + 1));
                stack.push((c + 1, right, depth + 1));
            }
        }
        s.mean_leaf_depth = depth_sum as f64 / s.leaves.max(1) as f64;
        s.mean_prims_per_leaf = self.prim_indices.len() as f64 / full_leaves.max(1) as f64;
        s.refs_per_prim =
            self.prim_indices.len() as f64 / self.build_stats.tree_prims.max(1) as f64;
        s.sah_cost = sah;
        s
    }

    /// Checks the structural invariants that traversal relies on (see the module doc).
    pub fn validate(&self) -> Result<(), String> {
        let n = self.nodes.len();
        if n.is_multiple_of(2) {
            return Err(format!("{n} nodes: expected the root plus pairs"));
        }
        let mut parents = vec![0u32; n];
        let mut ranges = Vec::with_capacity(self.leaves.len());
        let mut stack = vec![(0u32, 0u32)];
        while let Some((i, depth)) = stack.pop() {
            if depth > build::MAX_DEPTH {
                return Err(format!("node {i} at depth {depth} > {}", build::MAX_DEPTH));
            }
            let node = &self.nodes[i as usize];
            if node.is_leaf() {
                let (first, count) = (node.leaf_first(), node.leaf_count());
                ranges.push([first, count]);
                let end = first as usize + count as usize;
                if end > self.prim_indices.len() {
                    return Err(format!("leaf node {i}: range {first}+{count} out of range"));
                }
                if let Some(p) = self.prim_indices[first as usize..end]
                    .iter()
                    .find(|&&p| p >= self.prims.plane_base)
                {
                    return Err(format!("leaf node {i}: {p} is not a bounded primitive"));
                }
            } else {
                let c = node.children() as usize;
                if c == 0 || c.is_multiple_of(2) || c + 1 >= n {
                    return Err(format!("node {i}: bad child pair {c}"));
                }
                let flags = node::empty_flags(&self.nodes, c);
                if node.empty_children() != flags {
                    return Err(format!(
                        "node {i}: empty-child bits {} for children {flags}",
                        node.empty_children()
                    ));
                }
                if !node.split.is_finite() {
                    return Err(format!("node {i}: split {}", node.split));
                }
                for child in [c, c + 1] {
                    parents[child] += 1;
                    if parents[child] > 1 {
                        return Err(format!("node {child} has two parents"));
                    }
                    stack.push((child as u32, depth + 1));
                }
            }
        }
        if let Some(i) = (1..n).find(|&i| parents[i] != 1) {
            return Err(format!("node {i} is unreachable"));
        }
        let mut table = self.leaves.clone();
        ranges.sort_unstable();
        table.sort_unstable();
        if ranges != table {
            return Err("leaf ranges differ from the leaf table".to_string());
        }
        Ok(())
    }
}
