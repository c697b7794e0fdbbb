//! The fast builder's large nodes: min-max binning of the SAH (Shevtsov, Soupikov &
//! Kapustin, "Highly parallel fast kd-tree construction for interactive ray tracing of
//! dynamic scenes", 2007).
//!
//! - A node holds references: a primitive id and the bounds of its part in the cell.
//!   Each reference is counted in equal bins per axis ([`BINS`] for large nodes, a
//!   quarter of its references, at least [`MIN_BINS`], for smaller ones) twice, its minimum in one
//!   table and its maximum in another; one pass over the bin boundaries then knows, for
//!   each, how many references start left of it and how many end right of it, and the
//!   boundary with the lowest SAH ([`PlaneCost`], the sweep's cost) wins. A maximum on a
//!   boundary counts in the bin below it, as the partition puts it left of that plane.
//! - The references are partitioned against that plane; straddlers get perfect splits
//!   ([`Builder::split_prim`], as in the sweep).
//! - Below [`SMALL`] references the small nodes' exact counting takes over. Below
//!   [`BuildParams::sweep_below`](super::BuildParams::sweep_below) references (when set
//!   above [`SMALL`]), or when no boundary beats a leaf, the node's events are made and
//!   sorted and the exact sweep builds its subtree.
//! - Parallel: a large node bins and partitions its references in chunks of [`CHUNK`]
//!   on the rayon pool; bin counts are integers summed in any order and the chunks'
//!   outputs are concatenated in order, so the result is the serial one. Large subtrees
//!   are built in parallel as in the sweep.

use super::out::concat;
use super::small::SMALL;
use super::sweep::SweepSpace;
use super::{
    Builder, Out, PlaneCost, Ref, child_cells, cut_bounds, from_order_bits, order_bits,
    refs_bounds, tree_bounds,
};
use crate::accel::Prims;
use crate::accel::occupancy::{JOB, Meter};
use crate::geom::{Aabb, Geometry};
use glam::Vec3;
use rayon::prelude::*;
use wide::{f32x4, i32x4};

/// Most bins per axis (Mitsuba's kd-tree builder uses 128).
const BINS: usize = 128;
const _: () = assert!(BINS.is_power_of_two(), "bin indices are masked to BINS - 1");

/// Fewest bins per axis: a node of n references gets n / 4 bins between the two (the
/// refinement prices the bounds near the best boundary exactly, so small nodes lose
/// little with coarse bins, and pricing 3 x 127 boundaries would cost more than
/// counting their references).
const MIN_BINS: usize = 16;

/// Below this many references a node's straddlers are cut by the plane alone within
/// their bounds (as in the small nodes) instead of clipped to the cell again: cheaper,
/// a little looser. Above it the looseness would add up over many levels (binning with
/// it from the root: 45% more primitive tests per shadow ray in the conference room).
const CUT_WITHIN_BELOW: usize = 256;

/// References per chunk of the parallel passes (a fixed size, so the chunks, and the
/// order their outputs are joined in, do not depend on the thread count).
const CHUNK: usize = 16 * 1024;

/// Per axis, how many references have their minimum (`starts`) and their maximum
/// (`ends`) in each bin.
#[derive(Clone)]
struct Bins {
    starts: [[u32; BINS]; 3],
    ends: [[u32; BINS]; 3],
}

impl Bins {
    fn zero() -> Box<Bins> {
        Box::new(Bins::ZERO)
    }

    const ZERO: Bins = Bins {
        starts: [[0; BINS]; 3],
        ends: [[0; BINS]; 3],
    };

    fn add(mut self: Box<Bins>, other: Box<Bins>) -> Box<Bins> {
        for axis in 0..3 {
            for i in 0..BINS {
                self.starts[axis][i] += other.starts[axis][i];
                self.ends[axis][i] += other.ends[axis][i];
            }
        }
        self
    }
}

/// Maps coordinates of a cell to bins.
#[derive(Clone, Copy)]
struct Binner {
    lo: Vec3,
    /// `bins / extent` per axis (0 on a flat axis, which gets no plane).
    scale: Vec3,
    /// Bins per axis in use (at most [`BINS`]).
    bins: usize,
}

impl Binner {
    fn new(cell: &Aabb, refs: usize) -> Binner {
        let bins = (refs / 4).clamp(MIN_BINS, BINS);
        let e = cell.max - cell.min;
        let scale = Vec3::select(e.cmpgt(Vec3::ZERO), bins as f32 / e, Vec3::ZERO);
        Binner {
            lo: cell.min,
            scale,
            bins,
        }
    }

