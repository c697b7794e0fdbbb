//! The fast builder's small nodes: the exact SAH without events.
//!
//! Most of a tree's nodes are tiny (Sponza: 0.8M of its 1.05M nodes hold fewer than 16
//! references). Below [`SMALL`] references a node keeps its references' bounds in
//! fixed arrays, per axis each reference's minimum and maximum side by side (padding
//! NaN, which compares false), and prices each candidate plane, every reference's
//! minimum and maximum strictly inside the cell, by counting the references left of
//! it, right of it and lying in it: the counts the sweep has at that plane, priced with
//! the same [`PlaneCost`]. The counting runs over the candidates 16 at a time, one
//! reference after another (vector compares), and the pricing and the search for the
//! cheapest over the same chunks, so a node prices only the chunks its references fill.
//! The cheapest plane wins, ties going to the lower axis, then the lower position, as
//! in the sweep. The work grows as n^2 per node, but in vectors: up to 48 references it
//! is cheaper than keeping sorted lists (perf/log/kdtree.md, "Fast build, second round"). A
//! straddling triangle is cut by the split plane alone and its sides met with its
//! bounds in the cell ([`Builder::split_within`]): a little looser than clipping it to
//! the cell first, and cheaper.

use super::{Builder, Out, PlaneCost, child_cells, cut_bounds, from_order_bits, order_bits};
use crate::geom::Aabb;
use crate::simd::{AMap, Simd, dispatch};

/// Most references a small node holds.
pub(super) const SMALL: usize = 48;

/// Candidate planes of one axis of a small node: every reference's minimum and maximum
/// (NaN past the node's references, which prices as no plane).
const CANDIDATES: usize = 2 * SMALL;

/// Candidates counted and priced together: one 512-bit vector of `f32`.
const LANES: usize = 16;

/// A small node's references: per axis, reference `i`'s minimum in `lim[axis][2 i]` and
/// maximum in `lim[axis][2 i + 1]`, so the node's candidate planes are the first
/// `2 len` entries and a node of few references prices only the chunks it fills; NaN
/// past them.
#[derive(Clone, Copy)]
pub(super) struct SmallNode {
    lim: [[f32; CANDIDATES]; 3],
    prim: [u32; SMALL],
    len: usize,
}

impl SmallNode {
    pub(super) fn new() -> SmallNode {
        SmallNode {
            lim: [[f32::NAN; CANDIDATES]; 3],
            prim: [0; SMALL],
            len: 0,
        }
    }

    /// Drops every reference, keeping the arrays (a reused node: see [`SmallNode::seal`]).
    #[inline]
    fn clear(&mut self) {
        self.len = 0;
    }

    /// Pads the candidates past the references with NaN up to the end of their last
    /// chunk: all of a node that pricing reads beyond its references. A reused node
    /// needs only this, not [`SmallNode::new`]'s fill of every entry.
    #[inline]
    fn seal(&mut self) {
        let (used, end) = (2 * self.len, (2 * self.len).next_multiple_of(LANES));
        for lim in &mut self.lim {
            lim[used..end].fill(f32::NAN);
        }
    }

    /// The union of the node's references' bounds.
    fn union(&self) -> Aabb {
        (0..self.len).fold(Aabb::EMPTY, |b, i| b.union(&self.bounds(i)))
    }

    /// Appends a reference.
    #[inline]
    pub(super) fn push(&mut self, bounds: &Aabb, prim: u32) {
        let i = self.len;
        for axis in 0..3 {
            self.lim[axis][2 * i] = bounds.min[axis];
            self.lim[axis][2 * i + 1] = bounds.max[axis];
        }
        self.prim[i] = prim;
        self.len += 1;
    }

    /// Sets one coordinate of the reference in `slot` (the sweep's events, one by one).
    #[inline]
    pub(super) fn set(&mut self, slot: usize, axis: usize, min: Option<f32>, max: Option<f32>) {
        if let Some(x) = min {
            self.lim[axis][2 * slot] = x;
        }
        if let Some(x) = max {
            self.lim[axis][2 * slot + 1] = x;
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
            b.min[axis] = self.lim[axis][2 * i];
            b.max[axis] = self.lim[axis][2 * i + 1];
        }
        b
    }

