//! Every packet kernel against its scalar twin, bit for bit: each active lane of a packet
//! must return exactly what the scalar test returns for that lane's ray (`t`, `u`, `v`
//! compared with `to_bits`, and the primitive id), and inactive lanes, filled with NaN,
//! must neither hit nor change anything.
//!
//! Inputs are seeded random rays plus the adversarial set: axis-parallel rays, +-0.0
//! direction components, rays aimed exactly at vertices and edges, origins on the
//! surface, mixed direction signs in one packet, and inactive NaN lanes.

use glam::Vec3;
use raypack::accel::packet::{HitPacket, LaneHits, RayPacket};
use raypack::accel::prims::{intersect_box, intersect_plane, intersect_sphere};
use raypack::accel::prims_packet::{
    intersect_box_packet, intersect_plane_packet, intersect_sphere_packet,
};
use raypack::accel::triaccel::TriAccel;
use raypack::ray::{Hit, NO_HIT, Ray};
use raypack::scene::{Aabb, Plane, Sphere};
use raypack::simd::{LANES, Mask, Vf, Vu, mask_from_bits};

/// SplitMix64: small, seeded, and the same on every machine.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }

    fn below(&mut self, n: u32) -> u32 {
        (self.next_u64() % n as u64) as u32
    }

    fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }

    fn dir(&mut self) -> Vec3 {
        loop {
            let d = self.vec(-1.0, 1.0);
            if d.length_squared() > 1e-4 && d.length_squared() <= 1.0 {
                return d.normalize();
            }
        }
    }

    /// `0.0` or `-0.0`.
    fn zero(&mut self) -> f32 {
        if self.below(2) == 0 { 0.0 } else { -0.0 }
    }

    /// A unit axis direction with random sign and zeros of random sign.
    fn axis_dir(&mut self) -> Vec3 {
        let axis = self.below(3) as usize;
        let mut d = Vec3::new(self.zero(), self.zero(), self.zero());
        d[axis] = if self.below(2) == 0 { 1.0 } else { -1.0 };
        d
    }
}

