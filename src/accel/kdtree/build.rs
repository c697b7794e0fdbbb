//! Stage: accel. The SAH kd-tree builder of Wald & Havran, "On building fast kd-trees for
//! ray tracing, and on doing that in O(N log N)" (2006).
//!
//! - Events: every primitive gives, per axis, a start and an end event at the bounds of
//!   its part inside the node (or one planar event when that part is flat). Each event is
//!   one `u64` whose integer order is the sweep order: position, then end < planar <
//!   start, then primitive id. The events are sorted once, at the root.
//! - A node sweeps its three sorted lists once to price every candidate plane with the
//!   surface area heuristic (planar primitives go to the cheaper side), classifies its
//!   primitives left, right or both in one pass over the split axis's events, and splits
//!   its lists by filtering; only the straddling primitives get new events, which are
//!   sorted (few) and merged in during the filtering.
//! - Memory: the children's lists go into per-depth buffers that only grow (a node at
//!   depth d writes into `levels[d]`, which stay put while the left subtree is built
//!   below them), and the per-node scratch is per thread, so a node allocates nothing
//!   once the buffers have their size.
//! - Perfect splits: a straddling triangle is clipped (Sutherland-Hodgman) to the node's
//!   cell, only by the faces that cut its bounds, and that polygon is cut by the split
//!   plane for each child, so its events are the bounds of its part inside the child;
//!   when clipping leaves nothing, Akenine-Moller's separating-axis test decides. Spheres
//!   use the squared-distance test, boxes their intersection with the child. Clipped
//!   bounds are widened by a few ulps where clipping rounded, so a primitive is never
//!   left out of a cell it touches.
//! - Degenerate triangles (which no ray can hit) and non-finite primitives are left out;
//!   ids never change. Planes are never in the tree.
//! - Nodes are laid out depth first: a node's two children are allocated as a pair, then
//!   the left subtree, then the right. Large subtrees are built in parallel with rayon;
//!   the right subtree then goes into its own buffers that are appended, relocated, after
//!   the left one, so the parallel tree is the serial tree, node for node.

use super::KdTree;
use super::node::{KdNode, MAX_INDEX};
use crate::accel::Prims;
use crate::scene::{Aabb, Geometry, PrimRef};
use glam::Vec3;
use std::time::Instant;

/// The cost model and limits of the build.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildParams {
    /// Cost of one traversal step (`K_T` in Wald & Havran, who use 15 with `K_I` = 20).
    /// The default is 30: on the benchmark scenes it halves the nodes and cuts the build
    /// by a quarter, and the packet path traces primary rays 5-9% faster in the smaller
    /// tree while the scalar path loses about as much (perf/kdtree.md, "Cost constants").
    pub traversal_cost: f32,
    /// Cost of one primitive test (`K_I`).
    pub intersection_cost: f32,
    /// Fraction of the cost forgiven when a split cuts off empty space (1 - lambda).
    pub empty_bonus: f32,
    /// Depth limit; `None` gives `8 + 1.3 log2(N)`.
    pub max_depth: Option<u32>,
    /// Build subtrees in parallel on the current rayon pool.
    pub parallel: bool,
    /// A node with at least this many primitives builds its two children in parallel.
    pub parallel_min_prims: u32,
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            traversal_cost: 30.0,
            intersection_cost: 20.0,
            empty_bonus: 0.2,
            max_depth: None,
            parallel: true,
            parallel_min_prims: 4096,
        }
    }
}

/// The depth limit can never exceed this, so traversal stacks have a fixed size.
pub const MAX_DEPTH: u32 = 60;

/// The default depth limit for `prim_count` primitives: `8 + 1.3 log2(N)`.
pub fn default_max_depth(prim_count: u32) -> u32 {
    let d = 8.0 + 1.3 * (prim_count.max(1) as f32).log2();
    (d.round() as u32).min(MAX_DEPTH)
}

const END: u64 = 0;
const PLANAR: u64 = 1;
const START: u64 = 2;

/// Maps a float to a `u32` with the same order (negative values flipped).
#[inline]
fn order_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 { !b } else { b | 1 << 31 }
}

#[inline]
fn from_order_bits(o: u32) -> f32 {
    f32::from_bits(if o >> 31 == 1 { o & !(1 << 31) } else { !o })
}

/// An event key. `pos + 0.0` turns -0.0 into +0.0 so both zeros are one position.
#[inline]
fn event(pos: f32, kind: u64, prim: u32) -> u64 {
    ((order_bits(pos + 0.0) as u64) << 32) | (kind << 30) | prim as u64
}

#[cfg(test)]
fn event_pos(e: u64) -> f32 {
    from_order_bits((e >> 32) as u32)
}

