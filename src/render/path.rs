//! render: unidirectional path tracing with next-event estimation.
//!
//! At every vertex with a non-delta lobe one emitter sample is taken ([`GiScene::direct`]),
//! and one environment sample when the scene has a sky ([`GiScene::environment_query`]);
//! the path continues by sampling the BSDF ([`super::bsdf`]). Emission found by a BSDF
//! sample (an emitter, or the sky where the path escapes) is weighted against the
//! light-sampling density by the power heuristic (Veach 1997), so each light path is
//! counted once in expectation; emission seen by the camera, after a delta bounce, or
//! from an emitter light sampling never picks (spheres, planes) counts in full, except
//! the caustics left to light tracing ([`GiScene::light_tracing`], [`super::light_trace`]):
//! emission reached through delta bounces right after one or two smooth bounces from the
//! camera's first hit on counts nothing, nor does emission reached through delta bounces
//! after a smooth bounce from a surface that a delta bounce led to; such a surface (seen
//! in a mirror, through glass) reads that light from the caustic photons instead
//! ([`GiScene::photon_caustics`], [`super::light_trace::CausticPhotons`]). Russian
//! roulette ends paths from the fourth vertex on ([`super::gi::survives`]); `max_bounces`
//! optionally caps the scattering events, counting both kinds of paths alike (light
//! sampling at vertex `k` makes a path of `k + 1` bounces).
//!
//! Numbers drawn per vertex, in order ([`Sampler`]): a choice and a 2D point for the light
//! sample, a 2D point for the environment sample (with a sky only), a choice and a 2D
//! point for the BSDF sample, one value for Russian roulette.
//!
//! Paths are traced one vertex at a time (`PathTracer::advance`), either alone
//! ([`Integrator::radiance_traced`], the reference) or as a wavefront of many paths
//! ([`Integrator::radiance_batch`]): each generation's bounce rays go as one stream, its
//! shadow rays as another, and at the camera's vertex the shadow rays toward point lights
//! from neighbouring pixels as packets. A path draws only from its own generator and adds
//! to its radiance in the same order either way, so both give the same bits.

use super::batch::{intersect_unrelated, occluded_rays, occluded_unrelated};
use super::gi::{GiCounts, GiScene, Integrator, Segment, ShadowQuery, survives};
use super::light_trace::{CausticPhotons, SAMPLES_PER_LIGHT_PATH, SMOOTH_VERTICES, caustics};
use super::sample::{Draw, Sampler, draw_ahead};
use crate::accel::Mode;
use crate::ray::{Hit, Ray};
use crate::scene::CameraFrame;
use crate::simd::scalar_entry;
use glam::Vec3;
use std::sync::{Arc, RwLock};

/// How many hits ahead of the one it shades the wavefront asks for a hit's surface
/// records (half as far for its vertices' normals, which need the triangle first).
const PREFETCH_AHEAD: usize = 16;

/// Scenes with fewer triangles keep their surface records in cache, where asking
/// ahead only costs instructions (the Cornell box's 64-spp render: 2-7% slower with
/// it, `sponza_sky`'s 8% faster).
const PREFETCH_MIN_TRIANGLES: usize = 1 << 14;

/// What a vertex draws from its sampler, in order (the module's doc): the light sample's
/// choice and point, the BSDF sample's choice and point, Russian roulette's value; under
/// a sky the environment sample's point comes after the light sample's. The wavefront
/// draws these ahead ([`draw_ahead`]); were [`PathTracer::advance`] to draw otherwise,
/// its samplers would compute the draws as usual: the same values, only slower.
const VERTEX_DRAWS: [Draw; 5] = [Draw::One, Draw::Two, Draw::One, Draw::Two, Draw::One];
const VERTEX_DRAWS_SKY: [Draw; 6] = [
    Draw::One,
    Draw::Two,
    Draw::Two,
    Draw::One,
    Draw::Two,
    Draw::One,
];

/// The path tracer over a prepared scene.
pub struct PathTracer<'a> {
    pub scene: GiScene<'a>,
    /// The caustic photons of the last light pass ([`Integrator::light_image`]), read
    /// by the camera paths of the same render.
    caustics: RwLock<Arc<CausticPhotons>>,
}

