//! Inputs found by the cargo-fuzz targets of fuzz/ (see fuzz/README.md), kept as named
//! tests with the input inline so `cargo test` keeps them fixed without the fuzzer. Each
//! replays its target's checks on the input the fuzzer reported (as printed by
//! `cargo fuzz fmt TARGET ARTIFACT`).

mod common;

use common::hit_bits;
use glam::Vec3;
use raypack::accel::Accel;
use raypack::accel::brute::BruteForce;
use raypack::accel::kdtree::KdTree;
use raypack::accel::packet::RayPacket;
use raypack::ray::Ray;
use raypack::scene::{Aabb, Geometry, Plane, Sphere};
use raypack::simd::W16;

/// The `kdtree` target's input (`snap` false; the shrunk inputs never snapped).
struct KdInput {
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u8; 3]>,
    extras: bool,
    rays: Vec<([f32; 3], [f32; 3], f32, f32)>,
}

/// The `kdtree` target: the scene it builds (triangles, then with `extras` a sphere at
/// the first vertex, a box at the middle one and a plane through the last), and the
/// kd-tree's scalar and packet answers equal brute force's bit for bit.
fn check_kdtree(input: KdInput) {
    let mut g = Geometry {
        vertices: input.vertices.iter().map(|&a| Vec3::from(a)).collect(),
        ..Geometry::default()
    };
    let n = g.vertices.len() as u32;
    g.triangles = input
        .triangles
        .iter()
        .map(|t| t.map(|i| i as u32 % n))
        .collect();
    if input.extras {
        g.spheres.push(Sphere {
            center: g.vertices[0],
            radius: 0.75,
        });
        let b = g.vertices[n as usize / 2];
        g.boxes.push(Aabb::new(b, b + Vec3::new(0.5, 0.0, 1.0)));
        g.planes.push(Plane {
            normal: Vec3::Y,
            offset: g.vertices[n as usize - 1].y,
        });
    }
    let tree = KdTree::build(&g);
    tree.validate().expect("the tree validates");
    let brute = BruteForce::new(&g);
    let rays: Vec<Ray> = input
        .rays
        .iter()
        .map(|&(o, d, t_min, t_max)| Ray::new(Vec3::from(o), Vec3::from(d), t_min, t_max))
        .collect();
    let isas = common::isas();
    for (isa, chunk) in isas
        .iter()
        .flat_map(|&i| rays.chunks(16).map(move |c| (i, c)))
    {
        let packet = RayPacket::<W16>::from_rays(chunk);
        let (hits, occluded) = isa
            .scope(|| {
                (
                    tree.intersect_packet(&packet),
                    tree.occluded_packet(&packet),
                )
            })
            .expect("a supported instruction set");
        for (i, ray) in chunk.iter().enumerate() {
            let want = brute.intersect(ray);
            assert_eq!(
                hit_bits(tree.intersect(ray)),
                hit_bits(want),
                "kd-tree: {ray:?}"
            );
            let lane = hits.lane(i);
            assert_eq!(
                hit_bits(lane.is_hit().then_some(lane)),
                hit_bits(want),
                "packet: {ray:?}"
            );
            let blocked = brute.occluded(ray);
            assert_eq!(tree.occluded(ray), blocked, "occluded: {ray:?}");
            assert_eq!(
                occluded & (1 << i) != 0,
                blocked,
                "packet occluded: {ray:?}"
            );
        }
    }
}

/// kdtree crash-a672b1a1 (one of 47 artifacts of the first run, all alike): a ray with a
/// NaN `t_max` hit the plane in the kd-tree's scalar path (`best.t.min(NaN)` dropped
/// the NaN), while brute force and the packet path answered no hit.
#[test]
fn kdtree_nan_t_max_misses_the_plane() {
    check_kdtree(KdInput {
        vertices: vec![[3.622e-42, 7.909915e-24, 4.135908e-25]],
        triangles: vec![],
        extras: true,
        rays: vec![(
            [-8.0, 5.877943e-39, -2109888.0],
            [2.1381e-41, -3919417.5, 3.486075e-27],
            -5.7368214e-7,
            f32::NAN,
        )],
    });
}

