//! The instruction set the kernels run: detected once, forced lower by `RAYPACK_ISA`,
//! and for tests per thread ([`Isa::scope`]). The two places a lane count becomes a
//! type: [`by_width`] picks the portable width of a count known at run time (a mode's
//! packet, the native width), and [`dispatch`] the backend of the instruction set in
//! use behind a portable width.

use std::cell::Cell;
use std::sync::OnceLock;

/// An instruction set the kernels are compiled for, narrowest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// The x86-64 baseline (SSE2), or whatever the build targets elsewhere: the
    /// portable backends.
    Sse,
    /// AVX2 + FMA with BMI1/2, LZCNT, F16C and MOVBE (x86-64-v3): 8 lanes a register.
    Avx2,
    /// AVX-512 F, BW, CD, DQ and VL on top of AVX2 (x86-64-v4): 16 lanes a register,
    /// masks in `k` registers.
    Avx512,
}

/// `RAYPACK_ISA` names an instruction set that is unknown or that this CPU lacks.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum IsaError {
    /// Not one of the names.
    #[error("RAYPACK_ISA={0:?}: unknown instruction set (expected sse, avx2 or avx512)")]
    Unknown(String),
    /// A set the CPU does not run.
    #[error("RAYPACK_ISA={forced}: this CPU does not run {forced} (the widest it runs is {best})")]
    Unsupported {
        /// The set asked for.
        forced: Isa,
        /// The widest set the CPU runs.
        best: Isa,
    },
}

impl Isa {
    /// Every set, narrowest first.
    pub const ALL: [Isa; 3] = [Isa::Sse, Isa::Avx2, Isa::Avx512];

    /// The name `RAYPACK_ISA` takes and the reports print.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Sse => "sse",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Lanes of one register of this set (the width of its native packet).
    pub fn lanes(self) -> usize {
        match self {
            Isa::Sse => 4,
            Isa::Avx2 => 8,
            Isa::Avx512 => 16,
        }
    }

    /// True when this CPU runs the set (detected once per process).
    #[inline]
    pub fn supported(self) -> bool {
        self <= Isa::best()
    }

    /// The widest set this CPU runs.
    #[inline]
    pub fn best() -> Isa {
        static BEST: OnceLock<Isa> = OnceLock::new();
        *BEST.get_or_init(|| {
            *Isa::ALL
                .iter()
                .rev()
                .find(|i| i.detect())
                .unwrap_or(&Isa::Sse)
        })
    }

