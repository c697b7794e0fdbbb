//! render: caustics by light tracing, for the path tracer.
//!
//! A caustic is light that left an emitter, bounced off mirrors or through glass (delta
//! lobes) and landed on a surface with a smooth lobe. The path tracer finds it only when
//! a BSDF sample from that surface happens to run through the delta bounces into the
//! emitter, which for a small emitter is rare and bright. Traced from the other end the
//! caustics the camera sees are cheap: a path leaves an emitter, follows the delta
//! lobes, and at the first surface with a smooth lobe after them connects to the camera
//! by one shadow ray (Veach 1997, light tracing; Jensen's caustic photons, without the
//! density estimate); it then takes one smooth bounce and connects the next surface,
//! which the caustic lights, too ([`SMOOTH_VERTICES`]).
//!
//! The two estimators split the paths between them, so each path is counted once and
//! the sum is unbiased: the path tracer leaves out emission it reaches through delta
//! bounces right after one or two smooth bounces from the camera's first hit on
//! (`PathTracer::advance`), when the emitter is one light tracing starts from
//! ([`super::lights::Lights::is_sampled`]); light tracing counts exactly those paths,
//! and also the caustics of point lights and invisible area lights, which the path
//! tracer cannot reach at all.
//!
//! Caustics seen in a mirror or through glass (emitter, delta bounces, a smooth
//! surface, delta bounces, camera), and what they light in turn, neither end can
//! connect by a ray. Where a light path's delta bounces end it leaves a photon
//! ([`CausticPhotons`]); the path tracer, at a surface a delta bounce led to, reads
//! those photons and leaves out the emission its own smooth bounce from there reaches
//! through delta bounces. Those caustics are then a density estimate, biased by its
//! small radius and consistent. Caustics lit by the sky, and the photons when
//! `max_bounces` is set, stay with the path tracer.
//!
//! On the `spheres` scene (a mirror ball, a glass ball and a ceiling light; 256 spp,
//! perf/gi.md) the paths through delta bounces into the emitter carry 5% of the image's
//! light and two thirds of its variance. Light tracing's connections, 1.7% of the light,
//! took the MSE from 0.00189 to 0.00166, and the caustic photons to 0.00103 for 5% more
//! time.
//!
//! A render traces one light path per [`SAMPLES_PER_LIGHT_PATH`] camera samples.
//! Light path `i` draws only from its own generator, and the paths go in fixed chunks,
//! each a wavefront whose rays go as streams ([`intersect_unrelated`]); a chunk's
//! contributions are summed in path order and the chunks in chunk order, a batch of
//! chunks at a time, so the image is the same for any number of threads and in every
//! mode, and the memory it takes does not grow with the number of light paths.

use super::batch::{intersect_unrelated, occluded_unrelated};
use super::gi::{GiCounts, GiHit, GiScene, MAX_CHAIN, Segment, scatter_roulette};
use super::photon::{Photon, PhotonGrid};
use crate::accel::Mode;
use crate::ray::{Hit, Ray};
use crate::rng::Pcg32;
use crate::scene::CameraFrame;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::f32::consts::PI;

/// Light paths per parallel task: one wavefront.
const CHUNK: u64 = 4096;
/// Chunks traced in parallel before their contributions are summed into the image.
const CHUNKS_PER_BATCH: usize = 256;
/// Surfaces with a smooth lobe a light path connects to the camera from, one after the
/// other after its delta bounces: the caustic itself, and what it lights in turn.
pub const SMOOTH_VERTICES: u32 = 2;
/// Keeps the light paths' streams apart from the pixels' and the photons'.
const LIGHT_STREAM_SALT: u64 = 0x6c69_6768_7470_6174;

/// A light path in flight.
struct LightPath {
    seg: Segment,
    /// Power carried, times the number of light paths.
    beta: Vec3,
    /// Delta bounces so far.
    bounces: u32,
    /// Smooth bounces since the delta bounces.
    smooth: u32,
    /// The path leaves a caustic photon ([`photon_paths`]).
    photon: bool,
    rng: Pcg32,
}

