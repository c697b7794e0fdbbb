//! Stage: accel. Packet kd-tree traversal (Wald 2004, PhD thesis, section 7.3; Wald,
//! Slusallek, Benthin and Wagner 2001, "Interactive rendering with coherent ray
//! tracing"): the rays of a packet, at any width of [`crate::simd`], walk the tree together, one SIMD register per quantity.
//!
//! At an inner node every lane computes where it crosses the split plane; the packet
//! goes near-only, far-only, or near now and far later for all its lanes at once, with a
//! stack of `(node, lanes, t_near, t_far)` whose intervals are SIMD registers (any-hit
//! walks: far now and near later, as the scalar step, `KdTree::step`). A lane
//! rides along masked off where its own interval does not reach the node.
//!
//! Invariants, so each lane returns exactly what the scalar traversal
//! ([`super::traverse`]) returns for its ray:
//! - Every lane is set up by the scalar path's own function (`start`, generic over one
//!   lane or many), and every later per-lane quantity (the band's ends at the
//!   split, the near/far decisions, the intervals pushed) is computed with the scalar
//!   step's operations in its order, so a lane is active at exactly the nodes the scalar
//!   ray visits, with the same interval, in the same front-to-back order. One
//!   exception: where the instruction set has FMA the band's ends round once
//!   ([`Float::mul_add_fast`]), within the plane slack as the scalar path's two
//!   roundings are, so a lane may visit a cell more or fewer at a band's edge but finds
//!   the same hit (`super::traverse`'s notes).
//! - One rule for the lanes a SIMD walk cannot take (`KdTree::scalar_lanes`): a lane
//!   with a zero direction component (it has no near side) or one so small that the
//!   step may overflow takes the scalar walk, whose own rule for zero components is the
//!   only one. The tile and lane walks send the same lanes there.
//! - Near and far must mean the same child for every lane: the lanes of a packet must
//!   agree on the sign of each direction component. Packets that disagree are split
//!   into groups that agree and traced one group after the other (counted in
//!   [`super::stats`]). A group of at most `alone_max` lanes (1 of 4, 2 of 8, 3
//!   of 16) takes the scalar traversal lane by lane, whose answer is the same.
//! - A packet is the group walk (`KdTree::walk_groups`) of one group; a tile
//!   (traverse_tile.rs) is the same walk of several.
//! - Leaves run the SIMD tests of [`crate::accel::triaccel_packet`] and
//!   [`crate::accel::prims_packet`], bit-identical to the scalar tests, and merge in
//!   [`crate::ray::Hit::is_closer`] order; a stack entry is dropped for the lanes whose
//!   best hit lies before its entry distance, as the scalar path does.
//! - Inactive lanes (NaN or not) only ever appear masked: they never widen a decision,
//!   and their output lanes are left as they were.

use super::KdTree;
use super::stats::{bump, count_tests};
use super::traverse::{Bands, Stack, box_coord_max, start};
use crate::accel::packet::{HitPacket, RayPacket, alone_max, trace_lanes_alone};
use crate::simd::{Float, LaneBits, LaneMask, Mask, Simd, Vf, array_fn, dispatch, inl};

/// One pending far child of a group walk: its node and, per group, the lanes that need
/// it and their interval.
#[derive(Clone, Copy)]
struct Entry<W: Simd, const G: usize> {
    node: u32,
    lanes: [Mask<W>; G],
    t_near: [Vf<W>; G],
    t_far: [Vf<W>; G],
}

impl KdTree {
    /// The scalar walk's set-up ([`start`]) of each lane of `rays`: the bands, and the
    /// lanes of `active` that reach the tree's box with their intervals (never a lane
    /// that is not usable, [`RayPacket::usable`]).
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    pub(super) fn start_packet<W: Simd>(
        &self,
        rays: &RayPacket<W>,
        active: Mask<W>,
    ) -> (Bands<Vf<W>>, (Mask<W>, Vf<W>, Vf<W>)) {
        start(
            &self.bounds,
            [&rays.org, &rays.dir, &rays.inv_dir],
            (rays.t_min, rays.t_max),
            active & rays.usable(),
        )
    }

