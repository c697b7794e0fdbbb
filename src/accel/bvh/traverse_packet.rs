//! The packet walk: the rays of a coherent packet walk the BVH together, each step
//! testing one child box against every ray of the packet in one register (Wald, Boulos
//! and Shirley 2007), as Embree's hybrid traversal does (Benthin et al. 2012).
//! A primary or shadow packet's rays meet the same boxes, so one box load serves all
//! of them, where the single-ray walk ([`super::traverse`]) loads it once per ray.
//!
//! - Lanes are grouped by their direction's octant (the sign bit of each component,
//!   so +0.0 and -0.0 differ): within a group every ray has the same near plane on
//!   each axis, and the box test is the single walk's, lane for lane: the same
//!   margin written into the origin, the same inverses (infinite for a zero component,
//!   NaN where distances could overflow), fused where no lane has an infinite one. The
//!   reductions start from `t_min` and the limit, so a NaN slab limits nothing in any
//!   lane, whichever axis it is on.
//! - A group of few lanes (`alone_max`) walks one ray at a time through the single
//!   walk: a packet step costs about the same at any occupancy. Any-hit packets do the
//!   same at any node that few lanes still need: each of them walks that subtree alone
//!   (Embree's switch to single rays), and the packet pops.
//! - Each stack entry keeps every lane's entry distance (+inf for a lane that missed
//!   the box): a lane is tested in a leaf only if it reached the leaf's box before its
//!   best hit, and an entry whose lanes all have better hits is dropped when popped.
//!   The children a step hits go nearest first: closest-hit packets of up to 8 lanes
//!   sort them by the entry distance of their first hit lane; other packets keep the
//!   first and swap for a later one that is nearer for some lane (Embree's order).
//! - Leaves run `Prims::leaf_groups`, the kd-tree's packet leaf test,
//!   bit-identical to the scalar tests: every lane's hit is brute force's.
//! - Inactive lanes get an empty interval (`t_min` +inf, limit -inf): whatever they
//!   hold, NaN included, no box passes for them.

use super::traverse::{BOX_SLACK, STACK, Setup};
use super::{Bvh, EMPTY, LEAF_BIT};
use crate::accel::packet::{HitPacket, RayPacket, alone_max, trace_lanes_alone};
use crate::accel::stack::Stack;
use crate::ray::Hit;
use crate::simd::{
    AMap, Float, LaneBits, LaneMask, Mask, Simd, Vf, array_fn, dispatch, inl, max_abs,
};

impl Bvh {
    /// Closest hits of the active lanes of `rays` (planes included); inactive lanes get
    /// [`Hit::MISS`]. Lane by lane the same hit as [`crate::accel::Accel::intersect`],
    /// bit for bit.
    #[inline(always)]
    pub fn intersect_packet<W: Simd>(&self, rays: &RayPacket<W>) -> HitPacket<W> {
        dispatch!(W::LANES; self.intersect_packet_as::<@, W>(rays))
    }

    /// Bit `i` set when active lane `i` is occluded between `t_min` and `t_max`; the
    /// same answer as [`crate::accel::Accel::occluded`] lane by lane.
    #[inline(always)]
    pub fn occluded_packet<W: Simd>(&self, rays: &RayPacket<W>) -> LaneBits {
        dispatch!(W::LANES; self.occluded_packet_as::<@, W>(rays))
    }

    /// [`Bvh::intersect_packet`] of a packet of width `W` through backend `B`.
    #[inline(always)]
    fn intersect_packet_as<B: Simd, W: Simd>(&self, rays: &RayPacket<W>) -> HitPacket<W> {
        let rays = rays.recast::<B>();
        let (mut best, _) = self.walk_packet::<B, false>(&rays, rays.active, Mask::<B>::NONE);
        self.prims
            .intersect_planes_packet(&rays, rays.active, &mut best);
        best.recast()
    }

