//! Stage: accel. Ray tiles: up to [`TILE_RAYS`] coherent rays (64 consecutive rays of
//! an image set in RAYS.md's packet order are a 16x4 pixel block; their shadow rays
//! toward one point light agree as well) traced as groups of SIMD packets that share an
//! entry point (Reshetov, Soupikov and Hurley 2005, multi-level ray tracing).
//!
//! From the root, the whole tile descends while a conservative bound decides for all its
//! rays at once: per axis, the interval of the origins and of the reciprocal directions
//! gives an interval holding every lane's exact split distance (the corner products,
//! widened by [`PLANE_SLACK`] of their size for their own rounding), widened again by
//! twice the largest plane slack: a lane's band ends, `split * inv + off` rounded
//! ([`super::traverse`]), lie within a third of its slack of the exact ones, so the
//! widened interval holds each lane's rounded band. Where that interval lies past every
//! lane's `t_far`, every lane would go near only; where it lies before every lane's
//! `t_near`, far only. From the first node where the bound cannot decide, the groups
//! walk on together (Overbeck, Ramamoorthi and Mark 2008, partition traversal): one
//! node load per step for the whole tile, each group deciding for its own lanes with the
//! packet traversal's operations ([`super::traverse_packet`]), the tile going near only,
//! far only or both as the union of the groups needs, with one stack of per-group lane
//! masks and intervals. On Sponza's camera rays this takes a third of the node steps of
//! 16-lane packets (perf/log/wide.md).
//!
//! Invariant, so each lane returns exactly the scalar path's answer: the descent takes
//! only steps that every lane's own (scalar) decision takes too, near only or far only,
//! and such steps leave the lane's interval and the scalar stack unchanged. So each lane
//! arrives at the entry node with its clipped interval and an empty stack, exactly as
//! the scalar traversal does, and nothing it needs lies outside that node's subtree.
//! Below it, a lane is active exactly where its scalar traversal is, with the same
//! interval and in the same front-to-back order (all the tile's lanes agree on the
//! near child), and a group with no lane on a side rides along masked off.
//! Tiles whose lanes disagree on a direction sign, have a zero or non-invertible
//! direction component (or one so small that the node step may overflow,
//! `traverse_packet::overflow_lanes`), or fit in one group skip the descent and trace
//! each group as an ordinary packet; [`super::stats`] counts how often.

use super::KdTree;
use super::stats::bump;
use super::traverse::{PLANE_SLACK, Stack};
use super::traverse_packet::{clip_to_box_packet, step_overflows};
use crate::accel::packet::{HitPacket, RayPacket, low_bits};
use crate::ray::{Hit, Ray};
use crate::simd::{Float, LaneMask, Mask, Simd, Vf, array_fn, dispatch, inl, max_abs};

use crate::accel::{TILE_RAYS, TileWidth};

/// Groups of the narrowest width a tile is made of (8 lanes).
const MAX_GROUPS: usize = TILE_RAYS / 8;

/// Counts a tile ([`super::stats`]): whether it fell back to packets per group, and
/// the nodes it passed as a whole.
#[inline(always)]
fn count(fallback: bool, depth: u64) {
    bump(
        #[inline(always)]
        |c| {
            c.tiles += 1;
            c.tile_fallbacks += fallback as u64;
            c.tile_entry_depth += depth;
        },
    );
}

/// One pending far child of a tile: its node and, per group, the lanes that need it and
/// their interval.
#[derive(Clone, Copy)]
struct TileEntry<W: Simd, const G: usize> {
    node: u32,
    lanes: [Mask<W>; G],
    t_near: [Vf<W>; G],
    t_far: [Vf<W>; G],
}

/// Per-lane values reduced over the live lanes of all groups.
#[derive(Clone, Copy)]
struct Bound {
    o_lo: [f32; 3],
    o_hi: [f32; 3],
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    slack_max: [f32; 3],
    t_near_min: f32,
    t_far_max: f32,
    negative: [bool; 3],
}