/// Light paths that leave caustic photons, at most: the first 2^24 (a render of 2^28
/// camera samples, 1024x1024 at 256 spp), about a million photons in a scene like
/// `spheres`. Beyond it the photons, and the estimate's radius, stop growing with the
/// samples, so the memory they take stays bounded.
pub const MAX_PHOTON_PATHS: u64 = 1 << 24;

/// How many of `paths` light paths leave caustic photons: the first ones, up to
/// [`MAX_PHOTON_PATHS`]; none unless the path tracer reads them.
fn photon_paths(g: &GiScene, paths: u64) -> u64 {
    if g.photon_caustics() {
        paths.min(MAX_PHOTON_PATHS)
    } else {
        0
    }
}

/// Camera samples per light path. Most light paths miss the mirrors and glass and end
/// at their first hit, and those that reach the camera have little variance, so a few
/// suffice: on `spheres` at 256 spp (2 threads) one light path per 4, 8 and 16 camera
/// samples left MSEs of 0.00162, 0.00163 and 0.00166 (0.00189 without light tracing),
/// and one per 4 took 4.6% more time than one per 16 (paired one-thread renders), one
/// per 8 about the same (perf/gi.md).
pub const SAMPLES_PER_LIGHT_PATH: u64 = 16;

/// A connection to the camera waiting for its shadow ray.
struct Connection {
    ray: Ray,
    pixel: usize,
    value: Vec3,
}

/// What light tracing leaves for a render: the caustics the camera sees, and the photons
/// for those it sees through delta bounces.
pub struct Caustics {
    /// The mean over pixels that the path tracer leaves to light tracing, one value per
    /// pixel, row by row.
    pub image: Vec<Vec3>,
    pub photons: CausticPhotons,
}

/// The caustic photons: where light paths landed on a surface with a smooth lobe after
/// their delta bounces, for the camera paths that see that surface through delta bounces
/// of their own (in a mirror, through glass), which neither end can connect by a ray.
/// The path tracer leaves those paths' emission out and reads this instead
/// (`PathTracer::advance`): Jensen's density estimate over a disc of fixed radius. It is
/// biased by the disc's blur, and consistent: the radius shrinks as `paths^(-1/6)`, so
/// with more samples the bias (as `r^2`) and the variance (as `1 / (paths r^2)`) both
/// vanish (the rate of Knaus and Zwicker's progressive photon mapping, alpha = 2/3), up
/// to [`MAX_PHOTON_PATHS`].
#[derive(Clone, Debug, Default)]
pub struct CausticPhotons {
    grid: PhotonGrid,
}

/// The estimate's radius over the scene's bounding-box diagonal for one light path;
/// `paths^(-1/6)` times that for `paths`: 0.1% of the diagonal for `spheres` at 256 spp
/// (786,432 light paths). There radii from 0.05% to 1% of the diagonal, and k-nearest
/// estimates of 8 to 100 photons, left the same MSE (0.00103), while the time grew with
/// the photons an estimate sums: the glass ball's focus packs thousands into a disc of
/// 1% (perf/gi.md).
const RADIUS_OVER_DIAGONAL: f32 = 0.01;

impl CausticPhotons {
    /// The photons of `paths` light paths in a scene of bounding-box diagonal
    /// `diagonal`.
    pub fn new(photons: Vec<Photon>, paths: u64, diagonal: f32) -> CausticPhotons {
        let scale = if diagonal.is_finite() && diagonal > 0.0 {
            diagonal
        } else {
            1.0
        };
        let radius = RADIUS_OVER_DIAGONAL * scale * (paths.max(1) as f32).powf(-1.0 / 6.0);
        CausticPhotons {
            grid: PhotonGrid::build(photons, radius),
        }
    }

    pub fn len(&self) -> usize {
        self.grid.len()
    }

    pub fn is_empty(&self) -> bool {
        self.grid.is_empty()
    }

