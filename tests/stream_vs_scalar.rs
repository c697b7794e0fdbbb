//! The stream queries against the scalar path, ray by ray and bit for bit: each ray of
//! a stream given to `intersect_stream` gets exactly the hit `intersect` returns for it
//! (primitive, `t`, `u`, `v` as bits; a miss as `Hit::MISS`), and each ray given to
//! `occluded_stream` gets `occluded`'s answer, in input order, whatever order the
//! stream kernel works in.
//!
//! Inputs: the standard ray sets (primary, shadow, diffuse) of every scene in scenes/
//! and of the benchmark scenes of ../shared/scenes, the generated stress meshes with
//! random and adversarial rays, and batches built to break a stream kernel: empty, one
//! ray, lengths that are not a multiple of any batch width, unusable rays (NaN or
//! infinite components, zero direction, `t_min > t_max`) mixed among good ones, rays
//! starting exactly on surfaces, and shadow rays cut just before, at and after their
//! hit. Every batch is also traced reversed and cut into uneven pieces.

mod common;

use common::{
    adversarial_rays, camera_rays, hit_bits, looking_at, mixed_primitives, random_rays,
    shared_scene,
};
use glam::Vec3;
use raypack::accel::Accel;
use raypack::accel::brute::BruteForce;
use raypack::accel::kdtree::KdTree;
use raypack::ray::{Hit, Ray};
use raypack::rayset::standard::standard_sets;
use raypack::scene::generate::{self, Rng};
use raypack::scene::{Aabb, Camera, Geometry, Plane, Sphere, View};
use raypack::simd::{Isa, Simd, W4, W8, W16};

/// A hit that is no answer, written into the output first so a ray the stream kernel
/// forgets shows up.
const POISON: Hit = Hit {
    t: -7.0,
    u: 7.0,
    v: 7.0,
    prim: 7,
};

/// The kd-tree with its stream queries always on the lane walks at `width` lanes (4, 8
/// or 16) in `Some(groups)` groups of lanes (1 or 2), or with `None` on its flat queries
/// (a small scene's: every primitive tested, the triangles in lanes) at that width. The
/// tree's own stream queries walk ray by ray when the tree is small, and most test
/// trees are, use the native width only and two groups only in large trees.
struct Lanes<'a>(&'a KdTree, usize, Option<usize>);

impl Lanes<'_> {
    fn hits<W: Simd>(&self, rays: &[Ray], hits: &mut [Hit]) {
        match self.2 {
            Some(groups) => self.0.intersect_lanes_in::<W>(rays, hits, groups),
            None => self.0.intersect_flat_in::<W>(rays, hits),
        }
    }

    fn occluded<W: Simd>(&self, rays: &[Ray], occluded: &mut [bool]) {
        match self.2 {
            Some(groups) => self.0.occluded_lanes_in::<W>(rays, occluded, groups),
            None => self.0.occluded_flat_in::<W>(rays, occluded),
        }
    }
}

/// Every width of the lane walks, tested on every input.
const WIDTHS: [usize; 3] = [4, 8, 16];

/// Both group counts of the lane walks, tested on every input.
const GROUPS: [usize; 2] = [1, 2];

impl Accel for Lanes<'_> {
    fn bounds(&self) -> Aabb {
        self.0.bounds()
    }
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.0.intersect(ray)
    }
    fn occluded(&self, ray: &Ray) -> bool {
        self.0.occluded(ray)
    }
    fn intersect_stream(&self, rays: &[Ray], hits: &mut [Hit]) {
        match self.1 {
            4 => self.hits::<W4>(rays, hits),
            8 => self.hits::<W8>(rays, hits),
            _ => self.hits::<W16>(rays, hits),
        }
    }
    fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool]) {
        match self.1 {
            4 => Lanes::occluded::<W4>(self, rays, occluded),
            8 => Lanes::occluded::<W8>(self, rays, occluded),
            _ => Lanes::occluded::<W16>(self, rays, occluded),
        }
    }
}

