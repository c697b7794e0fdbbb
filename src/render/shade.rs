//! render: scalar Whitted shading, the reference every faster path is checked against.
//!
//! One ray at a time through any [`Accel`] (Bikker, "Raytracing: Theory &
//! Implementation", parts 1-6). At a hit:
//! - an ambient term `ambient * albedo * diffuse`;
//! - per light and per light sample: a shadow ray (any-hit, [`Accel::occluded`]) and, when
//!   it is unblocked, the diffuse term `diffuse * max(0, N.L) * albedo` and the Phong term
//!   `specular * max(0, R.V)^shininess`. Each sample carries its own visibility into both
//!   terms, and a light behind the surface (`N.L <= 0`) gives neither: part 2 of the
//!   tutorial shared one averaged shadow factor and lit highlights from behind. Lights
//!   have no distance falloff, as in the tutorial.
//! - mirror reflection `reflection * albedo * trace(R)`, or, with `glossiness > 0`, the
//!   average of rays in a cone of half-angle `glossiness` radians around `R`;
//! - refraction `refraction * trace(T)` with Snell's law; inside or outside is read from
//!   the side the ray hit (the geometric normal against the ray); past the critical angle
//!   the transmitted share is totally internally reflected instead.
//!
//! Beer's law: a ray that travels a distance `d` inside a medium is multiplied by
//! `exp(-C d)` per channel, with the absorption coefficient
//! `C = absorption * (1 - color)` of the medium's material ([`absorption_coefficient`]):
//! a glass absorbs the complement of its colour, so white glass is clear at any density.
//! A ray entering a refractive surface is inside that material until its next hit; rays
//! reflected inside stay inside; rays leaving go back to clear air. A ray inside an
//! absorbing medium that escapes to infinity is fully absorbed.
//!
//! Importance sampling (part 6): each ray carries a sample budget, 1 for primary rays,
//! halved by mirror and refraction bounces and quartered by glossy ones. An area light
//! takes `max(1, round(samples * budget))` shadow rays and a glossy surface
//! `max(1, round(glossy_samples * budget))` rays; every sum is divided by the count
//! actually taken, so the weights stay normalised.
//!
//! Secondary rays start at the hit point moved along the geometric normal by `1e-4` times
//! the diagonal of the scene's bounds (RAYS.md), toward the side they leave to.

use super::sample::{Pcg32, sample_cone, stratified};
use super::shade_packet::ShadowBatch;
use crate::accel::Accel;
use crate::ray::{Hit, NO_HIT, Ray};
use crate::scene::{Light, Material, PrimRef, Scene, Sphere};
use glam::{Vec2, Vec3};
use std::ops::AddAssign;

/// Rays traced, by kind. Summed over tiles, so totals never depend on thread count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    pub primary: u64,
    pub shadow: u64,
    /// Mirror rays, including totally internally reflected ones.
    pub reflection: u64,
    pub refraction: u64,
    pub glossy: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction + self.glossy
    }
}

impl AddAssign for RayCounts {
    fn add_assign(&mut self, o: RayCounts) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.reflection += o.reflection;
        self.refraction += o.refraction;
        self.glossy += o.glossy;
    }
}

/// What a primary ray saw, compared between neighbouring pixels by adaptive
/// anti-aliasing (tutorial part 3): a pixel whose signature differs from its left or
/// upper neighbour's is supersampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HitSignature {
    /// The primitive hit, or [`NO_HIT`].
    pub prim: u32,
    /// Two bits per light (lights 0..32): bit `2k` when some sample of light `k` is
    /// visible, bit `2k + 1` when all are, so umbra, penumbra and light all differ.
    pub lights: u64,
    /// The primitive hit by the first mirror or refraction ray, or [`NO_HIT`].
    pub secondary: u32,
}

impl HitSignature {
    /// The signature of a ray that left the scene.
    pub const MISS: HitSignature = HitSignature {
        prim: NO_HIT,
        lights: 0,
        secondary: NO_HIT,
    };
}

