//! The arrays a build writes, in depth-first order: nodes, the leaf table and the index
//! lists.
//!
//! A subtree built apart on another thread is not copied in when its parent takes it
//! ([`Out::append`]): the parent reserves its place, and [`Out::finish`] copies every
//! piece once, relocated, in parallel. Copying at each join had cost a serial pass over
//! half the tree at the root, a quarter at each of its children, and so on: on two
//! threads a fifth of the build's serial part (perf/log/kdtree.md, "The serial part").
//! Where each node lands does not change: a piece goes where the copy would have put it.

use super::super::node::{KdNode, MAX_CHILD, MAX_INDEX, ranged, with_leaf_ranges};
use crate::accel::occupancy::{JOB, Meter};
use rayon::prelude::*;

/// A run of consecutive entries that this `Out` wrote itself, starting at index
/// `start` of its own index space.
struct Run<T> {
    start: usize,
    items: Vec<T>,
}

/// Entries written in runs, with gaps where subtrees built apart go.
struct Runs<T> {
    runs: Vec<Run<T>>,
    /// Length of the index space, gaps included.
    len: usize,
}

impl<T> Default for Runs<T> {
    fn default() -> Self {
        Runs {
            runs: Vec::new(),
            len: 0,
        }
    }
}

impl<T> Runs<T> {
    /// The run that the next entry goes into (a new one after a gap).
    #[inline]
    fn tail(&mut self) -> &mut Vec<T> {
        let len = self.len;
        if self
            .runs
            .last()
            .is_none_or(|r| r.start + r.items.len() != len)
        {
            self.runs.push(Run {
                start: len,
                items: Vec::new(),
            });
        }
        &mut self.runs.last_mut().expect("just pushed").items
    }

    #[inline]
    fn extend(&mut self, items: impl IntoIterator<Item = T>) {
        let tail = self.tail();
        let before = tail.len();
        tail.extend(items);
        let added = tail.len() - before;
        self.len += added;
    }

    /// The entry at `i`, which this `Out` wrote itself (not in a gap).
    #[inline]
    fn get_mut(&mut self, i: usize) -> &mut T {
        // Most writes are to the run being written.
        let last = self.runs.len() - 1;
        let k = if self.runs[last].start <= i {
            last
        } else {
            self.runs.partition_point(|r| r.start <= i) - 1
        };
        let run = &mut self.runs[k];
        &mut run.items[i - run.start]
    }

    /// Each run's start and entries.
    fn iter(&self) -> impl Iterator<Item = (usize, &[T])> {
        self.runs.iter().map(|r| (r.start, &r.items[..]))
    }

    /// The entries of an `Out` that has no gaps (one run at most).
    fn whole(self) -> Vec<T> {
        debug_assert!(self.runs.len() <= 1);
        self.runs.into_iter().next().map_or(Vec::new(), |r| r.items)
    }

    fn first(&self) -> &T {
        &self.runs[0].items[0]
    }
}

/// A subtree built apart, and where it goes: its index spaces start `node_base`,
/// `leaf_base` and `index_base` later than this `Out`'s (its root, node 0, is already
/// in the parent's slot, so its node `i` goes to `node_base + i`).
struct Apart {
    out: Out,
    node_base: usize,
    leaf_base: usize,
    index_base: usize,
}

/// What one build (or one subtree built apart) has written.
pub(super) struct Out {
    nodes: Runs<KdNode>,
    leaves: Runs<[u32; 2]>,
    prim_indices: Runs<u32>,
    apart: Vec<Apart>,
}

impl Out {
    /// Buffers for a subtree, its root at node 0 (a leaf for now).
    pub(super) fn apart() -> Out {
        let mut out = Out {
            nodes: Runs::default(),
            leaves: Runs::default(),
            prim_indices: Runs::default(),
            apart: Vec::new(),
        };
        out.nodes.extend([KdNode::leaf(0)]);
        out
    }

