//! Every packet kernel against its scalar twin, bit for bit: each active lane of a packet
//! must return exactly what the scalar test returns for that lane's ray (`t`, `u`, `v`
//! compared with `to_bits`, and the primitive id), and inactive lanes, filled with NaN,
//! must neither hit nor change anything.
//!
//! The same holds one level up: the kd-tree's packet traversal returns, lane by lane,
//! the scalar traversal's closest hit (same primitive, `t`, `u`, `v` bit-identical) and
//! its any-hit answer, for camera quads, random and shadow packets on the generated
//! stress meshes and the benchmark scenes of ../shared/scenes.
//!
//! Inputs are seeded random rays plus the adversarial set: axis-parallel rays, +-0.0
//! direction components, rays aimed exactly at vertices and edges, origins on the
//! surface, mixed direction signs in one packet, and inactive NaN lanes.
//!
//! Every test runs at every width (4, 8 and 16 lanes) in the same binary, and under every
//! instruction set the CPU runs; the oracle is the scalar walk compiled for the baseline,
//! which the scalar walk of each set must match bit for bit as well.

mod common;

use common::{
    adversarial_rays, camera_rays, looking_at, mixed_primitives, random_rays, shared_scene,
};
use common::{hit_bits, packet};
use glam::Vec3;
use raypack::accel::Accel;
use raypack::accel::PacketWidth;
use raypack::accel::kdtree::stats;
use raypack::accel::kdtree::{BuildParams, KdTree};
use raypack::accel::packet::{HitPacket, LaneHits, RayPacket};
use raypack::accel::prims::{intersect_box, intersect_plane, intersect_sphere};
use raypack::accel::prims_packet::{
    intersect_box_packet, intersect_plane_packet, intersect_sphere_packet,
};
use raypack::accel::triaccel::TriAccel;
use raypack::accel::{TILE_RAYS, TileWidth};
use raypack::ray::{Hit, NO_HIT, Ray};
use raypack::scene::camera::{block_pixel, block_shape};
use raypack::scene::generate::{self, Rng};
use raypack::scene::{Aabb, Camera, Geometry, Plane, Sphere};
use raypack::simd::{Float, Isa, LaneMask, Mask, Simd, Uint, Vf, Vu, W4, W8, W16};

/// Draws the kernel tests need beyond [`Rng`]'s own.
trait Draw {
    fn vec(&mut self, lo: f32, hi: f32) -> Vec3;
    /// `0.0` or `-0.0`.
    fn zero(&mut self) -> f32;
    /// A unit axis direction with random sign and zeros of random sign.
    fn axis_dir(&mut self) -> Vec3;
}

impl Draw for Rng {
    fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        self.point(Vec3::splat(lo), Vec3::splat(hi))
    }

    fn zero(&mut self) -> f32 {
        if self.below(2) == 0 { 0.0 } else { -0.0 }
    }

    fn axis_dir(&mut self) -> Vec3 {
        let axis = self.below(3) as usize;
        let mut d = Vec3::new(self.zero(), self.zero(), self.zero());
        d[axis] = if self.below(2) == 0 { 1.0 } else { -1.0 };
        d
    }
}

/// Shows a ray with the signs of its zeros.
fn show(r: &Ray) -> String {
    format!(
        "org ({:?}, {:?}, {:?}) dir ({:?}, {:?}, {:?}) t_min {:?} t_max {:?}",
        r.org.x, r.org.y, r.org.z, r.dir.x, r.dir.y, r.dir.z, r.t_min, r.t_max
    )
}

fn bits3(h: Option<(f32, f32, f32)>) -> Option<[u32; 3]> {
    h.map(|(t, u, v)| [t.to_bits(), u.to_bits(), v.to_bits()])
}

