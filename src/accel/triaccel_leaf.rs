//! One ray against several TriAccel records at once: lanes are triangles (the leaf
//! kernel of the kd-tree's lane walks): [`Prims::intersect_tris_lanes`], the lane twin
//! of [`Prims::intersect_leaf`] (in [`crate::accel::prims`]) for a leaf's triangles,
//! and [`Prims::occludes_tris_lanes`], the twin of the scalar any-hit loop.
//! Each lane repeats [`super::triaccel::TriAccel::intersect`] operation by operation
//! with the ray's components picked by the lane's axis `k`, so its `t`, `u`, `v` and
//! edge bound are the scalar ones bit for bit; the lanes are then
//! folded into the closest hit in leaf order with the limit the scalar loop would have
//! used for each, and lanes within the bound of an edge run the scalar exact rule.
//! The records are read a 16-byte row at a time and transposed ([`Float::from_rows4`])
//! instead of field by field, lane by lane: 1.04x on the conference room's and the
//! bunny's diffuse streams (perf/log/stream.md, "Fifteenth session").

use super::Prims;
use super::triaccel::{TriAccel, exact_rule, max_abs};
use super::triaccel_packet::Projected;
use crate::ray::{Hit, Ray};
use crate::simd::{Float, LaneMask, Simd, Uint, Vf, Vu, inl};

/// The limit a hit must stay under for `best` to take it, as the scalar loops use it:
/// `t_max` for an any-hit query, else just past `best.t` (an equal `t` may still win on
/// id) within `t_max`.
#[inline(always)]
fn hit_limit<const ANY_HIT: bool>(ray: &Ray, best: &Hit) -> f32 {
    if ANY_HIT {
        ray.t_max
    } else {
        best.t.next_up().min(ray.t_max)
    }
}

impl Prims {
    /// Folds the triangles in slots `tris` (below `sphere_base`, at most `W::LANES`) into `best`
    /// exactly as [`Prims::intersect_leaf`] does: for each in order, a hit under
    /// `limit = min(next_up(best.t), ray.t_max)` replaces `best` when [`Hit::is_closer`].
    #[inline(always)]
    pub fn intersect_tris_lanes<W: Simd>(&self, tris: &[u32], ray: &Ray, best: &mut Hit) {
        self.tris_lanes::<W, false>(tris, ray, best);
    }

    /// Whether any triangle in slots `tris` (below `sphere_base`, at most `W::LANES`) is
    /// hit in `(t_min, t_max)`: the answer of [`Prims::intersect_prim`] with `t_max`
    /// over the slots, as the scalar any-hit loop asks it.
    #[inline(always)]
    pub fn occludes_tris_lanes<W: Simd>(&self, tris: &[u32], ray: &Ray) -> bool {
        let mut unused = Hit::MISS;
        self.tris_lanes::<W, true>(tris, ray, &mut unused)
    }

    /// [`Prims::intersect_tris_lanes`], or with `ANY_HIT` [`Prims::occludes_tris_lanes`]
    /// (the limit stays `t_max` and the first hit answers; `best` is left alone).
    #[inline(always)]
    pub(crate) fn tris_lanes<W: Simd, const ANY_HIT: bool>(
        &self,
        tris: &[u32],
        ray: &Ray,
        best: &mut Hit,
    ) -> bool {
        debug_assert!(tris.len() <= W::LANES);
        self.tris_lanes_with::<W, ANY_HIT>(
            tris.len(),
            #[inline(always)]
            |i| &self.tris[tris[i] as usize],
            #[inline(always)]
            |i| tris[i] as usize,
            ray,
            best,
        )
    }

    /// [`Prims::tris_lanes`] of the `n` records from slot `first` on (a leaf whose
    /// records lie in leaf order): no slot list to read first.
    #[inline(always)]
    pub(crate) fn tris_lanes_run<W: Simd, const ANY_HIT: bool>(
        &self,
        first: usize,
        n: usize,
        ray: &Ray,
        best: &mut Hit,
    ) -> bool {
        debug_assert!(n <= W::LANES);
        let recs = &self.tris[first..first + n];
        self.tris_lanes_with::<W, ANY_HIT>(
            n,
            #[inline(always)]
            |i| &recs[i],
            #[inline(always)]
            |i| first + i,
            ray,
            best,
        )
    }

