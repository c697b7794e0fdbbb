//! The scalar shader against closed forms: Lambert's N.L, mirrors, Snell's law and total
//! internal reflection, Beer's law through a slab, umbra and penumbra of an area light,
//! planar and per-vertex texture lookups, shading normals, and the sample budgets of
//! importance sampling. Scenes are built in code and traced through brute force.

use glam::{Vec2, Vec3};
use raypack::accel::Mode;
use raypack::accel::brute::BruteForce;
use raypack::ray::{NO_HIT, Ray};
use raypack::render::render;
use raypack::render::sample::{Pcg32, pixel_rng};
use raypack::render::shade::{
    RayCounts, Shader, absorption_coefficient, reflect, refract, transmission,
};
use raypack::scene::{
    Aabb, AntiAlias, Camera, Geometry, Light, Material, Plane, RenderSettings, Scene, Sphere,
    Texture,
};

fn settings(width: u32, height: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        max_depth: 6,
        antialias: AntiAlias::None,
        glossy_samples: 16,
        seed: 1,
        background: Vec3::ZERO,
        ambient: 0.0,
    }
}

fn matte(color: Vec3) -> Material {
    Material {
        color,
        ..Material::default()
    }
}

fn point(position: Vec3) -> Light {
    Light::Point {
        position,
        color: Vec3::ONE,
    }
}

/// Traces one camera ray through `scene` and returns its colour and counts.
fn shade(scene: &Scene, ray: Ray) -> (Vec3, RayCounts, raypack::render::HitSignature) {
    let accel = BruteForce::new(&scene.geometry);
    let shader = Shader::new(scene, &accel);
    let mut counts = RayCounts::default();
    let mut rng = Pcg32::new(9, 9);
    let (c, sig) = shader.trace_primary(&ray, &mut rng, &mut counts);
    (c, counts, sig)
}

fn down_at(x: f32, z: f32) -> Ray {
    Ray::new(Vec3::new(x, 1.0, z), -Vec3::Y, 0.0, f32::INFINITY)
}

fn assert_close(got: Vec3, want: Vec3, tol: f32, what: &str) {
    assert!(
        (got - want).abs().max_element() <= tol,
        "{what}: got {got}, want {want} (tolerance {tol})"
    );
}

/// Where a ray meets a sphere first, in f64 (independent of the f32 intersector).
fn sphere_hit(org: Vec3, dir: Vec3, s: &Sphere) -> Option<glam::DVec3> {
    let (o, d, c) = (org.as_dvec3(), dir.as_dvec3(), s.center.as_dvec3());
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - d.dot(d) * (oc.dot(oc) - (s.radius as f64).powi(2));
    (disc >= 0.0).then(|| o + d * ((-b - disc.sqrt()) / d.dot(d)))
}

#[test]
fn diffuse_sphere_under_a_point_light_follows_n_dot_l() {
    let sphere = Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
    };
    let albedo = Vec3::new(0.8, 0.6, 0.4);
    let light = Vec3::new(4.0, 2.0, -2.0);
    let scene = Scene {
        geometry: Geometry {
            spheres: vec![sphere],
            ..Geometry::default()
        },
        prim_material: vec![0],
        materials: vec![matte(albedo)],
        lights: vec![point(light)],
        camera: Camera {
            eye: Vec3::new(0.0, 0.0, -4.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 40.0,
        },
        settings: RenderSettings {
            background: Vec3::new(0.1, 0.2, 0.3),
            ..settings(48, 48)
        },
        ..Scene::default()
    };
    let accel = BruteForce::new(&scene.geometry);
    let img = render(&scene, &accel, Mode::Scalar, &|| {}).film;
    let frame = scene.camera.frame(48, 48);
    let (mut lit, mut dark, mut missed) = (0, 0, 0);
    for (x, y) in [
        (24, 24),
        (30, 20),
        (16, 30),
        (34, 14),
        (8, 24),
        (10, 34),
        (24, 36),
        (1, 1),
        (40, 10),
    ] {
        let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
        let got = img.get(x, y);
        let Some(p) = sphere_hit(ray.org, ray.dir, &sphere) else {
            assert_eq!(got, scene.settings.background, "pixel ({x},{y}) misses");
            missed += 1;
            continue;
        };
        let n = p.normalize();
        let n_dot_l = n.dot((light.as_dvec3() - p).normalize()).max(0.0) as f32;
        assert_close(got, albedo * n_dot_l, 2e-4, &format!("pixel ({x},{y})"));
        if n_dot_l > 0.05 {
            lit += 1;
        } else if n_dot_l == 0.0 {
            dark += 1;
        }
    }
    assert!(
        lit >= 3 && dark >= 1 && missed >= 1,
        "{lit} {dark} {missed}"
    );
}

