//! Stage: accel. Packet kd-tree traversal (Wald 2004, PhD thesis, section 7.3; Wald,
//! Slusallek, Benthin and Wagner 2001, "Interactive rendering with coherent ray
//! tracing"): `LANES` rays walk the tree together, one SIMD register per quantity.
//!
//! At an inner node every lane computes where it crosses the split plane; the packet
//! goes near-only, far-only, or near now and far later for all its lanes at once, with a
//! stack of `(node, lanes, t_near, t_far)` whose intervals are SIMD registers. A lane
//! rides along masked off where its own interval does not reach the node.
//!
//! Invariants, so each lane returns exactly what the scalar traversal
//! ([`super::traverse`]) returns for its ray:
//! - Every per-lane quantity (the clipped interval, the split distance and its slack,
//!   the near/far decisions, the intervals pushed) is computed with the scalar path's
//!   operations in its order, so a lane is active at exactly the nodes the scalar ray
//!   visits, with the same interval, in the same front-to-back order.
//! - Near and far must mean the same child for every lane: the lanes of a packet must
//!   agree on the sign of each direction component (a zero component has no near side
//!   and agrees with both). Packets that disagree are split into groups that agree and
//!   traced one group after the other; [`packet_split_count`] counts them. A group of
//!   one lane takes the scalar traversal, whose answer is the same.
//! - Leaves run the SIMD tests of [`crate::accel::triaccel_packet`] and
//!   [`crate::accel::prims_packet`], bit-identical to the scalar tests, and merge in
//!   [`crate::ray::Hit::is_closer`] order; a stack entry is dropped for the lanes whose
//!   best hit lies before its entry distance, as the scalar path does.
//! - Inactive lanes (NaN or not) only ever appear masked: they never widen a decision,
//!   and their output lanes are left as they were.

use super::KdTree;
use super::traverse::{PLANE_SLACK, Stack};
use crate::accel::packet::{HitPacket, RayPacket};
use crate::ray::{Hit, Ray};
use crate::scene::Aabb;
use crate::simd::{
    LANES, Mask, Vf, Vu, any, bits, mask_from_bits, max_abs, max_gt, min_lt, none, select, splat,
};
use std::cell::Cell;

thread_local! {
    static PACKET_SPLITS: Cell<u64> = const { Cell::new(0) };
}

/// Packets traced on this thread whose lanes disagreed on a direction sign and were
/// split into coherent groups.
pub fn packet_split_count() -> u64 {
    PACKET_SPLITS.with(Cell::get)
}

/// One pending far child: its node, the lanes that need it, and their interval.
#[derive(Clone, Copy)]
struct Entry {
    node: u32,
    lanes: Mask,
    t_near: Vf,
    t_far: Vf,
}

/// The smallest float above each lane (`f32::next_up`), used for the scalar path's
/// leaf limit `next_up(best.t)`.
#[inline]
fn next_up(v: Vf) -> Vf {
    let b = v.to_bits();
    let one = Vu::splat(1);
    let up = Vf::from_bits(b + one);
    let down = Vf::from_bits(b - one);
    let pos = v.simd_gt(Vf::ZERO) & v.simd_lt(splat(f32::INFINITY));
    let r = select(pos, up, select(v.simd_lt(Vf::ZERO), down, v));
    select(v.simd_eq(Vf::ZERO), Vf::from_bits(one), r)
}

/// The packet twin of [`super::traverse::clip_to_box`]: each lane's `[t_min, t_max]`
/// cut to the box widened by [`PLANE_SLACK`]; the mask holds the lanes that reach it
/// (never a lane with a NaN or infinite origin or direction, a zero direction or
/// `!(t_min <= t_max)`, as in the scalar path).
#[inline]
fn clip_to_box_packet(b: &Aabb, rays: &RayPacket, active: Mask) -> (Mask, Vf, Vf) {
    let (mut t0, mut t1) = (rays.t_min, rays.t_max);
    let mut live = active & rays.usable();
    let o_max = max_abs(&rays.org);
    for axis in 0..3 {
        let o = rays.org[axis];
        let (lo, hi) = (b.min[axis], b.max[axis]);
        let margin = (splat(lo.abs().max(hi.abs())) + o_max) * splat(PLANE_SLACK);
        let d = rays.dir[axis];
        let parallel = d.simd_eq(Vf::ZERO);
        let inside = o.simd_ge(splat(lo) - margin) & o.simd_le(splat(hi) + margin);
        live &= !parallel | inside;
        let inv = rays.inv_dir[axis];
        let slack = margin * inv.abs();
        let ta = (splat(lo) - o) * inv;
        let tb = (splat(hi) - o) * inv;
        let positive = d.simd_gt(Vf::ZERO);
        let t_lo = select(positive, ta, tb);
        let t_hi = select(positive, tb, ta);
        t0 = select(parallel, t0, t0.max(t_lo - slack));
        t1 = select(parallel, t1, t1.min(t_hi + slack));
    }
    (live & t0.simd_le(t1), t0, t1)
}

