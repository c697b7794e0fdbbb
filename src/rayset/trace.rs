//! Tracing a ray set through an [`Accel`]: scalar mode calls `intersect`/`occluded` per
//! ray, the packet modes call `intersect_packet`/`occluded_packet` on packets of 4, 8 or
//! 16 rays, tile mode calls `intersect_tile`/`occluded_tile` on every 64 consecutive
//! rays (in an image set, a 16x4 block), and stream mode calls
//! `intersect_stream`/`occluded_stream` on each chunk as a whole.
//!
//! A packet of an image set in RAYS.md's packet order is the pixel block of its width's
//! shape ([`crate::scene::camera::block_shape`]: 2x2, 4x2, 4x4), its lanes in
//! [`crate::scene::camera::block_pixel`]'s order: 4 and 8 consecutive rays already are such a
//! block, 16 are gathered from two rows of quads (16 consecutive rays are an 8x2 strip,
//! whose rays part ways sooner: a 4x4 block traces Sponza's camera rays 6% faster,
//! perf/log/wide.md). A set that is not an image goes in packets of consecutive rays; lanes
//! past its end are inactive.
//!
//! The timed kernel of `raypack bench` is [`checksum_chunk`]: it converts the rays of a
//! chunk to packets, traces them and folds every answer into a [`Checksum`] (hit count
//! and sum of primitive ids, as the Embree harness folds its answers), so the work
//! cannot be optimised away and two modes or two tracers can be compared.

use super::format::{RaySet, TILE, pixel_packet_index};
use crate::accel::Mode;
use crate::accel::{Accel, PacketTrace, PacketWidth, RayPacket, TILE_RAYS, intersect_each};
use crate::ray::{Hit, Ray};
use crate::scene::camera::{block_pixel, block_shape};
use crate::simd::{MAX_LANES, Simd, Uint, by_width};
use rayon::prelude::*;
use std::fmt;

/// Rays per unit of work handed to a thread (the harness's chunk size).
pub const CHUNK: usize = 4096;

/// Rays in one 16x16-pixel tile of an image set.
const TILE_PIXELS: usize = (TILE * TILE) as usize;

const _: () = assert!(
    CHUNK.is_multiple_of(MAX_LANES)
        && CHUNK.is_multiple_of(TILE_RAYS)
        && CHUNK.is_multiple_of(TILE_PIXELS)
);

/// How a slice of rays lies: an image set's rays in RAYS.md's packet order (whole
/// 16x16 tiles), whose packets are pixel blocks, or anything else, whose packets are
/// consecutive rays. Both give every ray the same answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    Image,
    Any,
}

impl Order {
    /// The order of `set`'s rays.
    pub fn of(set: &RaySet) -> Order {
        if set.width > 0 && set.height > 0 {
            Order::Image
        } else {
            Order::Any
        }
    }
}

/// For each packet of `W` lanes in a 16x16 tile of an image set, the tile's rays its
/// lanes take: packet `p` is the [`block_shape`] block `p` (blocks row-major), lane `i` its
/// pixel [`block_pixel`] `i`.
fn tile_lanes<W: Simd>() -> [u16; TILE_PIXELS] {
    let (w, h) = block_shape::<W>();
    let blocks_x = TILE / w;
    std::array::from_fn(|k| {
        let (p, i) = ((k / W::LANES) as u32, k % W::LANES);
        let (dx, dy) = block_pixel::<W>(i);
        let (x, y) = ((p % blocks_x) * w + dx, (p / blocks_x) * h + dy);
        pixel_packet_index(x, y, TILE) as u16
    })
}

/// Which rays of a slice the lanes of a packet hold: a run of consecutive rays, or
/// gathered ones (lane `i` holds ray `lanes[i]`).
#[derive(Clone, Copy)]
enum Lanes<'a> {
    Run { first: usize, len: usize },
    Gathered(&'a [usize]),
}

impl Lanes<'_> {
    #[inline]
    fn len(&self) -> usize {
        match *self {
            Lanes::Run { len, .. } => len,
            Lanes::Gathered(idx) => idx.len(),
        }
    }

    /// The ray of lane `i`.
    #[inline]
    fn ray(&self, i: usize) -> usize {
        match *self {
            Lanes::Run { first, .. } => first + i,
            Lanes::Gathered(idx) => idx[i],
        }
    }
}