    /// [`Bvh::occluded_packet`] of a packet of width `W` through backend `B`.
    #[inline(always)]
    fn occluded_packet_as<B: Simd, W: Simd>(&self, rays: &RayPacket<W>) -> LaneBits {
        let rays = rays.recast::<B>();
        let by_plane = self.prims.planes_occlude_packet(&rays, rays.active);
        let (_, occluded) = self.walk_packet::<B, true>(&rays, rays.active & !by_plane, by_plane);
        occluded.bits()
    }

    /// The usable lanes of `active` through the BVH (planes aside): each octant group
    /// as a packet ([`Bvh::walk_group`]), or ray by ray when it is small. Closest hit:
    /// the hits, other lanes missing. With `ANY_HIT`: `occluded` and the lanes that
    /// hit anything.
    #[inline(always)]
    fn walk_packet<W: Simd, const ANY_HIT: bool>(
        &self,
        rays: &RayPacket<W>,
        active: Mask<W>,
        mut occluded: Mask<W>,
    ) -> (HitPacket<W>, Mask<W>) {
        let mut best = HitPacket::<W>::miss();
        let active = (active & rays.usable()).bits();
        if self.nodes.is_empty() || active == 0 {
            return (best, occluded);
        }
        // The sign bit of each component: `1 / -0.0` is -inf.
        let neg = rays.inv_dir.amap(
            #[inline(always)]
            |r| r.cmp_lt(Vf::<W>::ZERO).bits(),
        );
        let mut single = 0;
        let mut left = active;
        while left != 0 {
            // The octant of the lowest lane left, and every lane that shares it.
            let i = left.trailing_zeros();
            let same = inl(
                #[inline(always)]
                |a: usize| {
                    if neg[a] >> i & 1 != 0 {
                        neg[a]
                    } else {
                        !neg[a]
                    }
                },
            );
            let group = left & same(0) & same(1) & same(2);
            left &= !group;
            if group.count_ones() <= alone_max::<W>() {
                single |= group;
                continue;
            }
            let octant = array_fn(
                #[inline(always)]
                |a| neg[a] >> i & 1 != 0,
            );
            self.walk_group::<W, ANY_HIT>(
                rays,
                Mask::<W>::from_bits(group),
                octant,
                &mut best,
                &mut occluded,
            );
        }
        if single != 0 {
            let mut stack = [(0u32, 0.0f32); STACK];
            trace_lanes_alone::<W, ANY_HIT>(
                rays,
                single,
                &mut best,
                &mut occluded,
                #[inline(always)]
                |ray, hit| self.walk::<W::X8, ANY_HIT>(ray, hit, &mut stack, 0),
            );
        }
        (best, occluded)
    }