impl<'a> PathTracer<'a> {
    pub fn new(scene: GiScene<'a>) -> PathTracer<'a> {
        PathTracer {
            scene,
            caustics: RwLock::default(),
        }
    }

    /// The caustic photons the camera paths read now (none before a light pass).
    pub fn caustic_photons(&self) -> Arc<CausticPhotons> {
        Arc::clone(&self.caustics.read().unwrap_or_else(|e| e.into_inner()))
    }
}

/// One path in flight: the ray it traces next and what it has gathered.
#[derive(Clone, Copy, Debug)]
struct Path {
    seg: Segment,
    beta: Vec3,
    l: Vec3,
    /// Density of the BSDF sample that made the current ray; `None` for the camera ray
    /// and after a delta lobe (emission then counts in full).
    bsdf_pdf: Option<f32>,
    /// Normal of the surface the current ray left (on its side): the environment
    /// sample's density there weighs the sky the ray finds.
    from_normal: Vec3,
    vertex: u32,
    /// Direct light waiting for its shadow rays (the emitter's, the environment's): the
    /// throughput at its vertex and the radiance the sample brings if unoccluded.
    waiting: [Option<(Vec3, Vec3)>; 2],
    alive: bool,
    /// Where the path stands against the shares of light tracing and the caustic photons.
    caustic: Caustic,
}

/// A path against the caustics estimated from the other end: light tracing's
/// ([`super::light_trace`]: it started with `n` smooth bounces from the camera's first
/// hit on, then came delta bounces) and the caustic photons' (a surface reached by a
/// delta bounce scattered smoothly, then came delta bounces).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Caustic {
    Smooth(u32),
    /// Delta bounces after one to [`SMOOTH_VERTICES`] smooth ones: emission reached now
    /// is light tracing's.
    Chain,
    /// The last bounce was a delta one, outside both shares.
    Delta,
    /// A smooth bounce from a surface reached by a delta bounce.
    Through,
    /// Delta bounces after [`Caustic::Through`]: emission reached now is the photons'.
    PhotonChain,
    No,
}

impl Caustic {
    /// The state after a bounce, `delta` or smooth; `photons` when the path tracer
    /// reads the caustic photons ([`GiScene::photon_caustics`]).
    #[inline(always)]
    fn after(self, delta: bool, photons: bool) -> Caustic {
        use Caustic::*;
        let next = match (self, delta) {
            (Smooth(n), false) if n < SMOOTH_VERTICES => Smooth(n + 1),
            (Smooth(n), true) if n > 0 => Chain,
            (Chain, true) => Chain,
            (Through | PhotonChain, true) => PhotonChain,
            (_, true) => Delta,
            (c, false) if c.by_delta() => Through,
            _ => No,
        };
        match next {
            Delta | Through | PhotonChain if !photons => No,
            _ => next,
        }
    }

    /// True when the current ray came from a delta bounce, so a surface it reaches with
    /// a smooth lobe reads the caustic photons.
    fn by_delta(self) -> bool {
        matches!(self, Caustic::Chain | Caustic::Delta | Caustic::PhotonChain)
    }
}

/// The shadow rays of one vertex: the emitter sample's, then the environment's.
type Queries = [Option<ShadowQuery>; 2];

impl Path {
    /// A path starting with camera ray `ray`.
    fn new(ray: Ray) -> Path {
        Path {
            seg: Segment::new(ray),
            beta: Vec3::ONE,
            l: Vec3::ZERO,
            bsdf_pdf: None,
            from_normal: Vec3::ZERO,
            vertex: 0,
            waiting: [None; 2],
            alive: true,
            caustic: Caustic::Smooth(0),
        }
    }

    /// Adds the waiting direct light of shadow ray `slot` once it is answered.
    fn resolve(&mut self, slot: usize, occluded: bool) {
        if let Some((beta, value)) = self.waiting[slot].take() {
            self.l += beta * if occluded { Vec3::ZERO } else { value };
        }
    }
}