/// A packet whose lane `i` is `rays[i]`, or inactive and full of NaN.
fn packet(rays: &[Option<Ray>; LANES]) -> RayPacket {
    let get = |f: &dyn Fn(&Ray) -> f32| Vf::from(rays.map(|r| r.as_ref().map_or(f32::NAN, f)));
    let org = [0, 1, 2].map(|a| get(&|r| r.org[a]));
    let dir = [0, 1, 2].map(|a| get(&|r| r.dir[a]));
    let mut active = 0;
    for (i, r) in rays.iter().enumerate() {
        if r.is_some() {
            active |= 1 << i;
        }
    }
    RayPacket {
        org,
        dir,
        inv_dir: dir.map(|d| Vf::ONE / d),
        t_min: get(&|r| r.t_min),
        t_max: get(&|r| r.t_max),
        active: mask_from_bits(active),
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
fn check(
    kernel: &str,
    what: &str,
    rays: &[Option<Ray>; LANES],
    scalar: impl Fn(&Ray) -> Option<(f32, f32, f32)>,
    got: LaneHits,
) {
    let mask = got.mask.to_bitmask();
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
        let have = (mask & (1 << i) != 0).then(|| {
            (
                got.t.as_array()[i],
                got.u.as_array()[i],
                got.v.as_array()[i],
            )
        });
        assert_eq!(
            bits3(want),
            bits3(have),
            "{kernel} lane {i} on {what}\n  ray: {}\n  scalar: {want:?}\n  packet: {have:?}",
            show(r)
        );
    }
    let sentinel = HitPacket {
        t: Vf::from([f32::NAN, 7.0, f32::INFINITY, -0.0]),
        u: Vf::splat(0.5),
        v: Vf::splat(-0.5),
        prim: Vu::from([1, 2, NO_HIT, 4]),
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
            let take = Hit::is_closer(got.t.as_array()[i], 3, &before);
            let want = if take { got.t.as_array()[i] } else { before.t };
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
fn lanes(rng: &mut Rng, mut make: impl FnMut(&mut Rng) -> Ray) -> [Option<Ray>; LANES] {
    let keep = 1 + rng.below((1 << LANES) - 1);
    std::array::from_fn(|i| {
        let r = make(rng);
        (keep & (1 << i) != 0 || rng.below(4) != 0).then_some(r)
    })
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
            let s = rng.unit();
            let (p, q) = [(a, b), (b, c), (c, a)][rng.below(3) as usize];
            p + (q - p) * s
        }
        _ => {
            let (mut u, mut v) = (rng.unit(), rng.unit());
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
        1 => Ray::new(target, rng.dir(), t_min.max(0.0), t_max),
        2 => Ray::new(rng.vec(-3.0, 3.0), rng.dir(), t_min, t_max),
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
fn run_kernel<P: std::fmt::Debug>(
    kernel: &str,
    seed: u64,
    prim: impl Fn(&mut Rng, usize) -> P,
    ray: impl Fn(&mut Rng, &P) -> Ray,
    scalar: impl Fn(&P, &Ray) -> Option<(f32, f32, f32)>,
    packet_test: impl Fn(&P, &RayPacket) -> LaneHits,
) {
    let mut rng = Rng(seed);
    let mut hits = 0;
    for n in 0..PACKETS {
        let p = prim(&mut rng, n);
        let rays = lanes(&mut rng, |rng| ray(rng, &p));
        let got = packet_test(&p, &packet(&rays));
        hits += got.mask.to_bitmask().count_ones();
        check(kernel, &format!("{p:?}"), &rays, |r| scalar(&p, r), got);
    }
    assert!(
        hits > PACKETS as u32,
        "{kernel}: too few hits ({hits}) to test anything"
    );
}

#[test]
fn triaccel_packet_matches_scalar() {
    run_kernel(
        "TriAccel::intersect_packet",
        0x7121,
        |rng, n| {
            let tri = random_triangle(rng);
            (tri, TriAccel::new(tri[0], tri[1], tri[2], n as u32))
        },
        |rng, (tri, _)| {
            let p = point_on(rng, *tri);
            ray_at(rng, p)
        },
        |(_, acc), r| acc.intersect(r, r.t_max),
        |(_, acc), p| acc.intersect_packet(p, p.active, p.t_max),
    );
}

#[test]
fn sphere_packet_matches_scalar() {
    run_kernel(
        "intersect_sphere_packet",
        0x5e7e,
        |rng, _| Sphere {
            center: rng.vec(-1.0, 1.0),
            radius: rng.range(0.05, 1.5),
        },
        |rng, s| {
            let on = s.center + rng.dir() * s.radius;
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
        |s, p| intersect_sphere_packet(s, p, p.active, p.t_max),
    );
}

#[test]
fn box_packet_matches_scalar() {
    run_kernel(
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
        |bx, p| intersect_box_packet(bx, p, p.active, p.t_max),
    );
}

#[test]
fn plane_packet_matches_scalar() {
    run_kernel(
        "intersect_plane_packet",
        0x91a7e,
        |rng, _| Plane {
            normal: if rng.below(2) == 0 {
                rng.axis_dir()
            } else {
                rng.dir()
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
        |pl, p| intersect_plane_packet(pl, p, p.active, p.t_max),
    );
}

#[test]
fn merge_breaks_ties_toward_the_smaller_id() {
    let mut best = HitPacket::miss();
    let all: Mask = mask_from_bits((1 << LANES) - 1);
    let at = |t: f32| LaneHits {
        mask: all,
        t: Vf::splat(t),
        u: Vf::ZERO,
        v: Vf::ZERO,
    };
    best.merge(&at(2.0), 9);
    best.merge(&at(2.0), 12);
    assert_eq!(best.prim.to_array(), [9; LANES], "equal t, larger id loses");
    best.merge(&at(2.0), 4);
    assert_eq!(best.prim.to_array(), [4; LANES], "equal t, smaller id wins");
    best.merge(&at(1.0), NO_HIT - 1);
    assert_eq!(best.prim.to_array(), [NO_HIT - 1; LANES], "smaller t wins");
}