#[test]
fn phong_highlight_has_its_own_shadow_and_needs_the_light_in_front() {
    // A floor seen straight down, the light straight above: R = V, so the specular term
    // is exactly `specular` and the diffuse term exactly the albedo.
    let floor = Plane {
        normal: Vec3::Y,
        offset: 0.0,
    };
    let mut m = matte(Vec3::new(0.2, 0.4, 0.6));
    m.specular = 0.5;
    m.shininess = 30.0;
    let mut scene = Scene {
        geometry: Geometry {
            planes: vec![floor],
            ..Geometry::default()
        },
        prim_material: vec![0],
        materials: vec![m],
        lights: vec![point(Vec3::new(0.0, 3.0, 0.0))],
        settings: settings(4, 4),
        ..Scene::default()
    };
    let (c, counts, _) = shade(&scene, down_at(0.0, 0.0));
    assert_close(c, Vec3::new(0.7, 0.9, 1.1), 1e-6, "diffuse + specular");
    assert_eq!(counts.shadow, 1);
    // A small blocker between point and light removes both terms.
    scene.geometry.spheres.push(Sphere {
        center: Vec3::new(0.0, 1.5, 0.0),
        radius: 0.1,
    });
    scene.prim_material = vec![0, 0];
    let (c, _, _) = shade(&scene, down_at(0.0, 0.0));
    assert_eq!(c, Vec3::ZERO);
    // A light below the floor lights neither term.
    scene.geometry.spheres.clear();
    scene.prim_material = vec![0];
    scene.lights = vec![point(Vec3::new(0.0, -3.0, 0.0))];
    let (c, counts, _) = shade(&scene, down_at(0.0, 0.0));
    assert_eq!(c, Vec3::ZERO);
    assert_eq!(
        counts.shadow, 0,
        "no shadow ray toward a light behind the surface"
    );
}

/// A mirror at z = 0 facing the camera and a matte wall at z = -10 behind the camera,
/// lit from (0, 3, -8).
fn mirror_scene(mirror: Material, wall: Vec3) -> Scene {
    Scene {
        geometry: Geometry {
            planes: vec![
                Plane {
                    normal: -Vec3::Z,
                    offset: 0.0,
                },
                Plane {
                    normal: Vec3::Z,
                    offset: -10.0,
                },
            ],
            ..Geometry::default()
        },
        prim_material: vec![0, 1],
        materials: vec![mirror, matte(wall)],
        lights: vec![point(Vec3::new(0.0, 3.0, -8.0))],
        camera: Camera {
            eye: Vec3::new(0.0, 0.0, -5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 50.0,
        },
        settings: settings(16, 16),
        ..Scene::default()
    }
}

#[test]
fn a_mirror_returns_the_reflected_colour() {
    let tint = Vec3::new(0.9, 0.8, 0.7);
    let mirror = Material {
        color: tint,
        diffuse: 0.0,
        reflection: 0.75,
        ..Material::default()
    };
    let wall = Vec3::new(0.3, 0.6, 0.9);
    let scene = mirror_scene(mirror, wall);
    let accel = BruteForce::new(&scene.geometry);
    let shader = Shader::new(&scene, &accel);
    let frame = scene.camera.frame(16, 16);
    let img = render(&scene, &accel, Mode::Scalar, &|| {}).film;
    let light = Vec3::new(0.0, 3.0, -8.0).as_dvec3();
    for (x, y) in [(8, 8), (3, 12), (13, 2), (0, 0)] {
        let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
        let (o, d) = (ray.org.as_dvec3(), ray.dir.as_dvec3());
        let p = o + d * (-o.z / d.z);
        let r = glam::DVec3::new(d.x, d.y, -d.z);
        let q = p + r * ((-10.0 - p.z) / r.z);
        let n_dot_l = (light - q).normalize().z.max(0.0) as f32;
        let want = tint * 0.75 * wall * n_dot_l;
        assert_close(img.get(x, y), want, 1e-4, &format!("pixel ({x},{y})"));
        // The same as looking at the wall point directly, scaled by the mirror.
        let direct = Ray::new(
            Vec3::new(q.x as f32, q.y as f32, -5.0),
            -Vec3::Z,
            0.0,
            f32::INFINITY,
        );
        let mut counts = RayCounts::default();
        let seen = shader
            .trace_primary(&direct, &mut pixel_rng(0, 0, 0, 0), &mut counts)
            .0;
        assert_close(img.get(x, y), tint * 0.75 * seen, 1e-4, "direct view");
    }
    // The signature names the mirror, then the wall it shows.
    let (_, counts, sig) = shade(&scene, frame.ray(8.5, 8.5));
    assert_eq!(sig.prim, 0);
    assert_eq!(sig.secondary, 1);
    assert_eq!(counts.reflection, 1);
}

#[test]
fn recursion_stops_at_max_depth() {
    // Two facing mirrors: every bounce spawns another until the depth limit.
    let mirror = Material {
        diffuse: 0.0,
        reflection: 1.0,
        color: Vec3::ONE,
        ..Material::default()
    };
    let mut scene = mirror_scene(mirror.clone(), Vec3::ONE);
    scene.materials[1] = mirror;
    for depth in [1, 2, 5] {
        scene.settings.max_depth = depth;
        let (_, counts, _) = shade(
            &scene,
            Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, 0.0, 1e9),
        );
        assert_eq!(counts.reflection, depth as u64 - 1, "max_depth {depth}");
    }
}

