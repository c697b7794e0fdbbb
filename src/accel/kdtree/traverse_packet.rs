//! Stage: accel. Packet kd-tree traversal (Wald 2004, PhD thesis, section 7.3; Wald,
//! Slusallek, Benthin and Wagner 2001, "Interactive rendering with coherent ray
//! tracing"): the rays of a packet, at any width of [`crate::simd`], walk the tree together, one SIMD register per quantity.
//!
//! At an inner node every lane computes where it crosses the split plane; the packet
//! goes near-only, far-only, or near now and far later for all its lanes at once, with a
//! stack of `(node, lanes, t_near, t_far)` whose intervals are SIMD registers. A lane
//! rides along masked off where its own interval does not reach the node.
//!
//! Invariants, so each lane returns exactly what the scalar traversal
//! ([`super::traverse`]) returns for its ray:
//! - Every per-lane quantity (the clipped interval, the band around the split distance,
//!   the near/far decisions, the intervals pushed) is computed with the scalar path's
//!   operations in its order, so a lane is active at exactly the nodes the scalar ray
//!   visits, with the same interval, in the same front-to-back order. One exception:
//!   where the instruction set has FMA the band's ends round once
//!   ([`Float::mul_add_fast`]), within the plane slack as the scalar path's two
//!   roundings are, so a lane may visit a cell more or fewer at a band's edge but finds
//!   the same hit (`super::traverse`'s notes); lanes whose step could overflow
//!   (`overflow_lanes`) take the scalar walk.
//! - Near and far must mean the same child for every lane: the lanes of a packet must
//!   agree on the sign of each direction component (a zero component has no near side
//!   and agrees with both). Packets that disagree are split into groups that agree and
//!   traced one group after the other (counted in [`super::stats`]). A group of
//!   at most `scalar_group_max` lanes (1 of 4, 2 of 8, 3 of 16) takes the scalar
//!   traversal lane by lane, whose answer is the same.
//! - Leaves run the SIMD tests of [`crate::accel::triaccel_packet`] and
//!   [`crate::accel::prims_packet`], bit-identical to the scalar tests, and merge in
//!   [`crate::ray::Hit::is_closer`] order; a stack entry is dropped for the lanes whose
//!   best hit lies before its entry distance, as the scalar path does.
//! - Inactive lanes (NaN or not) only ever appear masked: they never widen a decision,
//!   and their output lanes are left as they were.

use super::KdTree;
use super::stats::bump;
use super::traverse::{PLANE_SLACK, Stack, box_coord_max};
use crate::accel::packet::{HitPacket, RayPacket};
use crate::geom::Aabb;
use crate::ray::Hit;
use crate::simd::{
    AMap, Float, LaneBits, LaneMask, MAX_LANES, Mask, Simd, Uint, Vf, array_fn, dispatch, inl,
    max_abs, prefetch,
};

/// One pending far child: its node, the lanes that need it, and their interval.
#[derive(Clone, Copy)]
struct Entry<W: Simd> {
    node: u32,
    lanes: Mask<W>,
    t_near: Vf<W>,
    t_far: Vf<W>,
}

/// The smallest float above each lane (`f32::next_up`), used for the scalar path's
/// leaf limit `next_up(best.t)`.
#[inline(always)]
fn next_up<F: Float>(v: F) -> F {
    let b = v.to_bits();
    let one = F::U::splat(1);
    let up = F::from_bits(b + one);
    let down = F::from_bits(b - one);
    let pos = v.cmp_gt(F::ZERO) & v.cmp_lt(F::splat(f32::INFINITY));
    let r = F::select(pos, up, F::select(v.cmp_lt(F::ZERO), down, v));
    F::select(v.cmp_eq(F::ZERO), F::from_bits(one), r)
}