/// Asserts the tree's stream queries, and its lane walks (and flat queries, where the
/// tree chose them) at every width, equal the scalar ones on `rays` ([`assert_stream_matches`]; the scalar answers are computed
/// once). Returns the number of closest hits.
fn assert_tree_stream_matches(tree: &KdTree, rays: &[Ray], what: &str) -> usize {
    let want = scalar_answers(tree, rays);
    let mut closest = 0;
    common::each_isa(|| {
        let isa = Isa::in_use();
        for w in WIDTHS {
            for g in GROUPS {
                let how = format!("{what}, {isa}, {w} lanes, {g} groups");
                assert_stream_gives(&Lanes(tree, w, Some(g)), rays, &want, &how);
            }
            if tree.is_flat() {
                let how = format!("{what}, {isa}, flat, {w} lanes");
                assert_stream_gives(&Lanes(tree, w, None), rays, &want, &how);
            }
        }
        closest = assert_stream_gives(tree, rays, &want, &format!("{what}, {isa}"));
    });
    closest
}

/// The scalar answers of `rays`: closest hits as bits (a miss as [`Hit::MISS`]) and
/// any-hit answers.
type Answers = (Vec<Option<(u32, u32, u32, u32)>>, Vec<bool>);

fn scalar_answers<A: Accel + ?Sized>(a: &A, rays: &[Ray]) -> Answers {
    let hits = rays
        .iter()
        .map(|r| hit_bits(Some(a.intersect(r).unwrap_or(Hit::MISS))))
        .collect();
    (hits, rays.iter().map(|r| a.occluded(r)).collect())
}

/// The stream answers of `rays`, in one call.
fn stream_answers<A: Accel + ?Sized>(a: &A, rays: &[Ray]) -> (Vec<Hit>, Vec<bool>) {
    let mut hits = vec![POISON; rays.len()];
    a.intersect_stream(rays, &mut hits);
    // Alternating garbage, so neither a forgotten `true` nor a forgotten `false` passes.
    let mut occluded: Vec<bool> = (0..rays.len()).map(|i| i % 2 == 0).collect();
    a.occluded_stream(rays, &mut occluded);
    (hits, occluded)
}

/// Asserts both stream queries equal the scalar ones on `rays` traced as one stream,
/// reversed, and in uneven pieces. Returns the number of closest hits.
fn assert_stream_matches<A: Accel + ?Sized>(a: &A, rays: &[Ray], what: &str) -> usize {
    assert_stream_gives(a, rays, &scalar_answers(a, rays), what)
}

/// [`assert_stream_matches`] against scalar answers already computed.
fn assert_stream_gives<A: Accel + ?Sized>(
    a: &A,
    rays: &[Ray],
    (want_hits, want_occluded): &Answers,
    what: &str,
) -> usize {
    let check = |rays: &[Ray], want_h: &[Option<(u32, u32, u32, u32)>], want_o: &[bool], how| {
        let (hits, occluded) = stream_answers(a, rays);
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(
                hit_bits(Some(hits[i])),
                want_h[i],
                "{what} ({how}): closest hit of ray {i} {r:?}"
            );
            assert_eq!(
                occluded[i], want_o[i],
                "{what} ({how}): any hit of ray {i} {r:?}"
            );
        }
    };
    check(rays, want_hits, want_occluded, "one stream");
    let rev = |v: &[Ray]| v.iter().rev().copied().collect::<Vec<_>>();
    let (mut wh, mut wo) = (want_hits.clone(), want_occluded.clone());
    wh.reverse();
    wo.reverse();
    check(&rev(rays), &wh, &wo, "reversed");
    let mut start = 0;
    for len in [1usize, 2, 3, 5, 7, 9, 13, 17, 31, 33, 100].iter().cycle() {
        if start >= rays.len() {
            break;
        }
        let end = (start + len).min(rays.len());
        check(
            &rays[start..end],
            &want_hits[start..end],
            &want_occluded[start..end],
            "pieces",
        );
        start = end;
    }
    want_hits
        .iter()
        .filter(|h| h.is_some_and(|h| h.0 != Hit::MISS.prim))
        .count()
}

