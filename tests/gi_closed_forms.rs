//! Global illumination against closed forms: the white furnace, irradiance under a small
//! area light and a point light, a mirror, a glossy plane under the sky, a glass slab
//! (with and without Beer's law), and the energy each bounce adds. Both integrators
//! where the closed form applies to both.
//!
//! Every Monte Carlo check measures its own noise: `estimate` returns the mean of `n`
//! samples and its standard error `sqrt(var / n)` from the samples' variance (exact for
//! independent samples; for the Sobol sampler, the default, an upper bound),
//! and the check asserts agreement within `Z` standard errors (plus 1e-4 relative, the
//! f32 rounding of the closed forms); it also asserts that the standard error is small
//! against the expected value, so the check cannot pass by being noisy.

use glam::Vec3;
use raypack::accel::kdtree::KdTree;
use raypack::ray::Ray;
use raypack::render::bsdf::{Bsdf, fresnel_dielectric};
use raypack::render::gi::{GiCounts, GiScene, Integrator};
use raypack::render::path::PathTracer;
use raypack::render::photon::{PhotonMapper, PhotonSettings};
use raypack::render::sample::{Sampler, SamplerKind};
use raypack::scene::{Geometry, Light, Material, Scene};

/// Standard errors allowed between an estimate and its closed form. At 4.5 a correct
/// integrator fails one check per 150,000 or so: never in practice, over the ~40 checks.
const Z: f32 = 4.5;

/// Mean and standard error (per channel) of `n` samples of `integrator` along `ray`,
/// drawn by its sampler kind: independent samples from `n` pixels, or the first `n`
/// points of one pixel's Sobol sequence.
fn estimate(integrator: &dyn Integrator, ray: &Ray, n: u32, seed: u64) -> (Vec3, Vec3) {
    let (mut sum, mut sum2) = ([0f64; 3], [0f64; 3]);
    let mut counts = GiCounts::default();
    let kind = integrator.gi_scene().sampler;
    for i in 0..n {
        let mut sampler = match kind {
            SamplerKind::Independent => Sampler::new(kind, seed, i, 0, 0),
            SamplerKind::Sobol => Sampler::new(kind, seed, 0, 0, i),
        };
        let l = integrator.radiance(ray, &mut sampler, &mut counts);
        for c in 0..3 {
            sum[c] += l[c] as f64;
            sum2[c] += (l[c] as f64).powi(2);
        }
    }
    let n = n as f64;
    let mean = sum.map(|s| s / n);
    let se: Vec<f64> = (0..3)
        .map(|c| ((sum2[c] / n - mean[c] * mean[c]).max(0.0) / (n - 1.0)).sqrt())
        .collect();
    (
        Vec3::new(mean[0] as f32, mean[1] as f32, mean[2] as f32),
        Vec3::new(se[0] as f32, se[1] as f32, se[2] as f32),
    )
}

/// Asserts `got` within `Z` standard errors of `want`, and the standard error below
/// `max_rel_se` of `want` (where `want` is not zero).
fn assert_close(what: &str, (got, se): (Vec3, Vec3), want: Vec3, max_rel_se: f32) {
    for c in 0..3 {
        let tol = Z * se[c] + 1e-4 * want[c].abs() + 1e-6;
        assert!(
            (got[c] - want[c]).abs() <= tol,
            "{what}: channel {c} is {} +- {} (standard error), closed form {}",
            got[c],
            se[c],
            want[c]
        );
        if want[c] > 0.0 {
            assert!(
                se[c] <= max_rel_se * want[c],
                "{what}: channel {c} too noisy to check ({} +- {})",
                got[c],
                se[c]
            );
        }
    }
    eprintln!("{what}: {got} +- {se} (closed form {want})");
}

/// Adds the quad `a b c d` as triangles `(a, b, c)`, `(a, c, d)`: its winding normal is
/// `(b - a) x (c - a)`.
fn quad(g: &mut Geometry, mat: &mut Vec<u32>, m: u32, [a, b, c, d]: [Vec3; 4]) {
    let base = g.vertices.len() as u32;
    g.vertices.extend([a, b, c, d]);
    g.triangles.push([base, base + 1, base + 2]);
    g.triangles.push([base, base + 2, base + 3]);
    mat.extend([m, m]);
}

