//! Stage: accel. Scalar front-to-back kd-tree traversal with an explicit stack, in the
//! spirit of Havran's robust recursive scheme (PhD thesis 2000, appendix C) as Wald
//! writes it (PhD thesis 2004, section 7.2): clip the ray to the scene box, then at each
//! inner node compute where the ray crosses the split plane and go near-only, far-only,
//! or near now and far later (pushed with its interval). Any-hit walks take the far
//! child first and push the near one (`KdTree::step` says why).
//!
//! Exactness, so the tree returns what brute force returns, bit for bit:
//! - A direction component of +0.0 or -0.0 never enters a division: the ray is on one
//!   side of the plane, or lies in it and then visits both children with the same
//!   interval.
//! - Planes are widened by [`PLANE_SLACK`] relative to the coordinates involved (8 ulps): a
//!   ray passing within rounding of a plane visits the cells on both sides, because a
//!   triangle test can round such a ray onto a triangle that lies across the plane (an
//!   axis-parallel ray through a shared corner, say). For a crossing ray the margin
//!   becomes an interval in `t`; for a parallel one, a band around the plane. The
//!   coordinates involved are the ray origin's largest coordinate ([`max_abs`], as the
//!   triangle test's error bound has it) and the tree box's largest coordinate on any
//!   axis (`box_coord_max`), which bounds every split position and every corner (a
//!   sliver long along one axis rounds a grazing hit off along the others): the margin
//!   is then one number per ray, computed once. A wider margin only visits more cells,
//!   never fewer.
//! - A node step computes the band's two ends in `t` as `split * inv + off`, the
//!   offsets `-(org * inv) -+ slack` computed once per ray and axis (`Bands`, made
//!   by `start`, the one set-up of every walk with the box clip): a
//!   multiplication and an addition between the node's load and its decision. Its two
//!   roundings stay within a quarter of the slack. The scalar walk computes it so on
//!   every CPU; the packet, tile and lane walks fuse it where the instruction set has
//!   FMA ([`crate::simd::Float::mul_add_fast`]): one rounding, also within the slack, so
//!   a band may differ in its last bit and a lane visit a cell more or fewer at a band's
//!   edge, but never miss one the exact band reaches, and the answer is the same. Rays
//!   whose `org * inv` or `split * inv` could overflow take the scalar walk there: an
//!   exact product plus an infinite offset is infinite on the wrong side of the plane.
//! - A primitive found in a leaf may be hit outside the leaf's cell; the search stops only
//!   when every node left on the stack starts beyond the best hit (for ordered intervals
//!   this is Havran's "the hit lies before the current node's exit"), so a closer hit in
//!   a later cell, or an equal `t` with a smaller id, is never missed.
//! - Leaves test with `t_max = next_up(best.t)` so equal-`t` ties reach
//!   [`Hit::is_closer`].

use super::KdTree;
use super::build::MAX_DEPTH;
use super::stats::bump;
use crate::accel::tile_lanes;
use crate::accel::triaccel::{max_abs, max_gt, min_lt};
use crate::accel::{Accel, HitPacket, RayPacket};
use crate::geom::Aabb;
use crate::ray::{Hit, Ray};
use crate::simd::{self, Float, LaneBits, W4, W8, W16, array_fn, by_width, scalar_entry};
use glam::Vec3;

/// Stack entries: one per level at most (a push happens at most once per level on the
/// way down, and [`MAX_DEPTH`] bounds the levels).
pub(super) const STACK_SIZE: usize = MAX_DEPTH as usize + 4;

/// The kd-tree walks' stack.
pub(super) type Stack<T> = crate::accel::stack::Stack<T, STACK_SIZE>;

/// Relative widening of split planes and of the scene box (8 ulps of f32).
pub const PLANE_SLACK: f32 = 1.0 / (1u32 << 20) as f32;

impl KdTree {
    /// The ray's parameter interval inside the tree's box, widened by [`PLANE_SLACK`] and
    /// cut to `[t_min, t_max]`; `None` when the ray misses the box (or has NaNs).
    /// `inv_dir` is `1 / dir` (a true division, as the packet path computes it).
    #[inline(always)]
    pub fn clip_ray(&self, ray: &Ray, inv_dir: Vec3) -> Option<(f32, f32)> {
        clip_to_box(&self.bounds, ray, inv_dir)
    }