#[test]
fn refraction_obeys_snell_and_reflects_totally_past_the_critical_angle() {
    let n = Vec3::Y;
    for eta in [1.0f32 / 1.5, 1.0 / 1.33, 1.5, 2.4, 1.0] {
        let critical = if eta > 1.0 {
            (1.0 / eta).asin()
        } else {
            std::f32::consts::FRAC_PI_2
        };
        for k in 0..90 {
            let theta_i = (k as f32 + 0.5).to_radians();
            let phi = k as f32 * 0.7;
            let d = Vec3::new(
                theta_i.sin() * phi.cos(),
                -theta_i.cos(),
                theta_i.sin() * phi.sin(),
            );
            let t = refract(d, n, eta);
            if theta_i < critical - 1e-3 {
                let t = t.unwrap_or_else(|| panic!("eta {eta}: no refraction at {theta_i}"));
                assert!((t.length() - 1.0).abs() < 1e-5);
                assert!(t.dot(n) < 0.0, "transmitted ray crosses the surface");
                let sin_t = t.cross(n).length();
                let sin_i = d.cross(n).length();
                assert!(
                    (sin_t - eta * sin_i).abs() < 1e-5,
                    "Snell: sin_t {sin_t} != {eta} * {sin_i}"
                );
                // In the plane of incidence, on the far side of the normal.
                assert!(t.dot(d.cross(n)).abs() < 1e-5);
                let tangent = d - n * d.dot(n);
                assert!(t.dot(tangent) >= 0.0);
            } else if theta_i > critical + 1e-3 {
                assert_eq!(t, None, "eta {eta}: past the critical angle at {theta_i}");
            }
        }
    }
    // At normal incidence the ray goes straight through.
    assert_eq!(refract(-Vec3::Y, n, 1.0 / 1.5), Some(-Vec3::Y));
    assert_eq!(
        reflect(Vec3::new(1.0, -1.0, 0.0), n),
        Vec3::new(1.0, 1.0, 0.0)
    );
}

