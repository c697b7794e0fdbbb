//! Build: a binary BVH by binned SAH (Wald 2007), then collapsed into 8-wide nodes by
//! opening the largest child until eight remain (Embree's and tinybvh's way to a
//! BVH8). Deterministic: the same tree on any number of threads.

use super::{Bvh, EMPTY, LEAF_BIT, MAX_LEAF, Node8};
use crate::accel::Prims;
use crate::geom::{Aabb, Geometry};
use glam::Vec3;

/// Bins per axis of the SAH sweep.
const BINS: usize = 32;
/// Nodes with at least this many references split their halves on two threads.
const PARALLEL_MIN: usize = 4096;
/// Past this depth a node splits at its object median: the depth, and so the walks'
/// stack, stays bounded on any input.
const SAH_DEPTH: u32 = 48;
/// Primitives the SAH prices as one test: the leaf kernel tests up to four triangles
/// in one 4-lane pass (eight in an 8-lane one), so a leaf's cost grows by blocks, not
/// by triangles (Embree's blocks of four). Leaves then fill up where splitting gains
/// nothing: fewer nodes and leaves than at a price per triangle (perf/log/bvh.md).
const BLOCK: u32 = 4;
/// SAH cost of a node step against one block's test.
const TRAVERSAL_COST: f32 = 1.0;

/// A primitive's bounds and id.
#[derive(Clone, Copy)]
struct Ref {
    lo: Vec3,
    hi: Vec3,
    prim: u32,
}

impl Ref {
    #[inline]
    fn centroid(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }
}

/// A node of the binary tree: `count > 0` is a leaf over `refs[first..first + count]`,
/// else `first` is the left child (the right one follows the left subtree).
#[derive(Clone, Copy)]
struct Node2 {
    bounds: Aabb,
    first: u32,
    count: u32,
    right: u32,
}

fn bounds_of(refs: &[Ref]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut c = Aabb::EMPTY;
    for r in refs {
        b.min = b.min.min(r.lo);
        b.max = b.max.max(r.hi);
        c.grow(r.centroid());
    }
    (b, c)
}

