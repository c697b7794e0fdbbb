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
//! Tiles whose lanes disagree on a direction sign, have a lane the SIMD walks leave to
//! the scalar walk (a zero direction component, or one so small that the node step may
//! overflow: `KdTree::scalar_lanes`), or fit in one group skip the descent and trace
//! each group as an ordinary packet; [`super::stats`] counts how often. Below the
//! entry point a tile is the packets' group walk (`KdTree::walk_groups`) with
//! several groups.

use super::KdTree;
use super::stats::bump;
use super::traverse::{Bands, PLANE_SLACK, box_coord_max};
use crate::accel::packet::{HitPacket, RayPacket, low_bits};
use crate::ray::{Hit, Ray};
use crate::simd::{Float, LaneMask, Mask, Simd, Vf, array_fn, dispatch, inl};

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

/// Each group's lanes that reach the tree's box and their intervals
/// ([`KdTree::start_packet`]).
type Clips<W> = [(Mask<W>, Vf<W>, Vf<W>); MAX_GROUPS];

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
    /// its lanes and interval `clips`: the group walk
    /// ([`KdTree::walk_groups`]) of `G` groups (`G * W::LANES` = [`TILE_RAYS`]; groups
    /// past `groups.len()` have no lanes). Closest hit: folds hits into `best`; with
    /// `ANY_HIT`, sets the occluded lanes in `occluded`.
    #[inline(always)]
    fn tile_walk<W: Simd, const ANY_HIT: bool>(
        &self,
        groups: &[RayPacket<W>],
        node: u32,
        clips: &Clips<W>,
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

    /// [`Self::tile_walk`] with `G` groups.
    #[inline(always)]
    fn tile_walk_n<W: Simd, const G: usize, const ANY_HIT: bool>(
        &self,
        groups: &[RayPacket<W>],
        node: u32,
        clips: &Clips<W>,
        best: &mut [HitPacket<W>; MAX_GROUPS],
        occluded: &mut [Mask<W>; MAX_GROUPS],
    ) {
        let n_groups = groups.len().min(G);
        let lanes: [Mask<W>; G] = array_fn(
            #[inline(always)]
            |g| {
                if g < n_groups {
                    clips[g].0
                } else {
                    Mask::<W>::NONE
                }
            },
        );
        let t_near = array_fn(
            #[inline(always)]
            |g| clips[g].1,
        );
        let t_far = array_fn(
            #[inline(always)]
            |g| clips[g].2,
        );
        // The bands again (the bound's are not kept: passed in, they cost the walk
        // 10-20% on camera and shadow tiles).
        let coord_max = box_coord_max(&self.bounds);
        let bands: [Bands<Vf<W>>; G] = array_fn(
            #[inline(always)]
            |g| {
                let p = &groups[g.min(n_groups - 1)];
                Bands::new(&p.org, &p.inv_dir, coord_max)
            },
        );
        self.walk_groups::<W, G, ANY_HIT>(
            #[inline(always)]
            |g: usize| (&groups[g.min(n_groups - 1)], &bands[g]),
            (node, lanes, t_near, t_far),
            best,
            occluded,
        );
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
    ) -> Option<(u32, Clips<W>)> {
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
    ) -> Option<(Clips<W>, Bound)> {
        let splat = Vf::<W>::splat;
        let mut clips: Clips<W> = [(Mask::<W>::NONE, Vf::<W>::ZERO, Vf::<W>::ZERO); MAX_GROUPS];
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
            let (bands, clip) = self.start_packet(p, actives[g]);
            clips[g] = clip;
            let (lanes, t_near, t_far) = clip;
            if lanes.none() {
                continue;
            }
            // A zero (or subnormal) component has no finite reciprocal, and a tiny one
            // a step that may overflow: such lanes take the scalar walk.
            if (lanes & self.scalar_lanes(bands.reach, &p.inv_dir)).any() {
                return None;
            }
            for a in 0..3 {
                let d = p.dir[a];
                neg[a] |= (lanes & d.cmp_lt(Vf::<W>::ZERO)).any();
                pos[a] |= (lanes & d.cmp_gt(Vf::<W>::ZERO)).any();
                let inv = p.inv_dir[a];
                let slack = bands.slack[a];
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
