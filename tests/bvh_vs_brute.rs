//! The 8-wide BVH against the brute-force oracle, ray by ray, under every instruction
//! set this CPU runs: the same closest hit (primitive, `t`, `u`, `v` bit for bit) and
//! the same any-hit answer, one ray at a time, as a stream and in packets of 4, 8 and
//! 16 lanes. The rays include the
//! BVH's own weak spots: origins on its boxes' faces and corners, axis-parallel rays
//! with +0.0 and -0.0 there, subnormal direction components, negative `t_min`, and
//! unusable rays.

mod common;

use common::{adversarial_rays, camera_rays, hit_bits, random_rays};
use glam::Vec3;
use rayon::prelude::*;
use raypack::accel::brute::BruteForce;
use raypack::accel::bvh::Bvh;
use raypack::accel::kdtree::KdTree;
use raypack::accel::{Accel, PacketWidth};
use raypack::ray::{Hit, Ray};
use raypack::scene::generate::{self, Rng};
use raypack::scene::{Aabb, Camera, Geometry, Plane};
use raypack::simd::{Simd, W4, W8, W16};

/// Rays aimed at the BVH's boxes: origins on a face or at a corner of a child box,
/// axis-parallel along the face with signed zeros, and rays with a subnormal or a
/// negative-`t_min` twist.
fn box_rays(bvh: &Bvh, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let boxes: Vec<Aabb> = bvh
        .nodes()
        .iter()
        .flat_map(|n| {
            (0..8).filter_map(move |s| {
                let b = n.child_box(s);
                b.min.is_finite().then_some(b)
            })
        })
        .collect();
    let mut rays = Vec::with_capacity(count);
    if boxes.is_empty() {
        return rays;
    }
    while rays.len() < count {
        let b = boxes[rng.below(boxes.len() as u32) as usize];
        let mut org = rng.point(b.min, b.max);
        let axis = rng.below(3) as usize;
        org[axis] = if rng.below(2) == 0 {
            b.min[axis]
        } else {
            b.max[axis]
        };
        let mut dir = rng.unit_vector();
        match rays.len() % 5 {
            0 => dir[axis] = if rng.below(2) == 0 { 0.0 } else { -0.0 },
            1 => {
                org = if rng.below(2) == 0 { b.min } else { b.max };
                dir = -dir;
            }
            2 => dir[(axis + 1) % 3] = f32::from_bits(1 + rng.below(1 << 20)),
            _ => {}
        }
        let t_min = if rays.len() % 7 == 0 {
            -rng.range(0.0, 2.0) * b.diagonal()
        } else {
            0.0
        };
        rays.push(Ray::new(org, dir, t_min, f32::INFINITY));
    }
    rays.push(Ray::new(Vec3::splat(f32::NAN), Vec3::X, 0.0, f32::INFINITY));
    rays.push(Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, f32::INFINITY));
    rays.push(Ray::new(Vec3::ZERO, Vec3::X, 1.0, 0.5));
    rays
}

/// Brute force's closest hit of a ray, and the any-hit answers of the ray cut short
/// before, at and after it.
type Answers = (Option<Hit>, [(Ray, bool); 3]);

/// [`Answers`] of each ray.
fn oracle(brute: &BruteForce, rays: &[Ray]) -> Vec<Answers> {
    rays.par_iter()
        .enumerate()
        .map(|(i, ray)| {
            let hit = brute.intersect(ray);
            let t = hit.map_or(1.0, |h| h.t);
            let cut = 0.2 + 0.7 * ((i * 7919) % 1000) as f32 / 1000.0;
            let shadows = [t * cut, t, t * (1.0 + cut)].map(|t_max| {
                let s = Ray { t_max, ..*ray };
                (s, brute.occluded(&s))
            });
            (hit, shadows)
        })
        .collect()
}

