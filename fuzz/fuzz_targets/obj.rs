//! The OBJ loader on arbitrary bytes (written to a file, as the loader reads paths): it
//! must return a mesh or an `ObjError`, never panic.

#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn path() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| std::env::temp_dir().join(format!("raypack-fuzz-{}.obj", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    std::fs::write(path(), data).expect("write the input");
    match raypack::scene::obj::load(path()) {
        Ok(mesh) => {
            let _ = mesh.triangle_count();
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
