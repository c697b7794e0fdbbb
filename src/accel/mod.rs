//! Acceleration structures: the narrow interface the renderer traces through.
//!
//! As in pbrt-v4, an accelerator answers `bounds`, closest-hit `intersect` and any-hit
//! `occluded`, for single rays, for packets and for streams of unrelated rays. [`brute::BruteForce`] tests every
//! primitive and is the oracle; [`kdtree::KdTree`] is the fast path, and
//! [`bvh::Bvh`] a second one for incoherent rays (eight boxes per step, boxes that end at
//! the surface). All hold the same [`Prims`] records, so a disagreement points at
//! traversal, not at a primitive test.
//!
//! [`Prims`] and its scalar tests live in [`prims`]; its packet twins in
//! [`prims_packet`]; the lane test of a leaf's triangles in [`triaccel_leaf`]; the
//! triangle record and its tests in [`triaccel`] (packet twin [`triaccel_packet`]).

pub mod axis;
pub mod brute;
pub mod bvh;
pub mod kdtree;
mod mode;
pub mod occupancy;
pub mod packet;
pub mod prims;
pub mod prims_packet;
mod stack;
pub mod triaccel;
pub mod triaccel_leaf;
pub mod triaccel_packet;
pub mod watertight;

use crate::geom::Aabb;
use crate::ray::{Hit, Ray};
use crate::simd::{LaneBits, Simd, W4, W8, W16, native_lanes};
pub use mode::Mode;
pub use packet::{HitPacket, RayPacket};
pub use prims::Prims;

/// An intersector over one scene's primitives.
///
/// A miss is `None` where one ray gets one answer ([`Accel::intersect`]), and
/// [`Hit::MISS`] (`t = +inf`, `prim = NO_HIT`) where answers fill a slice or the lanes of
/// a [`HitPacket`] (packets, tiles, streams, batches): a slice of plain `Hit` records is
/// what the kernels write in place, 16 bytes a ray, and what a caller hands on to other
/// code without unwrapping. [`Hit::is_hit`] tells the two apart.
///
/// Numeric edge cases have one defined answer in every intersector and both paths: a
/// ray with a NaN or infinite origin or direction component, a zero direction, a
/// direction whose largest component lies outside [2^-64, 2^64] ([`crate::ray::DIR_MIN`]),
/// or `!(t_min <= t_max)` hits nothing (`intersect` is `None`, `occluded` false); a ray
/// starting exactly on a surface, an edge or a split plane gets the closest hit with
/// `t > t_min` strictly, the same as brute force's, bit for bit.
pub trait Accel: Sync {
    /// Bounds of the bounded primitives (planes excluded).
    fn bounds(&self) -> Aabb;

    /// The closest hit with `ray.t_min < t < ray.t_max`; ties go to the smaller id.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// True when anything lies between `ray.t_min` and `ray.t_max`.
    fn occluded(&self, ray: &Ray) -> bool;

    /// Closest hits of the active lanes of a 4-lane packet; inactive lanes get
    /// [`Hit::MISS`]. One method per width keeps the trait usable as `dyn Accel`;
    /// callers go through [`PacketTrace`], generic over the width.
    fn intersect_packet4(&self, rays: &RayPacket<W4>) -> HitPacket<W4> {
        lane_by_lane(self, rays)
    }
    /// [`Accel::intersect_packet4`] at 8 lanes.
    fn intersect_packet8(&self, rays: &RayPacket<W8>) -> HitPacket<W8> {
        lane_by_lane(self, rays)
    }
    /// [`Accel::intersect_packet4`] at 16 lanes.
    fn intersect_packet16(&self, rays: &RayPacket<W16>) -> HitPacket<W16> {
        lane_by_lane(self, rays)
    }

    /// Bit `i` set when active lane `i` of a 4-lane packet is occluded.
    fn occluded_packet4(&self, rays: &RayPacket<W4>) -> LaneBits {
        occluded_lane_by_lane(self, rays)
    }
    /// [`Accel::occluded_packet4`] at 8 lanes.
    fn occluded_packet8(&self, rays: &RayPacket<W8>) -> LaneBits {
        occluded_lane_by_lane(self, rays)
    }
    /// [`Accel::occluded_packet4`] at 16 lanes.
    fn occluded_packet16(&self, rays: &RayPacket<W16>) -> LaneBits {
        occluded_lane_by_lane(self, rays)
    }

    /// Closest hits of a tile of up to 64 coherent rays into `out` (same length), misses
    /// as [`Hit::MISS`]; the kd-tree traces them as SIMD groups sharing one entry point.
    fn intersect_tile(&self, rays: &[Ray], out: &mut [Hit]) {
        intersect_each(self, rays, out)
    }