/// Compares one kernel's packet answer with the scalar answers lane by lane, then checks
/// that merging it into a sentinel `HitPacket` touches only the lanes that hit.
fn check<W: Simd>(
    kernel: &str,
    what: &str,
    rays: &[Option<Ray>],
    scalar: impl Fn(&Ray) -> Option<(f32, f32, f32)>,
    got: LaneHits<W>,
) {
    let mask = got.mask.bits();
    let kernel = &format!("{kernel} ({} lanes)", W::LANES);
    for (i, r) in rays.iter().enumerate() {
        let Some(r) = r else {
            assert_eq!(
                mask & (1 << i),
                0,
                "{kernel}: inactive lane {i} hit ({what})"
            );
            continue;
        };
        let want = scalar(r);
        let have = (mask & (1 << i) != 0).then(|| (got.t.lane(i), got.u.lane(i), got.v.lane(i)));
        assert_eq!(
            bits3(want),
            bits3(have),
            "{kernel} lane {i} on {what}\n  ray: {}\n  scalar: {want:?}\n  packet: {have:?}",
            show(r)
        );
    }
    let sentinel = HitPacket::<W> {
        t: Vf::<W>::from_fn(|i| [f32::NAN, 7.0, f32::INFINITY, -0.0][i % 4]),
        u: Vf::<W>::splat(0.5),
        v: Vf::<W>::splat(-0.5),
        prim: Vu::<W>::from_fn(|i| [1, 2, NO_HIT, 4][i % 4]),
    };
    let mut merged = sentinel;
    merged.merge(&got, 3);
    for (i, r) in rays.iter().enumerate() {
        let (before, after) = (sentinel.lane(i), merged.lane(i));
        if r.is_none() || mask & (1 << i) == 0 {
            assert_eq!(
                format!("{before:?}"),
                format!("{after:?}"),
                "{kernel}: lane {i} changed without a hit"
            );
        } else {
            let take = Hit::is_closer(got.t.lane(i), 3, &before);
            let want = if take { got.t.lane(i) } else { before.t };
            assert_eq!(
                after.t.to_bits(),
                want.to_bits(),
                "{kernel}: merge lane {i}"
            );
            assert_eq!(after.prim, if take { 3 } else { before.prim });
        }
    }
}

/// Lanes of a packet: each active with probability 3/4 (at least one active).
fn lanes<W: Simd>(rng: &mut Rng, mut make: impl FnMut(&mut Rng) -> Ray) -> Vec<Option<Ray>> {
    let keep = 1 << rng.below(W::LANES as u32);
    (0..W::LANES)
        .map(|i| {
            let r = make(rng);
            (keep & (1 << i) != 0 || rng.below(4) != 0).then_some(r)
        })
        .collect()
}

fn t_range(rng: &mut Rng) -> (f32, f32) {
    let t_min = [0.0, 0.0, 1e-4, -1.0][rng.below(4) as usize];
    let t_max = [f32::INFINITY, rng.range(0.1, 6.0), 1e30][rng.below(3) as usize];
    (t_min, t_max)
}

fn random_triangle(rng: &mut Rng) -> [Vec3; 3] {
    match rng.below(4) {
        // Axis-aligned: all corners on one coordinate plane (a split plane, say).
        0 => {
            let axis = rng.below(3) as usize;
            let c = (rng.range(-1.0, 1.0) * 8.0).round() / 8.0;
            [0; 3].map(|_| {
                let mut p = rng.vec(-1.0, 1.0);
                p[axis] = c;
                p
            })
        }
        // Degenerate: collinear corners.
        1 if rng.below(8) == 0 => {
            let (a, b) = (rng.vec(-1.0, 1.0), rng.vec(-1.0, 1.0));
            [a, b, (a + b) * 0.5]
        }
        _ => [0; 3].map(|_| rng.vec(-1.0, 1.0)),
    }
}

