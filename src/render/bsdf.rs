//! render: the physically based materials of the global-illumination integrators
//! ([`super::path`], [`super::photon`]), mapped from the Whitted [`Material`].
//!
//! A material becomes a mixture of up to five lobes (scenes/README.md documents the rule):
//! - Lambertian: reflectance `diffuse * albedo`, `f = kd / pi`;
//! - a normalised Phong lobe for `specular` (white, exponent `shininess`):
//!   `f = ks (e + 2) / (2 pi) cos^e(alpha)`, `alpha` the angle between the incoming
//!   direction and the mirror direction of the outgoing one (Lafortune and Willems 1994);
//!   its reflectance at normal incidence is exactly `ks` and never more elsewhere;
//! - glossy reflection (`reflection` with `glossiness > 0`): a second Phong lobe of weight
//!   `reflection * albedo` and exponent `2 / glossiness^2`, whose lobe has about the
//!   Whitted cone's half-angle;
//! - ideal mirror (`reflection` with `glossiness = 0`): weight `reflection * albedo`;
//! - dielectric (`refraction`): reflects with the exact unpolarised Fresnel factor of
//!   `ior`, transmits the rest (total internal reflection past the critical angle); Beer's
//!   law inside is the Whitted tracer's ([`super::shade::absorption_coefficient`]).
//!
//! When the weights' largest channel sums to more than 1 they are scaled down together,
//! so no surface reflects more than it receives. All lobes use the geometric normal
//! (the benchmark meshes have none of their own; interpolated normals would break the
//! symmetry the closed-form tests rely on). Radiance is not scaled by the squared ratio
//! of refractive indices on transmission: what enters a closed glass object leaves it
//! unchanged, in the path tracer and in the photon tracer alike.
//!
//! Sampling picks a lobe with probability proportional to its mean weight. A non-delta
//! direction is weighted by the whole non-delta mixture (`f / sum_j p_j pdf_j`, the
//! one-sample balance heuristic over lobes); a delta lobe's by its weight over its
//! probability.

use super::sample::{Onb, cosine_hemisphere};
use super::shade::{absorption_coefficient, reflect, refract};
use crate::scene::Material;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

/// Lobes: Lambertian, Phong (specular), Phong (glossy), mirror, dielectric.
const LOBES: usize = 5;
const DIFFUSE: usize = 0;
const MIRROR: usize = 3;
const GLASS: usize = 4;

/// The scattering function at one hit point, in world space.
#[derive(Clone, Debug)]
pub struct Bsdf {
    /// Geometric normal on the side the ray came from.
    pub n: Vec3,
    /// True when the ray arrived on the side the normal points to (entering a solid).
    pub entering: bool,
    /// Weight of each lobe (after the energy scaling).
    weight: [Vec3; LOBES],
    /// Phong exponents of lobes 1 and 2.
    exponent: [f32; 2],
    ior: f32,
    /// Beer's law coefficient of the material's inside.
    pub absorption: Vec3,
    /// Probability of picking each lobe; sums to 1 unless the material is black.
    prob: [f32; LOBES],
}

/// A sampled incoming direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// `f cos / pdf`, or a delta lobe's weight over its probability.
    pub weight: Vec3,
    /// Solid-angle density of the non-delta mixture at `wi`; 0 for a delta lobe.
    pub pdf: f32,
    pub delta: bool,
    /// The direction goes through the surface (dielectric transmission).
    pub transmitted: bool,
}