/// The corners of the square of half-side `half` around the y axis at height `y`, for
/// [`quad`]: winding normal `+y` when `up`, else `-y`.
fn horizontal_square(y: f32, half: f32, up: bool) -> [Vec3; 4] {
    let c = [
        Vec3::new(-half, y, -half),
        Vec3::new(-half, y, half),
        Vec3::new(half, y, half),
        Vec3::new(half, y, -half),
    ];
    // Listed clockwise seen from above: normal +y.
    if up { c } else { [c[0], c[3], c[2], c[1]] }
}

/// An axis-aligned box of half-side `h` around the origin, every face's winding normal
/// pointing inward, material `m`.
fn inward_box(g: &mut Geometry, mat: &mut Vec<u32>, m: u32, h: f32) {
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z) * h;
    let faces = [
        [
            v(-1., -1., -1.),
            v(1., -1., -1.),
            v(1., -1., 1.),
            v(-1., -1., 1.),
        ],
        [
            v(-1., 1., -1.),
            v(-1., 1., 1.),
            v(1., 1., 1.),
            v(1., 1., -1.),
        ],
        [
            v(-1., -1., -1.),
            v(-1., -1., 1.),
            v(-1., 1., 1.),
            v(-1., 1., -1.),
        ],
        [
            v(1., -1., -1.),
            v(1., 1., -1.),
            v(1., 1., 1.),
            v(1., -1., 1.),
        ],
        [
            v(-1., -1., -1.),
            v(-1., 1., -1.),
            v(1., 1., -1.),
            v(1., -1., -1.),
        ],
        [
            v(-1., -1., 1.),
            v(1., -1., 1.),
            v(1., 1., 1.),
            v(-1., 1., 1.),
        ],
    ];
    for [a, b, c, d] in faces {
        // Listed counter-clockwise seen from outside: reversed to face in.
        quad(g, mat, m, [a, d, c, b]);
    }
    for tri in 0..12 {
        let [a, b, c] = g.triangle(tri);
        let centre = (a + b + c) / 3.0;
        assert!(
            (b - a).cross(c - a).dot(centre) < 0.0,
            "face {tri} faces out"
        );
    }
}

fn diffuse(albedo: f32, emission: Vec3) -> Material {
    Material {
        color: Vec3::splat(albedo),
        diffuse: 1.0,
        emission,
        ..Material::default()
    }
}

fn scene(geometry: Geometry, prim_material: Vec<u32>, materials: Vec<Material>) -> Scene {
    Scene {
        geometry,
        prim_material,
        materials,
        ..Scene::default()
    }
}

/// A unit-radius latitude-longitude sphere around the origin, winding normals outward.
/// Triangles, so that light sampling and photon emission see its emission.
fn sphere_mesh(g: &mut Geometry, mat: &mut Vec<u32>, m: u32, r: f32) {
    let (rings, segments) = (16u32, 32u32);
    let point = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        ) * r
    };
    for i in 0..rings {
        for j in 0..segments {
            let [a, b, c, d] = [
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            ];
            // Seen from outside, a d c b runs counter-clockwise; the poles' slivers of
            // zero area are left out.
            if i + 1 < rings {
                push_tri(g, mat, m, [a, c, b]);
            }
            if i > 0 {
                push_tri(g, mat, m, [a, d, c]);
            }
        }
    }
}

fn push_tri(g: &mut Geometry, mat: &mut Vec<u32>, m: u32, [a, b, c]: [Vec3; 3]) {
    let base = g.vertices.len() as u32;
    g.vertices.extend([a, b, c]);
    g.triangles.push([base, base + 1, base + 2]);
    mat.push(m);
    let centre = (a + b + c) / 3.0;
    assert!(
        (b - a).cross(c - a).dot(centre) > 0.0,
        "sphere facet faces in"
    );
}