    /// Closest hit among the tree's primitives (planes excluded), folded into `best`;
    /// with `ANY_HIT`, returns true at the first hit in `(t_min, t_max)` instead.
    #[inline(always)]
    pub(super) fn traverse<const ANY_HIT: bool>(&self, ray: &Ray, best: &mut Hit) -> bool {
        let mut walk = Walk::new();
        if !self.start_walk(ray, &mut walk) {
            return false;
        }
        loop {
            if let Some(answer) = self.step::<ANY_HIT>(&mut walk, ray, best) {
                return answer;
            }
        }
    }

    /// Sets `walk` up at the root for `ray`; false when the ray misses the tree's box
    /// (or is not usable), and then there is nothing to walk.
    #[inline(always)]
    pub(super) fn start_walk(&self, ray: &Ray, walk: &mut Walk) -> bool {
        let inv_dir = Vec3::ONE / ray.dir;
        let Some((bands, t_near, t_far)) = start_ray(&self.bounds, ray, inv_dir) else {
            return false;
        };
        walk.axes = RayAxes::new(ray, inv_dir, &bands);
        walk.stack.clear();
        walk.node = 0;
        walk.t_near = t_near;
        walk.t_far = t_far;
        true
    }

    /// One step of `ray`'s walk: an inner node, or a leaf and the stack pops that find
    /// the next node. `None` while the walk goes on; `Some(answer)` at its end (true
    /// when `ANY_HIT` found a hit). The near/far choice branches: a correct guess lets
    /// the CPU start the next node's load before the split test resolves (selects
    /// measured 5% slower on Sponza diffuse). The lane walks (traverse_lanes.rs) repeat
    /// this step in SIMD.
    ///
    /// With `ANY_HIT`, a ray that needs both children goes to the far one first and
    /// pushes the near one. Any hit answers, so the order is free, and a blocked ray is
    /// mostly blocked toward its far end: it leaves its surface through the detail
    /// around its origin and ends at a light or at the scene's outer walls, where the
    /// far-first walk meets a blocker after a few cells. Diffuse directions asked as
    /// any-hit (shadow rays toward a sky): Sponza 3.8x-4.0x, the conference room
    /// 2.0x-2.2x, isolated models (whose rays mostly escape, so every cell is walked
    /// either way) 0.93x-1.16x; point-light shadow sets 1.04x over the suite
    /// (perf/log/stream.md, "Far child first").
    #[inline(always)]
    pub(super) fn step<const ANY_HIT: bool>(
        &self,
        walk: &mut Walk,
        ray: &Ray,
        best: &mut Hit,
    ) -> Option<bool> {
        let axes = &walk.axes;
        let n = self.nodes[walk.node as usize];
        // An inner node whose ray goes only to empty children (they hold nothing) ends
        // the step here, at the pops below, as a leaf does.
        'visit: {
            if n.is_leaf() {
                break 'visit;
            }
            bump(|c| c.node_steps += 1);
            let axis = n.axis() & 3;
            let children = n.children();
            // Bit 0: the left child is an empty leaf; bit 1: the right one.
            let empty = n.empty_children();
            let o = axes.org[axis];
            // Within `margin` of the plane, a triangle test can round a ray onto
            // either side of it.
            let margin = axes.margin[axis];
            if axes.zero[axis] {
                let (left, right) = (empty & 1 == 0, empty & 2 == 0);
                if o + margin < n.split {
                    if !left {
                        break 'visit;
                    }
                    walk.node = children;
                } else if o - margin > n.split {
                    if !right {
                        break 'visit;
                    }
                    walk.node = children + 1;
                } else if !left {
                    walk.node = children + 1;
                } else {
                    if right {
                        walk.stack.push((children + 1, walk.t_near, walk.t_far));
                    }
                    walk.node = children;
                }
            } else {
                let inv = axes.inv[axis];
                let lo = n.split * inv + axes.lo_off[axis];
                let hi = n.split * inv + axes.hi_off[axis];
                let negative = axes.negative[axis];
                let near = children + negative;
                let far = children + 1 - negative;
                let near_far = n.empty_near_far(negative);
                let (near_empty, far_empty) = (near_far & 1 != 0, near_far & 2 != 0);
                if lo > walk.t_far {
                    if near_empty {
                        break 'visit;
                    }
                    walk.node = near;
                } else if hi < walk.t_near {
                    if far_empty {
                        break 'visit;
                    }
                    walk.node = far;
                } else {
                    // `max_gt`/`min_lt` keep `t_near`/`t_far` where the split distance is
                    // NaN (a ray in the plane with a subnormal component), as the packet
                    // path.
                    let entry = max_gt(lo, walk.t_near);
                    if ANY_HIT && !near_empty && !far_empty {
                        // Any-hit walks go far child first ([`KdTree::step`]).
                        walk.stack.push((near, walk.t_near, min_lt(hi, walk.t_far)));
                        walk.node = far;
                        walk.t_near = entry;
                    } else if near_empty {
                        // Straight to the far child, with the interval and the test
                        // its pop would have had.
                        if far_empty || (!ANY_HIT && entry > best.t) {
                            break 'visit;
                        }
                        walk.node = far;
                        walk.t_near = entry;
                    } else {
                        if !far_empty {
                            walk.stack.push((far, entry, walk.t_far));
                        }
                        walk.node = near;
                        walk.t_far = min_lt(hi, walk.t_far);
                    }
                }
            }
            return None;
        }
        // A leaf's primitives, then the pops that find the next node.
        if n.is_leaf()
            && let Some(answer) = self.leaf_step::<ANY_HIT>(&n, ray, best)
        {
            return Some(answer);
        }
        if walk.pop::<ANY_HIT>(best) {
            None
        } else {
            Some(false)
        }
    }

    /// The primitives of the leaf `n` against `ray`, one test each: closest hit folded
    /// into `best`, or with `ANY_HIT`, `Some(true)` at the first hit. The lane walks
    /// test the triangles in lanes instead (`traverse_lanes::leaf_lanes_step`).
    #[inline(always)]
    pub(super) fn leaf_step<const ANY_HIT: bool>(
        &self,
        n: &super::node::KdNode,
        ray: &Ray,
        best: &mut Hit,
    ) -> Option<bool> {
        let prims = self.visit_leaf(n)?;
        self.one_by_one::<ANY_HIT>(prims, ray, best).then_some(true)
    }

    /// The slots of the leaf `n`, counted as a visit; `None` when it is empty.
    #[inline(always)]
    pub(super) fn visit_leaf(&self, n: &super::node::KdNode) -> Option<&[u32]> {
        let prims = self.leaf_prims(n);
        bump(|c| c.leaf_visits += 1);
        (!prims.is_empty()).then_some(prims)
    }

    /// The primitives in `slots` against `ray`, one test each: closest hit folded into
    /// `best`, or with `ANY_HIT`, true at the first hit.
    #[inline(always)]
    pub(super) fn one_by_one<const ANY_HIT: bool>(
        &self,
        slots: &[u32],
        ray: &Ray,
        best: &mut Hit,
    ) -> bool {
        if ANY_HIT {
            // A loop, not `Iterator::any`, which LLVM may keep out of line (see
            // `crate::simd::inl`).
            for &p in slots {
                bump(|c| c.prim_tests += 1);
                if self.prims.intersect_prim(p, ray, ray.t_max).is_some() {
                    return true;
                }
            }
        } else {
            bump(|c| c.prim_tests += slots.len() as u64);
            self.prims.intersect_leaf(slots, ray, best);
        }
        false
    }
}