/// Calls `f` on every packet of `rays` with the rays its lanes hold (see the module docs
/// for which rays a packet takes).
#[inline]
fn for_each_packet<W: PacketWidth>(
    rays: &[Ray],
    order: Order,
    mut f: impl FnMut(&RayPacket<W>, Lanes<'_>),
) {
    let table = tile_lanes::<W>();
    let gather = order == Order::Image
        && rays.len().is_multiple_of(TILE_PIXELS)
        && table.iter().enumerate().any(|(k, &j)| k != j as usize);
    if !gather {
        for (k, group) in rays.chunks(W::LANES).enumerate() {
            let lanes = Lanes::Run {
                first: k * W::LANES,
                len: group.len(),
            };
            f(&RayPacket::from_rays(group), lanes);
        }
        return;
    }
    let mut idx = [0usize; MAX_LANES];
    // Each block is two runs of consecutive rays, its upper and its lower half (the
    // halves' rows of quads): no copy.
    let half = W::LANES / 2;
    let run = |l: &[u16]| l.windows(2).all(|w| w[1] == w[0] + 1);
    debug_assert!(
        table
            .chunks(W::LANES)
            .all(|l| run(&l[..half]) && run(&l[half..]))
    );
    for (t, tile) in rays.chunks(TILE_PIXELS).enumerate() {
        for lanes in table.chunks(W::LANES) {
            for (i, &j) in lanes.iter().enumerate() {
                idx[i] = t * TILE_PIXELS + j as usize;
            }
            let (a, b) = (lanes[0] as usize, lanes[half] as usize);
            f(
                &RayPacket::from_halves(&tile[a..a + half], &tile[b..b + half]),
                Lanes::Gathered(&idx[..W::LANES]),
            );
        }
    }
}

/// `[split, total]`: the packets of `mode` (as the mode forms them from `rays`, lying in
/// `order`) whose lanes disagree on a direction sign, and all of them: the tiles for
/// the tile mode, every ray for the scalar and stream modes (none split).
pub fn split_packets(rays: &[Ray], order: Order, mode: Mode) -> [usize; 2] {
    match mode {
        Mode::Scalar | Mode::Stream => [0, rays.len()],
        Mode::Packet4 | Mode::Packet8 | Mode::Packet16 => by_width!(mode.packet_size(), W => {
            sign_split_packets::<W>(rays, order)
        }),
        Mode::Tile64 => {
            let tiles = rays.chunks(TILE_RAYS);
            let total = tiles.len();
            let mixed = |tile: &[Ray]| {
                (0..3).any(|a| {
                    tile.iter().any(|r| r.dir[a] < 0.0) && tile.iter().any(|r| r.dir[a] > 0.0)
                })
            };
            [tiles.filter(|t| mixed(t)).count(), total]
        }
    }
}

/// [`split_packets`] of the packets of `W` lanes.
pub fn sign_split_packets<W: PacketWidth>(rays: &[Ray], order: Order) -> [usize; 2] {
    let mut counts = [0, 0];
    for_each_packet::<W>(rays, order, |p, _| {
        counts[0] += (p.sign_group_count() > 1) as usize;
        counts[1] += 1;
    });
    counts
}

/// The mode that suits `rays`, judged on the rays themselves (any order; `scale` is the
/// scene's size, its bounds' diagonal): the native packet mode when at least half the
/// groups of a packet's width of consecutive rays are coherent, their directions within
/// about 25 degrees of each other with the same signs and their origins within 5% of
/// `scale` (camera rays; shadow rays toward one light from neighbouring points, whose
/// origins a depth edge parts: 72% of the bunny's 8-ray groups lie within 1%, 99%
/// within 5%), else the stream mode (bounces, random rays). Every mode gives the same
/// answers; this only picks the fast one for callers that cannot know (the Python
/// package's `auto`).
///
/// It judges one group in `AUTO_STRIDE` (four), without a square root: judging every ray
/// with normalised directions took an eighth of the bunny's camera rays' time.
pub fn auto_mode(rays: &[Ray], scale: f32) -> Mode {
    let packet = Mode::native_packet();
    let near = 0.05 * scale;
    let signs = |d: glam::Vec3| d.cmplt(glam::Vec3::ZERO).bitmask();
    let coherent = |g: &[Ray]| {
        let (d0, o0) = (g[0].dir, g[0].org);
        let len0 = d0.length_squared();
        g.iter().all(|r| {
            // cos(angle) >= 0.9 as dot >= 0 and dot^2 >= 0.81 |d|^2 |d0|^2.
            let dot = r.dir.dot(d0);
            signs(r.dir) == signs(d0)
                && dot >= 0.0
                && dot * dot >= 0.81 * r.dir.length_squared() * len0
                && (r.org - o0).abs().max_element() <= near
        })
    };
    let (mut yes, mut groups) = (0usize, 0usize);
    for g in rays.chunks(packet.width()).step_by(AUTO_STRIDE) {
        yes += coherent(g) as usize;
        groups += 1;
    }
    if yes * 2 >= groups {
        packet
    } else {
        Mode::Stream
    }
}

/// [`auto_mode`] judges one group of consecutive rays in this many.
const AUTO_STRIDE: usize = 4;

/// The index of whichever of `accels` traces `sample` (lying in `order`) sooner in
/// `mode`, on the calling thread (0 when `accels` is empty). Each traces it once
/// untimed, so that none pays for caches left cold by the caller's recent work, then
/// twice timed, in the order given and then in reverse, so each takes a first and a
/// last turn; their totals compare.
/// Every accelerator gives the same answers, so this picks speed only: it is how the
/// Python package's `accel="auto"` chooses between the kd-tree and the BVH, on a
/// sample of the very rays it is asked about. Which tree is faster depends on the
/// scene, the rays and the CPU together (perf/log/python.md), so it is measured, not
/// guessed.
pub fn faster(
    accels: &[&dyn Accel],
    sample: &[Ray],
    order: Order,
    query: Query,
    mode: Mode,
) -> usize {
    let mut hits = vec![Hit::MISS; sample.len()];
    let mut occluded = vec![false; sample.len()];
    let time = |a: &dyn Accel, hits: &mut [Hit], occluded: &mut [bool]| {
        let start = std::time::Instant::now();
        match query {
            Query::Closest => intersect_into(a, sample, order, mode, hits),
            Query::Occluded => occluded_into(a, sample, order, mode, occluded),
        }
        start.elapsed()
    };
    for a in accels {
        time(*a, &mut hits, &mut occluded);
    }
    let mut total = vec![std::time::Duration::ZERO; accels.len()];
    let turns = (0..accels.len()).chain((0..accels.len()).rev());
    for i in turns {
        total[i] += time(accels[i], &mut hits, &mut occluded);
    }
    (0..accels.len()).min_by_key(|&i| total[i]).unwrap_or(0)
}

/// The rays [`faster`] races on, as ranges of `0..n`: runs of 256
/// consecutive rays (one 16x16 tile of an image set), spread evenly, [`race_rays`] in
/// all; or all of `0..n` when that is no more. Many short runs, not a few long ones:
/// an image's tiles differ (a model's tiles against the background's), and the race
/// must see them in their proportions.
pub fn race_ranges(n: usize) -> Vec<std::ops::Range<usize>> {
    let total = race_rays(n);
    if n <= total {
        return std::iter::once(0..n).collect();
    }
    let runs = total / TILE_PIXELS;
    // Starts on tiles, the first at 0 and the last within a tile of the end; as
    // `n > total`, neighbours lie more than a tile apart before rounding, so at least
    // one after it.
    let start = |k: usize| k * (n - TILE_PIXELS) / (runs - 1) / TILE_PIXELS * TILE_PIXELS;
    (0..runs)
        .map(|k| start(k)..start(k) + TILE_PIXELS)
        .collect()
}

/// How many of `n` rays [`race_ranges`] samples: [`CHUNK`], or four times that from
/// [`RACE_LARGE`] rays on. A sample of coherent rays traces in a fraction of a
/// millisecond, within a timer's and the host's noise, so a large query, which can
/// afford it, gets a larger one.
pub fn race_rays(n: usize) -> usize {
    if n >= RACE_LARGE { 4 * CHUNK } else { CHUNK }
}

/// See [`race_rays`].
pub const RACE_LARGE: usize = 1 << 18;

const _: () = assert!(CHUNK.is_multiple_of(TILE_PIXELS) && CHUNK / TILE_PIXELS >= 2);

/// [`trace_image`] through whichever of `accels` traces a sample of the image's rays
/// sooner ([`faster`]), and its index.
pub fn trace_image_faster(
    accels: &[&dyn Accel],
    view: &crate::scene::View,
    width: u32,
    height: u32,
    mode: Mode,
) -> Result<(Vec<Ray>, Vec<Hit>, usize), super::RaySetError> {
    let set = super::standard::padded_image_set(view, width, height)?;
    let sample: Vec<Ray> = race_ranges(set.len())
        .into_iter()
        .flat_map(|r| set.rays[r].iter().copied())
        .collect();
    let pick = faster(accels, &sample, Order::of(&set), Query::Closest, mode);
    let hits = trace_hits(accels[pick], &set, mode);
    let (rays, hits) = image_of(&set, &hits, width, height);
    Ok((rays, hits, pick))
}

/// Closest hit or any hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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

/// Closest hits of `rays` (lying in `order`) into `out` (same length) in `mode`.
pub fn intersect_into<A: Accel + ?Sized>(
    accel: &A,
    rays: &[Ray],
    order: Order,
    mode: Mode,
    out: &mut [Hit],
) {
    assert_eq!(rays.len(), out.len());
    match mode {
        Mode::Scalar => intersect_each(accel, rays, out),
        Mode::Packet4 | Mode::Packet8 | Mode::Packet16 => by_width!(mode.packet_size(), W => {
            intersect_packets::<A, W>(accel, rays, order, out)
        }),
        Mode::Tile64 => {
            for (tile, ht) in rays.chunks(TILE_RAYS).zip(out.chunks_mut(TILE_RAYS)) {
                accel.intersect_tile(tile, ht);
            }
        }
        Mode::Stream => accel.intersect_stream(rays, out),
    }
}

fn intersect_packets<A: Accel + ?Sized, W: PacketWidth>(
    accel: &A,
    rays: &[Ray],
    order: Order,
    out: &mut [Hit],
) {
    for_each_packet::<W>(rays, order, |p, lanes| {
        let hits = accel.intersect_packet(p);
        match lanes {
            Lanes::Run { first, len } => hits.write(&mut out[first..first + len]),
            Lanes::Gathered(_) => {
                for i in 0..lanes.len() {
                    out[lanes.ray(i)] = hits.lane(i);
                }
            }
        }
    });
}

/// Any-hit answers of `rays` (lying in `order`) into `out` (same length) in `mode`.
pub fn occluded_into<A: Accel + ?Sized>(
    accel: &A,
    rays: &[Ray],
    order: Order,
    mode: Mode,
    out: &mut [bool],
) {
    assert_eq!(rays.len(), out.len());
    match mode {
        Mode::Scalar => crate::accel::occluded_each(accel, rays, out),
        Mode::Packet4 | Mode::Packet8 | Mode::Packet16 => by_width!(mode.packet_size(), W => {
            occluded_packets::<A, W>(accel, rays, order, out)
        }),
        Mode::Tile64 => {
            for (tile, ot) in rays.chunks(TILE_RAYS).zip(out.chunks_mut(TILE_RAYS)) {
                let bits = accel.occluded_tile(tile);
                for (i, o) in ot.iter_mut().enumerate() {
                    *o = bits >> i & 1 == 1;
                }
            }
        }
        Mode::Stream => accel.occluded_stream(rays, out),
    }
}

fn occluded_packets<A: Accel + ?Sized, W: PacketWidth>(
    accel: &A,
    rays: &[Ray],
    order: Order,
    out: &mut [bool],
) {
    for_each_packet::<W>(rays, order, |p, lanes| {
        let bits = accel.occluded_packet(p);
        for i in 0..lanes.len() {
            out[lanes.ray(i)] = bits >> i & 1 == 1;
        }
    });
}

/// Closest hits of a whole set in `mode`, in chunks over the current rayon pool.
pub fn trace_hits<A: Accel + ?Sized>(accel: &A, set: &RaySet, mode: Mode) -> Vec<Hit> {
    let order = Order::of(set);
    let mut hits = vec![Hit::MISS; set.len()];
    hits.par_chunks_mut(CHUNK)
        .zip(set.rays.par_chunks(CHUNK))
        .for_each(|(h, r)| intersect_into(accel, r, order, mode, h));
    hits
}

/// The camera rays of `view` at any `width x height` and their closest hits, in
/// row-major order (pixel `(x, y)` at `y * width + x`): the rays bit for bit
/// [`super::standard::camera_rays`]'s, each hit that of [`Accel::intersect`], traced
/// in `mode` as an image set, so packets and tiles take pixel blocks. A size that is not
/// a multiple of [`super::TILE`] is traced padded to the next multiple
/// ([`super::standard::padded_image_set`]), its extra rays dropped.
pub fn trace_image<A: Accel + ?Sized>(
    accel: &A,
    view: &crate::scene::View,
    width: u32,
    height: u32,
    mode: Mode,
) -> Result<(Vec<Ray>, Vec<Hit>), super::RaySetError> {
    let set = super::standard::padded_image_set(view, width, height)?;
    let hits = trace_hits(accel, &set, mode);
    Ok(image_of(&set, &hits, width, height))
}

/// The rays and hits of the `width` x `height` image in a padded image set, row-major.
fn image_of(set: &RaySet, hits: &[Hit], width: u32, height: u32) -> (Vec<Ray>, Vec<Hit>) {
    (0..height)
        .into_par_iter()
        .flat_map_iter(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let i = super::pixel_packet_index(x, y, set.width);
            (set.rays[i], hits[i])
        })
        .unzip()
}

