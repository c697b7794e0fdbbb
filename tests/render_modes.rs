//! Every scene in scenes/, and scenes built to make each kind of packet form, rendered
//! in scalar mode and in every packet mode (4, 8 and 16 lanes): the images must be
//! identical, pixel for pixel and bit for bit, the ray counts equal, and the packet
//! path must actually have traced packets of its width.
//!
//! The tolerance is zero because both modes do the same arithmetic: the packet
//! traversal returns the scalar closest hit and any-hit answer bit for bit
//! (tests/packet_vs_scalar.rs), every hit is shaded by the same scalar code with the
//! pixel's own generator, and shadow samples are summed in the same order.
//! Secondary rays traced together keep each pixel's random draws in the scalar order
//! (src/render/shade_packet.rs).

mod common;

use raypack::accel::Mode;
use raypack::accel::kdtree::KdTree;
use raypack::render::shade::{Batching, PacketCounts};
use raypack::render::{RayCounts, Rendered, render};
use raypack::scene::Scene;
use std::path::Path;

#[test]
fn every_scene_renders_identically_in_scalar_and_packet_mode() {
    let paths = common::shipped_scenes();
    for path in &paths {
        let mut scene =
            raypack::scene::file::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // A smaller image keeps the test quick; odd sizes exercise partial quads.
        let s = &mut scene.settings;
        let aspect = s.height as f32 / s.width as f32;
        s.width = 161;
        s.height = (161.0 * aspect).round() as u32;
        for (_, packet) in render_all(&path.display().to_string(), &scene) {
            assert!(
                packet.counts.primary > 0,
                "{}: nothing rendered",
                path.display()
            );
        }
    }
}

/// Renders `scene` in every mode, asserts the images and ray counts are identical and
/// that scalar mode traced no packet, and returns each packet mode's rendering.
fn render_all(name: &str, scene: &Scene) -> Vec<(Mode, Rendered)> {
    let tree = KdTree::build(&scene.geometry);
    let scalar = render(scene, &tree, Mode::Scalar, &|| {});
    let packet_modes = [Mode::Packet4, Mode::Packet8, Mode::Packet16];
    packet_modes
        .into_iter()
        .map(|mode| {
            let name = format!("{name} ({mode})");
            (
                mode,
                same_as_scalar(&name, &scalar, render(scene, &tree, mode, &|| {})),
            )
        })
        .collect()
}

/// Asserts that `packet` has the image and ray counts of `scalar`; returns it.
fn same_as_scalar(name: &str, scalar: &Rendered, packet: Rendered) -> Rendered {
    assert_eq!(
        scalar.counts.packets,
        PacketCounts::default(),
        "{name}: scalar mode traced packets"
    );
    let rays = |c: &RayCounts| RayCounts {
        packets: PacketCounts::default(),
        ..*c
    };
    assert_eq!(
        rays(&scalar.counts),
        rays(&packet.counts),
        "{name}: ray counts"
    );
    for (i, (a, b)) in scalar
        .film
        .pixels
        .iter()
        .zip(&packet.film.pixels)
        .enumerate()
    {
        let (x, y) = (i as u32 % scalar.film.width, i as u32 / scalar.film.width);
        assert!(
            a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits),
            "{name}: pixel ({x}, {y}) scalar {a:?} packet {b:?}"
        );
    }
    packet
}