    /// The test of [`Prims::tris_lanes`] on `n` records: `rec(i)` is lane `i`'s record
    /// and `slot_of(i)` its slot.
    #[inline(always)]
    fn tris_lanes_with<'a, W: Simd, const ANY_HIT: bool>(
        &'a self,
        n: usize,
        rec: impl Fn(usize) -> &'a TriAccel,
        slot_of: impl Fn(usize) -> usize,
        ray: &Ray,
        best: &mut Hit,
    ) -> bool {
        // The records' rows, transposed: field per vector, triangle per lane (the
        // lanes past `n` repeat the last record).
        let row = inl(
            #[inline(always)]
            |r: usize| {
                Vf::<W>::from_rows4(
                    #[inline(always)]
                    |i| &rec(i.min(n - 1)).rows()[r],
                )
            },
        );
        let [
            [n_u, n_v, n_d, k_id],
            [b_nu, b_nv, b_d, err],
            [c_nu, c_nv, c_d, mag],
        ] = [row(0), row(1), row(2)];
        let valid = W::all_bits() >> (W::LANES - n);
        let k = k_id.to_bits() & Vu::<W>::splat(3);
        let (k_gt0, k_gt1) = (k.cmp_gt(Vu::<W>::splat(0)), k.cmp_gt(Vu::<W>::splat(1)));
        let (m0, m1) = (!k_gt0, k_gt0 & !k_gt1);
        let splat = Vf::<W>::splat;
        // Axis k, k + 1, k + 2 (mod 3) of a vector, per lane.
        let pick = inl(
            #[inline(always)]
            |x: f32, y: f32, z: f32| {
                let (x, y, z) = (splat(x), splat(y), splat(z));
                let sel = Vf::<W>::select;
                [
                    sel(m0, x, sel(m1, y, z)),
                    sel(m0, y, sel(m1, z, x)),
                    sel(m0, z, sel(m1, x, y)),
                ]
            },
        );
        let (o, d) = (ray.org, ray.dir);
        let lanes = Projected::<W> {
            o: pick(o.x, o.y, o.z),
            d: pick(d.x, d.y, d.z),
            o_max: splat(max_abs(o)),
            d_max: splat(max_abs(d)),
        };
        let (t, ad, reach, slack) = lanes.distance([n_u, n_v, n_d], mag);
        // The loosest limit of this leaf (limits only narrow): a lane failing here fails
        // under every later limit too.
        let limit0 = hit_limit::<ANY_HIT>(ray, best);
        let keep =
            ((t - splat(limit0)) * ad).cmp_lt(slack) & ((splat(ray.t_min) - t) * ad).cmp_lt(slack);
        // No early return when no lane is in range: on a diffuse ray's leaves that
        // branch goes either way, and its misses cost more than the barycentrics
        // (1.01x on the bunny, perf/log/stream.md).
        let mut bits = keep.bits() & valid;
        let (u, v, edge, bound) =
            lanes.barycentrics(t, ad, reach, [b_nu, b_nv, b_d], [c_nu, c_nv, c_d], err);
        bits &= edge.cmp_ge(-bound).bits();
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let limit = hit_limit::<ANY_HIT>(ray, best);
            let (ti, adi, si) = (t.lane(i), ad.lane(i), slack.lane(i));
            if !((ti - limit) * adi < si) {
                continue;
            }
            let (ei, bi) = (edge.lane(i), bound.lane(i));
            let slot = slot_of(i);
            let hit = if ei >= bi {
                (ti > ray.t_min && ti < limit).then(
                    #[inline(always)]
                    || (ti, u.lane(i), v.lane(i)),
                )
            } else {
                exact_rule(ray, limit, &self.corners[slot])
            };
            if ANY_HIT && hit.is_some() {
                return true;
            }
            let prim = self.tris[slot].id();
            if let Some((t, u, v)) = hit
                && Hit::is_closer(t, prim, best)
            {
                *best = Hit { t, u, v, prim };
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Geometry;
    use crate::scene::generate::{Rng, random_soup};
    use crate::simd::{W4, W8, W16};
    use glam::Vec3;

    fn bits(h: &Hit) -> (u32, u32, u32, u32) {
        (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits())
    }

    /// A soup, a fan of triangles sharing edges, exact duplicates (equal-`t` ties with
    /// different ids), axis-aligned triangles (every `k`) and a degenerate one.
    fn geometry() -> Geometry {
        let mut g = random_soup(48, 0.6, 7);
        let push = |g: &mut Geometry, a: Vec3, b: Vec3, c: Vec3| {
            let i = g.vertices.len() as u32;
            g.vertices.extend([a, b, c]);
            g.triangles.push([i, i + 1, i + 2]);
        };
        let hub = Vec3::new(0.5, 0.5, 0.5);
        for s in 0..8 {
            let a0 = s as f32 * std::f32::consts::TAU / 8.0;
            let a1 = (s + 1) as f32 * std::f32::consts::TAU / 8.0;
            let p = |a: f32| hub + Vec3::new(a.cos(), a.sin(), 0.3 * a.sin()) * 0.4;
            push(&mut g, hub, p(a0), p(a1));
        }
        for _ in 0..4 {
            let [a, b, c] = g.triangle(3);
            push(&mut g, a, b, c);
        }
        for k in 0..3 {
            let e = |i: usize| Vec3::AXES[(k + i) % 3];
            push(&mut g, e(1) * 0.1, e(1) * 0.9, e(2) * 0.9 + e(0) * 0.5);
            push(
                &mut g,
                e(1) * 0.1 + e(0) * 0.5,
                e(1) * 0.9 + e(0) * 0.5,
                e(2) * 0.9 + e(0) * 0.5,
            );
        }
        push(&mut g, Vec3::ZERO, Vec3::X, Vec3::X * 2.0);
        g
    }

    /// Random rays, rays aimed at corners and edge midpoints of the group's
    /// triangles, rays starting on them, axis-parallel rays with signed zeros, cut rays
    /// and NaN rays.
    fn rays(g: &Geometry, group: &[u32], rng: &mut Rng) -> Vec<Ray> {
        let mut out = Vec::new();
        for _ in 0..6 {
            let o = rng.point(Vec3::splat(-0.5), Vec3::splat(1.5));
            out.push(Ray::new(o, rng.unit_vector(), 0.0, f32::INFINITY));
        }
        for &prim in group {
            let [a, b, c] = g.triangle(prim);
            let o = rng.point(Vec3::splat(-1.0), Vec3::splat(2.0));
            for target in [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5] {
                out.push(Ray::new(o, target - o, 0.0, f32::INFINITY));
                out.push(Ray::new(o, target - o, 0.0, 1.0));
                out.push(Ray::new(o, target - o, 0.0, 1.0f32.next_down()));
            }
            let on = a * 0.25 + b * 0.25 + c * 0.5;
            out.push(Ray::new(on, rng.unit_vector(), 0.0, f32::INFINITY));
            out.push(Ray::new(on, rng.unit_vector(), 1e-4, f32::INFINITY));
            for axis in Vec3::AXES {
                for s in [1.0f32, -1.0] {
                    let d = axis * s;
                    let d = Vec3::select(d.cmpeq(Vec3::ZERO), Vec3::splat(-0.0), d);
                    out.push(Ray::new(on - d, d, 0.0, f32::INFINITY));
                    out.push(Ray::new(a - d, d, 0.0, f32::INFINITY));
                }
            }
        }
        out.push(Ray::new(Vec3::splat(f32::NAN), Vec3::X, 0.0, f32::INFINITY));
        out.push(Ray::new(
            Vec3::ZERO,
            Vec3::new(0.5, f32::NAN, 0.5),
            0.0,
            1.0,
        ));
        out
    }

    /// Every group size from 1 to `W::LANES`, random groups (leaf order is any order),
    /// against the scalar loop from a miss and from a hit found earlier.
    #[inline(always)]
    fn lanes_match_scalar<W: Simd>() {
        let g = geometry();
        let p = Prims::new(&g);
        let n = g.triangles.len() as u32;
        let mut rng = Rng::new(W::LANES as u64);
        let mut hits = 0;
        for size in 1..=W::LANES {
            for round in 0..12 {
                let group: Vec<u32> = (0..size).map(|_| rng.below(n)).collect();
                for ray in rays(&g, &group, &mut rng) {
                    let mut want = Hit::MISS;
                    p.intersect_leaf(&group, &ray, &mut want);
                    for start in [Hit::MISS, want, Hit { prim: n, ..want }] {
                        let (mut a, mut b) = (start, start);
                        p.intersect_leaf(&group, &ray, &mut a);
                        p.intersect_tris_lanes::<W>(&group, &ray, &mut b);
                        assert_eq!(
                            bits(&a),
                            bits(&b),
                            "{} lanes, group {group:?} (round {round}), ray {ray:?}, from {start:?}",
                            W::LANES
                        );
                    }
                    let occluded = group
                        .iter()
                        .any(|&t| p.intersect_prim(t, &ray, ray.t_max).is_some());
                    assert_eq!(
                        occluded,
                        p.occludes_tris_lanes::<W>(&group, &ray),
                        "{} lanes, group {group:?} (round {round}), ray {ray:?}: any hit",
                        W::LANES
                    );
                    hits += want.is_hit() as usize;
                }
            }
        }
        assert!(hits > 1_000, "{} lanes: only {hits} hits", W::LANES);
    }

    #[test]
    fn four_lanes_match_scalar() {
        lanes_match_scalar::<W4>();
    }

    #[test]
    fn eight_lanes_match_scalar() {
        lanes_match_scalar::<W8>();
    }

    #[test]
    fn sixteen_lanes_match_scalar() {
        lanes_match_scalar::<W16>();
    }

    /// The 4- and 8-lane backends of every instruction set this CPU runs, inside their
    /// entries: the lane walks test leaves with them ([`crate::simd::Simd::X8`]).
    #[test]
    fn every_instruction_set_matches_scalar() {
        #[cfg(target_arch = "x86_64")]
        {
            use crate::simd::{Avx2x4, Avx2x8, Avx512x4, Avx512x8, Isa};
            if Isa::Avx2.supported() {
                Avx2x4::enter(lanes_match_scalar::<Avx2x4>);
                Avx2x8::enter(lanes_match_scalar::<Avx2x8>);
            }
            if Isa::Avx512.supported() {
                Avx512x4::enter(lanes_match_scalar::<Avx512x4>);
                Avx512x8::enter(lanes_match_scalar::<Avx512x8>);
            }
            eprintln!("leaf lanes checked under {:?}", Isa::best());
        }
    }
}
