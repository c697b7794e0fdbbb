//! render: the physically based materials of the global-illumination integrators
//! ([`super::path`], [`super::photon`]), mapped from the Whitted [`Material`].
//!
//! A material becomes a mixture of up to five lobes (scenes/README.md documents the rule):
//! - Lambertian: reflectance `diffuse * albedo`, `f = kd / pi`;
//! - a normalised Phong lobe for `specular` (white, exponent `shininess`):
//!   `f = ks (e + 2) / (2 pi) cos^e(alpha)`, `alpha` the angle between the incoming
//!   direction and the mirror direction of the outgoing one (Lafortune and Willems 1994);
//!   its reflectance at normal incidence is exactly `ks` and never more elsewhere;
//! - glossy reflection (`reflection` with `glossiness > 0`): a rough perfect conductor
//!   (Fresnel factor 1) of weight `reflection * albedo`, Walter et al.'s GGX microfacet
//!   model (2007) with Smith's separable shadowing-masking, `f = D G1(wi) G1(wo) /
//!   (4 cos_i cos_o)`, as Mitsuba 3's `roughconductor` (material `none`) evaluates it,
//!   so the two renderers can be compared on the same scene. Its roughness is
//!   `alpha = g / sqrt(1 + g^2)` for `g = glossiness`: Walter's match of a Phong exponent
//!   `2 / g^2` (about the Whitted cone's half-angle) to a microfacet roughness. Directions
//!   are drawn from the visible normals (Heitz 2018), so a sample's weight is
//!   `G1(wi)` times the lobe's weight when the lobe is alone;
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

/// Lobes: Lambertian, Phong (specular), GGX (glossy), mirror, dielectric.
const LOBES: usize = 5;
const DIFFUSE: usize = 0;
const PHONG: usize = 1;
const GLOSSY: usize = 2;
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
    /// Phong exponent of the specular lobe.
    exponent: f32,
    /// GGX roughness of the glossy lobe.
    alpha: f32,
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
    /// The factor by which a light path (light tracing, photons) that sampled `s` here
    /// scales its power: `(n_from / n_to)^2` along the light's travel through a
    /// refraction, 1 otherwise. The path tracer leaves radiance unscaled on transmission
    /// (the module's doc), and the adjoint of that transport scales power by the squared
    /// ratio, so both ends agree where an emitter or the camera sits inside glass;
    /// across a closed object, entered and left, the factors cancel.
    #[inline(always)]
    pub fn adjoint_scale(&self, s: &BsdfSample) -> f32 {
        if !s.transmitted {
            return 1.0;
        }
        // The light arrives from the side `entering` refers to.
        let eta = if self.entering {
            1.0 / self.ior
        } else {
            self.ior
        };
        eta * eta
    }

    /// The mixture for `material` with (textured) `albedo` at a surface whose geometric
    /// normal facing the ray is `n`; `entering` is false when the ray hit the back.
    #[inline(always)]
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
        let g = m.glossiness;
        Bsdf {
            n,
            entering,
            weight,
            exponent: clamp(m.shininess),
            alpha: if glossy {
                g / (1.0 + g * g).sqrt()
            } else {
                0.0
            },
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
    #[inline(always)]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let cos_i = wi.dot(self.n);
        if cos_i <= 0.0 {
            return Vec3::ZERO;
        }
        let mut f = self.weight[DIFFUSE] * FRAC_1_PI;
        if self.weight[PHONG] != Vec3::ZERO {
            let (e, c) = (self.exponent, reflect(-wo, self.n).dot(wi).max(0.0));
            f += self.weight[PHONG] * ((e + 2.0) / TAU * c.powf(e));
        }
        if self.weight[GLOSSY] != Vec3::ZERO {
            f += self.weight[GLOSSY] * self.ggx().eval(wo, wi, self.n);
        }
        f
    }

    /// The glossy lobe's microfacet distribution.
    #[inline(always)]
    fn ggx(&self) -> Ggx {
        Ggx { alpha: self.alpha }
    }

    /// Solid-angle density with which [`Bsdf::sample`] picks `wi` by a non-delta lobe.
    #[inline(always)]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let cos_i = wi.dot(self.n);
        let mut pdf = 0.0;
        if self.prob[DIFFUSE] > 0.0 && cos_i > 0.0 {
            pdf += self.prob[DIFFUSE] * cos_i * FRAC_1_PI;
        }
        if self.prob[PHONG] > 0.0 {
            let (e, c) = (self.exponent, reflect(-wo, self.n).dot(wi).max(0.0));
            pdf += self.prob[PHONG] * (e + 1.0) / TAU * c.powf(e);
        }
        if self.prob[GLOSSY] > 0.0 {
            pdf += self.prob[GLOSSY] * self.ggx().pdf(wo, wi, self.n);
        }
        pdf
    }

    /// Draws a direction from three uniforms: `u[0]` picks the lobe, `u[1..]` the
    /// direction ([`super::sample::Sampler::next_choice_2d`]). `None`: the path is
    /// absorbed (a black material, or a Phong or GGX direction below the surface).
    #[inline(always)]
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
    #[inline(always)]
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
                let wi = match lobe {
                    DIFFUSE => Onb::from_w(n).to_world(cosine_hemisphere(u1, u2)),
                    PHONG => {
                        let e = self.exponent;
                        let c = u1.powf(1.0 / (e + 1.0));
                        let s = (1.0 - c * c).max(0.0).sqrt();
                        let phi = TAU * u2;
                        let local = Vec3::new(s * phi.cos(), s * phi.sin(), c);
                        Onb::from_w(reflect(-wo, n)).to_world(local)
                    }
                    _ => self.ggx().sample(wo, n, u1, u2),
                }
                .normalize();
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

