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
//! tracer cannot reach at all. Caustics seen in a mirror or through glass, those lit by
//! the sky and those further from the camera stay with the path tracer.
//!
//! On the `spheres` scene (a mirror ball, a glass ball and a ceiling light; 256 spp,
//! perf/gi.md) the paths through delta bounces into the emitter carry 5% of the image's
//! light and two thirds of its variance. Light tracing's share, 1.7% of the light, took
//! the MSE from 0.00189 to 0.00166; the largest part left, 0.0007 of it, is caustics
//! seen in the mirror or through the glass (emitter, delta, smooth, delta, ...,
//! camera), which neither end can connect.
//!
//! A render traces one light path per [`SAMPLES_PER_LIGHT_PATH`] camera samples.
//! Light path `i` draws only from its own generator, and the paths go in fixed chunks,
//! each a wavefront whose rays go as streams ([`intersect_unrelated`]); a chunk's
//! contributions are summed in path order and the chunks in chunk order, a batch of
//! chunks at a time, so the image is the same for any number of threads and in every
//! mode, and the memory it takes does not grow with the number of light paths.

use super::batch::{intersect_unrelated, occluded_unrelated};
use super::gi::{GiCounts, GiHit, GiScene, MAX_CHAIN, Segment, scatter_roulette};
use crate::accel::Mode;
use crate::ray::{Hit, Ray};
use crate::rng::Pcg32;
use crate::scene::CameraFrame;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

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
    rng: Pcg32,
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

/// The caustics of `g` as the camera `frame` sees them, from `paths` light paths drawn
/// with `seed`: the mean over pixels that the path tracer leaves to light tracing, one
/// value per pixel, row by row.
pub fn caustics(
    g: &GiScene,
    frame: &CameraFrame,
    paths: u64,
    seed: u64,
    mode: Mode,
    counts: &mut GiCounts,
) -> Vec<Vec3> {
    let (width, height) = (frame.width as usize, frame.height as usize);
    let chunks: Vec<u64> = (0..paths.div_ceil(CHUNK)).collect();
    // Summed in f64: a pixel may take many thousands of contributions.
    let mut image = vec![DVec3::ZERO; width * height];
    // A batch of chunks at a time, so the contributions waiting to be summed stay few
    // however many light paths a render takes.
    for batch in chunks.chunks(CHUNKS_PER_BATCH) {
        let done: Vec<(Vec<(usize, Vec3)>, GiCounts)> = batch
            .par_iter()
            .map(|&c| {
                let mut counts = GiCounts::default();
                let range = c * CHUNK..((c + 1) * CHUNK).min(paths);
                let splats = chunk(g, frame, range, paths, seed, mode, &mut counts);
                (splats, counts)
            })
            .collect();
        for (splats, c) in done {
            *counts += c;
            for (pixel, value) in splats {
                image[pixel] += value.as_dvec3();
            }
        }
    }
    image.into_iter().map(|p| p.as_vec3()).collect()
}

/// The light paths `range` of `paths`, as one wavefront: their contributions in path
/// order, as (pixel, value).
fn chunk(
    g: &GiScene,
    frame: &CameraFrame,
    range: std::ops::Range<u64>,
    paths: u64,
    seed: u64,
    mode: Mode,
    counts: &mut GiCounts,
) -> Vec<(usize, Vec3)> {
    let accel = g.shader.accel;
    let scale = 1.0 / paths as f32;
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
                rng,
            })
        })
        .collect();
    let mut splats = Vec::new();
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
            p.beta *= factor;
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
    splats
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