/// The packet twin of [`super::traverse::clip_to_box`]: each lane's `[t_min, t_max]`
/// cut to the box widened by [`PLANE_SLACK`]; the mask holds the lanes that reach it
/// (never a lane with a NaN or infinite origin or direction, a zero direction or
/// `!(t_min <= t_max)`, as in the scalar path).
#[inline(always)]
pub(super) fn clip_to_box_packet<W: Simd>(
    b: &Aabb,
    rays: &RayPacket<W>,
    active: Mask<W>,
) -> (Mask<W>, Vf<W>, Vf<W>) {
    let (splat, select) = (Vf::<W>::splat, Vf::<W>::select);
    let (mut t0, mut t1) = (rays.t_min, rays.t_max);
    let mut live = active & rays.usable();
    let margin = (splat(box_coord_max(b)) + max_abs(&rays.org)) * splat(PLANE_SLACK);
    for axis in 0..3 {
        let o = rays.org[axis];
        let (lo, hi) = (b.min[axis], b.max[axis]);
        let d = rays.dir[axis];
        let parallel = d.cmp_eq(Vf::<W>::ZERO);
        let inside = o.cmp_ge(splat(lo) - margin) & o.cmp_le(splat(hi) + margin);
        live &= !parallel | inside;
        let inv = rays.inv_dir[axis];
        let slack = margin * inv.abs();
        let ta = (splat(lo) - o) * inv;
        let tb = (splat(hi) - o) * inv;
        let positive = d.cmp_gt(Vf::<W>::ZERO);
        let t_lo = select(positive, ta, tb);
        let t_hi = select(positive, tb, ta);
        t0 = select(parallel, t0, t0.max(t_lo - slack));
        t1 = select(parallel, t1, t1.min(t_hi + slack));
    }
    (live & t0.cmp_le(t1), t0, t1)
}

/// Lanes with a non-zero direction component so small that the node step's
/// `org * inv` or `split * inv` may overflow (`(coord_max + |org|max) * |inv| * 2` not
/// finite). The fused step ([`Float::mul_add_fast`]) would put their band on the wrong
/// side of a plane (an exact product plus an infinite offset), so they take the scalar
/// walk; zero components have their own rule in the walks.
#[inline(always)]
pub(super) fn overflow_lanes<W: Simd>(b: &Aabb, rays: &RayPacket<W>) -> Mask<W> {
    let coord_max = box_coord_max(b);
    if !coord_max.is_finite() {
        // No box (a tree of planes alone): every band is infinite or NaN, fused or not,
        // and a walk visits both children everywhere.
        return Mask::<W>::NONE;
    }
    let reach = Vf::<W>::splat(coord_max) + max_abs(&rays.org);
    let over = inl(
        #[inline(always)]
        |a: usize| !rays.dir[a].cmp_eq(Vf::<W>::ZERO) & step_overflows(reach, rays.inv_dir[a]),
    );
    over(0) | over(1) | over(2)
}

/// The one rule of every SIMD walk's overflow guard ([`overflow_lanes`], the tile's
/// bound, the lane walks' starts): on an axis whose reciprocal direction is `inv`, with
/// `reach = coord_max + |org|max` (the largest coordinate a split or the origin has),
/// `reach * |inv| * 2` is not finite. Zero components (infinite `inv`) are set too.
#[inline(always)]
pub(super) fn step_overflows<F: Float>(reach: F, inv: F) -> F::Mask {
    !(reach * inv.abs() * F::splat(2.0)).finite()
}

/// Lane groups of `active` that agree on every direction sign, counting the packets
/// that had to be split ([`super::stats::TraversalCounts::packet_splits`]).
#[inline(always)]
pub(super) fn coherent_groups<W: Simd>(
    rays: &RayPacket<W>,
    active: LaneBits,
) -> ([LaneBits; 8], usize) {
    let (groups, count) = rays.sign_groups(active);
    if count > 1 {
        bump(
            #[inline(always)]
            |c| c.packet_splits += 1,
        );
    }
    (groups, count)
}

/// Groups of at most this many coherent lanes of a `W` packet are traced as single
/// rays: a packet step costs about the same at every occupancy, a scalar step a
/// fraction of it (1 of 4 lanes, 2 of 8, 3 of 16).
const fn scalar_group_max<W: Simd>() -> u32 {
    match W::LANES {
        4 => 1,
        8 => 2,
        _ => 3,
    }
}