/// kdtree crash-59ec9b7e: the same with a triangle before the sphere, box and plane (the
/// plane is prim 3).
#[test]
fn kdtree_nan_t_max_misses_the_plane_after_a_triangle() {
    check_kdtree(KdInput {
        vertices: vec![[3.622e-42, 1.435e-42, 1.4708e-41]],
        triangles: vec![[0, 23, 175]],
        extras: true,
        rays: vec![(
            [7.915083e-24, -2.1150853e-17, 2.807019e-26],
            [-2.3612374e38, 5.9950212e-36, -3.6650402e-23],
            7.3668304e-33,
            f32::NAN,
        )],
    });
}

/// Not found by the fuzzer, found beside the NaN `t_max` case while fixing it: a ray
/// with an infinite direction component along a plane's normal gets `t = 0` on the
/// plane, so brute force's `occluded` and every path's plane test said "hit" for a ray
/// that the accelerator interface says hits nothing.
#[test]
fn kdtree_infinite_direction_misses_the_plane() {
    check_kdtree(KdInput {
        vertices: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        triangles: vec![[0, 1, 2]],
        extras: true,
        rays: vec![
            ([0.25, 5.0, 0.25], [0.0, f32::NEG_INFINITY, 0.0], -1.0, 10.0),
            ([0.25, 5.0, 0.25], [0.0, -1.0, 0.0], -1.0, 10.0),
            ([0.25, 5.0, 0.25], [0.0, -1.0, 0.0], 0.0, f32::NAN),
            ([0.25, 5.0, 0.25], [0.0, 0.0, 0.0], 0.0, 10.0),
        ],
    });
    let g = Geometry {
        planes: vec![Plane {
            normal: Vec3::Y,
            offset: 0.0,
        }],
        ..Geometry::default()
    };
    let ray = Ray::new(
        Vec3::new(0.0, 5.0, 0.0),
        Vec3::NEG_Y * f32::INFINITY,
        -1.0,
        10.0,
    );
    assert!(!BruteForce::new(&g).occluded(&ray));
    assert!(BruteForce::new(&g).intersect(&ray).is_none());
}

/// The OBJ loader on the bytes of `text`, written to a file as the `obj` target does.
fn load_obj(
    test: &str,
    text: &str,
) -> Result<raypack::scene::obj::ObjMesh, raypack::scene::ObjError> {
    let path = std::env::temp_dir().join(format!("raypack-fuzz-{test}-{}.obj", std::process::id()));
    std::fs::write(&path, text).unwrap();
    let result = raypack::scene::obj::load(&path);
    std::fs::remove_file(&path).unwrap();
    result
}

