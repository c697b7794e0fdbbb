//! `raypack info --builder exact|fast --json FILE` end to end: the JSON holds what `info`
//! prints, for the builder asked for, and agrees with the library's own tree.

use raypack::accel::kdtree::{BuildParams, BuilderKind, KdTree};
use raypack::scene::catalog as scenes;
use std::process::{Command, Output};

const SCENE: &str = "spd:tetra:4";

fn raypack(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_raypack"))
        .args(args)
        .output()
        .expect("run raypack")
}

#[test]
fn info_json_reports_the_tree_of_each_builder() {
    let dir = std::env::temp_dir().join(format!("raypack-kdtree-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let geometry = scenes::load(SCENE).unwrap().geometry;
    for builder in [BuilderKind::Exact, BuilderKind::Fast] {
        let path = dir.join(format!("{builder}.json"));
        let out = raypack(&[
            "info",
            SCENE,
            "--threads",
            "1",
            "--repeat",
            "3",
            "--builder",
            builder.name(),
            "--json",
            path.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(stdout.contains(&format!("{builder} builder")), "{stdout}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let params = BuildParams {
            builder,
            parallel: false,
            ..BuildParams::default()
        };
        let tree = KdTree::build_with(&geometry, &params);
        let stats = tree.stats(&params);
        assert_eq!(json["builder"], builder.name());
        assert_eq!(json["threads"], 1);
        assert_eq!(json["nodes"], stats.nodes);
        assert_eq!(json["leaves"], stats.leaves);
        assert_eq!(json["sah"]["cost"].as_f64().unwrap(), stats.sah_cost);
        assert_eq!(json["sah"]["traversal_cost"], 30.0);
        let times = json["build_seconds"]["all"].as_array().unwrap();
        assert_eq!(times.len(), 3);
        let min = json["build_seconds"]["min"].as_f64().unwrap();
        let median = json["build_seconds"]["median"].as_f64().unwrap();
        assert!(min > 0.0 && min <= median, "{min} {median}");
        let memory = &json["memory"];
        let parts: u64 = ["nodes", "leaf_table", "index_lists", "triaccel"]
            .iter()
            .map(|k| memory[k]["bytes"].as_u64().unwrap())
            .sum();
        assert_eq!(memory["total"]["bytes"].as_u64().unwrap(), parts);
        assert_eq!(memory["nodes"]["bytes"], 8 * stats.nodes as u64);
        if cfg!(target_os = "linux") {
            assert!(json["build_peak_extra_bytes"].as_u64().is_some(), "{json}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_unknown_builder_is_bad_input() {
    let out = raypack(&["info", SCENE, "--builder", "quick"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("exact or fast"), "{err}");
}