/// Whether a group is traced lane by lane with the scalar traversal: a group of at most
/// [`scalar_group_max`] lanes, which gives the same answer bit for bit (the packet
/// path's invariant) for less work than a packet step with most lanes masked off.
/// Incoherent packets (cosine bounces) split into several groups, most of them small.
#[inline(always)]
fn goes_scalar<W: Simd>(group: LaneBits) -> bool {
    group.count_ones() <= scalar_group_max::<W>()
}

impl KdTree {
    /// Closest hits of the active lanes of `rays` (planes included); inactive lanes get
    /// [`crate::ray::Hit::MISS`]. Lane by lane, the same hit as
    /// [`crate::accel::Accel::intersect`], `t`, `u`, `v` bit-identical.
    #[inline(always)]
    pub fn intersect_packet<W: Simd>(&self, rays: &RayPacket<W>) -> HitPacket<W> {
        dispatch!(W::LANES; self.intersect_packet_as::<@, W>(rays))
    }

    /// [`KdTree::intersect_packet`] of a packet of width `W` through backend `B`.
    #[inline(always)]
    fn intersect_packet_as<B: Simd, W: Simd>(&self, rays: &RayPacket<W>) -> HitPacket<W> {
        self.intersect_packet_in::<B>(&rays.recast()).recast()
    }

    /// [`KdTree::intersect_packet`] at backend `W`, inside its entry.
    #[inline(always)]
    pub(super) fn intersect_packet_in<W: Simd>(&self, rays: &RayPacket<W>) -> HitPacket<W> {
        let mut best = HitPacket::miss();
        // Every lane is clipped to the tree's box once; only those that reach it are
        // grouped and walked.
        let (reach, t_near, t_far) = clip_to_box_packet(&self.bounds, rays, rays.active);
        let risky = reach & overflow_lanes(&self.bounds, rays);
        let (groups, count) = coherent_groups(rays, (reach & !risky).bits());
        let mut alone = [None; MAX_LANES];
        let mut alone_bits = risky.bits();
        for &group in &groups[..count] {
            if goes_scalar::<W>(group) {
                alone_bits |= group;
            } else {
                let lanes = Mask::<W>::from_bits(group);
                self.traverse_packet_from::<W, false>(
                    rays,
                    lanes,
                    (0, lanes, t_near, t_far),
                    &mut best,
                );
            }
        }
        let any_alone = alone_bits != 0;
        while alone_bits != 0 {
            let i = alone_bits.trailing_zeros() as usize;
            alone_bits &= alone_bits - 1;
            if let Some(ray) = rays.lane(i) {
                let mut hit = Hit::MISS;
                self.traverse::<false>(&ray, &mut hit);
                alone[i] = Some(hit);
            }
        }
        if any_alone {
            let grouped = best;
            best = HitPacket::from_lanes(
                #[inline(always)]
                |i| {
                    alone[i].unwrap_or_else(
                        #[inline(always)]
                        || grouped.lane(i),
                    )
                },
            );
        }
        self.prims
            .intersect_planes_packet(rays, rays.active, &mut best);
        best
    }

    /// Bit `i` set when active lane `i` is occluded between `t_min` and `t_max`; the
    /// same answer as [`crate::accel::Accel::occluded`] lane by lane.
    #[inline(always)]
    pub fn occluded_packet<W: Simd>(&self, rays: &RayPacket<W>) -> LaneBits {
        dispatch!(W::LANES; self.occluded_packet_as::<@, W>(rays))
    }

    /// [`KdTree::occluded_packet`] of a packet of width `W` through backend `B`.
    #[inline(always)]
    fn occluded_packet_as<B: Simd, W: Simd>(&self, rays: &RayPacket<W>) -> LaneBits {
        self.occluded_packet_in::<B>(&rays.recast())
    }

