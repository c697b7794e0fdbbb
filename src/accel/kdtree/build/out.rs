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
use crate::accel::occupancy::Meter;
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

    /// Each run as a piece going to `offset` plus its start, its first `skip` entries
    /// (at most one, a subtree's root) left out.
    fn pieces<'a>(&'a self, bases: Bases, offset: usize, skip: usize, out: &mut Vec<Piece<'a, T>>) {
        for r in &self.runs {
            let skip = if r.start == 0 { skip } else { 0 };
            out.push(Piece {
                bases,
                dst: offset + r.start + skip,
                items: &r.items[skip..],
            });
        }
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
        let mut pieces = Pieces::default();
        self.pieces(Bases::default(), false, &mut pieces);
        let leaf =
            |b: &Bases, &[first, count]: &[u32; 2]| [(first as usize + b.index) as u32, count];
        let leaves = gather(pieces.leaves, leaf, parallel, meter);
        let node = |b: &Bases, n: &KdNode| ranged(relocate(n, b.node, b.leaf), &leaves);
        let nodes = gather(pieces.nodes, node, parallel, meter);
        let indices = gather(pieces.indices, |_, &i| i, parallel, meter);
        (nodes, leaves, indices)
    }

    /// Lists this `Out`'s runs and, recursively, those of the subtrees built apart,
    /// with where each goes; `skip_root` leaves out node 0 (a subtree's root, which is
    /// in its parent's slot).
    fn pieces<'a>(&'a self, bases: Bases, skip_root: bool, out: &mut Pieces<'a>) {
        self.nodes
            .pieces(bases, bases.node, usize::from(skip_root), &mut out.nodes);
        self.leaves.pieces(bases, bases.leaf, 0, &mut out.leaves);
        self.prim_indices
            .pieces(bases, bases.index, 0, &mut out.indices);
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

/// One run to copy into a final array: its entries, where they go and the bases its
/// numbers move by.
struct Piece<'a, T> {
    bases: Bases,
    dst: usize,
    items: &'a [T],
}

/// The pieces of the three arrays.
#[derive(Default)]
struct Pieces<'a> {
    nodes: Vec<Piece<'a, KdNode>>,
    leaves: Vec<Piece<'a, [u32; 2]>>,
    indices: Vec<Piece<'a, u32>>,
}

/// One of the final arrays: every piece's entries mapped by `map` with the piece's
/// bases and written at its `dst`. The pieces tile the array.
fn gather<T: Copy + Send + Sync + bytemuck::Zeroable>(
    mut pieces: Vec<Piece<T>>,
    map: impl Fn(&Bases, &T) -> T + Sync,
    parallel: bool,
    meter: Meter,
) -> Vec<T> {
    pieces.retain(|p| !p.items.is_empty());
    pieces.sort_unstable_by_key(|p| p.dst);
    let mut at = 0;
    for p in &pieces {
        assert_eq!(
            p.dst, at,
            "kd-tree: the pieces of a build must tile its arrays"
        );
        at += p.items.len();
    }
    let parts: Vec<(Bases, &[T])> = pieces.iter().map(|p| (p.bases, p.items)).collect();
    concat(&parts, map, T::zeroed(), parallel, meter)
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
        meter
            .jobs(rayon::iter::repeat_n(fill, len))
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
