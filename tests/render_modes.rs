//! Every scene in scenes/ rendered in scalar and in packet mode: the images must be
//! identical, pixel for pixel and bit for bit.
//!
//! The tolerance is zero because both modes do the same arithmetic: the packet
//! traversal returns the scalar closest hit and any-hit answer bit for bit
//! (tests/packet_vs_scalar.rs), every hit is shaded by the same scalar code with the
//! pixel's own generator, and shadow samples are summed in the same order.

use raypack::accel::kdtree::KdTree;
use raypack::render::{Mode, RayCounts, render};
use std::path::Path;

#[test]
fn every_scene_renders_identically_in_scalar_and_packet_mode() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    assert!(
        paths.len() >= 7,
        "expected the tutorial scenes in {}",
        dir.display()
    );
    for path in &paths {
        let mut scene =
            raypack::scene::file::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // A smaller image keeps the test quick; odd sizes exercise partial quads.
        let s = &mut scene.settings;
        let aspect = s.height as f32 / s.width as f32;
        s.width = 161;
        s.height = (161.0 * aspect).round() as u32;
        let tree = KdTree::build(&scene.geometry);
        let scalar = render(&scene, &tree, Mode::Scalar, &|| {});
        let packet = render(&scene, &tree, Mode::Packet, &|| {});
        let name = path.display();
        assert_eq!(
            counts(&scalar.counts),
            counts(&packet.counts),
            "{name}: ray counts"
        );
        assert!(scalar.counts.primary > 0, "{name}: nothing rendered");
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
    }
}

fn counts(c: &RayCounts) -> String {
    format!("{c:?}")
}
