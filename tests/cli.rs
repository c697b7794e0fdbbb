//! The `rays`, `trace` and `bench` subcommands end to end: files in the layout of
//! RAYS.md, hits that match the in-process scalar path, and the errors users see.

mod common;

use common::cli::{check, raypack, raypack_env, s, scratch};

use raypack::accel::Accel;
use raypack::accel::brute::BruteForce;
use raypack::ray::Hit;
use raypack::rayset::{self, RaySetError};
use raypack::scene::spd;
use std::path::Path;
use std::process::Output;

const SCENE: &str = "spd:tetra:3";

/// `raypack rays SCENE --set SET -o PATH --width W --height H`, which must succeed.
fn write_set(set: &str, path: &Path, width: u32, height: u32) {
    let (w, h) = (width.to_string(), height.to_string());
    check(
        &raypack(&[
            "rays",
            SCENE,
            "--set",
            set,
            "-o",
            s(path),
            "--width",
            &w,
            "--height",
            &h,
        ]),
        "raypack rays",
    );
}

#[test]
fn trace_writes_the_hits_of_the_in_process_scalar_path() {
    let dir = scratch("trace");
    let oracle = BruteForce::new(&spd::generate_spec("tetra:3").unwrap().geometry);
    for set in ["primary", "shadow", "diffuse"] {
        let rays_path = dir.join(format!("{set}.rays"));
        write_set(set, &rays_path, 64, 48);
        let rays = rayset::read_rays(&rays_path).unwrap();
        let expected: Vec<Hit> = rays
            .rays
            .iter()
            .map(|r| oracle.intersect(r).unwrap_or(Hit::MISS))
            .collect();
        let hit_count = expected.iter().filter(|h| h.is_hit()).count();
        assert!(hit_count > 0, "{set}: the set must exercise hits");
        if set == "primary" {
            assert!(hit_count < rays.len(), "and misses");
        }
        for mode in ["scalar", "packet", "stream"] {
            let hits_path = dir.join(format!("{set}.{mode}.hits"));
            check(
                &raypack(&[
                    "trace",
                    SCENE,
                    "--rays",
                    s(&rays_path),
                    "-o",
                    s(&hits_path),
                    "--mode",
                    mode,
                ]),
                "raypack trace",
            );
            let hits = rayset::read_hits(&hits_path).unwrap();
            assert_eq!(hits.len(), rays.len());
            for (i, (got, want)) in hits.iter().zip(&expected).enumerate() {
                assert_eq!(
                    got.prim, want.prim,
                    "{set} {mode} ray {i}: {:?}",
                    rays.rays[i]
                );
                assert_eq!(got.t.to_bits(), want.t.to_bits(), "{set} {mode} ray {i}");
                assert_eq!(got.u.to_bits(), want.u.to_bits(), "{set} {mode} ray {i}");
                assert_eq!(got.v.to_bits(), want.v.to_bits(), "{set} {mode} ray {i}");
            }
        }
    }
    // Outputs are renamed into place: no temporary file is left behind.
    for e in std::fs::read_dir(&dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains(".tmp."), "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn primary_rays_file_has_the_documented_layout_and_packet_order() {
    let dir = scratch("layout");
    let path = dir.join("primary.rays");
    let (w, h) = (48u32, 32u32);
    write_set("primary", &path, 48, 32);
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..8], b"RAYS0001");
    let count = u64::from_le_bytes(bytes[8..16].try_into().unwrap());
    assert_eq!(count, (w * h) as u64);
    assert_eq!(u32::from_le_bytes(bytes[16..20].try_into().unwrap()), w);
    assert_eq!(u32::from_le_bytes(bytes[20..24].try_into().unwrap()), h);
    assert_eq!(bytes.len(), 24 + 32 * count as usize);

    // Recover each ray's pixel from its direction with the camera of RAYS.md.
    let view = spd::generate_spec("tetra:3").unwrap().view;
    let forward = (view.target - view.eye).normalize();
    let right = forward.cross(view.up).normalize();
    let up = right.cross(forward);
    let tan_half = (view.vfov_deg.to_radians() / 2.0).tan();
    let f = |rec: &[u8], k: usize| f32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().unwrap());
    let pixels: Vec<(i64, i64)> = bytes[24..]
        .chunks_exact(32)
        .map(|rec| {
            assert_eq!(
                [f(rec, 0), f(rec, 1), f(rec, 2)],
                view.eye.as_vec3().to_array()
            );
            assert_eq!((f(rec, 3), f(rec, 7)), (0.0, f32::INFINITY));
            let d = glam::DVec3::new(f(rec, 4) as f64, f(rec, 5) as f64, f(rec, 6) as f64);
            assert!((d.length() - 1.0).abs() < 1e-6);
            let (x, y) = (d.dot(right) / d.dot(forward), d.dot(up) / d.dot(forward));
            let px = ((x / (tan_half * w as f64 / h as f64) + 1.0) / 2.0 * w as f64 - 0.5).round();
            let py = ((1.0 - y / tan_half) / 2.0 * h as f64 - 0.5).round();
            (px as i64, py as i64)
        })
        .collect();
    for (i, &(x, y)) in pixels.iter().enumerate() {
        // Tile i / 256 in row-major order of the 16x16 tiles.
        let tile = i as i64 / 256;
        let tiles_x = (w / 16) as i64;
        assert_eq!(
            (x / 16, y / 16),
            (tile % tiles_x, tile / tiles_x),
            "ray {i}"
        );
        if i % 4 == 0 {
            assert!(
                x % 2 == 0 && y % 2 == 0,
                "quad {} starts at ({x}, {y})",
                i / 4
            );
            let quad = [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)];
            assert_eq!(&pixels[i..i + 4], &quad, "rays {i}..{}", i + 4);
            // Quads are row-major inside the tile.
            let q = (i as i64 % 256) / 4;
            assert_eq!(((x % 16) / 2, (y % 16) / 2), (q % 8, q / 8));
        }
    }
    let mut seen = pixels.clone();
    seen.sort();
    seen.dedup();
    assert_eq!(seen.len(), (w * h) as usize, "every pixel exactly once");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_ray_files_are_reported_with_file_and_field() {
    let dir = scratch("bad");
    let good = dir.join("good.rays");
    write_set("primary", &good, 16, 16);
    let bytes = std::fs::read(&good).unwrap();

    let magic = dir.join("magic.rays");
    let mut b = bytes.clone();
    b[..8].copy_from_slice(b"HITS0001");
    std::fs::write(&magic, &b).unwrap();
    let truncated = dir.join("truncated.rays");
    std::fs::write(&truncated, &bytes[..bytes.len() - 10]).unwrap();

    for (path, expect) in [
        (&magic, "bad magic \"HITS0001\""),
        (&truncated, "truncated: record 255 field `dy`"),
    ] {
        let out_path = dir.join("out.hits");
        let out = raypack(&["trace", SCENE, "--rays", s(path), "-o", s(&out_path)]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(s(path)) && err.contains(expect), "{err}");
        assert!(!out_path.exists(), "no output on bad input");
        // The library reports the same through its typed error.
        let e = rayset::read_rays(path).unwrap_err();
        assert!(
            matches!(
                e,
                RaySetError::BadMagic { .. } | RaySetError::Truncated { .. }
            ),
            "{e}"
        );
    }
    let out = raypack(&[
        "trace",
        SCENE,
        "--rays",
        s(&dir.join("missing.rays")),
        "-o",
        s(&dir.join("o.hits")),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.rays"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_prints_agreeing_checksums_and_writes_json() {
    let dir = scratch("bench");
    let json = dir.join("bench.json");
    let out = raypack(&[
        "bench",
        "spd:balls:2",
        "--width",
        "32",
        "--height",
        "32",
        "--repeat",
        "2",
        "--threads",
        "1,2",
        "--modes",
        "all",
        "--json",
        s(&json),
    ]);
    check(&out, "raypack bench");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("Mrays/s") && !stdout.contains("differs"),
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v["machine"]["cores"].as_u64().unwrap() >= 1);
    assert!(!v["machine"]["cpu"].as_str().unwrap().is_empty());
    let simd = v["machine"]["simd"]
        .as_str()
        .expect("machine.simd is a string");
    assert!(!simd.is_empty(), "machine.simd is empty");
    assert!(v["triangles"].is_number(), "triangles: {}", v["triangles"]);
    assert_eq!(v["triangles"], 2, "the floor of balls:2");
    assert_eq!(v["scene"], "spd:balls:2");
    assert_eq!(v["spheres"], 91);
    assert!(v["build_seconds"].as_f64().unwrap() >= 0.0);
    let rows = v["results"].as_array().unwrap();
    assert_eq!(rows.len(), 3 * 6 * 2, "sets x modes x thread counts");
    let modes: Vec<_> = rows[..6]
        .iter()
        .map(|r| {
            (
                r["mode"].as_str().unwrap(),
                r["width"].as_u64().unwrap(),
                r["packet_size"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        modes,
        [
            ("scalar", 1, 1),
            ("packet4", 4, 4),
            ("packet8", 8, 8),
            ("packet16", 16, 16),
            ("tile64", raypack::accel::tile_lanes() as u64, 64),
            ("stream", 1, 1)
        ],
        "every mode with its width and packet size"
    );
    for set in ["primary", "shadow", "diffuse"] {
        let sums: Vec<&str> = rows
            .iter()
            .filter(|r| r["set"] == set)
            .map(|r| r["checksum"].as_str().unwrap())
            .collect();
        assert!(sums.iter().all(|c| *c == sums[0]), "{set}: {sums:?}");
    }
    for r in rows {
        let (lo, med, hi) = (
            r["mrays_min"].as_f64().unwrap(),
            r["mrays_median"].as_f64().unwrap(),
            r["mrays_max"].as_f64().unwrap(),
        );
        assert!(lo > 0.0 && lo <= med && med <= hi, "{r}");
    }
    assert_eq!(rows[0]["rays"], 32 * 32);
    // Camera quads rarely disagree on a direction sign, cosine bounces nearly always.
    for (mode, lanes) in [
        ("packet4", 4),
        ("packet8", 8),
        ("packet16", 16),
        ("tile64", 64),
    ] {
        let split = |set: &str| {
            let pair = v["split_packets"][set][mode].as_array().unwrap();
            (pair[0].as_u64().unwrap(), pair[1].as_u64().unwrap())
        };
        let (primary_split, primary_total) = split("primary");
        let (diffuse_split, diffuse_total) = split("diffuse");
        assert_eq!(primary_total, 32 * 32 / lanes, "{mode}");
        assert!(
            primary_split * 10 < primary_total,
            "{mode}: {primary_split}"
        );
        assert!(
            diffuse_split * 2 > diffuse_total,
            "{mode}: {diffuse_split} of {diffuse_total}"
        );
    }

    // --rays DIR traces ray files instead: the same rays give the same checksum.
    let primary = dir.join("primary.rays");
    check(
        &raypack(&[
            "rays",
            "spd:balls:2",
            "-o",
            s(&primary),
            "--width",
            "32",
            "--height",
            "32",
        ]),
        "raypack rays",
    );
    let json2 = dir.join("files.json");
    check(
        &raypack(&[
            "bench",
            "spd:balls:2",
            "--rays",
            s(&dir),
            "--sets",
            "primary",
            "--repeat",
            "1",
            "--threads",
            "1",
            "--json",
            s(&json2),
        ]),
        "raypack bench",
    );
    let w: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json2).unwrap()).unwrap();
    assert_eq!(w["results"][0]["checksum"], rows[0]["checksum"]);
    assert_eq!(
        w["results"].as_array().unwrap().len(),
        3,
        "the default modes: packet, tile64 and stream"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_without_the_shared_scenes_says_where_they_belong() {
    let out = raypack_env(
        &["bench", "sponza"],
        &[("RAYPACK_SCENES", "/nonexistent/raypack-scenes")],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("../shared/scenes") && err.contains("/nonexistent/raypack-scenes"),
        "{err}"
    );
    let out = raypack(&["bench", "spd:teapot"]);
    assert_eq!(out.status.code(), Some(2));
    let out = raypack(&["bench", "spd:balls:1", "--sets", "primary,caustic"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_cost_flags_change_the_tree_not_the_hits() {
    let dir = scratch("costs");
    let run = |kt: &str| {
        let json = dir.join(format!("kt{kt}.json"));
        check(
            &raypack(&[
                "bench",
                "spd:tetra:4",
                "--width",
                "32",
                "--height",
                "32",
                "--repeat",
                "1",
                "--threads",
                "1",
                "--traversal-cost",
                kt,
                "--json",
                s(&json),
            ]),
            "raypack bench",
        );
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(v["sah_costs"][0].as_f64(), kt.parse().ok());
        v["results"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["checksum"].as_str().unwrap().to_string())
            .collect::<Vec<_>>()
    };
    assert_eq!(run("5"), run("60"));
    for bad in [
        ["--empty-bonus", "1"],
        ["--traversal-cost", "-1"],
        ["--intersection-cost", "0"],
        ["--traversal-cost", "NaN"],
        ["--min-saving", "-1"],
        ["--min-saving", "inf"],
    ] {
        let flag = format!("{}={}", bad[0], bad[1]);
        let out = raypack(&["bench", "spd:tetra:1", &flag]);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(bad[0]), "{bad:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--accel bvh8` times the 8-wide BVH on the same sets: every mode gives the kd-tree's
/// checksums (spheres too: the balls), and the JSON names the accelerator.
#[test]
fn bench_times_the_bvh_with_the_kd_tree_s_answers() {
    let dir = scratch("bvh8");
    let run = |accel: &str| {
        let json = dir.join(format!("{accel}.json"));
        let out = raypack(&[
            "bench",
            "spd:balls:2",
            "--width",
            "32",
            "--height",
            "32",
            "--repeat",
            "1",
            "--threads",
            "1",
            "--modes",
            "scalar,packet8,stream",
            "--accel",
            accel,
            "--json",
            s(&json),
        ]);
        check(&out, "raypack bench --accel");
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let sums: Vec<String> = v["results"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["checksum"].as_str().unwrap().to_string())
            .collect();
        (v["accel"].as_str().unwrap().to_string(), sums)
    };
    let (kd_name, kd) = run("kdtree");
    let (bvh_name, bvh) = run("bvh8");
    assert_eq!(
        (kd_name.as_str(), bvh_name.as_str()),
        ("SAH kd-tree", "8-wide BVH")
    );
    assert_eq!(kd.len(), 9);
    assert_eq!(kd, bvh);
    for bad in [
        vec!["--accel", "bvh4"],
        vec!["--accel", "bvh8", "--compare-tree", "--traversal-cost 10"],
    ] {
        let mut args = vec!["bench", "spd:tetra:1"];
        args.extend(&bad);
        let out = raypack(&args);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--accel") || err.contains("--compare-tree"),
            "{bad:?}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_times_a_second_tree_pass_by_pass() {
    let dir = scratch("compare");
    let json = dir.join("compare.json");
    let out = raypack(&[
        "bench",
        "spd:tetra:3",
        "--width",
        "32",
        "--height",
        "32",
        "--repeat",
        "3",
        "--threads",
        "1",
        "--modes",
        "scalar,stream,tile64",
        "--sets",
        "primary,diffuse",
        "--compare-tree",
        "--empty-cut 0 --traversal-cost 5",
        "--json",
        s(&json),
    ]);
    check(&out, "raypack bench");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("second tree (--compare-tree"), "{stdout}");
    assert_eq!(
        stdout
            .matches("the first (median of paired passes)")
            .count(),
        6,
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["compare_tree"], "--empty-cut 0 --traversal-cost 5");
    assert!(v["second_build_seconds"].as_f64().unwrap() >= 0.0);
    let rows = v["results"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    // Each tree's tile counts come from its own passes (counted with the `stats`
    // feature only; without it no tile note is printed).
    let notes = raypack::accel::kdtree::stats::ENABLED as usize;
    for set in ["primary", "diffuse"] {
        let note = format!("{set} 1 thread, second tree: ");
        assert_eq!(stdout.matches(&note).count(), notes, "{note}\n{stdout}");
    }
    for r in rows {
        let second = &r["second_tree"];
        let (lo, med, hi) = (
            second["mrays_min"].as_f64().unwrap(),
            second["mrays_median"].as_f64().unwrap(),
            second["mrays_max"].as_f64().unwrap(),
        );
        assert!(0.0 < lo && lo <= med && med <= hi, "{r}");
        assert!(second["ratio_median"].as_f64().unwrap() > 0.0, "{r}");
    }
    // Without the flag the rows and the report carry no second tree.
    let plain = dir.join("plain.json");
    let out = raypack(&[
        "bench",
        "spd:tetra:1",
        "--width",
        "16",
        "--height",
        "16",
        "--repeat",
        "1",
        "--threads",
        "1",
        "--sets",
        "primary",
        "--json",
        s(&plain),
    ]);
    check(&out, "raypack bench");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&plain).unwrap()).unwrap();
    assert!(v.get("compare_tree").is_none(), "{v}");
    assert!(v["results"][0].get("second_tree").is_none(), "{v}");
    // Bad flags are reported before any work, naming the flag.
    for (flags, named) in [
        ("--bogus 1", "--bogus"),
        ("--empty-cut 2", "--empty-cut"),
        ("--intersection-cost", "--intersection-cost"),
    ] {
        let out = raypack(&["bench", "spd:tetra:1", "--compare-tree", flags]);
        assert_eq!(out.status.code(), Some(2), "{flags}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--compare-tree") && err.contains(named),
            "{flags}: {err}"
        );
        assert!(out.stdout.is_empty(), "{flags}: work started");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn spd_scenes_export_to_obj() {
    let dir = scratch("obj");
    let obj = dir.join("rings.obj");
    check(
        &raypack(&[
            "rays",
            "spd:rings:1",
            "--obj",
            s(&obj),
            "--sphere-rings",
            "3",
        ]),
        "raypack rays",
    );
    let text = std::fs::read_to_string(&obj).unwrap();
    let faces = text.lines().filter(|l| l.starts_with("f ")).count();
    // One ring: 30 spheres of 6 segments x 3 bands, 30 six-sided tubes, the floor.
    assert_eq!(faces, 30 * 6 * 3 + 30 * 12 + 2);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The OS error's text, which a message must carry exactly once.
const NOT_FOUND: &str = "No such file or directory";

/// Asserts exit code `code` and a one-line message containing `want` and the OS error
/// text exactly once.
fn fails_with(out: &Output, code: i32, want: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{err}");
    assert!(err.contains(want), "`{err}` lacks `{want}`");
    assert_eq!(err.matches(NOT_FOUND).count(), 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn failing_to_write_an_output_exits_1_naming_the_os_error_once() {
    let dir = scratch("write");
    let rays = dir.join("primary.rays");
    write_set("primary", &rays, 16, 16);
    let missing = dir.join("missing");
    let out_in = |name: &str| missing.join(name).to_str().unwrap().to_string();
    let size = ["--width", "16", "--height", "16"];

    let mut args = vec!["rays", SCENE, "-o"];
    let target = out_in("x.rays");
    args.push(&target);
    args.extend(size);
    fails_with(&raypack(&args), 1, "x.rays: cannot write");

    let target = out_in("x.hits");
    let mut args = vec!["rays", SCENE, "-o", s(&rays), "--hits", &target];
    args.extend(size);
    fails_with(&raypack(&args), 1, "x.hits: cannot write");

    let target = out_in("x.obj");
    fails_with(
        &raypack(&["rays", SCENE, "--obj", &target]),
        1,
        "x.obj: cannot write",
    );

    let target = out_in("x.hits");
    fails_with(
        &raypack(&["trace", SCENE, "--rays", s(&rays), "-o", &target]),
        1,
        "x.hits: cannot write",
    );

    let target = out_in("x.json");
    let mut args = vec![
        "bench",
        SCENE,
        "--json",
        &target,
        "--repeat",
        "1",
        "--threads",
        "1",
    ];
    args.extend(size);
    fails_with(&raypack(&args), 1, "x.json: cannot write");

    // Failing to read the user's input stays bad input, and names the OS error once too.
    let target = dir.join("o.hits");
    fails_with(
        &raypack(&[
            "trace",
            SCENE,
            "--rays",
            &out_in("in.rays"),
            "-o",
            s(&target),
        ]),
        2,
        "in.rays: cannot read",
    );
    assert!(!missing.exists() && !target.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn image_sizes_past_the_scene_file_limit_are_bad_input() {
    let dir = scratch("huge");
    let rays = dir.join("x.rays");
    for (args, want) in [
        (
            vec![
                "bench",
                "spd:tetra:2",
                "--width",
                "1048576",
                "--height",
                "1048576",
            ],
            "--width 1048576 must be between 1 and 16384",
        ),
        (
            vec![
                "bench",
                "spd:tetra:2",
                "--width",
                "16384",
                "--height",
                "16384",
            ],
            "--width 16384 and --height 16384 make 268435456 pixels, more than the limit of 67108864",
        ),
        (
            vec![
                "rays",
                "spd:tetra:2",
                "--width",
                "16384",
                "--height",
                "16384",
                "-o",
                s(&rays),
            ],
            "--width 16384 and --height 16384 make 268435456 pixels, more than the limit of 67108864",
        ),
        (
            vec!["rays", "spd:tetra:2", "--height", "0", "-o", s(&rays)],
            "--height 0 must be between 1 and 16384",
        ),
    ] {
        let out = raypack(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: `{err}` lacks `{want}`");
        assert!(!rays.exists(), "{args:?}: a ray file was written");
    }
    // The limit itself is the scene files' (8192 x 8192 pixels): the library refuses
    // a larger primary set too.
    let view = spd::generate_spec("tetra:1").unwrap().view;
    assert_eq!(raypack::scene::file::MAX_PIXELS, 8192 * 8192);
    let e = rayset::standard::primary(&view, 16384, 8192 + 16).unwrap_err();
    assert!(matches!(e, RaySetError::BadParameter { .. }), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn spd_sizes_too_large_are_out_of_range_not_malformed() {
    for (scene, want) in [
        (
            "spd:tree:99999999999",
            "size 99999999999 is out of range: tree takes sizes 0 to 21",
        ),
        (
            "spd:gears:2147483648",
            "size 2147483648 is out of range: gears takes sizes 0 to 322",
        ),
        (
            "spd:tetra:4294967295",
            "size 4294967295 is out of range: tetra takes sizes 0 to 11",
        ),
        ("spd:tree:1x", "size `1x` is not a whole number"),
    ] {
        let out = raypack(&["bench", scene]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{scene}: {err}");
        assert!(err.contains(want), "{scene}: `{err}` lacks `{want}`");
        if !want.contains("whole") {
            assert!(!err.contains("whole number"), "{scene}: {err}");
        }
    }
}

/// Asserts that the run was refused as bad input (exit 2, no panic) with `want` in its
/// message.
fn refused(out: &Output, want: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(want), "`{err}` lacks `{want}`");
    assert!(!err.contains("panicked"), "{err}");
}

/// The help texts list every mode a command takes, an unknown mode's error lists what
/// that command takes, and `bench` by default runs the packet, tile and stream modes and
/// names the fastest of each set.
#[test]
fn modes_are_listed_as_each_command_takes_them() {
    for command in ["render", "trace"] {
        let out = raypack(&[command, "--help"]);
        check(&out, "help");
        let help = String::from_utf8_lossy(&out.stdout);
        for mode in [
            "scalar", "packet4", "packet8", "packet16", "tile64", "stream",
        ] {
            assert!(help.contains(mode), "{command} --help: no {mode}\n{help}");
        }
    }
    let out = raypack(&[
        "render",
        "scenes/part1.toml",
        "-o",
        "x.png",
        "--mode",
        "all",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown mode `all`") && !err.contains("or all"),
        "{err}"
    );
    let out = raypack(&["bench", SCENE, "--modes", "packet,bogus"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("packet or all"));

    let out = raypack(&[
        "bench",
        SCENE,
        "--width",
        "16",
        "--height",
        "16",
        "--repeat",
        "1",
        "--threads",
        "1",
    ]);
    check(&out, "bench with the default modes");
    let stdout = String::from_utf8_lossy(&out.stdout);
    for set in ["primary", "shadow", "diffuse"] {
        let modes: Vec<&str> = stdout
            .lines()
            .filter(|l| l.starts_with(&format!("{set} ")))
            .filter_map(|l| l.split_whitespace().nth(1))
            .collect();
        assert_eq!(modes.len(), 3, "{set}: {modes:?}\n{stdout}");
        assert!(
            modes.contains(&"tile64") && modes.contains(&"stream"),
            "{modes:?}"
        );
        let fastest = format!("fastest  {set} on 1 thread: ");
        let line = stdout.lines().find(|l| l.starts_with(&fastest));
        let best = line.and_then(|l| l[fastest.len()..].split_whitespace().next());
        assert!(best.is_some_and(|b| modes.contains(&b)), "{set}\n{stdout}");
    }
}

/// Each output of `trace` and `rays` is refused under a name of another format, before
/// any work, and nothing is written.
#[test]
fn ray_and_hit_files_must_be_named_as_such() {
    let dir = scratch("names");
    let rays = dir.join("primary.rays");
    write_set("primary", &rays, 16, 16);
    let png = dir.join("j.png");
    let out = raypack(&["trace", SCENE, "--rays", s(&rays), "-o", s(&png)]);
    refused(&out, "j.png: this file is written in the .hits format");
    let out = raypack(&["rays", SCENE, "-o", s(&dir.join("r.png"))]);
    refused(&out, "must end in .rays");
    let out = raypack(&["rays", SCENE, "-o", s(&rays), "--hits", s(&png)]);
    refused(&out, "must end in .hits");
    assert!(!png.exists() && !dir.join("r.png").exists());
    // Any case of the ending is the format's name.
    let upper = dir.join("J.HITS");
    check(
        &raypack(&["trace", SCENE, "--rays", s(&rays), "-o", s(&upper)]),
        "trace -o J.HITS",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `info` refuses `--repeat 0` as `bench` does, counts memory per primitive (a scene of
/// spheres has almost no triangles), and says what its depth limit limits.
#[test]
fn info_figures_mean_what_they_say() {
    refused(
        &raypack(&["info", SCENE, "--repeat", "0"]),
        "--repeat must be at least 1",
    );
    let out = raypack(&["info", "spd:balls:3"]);
    check(&out, "info spd:balls:3");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let total = stdout
        .lines()
        .find(|l| l.starts_with("memory total"))
        .unwrap_or_else(|| panic!("{stdout}"));
    let per_prim: f64 = total
        .split_whitespace()
        .rev()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{total}"));
    assert!(total.ends_with("bytes/primitive"), "{total}");
    assert!(per_prim > 0.0 && per_prim < 1000.0, "{total}");
    let depth = stdout
        .lines()
        .find(|l| l.starts_with("leaf depth"))
        .unwrap();
    assert!(depth.contains("SAH splits stop at depth"), "{depth}");
}

/// `info --accel bvh8` builds the BVH: its JSON counts what `bench --accel bvh8`
/// prints for the same tree, its occupancy record on two threads is a share of the
/// work (all of it for a tree too small to split across threads), and its primary
/// rays hit what the kd-tree's do.
#[test]
fn info_reports_the_bvh_and_its_serial_part() {
    let dir = scratch("info_bvh");
    let json = dir.join("bvh.json");
    let out = raypack(&[
        "info",
        "spd:balls:3",
        "--accel",
        "bvh8",
        "--threads",
        "2",
        "--occupancy",
        "--json",
        s(&json),
    ]);
    check(&out, "info --accel bvh8");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let nodes = report["nodes"].as_u64().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(&format!("nodes            {nodes} 8-wide")),
        "{stdout}"
    );
    let bench = raypack(&[
        "bench",
        "spd:balls:3",
        "--accel",
        "bvh8",
        "--sets",
        "shadow",
        "--modes",
        "stream",
        "--threads",
        "1",
        "--repeat",
        "1",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    check(&bench, "bench --accel bvh8");
    let bench_out = String::from_utf8_lossy(&bench.stdout);
    assert!(
        bench_out.contains(&format!("8-wide BVH ({nodes} nodes")),
        "{bench_out}"
    );
    assert!(report["bytes_per_primitive"].as_f64().unwrap() > 0.0);
    // `--primary` times each tree's one-ray walk on the same rays: the same hits.
    let checksum = |accel: &str| {
        let path = dir.join(format!("{accel}.json"));
        let out = raypack(&[
            "info",
            "spd:balls:3",
            "--accel",
            accel,
            "--primary",
            "--json",
            s(&path),
        ]);
        check(&out, "info --primary");
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert!(v["primary"]["hit_fraction"].as_f64().unwrap() > 0.0, "{v}");
        v["primary"]["checksum"].as_str().unwrap().to_string()
    };
    assert_eq!(checksum("kdtree"), checksum("bvh8"));
    let serial = report["occupancy"]["serial_fraction"].as_f64();
    // A pool of two threads on fewer cores reports no serial part; this tree is too
    // small to split on two threads, so all of it is.
    if std::thread::available_parallelism().map_or(1, |n| n.get()) >= 2 {
        let f = serial.unwrap_or_else(|| panic!("{report}"));
        assert!(f > 0.5 && f <= 1.0, "{report}");
    } else {
        assert!(serial.is_none(), "{report}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A triangle whose corners are finite but so far apart that its area overflows f32 is
/// not called zero-area.
#[test]
fn huge_triangles_are_not_called_zero_area() {
    let dir = scratch("huge");
    let obj = dir.join("huge.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1e30 0 0\nv 0 1e30 0\nv 0 0 0.5\nf 1 2 3\nf 6 4 5\nf 1 2 2\n",
    )
    .unwrap();
    let out = raypack(&["info", s(&obj)]);
    check(&out, "info huge.obj");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("2 degenerate (1 of zero area, 1 whose area overflows f32) triangles skipped"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `RAYPACK_ISA` picks the kernels: a lower set is taken and reported, an unknown name
/// or a set the CPU lacks is an error before any work.
#[test]
fn raypack_isa_forces_the_kernels_or_is_refused() {
    let scene = "scenes/part1.toml";
    let out = raypack_env(&["info", scene], &[("RAYPACK_ISA", "sse")]);
    check(&out, "info with RAYPACK_ISA=sse");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let kernels = stdout
        .lines()
        .find(|l| l.starts_with("kernels"))
        .expect("info names the kernels");
    assert!(kernels.contains("sse"), "{kernels}");

    let out = raypack_env(&["info", scene], &[("RAYPACK_ISA", "avx9")]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("RAYPACK_ISA=\"avx9\"") && stderr.contains("sse, avx2 or avx512"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty(), "no work before the error");

    if let Some(lacking) = raypack::simd::Isa::ALL.into_iter().find(|i| !i.supported()) {
        let out = raypack_env(&["info", scene], &[("RAYPACK_ISA", lacking.name())]);
        assert_eq!(out.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("this CPU does not run"), "{stderr}");
    }
}