/// One ray's kd-tree walk between steps: its per-axis quantities, its stack, the node
/// it goes to next and its interval there.
pub(super) struct Walk {
    pub(super) axes: RayAxes,
    pub(super) stack: Stack<(u32, f32, f32)>,
    pub(super) node: u32,
    pub(super) t_near: f32,
    pub(super) t_far: f32,
}

impl Walk {
    /// Pops the stack down to the next node the ray still needs (closest hit: one that
    /// starts no later than `best`), and goes there with its interval; false when the
    /// stack runs out and the walk is over.
    #[inline(always)]
    pub(super) fn pop<const ANY_HIT: bool>(&mut self, best: &Hit) -> bool {
        loop {
            let Some((next, entry, exit)) = self.stack.pop() else {
                return false;
            };
            if !ANY_HIT && entry > best.t {
                continue;
            }
            (self.node, self.t_near, self.t_far) = (next, entry, exit);
            return true;
        }
    }

    /// An idle walk, for [`KdTree::start_walk`] to set up.
    #[inline(always)]
    pub(super) fn new() -> Walk {
        Walk {
            axes: RayAxes {
                org: [0.0; 4],
                inv: [0.0; 4],
                margin: [0.0; 4],
                lo_off: [0.0; 4],
                hi_off: [0.0; 4],
                negative: [0; 4],
                zero: [false; 4],
            },
            stack: Stack::new(),
            node: 0,
            t_near: 0.0,
            t_far: 0.0,
        }
    }
}

