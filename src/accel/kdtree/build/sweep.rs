//! The exact SAH sweep of Wald & Havran, "On building fast kd-trees for ray tracing, and
//! on doing that in O(N log N)" (2006): the reference builder (`--builder exact`) and the
//! fast builder's way of finishing small nodes.
//!
//! - Events: every primitive gives, per axis, a start and an end event at the bounds of
//!   its part inside the node (or one planar event when that part is flat). Each event is
//!   one `u64` whose integer order is the sweep order: position, then end < planar <
//!   start, then primitive id. The events are sorted once, at the subtree's root.
//! - A node sweeps its three sorted lists once to price every candidate plane with the
//!   surface area heuristic (planar primitives go to the cheaper side), classifies its
//!   primitives left, right or both in one pass over the split axis's events, and splits
//!   its lists by filtering; only the straddling primitives get new events, which are
//!   sorted (few) and merged in during the filtering.
//! - Memory: the children's lists go into per-depth buffers that only grow (a node at
//!   depth d writes into `levels[d]`, which stay put while the left subtree is built
//!   below them), and the per-node scratch is per thread, so a node allocates nothing
//!   once the buffers have their size.

use super::small::{SMALL, SmallNode};
use super::{
    Builder, BuilderKind, MAX_DEPTH, Out, PlaneCost, Ref, child_cells, cut_bounds, from_order_bits,
    order_bits,
};
use crate::accel::kdtree::node::MAX_INDEX;
use crate::geom::Aabb;

const END: u64 = 0;
const PLANAR: u64 = 1;
const START: u64 = 2;

/// An event key. `pos + 0.0` turns -0.0 into +0.0 so both zeros are one position.
#[inline]
fn event(pos: f32, kind: u64, prim: u32) -> u64 {
    ((order_bits(pos + 0.0) as u64) << 32) | (kind << 30) | prim as u64
}

#[inline]
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

/// One thread's buffers for sweeping subtrees: the subtree root's events, the per-depth
/// lists and the scratch. A subtree built apart takes one from the build's spares
/// ([`Builder::take_space`]) and gives it back, so the scratch (one byte per primitive
/// of the scene) is allocated about once per thread, not once per parallel subtree (4M
/// triangles: thousands of 4 MiB arrays), and nodes allocate nothing once the buffers
/// have their size. Every node writes the scratch before reading it, so a reused space
/// changes nothing.
pub(super) struct SweepSpace {
    events: [Vec<u64>; 3],
    levels: Levels,
    scratch: Scratch,
}