    /// [`KdTree::occluded_packet`] at backend `W`, inside its entry.
    #[inline(always)]
    pub(super) fn occluded_packet_in<W: Simd>(&self, rays: &RayPacket<W>) -> LaneBits {
        let by_plane = self.prims.planes_occlude_packet(rays, rays.active);
        let mut best = HitPacket::miss();
        let (reach, t_near, t_far) =
            clip_to_box_packet(&self.bounds, rays, rays.active & !by_plane);
        let risky = reach & overflow_lanes(&self.bounds, rays);
        let (groups, count) = coherent_groups(rays, (reach & !risky).bits());
        let mut occluded = by_plane.bits();
        let mut alone_bits = risky.bits();
        for &group in &groups[..count] {
            if goes_scalar::<W>(group) {
                alone_bits |= group;
            } else {
                let lanes = Mask::<W>::from_bits(group);
                occluded |= self
                    .traverse_packet_from::<W, true>(
                        rays,
                        lanes,
                        (0, lanes, t_near, t_far),
                        &mut best,
                    )
                    .bits();
            }
        }
        while alone_bits != 0 {
            let i = alone_bits.trailing_zeros() as usize;
            alone_bits &= alone_bits - 1;
            let mut unused = Hit::MISS;
            if rays.lane(i).is_some_and(
                #[inline(always)]
                |ray| self.traverse::<true>(&ray, &mut unused),
            ) {
                occluded |= 1 << i;
            }
        }
        occluded
    }