/// obj corpus entry 10b97e63 (shrunk by removing lines): a face pointing forward to a
/// vertex defined after a `g` line. The line scan allowed forward indices, `tobj` closes
/// the mesh at `g` and refused it as "face vertex index out of bounds", naming no line.
/// Now the face's own line is reported.
#[test]
fn obj_forward_index_past_a_group_names_its_line() {
    let text = "v 0 1 0\nf 11 2 2 3\ng 1 2 0\nv 2 0 0\nv 1 0 0\nv 0 1 0\nv 0 1 0\n\
                v 0 1 0\nv 0 1 0\nv 0 0 0\nv 1 0 0\nv 0 1 00.176777\nv 2 0 0";
    let e = load_obj("forward", text).expect_err("a forward index loads");
    assert!(
        matches!(
            e,
            raypack::scene::ObjError::IndexOutOfRange {
                line: 2,
                index: 11,
                count: 1,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        e.to_string().contains(":2: f: index 11 is out of range"),
        "{e}"
    );
}

/// A ray at extreme magnitudes (origin 9.2e36 from the scene along -z, an unnormalised
/// direction, a `t` range wholly negative) grazing a sliver of a triangle that lies
/// almost in the plane y = 0 (artifact crash-22fab4bc): brute force hit triangle 2 and
/// the kd-tree's scalar path missed it. Fixed by the origin margins (`max_abs` of the origin); the
/// direction (3.7e19) is now also past `DIR_MAX`, so every path answers "no hit".
#[test]
fn kdtree_extreme_grazing_ray_behind_the_origin() {
    check_kdtree(KdInput {
        vertices: vec![
            [3.77507e-34, 2.8004812e-34, 1.0177144e-34],
            [2.6140072e-23, 1.0014031e-34, 2.1112888],
            [-3.195705e-10, 6.383234e-27, 1.838529e-9],
            [-9.812811e-30, 6.383234e-27, 1.0210487e-34],
            [39423.984, 3.2940758e-23, 1.3957111e-17],
        ],
        triangles: vec![
            [252, 50, 71],
            [7, 71, 175],
            [221, 252, 19],
            [184, 7, 7],
            [252, 255, 25],
            [175, 74, 31],
        ],
        extras: false,
        rays: vec![
            (
                [-6084.4375, 7.873303e29, 3.5362987e-34],
                [6.2187e-40, 9.738125e-35, 68111.836],
                -3.19325e-10,
                -9.208487e36,
            ),
            (
                [2.9416464e-8, 1.4973235e-34, -9.208487e36],
                [2.7758755e-34, 1.658137e-36, -3.689298e19],
                -3.2263715e19,
                -1.2303712e-10,
            ),
            (
                [9000859300000000.0, f32::NAN, 3.57e-43],
                [0.0, 0.0, 0.0],
                0.0,
                0.0,
            ),
        ],
    });
}

/// Artifact crash-28394ac9 of the `kdtree` target's second run: the kd-tree disagreed with
/// brute force on a ray at extreme magnitudes; fixed by the origin margins (`max_abs` of the origin).
#[test]
fn kdtree_far_origin_grazing_ray_2() {
    check_kdtree(KdInput {
        vertices: vec![
            [3.77507e-34, 2.8004812e-34, 1.0177144e-34],
            [7.4503e-41, 1.0055766e-34, 42783.355],
            [5.51274e-39, 129650690.0, -0.15967076],
            [-472893300000000.0, -474644050000000.0, -474644050000000.0],
            [9.3678e-41, 3.372861e-20, 51015.027],
            [-8.4e-44, 6.61381e-27, 7.4517175e-9],
        ],
        triangles: vec![[5, 71, 251], [71, 31, 236], [71, 235, 175]],
        extras: false,
        rays: vec![
            (
                [3.2940758e-23, 1.3957111e-17, 6.2195e-40],
                [9.738125e-35, 2.091905e-34, -3.19325e-10],
                -9.208487e36,
                -7.28951e36,
            ),
            (
                [9.70702e-35, 42783.355, 0.00825674],
                [-4.0970467e33, 1.3957111e-17, 1.0459528e-31],
                9.3678e-41,
                3.372861e-20,
            ),
            (
                [1.9530938e-14, 5743528.0, -0.00311435],
                [-1.7126169e18, -1.9983972e18, -1.9983972e18],
                -1.9983972e18,
                -1.7200811e-38,
            ),
            (
                [2.0844536e-27, -3.167264e-10, 4.408457e-31],
                [6e-45, 0.0, 0.0],
                0.0,
                0.0,
            ),
        ],
    });
}

/// Artifact crash-c3c40412 of the `kdtree` target's second run: the kd-tree disagreed with
/// brute force on a ray at extreme magnitudes; fixed by the origin margins (`max_abs` of the origin).
#[test]
fn kdtree_far_origin_grazing_ray_3() {
    check_kdtree(KdInput {
        vertices: vec![
            [3.77507e-34, 2.8004812e-34, -0.13272105],
            [7.666432e-36, 4.827697e-20, 6.54069e-40],
            [9.1576e-41, 4.5918e-41, 1.2221296e-38],
            [-3.1837308e-10, 2.9e-43, 8.4899e-41],
            [9.111465e17, 4.11851e-23, 4.728853e-38],
        ],
        triangles: vec![
            [6, 0, 31],
            [60, 7, 235],
            [133, 7, 0],
            [175, 175, 175],
            [221, 248, 19],
            [175, 252, 49],
            [7, 3, 71],
            [174, 221, 253],
            [125, 186, 7],
            [15, 252, 251],
            [127, 255, 223],
            [223, 223, 223],
            [71, 7, 175],
            [223, 209, 255],
            [89, 61, 255],
            [12, 35, 5],
            [251, 93, 71],
            [59, 154, 202],
        ],
        extras: true,
        rays: vec![
            (
                [2181315.0, 6.21727e-40, -2.6183829e36],
                [-3.6820923e19, -3.2263715e19, -1.2303712e-10],
                f32::NAN,
                -2.5168801e38,
            ),
            (
                [35738665000.0, 4.2217628e-20, 1.8606098e-38],
                [90043.37, -2548.6677, 3.447765e-17],
                -2.2197706e24,
                1.0197707e-34,
            ),
            (
                [-4.2925677e-10, -6.1495164e-15, 2.5987664e-26],
                [34744.027, 3.72027e-40, 0.0],
                0.0,
                0.0,
            ),
        ],
    });
}

/// Artifact crash-cc1a9abd of the `kdtree` target's second run: the kd-tree disagreed with
/// brute force on a ray at extreme magnitudes; fixed by the origin margins (`max_abs` of the origin).
#[test]
fn kdtree_far_origin_grazing_ray_4() {
    check_kdtree(KdInput {
        vertices: vec![
            [3.77507e-34, 2.8004812e-34, 1.0177144e-34],
            [7.4503e-41, 1.0055766e-34, 42783.355],
            [5.51274e-39, -3.6048022e33, -0.1596691],
            [7.666432e-36, 58112.004, 34591.12],
            [5.51274e-39, 4.5918e-41, 2.82681e-40],
            [7.666463e-36, 58363.277, 90072.24],
            [-8.383148e-5, 3.294046e-23, 1.3957111e-17],
        ],
        triangles: vec![
            [6, 0, 31],
            [89, 89, 61],
            [7, 12, 35],
            [71, 251, 99],
            [31, 252, 235],
            [71, 175, 221],
            [255, 255, 255],
            [255, 255, 71],
        ],
        extras: false,
        rays: vec![
            (
                [6.3993117e-27, 1.0210478e-34, 1.3234094e-23],
                [-2.6571527e36, -3.2263715e19, -2.5224255e19],
                8992063000000000.0,
                1.0534001e-34,
            ),
            (
                [-1.0384439e36, -3.3080924e36, -1.8164996e-10],
                [-1.8161424e-10, -1.1262009e-33, -2.3017015e-10],
                -3187.2466,
                7.873303e29,
            ),
            (
                [-6.390837e-36, -1.798154e38, 1.0177165e-34],
                [-3.1933153e-10, -9.208487e36, 4.684712e-16],
                -1.5824237e18,
                -6.0338512e-5,
            ),
            ([6.6575005e-30, 1.453e-42, 0.0], [0.0, 0.0, 0.0], 0.0, 0.0),
        ],
    });
}

/// Artifact crash-7191fd4c of the `kdtree` target's second run: the kd-tree disagreed with
/// brute force on a ray at extreme magnitudes; fixed by the direction range (DIR_MAX).
#[test]
fn kdtree_huge_direction_hits_nothing() {
    check_kdtree(KdInput {
        vertices: vec![
            [3.77507e-34, 2.8004812e-34, 1.0177144e-34],
            [7.4503e-41, 1.0055766e-34, 5.4000186e-25],
            [0.012145996, 129651256.0, -1.7241693e-38],
            [7.666432e-36, 58353.277, 116286.24],
            [5.51274e-39, 4.5918e-41, 1.2221296e-38],
            [7.05917e-40, 2.756e-42, 90073.33],
            [2.616627e-14, 1.2565777e-28, 1.3957111e-17],
        ],
        triangles: vec![
            [6, 0, 31],
            [1, 7, 235],
            [128, 35, 190],
            [6, 159, 31],
            [2, 7, 235],
            [133, 7, 0],
            [175, 175, 175],
            [221, 252, 19],
            [175, 252, 53],
            [175, 5, 7],
            [221, 175, 19],
            [125, 184, 15],
            [15, 255, 0],
            [25, 127, 255],
            [223, 223, 175],
            [175, 71, 179],
        ],
        extras: true,
        rays: vec![
            (
                [3835084500000000.0, 1.047683e-31, -1.03337126e36],
                [-3.3080905e36, -1.8161443e-10, -4.6493245e-8],
                58143.29,
                116286.24,
            ),
            (
                [0.0007172715, 4.5918e-41, 1.2221296e-38],
                [-1.8257016e36, 1.17663e-40, 2.39923e21],
                -6.032768e-5,
                1.0210352e-34,
            ),
            ([1.453e-42, 0.0, 0.0], [0.0, 0.0, 0.0], 0.0, 0.0),
        ],
    });
}

/// Artifact crash-c15b7499 of the `kdtree` target's second run: the kd-tree disagreed with
/// brute force on a ray at extreme magnitudes; fixed by the direction range (DIR_MAX).
#[test]
fn kdtree_huge_direction_hits_nothing_2() {
    check_kdtree(KdInput {
        vertices: vec![
            [2.936917e-8, 5.9042002e-36, 4.2198635e-20],
            [1.0158382e-34, -6.09365e26, 1.035843e-39],
            [7.6664624e-36, 2.9511387e21, -4.2950374e-10],
            [11336072000.0, 4.292018e-20, -1.7200538e-38],
            [6.2195e-40, 9.738125e-35, 2.001627e-34],
        ],
        triangles: vec![
            [175, 175, 175],
            [221, 252, 19],
            [175, 252, 48],
            [7, 5, 71],
            [175, 175, 175],
            [0, 0, 0],
        ],
        extras: false,
        rays: vec![
            (
                [-1.632405e26, -3.9452003e-31, -3.1957145e-10],
                [-6084.483, 1.2234305e37, 6.6575005e-30],
                2.0468026e38,
                -3.2263786e19,
            ),
            (
                [1.5036886e-34, -1.3158117e-36, 0.053056713],
                [7.5911084e-18, -2.1038678e38, -6.0959402e26],
                -1.578782e18,
                -6.528816e-39,
            ),
            (
                [2.0287832e-17, 3.0049854e-35, 6.83387e-40],
                [6.383234e-27, 1.4708232e-8, 6.6574155e-30],
                1.0177195e-34,
                -3.1933153e-10,
            ),
            (
                [6.383234e-27, 4.6576115e-10, -9.208487e36],
                [2.7758755e-34, 6.6575005e-30, 1.378986e-39],
                0.0,
                0.0,
            ),
        ],
    });
}

/// Artifact crash-25527c4e of the `kdtree` target's run with the stream kernels and tiles
/// (found in its scalar check): a ray grazing a sliver (corners about 1e-26 apart on x
/// and y, 4e16 long on z) near a corner. The exact edge rule's terms of `t` underflowed
/// to zero in f32, so brute force reported a hit at `t = 0`, before the kd-tree's box,
/// where the line meets the triangle at `t = 3.2e-27`, past the ray's `t_max`. Fixed by
/// computing the rule in f64 where an edge function or a term of `t` is not a normal
/// f32: every path now answers no hit.
#[test]
fn kdtree_exact_rule_underflow_misses_past_t_max() {
    check_kdtree(KdInput {
        vertices: vec![
            [7.571787e-27, 1.56733e-39, -5.0688257e-26],
            [1.285e-42, 1.49e-43, -6.04157e-26],
            [-6.041655e-26, 2.8982e-41, 4.1680287e16],
        ],
        triangles: vec![[122, 255, 202]],
        extras: false,
        rays: vec![(
            [-6.058369e-26, 1.225e-42, 0.0],
            [18.698038, -6.041655e-26, 1.945832e-13],
            -411206.25,
            1.8439126e-38,
        )],
    });
}

/// Artifact crash-9979e7b1 of the `kdtree` target's second run with the stream kernels
/// and tiles (found in its scalar check): a ray with a tiny direction (4e-17, nearly
/// along -x) grazing a sliver 6e8 long on x and 1e-8 thin on y. The exact edge rule's
/// `t` (0, its terms near 4e18 cancelling) is within rounding of the triangle, as the
/// rule promises, but at a point 2e-10 above the tree's box in y, while the box's
/// margin on y scaled only with y's coordinates (1e-8): brute force hit, the kd-tree's
/// clipped interval was empty. Fixed by scaling the box and plane margins with the
/// box's largest coordinate on any axis. The rays' directions are written as the
/// target passed them (`same_signs`: each takes the first ray's signs).
#[test]
fn kdtree_sliver_grazing_hit_outside_the_box_on_a_thin_axis() {
    check_kdtree(KdInput {
        vertices: vec![
            [-168.93332, -1.15996315e-8, 4.827791e-28],
            [91394.0, 1.1924442e-38, 50944.0],
            [1.6410672e-38, -2.98456e-38, -1.1768035e-35],
            [610181200.0, -1.6991024e-38, 4.4711393e-33],
        ],
        triangles: vec![
            [201, 154, 55],
            [185, 159, 16],
            [90, 20, 21],
            [80, 47, 86],
            [255, 255, 255],
            [255, 255, 255],
            [255, 128, 71],
        ],
        extras: false,
        rays: vec![
            (
                [1.3548744e-7, -1.8437068e28, -0.00012594622],
                [f32::NAN, f32::NAN, -0.00024318694],
                -8.354368e-23,
                9.881476e-12,
            ),
            (
                [9.8439425e-12, 1.9463542e-10, 6.081131e-13],
                [-3.9104265e-17, -4.0391754e-19, -2.6887e-39],
                -1.2218714e-35,
                38135810.0,
            ),
        ],
    });
}