    /// The cheapest plane on each axis as `(cost, position)`, ties going to the lower
    /// position; `cost` is infinite when no candidate lies strictly inside the cell. For
    /// each reference the counts of every candidate are updated in one loop over the
    /// candidates (vector compares), then every candidate is priced in a second loop:
    /// the same counts and costs as pricing one candidate at a time. Which side takes
    /// the planar references is left to [`SmallNode::planar_left`], for the winner only.
    #[inline(always)]
    fn best_on_axes(&self, pricing: &[PlaneCost; 3]) -> [(f32, f32); 3] {
        match (2 * self.len).div_ceil(LANES) {
            1 => self.best_on_axes_in::<1>(pricing),
            2 => self.best_on_axes_in::<2>(pricing),
            3 => self.best_on_axes_in::<3>(pricing),
            4 => self.best_on_axes_in::<4>(pricing),
            5 => self.best_on_axes_in::<5>(pricing),
            _ => self.best_on_axes_in::<{ CANDIDATES / LANES }>(pricing),
        }
    }

    /// [`SmallNode::best_on_axes`] for a node that fills `C` chunks: one choice of `C`
    /// for the three axes.
    #[inline(always)]
    fn best_on_axes_in<const C: usize>(&self, pricing: &[PlaneCost; 3]) -> [(f32, f32); 3] {
        [0, 1, 2].amap(
            #[inline(always)]
            |axis| self.best_in_chunks::<C>(axis, &pricing[axis]),
        )
    }

    /// [`SmallNode::best_on_axes`] on `axis` over the first `C` chunks of candidates, the counts
    /// in arrays of just those chunks (so a node of few references clears and prices
    /// only what it fills).
    #[inline(always)]
    fn best_in_chunks<const C: usize>(&self, axis: usize, pricing: &PlaneCost) -> (f32, f32) {
        let cand = &self.lim[axis];
        let mut left: Counts<C> = [[0.0; LANES]; C];
        let mut right: Counts<C> = [[0.0; LANES]; C];
        let mut planar: Counts<C> = [[0.0; LANES]; C];
        count::<C>(cand, self.len, (&mut left, &mut right, &mut planar));
        // Each candidate's cost and position as one integer key (costs and positions
        // order like their `order_bits`), so the cheapest, then lowest, is a vector
        // minimum whose bits give back both; a candidate outside the cell gets the
        // largest key.
        let mut least = [u64::MAX; LANES];
        for c in 0..C {
            let p: &[f32; LANES] = cand[c * LANES..][..LANES].try_into().expect("chunk");
            let (l, r, pl) = (&left[c], &right[c], &planar[c]);
            for i in 0..LANES {
                let p = p[i] + 0.0;
                let prob = pricing.probabilities(p);
                let with_left = pricing.cost_of_counts(prob, l[i] + pl[i], r[i]);
                let with_right = pricing.cost_of_counts(prob, l[i], r[i] + pl[i]);
                let c = if with_left < with_right {
                    with_left
                } else {
                    with_right
                };
                let key = (order_bits(c) as u64) << 32 | order_bits(p) as u64;
                let key = if p > pricing.lo && p < pricing.hi {
                    key
                } else {
                    u64::MAX
                };
                least[i] = least[i].min(key);
            }
        }
        let best = least.iter().fold(u64::MAX, |a, &k| a.min(k));
        if best == u64::MAX {
            return (f32::INFINITY, f32::INFINITY);
        }
        (
            from_order_bits((best >> 32) as u32),
            from_order_bits(best as u32),
        )
    }

