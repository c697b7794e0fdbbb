//! Stage: accel. Ray tiles: up to [`TILE_RAYS`] coherent rays (64 consecutive rays of
//! an image set in RAYS.md's packet order are a 16x4 pixel block; their shadow rays
//! toward one point light agree as well) traced as groups of SIMD packets that share an
//! entry point (Reshetov, Soupikov and Hurley 2005, multi-level ray tracing).
//!
//! From the root, the whole tile descends while a conservative bound decides for all its
//! rays at once: per axis, the interval of the origins and of the reciprocal directions
//! gives an interval holding every lane's split distance (f32 subtraction and
//! multiplication are monotone, so the corner products bound the lanes' own rounded
//! values), widened by the largest plane slack. Where that interval lies past every
//! lane's `t_far`, every lane would go near only; where it lies before every lane's
//! `t_near`, far only. At the first node where the bound cannot decide, each group
//! starts the packet traversal ([`super::traverse_packet`]) there.
//!
//! Invariant, so each lane returns exactly the scalar path's answer: the descent takes
//! only steps that every lane's own (scalar) decision takes too, near only or far only,
//! and such steps leave the lane's interval and the scalar stack unchanged. So each lane
//! arrives at the entry node with its clipped interval and an empty stack, exactly as
//! the scalar traversal does, and nothing it needs lies outside that node's subtree.
//! Tiles whose lanes disagree on a direction sign, have a zero or non-invertible
//! direction component, or fit in one group skip the descent and trace each group as an
//! ordinary packet; [`tile_counts`] reports how often.

use super::KdTree;
use super::stats::bump;
use super::traverse::PLANE_SLACK;
use super::traverse_packet::clip_to_box_packet;
use crate::accel::packet::{HitPacket, RayPacket, low_bits};
use crate::ray::{Hit, Ray};
use crate::simd::{Float, LaneMask, Mask, Simd, Vf, max_abs};
use std::cell::Cell;

/// Rays per tile.
pub const TILE_RAYS: usize = 64;

/// Groups of the narrowest width a tile is made of (8 lanes).
const MAX_GROUPS: usize = TILE_RAYS / 8;

/// Tiles traced on one thread: how many, how many fell back to packets per group, and
/// the sum of their entry depths (nodes passed for the whole tile at once).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileCounts {
    /// Tiles traced.
    pub tiles: u64,
    /// Tiles whose rays disagree on a direction sign, traced one packet per group.
    pub fallbacks: u64,
    /// Sum over tiles of the nodes passed for the whole tile at once.
    pub entry_depth: u64,
}

thread_local! {
    static COUNTS: Cell<TileCounts> = const { Cell::new(TileCounts { tiles: 0, fallbacks: 0, entry_depth: 0 }) };
}

/// The tiles traced on this thread so far.
pub fn tile_counts() -> TileCounts {
    COUNTS.with(Cell::get)
}