/// The closed white furnace: a sphere inside a box, every surface of albedo `a` emitting
/// `(1 - a) L`. Radiance `L` everywhere solves the rendering equation
/// (`(1 - a) L + a L = L`), so the sphere converges to `L` for any `a`.
fn furnace(a: f32, l: f32) -> (Scene, Ray) {
    let mut g = Geometry::default();
    let mut mat = Vec::new();
    inward_box(&mut g, &mut mat, 0, 4.0);
    sphere_mesh(&mut g, &mut mat, 0, 1.0);
    let m = diffuse(a, Vec3::splat((1.0 - a) * l));
    let ray = Ray::new(
        Vec3::new(0.3, 0.5, -3.0),
        (Vec3::ZERO - Vec3::new(0.3, 0.5, -3.0)).normalize(),
        0.0,
        f32::INFINITY,
    );
    (scene(g, mat, vec![m]), ray)
}

#[test]
fn path_tracer_white_furnace_converges_to_the_emitted_radiance_for_any_albedo() {
    for kind in [SamplerKind::Sobol, SamplerKind::Independent] {
        for a in [0.0, 0.3, 0.6, 0.9] {
            let (s, ray) = furnace(a, 2.0);
            let accel = KdTree::build(&s.geometry);
            let mut scene = GiScene::new(&s, &accel, Vec3::ZERO, None);
            scene.sampler = kind;
            let pt = PathTracer::new(scene);
            let e = estimate(&pt, &ray, 40_000, 1);
            assert_close(
                &format!("path furnace a={a}, {kind:?}"),
                e,
                Vec3::splat(2.0),
                0.01,
            );
        }
    }
}

#[test]
fn photon_map_white_furnace_converges_to_the_emitted_radiance_for_any_albedo() {
    for a in [0.3, 0.7] {
        let (s, ray) = furnace(a, 2.0);
        let accel = KdTree::build(&s.geometry);
        let pm = PhotonMapper::new(
            GiScene::new(&s, &accel, Vec3::ZERO, None),
            PhotonSettings {
                photons: 1_000_000,
                gather: 8,
                k: 32,
                ..PhotonSettings::default()
            },
        );
        let e = estimate(&pm, &ray, 3_000, 2);
        assert_close(&format!("photon furnace a={a}"), e, Vec3::splat(2.0), 0.01);
    }
}

/// With at most `d` bounces the furnace's sphere shows `(1 - a) L sum_{k<=d} a^k`: each
/// bounce adds `a` times what the one before added, so energy shrinks with depth.
#[test]
fn each_bounce_adds_albedo_times_the_previous_one() {
    let (a, l) = (0.6, 1.0);
    let (s, ray) = furnace(a, l);
    let accel = KdTree::build(&s.geometry);
    let mut previous = Vec3::ZERO;
    for d in 0..6u32 {
        let pt = PathTracer::new(GiScene::new(&s, &accel, Vec3::ZERO, Some(d)));
        let want: f32 = (0..=d).map(|k| (1.0 - a) * l * a.powi(k as i32)).sum();
        let e = estimate(&pt, &ray, 40_000, 3);
        assert_close(
            &format!("furnace at most {d} bounces"),
            e,
            Vec3::splat(want),
            0.01,
        );
        assert!(e.0.x >= previous.x - Z * e.1.x, "depth {d} lost energy");
        previous = e.0;
    }
}

/// `F` from a differential area to a parallel `x` by `y` rectangle at height `h` with a
/// corner straight above it (Howell's catalogue, B-3).
fn form_factor_corner(x: f64, y: f64, h: f64) -> f64 {
    let (x, y) = (x / h, y / h);
    let ax = (1.0 + x * x).sqrt();
    let ay = (1.0 + y * y).sqrt();
    (x / ax * (y / ax).atan() + y / ay * (x / ay).atan()) / (2.0 * std::f64::consts::PI)
}

/// A floor of albedo `rho` under a square emitter of side `side` and radiance `le` at
/// height `h`, centred above the origin and facing down; the emitter reflects nothing.
/// The floor at the origin then reflects `rho le F`, `F` the form factor to the square.
#[test]
fn irradiance_under_a_small_area_light_matches_the_form_factor() {
    // Also far from the origin, where hit points are rounded to a few thousandths: the
    // rays leaving the floor must start above it ([`Shader::rounding_offset`]), or their
    // own floor would shadow them.
    for shift in [Vec3::ZERO, Vec3::new(1500.0, -2500.0, 2000.0)] {
        irradiance_under_a_small_area_light(shift);
    }
}

