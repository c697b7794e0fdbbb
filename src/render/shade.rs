//! render: scalar Whitted shading, the reference every faster path is checked against.
//!
//! One ray at a time through any [`Accel`] (Bikker, "Raytracing: Theory &
//! Implementation", parts 1-6). At a hit:
//! - an ambient term `ambient * albedo * diffuse`, and the material's `emission` when the
//!   ray meets the emitting (front) side;
//! - per light and per light sample: a shadow ray (any-hit, [`Accel::occluded`]) and, when
//!   it is unblocked, the diffuse term `diffuse * max(0, N.L) * albedo` and the Phong term
//!   `specular * max(0, R.V)^shininess`. Each sample carries its own visibility into both
//!   terms, and a light behind the surface (`N.L <= 0`) gives neither: part 2 of the
//!   tutorial shared one averaged shadow factor and lit highlights from behind. Lights
//!   have no distance falloff, as in the tutorial.
//! - mirror reflection `reflection * albedo * trace(R)`, or, with `glossiness > 0`, the
//!   average of rays in a cone of half-angle `glossiness` radians around `R`, all of
//!   whose directions are drawn before the first is traced;
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
//! Random numbers are drawn in one fixed order per camera sample: area-light positions
//! light by light, then all glossy directions, then the glossy rays' trees in sample
//! order, then the mirror ray's tree, then the refraction ray's. Tracing draws nothing,
//! which is what lets the packet path ([`super::shade_packet`]) trace rays together and
//! still draw the same numbers.
//!
//! Importance sampling (part 6): each ray carries a sample budget, 1 for primary rays,
//! halved by mirror and refraction bounces and quartered by glossy ones. An area light
//! takes `max(1, round(samples * budget))` shadow rays and a glossy surface
//! `max(1, round(glossy_samples * budget))` rays; every sum is divided by the count
//! actually taken, so the weights stay normalised.
//!
//! Secondary rays start at the hit point moved along the geometric normal by `1e-4` times
//! the diagonal of the scene's bounds (RAYS.md), toward the side they leave to, or by
//! [`RELATIVE_OFFSET`] of the largest coordinate of the hit point or of the ray that found
//! it when that is more: a hit point is only known to a few ulps of those coordinates, so
//! far from the origin (a ground plane seen to the horizon, a scene whose bounded part is
//! small or absent) a fixed share of the diagonal would start shadow rays below the
//! surface (shadow acne). Both terms scale with the scene, so a scene rendered at 1e-4
//! or 1e4 times its size gives the same image.

use super::batch::ShadowBatch;
pub use super::counts::{Batching, PacketCounts, RayCounts};
use super::sample::{Pcg32, sample_cone, stratified};
use crate::accel::{Accel, Mode};
use crate::ray::{Hit, NO_HIT, Ray};
use crate::scene::{Light, Material, PrimRef, Scene, Sphere};
use crate::simd::prefetch;
use glam::{Vec2, Vec3};

/// What a primary ray saw, compared between neighbouring pixels by adaptive
/// anti-aliasing (tutorial part 3): a pixel whose signature differs from its left or
/// upper neighbour's is supersampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HitSignature {
    /// The primitive hit, or [`NO_HIT`].
    pub prim: u32,
    /// Two bits per light: bit `2k` when some sample of light `k` is visible, bit
    /// `2k + 1` when all are, so umbra, penumbra and light all differ. Lights from 32 on
    /// are folded in by XOR onto the bits of light `k % 32` ([`fold_light`]).
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

/// Share of a hit's coordinate magnitude that a secondary ray's origin is offset by at
/// least: 256 ulps of f32, well above the few ulps a hit point is off its surface.
pub const RELATIVE_OFFSET: f32 = 1.0 / 65536.0;

/// The scalar shader: a scene, an accelerator over its geometry and the ray offset.
pub struct Shader<'a> {
    pub scene: &'a Scene,
    pub accel: &'a dyn Accel,
    /// Offset of secondary ray origins from the surface.
    pub epsilon: f32,
    /// Scalar, or the packet width the shadow rays of an area light's samples and the
    /// glossy rays of a hit are tested at ([`super::batch::ShadowBatch`]); the
    /// answers, and so the image, are the same.
    pub mode: Mode,
    /// [`crate::geom::Geometry::triangle_normals`]: a hit's geometric normal in one read.
    pub triangle_normals: Vec<Vec3>,
}

/// The mutable state of one camera sample's ray tree.
pub(super) struct Path<'p> {
    pub(super) rng: &'p mut Pcg32,
    pub(super) counts: &'p mut RayCounts,
}