#[inline]
fn event_kind(e: u64) -> u64 {
    (e >> 30) & 3
}

#[inline]
fn event_prim(e: u64) -> u32 {
    e as u32 & MAX_INDEX
}

/// Appends the events of a primitive whose part in the node has bounds `b`.
fn push_events(events: &mut [Vec<u64>; 3], b: &Aabb, prim: u32) {
    for (axis, list) in events.iter_mut().enumerate() {
        let (lo, hi) = (b.min[axis], b.max[axis]);
        if lo == hi {
            list.push(event(lo, PLANAR, prim));
        } else {
            list.push(event(lo, START, prim));
            list.push(event(hi, END, prim));
        }
    }
}

/// A node waiting to be built: its cell and its three sorted event lists.
#[derive(Clone, Copy)]
struct Task<'e> {
    cell: Aabb,
    events: [&'e [u64]; 3],
    prim_count: u32,
    depth: u32,
}

/// The chosen plane.
#[derive(Clone, Copy, Debug)]
struct Split {
    axis: usize,
    pos: f32,
    /// Primitives lying in the plane go left (else right).
    planar_left: bool,
    cost: f32,
}

/// Where a primitive goes, in the per-node scratch array.
const LEFT: u8 = 1;
const RIGHT: u8 = 2;
const BOTH: u8 = 3;

/// Three event lists in buffers that only grow, so that once they have reached their
/// size a node's lists cost no allocation; `lens` is the part in use.
#[derive(Default)]
struct Lists {
    bufs: [Vec<u64>; 3],
    lens: [usize; 3],
}

impl Lists {
    fn get(&self) -> [&[u64]; 3] {
        [0, 1, 2].map(|axis| &self.bufs[axis][..self.lens[axis]])
    }

    /// `n` writable events on `axis` (the caller sets `lens[axis]`).
    fn room(&mut self, axis: usize, n: usize) -> &mut [u64] {
        let buf = &mut self.bufs[axis];
        if buf.len() < n {
            buf.resize(n, 0);
        }
        &mut buf[..n]
    }
}

/// One thread's working memory, reused by every node it splits.
struct Scratch {
    /// Where each primitive of the node being split goes, indexed by primitive id.
    side: Vec<u8>,
    /// The node's straddling primitives.
    straddlers: Vec<u32>,
    /// The straddlers' clipped events: left child, right child; per axis.
    fresh: [[Vec<u64>; 3]; 2],
}

/// The children's event lists, one pair per depth: a node at depth `d` writes its
/// children's lists into `levels[d]` (relative to the subtree's root), which stay put
/// while the left subtree is built below them.
type Levels = Vec<[Lists; 2]>;

fn new_levels() -> Levels {
    (0..=MAX_DEPTH).map(|_| Default::default()).collect()
}

/// The arrays being written, in depth-first order.
#[derive(Default)]
struct Out {
    nodes: Vec<KdNode>,
    leaves: Vec<[u32; 2]>,
    prim_indices: Vec<u32>,
}

impl Out {
    /// Appends `sub`, a subtree built into its own buffers with its root at `sub.nodes[0]`,
    /// putting its root into `slot`.
    fn append(&mut self, sub: Out, slot: usize) {
        let node_base = self.nodes.len() as u32 - 1;
        let leaf_base = self.leaves.len() as u32;
        let index_base = self.prim_indices.len() as u32;
        self.nodes[slot] = relocate(&sub.nodes[0], node_base, leaf_base);
        self.nodes.extend(
            sub.nodes[1..]
                .iter()
                .map(|n| relocate(n, node_base, leaf_base)),
        );
        self.leaves.extend(
            sub.leaves
                .iter()
                .map(|&[first, count]| [first + index_base, count]),
        );
        self.prim_indices.extend_from_slice(&sub.prim_indices);
    }
}

/// `n` moved from its own buffers to ones where its child pairs start `node_base` and
/// its leaves `leaf_base` later.
fn relocate(n: &KdNode, node_base: u32, leaf_base: u32) -> KdNode {
    if n.is_leaf() {
        KdNode::leaf(n.leaf_index() + leaf_base)
    } else {
        KdNode::inner(n.axis() as u32, n.split, n.children() + node_base)
    }
}

/// What the build reads, shared by all subtrees.
struct Builder<'a> {
    g: &'a Geometry,
    params: &'a BuildParams,
    max_depth: u32,
    /// Size of the classification scratch (one byte per bounded primitive).
    prim_total: usize,
}

/// Figures about one build, for `raypack info` and perf/.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildStats {
    pub build_seconds: f64,
    /// Primitives put in the tree (degenerate triangles are left out).
    pub tree_prims: u32,
    pub max_depth_limit: u32,
}

