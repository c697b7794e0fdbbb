//! render: the driver of the global-illumination integrators ([`super::path`],
//! [`super::photon`]): tiles rendered in parallel, `spp` jittered camera samples per
//! pixel, a tile's samples cut into [`passes`] when the image has few tiles. Sample `k`
//! of every pixel of a tile is one batch handed to an [`Integrator`], which may trace its
//! paths one by one or as a wavefront; light an integrator traces from the emitters
//! ([`Integrator::light_image`]) is added last.
//!
//! Speed: a path vertex (`PathTracer::advance` in [`super::path`]) is compiled as one
//! function. What it calls per vertex (the hit's surface and BSDF, light, environment
//! and BSDF sampling, the sampler) is `#[inline(always)]`, so the hit record and its
//! BSDF (about 200 bytes) never cross a call and the lobes the material lacks fold
//! away: the path tracer's renders take 0.8x-0.9x the time they took with calls
//! (perf/gi.md, "One function per vertex").
//!
//! Invariants: sample `k` of pixel `(x, y)` draws only from its own [`Sampler`]
//! (`Sampler::new(kind, seed, x, y, k)`), so the image is the same for any number of
//! threads and any tile order; a tile's passes are summed in pass order, and ray counts
//! per piece in tile and pass order.

use super::batch::{intersect_rays, intersect_unrelated};
use super::bsdf::Bsdf;
use super::film::Film;
use super::lights::Lights;
use super::sample::{Pcg32, Sampler, SamplerKind, pixel_seed};
use super::shade::{Shader, transmission};
use super::tiles::tiles;
use crate::accel::Accel;
use crate::accel::Mode;
use crate::ray::{Hit, Ray};
use crate::scene::{CameraFrame, Material, Scene};
use glam::Vec3;
use rayon::prelude::*;
use std::ops::AddAssign;

/// Rays traced by the global-illumination integrators, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GiCounts {
    pub camera: u64,
    /// Continuation rays of paths (BSDF samples after the camera ray).
    pub bounce: u64,
    /// Shadow rays of next-event estimation (any-hit).
    pub shadow: u64,
    /// Final-gather rays of the photon map, and their specular continuations.
    pub gather: u64,
    /// Rays traced while shooting photons.
    pub photon: u64,
    /// Rays of the light paths the path tracer traces for caustics ([`super::light_trace`]):
    /// from the emitters and on through delta bounces; their rays to the camera count
    /// as `shadow`.
    pub light: u64,
    /// Packets the camera rays were traced in (0 in scalar mode); not in the total.
    pub camera_packets: u64,
    /// Packets the camera vertex's shadow rays toward point lights were traced in (path
    /// tracer, packet modes); not in the total.
    pub shadow_packets: u64,
}

impl GiCounts {
    pub fn total(&self) -> u64 {
        self.camera + self.bounce + self.shadow + self.gather + self.photon + self.light
    }
}

impl AddAssign for GiCounts {
    fn add_assign(&mut self, o: GiCounts) {
        self.camera += o.camera;
        self.bounce += o.bounce;
        self.shadow += o.shadow;
        self.gather += o.gather;
        self.photon += o.photon;
        self.light += o.light;
        self.camera_packets += o.camera_packets;
        self.shadow_packets += o.shadow_packets;
    }
}

/// An estimator of the radiance arriving along a camera ray.
pub trait Integrator: Sync {
    /// The scene it traces.
    fn gi_scene(&self) -> &GiScene<'_>;

    /// One sample of the radiance along camera ray `ray` (already counted) whose closest
    /// hit `first` the caller has traced (in a packet, [`render_gi`]).
    fn radiance_traced(
        &self,
        ray: &Ray,
        first: Option<Hit>,
        sampler: &mut Sampler,
        counts: &mut GiCounts,
    ) -> Vec3;