/// A ray's per-axis quantities for the scalar walk, indexed by a node's axis (`axis &
/// 3`, so the index needs no bounds check; the fourth entry is never read).
pub(super) struct RayAxes {
    pub(super) org: [f32; 4],
    pub(super) inv: [f32; 4],
    /// [`Bands::margin`] on every axis (one `f32` here shifted the lane walks' stacks
    /// in memory and cost the streams about 1%, perf/log/overview.md).
    margin: [f32; 4],
    /// [`Bands::lo_off`] and [`Bands::hi_off`].
    pub(super) lo_off: [f32; 4],
    pub(super) hi_off: [f32; 4],
    /// 1 where the direction is negative (near is the right child), else 0.
    negative: [u32; 4],
    /// The direction component is +0.0 or -0.0.
    zero: [bool; 4],
}

impl RayAxes {
    #[inline(always)]
    fn new(ray: &Ray, inv_dir: Vec3, bands: &Bands<f32>) -> RayAxes {
        let four = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
        let d = four(ray.dir.to_array());
        RayAxes {
            org: four(ray.org.to_array()),
            inv: four(inv_dir.to_array()),
            margin: [bands.margin; 4],
            lo_off: four(bands.lo_off),
            hi_off: four(bands.hi_off),
            negative: d.map(|c| (c < 0.0) as u32),
            zero: d.map(|c| c == 0.0),
        }
    }
}

/// A ray's plane bands, set up once per ray by this one function for every walk: for
/// one ray (`F = f32`, the scalar walk) or one per lane (the packet, tile and lane
/// walks), so all start from the same bits.
///
/// A triangle test can round a ray onto either side of a plane within `margin` of it;
/// `margin` grows with the largest coordinate a split or the origin has (`reach`), on
/// every axis (module docs). In `t` that band is `slack` wide on each side of the
/// split distance, and its ends at a plane `split` are `split * inv + lo_off` and
/// `split * inv + hi_off`: a multiplication and an addition per node step.
#[derive(Clone, Copy)]
pub(super) struct Bands<F> {
    /// `coord_max + |org|max`.
    pub(super) reach: F,
    /// `reach * PLANE_SLACK`, the band's half-width in space.
    pub(super) margin: F,
    /// `margin * |inv|` per axis, its half-width in `t`.
    pub(super) slack: [F; 3],
    /// `-(org * inv) - slack` per axis.
    pub(super) lo_off: [F; 3],
    /// `-(org * inv) + slack` per axis.
    pub(super) hi_off: [F; 3],
}

impl<F: Float> Bands<F> {
    /// The bands of rays from `org` with reciprocal directions `inv` in a tree whose
    /// box has `coord_max` as its largest absolute coordinate ([`box_coord_max`]).
    #[inline(always)]
    pub(super) fn new(org: &[F; 3], inv: &[F; 3], coord_max: f32) -> Bands<F> {
        let reach = F::splat(coord_max) + simd::max_abs(org);
        let margin = reach * F::splat(PLANE_SLACK);
        let slack: [F; 3] = array_fn(
            #[inline(always)]
            |a| margin * inv[a].abs(),
        );
        let base: [F; 3] = array_fn(
            #[inline(always)]
            |a| -(org[a] * inv[a]),
        );
        Bands {
            reach,
            margin,
            slack,
            lo_off: array_fn(
                #[inline(always)]
                |a| base[a] - slack[a],
            ),
            hi_off: array_fn(
                #[inline(always)]
                |a| base[a] + slack[a],
            ),
        }
    }
}

/// The one set-up of every walk, for one ray (`F = f32`, the scalar walk) or one per
/// lane (the packet, tile and lane walks): the rays' [`Bands`], and `[t_min, t_max]`
/// of the rays `[org, dir, inv]` (`inv = 1 / dir`) cut to the part inside `b` (the
/// tree's box), widened by their bands' `margin`, with the mask of the rays of `live`
/// that reach the box. The caller leaves rays that are not usable out of `live` (a NaN
/// or infinite origin or direction component, or a zero direction): they miss every
/// primitive anyway, and must not walk the whole tree to find that out.
#[inline(always)]
pub(super) fn start<F: Float>(
    b: &Aabb,
    [org, dir, inv]: [&[F; 3]; 3],
    (t_min, t_max): (F, F),
    live: F::Mask,
) -> (Bands<F>, (F::Mask, F, F)) {
    let bands = Bands::new(org, inv, box_coord_max(b));
    let (splat, select) = (F::splat, F::select);
    let (mut t0, mut t1) = (t_min, t_max);
    let mut live = live;
    // The triangle test's rounding grows with the origin's largest coordinate on every
    // axis (a ray from far away along z can land a hit off in y by that much), so the box
    // is widened by it and by the box's (`box_coord_max`), not by the coordinates of
    // its own axis alone.
    let margin = bands.margin;
    for axis in 0..3 {
        let o = org[axis];
        let (lo, hi) = (b.min[axis], b.max[axis]);
        let d = dir[axis];
        // A ray parallel to the slab must start inside it.
        let parallel = d.cmp_eq(F::ZERO);
        let inside = o.cmp_ge(splat(lo) - margin) & o.cmp_le(splat(hi) + margin);
        live &= !parallel | inside;
        let slack = bands.slack[axis];
        let ta = (splat(lo) - o) * inv[axis];
        let tb = (splat(hi) - o) * inv[axis];
        let positive = d.cmp_gt(F::ZERO);
        let t_lo = select(positive, ta, tb);
        let t_hi = select(positive, tb, ta);
        t0 = select(parallel, t0, t0.max(t_lo - slack));
        t1 = select(parallel, t1, t1.min(t_hi + slack));
    }
    (bands, (live & t0.cmp_le(t1), t0, t1))
}

