//! Stage: accel. The kd-tree's stream kernel: [`STREAM_WAYS`] scalar walks advanced in
//! turn, one node step each, so a thread has several independent node loads in flight
//! instead of one. Incoherent rays (diffuse bounces) spend their time waiting on node
//! loads that miss the cache (perf/README.md); while one ray waits, the others step.
//! Each walk is the scalar path's own step (`KdTree::step` in traverse.rs), so every
//! ray's answer is the scalar answer bit for bit; here a step picks the next node
//! without branches (several rays' unrelated turns would defeat the branch predictor)
//! and asks for the line of that node, which arrives while the other walks step, and a
//! leaf's triangles are tested against the walk's ray in lanes, several at once
//! ([`crate::accel::Prims::intersect_tris_lanes`], the scalar answers bit for bit).
//! perf/stream.md has the figures of each choice.
//!
//! A tree small enough to stay in the cache has no load latency to hide, and there
//! interleaving only costs (the Cornell box's 45 nodes: 0.75x the scalar rate on diffuse
//! rays): below [`STREAM_MIN_NODES`] nodes the stream queries walk ray by ray.

use super::KdTree;
use super::traverse::Walk;
use crate::accel::{intersect_each, occluded_each};
use crate::ray::{Hit, Ray};

/// Walks in flight per thread (4 gained less on Sponza diffuse, 16 no more).
pub const STREAM_WAYS: usize = 8;

/// Trees with fewer nodes answer streams ray by ray (perf/stream.md, "Small trees").
pub const STREAM_MIN_NODES: usize = 8192;

/// A walk in flight: which ray it traces and its closest hit so far.
struct Slot {
    walk: Walk,
    ray: usize,
    best: Hit,
}

impl KdTree {
    /// Closest hits of `rays` into `hits` (same length), as [`crate::accel::Accel::intersect`]
    /// returns them, misses as [`Hit::MISS`]: interleaved walks, or ray by ray in a tree
    /// of fewer than [`STREAM_MIN_NODES`] nodes.
    pub fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        if self.nodes.len() < STREAM_MIN_NODES {
            intersect_each(self, rays, hits);
        } else {
            self.intersect_interleaved(rays, hits);
        }
    }

    /// Any-hit answers of `rays` into `occluded` (same length), as
    /// [`crate::accel::Accel::occluded`] returns them, chosen as in
    /// [`KdTree::intersect_stream`].
    pub fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
        if self.nodes.len() < STREAM_MIN_NODES {
            occluded_each(self, rays, occluded);
        } else {
            self.occluded_interleaved(rays, occluded);
        }
    }

    /// [`KdTree::intersect_stream`] through the interleaved walks whatever the tree's
    /// size (tests run the kernel on small trees through this).
    pub fn intersect_interleaved(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "intersect_stream: one hit per ray");
        self.walk_stream::<false>(rays, |i, _, mut best| {
            self.prims.intersect_planes(&rays[i], &mut best);
            hits[i] = if best.is_hit() { best } else { Hit::MISS };
        });
    }

    /// [`KdTree::occluded_stream`] through the interleaved walks whatever the tree's size.
    pub fn occluded_interleaved(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_stream: one answer per ray"
        );
        self.walk_stream::<true>(rays, |i, answer, _| occluded[i] = answer);
    }

    /// Walks every ray of `rays` through the tree, [`STREAM_WAYS`] at a time, calling
    /// `done(i, answer, best)` once per ray `i` (in no particular order) with the
    /// scalar traversal's answer and closest hit (planes not folded in). With
    /// `ANY_HIT`, a ray a plane occludes is answered without walking.
    fn walk_stream<const ANY_HIT: bool>(
        &self,
        rays: &[Ray],
        mut done: impl FnMut(usize, bool, Hit),
    ) {
        let mut slots: [Slot; STREAM_WAYS] = std::array::from_fn(|_| Slot {
            walk: Walk::new(),
            ray: 0,
            best: Hit::MISS,
        });
        let mut next = 0;
        let mut live = 0;
        // Starts the next ray that needs a walk in `slot`; false when none is left.
        let mut start = |slot: &mut Slot, done: &mut dyn FnMut(usize, bool, Hit)| {
            while next < rays.len() {
                let i = next;
                next += 1;
                if ANY_HIT && self.prims.planes_occlude(&rays[i]) {
                    done(i, true, Hit::MISS);
                } else if self.start_walk(&rays[i], &mut slot.walk) {
                    slot.ray = i;
                    slot.best = Hit::MISS;
                    return true;
                } else {
                    done(i, false, Hit::MISS);
                }
            }
            false
        };
        while live < STREAM_WAYS && start(&mut slots[live], &mut done) {
            live += 1;
        }
        while live > 0 {
            let mut k = 0;
            while k < live {
                let s = &mut slots[k];
                let Some(answer) =
                    self.step::<ANY_HIT, true, true>(&mut s.walk, &rays[s.ray], &mut s.best)
                else {
                    k += 1;
                    continue;
                };
                done(s.ray, answer, s.best);
                if !start(s, &mut done) {
                    live -= 1;
                    slots.swap(k, live);
                }
            }
        }
    }
}