    /// The bins of a reference's minimum and maximum on the three axes:
    /// [`Binner::bins_as_floats`] in 4-lane vectors (whose max and min pick like `clamp`
    /// on finite coordinates, and on -0 give a bin 0 all the same). The clamped
    /// coordinates are not negative, so their floors are truncations: one vector
    /// conversion gives the indices.
    #[inline]
    fn bins_of(&self, b: &Aabb) -> ([usize; 3], [usize; 3]) {
        let lanes = |v: Vec3| f32x4::new([v.x, v.y, v.z, 0.0]);
        let (lo, scale) = (lanes(self.lo), lanes(self.scale));
        let top = f32x4::splat(self.bins as f32);
        let f_min = (lanes(b.min) - lo) * scale;
        let f_max = (lanes(b.max) - lo) * scale;
        let first = f_min
            .max(f32x4::ZERO)
            .min(top - f32x4::ONE)
            .fast_trunc_int();
        let last = f_max.max(f32x4::ONE).min(top).ceil().fast_trunc_int() - i32x4::ONE;
        let index = |v: i32x4| {
            let v = v.to_array();
            [0, 1, 2].map(|axis| v[axis] as usize & (BINS - 1))
        };
        (index(first), index(last.max(first)))
    }

    /// The bins of the coordinates `min`, `max` on `axis` as whole floats (the
    /// refinement only compares them). A coordinate rounded below the cell gives bin 0,
    /// one above it the last bin; a maximum on a boundary counts in the bin below it.
    #[inline]
    fn bins_as_floats(&self, min: f32, max: f32, axis: usize) -> (f32, f32) {
        let f_min = (min - self.lo[axis]) * self.scale[axis];
        let first = f_min.clamp(0.0, self.bins as f32 - 1.0).floor();
        let last = self.last_bin(max, axis);
        (first, if last > first { last } else { first })
    }

    /// The bin of a maximum `max` on `axis` before it is raised to its minimum's bin
    /// (see [`Binner::bins_as_floats`]).
    #[inline]
    fn last_bin(&self, max: f32, axis: usize) -> f32 {
        let f_max = (max - self.lo[axis]) * self.scale[axis];
        f_max.ceil().clamp(1.0, self.bins as f32) - 1.0
    }

    /// The least coordinate on `axis` that `bin_of`, a bin that never falls as the
    /// coordinate grows, puts in bin `k` or above: -inf when every coordinate is,
    /// +inf when none is. Found from the bin edge by stepping a float at a time (the
    /// edge's rounding moves it a few steps at most), or by bisection should it not.
    fn least_with(&self, axis: usize, k: usize, bin_of: impl Fn(f32) -> f32) -> f32 {
        let k = k as f32;
        let at_least = |o: u32| bin_of(from_order_bits(o)) >= k;
        let (lowest, highest) = (order_bits(f32::NEG_INFINITY), order_bits(f32::INFINITY));
        if at_least(lowest) {
            return f32::NEG_INFINITY;
        }
        if !at_least(highest) {
            return f32::INFINITY;
        }
        // Invariant of the bisection: `!at_least(lo) && at_least(hi)`.
        let (mut lo, mut hi) = (lowest, highest);
        let edge = order_bits(self.lo[axis] + k / self.scale[axis]);
        if lowest < edge && edge <= highest {
            // Walk from the edge to the answer, a float at a time.
            let mut o = edge;
            for _ in 0..8 {
                match (at_least(o - 1), at_least(o)) {
                    (false, true) => return from_order_bits(o),
                    (true, _) => o -= 1,
                    (false, false) => o += 1,
                }
                if !(lowest < o && o <= highest) {
                    break;
                }
            }
            if at_least(edge) {
                hi = edge;
            } else {
                lo = edge;
            }
        }
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if at_least(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        from_order_bits(hi)
    }

    /// Counts `refs` into `bins`.
    fn count(&self, refs: &[Ref], bins: &mut Bins) {
        for r in refs {
            let (first, last) = self.bins_of(&r.bounds);
            for axis in 0..3 {
                bins.starts[axis][first[axis]] += 1;
                bins.ends[axis][last[axis]] += 1;
            }
        }
    }
}

/// Whether a reference's first and last bins on one axis are among the two bins
/// around boundary `i` (`i - 1` and `i`), from its coordinates by compares: the bins'
/// edges as coordinates, found once per node, instead of binning every coordinate. The
/// same answers as [`Binner::bins_as_floats`], since bins never fall as coordinates
/// grow.
struct NearBins {
    /// The least minimum whose bin is `i - 1` or more, and `i + 1` or more.
    first_lo: f32,
    first_hi: f32,
    /// The same for a maximum's own bin ([`Binner::last_bin`]).
    last_lo: f32,
    last_hi: f32,
}

impl NearBins {
    fn new(binner: &Binner, axis: usize, i: usize) -> NearBins {
        let first = |x| binner.bins_as_floats(x, x, axis).0;
        let last = |x| binner.last_bin(x, axis);
        NearBins {
            first_lo: binner.least_with(axis, i - 1, first),
            first_hi: binner.least_with(axis, i + 1, first),
            last_lo: binner.least_with(axis, i - 1, last),
            last_hi: binner.least_with(axis, i + 1, last),
        }
    }