fn irradiance_under_a_small_area_light(shift: Vec3) {
    let (rho, le, side, h) = (0.5f32, 10.0f32, 1.0f32, 2.0f32);
    let mut g = Geometry::default();
    let mut mat = Vec::new();
    let big = 50.0;
    let shifted = |c: [Vec3; 4]| c.map(|v| v + shift);
    quad(
        &mut g,
        &mut mat,
        0,
        shifted(horizontal_square(0.0, big, true)),
    );
    let s2 = side / 2.0;
    quad(
        &mut g,
        &mut mat,
        1,
        shifted(horizontal_square(h, s2, false)),
    );
    assert!(g.geometric_normal(0, Vec3::ZERO).y > 0.0 && g.geometric_normal(2, Vec3::ZERO).y < 0.0);
    let s = scene(
        g,
        mat,
        vec![diffuse(rho, Vec3::ZERO), diffuse(0.0, Vec3::splat(le))],
    );
    let f = 4.0 * form_factor_corner(s2 as f64, s2 as f64, h as f64);
    let want = Vec3::splat(rho * le * f as f32);
    let eye = Vec3::new(0.0, 1.0, -1.5);
    let ray = Ray::new(eye + shift, (-eye).normalize(), 0.0, f32::INFINITY);
    let accel = KdTree::build(&s.geometry);
    for bounces in [Some(1), None] {
        let pt = PathTracer::new(GiScene::new(&s, &accel, Vec3::ZERO, bounces));
        let e = estimate(&pt, &ray, 40_000, 4);
        assert_close(
            &format!("area light, path, bounces {bounces:?}, shifted by {shift}"),
            e,
            want,
            0.01,
        );
    }
    let pm = PhotonMapper::new(
        GiScene::new(&s, &accel, Vec3::ZERO, None),
        PhotonSettings {
            photons: 20_000,
            gather: 4,
            ..PhotonSettings::default()
        },
    );
    let e = estimate(&pm, &ray, 40_000, 5);
    assert_close(
        &format!("area light, photon, shifted by {shift}"),
        e,
        want,
        0.01,
    );
}

/// A point light of intensity `I` at height `h` above a floor of albedo `rho`: the floor
/// under it reflects `rho I / (pi h^2)`, with no noise at all.
#[test]
fn a_point_light_falls_off_with_the_squared_distance() {
    let (rho, intensity, h) = (0.8f32, 5.0f32, 3.0f32);
    let mut g = Geometry::default();
    let mut mat = Vec::new();
    quad(
        &mut g,
        &mut mat,
        0,
        [
            Vec3::new(-9.0, 0.0, -9.0),
            Vec3::new(-9.0, 0.0, 9.0),
            Vec3::new(9.0, 0.0, 9.0),
            Vec3::new(9.0, 0.0, -9.0),
        ],
    );
    let mut s = scene(g, mat, vec![diffuse(rho, Vec3::ZERO)]);
    s.lights.push(Light::Point {
        position: Vec3::new(0.0, h, 0.0),
        color: Vec3::splat(intensity),
    });
    let accel = KdTree::build(&s.geometry);
    let eye = Vec3::new(0.0, 1.0, -1.0);
    let ray = Ray::new(eye, (-eye).normalize(), 0.0, f32::INFINITY);
    let want = rho * intensity / (std::f32::consts::PI * h * h);
    let pt = PathTracer::new(GiScene::new(&s, &accel, Vec3::ZERO, None));
    let (got, se) = estimate(&pt, &ray, 1000, 6);
    assert!((got.x - want).abs() < 1e-4 * want, "{got} vs {want}");
    assert!(se.x < 1e-5 * want, "one bounce, one light: no noise ({se})");
}

