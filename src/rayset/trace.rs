//! Tracing a ray set through an [`Accel`]: scalar mode calls `intersect`/`occluded` per
//! ray, the packet modes call `intersect_packet`/`occluded_packet` on every 4, 8 or 16
//! consecutive rays (in an image set in RAYS.md's packet order, a 2x2 quad, a 4x2 block
//! or two 4x2 blocks side by side; lanes past the end of the set are inactive), and
//! tile mode calls `intersect_tile`/`occluded_tile` on every 64 (a 16x4 block), and
//! stream mode calls `intersect_stream`/`occluded_stream` on each chunk as a whole.
//!
//! The timed kernel of `raypack bench` is [`checksum_chunk`]: it converts the rays of a
//! chunk to packets, traces them and folds every answer into a [`Checksum`] (hit count
//! and sum of primitive ids, as the Embree harness folds its answers), so the work
//! cannot be optimised away and two modes or two tracers can be compared.

use crate::accel::Mode;
use crate::accel::kdtree::traverse_tile::TILE_RAYS;
use crate::accel::{Accel, PacketTrace, PacketWidth, RayPacket, intersect_each};
use crate::ray::{Hit, Ray};
use crate::simd::{MAX_LANES, Uint, W4, W8, W16};
use rayon::prelude::*;
use std::fmt;

/// Rays per unit of work handed to a thread (the harness's chunk size).
pub const CHUNK: usize = 4096;

const _: () = assert!(CHUNK.is_multiple_of(MAX_LANES) && CHUNK.is_multiple_of(TILE_RAYS));

/// Closest hit or any hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    Closest,
    Occluded,
}

/// Hit count and wrapping sum of the hit primitive ids (0 for occlusion queries, which
/// return no id).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Checksum {
    pub hits: u64,
    pub prim_sum: u64,
}

impl Checksum {
    #[inline]
    fn add_prim(&mut self, prim: u32) {
        if prim != crate::ray::NO_HIT {
            self.hits += 1;
            self.prim_sum = self.prim_sum.wrapping_add(prim as u64);
        }
    }

    pub fn merge(self, o: Checksum) -> Checksum {
        Checksum {
            hits: self.hits + o.hits,
            prim_sum: self.prim_sum.wrapping_add(o.prim_sum),
        }
    }

    /// Checksum of a hits array.
    pub fn of_hits(hits: &[Hit]) -> Checksum {
        let mut c = Checksum::default();
        for h in hits {
            c.add_prim(h.prim);
        }
        c
    }
}

impl fmt::Display for Checksum {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.hits, self.prim_sum)
    }
}

/// Closest hits of `rays` into `out` (same length) in `mode`.
pub fn intersect_into<A: Accel + ?Sized>(accel: &A, rays: &[Ray], mode: Mode, out: &mut [Hit]) {
    assert_eq!(rays.len(), out.len());
    match mode {
        Mode::Scalar => intersect_each(accel, rays, out),
        Mode::Packet4 => intersect_packets::<A, W4>(accel, rays, out),
        Mode::Packet8 => intersect_packets::<A, W8>(accel, rays, out),
        Mode::Packet16 => intersect_packets::<A, W16>(accel, rays, out),
        Mode::Tile64 => {
            for (tile, ht) in rays.chunks(TILE_RAYS).zip(out.chunks_mut(TILE_RAYS)) {
                accel.intersect_tile(tile, ht);
            }
        }
        Mode::Stream => accel.intersect_stream(rays, out),
    }
}

fn intersect_packets<A: Accel + ?Sized, W: PacketWidth>(accel: &A, rays: &[Ray], out: &mut [Hit]) {
    for (group, hg) in rays.chunks(W::LANES).zip(out.chunks_mut(W::LANES)) {
        accel
            .intersect_packet(&RayPacket::<W>::from_rays(group))
            .write(hg);
    }
}

/// Closest hits of a whole set in `mode`, in chunks over the current rayon pool.
pub fn trace_hits<A: Accel + ?Sized>(accel: &A, rays: &[Ray], mode: Mode) -> Vec<Hit> {
    let mut hits = vec![Hit::MISS; rays.len()];
    hits.par_chunks_mut(CHUNK)
        .zip(rays.par_chunks(CHUNK))
        .for_each(|(h, r)| intersect_into(accel, r, mode, h));
    hits
}

