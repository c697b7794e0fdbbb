//! Stage: accel. The kd-tree's stream queries: a slice of rays in, a slice of answers
//! out in input order, each ray's answer the scalar path's bit for bit. Incoherent rays
//! (diffuse bounces) spend their time waiting on node loads that miss the cache
//! (perf/log/overview.md), so a stream is walked one ray per SIMD lane at the CPU's native
//! width ([`KdTree::intersect_lanes`], traverse_lanes.rs): every iteration has a load
//! in flight for each lane and decides all inner steps without a branch. perf/log/stream.md
//! has the figures of each kernel tried.
//!
//! A scene of a few big triangles (a room, a Cornell box) defeats any tree: they
//! overlap most of its cells, and a ray tests most of them anyway, one by one, after
//! many steps. Where the SAH says so (`KdTree::choose_flat`), the stream queries of
//! a scene of at most [`FLAT_MAX_PRIMS`] primitives test every one of them instead:
//! the stream goes in packets of the native width, and each primitive's record,
//! loaded once, is tested against all the packet's rays (the packet walks' leaf
//! kernel, `Prims::leaf_groups`), with no traversal and no lane left idle.
//!
//! A tree small enough to stay in the cache has no load latency to hide: below
//! [`STREAM_MIN_NODES`] nodes the stream queries walk ray by ray. A tree far larger
//! than the cache has more than one group of lanes can hide: from
//! [`TWO_GROUPS_MIN_NODES`] nodes two groups step in turn.

use super::KdTree;
use super::build::BuildParams;
use super::stats::count_tests;
use crate::accel::packet::{HitPacket, RayPacket};
use crate::accel::{intersect_each, occluded_each};
use crate::ray::{Hit, Ray};
use crate::simd::{LaneMask, MAX_LANES, Mask, Simd, by_width, dispatch, native_lanes};

/// The most bounded primitives a scene may have for its stream queries to test every
/// primitive instead of walking the tree (`KdTree::is_flat` decides below it).
pub const FLAT_MAX_PRIMS: u32 = 128;

/// The cost of the flat queries per 16 triangles and one ray, in primitive tests
/// (`K_I`) of the SAH, where a scalar walk spends about 0.5 ns per unit: calibrated at
/// about 25 ns when sixteen triangles went through one ray's lanes (perf/log/stream.md,
/// "Flat queries"). Sixteen rays against each record do the same work in less time
/// (the Cornell box's diffuse rays, 36 triangles: about 50 ns a ray), so the rule
/// only errs toward the tree.
pub const FLAT_GROUP_TESTS: f32 = 4.0;

/// Trees with fewer nodes answer streams ray by ray (perf/log/stream.md, "Small trees").
pub const STREAM_MIN_NODES: usize = 8192;

/// Trees with at least this many nodes walk closest-hit streams in two groups of lanes
/// in turn, each prefetching its next nodes while the other steps: Sponza's diffuse
/// set (828K nodes) 1.08x, the 1.3M-node tetra 1.24x, while the conference room (329K)
/// and the bunny (264K), whose nodes stay closer in the cache, lose 1-3%
/// (perf/log/stream.md, "Two groups of lanes").
pub const TWO_GROUPS_MIN_NODES: usize = 512 * 1024;

/// [`TWO_GROUPS_MIN_NODES`] for any-hit streams, whose walks end sooner: Sponza's
/// shadow set lost 5% with two groups, the tetra's gained 20%.
pub const TWO_GROUPS_MIN_NODES_ANY_HIT: usize = 1024 * 1024;

