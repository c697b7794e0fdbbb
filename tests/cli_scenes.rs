//! `raypack render` of every kind of scene argument: a benchmark scene by its name in
//! ../shared/scenes/cameras.toml, an OBJ path (with and without a standard camera), and
//! the camera overrides, which apply to every kind; plus the `--json` report.

mod common;

use common::cli::{check, raypack, s, scratch};

use std::path::Path;

/// Renders `scene` at 64x48 into `dir/name` with `extra` arguments; returns the bytes.
fn render(dir: &Path, scene: &str, name: &str, extra: &[&str]) -> Vec<u8> {
    let out_path = dir.join(name);
    let mut args = vec![
        "render",
        scene,
        "-o",
        s(&out_path),
        "--width",
        "64",
        "--height",
        "48",
    ];
    args.extend(extra);
    check(&raypack(&args), &format!("{scene} {extra:?}"));
    std::fs::read(&out_path).unwrap()
}

/// Mean of the 8-bit PNG's samples.
fn brightness(png: &[u8]) -> f64 {
    let img = image::load_from_memory(png).unwrap().to_rgb8();
    img.as_raw().iter().map(|&b| b as f64).sum::<f64>() / img.as_raw().len() as f64
}

#[test]
fn benchmark_scenes_render_by_name_and_by_path() {
    let scenes = require_scenes!();
    let dir = scratch("kinds");
    // By name, as `raypack bench` takes it; Sponza is mostly lit stone.
    let sponza = render(&dir, "sponza", "s.png", &[]);
    assert!(brightness(&sponza) > 40.0, "sponza renders dark");
    // The Cornell box to OpenEXR, by name.
    let exr = render(&dir, "cornell_box", "c.exr", &[]);
    assert!(
        exr.starts_with(&[0x76, 0x2f, 0x31, 0x01]),
        "not an OpenEXR file"
    );
    // The same mesh by its path gets the same camera (cameras.toml) and the same image.
    let by_name = render(&dir, "cornell_box", "n.png", &[]);
    let by_path = render(
        &dir,
        s(&scenes.join("cornell_box/cornell_box.obj")),
        "p.png",
        &[],
    );
    assert!(
        by_name == by_path,
        "a shared mesh by path and by name differ"
    );
    // MTL colours: the left wall is red, the right one green.
    let img = image::load_from_memory(&by_name).unwrap().to_rgb8();
    let left = img.get_pixel(12, 24).0;
    let right = img.get_pixel(52, 24).0;
    assert!(
        left[0] > 2 * left[1] && right[1] > 2 * right[0],
        "{left:?} {right:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_cornell_box_by_name_is_lit_by_its_emitter_under_global_illumination() {
    require_scenes!(common::scenes_beside_crate());
    let dir = scratch("gi");
    let gi = ["--integrator", "path", "--spp", "4"];
    // By name, the MTL `light` emits (Ka 20): the same image as the GI scene file.
    let by_name = render(&dir, "cornell_box", "n.pfm", &gi);
    let by_file = render(&dir, "scenes/gi/cornell_box.toml", "f.pfm", &gi);
    assert!(
        by_name == by_file,
        "cornell_box by name and by scene file differ"
    );
    let json = dir.join("gi.json");
    let mut with_json = gi.to_vec();
    with_json.extend(["--json", s(&json)]);
    let png = render(&dir, "cornell_box", "n.png", &with_json);
    assert!(brightness(&png) > 20.0, "the box renders dark");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v["integrator"], "path");
    assert_eq!(v["rays"]["camera"], 64 * 48 * 4);
    let kinds: u64 = ["camera", "bounce", "shadow", "gather", "photon"]
        .iter()
        .map(|k| v["rays"][k].as_u64().unwrap())
        .sum();
    assert_eq!(v["rays"]["total"].as_u64().unwrap(), kinds);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_obj_without_a_camera_is_framed_and_overrides_move_any_camera() {
    let dir = scratch("overrides");
    // A unit square far from the origin: the default camera must find it.
    let obj = dir.join("square.obj");
    std::fs::write(
        &obj,
        "v 100 100 100\nv 101 100 100\nv 101 101 100\nv 100 101 100\nf 1 2 3 4\n",
    )
    .unwrap();
    let framed = render(&dir, s(&obj), "f.png", &[]);
    assert!(
        brightness(&framed) > 10.0,
        "the framing camera missed the mesh"
    );
    // Looking away from it shows the black background only.
    let away = render(&dir, s(&obj), "a.png", &["--target", "100.5,100.5,200"]);
    assert_eq!(brightness(&away), 0.0);

    // On a scene file, whose camera comes from the file.
    let part1 = "scenes/part1.toml";
    let moved = render(&dir, part1, "m.png", &["--eye", "0,1,-9"]);
    assert!(
        moved != render(&dir, part1, "m0.png", &[]),
        "--eye changed nothing"
    );
    // cameras.toml's own values as overrides change nothing; a new field of view does.
    if common::scenes().is_some() {
        let plain = render(&dir, "cornell_box", "c0.png", &[]);
        let same = [
            "--eye",
            "278,273,-800",
            "--target",
            "278,273,-799",
            "--up",
            "0,1,0",
            "--vfov",
            "39.3077",
        ];
        assert!(render(&dir, "cornell_box", "c1.png", &same) == plain);
        let wide = render(&dir, "cornell_box", "c2.png", &["--vfov", "80"]);
        assert!(wide != plain, "--vfov changed nothing");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unknown_names_and_unusable_cameras_are_bad_input() {
    require_scenes!();
    let dir = scratch("bad");
    let png = dir.join("x.png");
    let out = raypack(&["render", "sponzza", "-o", s(&png)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("sponzza") && stderr.contains("cornell_box"),
        "{stderr}"
    );
    // Procedural scenes have no materials to render: bench, trace, rays and info take them.
    let out = raypack(&["render", "spd:balls:2", "-o", s(&png)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("spd: scenes are for bench"), "{stderr}");
    // Eye on the target: no view direction.
    let out = raypack(&[
        "render",
        "cornell_box",
        "-o",
        s(&png),
        "--eye",
        "278,273,-799",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("must differ"), "{stderr}");
    assert!(!png.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn json_report_counts_what_the_summary_prints() {
    let dir = scratch("json");
    let json = dir.join("r.json");
    render(
        &dir,
        "scenes/part2.toml",
        "x.png",
        &["--json", s(&json), "--threads", "2"],
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v["width"], 64);
    assert_eq!(v["height"], 48);
    assert_eq!(v["threads"], 2);
    let rays = &v["rays"];
    let parts: u64 = ["primary", "shadow", "reflection", "refraction", "glossy"]
        .iter()
        .map(|k| rays[k].as_u64().unwrap())
        .sum();
    assert_eq!(rays["total"].as_u64().unwrap(), parts);
    assert_eq!(rays["primary"], 64 * 48);
    assert!(v["render_seconds"].as_f64().unwrap() > 0.0);
    assert!(v["mrays_per_second"].as_f64().unwrap() > 0.0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_scene_without_lights_renders_with_a_warning() {
    let dir = scratch("dark");
    let scene = dir.join("dark.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0.0, 0.0, -5.0]\ntarget = [0.0, 0.0, 0.0]\n\
         [[spheres]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\n",
    )
    .unwrap();
    let png = dir.join("dark.png");
    let out = raypack(&[
        "render",
        s(&scene),
        "-o",
        s(&png),
        "--width",
        "16",
        "--height",
        "16",
    ]);
    check(&out, "a scene without lights");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.matches("no lights").count(), 1, "{stderr}");
    assert_eq!(brightness(&std::fs::read(&png).unwrap()), 0.0);
    std::fs::remove_dir_all(&dir).unwrap();
}
