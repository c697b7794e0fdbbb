//! render: packet shading. Camera quads are traced as one 4-ray packet through
//! [`Accel::intersect_packet`] (the kd-tree's SIMD traversal), and the shadow rays of
//! one hit point toward the samples of an area light are tested [`LANES`] at a time
//! through [`Accel::occluded_packet`].
//!
//! Invariant: a pixel is bit-identical to the scalar path's. The packet traversal
//! returns the scalar closest hit bit for bit (tests/packet_vs_scalar.rs), each lane is
//! then shaded by the scalar [`Shader::shade_primary`] with the pixel's own generator,
//! and a batch of shadow rays is queued in sample order and summed in that order, so the
//! only thing the packets change is how the same hits and occlusion answers are found.
//! Glossy, mirror and refraction rays stay single rays: each draws from the pixel's
//! generator after the previous one's whole ray tree, so batching them would change
//! the random sequence.

use super::sample::pixel_rng;
use super::shade::{HitSignature, RayCounts, Shader};
use crate::accel::Accel;
use crate::accel::packet::RayPacket;
use crate::ray::Ray;
use crate::scene::CameraFrame;
use crate::simd::LANES;
use glam::Vec3;

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
    let hits = shader.accel.intersect_packet(&RayPacket::from_lanes(&rays));
    std::array::from_fn(|i| match (pixels[i], rays[i]) {
        (Some((x, y)), Some(ray)) => {
            let mut rng = pixel_rng(seed, x, y, 0);
            let hit = hits.lane(i);
            shader.shade_primary(&ray, hit.is_hit().then_some(hit), &mut rng, counts)
        }
        _ => (Vec3::ZERO, HitSignature::MISS),
    })
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
    ) {
        self.rays[self.len] = ray;
        self.values[self.len] = value;
        self.len += 1;
        if self.len == LANES {
            self.flush(accel, lit);
        }
    }

    /// Tests the queued rays and calls `lit` for each unoccluded one, in queue order.
    pub fn flush(&mut self, accel: &dyn Accel, lit: &mut impl FnMut(&Ray, f32)) {
        let queued = &self.rays[..self.len];
        let occluded = if self.packets && queued.len() > 1 {
            accel.occluded_packet(&RayPacket::from_rays(queued))
        } else {
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
