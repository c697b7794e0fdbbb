//! `raypack render` end to end: every shipped scene renders, the image has the asked size
//! and is not blank, PFM output matches PNG output, the same seed gives the same image on
//! any thread count, and bad arguments exit with 2.

mod common;

use common::cli::{check, raypack, s, scratch};
use common::shipped_scenes;

use std::path::PathBuf;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
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

/// A floor (y = 0) under an emissive square (y = 1) whose winding faces down, or up with
/// `facing_up`, as an OBJ with its MTL in `dir`.
fn lit_floor(dir: &std::path::Path, facing_up: bool) -> PathBuf {
    let light_faces = if facing_up {
        "f 5 8 7\nf 5 7 6\n"
    } else {
        "f 5 6 7\nf 5 7 8\n"
    };
    std::fs::write(
        dir.join("lit.mtl"),
        "newmtl floor\nKd 0.8 0.8 0.8\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe 10 10 10\n",
    )
    .unwrap();
    let obj = dir.join(format!("lit-{facing_up}.obj"));
    std::fs::write(
        &obj,
        format!(
            "mtllib lit.mtl\n\
             v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\n\
             v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\n\
             usemtl floor\nf 1 4 3\nf 1 3 2\nusemtl lamp\n{light_faces}"
        ),
    )
    .unwrap();
    obj
}

/// A mesh with emitters is lit by them in the Whitted tracer, one-sided as they emit,
/// and not by the key and fill lights a bare mesh gets: under a lamp facing down the
/// floor is bright, under one facing up it has the ambient term alone (and the camera
/// above sees the lamp's glowing front).
#[test]
fn whitted_lights_a_mesh_by_its_emitters() {
    let dir = scratch("emitters");
    let mut brightest = Vec::new();
    for facing_up in [false, true] {
        let obj = lit_floor(&dir, facing_up);
        let pfm = dir.join(format!("lit-{facing_up}.pfm"));
        let out = raypack(&[
            "render",
            s(&obj),
            "-o",
            s(&pfm),
            "--width",
            "32",
            "--height",
            "32",
            "--eye",
            "0,3,-3",
            "--target",
            "0,0,0",
        ]);
        check(&out, "render");
        let film = raypack::render::Film::read_pfm(&pfm).unwrap();
        // The lamp's own pixels show its emission (10) where its front faces the camera;
        // the brightest of the others is the lit floor.
        let lit = film
            .pixels
            .iter()
            .map(|p| p.max_element())
            .filter(|&v| v < 5.0);
        brightest.push(lit.fold(0.0, f32::max));
        let lamp = film.pixels.iter().any(|p| p.max_element() >= 10.0);
        assert_eq!(lamp, facing_up, "the lamp glows on its front side only");
    }
    // The floor's albedo 0.8 under a unit light at N.L near 1 / under the ambient 0.05.
    assert!(brightest[0] > 0.5, "lamp facing down: {brightest:?}");
    assert!(brightest[1] < 0.1, "lamp facing up: {brightest:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Path tracing a mesh without emitters gives a picture (a uniform sky, said on stderr),
/// and a dark PNG is told the exposure that brightens it.
#[test]
fn gi_renders_of_bare_meshes_and_dark_scenes_say_what_to_do() {
    let dir = scratch("gi-hints");
    let obj = dir.join("bare.obj");
    std::fs::write(&obj, "v -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 3 2\n").unwrap();
    let pfm = dir.join("bare.pfm");
    let out = raypack(&[
        "render",
        s(&obj),
        "-o",
        s(&pfm),
        "--integrator",
        "path",
        "--spp",
        "2",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    check(&out, "bare mesh");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("uniform sky of radiance 1"), "{err}");
    let film = raypack::render::Film::read_pfm(&pfm).unwrap();
    assert!(
        film.pixels.iter().all(|p| p.min_element() > 0.0),
        "sky everywhere"
    );

    // The tutorial's point lights are dim radiance for a path tracer.
    let scene = repo().join("scenes/part1.toml");
    let png = dir.join("part1.png");
    let args = [
        "render",
        s(&scene),
        "-o",
        s(&png),
        "--integrator",
        "path",
        "--spp",
        "1",
        "--width",
        "32",
        "--height",
        "24",
    ];
    let out = raypack(&args);
    check(&out, "part1 path");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("is dark") && err.contains("--exposure "),
        "{err}"
    );
    assert!(png.is_file());
    let out = raypack(&[&args[..], &["--exposure", "6"]].concat());
    check(&out, "part1 path exposed");
    assert!(!String::from_utf8_lossy(&out.stderr).contains("is dark"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A closed stdout (`raypack render ... | head`) loses nothing: the render exits 0 and
/// writes its image.
#[test]
fn a_closed_stdout_does_not_lose_the_image() {
    let dir = scratch("epipe");
    let png = dir.join("part1.png");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_raypack"))
        .current_dir(repo())
        .args([
            "render",
            "scenes/part1.toml",
            "-o",
            s(&png),
            "--width",
            "32",
            "--height",
            "24",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(png.is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--spp` of the path and photon integrators is bounded; the summary counts in words
/// that agree with their numbers.
#[test]
fn gi_spp_is_bounded_and_the_summary_speaks_of_one_thread() {
    let dir = scratch("spp");
    let scene = repo().join("scenes/part1.toml");
    let out_path = dir.join("x.pfm");
    for integrator in ["path", "photon"] {
        let out = raypack(&[
            "render",
            s(&scene),
            "-o",
            s(&out_path),
            "--integrator",
            integrator,
            "--spp",
            "4294967295",
            "--width",
            "8",
            "--height",
            "8",
        ]);
        assert_eq!(out.status.code(), Some(2), "{integrator}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("1 to 65536"), "{err}");
        assert!(!out_path.exists());
    }
    let out = raypack(&[
        "render",
        s(&scene),
        "-o",
        s(&out_path),
        "--integrator",
        "path",
        "--spp",
        "1",
        "--threads",
        "1",
        "--width",
        "8",
        "--height",
        "8",
    ]);
    check(&out, "one sample, one thread");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("1 sample per pixel, 1 thread\n"),
        "{stdout}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
