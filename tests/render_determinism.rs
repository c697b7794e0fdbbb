//! Whole renders: the image depends on the scene and its seed only, never on the number
//! of threads; adaptive anti-aliasing supersamples exactly the pixels whose hit
//! signature differs from a neighbour's; ray counts add up.

use glam::{Vec2, Vec3};
use raypack::accel::Mode;
use raypack::accel::brute::BruteForce;
use raypack::render::shade::{RayCounts, Shader};
use raypack::render::tiles::{centre_sample, supersample, tiles};
use raypack::render::{Film, Rendered, render};
use raypack::scene::{
    Aabb, AntiAlias, Camera, Geometry, Light, Material, Plane, RenderSettings, Scene, Sphere,
    Texture,
};

/// Every feature at once: a textured floor, a tetrahedron mesh with normals and UVs, an
/// absorbing glass sphere, a glossy sphere, a mirror box, a point and an area light.
fn showcase(antialias: AntiAlias, seed: u64) -> Scene {
    let checker = Texture {
        width: 2,
        height: 2,
        texels: vec![
            Vec3::splat(0.9),
            Vec3::splat(0.2),
            Vec3::splat(0.2),
            Vec3::splat(0.9),
        ],
    };
    let vertices = vec![
        Vec3::new(1.5, 0.0, 1.0),
        Vec3::new(2.5, 0.0, 1.0),
        Vec3::new(2.0, 0.0, 2.0),
        Vec3::new(2.0, 1.2, 1.4),
    ];
    let normals = vertices
        .iter()
        .map(|v| (*v - Vec3::new(2.0, 0.3, 1.4)).normalize())
        .collect();
    let geometry = Geometry {
        vertices,
        triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
        spheres: vec![
            Sphere {
                center: Vec3::new(-1.0, 0.8, 0.0),
                radius: 0.8,
            },
            Sphere {
                center: Vec3::new(0.8, 0.5, -0.8),
                radius: 0.5,
            },
        ],
        boxes: vec![Aabb::new(
            Vec3::new(-2.5, 0.0, 2.0),
            Vec3::new(-1.5, 1.5, 2.5),
        )],
        planes: vec![Plane {
            normal: Vec3::Y,
            offset: 0.0,
        }],
    };
    let materials = vec![
        Material {
            color: Vec3::new(0.9, 0.3, 0.2),
            specular: 0.4,
            texture: Some(0),
            ..Material::default()
        },
        Material {
            color: Vec3::new(0.6, 0.9, 1.0),
            diffuse: 0.0,
            specular: 0.6,
            shininess: 60.0,
            reflection: 0.1,
            refraction: 0.9,
            ior: 1.5,
            absorption: 0.6,
            ..Material::default()
        },
        Material {
            color: Vec3::new(0.9, 0.8, 0.4),
            diffuse: 0.3,
            reflection: 0.7,
            glossiness: 0.15,
            ..Material::default()
        },
        Material {
            color: Vec3::splat(0.95),
            diffuse: 0.1,
            reflection: 0.85,
            ..Material::default()
        },
        Material {
            color: Vec3::ONE,
            texture: Some(0),
            uv_scale: Vec2::splat(0.5),
            ..Material::default()
        },
    ];
    Scene {
        geometry,
        normals,
        uvs: vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.5, 1.0),
            Vec2::new(0.5, 0.5),
        ],
        prim_material: vec![0, 0, 0, 0, 1, 2, 3, 4],
        materials,
        textures: vec![checker],
        lights: vec![
            Light::Point {
                position: Vec3::new(3.0, 5.0, -3.0),
                color: Vec3::splat(0.5),
            },
            Light::Area {
                corner: Vec3::new(-1.0, 4.0, -1.0),
                edge_u: Vec3::new(1.5, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 1.5),
                color: Vec3::splat(0.6),
                samples: 16,
            },
        ],
        camera: Camera {
            eye: Vec3::new(0.5, 2.5, -5.5),
            target: Vec3::new(0.0, 0.6, 0.5),
            up: Vec3::Y,
            vfov_deg: 50.0,
        },
        settings: RenderSettings {
            width: 80,
            height: 70,
            max_depth: 5,
            antialias,
            glossy_samples: 8,
            seed,
            background: Vec3::new(0.1, 0.15, 0.3),
            ambient: 0.05,
        },
    }
}

fn render_on(threads: usize, scene: &Scene) -> Rendered {
    let accel = BruteForce::new(&scene.geometry);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a local rayon pool");
    pool.install(|| render(scene, &accel, Mode::Scalar, &|| {}))
}

