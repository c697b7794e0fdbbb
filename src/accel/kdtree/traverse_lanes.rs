//! Stage: accel. The kd-tree's lane walks: one ray per SIMD lane, each lane on its own
//! walk (Wald, Benthin and Boulos 2008 call this the SPMD or "single ray per lane"
//! form; Aila and Laine 2009 run it on GPUs). Incoherent rays share no nodes, so a
//! packet's lanes cannot decide together; here they do not have to. Every iteration
//! loads each lane's node ([`Uint::gather_pairs`]: `W` independent loads in flight, so
//! the cache misses of `W` rays overlap), decides the inner-node step of every lane in
//! SIMD without a branch, and ends the steps at leaves and empty children lane by lane
//! with the scalar code (`KdTree::leaf_step`, `Walk::pop`). A lane whose walk ends takes the
//! next ray of the stream.
//!
//! Invariant, so each ray's answer is the scalar path's bit for bit: a lane repeats
//! `KdTree::step` for its ray operation by operation (the band's ends at the split,
//! the near/far tests, the empty-child skips, the intervals and the pushes on the
//! lane's own stack), so it visits the scalar ray's leaves with its intervals in its
//! order; leaves, pops and the best-hit test run the scalar code itself. A ray with a
//! zero direction component takes the scalar walk whole (the parallel case is rare and
//! needs its own rule).

use super::KdTree;
use super::node::{NodeLanes, as_words};
use super::stats::bump;
use super::traverse::Walk;
use crate::ray::{Hit, Ray};
use crate::simd::{Float, LaneBits, LaneMask, MAX_LANES, Mask, Simd, Uint, Vf, Vu};
use glam::Vec3;

/// The lanes' walk state as arrays, one entry per lane: what the SIMD step loads and
/// stores, and what the lane-by-lane code reads and writes between steps.
#[repr(C, align(64))]
struct Lanes {
    node: [u32; MAX_LANES],
    t_near: [f32; MAX_LANES],
    t_far: [f32; MAX_LANES],
    /// The lane's best `t` so far (for the skip to a far child past it).
    best_t: [f32; MAX_LANES],
    /// Per axis: `1 / d` and the offsets of the band's ends in `t` ([`Walk`]'s axes).
    inv: [[f32; MAX_LANES]; 3],
    lo_off: [[f32; MAX_LANES]; 3],
    hi_off: [[f32; MAX_LANES]; 3],
}

impl Lanes {
    fn new() -> Lanes {
        Lanes {
            node: [0; MAX_LANES],
            t_near: [0.0; MAX_LANES],
            t_far: [0.0; MAX_LANES],
            best_t: [f32::INFINITY; MAX_LANES],
            inv: [[0.0; MAX_LANES]; 3],
            lo_off: [[0.0; MAX_LANES]; 3],
            hi_off: [[0.0; MAX_LANES]; 3],
        }
    }

    /// Lane `i` from `walk` (after [`KdTree::start_walk`] or [`Walk::pop`]).
    #[inline]
    fn load_walk(&mut self, i: usize, walk: &Walk, best: &Hit) {
        self.node[i] = walk.node;
        self.t_near[i] = walk.t_near;
        self.t_far[i] = walk.t_far;
        self.best_t[i] = best.t;
    }
}

#[inline(always)]
fn vf<W: Simd>(a: &[f32; MAX_LANES]) -> Vf<W> {
    Vf::<W>::from_fn(|i| a[i])
}

#[inline(always)]
fn store_f<W: Simd>(v: Vf<W>, a: &mut [f32; MAX_LANES]) {
    for (i, x) in a.iter_mut().enumerate().take(W::LANES) {
        *x = v.lane(i);
    }
}

/// Set bits of `bits`, lowest first.
#[inline]
fn lanes_of(mut bits: LaneBits) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            i
        })
    })
}