#[test]
fn total_internal_reflection_keeps_the_ray_inside_the_glass() {
    // Glass sphere seen from inside at a grazing angle: no refraction ray escapes.
    let glass = Material {
        diffuse: 0.0,
        refraction: 1.0,
        ior: 1.5,
        color: Vec3::ONE,
        ..Material::default()
    };
    let mut scene = Scene {
        geometry: Geometry {
            spheres: vec![Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            }],
            ..Geometry::default()
        },
        prim_material: vec![0],
        materials: vec![glass],
        settings: RenderSettings {
            max_depth: 2,
            background: Vec3::ONE,
            ..settings(4, 4)
        },
        ..Scene::default()
    };
    // A chord at distance 0.9 from the centre meets the surface at 64 degrees from the
    // normal, past glass's critical angle of 41.8 degrees.
    let inside = Ray::new(Vec3::new(-0.2, 0.9, 0.0), Vec3::X, 0.0, f32::INFINITY);
    let (_, counts, _) = shade(&scene, inside);
    assert_eq!((counts.refraction, counts.reflection), (0, 1));
    // Near the centre the angle is small and the ray leaves.
    let centre = Ray::new(Vec3::new(-0.2, 0.1, 0.0), Vec3::X, 0.0, f32::INFINITY);
    let (c, counts, _) = shade(&scene, centre);
    assert_eq!((counts.refraction, counts.reflection), (1, 0));
    assert_eq!(c, Vec3::ONE, "clear glass passes the background unchanged");
    scene.settings.max_depth = 1;
    let (_, counts, _) = shade(&scene, centre);
    assert_eq!(counts.refraction, 0);
}

/// A slab `|x|, |y| < 2`, `0 < z < d` of absorbing, non-bending glass (ior 1) in front of
/// a white background.
fn slab_scene(d: f32, glass: Material) -> Scene {
    Scene {
        geometry: Geometry {
            boxes: vec![Aabb::new(
                Vec3::new(-2.0, -2.0, 0.0),
                Vec3::new(2.0, 2.0, d),
            )],
            ..Geometry::default()
        },
        prim_material: vec![0],
        materials: vec![glass],
        settings: RenderSettings {
            background: Vec3::ONE,
            ..settings(4, 4)
        },
        ..Scene::default()
    }
}

#[test]
fn transmission_through_a_slab_is_exp_minus_c_d() {
    let glass = Material {
        color: Vec3::new(1.0, 0.5, 0.1),
        diffuse: 0.0,
        refraction: 1.0,
        ior: 1.0,
        absorption: 0.8,
        ..Material::default()
    };
    let c = absorption_coefficient(&glass);
    assert_close(
        c,
        Vec3::new(0.0, 0.4, 0.72),
        1e-6,
        "C = absorption (1 - color)",
    );
    for d in [0.25f32, 1.0, 3.0] {
        let scene = slab_scene(d, glass.clone());
        let accel = BruteForce::new(&scene.geometry);
        let shader = Shader::new(&scene, &accel);
        // The inner ray starts `epsilon` inside the front face.
        for slope in [0.0f32, 0.2, 0.3] {
            let dir = Vec3::new(slope, 0.0, 1.0).normalize();
            let ray = Ray::new(Vec3::new(0.0, 0.0, -0.5), dir, 0.0, f32::INFINITY);
            let mut counts = RayCounts::default();
            let got = shader
                .trace_primary(&ray, &mut Pcg32::new(0, 0), &mut counts)
                .0;
            let path = (d - shader.epsilon) / dir.z;
            let want = Vec3::new(
                (-c.x * path).exp(),
                (-c.y * path).exp(),
                (-c.z * path).exp(),
            );
            assert_close(got, want, 1e-5, &format!("d {d} slope {slope}"));
            // Within the offset, the closed form over the slab's full thickness.
            let exact = transmission(c, d / dir.z);
            assert_close(got, exact, 2.0 * shader.epsilon, "exp(-C d)");
            assert_eq!(got.x, 1.0, "a channel with C = 0 is not absorbed");
            assert_eq!((counts.refraction, counts.primary), (2, 1));
        }
    }
}

/// A floor lit by a 1x1 area light at height 4, with a 2x2 blocker at height 2, or
/// without it: then the blocker lies under the floor, so both scenes have the same
/// bounds and hence the same ray offsets.
fn shadow_scene(blocker: bool) -> Scene {
    let y = if blocker { 2.0 } else { -2.2 };
    let geometry = Geometry {
        planes: vec![Plane {
            normal: Vec3::Y,
            offset: 0.0,
        }],
        boxes: vec![Aabb::new(
            Vec3::new(-1.0, y, -1.0),
            Vec3::new(1.0, y + 0.2, 1.0),
        )],
        ..Geometry::default()
    };
    let prim_count = geometry.prim_count() as usize;
    Scene {
        geometry,
        prim_material: vec![0; prim_count],
        materials: vec![matte(Vec3::ONE)],
        lights: vec![Light::Area {
            corner: Vec3::new(-0.5, 4.0, -0.5),
            edge_u: Vec3::X,
            edge_v: Vec3::Z,
            color: Vec3::ONE,
            samples: 16,
        }],
        settings: settings(4, 4),
        ..Scene::default()
    }
}

