//! render: packet shading. Camera quads and supersampling's sub-pixel samples are traced
//! as 4-ray packets through [`Accel::intersect_packet`] (the kd-tree's SIMD traversal);
//! the mirror and refraction rays their lanes spawn are traced as packets again, down
//! the whole tree (`Shader::finish_packet`); the lanes' shadow rays toward each point
//! light form a packet (`Shader::point_shadows_packet`); the glossy rays of one hit
//! point and the shadow rays toward the samples of one area light are traced [`LANES`]
//! at a time.
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

use super::sample::{Pcg32, pixel_rng};
use super::shade::{
    Batching, Bounce, HitSignature, Lit, POINT_SHADOW_BITS, Path, RayCounts, Shader, Spawn,
    Surface, shadow_origin, shadow_ray,
};
use super::tiles::sub_pixel_sample;
use crate::accel::Accel;
use crate::accel::packet::{HitPacket, RayPacket};
use crate::ray::{Hit, NO_HIT, Ray};
use crate::scene::{CameraFrame, Light};
use crate::simd::LANES;
use glam::Vec3;

#[cfg(doc)]
use super::shade::PacketCounts;

/// [`Shader::mirror`] or [`Shader::refraction`]: the secondary ray a lit hit spawns.
type SpawnStep<'a> = fn(&Shader<'a>, &Ray, &Lit, Bounce, &mut RayCounts) -> Option<Spawn>;

/// Fewest mirror or refraction rays traced as a packet; fewer go alone.
pub const MIN_PACKET_LANES: usize = 2;

/// The packet twin of [`super::tiles::centre_sample`] for up to [`LANES`] pixels: their
/// centre rays traced as one packet, each lane shaded as the scalar path shades it.
pub fn shade_quad_packet(
    shader: &Shader,
    frame: &CameraFrame,
    seed: u64,
    pixels: [Option<(u32, u32)>; LANES],
    counts: &mut RayCounts,
) -> [(Vec3, HitSignature); LANES] {
    let rays = pixels.map(|p| p.map(|(x, y)| frame.ray(x as f32 + 0.5, y as f32 + 0.5)));
    let mut rngs = pixels.map(|p| match p {
        Some((x, y)) => pixel_rng(seed, x, y, 0),
        None => Pcg32::new(0, 0),
    });
    shader.trace_primary_packet(&rays, &mut rngs, counts)
}

/// The packet twin of [`super::tiles::supersample`]: the `n x n` samples, each with its
/// own generator, traced [`LANES`] at a time and summed in the scalar order.
pub fn supersample_packet(
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
    for start in (0..total).step_by(LANES) {
        let mut rngs: [Pcg32; LANES] = std::array::from_fn(|_| Pcg32::new(0, 0));
        let mut rays = [None; LANES];
        for (lane, k) in (start..total.min(start + LANES as u32)).enumerate() {
            let (ray, rng) = sub_pixel_sample(frame, seed, (x, y), n, first, k);
            rays[lane] = Some(ray);
            rngs[lane] = rng;
        }
        let shaded = shader.trace_primary_packet(&rays, &mut rngs, counts);
        for (ray, (colour, _)) in rays.iter().zip(shaded) {
            if ray.is_some() {
                sum += colour;
            }
        }
    }
    sum / total as f32
}

impl<'a> Shader<'a> {
    /// Camera rays of up to [`LANES`] samples, lane `i` drawing from `rngs[i]`, traced
    /// as one packet: lane by lane the colour and signature of [`Shader::trace_primary`].
    pub fn trace_primary_packet(
        &self,
        rays: &[Option<Ray>; LANES],
        rngs: &mut [Pcg32; LANES],
        counts: &mut RayCounts,
    ) -> [(Vec3, HitSignature); LANES] {
        let lanes = rays.iter().flatten().count();
        counts.primary += lanes as u64;
        counts.packets.primary.packet(lanes);
        let hits = self.accel.intersect_packet(&RayPacket::from_lanes(rays));
        self.finish_packet(rays, &[Bounce::CAMERA; LANES], &hits, rngs, counts)
    }