/// Where a ray sits in its tree: recursion depth (1 for camera rays), sample budget (1
/// for camera rays) and the absorption coefficient of the medium it travels through.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounce {
    depth: u32,
    budget: f32,
    pub(super) medium: Vec3,
}

impl Bounce {
    pub(super) const CAMERA: Bounce = Bounce {
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

/// A hit point after its direct lighting: what its secondary rays start from.
pub(super) struct Lit<'m> {
    s: Surface<'m>,
    /// Offset of the secondary rays' origins from the surface ([`Shader::offset`]).
    epsilon: f32,
    /// The colour so far; each secondary ray adds its weighted colour.
    pub(super) colour: Vec3,
    light_bits: u64,
}

impl Lit<'_> {
    /// Whether [`Shader::mirror`] or [`Shader::refraction`] may spawn a ray here: false
    /// lets the packet path skip both steps for a packet of matte or final-bounce hits.
    pub(super) fn may_spawn(&self, at: Bounce, shader: &Shader) -> bool {
        let m = self.s.material;
        at.depth < shader.scene.settings.max_depth
            && ((m.reflection > 0.0 && !is_glossy(m)) || m.refraction > 0.0)
    }

    /// The hit's signature, given what its first mirror or refraction ray hit.
    pub(super) fn signature(&self, hit: &Hit, secondary: u32) -> HitSignature {
        HitSignature {
            prim: hit.prim,
            lights: self.light_bits,
            secondary,
        }
    }
}

/// A mirror or refraction ray, where it sits in the tree and the weight its colour
/// adds to the hit that spawned it with.
#[derive(Clone, Copy, Debug)]
pub(super) struct Spawn {
    pub(super) ray: Ray,
    pub(super) at: Bounce,
    pub(super) weight: Vec3,
}

/// Point lights whose shadow rays the packet path can trace ahead of shading, one bit
/// each in the mask [`Shader::direct_on`] takes; later ones are traced during shading.
pub(super) const POINT_SHADOW_BITS: usize = 64;

/// The shadow ray from `origin` toward `target` on a surface with shading normal `ns`,
/// and its `N.L`: `None` when the target is behind the surface or not a distance away.
/// Both paths build every shadow ray here, so the packet path traces the scalar rays.
#[inline]
pub(super) fn shadow_ray(origin: Vec3, ns: Vec3, target: Vec3) -> Option<(Ray, f32)> {
    let to_light = target - origin;
    let dist = to_light.length();
    if dist.is_nan() || dist <= 0.0 {
        return None;
    }
    let l = to_light / dist;
    let n_dot_l = ns.dot(l);
    if n_dot_l <= 0.0 {
        return None;
    }
    Some((Ray::new(origin, l, 0.0, dist * (1.0 - 1e-5)), n_dot_l))
}

/// Where the shadow rays of a hit on `s` start, `epsilon` ([`Shader::offset`]) off the
/// surface: `None` when the material takes no direct light (no shadow ray leaves it).
pub(super) fn shadow_origin(s: &Surface, epsilon: f32) -> Option<Vec3> {
    let m = s.material;
    (m.diffuse > 0.0 || m.specular > 0.0).then(|| s.p + s.ng * epsilon)
}

/// Glossy materials reflect in a cone instead of along the mirror direction.
fn is_glossy(m: &Material) -> bool {
    m.glossiness > 0.0
}

/// Where a ray hit, prepared for shading.
pub(super) struct Surface<'m> {
    pub(super) p: Vec3,
    /// Geometric normal, facing the incoming ray.
    pub(super) ng: Vec3,
    /// Shading normal, facing the incoming ray.
    pub(super) ns: Vec3,
    /// True when the ray hit the surface from its back (leaving a solid).
    pub(super) inside: bool,
    pub(super) material: &'m Material,
    pub(super) albedo: Vec3,
}