#[test]
fn area_light_gives_umbra_penumbra_and_full_light() {
    let open = shadow_scene(false);
    let blocked = shadow_scene(true);
    // x = 0 is under the blocker's centre; x = 2 sees half the light past its edge; x = 5
    // sees all of it.
    let (umbra, counts, sig) = shade(&blocked, down_at(0.0, 0.0));
    assert_eq!(umbra, Vec3::ZERO);
    assert_eq!(counts.shadow, 16);
    assert_eq!(sig.lights & 0b11, 0b00);

    let (lit, _, sig) = shade(&blocked, down_at(5.0, 0.0));
    let (unblocked, _, _) = shade(&open, down_at(5.0, 0.0));
    assert!(lit.x > 0.0);
    assert_eq!(lit, unblocked, "nothing between the point and the light");
    assert_eq!(sig.lights & 0b11, 0b11);

    let (half, _, sig) = shade(&blocked, down_at(2.0, 0.0));
    let (full, _, _) = shade(&open, down_at(2.0, 0.0));
    assert!(half.x > 0.0 && half.x < full.x, "penumbra {half} vs {full}");
    assert_eq!(sig.lights & 0b11, 0b01);
    // Rays to the light point (s, 4, t) leave the blocker's level y = 2.2 at
    // x = 0.9 + 0.55 s, so samples with s < 0.18 are blocked: the two columns of strata
    // with s < 0 always, the column above (0, 0.25) mostly, the last never.
    assert!(half.x < 0.6 * full.x, "{half} of {full}");
}

/// A 2x2 texture: red, green / blue, white.
fn checker() -> Texture {
    Texture {
        width: 2,
        height: 2,
        texels: vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE],
    }
}

#[test]
fn planar_texture_lookup_is_the_bilinear_blend() {
    // Floor y = 0: u runs along +x, v along -z. With uv_scale 0.5 the point (0.75, 0, -1.25)
    // looks up (0.375, 0.625), i.e. texel space (0.25, 0.75): the blend
    // 0.25 * (0.75 red + 0.25 green) + 0.75 * (0.75 blue + 0.25 white).
    let mut m = matte(Vec3::ONE);
    m.texture = Some(0);
    m.uv_scale = Vec2::splat(0.5);
    let scene = Scene {
        geometry: Geometry {
            planes: vec![Plane {
                normal: Vec3::Y,
                offset: 0.0,
            }],
            ..Geometry::default()
        },
        prim_material: vec![0],
        materials: vec![m],
        textures: vec![checker()],
        lights: vec![point(Vec3::new(0.75, 5.0, -1.25))],
        settings: settings(4, 4),
        ..Scene::default()
    };
    let (c, _, _) = shade(&scene, down_at(0.75, -1.25));
    assert_close(c, Vec3::new(0.375, 0.25, 0.75), 1e-5, "blend");
}

#[test]
fn meshes_use_per_vertex_uvs_and_interpolated_normals() {
    // One triangle in the floor plane with normals tilted toward +x at every vertex: the
    // shading uses the tilted normal, not the geometric one.
    let tilt = Vec3::new(1.0, 1.0, 0.0).normalize();
    let mut m = matte(Vec3::ONE);
    m.texture = Some(0);
    let scene = Scene {
        geometry: Geometry {
            vertices: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 4.0),
                Vec3::new(4.0, 0.0, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
            ..Geometry::default()
        },
        normals: vec![tilt; 3],
        uvs: vec![
            Vec2::new(0.25, 0.25),
            Vec2::new(0.25, 0.75),
            Vec2::new(0.75, 0.25),
        ],
        prim_material: vec![0],
        materials: vec![m],
        textures: vec![checker()],
        lights: vec![point(Vec3::new(1.0, 100.0, 1.0))],
        settings: settings(4, 4),
        ..Scene::default()
    };
    // At the first vertex's corner, uv = (0.25, 0.25): texel (0, 0), red. Moving toward
    // vertex 2 (u weight) blends in the next texel column.
    let (c, _, sig) = shade(&scene, down_at(0.01, 0.01));
    assert_eq!(sig.prim, 0);
    let n_dot_l = tilt.dot((Vec3::new(1.0, 100.0, 1.0) - Vec3::new(0.01, 0.0, 0.01)).normalize());
    let uv = Vec2::new(0.25, 0.25)
        + Vec2::new(0.5, 0.0) * (0.01 / 4.0)
        + Vec2::new(0.0, 0.5) * (0.01 / 4.0);
    let want = checker().sample(uv.x, uv.y) * n_dot_l;
    assert_close(c, want, 1e-4, "tilted, textured");
    assert!((n_dot_l - std::f32::consts::FRAC_1_SQRT_2).abs() < 0.01);
}