    /// `(first near, last near)` for a reference from `min` to `max`: the last bin is
    /// the maximum's own bin raised to the first.
    #[inline]
    fn test(&self, min: f32, max: f32) -> (bool, bool) {
        if min >= self.first_hi {
            return (false, false);
        }
        let first = min >= self.first_lo;
        (first, max < self.last_hi && (first || max >= self.last_lo))
    }
}

/// The bin boundary a node's plane is refined around.
struct Window {
    binner: Binner,
    axis: usize,
    boundary: usize,
}

/// The references of the root: every bounded primitive that goes into the tree, in id
/// order, with its bounds.
pub(super) fn root_refs(
    g: &Geometry,
    prims: &Prims,
    bounded: u32,
    parallel: bool,
    meter: Meter,
) -> Vec<Ref> {
    let one = |prim: u32| tree_bounds(g, prims, prim).map(|bounds| Ref { bounds, prim });
    if parallel {
        let job = JOB as u32;
        let parts: Vec<Vec<Ref>> = meter.hand_off(|| {
            (0..bounded.div_ceil(job))
                .into_par_iter()
                .map(|c| {
                    meter.work(|| {
                        (c * job..bounded.min(c * job + job))
                            .filter_map(one)
                            .collect()
                    })
                })
                .collect()
        });
        let parts: Vec<((), &[Ref])> = parts.iter().map(|p| ((), &p[..])).collect();
        concat(&parts, |_, r| *r, Ref::NONE, true, meter)
    } else {
        // Sized up front: a filter's collect would grow the array by copies.
        let mut refs = Vec::with_capacity(bounded as usize);
        refs.extend((0..bounded).filter_map(one));
        refs
    }
}

/// Which side of the plane at `pos` on `axis` a reference goes to: left, right, or
/// both (a straddler, clipped for each). A reference flat in the plane goes right,
/// where the bins count it.
#[derive(PartialEq)]
enum Side {
    Left,
    Right,
    Both,
}

#[inline]
fn side(r: &Ref, axis: usize, pos: f32) -> Side {
    let (lo, hi) = (r.bounds.min[axis], r.bounds.max[axis]);
    if lo == hi {
        if lo < pos { Side::Left } else { Side::Right }
    } else if hi <= pos {
        Side::Left
    } else if lo >= pos {
        Side::Right
    } else {
        Side::Both
    }
}

impl Builder<'_> {
    /// Builds the subtree of the node at `depth` holding `refs` in `cell`, its root at
    /// `slot`; `space` is this thread's sweep buffers (made on first use).
    pub(super) fn build_binned(
        &self,
        cell: Aabb,
        refs: Vec<Ref>,
        depth: u32,
        slot: usize,
        out: &mut Out,
        space: &mut Option<SweepSpace>,
    ) {
        let n = refs.len();
        if n < SMALL {
            self.build_small(cell, depth, slot, out, |node| {
                refs.iter().for_each(|r| node.push(&r.bounds, r.prim))
            });
            return;
        }
        if !self.may_split(&cell, n, depth) {
            let bounds = cut_bounds(n, || refs_bounds(&refs));
            self.leaf(out, slot, cell, depth, bounds, refs.iter().map(|r| r.prim));
            return;
        }
        let plane = if n >= self.params.sweep_below as usize {
            self.binned_plane(&cell, &refs)
        } else {
            None
        };
        let Some((axis, pos)) = plane else {
            let space = space.get_or_insert_with(|| self.take_space());
            self.sweep_refs(cell, &refs, depth, slot, out, space, false);
            return;
        };
        let mut left = refs;
        let right = self.partition(&mut left, &cell, axis, pos);
        let (left_cell, right_cell) = child_cells(&cell, axis, pos);
        let first = out.inner(slot, axis, pos);
        let big = left.len().max(right.len()) >= self.params.parallel_min_prims as usize;
        if self.params.parallel && big {
            let m = self.meter;
            let (_, sub) = m.hand_off(|| {
                rayon::join(
                    || m.work(|| self.build_binned(left_cell, left, depth + 1, first, out, space)),
                    || {
                        m.work(|| {
                            let mut sub = Out::apart();
                            let mut space = None;
                            self.build_binned(
                                right_cell,
                                right,
                                depth + 1,
                                0,
                                &mut sub,
                                &mut space,
                            );
                            if let Some(space) = space {
                                self.put_space(space);
                            }
                            sub
                        })
                    },
                )
            });
            out.append(sub, first + 1);
        } else {
            self.build_binned(left_cell, left, depth + 1, first, out, space);
            self.build_binned(right_cell, right, depth + 1, first + 1, out, space);
        }
    }

