//! Build: a binary BVH by binned SAH (Wald 2007), then collapsed into 8-wide nodes by
//! opening the largest child until eight remain (Embree's and tinybvh's way to a
//! BVH8). Deterministic: the same tree on any number of threads.
//!
//! Parallel: the halves of a node go to two threads, and a node of at least [`WIDE`]
//! references (the top levels, where there are fewer nodes than threads) bins and
//! partitions its references in jobs of [`JOB`] on the whole pool. Its partition is
//! stable, so the serial build, which takes the same path, makes the same tree. The
//! build marks its work on a [`Meter`] (`raypack info --accel bvh8 --occupancy`).

use super::{Bvh, EMPTY, LEAF_BIT, MAX_LEAF, Node8};
use crate::accel::Prims;
use crate::accel::occupancy::{JOB, Meter};
use crate::geom::{Aabb, Geometry};
use glam::Vec3;
use rayon::prelude::*;

/// Bins per axis of the SAH sweep.
const BINS: usize = 32;
/// Nodes with at least this many references split their halves on two threads.
const PARALLEL_MIN: usize = 4096;
/// Nodes with at least this many references bin and partition them in jobs.
const WIDE: usize = 1 << 16;
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
/// else `first` is the left child (the right one follows the left subtree) and `size`
/// the subtree's references.
#[derive(Clone, Copy)]
struct Node2 {
    bounds: Aabb,
    first: u32,
    count: u32,
    right: u32,
    size: u32,
}

/// The bounds of `refs` and of their centroids.
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

/// [`bounds_of`] in jobs (exact: minima and maxima do not depend on the order).
fn bounds_wide(refs: &[Ref], meter: Meter) -> (Aabb, Aabb) {
    let union = |(a, b): (Aabb, Aabb), (c, d): (Aabb, Aabb)| (a.union(&c), b.union(&d));
    meter.hand_off(|| {
        refs.par_chunks(JOB)
            .map(|c| meter.work(|| bounds_of(c)))
            .reduce(|| (Aabb::EMPTY, Aabb::EMPTY), union)
    })
}