/// Traces one chunk (lying in `order`) and folds the answers into a checksum (the timed
/// kernel).
pub fn checksum_chunk<A: Accel + ?Sized>(
    accel: &A,
    rays: &[Ray],
    order: Order,
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
        (Mode::Packet4 | Mode::Packet8 | Mode::Packet16, _) => {
            return by_width!(mode.packet_size(), W => {
                checksum_packets::<A, W>(accel, rays, order, query)
            });
        }
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

/// [`checksum_chunk`] of the packet modes (packets as the module docs say).
#[inline]
fn checksum_packets<A: Accel + ?Sized, W: PacketWidth>(
    accel: &A,
    rays: &[Ray],
    order: Order,
    query: Query,
) -> Checksum {
    let mut c = Checksum::default();
    match query {
        Query::Closest => for_each_packet::<W>(rays, order, |p, lanes| {
            let hp = accel.intersect_packet(p);
            for i in 0..lanes.len() {
                c.add_prim(hp.prim.lane(i));
            }
        }),
        Query::Occluded => for_each_packet::<W>(rays, order, |p, lanes| {
            let bits = accel.occluded_packet(p);
            c.hits += (bits & crate::accel::packet::low_bits(lanes.len())).count_ones() as u64;
        }),
    }
    c
}

/// Traces a whole set in chunks of [`CHUNK`] rays over the current rayon pool.
pub fn checksum_set<A: Accel + ?Sized>(
    accel: &A,
    set: &RaySet,
    mode: Mode,
    query: Query,
) -> Checksum {
    let order = Order::of(set);
    set.rays
        .par_chunks(CHUNK)
        .map(|r| checksum_chunk(accel, r, order, mode, query))
        .reduce(Checksum::default, Checksum::merge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;
    use crate::rayset::format::packet_pixel;
    use crate::scene::{Geometry, Sphere};
    use crate::simd::Float;
    use crate::simd::{W4, W8, W16};
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

    /// An image set's packets: every ray once, each packet the pixel block of its
    /// width's shape with its lanes in `block_pixel` order.
    fn image_packets_are_blocks<W: PacketWidth>() {
        let width = 32;
        let rays: Vec<Ray> = (0..width * 48)
            .map(|i| Ray::new(Vec3::new(i as f32, 0.0, 0.0), Vec3::Z, 0.0, 1.0))
            .collect();
        let mut seen = vec![0u32; rays.len()];
        for_each_packet::<W>(&rays, Order::Image, |p, lanes| {
            assert_eq!(lanes.len(), W::LANES);
            let (x0, y0) = packet_pixel(lanes.ray(0), width);
            for (i, r) in (0..lanes.len()).map(|i| (i, lanes.ray(i))) {
                seen[r] += 1;
                assert_eq!(p.org[0].lane(i), r as f32, "lane {i} holds ray {r}");
                let (dx, dy) = block_pixel::<W>(i);
                assert_eq!(packet_pixel(r, width), (x0 + dx, y0 + dy), "lane {i}");
            }
            let (bw, bh) = block_shape::<W>();
            assert_eq!((x0 % bw, y0 % bh), (0, 0));
        });
        assert!(seen.iter().all(|&n| n == 1));
    }

    #[test]
    fn race_ranges_are_whole_tiles_inside_the_rays() {
        let large = RACE_LARGE;
        for n in [
            0,
            1,
            100,
            CHUNK,
            CHUNK + 1,
            3 * CHUNK + 17,
            large - 1,
            large,
            1_000_003,
        ] {
            let ranges = race_ranges(n);
            let total: usize = ranges.iter().map(|r| r.len()).sum();
            let want = if n >= large { 4 * CHUNK } else { CHUNK };
            assert_eq!(total, n.min(want), "{n} rays");
            for (k, r) in ranges.iter().enumerate() {
                assert!(r.end <= n, "{n} rays: {r:?}");
                if n > want {
                    assert_eq!(r.start % TILE_PIXELS, 0, "{n} rays: {r:?}");
                    assert_eq!(r.len(), TILE_PIXELS);
                }
                if k > 0 {
                    assert!(ranges[k - 1].end <= r.start, "{n} rays: overlap at {r:?}");
                }
            }
            // Spread: from the first tile to within a tile of the end.
            if n > want {
                let last = ranges.last().unwrap().start;
                assert_eq!(ranges[0].start, 0, "{n} rays");
                assert!(last + 2 * TILE_PIXELS > n, "{n} rays: ends at {last}");
            }
        }
    }

    #[test]
    fn the_race_names_one_of_its_runners() {
        let (g, rays) = spheres_and_rays();
        let brute = BruteForce::new(&g);
        let kd = crate::accel::kdtree::KdTree::build(&g);
        let accels: [&dyn Accel; 2] = [&brute, &kd];
        for query in [Query::Closest, Query::Occluded] {
            for mode in [Mode::Scalar, Mode::Stream, Mode::Packet8] {
                assert!(faster(&accels, &rays, Order::Any, query, mode) < 2);
                assert_eq!(faster(&accels[1..], &rays, Order::Any, query, mode), 0);
            }
        }
        assert_eq!(
            faster(&[], &rays, Order::Any, Query::Closest, Mode::Stream),
            0
        );
    }

    #[test]
    fn image_packets_at_every_width() {
        image_packets_are_blocks::<W4>();
        image_packets_are_blocks::<W8>();
        image_packets_are_blocks::<W16>();
    }

    #[test]
    fn image_sets_give_every_ray_its_answer_in_every_mode() {
        let (g, _) = spheres_and_rays();
        let accel = BruteForce::new(&g);
        let (width, height) = (48, 32);
        let rays = (0..width * height)
            .map(|i| {
                let (x, y) = packet_pixel(i as usize, width);
                let d = Vec3::new(x as f32 / 40.0 - 0.6, y as f32 / 40.0 - 0.4, 1.0);
                Ray::new(Vec3::ZERO, d.normalize(), 0.0, f32::INFINITY)
            })
            .collect();
        let set = RaySet {
            width,
            height,
            rays,
        };
        let scalar = trace_hits(&accel, &set, Mode::Scalar);
        let c = Checksum::of_hits(&scalar);
        assert!(c.hits > 100 && c.hits < set.len() as u64, "{c}");
        for mode in Mode::ALL {
            assert_eq!(trace_hits(&accel, &set, mode), scalar, "{mode}");
            assert_eq!(
                checksum_set(&accel, &set, mode, Query::Closest),
                c,
                "{mode}"
            );
            let o = checksum_set(&accel, &set, mode, Query::Occluded);
            assert_eq!(o.hits, c.hits, "{mode}");
        }
    }

    #[test]
    fn modes_and_chunkings_agree() {
        let (g, rays) = spheres_and_rays();
        let accel = BruteForce::new(&g);
        let set = RaySet::from_rays(rays.clone());
        let scalar = trace_hits(&accel, &set, Mode::Scalar);
        for mode in Mode::ALL {
            assert_eq!(trace_hits(&accel, &set, mode), scalar, "{mode}");
        }
        let c = Checksum::of_hits(&scalar);
        assert!(c.hits > 10 && c.hits < rays.len() as u64, "{c}");
        for mode in Mode::ALL {
            assert_eq!(checksum_set(&accel, &set, mode, Query::Closest), c);
            let occluded = rays.iter().filter(|r| accel.occluded(r)).count() as u64;
            let o = checksum_set(&accel, &set, mode, Query::Occluded);
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