/// Lane groups of `active` that agree on every direction sign, counting the packets
/// that had to be split ([`packet_split_count`]).
#[inline]
fn coherent_groups(rays: &RayPacket, active: u32) -> ([u32; LANES], usize) {
    let (groups, count) = sign_groups(rays, active);
    if count > 1 {
        PACKET_SPLITS.with(|c| c.set(c.get() + 1));
    }
    (groups, count)
}

/// The lane of a group of one, and its ray: such a group is traced by the scalar
/// traversal, which gives the same answer bit for bit (the packet path's invariant) for
/// less work than a packet step with three lanes masked off. Incoherent packets (cosine
/// bounces) split into about three groups, most of them lone lanes.
#[inline]
fn lone_lane(rays: &RayPacket, group: u32) -> Option<(usize, Ray)> {
    if group.count_ones() != 1 {
        return None;
    }
    let i = group.trailing_zeros() as usize;
    rays.lane(i).map(|ray| (i, ray))
}

/// How many groups the traversal walks the active lanes of `rays` in: 1 for a packet
/// whose lanes agree on every direction sign, else one per sign octant present.
/// `raypack bench` reports the share of packets of a ray set that split.
pub fn sign_group_count(rays: &RayPacket) -> usize {
    sign_groups(rays, bits(rays.active)).1
}

/// Lane groups of `active` that agree on every direction sign: one group when the
/// packet is coherent, else one per sign octant present (zero components count as
/// positive; they agree with either side).
#[inline]
fn sign_groups(rays: &RayPacket, active: u32) -> ([u32; LANES], usize) {
    let neg = rays.dir.map(|d| bits(d.simd_lt(Vf::ZERO)) & active);
    let pos = rays.dir.map(|d| bits(d.simd_gt(Vf::ZERO)) & active);
    let mut groups = [0u32; LANES];
    if (0..3).all(|a| neg[a] == 0 || pos[a] == 0) {
        groups[0] = active;
        return (groups, 1);
    }
    let octant = |lane: u32| (0..3).map(|a| ((neg[a] >> lane) & 1) << a).sum::<u32>();
    let (mut left, mut count) = (active, 0);
    while left != 0 {
        let key = octant(left.trailing_zeros());
        let group = (0..LANES as u32)
            .filter(|&i| left & (1 << i) != 0 && octant(i) == key)
            .fold(0, |g, i| g | (1 << i));
        groups[count] = group;
        count += 1;
        left &= !group;
    }
    (groups, count)
}

impl KdTree {
    /// Closest hits of the active lanes of `rays` (planes included); inactive lanes get
    /// [`crate::ray::Hit::MISS`]. Lane by lane, the same hit as
    /// [`crate::accel::Accel::intersect`], `t`, `u`, `v` bit-identical.
    pub fn intersect_packet(&self, rays: &RayPacket) -> HitPacket {
        let mut best = HitPacket::miss();
        let (groups, count) = coherent_groups(rays, bits(rays.active));
        let mut alone = [None; LANES];
        for &group in &groups[..count] {
            match lone_lane(rays, group) {
                Some((i, ray)) => {
                    let mut hit = Hit::MISS;
                    self.traverse::<false>(&ray, &mut hit);
                    alone[i] = Some(hit);
                }
                None => {
                    self.traverse_packet::<false>(rays, mask_from_bits(group), &mut best);
                }
            }
        }
        if alone.iter().any(Option::is_some) {
            let grouped = best;
            best = HitPacket::from_lanes(|i| alone[i].unwrap_or_else(|| grouped.lane(i)));
        }
        self.prims
            .intersect_planes_packet(rays, rays.active, &mut best);
        best
    }

    /// Bit `i` set when active lane `i` is occluded between `t_min` and `t_max`; the
    /// same answer as [`crate::accel::Accel::occluded`] lane by lane.
    pub fn occluded_packet(&self, rays: &RayPacket) -> u32 {
        let by_plane = self.prims.planes_occlude_packet(rays, rays.active);
        let mut best = HitPacket::miss();
        let rest = bits(rays.active & !by_plane);
        let (groups, count) = coherent_groups(rays, rest);
        let mut occluded = bits(by_plane);
        for &group in &groups[..count] {
            match lone_lane(rays, group) {
                Some((_, ray)) => {
                    let mut unused = Hit::MISS;
                    if self.traverse::<true>(&ray, &mut unused) {
                        occluded |= group;
                    }
                }
                None => {
                    let lanes = mask_from_bits(group);
                    occluded |= bits(self.traverse_packet::<true>(rays, lanes, &mut best));
                }
            }
        }
        occluded
    }