    /// Whether the references lying in the plane `pos` on `axis` go left: the side
    /// [`SmallNode::best_on_axes`] priced cheaper (right on a tie), from the counts
    /// every candidate at `pos` shares.
    fn planar_left(&self, axis: usize, pos: f32, pricing: &PlaneCost) -> bool {
        let (mut left, mut right, mut planar) = (0u32, 0u32, 0u32);
        for i in 0..self.len {
            let (lo, hi) = (self.lim[axis][2 * i], self.lim[axis][2 * i + 1]);
            left += (lo < pos) as u32;
            right += (hi > pos) as u32;
            planar += (lo == hi && lo == pos) as u32;
        }
        let prob = pricing.probabilities(pos);
        pricing.cost(prob, left + planar, right) < pricing.cost(prob, left, right + planar)
    }
}

/// One count per candidate of `C` chunks.
type Counts<const C: usize> = [[f32; LANES]; C];

/// The counts of the first `C` chunks of candidates `cand` of a node of `len` references:
/// per candidate, the references starting left of it, ending right of it and lying in
/// it, as floats (exact; the pricing then needs no conversions). `C` is a constant so the
/// chunks and their counts stay in vector registers while the references go by.
#[inline(always)]
fn count<const C: usize>(
    cand: &[f32; CANDIDATES],
    len: usize,
    (left, right, planar): (&mut Counts<C>, &mut Counts<C>, &mut Counts<C>),
) {
    let (left, right, planar) = (
        left.as_flattened_mut(),
        right.as_flattened_mut(),
        planar.as_flattened_mut(),
    );
    for i in 0..len {
        let (lo, hi) = (cand[2 * i], cand[2 * i + 1]);
        for j in 0..C * LANES {
            left[j] = count_if(left[j], lo < cand[j]);
            right[j] = count_if(right[j], hi > cand[j]);
        }
        if lo == hi {
            for j in 0..C * LANES {
                planar[j] = count_if(planar[j], lo == cand[j]);
            }
        }
    }
}

/// `count` plus one where `yes`, written for the vector code each ISA does best: with
/// AVX-512, a select of the incremented count (one masked add); with AVX2, adding the
/// compare's 0 or 1 (a select there costs a blend: 2.5% of the conference build).
#[inline(always)]
fn count_if(count: f32, yes: bool) -> f32 {
    if cfg!(target_feature = "avx512f") {
        if yes { count + 1.0 } else { count }
    } else {
        count + if yes { 1.0 } else { 0.0 }
    }
}

/// The chosen plane of a small node.
struct Plane {
    axis: usize,
    pos: f32,
    planar_left: bool,
}

thread_local! {
    /// Each thread's children of small nodes, a pair per level below the small subtree
    /// being built: reused, so a small node does not fill two fresh nodes' 2.7 KB with
    /// NaN (about 5% of Sponza's build, perf/log/kdtree.md).
    static KIDS: std::cell::Cell<Vec<[SmallNode; 2]>> = const { std::cell::Cell::new(Vec::new()) };
}

