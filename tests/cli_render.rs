//! `raypack render` end to end: every shipped scene renders, the image has the asked size
//! and is not blank, PFM output matches PNG output, the same seed gives the same image on
//! any thread count, and bad arguments exit with 2.

mod common;

use common::cli::{check, raypack, s, scratch};

use std::path::PathBuf;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn shipped_scenes() -> Vec<PathBuf> {
    let dir = repo().join("scenes");
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    scenes.sort();
    assert!(!scenes.is_empty(), "no scene files in {}", dir.display());
    scenes
}

#[test]
fn every_shipped_scene_renders() {
    let dir = scratch("all");
    for scene in shipped_scenes() {
        let name = scene.file_stem().unwrap().to_string_lossy().into_owned();
        let png = dir.join(format!("{name}.png"));
        let out = raypack(&[
            "render",
            s(&scene),
            "-o",
            s(&png),
            "--width",
            "64",
            "--height",
            "48",
            "--threads",
            "2",
        ]);
        check(&out, &name);
        let stdout = String::from_utf8_lossy(&out.stdout);
        for word in ["render", "primary", "shadow", "rays/s"] {
            assert!(
                stdout.contains(word),
                "{name}: summary lacks {word}:\n{stdout}"
            );
        }
        let img = image::open(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (64, 48), "{name}");
        let first = img.get_pixel(0, 0).0;
        assert!(
            img.pixels().any(|p| p.0 != first),
            "{name}: every pixel is {first:?}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pfm_output_matches_png_and_threads_do_not_change_it() {
    let dir = scratch("pfm");
    let scene = shipped_scenes().pop().unwrap();
    let size = ["--width", "40", "--height", "30", "--seed", "3"];
    let mut outputs = Vec::new();
    for (threads, name) in [("1", "one.pfm"), ("2", "two.pfm"), ("2", "two.png")] {
        let path = dir.join(name);
        let mut args = vec!["render", s(&scene), "-o", s(&path), "--threads", threads];
        args.extend(size);
        check(&raypack(&args), name);
        outputs.push(path);
    }
    let one = std::fs::read(&outputs[0]).unwrap();
    let two = std::fs::read(&outputs[1]).unwrap();
    assert!(one == two, "1 and 2 threads wrote different PFM files");
    let film = raypack::render::Film::read_pfm(&outputs[0]).unwrap();
    let png = image::open(&outputs[2]).unwrap().to_rgb8();
    assert_eq!(png.as_raw(), &film.to_srgb8(0.0));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_arguments_exit_with_2_and_write_nothing() {
    let dir = scratch("bad");
    let scene = shipped_scenes().pop().unwrap();
    let png = dir.join("x.png");
    let missing = dir.join("no-such-scene.toml");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--width", "0"], "--width"),
        (vec!["--height", "100000"], "--height"),
        (vec!["--spp", "3"], "--spp"),
        (vec!["--spp", "0"], "--spp"),
        (vec!["--threads", "many"], "--threads"),
        (vec!["--vfov", "180"], "--vfov"),
        (vec!["--eye", "1,2"], "--eye"),
        (vec!["--up", "0,nan,0"], "--up"),
        (vec!["--half"], "--half"),
        (
            vec!["--max-bounces", "3"],
            "--max-bounces applies to --integrator path",
        ),
        (
            vec!["--integrator", "photon", "--max-bounces", "3"],
            "--max-bounces applies to --integrator path",
        ),
        (vec!["--seed", "minus-one"], "--seed"),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["render", s(&scene), "-o", s(&png)];
        args.extend(&extra);
        let out = raypack(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(needle), "{extra:?}: {stderr}");
    }
    // Tone mapping belongs to PNG: a PFM or EXR keeps linear radiance.
    for name in ["x.pfm", "x.exr"] {
        let out = raypack(&[
            "render",
            s(&scene),
            "-o",
            s(&dir.join(name)),
            "--exposure",
            "1",
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
        assert!(stderr.contains("--exposure applies to PNG"), "{stderr}");
    }
    let out = raypack(&["render", s(&missing), "-o", s(&png)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("no-such-scene.toml"), "{stderr}");
    assert!(!png.exists());
    // An output folder that does not exist, or an output that is a folder, is not bad
    // input but a failed write; both are found before the scene is even loaded.
    let nowhere = dir.join("missing").join("x.png");
    let folder = dir.join("folder.png");
    std::fs::create_dir(&folder).unwrap();
    for (target, os_error) in [
        (&nowhere, "No such file or directory"),
        (&folder, "is a directory"),
    ] {
        let out = raypack(&["render", s(&scene), "-o", s(target)]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!("-o {}: cannot write there", s(target))),
            "{stderr}"
        );
        // The chain names the OS error once, not once per layer.
        assert_eq!(stderr.matches(os_error).count(), 1, "{stderr}");
        assert!(
            out.stdout.is_empty(),
            "rendered before finding the bad output"
        );
    }
    std::fs::remove_dir(&folder).unwrap();
    assert!(
        std::fs::read_dir(&dir).unwrap().next().is_none(),
        "files left behind"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn size_overrides_are_held_to_the_scene_file_pixel_limit() {
    let dir = scratch("huge");
    let scene = shipped_scenes().pop().unwrap();
    let png = dir.join("x.png");
    for (extra, want) in [
        (
            vec!["--width", "16384", "--height", "16384"],
            "--width 16384 and --height 16384 make 268435456 pixels, more than the limit of 67108864",
        ),
        (
            vec!["--width", "16384", "--height", "8193"],
            "more than the limit of 67108864",
        ),
        (
            vec!["--height", "16385"],
            "--height 16385 must be between 1 and 16384",
        ),
    ] {
        let mut args = vec!["render", s(&scene), "-o", s(&png)];
        args.extend(&extra);
        let out = raypack(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(
            stderr.contains(want),
            "{extra:?}: `{stderr}` lacks `{want}`"
        );
        assert!(!png.exists(), "{extra:?}: an image was written");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn output_names_other_than_png_pfm_and_exr_are_refused_before_rendering() {
    let dir = scratch("ext");
    let scene = shipped_scenes().pop().unwrap();
    let size = ["--width", "8", "--height", "8"];
    for name in ["x.tif", "x.jpg", "x.JPEG", "x.png.tmp", "x"] {
        let path = dir.join(name);
        let mut args = vec!["render", s(&scene), "-o", s(&path)];
        args.extend(size);
        let out = raypack(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains(name) && stderr.contains(".png, .pfm or .exr"),
            "{name}: {stderr}"
        );
        // Refused before the render: no summary, no file.
        assert!(out.stdout.is_empty(), "{name}: rendered anyway");
        assert!(!path.exists(), "{name}: written anyway");
    }
    // Either case of the known extensions is accepted, and gives that format.
    for (name, magic) in [
        ("x.PNG", &b"\x89PNG"[..]),
        ("x.Pfm", &b"PF\n"[..]),
        ("x.eXr", &b"\x76\x2f\x31\x01"[..]),
    ] {
        let path = dir.join(name);
        let mut args = vec!["render", s(&scene), "-o", s(&path)];
        args.extend(size);
        check(&raypack(&args), name);
        assert!(std::fs::read(&path).unwrap().starts_with(magic), "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--integrator path` and `photon` render the GI Cornell box (any `--spp`), print rays
/// by kind and the photon map's times, give the same PFM on 1 and 2 threads, and refuse
/// `--spp 0`.
#[test]
fn gi_integrators_render_the_cornell_box() {
    require_scenes!(common::scenes_beside_crate());
    let dir = scratch("gi");
    let scene = repo().join("scenes/gi/cornell_box.toml");
    for integrator in ["path", "photon"] {
        let mut files = Vec::new();
        for threads in ["1", "2"] {
            let pfm = dir.join(format!("{integrator}-{threads}.pfm"));
            let out = raypack(&[
                "render",
                s(&scene),
                "-o",
                s(&pfm),
                "--integrator",
                integrator,
                "--spp",
                "3",
                "--photons",
                "5000",
                "--gather",
                "2",
                "--width",
                "20",
                "--height",
                "16",
                "--threads",
                threads,
            ]);
            check(&out, integrator);
            let stdout = String::from_utf8_lossy(&out.stdout);
            for word in [
                "camera",
                "bounce",
                "shadow",
                "rays/s",
                "3 samples per pixel",
            ] {
                assert!(stdout.contains(word), "{integrator}: no {word}:\n{stdout}");
            }
            if integrator == "photon" {
                assert!(stdout.contains("lookup"), "{stdout}");
            }
            files.push(std::fs::read(&pfm).unwrap());
        }
        assert!(files[0] == files[1], "{integrator}: 1 and 2 threads differ");
        let film =
            raypack::render::Film::read_pfm(&dir.join(format!("{integrator}-1.pfm"))).unwrap();
        assert_eq!((film.width, film.height), (20, 16));
        assert!(film.pixels.iter().any(|p| p.max_element() > 0.0));
    }
    let out = raypack(&[
        "render",
        s(&scene),
        "-o",
        s(&dir.join("zero.pfm")),
        "--integrator",
        "path",
        "--spp",
        "0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.join("zero.pfm").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
