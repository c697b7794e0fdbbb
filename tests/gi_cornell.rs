//! Global illumination on the benchmark Cornell box (../shared/scenes): both integrators
//! agree block by block within the noise this test measures, colour bleeds, and images
//! do not depend on the thread count.

mod common;

use glam::Vec3;
use raypack::accel::kdtree::KdTree;
use raypack::accel::{Accel, Mode};
use raypack::ray::Hit;
use raypack::render::gi::{GiCounts, GiScene, Integrator, render_gi};
use raypack::render::path::PathTracer;
use raypack::render::photon::{PhotonMapper, PhotonSettings};
use raypack::render::sample::{Sampler, SamplerKind};
use raypack::scene::{Camera, Scene, obj};
use raypack::simd::Isa;
use std::path::Path;

/// The Cornell box as `raypack render cornell_box` loads it ([`Scene::from_obj`], mapped
/// as scenes/README.md says): the camera of cameras.toml, every MTL material Lambertian
/// with albedo `Kd`, the `light` material emitting its `Ka` (20), no other light. `width x height` pixels.
fn cornell(width: u32, height: u32) -> Scene {
    let (entry, path) = raypack::scene::catalog::shared_scene("cornell_box").expect("cameras.toml");
    let (mut scene, _) =
        Scene::from_obj(&path, Camera::from(&entry.view())).expect("load the Cornell box");
    assert!(
        scene.lights.is_empty(),
        "lit by its emissive material alone"
    );
    let mesh = obj::load(&path).expect("load the Cornell box materials");
    scene.settings.width = width;
    scene.settings.height = height;
    let light = mesh.materials.iter().find(|m| m.name == "light").unwrap();
    assert_eq!(light.emission, Vec3::splat(20.0), "the light's Ka 20 20 20");
    scene
}

/// Per block of `block x block` pixels: sum and sum of squares of every sample, and the
/// sample count. The samples of a block are independent given the photon map; pooled,
/// their variance over-estimates that of the stratified block mean, so the standard
/// error drawn from it is conservative.
struct Blocks {
    block: u32,
    across: u32,
    sum: Vec<[f64; 3]>,
    sum2: Vec<[f64; 3]>,
    n: Vec<f64>,
}

impl Blocks {
    fn mean_se(&self, b: usize) -> ([f64; 3], [f64; 3]) {
        let n = self.n[b];
        let mean = self.sum[b].map(|s| s / n);
        let se = std::array::from_fn(|c| {
            ((self.sum2[b][c] / n - mean[c] * mean[c]).max(0.0) / (n - 1.0)).sqrt()
        });
        (mean, se)
    }
}

fn render_blocks(scene: &Scene, integrator: &dyn Integrator, spp: u32, block: u32) -> Blocks {
    let (w, h) = (scene.settings.width, scene.settings.height);
    let frame = scene.camera.frame(w, h);
    let across = w / block;
    let count = (across * (h / block)) as usize;
    let mut out = Blocks {
        block,
        across,
        sum: vec![[0.0; 3]; count],
        sum2: vec![[0.0; 3]; count],
        n: vec![0.0; count],
    };
    let mut counts = GiCounts::default();
    for y in 0..h / block * block {
        for x in 0..across * block {
            let b = ((y / block) * across + x / block) as usize;
            for k in 0..spp {
                let mut sampler =
                    Sampler::new(SamplerKind::Independent, scene.settings.seed, x, y, k);
                let (jx, jy) = sampler.next_2d();
                let ray = frame.ray(x as f32 + jx, y as f32 + jy);
                let l = integrator.radiance(&ray, &mut sampler, &mut counts);
                for c in 0..3 {
                    out.sum[b][c] += l[c] as f64;
                    out.sum2[b][c] += (l[c] as f64).powi(2);
                }
                out.n[b] += 1.0;
            }
        }
    }
    out
}