/// A mirror and a glass slab between two emitters: red behind the camera (seen by
/// reflection), green beyond the slab (seen by transmission). Returns the scene and the
/// camera ray at `theta` from the slab's normal.
fn slab(front: Material, thickness: Option<f32>, theta: f32) -> (Scene, Ray) {
    let mut g = Geometry::default();
    let mut mat = Vec::new();
    let b = 200.0;
    let at_z = |z: f32, toward_plus: bool| {
        let (p, q) = (Vec3::new(-b, -b, z), Vec3::new(b, b, z));
        let corners = [p, Vec3::new(q.x, p.y, z), q, Vec3::new(p.x, q.y, z)];
        // Counter-clockwise seen from +z: normal +z.
        if toward_plus {
            corners
        } else {
            [corners[0], corners[3], corners[2], corners[1]]
        }
    };
    // The slab's front face looks at the camera (-z), its back face away (+z).
    quad(&mut g, &mut mat, 0, at_z(0.0, false));
    if let Some(t) = thickness {
        quad(&mut g, &mut mat, 0, at_z(t, true));
    }
    // Red emitter behind the camera facing +z; green beyond the slab facing -z.
    quad(&mut g, &mut mat, 1, at_z(-5.0, true));
    quad(&mut g, &mut mat, 2, at_z(5.0, false));
    let s = scene(
        g,
        mat,
        vec![
            front,
            diffuse(0.0, Vec3::new(1.0, 0.0, 0.0)),
            diffuse(0.0, Vec3::new(0.0, 1.0, 0.0)),
        ],
    );
    let dir = Vec3::new(theta.sin(), 0.0, theta.cos());
    (
        s,
        Ray::new(Vec3::new(0.0, 0.0, -1.0), dir, 0.0, f32::INFINITY),
    )
}

fn both_integrators(s: &Scene, ray: &Ray, n: u32, what: &str, want: Vec3, max_rel_se: f32) {
    let accel = KdTree::build(&s.geometry);
    let pt = PathTracer::new(GiScene::new(s, &accel, Vec3::ZERO, None));
    assert_close(
        &format!("{what}, path"),
        estimate(&pt, ray, n, 7),
        want,
        max_rel_se,
    );
    let pm = PhotonMapper::new(
        GiScene::new(s, &accel, Vec3::ZERO, None),
        PhotonSettings {
            photons: 10_000,
            gather: 1,
            ..PhotonSettings::default()
        },
    );
    assert_close(
        &format!("{what}, photon"),
        estimate(&pm, ray, n, 8),
        want,
        max_rel_se,
    );
}

#[test]
fn a_mirror_reflects_its_colour_of_what_it_sees() {
    let c = Vec3::new(0.9, 0.5, 0.2);
    let mirror = Material {
        color: c,
        diffuse: 0.0,
        reflection: 1.0,
        ..Material::default()
    };
    let (s, ray) = slab(mirror, None, 0.7);
    both_integrators(&s, &ray, 200, "mirror", Vec3::new(c.x, 0.0, 0.0), 0.01);
}

/// The directional albedo `integral f(wo, wi) cos_i dwi` of `bsdf` (normal `+y`) by the
/// midpoint rule on a `steps x steps` grid of `(cos_i, phi)`, in f64.
fn directional_albedo(bsdf: &Bsdf, wo: Vec3, steps: u32) -> Vec3 {
    let mut sum = [0f64; 3];
    let h = 1.0 / steps as f64;
    for i in 0..steps {
        let mu = (i as f64 + 0.5) * h;
        let s = (1.0 - mu * mu).sqrt();
        for j in 0..steps {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) * h;
            let wi = Vec3::new((s * phi.cos()) as f32, mu as f32, (s * phi.sin()) as f32);
            let f = bsdf.eval(wo, wi);
            for c in 0..3 {
                sum[c] += f[c] as f64 * mu;
            }
        }
    }
    let w = h * std::f64::consts::TAU * h;
    Vec3::new(
        (sum[0] * w) as f32,
        (sum[1] * w) as f32,
        (sum[2] * w) as f32,
    )
}

