//! render: the emitters of the global-illumination integrators, for next-event
//! estimation and photon emission.
//!
//! Emitters are the scene's triangles whose material has `emission` (one-sided,
//! Lambertian, toward the winding normal), its rectangular area lights (two-sided
//! Lambertian emitters of radiance `color`, invisible to rays, as in the Whitted tracer),
//! its point lights (intensity `color`, falling off with the squared distance) and,
//! a uniform environment of radiance `environment` seen by rays that leave the scene.
//! Light sampling picks an emitter with probability proportional to its power, then a
//! point uniformly on its area. The environment is sampled on its own, by a
//! cosine-weighted direction about the surface normal ([`Lights::sample_environment`]):
//! the path tracer takes one such sample at every vertex beside the emitter sample, and
//! the photon map shoots environment photons. Emissive spheres and planes shine on what
//! sees them but are never sampled.

use super::sample::{Onb, cosine_hemisphere};
use crate::scene::{Light, Scene};
use glam::Vec3;
use std::collections::HashMap;
use std::f32::consts::{FRAC_1_PI, PI};

/// A flat emitter: a triangle (one-sided, toward `normal`) or an area light's
/// parallelogram `corner + s edge_u + t edge_v` (two-sided).
#[derive(Clone, Debug)]
struct Patch {
    corner: Vec3,
    edge_u: Vec3,
    edge_v: Vec3,
    normal: Vec3,
    area: f32,
    radiance: Vec3,
    two_sided: bool,
}

impl Patch {
    /// The point at `(s, t)` in `[0, 1)^2`, uniform over the area (a triangle folds the
    /// far half of the square back onto itself).
    fn point(&self, mut s: f32, mut t: f32) -> Vec3 {
        if !self.two_sided && s + t > 1.0 {
            (s, t) = (1.0 - s, 1.0 - t);
        }
        self.corner + self.edge_u * s + self.edge_v * t
    }

    /// Cosine between the emitting side's normal and the direction `w` leaving it; not
    /// positive where nothing is emitted.
    fn cos_out(&self, w: Vec3) -> f32 {
        let c = w.dot(self.normal);
        if self.two_sided { c.abs() } else { c }
    }
}

#[derive(Clone, Debug)]
enum Emitter {
    Patch(Patch),
    Point { position: Vec3, intensity: Vec3 },
}

/// A light sample seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction toward the light.
    pub wi: Vec3,
    /// Distance to the sampled point.
    pub dist: f32,
    /// The sampled point (a point light's position).
    pub point: Vec3,
    /// Radiance arriving along `wi` (for a point light, `I / d^2`).
    pub li: Vec3,
    /// Solid-angle density of the sample, selection included (for a point light, the
    /// selection probability).
    pub pdf: f32,
    /// A point light: no other strategy can find it.
    pub delta: bool,
}

/// A photon leaving a light.
#[derive(Clone, Copy, Debug)]
pub struct Emitted {
    pub org: Vec3,
    pub dir: Vec3,
    /// Power carried when this is one of `n` photons: multiply by `1 / n`.
    pub power: Vec3,
}

/// Every emitter of a scene, with the sampling distributions over them.
#[derive(Clone, Debug)]
pub struct Lights {
    emitters: Vec<Emitter>,
    /// Cumulative selection probabilities of `emitters` (last is 1).
    cdf: Vec<f32>,
    /// Selection probability of each emitter.
    prob: Vec<f32>,
    /// Emitter index of each emissive triangle, by primitive id.
    by_prim: HashMap<u32, u32>,
    /// Radiance of rays that leave the scene.
    pub environment: Vec3,
    /// Sphere around the bounded geometry, for environment photons.
    centre: Vec3,
    radius: f32,
    /// Power of the emitters and of the environment, for photon emission.
    emitter_power: f32,
    environment_power: f32,
}

fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl Lights {
    pub fn new(scene: &Scene, environment: Vec3) -> Lights {
        let g = &scene.geometry;
        let mut emitters = Vec::new();
        let mut by_prim = HashMap::new();
        for tri in 0..g.triangles.len() as u32 {
            let radiance = scene.material(tri).emission;
            if radiance.max_element() <= 0.0 {
                continue;
            }
            let [a, b, c] = g.triangle(tri);
            let cross = (b - a).cross(c - a);
            let area = 0.5 * cross.length();
            if !(area > 0.0 && area.is_finite()) {
                continue;
            }
            by_prim.insert(tri, emitters.len() as u32);
            emitters.push(Emitter::Patch(Patch {
                corner: a,
                edge_u: b - a,
                edge_v: c - a,
                normal: cross.normalize(),
                area,
                radiance,
                two_sided: false,
            }));
        }
        for light in &scene.lights {
            match *light {
                Light::Point { position, color } => emitters.push(Emitter::Point {
                    position,
                    intensity: color,
                }),
                Light::Area {
                    corner,
                    edge_u,
                    edge_v,
                    color,
                    ..
                }
                | Light::Triangle {
                    corner,
                    edge_u,
                    edge_v,
                    color,
                    ..
                } => {
                    let two_sided = matches!(light, Light::Area { .. });
                    let cross = edge_u.cross(edge_v);
                    let length = cross.length();
                    let area = if two_sided { length } else { 0.5 * length };
                    if area > 0.0 && area.is_finite() {
                        emitters.push(Emitter::Patch(Patch {
                            corner,
                            edge_u,
                            edge_v,
                            normal: cross / length,
                            area,
                            radiance: color,
                            two_sided,
                        }));
                    }
                }
            }
        }
        let power: Vec<f32> = emitters.iter().map(Emitter::power).collect();
        let total: f32 = power.iter().sum();
        let prob: Vec<f32> = power
            .iter()
            .map(|&p| if total > 0.0 { p / total } else { 0.0 })
            .collect();
        let mut acc = 0.0;
        let mut cdf: Vec<f32> = prob
            .iter()
            .map(|&p| {
                acc += p;
                acc
            })
            .collect();
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        let bounds = g.bounds();
        let (centre, radius) = if bounds.is_empty() {
            (Vec3::ZERO, 1.0)
        } else {
            (
                (bounds.min + bounds.max) * 0.5,
                (0.5 * bounds.diagonal()).max(f32::MIN_POSITIVE),
            )
        };
        let environment_power = 4.0 * PI * PI * radius * radius * mean(environment);
        Lights {
            emitters,
            cdf,
            prob,
            by_prim,
            environment,
            centre,
            radius,
            emitter_power: total,
            environment_power,
        }
    }

    /// True when rays that leave the scene bring light: the path tracer then samples the
    /// environment at each vertex ([`Lights::sample_environment`]).
    #[inline(always)]
    pub fn has_environment(&self) -> bool {
        self.environment.max_element() > 0.0
    }

    /// A direction toward the environment from a surface of normal `n` (unit, on the
    /// side the light arrives), cosine-weighted about `n` from a 2D point: the ideal
    /// density for a uniform sky over a Lambertian surface. Returns the direction and its
    /// density ([`Lights::environment_pdf`]).
    #[inline(always)]
    pub fn sample_environment(&self, n: Vec3, (u1, u2): (f32, f32)) -> (Vec3, f32) {
        let wi = Onb::from_w(n)
            .to_world(cosine_hemisphere(u1, u2))
            .normalize();
        (wi, self.environment_pdf(n, wi))
    }

    /// The solid-angle density with which [`Lights::sample_environment`] from a surface
    /// of normal `n` picks `wi`.
    #[inline(always)]
    pub fn environment_pdf(&self, n: Vec3, wi: Vec3) -> f32 {
        wi.dot(n).max(0.0) * FRAC_1_PI
    }

    /// True when next-event estimation has nothing to sample.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty() || self.emitter_power <= 0.0
    }

    /// The emitter picked by uniform `u`.
    #[inline(always)]
    fn pick(&self, u: f32) -> usize {
        self.cdf
            .partition_point(|&c| c <= u)
            .min(self.emitters.len() - 1)
    }

    /// A light sample seen from `p` (three uniforms). `None` when there is no emitter or
    /// the sampled point emits nothing toward `p`.
    #[inline(always)]
    pub fn sample(&self, p: Vec3, u: [f32; 3]) -> Option<LightSample> {
        if self.is_empty() {
            return None;
        }
        let i = self.pick(u[0]);
        let select = self.prob[i];
        if select <= 0.0 {
            return None;
        }
        match self.emitters[i] {
            Emitter::Point {
                position,
                intensity,
            } => {
                let d = position - p;
                let dist = d.length();
                if !(dist > 0.0) {
                    return None;
                }
                Some(LightSample {
                    wi: d / dist,
                    dist,
                    point: position,
                    li: intensity / (dist * dist),
                    pdf: select,
                    delta: true,
                })
            }
            Emitter::Patch(ref e) => {
                let q = e.point(u[1], u[2]);
                let d = q - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                if !(dist > 0.0) {
                    return None;
                }
                let wi = d / dist;
                let cos_l = e.cos_out(-wi);
                if cos_l <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    dist,
                    point: q,
                    li: e.radiance,
                    pdf: select * dist2 / (cos_l * e.area),
                    delta: false,
                })
            }
        }
    }

    /// The density with which [`Lights::sample`] from `p` picks the point `q` on
    /// primitive `prim`, in solid angle; 0 when `prim` is not a sampled emitter.
    #[inline(always)]
    pub fn pdf(&self, prim: u32, p: Vec3, q: Vec3) -> f32 {
        let Some(&i) = self.by_prim.get(&prim) else {
            return 0.0;
        };
        let Emitter::Patch(ref e) = self.emitters[i as usize] else {
            return 0.0;
        };
        let d = q - p;
        let dist2 = d.length_squared();
        let cos_l = e.cos_out(-d / dist2.sqrt());
        if !(cos_l > 0.0) {
            return 0.0;
        }
        self.prob[i as usize] * dist2 / (cos_l * e.area)
    }

    /// Total power of the emitters and the environment: zero means no photon carries
    /// anything.
    pub fn photon_power(&self) -> f32 {
        self.emitter_power + self.environment_power
    }

    /// A photon's origin, direction and power times the photon count (five uniforms).
    /// Emitters and the environment are picked in proportion to their power, then a
    /// point uniformly on the emitter and a cosine-weighted direction (uniform for a
    /// point light); an environment photon enters along a uniform direction through a
    /// disc as wide as the scene's bounding sphere.
    pub fn emit(&self, u: [f32; 5]) -> Option<Emitted> {
        let total = self.photon_power();
        if total <= 0.0 {
            return None;
        }
        let p_env = self.environment_power / total;
        if u[0] < p_env || self.is_empty() {
            // Toward the scene along `dir`, through a disc facing it.
            let dir = -uniform_sphere(u[1], u[2]);
            let basis = Onb::from_w(dir);
            let r = self.radius * u[3].sqrt();
            let phi = 2.0 * PI * u[4];
            let org = self.centre - dir * self.radius
                + basis.u * (r * phi.cos())
                + basis.v * (r * phi.sin());
            let power = self.environment * (4.0 * PI * PI * self.radius * self.radius) / p_env;
            return Some(Emitted { org, dir, power });
        }
        // Reuse u[0] inside the emitters' share.
        let v = ((u[0] - p_env) / (1.0 - p_env)).clamp(0.0, 1.0 - f32::EPSILON);
        self.emit_from_emitter(v, 1.0 - p_env, [u[1], u[2], u[3], u[4]])
    }

    /// A light path's start from the emitters alone, the environment left out (five
    /// uniforms): as [`Lights::emit`] picks an emitter, a point and a direction. `None`
    /// when there is no emitter.
    pub fn emit_from_emitters(&self, u: [f32; 5]) -> Option<Emitted> {
        if self.is_empty() {
            return None;
        }
        self.emit_from_emitter(u[0], 1.0, [u[1], u[2], u[3], u[4]])
    }

    /// True when light sampling picks points on primitive `prim` (an emissive
    /// triangle), so light tracing starts paths there too.
    pub fn is_sampled(&self, prim: u32) -> bool {
        self.by_prim.contains_key(&prim)
    }

    /// The emitter picked by `v`, of which the emitters' share of all emission is
    /// `share`, and a point and a direction from `u`.
    fn emit_from_emitter(&self, v: f32, share: f32, u: [f32; 4]) -> Option<Emitted> {
        let i = self.pick(v);
        let select = self.prob[i] * share;
        if select <= 0.0 {
            return None;
        }
        match self.emitters[i] {
            Emitter::Point {
                position,
                intensity,
            } => Some(Emitted {
                org: position,
                dir: uniform_sphere(u[0], u[1]),
                power: intensity * (4.0 * PI) / select,
            }),
            Emitter::Patch(ref e) => {
                let (mut s, mut normal, mut sides) = (u[0], e.normal, 1.0);
                if e.two_sided {
                    // The first uniform picks a side and is reused along the patch.
                    sides = 2.0;
                    if s < 0.5 {
                        s *= 2.0;
                    } else {
                        s = 2.0 * s - 1.0;
                        normal = -normal;
                    }
                }
                let org = e.point(s, u[1]);
                let local = cosine_hemisphere(u[2], u[3]);
                let dir = Onb::from_w(normal).to_world(local).normalize();
                Some(Emitted {
                    org,
                    dir,
                    power: e.radiance * (PI * e.area * sides) / select,
                })
            }
        }
    }
}

impl Emitter {
    fn power(&self) -> f32 {
        match *self {
            Emitter::Patch(ref e) => {
                let sides = if e.two_sided { 2.0 } else { 1.0 };
                sides * PI * e.area * mean(e.radiance)
            }
            Emitter::Point { intensity, .. } => 4.0 * PI * mean(intensity),
        }
    }
}

/// A uniform direction on the unit sphere.
fn uniform_sphere(u1: f32, u2: f32) -> Vec3 {
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}