impl KdTree {
    /// Closest hits of `rays` into `hits` (same length), as [`crate::accel::Accel::intersect`]
    /// returns them, misses as [`Hit::MISS`]: lane walks at the native width, or ray by
    /// ray in a tree of fewer than [`STREAM_MIN_NODES`] nodes.
    pub fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        if self.is_flat() {
            by_width!(native_lanes(), W => self.intersect_flat_in::<W>(rays, hits));
            return;
        }
        if self.nodes.len() < STREAM_MIN_NODES {
            intersect_each(self, rays, hits);
            return;
        }
        by_width!(native_lanes(), W => self.intersect_lanes::<W>(rays, hits))
    }

    /// Any-hit answers of `rays` into `occluded` (same length), as
    /// [`crate::accel::Accel::occluded`] returns them, chosen as in
    /// [`KdTree::intersect_stream`].
    pub fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
        if self.is_flat() {
            by_width!(native_lanes(), W => self.occluded_flat_in::<W>(rays, occluded));
            return;
        }
        if self.nodes.len() < STREAM_MIN_NODES {
            occluded_each(self, rays, occluded);
            return;
        }
        by_width!(native_lanes(), W => self.occluded_lanes::<W>(rays, occluded))
    }

    /// Whether the stream queries test every primitive instead of walking the tree
    /// (chosen by `KdTree::choose_flat`).
    pub fn is_flat(&self) -> bool {
        !self.flat.is_empty()
    }

    /// Makes the stream queries flat where that is cheaper than the tree by the SAH:
    /// in a scene of at most [`FLAT_MAX_PRIMS`] bounded primitives, none of them
    /// non-finite, when one step
    /// ([`BuildParams::traversal_cost`]), [`FLAT_GROUP_TESTS`] primitive tests per
    /// group of 16 triangles and one per other primitive cost less than the tree's SAH
    /// cost. Called once the tree is built.
    pub(super) fn choose_flat(&mut self, params: &BuildParams) {
        let p = &self.prims;
        if p.sphere_base == 0 || p.plane_base > FLAT_MAX_PRIMS {
            return;
        }
        let slots: Vec<u32> = (0..p.plane_base)
            .filter(|&slot| slot >= p.sphere_base || !p.tris[slot as usize].is_degenerate())
            .collect();
        // What the tree left out must be what no ray hits: degenerate triangles, not a
        // non-finite sphere or box.
        if self.build_stats.tree_prims != slots.len() as u32 {
            return;
        }
        let groups = p.sphere_base.div_ceil(MAX_LANES as u32) as f32;
        let others = (p.plane_base - p.sphere_base) as f32;
        let flat =
            params.traversal_cost + params.intersection_cost * (FLAT_GROUP_TESTS * groups + others);
        if (flat as f64) < self.stats(params).sah_cost {
            self.flat = slots;
        }
    }

    /// The flat closest-hit stream queries at width `W` whatever the native width (tests
    /// run every width). Panics unless [`KdTree::is_flat`] holds, or when `hits` is not
    /// as long as `rays`.
    pub fn intersect_flat_in<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert!(
            self.is_flat(),
            "intersect_flat_in: the tree chose no flat queries"
        );
        assert_eq!(rays.len(), hits.len(), "intersect_stream: one hit per ray");
        dispatch!(W::LANES; self.intersect_flat_as::<@>(rays, hits))
    }

    /// The flat any-hit stream queries at width `W`, as [`KdTree::intersect_flat_in`]
    /// (and panicking as it does).
    pub fn occluded_flat_in<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert!(
            self.is_flat(),
            "occluded_flat_in: the tree chose no flat queries"
        );
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_stream: one answer per ray"
        );
        dispatch!(W::LANES; self.occluded_flat_as::<@>(rays, occluded))
    }

    /// The flat closest-hit stream at backend `W`, inside its entry: each ray's answer
    /// is the closest hit over all primitives in [`Hit::is_closer`]'s order, none for
    /// an unusable ray: the brute-force oracle's answer ([`crate::accel::brute`]), which
    /// the walks are tested to give. No box clip: it cost the Cornell box's streams a
    /// fifth of their rate, and a ray it would reject hits nothing.
    #[inline(always)]
    fn intersect_flat_as<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit]) {
        for (chunk, out) in rays.chunks(W::LANES).zip(hits.chunks_mut(W::LANES)) {
            let packet = RayPacket::<W>::from_rays(chunk);
            let lanes = [packet.active & packet.usable()];
            let mut best = [HitPacket::<W>::miss()];
            let mut unused = [Mask::<W>::NONE];
            self.prims.leaf_groups::<W, 1, false>(
                &self.flat,
                |_| &packet,
                &lanes,
                &mut best,
                &mut unused,
                count_tests,
            );
            self.prims
                .intersect_planes_packet(&packet, packet.active, &mut best[0]);
            best[0].write(out);
        }
    }

    /// The flat any-hit stream at backend `W`, inside its entry: hit in `(t_min,
    /// t_max)` by any primitive.
    #[inline(always)]
    fn occluded_flat_as<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool]) {
        for (chunk, out) in rays.chunks(W::LANES).zip(occluded.chunks_mut(W::LANES)) {
            let packet = RayPacket::<W>::from_rays(chunk);
            let lanes = [packet.active & packet.usable()];
            let mut unused = [HitPacket::<W>::miss()];
            let mut hit = [Mask::<W>::NONE];
            self.prims.leaf_groups::<W, 1, true>(
                &self.flat,
                |_| &packet,
                &lanes,
                &mut unused,
                &mut hit,
                count_tests,
            );
            let hit = hit[0]
                | self
                    .prims
                    .planes_occlude_packet(&packet, packet.active & !hit[0]);
            let bits = hit.bits();
            for (i, o) in out.iter_mut().enumerate() {
                *o = bits & (1 << i) != 0;
            }
        }
    }

    /// [`KdTree::intersect_stream`] through the lane walks at width `W` whatever the
    /// tree's size, in one group of lanes or two by [`TWO_GROUPS_MIN_NODES`].
    pub fn intersect_lanes<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit]) {
        let groups = 1 + (self.nodes.len() >= TWO_GROUPS_MIN_NODES) as usize;
        self.intersect_lanes_in::<W>(rays, hits, groups);
    }

    /// [`KdTree::intersect_lanes`] in `groups` (1 or 2) groups of lanes whatever the
    /// tree's size (tests run every width and both group counts on small trees).
    pub fn intersect_lanes_in<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit], groups: usize) {
        assert_eq!(rays.len(), hits.len(), "intersect_stream: one hit per ray");
        dispatch!(W::LANES; self.intersect_lanes_as::<@>(rays, hits, groups))
    }

    /// [`KdTree::intersect_lanes_in`] at backend `W`, inside its entry.
    #[inline(always)]
    fn intersect_lanes_as<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit], groups: usize) {
        self.walk_lanes::<W, false>(
            rays,
            groups,
            #[inline(always)]
            |i, _, mut best| {
                self.prims.intersect_planes(&rays[i], &mut best);
                hits[i] = if best.is_hit() { best } else { Hit::MISS };
            },
        );
    }

    /// [`KdTree::occluded_stream`] through the lane walks at width `W` whatever the
    /// tree's size, in one group of lanes or two by [`TWO_GROUPS_MIN_NODES_ANY_HIT`].
    pub fn occluded_lanes<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool]) {
        let groups = 1 + (self.nodes.len() >= TWO_GROUPS_MIN_NODES_ANY_HIT) as usize;
        self.occluded_lanes_in::<W>(rays, occluded, groups);
    }

    /// [`KdTree::occluded_lanes`] in `groups` (1 or 2) groups of lanes whatever the
    /// tree's size.
    pub fn occluded_lanes_in<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool], groups: usize) {
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_stream: one answer per ray"
        );
        dispatch!(W::LANES; self.occluded_lanes_as::<@>(rays, occluded, groups))
    }

    /// [`KdTree::occluded_lanes_in`] at backend `W`, inside its entry.
    #[inline(always)]
    fn occluded_lanes_as<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool], groups: usize) {
        self.walk_lanes::<W, true>(
            rays,
            groups,
            #[inline(always)]
            |i, answer, _| occluded[i] = answer,
        );
    }
}