fn parse(name: &str, text: &str) -> Scene {
    raypack::scene::file::parse(Path::new(name), text).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A mirror filling the whole view reflects every camera ray onto a lit wall behind the
/// camera: every quad's 4 mirror rays agree, so each quad traces exactly one packet of
/// 4 reflection rays and none alone.
#[test]
fn mirror_rays_of_a_quad_are_traced_as_one_packet() {
    let scene = parse(
        "mirror.toml",
        r#"
[camera]
eye = [0.0, 0.0, -5.0]
target = [0.0, 0.0, 0.0]
vfov = 50.0

[render]
width = 16
height = 12
max_depth = 2

[materials.mirror]
color = [0.9, 0.8, 0.7]
diffuse = 0.0
reflection = 0.75

[materials.wall]
color = [0.3, 0.6, 0.9]

[[planes]]
normal = [0.0, 0.0, -1.0]
offset = 0.0
material = "mirror"

[[planes]]
normal = [0.0, 0.0, 1.0]
offset = -10.0
material = "wall"

[[lights]]
kind = "point"
position = [0.0, 3.0, -8.0]
color = [1.0, 1.0, 1.0]
"#,
    );
    for (mode, r) in render_all("mirror.toml", &scene) {
        let c = r.counts;
        let blocks = 16 * 12 / mode.packet_size() as u64;
        assert_eq!(c.reflection, 16 * 12);
        let want = Batching {
            packets: blocks,
            packet_rays: 16 * 12,
            single_rays: 0,
        };
        assert_eq!(c.packets.secondary, want, "{mode}: {c:?}");
        assert_eq!(c.packets.primary, want, "{mode}: {c:?}");
    }
}

/// A floor under two point lights and a sphere that shadows part of it: every camera
/// quad sees the floor or the sphere, so each quad sends one packet of shadow rays
/// toward each light (4 lanes, fewer where a sphere point faces away from the light),
/// and no ray alone, while the image stays the scalar one.
#[test]
fn point_light_shadow_rays_of_a_quad_are_traced_as_one_packet() {
    let scene = parse(
        "point_shadows.toml",
        r#"
[camera]
eye = [0.0, 4.0, -4.0]
target = [0.0, 0.0, 0.0]
vfov = 40.0

[render]
width = 16
height = 12
max_depth = 1

[materials.floor]
color = [0.8, 0.8, 0.8]
specular = 0.3

[[planes]]
normal = [0.0, 1.0, 0.0]
offset = 0.0
material = "floor"

[[spheres]]
center = [0.3, 0.6, 0.2]
radius = 0.5
material = "floor"

[[lights]]
kind = "point"
position = [-2.0, 5.0, 1.0]
color = [1.0, 1.0, 1.0]

[[lights]]
kind = "point"
position = [3.0, 4.0, -1.0]
color = [0.5, 0.5, 0.5]
"#,
    );
    for (mode, r) in render_all("point_shadows.toml", &scene) {
        let c = r.counts;
        let blocks = 16 * 12 / mode.packet_size() as u64;
        assert!(
            c.shadow > 2 * 16 * 12 - 16 && c.shadow <= 2 * 16 * 12,
            "{c:?}"
        );
        let want = Batching {
            packets: 2 * blocks,
            packet_rays: c.shadow,
            single_rays: 0,
        };
        assert_eq!(c.packets.shadow, want, "{mode}: {c:?}");
    }
}

/// A glass sphere in front of a mirror wall: refracted, totally internally reflected and
/// mirror rays, lanes that disagree (some quads straddle the sphere's rim) and rays
/// that leave the scene. Most secondary rays still go in packets; the image is exact.
#[test]
fn refraction_through_a_glass_sphere_uses_packets_where_lanes_agree() {
    let scene = parse(
        "glass.toml",
        r#"
[camera]
eye = [0.0, 0.0, -5.0]
target = [0.0, 0.0, 0.0]
vfov = 60.0

[render]
width = 40
height = 30
max_depth = 5

[materials.glass]
color = [1.0, 0.9, 0.8]
diffuse = 0.1
specular = 0.5
shininess = 40
refraction = 0.9
ior = 1.5
absorption = 0.3

[materials.mirror]
color = [0.6, 0.9, 0.6]
diffuse = 0.4
reflection = 0.5

[[spheres]]
center = [0.0, 0.0, 2.0]
radius = 1.5
material = "glass"

[[planes]]
normal = [0.0, 0.0, -1.0]
offset = -6.0
material = "mirror"

[[lights]]
kind = "point"
position = [3.0, 4.0, -2.0]
color = [1.0, 1.0, 1.0]
"#,
    );
    for (mode, r) in render_all("glass.toml", &scene) {
        let c = r.counts;
        let s = c.packets.secondary;
        assert!(c.refraction > 0, "{c:?}");
        assert_eq!(
            s.packet_rays + s.single_rays,
            c.reflection + c.refraction,
            "{mode}: {c:?}"
        );
        assert!(
            s.packets > 0 && s.packet_rays > s.single_rays,
            "{mode}: {c:?}"
        );
    }
}

/// Full 3x3 supersampling, a glossy floor and an area light: each pixel's 9 samples
/// go as packets of 4, 4 and 1 at 4 lanes (8 and 1 at 8, one packet at 16); each glossy
/// hit's 6 rays as packets of 4 and 2 (one packet wider); the area light's shadow rays
/// in packets.
#[test]
fn supersamples_glossy_and_area_light_rays_fill_packets() {
    let scene = parse(
        "glossy.toml",
        r#"
[camera]
eye = [0.0, 1.0, -5.0]
target = [0.0, -1.0, 0.0]
vfov = 60.0

[render]
width = 12
height = 10
max_depth = 2
antialias = "full"
antialias_n = 3
glossy_samples = 6

[materials.floor]
color = [0.4, 0.3, 0.3]
diffuse = 0.8
reflection = 0.5
glossiness = 0.2

[materials.ball]
color = [0.7, 0.7, 1.0]

[[planes]]
normal = [0.0, 1.0, 0.0]
offset = -1.0
material = "floor"

[[spheres]]
center = [0.0, 0.0, 1.0]
radius = 1.0
material = "ball"

[[lights]]
kind = "area"
center = [0.0, 4.0, 0.0]
size = [2.0, 2.0]
color = [0.9, 0.9, 0.9]
samples = 16
"#,
    );
    for (mode, r) in render_all("glossy.toml", &scene) {
        let c = r.counts;
        let lanes = mode.packet_size() as u64;
        let pixels = 12 * 10;
        assert_eq!(c.primary, 9 * pixels, "{c:?}");
        // A pixel's 9 samples: full packets and one partial one.
        let primary = Batching {
            packets: 9_u64.div_ceil(lanes) * pixels,
            packet_rays: 9 * pixels,
            single_rays: 0,
        };
        assert_eq!(c.packets.primary, primary, "{mode}: {c:?}");
        // A glossy hit's 6 rays: 4 + 2 at 4 lanes, one packet wider.
        let g = c.packets.glossy;
        assert!(c.glossy > 0 && c.glossy.is_multiple_of(6), "{c:?}");
        assert_eq!(
            g.packets,
            c.glossy / 6 * 6_u64.div_ceil(lanes),
            "{mode}: {c:?}"
        );
        assert_eq!(
            (g.packet_rays, g.single_rays),
            (c.glossy, 0),
            "{mode}: {c:?}"
        );
        let sh = c.packets.shadow;
        assert_eq!(sh.packet_rays + sh.single_rays, c.shadow, "{mode}: {c:?}");
        assert!(sh.packet_rays > sh.single_rays, "{mode}: {c:?}");
    }
}
