//! Each instruction set's kernels really are compiled for it, read off the `raypack`
//! binary's disassembly (`objdump`, from binutils).
//!
//! A kernel runs inside its backend's entry, a function compiled for the set
//! (`Simd::enter`); everything below it must be inlined into it. A vector operation
//! left out of line is compiled for the baseline and called once per operation: the
//! answers stay right and the speed is gone, which no other test would see. So: no
//! call may reach a `core::arch` intrinsic or a `wide` operation, no entry may call
//! raypack's code, a closure or an iterator adapter out of line (scalar code such as the
//! single-ray walk runs in the entries too), the AVX2 entries use
//! `ymm` registers, the AVX-512 entries `zmm` registers and `k` masks, and in a build
//! for the baseline the portable entries use neither.

use std::process::Command;

/// The disassembly of the `raypack` binary, symbols demangled.
fn disassembly() -> String {
    let bin = env!("CARGO_BIN_EXE_raypack");
    let out = Command::new("objdump")
        .args(["-d", "--no-show-raw-insn", "-C", bin])
        .output()
        .unwrap_or_else(|e| panic!("cannot run objdump (binutils) on {bin}: {e}"));
    assert!(out.status.success(), "objdump {bin} failed");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The instructions of every instance of the function whose demangled name starts with
/// `name`.
fn bodies<'a>(dis: &'a str, name: &str) -> Vec<&'a str> {
    let mut inside = false;
    let mut lines = Vec::new();
    for line in dis.lines() {
        if line.ends_with(">:") {
            inside = line.contains(&format!("<{name}"));
        } else if inside {
            lines.push(line);
        }
    }
    lines
}

fn count(lines: &[&str], needle: &str) -> usize {
    lines.iter().filter(|l| l.contains(needle)).count()
}

#[cfg(target_arch = "x86_64")]
#[test]
fn kernels_are_compiled_for_their_instruction_set() {
    let dis = disassembly();
    let calls: Vec<&str> = dis
        .lines()
        .filter(|l| l.contains("call"))
        .filter(|l| {
            (l.contains("core::core_arch::") && !l.contains("_xgetbv") && !l.contains("cpuid"))
                || l.contains("<wide::")
                || l.contains("<<wide::")
                || l.contains("<safe_arch::")
        })
        .collect();
    assert!(
        calls.is_empty(),
        "vector operations called out of line (not inlined into a kernel entry):\n{}",
        calls[..calls.len().min(20)].join("\n")
    );

    // Scalar code called out of line from an entry is compiled for the baseline too: a
    // closure, an iterator adapter (`(0..3).any`) or a helper such as `Ray::is_usable`
    // run per ray or per packet. The node-split choice of the build runs once per node.
    let entries = ["avx2::entry", "avx512::entry", "portable::enter_base"];
    let allowed = ["OnceLock<T>::initialize", "SmallNode::planar_left"];
    let scalar_calls: Vec<&str> = entries
        .iter()
        .flat_map(|e| bodies(&dis, &format!("raypack::simd::{e}")))
        .filter(|l| {
            (l.contains("\tcall ") || l.contains("\tjmp "))
                && l.contains(" <")
                && !l.contains("+0x")
                && !allowed.iter().any(|a| l.contains(a))
                && (l.contains("<raypack::")
                    || l.contains("{{closure}}")
                    || l.contains("FnOnce")
                    || l.contains("core::iter::"))
        })
        .collect();
    assert!(
        scalar_calls.is_empty(),
        "kernel entries call code out of line (compiled for the baseline):\n{}",
        scalar_calls[..scalar_calls.len().min(20)].join("\n")
    );

    let avx2 = bodies(&dis, "raypack::simd::avx2::entry");
    assert!(!avx2.is_empty(), "no AVX2 entry in the binary");
    assert!(
        count(&avx2, "%ymm") > 1000,
        "the AVX2 entries use no ymm registers"
    );

    let avx512 = bodies(&dis, "raypack::simd::avx512::entry");
    assert!(!avx512.is_empty(), "no AVX-512 entry in the binary");
    assert!(
        count(&avx512, "%zmm") > 1000,
        "the AVX-512 entries use no zmm registers"
    );
    assert!(
        count(&avx512, "%k1") > 100,
        "the AVX-512 entries use no mask registers"
    );

    let base = bodies(&dis, "raypack::simd::portable::enter_base");
    assert!(!base.is_empty(), "no portable entry in the binary");
    if !cfg!(target_feature = "avx") {
        assert_eq!(
            count(&base, "%ymm"),
            0,
            "baseline entries use AVX registers"
        );
        assert_eq!(
            count(&base, "%zmm"),
            0,
            "baseline entries use AVX-512 registers"
        );
    }
}