impl PathTracer<'_> {
    /// Takes `p` through the vertex where its current ray ends (`hit`, its closest hit):
    /// emission, the light samples, one BSDF sample and Russian roulette. Returns the
    /// light samples' shadow rays (counted), whose answers [`Path::resolve`] takes by
    /// slot; the path is then done, or holds the next ray to trace. Inlined whole into
    /// the two loops that run it (the module [`super::gi`] says why).
    #[inline(always)]
    fn advance(
        &self,
        p: &mut Path,
        hit: Option<Hit>,
        sampler: &mut Sampler,
        caustics: &CausticPhotons,
        counts: &mut GiCounts,
    ) -> Queries {
        let g = &self.scene;
        let Some(h) = g.at_hit(&p.seg, hit, &mut p.beta) else {
            let w = g.environment_weight(p.bsdf_pdf, p.from_normal, p.seg.ray.dir);
            p.l += p.beta * g.lights.environment * w;
            p.alive = false;
            return [None; 2];
        };
        let le = g.emitted(&h);
        if le != Vec3::ZERO {
            let w = match p.bsdf_pdf {
                Some(pdf) => {
                    let light_pdf = g.lights.pdf(h.hit.prim, p.seg.ray.org, h.p);
                    super::bsdf::power_heuristic(pdf, light_pdf)
                }
                // Counted by light tracing, or by its photons, instead.
                None if (p.caustic == Caustic::Chain && g.light_tracing
                    || p.caustic == Caustic::PhotonChain && g.photon_caustics())
                    && g.lights.is_sampled(h.hit.prim) =>
                {
                    0.0
                }
                None => 1.0,
            };
            p.l += p.beta * le * w;
        }
        if g.max_bounces.is_some_and(|m| p.vertex >= m) {
            p.alive = false;
            return [None; 2];
        }
        let wo = -p.seg.ray.dir;
        // A surface seen through delta bounces: its caustics come from the photons.
        if p.caustic.by_delta() && g.photon_caustics() && h.bsdf.has_smooth() {
            p.l += p.beta * caustics.radiance(&h, wo);
        }
        let queries = [
            g.direct_query(&h, wo, sampler, true),
            g.environment_query(&h, wo, sampler),
        ];
        match queries[0] {
            Some(q) => p.waiting[0] = Some((p.beta, q.value)),
            None => p.l += p.beta * Vec3::ZERO,
        }
        if let Some(q) = queries[1] {
            p.waiting[1] = Some((p.beta, q.value));
        }
        counts.shadow += queries.iter().flatten().count() as u64;
        let Some(s) = h.bsdf.sample(wo, sampler.next_choice_2d()) else {
            p.alive = false;
            return queries;
        };
        p.beta *= s.weight;
        if !survives(p.vertex, &mut p.beta, sampler) {
            p.alive = false;
            return queries;
        }
        p.caustic = p.caustic.after(s.delta, g.photon_caustics());
        p.bsdf_pdf = (!s.delta).then_some(s.pdf);
        p.from_normal = h.n;
        p.seg = g.spawn(&h, s.wi, s.transmitted, p.seg.medium);
        counts.bounce += 1;
        p.vertex += 1;
        queries
    }

    /// Answers a generation's shadow rays (`rays`, `point_light[i]` when ray `i` ends at
    /// a point light) into `occluded`. In a packet mode the camera vertex's rays toward
    /// point lights go as packets of the mode's width, in path order (neighbouring pixels,
    /// so nearly one direction); every other ray goes in one stream.
    #[inline(always)]
    fn shadows(
        &self,
        mode: Mode,
        camera_vertex: bool,
        rays: &[Ray],
        point_light: &[bool],
        occluded: &mut Vec<bool>,
        counts: &mut GiCounts,
    ) {
        let accel = self.scene.shader.accel;
        occluded.clear();
        occluded.resize(rays.len(), false);
        let packet = mode.group_mode();
        if !camera_vertex || packet == Mode::Scalar || !point_light.contains(&true) {
            occluded_unrelated(accel, mode, rays, occluded);
            return;
        }
        let (mut packed, mut loose) = (Vec::new(), Vec::new());
        for (i, &p) in point_light.iter().enumerate() {
            if p { &mut packed } else { &mut loose }.push(i);
        }
        for group in packed.chunks(packet.packet_size()) {
            counts.shadow_packets += 1;
            let group_rays: Vec<Ray> = group.iter().map(|&i| rays[i]).collect();
            let bits = occluded_rays(accel, packet, &group_rays);
            for (lane, &i) in group.iter().enumerate() {
                occluded[i] = bits & (1 << lane) != 0;
            }
        }
        let loose_rays: Vec<Ray> = loose.iter().map(|&i| rays[i]).collect();
        let mut answers = vec![false; loose_rays.len()];
        occluded_unrelated(accel, mode, &loose_rays, &mut answers);
        for (&i, a) in loose.iter().zip(answers) {
            occluded[i] = a;
        }
    }
}

