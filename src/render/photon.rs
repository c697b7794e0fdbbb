//! render: photon mapping after Jensen ("Realistic Image Synthesis Using Photon
//! Mapping", 2001): a global and a caustic photon map, each a balanced kd-tree searched
//! for the k nearest photons, and final gathering for indirect diffuse light.
//!
//! Pass 1 shoots `photons` photons from the emitters ([`super::lights::Lights::emit`]). At every hit on
//! a surface with a Lambertian lobe a photon is stored in the global map, and also in the
//! caustic map when every bounce before it was a delta (mirror or dielectric) one. Paths
//! scatter by sampling the BSDF and continue by Russian roulette on the weight, so stored
//! powers stay near the emitted ones. Photon `i` draws only from its own stream of
//! [`Pcg32`], so both maps are the same for any thread count.
//!
//! Pass 2 follows camera rays through delta lobes; at the first vertex with a non-delta
//! lobe the radiance is split as Jensen does: emission, direct light by light sampling,
//! caustics from the caustic map, and the rest by `gather` final-gather rays sampled from
//! the BSDF, each reading the global map where it lands on a Lambertian surface (through
//! any delta lobes on the way). Those reads use irradiance precomputed at every
//! [`PRECOMPUTE_STRIDE`]-th global photon (Christensen 1999): the nearest such point on a
//! surface facing the same way answers, one nearest-neighbour search instead of `k`. Light reaching a gather ray's end straight from an emitter
//! is left out: direct light and caustics already hold it. The environment is the
//! exception: light sampling never picks it, so a gather ray that leaves the scene at once
//! brings it in.
//!
//! Density estimation: the radiance reflected by the Lambertian lobe of reflectance `kd` is
//! `kd / pi * sum(power) / (pi r^2)` over the `k` photons nearest to the point that
//! arrived from its side, `r` the distance to the `k`-th; the `k`-th photon's own power
//! is left out, which makes the estimate unbiased for a uniform density (the sum of `k`
//! powers over the disc through the `k`-th overestimates by `k / (k - 1)`). When fewer
//! than `k` photons lie within `max_radius`, all of them count over that disc. Only the
//! Lambertian lobe reads the maps: at the camera's vertex the gather rays sample every
//! non-delta lobe, Phong and GGX ones included, but where a gather ray ends only the Lambertian
//! reflection is estimated; a glossy lobe there is left out, a bias that vanishes in
//! Lambertian scenes such as the Cornell box. [`GiScene::max_bounces`] caps the path
//! tracer only; photon paths end by Russian roulette.

use super::gi::{GiCounts, GiHit, GiScene, Integrator, MAX_CHAIN, Segment, scatter_roulette};
use super::sample::{Pcg32, Sampler};
use crate::ray::{Hit, Ray};
use glam::Vec3;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f32::consts::{FRAC_1_PI, PI};
use std::time::Instant;

/// A stored photon: where it landed, the direction it travelled and its power.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Photon {
    pub p: Vec3,
    pub dir: Vec3,
    pub power: Vec3,
    /// Geometric normal of the surface on the side the photon arrived from.
    pub n: Vec3,
}

/// Photons in a balanced kd-tree laid out implicitly: the node of a range is its middle
/// element (the median along `axis[mid]`), its children the ranges on either side.
#[derive(Clone, Debug, Default)]
pub struct PhotonMap {
    photons: Vec<Photon>,
    axis: Vec<u8>,
}

/// A candidate of the k-nearest search, ordered by squared distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Near {
    d2: f32,
    index: u32,
}

impl Eq for Near {}