/// The references' boxes and counts in `BINS` bins per axis of the centroid bounds.
#[derive(Clone, Copy)]
struct Bins {
    boxes: [[Aabb; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Bins {
    fn of(refs: &[Ref], cb: &Aabb) -> Bins {
        let mut bins = Bins {
            boxes: [[Aabb::EMPTY; BINS]; 3],
            counts: [[0; BINS]; 3],
        };
        let ext = cb.max - cb.min;
        for axis in 0..3 {
            if !(ext[axis] > 0.0) {
                continue;
            }
            let scale = BINS as f32 / ext[axis];
            let (boxes, counts) = (&mut bins.boxes[axis], &mut bins.counts[axis]);
            for r in refs {
                let b = bin_of(r.centroid()[axis], cb.min[axis], scale);
                boxes[b].min = boxes[b].min.min(r.lo);
                boxes[b].max = boxes[b].max.max(r.hi);
                counts[b] += 1;
            }
        }
        bins
    }

    /// [`Bins::of`] in jobs (exact, as [`bounds_wide`]).
    fn wide(refs: &[Ref], cb: &Aabb, meter: Meter) -> Bins {
        meter.hand_off(|| {
            refs.par_chunks(JOB)
                .map(|c| meter.work(|| Bins::of(c, cb)))
                .reduce_with(|mut a, b| {
                    for axis in 0..3 {
                        for k in 0..BINS {
                            a.boxes[axis][k] = a.boxes[axis][k].union(&b.boxes[axis][k]);
                            a.counts[axis][k] += b.counts[axis][k];
                        }
                    }
                    a
                })
                .expect("a wide node has references")
        })
    }

    /// The best SAH split: `(cost, axis, bin)` where references whose centroid bins
    /// below `bin` go left.
    fn best(&self) -> Option<(f32, usize, usize)> {
        let mut best: Option<(f32, usize, usize)> = None;
        for axis in 0..3 {
            let (boxes, counts) = (&self.boxes[axis], &self.counts[axis]);
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
/// least two references), or `None` for a leaf. A wide node (at least [`WIDE`]
/// references) bins and partitions in jobs, and stably, whether `parallel` or not.
fn partition(
    refs: &mut [Ref],
    bounds: &Aabb,
    cb: &Aabb,
    depth: u32,
    parallel: bool,
    meter: Meter,
) -> Option<usize> {
    let n = refs.len();
    let wide = n >= WIDE;
    let split = if depth >= SAH_DEPTH {
        None
    } else if wide && parallel {
        Bins::wide(refs, cb, meter).best()
    } else {
        Bins::of(refs, cb).best()
    };
    if let Some((cost, axis, bin)) = split {
        let leaf_cost = blocks(n as u32);
        let split_cost = TRAVERSAL_COST + cost / area(bounds).max(f32::MIN_POSITIVE);
        if n <= MAX_LEAF && (leaf_cost <= split_cost || area(bounds) == 0.0) {
            return None;
        }
        let scale = BINS as f32 / (cb.max[axis] - cb.min[axis]);
        let left = |r: &Ref| bin_of(r.centroid()[axis], cb.min[axis], scale) < bin;
        let i = if wide {
            stable_partition(refs, left, parallel, meter)
        } else {
            let mut i = 0;
            for j in 0..n {
                if left(&refs[j]) {
                    refs.swap(i, j);
                    i += 1;
                }
            }
            i
        };
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

/// Moves the references for which `left` holds before the others, each part in its
/// order; returns the left part's length. In jobs when `parallel`: each chunk splits
/// its own, then the chunks' parts are copied to their places.
fn stable_partition(
    refs: &mut [Ref],
    left: impl Fn(&Ref) -> bool + Sync,
    parallel: bool,
    meter: Meter,
) -> usize {
    let split = |c: &[Ref]| -> (Vec<Ref>, Vec<Ref>) { c.iter().partition(|r| left(r)) };
    let parts: Vec<(Vec<Ref>, Vec<Ref>)> = if parallel {
        meter.hand_off(|| {
            refs.par_chunks(JOB)
                .map(|c| meter.work(|| split(c)))
                .collect()
        })
    } else {
        refs.chunks(JOB).map(split).collect()
    };
    let n_left: usize = parts.iter().map(|(l, _)| l.len()).sum();
    // Each part's destination, in order: every left part, then every right one.
    let mut places: Vec<(&mut [Ref], &[Ref])> = Vec::with_capacity(2 * parts.len());
    let (mut lefts, mut rights) = refs.split_at_mut(n_left);
    for (l, r) in &parts {
        let (to, rest) = std::mem::take(&mut lefts).split_at_mut(l.len());
        places.push((to, l));
        lefts = rest;
        let (to, rest) = std::mem::take(&mut rights).split_at_mut(r.len());
        places.push((to, r));
        rights = rest;
    }
    let copy = |(to, from): (&mut [Ref], &[Ref])| to.copy_from_slice(from);
    if parallel {
        meter.hand_off(|| places.into_par_iter().for_each(|p| meter.work(|| copy(p))));
    } else {
        places.into_iter().for_each(copy);
    }
    n_left
}

/// The subtree over `refs` (which start at `first` in the whole array), root first.
fn build2(refs: &mut [Ref], first: u32, depth: u32, parallel: bool, meter: Meter) -> Vec<Node2> {
    let (bounds, cb) = if parallel && refs.len() >= WIDE {
        bounds_wide(refs, meter)
    } else {
        bounds_of(refs)
    };
    let size = refs.len() as u32;
    let Some(mid) = partition(refs, &bounds, &cb, depth, parallel, meter) else {
        return vec![Node2 {
            bounds,
            first,
            count: size,
            right: 0,
            size,
        }];
    };
    let (l, r) = refs.split_at_mut(mid);
    let (left, right) = if parallel && l.len() + r.len() >= PARALLEL_MIN {
        meter.hand_off(|| {
            rayon::join(
                || meter.work(|| build2(l, first, depth + 1, parallel, meter)),
                || meter.work(|| build2(r, first + mid as u32, depth + 1, parallel, meter)),
            )
        })
    } else {
        (
            build2(l, first, depth + 1, parallel, meter),
            build2(r, first + mid as u32, depth + 1, parallel, meter),
        )
    };
    let mut out = Vec::with_capacity(1 + left.len() + right.len());
    out.push(Node2 {
        bounds,
        first: 1,
        count: 0,
        right: 1 + left.len() as u32,
        size,
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
/// `out`; returns its index. A wide node's children collapse on the pool, each into
/// its own list, appended in order.
fn collapse(tree: &[Node2], n: u32, out: &mut Vec<Node8>, parallel: bool, meter: Meter) -> u32 {
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
    let inner = |k: u32| tree[k as usize].count == 0;
    if parallel && node.size as usize >= WIDE {
        let subtree = |k: u32| {
            let mut sub = Vec::new();
            meter.work(|| collapse(tree, k, &mut sub, parallel, meter));
            sub
        };
        let subs: Vec<Vec<Node8>> = meter.hand_off(|| {
            (kids.par_iter())
                .map(|&k| if inner(k) { subtree(k) } else { Vec::new() })
                .collect()
        });
        for (slot, (&k, sub)) in kids.iter().zip(subs).enumerate() {
            let c = &tree[k as usize];
            if !inner(k) {
                children[slot] = leaf_word(c.first, c.count);
                continue;
            }
            let base = out.len() as u32;
            children[slot] = base;
            out.extend(sub.into_iter().map(|mut n8| {
                for w in &mut n8.child {
                    if *w & LEAF_BIT == 0 {
                        *w += base;
                    }
                }
                n8
            }));
        }
    } else {
        for (slot, &k) in kids.iter().enumerate() {
            let c = &tree[k as usize];
            children[slot] = if inner(k) {
                collapse(tree, k, out, parallel, meter)
            } else {
                leaf_word(c.first, c.count)
            };
        }
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
        Bvh::build_metered(g, parallel, Meter::OFF)
    }

    /// [`Bvh::build_with`], marking its work on `meter`.
    pub fn build_metered(g: &Geometry, parallel: bool, meter: Meter) -> Bvh {
        let start = std::time::Instant::now();
        let mut bvh = meter.work(|| Bvh::build_marked(g, parallel, meter));
        bvh.build_seconds = start.elapsed().as_secs_f64();
        bvh
    }

    fn build_marked(g: &Geometry, parallel: bool, meter: Meter) -> Bvh {
        use crate::accel::kdtree::build::{inverse, leaf_order};
        let mut prims = Prims::with(g, parallel, meter);
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
            meter.hand_off(|| {
                (meter.jobs((0..bounded).into_par_iter()))
                    .filter_map(make)
                    .collect()
            })
        } else {
            (0..bounded).filter_map(make).collect()
        };
        let mut nodes = Vec::new();
        let mut bounds = Aabb::EMPTY;
        if !refs.is_empty() {
            let tree = build2(&mut refs, 0, 0, parallel, meter);
            bounds = tree[0].bounds;
            if tree[0].count > 0 {
                let mut root = Node8::EMPTY;
                root.set_child(0, &tree[0].bounds, leaf_word(0, tree[0].count));
                nodes.push(root);
            } else {
                collapse(&tree, 0, &mut nodes, parallel, meter);
            }
        }
        // Triangles' records in leaf order; the others keep their ids as slots.
        let tri_count = prims.tris.len() as u32;
        let named: Vec<u32> = if parallel {
            meter.hand_off(|| meter.jobs(refs.par_iter()).map(|r| r.prim).collect())
        } else {
            refs.iter().map(|r| r.prim).collect()
        };
        let order = leaf_order(&named, tri_count, parallel, meter);
        let slot_of = inverse(&order, parallel, meter);
        prims.reorder_triangles(&order, parallel, meter);
        let slot = |r: &Ref| {
            if r.prim < tri_count {
                slot_of[r.prim as usize]
            } else {
                r.prim
            }
        };
        let slots: Vec<u32> = if parallel {
            meter.hand_off(|| meter.jobs(refs.par_iter()).map(slot).collect())
        } else {
            refs.iter().map(slot).collect()
        };
        debug_assert!(
            !prims.triangles_only() || slots.iter().enumerate().all(|(j, &s)| s == j as u32),
            "a scene of triangles only has its records in leaf order"
        );
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
            build_seconds: 0.0,
        }
    }
}