/// Path tracing (64 samples per pixel) and photon mapping (4 independent photon maps of
/// 125,000 photons, each with 2 samples of 16 gather rays per pixel) of a 40 x 40 Cornell
/// box, compared in 8 x 8 pixel blocks: every block and channel must agree within 4.5
/// combined standard errors, and colour must bleed in both: the white floor near the red
/// wall is redder than near the green wall.
///
/// The path tracer's standard error comes from its samples. The photon mapper's is the
/// larger of the same (over all its samples) and the photon maps' own noise, which every
/// sample of one map shares: the spread of the 4 maps' block means, pooled over all
/// blocks and channels as a relative variance (75 blocks and channels, 3 degrees of
/// freedom each).
#[test]
fn path_and_photon_block_averages_agree_on_the_cornell_box() {
    require_scenes!();
    let scene = cornell(40, 40);
    let accel = KdTree::build(&scene.geometry);
    let pt = PathTracer::new(GiScene::new(&scene, &accel, Vec3::ZERO, None));
    let a = render_blocks(&scene, &pt, 64, 8);
    let replicas: Vec<Blocks> = (0..4u64)
        .map(|seed| {
            let pm = PhotonMapper::new(
                GiScene::new(&scene, &accel, Vec3::ZERO, None),
                PhotonSettings {
                    photons: 125_000,
                    gather: 16,
                    seed,
                    ..PhotonSettings::default()
                },
            );
            render_blocks(&scene, &pm, 2, 8)
        })
        .collect();
    let r = replicas.len() as f64;
    // All replicas' samples in one set of blocks, and the pooled relative variance of one
    // replica's block mean.
    let mut b = Blocks {
        block: a.block,
        across: a.across,
        sum: vec![[0.0; 3]; a.n.len()],
        sum2: vec![[0.0; 3]; a.n.len()],
        n: vec![0.0; a.n.len()],
    };
    let (mut rel, mut dof) = (0.0, 0.0);
    for blk in 0..a.n.len() {
        let means: Vec<[f64; 3]> = replicas.iter().map(|x| x.mean_se(blk).0).collect();
        for c in 0..3 {
            let m = means.iter().map(|x| x[c]).sum::<f64>() / r;
            if m > 0.01 {
                rel += means.iter().map(|x| (x[c] / m - 1.0).powi(2)).sum::<f64>();
                dof += r - 1.0;
            }
        }
        for x in &replicas {
            for c in 0..3 {
                b.sum[blk][c] += x.sum[blk][c];
                b.sum2[blk][c] += x.sum2[blk][c];
            }
            b.n[blk] += x.n[blk];
        }
    }
    let map_rel_se = (rel / dof / r).sqrt();
    eprintln!("photon maps' relative standard error per block: {map_rel_se:.4}");
    let mut worst: f64 = 0.0;
    for blk in 0..a.n.len() {
        let (ma, sa) = a.mean_se(blk);
        let (mb, sb) = b.mean_se(blk);
        for c in 0..3 {
            let sb = sb[c].max(map_rel_se * mb[c]);
            let se = (sa[c] * sa[c] + sb * sb).sqrt();
            let tol = 4.5 * se + 1e-4;
            let z = (ma[c] - mb[c]).abs() / se.max(1e-12);
            worst = worst.max(z);
            assert!(
                (ma[c] - mb[c]).abs() <= tol,
                "block {blk} ({}, {}) channel {c}: path {:.4} +- {:.4}, photon {:.4} +- {:.4}",
                blk as u32 % a.across * a.block,
                blk as u32 / a.across * a.block,
                ma[c],
                sa[c],
                mb[c],
                sb
            );
        }
    }
    eprintln!("largest block difference: {worst:.2} standard errors");
    for blocks in [&a, &b] {
        // Bottom row of blocks: the floor; left block near the red wall, right near the
        // green one. Red minus green flips between them.
        let row = (blocks.n.len() as u32 / blocks.across - 1) * blocks.across;
        let (left, _) = blocks.mean_se(row as usize + 1);
        let (right, _) = blocks.mean_se((row + blocks.across - 2) as usize);
        assert!(
            left[0] - left[1] > right[0] - right[1],
            "no colour bleeding: floor left {left:?}, right {right:?}"
        );
    }
}

/// The same image, bit for bit, on 1 and 3 threads and with camera rays traced in
/// packets or one by one, for both integrators and both samplers.
#[test]
fn gi_images_do_not_depend_on_the_thread_count() {
    require_scenes!();
    let scene = cornell(24, 20);
    let accel = KdTree::build(&scene.geometry);
    for kind in [SamplerKind::Sobol, SamplerKind::Independent] {
        gi_images_agree_across_threads_and_modes(&scene, &accel, kind);
    }
}