/// The best SAH split of `refs` over `BINS` bins per axis: `(cost, axis, bin)` where
/// references whose centroid bins below `bin` go left.
fn best_split(refs: &[Ref], cb: &Aabb) -> Option<(f32, usize, usize)> {
    let ext = cb.max - cb.min;
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if !(ext[axis] > 0.0) {
            continue;
        }
        let scale = BINS as f32 / ext[axis];
        let mut boxes = [Aabb::EMPTY; BINS];
        let mut counts = [0u32; BINS];
        for r in refs {
            let b = bin_of(r.centroid()[axis], cb.min[axis], scale);
            boxes[b].min = boxes[b].min.min(r.lo);
            boxes[b].max = boxes[b].max.max(r.hi);
            counts[b] += 1;
        }
        // Sweep from the right, then from the left pricing each boundary.
        let mut right_area = [0.0f32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        let mut right_count = [0u32; BINS];
        for b in (1..BINS).rev() {
            acc = acc.union(&boxes[b]);
            n += counts[b];
            right_area[b] = area(&acc);
            right_count[b] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in 1..BINS {
            acc = acc.union(&boxes[b - 1]);
            n += counts[b - 1];
            if n == 0 || right_count[b] == 0 {
                continue;
            }
            let cost = area(&acc) * blocks(n) + right_area[b] * blocks(right_count[b]);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    best
}

/// The SAH's price of a leaf of `n` primitives: its lane tests of up to [`BLOCK`].
#[inline]
fn blocks(n: u32) -> f32 {
    n.div_ceil(BLOCK) as f32
}

#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// Half the surface area (the SAH needs ratios only); zero for an empty box.
#[inline]
fn area(b: &Aabb) -> f32 {
    let e = b.extent();
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Splits `refs` in place into a left and a right part, both non-empty (`refs` holds at
/// least two references).
fn partition(refs: &mut [Ref], bounds: &Aabb, cb: &Aabb, depth: u32) -> Option<usize> {
    let n = refs.len();
    let split = if depth < SAH_DEPTH {
        best_split(refs, cb)
    } else {
        None
    };
    if let Some((cost, axis, bin)) = split {
        let leaf_cost = blocks(n as u32);
        let split_cost = TRAVERSAL_COST + cost / area(bounds).max(f32::MIN_POSITIVE);
        if n <= MAX_LEAF && (leaf_cost <= split_cost || area(bounds) == 0.0) {
            return None;
        }
        let scale = BINS as f32 / (cb.max[axis] - cb.min[axis]);
        let mut i = 0;
        for j in 0..n {
            if bin_of(refs[j].centroid()[axis], cb.min[axis], scale) < bin {
                refs.swap(i, j);
                i += 1;
            }
        }
        debug_assert!(i > 0 && i < n);
        return Some(i);
    }
    if n <= MAX_LEAF {
        return None;
    }
    // Equal centroids, or too deep: the object median on the longest centroid axis.
    let axis = (cb.max - cb.min).max_position();
    let mid = n / 2;
    refs.select_nth_unstable_by(mid, |a, b| {
        (a.centroid()[axis], a.prim)
            .partial_cmp(&(b.centroid()[axis], b.prim))
            .unwrap()
    });
    Some(mid)
}

/// The subtree over `refs` (which start at `first` in the whole array), root first.
fn build2(refs: &mut [Ref], first: u32, depth: u32, parallel: bool) -> Vec<Node2> {
    let (bounds, cb) = bounds_of(refs);
    let Some(mid) = partition(refs, &bounds, &cb, depth) else {
        return vec![Node2 {
            bounds,
            first,
            count: refs.len() as u32,
            right: 0,
        }];
    };
    let (l, r) = refs.split_at_mut(mid);
    let (left, right) = if parallel && l.len() + r.len() >= PARALLEL_MIN {
        rayon::join(
            || build2(l, first, depth + 1, parallel),
            || build2(r, first + mid as u32, depth + 1, parallel),
        )
    } else {
        (
            build2(l, first, depth + 1, parallel),
            build2(r, first + mid as u32, depth + 1, parallel),
        )
    };
    let mut out = Vec::with_capacity(1 + left.len() + right.len());
    out.push(Node2 {
        bounds,
        first: 1,
        count: 0,
        right: 1 + left.len() as u32,
    });
    let shift = |n: &Node2, by: u32| {
        let mut n = *n;
        if n.count == 0 {
            n.first += by;
            n.right += by;
        }
        n
    };
    out.extend(left.iter().map(|n| shift(n, 1)));
    let by = 1 + left.len() as u32;
    out.extend(right.iter().map(|n| shift(n, by)));
    out
}

/// Appends the 8-wide node of binary node `n` (an inner node) and its subtree to
/// `out`; returns its index.
fn collapse(tree: &[Node2], n: u32, out: &mut Vec<Node8>) -> u32 {
    let node = &tree[n as usize];
    let mut kids = vec![node.first, node.right];
    while kids.len() < 8 {
        // Open the inner child of the largest area.
        let open = (0..kids.len())
            .filter(|&k| tree[kids[k] as usize].count == 0)
            .max_by(|&a, &b| {
                let (a, b) = (&tree[kids[a] as usize], &tree[kids[b] as usize]);
                area(&a.bounds).total_cmp(&area(&b.bounds))
            });
        let Some(k) = open else { break };
        let c = tree[kids[k] as usize];
        kids[k] = c.first;
        kids.push(c.right);
    }
    let index = out.len() as u32;
    out.push(Node8::EMPTY);
    let mut children = [EMPTY; 8];
    for (slot, &k) in kids.iter().enumerate() {
        let c = &tree[k as usize];
        children[slot] = if c.count > 0 {
            leaf_word(c.first, c.count)
        } else {
            collapse(tree, k, out)
        };
    }
    let n8 = &mut out[index as usize];
    for (slot, &k) in kids.iter().enumerate() {
        n8.set_child(slot, &tree[k as usize].bounds, children[slot]);
    }
    index
}

/// The child word of a leaf over `refs[first..first + count]`.
fn leaf_word(first: u32, count: u32) -> u32 {
    debug_assert!((1..=MAX_LEAF as u32).contains(&count) && first < 1 << 27);
    LEAF_BIT | ((count - 1) << 27) | first
}

impl Bvh {
    /// Builds the BVH of `g`'s bounded primitives (the triangles' records placed in
    /// leaf order), on the current rayon pool when `parallel`. Degenerate triangles
    /// and non-finite primitives stay out, as in the kd-tree.
    ///
    /// Panics on more than 2^27 bounded primitives (a leaf word's 27 bits).
    pub fn build_with(g: &Geometry, parallel: bool) -> Bvh {
        use crate::accel::occupancy::Meter;
        use rayon::prelude::*;
        let start = std::time::Instant::now();
        let mut prims = Prims::with(g, parallel, Meter::OFF);
        let bounded = g.bounded_count();
        assert!(bounded < 1 << 27, "BVH: more than 2^27 primitives");
        let make = |p: u32| {
            crate::accel::kdtree::build::tree_bounds(g, &prims, p).map(|b| Ref {
                lo: b.min,
                hi: b.max,
                prim: p,
            })
        };
        let mut refs: Vec<Ref> = if parallel {
            (0..bounded).into_par_iter().filter_map(make).collect()
        } else {
            (0..bounded).filter_map(make).collect()
        };
        let mut nodes = Vec::new();
        let mut bounds = Aabb::EMPTY;
        if !refs.is_empty() {
            let tree = build2(&mut refs, 0, 0, parallel);
            bounds = tree[0].bounds;
            if tree[0].count > 0 {
                let mut root = Node8::EMPTY;
                root.set_child(0, &tree[0].bounds, leaf_word(0, tree[0].count));
                nodes.push(root);
            } else {
                collapse(&tree, 0, &mut nodes);
            }
        }
        // Triangles' records in leaf order; the others keep their ids as slots.
        let tri_count = prims.tris.len();
        let mut order: Vec<u32> = Vec::with_capacity(tri_count);
        let mut placed = vec![false; tri_count];
        for r in &refs {
            if (r.prim as usize) < tri_count {
                order.push(r.prim);
                placed[r.prim as usize] = true;
            }
        }
        order.extend((0..tri_count as u32).filter(|&t| !placed[t as usize]));
        let mut slot_of = vec![0u32; tri_count];
        for (s, &t) in order.iter().enumerate() {
            slot_of[t as usize] = s as u32;
        }
        prims.reorder_triangles(&order, parallel, Meter::OFF);
        let slots = refs
            .iter()
            .map(|r| {
                if (r.prim as usize) < tri_count {
                    slot_of[r.prim as usize]
                } else {
                    r.prim
                }
            })
            .collect();
        Bvh {
            nodes,
            slots,
            prims,
            bounds,
            coord_max: if refs.is_empty() {
                0.0
            } else {
                crate::accel::kdtree::traverse::box_coord_max(&bounds)
            },
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }
}