/// Walter et al.'s GGX distribution of microfacet normals (2007), isotropic, with the
/// separable Smith shadowing-masking term; directions in world space about the normal
/// `n`, `wo` and `wi` pointing away from the surface.
#[derive(Clone, Copy, Debug)]
struct Ggx {
    alpha: f32,
}

impl Ggx {
    /// Density of microfacet normals `m` per projected area: `D(m)`.
    fn d(self, cos_m: f32) -> f32 {
        if cos_m <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let c2 = cos_m * cos_m;
        let t = c2 * (a2 - 1.0) + 1.0;
        a2 * FRAC_1_PI / (t * t)
    }

    /// Smith's masking of direction `w` (cosine `cos_w` to the normal) by facets of
    /// normal `m`; 0 when `w` sees `m`'s back.
    fn g1(self, w: Vec3, m: Vec3, cos_w: f32) -> f32 {
        if w.dot(m) * cos_w <= 0.0 {
            return 0.0;
        }
        let c2 = cos_w * cos_w;
        let tan2 = ((1.0 - c2) / c2).max(0.0);
        2.0 / (1.0 + (1.0 + self.alpha * self.alpha * tan2).sqrt())
    }

    /// The half vector of a reflection, or `None` when it is undefined or either
    /// direction lies below the surface.
    fn half(wo: Vec3, wi: Vec3, n: Vec3) -> Option<(Vec3, f32, f32)> {
        let (cos_o, cos_i) = (wo.dot(n), wi.dot(n));
        if cos_o <= 0.0 || cos_i <= 0.0 {
            return None;
        }
        let h = (wo + wi).normalize_or_zero();
        (h != Vec3::ZERO).then_some((h, cos_o, cos_i))
    }

    /// `f(wo, wi)` of a perfect conductor: `D G1(wi) G1(wo) / (4 cos_i cos_o)`.
    fn eval(self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some((h, cos_o, cos_i)) = Ggx::half(wo, wi, n) else {
            return 0.0;
        };
        let g = self.g1(wi, h, cos_i) * self.g1(wo, h, cos_o);
        self.d(h.dot(n)) * g / (4.0 * cos_i * cos_o)
    }

    /// Solid-angle density of [`Ggx::sample`] at `wi`: the visible normals' density
    /// `G1(wo) D(m) (wo.m) / cos_o` times the reflection's Jacobian `1 / (4 wo.m)`.
    fn pdf(self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some((h, cos_o, _)) = Ggx::half(wo, wi, n) else {
            return 0.0;
        };
        self.g1(wo, h, cos_o) * self.d(h.dot(n)) / (4.0 * cos_o)
    }

