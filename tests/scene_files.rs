//! Every scene in scenes/ loads, and the committed mesh is the generator's output.

use raypack::accel::Mode;
use raypack::accel::brute::BruteForce;
use raypack::render::render;
use raypack::scene::{AntiAlias, Light, file, generate};
use std::path::{Path, PathBuf};

fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

fn scene_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(scenes_dir())
        .expect("scenes/ is readable")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
}

#[test]
fn every_scene_loads() {
    let files = scene_files();
    assert!(
        files.len() >= 7,
        "expected the seven tutorial scenes, found {files:?}"
    );
    for f in &files {
        let s = file::load(f).unwrap_or_else(|e| panic!("{e}"));
        let g = &s.geometry;
        assert!(g.prim_count() > 0, "{}", f.display());
        assert_eq!(s.prim_material.len(), g.prim_count() as usize);
        assert!(
            s.prim_material
                .iter()
                .all(|&m| (m as usize) < s.materials.len())
        );
        let emits = s.materials.iter().any(|m| m.emission.max_element() > 0.0);
        assert!(
            !s.lights.is_empty() || emits,
            "{} has no light and nothing emissive",
            f.display()
        );
        assert!(s.normals.is_empty() || s.normals.len() == g.vertices.len());
        assert!(s.uvs.is_empty() || s.uvs.len() == g.vertices.len());
    }
}

#[test]
fn tutorial_scenes_have_their_features() {
    let load = |name: &str| file::load(&scenes_dir().join(name)).unwrap_or_else(|e| panic!("{e}"));
    let p1 = load("part1.toml");
    assert_eq!(
        (
            p1.geometry.planes.len(),
            p1.geometry.spheres.len(),
            p1.lights.len()
        ),
        (1, 2, 2)
    );
    let p3 = load("part3.toml");
    assert!(
        p3.materials
            .iter()
            .any(|m| m.refraction > 0.0 && m.absorption > 0.0)
    );
    assert_eq!(p3.settings.antialias, AntiAlias::Adaptive(3));
    assert_eq!(load("part4.toml").geometry.spheres.len(), 3 + 256);
    let p5 = load("part5.toml");
    assert!(
        p5.lights
            .iter()
            .any(|l| matches!(l, Light::Area { samples: 16, .. }))
    );
    assert!(p5.materials.iter().any(|m| m.glossiness > 0.0));
    let p6 = load("part6.toml");
    assert_eq!(p6.textures.len(), 3);
    assert!(p6.materials.iter().any(|m| m.texture.is_some()));
    let p7 = load("part7.toml");
    assert_eq!(p7.geometry.triangles.len(), 1536);
    assert!(!p7.geometry.spheres.is_empty());
}

/// scenes/README.md, "Handedness": with the tutorial's camera (at z = -5 looking down +z,
/// y up) screen-right is world -x, so a sphere at negative x lands in the right half of
/// the image and one at positive x in the left half.
#[test]
fn world_minus_x_is_screen_right_with_the_tutorial_camera() {
    for (x, right_side) in [(-2.5, true), (2.5, false)] {
        let text = format!(
            "[camera]\neye = [0.0, 0.0, -5.0]\ntarget = [0.0, 0.0, 0.0]\nvfov = 61.9275\n\
             [render]\nwidth = 80\nheight = 60\n\
             [[spheres]]\ncenter = [{x:?}, 0.0, 3.0]\nradius = 1.0\n\
             [[lights]]\nkind = \"point\"\nposition = [0.0, 0.0, -5.0]\ncolor = [1.0, 1.0, 1.0]\n"
        );
        let scene =
            file::parse(Path::new("handedness.toml"), &text).unwrap_or_else(|e| panic!("{e}"));
        let accel = BruteForce::new(&scene.geometry);
        let film = render(&scene, &accel, Mode::Scalar, &|| {}).film;
        let half = |right: bool| -> f32 {
            (0..film.height)
                .flat_map(|y| (0..film.width).map(move |x| (x, y)))
                .filter(|&(px, _)| (px >= film.width / 2) == right)
                .map(|(px, py)| film.get(px, py).element_sum())
                .sum()
        };
        let (lit, dark) = (half(right_side), half(!right_side));
        assert!(
            lit > 0.0 && dark == 0.0,
            "sphere at x = {x}: lit {lit}, other half {dark}"
        );
    }
}

/// scenes/knot.obj is generated, not drawn by hand: it must equal the generator's output.
/// `RAYPACK_BLESS=1 cargo test --release --test scene_files knot` rewrites it.
#[test]
fn knot_obj_is_the_generator_output() {
    let path = scenes_dir().join("knot.obj");
    let generated = generate::part7_knot_obj();
    if std::env::var_os("RAYPACK_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("scenes/knot.obj is writable");
    }
    let committed = std::fs::read_to_string(&path).expect("scenes/knot.obj is readable");
    assert!(
        committed == generated,
        "{} differs from raypack::scene::generate::part7_knot_obj(); regenerate it with \
         `RAYPACK_BLESS=1 cargo test --release --test scene_files knot`",
        path.display()
    );
}