impl KdTree {
    /// Closest hits of `rays` (at most [`TILE_RAYS`]) into `out`, groups of `W::LANES`
    /// sharing an entry point; lane by lane the answer of
    /// [`crate::accel::Accel::intersect`], bit for bit. A tile takes groups of 8 or 16
    /// lanes ([`TileWidth`]); 4 is a compile error:
    ///
    /// ```compile_fail
    /// use raypack::prelude::*;
    /// let tree = KdTree::build(&Geometry::default());
    /// tree.intersect_tile::<W4>(&[], &mut []);
    /// ```
    #[inline(always)]
    pub fn intersect_tile<W: TileWidth>(&self, rays: &[Ray], out: &mut [Hit]) {
        dispatch!(W::LANES; self.intersect_tile_in::<@>(rays, out))
    }

    /// [`KdTree::intersect_tile`] at backend `W`, inside its entry.
    #[inline(always)]
    fn intersect_tile_in<W: Simd>(&self, rays: &[Ray], out: &mut [Hit]) {
        assert!(rays.len() <= TILE_RAYS && rays.len() == out.len());
        let n = rays.len().div_ceil(W::LANES);
        let groups = groups::<W>(rays);
        let groups = &groups[..n];
        let actives: [Mask<W>; MAX_GROUPS] = array_fn(
            #[inline(always)]
            |g| match groups.get(g) {
                Some(p) => p.active,
                None => Mask::<W>::NONE,
            },
        );
        let mut best = [HitPacket::<W>::miss(); MAX_GROUPS];
        match self.tile_entry(groups, &actives[..n]) {
            Some((node, clips)) => {
                let mut unused = [Mask::<W>::NONE; MAX_GROUPS];
                self.tile_walk::<W, false>(groups, node, &clips, &mut best, &mut unused);
                for (g, p) in groups.iter().enumerate() {
                    self.prims
                        .intersect_planes_packet(p, p.active, &mut best[g]);
                }
            }
            None => {
                for (g, p) in groups.iter().enumerate() {
                    best[g] = self.intersect_packet_in(p);
                }
            }
        }
        for (g, hits) in out.chunks_mut(W::LANES).enumerate() {
            best[g].write(hits);
        }
    }

    /// Bit `i` set when ray `i` of `rays` (at most [`TILE_RAYS`]) is occluded; the answer
    /// of [`crate::accel::Accel::occluded`] ray by ray.
    #[inline(always)]
    pub fn occluded_tile<W: TileWidth>(&self, rays: &[Ray]) -> u64 {
        dispatch!(W::LANES; self.occluded_tile_in::<@>(rays))
    }

    /// [`KdTree::occluded_tile`] at backend `W`, inside its entry.
    #[inline(always)]
    fn occluded_tile_in<W: Simd>(&self, rays: &[Ray]) -> u64 {
        assert!(rays.len() <= TILE_RAYS);
        let n = rays.len().div_ceil(W::LANES);
        let groups = groups::<W>(rays);
        let groups = &groups[..n];
        let by_plane: [Mask<W>; MAX_GROUPS] = array_fn(
            #[inline(always)]
            |g| match groups.get(g) {
                Some(p) => self.prims.planes_occlude_packet(p, p.active),
                None => Mask::<W>::NONE,
            },
        );
        let actives: [Mask<W>; MAX_GROUPS] = array_fn(
            #[inline(always)]
            |g| match groups.get(g) {
                Some(p) => p.active & !by_plane[g],
                None => Mask::<W>::NONE,
            },
        );
        let mut bits = 0u64;
        match self.tile_entry(groups, &actives[..n]) {
            Some((node, clips)) => {
                let mut unused = [HitPacket::<W>::miss(); MAX_GROUPS];
                let mut hit = by_plane;
                self.tile_walk::<W, true>(groups, node, &clips, &mut unused, &mut hit);
                for (g, h) in hit.iter().enumerate().take(n) {
                    bits |= (h.bits() as u64) << (g * W::LANES);
                }
            }
            None => {
                for (g, p) in groups.iter().enumerate() {
                    bits |= (self.occluded_packet_in(p) as u64) << (g * W::LANES);
                }
            }
        }
        bits
    }

