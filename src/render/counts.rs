//! render: the counts of traced rays by kind, and by how the packet path traced them.
//! Kept apart from the shaders that fill them so the ray batches below the shaders can
//! count too.

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
    /// How the packet path traced these rays; all zero in scalar mode. Not part of
    /// [`RayCounts::total`]: the same rays, counted by how they were traced.
    pub packets: PacketCounts,
}

/// Rays of one kind traced in packets or, where no packet formed, one by one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Batching {
    /// Packets traced.
    pub packets: u64,
    /// Active lanes of those packets.
    pub packet_rays: u64,
    /// Rays traced alone because too few rays of their kind were ready together.
    pub single_rays: u64,
}

impl Batching {
    /// Counts one packet of `lanes` active rays.
    #[inline]
    pub fn packet(&mut self, lanes: usize) {
        self.packets += 1;
        self.packet_rays += lanes as u64;
    }
}

impl AddAssign for Batching {
    fn add_assign(&mut self, o: Batching) {
        self.packets += o.packets;
        self.packet_rays += o.packet_rays;
        self.single_rays += o.single_rays;
    }
}

/// [`Batching`] by ray kind, in packet mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PacketCounts {
    /// Camera rays: pixel quads and supersampling's sub-pixel samples.
    pub primary: Batching,
    /// Shadow rays toward the samples of one light from one hit point.
    pub shadow: Batching,
    /// Mirror and refraction rays (totally internally reflected ones included) spawned
    /// by the lanes of packets. Those below a glossy ray are shaded one hit at a time by
    /// the scalar steps (the glossy rays share one generator) and are not counted here.
    pub secondary: Batching,
    /// Glossy rays of one hit point.
    pub glossy: Batching,
}

impl AddAssign for PacketCounts {
    fn add_assign(&mut self, o: PacketCounts) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.secondary += o.secondary;
        self.glossy += o.glossy;
    }
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
        self.packets += o.packets;
    }
}