    /// Makes the node at `slot` an inner node and appends its child pair (leaves for
    /// now); returns the left child's index.
    pub(super) fn inner(&mut self, slot: usize, axis: usize, pos: f32) -> usize {
        let first = self.nodes.len;
        assert!(first < MAX_CHILD as usize, "kd-tree: too many nodes");
        *self.nodes.get_mut(slot) = KdNode::inner(axis as u32, pos, first as u32);
        self.nodes.extend([KdNode::leaf(0), KdNode::leaf(0)]);
        first
    }

    /// Makes the node at `slot` a leaf holding `prims` in ascending id order.
    pub(super) fn leaf(&mut self, slot: usize, prims: impl Iterator<Item = u32>) {
        let first = self.prim_indices.len;
        let tail = self.prim_indices.tail();
        let from = tail.len();
        tail.extend(prims);
        tail[from..].sort_unstable();
        let count = tail.len() - from;
        self.prim_indices.len += count;
        let leaf = self.leaves.len;
        assert!(leaf <= MAX_INDEX as usize, "kd-tree: too many leaves");
        self.leaves.extend([[first as u32, count as u32]]);
        *self.nodes.get_mut(slot) = KdNode::leaf(leaf as u32);
    }

    /// Takes `sub`, a subtree built into its own buffers with its root at node 0,
    /// putting its root into `slot` and the rest after what this `Out` holds so far.
    pub(super) fn append(&mut self, sub: Out, slot: usize) {
        let node_base = self.nodes.len - 1;
        let leaf_base = self.leaves.len;
        let index_base = self.prim_indices.len;
        *self.nodes.get_mut(slot) = relocate(sub.nodes.first(), node_base, leaf_base);
        self.nodes.len += sub.nodes.len - 1;
        self.leaves.len += sub.leaves.len;
        self.prim_indices.len += sub.prim_indices.len;
        self.apart.push(Apart {
            out: sub,
            node_base,
            leaf_base,
            index_base,
        });
    }

    /// The whole arrays: nodes (leaves as their ranges of the index lists,
    /// [`with_leaf_ranges`]), leaf table and index lists, each piece copied once, on
    /// the current rayon pool when `parallel`.
    pub(super) fn finish(
        self,
        parallel: bool,
        meter: Meter,
    ) -> (Vec<KdNode>, Vec<[u32; 2]>, Vec<u32>) {
        if self.apart.is_empty() {
            // Built in one piece (a serial build): the arrays are the runs themselves.
            let (nodes, leaves) = (self.nodes.whole(), self.leaves.whole());
            return (
                with_leaf_ranges(nodes, &leaves),
                leaves,
                self.prim_indices.whole(),
            );
        }
        let mut pieces = Vec::new();
        self.pieces(Bases::default(), false, &mut pieces);
        let leaf = |p: &Piece, &[first, count]: &[u32; 2]| {
            [(first as usize + p.bases.index) as u32, count]
        };
        let leaves = gather(&pieces, |p| p.leaves, |p| p.leaf_dst, leaf, parallel, meter);
        let node = |p: &Piece, n: &KdNode| ranged(relocate(n, p.bases.node, p.bases.leaf), &leaves);
        let index = |_: &Piece, &i: &u32| i;
        (
            gather(&pieces, |p| p.nodes, |p| p.node_dst, node, parallel, meter),
            leaves,
            gather(
                &pieces,
                |p| p.indices,
                |p| p.index_dst,
                index,
                parallel,
                meter,
            ),
        )
    }

    /// Lists this `Out`'s runs and, recursively, those of the subtrees built apart,
    /// with where each goes; `skip_root` leaves out node 0 (a subtree's root, which is
    /// in its parent's slot).
    fn pieces<'a>(&'a self, bases: Bases, skip_root: bool, out: &mut Vec<Piece<'a>>) {
        for (start, items) in self.nodes.iter() {
            let skip = usize::from(skip_root && start == 0);
            out.push(Piece {
                bases,
                nodes: &items[skip..],
                node_dst: bases.node + start + skip,
                ..Piece::default()
            });
        }
        for (start, items) in self.leaves.iter() {
            out.push(Piece {
                bases,
                leaves: items,
                leaf_dst: bases.leaf + start,
                ..Piece::default()
            });
        }
        for (start, items) in self.prim_indices.iter() {
            out.push(Piece {
                bases,
                indices: items,
                index_dst: bases.index + start,
                ..Piece::default()
            });
        }
        for a in &self.apart {
            let inner = Bases {
                node: bases.node + a.node_base,
                leaf: bases.leaf + a.leaf_base,
                index: bases.index + a.index_base,
            };
            a.out.pieces(inner, true, out);
        }
    }
}