    /// The tile's groups walk the tree together from `node` (the entry point), each with
    /// its lanes and interval `clips`: one node load and one decision per step for the
    /// whole tile, one shared stack (Overbeck, Ramamoorthi and Mark 2008, partition
    /// traversal). Closest hit: folds hits into `best`; with `ANY_HIT`, sets the
    /// occluded lanes in `occluded`.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    fn tile_walk<W: Simd, const ANY_HIT: bool>(
        &self,
        groups: &[RayPacket<W>],
        node: u32,
        clips: &[(Mask<W>, Vf<W>, Vf<W>); MAX_GROUPS],
        best: &mut [HitPacket<W>; MAX_GROUPS],
        occluded: &mut [Mask<W>; MAX_GROUPS],
    ) {
        // Out of line, compiled for `W`'s instruction set: the walk apart from the
        // tile's set-up (inlined, tile64 lost 3-8% on the bunny, perf/isa.md).
        W::enter(
            #[inline(always)]
            || match W::LANES {
                16 => self.tile_walk_n::<W, 4, ANY_HIT>(groups, node, clips, best, occluded),
                _ => {
                    self.tile_walk_n::<W, MAX_GROUPS, ANY_HIT>(groups, node, clips, best, occluded)
                }
            },
        )
    }

    /// [`Self::tile_walk`] with `G` groups (`G * W::LANES` = [`TILE_RAYS`]; groups past
    /// `groups.len()` have no lanes).
    ///
    /// Each group's lanes take the packet traversal's decisions with its operations
    /// ([`super::traverse_packet`]), and the tile goes near only, far only, or near now
    /// and far later as the union of its groups requires; a group with no lane on a side
    /// rides along masked off. The tile's lanes agree on every direction sign and have
    /// no zero component ([`Self::tile_bound`]), so near and far mean the same child for
    /// all of them, and each lane visits exactly the nodes the scalar path visits, with
    /// the same interval, front to back.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    fn tile_walk_n<W: Simd, const G: usize, const ANY_HIT: bool>(
        &self,
        groups: &[RayPacket<W>],
        mut node: u32,
        clips: &[(Mask<W>, Vf<W>, Vf<W>); MAX_GROUPS],
        best: &mut [HitPacket<W>; MAX_GROUPS],
        occluded: &mut [Mask<W>; MAX_GROUPS],
    ) {
        let splat = Vf::<W>::splat;
        let n_groups = groups.len().min(G);
        let mut lanes: [Mask<W>; G] = array_fn(
            #[inline(always)]
            |g| {
                if g < n_groups {
                    clips[g].0
                } else {
                    Mask::<W>::NONE
                }
            },
        );
        let mut t_near: [Vf<W>; G] = array_fn(
            #[inline(always)]
            |g| clips[g].1,
        );
        let mut t_far: [Vf<W>; G] = array_fn(
            #[inline(always)]
            |g| clips[g].2,
        );
        if union::<W, G>(&lanes).none() {
            return;
        }
        let rays = inl(
            #[inline(always)]
            |g: usize| &groups[g.min(n_groups - 1)],
        );
        let actives: [Mask<W>; G] = array_fn(
            #[inline(always)]
            |g| lanes[g],
        );
        let mut negative = [false; 3];
        for (g, l) in lanes.iter().enumerate() {
            for (a, n) in negative.iter_mut().enumerate() {
                *n |= (*l & rays(g).dir[a].cmp_lt(Vf::<W>::ZERO)).any();
            }
        }
        // Per axis, the groups' origins, reciprocals and plane slacks side by side, so
        // that a step loads them at one offset.
        // As bits, so that the next node's index is a shift from the node just loaded.
        let neg_bits = (0..3).fold(
            0u32,
            #[inline(always)]
            |b, a| b | (negative[a] as u32) << a,
        );
        let coord_max = self.coord_max();
        let o_max: [Vf<W>; G] = array_fn(
            #[inline(always)]
            |g| max_abs(&rays(g).org),
        );
        let inv: [[Vf<W>; G]; 3] = array_fn(
            #[inline(always)]
            |a| {
                array_fn(
                    #[inline(always)]
                    |g| rays(g).inv_dir[a],
                )
            },
        );
        // The band's ends at a plane as `split * inv + off` (`RayAxes`).
        let offs = inl(
            #[inline(always)]
            |sign: f32| -> [[Vf<W>; G]; 3] {
                array_fn(
                    #[inline(always)]
                    |a| {
                        array_fn(
                            #[inline(always)]
                            |g| {
                                let slack = (splat(coord_max[a]) + o_max[g])
                                    * splat(PLANE_SLACK)
                                    * inv[a][g].abs();
                                let neg = -(rays(g).org[a] * inv[a][g]);
                                if sign < 0.0 { neg - slack } else { neg + slack }
                            },
                        )
                    },
                )
            },
        );
        let (lo_offs, hi_offs) = (offs(-1.0), offs(1.0));
        let mut stack = Stack::<TileEntry<W, G>>::new();
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
                    if !prims.is_empty() {
                        self.leaf_groups::<W, G, ANY_HIT>(prims, &rays, &lanes, best, occluded);
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
                    // The commonest step: every lane goes near only (an empty near
                    // leaf holds nothing for them).
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
                } else {
                    stack.push(TileEntry {
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

    /// The entry node of the tile's groups (their lanes `actives`) and each group's lanes
    /// and interval clipped to the tree's box; `None` where the tile falls back to one
    /// packet per group (see the module docs). Counts the tile.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    fn tile_entry<W: Simd>(
        &self,
        groups: &[RayPacket<W>],
        actives: &[Mask<W>],
    ) -> Option<(u32, [(Mask<W>, Vf<W>, Vf<W>); MAX_GROUPS])> {
        let Some(bound) = (groups.len() > 1)
            .then(
                #[inline(always)]
                || self.tile_bound(groups, actives),
            )
            .flatten()
        else {
            count(true, 0);
            return None;
        };
        let (clips, b) = bound;
        let mut node = 0u32;
        let mut depth = 0;
        if !(b.t_near_min <= b.t_far_max) {
            // No lane reaches the tree.
            count(false, 0);
            return Some((node, clips));
        }
        loop {
            let n = self.nodes[node as usize];
            if n.is_leaf() {
                break;
            }
            bump(
                #[inline(always)]
                |c| c.node_steps += 1,
            );
            let a = n.axis();
            let (d_lo, d_hi) = (n.split - b.o_hi[a], n.split - b.o_lo[a]);
            let corners = [
                d_lo * b.inv_lo[a],
                d_lo * b.inv_hi[a],
                d_hi * b.inv_lo[a],
                d_hi * b.inv_hi[a],
            ];
            let t_min = corners.iter().copied().fold(f32::INFINITY, f32::min);
            let t_max = corners.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            // Room for the corners' rounding and the lanes' (module docs).
            let pad = t_min.abs().max(t_max.abs()) * PLANE_SLACK + 2.0 * b.slack_max[a];
            let children = n.children();
            let (near, far) = if b.negative[a] {
                (children + 1, children)
            } else {
                (children, children + 1)
            };
            if t_min - pad > b.t_far_max {
                node = near;
            } else if t_max + pad < b.t_near_min {
                node = far;
            } else {
                break;
            }
            depth += 1;
        }
        count(false, depth);
        Some((node, clips))
    }

    /// The groups' clipped lanes and intervals and the tile's bound; `None` when the
    /// lanes disagree on a direction sign or have a zero, non-invertible or
    /// overflowing component.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    fn tile_bound<W: Simd>(
        &self,
        groups: &[RayPacket<W>],
        actives: &[Mask<W>],
    ) -> Option<([(Mask<W>, Vf<W>, Vf<W>); MAX_GROUPS], Bound)> {
        let splat = Vf::<W>::splat;
        let coord_max = self.coord_max();
        let mut clips = [(Mask::<W>::NONE, Vf::<W>::ZERO, Vf::<W>::ZERO); MAX_GROUPS];
        let mut b = Bound {
            o_lo: [f32::INFINITY; 3],
            o_hi: [f32::NEG_INFINITY; 3],
            inv_lo: [f32::INFINITY; 3],
            inv_hi: [f32::NEG_INFINITY; 3],
            slack_max: [0.0; 3],
            t_near_min: f32::INFINITY,
            t_far_max: f32::NEG_INFINITY,
            negative: [false; 3],
        };
        let (mut neg, mut pos) = ([false; 3], [false; 3]);
        // Lane-wise minima and maxima over the groups, reduced across lanes once at
        // the end (min and max are exact, so the order does not matter; no live lane
        // holds a NaN, so one `minps`/`maxps` each).
        let (inf, ninf) = (splat(f32::INFINITY), splat(f32::NEG_INFINITY));
        let (mut o_lo, mut o_hi, mut inv_lo, mut inv_hi) =
            ([inf; 3], [ninf; 3], [inf; 3], [ninf; 3]);
        let mut slack_max = [Vf::<W>::ZERO; 3];
        let (mut t_near_min, mut t_far_max) = (inf, ninf);
        let select = Vf::<W>::select;
        for (g, p) in groups.iter().enumerate() {
            let (lanes, t_near, t_far) = clip_to_box_packet(&self.bounds, p, actives[g]);
            clips[g] = (lanes, t_near, t_far);
            if lanes.none() {
                continue;
            }
            let o_max = max_abs(&p.org);
            for a in 0..3 {
                let d = p.dir[a];
                neg[a] |= (lanes & d.cmp_lt(Vf::<W>::ZERO)).any();
                pos[a] |= (lanes & d.cmp_gt(Vf::<W>::ZERO)).any();
                let inv = p.inv_dir[a];
                // A zero (or subnormal) component has no finite reciprocal, and a tiny
                // one a step that may overflow (`overflow_lanes`).
                let reach = splat(coord_max[a]) + o_max;
                if (lanes & step_overflows(reach, inv)).any() {
                    return None;
                }
                let slack = reach * splat(PLANE_SLACK) * inv.abs();
                o_lo[a] = o_lo[a].min_lt(select(lanes, p.org[a], inf));
                o_hi[a] = o_hi[a].max_gt(select(lanes, p.org[a], ninf));
                inv_lo[a] = inv_lo[a].min_lt(select(lanes, inv, inf));
                inv_hi[a] = inv_hi[a].max_gt(select(lanes, inv, ninf));
                slack_max[a] = slack_max[a].max_gt(select(lanes, slack, Vf::<W>::ZERO));
            }
            t_near_min = t_near_min.min_lt(select(lanes, t_near, inf));
            t_far_max = t_far_max.max_gt(select(lanes, t_far, ninf));
        }
        let lanes_min = inl(
            #[inline(always)]
            |v: Vf<W>| {
                (0..W::LANES).fold(
                    f32::INFINITY,
                    #[inline(always)]
                    |m, i| m.min(v.lane(i)),
                )
            },
        );
        let lanes_max = inl(
            #[inline(always)]
            |v: Vf<W>, init: f32| {
                (0..W::LANES).fold(
                    init,
                    #[inline(always)]
                    |m, i| m.max(v.lane(i)),
                )
            },
        );
        for a in 0..3 {
            b.o_lo[a] = lanes_min(o_lo[a]);
            b.o_hi[a] = lanes_max(o_hi[a], f32::NEG_INFINITY);
            b.inv_lo[a] = lanes_min(inv_lo[a]);
            b.inv_hi[a] = lanes_max(inv_hi[a], f32::NEG_INFINITY);
            b.slack_max[a] = lanes_max(slack_max[a], 0.0);
        }
        b.t_near_min = lanes_min(t_near_min);
        b.t_far_max = lanes_max(t_far_max, f32::NEG_INFINITY);
        // Written out: `(0..3).any` stays out of line, compiled for the baseline.
        if (neg[0] && pos[0]) || (neg[1] && pos[1]) || (neg[2] && pos[2]) {
            return None;
        }
        b.negative = neg;
        Some((clips, b))
    }
}

/// `rays` as packets of `W::LANES` consecutive rays (the last one partial); slots past
/// them repeat the first packet and are never read.
#[inline(always)]
fn groups<W: Simd>(rays: &[Ray]) -> [RayPacket<W>; MAX_GROUPS] {
    let first = RayPacket::<W>::from_rays(&rays[..rays.len().min(W::LANES)]);
    let mut out = [first; MAX_GROUPS];
    for (g, chunk) in rays.chunks(W::LANES).enumerate().skip(1) {
        out[g] = RayPacket::from_rays(chunk);
    }
    debug_assert!(out[0].active.bits() == low_bits(rays.len().min(W::LANES)));
    out
}

/// The lanes set in any of the groups' masks (a loop, not `Iterator::fold`, which LLVM
/// may keep out of line: see [`crate::simd::inl`]).
#[inline(always)]
fn union<W: Simd, const G: usize>(masks: &[Mask<W>; G]) -> Mask<W> {
    let mut all = Mask::<W>::NONE;
    for &m in masks {
        all |= m;
    }
    all
}
