//! The walk: one ray, eight child boxes per step in one SIMD register, the hit children
//! pushed farthest first, leaves tested in lanes.
//!
//! The box test only decides which leaves a ray tests, so it need not be exact, only
//! conservative: a box that holds a hit must pass. Boxes are widened by the kd-tree's
//! margin ([`PLANE_SLACK`] of the largest coordinate of the scene and the origin; its
//! module docs say why a triangle test can round a ray that far), written into the
//! origin: `(plane - (org -+ margin)) * (1 / dir)`, whose rounding stays within the
//! margin. A direction component of zero gives an infinite inverse: the slab is
//! everything or nothing, and a ray on the widened face itself gives NaN, which the
//! `max`/`min` order drops (no limit). A component whose distances could overflow is
//! given a NaN inverse: that axis then limits nothing. (In the single walk a NaN on z
//! drops y's limit with it: the reductions are two levels deep, not a chain of three;
//! the box only widens.) The hits come from the leaf kernel, the scalar test lane for
//! lane, so every answer is brute force's.

use super::{Bvh, LEAF_BIT};
use crate::accel::kdtree::traverse::PLANE_SLACK;
use crate::accel::triaccel::max_abs;
use crate::ray::{Hit, Ray};
use crate::simd::{Float, LaneMask, Simd, Vf, array_fn, inl};

/// The boxes' margin relative to the largest coordinate: twice the kd-tree's
/// [`PLANE_SLACK`], half for the triangle test's rounding and half for the box test's
/// own (a fused or an unfused distance, the inverse's rounding).
pub(super) const BOX_SLACK: f32 = 2.0 * PLANE_SLACK;

/// Stack entries: the binary tree's depth is at most 48 SAH levels plus 27 median
/// levels (2^27 primitives), and each 8-wide node pushes at most seven children.
pub(super) const STACK: usize = 7 * 76 + 8;

/// A box-test set-up, per axis x, y, z ([`Bvh::walk`]'s one ray in all lanes, or a
/// packet group's rays, one per lane): the origin moved by the
/// margin toward the near and the far plane, the same as offsets `-(org * rcp)`, the
/// inverse direction, and the rows of the near and far planes.
#[derive(Clone, Copy)]
pub(super) struct Setup<W: Simd> {
    pub(super) org_near: [Vf<W>; 3],
    pub(super) org_far: [Vf<W>; 3],
    pub(super) off_near: [Vf<W>; 3],
    pub(super) off_far: [Vf<W>; 3],
    pub(super) rcp: [Vf<W>; 3],
    pub(super) near: [usize; 3],
    pub(super) far: [usize; 3],
}

impl Bvh {
    /// Asks the caches for what child word `w` names (a node's boxes, a leaf's first
    /// records) while the walk goes on elsewhere: a pushed child is popped later.
    #[inline(always)]
    fn prefetch(&self, w: u32) {
        if w & LEAF_BIT == 0 {
            let node = &self.nodes[w as usize];
            for row in [0, 2, 4] {
                crate::simd::prefetch(&node.planes[row]);
            }
            crate::simd::prefetch(&node.child);
        } else {
            let (first, _) = Bvh::leaf_run(w);
            let slot = if self.prims.triangles_only() {
                first
            } else {
                self.slots[first] as usize
            };
            // A sphere's or a box's slot lies past the triangles' records.
            if let Some(tri) = self.prims.tris.get(slot) {
                crate::simd::prefetch(tri);
            }
        }
    }