impl PartialOrd for Near {
    fn partial_cmp(&self, o: &Near) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Near {
    fn cmp(&self, o: &Near) -> Ordering {
        self.d2.total_cmp(&o.d2).then(self.index.cmp(&o.index))
    }
}

impl PhotonMap {
    /// Balances `photons` into a tree: median split on the axis of largest extent, the
    /// halves in parallel (the result does not depend on the thread count).
    pub fn build(mut photons: Vec<Photon>) -> PhotonMap {
        let mut axis = vec![0u8; photons.len()];
        balance(&mut photons, &mut axis);
        PhotonMap { photons, axis }
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    pub fn photons(&self) -> &[Photon] {
        &self.photons
    }

    /// The `k` photons nearest to `p` within `max_radius` that pass `keep`, nearest
    /// first, with their squared distances; `heap` is scratch space.
    pub fn nearest(
        &self,
        p: Vec3,
        k: usize,
        max_radius: f32,
        keep: &dyn Fn(&Photon) -> bool,
        heap: &mut BinaryHeap<Near>,
    ) -> Vec<(f32, u32)> {
        heap.clear();
        let mut r2 = max_radius * max_radius;
        if k > 0 {
            self.search(0, self.photons.len(), p, k, &mut r2, keep, heap);
        }
        let mut out: Vec<(f32, u32)> = heap.drain().map(|n| (n.d2, n.index)).collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out
    }

    #[allow(clippy::too_many_arguments)]
    fn search(
        &self,
        lo: usize,
        hi: usize,
        p: Vec3,
        k: usize,
        r2: &mut f32,
        keep: &dyn Fn(&Photon) -> bool,
        heap: &mut BinaryHeap<Near>,
    ) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let ph = &self.photons[mid];
        let a = self.axis[mid] as usize;
        let delta = p[a] - ph.p[a];
        let (near, far) = if delta < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(near.0, near.1, p, k, r2, keep, heap);
        let d2 = (ph.p - p).length_squared();
        if d2 <= *r2 && keep(ph) {
            heap.push(Near {
                d2,
                index: mid as u32,
            });
            if heap.len() > k {
                heap.pop();
            }
            if heap.len() == k {
                *r2 = heap.peek().map_or(*r2, |n| n.d2);
            }
        }
        if delta * delta <= *r2 {
            self.search(far.0, far.1, p, k, r2, keep, heap);
        }
    }