fn gi_images_agree_across_threads_and_modes(scene: &Scene, accel: &KdTree, kind: SamplerKind) {
    let render = |threads: usize, photon: bool, mode: Mode| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut gi = GiScene::new(scene, accel, Vec3::ZERO, None);
            gi.sampler = kind;
            if photon {
                let pm = PhotonMapper::new(
                    gi,
                    PhotonSettings {
                        photons: 20_000,
                        gather: 4,
                        ..PhotonSettings::default()
                    },
                );
                render_gi(scene, &pm, 2, mode, &|| ())
            } else {
                render_gi(scene, &PathTracer::new(gi), 5, mode, &|| ())
            }
        })
    };
    for photon in [false, true] {
        let one = render(1, photon, Mode::native_packet());
        let three = render(3, photon, Mode::native_packet());
        let scalar = render(3, photon, Mode::Scalar);
        let bits = |f: &raypack::render::Film| -> Vec<[u32; 3]> {
            f.pixels
                .iter()
                .map(|p| p.to_array().map(f32::to_bits))
                .collect()
        };
        assert_eq!(
            bits(&one.film),
            bits(&three.film),
            "photon: {photon}, {kind:?}"
        );
        assert_eq!(one.counts, three.counts);
        assert_eq!(
            bits(&one.film),
            bits(&scalar.film),
            "packets, photon: {photon}, {kind:?}"
        );
        assert_eq!(
            (scalar.counts.camera_packets, scalar.counts.shadow_packets),
            (0, 0)
        );
        assert_eq!(
            (one.counts.camera, one.counts.total()),
            (scalar.counts.camera, scalar.counts.total())
        );
        assert!(one.counts.camera_packets > 0);
        // Every packet width gives the scalar image, bit for bit.
        for mode in Mode::ALL.into_iter().filter(|&m| m != Mode::Scalar) {
            let packed = render(3, photon, mode);
            assert_eq!(
                bits(&packed.film),
                bits(&scalar.film),
                "{mode}, photon: {photon}, {kind:?}"
            );
        }
        assert!(one.film.pixels.iter().any(|p| p.max_element() > 0.0));
    }
}

/// The path tracer's wavefront (bounces and shadow rays as streams, the camera vertex's
/// shadow rays toward point lights as packets) gives the image of paths traced one by
/// one, bit for bit, with the same ray counts, on every tutorial scene: point and area
/// lights, mirrors, glass with Beer's law, textures, spheres, planes and boxes. Light
/// tracing's caustics too: several of the scenes have mirrors or glass. Every mode
/// under every instruction set this CPU runs, against the scalar mode under its own.
#[test]
fn path_tracer_wavefront_matches_paths_one_by_one_on_every_scene() {
    let mut light_traced = 0;
    for path in common::shipped_scenes() {
        let mut scene =
            raypack::scene::file::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let s = &mut scene.settings;
        let aspect = s.height as f32 / s.width as f32;
        s.width = 67;
        s.height = (67.0 * aspect).round() as u32;
        let accel = KdTree::build(&scene.geometry);
        let render = |mode: Mode, max_bounces: Option<u32>| {
            let gi = GiScene::new(&scene, &accel, scene.settings.background, max_bounces);
            render_gi(&scene, &PathTracer::new(gi), 3, mode, &|| ())
        };
        // The scalar mode under this CPU's own instruction set is the reference.
        let scalar: Vec<_> = [None, Some(2)]
            .map(|max_bounces| render(Mode::Scalar, max_bounces))
            .into();
        for s in &scalar {
            assert!(s.counts.shadow > 0 && s.counts.bounce > 0);
        }
        light_traced += (scalar[0].counts.light > 0) as u32;
        common::each_isa(|| {
            for (max_bounces, scalar) in [None, Some(2)].into_iter().zip(&scalar) {
                for mode in Mode::ALL {
                    let other = render(mode, max_bounces);
                    let name = format!(
                        "{} ({mode}, {}, max bounces {max_bounces:?})",
                        path.display(),
                        Isa::in_use()
                    );
                    assert_eq!(film_bits(&other.film), film_bits(&scalar.film), "{name}");
                    let mut counts = other.counts;
                    counts.camera_packets = 0;
                    counts.shadow_packets = 0;
                    assert_eq!(counts, scalar.counts, "{name}");
                }
            }
        });
    }
    assert!(light_traced > 0, "no scene traced light paths");
}