/// The exact Fresnel reflectance of unpolarised light at a dielectric interface, for the
/// cosine `cos_i` of the angle of incidence and `eta = n_from / n_to`; 1 past the
/// critical angle.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl Bsdf {
    /// The mixture for `material` with (textured) `albedo` at a surface whose geometric
    /// normal facing the ray is `n`; `entering` is false when the ray hit the back.
    pub fn new(material: &Material, albedo: Vec3, n: Vec3, entering: bool) -> Bsdf {
        let m = material;
        let clamp = |x: f32| x.max(0.0);
        let glossy = m.glossiness > 0.0;
        let reflection = albedo * clamp(m.reflection);
        let mut weight = [
            albedo * clamp(m.diffuse),
            Vec3::splat(clamp(m.specular)),
            if glossy { reflection } else { Vec3::ZERO },
            if glossy { Vec3::ZERO } else { reflection },
            Vec3::splat(clamp(m.refraction)),
        ];
        let total = weight.iter().fold(Vec3::ZERO, |a, &w| a + w).max_element();
        if total > 1.0 {
            for w in &mut weight {
                *w /= total;
            }
        }
        let means = weight.map(mean);
        let sum: f32 = means.iter().sum();
        let prob = if sum > 0.0 {
            means.map(|x| x / sum)
        } else {
            [0.0; LOBES]
        };
        let glossy_exponent = if glossy {
            2.0 / (m.glossiness * m.glossiness)
        } else {
            0.0
        };
        Bsdf {
            n,
            entering,
            weight,
            exponent: [clamp(m.shininess), glossy_exponent],
            ior: m.ior,
            absorption: absorption_coefficient(m),
            prob,
        }
    }

    /// Reflectance of the Lambertian lobe: what the photon map's estimates are scaled by.
    pub fn diffuse(&self) -> Vec3 {
        self.weight[DIFFUSE]
    }

    /// True when some lobe is not a delta: light sampling and photon estimates apply.
    pub fn has_smooth(&self) -> bool {
        self.prob[..MIRROR].iter().any(|&p| p > 0.0)
    }

    /// True when the mirror or the dielectric lobe is present.
    pub fn has_delta(&self) -> bool {
        self.prob[MIRROR] > 0.0 || self.prob[GLASS] > 0.0
    }

    /// `f(wo, wi)` of the non-delta lobes (`wo` points away from the surface, toward
    /// where the ray came from; `wi` toward the light).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let cos_i = wi.dot(self.n);
        if cos_i <= 0.0 {
            return Vec3::ZERO;
        }
        let mut f = self.weight[DIFFUSE] * FRAC_1_PI;
        let r = reflect(-wo, self.n);
        for (j, &e) in self.exponent.iter().enumerate() {
            let w = self.weight[1 + j];
            if w != Vec3::ZERO {
                let c = r.dot(wi).max(0.0);
                f += w * ((e + 2.0) / TAU * c.powf(e));
            }
        }
        f
    }

    /// Solid-angle density with which [`Bsdf::sample`] picks `wi` by a non-delta lobe.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let cos_i = wi.dot(self.n);
        let mut pdf = 0.0;
        if self.prob[DIFFUSE] > 0.0 && cos_i > 0.0 {
            pdf += self.prob[DIFFUSE] * cos_i * FRAC_1_PI;
        }
        let r = reflect(-wo, self.n);
        for (j, &e) in self.exponent.iter().enumerate() {
            let p = self.prob[1 + j];
            if p > 0.0 {
                let c = r.dot(wi).max(0.0);
                pdf += p * (e + 1.0) / TAU * c.powf(e);
            }
        }
        pdf
    }

    /// Draws a direction from three uniforms: `u[0]` picks the lobe, `u[1..]` the
    /// direction ([`super::sample::Sampler::next_choice_2d`]). `None`: the path is
    /// absorbed (a black material, or a Phong direction below the surface).
    pub fn sample(&self, wo: Vec3, [u0, u1, u2]: [f32; 3]) -> Option<BsdfSample> {
        let mut acc = 0.0;
        let mut lobe = LOBES;
        for (j, &p) in self.prob.iter().enumerate() {
            acc += p;
            if p > 0.0 && u0 < acc {
                lobe = j;
                break;
            }
        }
        if lobe == LOBES {
            // Rounding left u0 above the last sum: take the last lobe present.
            lobe = self.prob.iter().rposition(|&p| p > 0.0)?;
        }
        self.sample_lobe(lobe, wo, u1, u2, self.prob[lobe])
    }

    /// Like [`Bsdf::sample`], restricted to the non-delta lobes (the photon map's final
    /// gather). `None` also when there is no such lobe.
    pub fn sample_smooth(&self, wo: Vec3, [u0, u1, u2]: [f32; 3]) -> Option<BsdfSample> {
        let total: f32 = self.prob[..MIRROR].iter().sum();
        if total <= 0.0 {
            return None;
        }
        let mut acc = 0.0;
        let mut lobe = MIRROR;
        for (j, &p) in self.prob[..MIRROR].iter().enumerate() {
            acc += p / total;
            if p > 0.0 && u0 < acc {
                lobe = j;
                break;
            }
        }
        if lobe == MIRROR {
            lobe = self.prob[..MIRROR].iter().rposition(|&p| p > 0.0)?;
        }
        let s = self.sample_lobe(lobe, wo, u1, u2, self.prob[lobe])?;
        // The mixture was renormalised to the smooth lobes: so is its density.
        Some(BsdfSample {
            weight: s.weight * total,
            pdf: s.pdf / total,
            ..s
        })
    }

    /// Like [`Bsdf::sample`], restricted to the delta lobes (mirror and dielectric).
    pub fn sample_delta(&self, wo: Vec3, [u0, u1, u2]: [f32; 3]) -> Option<BsdfSample> {
        let (pm, pg) = (self.prob[MIRROR], self.prob[GLASS]);
        let total = pm + pg;
        if total <= 0.0 {
            return None;
        }
        let lobe = if pg == 0.0 || (pm > 0.0 && u0 * total < pm) {
            MIRROR
        } else {
            GLASS
        };
        self.sample_lobe(lobe, wo, u1, u2, self.prob[lobe] / total)
    }

    /// Samples lobe `lobe`, picked with probability `p`.
    fn sample_lobe(&self, lobe: usize, wo: Vec3, u1: f32, u2: f32, p: f32) -> Option<BsdfSample> {
        let n = self.n;
        match lobe {
            MIRROR => Some(BsdfSample {
                wi: reflect(-wo, n),
                weight: self.weight[MIRROR] / p,
                pdf: 0.0,
                delta: true,
                transmitted: false,
            }),
            GLASS => {
                let eta = if self.entering {
                    1.0 / self.ior
                } else {
                    self.ior
                };
                let f = fresnel_dielectric(wo.dot(n), eta);
                let transmitted = u1 >= f;
                let wi = if transmitted {
                    refract(-wo, n, eta)?
                } else {
                    reflect(-wo, n)
                };
                Some(BsdfSample {
                    wi,
                    weight: self.weight[GLASS] / p,
                    pdf: 0.0,
                    delta: true,
                    transmitted,
                })
            }
            _ => {
                let local = if lobe == DIFFUSE {
                    cosine_hemisphere(u1, u2)
                } else {
                    let e = self.exponent[lobe - 1];
                    let c = u1.powf(1.0 / (e + 1.0));
                    let s = (1.0 - c * c).max(0.0).sqrt();
                    let phi = TAU * u2;
                    Vec3::new(s * phi.cos(), s * phi.sin(), c)
                };
                let axis = if lobe == DIFFUSE { n } else { reflect(-wo, n) };
                let wi = Onb::from_w(axis).to_world(local).normalize();
                let cos_i = wi.dot(n);
                if cos_i <= 0.0 {
                    return None;
                }
                let pdf = self.pdf(wo, wi);
                if pdf <= 0.0 {
                    return None;
                }
                Some(BsdfSample {
                    wi,
                    weight: self.eval(wo, wi) * (cos_i / pdf),
                    pdf,
                    delta: false,
                    transmitted: false,
                })
            }
        }
    }
}