/// The walks of `W::LANES` rays, one per lane.
struct Group {
    st: Lanes,
    walks: [Walk; MAX_LANES],
    best: [Hit; MAX_LANES],
    ray_of: [usize; MAX_LANES],
    live: LaneBits,
}

impl KdTree {
    /// Walks every ray of `rays` through the tree, `W::LANES` at a time, one ray per
    /// lane, calling `done(i, answer, best)` once per ray `i` (in no particular order)
    /// with the scalar traversal's answer and closest hit (planes not folded in). With
    /// `ANY_HIT`, a ray a plane occludes is answered without walking.
    pub(super) fn walk_lanes<W: Simd, const ANY_HIT: bool>(
        &self,
        rays: &[Ray],
        mut done: impl FnMut(usize, bool, Hit),
    ) {
        let mut g = Group {
            st: Lanes::new(),
            walks: std::array::from_fn(|_| Walk::new()),
            best: [Hit::MISS; MAX_LANES],
            ray_of: [0; MAX_LANES],
            live: 0,
        };
        let mut next = 0;
        for i in 0..W::LANES {
            self.start_lane::<ANY_HIT>(&mut g, i, rays, &mut next, &mut done);
        }
        while g.live != 0 {
            self.lanes_step::<W, ANY_HIT>(&mut g, rays, &mut next, &mut done);
        }
    }

    /// Starts the next ray of `rays` from `*next` on that needs a walk in lane `i` of
    /// `g`, answering the others at once; the lane goes idle when none is left.
    fn start_lane<const ANY_HIT: bool>(
        &self,
        g: &mut Group,
        i: usize,
        rays: &[Ray],
        next: &mut usize,
        done: &mut impl FnMut(usize, bool, Hit),
    ) {
        g.live &= !(1 << i);
        g.st.node[i] = 0;
        while *next < rays.len() {
            let r = *next;
            *next += 1;
            let ray = &rays[r];
            if ANY_HIT && self.prims.planes_occlude(ray) {
                done(r, true, Hit::MISS);
            } else if ray.dir.cmpeq(Vec3::ZERO).any() {
                let mut hit = Hit::MISS;
                let answer = self.traverse::<ANY_HIT>(ray, &mut hit);
                done(r, answer, hit);
            } else if self.start_walk(ray, &mut g.walks[i]) {
                let walk = &g.walks[i];
                g.best[i] = Hit::MISS;
                g.st.load_walk(i, walk, &g.best[i]);
                for a in 0..3 {
                    g.st.inv[a][i] = walk.axes.inv[a];
                    g.st.lo_off[a][i] = walk.axes.lo_off[a];
                    g.st.hi_off[a][i] = walk.axes.hi_off[a];
                }
                g.ray_of[i] = r;
                g.live |= 1 << i;
                return;
            } else {
                done(r, false, Hit::MISS);
            }
        }
    }