fn film_bits(f: &raypack::render::Film) -> Vec<[u32; 3]> {
    f.pixels
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

/// The GI scene files of scenes/gi load from ../shared/scenes: the Cornell box lit by its
/// emissive `light` alone, Sponza by a point sun and a sky.
#[test]
fn gi_scene_files_load() {
    require_scenes!(common::scenes_beside_crate());
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gi");
    let cb = raypack::scene::file::load(&dir.join("cornell_box.toml")).unwrap();
    assert!(cb.lights.is_empty());
    assert_eq!(cb.geometry.triangles.len(), 36);
    let emissive = (0..36).filter(|&t| cb.material(t).emission == Vec3::splat(20.0));
    assert_eq!(emissive.count(), 2, "the light quad");
    let sp = raypack::scene::file::load(&dir.join("sponza.toml")).unwrap();
    assert_eq!(sp.geometry.triangles.len(), 262_267);
    assert_eq!(sp.lights.len(), 1);
    assert!(sp.settings.background.min_element() > 0.0);
    // Sponza under the sky alone, every triangle grey Lambertian 0.5.
    let sky = raypack::scene::file::load(&dir.join("sponza_sky.toml")).unwrap();
    assert_eq!(sky.geometry.triangles.len(), 262_267);
    assert!(sky.lights.is_empty());
    assert_eq!(sky.settings.background, Vec3::ONE);
    let grey = sky.material(0);
    assert_eq!(
        (grey.color * grey.diffuse, grey.emission),
        (Vec3::splat(0.5), Vec3::ZERO)
    );
    // The Cornell box with a mirror sphere, a glass sphere and a glossy sphere.
    let spheres = raypack::scene::file::load(&dir.join("spheres.toml")).unwrap();
    assert_eq!(spheres.geometry.triangles.len(), 36);
    assert_eq!(spheres.geometry.spheres.len(), 3);
    let [mirror, glass, gold] = [36, 37, 38].map(|p| spheres.material(p));
    assert_eq!(
        (mirror.reflection, mirror.glossiness, mirror.diffuse),
        (1.0, 0.0, 0.0)
    );
    assert_eq!(
        (glass.refraction, glass.ior, glass.diffuse),
        (1.0, 1.5, 0.0)
    );
    assert_eq!(
        (gold.reflection, gold.glossiness, gold.diffuse),
        (1.0, 0.3, 0.0)
    );
}

/// Each path of the path tracer's wavefront ([`Integrator::radiance_batch`]: a generation's
/// vertices, then its shadow rays and bounce rays as queries) ends with the radiance of
/// the same path traced alone ([`Integrator::radiance`], one vertex and its shadow rays
/// at a time), bit for bit, with the same ray counts: in every mode, under every
/// instruction set, with both samplers (the wavefront draws a generation's Sobol values
/// ahead, in lanes), under a sky (six draws a vertex instead of five) and on Sponza, a
/// mesh large enough that the wavefront asks for hits' surface records ahead.
#[test]
fn path_tracer_wavefront_matches_each_path_traced_alone() {
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files = vec![shipped.join("part3.toml"), shipped.join("part7.toml")];
    if common::scenes_beside_crate().is_some() {
        files.extend(["spheres", "sponza_sky"].map(|s| shipped.join(format!("gi/{s}.toml"))));
    }
    for file in files {
        let scene =
            raypack::scene::file::load(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let accel = KdTree::build(&scene.geometry);
        let (w, h) = (40, 30);
        let frame = scene.camera.frame(w, h);
        for kind in [SamplerKind::Sobol, SamplerKind::Independent] {
            let mut gi = GiScene::new(&scene, &accel, scene.settings.background, None);
            gi.sampler = kind;
            let tracer = PathTracer::new(gi);
            // Two samples of every pixel, as one batch of 2,400 paths.
            let (mut rays, mut samplers) = (Vec::new(), Vec::new());
            for k in 0..2 {
                for y in 0..h {
                    for x in 0..w {
                        let mut s = Sampler::new(kind, scene.settings.seed, x, y, k);
                        let (jx, jy) = s.next_2d();
                        rays.push(frame.ray(x as f32 + jx, y as f32 + jy));
                        samplers.push(s);
                    }
                }
            }
            let mut alone_counts = GiCounts::default();
            let alone: Vec<Vec3> = rays
                .iter()
                .zip(samplers.clone())
                .map(|(ray, mut s)| tracer.radiance(ray, &mut s, &mut alone_counts))
                .collect();
            assert!(alone_counts.shadow > 0 && alone_counts.bounce > 0);
            let first: Vec<Hit> = rays
                .iter()
                .map(|r| accel.intersect(r).unwrap_or(Hit::MISS))
                .collect();
            common::each_isa(|| {
                for mode in Mode::ALL {
                    let mut counts = GiCounts::default();
                    let mut s = samplers.clone();
                    let batch = tracer.radiance_batch(&rays, &first, &mut s, mode, &mut counts);
                    let name = format!("{} ({kind:?}, {mode}, {})", file.display(), Isa::in_use());
                    for (i, (b, a)) in batch.iter().zip(&alone).enumerate() {
                        assert_eq!(
                            b.to_array().map(f32::to_bits),
                            a.to_array().map(f32::to_bits),
                            "{name}: path {i}"
                        );
                    }
                    counts.shadow_packets = 0;
                    assert_eq!(
                        (counts.shadow, counts.bounce),
                        (alone_counts.shadow, alone_counts.bounce),
                        "{name}"
                    );
                }
            });
        }
    }
}

/// The mean of `x` and its standard error.
fn mean_and_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// `spheres` (scenes/gi) as the file has it, and with a glass ball over its light, the
/// emitter inside glass: there light paths cross one refraction that camera paths cross
/// the other way (`Bsdf::adjoint_scale`).
fn spheres_scenes() -> Vec<(&'static str, Scene)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gi/spheres.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let dome = format!(
        "{text}\n[[spheres]]\ncenter = [278.0, 548.8, 279.5]\nradius = 100.0\nmaterial = \"glass\"\n"
    );
    vec![
        (
            "spheres",
            raypack::scene::file::parse(&path, &text).unwrap(),
        ),
        (
            "spheres, light in glass",
            raypack::scene::file::parse(&path, &dome).unwrap(),
        ),
    ]
}

/// Light tracing counts the caustics the path tracer leaves to it (`spheres`: a mirror
/// ball and a glass ball under the ceiling light; paths emitter, delta bounces, one or
/// two smooth surfaces, camera): their mean over the image agrees with what the path
/// tracer alone finds on the same paths, with any number of bounces and with at most
/// two, and with the light in glass, whose light paths cross one refraction the camera's
/// cross the other way (0.44x the path tracer's before `Bsdf::adjoint_scale`). With
/// the same seed the path tracer's paths are the same with light tracing on
/// or off, so the difference of the two images, less the light image, is exactly the
/// path tracer's share of those caustics. 32 seeds; agreement within 5 standard
/// errors, which are small enough to see a fifth too much or too little.
#[test]
fn light_traced_caustics_agree_with_the_path_tracers() {
    require_scenes!();
    let (width, height, spp) = (64, 48, 128);
    let mean = |px: &[Vec3]| {
        px.iter().map(|p| p.element_sum() as f64).sum::<f64>() / (3.0 * px.len() as f64)
    };
    for (i, (name, mut scene)) in spheres_scenes().into_iter().enumerate() {
        scene.settings.width = width;
        scene.settings.height = height;
        let frame = scene.camera.frame(width, height);
        let accel = KdTree::build(&scene.geometry);
        let limits: &[Option<u32>] = if i == 0 { &[None, Some(2)] } else { &[None] };
        for &max_bounces in limits {
            let (mut traced, mut alone) = (Vec::new(), Vec::new());
            for seed in 0..32u64 {
                scene.settings.seed = seed;
                // Light tracing's connections alone: the caustic photons have their own
                // test.
                let gi = || {
                    let mut gi = GiScene::new(&scene, &accel, Vec3::ZERO, max_bounces);
                    gi.caustic_photons = false;
                    gi
                };
                let on = PathTracer::new(gi());
                assert!(on.scene.light_tracing);
                let mut off = PathTracer::new(gi());
                off.scene.light_tracing = false;
                let light = on
                    .light_image(&frame, spp, seed, Mode::Packet8, &mut GiCounts::default())
                    .unwrap();
                let with = render_gi(&scene, &on, spp, Mode::Packet8, &|| ())
                    .film
                    .pixels;
                let without = render_gi(&scene, &off, spp, Mode::Packet8, &|| ())
                    .film
                    .pixels;
                let share: Vec<Vec3> = (0..with.len())
                    .map(|i| without[i] - (with[i] - light[i]))
                    .collect();
                traced.push(mean(&light));
                alone.push(mean(&share));
            }
            let ((a, sa), (b, sb)) = (mean_and_se(&traced), mean_and_se(&alone));
            let name = format!("{name}, max bounces {max_bounces:?}");
            eprintln!(
                "{name}: caustics light traced {a:.6} +- {sa:.6}, path traced {b:.6} +- {sb:.6}"
            );
            let se = (sa * sa + sb * sb).sqrt();
            assert!(
                a > 0.0 && se < 0.04 * a,
                "{name}: too noisy to tell: {a} +- {se}"
            );
            assert!(
                (a - b).abs() < 5.0 * se,
                "{name}: light traced {a} +- {sa}, path traced {b} +- {sb}"
            );
        }
    }
}

/// The caustic photons stand in for the paths the path tracer leaves to them (`spheres`:
/// surfaces seen in the mirror ball or through the glass ball, lit through one of them,
/// and what those surfaces light in turn; with the light in glass, nearly all light on
/// what the mirror and the glass show): over the image their estimate agrees with
/// what the path tracer alone finds on the same camera paths. Three path tracers trace
/// the same samples: one that reads the photons of a light pass, one that leaves those
/// paths out and reads no photons (its light pass never ran), and one that counts the
/// paths itself (`caustic_photons` off). The photons' share is the first less the
/// second, the path tracer's the third less the second. 24 light passes with their own
/// seeds; agreement within 5 standard errors of the difference, which are small enough
/// to see the photons' estimate a fifth too bright or too dark. The estimate's blur is
/// a bias this allows: its radius is small beside the caustics it blurs.
#[test]
fn caustic_photons_agree_with_the_path_tracers() {
    require_scenes!();
    for (name, scene) in spheres_scenes() {
        photons_agree(name, scene);
    }
}

fn photons_agree(name: &str, mut scene: Scene) {
    use rayon::prelude::*;
    let (width, height, spp) = (32u32, 24u32, 160u32);
    // The light pass of a render of this many samples per pixel: its photons are many
    // beside the camera's samples, as in a render at full size.
    const LIGHT_SPP: u32 = 2048;
    scene.settings.width = width;
    scene.settings.height = height;
    let frame = scene.camera.frame(width, height);
    let accel = KdTree::build(&scene.geometry);
    let mean_over_image = |integrator: &PathTracer, seed: u64| -> f64 {
        let sum: f64 = (0..height)
            .into_par_iter()
            .map(|y| {
                let mut counts = GiCounts::default();
                let mut sum = 0f64;
                for x in 0..width {
                    for k in 0..spp {
                        let mut sampler = Sampler::new(SamplerKind::Independent, seed, x, y, k);
                        let (jx, jy) = sampler.next_2d();
                        let ray = frame.ray(x as f32 + jx, y as f32 + jy);
                        let l = integrator.radiance(&ray, &mut sampler, &mut counts);
                        sum += l.element_sum() as f64 / 3.0;
                    }
                }
                sum
            })
            .sum();
        sum / f64::from(width * height * spp)
    };
    let (mut photons, mut paths, mut differences) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 0..24u64 {
        let reading = PathTracer::new(GiScene::new(&scene, &accel, Vec3::ZERO, None));
        assert!(reading.scene.photon_caustics());
        reading
            .light_image(
                &frame,
                LIGHT_SPP,
                seed,
                Mode::Packet8,
                &mut GiCounts::default(),
            )
            .unwrap();
        assert!(reading.caustic_photons().len() > 1000);
        let leaving = PathTracer::new(GiScene::new(&scene, &accel, Vec3::ZERO, None));
        assert!(leaving.caustic_photons().is_empty());
        let mut counting = PathTracer::new(GiScene::new(&scene, &accel, Vec3::ZERO, None));
        counting.scene.caustic_photons = false;
        let (read, left, counted) = (
            mean_over_image(&reading, seed),
            mean_over_image(&leaving, seed),
            mean_over_image(&counting, seed),
        );
        photons.push(read - left);
        paths.push(counted - left);
        differences.push(read - counted);
    }
    let ((a, sa), (b, sb), (d, sd)) = (
        mean_and_se(&photons),
        mean_and_se(&paths),
        mean_and_se(&differences),
    );
    eprintln!(
        "{name}: photons {a:.6} +- {sa:.6}, path traced {b:.6} +- {sb:.6}, \
         difference {d:.6} +- {sd:.6}"
    );
    assert!(
        a > 0.0 && sd < 0.04 * a,
        "{name}: too noisy to tell: {a} +- {sd}"
    );
    assert!(
        d.abs() < 5.0 * sd,
        "{name}: photons {a} +- {sa}, path traced {b} +- {sb}"
    );
}