    /// A reflected direction about a normal drawn from the normals `wo` sees (Heitz 2018,
    /// "Sampling the GGX Distribution of Visible Normals", listing 1); it may point below
    /// the surface, which the caller rejects.
    fn sample(self, wo: Vec3, n: Vec3, u1: f32, u2: f32) -> Vec3 {
        let frame = Onb::from_w(n);
        let a = self.alpha;
        let v = Vec3::new(wo.dot(frame.u), wo.dot(frame.v), wo.dot(n));
        // The view direction in the frame where the facets are a hemisphere.
        let vh = Vec3::new(a * v.x, a * v.y, v.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        let r = u1.sqrt();
        let phi = TAU * u2;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let m = Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize();
        let m = frame.to_world(m);
        reflect(-wo, m)
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
    use crate::rng::{Pcg32, SplitMix64};

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
        for m in [material(0.6, 0.3, 0.0, 0.0), material(0.3, 0.2, 0.5, 0.3)] {
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
    }

    /// A glossy lobe alone, of roughness `alpha` (the inverse of the glossiness map).
    fn glossy(alpha: f32, n: Vec3) -> Bsdf {
        let g = alpha / (1.0 - alpha * alpha).sqrt();
        let m = material(0.0, 0.0, 1.0, g);
        let bsdf = Bsdf::new(&m, Vec3::ONE, n, true);
        assert!((bsdf.alpha - alpha).abs() < 1e-5);
        bsdf
    }

    /// Mean and standard error of `n` draws of `f`.
    fn estimate(n: usize, mut f: impl FnMut() -> f64) -> (f64, f64) {
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let x = f();
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as f64;
        let var = (sum2 / n as f64 - mean * mean).max(0.0);
        (mean, (var / n as f64).sqrt())
    }

    /// The GGX lobe's sampler draws what its `pdf` says: over uniform directions on the
    /// sphere, `pdf` integrates to the share of samples the sampler returns (the rest
    /// fall below the surface), and the sampled estimate of the directional albedo
    /// `E[f cos / pdf]` equals the uniform estimate of `integral f cos`. A density off
    /// by any factor, or a sampler drawing other normals than `D` weighted by their
    /// visibility, fails one of the two.
    #[test]
    fn ggx_sampler_matches_its_density() {
        let mut rng = Pcg32::new(21, 22);
        let mut dirs = SplitMix64::new(23);
        let n = Vec3::new(0.2, 0.9, -0.4).normalize();
        let frame = Onb::from_w(n);
        for alpha in [0.1f32, 0.3, 0.6, 0.8] {
            let bsdf = glossy(alpha, n);
            for theta in [0.0f32, 0.7, 1.3] {
                let wo = frame.to_world(Vec3::new(theta.sin(), 0.0, theta.cos()));
                let count = 400_000;
                let mut returned = 0usize;
                let (albedo, albedo_se) =
                    estimate(count, || match bsdf.sample(wo, uniforms(&mut rng)) {
                        Some(s) => {
                            returned += 1;
                            assert!(s.pdf > 0.0 && !s.delta);
                            f64::from(s.weight.x)
                        }
                        None => 0.0,
                    });
                let share = returned as f64 / count as f64;
                let sphere = 4.0 * std::f64::consts::PI;
                let (mass, mass_se) = estimate(count, || {
                    let wi = dirs.unit_vector();
                    f64::from(bsdf.pdf(wo, wi)) * sphere
                });
                let (uniform, uniform_se) = estimate(count, || {
                    let wi = dirs.unit_vector();
                    f64::from(bsdf.eval(wo, wi).x * wi.dot(n).max(0.0)) * sphere
                });
                let share_se = (share * (1.0 - share) / count as f64).sqrt();
                let tol = |a: f64, b: f64| 5.0 * (a * a + b * b).sqrt() + 1e-3;
                assert!(
                    (mass - share).abs() < tol(mass_se, share_se),
                    "alpha {alpha} theta {theta}: pdf integrates to {mass} +- {mass_se}, \
                     sampler returns {share}"
                );
                assert!(
                    (albedo - uniform).abs() < tol(albedo_se, uniform_se),
                    "alpha {alpha} theta {theta}: albedo {albedo} +- {albedo_se} sampled, \
                     {uniform} +- {uniform_se} uniform"
                );
                assert!(albedo <= 1.0 + 5.0 * albedo_se, "{albedo}");
            }
        }
    }

    /// The GGX lobe is reciprocal, vanishes below the surface, and approaches the mirror
    /// as the roughness shrinks: at `alpha = 0.01`, 96% of the facet slopes lie below
    /// 0.05 (`P(tan < t) = t^2 / (alpha^2 + t^2)`), so at least 90% of the directions lie
    /// within 0.1 radians of the mirror direction, and the albedo is near 1
    /// (shadowing-masking costs little near normal incidence).
    #[test]
    fn ggx_is_reciprocal_and_narrows_to_the_mirror() {
        let mut rng = Pcg32::new(5, 6);
        let mut dirs = SplitMix64::new(7);
        let n = Vec3::Z;
        let bsdf = glossy(0.4, n);
        for _ in 0..10_000 {
            let (a, b) = (dirs.unit_vector(), dirs.unit_vector());
            let (fab, fba) = (bsdf.eval(a, b).x, bsdf.eval(b, a).x);
            assert!((fab - fba).abs() <= 1e-5 * fab.max(1.0), "{fab} vs {fba}");
            if a.z <= 0.0 || b.z <= 0.0 {
                assert_eq!(fab, 0.0);
            }
        }
        let smooth = glossy(0.01, n);
        let wo = Vec3::new(0.3, 0.0, 1.0).normalize();
        let mirror = reflect(-wo, n);
        let mut near = 0;
        let (albedo, _) = estimate(20_000, || {
            let Some(s) = smooth.sample(wo, uniforms(&mut rng)) else {
                return 0.0;
            };
            near += (s.wi.dot(mirror) > 0.1f32.cos()) as u32;
            f64::from(s.weight.x)
        });
        assert!(near >= 18_000, "{near} of 20000 near the mirror direction");
        assert!(albedo > 0.99 && albedo <= 1.0 + 1e-4, "{albedo}");
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