/// Bounds of a bounded primitive, or `None` when it must stay out of the tree: a triangle
/// no ray can hit (zero area) or anything with non-finite coordinates.
fn tree_bounds(g: &Geometry, prims: &Prims, prim: u32) -> Option<Aabb> {
    if let PrimRef::Triangle(t) = g.prim_ref(prim) {
        let acc = &prims.tris[t as usize];
        if acc.b_nu == 0.0 && acc.b_nv == 0.0 && acc.c_nu == 0.0 && acc.c_nv == 0.0 {
            return None;
        }
    }
    let b = g.prim_bounds(prim);
    (b.min.is_finite() && b.max.is_finite() && !b.is_empty()).then_some(b)
}

/// The cells on either side of the plane `pos` on `axis`.
fn child_cells(cell: &Aabb, axis: usize, pos: f32) -> (Aabb, Aabb) {
    let (mut left, mut right) = (*cell, *cell);
    left.max[axis] = pos;
    right.min[axis] = pos;
    (left, right)
}

impl KdTree {
    /// Builds the tree with [`BuildParams::default`].
    pub fn build(g: &Geometry) -> KdTree {
        KdTree::build_with(g, &BuildParams::default())
    }

    /// Builds the tree of `g`'s bounded primitives.
    pub fn build_with(g: &Geometry, params: &BuildParams) -> KdTree {
        let start = Instant::now();
        let prims = Prims::new(g);
        let bounded = g.bounded_count();
        assert!(bounded <= MAX_INDEX, "kd-tree: more than 2^30 primitives");
        let mut cell = Aabb::EMPTY;
        let mut events: [Vec<u64>; 3] = Default::default();
        for list in &mut events {
            list.reserve(2 * bounded as usize);
        }
        let mut prim_count = 0;
        for prim in 0..bounded {
            if let Some(b) = tree_bounds(g, &prims, prim) {
                cell = cell.union(&b);
                push_events(&mut events, &b, prim);
                prim_count += 1;
            }
        }
        if params.parallel {
            use rayon::prelude::*;
            events.par_iter_mut().for_each(|l| l.sort_unstable());
        } else {
            events.iter_mut().for_each(|l| l.sort_unstable());
        }
        let max_depth = params
            .max_depth
            .unwrap_or_else(|| default_max_depth(prim_count))
            .min(MAX_DEPTH);
        let builder = Builder {
            g,
            params,
            max_depth,
            prim_total: bounded as usize,
        };
        let mut out = Out::default();
        out.nodes.push(KdNode::leaf(0));
        let task = Task {
            cell,
            events: [&events[0], &events[1], &events[2]],
            prim_count,
            depth: 0,
        };
        builder.build_node(task, 0, &mut out, &mut builder.scratch(), &mut new_levels());
        let stats = BuildStats {
            build_seconds: start.elapsed().as_secs_f64(),
            tree_prims: prim_count,
            max_depth_limit: max_depth,
        };
        KdTree {
            nodes: super::node::with_leaf_ranges(out.nodes, &out.leaves).into(),
            leaves: out.leaves,
            prim_indices: out.prim_indices,
            prims,
            bounds: cell,
            build_stats: stats,
        }
    }
}

