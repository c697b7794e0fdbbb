//! Self-intersection: secondary rays start off the surface by an offset that scales with
//! the scene, so the same scene at 1e-4, 1 and 1e4 times its size shows no shadow acne
//! (lit ground pixels that come out shadowed) and no light leaking into the shadow.
//! The ground is a triangle mesh, an infinite plane seen to the horizon (where hit points
//! are far from the origin and the scene's bounded part is small), and that plane alone
//! (no bounded primitive at all, so the offset cannot come from the scene's bounds).

use glam::{DVec3, Vec3};
use raypack::accel::kdtree::KdTree;
use raypack::ray::Ray;
use raypack::render::sample::Pcg32;
use raypack::render::shade::{RayCounts, Shader};
use raypack::scene::{
    AntiAlias, Camera, Geometry, Light, Material, Plane, RenderSettings, Scene, Sphere,
};

const WIDTH: u32 = 200;
const HEIGHT: u32 = 150;
const SPHERE_Y: f32 = 1.2;
const LIGHT: Vec3 = Vec3::new(2.0, 5.0, -1.5);

/// The scene at `scale`: a unit sphere over the ground `y = 0`, a point light, and a low
/// camera looking across the ground.
fn scene(scale: f32, plane_ground: bool, with_sphere: bool) -> Scene {
    let mut geometry = Geometry::default();
    if plane_ground {
        geometry.planes.push(Plane {
            normal: Vec3::Y,
            offset: 0.0,
        });
    } else {
        let r = 60.0 * scale;
        geometry.vertices = vec![
            Vec3::new(-r, 0.0, -r),
            Vec3::new(r, 0.0, -r),
            Vec3::new(r, 0.0, r),
            Vec3::new(-r, 0.0, r),
        ];
        geometry.triangles = vec![[0, 2, 1], [0, 3, 2]];
    }
    if with_sphere {
        geometry.spheres.push(Sphere {
            center: Vec3::new(0.0, SPHERE_Y, 0.0) * scale,
            radius: scale,
        });
    }
    let prims = geometry.prim_count() as usize;
    Scene {
        geometry,
        prim_material: vec![0; prims],
        materials: vec![Material {
            color: Vec3::ONE,
            ..Material::default()
        }],
        lights: vec![Light::Point {
            position: LIGHT * scale,
            color: Vec3::ONE,
        }],
        camera: Camera {
            eye: Vec3::new(0.3, 2.0, -5.0) * scale,
            target: Vec3::new(0.0, 0.4, 1.0) * scale,
            up: Vec3::Y,
            vfov_deg: 60.0,
        },
        settings: RenderSettings {
            width: WIDTH,
            height: HEIGHT,
            max_depth: 2,
            antialias: AntiAlias::None,
            ambient: 0.0,
            ..RenderSettings::default()
        },
        ..Scene::default()
    }
}

/// Ground pixels of `scene` by their exact (f64) shadow state, with a margin of 3% of
/// the radius around the shadow's edge: returns (lit, acne, shadowed, leaks).
fn ground_pixels(scene: &Scene, scale: f32, with_sphere: bool) -> (u32, u32, u32, u32) {
    let tree = KdTree::build(&scene.geometry);
    let shader = Shader::new(scene, &tree);
    let frame = scene.camera.frame(WIDTH, HEIGHT);
    let sphere_prim = scene.geometry.triangles.len() as u32;
    let centre = DVec3::new(0.0, SPHERE_Y as f64, 0.0);
    let light = LIGHT.as_dvec3();
    let (mut lit, mut acne, mut shadowed, mut leaks) = (0, 0, 0, 0);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let ray: Ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(hit) = raypack::accel::Accel::intersect(&tree, &ray) else {
                continue;
            };
            if with_sphere && hit.prim == sphere_prim {
                continue;
            }
            // Where the ray meets y = 0, in f64 and in unit-scale coordinates.
            let (o, d) = (ray.org.as_dvec3() / scale as f64, ray.dir.as_dvec3());
            let p = o + d * (-o.y / d.y);
            let to_light = light - p;
            let s = ((centre - p).dot(to_light) / to_light.length_squared()).clamp(0.0, 1.0);
            let miss_by = if with_sphere {
                (p + to_light * s - centre).length()
            } else {
                f64::INFINITY
            };
            let expected = to_light.normalize().y as f32;
            let (colour, _) =
                shader.trace_primary(&ray, &mut Pcg32::new(1, 1), &mut RayCounts::default());
            if miss_by > 1.03 {
                lit += 1;
                acne += (colour.x < 0.5 * expected) as u32;
            } else if miss_by < 0.97 {
                shadowed += 1;
                leaks += (colour.x > 0.01) as u32;
            }
        }
    }
    (lit, acne, shadowed, leaks)
}

#[test]
fn no_shadow_acne_at_any_scale() {
    let mut failures = Vec::new();
    for (ground, plane_ground, with_sphere) in [
        ("triangle ground", false, true),
        ("plane ground", true, true),
        ("plane alone", true, false),
    ] {
        for scale in [1e-4f32, 1.0, 1e4] {
            let scene = scene(scale, plane_ground, with_sphere);
            let (lit, acne, shadowed, leaks) = ground_pixels(&scene, scale, with_sphere);
            let what = format!(
                "{ground} at scale {scale:e}: {acne} acne of {lit} lit pixels, {leaks} lit of {shadowed} shadowed"
            );
            println!("{what}");
            assert!(
                lit > 5_000 && (shadowed > 300 || !with_sphere),
                "{what}: scene does not test much"
            );
            if acne > 0 || leaks > 0 {
                failures.push(what);
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
