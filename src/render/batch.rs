//! render: rays traced together. Rays of one hit point (shadow rays toward a light's
//! samples, glossy rays) are queued, then tested as one packet of the mode's width, or
//! one by one in scalar mode; unrelated rays (the bounces of many paths) go as one
//! stream. Below the shading paths and the integrators, which share it.

use super::counts::RayCounts;
use crate::accel::packet::RayPacket;
use crate::accel::{Accel, Mode, PacketTrace, PacketWidth, intersect_each, occluded_each};
use crate::ray::{Hit, Ray};
use crate::simd::{MAX_LANES, by_width};
use glam::Vec3;

/// Closest hits of at most one packet of `rays`, traced as a packet at `mode`'s width.
pub fn intersect_rays(accel: &dyn Accel, mode: Mode, rays: &[Ray]) -> [Hit; MAX_LANES] {
    fn at<W: PacketWidth>(accel: &dyn Accel, rays: &[Ray]) -> [Hit; MAX_LANES] {
        let p = accel.intersect_packet(&RayPacket::<W>::from_rays(rays));
        std::array::from_fn(|i| if i < W::LANES { p.lane(i) } else { Hit::MISS })
    }
    by_width!(mode.packet_size(), W => at::<W>(accel, rays))
}

/// Occlusion bits of at most one packet of `rays`, traced as a packet at `mode`'s width.
pub fn occluded_rays(accel: &dyn Accel, mode: Mode, rays: &[Ray]) -> u32 {
    by_width!(mode.packet_size(), W => accel.occluded_packet(&RayPacket::<W>::from_rays(rays)))
}

/// Shadow rays of one hit point, queued in sample order and tested a packet width at a
/// time: as one packet in a packet mode, one by one in scalar mode. Each unoccluded ray is
/// handed back, in queue order, with the value queued beside it.
pub struct ShadowBatch {
    rays: [Ray; MAX_LANES],
    values: [f32; MAX_LANES],
    len: usize,
    mode: Mode,
}

impl ShadowBatch {
    pub fn new(mode: Mode) -> ShadowBatch {
        ShadowBatch {
            rays: [Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0); MAX_LANES],
            values: [0.0; MAX_LANES],
            len: 0,
            mode,
        }
    }

    /// Queues `ray`; once a packet width of rays is queued (4 in scalar mode), tests them
    /// (see [`Self::flush`]).
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
        if self.len == batch_size(self.mode) {
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
        let packets = self.mode != Mode::Scalar;
        let occluded = if packets && queued.len() > 1 {
            counts.packets.shadow.packet(queued.len());
            occluded_rays(accel, self.mode, queued)
        } else {
            if packets {
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

/// Rays of one hit point batched together in `mode` (glossy rays, area-light shadow
/// rays): the packet width, and 4 in scalar mode, whose batches only order the work.
pub fn batch_size(mode: Mode) -> usize {
    mode.packet_size().max(4)
}

/// Closest hits of unrelated rays into `hits` (same length), misses as [`Hit::MISS`]: one
/// by one in scalar mode (the reference), as one stream ([`Accel::intersect_stream`]) in
/// every other mode. The answers are the same either way.
pub fn intersect_unrelated(accel: &dyn Accel, mode: Mode, rays: &[Ray], hits: &mut [Hit]) {
    if mode == Mode::Scalar {
        intersect_each(accel, rays, hits);
    } else {
        accel.intersect_stream(rays, hits);
    }
}

/// Any-hit answers of unrelated rays into `occluded` (same length), as
/// [`intersect_unrelated`] traces them.
pub fn occluded_unrelated(accel: &dyn Accel, mode: Mode, rays: &[Ray], occluded: &mut [bool]) {
    if mode == Mode::Scalar {
        occluded_each(accel, rays, occluded);
    } else {
        accel.occluded_stream(rays, occluded);
    }
}