/// Builds the BVH of `g` and compares it with brute force on random, adversarial,
/// box and camera rays under every instruction set, ray by ray and as streams.
fn check_scene(g: &Geometry, camera: &Camera, seed: u64, ray_count: usize, what: &str) {
    let bvh = Bvh::build(g);
    let brute = BruteForce::new(g);
    let b = g.bounds();
    let b = if b.is_empty() {
        Aabb::new(Vec3::splat(-1.0), Vec3::ONE)
    } else {
        b
    };
    let mut rays = random_rays(b.min, b.max, ray_count, seed);
    rays.extend(adversarial_rays(&KdTree::build(g), g, ray_count, seed + 1));
    rays.extend(box_rays(&bvh, ray_count, seed + 2));
    rays.extend(camera_rays(camera, 64, 48, 1));
    let want = oracle(&brute, &rays);
    let shadows: Vec<Ray> = want.iter().flat_map(|w| w.1.map(|s| s.0)).collect();
    common::each_isa(|| {
        let isa = raypack::simd::Isa::in_use();
        let mut hits = vec![Hit::MISS; rays.len()];
        bvh.intersect_stream(&rays, &mut hits);
        let mut occluded = vec![false; shadows.len()];
        bvh.occluded_stream(&shadows, &mut occluded);
        let mut hit_count = 0;
        for (i, (ray, (hit, cuts))) in rays.iter().zip(&want).enumerate() {
            let one = bvh.intersect(ray);
            assert_eq!(
                hit_bits(one),
                hit_bits(*hit),
                "{what} ({isa}): ray {i} {ray:?}\n  bvh   {one:?}\n  brute {hit:?}"
            );
            assert_eq!(
                hit_bits(hits[i].is_hit().then_some(hits[i])),
                hit_bits(*hit),
                "{what} ({isa}): ray {i} {ray:?} as a stream"
            );
            hit_count += hit.is_some() as usize;
            for (k, (shadow, blocked)) in cuts.iter().enumerate() {
                assert_eq!(
                    bvh.occluded(shadow),
                    *blocked,
                    "{what} ({isa}): shadow ray {i} {shadow:?}"
                );
                assert_eq!(
                    occluded[3 * i + k],
                    *blocked,
                    "{what} ({isa}): shadow ray {i} {shadow:?} as a stream"
                );
            }
        }
        if g.bounded_count() > 0 {
            assert!(
                hit_count > rays.len() / 20,
                "{what}: only {hit_count} hits, rays miss the scene"
            );
        }
    });
    let packet_seed = seed + 3;
    let check = (
        &bvh,
        &brute,
        rays.as_slice(),
        want.as_slice(),
        camera,
        packet_seed,
        what,
    );
    std::thread::scope(|s| {
        s.spawn(|| check_packets::<W4>(check));
        s.spawn(|| check_packets::<W8>(check));
        check_packets::<W16>(check);
    });
}

/// Packets of width `W` for the packet walk, as indices into `rays` followed by the
/// new rays returned (`None` lanes inactive, full of NaN): `rays` a width at a time
/// with some lanes inactive (mostly mixed octants, so most go one ray at a time);
/// camera blocks; and fans, each of one ray of `rays` and copies of it with every
/// nonzero direction component scaled by up to 2% (the same octant, the same zero
/// components, so they walk as one group: origins on box faces, signed zeros,
/// subnormal components), some cut shorter.
fn packets<W: Simd>(
    rays: &[Ray],
    camera: &Camera,
    seed: u64,
) -> (Vec<Vec<Option<usize>>>, Vec<Ray>) {
    let mut rng = Rng::new(seed);
    let mut out: Vec<Vec<Option<usize>>> = (0..rays.len())
        .step_by(W::LANES)
        .map(|first| {
            (first..first + W::LANES)
                .map(|i| Some(i).filter(|&i| i < rays.len() && rng.below(5) != 0))
                .collect()
        })
        .collect();
    let mut extra = Vec::new();
    let mut add = |lanes: Vec<Option<Ray>>| {
        out.push(
            lanes
                .into_iter()
                .map(|r| {
                    r.map(|r| {
                        extra.push(r);
                        rays.len() + extra.len() - 1
                    })
                })
                .collect(),
        )
    };
    let frame = camera.frame(64, 48);
    let (bw, bh) = raypack::scene::camera::block_shape::<W>();
    for y in (0..48 - bh + 1).step_by(bh as usize) {
        for x in (0..64 - bw + 1).step_by(bw as usize) {
            add(frame.block_rays::<W>(x, y).into_iter().map(Some).collect());
        }
    }
    for base in rays.iter().step_by(rays.len() / 250 + 1) {
        add((0..W::LANES)
            .map(|i| {
                if i == 0 {
                    return Some(*base);
                }
                let mut r = *base;
                for a in 0..3 {
                    r.dir[a] *= 1.0 + rng.range(-0.02, 0.02);
                }
                if rng.below(4) == 0 {
                    r.t_max = rng.range(0.0, 2.0);
                }
                Some(r).filter(|_| rng.below(8) != 0)
            })
            .collect());
    }
    (out, extra)
}