impl<'a> Shader<'a> {
    pub fn new(scene: &'a Scene, accel: &'a dyn Accel) -> Shader<'a> {
        let diagonal = accel.bounds().diagonal();
        let epsilon = if diagonal.is_finite() && diagonal > 0.0 {
            1e-4 * diagonal
        } else {
            0.0
        };
        Shader {
            scene,
            accel,
            epsilon,
            mode: Mode::Scalar,
            triangle_normals: scene.geometry.triangle_normals(),
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
    pub(super) fn finish(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        at: Bounce,
        path: &mut Path,
    ) -> (Vec3, HitSignature) {
        let Some(hit) = hit else {
            return (self.background(at), HitSignature::MISS);
        };
        let (colour, sig) = self.shade(ray, &hit, at, path);
        (colour * transmission(at.medium, hit.t), sig)
    }

    /// What a ray that leaves the scene sees: the background, through its medium.
    pub(super) fn background(&self, at: Bounce) -> Vec3 {
        self.scene.settings.background * transmission(at.medium, f32::INFINITY)
    }

    /// How far a secondary ray from hit point `p`, found by a ray from `from`, starts off
    /// the surface: the scene's `epsilon`, or [`RELATIVE_OFFSET`] of the larger
    /// coordinate magnitude when that is more (see the module doc). Never zero.
    pub fn offset(&self, from: Vec3, p: Vec3) -> f32 {
        self.epsilon.max(Self::rounding_offset(from, p))
    }

    /// How far a ray of the global-illumination integrators from hit point `p`, found by
    /// a ray from `from`, starts off the surface: [`RELATIVE_OFFSET`] of the larger
    /// coordinate magnitude alone, the margin of the hit point's rounding, without the
    /// Whitted tracer's floor of `1e-4` times the scene's diagonal. Lifting every bounce
    /// by that floor lets it skip blockers next to the surface: Sponza under a sky came
    /// out 0.36% brighter than Mitsuba 3's image with it (perf/gi.md). Never zero.
    pub fn rounding_offset(from: Vec3, p: Vec3) -> f32 {
        let magnitude = from.abs().max_element().max(p.abs().max_element());
        (magnitude * RELATIVE_OFFSET).max(f32::MIN_POSITIVE)
    }

    /// Direct light, then glossy or mirror reflection, then refraction, each bounce's
    /// ray tree traced to the end before the next draws from the generator.
    fn shade(&self, ray: &Ray, hit: &Hit, at: Bounce, path: &mut Path) -> (Vec3, HitSignature) {
        let mut lit = self.direct(ray, hit, at, path);
        if let Some(c) = self.glossy(ray, &lit, at, path) {
            lit.colour += c;
        }
        let mut secondary = NO_HIT;
        if let Some(mirror) = self.mirror(ray, &lit, at, path.counts) {
            let (c, seen) = self.trace(&mirror.ray, mirror.at, path);
            lit.colour += mirror.weight * c;
            secondary = seen.prim;
        }
        if let Some(refraction) = self.refraction(ray, &lit, at, path.counts) {
            let (c, seen) = self.trace(&refraction.ray, refraction.at, path);
            lit.colour += refraction.weight * c;
            if secondary == NO_HIT {
                secondary = seen.prim;
            }
        }
        (lit.colour, lit.signature(hit, secondary))
    }

    /// The ambient term and every light's samples at `hit`: the colour before any
    /// secondary ray. Draws the area lights' sample positions from the generator.
    pub(super) fn direct(&self, ray: &Ray, hit: &Hit, at: Bounce, path: &mut Path) -> Lit<'a> {
        let s = self.surface(ray, hit);
        self.direct_on(ray, s, at, path, None)
    }

    /// [`Shader::direct`] on a prepared surface. With `point_occluded`, the shadow rays
    /// toward point lights below [`POINT_SHADOW_BITS`] were traced already (bit `k` set
    /// when light `k`'s is occluded; [`shadow_ray`] built them), so they are counted here
    /// but not traced again.
    pub(super) fn direct_on(
        &self,
        ray: &Ray,
        s: Surface<'a>,
        at: Bounce,
        path: &mut Path,
        point_occluded: Option<u64>,
    ) -> Lit<'a> {
        let epsilon = self.offset(ray.org, s.p);
        let m = s.material;
        let settings = &self.scene.settings;
        let mut colour = s.albedo * (settings.ambient * m.diffuse);
        if !s.inside {
            // An emitter shows its own light, one-sided as it emits, so a mesh lit by
            // its emitters shows where the light comes from.
            colour += m.emission;
        }
        let mut light_bits = 0u64;