    /// The packet twin of [`Shader::finish`]: shades each lane's closest hit with the
    /// scalar steps in the scalar order, except that the lanes' mirror rays, then their
    /// refraction rays, are traced together ([`Shader::trace_spawns`]).
    pub(super) fn finish_packet(
        &self,
        rays: &[Option<Ray>; LANES],
        at: &[Bounce; LANES],
        hits: &HitPacket,
        rngs: &mut [Pcg32; LANES],
        counts: &mut RayCounts,
    ) -> [(Vec3, HitSignature); LANES] {
        let mut out = [(Vec3::ZERO, HitSignature::MISS); LANES];
        let mut lit: [Option<(Hit, Lit<'a>)>; LANES] = Default::default();
        let mut surfaces: [Option<Surface<'a>>; LANES] = std::array::from_fn(|i| {
            let hit = hits.lane(i);
            let ray = rays[i].as_ref().filter(|_| hit.is_hit())?;
            Some(self.surface(ray, &hit))
        });
        let point_occluded = self.point_shadows_packet(rays, &surfaces, counts);
        for (i, rng) in rngs.iter_mut().enumerate() {
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
        let mut secondary = [NO_HIT; LANES];
        let spawning = (0..LANES).any(|i| {
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
            let seen = self.trace_spawns(&spawns, rngs, counts);
            for i in 0..LANES {
                if let (Some(sp), Some((_, l))) = (&spawns[i], &mut lit[i]) {
                    l.colour += sp.weight * seen[i].0;
                    if secondary[i] == NO_HIT {
                        secondary[i] = seen[i].1.prim;
                    }
                }
            }
        }
        for i in 0..LANES {
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
    fn point_shadows_packet(
        &self,
        rays: &[Option<Ray>; LANES],
        surfaces: &[Option<Surface<'a>>; LANES],
        counts: &mut RayCounts,
    ) -> [u64; LANES] {
        let mut occluded = [0u64; LANES];
        let origins: [Option<Vec3>; LANES] = std::array::from_fn(|i| {
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
            let shadows: [Option<Ray>; LANES] = std::array::from_fn(|i| {
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
                    self.accel.occluded_packet(&RayPacket::from_lanes(&shadows))
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
    fn trace_spawns(
        &self,
        spawns: &[Option<Spawn>; LANES],
        rngs: &mut [Pcg32; LANES],
        counts: &mut RayCounts,
    ) -> [(Vec3, HitSignature); LANES] {
        let rays = spawns.map(|s| s.map(|s| s.ray));
        let lanes = rays.iter().flatten().count();
        if lanes == 0 {
            return [(Vec3::ZERO, HitSignature::MISS); LANES];
        }
        let hits = if lanes >= MIN_PACKET_LANES {
            counts.packets.secondary.packet(lanes);
            self.accel.intersect_packet(&RayPacket::from_lanes(&rays))
        } else {
            counts.packets.secondary.single_rays += lanes as u64;
            HitPacket::from_lanes(|i| {
                rays[i]
                    .and_then(|r| self.accel.intersect(&r))
                    .unwrap_or(Hit::MISS)
            })
        };
        let at = spawns.map(|s| s.map_or(Bounce::CAMERA, |s| s.at));
        self.finish_packet(&rays, &at, &hits, rngs, counts)
    }

    /// The closest hits of up to [`LANES`] rays of one hit point, in order: one packet
    /// when the shader traces packets and there are two rays or more, else one by one.
    pub(super) fn closest_hits(
        &self,
        rays: &[Ray],
        batching: &mut Batching,
    ) -> [Option<Hit>; LANES] {
        let mut hits = [None; LANES];
        if self.packets && rays.len() > 1 {
            batching.packet(rays.len());
            let packet = self.accel.intersect_packet(&RayPacket::from_rays(rays));
            for (i, h) in hits.iter_mut().enumerate().take(rays.len()) {
                let hit = packet.lane(i);
                *h = hit.is_hit().then_some(hit);
            }
        } else {
            if self.packets {
                batching.single_rays += rays.len() as u64;
            }
            for (h, ray) in hits.iter_mut().zip(rays) {
                *h = self.accel.intersect(ray);
            }
        }
        hits
    }
}

/// Shadow rays of one hit point, queued in sample order and tested [`LANES`] at a time:
/// as one packet when `packets` is set, one by one otherwise. Each unoccluded ray is
/// handed back, in queue order, with the value queued beside it.
pub struct ShadowBatch {
    rays: [Ray; LANES],
    values: [f32; LANES],
    len: usize,
    packets: bool,
}

impl ShadowBatch {
    pub fn new(packets: bool) -> ShadowBatch {
        ShadowBatch {
            rays: [Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0); LANES],
            values: [0.0; LANES],
            len: 0,
            packets,
        }
    }

    /// Queues `ray`; once [`LANES`] rays are queued, tests them (see [`Self::flush`]).
    #[inline]
    pub fn push(
        &mut self,
        accel: &dyn Accel,
        ray: Ray,
        value: f32,
        lit: &mut impl FnMut(&Ray, f32),
        counts: &mut RayCounts,
    ) {
        self.rays[self.len] = ray;
        self.values[self.len] = value;
        self.len += 1;
        if self.len == LANES {
            self.flush(accel, lit, counts);
        }
    }

    /// Tests the queued rays and calls `lit` for each unoccluded one, in queue order.
    /// Counts the packet or the single rays in `counts.packets.shadow` in packet mode.
    pub fn flush(
        &mut self,
        accel: &dyn Accel,
        lit: &mut impl FnMut(&Ray, f32),
        counts: &mut RayCounts,
    ) {
        let queued = &self.rays[..self.len];
        let occluded = if self.packets && queued.len() > 1 {
            counts.packets.shadow.packet(queued.len());
            accel.occluded_packet(&RayPacket::from_rays(queued))
        } else {
            if self.packets {
                counts.packets.shadow.single_rays += queued.len() as u64;
            }
            (0..queued.len()).fold(0, |m, i| m | ((accel.occluded(&queued[i]) as u32) << i))
        };
        for i in 0..self.len {
            if occluded & (1 << i) == 0 {
                lit(&self.rays[i], self.values[i]);
            }
        }
        self.len = 0;
    }
}