/// Traces one chunk and folds the answers into a checksum (the timed kernel).
pub fn checksum_chunk<A: Accel + ?Sized>(
    accel: &A,
    rays: &[Ray],
    mode: Mode,
    query: Query,
) -> Checksum {
    let mut c = Checksum::default();
    match (mode, query) {
        (Mode::Scalar, Query::Closest) => {
            for r in rays {
                if let Some(h) = accel.intersect(r) {
                    c.add_prim(h.prim);
                }
            }
        }
        (Mode::Scalar, Query::Occluded) => {
            c.hits = rays.iter().filter(|r| accel.occluded(r)).count() as u64;
        }
        (Mode::Packet4, _) => return checksum_packets::<A, W4>(accel, rays, query),
        (Mode::Packet8, _) => return checksum_packets::<A, W8>(accel, rays, query),
        (Mode::Packet16, _) => return checksum_packets::<A, W16>(accel, rays, query),
        (Mode::Tile64, Query::Closest) => {
            let mut hits = [Hit::MISS; TILE_RAYS];
            for tile in rays.chunks(TILE_RAYS) {
                accel.intersect_tile(tile, &mut hits[..tile.len()]);
                for h in &hits[..tile.len()] {
                    c.add_prim(h.prim);
                }
            }
        }
        (Mode::Tile64, Query::Occluded) => {
            for tile in rays.chunks(TILE_RAYS) {
                c.hits += accel.occluded_tile(tile).count_ones() as u64;
            }
        }
        (Mode::Stream, Query::Closest) => {
            let mut hits = vec![Hit::MISS; rays.len()];
            accel.intersect_stream(rays, &mut hits);
            return Checksum::of_hits(&hits);
        }
        (Mode::Stream, Query::Occluded) => {
            let mut occluded = vec![false; rays.len()];
            accel.occluded_stream(rays, &mut occluded);
            c.hits = occluded.iter().filter(|&&o| o).count() as u64;
        }
    }
    c
}

/// [`checksum_chunk`] of the packet modes: `W::LANES` consecutive rays per packet.
#[inline]
fn checksum_packets<A: Accel + ?Sized, W: PacketWidth>(
    accel: &A,
    rays: &[Ray],
    query: Query,
) -> Checksum {
    let mut c = Checksum::default();
    match query {
        Query::Closest => {
            for group in rays.chunks(W::LANES) {
                let hp = accel.intersect_packet(&RayPacket::<W>::from_rays(group));
                for i in 0..group.len() {
                    c.add_prim(hp.prim.lane(i));
                }
            }
        }
        Query::Occluded => {
            for group in rays.chunks(W::LANES) {
                let bits = accel.occluded_packet(&RayPacket::<W>::from_rays(group));
                c.hits += (bits & crate::accel::packet::low_bits(group.len())).count_ones() as u64;
            }
        }
    }
    c
}

/// Traces a whole set in chunks of [`CHUNK`] rays over the current rayon pool.
pub fn checksum_set<A: Accel + ?Sized>(
    accel: &A,
    rays: &[Ray],
    mode: Mode,
    query: Query,
) -> Checksum {
    rays.par_chunks(CHUNK)
        .map(|r| checksum_chunk(accel, r, mode, query))
        .reduce(Checksum::default, Checksum::merge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;
    use crate::scene::{Geometry, Sphere};
    use glam::Vec3;

    fn spheres_and_rays() -> (Geometry, Vec<Ray>) {
        let g = Geometry {
            spheres: (0..9)
                .map(|i| Sphere {
                    center: Vec3::new((i % 3) as f32 * 2.0 - 2.0, (i / 3) as f32 * 2.0 - 2.0, 5.0),
                    radius: 0.8,
                })
                .collect(),
            ..Geometry::default()
        };
        let rays = (0..103)
            .map(|i| {
                let d = Vec3::new(
                    (i % 11) as f32 * 0.07 - 0.35,
                    (i / 11) as f32 * 0.07 - 0.35,
                    1.0,
                );
                Ray::new(
                    Vec3::ZERO,
                    d.normalize(),
                    0.0,
                    if i % 3 == 0 { 4.5 } else { f32::INFINITY },
                )
            })
            .collect();
        (g, rays)
    }

    #[test]
    fn modes_and_chunkings_agree() {
        let (g, rays) = spheres_and_rays();
        let accel = BruteForce::new(&g);
        let scalar = trace_hits(&accel, &rays, Mode::Scalar);
        for mode in Mode::ALL {
            assert_eq!(trace_hits(&accel, &rays, mode), scalar, "{mode}");
        }
        let c = Checksum::of_hits(&scalar);
        assert!(c.hits > 10 && c.hits < rays.len() as u64, "{c}");
        for mode in Mode::ALL {
            assert_eq!(checksum_set(&accel, &rays, mode, Query::Closest), c);
            let occluded = rays.iter().filter(|r| accel.occluded(r)).count() as u64;
            let o = checksum_set(&accel, &rays, mode, Query::Occluded);
            assert_eq!(
                o,
                Checksum {
                    hits: occluded,
                    prim_sum: 0
                }
            );
            // Any hit exists exactly where a closest hit does.
            assert_eq!(occluded, c.hits);
        }
        assert_eq!("packet8".parse::<Mode>(), Ok(Mode::Packet8));
        assert_eq!("packet".parse::<Mode>(), Ok(Mode::native_packet()));
        assert_eq!(Mode::parse_list("all"), Ok(Mode::ALL.to_vec()));
        assert_eq!(
            Mode::parse_list("scalar,packet16"),
            Ok(vec![Mode::Scalar, Mode::Packet16])
        );
        assert!("simd".parse::<Mode>().is_err());
        assert!(Mode::parse_list("scalar,packet5").is_err());
    }
}