    /// The radiance toward `wo` that `h` reflects of the photons that landed within the
    /// radius on its side: `sum f(wo, wi) power / (pi r^2)`.
    #[inline(always)]
    pub fn radiance(&self, h: &GiHit, wo: Vec3) -> Vec3 {
        if self.grid.is_empty() {
            return Vec3::ZERO;
        }
        let mut sum = Vec3::ZERO;
        self.grid.within(
            h.p,
            #[inline(always)]
            |ph| {
                if ph.n.dot(h.n) > 0.0 {
                    sum += h.bsdf.eval(wo, -ph.dir) * ph.power;
                }
            },
        );
        let r = self.grid.radius();
        sum / (PI * r * r)
    }
}

/// The caustics of `g` as the camera `frame` sees them, from `paths` light paths drawn
/// with `seed`.
pub fn caustics(
    g: &GiScene,
    frame: &CameraFrame,
    paths: u64,
    seed: u64,
    mode: Mode,
    counts: &mut GiCounts,
) -> Caustics {
    let (width, height) = (frame.width as usize, frame.height as usize);
    let chunks: Vec<u64> = (0..paths.div_ceil(CHUNK)).collect();
    // Summed in f64: a pixel may take many thousands of contributions.
    let mut image = vec![DVec3::ZERO; width * height];
    let mut photons = Vec::new();
    // A batch of chunks at a time, so the contributions waiting to be summed stay few
    // however many light paths a render takes.
    for batch in chunks.chunks(CHUNKS_PER_BATCH) {
        let done: Vec<(Traced, GiCounts)> = batch
            .par_iter()
            .map(|&c| {
                let mut counts = GiCounts::default();
                let range = c * CHUNK..((c + 1) * CHUNK).min(paths);
                let traced = chunk(g, frame, range, paths, seed, mode, &mut counts);
                (traced, counts)
            })
            .collect();
        // In chunk order, so the photon map is the same for any thread count.
        for (traced, c) in done {
            *counts += c;
            photons.extend(traced.photons);
            for (pixel, value) in traced.splats {
                image[pixel] += value.as_dvec3();
            }
        }
    }
    let diagonal = g.shader.accel.bounds().diagonal();
    Caustics {
        image: image.into_iter().map(|p| p.as_vec3()).collect(),
        photons: CausticPhotons::new(photons, photon_paths(g, paths), diagonal),
    }
}

/// What a chunk of light paths leaves, in path order.
struct Traced {
    /// Contributions to the image, as (pixel, value).
    splats: Vec<(usize, Vec3)>,
    photons: Vec<Photon>,
}