    /// Irradiance at `p` (normal `n`) from the photons that arrived from `n`'s side:
    /// the module's estimator.
    pub fn irradiance(
        &self,
        p: Vec3,
        n: Vec3,
        k: usize,
        max_radius: f32,
        heap: &mut BinaryHeap<Near>,
    ) -> Vec3 {
        if self.photons.is_empty() {
            return Vec3::ZERO;
        }
        let keep = |ph: &Photon| ph.dir.dot(n) < 0.0;
        let found = self.nearest(p, k, max_radius, &keep, heap);
        let (sum_of, r2) = if found.len() == k && k > 1 {
            (&found[..k - 1], found[k - 1].0)
        } else {
            (&found[..], max_radius * max_radius)
        };
        if r2 <= 0.0 {
            return Vec3::ZERO;
        }
        let sum = sum_of
            .iter()
            .fold(Vec3::ZERO, |s, &(_, i)| s + self.photons[i as usize].power);
        sum / (PI * r2)
    }
}

/// Photons in a hashed uniform grid for searches of one fixed radius: cells of twice
/// the radius, so a search reads at most 8 cells, each a run of the photon array; an
/// empty cell costs one read of the run starts. Cells share buckets by a spatial hash
/// (Teschner et al. 2003), and a search keeps only photons of the cells it asked for.
#[derive(Clone, Debug, Default)]
pub struct PhotonGrid {
    /// The photons by bucket, in their given order within a bucket.
    photons: Vec<Photon>,
    /// Where each bucket's run starts, and one past the last.
    starts: Vec<u32>,
    radius: f32,
    inv_cell: f32,
}

impl PhotonGrid {
    /// `photons` for searches of `radius` (positive and finite, else nothing is found).
    pub fn build(photons: Vec<Photon>, radius: f32) -> PhotonGrid {
        if photons.is_empty() || !(radius > 0.0 && radius.is_finite()) {
            return PhotonGrid::default();
        }
        let inv_cell = 0.5 / radius;
        let buckets = (2 * photons.len()).next_power_of_two();
        let bucket = |ph: &Photon| Self::hash(Self::cell(ph.p, inv_cell)) & (buckets - 1);
        let mut starts = vec![0u32; buckets + 1];
        for ph in &photons {
            starts[bucket(ph) + 1] += 1;
        }
        for b in 0..buckets {
            starts[b + 1] += starts[b];
        }
        let mut next = starts.clone();
        let mut sorted = photons.clone();
        for ph in photons {
            let b = bucket(&ph);
            sorted[next[b] as usize] = ph;
            next[b] += 1;
        }
        PhotonGrid {
            photons: sorted,
            starts,
            radius,
            inv_cell,
        }
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// The radius it searches.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    #[inline(always)]
    fn cell(p: Vec3, inv_cell: f32) -> [i32; 3] {
        // Saturating casts: far-off points share the edge cells, which the distance
        // test sorts out.
        (p * inv_cell).floor().to_array().map(|c| c as i32)
    }

    #[inline(always)]
    fn hash([x, y, z]: [i32; 3]) -> usize {
        (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ z.wrapping_mul(83_492_791))
            as u32 as usize
    }

    /// Calls `visit` with every photon within the radius of `p`, in an order fixed by
    /// the build (the same for any thread count).
    #[inline(always)]
    pub fn within(&self, p: Vec3, mut visit: impl FnMut(&Photon)) {
        if self.photons.is_empty() {
            return;
        }
        let r2 = self.radius * self.radius;
        let lo = Self::cell(p - self.radius, self.inv_cell);
        let hi = Self::cell(p + self.radius, self.inv_cell);
        let mask = self.starts.len() - 2;
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    let b = Self::hash([x, y, z]) & mask;
                    let run = self.starts[b] as usize..self.starts[b + 1] as usize;
                    for ph in &self.photons[run] {
                        if (ph.p - p).length_squared() <= r2
                            && Self::cell(ph.p, self.inv_cell) == [x, y, z]
                        {
                            visit(ph);
                        }
                    }
                }
            }
        }
    }
}

/// Orders `photons` as an implicit balanced kd-tree (see [`PhotonMap`]).
fn balance(photons: &mut [Photon], axis: &mut [u8]) {
    if photons.len() <= 1 {
        return;
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for ph in photons.iter() {
        lo = lo.min(ph.p);
        hi = hi.max(ph.p);
    }
    let e = hi - lo;
    let a = if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    };
    let mid = photons.len() / 2;
    photons.select_nth_unstable_by(mid, |x, y| x.p[a].total_cmp(&y.p[a]));
    axis[mid] = a as u8;
    let (left, rest) = photons.split_at_mut(mid);
    let (left_axis, rest_axis) = axis.split_at_mut(mid);
    let (right, right_axis) = (&mut rest[1..], &mut rest_axis[1..]);
    if left.len() > 4096 {
        rayon::join(|| balance(left, left_axis), || balance(right, right_axis));
    } else {
        balance(left, left_axis);
        balance(right, right_axis);
    }
}

/// Settings of the photon mapper.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonSettings {
    /// Photons shot from the emitters.
    pub photons: u32,
    /// Final-gather rays per camera sample.
    pub gather: u32,
    /// Photons per density estimate.
    pub k: usize,
    /// Largest search radius, as a share of the scene's bounding-box diagonal.
    pub max_radius: f32,
    pub seed: u64,
}

impl Default for PhotonSettings {
    fn default() -> Self {
        PhotonSettings {
            photons: 200_000,
            gather: 16,
            k: 64,
            max_radius: 0.1,
            seed: 0,
        }
    }
}