    /// Bit `i` set when ray `i` of a tile of up to 64 rays is occluded.
    fn occluded_tile(&self, rays: &[Ray]) -> u64 {
        let mut bits = 0;
        for (i, r) in rays.iter().enumerate() {
            bits |= (self.occluded(r) as u64) << i;
        }
        bits
    }

    /// Closest hits of a stream of unrelated rays (any length, any directions) into
    /// `hits` (same length, same order), misses as [`Hit::MISS`]: Embree's
    /// `rtcIntersect1M`. Each answer is bit for bit [`Accel::intersect`]'s; the work may
    /// be done in any order, so an accelerator can keep several rays in flight.
    fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        intersect_each(self, rays, hits)
    }

    /// Any-hit answers of a stream of unrelated rays into `occluded` (same length, same
    /// order), each [`Accel::occluded`]'s.
    fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
        occluded_each(self, rays, occluded)
    }

    /// Closest hits of any number of rays on every thread of the current rayon pool (the
    /// global one, or the one a caller [`rayon::ThreadPool::install`]s): chunks of
    /// [`BATCH_RAYS`] rays through [`Accel::intersect_stream`], misses as [`Hit::MISS`].
    /// This is the call for tracing many rays; each answer is bit for bit
    /// [`Accel::intersect`]'s, on any number of threads.
    ///
    /// Panics when `hits` and `rays` differ in length, as `copy_from_slice` does.
    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Hit]) {
        use rayon::prelude::*;
        assert_eq!(rays.len(), hits.len(), "intersect_batch: one hit per ray");
        rays.par_chunks(BATCH_RAYS)
            .zip(hits.par_chunks_mut(BATCH_RAYS))
            .for_each(|(rays, hits)| self.intersect_stream(rays, hits));
    }

    /// Any-hit answers of any number of rays on every thread of the current rayon pool:
    /// [`Accel::intersect_batch`] for [`Accel::occluded_stream`].
    ///
    /// Panics when `occluded` and `rays` differ in length.
    fn occluded_batch(&self, rays: &[Ray], occluded: &mut [bool]) {
        use rayon::prelude::*;
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_batch: one answer per ray"
        );
        rays.par_chunks(BATCH_RAYS)
            .zip(occluded.par_chunks_mut(BATCH_RAYS))
            .for_each(|(rays, occluded)| self.occluded_stream(rays, occluded));
    }
}

/// The most rays [`Accel::intersect_tile`] and [`Accel::occluded_tile`] take (the bits
/// of the occluded answer).
pub const TILE_RAYS: usize = 64;

/// Rays per task of [`Accel::intersect_batch`] and [`Accel::occluded_batch`]: enough for
/// the stream kernel to keep its lanes full and the task overhead small, few enough that
/// two threads share a 64K-ray batch evenly.
pub const BATCH_RAYS: usize = 4096;

/// The stream queries' default, and the reference they are tested against: closest hits
/// of `rays` one ray at a time through [`Accel::intersect`], misses as [`Hit::MISS`].
#[inline]
pub fn intersect_each<A: Accel + ?Sized>(a: &A, rays: &[Ray], hits: &mut [Hit]) {
    assert_eq!(rays.len(), hits.len(), "intersect_stream: one hit per ray");
    for (r, h) in rays.iter().zip(hits.iter_mut()) {
        *h = a.intersect(r).unwrap_or(Hit::MISS);
    }
}

/// [`intersect_each`] for any-hit answers, through [`Accel::occluded`].
#[inline]
pub fn occluded_each<A: Accel + ?Sized>(a: &A, rays: &[Ray], occluded: &mut [bool]) {
    assert_eq!(
        rays.len(),
        occluded.len(),
        "occluded_stream: one answer per ray"
    );
    for (r, o) in rays.iter().zip(occluded.iter_mut()) {
        *o = a.occluded(r);
    }
}

/// The packet entry points' default: each active lane through the single-ray method.
fn lane_by_lane<A: Accel + ?Sized, W: Simd>(a: &A, rays: &RayPacket<W>) -> HitPacket<W> {
    HitPacket::from_lanes(|i| match rays.lane(i) {
        Some(r) => a.intersect(&r).unwrap_or(Hit::MISS),
        None => Hit::MISS,
    })
}

fn occluded_lane_by_lane<A: Accel + ?Sized, W: Simd>(a: &A, rays: &RayPacket<W>) -> LaneBits {
    let mut bits = 0;
    for i in 0..W::LANES {
        if rays.lane(i).is_some_and(|r| a.occluded(&r)) {
            bits |= 1 << i;
        }
    }
    bits
}