/// A glossy (GGX) plane under a uniform sky of radiance 1 and nothing else: every
/// reflected direction escapes, so the plane's radiance toward the camera is its
/// directional albedo, computed here by quadrature from the BSDF's `eval`. The path
/// tracer reaches it by the sky's next-event estimation and the GGX lobe's own samples,
/// weighted by MIS, so a density that disagrees with the sampler, or an MIS weight
/// that does not sum to one, moves the estimate off.
#[test]
fn a_glossy_plane_under_the_sky_reflects_its_directional_albedo() {
    let c = Vec3::new(0.9, 0.6, 0.3);
    for alpha in [0.3f32, 0.6] {
        let glossy = Material {
            color: c,
            diffuse: 0.0,
            reflection: 1.0,
            glossiness: alpha / (1.0 - alpha * alpha).sqrt(),
            ..Material::default()
        };
        let mut g = Geometry::default();
        let mut mat = Vec::new();
        quad(&mut g, &mut mat, 0, horizontal_square(0.0, 100.0, true));
        let s = scene(g, mat, vec![glossy.clone()]);
        let accel = KdTree::build(&s.geometry);
        let bsdf = Bsdf::new(&glossy, c, Vec3::Y, true);
        for theta in [0.3f32, 1.1] {
            let wo = Vec3::new(theta.sin(), theta.cos(), 0.0);
            let want = directional_albedo(&bsdf, wo, 1500);
            let ray = Ray::new(wo * 5.0, -wo, 0.0, f32::INFINITY);
            for kind in [SamplerKind::Sobol, SamplerKind::Independent] {
                let mut scene = GiScene::new(&s, &accel, Vec3::ONE, None);
                scene.sampler = kind;
                let pt = PathTracer::new(scene);
                let e = estimate(&pt, &ray, 40_000, 3);
                assert_close(
                    &format!("glossy plane alpha {alpha} theta {theta}, {kind:?}"),
                    e,
                    want,
                    0.01,
                );
            }
        }
    }
}

/// Clear glass of index 1.5, no diffuse part.
fn clear_glass() -> Material {
    Material {
        color: Vec3::ONE,
        diffuse: 0.0,
        refraction: 1.0,
        ior: 1.5,
        ..Material::default()
    }
}

/// A clear slab of index 1.5: reflects `2F / (1 + F)` and transmits `(1 - F) / (1 + F)`
/// (all internal reflections summed), `F` the Fresnel reflectance at the entry angle.
#[test]
fn a_glass_slab_reflects_and_transmits_per_fresnel() {
    let glass = clear_glass();
    for theta in [0.0f32, 1.0, 1.35] {
        let (s, ray) = slab(glass.clone(), Some(0.1), theta);
        let f = fresnel_dielectric(theta.cos(), 1.0 / 1.5);
        let want = Vec3::new(2.0 * f / (1.0 + f), (1.0 - f) / (1.0 + f), 0.0);
        both_integrators(
            &s,
            &ray,
            40_000,
            &format!("slab at {theta} rad"),
            want,
            0.02,
        );
    }
}

/// Beer's law in the slab: with transmittance `tau = exp(-C d)` across it, the slab
/// transmits `(1 - F)^2 tau / (1 - F^2 tau^2)` and reflects
/// `F + (1 - F)^2 F tau^2 / (1 - F^2 tau^2)` at normal incidence.
#[test]
fn an_absorbing_slab_follows_beers_law() {
    // C = absorption * (1 - colour) = 2 * 0.5 = 1 per unit in every channel.
    let glass = Material {
        color: Vec3::splat(0.5),
        diffuse: 0.0,
        refraction: 1.0,
        ior: 1.5,
        absorption: 2.0,
        ..Material::default()
    };
    let d = 0.5f32;
    let (s, ray) = slab(glass, Some(d), 0.0);
    let f = fresnel_dielectric(1.0, 1.0 / 1.5);
    let tau = (-d).exp();
    let den = 1.0 - f * f * tau * tau;
    let want = Vec3::new(
        f + (1.0 - f).powi(2) * f * tau * tau / den,
        (1.0 - f).powi(2) * tau / den,
        0.0,
    );
    both_integrators(&s, &ray, 20_000, "absorbing slab", want, 0.05);
}