    /// Asks the CPU (through the standard library's feature detection).
    fn detect(self) -> bool {
        match self {
            Isa::Sse => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                use std::arch::is_x86_feature_detected as has;
                has!("avx2")
                    && has!("fma")
                    && has!("bmi1")
                    && has!("bmi2")
                    && has!("lzcnt")
                    && has!("f16c")
                    && has!("movbe")
                    && has!("popcnt")
            }
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => {
                use std::arch::is_x86_feature_detected as has;
                Isa::Avx2.detect()
                    && has!("avx512f")
                    && has!("avx512bw")
                    && has!("avx512cd")
                    && has!("avx512dq")
                    && has!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// Every set this CPU runs, narrowest first: the paths the tests compare with the
    /// scalar oracle.
    pub fn all_supported() -> Vec<Isa> {
        Isa::ALL.into_iter().filter(|i| i.supported()).collect()
    }

    /// The set `RAYPACK_ISA` forces, `None` when it is unset or empty. The command line
    /// calls this first so that a bad value is an error; the library falls back to
    /// [`Isa::best`] on one.
    pub fn from_env() -> Result<Option<Isa>, IsaError> {
        let Some(value) = std::env::var_os("RAYPACK_ISA") else {
            return Ok(None);
        };
        let value = value.to_string_lossy();
        if value.is_empty() {
            return Ok(None);
        }
        let forced: Isa = value.parse()?;
        if !forced.supported() {
            return Err(IsaError::Unsupported {
                forced,
                best: Isa::best(),
            });
        }
        Ok(Some(forced))
    }

    /// The set the kernels run on this thread: the one [`Isa::scope`] set, else
    /// `RAYPACK_ISA`'s, else [`Isa::best`]; decided once per process.
    #[inline]
    pub fn in_use() -> Isa {
        static CHOSEN: OnceLock<Isa> = OnceLock::new();
        SCOPED.with(Cell::get).unwrap_or_else(|| {
            *CHOSEN.get_or_init(|| Isa::from_env().ok().flatten().unwrap_or_else(Isa::best))
        })
    }

    /// Runs `f` with the kernels of this set on the calling thread (work `f` hands to
    /// other threads runs theirs). Tests run every supported set this way; `None`
    /// when the CPU lacks this one.
    pub fn scope<R>(self, f: impl FnOnce() -> R) -> Option<R> {
        if !self.supported() {
            return None;
        }
        struct Restore(Option<Isa>);
        impl Drop for Restore {
            fn drop(&mut self) {
                SCOPED.with(|s| s.set(self.0));
            }
        }
        let _restore = Restore(SCOPED.with(|s| s.replace(Some(self))));
        Some(f())
    }
}

thread_local! {
    /// The set [`Isa::scope`] forces on this thread.
    static SCOPED: Cell<Option<Isa>> = const { Cell::new(None) };
}

impl std::fmt::Display for Isa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Isa {
    type Err = IsaError;
    fn from_str(s: &str) -> Result<Isa, IsaError> {
        match s.to_ascii_lowercase().as_str() {
            "sse" | "sse2" => Ok(Isa::Sse),
            "avx2" => Ok(Isa::Avx2),
            "avx512" => Ok(Isa::Avx512),
            _ => Err(IsaError::Unknown(s.to_string())),
        }
    }
}

/// Runs `f`, a scalar kernel, inside the entry of the set in use, so that it is compiled
/// for that set as the vector kernels are (VEX three-operand forms, BMI): the single-ray
/// walk of a default build ran 4-10% behind a `target-cpu=native` build's (perf/isa.md).
/// Scalar code gives the same bits under every set: Rust never fuses a multiply and add.
#[inline(always)]
pub(crate) fn scalar_entry<R>(f: impl FnOnce() -> R) -> R {
    use super::{Avx2x4, Avx512x4, Simd, W4};
    match Isa::in_use() {
        Isa::Avx512 => Avx512x4::enter(f),
        Isa::Avx2 => Avx2x4::enter(f),
        Isa::Sse => W4::enter(f),
    }
}

/// `$body` with the type `$w` the portable width ([`super::W4`], [`super::W8`] or
/// [`super::W16`]) of `$lanes` lanes, a count known at run time: `by_width!(lanes, W =>
/// f::<W>(x))`. A count of 16 is `W16`, 8 is `W8`, any other `W4` (a mode's packet
/// size is 1 in scalar mode, whose blocks and batches are 4 wide). `$w in [8, 16]`
/// takes 8 for every count but 16 (a tile's groups: 4 lanes is no tile width).
macro_rules! by_width {
    ($lanes:expr, $w:ident => $body:expr) => {
        match $lanes {
            16 => {
                type $w = $crate::simd::W16;
                $body
            }
            8 => {
                type $w = $crate::simd::W8;
                $body
            }
            _ => {
                type $w = $crate::simd::W4;
                $body
            }
        }
    };
    ($lanes:expr, $w:ident in [8, 16] => $body:expr) => {
        match $lanes {
            16 => {
                type $w = $crate::simd::W16;
                $body
            }
            _ => {
                type $w = $crate::simd::W8;
                $body
            }
        }
    };
}
pub(crate) use by_width;

/// `$recv.$method::<B, ..>(args)` with `B` the backend of `$lanes` lanes (4, 8 or 16)
/// for the instruction set in use, entered through [`super::Simd::enter`]: the one
/// place a width becomes a backend. The method's other generic arguments follow `@`.
macro_rules! dispatch {
    ($lanes:expr; $recv:ident . $m:ident :: < @ $(, $g:tt)* > ( $($a:expr),* $(,)? )) => {{
        #[allow(unused_imports)]
        use $crate::simd::{
            Avx2x4, Avx2x8, Avx2x16, Avx512x4, Avx512x8, Avx512x16, Isa, Simd, W4, W8, W16,
        };
        match (Isa::in_use(), $lanes) {
            (Isa::Avx512, 16) => Avx512x16::enter(#[inline(always)] || $recv.$m::<Avx512x16 $(, $g)*>($($a),*)),
            (Isa::Avx512, 8) => Avx512x8::enter(#[inline(always)] || $recv.$m::<Avx512x8 $(, $g)*>($($a),*)),
            (Isa::Avx512, _) => Avx512x4::enter(#[inline(always)] || $recv.$m::<Avx512x4 $(, $g)*>($($a),*)),
            (Isa::Avx2, 16) => Avx2x16::enter(#[inline(always)] || $recv.$m::<Avx2x16 $(, $g)*>($($a),*)),
            (Isa::Avx2, 8) => Avx2x8::enter(#[inline(always)] || $recv.$m::<Avx2x8 $(, $g)*>($($a),*)),
            (Isa::Avx2, _) => Avx2x4::enter(#[inline(always)] || $recv.$m::<Avx2x4 $(, $g)*>($($a),*)),
            (Isa::Sse, 16) => W16::enter(#[inline(always)] || $recv.$m::<W16 $(, $g)*>($($a),*)),
            (Isa::Sse, 8) => W8::enter(#[inline(always)] || $recv.$m::<W8 $(, $g)*>($($a),*)),
            (Isa::Sse, _) => W4::enter(#[inline(always)] || $recv.$m::<W4 $(, $g)*>($($a),*)),
        }
    }};
    ($lanes:expr; fn $f:ident :: < @ $(, $g:tt)* > ( $($a:expr),* $(,)? )) => {{
        #[allow(unused_imports)]
        use $crate::simd::{
            Avx2x4, Avx2x8, Avx2x16, Avx512x4, Avx512x8, Avx512x16, Isa, Simd, W4, W8, W16,
        };
        match (Isa::in_use(), $lanes) {
            (Isa::Avx512, 16) => Avx512x16::enter(#[inline(always)] || $f::<Avx512x16 $(, $g)*>($($a),*)),
            (Isa::Avx512, 8) => Avx512x8::enter(#[inline(always)] || $f::<Avx512x8 $(, $g)*>($($a),*)),
            (Isa::Avx512, _) => Avx512x4::enter(#[inline(always)] || $f::<Avx512x4 $(, $g)*>($($a),*)),
            (Isa::Avx2, 16) => Avx2x16::enter(#[inline(always)] || $f::<Avx2x16 $(, $g)*>($($a),*)),
            (Isa::Avx2, 8) => Avx2x8::enter(#[inline(always)] || $f::<Avx2x8 $(, $g)*>($($a),*)),
            (Isa::Avx2, _) => Avx2x4::enter(#[inline(always)] || $f::<Avx2x4 $(, $g)*>($($a),*)),
            (Isa::Sse, 16) => W16::enter(#[inline(always)] || $f::<W16 $(, $g)*>($($a),*)),
            (Isa::Sse, 8) => W8::enter(#[inline(always)] || $f::<W8 $(, $g)*>($($a),*)),
            (Isa::Sse, _) => W4::enter(#[inline(always)] || $f::<W4 $(, $g)*>($($a),*)),
        }
    }};
}
pub(crate) use dispatch;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for isa in Isa::ALL {
            assert_eq!(isa.name().parse::<Isa>(), Ok(isa));
        }
        assert!(matches!("avx3".parse::<Isa>(), Err(IsaError::Unknown(_))));
    }

    #[test]
    fn scope_sets_and_restores_the_thread_s_set() {
        let outside = Isa::in_use();
        for isa in Isa::all_supported() {
            assert_eq!(isa.scope(Isa::in_use), Some(isa));
            assert_eq!(Isa::in_use(), outside);
        }
        assert!(Isa::Sse.supported());
        assert!(Isa::best() >= Isa::Sse);
    }
}
