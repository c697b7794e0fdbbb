//! render: unidirectional path tracing with next-event estimation.
//!
//! At every vertex with a non-delta lobe one light sample is taken ([`GiScene::direct`])
//! and the path continues by sampling the BSDF ([`super::bsdf`]). Emission found by a
//! BSDF sample is weighted against the light-sampling density by the power heuristic
//! (Veach 1997), so each light path is counted once in expectation; emission seen by the
//! camera, after a delta bounce, or from an emitter light sampling never picks (spheres,
//! planes, the environment) counts in full. Russian roulette ends paths from the fourth
//! vertex on ([`super::gi::survives`]); `max_bounces` optionally caps the scattering
//! events, counting both kinds of paths alike (light sampling at vertex `k` makes a path
//! of `k + 1` bounces).
//!
//! Random numbers per vertex, in order: three for the light sample, three for the BSDF
//! sample, one for Russian roulette.

use super::gi::{GiCounts, GiScene, Integrator, Segment, survives};
use super::sample::Pcg32;
use crate::ray::{Hit, Ray};
use glam::Vec3;

/// The path tracer over a prepared scene.
pub struct PathTracer<'a> {
    pub scene: GiScene<'a>,
}

impl Integrator for PathTracer<'_> {
    fn gi_scene(&self) -> &GiScene<'_> {
        &self.scene
    }

    fn radiance_traced(
        &self,
        ray: &Ray,
        first: Option<Hit>,
        rng: &mut Pcg32,
        counts: &mut GiCounts,
    ) -> Vec3 {
        let g = &self.scene;
        let mut seg = Segment::new(*ray);
        let mut beta = Vec3::ONE;
        let mut l = Vec3::ZERO;
        // Density of the BSDF sample that made the current ray; `None` for the camera ray
        // and after a delta lobe (emission then counts in full).
        let mut bsdf_pdf: Option<f32> = None;
        let mut vertex = 0u32;
        let mut first = Some(first);
        loop {
            let Some(h) = g.trace_known(&seg, first.take(), &mut beta) else {
                l += beta * g.lights.environment;
                break;
            };
            let le = g.emitted(&h);
            if le != Vec3::ZERO {
                let w = match bsdf_pdf {
                    Some(pdf) => {
                        let light_pdf = g.lights.pdf(h.hit.prim, seg.ray.org, h.p);
                        super::bsdf::power_heuristic(pdf, light_pdf)
                    }
                    None => 1.0,
                };
                l += beta * le * w;
            }
            if g.max_bounces.is_some_and(|m| vertex >= m) {
                break;
            }
            let wo = -seg.ray.dir;
            l += beta * g.direct(&h, wo, rng, true, counts);
            let Some(s) = h.bsdf.sample(wo, rng) else {
                break;
            };
            beta *= s.weight;
            if !survives(vertex, &mut beta, rng) {
                break;
            }
            bsdf_pdf = (!s.delta).then_some(s.pdf);
            seg = g.spawn(&h, s.wi, s.transmitted, seg.medium);
            counts.bounce += 1;
            vertex += 1;
        }
        l
    }
}