    /// Closest hits of `rays` into `hits` (misses as [`Hit::MISS`]) with the 8-lane
    /// backend `W`; inside `W`'s entry.
    #[inline(always)]
    pub(crate) fn intersect_rays<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit]) {
        let mut stack = [(0u32, 0.0f32); STACK];
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            let mut best = Hit::MISS;
            if ray.is_usable() && !self.nodes.is_empty() {
                self.walk::<W, false>(ray, &mut best, &mut stack, 0);
            }
            self.prims.intersect_planes(ray, &mut best);
            *hit = best;
        }
    }

    /// Any-hit answers of `rays` into `occluded`, as [`Bvh::intersect_rays`].
    #[inline(always)]
    pub(crate) fn occluded_rays<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool]) {
        let mut stack = [(0u32, 0.0f32); STACK];
        for (ray, o) in rays.iter().zip(occluded.iter_mut()) {
            let mut unused = Hit::MISS;
            *o = (ray.is_usable()
                && !self.nodes.is_empty()
                && self.walk::<W, true>(ray, &mut unused, &mut stack, 0))
                || self.prims.planes_occlude(ray);
        }
    }

    /// Walks a usable ray from node `start` (0, the root, or a node the packet walk
    /// hands on): folds the closest hit into `best` (only hits closer than `best` are
    /// looked for), or with `ANY_HIT` returns whether anything is hit in `(t_min,
    /// t_max)`.
    #[inline(always)]
    pub(super) fn walk<W: Simd, const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        best: &mut Hit,
        stack: &mut [(u32, f32); STACK],
        start: u32,
    ) -> bool {
        debug_assert_eq!(W::LANES, 8);
        let splat = Vf::<W>::splat;
        let (o, d) = (ray.org, ray.dir);
        // The kd-tree's margin (its module docs): a triangle test may round a ray onto
        // a triangle within `margin` of it, so each box is that much wider on every
        // side, moved into the origin: `(plane - (org -+ margin)) * rcp`.
        let reach = self.coord_max + max_abs(o);
        let margin = reach * BOX_SLACK;
        // An inverse whose distances could overflow limits nothing (NaN, dropped by
        // the reductions); a zero component keeps its infinite inverse (everything
        // or nothing, NaN on the widened face itself). Branch-free: a diffuse ray's
        // set-up is a fifth of its walk.
        let inv = inl(
            #[inline(always)]
            |x: f32| {
                let r = 1.0 / x;
                let keep = (x == 0.0) | (r.abs() * (4.0 * reach) <= f32::MAX);
                if keep { r } else { f32::NAN }
            },
        );
        let rcp = [inv(d.x), inv(d.y), inv(d.z)];
        // Toward the near plane on each axis, and away from it toward the far one.
        let step = [d.x, d.y, d.z].map(
            #[inline(always)]
            |c| margin.copysign(c),
        );
        let org_near = array_fn(
            #[inline(always)]
            |a| o[a] + step[a],
        );
        let org_far = array_fn(
            #[inline(always)]
            |a| o[a] - step[a],
        );
        // The near plane of each axis is the minimum where the ray goes up (+0 too).
        let near = array_fn(
            #[inline(always)]
            |a| 2 * a + d[a].is_sign_negative() as usize,
        );
        let setup = Setup {
            org_near: org_near.map(splat),
            org_far: org_far.map(splat),
            off_near: array_fn(
                #[inline(always)]
                |a| splat(-(org_near[a] * rcp[a])),
            ),
            off_far: array_fn(
                #[inline(always)]
                |a| splat(-(org_far[a] * rcp[a])),
            ),
            rcp: rcp.map(splat),
            near,
            far: near.map(
                #[inline(always)]
                |k| k ^ 1,
            ),
        };
        if rcp.iter().all(
            #[inline(always)]
            |r| r.abs() != f32::INFINITY,
        ) {
            self.descend::<W, ANY_HIT, true>(ray, best, stack, &setup, start)
        } else {
            self.descend::<W, ANY_HIT, false>(ray, best, stack, &setup, start)
        }
    }

    /// The walk of [`Bvh::walk`] from the root with `setup`. `FUSED` when no inverse
    /// is infinite: a distance is then `plane * rcp + off` (one fused multiply-add where
    /// the set has it); else `(plane - org) * rcp`, which keeps a zero component's
    /// slab exact.
    #[inline(always)]
    fn descend<W: Simd, const ANY_HIT: bool, const FUSED: bool>(
        &self,
        ray: &Ray,
        best: &mut Hit,
        stack: &mut [(u32, f32); STACK],
        setup: &Setup<W>,
        start: u32,
    ) -> bool {
        let splat = Vf::<W>::splat;
        let Setup {
            org_near,
            org_far,
            off_near,
            off_far,
            rcp,
            near,
            far,
        } = *setup;
        let t_min = splat(ray.t_min);
        let triangles_only = self.prims.triangles_only();
        let mut limit = best.t.min(ray.t_max);
        let mut sp = 0usize;
        let mut cur = start;
        loop {
            if cur & LEAF_BIT == 0 {
                let node = &self.nodes[cur as usize];
                let plane = inl(
                    #[inline(always)]
                    |k: usize| -> Vf<W> { bytemuck::cast(node.planes[k]) },
                );
                let slab = inl(
                    #[inline(always)]
                    |i: usize| {
                        if FUSED {
                            (
                                plane(near[i]).mul_add_fast(rcp[i], off_near[i]),
                                plane(far[i]).mul_add_fast(rcp[i], off_far[i]),
                            )
                        } else {
                            (
                                (plane(near[i]) - org_near[i]) * rcp[i],
                                (plane(far[i]) - org_far[i]) * rcp[i],
                            )
                        }
                    },
                );
                let ((n0, f0), (n1, f1), (n2, f2)) = (slab(0), slab(1), slab(2));
                // Two levels, not a chain of three. `a.max_gt(b)` is `b` where either is
                // NaN: the pair (y, z) yields NaN only where z does, and then the x side
                // (which starts from the ray's own bound, never NaN) stands alone, which
                // widens the box, never narrows it.
                let t_near = n1.max_gt(n2).max_gt(n0.max_gt(t_min));
                let t_far = f1.min_lt(f2).min_lt(f0.min_lt(splat(limit)));
                let mut bits = t_near.cmp_le(t_far).bits();
                match bits.count_ones() {
                    0 => {}
                    1 => {
                        cur = node.child[bits.trailing_zeros() as usize];
                        continue;
                    }
                    _ => {
                        let t: [f32; 8] = bytemuck::cast(t_near);
                        // Insert each hit child so the stack's top run is sorted,
                        // nearest on top.
                        let base = sp;
                        while bits != 0 {
                            let i = bits.trailing_zeros() as usize;
                            bits &= bits - 1;
                            let entry = (node.child[i], t[i]);
                            self.prefetch(entry.0);
                            let mut j = sp;
                            while j > base && stack[j - 1].1 < entry.1 {
                                stack[j] = stack[j - 1];
                                j -= 1;
                            }
                            stack[j] = entry;
                            sp += 1;
                        }
                        sp -= 1;
                        cur = stack[sp].0;
                        continue;
                    }
                }
            } else {
                let slots = self.leaf(cur);
                let hit = if triangles_only {
                    // The records of slots `first..first + n` (the module docs).
                    let (first, n) = Bvh::leaf_run(cur);
                    if n <= 4 {
                        self.prims
                            .tris_lanes_run::<W::X4, ANY_HIT>(first, n, ray, best)
                    } else {
                        self.prims.tris_lanes_run::<W, ANY_HIT>(first, n, ray, best)
                    }
                } else if ANY_HIT {
                    self.prims.occludes_leaf(slots, ray)
                } else {
                    self.prims.intersect_leaf(slots, ray, best);
                    false
                };
                if ANY_HIT && hit {
                    return true;
                }
                if !ANY_HIT {
                    limit = best.t.min(ray.t_max);
                }
            }
            // Pop the nearest entry that may still hold a closer hit.
            loop {
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                let (n, t) = stack[sp];
                if t <= limit {
                    cur = n;
                    break;
                }
            }
        }
    }
}
