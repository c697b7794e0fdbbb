//! render: packet shading. Camera blocks (2x2, 4x2 or 4x4 pixels, the shape of the
//! width: [`crate::scene::camera::block_shape`]) and supersampling's sub-pixel samples are traced
//! as packets of the mode's width through [`PacketTrace::intersect_packet`] (the
//! kd-tree's SIMD traversal);
//! the mirror and refraction rays their lanes spawn are traced as packets again, down
//! the whole tree (`Shader::finish_packet`); the lanes' shadow rays toward each point
//! light form a packet (`Shader::point_shadows_packet`); the glossy rays of one hit
//! point and the shadow rays toward the samples of one area light are traced a packet
//! width at a time.
//!
//! Lane arrays are [`MAX_LANES`] long at every width; only the first `W::LANES` are used.
//!
//! Invariant: a pixel is bit-identical to the scalar path's. The packet traversal
//! returns the scalar closest hit and any-hit answer bit for bit
//! (tests/packet_vs_scalar.rs); every hit is shaded by the scalar code's own steps
//! (`Shader::direct`, `Shader::glossy`, `Shader::mirror`, `Shader::refraction`),
//! and tracing draws no random numbers, so only the order of the draws matters. Each
//! lane of a packet is a camera sample with its own generator, and each lane's events
//! keep the scalar order: its direct light and glossy rays, then its mirror ray's whole
//! tree, then its refraction ray's. The lanes of a glossy or shadow batch share one
//! generator: all their directions or light samples are drawn before any is traced (the
//! scalar path does the same), and their hits are shaded one by one in sample order.
//!
//! A packet forms where at least [`MIN_PACKET_LANES`] lanes spawn a ray of the same kind;
//! otherwise the rays are traced alone. [`PacketCounts`] counts both.

use super::batch::intersect_rays;
use super::sample::{Pcg32, pixel_rng, sub_pixel_sample};
use super::shade::{
    Batching, Bounce, HitSignature, Lit, POINT_SHADOW_BITS, Path, RayCounts, Shader, Spawn,
    Surface, shadow_origin, shadow_ray,
};
use crate::accel::packet::{HitPacket, RayPacket};
use crate::accel::{Mode, PacketTrace, PacketWidth};
use crate::ray::{Hit, NO_HIT, Ray};
use crate::scene::{CameraFrame, Light};
use crate::simd::MAX_LANES;
use glam::Vec3;

#[cfg(doc)]
use super::shade::PacketCounts;

/// [`Shader::mirror`] or [`Shader::refraction`]: the secondary ray a lit hit spawns.
type SpawnStep<'a> = fn(&Shader<'a>, &Ray, &Lit, Bounce, &mut RayCounts) -> Option<Spawn>;

/// Fewest mirror or refraction rays traced as a packet; fewer go alone.
pub const MIN_PACKET_LANES: usize = 2;

/// The packet twin of [`super::tiles::centre_sample`] for up to `W::LANES` pixels: their
/// centre rays traced as one packet, each lane shaded as the scalar path shades it.
pub fn shade_block_packet<W: PacketWidth>(
    shader: &Shader,
    frame: &CameraFrame,
    seed: u64,
    pixels: [Option<(u32, u32)>; MAX_LANES],
    counts: &mut RayCounts,
) -> [(Vec3, HitSignature); MAX_LANES] {
    assert!(
        pixels[W::LANES..].iter().all(Option::is_none),
        "more pixels than lanes"
    );
    let rays = pixels.map(|p| p.map(|(x, y)| frame.ray(x as f32 + 0.5, y as f32 + 0.5)));
    let mut rngs = pixels.map(|p| match p {
        Some((x, y)) => pixel_rng(seed, x, y, 0),
        None => Pcg32::new(0, 0),
    });
    shader.trace_primary_packet::<W>(&rays, &mut rngs, counts)
}

/// The packet twin of [`super::tiles::supersample`]: the `n x n` samples, each with its
/// own generator, traced `W::LANES` at a time and summed in the scalar order.
pub fn supersample_packet<W: PacketWidth>(
    shader: &Shader,
    frame: &CameraFrame,
    seed: u64,
    (x, y): (u32, u32),
    n: u32,
    first: u32,
    counts: &mut RayCounts,
) -> Vec3 {
    let n = n.max(1);
    let total = n * n;
    let mut sum = Vec3::ZERO;
    for start in (0..total).step_by(W::LANES) {
        let mut rngs: [Pcg32; MAX_LANES] = std::array::from_fn(|_| Pcg32::new(0, 0));
        let mut rays = [None; MAX_LANES];
        for (lane, k) in (start..total.min(start + W::LANES as u32)).enumerate() {
            let (ray, rng) = sub_pixel_sample(frame, seed, (x, y), n, first, k);
            rays[lane] = Some(ray);
            rngs[lane] = rng;
        }
        let shaded = shader.trace_primary_packet::<W>(&rays, &mut rngs, counts);
        for (ray, (colour, _)) in rays.iter().zip(shaded) {
            if ray.is_some() {
                sum += colour;
            }
        }
    }
    sum / total as f32
}