/// Times and sizes of the photon pass.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhotonStats {
    /// Shooting and tracing the photons.
    pub trace_seconds: f64,
    /// Balancing both kd-trees.
    pub build_seconds: f64,
    /// Precomputing irradiance at a share of the global photons, and its kd-tree.
    pub precompute_seconds: f64,
    pub global: usize,
    pub caustic: usize,
    /// Rays traced while shooting.
    pub rays: u64,
}

/// The photon mapper: both maps and the scene they were shot in.
pub struct PhotonMapper<'a> {
    pub scene: GiScene<'a>,
    pub global: PhotonMap,
    pub caustic: PhotonMap,
    /// Irradiance precomputed at every [`PRECOMPUTE_STRIDE`]-th global photon (in
    /// `power`, with the surface normal in `n`): what final-gather rays read.
    pub irradiance: PhotonMap,
    pub settings: PhotonSettings,
    /// `max_radius` in scene units.
    pub radius: f32,
    pub stats: PhotonStats,
}

/// One global photon in this many carries a precomputed irradiance (Christensen,
/// "Faster Photon Map Global Illumination", 1999): a gather ray then needs the nearest
/// such point, not a k-nearest search.
pub const PRECOMPUTE_STRIDE: usize = 4;
/// Smallest cosine between a gather hit's normal and a precomputed point's.
const SAME_SIDE_COS: f32 = 0.9;

/// Photons per parallel task.
const PHOTON_CHUNK: u32 = 4096;
/// Keeps the photon streams apart from the pixels' ([`super::sample::pixel_rng`]).
const PHOTON_STREAM_SALT: u64 = 0x7068_6f74_6f6e_7321;