        if let Some(origin) = shadow_origin(&s, epsilon) {
            let view = -ray.dir;
            for (k, light) in self.scene.lights.iter().enumerate() {
                let count = match light {
                    Light::Point { .. } => 1,
                    _ => scaled_count(light.samples(), at.budget),
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
                let traced = point_occluded.filter(|_| k < POINT_SHADOW_BITS);
                if let (Light::Point { position, .. }, Some(occluded)) = (light, traced) {
                    if let Some((shadow, n_dot_l)) = shadow_ray(origin, s.ns, *position) {
                        path.counts.shadow += 1;
                        if occluded & (1 << k) == 0 {
                            lit(&shadow, n_dot_l);
                        }
                    }
                } else {
                    let mut batch = ShadowBatch::new(self.mode);
                    for i in 0..count {
                        let target = match light {
                            Light::Point { position, .. } => *position,
                            _ => {
                                let (u, v) =
                                    stratified(i, path.rng.next_f32(), path.rng.next_f32());
                                light.point_at(u, v)
                            }
                        };
                        // Drawn all the same, so the numbers that follow do not depend
                        // on which side of a one-sided light the point is.
                        if !light.faces(origin) {
                            continue;
                        }
                        let Some((shadow, n_dot_l)) = shadow_ray(origin, s.ns, target) else {
                            continue;
                        };
                        path.counts.shadow += 1;
                        batch.push(self.accel, shadow, n_dot_l, &mut lit, path.counts);
                    }
                    batch.flush(self.accel, &mut lit, path.counts);
                }
                let inv = 1.0 / count as f32;
                colour += light.color()
                    * (s.albedo * (m.diffuse * diffuse * inv)
                        + Vec3::splat(m.specular * specular * inv));
                light_bits = fold_light(light_bits, k, visible, count);
            }
        }
        Lit {
            s,
            epsilon,
            colour,
            light_bits,
        }
    }

    /// Glossy reflection at a lit hit, when its material has it and the depth allows:
    /// the average over rays in a cone around the mirror direction, weighted. All the
    /// cone's directions are drawn before any of its rays is traced, so the rays can be
    /// traced together ([`Shader::closest_hits`]) and then shaded one by one in order,
    /// each ray tree drawing from the generator after the previous one's, in both modes.
    #[inline]
    pub(super) fn glossy(&self, ray: &Ray, lit: &Lit, at: Bounce, path: &mut Path) -> Option<Vec3> {
        let m = lit.s.material;
        if at.depth >= self.scene.settings.max_depth || m.reflection <= 0.0 || !is_glossy(m) {
            return None;
        }
        Some(self.glossy_cone(ray, lit, at, path))
    }

    /// The body of [`Shader::glossy`], apart so that the test above inlines at every hit.
    fn glossy_cone(&self, ray: &Ray, lit: &Lit, at: Bounce, path: &mut Path) -> Vec3 {
        let (s, m) = (&lit.s, lit.s.material);
        let settings = &self.scene.settings;
        let axis = self.mirror_direction(ray.dir, s);
        let origin = s.p + s.ng * lit.epsilon;
        let count = scaled_count(settings.glossy_samples, at.budget);
        let cos_max = m.glossiness.min(std::f32::consts::FRAC_PI_2).cos();
        let rays: Vec<Ray> = (0..count)
            .map(|i| {
                let (r1, r2) = stratified(i, path.rng.next_f32(), path.rng.next_f32());
                let mut dir = sample_cone(axis, cos_max, r1, r2);
                if dir.dot(s.ng) <= 0.0 {
                    dir = reflect(dir, s.ng);
                }
                Ray::new(origin, dir, 0.0, f32::INFINITY)
            })
            .collect();
        path.counts.glossy += count as u64;
        let next = at.next(0.25, at.medium);
        let mut sum = Vec3::ZERO;
        for chunk in rays.chunks(super::batch::batch_size(self.mode)) {
            let hits = self.closest_hits(chunk, &mut path.counts.packets.glossy);
            for (r, hit) in chunk.iter().zip(hits) {
                sum += self.finish(r, hit, next, path).0;
            }
        }
        s.albedo * (m.reflection / count as f32) * sum
    }

    /// The mirror ray of a lit hit, when its material is a (non-glossy) mirror and the
    /// depth allows. Counts it.
    pub(super) fn mirror(
        &self,
        ray: &Ray,
        lit: &Lit,
        at: Bounce,
        counts: &mut RayCounts,
    ) -> Option<Spawn> {
        let (s, m) = (&lit.s, lit.s.material);
        if at.depth >= self.scene.settings.max_depth || m.reflection <= 0.0 || is_glossy(m) {
            return None;
        }
        counts.reflection += 1;
        let dir = self.mirror_direction(ray.dir, s);
        Some(Spawn {
            ray: Ray::new(s.p + s.ng * lit.epsilon, dir, 0.0, f32::INFINITY),
            at: at.next(0.5, at.medium),
            weight: s.albedo * m.reflection,
        })
    }