    /// The walk of the lanes `lanes`, whose directions all lie in `octant` (true where
    /// an axis's component is negative), from the root. Closest hit: folds their hits
    /// into `best`. With `ANY_HIT`: adds to `occluded` the lanes that hit anything in
    /// `(t_min, t_max)` and stops once every lane has.
    #[inline(always)]
    fn walk_group<W: Simd, const ANY_HIT: bool>(
        &self,
        rays: &RayPacket<W>,
        lanes: Mask<W>,
        octant: [bool; 3],
        best: &mut HitPacket<W>,
        occluded: &mut Mask<W>,
    ) {
        let splat = Vf::<W>::splat;
        let inf = splat(f32::INFINITY);
        // The single walk's margin and inverses, lane by lane (its docs say why).
        let reach = splat(self.coord_max) + max_abs(&rays.org);
        let margin = reach * splat(BOX_SLACK);
        let rcp = [0, 1, 2].amap(
            #[inline(always)]
            |a| {
                let (d, r) = (rays.dir[a], rays.inv_dir[a]);
                let keep = d.cmp_eq(Vf::<W>::ZERO) | (r.abs() * (reach * splat(4.0))).finite();
                Vf::<W>::select(keep, r, splat(f32::NAN))
            },
        );
        let toward = inl(
            #[inline(always)]
            |a: usize, far: bool| {
                if octant[a] != far {
                    rays.org[a] - margin
                } else {
                    rays.org[a] + margin
                }
            },
        );
        let org_near = array_fn(
            #[inline(always)]
            |a| toward(a, false),
        );
        let org_far = array_fn(
            #[inline(always)]
            |a| toward(a, true),
        );
        let near = array_fn(
            #[inline(always)]
            |a| 2 * a + octant[a] as usize,
        );
        let setup = Setup {
            off_near: array_fn(
                #[inline(always)]
                |a| -(org_near[a] * rcp[a]),
            ),
            off_far: array_fn(
                #[inline(always)]
                |a| -(org_far[a] * rcp[a]),
            ),
            org_near,
            org_far,
            rcp,
            near,
            far: near.map(
                #[inline(always)]
                |k| k ^ 1,
            ),
        };
        let infinite =
            (rcp[0].abs().cmp_eq(inf) | rcp[1].abs().cmp_eq(inf) | rcp[2].abs().cmp_eq(inf))
                & lanes;
        if infinite.none() {
            self.descend_group::<W, ANY_HIT, true>(rays, lanes, &setup, best, occluded);
        } else {
            self.descend_group::<W, ANY_HIT, false>(rays, lanes, &setup, best, occluded);
        }
    }