impl<'a> PhotonMapper<'a> {
    /// Shoots the photons and builds both maps (on the current rayon pool).
    pub fn new(scene: GiScene<'a>, settings: PhotonSettings) -> PhotonMapper<'a> {
        let start = Instant::now();
        let n = settings.photons;
        let chunks: Vec<u32> = (0..n.div_ceil(PHOTON_CHUNK)).collect();
        let shot: Vec<(Vec<Photon>, Vec<Photon>, u64)> = chunks
            .par_iter()
            .map(|&c| {
                let (mut global, mut caustic, mut rays) = (Vec::new(), Vec::new(), 0);
                for i in c * PHOTON_CHUNK..((c + 1) * PHOTON_CHUNK).min(n) {
                    let mut rng = Pcg32::new(settings.seed ^ PHOTON_STREAM_SALT, i as u64);
                    rays += shoot(&scene, n, &mut rng, &mut global, &mut caustic);
                }
                (global, caustic, rays)
            })
            .collect();
        let (mut global, mut caustic, mut rays) = (Vec::new(), Vec::new(), 0);
        for (g, c, r) in shot {
            global.extend(g);
            caustic.extend(c);
            rays += r;
        }
        let trace_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let (global, caustic) =
            rayon::join(|| PhotonMap::build(global), || PhotonMap::build(caustic));
        let build_seconds = start.elapsed().as_secs_f64();
        let diagonal = scene.shader.accel.bounds().diagonal();
        let radius = if diagonal.is_finite() && diagonal > 0.0 {
            settings.max_radius * diagonal
        } else {
            settings.max_radius
        };
        let start = Instant::now();
        let points: Vec<Photon> = global
            .photons()
            .par_iter()
            .step_by(PRECOMPUTE_STRIDE)
            .map_init(BinaryHeap::new, |heap, ph| Photon {
                power: global.irradiance(ph.p, ph.n, settings.k, radius, heap),
                ..*ph
            })
            .collect();
        let irradiance = PhotonMap::build(points);
        let precompute_seconds = start.elapsed().as_secs_f64();
        let stats = PhotonStats {
            trace_seconds,
            build_seconds,
            precompute_seconds,
            global: global.len(),
            caustic: caustic.len(),
            rays,
        };
        PhotonMapper {
            scene,
            global,
            caustic,
            irradiance,
            settings,
            radius,
            stats,
        }
    }

    /// Radiance reflected by the Lambertian lobe of `h` toward any direction, from `map`.
    pub fn estimate(&self, map: &PhotonMap, h: &GiHit, heap: &mut BinaryHeap<Near>) -> Vec3 {
        let kd = h.bsdf.diffuse();
        if kd == Vec3::ZERO {
            return Vec3::ZERO;
        }
        kd * FRAC_1_PI * map.irradiance(h.p, h.n, self.settings.k, self.radius, heap)
    }

    /// Radiance reflected by the Lambertian lobe of `h`, from the precomputed irradiance
    /// nearest to it on a surface facing the same way (the full estimate where there is
    /// none within the search radius).
    pub fn gathered(&self, h: &GiHit, heap: &mut BinaryHeap<Near>) -> Vec3 {
        let kd = h.bsdf.diffuse();
        if kd == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let keep = |q: &Photon| q.n.dot(h.n) >= SAME_SIDE_COS;
        match self
            .irradiance
            .nearest(h.p, 1, self.radius, &keep, heap)
            .first()
        {
            Some(&(_, i)) => kd * FRAC_1_PI * self.irradiance.photons()[i as usize].power,
            None => self.estimate(&self.global, h, heap),
        }
    }

    /// The indirect light at `h` toward `wo` by final gathering.
    fn gather(
        &self,
        h: &GiHit,
        wo: Vec3,
        medium: Vec3,
        sampler: &mut Sampler,
        counts: &mut GiCounts,
        heap: &mut BinaryHeap<Near>,
    ) -> Vec3 {
        let g = &self.scene;
        let count = self.settings.gather.max(1);
        let mut sum = Vec3::ZERO;
        for _ in 0..count {
            let Some(s) = h.bsdf.sample_smooth(wo, sampler.next_choice_2d()) else {
                continue;
            };
            let mut beta = s.weight;
            let mut seg = g.spawn(h, s.wi, false, medium);
            for step in 0..MAX_CHAIN {
                counts.gather += 1;
                let Some(y) = g.trace(&seg, &mut beta) else {
                    if step == 0 {
                        sum += beta * g.lights.environment;
                    }
                    break;
                };
                sum += beta * self.gathered(&y, heap);
                let Some(d) = y.bsdf.sample_delta(-seg.ray.dir, sampler.next_choice_2d()) else {
                    break;
                };
                beta *= d.weight;
                if beta.max_element() <= 0.0 {
                    break;
                }
                seg = g.spawn(&y, d.wi, d.transmitted, seg.medium);
            }
        }
        sum / count as f32
    }
}

/// Traces photon `rng`'s path (one of `n`) and stores its hits; returns the rays traced.
fn shoot(
    g: &GiScene,
    n: u32,
    rng: &mut Pcg32,
    global: &mut Vec<Photon>,
    caustic: &mut Vec<Photon>,
) -> u64 {
    let u = [(); 5].map(|_| rng.next_f32());
    let Some(e) = g.lights.emit(u) else {
        return 0;
    };
    let mut power = e.power / n as f32;
    let mut seg = Segment::new(Ray::new(e.org, e.dir, 0.0, f32::INFINITY));
    let mut specular_only = true;
    let mut rays = 0;
    for bounce in 0..MAX_CHAIN {
        rays += 1;
        let Some(h) = g.trace(&seg, &mut power) else {
            break;
        };
        if h.bsdf.diffuse() != Vec3::ZERO {
            let ph = Photon {
                p: h.p,
                dir: seg.ray.dir,
                power,
                n: h.n,
            };
            global.push(ph);
            if specular_only && bounce > 0 {
                caustic.push(ph);
            }
        }
        let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        let Some(s) = h.bsdf.sample(-seg.ray.dir, u) else {
            break;
        };
        let Some(factor) = scatter_roulette(s.weight, rng) else {
            break;
        };
        // Scaled after the roulette, so a closed object's two factors cancel exactly.
        power *= factor * h.bsdf.adjoint_scale(&s);
        specular_only &= s.delta;
        seg = g.spawn(&h, s.wi, s.transmitted, seg.medium);
    }
    rays
}

impl Integrator for PhotonMapper<'_> {
    fn gi_scene(&self) -> &GiScene<'_> {
        &self.scene
    }

    fn radiance_traced(
        &self,
        ray: &Ray,
        first: Option<Hit>,
        sampler: &mut Sampler,
        counts: &mut GiCounts,
    ) -> Vec3 {
        let g = &self.scene;
        let mut heap = BinaryHeap::with_capacity(self.settings.k + 1);
        let mut seg = Segment::new(*ray);
        let mut beta = Vec3::ONE;
        let mut l = Vec3::ZERO;
        let mut first = Some(first);
        for step in 0..MAX_CHAIN {
            if step > 0 {
                counts.bounce += 1;
            }
            let Some(h) = g.trace_known(&seg, first.take(), &mut beta) else {
                l += beta * g.lights.environment;
                break;
            };
            l += beta * g.emitted(&h);
            let wo = -seg.ray.dir;
            if h.bsdf.has_smooth() {
                let direct = g.direct(&h, wo, sampler, false, counts);
                let caustic = self.estimate(&self.caustic, &h, &mut heap);
                let indirect = self.gather(&h, wo, seg.medium, sampler, counts, &mut heap);
                l += beta * (direct + caustic + indirect);
            }
            let Some(d) = h.bsdf.sample_delta(wo, sampler.next_choice_2d()) else {
                break;
            };
            beta *= d.weight;
            if beta.max_element() <= 0.0 {
                break;
            }
            seg = g.spawn(&h, d.wi, d.transmitted, seg.medium);
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid's search finds exactly the photons a brute-force scan finds, each once,
    /// on random clouds with duplicates and points on a plane (the caustics' usual
    /// shape), for radii from tiny to past the cloud, at query points on photons and off
    /// them, near the origin and far from it (negative cells, saturated casts).
    #[test]
    fn grid_finds_what_a_scan_finds() {
        let mut rng = Pcg32::new(7, 1);
        for (n, flat, offset) in [
            (0, false, 0.0),
            (1, false, 0.0),
            (2, true, -3.0),
            (37, false, 0.0),
            (1000, true, -0.5),
            (300, false, 1e12),
        ] {
            let mut photons: Vec<Photon> = (0..n)
                .map(|_| {
                    let y = if flat { 0.5 } else { rng.next_f32() };
                    Photon {
                        p: Vec3::new(rng.next_f32(), y, rng.next_f32()) + offset,
                        dir: Vec3::NEG_Y,
                        power: Vec3::splat(rng.next_f32()),
                        n: Vec3::Y,
                    }
                })
                .collect();
            if n > 2 {
                photons[1].p = photons[0].p;
            }
            for r in [1e-3, 0.01, 0.1, 0.3, 2.0] {
                let grid = PhotonGrid::build(photons.clone(), r);
                let mut queries: Vec<Vec3> = photons.iter().take(5).map(|p| p.p).collect();
                queries.extend((0..20).map(|_| {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 1.2 - 0.1 + offset
                }));
                for q in queries {
                    let mut found = Vec::new();
                    grid.within(q, |ph| found.push(*ph));
                    let key = |p: &Photon| (p.p.to_array().map(f32::to_bits), p.power.x.to_bits());
                    found.sort_by_key(key);
                    let mut want: Vec<Photon> = photons
                        .iter()
                        .filter(|ph| (ph.p - q).length_squared() <= r * r)
                        .copied()
                        .collect();
                    want.sort_by_key(key);
                    assert_eq!(found, want, "{n} photons, query {q}, radius {r}");
                }
            }
        }
        assert!(PhotonGrid::build(vec![], 1.0).is_empty());
    }
}