    /// [`Integrator::radiance_traced`] for many camera rays at once, `first[i]` the
    /// closest hit of ray `i` ([`Hit::MISS`] for none, as the stream queries write it)
    /// and `samplers[i]` its sampler, the same values bit for bit; `mode` says how rays
    /// traced together go (one by one in scalar mode). The default takes the rays one
    /// at a time.
    fn radiance_batch(
        &self,
        rays: &[Ray],
        first: &[Hit],
        samplers: &mut [Sampler],
        _mode: Mode,
        counts: &mut GiCounts,
    ) -> Vec<Vec3> {
        rays.iter()
            .zip(first)
            .zip(samplers)
            .map(|((ray, h), s)| self.radiance_traced(ray, h.is_hit().then_some(*h), s, counts))
            .collect()
    }

    /// Light the integrator finds by tracing paths from the emitters to the camera
    /// instead of from the camera (`None`: none), to be added to the image of `spp`
    /// camera samples per pixel rendered with `seed`: one value per pixel, row by row,
    /// the same bits in every `mode`. The path tracer's caustics ([`super::light_trace`]).
    fn light_image(
        &self,
        _frame: &CameraFrame,
        _spp: u32,
        _seed: u64,
        _mode: Mode,
        _counts: &mut GiCounts,
    ) -> Option<Vec<Vec3>> {
        None
    }

    /// One sample of the radiance along camera ray `ray` (already counted).
    fn radiance(&self, ray: &Ray, sampler: &mut Sampler, counts: &mut GiCounts) -> Vec3 {
        let first = self.gi_scene().shader.accel.intersect(ray);
        self.radiance_traced(ray, first, sampler, counts)
    }
}

/// What both integrators trace against: the scene, its accelerator, its emitters and
/// the offset of rays leaving a surface ([`Shader::rounding_offset`]).
pub struct GiScene<'a> {
    pub shader: Shader<'a>,
    pub lights: Lights,
    /// Scattering events per path; `None` leaves paths to Russian roulette alone.
    pub max_bounces: Option<u32>,
    /// How [`render_gi`] draws each camera sample's numbers (Sobol unless set).
    pub sampler: SamplerKind,
    /// The path tracer leaves caustics to light tracing ([`super::light_trace`]): set
    /// when some material has a delta lobe (a mirror, a dielectric) and some emitter is
    /// sampled. The photon mapper ignores it.
    pub light_tracing: bool,
    /// With light tracing, the path tracer estimates the caustics it sees through delta
    /// bounces from the light paths' photons ([`super::light_trace`]); set unless
    /// `max_bounces` is, since a photon does not know the path's length on the camera's
    /// side.
    pub caustic_photons: bool,
}

/// A hit prepared for the global-illumination integrators.
pub struct GiHit<'a> {
    pub hit: Hit,
    pub p: Vec3,
    /// Geometric normal on the side the ray came from.
    pub n: Vec3,
    /// True when the ray arrived on the side the normal points to (the emitting side).
    pub front: bool,
    pub material: &'a Material,
    pub bsdf: Bsdf,
    /// Offset of rays leaving `p` ([`Shader::rounding_offset`]).
    pub epsilon: f32,
}

/// Where a path stands: the ray to trace next and the absorption of the medium it runs
/// through (Beer's law, as in the Whitted tracer).
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    pub ray: Ray,
    pub medium: Vec3,
    /// The surface point the ray left (its origin before the offset): Beer's law counts
    /// the distance from here, so the offset does not thin a medium.
    pub from: Vec3,
}

impl Segment {
    /// A ray starting in clear air (a camera ray, a photon leaving its light).
    pub fn new(ray: Ray) -> Segment {
        Segment {
            ray,
            medium: Vec3::ZERO,
            from: ray.org,
        }
    }
}

