//! The portable backends [`W4`], [`W8`] and [`W16`]: `wide`'s vectors, compiled for
//! the target the crate is built for (the x86-64 baseline, SSE2, unless `-C
//! target-cpu` says more). The kernels' public entry points take these widths; the
//! wider instruction sets' backends of the same widths stand behind them
//! ([`super::dispatch`]).

use super::{
    AMap, Float, Isa, LaneBits, LaneMask, Uint, VBool, array_fn, rows4_lanes, transpose4_lanes,
    transpose8_lanes,
};
use std::ops::{BitAnd, BitAndAssign, BitOr, BitOrAssign, Not};

/// The entry of the portable backends: a function boundary and nothing more (the
/// portable vectors need no instruction set beyond the build's).
#[inline(never)]
pub(crate) fn enter_base<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// [`Float::transpose8`] of `wide`'s f32x8: a full packet's eight records as one 8x8
/// transpose (`wide`'s, 24 shuffles with AVX) instead of 64 single-lane inserts.
#[inline(always)]
fn transpose8_x8(records: &[[f32; 8]]) -> [wide::f32x8; 8] {
    let Ok(records) = <&[[f32; 8]; 8]>::try_from(records) else {
        return transpose8_lanes(records);
    };
    wide::f32x8::transpose(records.amap(wide::f32x8::new))
}

/// [`Float::transpose4_into`] of `wide`'s f32x8: the low and the high halves of the
/// four vectors as two 4x4 transposes, eight stores.
#[inline(always)]
fn transpose4_x8(v: [wide::f32x8; 4], out: &mut [[f32; 4]]) {
    let Ok(out) = <&mut [[f32; 4]; 8]>::try_from(&mut *out) else {
        return transpose4_lanes(v, out);
    };
    let a = v.amap(|x| x.to_array());
    for h in 0..2 {
        let half = a.amap(|x| wide::f32x4::new(array_fn(|j| x[4 * h + j])));
        for (r, t) in out[4 * h..].iter_mut().zip(wide::f32x4::transpose(half)) {
            *r = t.to_array();
        }
    }
}

/// [`Float::from_rows4`] of `wide`'s f32x4: four row loads and one 4x4 transpose
/// (eight shuffles for sixteen words).
#[inline(always)]
fn rows4_x4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [wide::f32x4; 4] {
    wide::f32x4::transpose(array_fn(|i| wide::f32x4::new(*rows(i))))
}