/// The light paths `range` of `paths`, as one wavefront.
fn chunk(
    g: &GiScene,
    frame: &CameraFrame,
    range: std::ops::Range<u64>,
    paths: u64,
    seed: u64,
    mode: Mode,
    counts: &mut GiCounts,
) -> Traced {
    let accel = g.shader.accel;
    let scale = 1.0 / paths as f32;
    let photon_paths = photon_paths(g, paths);
    let photon_scale = 1.0 / photon_paths.max(1) as f32;
    let mut live: Vec<LightPath> = range
        .filter_map(|i| {
            let mut rng = Pcg32::new(seed ^ LIGHT_STREAM_SALT, i);
            let u = [(); 5].map(|_| rng.next_f32());
            let e = g.lights.emit_from_emitters(u)?;
            Some(LightPath {
                seg: Segment::new(Ray::new(e.org, e.dir, 0.0, f32::INFINITY)),
                beta: e.power,
                bounces: 0,
                smooth: 0,
                photon: i < photon_paths,
                rng,
            })
        })
        .collect();
    let (mut splats, mut photons) = (Vec::new(), Vec::new());
    let (mut rays, mut hits) = (Vec::new(), Vec::new());
    let mut connections: Vec<Connection> = Vec::new();
    let mut occluded = Vec::new();
    while !live.is_empty() {
        rays.clear();
        rays.extend(live.iter().map(|p| p.seg.ray));
        hits.clear();
        hits.resize(rays.len(), Hit::MISS);
        intersect_unrelated(accel, mode, &rays, &mut hits);
        counts.light += rays.len() as u64;
        connections.clear();
        let mut next = Vec::with_capacity(live.len() / 4);
        for (mut p, h) in live.into_iter().zip(&hits) {
            let Some(h) = g.at_hit(&p.seg, h.is_hit().then_some(*h), &mut p.beta) else {
                continue;
            };
            let within = |bounces: u32| g.max_bounces.is_none_or(|m| bounces <= m);
            // Where the delta bounces end: a caustic photon for the camera paths that see
            // this surface through delta bounces themselves.
            if p.photon && p.bounces > 0 && p.smooth == 0 && h.bsdf.has_smooth() {
                photons.push(Photon {
                    p: h.p,
                    dir: p.seg.ray.dir,
                    power: p.beta * photon_scale,
                    n: h.n,
                });
            }
            // A smooth surface after the delta bounces: the camera may see it lit.
            if p.bounces > 0
                && h.bsdf.has_smooth()
                && within(p.bounces + p.smooth + 1)
                && let Some(c) = connect(frame, &h, -p.seg.ray.dir, p.beta * scale)
            {
                connections.push(c);
            }
            // On: more delta bounces before the first smooth surface, or one smooth
            // bounce from it; the next surface must still be within the bounces.
            if p.smooth + 1 >= SMOOTH_VERTICES
                || p.bounces >= MAX_CHAIN
                || !within(p.bounces + p.smooth + 2)
            {
                continue;
            }
            let u = [(); 3].map(|_| p.rng.next_f32());
            let wo = -p.seg.ray.dir;
            let s = if p.bounces == 0 {
                h.bsdf.sample_delta(wo, u)
            } else {
                h.bsdf.sample(wo, u)
            };
            let Some(s) = s else {
                continue;
            };
            let Some(factor) = scatter_roulette(s.weight, &mut p.rng) else {
                continue;
            };
            // Scaled after the roulette, so a closed object's two factors cancel exactly.
            p.beta *= factor * h.bsdf.adjoint_scale(&s);
            p.seg = g.spawn(&h, s.wi, s.transmitted, p.seg.medium);
            if s.delta {
                p.bounces += 1;
            } else {
                p.smooth += 1;
            }
            next.push(p);
        }
        live = next;
        if connections.is_empty() {
            continue;
        }
        rays.clear();
        rays.extend(connections.iter().map(|c| c.ray));
        occluded.clear();
        occluded.resize(rays.len(), false);
        occluded_unrelated(accel, mode, &rays, &mut occluded);
        counts.shadow += rays.len() as u64;
        for (c, &o) in connections.iter().zip(&occluded) {
            if !o {
                splats.push((c.pixel, c.value));
            }
        }
    }
    Traced { splats, photons }
}

/// The connection of the light path that arrived at `h` from direction `wi` (pointing
/// back along it) with power `beta` to the camera: the shadow ray toward the eye, the
/// pixel it crosses and the value it adds there if unoccluded, `beta f cos W / d^2`
/// (`W` the film's importance, [`CameraFrame::project`]). `None` when the camera does
/// not see the point's lit side or the point is outside the image.
fn connect(frame: &CameraFrame, h: &GiHit, wi: Vec3, beta: Vec3) -> Option<Connection> {
    let (x, y, importance) = frame.project(h.p)?;
    let org = h.p + h.n * h.epsilon;
    let to = frame.eye - org;
    let dist = to.length();
    if !(dist > 0.0) {
        return None;
    }
    let wo = to / dist;
    let cos = wo.dot(h.n);
    if !(cos > 0.0) {
        return None;
    }
    let f = h.bsdf.eval(wo, wi);
    let d2 = (frame.eye - h.p).length_squared();
    let value = beta * f * (cos * importance / d2);
    if value == Vec3::ZERO || !value.is_finite() {
        return None;
    }
    Some(Connection {
        ray: Ray::new(org, wo, 0.0, dist * (1.0 - 1e-4)),
        pixel: y as usize * frame.width as usize + x as usize,
        value,
    })
}