/// The packet walk at width `W` against brute force under every instruction set: each
/// active lane's closest hit bit for bit, and the any-hit answers of its ray cut short
/// before, at and after its hit ([`oracle`]); inactive lanes neither hit nor are
/// occluded. `want` holds the answers of `rays`.
fn check_packets<W: PacketWidth>(
    (bvh, brute, rays, want, camera, seed, what): (
        &Bvh,
        &BruteForce,
        &[Ray],
        &[Answers],
        &Camera,
        u64,
        &str,
    ),
) {
    let (packets, extra) = packets::<W>(rays, camera, seed);
    let all: Vec<Ray> = rays.iter().chain(&extra).copied().collect();
    let want: Vec<Answers> = want.iter().copied().chain(oracle(brute, &extra)).collect();
    common::each_isa(|| {
        let what = format!(
            "{what} ({}, {} lanes)",
            raypack::simd::Isa::in_use(),
            W::LANES
        );
        for (n, lanes) in packets.iter().enumerate() {
            let rays: Vec<Option<Ray>> = lanes.iter().map(|i| i.map(|i| all[i])).collect();
            let got = W::intersect(bvh, &common::packet::<W>(&rays));
            let occluded = [0, 1, 2].map(|k| {
                let cut: Vec<Option<Ray>> =
                    lanes.iter().map(|i| i.map(|i| want[i].1[k].0)).collect();
                W::occluded(bvh, &common::packet::<W>(&cut))
            });
            for (i, lane) in lanes.iter().enumerate() {
                let hit = got.lane(i);
                let Some(j) = *lane else {
                    assert!(!hit.is_hit(), "{what}: inactive lane {i} of packet {n} hit");
                    for o in occluded {
                        assert_eq!(o & (1 << i), 0, "{what}: inactive lane {i} occluded");
                    }
                    continue;
                };
                let (closest, cuts) = want[j];
                assert_eq!(
                    hit_bits(hit.is_hit().then_some(hit)),
                    hit_bits(closest),
                    "{what}: packet {n} lane {i} {:?}",
                    all[j]
                );
                for (k, (shadow, blocked)) in cuts.iter().enumerate() {
                    assert_eq!(
                        occluded[k] & (1 << i) != 0,
                        *blocked,
                        "{what}: packet {n} lane {i} cut {k}: {shadow:?}"
                    );
                }
            }
        }
    });
}

// One test per kind of stress scene, each through `check_stress`.
crate::stress_tests!();

/// [`check_scene`] on each of [`common::stress_scenes`]`(kind)`.
fn check_stress(kind: &str) {
    for s in common::stress_scenes(kind) {
        check_scene(&s.geometry, &s.camera, s.seed, s.rays, &s.what);
    }
}

#[test]
fn every_shipped_scene_matches_brute_force() {
    for (i, path) in common::shipped_scenes().iter().enumerate() {
        let scene =
            raypack::scene::file::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        check_scene(
            &scene.geometry,
            &scene.camera,
            200 + i as u64,
            1_000,
            &path.display().to_string(),
        );
    }
}