/// [`start`] for one ray: its bands and its interval in `b`, `None` when the ray is not
/// usable or misses `b`.
#[inline(always)]
fn start_ray(b: &Aabb, ray: &Ray, inv_dir: Vec3) -> Option<(Bands<f32>, f32, f32)> {
    if !ray.is_usable() {
        return None;
    }
    let (org, dir, inv) = (ray.org.to_array(), ray.dir.to_array(), inv_dir.to_array());
    let (bands, (reach, t0, t1)) = start(b, [&org, &dir, &inv], (ray.t_min, ray.t_max), true);
    reach.then_some((bands, t0, t1))
}

/// `[t_min, t_max]` cut to the part of the ray inside `b`, widened by [`PLANE_SLACK`]
/// (the interval of the walks' set-up). A ray with a NaN or infinite origin or
/// direction component, a zero direction, or `!(t_min <= t_max)` gets `None`.
#[inline(always)]
pub fn clip_to_box(b: &Aabb, ray: &Ray, inv_dir: Vec3) -> Option<(f32, f32)> {
    start_ray(b, ray, inv_dir).map(|(_, t0, t1)| (t0, t1))
}

/// The largest absolute coordinate of `b` on any axis. The triangle test's rounding
/// grows with the triangle's largest coordinate on every axis, as it does with the
/// origin's (a sliver long along x can land a grazing ray's hit off in y by that much),
/// so the box and plane margins are scaled by it, not by the coordinates of their own
/// axis alone.
#[inline(always)]
pub(crate) fn box_coord_max(b: &Aabb) -> f32 {
    max_abs(b.min).max(max_abs(b.max))
}

impl Accel for KdTree {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        scalar_entry(
            #[inline(always)]
            || {
                let mut best = Hit::MISS;
                self.traverse::<false>(ray, &mut best);
                self.prims.intersect_planes(ray, &mut best);
                best.is_hit().then_some(best)
            },
        )
    }

    fn occluded(&self, ray: &Ray) -> bool {
        scalar_entry(
            #[inline(always)]
            || {
                let mut unused = Hit::MISS;
                self.prims.planes_occlude(ray) || self.traverse::<true>(ray, &mut unused)
            },
        )
    }

    fn intersect_packet4(&self, rays: &RayPacket<W4>) -> HitPacket<W4> {
        KdTree::intersect_packet(self, rays)
    }

    fn intersect_packet8(&self, rays: &RayPacket<W8>) -> HitPacket<W8> {
        KdTree::intersect_packet(self, rays)
    }

    fn intersect_packet16(&self, rays: &RayPacket<W16>) -> HitPacket<W16> {
        KdTree::intersect_packet(self, rays)
    }

    fn occluded_packet4(&self, rays: &RayPacket<W4>) -> LaneBits {
        KdTree::occluded_packet(self, rays)
    }

    fn occluded_packet8(&self, rays: &RayPacket<W8>) -> LaneBits {
        KdTree::occluded_packet(self, rays)
    }

    fn occluded_packet16(&self, rays: &RayPacket<W16>) -> LaneBits {
        KdTree::occluded_packet(self, rays)
    }

    fn intersect_tile(&self, rays: &[Ray], out: &mut [Hit]) {
        by_width!(tile_lanes(), W in [8, 16] => KdTree::intersect_tile::<W>(self, rays, out))
    }

    fn occluded_tile(&self, rays: &[Ray]) -> u64 {
        by_width!(tile_lanes(), W in [8, 16] => KdTree::occluded_tile::<W>(self, rays))
    }

    fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        KdTree::intersect_stream(self, rays, hits)
    }

    fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
        KdTree::occluded_stream(self, rays, occluded)
    }
}