/// Rays from points exactly on triangles (barycentric interior points and corners), in
/// random directions with `t_min = 0`, and the same with `t_min` a little above 0.
fn rays_from_surfaces(g: &Geometry, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|i| {
            let [p, q, r] = g.triangle(rng.below(g.triangles.len() as u32));
            let org = if i % 4 == 0 {
                p
            } else {
                let (a, b) = (rng.range(0.0, 1.0), rng.range(0.0, 1.0));
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                p + (q - p) * a + (r - p) * b
            };
            let t_min = if i % 3 == 0 { 1e-4 } else { 0.0 };
            Ray::new(org, rng.unit_vector(), t_min, f32::INFINITY)
        })
        .collect()
}

/// Rays no intersector may hit: NaN and infinite components, zero and subnormal
/// directions, `t_min > t_max`, NaN bounds.
fn unusable_rays() -> Vec<Ray> {
    let (o, d) = (Vec3::new(0.5, 0.5, -3.0), Vec3::Z);
    vec![
        Ray::new(Vec3::new(f32::NAN, 0.5, -3.0), d, 0.0, f32::INFINITY),
        Ray::new(o, Vec3::new(0.0, f32::NAN, 1.0), 0.0, f32::INFINITY),
        Ray::new(o, Vec3::new(0.0, 0.0, f32::INFINITY), 0.0, f32::INFINITY),
        Ray::new(
            Vec3::new(f32::NEG_INFINITY, 0.5, 0.5),
            Vec3::X,
            0.0,
            f32::INFINITY,
        ),
        Ray::new(o, Vec3::ZERO, 0.0, f32::INFINITY),
        Ray::new(o, -Vec3::ZERO, 0.0, f32::INFINITY),
        Ray::new(o, Vec3::splat(1e-40), 0.0, f32::INFINITY),
        Ray::new(o, d, 5.0, 1.0),
        Ray::new(o, d, f32::NAN, f32::INFINITY),
        Ray::new(o, d, 0.0, f32::NAN),
        Ray::new(o, d, f32::INFINITY, f32::INFINITY),
    ]
}

/// Usable rays whose direction has a subnormal component (its inverse is infinite, so
/// the lane walks set such a ray up with the scalar code) or a tiny normal one, aimed
/// at the middle of `b` from outside and from its centre.
fn tiny_component_rays(b: &Aabb) -> Vec<Ray> {
    let c = (b.min + b.max) * 0.5;
    let mut out = Vec::new();
    for tiny in [1e-40f32, -1e-40, f32::MIN_POSITIVE, -1e-30] {
        for axis in 0..3 {
            let mut d = Vec3::new(0.6, -0.48, 0.64);
            d[axis] = tiny;
            let d = d.normalize();
            out.push(Ray::new(c, d, 0.0, f32::INFINITY));
            out.push(Ray::new(c - d * b.diagonal(), d, 0.0, f32::INFINITY));
        }
    }
    out
}

/// Shadow rays along camera rays that hit, ending just before, at and just after the
/// hit, and starting at it.
fn cut_rays<A: Accel + ?Sized>(a: &A, rays: &[Ray]) -> Vec<Ray> {
    let mut out = Vec::new();
    for r in rays {
        if let Some(h) = a.intersect(r) {
            for t_max in [h.t.next_down(), h.t, h.t.next_up()] {
                out.push(Ray { t_max, ..*r });
            }
            out.push(Ray::new(r.at(h.t), r.dir, 0.0, f32::INFINITY));
        }
    }
    out
}

/// Good rays with the unusable ones mixed in every few places.
fn mixed_in(good: &[Ray]) -> Vec<Ray> {
    let bad = unusable_rays();
    let mut out = Vec::new();
    for (i, r) in good.iter().enumerate() {
        if i % 5 == 2 {
            out.push(bad[(i / 5) % bad.len()]);
        }
        out.push(*r);
    }
    out.extend(&bad);
    out
}