impl Builder<'_> {
    fn scratch(&self) -> Scratch {
        Scratch {
            side: vec![0; self.prim_total],
            straddlers: Vec::new(),
            fresh: Default::default(),
        }
    }

    /// Builds the subtree of `task` into `out`, its root at `slot`; `levels[0]` takes the
    /// children's lists.
    fn build_node(
        &self,
        task: Task<'_>,
        slot: usize,
        out: &mut Out,
        scratch: &mut Scratch,
        levels: &mut [[Lists; 2]],
    ) {
        let split = if task.prim_count == 0 || task.depth >= self.max_depth {
            None
        } else {
            self.find_split(&task)
        };
        let leaf_cost = self.params.intersection_cost * task.prim_count as f32;
        let Some(split) = split.filter(|s| s.cost < leaf_cost) else {
            self.make_leaf(&task, slot, out);
            return;
        };
        let (here, deeper) = levels
            .split_first_mut()
            .expect("a level for every depth below the limit");
        let (n_left, n_right) = self.split_task(&task, &split, scratch, here);
        let (left_cell, right_cell) = child_cells(&task.cell, split.axis, split.pos);
        let [left_lists, right_lists] = &*here;
        let left = Task {
            cell: left_cell,
            events: left_lists.get(),
            prim_count: n_left,
            depth: task.depth + 1,
        };
        let right = Task {
            cell: right_cell,
            events: right_lists.get(),
            prim_count: n_right,
            depth: task.depth + 1,
        };
        let first = out.nodes.len();
        assert!(first < MAX_INDEX as usize, "kd-tree: too many nodes");
        out.nodes[slot] = KdNode::inner(split.axis as u32, split.pos, first as u32);
        out.nodes.extend([KdNode::leaf(0), KdNode::leaf(0)]);
        let big = n_left.max(n_right) >= self.params.parallel_min_prims;
        if self.params.parallel && big {
            let (_, sub) = rayon::join(
                || self.build_node(left, first, out, scratch, deeper),
                || {
                    let mut sub = Out::default();
                    sub.nodes.push(KdNode::leaf(0));
                    let mut levels = new_levels();
                    self.build_node(right, 0, &mut sub, &mut self.scratch(), &mut levels);
                    sub
                },
            );
            out.append(sub, first + 1);
        } else {
            self.build_node(left, first, out, scratch, deeper);
            self.build_node(right, first + 1, out, scratch, deeper);
        }
    }

    /// A leaf holding the node's primitives in ascending id order.
    fn make_leaf(&self, task: &Task, slot: usize, out: &mut Out) {
        let first = out.prim_indices.len();
        out.prim_indices.extend(
            task.events[0]
                .iter()
                .filter(|&&e| event_kind(e) != END)
                .map(|&e| event_prim(e)),
        );
        out.prim_indices[first..].sort_unstable();
        let leaf = out.leaves.len();
        assert!(leaf <= MAX_INDEX as usize, "kd-tree: too many leaves");
        out.leaves
            .push([first as u32, (out.prim_indices.len() - first) as u32]);
        out.nodes[slot] = KdNode::leaf(leaf as u32);
    }

    /// The cheapest plane over all three axes by one sweep each (Wald & Havran's
    /// `FindPlane`). Ties keep the first plane found, so the choice is deterministic.
    fn find_split(&self, task: &Task) -> Option<Split> {
        let cell = &task.cell;
        let e = cell.max - cell.min;
        let area = e.x * e.y + e.y * e.z + e.z * e.x;
        if area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let inv_area = 1.0 / area;
        let (k_t, k_i) = (self.params.traversal_cost, self.params.intersection_cost);
        let bonus = 1.0 - self.params.empty_bonus;
        let n = task.prim_count;
        let mut best: Option<Split> = None;
        let mut best_cost = f32::INFINITY;
        for (axis, events) in task.events.iter().enumerate() {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let cap = e[u] * e[v];
            let perimeter = e[u] + e[v];
            let (lo, hi) = (cell.min[axis], cell.max[axis]);
            // Planes strictly inside the cell, as key bounds (keys order like positions).
            let (lo_key, hi_key) = (order_bits(lo + 0.0) as u64, order_bits(hi + 0.0) as u64);
            let (mut n_left, mut n_right) = (0u32, n);
            // This position's planar events, and its planar and start events that join
            // the left side once the plane through it has been priced.
            let (mut planars, mut pending) = (0u32, 0u32);
            let mut next_key = events.first().map_or(0, |&ev| ev >> 32);
            for (i, &ev) in events.iter().enumerate() {
                let kind = event_kind(ev);
                n_right -= (kind != START) as u32;
                planars += (kind == PLANAR) as u32;
                pending += (kind != END) as u32;
                let key = next_key;
                next_key = events.get(i + 1).map_or(u64::MAX, |&next| next >> 32);
                // A plane is priced once, at the last event of its position.
                if next_key == key {
                    continue;
                }
                if key > lo_key && key < hi_key {
                    let pos = from_order_bits(key as u32);
                    let p_left = (cap + (pos - lo) * perimeter) * inv_area;
                    let p_right = (cap + (hi - pos) * perimeter) * inv_area;
                    let cost = |nl: u32, nr: u32| {
                        let c = k_t + k_i * (p_left * nl as f32 + p_right * nr as f32);
                        if nl == 0 || nr == 0 { c * bonus } else { c }
                    };
                    let with_left = cost(n_left + planars, n_right);
                    let with_right = cost(n_left, n_right + planars);
                    let planar_left = with_left < with_right;
                    let c = if planar_left { with_left } else { with_right };
                    if c < best_cost {
                        best_cost = c;
                        best = Some(Split {
                            axis,
                            pos,
                            planar_left,
                            cost: c,
                        });
                    }
                }
                n_left += pending;
                pending = 0;
                planars = 0;
            }
        }
        best
    }

    /// Classifies the node's primitives against `split` and writes the children's event
    /// lists into `kids`: filtered copies of the parent's, merged with the freshly clipped
    /// events of the straddling primitives. Returns the children's primitive counts.
    fn split_task(
        &self,
        task: &Task,
        split: &Split,
        scratch: &mut Scratch,
        kids: &mut [Lists; 2],
    ) -> (u32, u32) {
        let (axis, pos) = (split.axis, split.pos);
        let Scratch {
            side,
            straddlers,
            fresh,
        } = scratch;
        straddlers.clear();
        // One pass in sweep order (a primitive's start comes before its end): a start at
        // or after the plane makes a primitive right, an earlier one makes it straddle
        // until an end at or before the plane makes it left; a planar event decides
        // alone. Keys compare like positions.
        let key = order_bits(pos) as u64;
        let (mut n_left, mut n_right) = (0, 0);
        for &e in task.events[axis] {
            let (kind, at, prim) = (event_kind(e), e >> 32, event_prim(e));
            let s = &mut side[prim as usize];
            if kind == START {
                let right = at >= key;
                *s = if right { RIGHT } else { BOTH };
                n_right += right as u32;
            } else if kind == END {
                let left = at <= key;
                if left {
                    *s = LEFT;
                } else if *s == BOTH {
                    straddlers.push(prim);
                }
                n_left += left as u32;
            } else {
                let left = at < key || (at == key && split.planar_left);
                *s = if left { LEFT } else { RIGHT };
                n_left += left as u32;
                n_right += !left as u32;
            }
        }
        let (left_cell, right_cell) = child_cells(&task.cell, axis, pos);
        let [left_new, right_new] = fresh;
        left_new.iter_mut().for_each(Vec::clear);
        right_new.iter_mut().for_each(Vec::clear);
        for &prim in straddlers.iter() {
            let parts = match self.g.prim_ref(prim) {
                PrimRef::Triangle(t) => split_triangle(self.g.triangle(t), &task.cell, axis, pos),
                _ => [self.clip(prim, &left_cell), self.clip(prim, &right_cell)],
            };
            if let Some(b) = parts[0] {
                push_events(left_new, &b, prim);
                n_left += 1;
            }
            if let Some(b) = parts[1] {
                push_events(right_new, &b, prim);
                n_right += 1;
            }
        }
        for a in 0..3 {
            for list in [&mut left_new[a], &mut right_new[a]] {
                list.sort_unstable();
                // A sentinel above every event key ends the merge without a length test.
                list.push(u64::MAX);
            }
            split_events(task.events[a], side, [&left_new[a], &right_new[a]], a, kids);
        }
        (n_left, n_right)
    }

    /// Bounds of the part of `prim` inside `cell`, or `None` when it misses the cell.
    fn clip(&self, prim: u32, cell: &Aabb) -> Option<Aabb> {
        match self.g.prim_ref(prim) {
            PrimRef::Triangle(t) => clip_triangle(self.g.triangle(t), cell),
            PrimRef::Sphere(s) => {
                let s = &self.g.spheres[s as usize];
                let nearest = s.center.clamp(cell.min, cell.max);
                let d2 = (nearest - s.center).length_squared();
                // A touch of slack: an overlap lost to rounding would lose hits.
                (d2 <= s.radius * s.radius * (1.0 + 1e-5))
                    .then(|| intersect_boxes(&s.bounds(), cell))
                    .filter(|b| !b.is_empty())
            }
            PrimRef::Box(b) => {
                Some(intersect_boxes(&self.g.boxes[b as usize], cell)).filter(|b| !b.is_empty())
            }
            PrimRef::Plane(_) => None,
        }
    }
}