impl Builder<'_> {
    /// Builds the subtree of a small node at `depth` in `cell`, its root at `slot`:
    /// `fill` puts its references (fewer than [`SMALL`]) into an empty node, one this
    /// thread reuses rather than a fresh one.
    pub(super) fn build_small(
        &self,
        cell: Aabb,
        depth: u32,
        slot: usize,
        out: &mut Out,
        fill: impl FnOnce(&mut SmallNode),
    ) {
        let mut kids = KIDS.take();
        // A split happens only above the depth limit: one level of children per level
        // left, and one more for the node itself.
        let levels = self.max_depth.saturating_sub(depth) as usize + 1;
        if kids.len() < levels {
            kids.resize(levels, [SmallNode::new(), SmallNode::new()]);
        }
        let ([node, _], levels) = kids.split_first_mut().expect("a level for the node");
        node.clear();
        fill(node);
        node.seal();
        self.build_small_in(cell, node, depth, slot, out, levels);
        KIDS.set(kids);
    }

    /// [`Builder::build_small`] with the children of each level below in `levels`.
    fn build_small_in(
        &self,
        cell: Aabb,
        node: &SmallNode,
        depth: u32,
        slot: usize,
        out: &mut Out,
        levels: &mut [[SmallNode; 2]],
    ) {
        let plane = if self.may_split(&cell, node.len, depth) {
            self.small_plane(&cell, node)
        } else {
            None
        };
        let Some(Plane {
            axis,
            pos,
            planar_left,
        }) = plane
        else {
            let bounds = cut_bounds(node.len, || node.union());
            self.leaf(
                out,
                slot,
                cell,
                depth,
                bounds,
                node.prim[..node.len].iter().copied(),
            );
            return;
        };
        let (kids, deeper) = levels
            .split_first_mut()
            .expect("a level of children below every split above the depth limit");
        kids.iter_mut().for_each(SmallNode::clear);
        for i in 0..node.len {
            let (lo, hi) = (node.lim[axis][2 * i], node.lim[axis][2 * i + 1]);
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
        kids.iter_mut().for_each(SmallNode::seal);
        let (left_cell, right_cell) = child_cells(&cell, axis, pos);
        let first = out.inner(slot, axis, pos);
        self.build_small_in(left_cell, &kids[0], depth + 1, first, out, deeper);
        self.build_small_in(right_cell, &kids[1], depth + 1, first + 1, out, deeper);
    }

    /// The cheapest plane of a small node if it beats a leaf (see the module doc); a
    /// later axis must be strictly cheaper to win. The candidate counts are vector
    /// loops: they run compiled for the instruction set in use ([`dispatch`]).
    fn small_plane(&self, cell: &Aabb, node: &SmallNode) -> Option<Plane> {
        dispatch!(4; self.small_plane_as::<@>(cell, node))
    }

    /// [`Builder::small_plane`] inside the entry of backend `B`'s instruction set.
    #[inline(always)]
    #[allow(
        clippy::extra_unused_type_parameters,
        reason = "B picks the entry (the instruction set) the body is compiled for"
    )]
    fn small_plane_as<B: Simd>(&self, cell: &Aabb, node: &SmallNode) -> Option<Plane> {
        let mut best = None;
        let mut best_cost = self.params.intersection_cost * node.len as f32;
        let pricing = [
            PlaneCost::new(cell, 0, self.params)?,
            PlaneCost::new(cell, 1, self.params)?,
            PlaneCost::new(cell, 2, self.params)?,
        ];
        for (axis, (cost, pos)) in node.best_on_axes(&pricing).into_iter().enumerate() {
            if cost < best_cost {
                best_cost = cost;
                best = Some((axis, pos, pricing[axis]));
            }
        }
        let (axis, pos, pricing) = best?;
        Some(Plane {
            axis,
            pos,
            planar_left: node.planar_left(axis, pos, &pricing),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::kdtree::build::BuildParams;
    use crate::scene::generate::Rng;
    use glam::Vec3;

    /// A node reused after holding more references ([`SmallNode::clear`], then pushes and
    /// [`SmallNode::seal`]) prices every axis as a fresh node of the same references,
    /// at every size up to [`SMALL`].
    #[test]
    fn reused_nodes_price_as_fresh_ones() {
        let mut rng = Rng::new(5);
        let cell = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let params = BuildParams::default();
        let pricing = [0, 1, 2].map(|a| PlaneCost::new(&cell, a, &params).expect("a cell"));
        let mut reused = SmallNode::new();
        for round in 0..200 {
            let len = 1 + rng.below(SMALL as u32) as usize;
            let boxes: Vec<Aabb> = (0..len)
                .map(|_| {
                    let (a, b) = (
                        rng.point(Vec3::ZERO, Vec3::ONE),
                        rng.point(Vec3::ZERO, Vec3::ONE),
                    );
                    Aabb::new(a.min(b), a.max(b))
                })
                .collect();
            let mut fresh = SmallNode::new();
            reused.clear();
            for (i, b) in boxes.iter().enumerate() {
                fresh.push(b, i as u32);
                reused.push(b, i as u32);
            }
            reused.seal();
            let bits = |n: &SmallNode| {
                n.best_on_axes(&pricing)
                    .map(|(c, p)| (c.to_bits(), p.to_bits()))
            };
            assert_eq!(
                bits(&reused),
                bits(&fresh),
                "round {round}, {len} references"
            );
        }
    }
}