/// Stacks of 1 to 20 copies of one triangle apart along `z`: a stack of `n` cannot be
/// split, so the kd-tree has leaves of every size from 1 to 20 (more than one group of
/// the stream walks' lanes) with equal-`t` ties between the copies (rays from below
/// along `z` hit them at distinct `t`, the others at equal `t` when the copies coincide:
/// every other stack's copies do).
fn leaf_stacks() -> Geometry {
    let mut g = Geometry::default();
    for n in 1..=20u32 {
        let base = Vec3::new((n % 5) as f32 * 3.0, (n / 5) as f32 * 3.0, 0.0);
        let (a, b, c) = (
            base,
            base + Vec3::new(1.7, 0.2, 0.1),
            base + Vec3::new(0.3, 1.9, -0.2),
        );
        for i in 0..n {
            let dz = if n % 2 == 0 { 0.0 } else { i as f32 * 1e-3 };
            let at = g.vertices.len() as u32;
            g.vertices.extend([a, b, c].map(|p| p + Vec3::Z * dz));
            g.triangles.push([at, at + 1, at + 2]);
        }
    }
    g
}

/// Every kind of batch on one geometry, through the kd-tree and through brute force.
fn check_geometry(g: &Geometry, camera: &Camera, seed: u64, what: &str) {
    let tree = KdTree::build(g);
    let brute = BruteForce::new(g);
    let b = g.bounds();
    let camera_set = camera_rays(camera, 64, 48, 1);
    let mut rays = camera_set.clone();
    rays.extend(random_rays(b.min, b.max, 1_500, seed));
    rays.extend(adversarial_rays(&tree, g, 1_000, seed + 1));
    if !g.triangles.is_empty() {
        rays.extend(rays_from_surfaces(g, 500, seed + 2));
    }
    rays.extend(cut_rays(&tree, &camera_set[..400]));
    rays.extend(tiny_component_rays(&b));
    let rays = mixed_in(&rays);
    let hits = assert_tree_stream_matches(&tree, &rays, &format!("{what}, kd-tree"));
    assert!(
        hits > rays.len() / 10,
        "{what}: only {hits} of {} rays hit",
        rays.len()
    );
    assert_stream_matches(&brute, &rays[..2_000], &format!("{what}, brute force"));
}

/// The standard sets of a scene at `width x height`: every ray of each set.
fn check_standard_sets(g: &Geometry, camera: &Camera, width: u32, height: u32, what: &str) {
    let tree = KdTree::build(g);
    let sets = standard_sets(&tree, g, &View::from(camera), width, height, None)
        .unwrap_or_else(|e| panic!("{what}: standard sets: {e}"));
    for (name, set) in [
        ("primary", &sets.primary),
        ("shadow", &sets.shadow),
        ("diffuse", &sets.diffuse),
    ] {
        assert!(!set.rays.is_empty(), "{what}: empty {name} set");
        assert_tree_stream_matches(&tree, &set.rays, &format!("{what}, {name}"));
    }
}

#[test]
fn empty_and_single_ray_batches() {
    let g = generate::random_soup(200, 0.2, 5);
    let tree = KdTree::build(&g);
    let lanes: Vec<Lanes> = WIDTHS
        .iter()
        .flat_map(|&w| GROUPS.map(|g| Lanes(&tree, w, Some(g))))
        .collect();
    let all: Vec<&dyn Accel> = std::iter::once(&tree as &dyn Accel)
        .chain(lanes.iter().map(|l| l as &dyn Accel))
        .collect();
    for &a in &all {
        let (hits, occluded) = stream_answers(a, &[]);
        assert!(hits.is_empty() && occluded.is_empty());
    }
    let camera = looking_at(&g, Vec3::new(0.2, 0.3, -1.0));
    let rays = camera_rays(&camera, 16, 16, 1);
    let mut hit_one = false;
    for r in rays.iter().chain(&unusable_rays()) {
        assert_tree_stream_matches(&tree, std::slice::from_ref(r), "one ray");
        hit_one |= tree.intersect(r).is_some();
    }
    assert!(hit_one, "no camera ray hits the soup");
    // A stream of unusable rays only.
    let bad = unusable_rays();
    for &a in &all {
        let (hits, occluded) = stream_answers(a, &bad);
        assert!(
            hits.iter()
                .all(|h| hit_bits(Some(*h)) == hit_bits(Some(Hit::MISS)))
        );
        assert!(occluded.iter().all(|&o| !o));
    }
}