/// Writes into `kids` the events of `src` (one axis) whose primitives went left and
/// right (straddlers dropped), each list merged on the way with the sorted new events
/// of its side (`fresh`, each ending in a `u64::MAX` sentinel). The copy is
/// branch-free: every event is written to both lists, and only its side's list moves on.
/// The merge is one well-predicted test per event against the smaller of the two next
/// new events; the new events are few (straddlers only).
fn split_events(src: &[u64], side: &[u8], fresh: [&[u64]; 2], axis: usize, kids: &mut [Lists; 2]) {
    let [left, right] = kids;
    let [left_new, right_new] = fresh;
    let l = left.room(axis, src.len() + left_new.len());
    let r = right.room(axis, src.len() + right_new.len());
    let (mut n_left, mut n_right) = (0, 0);
    let (mut i_left, mut i_right) = (0, 0);
    let mut next_new = left_new[0].min(right_new[0]);
    for &e in src {
        if next_new < e {
            while left_new[i_left] < e {
                l[n_left] = left_new[i_left];
                n_left += 1;
                i_left += 1;
            }
            while right_new[i_right] < e {
                r[n_right] = right_new[i_right];
                n_right += 1;
                i_right += 1;
            }
            next_new = left_new[i_left].min(right_new[i_right]);
        }
        let s = side[event_prim(e) as usize];
        l[n_left] = e;
        r[n_right] = e;
        n_left += (s == LEFT) as usize;
        n_right += (s == RIGHT) as usize;
    }
    for &e in &left_new[i_left..left_new.len() - 1] {
        l[n_left] = e;
        n_left += 1;
    }
    for &e in &right_new[i_right..right_new.len() - 1] {
        r[n_right] = e;
        n_right += 1;
    }
    left.lens[axis] = n_left;
    right.lens[axis] = n_right;
}