    /// Walks the tree with the lanes of `active`, which agree on every direction sign.
    /// Closest hit: folds hits into `best`. With `ANY_HIT`: returns the lanes that hit
    /// anything in `(t_min, t_max)`, each lane leaving at its first hit.
    fn traverse_packet<const ANY_HIT: bool>(
        &self,
        rays: &RayPacket,
        active: Mask,
        best: &mut HitPacket,
    ) -> Mask {
        let (mut lanes, mut t_near, mut t_far) = clip_to_box_packet(&self.bounds, rays, active);
        let mut occluded = Mask::ZERO;
        if none(lanes) {
            return occluded;
        }
        // Near is the left child on axes where the group's directions are not negative.
        let negative = rays.dir.map(|d| any(lanes & d.simd_lt(Vf::ZERO)));
        let zero = rays.dir.map(|d| d.simd_eq(Vf::ZERO));
        let any_zero = zero.map(|z| any(lanes & z));
        // The plane margin and its `t` interval per axis, as the scalar path's `RayAxes`.
        let coord_max = self.coord_max();
        let o_max = max_abs(&rays.org);
        let margins: [Vf; 3] =
            std::array::from_fn(|a| (splat(coord_max[a]) + o_max) * splat(PLANE_SLACK));
        let slacks: [Vf; 3] = std::array::from_fn(|a| margins[a] * rays.inv_dir[a].abs());
        let mut stack = Stack::<Entry>::new();
        let mut node = 0u32;
        loop {
            let n = self.nodes[node as usize];
            if !n.is_leaf() {
                let axis = n.axis();
                let children = n.children();
                let (o, inv) = (rays.org[axis], rays.inv_dir[axis]);
                let split = splat(n.split);
                let margin = margins[axis];
                let t_split = (split - o) * inv;
                let slack = slacks[axis];
                let lo = t_split - slack;
                let hi = t_split + slack;
                let (near, far) = if negative[axis] {
                    (children + 1, children)
                } else {
                    (children, children + 1)
                };
                let (near_only, far_only) = if any_zero[axis] {
                    // Lanes parallel to the plane keep their interval and go to the
                    // sides within `margin` of their origin.
                    let z = zero[axis];
                    let left_only = (o + margin).simd_lt(split);
                    let right_only = (o - margin).simd_gt(split);
                    let (near_z, far_z) = if negative[axis] {
                        (right_only, left_only)
                    } else {
                        (left_only, right_only)
                    };
                    (
                        select(z, near_z, lo.simd_gt(t_far)),
                        select(z, far_z, hi.simd_lt(t_near)),
                    )
                } else {
                    let near_only = lo.simd_gt(t_far);
                    // The commonest step: every lane goes near only, its mask unchanged
                    // (the far test below could not remove a near-only lane).
                    if none(lanes & !near_only) {
                        node = near;
                        continue;
                    }
                    (near_only, hi.simd_lt(t_near))
                };
                // As in the scalar path, near-only wins when both tests pass.
                let near_lanes = lanes & !(far_only & !near_only);
                let far_lanes = lanes & !near_only;
                if none(far_lanes) {
                    node = near;
                    lanes = near_lanes;
                } else if none(near_lanes) {
                    node = far;
                    lanes = far_lanes;
                } else {
                    stack.push(Entry {
                        node: far,
                        lanes: far_lanes,
                        t_near: select(zero[axis], t_near, max_gt(lo, t_near)),
                        t_far,
                    });
                    node = near;
                    lanes = near_lanes;
                    t_far = select(zero[axis], t_far, min_lt(hi, t_far));
                }
                continue;
            }
            let first = n.leaf_first() as usize;
            let prims = &self.prim_indices[first..first + n.leaf_count() as usize];
            // Half the leaves are empty: skip the limit's arithmetic there.
            if !prims.is_empty() {
                if ANY_HIT {
                    let mut live = lanes;
                    for &p in prims {
                        let hits = self.prims.intersect_prim_packet(p, rays, live, rays.t_max);
                        occluded |= hits.mask;
                        live &= !hits.mask;
                        if none(live) {
                            break;
                        }
                    }
                    if none(active & !occluded) {
                        return occluded;
                    }
                } else {
                    let mut limit = next_up(best.t).min(rays.t_max);
                    for &p in prims {
                        let hits = self.prims.intersect_prim_packet(p, rays, lanes, limit);
                        if any(best.merge(&hits, p)) {
                            limit = next_up(best.t).min(rays.t_max);
                        }
                    }
                }
            }
            loop {
                let Some(e) = stack.pop() else {
                    return occluded;
                };
                lanes = if ANY_HIT {
                    e.lanes & !occluded
                } else {
                    e.lanes & !e.t_near.simd_gt(best.t)
                };
                if any(lanes) {
                    (node, t_near, t_far) = (e.node, e.t_near, e.t_far);
                    break;
                }
            }
        }
    }
}