fn count(fallback: bool, depth: u64) {
    COUNTS.with(|c| {
        let mut v = c.get();
        v.tiles += 1;
        v.fallbacks += fallback as u64;
        v.entry_depth += depth;
        c.set(v);
    });
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
    /// [`crate::accel::Accel::intersect`], bit for bit.
    pub fn intersect_tile<W: Simd>(&self, rays: &[Ray], out: &mut [Hit]) {
        assert!(rays.len() <= TILE_RAYS && rays.len() == out.len());
        let n = rays.len().div_ceil(W::LANES);
        let groups = groups::<W>(rays);
        let groups = &groups[..n];
        let actives: [Mask<W>; MAX_GROUPS] = std::array::from_fn(|g| match groups.get(g) {
            Some(p) => p.active,
            None => Mask::<W>::NONE,
        });
        let mut best = [HitPacket::<W>::miss(); MAX_GROUPS];
        match self.tile_entry(groups, &actives[..n]) {
            Some((node, clips)) => {
                for (g, p) in groups.iter().enumerate() {
                    let (lanes, t_near, t_far) = clips[g];
                    if lanes.any() {
                        let start = (node, lanes, t_near, t_far);
                        self.traverse_packet_from::<W, false>(p, p.active, start, &mut best[g]);
                    }
                    self.prims
                        .intersect_planes_packet(p, p.active, &mut best[g]);
                }
            }
            None => {
                for (g, p) in groups.iter().enumerate() {
                    best[g] = self.intersect_packet(p);
                }
            }
        }
        for (i, h) in out.iter_mut().enumerate() {
            *h = best[i / W::LANES].lane(i % W::LANES);
        }
    }

    /// Bit `i` set when ray `i` of `rays` (at most [`TILE_RAYS`]) is occluded; the answer
    /// of [`crate::accel::Accel::occluded`] ray by ray.
    pub fn occluded_tile<W: Simd>(&self, rays: &[Ray]) -> u64 {
        assert!(rays.len() <= TILE_RAYS);
        let n = rays.len().div_ceil(W::LANES);
        let groups = groups::<W>(rays);
        let groups = &groups[..n];
        let by_plane: [Mask<W>; MAX_GROUPS] = std::array::from_fn(|g| match groups.get(g) {
            Some(p) => self.prims.planes_occlude_packet(p, p.active),
            None => Mask::<W>::NONE,
        });
        let actives: [Mask<W>; MAX_GROUPS] = std::array::from_fn(|g| match groups.get(g) {
            Some(p) => p.active & !by_plane[g],
            None => Mask::<W>::NONE,
        });
        let mut bits = 0u64;
        match self.tile_entry(groups, &actives[..n]) {
            Some((node, clips)) => {
                for (g, p) in groups.iter().enumerate() {
                    let (lanes, t_near, t_far) = clips[g];
                    let mut hit = by_plane[g];
                    if lanes.any() {
                        let mut unused = HitPacket::miss();
                        let start = (node, lanes, t_near, t_far);
                        hit |=
                            self.traverse_packet_from::<W, true>(p, actives[g], start, &mut unused);
                    }
                    bits |= (hit.bits() as u64) << (g * W::LANES);
                }
            }
            None => {
                for (g, p) in groups.iter().enumerate() {
                    bits |= (self.occluded_packet(p) as u64) << (g * W::LANES);
                }
            }
        }
        bits
    }

    /// The entry node of the tile's groups (their lanes `actives`) and each group's lanes
    /// and interval clipped to the tree's box; `None` where the tile falls back to one
    /// packet per group (see the module docs). Counts the tile.
    #[allow(clippy::type_complexity)]
    fn tile_entry<W: Simd>(
        &self,
        groups: &[RayPacket<W>],
        actives: &[Mask<W>],
    ) -> Option<(u32, [(Mask<W>, Vf<W>, Vf<W>); MAX_GROUPS])> {
        let Some(bound) = (groups.len() > 1)
            .then(|| self.tile_bound(groups, actives))
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
            bump(|c| c.node_steps += 1);
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
            let children = n.children();
            let (near, far) = if b.negative[a] {
                (children + 1, children)
            } else {
                (children, children + 1)
            };
            if t_min - b.slack_max[a] > b.t_far_max {
                node = near;
            } else if t_max + b.slack_max[a] < b.t_near_min {
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
    /// lanes disagree on a direction sign or have a zero or non-invertible component.
    #[allow(clippy::type_complexity)]
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
        for (g, p) in groups.iter().enumerate() {
            let (lanes, t_near, t_far) = clip_to_box_packet(&self.bounds, p, actives[g]);
            clips[g] = (lanes, t_near, t_far);
            if lanes.none() {
                continue;
            }
            let o_max = max_abs(&p.org);
            let live = lanes.bits();
            for a in 0..3 {
                let d = p.dir[a];
                neg[a] |= (lanes & d.cmp_lt(Vf::<W>::ZERO)).any();
                pos[a] |= (lanes & d.cmp_gt(Vf::<W>::ZERO)).any();
                let inv = p.inv_dir[a];
                // A zero (or subnormal) component has no finite reciprocal.
                if (lanes & !inv.finite()).any() {
                    return None;
                }
                let slack = (splat(coord_max[a]) + o_max) * splat(PLANE_SLACK) * inv.abs();
                for_lanes(live, |i| {
                    b.o_lo[a] = b.o_lo[a].min(p.org[a].lane(i));
                    b.o_hi[a] = b.o_hi[a].max(p.org[a].lane(i));
                    b.inv_lo[a] = b.inv_lo[a].min(inv.lane(i));
                    b.inv_hi[a] = b.inv_hi[a].max(inv.lane(i));
                    b.slack_max[a] = b.slack_max[a].max(slack.lane(i));
                });
            }
            for_lanes(live, |i| {
                b.t_near_min = b.t_near_min.min(t_near.lane(i));
                b.t_far_max = b.t_far_max.max(t_far.lane(i));
            });
        }
        if (0..3).any(|a| neg[a] && pos[a]) {
            return None;
        }
        b.negative = neg;
        Some((clips, b))
    }
}

/// Calls `f` with the index of each set bit of `bits`.
#[inline]
fn for_lanes(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// `rays` as packets of `W::LANES` consecutive rays (the last one partial); slots past
/// them repeat the first packet and are never read.
fn groups<W: Simd>(rays: &[Ray]) -> [RayPacket<W>; MAX_GROUPS] {
    let first = RayPacket::<W>::from_rays(&rays[..rays.len().min(W::LANES)]);
    let mut out = [first; MAX_GROUPS];
    for (g, chunk) in rays.chunks(W::LANES).enumerate().skip(1) {
        out[g] = RayPacket::from_rays(chunk);
    }
    debug_assert!(out[0].active.bits() == low_bits(rays.len().min(W::LANES)));
    out
}