/// A point on the triangle: inside, on an edge, or at a vertex.
fn point_on(rng: &mut Rng, [a, b, c]: [Vec3; 3]) -> Vec3 {
    match rng.below(4) {
        0 => [a, b, c][rng.below(3) as usize],
        1 => {
            let s = rng.f32();
            let (p, q) = [(a, b), (b, c), (c, a)][rng.below(3) as usize];
            p + (q - p) * s
        }
        _ => {
            let (mut u, mut v) = (rng.f32(), rng.f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            a * (1.0 - u - v) + b * u + c * v
        }
    }
}

/// A ray toward (or from) `target`, in one of the adversarial forms.
fn ray_at(rng: &mut Rng, target: Vec3) -> Ray {
    let (t_min, t_max) = t_range(rng);
    match rng.below(5) {
        0 => {
            let d = rng.axis_dir();
            Ray::new(target - d * rng.range(0.5, 3.0), d, t_min, t_max)
        }
        // Starting on the surface.
        1 => Ray::new(target, rng.unit_vector(), t_min.max(0.0), t_max),
        2 => Ray::new(rng.vec(-3.0, 3.0), rng.unit_vector(), t_min, t_max),
        _ => {
            let org = rng.vec(-3.0, 3.0);
            let mut d = (target - org).normalize();
            if rng.below(4) == 0 {
                d[rng.below(3) as usize] = rng.zero();
            }
            Ray::new(org, d, t_min, t_max)
        }
    }
}

const PACKETS: usize = 40_000;

/// Runs `PACKETS` packets through one kernel and its scalar twin: each packet gets a
/// fresh primitive from `prim` and rays from `ray`.
fn run_kernel<W: Simd, P: std::fmt::Debug>(
    kernel: &str,
    seed: u64,
    prim: impl Fn(&mut Rng, usize) -> P,
    ray: impl Fn(&mut Rng, &P) -> Ray,
    scalar: impl Fn(&P, &Ray) -> Option<(f32, f32, f32)>,
    packet_test: impl Fn(&P, &RayPacket<W>) -> LaneHits<W>,
) {
    let mut rng = Rng::new(seed);
    let mut hits = 0;
    for n in 0..PACKETS * 4 / W::LANES {
        let p = prim(&mut rng, n);
        let rays = lanes::<W>(&mut rng, |rng| ray(rng, &p));
        let got = packet_test(&p, &packet(&rays));
        hits += got.mask.bits().count_ones();
        check(kernel, &format!("{p:?}"), &rays, |r| scalar(&p, r), got);
    }
    assert!(
        hits > PACKETS as u32,
        "{kernel}: too few hits ({hits}) to test anything"
    );
}

#[test]
fn triaccel_packet_matches_scalar() {
    at_every_width!(triaccel_packet_matches_scalar_at);
}

fn triaccel_packet_matches_scalar_at<W: Simd>() {
    run_kernel::<W, _>(
        "TriAccel::intersect_packet",
        0x7121,
        |rng, _| {
            let tri = random_triangle(rng);
            (tri, TriAccel::new(tri[0], tri[1], tri[2]))
        },
        |rng, (tri, _)| {
            let p = point_on(rng, *tri);
            ray_at(rng, p)
        },
        |(tri, acc), r| acc.intersect(r, r.t_max, tri),
        |(tri, acc), p: &RayPacket<W>| acc.intersect_packet(p, p.active, p.t_max, tri),
    );
}

#[test]
fn sphere_packet_matches_scalar() {
    at_every_width!(sphere_packet_matches_scalar_at);
}

fn sphere_packet_matches_scalar_at<W: Simd>() {
    run_kernel::<W, _>(
        "intersect_sphere_packet",
        0x5e7e,
        |rng, _| Sphere {
            center: rng.vec(-1.0, 1.0),
            radius: rng.range(0.05, 1.5),
        },
        |rng, s| {
            let on = s.center + rng.unit_vector() * s.radius;
            match rng.below(3) {
                // Grazing: tangent to the sphere at `on`.
                0 => {
                    let d = (on - s.center).normalize().any_orthonormal_vector();
                    let (t_min, t_max) = t_range(rng);
                    Ray::new(on - d * 2.0, d, t_min, t_max)
                }
                1 => ray_at(rng, s.center),
                _ => ray_at(rng, on),
            }
        },
        |s, r| intersect_sphere(s, r, r.t_max).map(|t| (t, 0.0, 0.0)),
        |s, p: &RayPacket<W>| intersect_sphere_packet(s, p, p.active, p.t_max),
    );
}

#[test]
fn box_packet_matches_scalar() {
    at_every_width!(box_packet_matches_scalar_at);
}

fn box_packet_matches_scalar_at<W: Simd>() {
    run_kernel::<W, _>(
        "intersect_box_packet",
        0xb0c5,
        |rng, _| {
            let (a, b) = (rng.vec(-1.0, 1.0), rng.vec(-1.0, 1.0));
            Aabb::new(a.min(b), a.max(b))
        },
        |rng, bx| {
            // A point on a face, an edge or a corner of the box, or inside it.
            let mut p = Vec3::new(
                rng.range(bx.min.x, bx.max.x),
                rng.range(bx.min.y, bx.max.y),
                rng.range(bx.min.z, bx.max.z),
            );
            for a in 0..3 {
                if rng.below(2) == 0 {
                    p[a] = if rng.below(2) == 0 {
                        bx.min[a]
                    } else {
                        bx.max[a]
                    };
                }
            }
            ray_at(rng, p)
        },
        |bx, r| intersect_box(bx, r, r.t_max).map(|t| (t, 0.0, 0.0)),
        |bx, p: &RayPacket<W>| intersect_box_packet(bx, p, p.active, p.t_max),
    );
}

#[test]
fn plane_packet_matches_scalar() {
    at_every_width!(plane_packet_matches_scalar_at);
}

fn plane_packet_matches_scalar_at<W: Simd>() {
    run_kernel::<W, _>(
        "intersect_plane_packet",
        0x91a7e,
        |rng, _| Plane {
            normal: if rng.below(2) == 0 {
                rng.axis_dir()
            } else {
                rng.unit_vector()
            },
            offset: rng.range(-1.0, 1.0),
        },
        |rng, pl| {
            let n = pl.normal;
            let on = rng.vec(-2.0, 2.0);
            let on = on + n * (pl.offset - n.dot(on));
            if rng.below(3) == 0 {
                // Parallel to the plane (zero denominator), in it or beside it.
                let (t_min, t_max) = t_range(rng);
                let off = n * rng.range(-1.0, 1.0) * rng.below(2) as f32;
                Ray::new(on + off, n.any_orthonormal_vector(), t_min, t_max)
            } else {
                ray_at(rng, on)
            }
        },
        |pl, r| intersect_plane(pl, r, r.t_max).map(|t| (t, 0.0, 0.0)),
        |pl, p: &RayPacket<W>| intersect_plane_packet(pl, p, p.active, p.t_max),
    );
}

#[test]
fn merge_breaks_ties_toward_the_smaller_id() {
    at_every_width!(merge_breaks_ties_at);
}

fn merge_breaks_ties_at<W: Simd>() {
    let mut best = HitPacket::<W>::miss();
    let all = Mask::<W>::from_bits(W::all_bits());
    let at = |t: f32| LaneHits::<W> {
        mask: all,
        t: Vf::<W>::splat(t),
        u: Vf::<W>::ZERO,
        v: Vf::<W>::ZERO,
    };
    let prims = |b: &HitPacket<W>| (0..W::LANES).map(|i| b.prim.lane(i)).collect::<Vec<_>>();
    best.merge(&at(2.0), 9);
    best.merge(&at(2.0), 12);
    assert_eq!(prims(&best), vec![9; W::LANES], "equal t, larger id loses");
    best.merge(&at(2.0), 4);
    assert_eq!(prims(&best), vec![4; W::LANES], "equal t, smaller id wins");
    best.merge(&at(1.0), NO_HIT - 1);
    assert_eq!(prims(&best), vec![NO_HIT - 1; W::LANES], "smaller t wins");
}

fn show_hit(h: Option<Hit>) -> String {
    h.map_or("miss".into(), |h| {
        format!("prim {} t {:?} u {:?} v {:?}", h.prim, h.t, h.u, h.v)
    })
}

/// One ray's closest hit (a miss as [`Hit::MISS`]) and any-hit answer against the
/// scalar path's, bit for bit; `at` names the ray on failure. The oracle is the scalar
/// walk compiled for the baseline; the scalar walk of the set in use (it runs in that
/// set's entry too) must give the same bits.
fn assert_ray_matches(tree: &KdTree, r: &Ray, got: Hit, occluded: bool, at: impl Fn() -> String) {
    let (want, want_occluded) = Isa::Sse
        .scope(|| (tree.intersect(r), tree.occluded(r)))
        .expect("the baseline always runs");
    assert_eq!(
        (hit_bits(tree.intersect(r)), tree.occluded(r)),
        (hit_bits(want), want_occluded),
        "{}: the scalar walk of {} against the baseline's\n  ray: {}",
        at(),
        Isa::in_use(),
        show(r)
    );
    let have = got.is_hit().then_some(got);
    assert_eq!(
        hit_bits(have),
        hit_bits(want),
        "{}\n  ray: {}\n  scalar: {}\n  packet: {}",
        at(),
        show(r),
        show_hit(want),
        show_hit(have)
    );
    assert_eq!(
        occluded,
        want_occluded,
        "{}: any-hit\n  ray: {}",
        at(),
        show(r)
    );
}

/// Closest hits and any-hit answers of `tree`'s packet path against its scalar path,
/// for every active lane of every packet. Returns the number of lanes that hit.
/// Runs through the [`raypack::accel::Accel`] entry point of width `W`, as the tracers do.
fn assert_tree_matches<W: PacketWidth>(
    tree: &KdTree,
    packets: &[Vec<Option<Ray>>],
    what: &str,
) -> usize {
    let what = &format!("{what} ({} lanes)", W::LANES);
    let mut hits = 0;
    for (n, rays) in packets.iter().enumerate() {
        let p = packet::<W>(rays);
        let got = W::intersect(tree, &p);
        let occluded = W::occluded(tree, &p);
        for (i, r) in rays.iter().enumerate() {
            let lane = got.lane(i);
            let Some(r) = r else {
                assert_eq!(
                    lane.prim, NO_HIT,
                    "{what}: inactive lane {i} of packet {n} hit"
                );
                assert_eq!(occluded & (1 << i), 0, "{what}: inactive lane {i} occluded");
                continue;
            };
            hits += lane.is_hit() as usize;
            let at = || format!("{what}: packet {n} lane {i}");
            assert_ray_matches(tree, r, lane, occluded & (1 << i) != 0, at);
        }
    }
    hits
}

/// Closest hits and any-hit answers of `tree`'s ray tiles ([`TILE_RAYS`] consecutive
/// rays of `rays`, groups of `W::LANES` sharing an entry point) against its scalar path.
/// Returns the nodes the tiles descended together (their entry depths), summed (zero
/// without the `stats` feature).
fn assert_tiles_match<W: TileWidth>(tree: &KdTree, rays: &[Ray], what: &str) -> u64 {
    let what = &format!("{what} (tiles of {} lanes)", W::LANES);
    let before = stats::counts();
    for (n, tile) in rays.chunks(TILE_RAYS).enumerate() {
        let mut got = vec![Hit::MISS; tile.len()];
        tree.intersect_tile::<W>(tile, &mut got);
        let occluded = tree.occluded_tile::<W>(tile);
        for (i, r) in tile.iter().enumerate() {
            let at = || format!("{what}: tile {n} ray {i}");
            assert_ray_matches(tree, r, got[i], occluded & (1 << i) != 0, at);
        }
        let past = occluded.checked_shr(tile.len() as u32).unwrap_or(0);
        assert_eq!(past, 0, "{what}: bits past the tile");
    }
    stats::counts().tile_entry_depth - before.tile_entry_depth
}

/// The rays of packets (active lanes only), in order.
fn flatten(packets: &[Vec<Option<Ray>>]) -> Vec<Ray> {
    packets.iter().flatten().flatten().copied().collect()
}

/// `rays` a packet width at a time; with `rng`, some lanes made inactive (NaN).
fn packets_of<W: Simd>(rays: &[Ray], mut rng: Option<&mut Rng>) -> Vec<Vec<Option<Ray>>> {
    rays.chunks(W::LANES)
        .map(|c| {
            (0..W::LANES)
                .map(|i| {
                    let drop = rng.as_mut().is_some_and(|g| g.below(5) == 0);
                    c.get(i).copied().filter(|_| !drop)
                })
                .collect()
        })
        .collect()
}

/// Camera rays as blocks of `W`'s packet shape, at the top-left corners of RAYS.md's
/// quads (blocks overlap at widths above 4; each one is a packet on its own). With
/// `aligned`, only the corners at multiples of the block size: each pixel in one block.
fn block_packets<W: Simd>(
    camera: &Camera,
    width: u32,
    height: u32,
    stride: usize,
    aligned: bool,
) -> Vec<Vec<Ray>> {
    let frame = camera.frame(width, height);
    let (bw, bh) = block_shape::<W>();
    common::quad_corners(width, height)
        .into_iter()
        .filter(|&(x, y)| x + bw <= width && y + bh <= height)
        .filter(|&(x, y)| !aligned || (x % bw == 0 && y % bh == 0))
        .step_by(stride)
        .map(|(x, y)| frame.block_rays::<W>(x, y))
        .collect()
}

/// Shadow packets: from each quad's hits toward `light` (lanes that missed are
/// inactive), and from one hit point toward four points of an area light around it.
fn shadow_packets<W: Simd>(
    tree: &KdTree,
    quads: &[Vec<Ray>],
    light: Vec3,
    eps: f32,
) -> Vec<Vec<Option<Ray>>> {
    let shadow = |p: Vec3, to: Vec3| {
        let d = to - p;
        Ray::new(p, d.normalize(), eps, d.length())
    };
    let mut out = Vec::new();
    for (n, quad) in quads.iter().enumerate() {
        let hits: Vec<_> = quad
            .iter()
            .map(|r| tree.intersect(r).map(|h| r.at(h.t)))
            .collect();
        out.push(hits.iter().map(|h| h.map(|p| shadow(p, light))).collect());
        if let Some(p) = hits[n % W::LANES] {
            let size = eps * 1e4;
            out.push(
                (0..W::LANES)
                    .map(|i| {
                        let (x, z) = block_pixel::<W>(i);
                        let corner = Vec3::new(x as f32 - 0.5, 0.0, z as f32 - 0.5);
                        Some(shadow(p, light + corner * size))
                    })
                    .collect(),
            );
        }
    }
    out
}

/// Coherent packets: one origin, four directions close to one another (so most agree on
/// every sign, and some straddle an axis).
fn coherent_packets<W: Simd>(b: &Aabb, count: usize, rng: &mut Rng) -> Vec<Vec<Option<Ray>>> {
    (0..count)
        .map(|_| {
            let org = Vec3::new(
                rng.range(b.min.x, b.max.x),
                rng.range(b.min.y, b.max.y),
                rng.range(b.min.z, b.max.z),
            );
            let centre = if rng.below(4) == 0 {
                rng.axis_dir()
            } else {
                rng.unit_vector()
            };
            (0..W::LANES)
                .map(|_| {
                    let d = (centre + rng.vec(-0.02, 0.02)).normalize();
                    Some(Ray::new(org, d, 0.0, f32::INFINITY))
                })
                .collect()
        })
        .collect()
}

/// Every packet kind on one scene, at every width.
fn check_tree_scene(g: &Geometry, camera: &Camera, seed: u64, count: usize, what: &str) {
    at_every_width!(check_tree_scene_at, g, camera, seed, count, what);
}

/// The tile checks at the widths a tile is traced in ([`TileWidth`]); none at 4 lanes.
trait TileChecks: PacketWidth {
    /// [`assert_tiles_match`] at this width, or `None` at a width tiles do not take.
    fn tiles_match(tree: &KdTree, rays: &[Ray], what: &str) -> Option<u64>;
}

impl TileChecks for W4 {
    fn tiles_match(_: &KdTree, _: &[Ray], _: &str) -> Option<u64> {
        None
    }
}

macro_rules! tile_checks {
    ($($w:ty),*) => {$(
        impl TileChecks for $w {
            fn tiles_match(tree: &KdTree, rays: &[Ray], what: &str) -> Option<u64> {
                Some(assert_tiles_match::<$w>(tree, rays, what))
            }
        }
    )*};
}
tile_checks!(W8, W16);

fn check_tree_scene_at<W: TileChecks>(
    g: &Geometry,
    camera: &Camera,
    seed: u64,
    count: usize,
    what: &str,
) {
    let tree = KdTree::build_with(g, &BuildParams::default());
    tree.validate()
        .unwrap_or_else(|e| panic!("{what}: invalid tree: {e}"));
    let mut rng = Rng::new(seed);
    let b = g.bounds();
    let b = if b.is_empty() {
        Aabb::new(Vec3::splat(-1.0), Vec3::ONE)
    } else {
        b
    };
    let quads = block_packets::<W>(camera, 128, 96, 1, false);
    let camera_packets: Vec<_> = quads
        .iter()
        .map(|q| q.iter().copied().map(Some).collect())
        .collect();
    let hits = assert_tree_matches::<W>(&tree, &camera_packets, &format!("{what}, camera blocks"));
    if g.bounded_count() > 0 {
        assert!(hits > quads.len() / 20, "{what}: only {hits} camera hits");
    }
    let splits_before = stats::counts().packet_splits;
    let random = random_rays(b.min, b.max, count, seed);
    assert_tree_matches::<W>(
        &tree,
        &packets_of::<W>(&random, Some(&mut rng)),
        &format!("{what}, random"),
    );
    // The counters are there with the `stats` feature only.
    assert!(
        !stats::ENABLED || stats::counts().packet_splits > splits_before,
        "{what}: no mixed-sign packet was split"
    );
    let adversarial = adversarial_rays(&tree, g, count, seed + 1);
    let packets = packets_of::<W>(&adversarial, Some(&mut rng));
    assert_tree_matches::<W>(&tree, &packets, &format!("{what}, adversarial"));
    let coherent = coherent_packets::<W>(&b, count / W::LANES, &mut rng);
    assert_tree_matches::<W>(&tree, &coherent, &format!("{what}, coherent"));
    let light = Vec3::new(
        (b.min.x + b.max.x) * 0.5,
        b.max.y + b.diagonal() * 0.3,
        b.min.z,
    );
    let shadows = shadow_packets::<W>(&tree, &quads, light, 1e-4 * b.diagonal());
    assert_tree_matches::<W>(&tree, &shadows, &format!("{what}, shadows"));
    if W::LANES >= 8 {
        // Ray tiles of the same rays (tiles take 8 and 16 lanes): camera rays in packet
        // order (16x4 pixel blocks), random, adversarial, coherent and shadow rays.
        let frame = camera.frame(128, 96);
        let camera_rays: Vec<Ray> = common::quad_corners(128, 96)
            .into_iter()
            .flat_map(|(x, y)| frame.block_rays::<W4>(x, y))
            .collect();
        W::tiles_match(&tree, &camera_rays, &format!("{what}, camera"));
        W::tiles_match(&tree, &random, &format!("{what}, random"));
        W::tiles_match(&tree, &adversarial, &format!("{what}, adversarial"));
        let coherent = flatten(&coherent);
        W::tiles_match(&tree, &coherent, &format!("{what}, coherent"));
        let shadows = flatten(&shadows);
        W::tiles_match(&tree, &shadows, &format!("{what}, shadows"));
    }
}

#[test]
fn packet_tree_matches_scalar_on_random_soups() {
    for (count, size, seed) in [
        (1, 0.5, 1),
        (40, 0.5, 2),
        (2_000, 0.1, 3),
        (20_000, 0.03, 4),
    ] {
        let g = generate::random_soup(count, size, seed);
        let camera = looking_at(&g, Vec3::new(0.3, 0.4, -1.0));
        check_tree_scene(&g, &camera, seed, 4_000, &format!("soup {count}"));
    }
}

#[test]
fn packet_tree_matches_scalar_on_tessellated_sphere_and_closed_box() {
    let g = generate::tessellated_sphere(Vec3::new(1.0, 2.0, 3.0), 2.0, 48, 64);
    check_tree_scene(
        &g,
        &looking_at(&g, Vec3::new(0.0, 0.2, -1.0)),
        11,
        8_000,
        "sphere",
    );
    let g = generate::closed_box(8);
    check_tree_scene(
        &g,
        &looking_at(&g, Vec3::new(0.1, 0.1, -0.2)),
        31,
        8_000,
        "closed box",
    );
}

#[test]
fn packet_tree_matches_scalar_on_axis_aligned_grid() {
    let g = generate::axis_aligned_grid(6);
    check_tree_scene(
        &g,
        &looking_at(&g, Vec3::new(0.7, 0.5, -1.0)),
        21,
        8_000,
        "grid",
    );
    // Rays in lattice planes, running along the triangles' edges.
    let camera = Camera {
        eye: Vec3::new(3.0, 3.0, -10.0),
        target: Vec3::new(3.0, 3.0, 0.0),
        up: Vec3::Y,
        vfov_deg: 40.0,
    };
    check_tree_scene(&g, &camera, 22, 2_000, "grid, straight camera");
}

#[test]
fn packet_tree_matches_scalar_on_mixed_primitives_and_planes() {
    let mut g = mixed_primitives();
    g.planes.push(Plane {
        normal: Vec3::new(1.0, 0.0, 1.0).normalize(),
        offset: 2.0,
    });
    let camera = looking_at(&g, Vec3::new(0.2, 0.5, -1.0));
    check_tree_scene(&g, &camera, 43, 8_000, "mixed primitives");
    // Planes only: the tree is empty and every hit comes from beside it.
    let planes = Geometry {
        planes: g.planes.clone(),
        ..Geometry::default()
    };
    check_tree_scene(&planes, &camera, 44, 2_000, "planes only");
}

/// Camera blocks (every `stride`-th of those that hold each pixel once, at every width)
/// and shadow packets of a benchmark scene.
fn check_shared_scene(name: &str, stride: usize) {
    let (g, camera) = shared_scene(name);
    let tree = KdTree::build_with(&g, &BuildParams::default());
    tree.validate()
        .unwrap_or_else(|e| panic!("{name}: invalid tree: {e}"));
    at_every_width!(check_shared_scene_at, name, &g, &camera, &tree, stride);
}

fn check_shared_scene_at<W: TileChecks>(
    name: &str,
    g: &Geometry,
    camera: &Camera,
    tree: &KdTree,
    stride: usize,
) {
    let quads = block_packets::<W>(camera, 1024, 768, stride, true);
    let packets: Vec<_> = quads
        .iter()
        .map(|q| q.iter().copied().map(Some).collect())
        .collect();
    let hits = assert_tree_matches::<W>(tree, &packets, &format!("{name}, camera blocks"));
    assert!(hits > quads.len() / 10, "{name}: only {hits} camera hits");
    let b = g.bounds();
    let light = Vec3::new((b.min.x + b.max.x) * 0.5, b.max.y * 0.9, b.min.z * 0.3);
    let shadows = shadow_packets::<W>(tree, &quads, light, 1e-4 * b.diagonal());
    assert_tree_matches::<W>(tree, &shadows, &format!("{name}, shadows"));
    if W::LANES >= 8 {
        let flat: Vec<Ray> = quads.iter().flatten().copied().collect();
        let depth = W::tiles_match(tree, &flat, &format!("{name}, camera")).unwrap_or(0);
        if stats::ENABLED {
            println!(
                "{name}, {} lanes: camera tiles descended {depth} nodes together",
                W::LANES
            );
            assert!(
                depth > 0,
                "{name}: no camera tile shared an entry point below the root"
            );
        }
        W::tiles_match(tree, &flatten(&shadows), &format!("{name}, shadows"));
    }
    let mut rng = Rng::new(name.len() as u64);
    let random = camera_rays(camera, 64, 48, 1)
        .into_iter()
        .map(|r| {
            let from = r.at(rng.range(0.0, b.diagonal() * 0.5));
            Ray::new(from, rng.unit_vector(), 0.0, f32::INFINITY)
        })
        .collect::<Vec<_>>();
    assert_tree_matches::<W>(
        tree,
        &packets_of::<W>(&random, Some(&mut rng)),
        &format!("{name}, random"),
    );
}

#[test]
fn packet_tree_matches_scalar_on_cornell_box() {
    require_scenes!();
    check_shared_scene("cornell_box", 1);
}

#[test]
fn packet_tree_matches_scalar_on_bunny() {
    require_scenes!();
    check_shared_scene("bunny", 3);
}

#[test]
fn packet_tree_matches_scalar_on_sponza() {
    require_scenes!();
    check_shared_scene("sponza", 7);
}