    fn parallel_here(&self, n: usize) -> bool {
        self.params.parallel && n >= 2 * CHUNK
    }

    /// The cheapest bin boundary of the node `(axis, position)`, if it beats a leaf.
    /// Ties keep the first boundary (axes in order, then positions), so the choice is
    /// deterministic.
    fn binned_plane(&self, cell: &Aabb, refs: &[Ref]) -> Option<(usize, f32)> {
        let binner = Binner::new(cell, refs.len());
        let bins = if self.parallel_here(refs.len()) {
            let m = self.meter;
            m.hand_off(|| {
                refs.par_chunks(CHUNK)
                    .with_max_len(1)
                    .map(|chunk| {
                        m.work(|| {
                            let mut bins = Bins::zero();
                            binner.count(chunk, &mut bins);
                            bins
                        })
                    })
                    .reduce(Bins::zero, |a, b| m.work(|| Bins::add(a, b)))
            })
        } else {
            let mut bins = Box::new(Bins::ZERO);
            binner.count(refs, &mut bins);
            bins
        };
        let n = refs.len() as u32;
        let mut best = None;
        let mut best_cost = self.params.intersection_cost * n as f32;
        for axis in 0..3 {
            let pricing = PlaneCost::new(cell, axis, self.params)?;
            let (lo, hi) = (pricing.lo, pricing.hi);
            let step = (hi - lo) / binner.bins as f32;
            let (mut n_left, mut n_right) = (0u32, n);
            for i in 1..binner.bins {
                n_left += bins.starts[axis][i - 1];
                n_right -= bins.ends[axis][i - 1];
                let pos = lo + step * i as f32;
                if !(pos > lo && pos < hi) {
                    continue;
                }
                let cost = pricing.cost(pricing.probabilities(pos), n_left, n_right);
                if cost < best_cost {
                    best_cost = cost;
                    best = Some((axis, i, pos, pricing));
                }
            }
        }
        let (axis, i, pos, pricing) = best?;
        let window = Window {
            binner,
            axis,
            boundary: i,
        };
        Some((
            axis,
            self.refine(refs, &bins, &window, &pricing, pos, best_cost),
        ))
    }