    /// The refraction ray of a lit hit (Snell's law, or the totally internally reflected
    /// ray past the critical angle), when its material refracts and the depth allows.
    /// Counts it.
    pub(super) fn refraction(
        &self,
        ray: &Ray,
        lit: &Lit,
        at: Bounce,
        counts: &mut RayCounts,
    ) -> Option<Spawn> {
        let (s, m) = (&lit.s, lit.s.material);
        if at.depth >= self.scene.settings.max_depth || m.refraction <= 0.0 {
            return None;
        }
        let eta = if s.inside { m.ior } else { 1.0 / m.ior };
        let (ray, at) = match self.refract_direction(ray.dir, s, eta) {
            Some(dir) => {
                counts.refraction += 1;
                let beyond = if s.inside {
                    Vec3::ZERO
                } else {
                    absorption_coefficient(m)
                };
                let r = Ray::new(s.p - s.ng * lit.epsilon, dir, 0.0, f32::INFINITY);
                (r, at.next(0.5, beyond))
            }
            None => {
                counts.reflection += 1;
                let dir = self.mirror_direction(ray.dir, s);
                let r = Ray::new(s.p + s.ng * lit.epsilon, dir, 0.0, f32::INFINITY);
                (r, at.next(0.5, at.medium))
            }
        };
        Some(Spawn {
            ray,
            at,
            weight: Vec3::splat(m.refraction),
        })
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

    /// Asks for the records [`Shader::surface`] reads for `hit` (its geometric normal,
    /// material index and triangle) ahead of time: a wavefront shades hits scattered
    /// over the scene, and each of those reads is a cache miss otherwise.
    #[inline(always)]
    pub(super) fn prefetch_surface(&self, hit: &Hit) {
        let i = hit.prim as usize;
        let scene = self.scene;
        if let Some(n) = self.triangle_normals.get(i) {
            prefetch(n);
        }
        if let Some(m) = scene.prim_material.get(i) {
            prefetch(m);
        }
        if let Some(t) = scene.geometry.triangles.get(i) {
            prefetch(t);
        }
    }

    /// The second step of [`Shader::prefetch_surface`], once `hit`'s triangle is in
    /// cache: its vertices' shading normals.
    #[inline(always)]
    pub(super) fn prefetch_vertices(&self, hit: &Hit) {
        let scene = self.scene;
        if scene.normals.is_empty() {
            return;
        }
        if let Some(tri) = scene.geometry.triangles.get(hit.prim as usize) {
            for &v in tri {
                if let Some(n) = scene.normals.get(v as usize) {
                    prefetch(n);
                }
            }
        }
    }

    #[inline(always)]
    pub(super) fn surface(&self, ray: &Ray, hit: &Hit) -> Surface<'a> {
        let scene = self.scene;
        let p = ray.at(hit.t);
        let mut ng = match self.triangle_normals.get(hit.prim as usize) {
            Some(&n) => n,
            None => scene.geometry.geometric_normal(hit.prim, p),
        };
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

/// `(1 - u - v) a + u b + v c` over a triangle's per-vertex attribute. Inlined: the path
/// tracer's vertex runs inside the instruction set's entry (tests/isa_inlining.rs).
#[inline(always)]
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

/// Adds light `k`'s visibility (`visible` of `count` samples unblocked) to the light bits
/// of a [`HitSignature`]: its two bits (`01` some, `11` all, `00` none) are XORed in at
/// bits `2 (k % 32)`. For lights 0..32 the bits start clear, so XOR sets them exactly as
/// the one-slot-per-light layout did (images of scenes with fewer lights do not change);
/// past 32 lights, XOR rather than OR keeps every light counted: two points that differ
/// in the visibility of any one light, whatever its index, differ in the signature, at
/// the price of a collision when two lights 32 apart change the same way at once. The
/// signature stays 64 bits however many lights the scene has.
#[inline]
pub fn fold_light(bits: u64, k: usize, visible: u32, count: u32) -> u64 {
    let state = (visible > 0) as u64 | (((visible == count) as u64) << 1);
    bits ^ (state << (2 * (k % 32)))
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
    fn lights_past_32_still_change_the_signature() {
        let fold = |visible: &[(u32, u32)]| {
            visible
                .iter()
                .enumerate()
                .fold(0, |bits, (k, &(v, n))| fold_light(bits, k, v, n))
        };
        // 40 fully visible lights; then light 33 in umbra, then in penumbra.
        let lit = vec![(4, 4); 40];
        let mut umbra = lit.clone();
        umbra[33] = (0, 4);
        let mut penumbra = lit.clone();
        penumbra[33] = (2, 4);
        let (a, b, c) = (fold(&lit), fold(&umbra), fold(&penumbra));
        assert!(a != b && b != c && a != c, "{a:#x} {b:#x} {c:#x}");
        // Lights below 32 keep their own two bits, as before the fold.
        let mut first = vec![(0, 1); 32];
        first[5] = (1, 1);
        first[31] = (1, 2);
        assert_eq!(fold(&first), (0b11 << 10) | (0b01 << 62));
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