/// The power heuristic (beta = 2) weight of a sample drawn with density `a` against an
/// alternative strategy of density `b` (Veach 1997).
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn material(diffuse: f32, specular: f32, reflection: f32, glossiness: f32) -> Material {
        Material {
            color: Vec3::new(0.9, 0.6, 0.3),
            diffuse,
            specular,
            shininess: 12.0,
            reflection,
            glossiness,
            ..Material::default()
        }
    }

    fn uniforms(rng: &mut Pcg32) -> [f32; 3] {
        [rng.next_f32(), rng.next_f32(), rng.next_f32()]
    }

    /// The directional albedo `E[weight]` of a BSDF never exceeds 1 in any channel: a
    /// bounce never adds energy. 200,000 samples per direction; the mean's standard error
    /// is measured and the bound is checked 4 of them above 1.
    #[test]
    fn albedo_never_exceeds_one() {
        let mut rng = Pcg32::new(11, 12);
        let n = Vec3::Y;
        let cases = [
            material(1.0, 0.0, 0.0, 0.0),
            material(1.0, 1.0, 0.0, 0.0),
            material(0.7, 0.5, 0.6, 0.2),
            material(0.0, 1.0, 0.0, 0.0),
            material(0.5, 0.0, 1.0, 0.0),
        ];
        for (i, m) in cases.iter().enumerate() {
            let bsdf = Bsdf::new(m, m.color, n, true);
            for theta in [0.0f32, 0.5, 1.0, 1.4] {
                let wo = Vec3::new(theta.sin(), theta.cos(), 0.0);
                let count = 200_000;
                let (mut sum, mut sum2) = (Vec3::ZERO, Vec3::ZERO);
                for _ in 0..count {
                    if let Some(s) = bsdf.sample(wo, uniforms(&mut rng)) {
                        sum += s.weight;
                        sum2 += s.weight * s.weight;
                    }
                }
                let mean = sum / count as f32;
                let var = sum2 / count as f32 - mean * mean;
                let se = (var / count as f32).max(Vec3::ZERO).powf(0.5);
                for c in 0..3 {
                    assert!(
                        mean[c] <= 1.0 + 4.0 * se[c] + 1e-6,
                        "case {i} theta {theta}: albedo {} (standard error {})",
                        mean[c],
                        se[c]
                    );
                }
            }
        }
    }

    /// For the smooth lobes, the sample weight is `f cos / pdf` with `pdf` and `f` from
    /// `pdf` and `eval`: the estimator MIS relies on.
    #[test]
    fn sample_weight_matches_eval_over_pdf() {
        let mut rng = Pcg32::new(3, 4);
        let m = material(0.6, 0.3, 0.0, 0.0);
        let bsdf = Bsdf::new(&m, m.color, Vec3::Z, true);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        for _ in 0..1000 {
            if let Some(s) = bsdf.sample(wo, uniforms(&mut rng)) {
                let expect = bsdf.eval(wo, s.wi) * s.wi.dot(Vec3::Z) / bsdf.pdf(wo, s.wi);
                assert!((s.weight - expect).abs().max_element() < 1e-4);
                assert_eq!(s.pdf, bsdf.pdf(wo, s.wi));
            }
        }
    }

    #[test]
    fn fresnel_matches_known_values() {
        // Normal incidence: ((n - 1) / (n + 1))^2 = 0.04 for n = 1.5, from either side.
        assert!((fresnel_dielectric(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything; past the critical angle too.
        assert!((fresnel_dielectric(0.0, 1.0 / 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(fresnel_dielectric(0.5, 1.5), 1.0);
        // Brewster's angle: the p-polarised part vanishes, F = rs^2 / 2.
        let theta_b = 1.5f32.atan();
        let f = fresnel_dielectric(theta_b.cos(), 1.0 / 1.5);
        let theta_t = std::f32::consts::FRAC_PI_2 - theta_b;
        let rs = (theta_b - theta_t).sin() / (theta_b + theta_t).sin();
        assert!((f - 0.5 * rs * rs).abs() < 1e-6, "{f}");
    }
}