#[test]
fn stress_meshes() {
    let soup = generate::random_soup(3_000, 0.1, 3);
    check_geometry(
        &soup,
        &looking_at(&soup, Vec3::new(0.3, 0.4, -1.0)),
        10,
        "soup",
    );
    let sphere = generate::tessellated_sphere(Vec3::new(1.0, 2.0, 3.0), 2.0, 48, 64);
    check_geometry(
        &sphere,
        &looking_at(&sphere, Vec3::new(0.0, 0.2, -1.0)),
        20,
        "sphere",
    );
    let grid = generate::axis_aligned_grid(6);
    check_geometry(
        &grid,
        &looking_at(&grid, Vec3::new(0.7, 0.5, -1.0)),
        30,
        "grid",
    );
    let closed = generate::closed_box(8);
    check_geometry(
        &closed,
        &looking_at(&closed, Vec3::new(0.1, 0.1, -0.2)),
        40,
        "closed box",
    );
    let stacks = leaf_stacks();
    let tree = KdTree::build(&stacks);
    let mut sizes: Vec<u32> = tree
        .nodes()
        .iter()
        .filter(|n| n.is_leaf())
        .map(|n| n.leaf_count())
        .collect();
    sizes.sort_unstable();
    sizes.dedup();
    assert!(
        (1..=20).all(|n| sizes.contains(&n)),
        "stacks: leaf sizes {sizes:?} miss some of 1..=20"
    );
    check_geometry(
        &stacks,
        &looking_at(&stacks, Vec3::new(0.2, -0.3, -1.0)),
        60,
        "leaf stacks",
    );
    let mixed = mixed_primitives();
    check_geometry(
        &mixed,
        &looking_at(&mixed, Vec3::new(0.2, 0.5, -1.0)),
        50,
        "mixed primitives",
    );
}

/// Small scenes, whose trees choose the flat stream queries: a closed room seen from
/// inside (with two degenerate triangles the queries leave out), a soup with exact
/// duplicates (ties of equal `t`), and a soup with spheres, boxes and a plane beside its
/// triangles.
#[test]
fn small_scenes_flat_queries() {
    let mut room = generate::closed_box(2);
    let b = room.bounds();
    let centre = (b.min + b.max) * 0.5;
    let i = room.vertices.len() as u32;
    // A zero-area sliver across the room and a triangle of one repeated corner.
    room.vertices
        .extend([b.min, centre, b.max, centre + Vec3::new(0.1, 0.0, 0.0)]);
    room.triangles
        .extend([[i, i + 1, i + 2], [i + 3, i + 3, i + 3]]);
    let mut soup = generate::random_soup(60, 0.8, 5);
    for t in 0..8 {
        let [a, b, c] = soup.triangle(t * 7);
        let i = soup.vertices.len() as u32;
        soup.vertices.extend([a, b, c]);
        soup.triangles.push([i, i + 1, i + 2]);
    }
    let mut mixed = generate::random_soup(40, 0.8, 6);
    let mut rng = Rng::new(7);
    for _ in 0..2 {
        mixed.spheres.push(Sphere {
            center: rng.point(Vec3::ZERO, Vec3::ONE),
            radius: rng.range(0.02, 0.2),
        });
        let lo = rng.point(Vec3::ZERO, Vec3::ONE);
        mixed
            .boxes
            .push(Aabb::new(lo, lo + rng.point(Vec3::ZERO, Vec3::splat(0.2))));
    }
    mixed.planes.push(Plane {
        normal: Vec3::Y,
        offset: -0.1,
    });
    let b = room.bounds();
    let inside = Camera {
        eye: b.min + (b.max - b.min) * Vec3::new(0.5, 0.5, 0.05),
        target: b.min + (b.max - b.min) * Vec3::new(0.5, 0.5, 1.0),
        up: Vec3::Y,
        vfov_deg: 60.0,
    };
    for (g, camera, seed, what) in [
        (&room, inside, 70, "small room"),
        (
            &soup,
            looking_at(&soup, Vec3::new(0.3, 0.4, -1.0)),
            80,
            "small soup",
        ),
        (
            &mixed,
            looking_at(&mixed, Vec3::new(0.2, 0.5, -1.0)),
            90,
            "small mixed",
        ),
    ] {
        assert!(
            KdTree::build(g).is_flat(),
            "{what}: the tree chose no flat queries"
        );
        check_geometry(g, &camera, seed, what);
    }
}