impl Integrator for PathTracer<'_> {
    fn gi_scene(&self) -> &GiScene<'_> {
        &self.scene
    }

    /// The caustics the path tracer leaves out ([`GiScene::light_tracing`]), from one
    /// light path per [`SAMPLES_PER_LIGHT_PATH`] camera samples.
    fn light_image(
        &self,
        frame: &CameraFrame,
        spp: u32,
        seed: u64,
        mode: Mode,
        counts: &mut GiCounts,
    ) -> Option<Vec<Vec3>> {
        let samples = u64::from(spp) * u64::from(frame.width) * u64::from(frame.height);
        let paths = samples.div_ceil(SAMPLES_PER_LIGHT_PATH);
        if !self.scene.light_tracing {
            return None;
        }
        let c = caustics(&self.scene, frame, paths, seed, mode, counts);
        *self.caustics.write().unwrap_or_else(|e| e.into_inner()) = Arc::new(c.photons);
        Some(c.image)
    }

    fn radiance_traced(
        &self,
        ray: &Ray,
        first: Option<Hit>,
        sampler: &mut Sampler,
        counts: &mut GiCounts,
    ) -> Vec3 {
        let accel = self.scene.shader.accel;
        let mut p = Path::new(*ray);
        let mut hit = first;
        let caustics = self.caustic_photons();
        loop {
            let queries = self.advance(&mut p, hit, sampler, &caustics, counts);
            for (slot, q) in queries.iter().enumerate() {
                if let Some(q) = q {
                    p.resolve(slot, accel.occluded(&q.ray));
                }
            }
            if !p.alive {
                return p.l;
            }
            hit = accel.intersect(&p.seg.ray);
        }
    }

    /// Traces a batch of paths generation by generation (every live path's vertex,
    /// then the generation's shadow rays and bounce rays, each as one query), inside
    /// the instruction set's entry (`scalar_entry`): the vertex is scalar code, 6%
    /// faster on `spheres` in VEX form, and the same bits under every set.
    fn radiance_batch(
        &self,
        rays: &[Ray],
        first: &[Hit],
        samplers: &mut [Sampler],
        mode: Mode,
        counts: &mut GiCounts,
    ) -> Vec<Vec3> {
        scalar_entry(
            #[inline(always)]
            || {
                let accel = self.scene.shader.accel;
                let caustics = self.caustic_photons();
                let mut paths: Vec<Path> = rays.iter().map(|r| Path::new(*r)).collect();
                // Live paths and the closest hits of their current rays, in the same order.
                let mut live: Vec<usize> = (0..paths.len()).collect();
                let mut hits = first.to_vec();
                let mut camera_vertex = true;
                let shader = &self.scene.shader;
                let prefetch = shader.triangle_normals.len() >= PREFETCH_MIN_TRIANGLES;
                let draws: &[Draw] = if self.scene.lights.has_environment() {
                    &VERTEX_DRAWS_SKY
                } else {
                    &VERTEX_DRAWS
                };
                // The generation's shadow rays, the paths (and slots) they belong to and their
                // answers.
                let (mut owners, mut shadow_rays, mut point_light) =
                    (Vec::new(), Vec::new(), Vec::new());
                let mut occluded = Vec::new();
                let mut bounce_rays = Vec::new();
                while !live.is_empty() {
                    owners.clear();
                    shadow_rays.clear();
                    point_light.clear();
                    // The generation's random numbers in lanes, as the vertices will draw
                    // them.
                    draw_ahead(samplers, &live, draws);
                    for (k, (&i, h)) in live.iter().zip(&hits).enumerate() {
                        if prefetch {
                            if let Some(ahead) = hits.get(k + PREFETCH_AHEAD) {
                                shader.prefetch_surface(ahead);
                            }
                            if let Some(ahead) = hits.get(k + PREFETCH_AHEAD / 2) {
                                shader.prefetch_vertices(ahead);
                            }
                        }
                        let hit = h.is_hit().then_some(*h);
                        let queries =
                            self.advance(&mut paths[i], hit, &mut samplers[i], &caustics, counts);
                        for (slot, q) in queries.iter().enumerate() {
                            if let Some(q) = q {
                                owners.push((i, slot));
                                shadow_rays.push(q.ray);
                                point_light.push(q.point_light);
                            }
                        }
                    }
                    self.shadows(
                        mode,
                        camera_vertex,
                        &shadow_rays,
                        &point_light,
                        &mut occluded,
                        counts,
                    );
                    for (&(i, slot), &o) in owners.iter().zip(&occluded) {
                        paths[i].resolve(slot, o);
                    }
                    live.retain(|&i| paths[i].alive);
                    bounce_rays.clear();
                    bounce_rays.extend(live.iter().map(|&i| paths[i].seg.ray));
                    hits.clear();
                    hits.resize(bounce_rays.len(), Hit::MISS);
                    intersect_unrelated(accel, mode, &bounce_rays, &mut hits);
                    camera_vertex = false;
                }
                paths.iter().map(|p| p.l).collect()
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Who counts the emission a path reaches right after bounce `m - 1` of `bounces`
    /// (`true`: a delta bounce; bounce 0 is at the camera's first hit), by the shares'
    /// definitions rather than the state machine: light tracing takes emission reached
    /// through delta bounces after one or two smooth bounces from the first hit on, the
    /// caustic photons that reached through delta bounces after a smooth bounce from a
    /// surface a delta bounce led to, the path tracer the rest.
    fn owner(bounces: &[bool]) -> &'static str {
        let m = bounces.len();
        if m == 0 || !bounces[m - 1] {
            return "path";
        }
        let Some(j) = bounces.iter().rposition(|&delta| !delta) else {
            return "path";
        };
        if !bounces[..=j].contains(&true) && j < SMOOTH_VERTICES as usize {
            "light"
        } else if j > 0 && bounces[j - 1] {
            "photons"
        } else {
            "path"
        }
    }

    /// Every sequence of up to 9 bounces: the state machine leaves emission to the share
    /// that owns it, and reads the photons at exactly the surfaces a delta bounce led to,
    /// so each path is counted once; with the photons off it is light tracing's alone.
    #[test]
    fn each_path_has_one_owner() {
        for m in 0..=9usize {
            for bits in 0..1u32 << m {
                let bounces: Vec<bool> = (0..m).map(|i| bits >> i & 1 == 1).collect();
                for photons in [true, false] {
                    let mut c = Caustic::Smooth(0);
                    for (i, &delta) in bounces.iter().enumerate() {
                        let by_delta = i > 0 && bounces[i - 1];
                        assert_eq!(c.by_delta(), by_delta && c != Caustic::No, "{bounces:?}");
                        c = c.after(delta, photons);
                    }
                    let got = match c {
                        Caustic::Chain => "light",
                        Caustic::PhotonChain => "photons",
                        _ => "path",
                    };
                    let want = match owner(&bounces) {
                        "photons" if !photons => "path",
                        w => w,
                    };
                    assert_eq!(got, want, "{bounces:?}, photons {photons}");
                    if photons {
                        // The photons read at the surface reached by a delta bounce.
                        let reached_by_delta = m > 0 && bounces[m - 1];
                        assert_eq!(c.by_delta(), reached_by_delta, "{bounces:?}");
                    }
                }
            }
        }
    }
}