/// How far a piece's indices move: added to its node, child, leaf and index numbers.
#[derive(Clone, Copy, Default)]
struct Bases {
    node: usize,
    leaf: usize,
    index: usize,
}

/// One run to copy into the final arrays (only one of its three slices is non-empty).
#[derive(Default)]
struct Piece<'a> {
    bases: Bases,
    nodes: &'a [KdNode],
    node_dst: usize,
    leaves: &'a [[u32; 2]],
    leaf_dst: usize,
    indices: &'a [u32],
    index_dst: usize,
}

/// One of the final arrays: every piece's `slice` mapped by `map` and written at its
/// `dst`. The pieces tile the array.
fn gather<'a, T: Copy + Send + Sync + bytemuck::Zeroable + 'a>(
    pieces: &[Piece<'a>],
    slice: impl Fn(&Piece<'a>) -> &'a [T] + Sync,
    dst: impl Fn(&Piece<'a>) -> usize,
    map: impl Fn(&Piece<'a>, &T) -> T + Sync,
    parallel: bool,
    meter: Meter,
) -> Vec<T> {
    let mut jobs: Vec<(usize, &Piece)> = (pieces.iter())
        .filter(|p| !slice(p).is_empty())
        .map(|p| (dst(p), p))
        .collect();
    jobs.sort_unstable_by_key(|j| j.0);
    let mut at = 0;
    for &(d, p) in &jobs {
        assert_eq!(d, at, "kd-tree: the pieces of a build must tile its arrays");
        at += slice(p).len();
    }
    let parts: Vec<(&Piece, &[T])> = jobs.iter().map(|&(_, p)| (p, slice(p))).collect();
    concat(&parts, |p, x| map(p, x), T::zeroed(), parallel, meter)
}

/// The `parts`' slices one after another, each element mapped by `map` with its part's
/// key; on the current rayon pool when `parallel` (one job per part, the array first
/// filled with `fill`: a fresh allocation that the allocator takes from its heap would
/// be zeroed by one thread, 1.7 ms of the bunny's 4 ms serial part).
pub(super) fn concat<K: Sync, S: Sync, T: Copy + Send + Sync>(
    parts: &[(K, &[S])],
    map: impl Fn(&K, &S) -> T + Sync,
    fill: T,
    parallel: bool,
    meter: Meter,
) -> Vec<T> {
    let len = parts.iter().map(|(_, s)| s.len()).sum();
    let mut all = Vec::with_capacity(len);
    if !parallel {
        for (k, s) in parts {
            all.extend(s.iter().map(|x| map(k, x)));
        }
        return all;
    }
    meter.hand_off(|| {
        (rayon::iter::repeat_n(fill, len))
            .with_min_len(JOB)
            .with_max_len(JOB)
            .map_init(|| meter.working(), |_, z| z)
            .collect_into_vec(&mut all)
    });
    let mut rest = &mut all[..];
    let mut work = Vec::with_capacity(parts.len());
    for (k, s) in parts {
        let (here, after) = rest.split_at_mut(s.len());
        work.push((here, k, *s));
        rest = after;
    }
    meter.hand_off(|| {
        work.into_par_iter().for_each(|(here, k, s)| {
            meter.work(|| {
                for (d, x) in here.iter_mut().zip(s) {
                    *d = map(k, x);
                }
            })
        })
    });
    all
}

/// `n` moved from its own buffers to ones where its child pairs start `node_base` and
/// its leaves `leaf_base` later.
fn relocate(n: &KdNode, node_base: usize, leaf_base: usize) -> KdNode {
    if n.is_leaf() {
        KdNode::leaf(n.leaf_index() + leaf_base as u32)
    } else {
        let left = n.children() as usize + node_base;
        assert!(left < MAX_CHILD as usize, "kd-tree: too many nodes");
        KdNode::inner(n.axis() as u32, n.split, left as u32)
    }
}