#[test]
fn every_shipped_scene_standard_sets() {
    let paths = common::shipped_scenes();
    for path in &paths {
        let scene =
            raypack::scene::file::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        check_standard_sets(
            &scene.geometry,
            &scene.camera,
            96,
            64,
            &path.display().to_string(),
        );
    }
}

#[test]
fn shared_scenes_standard_sets() {
    require_scenes!();
    for name in ["cornell_box", "bunny", "conference", "sponza"] {
        let (g, camera) = shared_scene(name);
        check_standard_sets(&g, &camera, 160, 128, name);
    }
}

/// The camera rays of any image size in row-major order are the primary set's rays of
/// the same pixels, and `trace_image` (padded to whole tiles, traced as an image set in
/// every mode) gives each pixel the scalar hit of its ray.
#[test]
fn camera_rays_and_trace_image_of_any_size() {
    use raypack::accel::Mode;
    use raypack::rayset::standard::{camera_rays, primary};
    use raypack::rayset::{pixel_packet_index, trace::trace_image};
    let g = mixed_primitives();
    let view = View::from(&looking_at(&g, Vec3::new(0.3, 0.5, 1.2)));
    let tree = KdTree::build(&g);

    let set = primary(&view, 48, 32).unwrap();
    let rays = camera_rays(&view, 48, 32).unwrap();
    for (i, r) in rays.iter().enumerate() {
        let (x, y) = ((i % 48) as u32, (i / 48) as u32);
        assert_eq!(
            Ray::as_records(&[*r]),
            Ray::as_records(&[set.rays[pixel_packet_index(x, y, 48)]])
        );
    }
    for (w, h) in [(1, 1), (37, 23), (48, 32), (17, 40)] {
        let rays = camera_rays(&view, w, h).unwrap();
        assert_eq!(rays.len(), (w * h) as usize);
        let want: Vec<_> = rays.iter().map(|r| hit_bits(tree.intersect(r))).collect();
        common::each_isa(|| {
            for mode in Mode::ALL {
                let (traced, got) = trace_image(&tree, &view, w, h, mode).unwrap();
                assert_eq!(Ray::as_records(&traced), Ray::as_records(&rays));
                let got: Vec<_> = got
                    .iter()
                    .map(|h| hit_bits(h.is_hit().then_some(*h)))
                    .collect();
                assert!(
                    got == want,
                    "{w}x{h} {mode}: trace_image differs from the scalar hits"
                );
            }
        });
    }
    assert!(camera_rays(&view, 0, 5).is_err());
    assert!(trace_image(&tree, &view, 5, 0, Mode::Tile64).is_err());
}

/// `occluded_into` answers in every mode as the scalar `occluded`, and `auto_mode`
/// takes packets for camera rays and streams for rays in random order.
#[test]
fn occluded_into_every_mode_and_auto_mode() {
    use raypack::accel::Mode;
    use raypack::rayset::standard::camera_rays;
    use raypack::rayset::trace::{Order, auto_mode, occluded_into};
    let g = mixed_primitives();
    let tree = KdTree::build(&g);
    let b = g.bounds();
    let mut rays = random_rays(b.min, b.max, 3000, 77);
    for (i, r) in rays.iter_mut().enumerate() {
        r.t_max = (i % 7) as f32 * 0.2;
    }
    let want: Vec<bool> = rays.iter().map(|r| tree.occluded(r)).collect();
    assert!(want.iter().any(|&o| o) && !want.iter().all(|&o| o));
    common::each_isa(|| {
        for mode in Mode::ALL {
            let mut got = vec![false; rays.len()];
            occluded_into(&tree, &rays, Order::Any, mode, &mut got);
            assert!(
                got == want,
                "{mode}: occluded_into differs from the scalar answers"
            );
        }
    });
    let view = View::from(&looking_at(&g, Vec3::new(0.3, 0.5, 1.2)));
    let camera = camera_rays(&view, 64, 64).unwrap();
    assert_eq!(auto_mode(&camera, b.diagonal()), Mode::native_packet());
    assert_eq!(auto_mode(&rays, b.diagonal()), Mode::Stream);
}
