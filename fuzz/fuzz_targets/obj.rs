//! The OBJ loader on arbitrary bytes (written to a file, as the loader reads paths): it
//! must return a mesh that keeps the `ObjMesh` invariants or an `ObjError` about the
//! input, never panic, and never report that its two readers disagree (`Inconsistent`,
//! or `tobj` refusing what raypack's line scan accepted).

#![no_main]

use libfuzzer_sys::fuzz_target;
use raypack::scene::ObjError;
use std::path::PathBuf;
use std::sync::OnceLock;

fn path() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        std::env::temp_dir().join(format!("raypack-fuzz-{}.obj", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    std::fs::write(path(), data).expect("write the input");
    match raypack::scene::obj::load(path()) {
        Ok(mesh) => {
            let n = mesh.positions.len();
            assert!(mesh.triangle_count() > 0, "a mesh without faces loaded");
            assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
            assert!(mesh.positions.iter().all(|p| p.is_finite()));
            assert_eq!(mesh.normals.len(), n);
            assert!(mesh.uvs.is_empty() || mesh.uvs.len() == n);
            assert_eq!(mesh.tri_material.len(), mesh.triangles.len());
            assert!(mesh.degenerate_count <= mesh.triangle_count());
        }
        Err(e) => {
            // The line scan must catch all that `tobj` refuses, so the error names a line.
            assert!(
                !matches!(e, ObjError::Inconsistent { .. } | ObjError::Parse { .. }),
                "{e}"
            );
            assert!(!e.to_string().is_empty());
        }
    }
});