fn intersect_boxes(a: &Aabb, b: &Aabb) -> Aabb {
    Aabb::new(a.min.max(b.min), a.max.min(b.max))
}

/// Relative widening of coordinates that clipping computed (a few ulps of f32).
const CLIP_SLACK: f32 = 1e-6;

/// Room for a triangle clipped by seven planes (3 + 7 corners); a polygon that rounding
/// made more ragged than that takes the exact overlap test's answer instead.
const CLIP_VERTICES: usize = 10;

/// The point where the edge from `a` to `b` crosses the plane `p[axis] = plane`, put
/// exactly on it; [`Polygon::clip`] and [`Polygon::split`] share it so both cut alike.
#[inline]
fn crossing(a: &[f32; 3], b: &[f32; 3], axis: usize, plane: f32) -> [f32; 3] {
    let t = (plane - a[axis]) / (b[axis] - a[axis]);
    let mut p = [0.0; 3];
    for k in 0..3 {
        p[k] = a[k] + (b[k] - a[k]) * t;
    }
    p[axis] = plane;
    p
}

/// A convex polygon being clipped (Sutherland-Hodgman): its corners, and a bit per
/// corner set when the corner is one of the triangle's own rather than computed.
#[derive(Clone, Copy)]
struct Polygon {
    corners: [[f32; 3]; CLIP_VERTICES],
    exact: u32,
    len: usize,
}

impl Polygon {
    fn triangle(tri: [Vec3; 3]) -> Polygon {
        let mut corners = [[0.0; 3]; CLIP_VERTICES];
        for (c, p) in corners.iter_mut().zip(tri) {
            *c = p.to_array();
        }
        Polygon {
            corners,
            exact: 0b111,
            len: 3,
        }
    }

    /// The part with `p[axis] <= plane` (`keep_below`) or `>= plane`. `None` when
    /// rounding made the polygon so ragged that it would overflow the corner array.
    fn clip(&self, axis: usize, plane: f32, keep_below: bool) -> Option<Polygon> {
        let inside = |p: &[f32; 3]| {
            if keep_below {
                p[axis] <= plane
            } else {
                p[axis] >= plane
            }
        };
        let len = self.len;
        let corners = &self.corners[..len];
        // Bit i: corner i is on the kept side.
        let mut kept = 0u32;
        for (i, p) in corners.iter().enumerate() {
            kept |= (inside(p) as u32) << i;
        }
        if kept == (1 << len) - 1 {
            return Some(*self);
        }
        let mut out = Polygon {
            corners: [[0.0; 3]; CLIP_VERTICES],
            exact: 0,
            len: 0,
        };
        let mut n = 0;
        for (i, a) in corners.iter().enumerate() {
            let j = if i + 1 == len { 0 } else { i + 1 };
            let (a_in, b_in) = (kept >> i & 1, kept >> j & 1);
            if a_in == 1 {
                *out.corners.get_mut(n)? = *a;
                out.exact |= (self.exact >> i & 1) << n;
                n += 1;
            }
            if a_in != b_in {
                *out.corners.get_mut(n)? = crossing(a, &corners[j], axis, plane);
                n += 1;
            }
        }
        out.len = n;
        Some(out)
    }

    /// Appends corner `p` (`exact` when it is one of the triangle's own); `false` when the
    /// corner array is full.
    fn push(&mut self, p: [f32; 3], exact: u32) -> bool {
        let Some(slot) = self.corners.get_mut(self.len) else {
            return false;
        };
        *slot = p;
        self.exact |= exact << self.len;
        self.len += 1;
        true
    }