    /// The lanes the SIMD walks leave to the scalar walk: those with a zero direction
    /// component (they have no near side, and the scalar walk's own rule for them,
    /// `KdTree::step`, is the one rule) or one so small that the node step's `org *
    /// inv` or `split * inv` may overflow ([`step_overflows`]), where the fused step
    /// ([`Float::mul_add_fast`]) would put their band on the wrong side of a plane (an
    /// exact product plus an infinite offset). `reach` is the lanes' [`Bands::reach`].
    #[inline(always)]
    pub(super) fn scalar_lanes<F: Float>(&self, reach: F, inv: &[F; 3]) -> F::Mask {
        if !box_coord_max(&self.bounds).is_finite() {
            // No box (a tree of planes alone, whose root is an empty leaf): no step.
            return F::Mask::NONE;
        }
        step_overflows(reach, inv[0])
            | step_overflows(reach, inv[1])
            | step_overflows(reach, inv[2])
    }
}

/// The one rule of every SIMD walk's guard ([`KdTree::scalar_lanes`]): on an axis whose
/// reciprocal direction is `inv`, with `reach = coord_max + |org|max` (the largest
/// coordinate a split or the origin has), `reach * |inv| * 2` is not finite. Zero
/// components (infinite `inv`) are set too.
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

/// Whether a group is traced lane by lane with the scalar traversal: a group of at most
/// [`alone_max`] lanes, which gives the same answer bit for bit (the packet
/// path's invariant) for less work than a packet step with most lanes masked off.
/// Incoherent packets (cosine bounces) split into several groups, most of them small.
#[inline(always)]
fn goes_scalar<W: Simd>(group: LaneBits) -> bool {
    group.count_ones() <= alone_max::<W>()
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
        let (mut best, _) = self.walk_packet::<W, false>(rays, rays.active, Mask::<W>::NONE);
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
        let (_, occluded) = self.walk_packet::<W, true>(rays, rays.active & !by_plane, by_plane);
        occluded.bits()
    }

    /// The lanes of `active` through the tree (planes aside): set up and clipped to the
    /// tree's box once, then each coherent group of them walked as one group
    /// ([`KdTree::walk_groups`]), and the lanes the SIMD walks leave to the scalar walk
    /// ([`KdTree::scalar_lanes`]), with those of groups too small to pay
    /// ([`goes_scalar`]), walked one by one. Closest hit: the hits, lanes outside
    /// `active` missing. With `ANY_HIT`: `occluded` and the lanes that hit anything.
    #[inline(always)]
    fn walk_packet<W: Simd, const ANY_HIT: bool>(
        &self,
        rays: &RayPacket<W>,
        active: Mask<W>,
        occluded: Mask<W>,
    ) -> (HitPacket<W>, Mask<W>) {
        let mut best = [HitPacket::miss()];
        let mut occluded = [occluded];
        let (bands, (reach, t_near, t_far)) = self.start_packet(rays, active);
        let to_scalar = reach & self.scalar_lanes(bands.reach, &rays.inv_dir);
        let (groups, count) = coherent_groups(rays, (reach & !to_scalar).bits());
        let mut scalar_bits = to_scalar.bits();
        for &group in &groups[..count] {
            if goes_scalar::<W>(group) {
                scalar_bits |= group;
            } else {
                let lanes = Mask::<W>::from_bits(group);
                self.walk_groups::<W, 1, ANY_HIT>(
                    #[inline(always)]
                    |_| (rays, &bands),
                    (0, [lanes], [t_near], [t_far]),
                    &mut best,
                    &mut occluded,
                );
            }
        }
        let ([mut best], [mut occluded]) = (best, occluded);
        trace_lanes_alone::<W, ANY_HIT>(
            rays,
            scalar_bits,
            &mut best,
            &mut occluded,
            #[inline(always)]
            |ray, hit| self.traverse::<ANY_HIT>(ray, hit),
        );
        (best, occluded)
    }

    /// The group walk: `G` packets (`groups(g)`, with their [`Bands`]) walk the tree
    /// together from `node`, one node load and one decision per step for all of them,
    /// with one stack (a packet is one group; a tile is several, traverse_tile.rs:
    /// Overbeck, Ramamoorthi and Mark 2008, partition traversal). Every lane of
    /// `lanes` agrees on every direction sign, has no zero component
    /// ([`KdTree::scalar_lanes`]), and arrives at `node` with the interval `[t_near,
    /// t_far]` it had when clipped to the tree's box: from the root, or from a tile's
    /// entry point, which only passes near-only and far-only steps that every lane
    /// takes, so no lane needs anything outside `node`'s subtree.
    ///
    /// Each group's lanes take the scalar step's decisions with its operations, and the
    /// walk goes near only, far only, or near now and far later as the union of its
    /// groups requires; a group with no lane on a side rides along masked off. So each
    /// lane visits exactly the nodes the scalar path visits, with the same interval,
    /// front to back. Closest hit: folds group `g`'s hits into `best[g]`. With
    /// `ANY_HIT`: adds to `occluded[g]` the lanes that hit anything in `(t_min, t_max)`,
    /// each lane leaving at its first hit, and stops once every lane has.
    ///
    /// Inlined: into the packet kernel (out of line, with the packet passed through
    /// memory, packet8 on primary rays lost a tenth, perf/isa.md), and into a tile's
    /// walk entry.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    pub(super) fn walk_groups<'r, W: Simd, const G: usize, const ANY_HIT: bool>(
        &self,
        groups: impl Fn(usize) -> (&'r RayPacket<W>, &'r Bands<Vf<W>>),
        (mut node, mut lanes, mut t_near, mut t_far): (u32, [Mask<W>; G], [Vf<W>; G], [Vf<W>; G]),
        best: &mut [HitPacket<W>],
        occluded: &mut [Mask<W>],
    ) {
        let splat = Vf::<W>::splat;
        let (best, occluded) = (&mut best[..G], &mut occluded[..G]);
        if union::<W, G>(&lanes).none() {
            return;
        }
        let rays = inl(
            #[inline(always)]
            |g: usize| groups(g).0,
        );
        let actives = lanes;
        // Near is the left child on axes where the lanes' directions are not negative.
        let mut negative = [false; 3];
        for (g, l) in lanes.iter().enumerate() {
            for (a, n) in negative.iter_mut().enumerate() {
                *n |= (*l & rays(g).dir[a].cmp_lt(Vf::<W>::ZERO)).any();
            }
        }
        // As bits, so that the next node's index is a shift from the node just loaded,
        // not a dependent load.
        let neg_bits = (0..3).fold(
            0u32,
            #[inline(always)]
            |b, a| b | (negative[a] as u32) << a,
        );
        // Per axis, the groups' reciprocals and band offsets side by side, so that a
        // step loads them at one offset.
        let inv = per_axis::<W, G>(
            #[inline(always)]
            |a, g| rays(g).inv_dir[a],
        );
        let lo_offs = per_axis::<W, G>(
            #[inline(always)]
            |a, g| groups(g).1.lo_off[a],
        );
        let hi_offs = per_axis::<W, G>(
            #[inline(always)]
            |a, g| groups(g).1.hi_off[a],
        );
        let mut stack = Stack::<Entry<W, G>>::new();
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
                        self.prims.leaf_groups::<W, G, ANY_HIT>(
                            prims,
                            &rays,
                            &lanes,
                            best,
                            occluded,
                            count_tests,
                        );
                        if ANY_HIT
                            && union::<W, G>(&array_fn(
                                #[inline(always)]
                                |g| actives[g] & !occluded[g],
                            ))
                            .none()
                        {
                            return;
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
                let split = splat(n.split);
                let flip = (neg_bits >> axis) & 1;
                let (near, far) = (children + flip, children + (flip ^ 1));
                let (inv, lo_off, hi_off) = (&inv[axis], &lo_offs[axis], &hi_offs[axis]);
                let lo: [Vf<W>; G] = array_fn(
                    #[inline(always)]
                    |g| split.mul_add_fast(inv[g], lo_off[g]),
                );
                let hi: [Vf<W>; G] = array_fn(
                    #[inline(always)]
                    |g| split.mul_add_fast(inv[g], hi_off[g]),
                );
                let near_only: [Mask<W>; G] = array_fn(
                    #[inline(always)]
                    |g| lo[g].cmp_gt(t_far[g]),
                );
                let mut far_lanes: [Mask<W>; G] = array_fn(
                    #[inline(always)]
                    |g| lanes[g] & !near_only[g],
                );
                if union::<W, G>(&far_lanes).none() {
                    // The commonest step: every lane goes near only, its mask unchanged
                    // (an empty near leaf holds nothing for them).
                    if n.empty_near_far(flip) & 1 != 0 {
                        break 'visit;
                    }
                    node = near;
                    continue 'walk;
                }
                // Bit 0 for an empty near leaf, bit 1 for an empty far one.
                let empty = n.empty_near_far(flip);
                // As in the scalar path, near-only wins when both tests pass. No lane
                // goes to an empty leaf: it holds nothing.
                let mut near_lanes: [Mask<W>; G] = array_fn(
                    #[inline(always)]
                    |g| lanes[g] & !(hi[g].cmp_lt(t_near[g]) & !near_only[g]),
                );
                if empty & 1 != 0 {
                    near_lanes = [Mask::<W>::NONE; G];
                }
                if empty & 2 != 0 {
                    far_lanes = [Mask::<W>::NONE; G];
                }
                let any = inl(
                    #[inline(always)]
                    |m: &[Mask<W>; G]| union::<W, G>(m).any(),
                );
                if !any(&far_lanes) {
                    if !any(&near_lanes) {
                        break 'visit;
                    }
                    node = near;
                    lanes = near_lanes;
                    // The near interval of lanes that would also have gone far;
                    // near-only lanes keep theirs (`hi > t_far` there).
                    t_far = array_fn(
                        #[inline(always)]
                        |g| hi[g].min_lt(t_far[g]),
                    );
                } else if !any(&near_lanes) {
                    node = far;
                    lanes = far_lanes;
                    if empty != 0 {
                        // The interval the pop of the far child would have given the
                        // lanes that went near first (far-only lanes keep theirs), and
                        // the pop's test against their best hits.
                        t_near = array_fn(
                            #[inline(always)]
                            |g| lo[g].max_gt(t_near[g]),
                        );
                        if !ANY_HIT {
                            for g in 0..G {
                                lanes[g] &= !t_near[g].cmp_gt(best[g].t);
                            }
                            if !any(&lanes) {
                                break 'visit;
                            }
                        }
                    }
                } else if ANY_HIT {
                    // Far child first, as the scalar any-hit walk ([`KdTree::step`]).
                    stack.push(Entry {
                        node: near,
                        lanes: near_lanes,
                        t_near,
                        t_far: array_fn(
                            #[inline(always)]
                            |g| hi[g].min_lt(t_far[g]),
                        ),
                    });
                    node = far;
                    lanes = far_lanes;
                    t_near = array_fn(
                        #[inline(always)]
                        |g| lo[g].max_gt(t_near[g]),
                    );
                } else {
                    stack.push(Entry {
                        node: far,
                        lanes: far_lanes,
                        t_near: array_fn(
                            #[inline(always)]
                            |g| lo[g].max_gt(t_near[g]),
                        ),
                        t_far,
                    });
                    node = near;
                    lanes = near_lanes;
                    t_far = array_fn(
                        #[inline(always)]
                        |g| hi[g].min_lt(t_far[g]),
                    );
                }
                continue 'walk;
            }
            loop {
                let Some(e) = stack.pop() else {
                    return;
                };
                let mut any = Mask::<W>::NONE;
                for g in 0..G {
                    lanes[g] = if ANY_HIT {
                        e.lanes[g] & !occluded[g]
                    } else {
                        e.lanes[g] & !e.t_near[g].cmp_gt(best[g].t)
                    };
                    any |= lanes[g];
                }
                if any.any() {
                    (node, t_near, t_far) = (e.node, e.t_near, e.t_far);
                    break;
                }
            }
        }
    }
}

/// The lanes set in any of the groups' masks (a loop, not `Iterator::fold`, which LLVM
/// may keep out of line: see [`crate::simd::inl`]).
#[inline(always)]
pub(super) fn union<W: Simd, const G: usize>(masks: &[Mask<W>; G]) -> Mask<W> {
    let mut all = Mask::<W>::NONE;
    for &m in masks {
        all |= m;
    }
    all
}

/// `f(axis, group)` for every axis and group, axis first.
#[inline(always)]
fn per_axis<W: Simd, const G: usize>(f: impl Fn(usize, usize) -> Vf<W>) -> [[Vf<W>; G]; 3] {
    array_fn(
        #[inline(always)]
        |a| {
            array_fn(
                #[inline(always)]
                |g| f(a, g),
            )
        },
    )
}