    /// One iteration: every live lane's node loaded, the inner steps decided in SIMD,
    /// then leaves and stopped steps ended lane by lane and finished lanes restarted.
    #[inline(always)]
    fn lanes_step<W: Simd, const ANY_HIT: bool>(
        &self,
        g: &mut Group,
        rays: &[Ray],
        next: &mut usize,
        done: &mut impl FnMut(usize, bool, Hit),
    ) {
        let words = as_words(&self.nodes);
        let select = Vf::<W>::select;
        let one = Vu::<W>::splat(1);
        let st = &mut g.st;
        // Idle lanes sit at the root, a valid index.
        let node = Vu::<W>::from_fn(|i| st.node[i]);
        let (split, bits) = Vu::<W>::gather_pairs(words, node);
        let split = Vf::<W>::from_bits(split);
        let n = NodeLanes::<W>::decode(bits);
        let live_m = Mask::<W>::from_bits(g.live);
        let inner = live_m & !n.leaf;
        let pick = |v: &[[f32; MAX_LANES]; 3]| {
            select(
                n.axis[0],
                vf::<W>(&v[0]),
                select(n.axis[1], vf::<W>(&v[1]), vf::<W>(&v[2])),
            )
        };
        let (inv, lo_off, hi_off) = (pick(&st.inv), pick(&st.lo_off), pick(&st.hi_off));
        let (t_near, t_far) = (vf::<W>(&st.t_near), vf::<W>(&st.t_far));
        // Near is the right child where the direction is negative (never zero here).
        let negative = inv.cmp_lt(Vf::<W>::ZERO);
        let right = n.children + one;
        let near = Vu::<W>::select(negative, right, n.children);
        let far = Vu::<W>::select(negative, n.children, right);
        let [left_empty, right_empty] = n.empty;
        let near_empty = (negative & right_empty) | (!negative & left_empty);
        let far_empty = (negative & left_empty) | (!negative & right_empty);
        // The scalar step's tests, in its order.
        let (lo, hi) = (split.mul_add(inv, lo_off), split.mul_add(inv, hi_off));
        let near_only = lo.cmp_gt(t_far);
        let far_only = !near_only & hi.cmp_lt(t_near);
        let both = !near_only & !far_only;
        let entry = lo.max_gt(t_near);
        let past_best = if ANY_HIT {
            Mask::<W>::NONE
        } else {
            entry.cmp_gt(vf::<W>(&st.best_t))
        };
        // Lanes whose step goes only to empty children end it at the pops.
        let stop = inner
            & ((near_only & near_empty)
                | (far_only & far_empty)
                | (both & near_empty & (far_empty | past_best)));
        let to_far = far_only | (both & near_empty);
        let push = (inner & both & !near_empty & !far_empty).bits();
        let moving = inner & !stop;
        let next_node = Vu::<W>::select(moving & to_far, far, Vu::<W>::select(moving, near, node));
        let new_near = select(moving & both & near_empty, entry, t_near);
        let new_far = select(moving & both & !near_empty, hi.min_lt(t_far), t_far);
        bump(|c| c.node_steps += inner.bits().count_ones() as u64);
        for i in lanes_of(push) {
            g.walks[i]
                .stack
                .push((far.lane(i), entry.lane(i), t_far.lane(i)));
        }
        for (i, x) in st.node.iter_mut().enumerate().take(W::LANES) {
            *x = next_node.lane(i);
        }
        store_f::<W>(new_near, &mut st.t_near);
        store_f::<W>(new_far, &mut st.t_far);
        // Steps that went only to empty children pop at once; then the leaves, lane by
        // lane with the scalar code, and their pops (two loops, so neither branches on
        // which kind of lane it holds).
        for i in lanes_of(stop.bits()) {
            self.pop_lane::<ANY_HIT>(g, i, rays, next, done);
        }
        for i in lanes_of((live_m & n.leaf).bits()) {
            let here = self.nodes[g.st.node[i] as usize];
            let ray = &rays[g.ray_of[i]];
            if let Some(answer) = self.leaf_step::<ANY_HIT, true>(&here, ray, &mut g.best[i]) {
                done(g.ray_of[i], answer, g.best[i]);
                self.start_lane::<ANY_HIT>(g, i, rays, next, done);
            } else {
                self.pop_lane::<ANY_HIT>(g, i, rays, next, done);
            }
        }
    }

    /// Lane `i` goes on at the next node its stack holds ([`Walk::pop`]); when none is
    /// left its ray is done (no any-hit found) and the lane takes the next ray.
    #[inline(always)]
    fn pop_lane<const ANY_HIT: bool>(
        &self,
        g: &mut Group,
        i: usize,
        rays: &[Ray],
        next: &mut usize,
        done: &mut impl FnMut(usize, bool, Hit),
    ) {
        let walk = &mut g.walks[i];
        if walk.pop::<ANY_HIT>(&g.best[i]) {
            g.st.load_walk(i, walk, &g.best[i]);
        } else {
            done(g.ray_of[i], false, g.best[i]);
            self.start_lane::<ANY_HIT>(g, i, rays, next, done);
        }
    }
}
