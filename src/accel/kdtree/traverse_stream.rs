//! Stage: accel. The kd-tree's stream queries: a slice of rays in, a slice of answers
//! out in input order, each ray's answer the scalar path's bit for bit. Incoherent rays
//! (diffuse bounces) spend their time waiting on node loads that miss the cache
//! (perf/log/overview.md), so a stream is walked one ray per SIMD lane at the CPU's native
//! width ([`KdTree::intersect_lanes`], traverse_lanes.rs): every iteration has a load
//! in flight for each lane and decides all inner steps without a branch. perf/log/stream.md
//! has the figures of each kernel tried.
//!
//! A tree small enough to stay in the cache has no load latency to hide: below
//! [`STREAM_MIN_NODES`] nodes the stream queries walk ray by ray. A tree far larger
//! than the cache has more than one group of lanes can hide: from
//! [`TWO_GROUPS_MIN_NODES`] nodes two groups step in turn.

use super::KdTree;
use crate::accel::{intersect_each, occluded_each};
use crate::ray::{Hit, Ray};
use crate::simd::{Simd, by_width, dispatch, native_lanes};

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
        if self.nodes.len() < STREAM_MIN_NODES {
            occluded_each(self, rays, occluded);
            return;
        }
        by_width!(native_lanes(), W => self.occluded_lanes::<W>(rays, occluded))
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