/// The mirror image of direction `d` about the plane with unit normal `n`.
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - n * (2.0 * d.dot(n))
}

/// The direction a unit ray `d` takes through a surface with unit normal `n` (facing the
/// ray, `d.n < 0`) when `eta = n_from / n_to` (Snell's law). `None` past the critical
/// angle: total internal reflection.
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t > 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

/// Beer's law coefficient `C = absorption * (1 - color)` of a material, per channel.
pub fn absorption_coefficient(m: &Material) -> Vec3 {
    (Vec3::ONE - m.color).max(Vec3::ZERO) * m.absorption.max(0.0)
}

/// `exp(-C d)` per channel; exactly 1 where `C = 0`, even for `d = inf`.
#[inline]
pub fn transmission(c: Vec3, d: f32) -> Vec3 {
    let one = |c: f32| if c == 0.0 { 1.0 } else { (-c * d).exp() };
    Vec3::new(one(c.x), one(c.y), one(c.z))
}

/// The scalar shader: a scene, an accelerator over its geometry and the ray offset.
pub struct Shader<'a> {
    pub scene: &'a Scene,
    pub accel: &'a dyn Accel,
    /// Offset of secondary ray origins from the surface.
    pub epsilon: f32,
    /// Test the shadow rays of an area light's samples as packets
    /// ([`super::shade_packet::ShadowBatch`]); the answers, and so the image, are the same.
    pub packets: bool,
}

/// The mutable state of one camera sample's ray tree.
struct Path<'p> {
    rng: &'p mut Pcg32,
    counts: &'p mut RayCounts,
}

/// Where a ray sits in its tree: recursion depth (1 for camera rays), sample budget (1
/// for camera rays) and the absorption coefficient of the medium it travels through.
#[derive(Clone, Copy, Debug)]
struct Bounce {
    depth: u32,
    budget: f32,
    medium: Vec3,
}

impl Bounce {
    const CAMERA: Bounce = Bounce {
        depth: 1,
        budget: 1.0,
        medium: Vec3::ZERO,
    };

    /// The next bounce, with its budget scaled by `share`, travelling through `medium`.
    fn next(&self, share: f32, medium: Vec3) -> Bounce {
        Bounce {
            depth: self.depth + 1,
            budget: self.budget * share,
            medium,
        }
    }
}

/// Where a ray hit, prepared for shading.
struct Surface<'m> {
    p: Vec3,
    /// Geometric normal, facing the incoming ray.
    ng: Vec3,
    /// Shading normal, facing the incoming ray.
    ns: Vec3,
    /// True when the ray hit the surface from its back (leaving a solid).
    inside: bool,
    material: &'m Material,
    albedo: Vec3,
}