impl Builder<'_> {
    fn scratch(&self) -> Scratch {
        Scratch {
            side: vec![0; self.prim_total],
            straddlers: Vec::new(),
            fresh: Default::default(),
        }
    }

    /// A spare sweep space, or a new one.
    pub(super) fn take_space(&self) -> SweepSpace {
        let spare = self.spare.lock().map(|mut s| s.pop()).unwrap_or(None);
        spare.unwrap_or_else(|| SweepSpace {
            events: Default::default(),
            levels: new_levels(),
            scratch: self.scratch(),
        })
    }

    /// Gives a sweep space back for the next subtree built apart.
    pub(super) fn put_space(&self, space: SweepSpace) {
        if let Ok(mut spare) = self.spare.lock() {
            spare.push(space);
        }
    }

    /// Builds the whole tree of `refs` (the bounded primitives in `cell`) with the sweep:
    /// the exact builder.
    pub(super) fn build_swept(&self, cell: Aabb, refs: &[Ref], out: &mut Out) {
        let mut space = self.take_space();
        self.sweep_refs(cell, refs, 0, 0, out, &mut space, self.params.parallel);
    }

    /// Builds the subtree of the node at `depth` whose primitives' parts in `cell` have
    /// the bounds of `refs`, its root at `slot`: makes and sorts its events (the three
    /// axes in parallel when `parallel_sort`), then sweeps.
    #[allow(
        clippy::too_many_arguments,
        reason = "one call per subtree, all distinct"
    )]
    pub(super) fn sweep_refs(
        &self,
        cell: Aabb,
        refs: &[Ref],
        depth: u32,
        slot: usize,
        out: &mut Out,
        space: &mut SweepSpace,
        parallel_sort: bool,
    ) {
        let SweepSpace {
            events,
            levels,
            scratch,
        } = space;
        for list in events.iter_mut() {
            list.clear();
            list.reserve(2 * refs.len());
        }
        for r in refs {
            push_events(events, &r.bounds, r.prim);
        }
        if parallel_sort {
            use rayon::prelude::*;
            let m = self.meter;
            m.hand_off(|| {
                events
                    .par_iter_mut()
                    .for_each(|l| m.work(|| l.sort_unstable()))
            });
        } else {
            events.iter_mut().for_each(|l| l.sort_unstable());
        }
        let task = Task {
            cell,
            events: [&events[0], &events[1], &events[2]],
            prim_count: refs.len() as u32,
            depth,
        };
        self.build_node(task, slot, out, scratch, levels);
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
        if self.params.builder == BuilderKind::Fast && (task.prim_count as usize) < SMALL {
            let side = &mut scratch.side;
            self.build_small(task.cell, task.depth, slot, out, |node| {
                small_node(&task, side, node)
            });
            return;
        }
        let split = if self.may_split(&task.cell, task.prim_count as usize, task.depth) {
            self.find_split(&task)
        } else {
            None
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
        let first = out.inner(slot, split.axis, split.pos);
        let big = n_left.max(n_right) >= self.params.parallel_min_prims;
        if self.params.parallel && big {
            let m = self.meter;
            let (_, sub) = m.hand_off(|| {
                rayon::join(
                    || m.work(|| self.build_node(left, first, out, scratch, deeper)),
                    || {
                        m.work(|| {
                            let mut sub = Out::apart();
                            // The spare's scratch, but lists of its own: they would keep
                            // this subtree's size in the spare after it is done.
                            let mut space = self.take_space();
                            let mut levels = new_levels();
                            self.build_node(right, 0, &mut sub, &mut space.scratch, &mut levels);
                            self.put_space(space);
                            sub
                        })
                    },
                )
            });
            out.append(sub, first + 1);
        } else {
            self.build_node(left, first, out, scratch, deeper);
            self.build_node(right, first + 1, out, scratch, deeper);
        }
    }

    /// A leaf holding the node's primitives in ascending id order.
    fn make_leaf(&self, task: &Task, slot: usize, out: &mut Out) {
        // Each axis's events are in order of position: its first and last are the
        // bounds of the node's references.
        let bounds = cut_bounds(task.prim_count as usize, || {
            let mut b = Aabb::EMPTY;
            for (axis, list) in task.events.iter().enumerate() {
                if let (Some(&lo), Some(&hi)) = (list.first(), list.last()) {
                    b.min[axis] = event_pos(lo);
                    b.max[axis] = event_pos(hi);
                }
            }
            b
        });
        self.leaf(
            out,
            slot,
            task.cell,
            task.depth,
            bounds,
            task.events[0]
                .iter()
                .filter(|&&e| event_kind(e) != END)
                .map(|&e| event_prim(e)),
        );
    }

    /// The cheapest plane over all three axes by one sweep each (Wald & Havran's
    /// `FindPlane`). Ties keep the first plane found, so the choice is deterministic.
    fn find_split(&self, task: &Task) -> Option<Split> {
        let n = task.prim_count;
        let mut best: Option<Split> = None;
        let mut best_cost = f32::INFINITY;
        for (axis, events) in task.events.iter().enumerate() {
            let pricing = PlaneCost::new(&task.cell, axis, self.params)?;
            let (lo, hi) = (pricing.lo, pricing.hi);
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
                    let p = pricing.probabilities(pos);
                    let cost = |nl: u32, nr: u32| pricing.cost(p, nl, nr);
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
        let [left_new, right_new] = fresh;
        left_new.iter_mut().for_each(Vec::clear);
        right_new.iter_mut().for_each(Vec::clear);
        for &prim in straddlers.iter() {
            let parts = self.split_prim(prim, &task.cell, axis, pos);
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
}

/// Puts the references of `task` into the empty small node `node` (in the order of their
/// first events on x), their coordinates read back from the events; `slot` is scratch
/// indexed by primitive.
fn small_node(task: &Task, slot: &mut [u8], node: &mut SmallNode) {
    for &e in task.events[0] {
        if event_kind(e) != END {
            let prim = event_prim(e);
            slot[prim as usize] = node.open(prim) as u8;
        }
    }
    for (axis, events) in task.events.iter().enumerate() {
        for &e in events.iter() {
            let (kind, pos) = (event_kind(e), Some(event_pos(e)));
            let i = slot[event_prim(e) as usize] as usize;
            match kind {
                START => node.set(i, axis, pos, None),
                END => node.set(i, axis, None, pos),
                _ => node.set(i, axis, pos, pos),
            }
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
}
