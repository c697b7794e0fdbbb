//! Watertightness: rays from strictly inside closed meshes must all hit the surface, for
//! the scalar kd-tree path and the packet path. Each mesh gets 131,072 rays in random
//! directions plus 65,536 rays aimed exactly at shared vertices and edges (1,048,576 and
//! 262,144 with `RAYPACK_EXHAUSTIVE=1`, as CI runs it), and the test asserts zero leaks. The counts are printed (`cargo test --release --test watertight
//! -- --nocapture`) so the leak rate of a triangle test can be read off directly.

mod common;

use common::closed::{aimed_rays, closed_meshes, interior_rays, leaks_packet, leaks_scalar};
use raypack::accel::kdtree::KdTree;
use raypack::simd::{Isa, W4, W8, W16};

#[test]
fn closed_meshes_leak_no_ray() {
    let mut report = Vec::new();
    let mut failures = Vec::new();
    let random_count = common::ray_count(1 << 17, 1 << 20);
    let aimed_count = common::ray_count(1 << 16, 1 << 18);
    for (m, mesh) in closed_meshes().iter().enumerate() {
        let start = std::time::Instant::now();
        let tree = KdTree::build(&mesh.geometry);
        println!("{}: tree built in {:?}", mesh.name, start.elapsed());
        let sets = [
            ("random", interior_rays(mesh, random_count, 100 + m as u64)),
            ("aimed", aimed_rays(mesh, aimed_count, 200 + m as u64)),
        ];
        for (set, rays) in &sets {
            let isas = common::isas();
            let paths = std::iter::once(("scalar", Isa::Sse)).chain(
                isas.iter()
                    .flat_map(|&i| ["packet4", "packet8", "packet16"].map(|p| (p, i))),
            );
            for (path, isa) in paths {
                let start = std::time::Instant::now();
                let leaks = match path {
                    "scalar" => leaks_scalar(&tree, rays),
                    "packet4" => leaks_packet::<W4>(isa, &tree, rays),
                    "packet8" => leaks_packet::<W8>(isa, &tree, rays),
                    _ => leaks_packet::<W16>(isa, &tree, rays),
                };
                let path = if path == "scalar" {
                    path.to_string()
                } else {
                    format!("{path}/{isa}")
                };
                let elapsed = start.elapsed();
                let line = format!(
                    "{:<12} {:>7} tris  {set:<6} {path:<15} {:>4} leaks / {} rays ({elapsed:.2?})",
                    mesh.name,
                    mesh.geometry.triangles.len(),
                    leaks.len(),
                    rays.len()
                );
                println!("{line}");
                if let Some(&i) = leaks.first() {
                    failures.push(format!("{line}; first: ray {i} {:?}", rays[i]));
                }
                report.push(line);
            }
        }
    }
    assert!(failures.is_empty(), "leaks:\n{}", failures.join("\n"));
    let paths = 1 + 3 * common::isas().len();
    assert_eq!(report.len(), 4 * 2 * paths, "meshes x ray sets x paths");
}