    /// The walk of [`Bvh::walk_group`] with `setup`. `FUSED` when no lane has an
    /// infinite inverse: a distance is then `plane * rcp + off`; else `(plane - org) *
    /// rcp`, which keeps a zero component's slab exact.
    #[inline(always)]
    fn descend_group<W: Simd, const ANY_HIT: bool, const FUSED: bool>(
        &self,
        rays: &RayPacket<W>,
        lanes: Mask<W>,
        setup: &Setup<W>,
        best: &mut HitPacket<W>,
        occluded: &mut Mask<W>,
    ) {
        let splat = Vf::<W>::splat;
        let select = Vf::<W>::select;
        let inf = splat(f32::INFINITY);
        // Outside `lanes` the interval is empty. The limit is also at most f32::MAX, so
        // that `dist <= limit` fails for a lane that missed a box (`dist` +inf).
        let t_min = select(lanes, rays.t_min, inf);
        let start = select(lanes, rays.t_max.min(splat(f32::MAX)), -inf);
        let mut limit = start;
        let mut words = Stack::<u32, STACK>::new();
        let mut dists = Stack::<Vf<W>, STACK>::new();
        let mut cur = 0u32;
        let mut cur_dist = t_min;
        // The single walk's stack, set up on the first hand-over.
        let mut single_stack = None;
        'walk: loop {
            // Few lanes need this node: with `ANY_HIT` each walks its subtree alone
            // (Embree's switch to single rays), and the packet pops. Closest-hit
            // packets keep walking together: the switch cost their primary sets 8-15%.
            let live = cur_dist.cmp_le(limit).bits();
            let handed_over = if ANY_HIT { alone_max::<W>() } else { 0 };
            if live.count_ones() <= handed_over {
                if ANY_HIT {
                    // Lazily: zeroing it costs a packet that never hands over.
                    #[allow(clippy::unnecessary_lazy_evaluations)]
                    let stack = single_stack.get_or_insert_with(
                        #[inline(always)]
                        || [(0u32, 0.0f32); STACK],
                    );
                    let mut bits = live;
                    while bits != 0 {
                        let i = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        if let Some(ray) = rays.lane(i) {
                            let mut unused = Hit::MISS;
                            if self.walk::<W::X8, true>(&ray, &mut unused, stack, cur) {
                                *occluded |= Mask::<W>::from_bits(1 << i);
                            }
                        }
                    }
                    if (lanes & !*occluded).none() {
                        return;
                    }
                    limit = select(*occluded, -inf, limit);
                }
            } else if cur & LEAF_BIT == 0 {
                let node = &self.nodes[cur as usize];
                let mut next = EMPTY;
                let mut next_dist = inf;
                // Closest-hit packets of up to 8 lanes go to the hit children nearest
                // first by their first hit lane's entry; at 16 lanes Embree's order
                // paid more (perf/log/bvh.md).
                let sorted = !ANY_HIT && W::LANES <= 8;
                let mut keys = [0.0f32; 8];
                let mut order = [(0u32, inf); 8];
                let mut nh = 0usize;
                for c in 0..8 {
                    let w = node.child[c];
                    if w == EMPTY {
                        break;
                    }
                    let slab = inl(
                        #[inline(always)]
                        |a: usize| {
                            let p_near = splat(node.planes[setup.near[a]][c]);
                            let p_far = splat(node.planes[setup.far[a]][c]);
                            if FUSED {
                                (
                                    p_near.mul_add_fast(setup.rcp[a], setup.off_near[a]),
                                    p_far.mul_add_fast(setup.rcp[a], setup.off_far[a]),
                                )
                            } else {
                                (
                                    (p_near - setup.org_near[a]) * setup.rcp[a],
                                    (p_far - setup.org_far[a]) * setup.rcp[a],
                                )
                            }
                        },
                    );
                    let ((n0, f0), (n1, f1), (n2, f2)) = (slab(0), slab(1), slab(2));
                    // `a.max_gt(acc)` keeps `acc` where `a` is NaN, and the chains start
                    // from the interval's ends, never NaN.
                    let t_near = n0.max_gt(n1.max_gt(n2.max_gt(t_min)));
                    let t_far = f0.min_lt(f1.min_lt(f2.min_lt(limit)));
                    let hit = t_near.cmp_le(t_far);
                    if hit.none() {
                        continue;
                    }
                    let dist = select(hit, t_near, inf);
                    if sorted {
                        // By the first hit lane's entry, farthest first.
                        let key = dist.lane(hit.bits().trailing_zeros() as usize);
                        let mut j = nh;
                        while j > 0 && keys[j - 1] < key {
                            keys[j] = keys[j - 1];
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        keys[j] = key;
                        order[j] = (w, dist);
                        nh += 1;
                        continue;
                    }
                    if next == EMPTY {
                        (next, next_dist) = (w, dist);
                    } else if dist.cmp_lt(next_dist).any() {
                        words.push(next);
                        dists.push(next_dist);
                        (next, next_dist) = (w, dist);
                    } else {
                        words.push(w);
                        dists.push(dist);
                    }
                }
                if sorted && nh > 0 {
                    for &(w, d) in &order[..nh - 1] {
                        words.push(w);
                        dists.push(d);
                    }
                    (next, next_dist) = order[nh - 1];
                }
                if next != EMPTY {
                    (cur, cur_dist) = (next, next_dist);
                    continue 'walk;
                }
            } else {
                let mut b = [*best];
                let mut o = [*occluded];
                self.prims.leaf_groups::<W, 1, ANY_HIT>(
                    self.leaf(cur),
                    #[inline(always)]
                    |_| rays,
                    &[Mask::<W>::from_bits(live)],
                    &mut b,
                    &mut o,
                    #[inline(always)]
                    |_| {},
                );
                (*best, *occluded) = (b[0], o[0]);
                if ANY_HIT {
                    if (lanes & !*occluded).none() {
                        return;
                    }
                    limit = select(*occluded, -inf, limit);
                } else {
                    limit = select(lanes, best.t.min(start), -inf);
                }
            }
            // Pop the next entry that some lane may still need.
            loop {
                let Some(w) = words.pop() else {
                    return;
                };
                let d = dists.pop().expect("one distance per entry");
                if d.cmp_le(limit).any() {
                    (cur, cur_dist) = (w, d);
                    continue 'walk;
                }
            }
        }
    }
}