impl<'a> GiScene<'a> {
    /// `environment` is the radiance of rays that leave the scene.
    pub fn new(
        scene: &'a Scene,
        accel: &'a dyn Accel,
        environment: Vec3,
        max_bounces: Option<u32>,
    ) -> GiScene<'a> {
        let lights = Lights::new(scene, environment);
        let delta = scene
            .materials
            .iter()
            .any(|m| Bsdf::new(m, Vec3::ONE, Vec3::Z, true).has_delta());
        GiScene {
            shader: Shader::new(scene, accel),
            light_tracing: delta && !lights.is_empty(),
            caustic_photons: max_bounces.is_none(),
            lights,
            max_bounces,
            sampler: SamplerKind::default(),
        }
    }

    /// True when the path tracer reads caustics seen through delta bounces from photons
    /// ([`GiScene::caustic_photons`]).
    pub fn photon_caustics(&self) -> bool {
        self.light_tracing && self.caustic_photons
    }

    pub fn scene(&self) -> &'a Scene {
        self.shader.scene
    }

    /// Traces `seg`; `None` on a miss. `throughput` is multiplied by the medium's
    /// transmission over the distance travelled (to zero for an absorbing medium that
    /// never ends).
    pub fn trace(&self, seg: &Segment, throughput: &mut Vec3) -> Option<GiHit<'a>> {
        self.at_hit(seg, self.shader.accel.intersect(&seg.ray), throughput)
    }

    /// [`GiScene::trace`], or [`GiScene::at_hit`] when `known` holds the segment's
    /// closest hit already (a camera ray traced in a packet).
    pub fn trace_known(
        &self,
        seg: &Segment,
        known: Option<Option<Hit>>,
        throughput: &mut Vec3,
    ) -> Option<GiHit<'a>> {
        match known {
            Some(hit) => self.at_hit(seg, hit, throughput),
            None => self.trace(seg, throughput),
        }
    }

    /// [`GiScene::trace`] for a segment whose closest hit `hit` is already known.
    #[inline(always)]
    pub fn at_hit(
        &self,
        seg: &Segment,
        hit: Option<Hit>,
        throughput: &mut Vec3,
    ) -> Option<GiHit<'a>> {
        let Some(hit) = hit else {
            *throughput *= transmission(seg.medium, f32::INFINITY);
            return None;
        };
        let s = self.shader.surface(&seg.ray, &hit);
        if seg.medium != Vec3::ZERO {
            *throughput *= transmission(seg.medium, (s.p - seg.from).length());
        }
        Some(GiHit {
            hit,
            p: s.p,
            n: s.ng,
            front: !s.inside,
            material: s.material,
            bsdf: Bsdf::new(s.material, s.albedo, s.ng, !s.inside),
            epsilon: Shader::rounding_offset(seg.ray.org, s.p),
        })
    }

    /// Radiance emitted by `h` toward where its ray came from (one-sided).
    #[inline(always)]
    pub fn emitted(&self, h: &GiHit) -> Vec3 {
        if h.front {
            h.material.emission
        } else {
            Vec3::ZERO
        }
    }

    /// The ray leaving `h` along `wi`, off the surface on the side it leaves to, with the
    /// medium it enters: a transmitted ray entering a dielectric is inside it, one leaving
    /// is back in clear air, a reflected ray stays where it was.
    #[inline(always)]
    pub fn spawn(&self, h: &GiHit, wi: Vec3, transmitted: bool, medium: Vec3) -> Segment {
        let side = if transmitted { -h.n } else { h.n };
        let medium = match (transmitted, h.front) {
            (true, true) => h.bsdf.absorption,
            (true, false) => Vec3::ZERO,
            (false, _) => medium,
        };
        Segment {
            ray: Ray::new(h.p + side * h.epsilon, wi, 0.0, f32::INFINITY),
            medium,
            from: h.p,
        }
    }

    /// Next-event estimation at `h` for outgoing `wo`: one light sample, its shadow ray,
    /// `f cos Li / pdf` weighted by the power heuristic against BSDF sampling when `mis`
    /// (the photon map takes light samples alone: `mis = false`). Draws a choice and a
    /// 2D point ([`Sampler::next_choice_2d`]).
    pub fn direct(
        &self,
        h: &GiHit,
        wo: Vec3,
        sampler: &mut Sampler,
        mis: bool,
        counts: &mut GiCounts,
    ) -> Vec3 {
        match self.direct_query(h, wo, sampler, mis) {
            Some(q) => {
                counts.shadow += 1;
                if self.shader.accel.occluded(&q.ray) {
                    Vec3::ZERO
                } else {
                    q.value
                }
            }
            None => Vec3::ZERO,
        }
    }

    /// The light sample of [`GiScene::direct`] without its shadow ray traced: the ray,
    /// and what the sample brings when the ray is unoccluded. `None` when it brings
    /// nothing whatever the ray meets. Draws what `direct` draws, so a
    /// caller that traces the shadow rays of many paths together takes the same samples.
    #[inline(always)]
    pub fn direct_query(
        &self,
        h: &GiHit,
        wo: Vec3,
        sampler: &mut Sampler,
        mis: bool,
    ) -> Option<ShadowQuery> {
        let u = sampler.next_choice_2d();
        if !h.bsdf.has_smooth() {
            return None;
        }
        let ls = self.lights.sample(h.p, u)?;
        let f = h.bsdf.eval(wo, ls.wi) * ls.wi.dot(h.n).max(0.0);
        if f == Vec3::ZERO || ls.pdf <= 0.0 {
            return None;
        }
        // Aimed from the offset origin at the sampled point itself, stopping just short
        // of it: the emitter's own surface must not count as a blocker.
        let org = h.p + h.n * h.epsilon;
        let to = ls.point - org;
        let len = to.length();
        if !(len > 0.0) {
            return None;
        }
        let w = if mis && !ls.delta {
            super::bsdf::power_heuristic(ls.pdf, h.bsdf.pdf(wo, ls.wi))
        } else {
            1.0
        };
        Some(ShadowQuery {
            ray: Ray::new(org, to / len, 0.0, len * (1.0 - 1e-4)),
            value: f * ls.li * (w / ls.pdf),
            point_light: ls.delta,
        })
    }

    /// Next-event estimation of the environment at `h` for outgoing `wo`: a direction
    /// from [`Lights::sample_environment`], its shadow ray to infinity, and
    /// `f cos L / pdf` weighted by the power heuristic against BSDF sampling. Draws a 2D
    /// point when the scene has an environment ([`Lights::has_environment`]), nothing
    /// otherwise; `None` when the sample brings nothing whatever the ray meets. One
    /// sample per vertex: four made Sponza under a sky more efficient but open scenes
    /// under it noisier, since they shift the MIS weights toward the sky (perf/gi.md,
    /// "Tried and not kept").
    #[inline(always)]
    pub fn environment_query(
        &self,
        h: &GiHit,
        wo: Vec3,
        sampler: &mut Sampler,
    ) -> Option<ShadowQuery> {
        if !self.lights.has_environment() {
            return None;
        }
        let u = sampler.next_2d();
        if !h.bsdf.has_smooth() {
            return None;
        }
        let (wi, pdf) = self.lights.sample_environment(h.n, u);
        let f = h.bsdf.eval(wo, wi) * wi.dot(h.n).max(0.0);
        if f == Vec3::ZERO || !(pdf > 0.0) {
            return None;
        }
        let w = super::bsdf::power_heuristic(pdf, h.bsdf.pdf(wo, wi));
        Some(ShadowQuery {
            ray: Ray::new(h.p + h.n * h.epsilon, wi, 0.0, f32::INFINITY),
            value: f * self.lights.environment * (w / pdf),
            point_light: false,
        })
    }

    /// The weight of environment light found by a BSDF sample of density `bsdf_pdf`
    /// (`None` after a delta lobe or for a camera ray) leaving a surface of normal `n`
    /// along `wi`: the power heuristic against [`GiScene::environment_query`], or 1 when
    /// that strategy could not have found it.
    #[inline(always)]
    pub fn environment_weight(&self, bsdf_pdf: Option<f32>, n: Vec3, wi: Vec3) -> f32 {
        match bsdf_pdf {
            Some(pdf) if self.lights.has_environment() => {
                super::bsdf::power_heuristic(pdf, self.lights.environment_pdf(n, wi))
            }
            _ => 1.0,
        }
    }
}