#[test]
fn bunny_matches_brute_force() {
    require_scenes!();
    let (g, camera) = common::shared_scene("bunny");
    check_scene(&g, &camera, 51, 2_000, "bunny");
}

#[test]
fn empty_and_planes_only_scenes() {
    let mut g = Geometry::default();
    let camera = Camera {
        eye: Vec3::new(0.0, 1.0, -5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        vfov_deg: 60.0,
    };
    let bvh = Bvh::build(&g);
    assert!(bvh.nodes().is_empty());
    assert!(bvh.intersect(&camera_rays(&camera, 4, 4, 1)[0]).is_none());
    g.planes.push(Plane {
        normal: Vec3::Y,
        offset: 0.0,
    });
    let bvh = Bvh::build(&g);
    let brute = BruteForce::new(&g);
    let rays = camera_rays(&camera, 32, 32, 1);
    let hits = rays.iter().filter(|r| bvh.intersect(r).is_some()).count();
    assert!(hits > 0 && hits < rays.len());
    for r in &rays {
        assert_eq!(hit_bits(bvh.intersect(r)), hit_bits(brute.intersect(r)));
        assert_eq!(bvh.occluded(r), brute.occluded(r));
    }
}

/// The build does not depend on the number of threads: a one-thread pool, the
/// global pool and the serial build give the same nodes, bit for bit, on a soup large
/// enough that its top nodes bin and partition in jobs; and that tree answers as
/// brute force does.
#[test]
fn parallel_build_equals_serial() {
    let g = generate::random_soup(90_000, 0.02, 9);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| Bvh::build(&g));
    let serial = Bvh::build_with(&g, false);
    let parallel = Bvh::build(&g);
    let bits = |b: &Bvh| -> Vec<u32> {
        b.nodes()
            .iter()
            .flat_map(|n| {
                n.planes
                    .iter()
                    .flatten()
                    .map(|x| x.to_bits())
                    .chain(n.child)
            })
            .collect()
    };
    assert!(serial.nodes().len() > 100);
    assert_eq!(bits(&serial), bits(&parallel));
    assert_eq!(bits(&one_thread), bits(&parallel));
    let b = g.bounds();
    let mut rays = random_rays(b.min, b.max, 200, 90);
    rays.extend(box_rays(&parallel, 200, 91));
    let brute = BruteForce::new(&g);
    let mut hits = vec![Hit::MISS; rays.len()];
    parallel.intersect_stream(&rays, &mut hits);
    for (ray, hit) in rays.iter().zip(&hits) {
        let want = brute.intersect(ray);
        assert_eq!(
            hit_bits(hit.is_hit().then_some(*hit)),
            hit_bits(want),
            "{ray:?}"
        );
    }
}

/// The statistics count what the tree holds: every triangle of a soup in one leaf,
/// leaves within their size limit, the root's box priced at one step, and each child
/// box inside the root's (so no leaf costs more than the root).
#[test]
fn stats_count_the_tree() {
    let mut g = generate::random_soup(5_000, 0.05, 3);
    // Without the soup's collinear triangles, which the build leaves out.
    let mut i = 0;
    g.triangles.retain(|_| {
        i += 1;
        (i - 1) % 97 != 13
    });
    let bvh = Bvh::build(&g);
    let s = bvh.stats();
    assert_eq!(s.nodes, bvh.nodes().len());
    let placed = (s.leaves as f64 * s.mean_leaf).round() as usize;
    assert_eq!(placed, g.triangles.len());
    assert!(s.mean_leaf >= 1.0 && s.mean_leaf <= raypack::accel::bvh::MAX_LEAF as f64);
    assert!(s.fill > 0.0 && s.fill <= 1.0);
    assert!(s.depth >= 2, "5000 triangles in one level: {s:?}");
    assert!(s.sah_nodes >= 1.0 && s.sah_nodes < s.nodes as f64, "{s:?}");
    assert!(
        s.sah_leaves > 0.0 && s.sah_leaves < s.leaves as f64,
        "{s:?}"
    );
    assert_eq!(Bvh::build(&Geometry::default()).stats().leaves, 0);
}
