//! Running the `raypack` binary from the integration tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `raypack ARGS` from the crate root (so `scenes/...` and `../shared/scenes`
/// resolve as in the README) and returns what it printed.
pub fn raypack(args: &[&str]) -> Output {
    raypack_env(args, &[])
}

/// [`raypack`] with extra environment variables.
pub fn raypack_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_raypack"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("run the raypack binary")
}

/// Asserts that the run succeeded, showing its output when it did not.
pub fn check(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what}: exit {:?}\nstdout:\n{}\nstderr:\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A fresh, empty folder for one test's files, named after the test binary and `name`.
pub fn scratch(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let binary = exe.file_stem().unwrap().to_string_lossy();
    let dir = std::env::temp_dir().join(format!("raypack-{binary}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A path as the `&str` an argument list takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