/// A light sample's shadow ray and the radiance it brings if nothing blocks it.
#[derive(Clone, Copy, Debug)]
pub struct ShadowQuery {
    pub ray: Ray,
    pub value: Vec3,
    /// The ray ends at a point light: from neighbouring camera hits such rays are
    /// coherent, and are traced as packets.
    pub point_light: bool,
}

/// Russian roulette from the fourth vertex on: a path goes on with probability
/// `min(0.95, max channel of throughput)` and is reweighted; draws one value always.
#[inline(always)]
pub fn survives(vertex: u32, throughput: &mut Vec3, sampler: &mut Sampler) -> bool {
    let u = sampler.next_1d();
    if vertex < 3 {
        return true;
    }
    let p = throughput.max_element().min(0.95);
    if p <= 0.0 || u >= p {
        return false;
    }
    *throughput /= p;
    true
}

/// Bounces a path from an emitter (a photon, a light path), or a specular chain of a
/// camera or gather ray, may take at most (a ray caught between two glass faces).
pub const MAX_CHAIN: u32 = 64;

/// Russian roulette on the scattering weight of a path from an emitter (photons, light
/// paths): the path goes on with probability `min(1, max channel of weight)`, drawn from
/// `rng` only when that is positive, and the factor its power takes is returned; so
/// powers stay level. `None`: the path ends.
#[inline(always)]
pub fn scatter_roulette(weight: Vec3, rng: &mut Pcg32) -> Option<Vec3> {
    let q = weight.max_element().min(1.0);
    if !(q > 0.0) || rng.next_f32() >= q {
        return None;
    }
    Some(weight / q)
}