    /// The best plane near bin boundary `window.boundary` (cost `cost` by the bins):
    /// the bounds of the references that start or end in the two bins around it are
    /// priced exactly, as the sweep prices them, the references of the other bins
    /// counted by their bins. Binning alone misses the planes that cut off empty space
    /// tightly; on the tetra scene (4M triangles) that cost 15% in SAH. Ties go to the
    /// lower position.
    fn refine(
        &self,
        refs: &[Ref],
        bins: &Bins,
        window: &Window,
        pricing: &PlaneCost,
        pos: f32,
        cost: f32,
    ) -> f32 {
        let Window {
            binner,
            axis,
            boundary: i,
        } = *window;
        let base_left: u32 = bins.starts[axis][..i - 1].iter().sum();
        let base_right: u32 = bins.ends[axis][i + 1..].iter().sum();
        // Minima (planar references included), maxima of the others, planar positions.
        let (mut mins, mut maxs, mut planars) = (Vec::new(), Vec::new(), Vec::new());
        let near = NearBins::new(&binner, axis, i);
        for r in refs {
            let (a, b) = (r.bounds.min.as_ref()[axis], r.bounds.max.as_ref()[axis]);
            let (first, last) = near.test(a, b);
            if first {
                mins.push(a + 0.0);
            }
            if last {
                if a == b {
                    planars.push(a + 0.0)
                } else {
                    maxs.push(b + 0.0)
                }
            }
        }
        for list in [&mut mins, &mut maxs, &mut planars] {
            list.sort_unstable_by(f32::total_cmp);
        }
        let (mut best_pos, mut best_cost) = (pos, cost);
        // Each list is sorted, so within one list the counts below a candidate only grow:
        // three cursors walk forward instead of searching for every candidate.
        for list in [&mins, &maxs, &planars] {
            let (mut below_min, mut upto_max, mut below_planar) = (0, 0, 0);
            for &p in list.iter() {
                if !(p > pricing.lo && p < pricing.hi) {
                    continue;
                }
                while below_min < mins.len() && mins[below_min] < p {
                    below_min += 1;
                }
                while upto_max < maxs.len() && maxs[upto_max] <= p {
                    upto_max += 1;
                }
                while below_planar < planars.len() && planars[below_planar] < p {
                    below_planar += 1;
                }
                // A reference flat in the plane goes right (see `side`).
                let n_left = base_left + below_min as u32;
                let n_right = base_right
                    + (maxs.len() - upto_max) as u32
                    + (planars.len() - below_planar) as u32;
                let c = pricing.cost(pricing.probabilities(p), n_left, n_right);
                if c < best_cost || (c == best_cost && p < best_pos) {
                    (best_pos, best_cost) = (p, c);
                }
            }
        }
        best_pos
    }

    /// Splits `refs`, a node's references, at `pos` on `axis` in `cell`: `refs` keeps
    /// the left child's, the right child's are returned, both in the order of `refs`.
    /// Straddlers are clipped to the cell (perfect splits), or below
    /// [`CUT_WITHIN_BELOW`] references cut by the plane alone within their bounds.
    fn partition(&self, refs: &mut Vec<Ref>, cell: &Aabb, axis: usize, pos: f32) -> Vec<Ref> {
        if self.parallel_here(refs.len()) {
            let m = self.meter;
            let parts: Vec<(usize, Vec<Ref>)> = m.hand_off(|| {
                refs.par_chunks_mut(CHUNK)
                    .with_max_len(1)
                    .map(|chunk| m.work(|| self.partition_in_place(chunk, cell, axis, pos, false)))
                    .collect()
            });
            // Each chunk's left references are at its front: both sides are copied
            // out whole, in parallel.
            let lefts: Vec<((), &[Ref])> = (parts.iter().enumerate())
                .map(|(k, &(chunk_left, _))| ((), &refs[k * CHUNK..][..chunk_left]))
                .collect();
            let left = concat(&lefts, |_, r| *r, Ref::NONE, true, m);
            let rights: Vec<((), &[Ref])> = parts.iter().map(|(_, r)| ((), &r[..])).collect();
            let right = concat(&rights, |_, r| *r, Ref::NONE, true, m);
            *refs = left;
            right
        } else {
            let loose = refs.len() < CUT_WITHIN_BELOW;
            let (n_left, right) = self.partition_in_place(refs, cell, axis, pos, loose);
            refs.truncate(n_left);
            right
        }
    }