    /// The parts with `p[axis] <= plane` and with `p[axis] >= plane`, the same polygons
    /// as [`Polygon::clip`] gives for each side, in one pass that computes each point
    /// where an edge crosses the plane once for both (the division is the clipper's
    /// slowest step). A part is `None` when it would overflow the corner array.
    fn split(&self, axis: usize, plane: f32) -> [Option<Polygon>; 2] {
        let len = self.len;
        let corners = &self.corners[..len];
        // Bit i: corner i is on the part's side.
        let (mut below, mut above) = (0u32, 0u32);
        for (i, p) in corners.iter().enumerate() {
            below |= ((p[axis] <= plane) as u32) << i;
            above |= ((p[axis] >= plane) as u32) << i;
        }
        let empty = Polygon {
            corners: [[0.0; 3]; CLIP_VERTICES],
            exact: 0,
            len: 0,
        };
        let mut parts = [empty; 2];
        let mut fits = [true; 2];
        for (i, a) in corners.iter().enumerate() {
            let j = if i + 1 == len { 0 } else { i + 1 };
            let mut cut = None;
            for (k, kept) in [below, above].into_iter().enumerate() {
                let (a_in, b_in) = (kept >> i & 1, kept >> j & 1);
                if a_in == 1 {
                    fits[k] &= parts[k].push(*a, self.exact >> i & 1);
                }
                if a_in != b_in {
                    let p = *cut.get_or_insert_with(|| crossing(a, &corners[j], axis, plane));
                    fits[k] &= parts[k].push(p, 0);
                }
            }
        }
        let [below_part, above_part] = parts;
        [fits[0].then_some(below_part), fits[1].then_some(above_part)]
    }

    /// The part inside `cell`, clipping only by the faces that cut `whole`, the bounds
    /// of the triangle the polygon came from (the others leave it whole).
    fn clip_to_cell(self, whole: &Aabb, cell: &Aabb) -> Option<Polygon> {
        let mut poly = self;
        for axis in 0..3 {
            if whole.min[axis] < cell.min[axis] {
                poly = poly.clip(axis, cell.min[axis], false)?;
            }
            if whole.max[axis] > cell.max[axis] {
                poly = poly.clip(axis, cell.max[axis], true)?;
            }
            if poly.len == 0 {
                return None;
            }
        }
        Some(poly)
    }

    /// Bounds of the corners in `cell`: the triangle's own count exactly, computed ones
    /// are widened by a few ulps of `scale`, the triangle's largest coordinate. `None`
    /// when the polygon is empty.
    fn bounds_in(&self, scale: Vec3, cell: &Aabb) -> Option<Aabb> {
        if self.len == 0 {
            return None;
        }
        let mut b = Aabb::EMPTY;
        for (i, &p) in self.corners[..self.len].iter().enumerate() {
            let p = Vec3::from_array(p);
            if self.exact >> i & 1 == 1 {
                b.grow(p);
            } else {
                let widen = p.abs().max(scale) * CLIP_SLACK;
                b.grow(p - widen);
                b.grow(p + widen);
            }
        }
        let b = intersect_boxes(&b, cell);
        (!b.is_empty()).then_some(b)
    }
}

/// When clipping leaves nothing (or, in theory, rounding makes the polygon ragged),
/// Akenine-Moller's test on `cell` widened by [`CLIP_SLACK`] decides; if it finds a
/// sliver that rounding lost, the triangle's bounds `whole` in the cell are the safe
/// answer.
fn overlap_fallback(tri: [Vec3; 3], whole: &Aabb, cell: &Aabb) -> Option<Aabb> {
    let centre = (cell.min + cell.max) * 0.5;
    let half = (cell.max - cell.min) * 0.5;
    let slack = (centre.abs() + half) * CLIP_SLACK;
    if tri_box_overlap(centre, half + slack, tri) {
        Some(intersect_boxes(whole, cell)).filter(|b| !b.is_empty())
    } else {
        None
    }
}

fn triangle_bounds(tri: &[Vec3; 3]) -> Aabb {
    let mut whole = Aabb::EMPTY;
    tri.iter().for_each(|&p| whole.grow(p));
    whole
}

fn contains(cell: &Aabb, b: &Aabb) -> bool {
    b.min.cmpge(cell.min).all() && b.max.cmple(cell.max).all()
}

/// Bounds of the part of triangle `tri` inside `cell`, or `None` when they do not meet.
///
/// The triangle is clipped to the cell (Sutherland-Hodgman); when nothing is left,
/// Akenine-Moller's exact overlap test (on the cell widened by `CLIP_SLACK`) has the
/// last word, so rounding in the clipper never drops a triangle that touches the cell.
/// Corners of the triangle count exactly; points that clipping computed are widened by
/// a few ulps, and the result is intersected with the cell.
pub fn clip_triangle(tri: [Vec3; 3], cell: &Aabb) -> Option<Aabb> {
    let whole = triangle_bounds(&tri);
    if contains(cell, &whole) {
        return Some(whole);
    }
    let scale = whole.min.abs().max(whole.max.abs());
    Polygon::triangle(tri)
        .clip_to_cell(&whole, cell)
        .and_then(|p| p.bounds_in(scale, cell))
        .or_else(|| overlap_fallback(tri, &whole, cell))
}