/// A rendered image with the rays it took.
#[derive(Clone, Debug)]
pub struct GiRendered {
    pub film: Film,
    pub counts: GiCounts,
}

/// The pieces [`render_gi`] cuts a render into at least: so many that the last ones to
/// finish are short and no thread waits long for the others (a 256x192 image has 48
/// tiles, so its threads waited 4-6% of the render, the last tiles being the slowest).
/// Fixed, not set by the thread count, so the image is the same on any number of
/// threads.
pub const MIN_PIECES: usize = 384;

/// How many pieces [`render_gi`] cuts a `width x height` render of `spp` samples per
/// pixel into: what its `progress` counts.
pub fn pieces(width: u32, height: u32, spp: u32) -> usize {
    let tiles = tiles(width, height).len();
    tiles * passes(tiles, spp) as usize
}

/// How many passes [`render_gi`] splits each of `tiles` tiles' `spp` samples into.
pub fn passes(tiles: usize, spp: u32) -> u32 {
    MIN_PIECES
        .div_ceil(tiles.max(1))
        .clamp(1, spp.max(1) as usize) as u32
}

/// The samples of pass `pass` of `passes`.
fn pass_samples(spp: u32, passes: u32, pass: u32) -> std::ops::Range<u32> {
    let at = |q: u32| (u64::from(spp) * u64::from(q) / u64::from(passes)) as u32;
    at(pass)..at(pass + 1)
}