    /// Walks the tree from `node` with the lanes `lanes` (of `active`, which agree on
    /// every direction sign), arriving there with the interval `[t_near, t_far]` they
    /// had when clipped to the tree's box: from the root, or from the entry point of
    /// [`super::traverse_tile`], which only passes near-only and far-only steps that
    /// every lane takes, so no lane needs anything outside `node`'s subtree. Closest
    /// hit: folds hits into `best`. With `ANY_HIT`: returns the lanes that hit anything
    /// in `(t_min, t_max)`, each lane leaving at its first hit, and stops once every
    /// lane of `active` has.
    ///
    /// Inlined into the packet kernel: out of line (an entry of its own, with the
    /// packet passed through memory) packet8 on primary rays lost a tenth
    /// (perf/isa.md).
    #[inline(always)]
    pub(super) fn traverse_packet_from<W: Simd, const ANY_HIT: bool>(
        &self,
        rays: &RayPacket<W>,
        active: Mask<W>,
        (mut node, mut lanes, mut t_near, mut t_far): (u32, Mask<W>, Vf<W>, Vf<W>),
        best: &mut HitPacket<W>,
    ) -> Mask<W> {
        let (splat, select) = (Vf::<W>::splat, Vf::<W>::select);
        let mut occluded = Mask::<W>::NONE;
        if lanes.none() {
            return occluded;
        }
        // Near is the left child on axes where the group's directions are not negative.
        let negative = rays.dir.amap(
            #[inline(always)]
            |d| (lanes & d.cmp_lt(Vf::<W>::ZERO)).any(),
        );
        // The same as bits (bit `a` for axis `a`), so that the next node's index is a
        // shift away from the node just loaded, not a dependent load.
        let neg_bits = (0..3).fold(
            0u32,
            #[inline(always)]
            |b, a| b | (negative[a] as u32) << a,
        );
        let zero = rays.dir.amap(
            #[inline(always)]
            |d| d.cmp_eq(Vf::<W>::ZERO),
        );
        let any_zero = zero.amap(
            #[inline(always)]
            |z| (lanes & z).any(),
        );
        // The plane margin and its `t` interval per axis, as the scalar path's `RayAxes`.
        let coord_max = self.coord_max();
        let o_max = max_abs(&rays.org);
        let margins: [Vf<W>; 3] = array_fn(
            #[inline(always)]
            |a| (splat(coord_max[a]) + o_max) * splat(PLANE_SLACK),
        );
        // The band's ends at a plane as `split * inv + off` (`RayAxes`).
        let slacks: [Vf<W>; 3] = array_fn(
            #[inline(always)]
            |a| margins[a] * rays.inv_dir[a].abs(),
        );
        let lo_off: [Vf<W>; 3] = array_fn(
            #[inline(always)]
            |a| -(rays.org[a] * rays.inv_dir[a]) - slacks[a],
        );
        let hi_off: [Vf<W>; 3] = array_fn(
            #[inline(always)]
            |a| -(rays.org[a] * rays.inv_dir[a]) + slacks[a],
        );
        let mut stack = Stack::<Entry<W>>::new();
        'walk: loop {
            let n = self.nodes[node as usize];
            // Leaves, and inner nodes whose lanes all go to empty children, end here and
            // fall through to the pops; every other step continues at a child.
            'visit: {
                if n.is_leaf() {
                    let prims = self.leaf_prims(&n);
                    bump(
                        #[inline(always)]
                        |c| c.leaf_visits += 1,
                    );
                    // Walks never enter empty leaves but a tree that is one.
                    if !prims.is_empty() {
                        let mut hit = [Mask::<W>::NONE];
                        let one = std::slice::from_mut(best);
                        self.leaf_groups::<W, 1, ANY_HIT>(
                            prims,
                            #[inline(always)]
                            |_| rays,
                            &[lanes],
                            one,
                            &mut hit,
                        );
                        occluded |= hit[0];
                        if ANY_HIT && (active & !occluded).none() {
                            return occluded;
                        }
                    }
                    break 'visit;
                }
                bump(
                    #[inline(always)]
                    |c| c.node_steps += 1,
                );
                let axis = n.axis();
                let children = n.children();
                let (o, inv) = (rays.org[axis], rays.inv_dir[axis]);
                let split = splat(n.split);
                let margin = margins[axis];
                let lo = split.mul_add_fast(inv, lo_off[axis]);
                let hi = split.mul_add_fast(inv, hi_off[axis]);
                let flip = (neg_bits >> axis) & 1;
                let (near, far) = (children + flip, children + (flip ^ 1));
                let (near_only, far_only) = if any_zero[axis] {
                    // Lanes parallel to the plane keep their interval and go to the
                    // sides within `margin` of their origin.
                    let z = zero[axis];
                    let left_only = (o + margin).cmp_lt(split);
                    let right_only = (o - margin).cmp_gt(split);
                    let (near_z, far_z) = if negative[axis] {
                        (right_only, left_only)
                    } else {
                        (left_only, right_only)
                    };
                    (
                        (z & near_z) | (!z & lo.cmp_gt(t_far)),
                        (z & far_z) | (!z & hi.cmp_lt(t_near)),
                    )
                } else {
                    let near_only = lo.cmp_gt(t_far);
                    // The commonest step: every lane goes near only, its mask unchanged
                    // (the far test below could not remove a near-only lane).
                    if (lanes & !near_only).none() {
                        // An empty near leaf holds nothing for them.
                        if n.empty_near_far(flip) & 1 != 0 {
                            break 'visit;
                        }
                        node = near;
                        continue 'walk;
                    }
                    (near_only, hi.cmp_lt(t_near))
                };
                // Bit 0 for an empty near leaf, bit 1 for an empty far one.
                let empty = n.empty_near_far(flip);
                // As in the scalar path, near-only wins when both tests pass. No lane
                // goes to an empty leaf: it holds nothing.
                let mut near_lanes = lanes & !(far_only & !near_only);
                let mut far_lanes = lanes & !near_only;
                if empty != 0 {
                    if empty & 1 != 0 {
                        near_lanes = Mask::<W>::NONE;
                    }
                    if empty & 2 != 0 {
                        far_lanes = Mask::<W>::NONE;
                    }
                }
                if far_lanes.none() {
                    if near_lanes.none() {
                        break 'visit;
                    }
                    node = near;
                    lanes = near_lanes;
                    if empty != 0 {
                        // The near interval of lanes that would also have gone far;
                        // near-only lanes keep theirs (`hi > t_far` there).
                        t_far = select(zero[axis], t_far, hi.min_lt(t_far));
                    }
                } else if near_lanes.none() {
                    node = far;
                    lanes = far_lanes;
                    if empty != 0 {
                        // The interval the pop of the far child would have given the
                        // lanes that went near first (far-only lanes keep theirs), and
                        // the pop's test against their best hits.
                        t_near = select(zero[axis], t_near, lo.max_gt(t_near));
                        if !ANY_HIT {
                            lanes &= !t_near.cmp_gt(best.t);
                            if lanes.none() {
                                break 'visit;
                            }
                        }
                    }
                } else {
                    stack.push(Entry {
                        node: far,
                        lanes: far_lanes,
                        t_near: select(zero[axis], t_near, lo.max_gt(t_near)),
                        t_far,
                    });
                    node = near;
                    lanes = near_lanes;
                    t_far = select(zero[axis], t_far, hi.min_lt(t_far));
                }
                continue 'walk;
            }
            loop {
                let Some(e) = stack.pop() else {
                    return occluded;
                };
                lanes = if ANY_HIT {
                    e.lanes & !occluded
                } else {
                    e.lanes & !e.t_near.cmp_gt(best.t)
                };
                if lanes.any() {
                    (node, t_near, t_far) = (e.node, e.t_near, e.t_far);
                    break;
                }
            }
        }
    }

    /// The primitives `prims` of a leaf against the lanes `lanes[g]` of each group
    /// `rays(g)`: one group for a packet, several for a tile (traverse_tile.rs). It goes
    /// primitive by primitive, so each record is loaded once for all groups and the
    /// groups' tests, independent of one another, overlap; each group sees the
    /// primitives in the leaf's order, so its answers do not depend on the others.
    /// Closest hit: folds group `g`'s hits into `best[g]` (in [`Hit::is_closer`]
    /// order). With `ANY_HIT`: adds to `occluded[g]` the lanes that hit anything in
    /// `(t_min, t_max)`, each lane leaving at its first hit.
    #[inline(always)]
    pub(super) fn leaf_groups<'r, W: Simd, const G: usize, const ANY_HIT: bool>(
        &self,
        prims: &[u32],
        rays: impl Fn(usize) -> &'r RayPacket<W>,
        lanes: &[Mask<W>; G],
        best: &mut [HitPacket<W>],
        occluded: &mut [Mask<W>],
    ) {
        let (best, occluded) = (&mut best[..G], &mut occluded[..G]);
        if ANY_HIT {
            let mut live = *lanes;
            for &p in prims {
                let mut any = Mask::<W>::NONE;
                for g in 0..G {
                    if live[g].any() {
                        bump(
                            #[inline(always)]
                            |c| c.prim_tests += 1,
                        );
                        let hits =
                            self.prims
                                .intersect_prim_packet(p, rays(g), live[g], rays(g).t_max);
                        occluded[g] |= hits.mask;
                        live[g] &= !hits.mask;
                        any |= live[g];
                    }
                }
                if any.none() {
                    break;
                }
            }
        } else {
            // Lanes near an edge need the triangle's corners (the exact rule,
            // triaccel.rs), which sit apart from its record: ask for them now, while
            // the leaf's tests run.
            for &p in prims {
                if let Some(c) = self.prims.corners.get(p as usize) {
                    prefetch(c);
                }
            }
            let mut limit: [Vf<W>; G] = array_fn(
                #[inline(always)]
                |g| next_up(best[g].t).min(rays(g).t_max),
            );
            let groups = lanes
                .iter()
                .filter(
                    #[inline(always)]
                    |l| l.any(),
                )
                .count() as u64;
            bump(
                #[inline(always)]
                |c| c.prim_tests += groups * prims.len() as u64,
            );
            for &p in prims {
                let id = self.prims.id(p);
                for g in 0..G {
                    if lanes[g].any() {
                        let hits = self
                            .prims
                            .intersect_prim_packet(p, rays(g), lanes[g], limit[g]);
                        if best[g].merge(&hits, id).any() {
                            limit[g] = next_up(best[g].t).min(rays(g).t_max);
                        }
                    }
                }
            }
        }
    }
}