/// The [`Float`], [`Uint`] and [`LaneMask`] impls of one pair of `wide` types: masks
/// are float vectors with every bit of a lane set or clear. `$t8` and `$t4` are the
/// type's [`Float::transpose8`] and [`Float::transpose4_into`], `$r4` its
/// [`Float::from_rows4`].
macro_rules! wide_backend {
    ($f:ident, $u:ident, $t8:path, $t4:path, $r4:path) => {
        impl BitAnd for VBool<wide::$f> {
            type Output = Self;
            #[inline(always)]
            fn bitand(self, o: Self) -> Self {
                VBool(self.0 & o.0)
            }
        }

        impl BitOr for VBool<wide::$f> {
            type Output = Self;
            #[inline(always)]
            fn bitor(self, o: Self) -> Self {
                VBool(self.0 | o.0)
            }
        }

        impl Not for VBool<wide::$f> {
            type Output = Self;
            #[inline(always)]
            fn not(self) -> Self {
                VBool(!self.0)
            }
        }

        impl BitAndAssign for VBool<wide::$f> {
            #[inline(always)]
            fn bitand_assign(&mut self, o: Self) {
                self.0 = self.0 & o.0;
            }
        }

        impl BitOrAssign for VBool<wide::$f> {
            #[inline(always)]
            fn bitor_assign(&mut self, o: Self) {
                self.0 = self.0 | o.0;
            }
        }

        impl LaneMask for VBool<wide::$f> {
            const NONE: Self = VBool(wide::$f::ZERO);
            #[inline(always)]
            fn from_bits(bits: LaneBits) -> Self {
                let lanes = wide::$u::new(array_fn(|i| 1 << i));
                let set = (wide::$u::splat(bits) & lanes).simd_eq(lanes);
                VBool(wide::$f::from_bits(set))
            }
            #[inline(always)]
            fn bits(self) -> LaneBits {
                self.0.to_bitmask()
            }
            #[inline(always)]
            fn any(self) -> bool {
                self.0.any()
            }
        }

        impl Float for wide::$f {
            type Mask = VBool<wide::$f>;
            type U = wide::$u;
            const ZERO: Self = wide::$f::ZERO;
            const ONE: Self = wide::$f::ONE;
            #[inline(always)]
            fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
                $t8(records)
            }
            #[inline(always)]
            fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
                $t4(v, out)
            }
            #[inline(always)]
            fn from_rows4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [Self; 4] {
                $r4(rows)
            }
            #[inline(always)]
            fn splat(x: f32) -> Self {
                wide::$f::splat(x)
            }
            #[inline(always)]
            fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
                wide::$f::new(array_fn(f))
            }
            #[inline(always)]
            fn lane(&self, i: usize) -> f32 {
                self.as_array()[i]
            }
            #[inline(always)]
            fn cmp_lt(self, o: Self) -> Self::Mask {
                VBool(self.simd_lt(o))
            }
            #[inline(always)]
            fn cmp_gt(self, o: Self) -> Self::Mask {
                VBool(self.simd_gt(o))
            }
            #[inline(always)]
            fn cmp_le(self, o: Self) -> Self::Mask {
                VBool(self.simd_le(o))
            }
            #[inline(always)]
            fn cmp_ge(self, o: Self) -> Self::Mask {
                VBool(self.simd_ge(o))
            }
            #[inline(always)]
            fn cmp_eq(self, o: Self) -> Self::Mask {
                VBool(self.simd_eq(o))
            }
            #[inline(always)]
            fn finite(self) -> Self::Mask {
                VBool(wide::$f::is_finite(self))
            }
            #[inline(always)]
            fn abs(self) -> Self {
                wide::$f::abs(self)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                wide::$f::sqrt(self)
            }
            #[inline(always)]
            fn min(self, o: Self) -> Self {
                wide::$f::min(self, o)
            }
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                wide::$f::max(self, o)
            }
            #[inline(always)]
            fn min_lt(self, o: Self) -> Self {
                self.fast_min(o)
            }
            #[inline(always)]
            fn max_gt(self, o: Self) -> Self {
                self.fast_max(o)
            }
            #[inline(always)]
            fn to_bits(self) -> wide::$u {
                wide::$f::to_bits(self)
            }
            #[inline(always)]
            fn from_bits(u: wide::$u) -> Self {
                wide::$f::from_bits(u)
            }
            #[inline(always)]
            fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
                mask.0.bitselect(if_true, if_false)
            }
        }

        impl Uint for wide::$u {
            type Mask = VBool<wide::$f>;
            #[inline(always)]
            fn splat(x: u32) -> Self {
                wide::$u::splat(x)
            }
            #[inline(always)]
            fn from_fn(f: impl FnMut(usize) -> u32) -> Self {
                wide::$u::new(array_fn(f))
            }
            #[inline(always)]
            fn lane(&self, i: usize) -> u32 {
                self.as_array()[i]
            }
            #[inline(always)]
            fn cmp_gt(self, o: Self) -> Self::Mask {
                VBool(wide::$f::from_bits(self.simd_gt(o)))
            }
            #[inline(always)]
            fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
                mask.0.to_bits().bitselect(if_true, if_false)
            }
            #[inline(always)]
            fn shr(self, n: u32) -> Self {
                self >> n
            }
        }
    };
}

wide_backend!(f32x4, u32x4, transpose8_lanes, transpose4_lanes, rows4_x4);
wide_backend!(f32x8, u32x8, transpose8_x8, transpose4_x8, rows4_lanes);
wide_backend!(
    f32x16,
    u32x16,
    transpose8_lanes,
    transpose4_lanes,
    rows4_lanes
);

backend!(
    pub W4,
    Isa::Sse,
    enter_base,
    wide::f32x4,
    wide::u32x4,
    VBool<wide::f32x4>,
    4,
    [W4, W8],
    "4 lanes, portable (`wide`'s f32x4; SSE): the Wald packet."
);
backend!(
    pub W8,
    Isa::Sse,
    enter_base,
    wide::f32x8,
    wide::u32x8,
    VBool<wide::f32x8>,
    8,
    [W4, W8],
    "8 lanes, portable (`wide`'s f32x8: two SSE registers in a baseline build)."
);
backend!(
    pub W16,
    Isa::Sse,
    enter_base,
    wide::f32x16,
    wide::u32x16,
    VBool<wide::f32x16>,
    16,
    [W4, W8],
    "16 lanes, portable (`wide`'s f32x16: four SSE registers in a baseline build)."
);