    /// [`Builder::partition`] of one run of references: the left child's are written
    /// over `refs` from the front (each reference read adds at most one on the left,
    /// so the writes never pass the reads), where the node's own passes have just
    /// brought them into cache; returns how many, and the right child's.
    fn partition_in_place(
        &self,
        refs: &mut [Ref],
        cell: &Aabb,
        axis: usize,
        pos: f32,
        loose: bool,
    ) -> (usize, Vec<Ref>) {
        let mut right = Vec::with_capacity(refs.len());
        let mut n_left = 0;
        for read in 0..refs.len() {
            // Copied straight from the array (a copy of `refs[read]` held across the
            // writes would go through the stack, whose stores and loads of other widths
            // stall on store forwarding).
            match side(&refs[read], axis, pos) {
                Side::Left => {
                    refs[n_left] = refs[read];
                    n_left += 1;
                }
                Side::Right => right.extend_from_slice(&refs[read..read + 1]),
                Side::Both => {
                    let r = refs[read];
                    let [l, rt] = if loose {
                        self.split_within(r.prim, &r.bounds, cell, axis, pos)
                    } else {
                        self.split_prim(r.prim, cell, axis, pos)
                    };
                    if let Some(bounds) = rt {
                        right.push(Ref {
                            bounds,
                            prim: r.prim,
                        });
                    }
                    if let Some(bounds) = l {
                        refs[n_left] = Ref {
                            bounds,
                            prim: r.prim,
                        };
                        n_left += 1;
                    }
                }
            }
        }
        (n_left, right)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bins as integer casts give them, clamped (the oracle of [`Binner::bins_of`]).
    fn bins_by_casts(binner: &Binner, b: &Aabb, axis: usize) -> (usize, usize) {
        let f_min = (b.min[axis] - binner.lo[axis]) * binner.scale[axis];
        let f_max = (b.max[axis] - binner.lo[axis]) * binner.scale[axis];
        let top = binner.bins as f32;
        let first = f_min.clamp(0.0, top - 1.0) as usize;
        let last = (f_max.ceil().clamp(1.0, top) as usize)
            .saturating_sub(1)
            .max(first);
        (first, last)
    }

    #[test]
    fn near_bins_by_compares_equal_near_bins_by_binning() {
        let mut rng = crate::scene::generate::Rng::new(12);
        for trial in 0..200 {
            let lo = Vec3::new(rng.range(-5.0, 5.0), 0.0, -1e-3);
            let extent = Vec3::new(rng.range(1e-3, 10.0), 1e4, 2e-3);
            let cell = Aabb::new(lo, lo + extent);
            let binner = Binner::new(&cell, [48, 64, 200, 511, 4096][trial % 5]);
            for axis in 0..3 {
                let (c_lo, c_hi) = (cell.min[axis], cell.max[axis]);
                for i in 1..binner.bins {
                    let near = NearBins::new(&binner, axis, i);
                    let edge = |k: usize| c_lo + (c_hi - c_lo) * (k as f32 / binner.bins as f32);
                    for _ in 0..64 {
                        // Coordinates anywhere, a little outside the cell, on and a float
                        // either side of the bin edges, and +-0.
                        let pick = |rng: &mut crate::scene::generate::Rng| match rng.next_u64() % 4
                        {
                            0 => rng.range(c_lo - 0.1 * extent[axis], c_hi + 0.1 * extent[axis]),
                            1 => {
                                let e = edge((i + (rng.next_u64() % 5) as usize).saturating_sub(2));
                                let step = (rng.next_u64() % 3) as i32 - 1;
                                from_order_bits(order_bits(e).wrapping_add_signed(step))
                            }
                            2 => [0.0, -0.0][(rng.next_u64() % 2) as usize],
                            _ => edge((rng.next_u64() % (binner.bins as u64 + 1)) as usize),
                        };
                        let (mut a, mut b) = (pick(&mut rng), pick(&mut rng));
                        if rng.next_u64().is_multiple_of(8) {
                            b = a;
                        }
                        if a > b {
                            (a, b) = (b, a);
                        }
                        let (first, last) = binner.bins_as_floats(a, b, axis);
                        let by_bins = |bin: f32| bin == (i - 1) as f32 || bin == i as f32;
                        assert_eq!(
                            near.test(a, b),
                            (by_bins(first), by_bins(last)),
                            "cell {cell:?} axis {axis} boundary {i}: {a} {b}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn bins_in_floats_equal_bins_by_casts() {
        let mut rng = crate::scene::generate::Rng::new(11);
        let cell = Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 0.5, 2.25));
        for refs in [48, 100, 600] {
            let binner = Binner::new(&cell, refs);
            for k in 0..20_000 {
                // Random bounds, some a little outside the cell, some on bin boundaries.
                let mut b = Aabb::EMPTY;
                for _ in 0..2 {
                    let mut p = Vec3::new(
                        rng.range(-1.1, 3.1),
                        rng.range(-0.05, 0.55),
                        rng.range(1.99, 2.26),
                    );
                    if k % 4 == 0 {
                        let bin = (rng.next_u64() % (binner.bins as u64 + 1)) as f32;
                        p = cell.min + (cell.max - cell.min) * (bin / binner.bins as f32);
                    }
                    b.grow(p);
                }
                let (firsts, lasts) = binner.bins_of(&b);
                for axis in 0..3 {
                    let by_casts = bins_by_casts(&binner, &b, axis);
                    assert_eq!((firsts[axis], lasts[axis]), by_casts, "{b:?} axis {axis}");
                    let (first, last) = binner.bins_as_floats(b.min[axis], b.max[axis], axis);
                    assert_eq!((first as usize, last as usize), by_casts);
                }
            }
        }
    }
}