/// [`clip_triangle`] for both children of `cell` split at `pos` on `axis`: the triangle
/// is clipped to `cell` once, and that polygon cut by the plane for each side.
pub fn split_triangle(tri: [Vec3; 3], cell: &Aabb, axis: usize, pos: f32) -> [Option<Aabb>; 2] {
    let whole = triangle_bounds(&tri);
    let scale = whole.min.abs().max(whole.max.abs());
    let (left_cell, right_cell) = child_cells(cell, axis, pos);
    let parts = Polygon::triangle(tri)
        .clip_to_cell(&whole, cell)
        .map_or([None, None], |p| p.split(axis, pos));
    let mut bounds = [None; 2];
    for ((b, part), child) in bounds.iter_mut().zip(&parts).zip([left_cell, right_cell]) {
        *b = if contains(&child, &whole) {
            Some(whole)
        } else {
            part.and_then(|p| p.bounds_in(scale, &child))
                .or_else(|| overlap_fallback(tri, &whole, &child))
        };
    }
    bounds
}

/// Akenine-Moller's triangle/box overlap test (2001): the separating axis theorem over
/// the box's three axes, the triangle's normal and the nine edge cross products.
pub fn tri_box_overlap(centre: Vec3, half: Vec3, tri: [Vec3; 3]) -> bool {
    let v = tri.map(|p| p - centre);
    for axis in 0..3 {
        let lo = v[0][axis].min(v[1][axis]).min(v[2][axis]);
        let hi = v[0][axis].max(v[1][axis]).max(v[2][axis]);
        if lo > half[axis] || hi < -half[axis] {
            return false;
        }
    }
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let normal = edges[0].cross(edges[1]);
    let d = normal.dot(v[0]);
    let r = half.dot(normal.abs());
    if d > r || d < -r {
        return false;
    }
    for e in edges {
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let a = axis.cross(e);
            let p = v.map(|x| a.dot(x));
            let lo = p[0].min(p[1]).min(p[2]);
            let hi = p[0].max(p[1]).max(p[2]);
            let r = half.dot(a.abs());
            if lo > r || hi < -r {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn event_keys_sort_by_position_then_kind_then_prim() {
        let mut keys = [
            event(1.0, START, 0),
            event(1.0, END, 5),
            event(-2.0, START, 1),
            event(1.0, PLANAR, 2),
            event(-0.0, END, 3),
            event(0.0, START, 4),
            event(f32::MIN_POSITIVE, END, 9),
        ];
        keys.sort_unstable();
        let order: Vec<u32> = keys.iter().map(|&e| event_prim(e)).collect();
        assert_eq!(order, vec![1, 3, 4, 9, 5, 2, 0]);
        assert_eq!(event_pos(event(-2.5, END, 7)), -2.5);
        assert_eq!(event_pos(event(-0.0, END, 7)).to_bits(), 0.0f32.to_bits());
        assert_eq!(event_kind(event(3.0, PLANAR, MAX_INDEX)), PLANAR);
        assert_eq!(event_prim(event(3.0, START, MAX_INDEX)), MAX_INDEX);
    }

    #[test]
    fn clipping_gives_the_part_inside_the_cell() {
        let tri = [
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
        ];
        let cell = Aabb::new(Vec3::new(1.0, 1.0, -1.0), Vec3::new(5.0, 5.0, 1.0));
        let b = clip_triangle(tri, &cell).expect("overlaps");
        // The part with x >= 1, y >= 1 is the triangle (1,1) (3,1) (1,3).
        assert!((b.min - Vec3::new(1.0, 1.0, 0.0)).abs().max_element() < 1e-5);
        assert!((b.max - Vec3::new(3.0, 3.0, 0.0)).abs().max_element() < 1e-5);
        assert!(b.min.x >= 1.0 && b.min.y >= 1.0 && b.max.x >= 3.0 && b.max.y >= 3.0);
        // A cell beyond the hypotenuse: the bounds overlap, the triangle does not.
        let beyond = Aabb::new(Vec3::new(2.5, 2.5, -1.0), Vec3::new(5.0, 5.0, 1.0));
        assert_eq!(clip_triangle(tri, &beyond), None);
        // Touching the cell at one corner still counts.
        let corner = Aabb::new(Vec3::new(4.0, -1.0, -1.0), Vec3::new(5.0, 0.0, 1.0));
        assert!(clip_triangle(tri, &corner).is_some());
    }

    #[test]
    fn depth_limit_follows_the_paper() {
        assert_eq!(default_max_depth(1), 8);
        assert_eq!(default_max_depth(1 << 20), 34);
    }
}