fn bits(film: &Film) -> Vec<[u32; 3]> {
    film.pixels
        .iter()
        .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
        .collect()
}

fn first_difference(a: &Film, b: &Film) -> Option<(u32, u32)> {
    let i = bits(a).iter().zip(bits(b)).position(|(x, y)| *x != y)?;
    Some((i as u32 % a.width, i as u32 / a.width))
}

#[test]
fn images_do_not_depend_on_the_thread_count() {
    for aa in [AntiAlias::Adaptive(3), AntiAlias::Full(2), AntiAlias::None] {
        let scene = showcase(aa, 7);
        let one = render_on(1, &scene);
        for threads in [2, 3] {
            let many = render_on(threads, &scene);
            assert_eq!(
                first_difference(&one.film, &many.film),
                None,
                "{aa:?}: 1 thread and {threads} threads differ"
            );
            assert_eq!(one.counts, many.counts, "{aa:?}, {threads} threads");
        }
        // Something is lit, something is in shadow, and every kind of ray was traced.
        let c = one.counts;
        assert!(c.shadow > 0 && c.reflection > 0 && c.refraction > 0 && c.glossy > 0);
        let luma: Vec<f32> = one.film.pixels.iter().map(|p| p.x + p.y + p.z).collect();
        assert!(luma.iter().any(|&l| l > 1.0) && luma.iter().any(|&l| l < 0.3));
    }
}

#[test]
fn the_seed_changes_the_noise_and_only_the_seed() {
    let a = render_on(2, &showcase(AntiAlias::None, 1)).film;
    let again = render_on(2, &showcase(AntiAlias::None, 1)).film;
    let b = render_on(2, &showcase(AntiAlias::None, 2)).film;
    assert_eq!(first_difference(&a, &again), None);
    assert!(
        first_difference(&a, &b).is_some(),
        "area light and glossy use the seed"
    );
}

#[test]
fn ray_counts_follow_the_sampling_mode() {
    let pixels = 80 * 70;
    let none = render_on(2, &showcase(AntiAlias::None, 3)).counts;
    assert_eq!(none.primary, pixels);
    let full = render_on(2, &showcase(AntiAlias::Full(3), 3)).counts;
    assert_eq!(full.primary, 9 * pixels);
    let total = |c: RayCounts| c.primary + c.shadow + c.reflection + c.refraction + c.glossy;
    assert_eq!(full.total(), total(full));
}

#[test]
fn adaptive_supersamples_exactly_where_signatures_differ() {
    let n = 2;
    let scene = showcase(AntiAlias::Adaptive(n), 5);
    let rendered = render_on(2, &scene);
    let (w, h) = (scene.settings.width, scene.settings.height);
    let accel = BruteForce::new(&scene.geometry);
    let shader = Shader::new(&scene, &accel);
    let frame = scene.camera.frame(w, h);
    let seed = scene.settings.seed;
    let mut counts = RayCounts::default();
    let centre: Vec<_> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| centre_sample(&shader, &frame, seed, x, y, &mut counts))
        .collect();
    let mut edges = 0;
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let sig = centre[i].1;
            let edge =
                (x > 0 && centre[i - 1].1 != sig) || (y > 0 && centre[i - w as usize].1 != sig);
            let want = if edge {
                edges += 1;
                supersample(&shader, &frame, seed, (x, y), n, 1, &mut counts)
            } else {
                centre[i].0
            };
            let got = rendered.film.get(x, y);
            assert_eq!(
                [got.x.to_bits(), got.y.to_bits(), got.z.to_bits()],
                [want.x.to_bits(), want.y.to_bits(), want.z.to_bits()],
                "pixel ({x},{y}), edge {edge}: got {got}, want {want}"
            );
        }
    }
    let pixels = (w * h) as u64;
    assert!(edges > 50 && edges < pixels / 2, "{edges} edge pixels");
    // Primary rays: one per pixel, n*n per edge pixel, plus the neighbours' signatures
    // that tiles recompute along their left and top borders.
    let border: u64 = tiles(w, h)
        .iter()
        .map(|t| {
            let left = if t.x0 > 0 { t.height } else { 0 };
            let up = if t.y0 > 0 { t.width } else { 0 };
            (left + up) as u64
        })
        .sum();
    assert_eq!(border, 2 * (32 + 32 + 6) + 2 * 80);
    assert_eq!(
        rendered.counts.primary,
        pixels + edges * (n * n) as u64 + border
    );
}