impl<'a> Shader<'a> {
    /// Camera rays of up to `W::LANES` samples, lane `i` drawing from `rngs[i]`, traced
    /// as one packet: lane by lane the colour and signature of [`Shader::trace_primary`].
    pub fn trace_primary_packet<W: PacketWidth>(
        &self,
        rays: &[Option<Ray>; MAX_LANES],
        rngs: &mut [Pcg32; MAX_LANES],
        counts: &mut RayCounts,
    ) -> [(Vec3, HitSignature); MAX_LANES] {
        let lanes = rays.iter().flatten().count();
        counts.primary += lanes as u64;
        counts.packets.primary.packet(lanes);
        let hits = self
            .accel
            .intersect_packet(&RayPacket::<W>::from_lanes(&rays[..W::LANES]));
        self.finish_packet::<W>(rays, &[Bounce::CAMERA; MAX_LANES], &hits, rngs, counts)
    }

    /// The packet twin of [`Shader::finish`]: shades each lane's closest hit with the
    /// scalar steps in the scalar order, except that the lanes' mirror rays, then their
    /// refraction rays, are traced together ([`Shader::trace_spawns`]).
    pub(super) fn finish_packet<W: PacketWidth>(
        &self,
        rays: &[Option<Ray>; MAX_LANES],
        at: &[Bounce; MAX_LANES],
        hits: &HitPacket<W>,
        rngs: &mut [Pcg32; MAX_LANES],
        counts: &mut RayCounts,
    ) -> [(Vec3, HitSignature); MAX_LANES] {
        let mut out = [(Vec3::ZERO, HitSignature::MISS); MAX_LANES];
        let mut lit: [Option<(Hit, Lit<'a>)>; MAX_LANES] = Default::default();
        let mut surfaces: [Option<Surface<'a>>; MAX_LANES] = std::array::from_fn(|i| {
            let ray = rays[i].as_ref()?;
            let hit = hits.lane(i);
            hit.is_hit().then(|| self.surface(ray, &hit))
        });
        let point_occluded = self.point_shadows_packet::<W>(rays, &surfaces, counts);
        for (i, rng) in rngs.iter_mut().enumerate().take(W::LANES) {
            let Some(ray) = &rays[i] else { continue };
            let hit = hits.lane(i);
            let Some(s) = surfaces[i].take() else {
                out[i].0 = self.background(at[i]);
                continue;
            };
            let mut path = Path { rng, counts };
            let mut l = self.direct_on(ray, s, at[i], &mut path, Some(point_occluded[i]));
            if let Some(c) = self.glossy(ray, &l, at[i], &mut path) {
                l.colour += c;
            }
            lit[i] = Some((hit, l));
        }
        let mut secondary = [NO_HIT; MAX_LANES];
        let spawning = (0..W::LANES).any(|i| {
            lit[i]
                .as_ref()
                .is_some_and(|(_, l)| l.may_spawn(at[i], self))
        });
        let steps: [SpawnStep<'a>; 2] = [Self::mirror, Self::refraction];
        for spawn in steps.into_iter().filter(|_| spawning) {
            let spawns = std::array::from_fn(|i| match (&rays[i], &lit[i]) {
                (Some(ray), Some((_, l))) => spawn(self, ray, l, at[i], counts),
                _ => None,
            });
            let seen = self.trace_spawns::<W>(&spawns, rngs, counts);
            for i in 0..W::LANES {
                if let (Some(sp), Some((_, l))) = (&spawns[i], &mut lit[i]) {
                    l.colour += sp.weight * seen[i].0;
                    if secondary[i] == NO_HIT {
                        secondary[i] = seen[i].1.prim;
                    }
                }
            }
        }
        for i in 0..W::LANES {
            if let Some((hit, l)) = &lit[i] {
                let colour = l.colour * super::shade::transmission(at[i].medium, hit.t);
                out[i] = (colour, l.signature(hit, secondary[i]));
            }
        }
        out
    }

    /// The shadow rays of the lanes' hits toward each point light (the first
    /// [`POINT_SHADOW_BITS`]), traced before the lanes are shaded: one packet per light
    /// when two lanes or more have a ray toward it (the hits of a camera quad are close,
    /// so these packets are coherent), else the one ray alone. Bit `k` of lane `i` is set
    /// when lane `i`'s ray toward light `k` is occluded. The rays are [`shadow_ray`]'s, as
    /// in the scalar path, and point lights draw no random numbers, so shading with these
    /// answers ([`Shader::direct_on`]) gives the scalar pixels.
    fn point_shadows_packet<W: PacketWidth>(
        &self,
        rays: &[Option<Ray>; MAX_LANES],
        surfaces: &[Option<Surface<'a>>; MAX_LANES],
        counts: &mut RayCounts,
    ) -> [u64; MAX_LANES] {
        let mut occluded = [0u64; MAX_LANES];
        let origins: [Option<Vec3>; MAX_LANES] = std::array::from_fn(|i| {
            let s = surfaces[i].as_ref()?;
            shadow_origin(s, self.offset(rays[i].as_ref()?.org, s.p))
        });
        if origins.iter().all(Option::is_none) {
            return occluded;
        }
        let lights = self.scene.lights.iter().take(POINT_SHADOW_BITS);
        for (k, light) in lights.enumerate() {
            let Light::Point { position, .. } = light else {
                continue;
            };
            let shadows: [Option<Ray>; MAX_LANES] = std::array::from_fn(|i| {
                let ns = surfaces[i].as_ref()?.ns;
                shadow_ray(origins[i]?, ns, *position).map(|(ray, _)| ray)
            });
            let bits = match shadows.iter().flatten().count() {
                0 => continue,
                1 => {
                    counts.packets.shadow.single_rays += 1;
                    let bit = |(i, r): (usize, &Option<Ray>)| {
                        r.as_ref().map(|r| (self.accel.occluded(r) as u32) << i)
                    };
                    shadows.iter().enumerate().find_map(bit).unwrap_or(0)
                }
                lanes => {
                    counts.packets.shadow.packet(lanes);
                    self.accel
                        .occluded_packet(&RayPacket::<W>::from_lanes(&shadows[..W::LANES]))
                }
            };
            for (i, lane) in occluded.iter_mut().enumerate() {
                *lane |= (((bits >> i) & 1) as u64) << k;
            }
        }
        occluded
    }

    /// Traces the lanes' spawned rays, lane `i` drawing from `rngs[i]`, and shades them
    /// with [`Shader::finish_packet`]: as one packet when at least [`MIN_PACKET_LANES`]
    /// lanes have one, else each alone through the scalar [`Accel::intersect`]. Either
    /// way their own spawned rays may form packets again.
    fn trace_spawns<W: PacketWidth>(
        &self,
        spawns: &[Option<Spawn>; MAX_LANES],
        rngs: &mut [Pcg32; MAX_LANES],
        counts: &mut RayCounts,
    ) -> [(Vec3, HitSignature); MAX_LANES] {
        let rays = spawns.map(|s| s.map(|s| s.ray));
        let lanes = rays.iter().flatten().count();
        if lanes == 0 {
            return [(Vec3::ZERO, HitSignature::MISS); MAX_LANES];
        }
        let hits = if lanes >= MIN_PACKET_LANES {
            counts.packets.secondary.packet(lanes);
            self.accel
                .intersect_packet(&RayPacket::<W>::from_lanes(&rays[..W::LANES]))
        } else {
            counts.packets.secondary.single_rays += lanes as u64;
            HitPacket::<W>::from_lanes(|i| {
                rays[i]
                    .and_then(|r| self.accel.intersect(&r))
                    .unwrap_or(Hit::MISS)
            })
        };
        let at = spawns.map(|s| s.map_or(Bounce::CAMERA, |s| s.at));
        self.finish_packet::<W>(&rays, &at, &hits, rngs, counts)
    }

    /// The closest hits of up to one packet width of rays of one hit point, in order: one
    /// packet when the shader traces packets and there are two rays or more, else one by
    /// one.
    pub(super) fn closest_hits(
        &self,
        rays: &[Ray],
        batching: &mut Batching,
    ) -> [Option<Hit>; MAX_LANES] {
        let mut hits = [None; MAX_LANES];
        let packets = self.mode != Mode::Scalar;
        if packets && rays.len() > 1 {
            batching.packet(rays.len());
            let packet = intersect_rays(self.accel, self.mode, rays);
            for (h, hit) in hits.iter_mut().zip(packet).take(rays.len()) {
                *h = hit.is_hit().then_some(hit);
            }
        } else {
            if packets {
                batching.single_rays += rays.len() as u64;
            }
            for (h, ray) in hits.iter_mut().zip(rays) {
                *h = self.accel.intersect(ray);
            }
        }
        hits
    }
}
