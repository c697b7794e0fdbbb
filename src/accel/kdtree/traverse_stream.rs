//! Stage: accel. The kd-tree's stream kernel: [`STREAM_WAYS`] scalar walks advanced in
//! turn, one node step each, so a thread has several independent node loads in flight
//! instead of one. Incoherent rays (diffuse bounces) spend their time waiting on node
//! loads that miss the cache (perf/README.md); while one ray waits, the others step.
//! Each walk is the scalar path's own step (`KdTree::step` in traverse.rs), so every
//! ray's answer is the scalar answer bit for bit; here a step picks the next node
//! without branches (several rays' unrelated turns would defeat the branch predictor)
//! and asks for the line of that node, which arrives while the other walks step.
//! perf/stream.md has the figures of each choice.

use super::KdTree;
use super::traverse::Walk;
use crate::ray::{Hit, Ray};

/// Walks in flight per thread (4 gained less on Sponza diffuse, 16 no more).
pub const STREAM_WAYS: usize = 8;

/// A walk in flight: which ray it traces and its closest hit so far.
struct Slot {
    walk: Walk,
    ray: usize,
    best: Hit,
}

impl KdTree {
    /// Closest hits of `rays` into `hits` (same length), as [`crate::accel::Accel::intersect`]
    /// returns them, misses as [`Hit::MISS`].
    pub fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "intersect_stream: one hit per ray");
        self.walk_stream::<false>(rays, |i, _, mut best| {
            self.prims.intersect_planes(&rays[i], &mut best);
            hits[i] = if best.is_hit() { best } else { Hit::MISS };
        });
    }

    /// Any-hit answers of `rays` into `occluded` (same length), as
    /// [`crate::accel::Accel::occluded`] returns them.
    pub fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
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