impl<'a> Shader<'a> {
    pub fn new(scene: &'a Scene, accel: &'a dyn Accel) -> Shader<'a> {
        let diagonal = accel.bounds().diagonal();
        let epsilon = if diagonal.is_finite() && diagonal > 0.0 {
            1e-4 * diagonal
        } else {
            1e-4
        };
        Shader {
            scene,
            accel,
            epsilon,
            packets: false,
        }
    }

    /// The colour seen along a camera ray, with its signature for adaptive
    /// anti-aliasing. Counts the primary ray and everything it spawns.
    pub fn trace_primary(
        &self,
        ray: &Ray,
        rng: &mut Pcg32,
        counts: &mut RayCounts,
    ) -> (Vec3, HitSignature) {
        self.shade_primary(ray, self.accel.intersect(ray), rng, counts)
    }

    /// Like [`Shader::trace_primary`] for a camera ray whose closest hit is already known
    /// (a packet traversal found it): the same shading, so the same colour bit for bit.
    pub fn shade_primary(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        rng: &mut Pcg32,
        counts: &mut RayCounts,
    ) -> (Vec3, HitSignature) {
        counts.primary += 1;
        let mut path = Path { rng, counts };
        self.finish(ray, hit, Bounce::CAMERA, &mut path)
    }

    /// The colour along `ray` and what it hit. The caller has counted the ray.
    fn trace(&self, ray: &Ray, at: Bounce, path: &mut Path) -> (Vec3, HitSignature) {
        self.finish(ray, self.accel.intersect(ray), at, path)
    }

    /// Shades `ray`'s closest hit `hit` and applies the absorption along the way to it.
    fn finish(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        at: Bounce,
        path: &mut Path,
    ) -> (Vec3, HitSignature) {
        let Some(hit) = hit else {
            let background = self.scene.settings.background;
            return (
                background * transmission(at.medium, f32::INFINITY),
                HitSignature::MISS,
            );
        };
        let (colour, sig) = self.shade(ray, &hit, at, path);
        (colour * transmission(at.medium, hit.t), sig)
    }

    fn shade(&self, ray: &Ray, hit: &Hit, at: Bounce, path: &mut Path) -> (Vec3, HitSignature) {
        let Bounce {
            depth,
            budget,
            medium,
        } = at;
        let s = self.surface(ray, hit);
        let m = s.material;
        let settings = &self.scene.settings;
        let mut colour = s.albedo * (settings.ambient * m.diffuse);
        let mut light_bits = 0u64;

        if m.diffuse > 0.0 || m.specular > 0.0 {
            let origin = s.p + s.ng * self.epsilon;
            let view = -ray.dir;
            for (k, light) in self.scene.lights.iter().enumerate() {
                let count = match light {
                    Light::Point { .. } => 1,
                    Light::Area { samples, .. } => scaled_count(*samples, budget),
                };
                let (mut diffuse, mut specular, mut visible) = (0.0f32, 0.0f32, 0u32);
                let mut lit = |shadow: &Ray, n_dot_l: f32| {
                    visible += 1;
                    diffuse += n_dot_l;
                    if m.specular > 0.0 {
                        let r_dot_v = reflect(-shadow.dir, s.ns).dot(view);
                        if r_dot_v > 0.0 {
                            specular += r_dot_v.powf(m.shininess);
                        }
                    }
                };
                let mut batch = ShadowBatch::new(self.packets);
                for i in 0..count {
                    let target = match light {
                        Light::Point { position, .. } => *position,
                        Light::Area { .. } => {
                            let (u, v) = stratified(i, path.rng.next_f32(), path.rng.next_f32());
                            light.point_at(u, v)
                        }
                    };
                    let to_light = target - origin;
                    let dist = to_light.length();
                    if dist.is_nan() || dist <= 0.0 {
                        continue;
                    }
                    let l = to_light / dist;
                    let n_dot_l = s.ns.dot(l);
                    if n_dot_l <= 0.0 {
                        continue;
                    }
                    path.counts.shadow += 1;
                    let shadow = Ray::new(origin, l, 0.0, dist * (1.0 - 1e-5));
                    batch.push(self.accel, shadow, n_dot_l, &mut lit);
                }
                batch.flush(self.accel, &mut lit);
                let inv = 1.0 / count as f32;
                colour += light.color()
                    * (s.albedo * (m.diffuse * diffuse * inv)
                        + Vec3::splat(m.specular * specular * inv));
                if k < 32 {
                    let all = visible == count;
                    light_bits |= ((visible > 0) as u64 | ((all as u64) << 1)) << (2 * k);
                }
            }
        }

        let mut secondary = NO_HIT;
        if depth < settings.max_depth {
            if m.reflection > 0.0 {
                let mirror = self.mirror_direction(ray.dir, &s);
                let origin = s.p + s.ng * self.epsilon;
                if m.glossiness > 0.0 {
                    let count = scaled_count(settings.glossy_samples, budget);
                    let cos_max = m.glossiness.min(std::f32::consts::FRAC_PI_2).cos();
                    let mut sum = Vec3::ZERO;
                    for i in 0..count {
                        let (r1, r2) = stratified(i, path.rng.next_f32(), path.rng.next_f32());
                        let mut dir = sample_cone(mirror, cos_max, r1, r2);
                        if dir.dot(s.ng) <= 0.0 {
                            dir = reflect(dir, s.ng);
                        }
                        path.counts.glossy += 1;
                        let r = Ray::new(origin, dir, 0.0, f32::INFINITY);
                        sum += self.trace(&r, at.next(0.25, medium), path).0;
                    }
                    colour += s.albedo * (m.reflection / count as f32) * sum;
                } else {
                    path.counts.reflection += 1;
                    let r = Ray::new(origin, mirror, 0.0, f32::INFINITY);
                    let (c, seen) = self.trace(&r, at.next(0.5, medium), path);
                    secondary = seen.prim;
                    colour += s.albedo * m.reflection * c;
                }
            }
            if m.refraction > 0.0 {
                let eta = if s.inside { m.ior } else { 1.0 / m.ior };
                let (c, seen) = match self.refract_direction(ray.dir, &s, eta) {
                    Some(dir) => {
                        path.counts.refraction += 1;
                        let beyond = if s.inside {
                            Vec3::ZERO
                        } else {
                            absorption_coefficient(m)
                        };
                        let r = Ray::new(s.p - s.ng * self.epsilon, dir, 0.0, f32::INFINITY);
                        self.trace(&r, at.next(0.5, beyond), path)
                    }
                    None => {
                        path.counts.reflection += 1;
                        let dir = self.mirror_direction(ray.dir, &s);
                        let r = Ray::new(s.p + s.ng * self.epsilon, dir, 0.0, f32::INFINITY);
                        self.trace(&r, at.next(0.5, medium), path)
                    }
                };
                if secondary == NO_HIT {
                    secondary = seen.prim;
                }
                colour += c * m.refraction;
            }
        }

        let sig = HitSignature {
            prim: hit.prim,
            lights: light_bits,
            secondary,
        };
        (colour, sig)
    }

    /// Mirror direction about the shading normal, or about the geometric normal when an
    /// interpolated normal would send it below the surface.
    fn mirror_direction(&self, d: Vec3, s: &Surface) -> Vec3 {
        let r = reflect(d, s.ns);
        if r.dot(s.ng) > 0.0 {
            r
        } else {
            reflect(d, s.ng)
        }
    }

    /// Refracted direction about the shading normal, falling back to the geometric normal
    /// when an interpolated normal would keep the ray on the near side.
    fn refract_direction(&self, d: Vec3, s: &Surface, eta: f32) -> Option<Vec3> {
        match refract(d, s.ns, eta) {
            Some(t) if t.dot(s.ng) < 0.0 => Some(t),
            _ => refract(d, s.ng, eta),
        }
    }

    fn surface(&self, ray: &Ray, hit: &Hit) -> Surface<'a> {
        let scene = self.scene;
        let p = ray.at(hit.t);
        let mut ng = scene.geometry.geometric_normal(hit.prim, p);
        let mut ns = ng;
        let prim = scene.geometry.prim_ref(hit.prim);
        if let PrimRef::Triangle(tri) = prim
            && !scene.normals.is_empty()
        {
            let n = barycentric(&scene.normals, scene.geometry.triangles[tri as usize], hit)
                .normalize_or_zero();
            if n != Vec3::ZERO {
                ns = n;
            }
        }
        let inside = ng.dot(ray.dir) > 0.0;
        if inside {
            ng = -ng;
            ns = -ns;
        }
        if ns.dot(ray.dir) >= 0.0 {
            ns = ng;
        }
        let material = scene.material(hit.prim);
        let mut albedo = material.color;
        if let Some(texture) = material
            .texture
            .and_then(|t| scene.textures.get(t as usize))
        {
            let uv = self.texture_uv(prim, p, hit) * material.uv_scale;
            albedo *= texture.sample(uv.x, uv.y);
        }
        Surface {
            p,
            ng,
            ns,
            inside,
            material,
            albedo,
        }
    }

    /// Texture coordinates before `uv_scale`: per-vertex UVs on meshes that have them,
    /// spherical on spheres, planar elsewhere (u, v along two axes perpendicular to the
    /// unoriented geometric normal, [`super::sample::Onb`]).
    fn texture_uv(&self, prim: PrimRef, p: Vec3, hit: &Hit) -> Vec2 {
        let scene = self.scene;
        match prim {
            PrimRef::Triangle(tri) if !scene.uvs.is_empty() => {
                barycentric(&scene.uvs, scene.geometry.triangles[tri as usize], hit)
            }
            PrimRef::Sphere(i) => spherical_uv(&scene.geometry.spheres[i as usize], p),
            _ => planar_uv(scene.geometry.geometric_normal(hit.prim, p), p),
        }
    }
}