/// Lanes of a tile's SIMD groups: 16 with AVX-512, else 8.
pub fn tile_lanes() -> usize {
    native_lanes().max(8)
}

/// A width the accelerators trace packets at: maps `W` to its [`Accel`] method.
pub trait PacketWidth: Simd {
    /// `a`'s closest-hit packet method of this width.
    fn intersect<A: Accel + ?Sized>(a: &A, rays: &RayPacket<Self>) -> HitPacket<Self>;
    /// `a`'s any-hit packet method of this width.
    fn occluded<A: Accel + ?Sized>(a: &A, rays: &RayPacket<Self>) -> LaneBits;
}

macro_rules! packet_width {
    ($w:ty, $i:ident, $o:ident) => {
        impl PacketWidth for $w {
            #[inline]
            fn intersect<A: Accel + ?Sized>(a: &A, rays: &RayPacket<Self>) -> HitPacket<Self> {
                a.$i(rays)
            }
            #[inline]
            fn occluded<A: Accel + ?Sized>(a: &A, rays: &RayPacket<Self>) -> LaneBits {
                a.$o(rays)
            }
        }
    };
}

packet_width!(W4, intersect_packet4, occluded_packet4);
packet_width!(W8, intersect_packet8, occluded_packet8);
packet_width!(W16, intersect_packet16, occluded_packet16);

/// A width ray tiles are traced in: groups of 8 or 16 lanes (a tile of [`TILE_RAYS`]
/// rays is at most 8 groups). 4 lanes is not one, so a 4-lane tile does not compile.
pub trait TileWidth: PacketWidth {}
impl TileWidth for W8 {}
impl TileWidth for W16 {}

/// Packet tracing at any width, for every accelerator (`dyn Accel` included).
pub trait PacketTrace {
    /// Closest hits of the active lanes of `rays`; inactive lanes get [`Hit::MISS`].
    fn intersect_packet<W: PacketWidth>(&self, rays: &RayPacket<W>) -> HitPacket<W>;
    /// Bit `i` set when active lane `i` is occluded.
    fn occluded_packet<W: PacketWidth>(&self, rays: &RayPacket<W>) -> LaneBits;
}

impl<A: Accel + ?Sized> PacketTrace for A {
    #[inline]
    fn intersect_packet<W: PacketWidth>(&self, rays: &RayPacket<W>) -> HitPacket<W> {
        W::intersect(self, rays)
    }
    #[inline]
    fn occluded_packet<W: PacketWidth>(&self, rays: &RayPacket<W>) -> LaneBits {
        W::occluded(self, rays)
    }
}

#[cfg(test)]
mod tests {
    use super::Accel;
    use crate::accel::kdtree::KdTree;
    use crate::ray::{Hit, Ray};
    use crate::rng::Pcg32;
    use crate::scene::generate::random_soup;
    use glam::Vec3;

    /// The batch queries give [`Accel::intersect`]'s and [`Accel::occluded`]'s answers in
    /// input order, for lengths around the chunk size and on one to three threads.
    #[test]
    fn batches_answer_as_single_rays_do_on_any_thread_count() {
        let tree = KdTree::build(&random_soup(300, 0.3, 5));
        let mut rng = Pcg32::new(11, 3);
        let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let rays: Vec<Ray> = (0..2 * super::BATCH_RAYS + 17)
            .map(|_| Ray::new(v() * 2.0, v().normalize_or(Vec3::Y), 0.0, f32::INFINITY))
            .collect();
        let want: Vec<Hit> = rays
            .iter()
            .map(|r| tree.intersect(r).unwrap_or(Hit::MISS))
            .collect();
        assert!(want.iter().any(|h| h.is_hit()) && want.iter().any(|h| !h.is_hit()));
        let key = |h: &Hit| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
        for threads in 1..=3 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            for n in [0, 1, super::BATCH_RAYS, rays.len()] {
                let mut hits = vec![Hit::MISS; n];
                let mut blocked = vec![false; n];
                pool.install(|| {
                    tree.intersect_batch(&rays[..n], &mut hits);
                    tree.occluded_batch(&rays[..n], &mut blocked);
                });
                for i in 0..n {
                    assert_eq!(
                        key(&hits[i]),
                        key(&want[i]),
                        "ray {i} of {n}, {threads} threads"
                    );
                    assert_eq!(blocked[i], tree.occluded(&rays[i]), "ray {i} of {n}");
                }
            }
        }
    }
}