/// Caustics: a floor of albedo 0.5 under a clear glass slab, lit by a square emitter
/// above the slab. Every shadow ray from the floor is blocked by the glass, so the
/// floor is lit only through it: by BSDF-sampled paths in the path tracer, by the
/// caustic map in the photon mapper. The mean over the floor seen by a 16 x 16 camera
/// looking down must agree between them within 4.5 combined standard errors: the path
/// tracer's from its samples, the photon mapper's from 8 independent photon maps (so it
/// includes the maps' own noise; with 7 degrees of freedom a correct pair still fails
/// about once in 300 runs).
#[test]
fn caustics_through_a_glass_slab_agree_between_path_and_photon() {
    let mut g = Geometry::default();
    let mut mat = Vec::new();
    let big = 20.0;
    quad(&mut g, &mut mat, 0, horizontal_square(0.0, big, true));
    quad(&mut g, &mut mat, 1, horizontal_square(1.0, big, false));
    quad(&mut g, &mut mat, 1, horizontal_square(1.3, big, true));
    quad(&mut g, &mut mat, 2, horizontal_square(4.0, 1.0, false));
    assert!(g.geometric_normal(0, Vec3::ZERO).y > 0.0);
    assert!(g.geometric_normal(6, Vec3::ZERO).y < 0.0);
    let glass = clear_glass();
    let mut s = scene(
        g,
        mat,
        vec![
            diffuse(0.5, Vec3::ZERO),
            glass,
            diffuse(0.0, Vec3::splat(10.0)),
        ],
    );
    s.camera = raypack::scene::Camera {
        eye: Vec3::new(0.0, 0.9, 0.0),
        target: Vec3::ZERO,
        up: Vec3::Z,
        vfov_deg: 60.0,
    };
    let frame = s.camera.frame(16, 16);
    let accel = KdTree::build(&s.geometry);
    let mean_over_image = |integrator: &dyn Integrator, spp: u32| {
        let (mut sum, mut sum2, mut n) = (0f64, 0f64, 0f64);
        let mut counts = GiCounts::default();
        for y in 0..16 {
            for x in 0..16 {
                for k in 0..spp {
                    let mut sampler = Sampler::new(SamplerKind::Independent, 9, x, y, k);
                    let (jx, jy) = sampler.next_2d();
                    let ray = frame.ray(x as f32 + jx, y as f32 + jy);
                    let l = integrator.radiance(&ray, &mut sampler, &mut counts);
                    let v = (l.x + l.y + l.z) as f64 / 3.0;
                    sum += v;
                    sum2 += v * v;
                    n += 1.0;
                }
            }
        }
        let mean = sum / n;
        (mean, ((sum2 / n - mean * mean).max(0.0) / (n - 1.0)).sqrt())
    };
    // The path tracer alone, each sample from the camera: light tracing's share of the
    // caustics comes in `render_gi` (tests/gi_cornell.rs checks the two agree).
    let mut pt = PathTracer::new(GiScene::new(&s, &accel, Vec3::ZERO, None));
    assert!(pt.scene.light_tracing);
    pt.scene.light_tracing = false;
    let (a, sa) = mean_over_image(&pt, 2048);
    // The photon map is itself random and shared by every sample: its noise is measured
    // across 8 maps shot with different seeds (the spread of their 8 image means).
    let replicas: Vec<f64> = (0..8u64)
        .map(|seed| {
            let pm = PhotonMapper::new(
                GiScene::new(&s, &accel, Vec3::ZERO, None),
                PhotonSettings {
                    photons: 100_000,
                    gather: 2,
                    seed,
                    ..PhotonSettings::default()
                },
            );
            assert!(
                pm.caustic.len() > 25_000,
                "caustic map: {}",
                pm.caustic.len()
            );
            mean_over_image(&pm, 4).0
        })
        .collect();
    let r = replicas.len() as f64;
    let b = replicas.iter().sum::<f64>() / r;
    let sb = (replicas.iter().map(|x| (x - b).powi(2)).sum::<f64>() / (r - 1.0) / r).sqrt();
    let se = (sa * sa + sb * sb).sqrt();
    eprintln!("floor under glass: path {a:.4} +- {sa:.4}, photon {b:.4} +- {sb:.4}");
    assert!(a > 0.05, "the floor is lit through the glass ({a})");
    assert!(se < 0.02 * a, "too noisy to compare: {se}");
    assert!(
        (a - b).abs() <= Z as f64 * se,
        "path {a} photon {b}, se {se}"
    );
}