/// `(1 - u - v) a + u b + v c` over a triangle's per-vertex attribute.
fn barycentric<T>(attr: &[T], tri: [u32; 3], hit: &Hit) -> T
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    let get = |i: u32| attr[i as usize];
    get(tri[0]) * (1.0 - hit.u - hit.v) + get(tri[1]) * hit.u + get(tri[2]) * hit.v
}

/// Planar mapping: `(p.u_axis, p.v_axis)` with the axes of the basis around `n`.
pub fn planar_uv(n: Vec3, p: Vec3) -> Vec2 {
    let onb = super::sample::Onb::from_w(n);
    Vec2::new(p.dot(onb.u), p.dot(onb.v))
}

/// Spherical mapping: `u` is the longitude around +y (0 at +x, growing toward +z),
/// `v` the colatitude from +y, both scaled to `[0, 1]`.
pub fn spherical_uv(s: &Sphere, p: Vec3) -> Vec2 {
    let d = ((p - s.center) / s.radius).normalize_or_zero();
    let u = 0.5 + d.z.atan2(d.x) / std::f32::consts::TAU;
    let v = d.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    Vec2::new(u, v)
}

/// `max(1, round(base * budget))`: the samples a ray with this budget may spend.
fn scaled_count(base: u32, budget: f32) -> u32 {
    ((base as f32 * budget).round() as u32).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_shrink_but_never_to_zero() {
        assert_eq!(scaled_count(16, 1.0), 16);
        assert_eq!(scaled_count(16, 0.5), 8);
        assert_eq!(scaled_count(16, 0.25), 4);
        assert_eq!(scaled_count(16, 0.25 * 0.25), 1);
        assert_eq!(scaled_count(0, 1.0), 1);
    }

    #[test]
    fn transmission_is_one_for_clear_media_even_at_infinity() {
        assert_eq!(transmission(Vec3::ZERO, f32::INFINITY), Vec3::ONE);
        let t = transmission(Vec3::new(0.0, 1.0, 2.0), f32::INFINITY);
        assert_eq!(t, Vec3::new(1.0, 0.0, 0.0));
    }

    #[test]
    fn uv_maps_are_periodic_friendly_and_in_range() {
        let s = Sphere {
            center: Vec3::new(1.0, 2.0, 3.0),
            radius: 2.0,
        };
        let north = spherical_uv(&s, s.center + Vec3::Y * 2.0);
        assert_eq!(north.y, 0.0);
        let east = spherical_uv(&s, s.center + Vec3::X * 2.0);
        assert!((east - Vec2::new(0.5, 0.5)).length() < 1e-6);
        let floor = planar_uv(Vec3::Y, Vec3::new(3.0, 0.0, -2.0));
        assert_eq!(floor.length(), Vec2::new(3.0, -2.0).length());
    }
}
