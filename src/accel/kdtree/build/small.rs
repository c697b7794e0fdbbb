//! The fast builder's small nodes: the exact SAH without events.
//!
//! Most of a tree's nodes are tiny (Sponza: 0.8M of its 1.05M nodes hold fewer than 16
//! references). Below [`SMALL`] references a node keeps its references' bounds in
//! fixed arrays, one per axis and side (padding NaN, which compares false), and prices
//! each candidate plane, every reference's minimum and maximum strictly inside the
//! cell, by counting the references left of it, right of it and lying in it: the
//! counts the sweep has at that plane, priced with the same [`PlaneCost`], in loops over
//! fixed-size chunks that compile to vector compares. The cheapest plane wins, ties
//! going to the lower axis, then the lower position, as in the sweep, so a small node
//! splits exactly as the sweep would split it, without sorted lists to keep. The work
//! grows as n^2 per node: past about 12 references the sweep is cheaper (perf/kdtree.md,
//! "Fast build"). A straddling triangle is cut by the split plane alone and its sides
//! met with its bounds in the cell ([`Builder::split_within`]): a little looser than
//! clipping it to the cell first, and cheaper.

use super::{Builder, Out, PlaneCost, child_cells};
use crate::scene::Aabb;

/// Most references a small node holds.
pub(super) const SMALL: usize = 12;

/// Lanes of one counting chunk.
const CHUNK: usize = 4;

/// A small node's references: bounds per axis in fixed arrays, NaN past `len`.
#[derive(Clone, Copy)]
pub(super) struct SmallNode {
    min: [[f32; SMALL]; 3],
    max: [[f32; SMALL]; 3],
    prim: [u32; SMALL],
    len: usize,
}

impl SmallNode {
    pub(super) fn new() -> SmallNode {
        SmallNode {
            min: [[f32::NAN; SMALL]; 3],
            max: [[f32::NAN; SMALL]; 3],
            prim: [0; SMALL],
            len: 0,
        }
    }

    /// Appends a reference.
    #[inline]
    pub(super) fn push(&mut self, bounds: &Aabb, prim: u32) {
        let i = self.len;
        for axis in 0..3 {
            self.min[axis][i] = bounds.min[axis];
            self.max[axis][i] = bounds.max[axis];
        }
        self.prim[i] = prim;
        self.len += 1;
    }

    /// Sets one coordinate of the reference in `slot` (the sweep's events, one by one).
    #[inline]
    pub(super) fn set(&mut self, slot: usize, axis: usize, min: Option<f32>, max: Option<f32>) {
        if let Some(x) = min {
            self.min[axis][slot] = x;
        }
        if let Some(x) = max {
            self.max[axis][slot] = x;
        }
    }

    /// Starts a reference of `prim` whose coordinates [`SmallNode::set`] fills in.
    #[inline]
    pub(super) fn open(&mut self, prim: u32) -> usize {
        let i = self.len;
        self.prim[i] = prim;
        self.len += 1;
        i
    }

    fn bounds(&self, i: usize) -> Aabb {
        let mut b = Aabb::EMPTY;
        for axis in 0..3 {
            b.min[axis] = self.min[axis][i];
            b.max[axis] = self.max[axis][i];
        }
        b
    }

    /// On `axis`, the references that start left of `p`, end right of it, and lie in it.
    #[inline]
    fn counts(&self, axis: usize, p: f32) -> [u32; 3] {
        let chunks = self.len.div_ceil(CHUNK);
        let (min, max) = (&self.min[axis], &self.max[axis]);
        let mut left = [0u32; CHUNK];
        let mut right = [0u32; CHUNK];
        let mut planar = [0u32; CHUNK];
        for c in 0..chunks {
            let lo: &[f32; CHUNK] = min[c * CHUNK..][..CHUNK].try_into().expect("chunk");
            let hi: &[f32; CHUNK] = max[c * CHUNK..][..CHUNK].try_into().expect("chunk");
            for l in 0..CHUNK {
                left[l] += (lo[l] < p) as u32;
                right[l] += (hi[l] > p) as u32;
                planar[l] += (lo[l] == p && hi[l] == p) as u32;
            }
        }
        [left, right, planar].map(|a| a.iter().sum())
    }
}

/// The chosen plane of a small node.
struct Plane {
    axis: usize,
    pos: f32,
    planar_left: bool,
}

impl Builder<'_> {
    /// Builds the subtree of the small node `node` at `depth` in `cell`, its root at
    /// `slot`.
    pub(super) fn build_small(
        &self,
        cell: Aabb,
        node: &SmallNode,
        depth: u32,
        slot: usize,
        out: &mut Out,
    ) {
        let plane = if node.len == 0 || depth >= self.max_depth {
            None
        } else {
            self.small_plane(&cell, node)
        };
        let Some(Plane {
            axis,
            pos,
            planar_left,
        }) = plane
        else {
            out.leaf(slot, node.prim[..node.len].iter().copied());
            return;
        };
        let mut kids = [SmallNode::new(), SmallNode::new()];
        for i in 0..node.len {
            let (lo, hi) = (node.min[axis][i], node.max[axis][i]);
            let prim = node.prim[i];
            let to = if lo == hi {
                if lo < pos || (lo == pos && planar_left) {
                    0
                } else {
                    1
                }
            } else if hi <= pos {
                0
            } else if lo >= pos {
                1
            } else {
                let parts = self.split_within(prim, &node.bounds(i), &cell, axis, pos);
                for (kid, part) in kids.iter_mut().zip(parts) {
                    if let Some(b) = part {
                        kid.push(&b, prim);
                    }
                }
                continue;
            };
            kids[to].push(&node.bounds(i), prim);
        }
        let (left_cell, right_cell) = child_cells(&cell, axis, pos);
        let first = out.inner(slot, axis, pos);
        self.build_small(left_cell, &kids[0], depth + 1, first, out);
        self.build_small(right_cell, &kids[1], depth + 1, first + 1, out);
    }

    /// The cheapest plane of a small node if it beats a leaf (see the module doc).
    fn small_plane(&self, cell: &Aabb, node: &SmallNode) -> Option<Plane> {
        let mut best = None;
        let mut best_cost = self.params.intersection_cost * node.len as f32;
        let mut best_pos = f32::INFINITY;
        for axis in 0..3 {
            let pricing = PlaneCost::new(cell, axis, self.params)?;
            let (lo, hi) = (pricing.lo, pricing.hi);
            let candidates = node.min[axis][..node.len]
                .iter()
                .chain(&node.max[axis][..node.len]);
            let mut axis_best = false;
            for &c in candidates {
                let p = c + 0.0;
                if !(p > lo && p < hi) {
                    continue;
                }
                let [n_left, n_right, planars] = node.counts(axis, p);
                let prob = pricing.probabilities(p);
                let with_left = pricing.cost(prob, n_left + planars, n_right);
                let with_right = pricing.cost(prob, n_left, n_right + planars);
                let planar_left = with_left < with_right;
                let cost = if planar_left { with_left } else { with_right };
                if cost < best_cost || (cost == best_cost && axis_best && p < best_pos) {
                    best_cost = cost;
                    best_pos = p;
                    axis_best = true;
                    best = Some(Plane {
                        axis,
                        pos: p,
                        planar_left,
                    });
                }
            }
        }
        best
    }
}