/// Renders `spp` samples per pixel of `scene`'s camera at its settings' size through
/// `integrator` on the current rayon pool, drawing from the integrator's sampler kind
/// ([`GiScene::sampler`]); `progress` is called once per finished piece: a tile's pass
/// ([`passes`] per tile).
/// In a packet mode the camera rays of a packet width of neighbouring pixels are traced as
/// one packet, and the integrator sends its other rays as it says
/// ([`Integrator::radiance_batch`]); the image is that of [`Mode::Scalar`], bit for bit.
pub fn render_gi(
    scene: &Scene,
    integrator: &dyn Integrator,
    spp: u32,
    mode: Mode,
    progress: &(dyn Fn() + Sync),
) -> GiRendered {
    let accel = integrator.gi_scene().shader.accel;
    let (width, height) = (scene.settings.width, scene.settings.height);
    let frame = scene.camera.frame(width, height);
    let seed = scene.settings.seed;
    let kind = integrator.gi_scene().sampler;
    let spp = spp.max(1);
    let mut light_counts = GiCounts::default();
    let light = integrator.light_image(&frame, spp, seed, mode, &mut light_counts);
    let tiles = tiles(width, height);
    let passes = passes(tiles.len(), spp);
    let pieces: Vec<(usize, u32)> = (0..tiles.len())
        .flat_map(|t| (0..passes).map(move |q| (t, q)))
        .collect();
    let done: Vec<(Vec<Vec3>, GiCounts)> = pieces
        .par_iter()
        .map(|&(tile, pass)| {
            let t = &tiles[tile];
            let samples = pass_samples(spp, passes, pass);
            let mut counts = GiCounts::default();
            let pixels: Vec<(u32, u32)> = (t.y0..t.y0 + t.height)
                .flat_map(|y| (t.x0..t.x0 + t.width).map(move |x| (x, y)))
                .collect();
            // Sample k of every pixel of the tile is one batch: its camera rays go in
            // groups of a packet width of pixels along the tile's rows (one by one in
            // scalar mode, as one stream in stream mode), then the integrator takes the
            // batch on.
            let packet = mode.group_mode();
            let n = pixels.len();
            let mut sums = vec![Vec3::ZERO; n];
            let mut rays = Vec::with_capacity(n);
            let mut samplers = Vec::with_capacity(n);
            let mut hits = vec![Hit::MISS; n];
            let seeds: Vec<u64> = pixels
                .iter()
                .map(|&(x, y)| pixel_seed(seed, x, y))
                .collect();
            for k in samples {
                rays.clear();
                samplers.clear();
                for (&(x, y), &pixel) in pixels.iter().zip(&seeds) {
                    let mut sampler = Sampler::for_pixel(kind, pixel, k);
                    let (jx, jy) = sampler.next_2d();
                    rays.push(frame.ray(x as f32 + jx, y as f32 + jy));
                    samplers.push(sampler);
                }
                counts.camera += n as u64;
                if packet == Mode::Scalar {
                    intersect_unrelated(accel, mode, &rays, &mut hits);
                } else {
                    let size = packet.packet_size();
                    for (group, out) in rays.chunks(size).zip(hits.chunks_mut(size)) {
                        counts.camera_packets += 1;
                        out.copy_from_slice(&intersect_rays(accel, packet, group)[..group.len()]);
                    }
                }
                let l = integrator.radiance_batch(&rays, &hits, &mut samplers, mode, &mut counts);
                for (sum, l) in sums.iter_mut().zip(l) {
                    // A NaN or infinite sample would poison the pixel: drop it.
                    if l.is_finite() {
                        *sum += l;
                    }
                }
            }
            progress();
            (sums, counts)
        })
        .collect();
    let mut film = Film::new(width, height);
    let mut counts = light_counts;
    // A tile's passes in order: the same sums whatever thread took each.
    for (t, passes) in tiles.iter().zip(done.chunks(passes as usize)) {
        let mut sums = vec![Vec3::ZERO; (t.width * t.height) as usize];
        for (pass, c) in passes {
            counts += *c;
            for (sum, s) in sums.iter_mut().zip(pass) {
                *sum += *s;
            }
        }
        for (i, s) in sums.into_iter().enumerate() {
            film.set(
                t.x0 + i as u32 % t.width,
                t.y0 + i as u32 / t.width,
                s / spp as f32,
            );
        }
    }
    if let Some(light) = light {
        for (i, l) in light.into_iter().enumerate() {
            let (x, y) = (i as u32 % width, i as u32 / width);
            film.set(x, y, film.get(x, y) + l);
        }
    }
    GiRendered { film, counts }
}