#[test]
fn secondary_bounces_take_fewer_samples() {
    // A mirror floor shows a matte ceiling lit from below by a 16-sample area light: the
    // mirror has no diffuse term, the ceiling point seen in it gets half the samples.
    let mirror = Material {
        diffuse: 0.0,
        reflection: 1.0,
        color: Vec3::ONE,
        ..Material::default()
    };
    let mut scene = shadow_scene(false);
    scene.geometry.planes.push(Plane {
        normal: -Vec3::Y,
        offset: -10.0,
    });
    scene.prim_material = vec![0, 1, 0];
    scene.materials.push(mirror);
    let ray = Ray::new(
        Vec3::new(0.0, 5.0, -5.0),
        Vec3::new(0.0, -1.0, 1.0).normalize(),
        0.0,
        f32::INFINITY,
    );
    let (c, counts, sig) = shade(&scene, ray);
    assert_eq!(sig.prim, 1, "the mirror");
    assert_eq!(sig.secondary, 2, "the ceiling");
    assert!(c.x > 0.0);
    assert_eq!((counts.reflection, counts.shadow), (1, 8));

    // A glossy mirror: 16 cone rays at the first bounce, each lighting its ceiling point
    // with a quarter of the light samples.
    scene.materials[1].glossiness = 0.1;
    let (c, counts, sig) = shade(&scene, ray);
    assert!(c.x > 0.0);
    assert_eq!((counts.glossy, counts.shadow), (16, 16 * 4));
    assert_eq!(counts.reflection, 0);
    assert_eq!(
        sig.secondary, NO_HIT,
        "glossy rays are random, not part of the signature"
    );
}

#[test]
fn a_miss_has_the_background_and_no_signature() {
    let scene = Scene {
        settings: RenderSettings {
            background: Vec3::new(0.5, 0.25, 1.0),
            ..settings(4, 4)
        },
        ..Scene::default()
    };
    let (c, counts, sig) = shade(&scene, down_at(0.0, 0.0));
    assert_eq!(c, Vec3::new(0.5, 0.25, 1.0));
    assert_eq!(sig.prim, NO_HIT);
    assert_eq!(counts.total(), 1);
}

/// Adaptive anti-aliasing compares signatures, so a light's shadow edge must show in
/// them whatever the light's index: here 32 lights see both floor points, and light 32,
/// the 33rd, is blocked at one of them only.
#[test]
fn a_shadow_of_the_33rd_light_changes_the_signature() {
    let mut scene = shadow_scene(true);
    scene.lights = (0..32)
        .map(|k| point(Vec3::new(20.0 + k as f32, 3.0, 20.0)))
        .collect();
    scene.lights.push(point(Vec3::new(0.0, 4.0, 0.0)));
    // x = 0 is under the blocker, which hides light 32 from it; from x = 5 the ray to
    // light 32 passes beside the blocker (at x = 2.5 at its height).
    let (_, counts, shadowed) = shade(&scene, down_at(0.0, 0.0));
    assert_eq!(counts.shadow, 33);
    let (_, _, lit) = shade(&scene, down_at(5.0, 0.0));
    let floor = scene.geometry.prim_count() - 1;
    assert_eq!(
        (shadowed.prim, lit.prim),
        (floor, floor),
        "both on the floor"
    );
    assert_eq!(shadowed.secondary, lit.secondary);
    assert_ne!(shadowed.lights, lit.lights, "{shadowed:?} vs {lit:?}");
    // Lights 0..32 are seen in full by both points: their bits are as before the fold.
    let mut first_32 = scene.clone();
    first_32.lights.truncate(32);
    let (_, _, sig) = shade(&first_32, down_at(0.0, 0.0));
    assert_eq!(sig.lights, u64::MAX);
}
