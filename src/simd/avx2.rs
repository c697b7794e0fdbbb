//! The AVX2 + FMA backends: 8 lanes in one `ymm` register ([`F32x8`]), 16 in two
//! ([`F32x16`]), and 4 as `wide`'s f32x4 compiled inside AVX2 entries (VEX-encoded).
//!
//! Every operation is the instruction `wide` issues when it is built for AVX2 (same
//! operand order, same NaN rule), so these backends, the portable ones and the scalar
//! path give the same bits; the tests in `super` compare them lane by lane.
//!
//! The types are crate-private and only made inside [`enter_avx2`], which checks the
//! CPU first: that is what makes the `unsafe` intrinsic calls below sound.

use super::{
    AMap, Float, Isa, LaneBits, LaneMask, Uint, VBool, array_fn, inl, transpose4_lanes,
    transpose8_halves_lanes, transpose8_lanes,
};
use std::arch::x86_64::*;
use std::fmt;
use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

/// Runs `f` compiled for AVX2 + FMA: the entry of every AVX2 kernel. Panics when the
/// CPU lacks AVX2.
#[inline(always)]
pub(crate) fn enter_avx2<R>(f: impl FnOnce() -> R) -> R {
    assert!(Isa::Avx2.supported(), "AVX2 kernel on a CPU without AVX2");
    // SAFETY: the CPU runs every feature of `entry` (checked above).
    unsafe { entry(f) }
}

/// The features of x86-64-v3, the set [`Isa::Avx2`] detects.
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,f16c,movbe,popcnt")]
#[inline(never)]
unsafe fn entry<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// Calls AVX/AVX2 intrinsics, unsafe outside functions that enable the features.
macro_rules! avx {
    ($e:expr) => {
        // SAFETY: values of this module's types exist only under `enter_avx2` (or in
        // tests on a CPU that has AVX2), which checks the CPU.
        unsafe { $e }
    };
}

/// Eight f32 lanes in one `ymm` register.
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct F32x8(__m256);

/// Eight u32 lanes in one `ymm` register.
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct U32x8(__m256i);

impl F32x8 {
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        bytemuck::cast(self.0)
    }
}

impl U32x8 {
    #[inline(always)]
    fn to_array(self) -> [u32; 8] {
        bytemuck::cast(self.0)
    }
}

impl fmt::Debug for F32x8 {
    #[inline(always)]
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.to_array()).finish()
    }
}

impl fmt::Debug for U32x8 {
    #[inline(always)]
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.to_array()).finish()
    }
}

macro_rules! binary {
    ($t:ident, $tr:ident, $m:ident, $op:ident) => {
        impl $tr for $t {
            type Output = $t;
            #[inline(always)]
            fn $m(self, o: $t) -> $t {
                avx!($t($op(self.0, o.0)))
            }
        }
    };
}
binary!(F32x8, Add, add, _mm256_add_ps);
binary!(F32x8, Sub, sub, _mm256_sub_ps);
binary!(F32x8, Mul, mul, _mm256_mul_ps);
binary!(F32x8, Div, div, _mm256_div_ps);
binary!(U32x8, Add, add, _mm256_add_epi32);
binary!(U32x8, Sub, sub, _mm256_sub_epi32);
binary!(U32x8, BitAnd, bitand, _mm256_and_si256);

impl Neg for F32x8 {
    type Output = F32x8;
    /// Flips the sign bit (`-0.0` from `0.0`), as `wide` and the scalar `-x`.
    #[inline(always)]
    fn neg(self) -> F32x8 {
        avx!(F32x8(_mm256_xor_ps(self.0, _mm256_set1_ps(-0.0))))
    }
}

impl BitAnd for VBool<__m256> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, o: Self) -> Self {
        avx!(VBool(_mm256_and_ps(self.0, o.0)))
    }
}

impl BitOr for VBool<__m256> {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, o: Self) -> Self {
        avx!(VBool(_mm256_or_ps(self.0, o.0)))
    }
}

impl Not for VBool<__m256> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        avx!(VBool(_mm256_xor_ps(
            self.0,
            _mm256_castsi256_ps(_mm256_set1_epi32(-1))
        )))
    }
}

impl BitAndAssign for VBool<__m256> {
    #[inline(always)]
    fn bitand_assign(&mut self, o: Self) {
        *self = *self & o;
    }
}

impl BitOrAssign for VBool<__m256> {
    #[inline(always)]
    fn bitor_assign(&mut self, o: Self) {
        *self = *self | o;
    }
}

impl LaneMask for VBool<__m256> {
    // SAFETY: 32 zero bytes are a valid `__m256`.
    const NONE: Self = VBool(unsafe { std::mem::transmute::<[u32; 8], __m256>([0; 8]) });
    #[inline(always)]
    fn from_bits(bits: LaneBits) -> Self {
        avx!({
            let lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let set = _mm256_cmpeq_epi32(
                _mm256_and_si256(_mm256_set1_epi32(bits as i32), lanes),
                lanes,
            );
            VBool(_mm256_castsi256_ps(set))
        })
    }
    #[inline(always)]
    fn bits(self) -> LaneBits {
        avx!(_mm256_movemask_ps(self.0) as LaneBits)
    }
    #[inline(always)]
    fn any(self) -> bool {
        avx!(_mm256_movemask_ps(self.0) != 0)
    }
}

/// `a OP b` per lane; the `_OQ` predicates are false on NaN, as `wide`'s ordered
/// comparisons and the scalar operators.
#[inline(always)]
fn cmp<const P: i32>(a: F32x8, b: F32x8) -> VBool<__m256> {
    avx!(VBool(_mm256_cmp_ps::<P>(a.0, b.0)))
}

/// [`Float::transpose8`] of eight records: one 8x8 transpose (24 shuffles), `wide`'s.
#[inline(always)]
fn transpose8_x8(records: &[[f32; 8]]) -> [F32x8; 8] {
    let Ok(r) = <&[[f32; 8]; 8]>::try_from(records) else {
        return transpose8_lanes(records);
    };
    avx!({
        let row = inl(
            #[inline(always)]
            |i: usize| _mm256_loadu_ps(r[i].as_ptr()),
        );
        let (a, b, c, d) = (row(0), row(1), row(2), row(3));
        let (e, f, g, h) = (row(4), row(5), row(6), row(7));
        let (t0, t1) = (_mm256_unpacklo_ps(a, b), _mm256_unpackhi_ps(a, b));
        let (t2, t3) = (_mm256_unpacklo_ps(c, d), _mm256_unpackhi_ps(c, d));
        let (t4, t5) = (_mm256_unpacklo_ps(e, f), _mm256_unpackhi_ps(e, f));
        let (t6, t7) = (_mm256_unpacklo_ps(g, h), _mm256_unpackhi_ps(g, h));
        let s0 = _mm256_shuffle_ps::<0x44>(t0, t2);
        let s1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
        let s2 = _mm256_shuffle_ps::<0x44>(t1, t3);
        let s3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
        let s4 = _mm256_shuffle_ps::<0x44>(t4, t6);
        let s5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
        let s6 = _mm256_shuffle_ps::<0x44>(t5, t7);
        let s7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
        [
            _mm256_permute2f128_ps::<0x20>(s0, s4),
            _mm256_permute2f128_ps::<0x20>(s1, s5),
            _mm256_permute2f128_ps::<0x20>(s2, s6),
            _mm256_permute2f128_ps::<0x20>(s3, s7),
            _mm256_permute2f128_ps::<0x31>(s0, s4),
            _mm256_permute2f128_ps::<0x31>(s1, s5),
            _mm256_permute2f128_ps::<0x31>(s2, s6),
            _mm256_permute2f128_ps::<0x31>(s3, s7),
        ]
        .amap(F32x8)
    })
}

/// [`Float::transpose4_into`] of eight records: the low and high halves of the four
/// vectors as two 4x4 transposes, eight stores.
#[inline(always)]
fn transpose4_x8(v: [F32x8; 4], out: &mut [[f32; 4]]) {
    let Ok(out) = <&mut [[f32; 4]; 8]>::try_from(&mut *out) else {
        return transpose4_lanes(v, out);
    };
    avx!({
        let (a, b, c, d) = (v[0].0, v[1].0, v[2].0, v[3].0);
        let (ab_lo, ab_hi) = (_mm256_unpacklo_ps(a, b), _mm256_unpackhi_ps(a, b));
        let (cd_lo, cd_hi) = (_mm256_unpacklo_ps(c, d), _mm256_unpackhi_ps(c, d));
        // Records 0 and 4, 1 and 5, 2 and 6, 3 and 7 in the halves.
        let r = [
            _mm256_shuffle_ps::<0x44>(ab_lo, cd_lo),
            _mm256_shuffle_ps::<0xEE>(ab_lo, cd_lo),
            _mm256_shuffle_ps::<0x44>(ab_hi, cd_hi),
            _mm256_shuffle_ps::<0xEE>(ab_hi, cd_hi),
        ];
        for (k, x) in r.into_iter().enumerate() {
            _mm_storeu_ps(out[k].as_mut_ptr(), _mm256_castps256_ps128(x));
            _mm_storeu_ps(out[k + 4].as_mut_ptr(), _mm256_extractf128_ps::<1>(x));
        }
    })
}

/// [`Float::from_rows4`] of eight rows: rows `i` and `i + 4` loaded into the two
/// halves of one register, then a 4x4 transpose within each half (eight shuffles for
/// thirty-two words).
#[inline(always)]
fn rows4_x8<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [F32x8; 4] {
    avx!({
        let half = inl(
            #[inline(always)]
            |i: usize| _mm_loadu_ps(rows(i).as_ptr()),
        );
        let row = inl(
            #[inline(always)]
            |i: usize| _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(half(i)), half(i + 4)),
        );
        let (a, b, c, d) = (row(0), row(1), row(2), row(3));
        // Words 0, 1 (lo) and 2, 3 (hi) of rows a and b, interleaved; likewise c, d.
        let (ab_lo, ab_hi) = (_mm256_unpacklo_ps(a, b), _mm256_unpackhi_ps(a, b));
        let (cd_lo, cd_hi) = (_mm256_unpacklo_ps(c, d), _mm256_unpackhi_ps(c, d));
        [
            _mm256_shuffle_ps::<0x44>(ab_lo, cd_lo),
            _mm256_shuffle_ps::<0xEE>(ab_lo, cd_lo),
            _mm256_shuffle_ps::<0x44>(ab_hi, cd_hi),
            _mm256_shuffle_ps::<0xEE>(ab_hi, cd_hi),
        ]
        .amap(F32x8)
    })
}

impl Float for F32x8 {
    type Mask = VBool<__m256>;
    type U = U32x8;
    // SAFETY: eight f32 fill a `__m256` exactly.
    const ZERO: Self = F32x8(unsafe { std::mem::transmute::<[f32; 8], __m256>([0.0; 8]) });
    // SAFETY: as for `ZERO`.
    const ONE: Self = F32x8(unsafe { std::mem::transmute::<[f32; 8], __m256>([1.0; 8]) });
    #[inline(always)]
    fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
        transpose8_x8(records)
    }
    #[inline(always)]
    fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
        transpose4_x8(v, out)
    }
    #[inline(always)]
    fn from_rows4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [Self; 4] {
        rows4_x8(rows)
    }
    #[inline(always)]
    fn mul_add_fast(self, a: Self, b: Self) -> Self {
        avx!(F32x8(_mm256_fmadd_ps(self.0, a.0, b.0)))
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        avx!(F32x8(_mm256_set1_ps(x)))
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
        let a: [f32; 8] = array_fn(f);
        avx!(F32x8(_mm256_loadu_ps(a.as_ptr())))
    }
    #[inline(always)]
    fn lane(&self, i: usize) -> f32 {
        // SAFETY: `F32x8` is a transparent `__m256`, of the size of and a stricter
        // alignment than `[f32; 8]`; every bit pattern is a valid f32.
        let lanes = unsafe { &*(self as *const F32x8).cast::<[f32; 8]>() };
        lanes[i]
    }
    #[inline(always)]
    fn cmp_lt(self, o: Self) -> Self::Mask {
        cmp::<_CMP_LT_OQ>(self, o)
    }
    #[inline(always)]
    fn cmp_gt(self, o: Self) -> Self::Mask {
        cmp::<_CMP_GT_OQ>(self, o)
    }
    #[inline(always)]
    fn cmp_le(self, o: Self) -> Self::Mask {
        cmp::<_CMP_LE_OQ>(self, o)
    }
    #[inline(always)]
    fn cmp_ge(self, o: Self) -> Self::Mask {
        cmp::<_CMP_GE_OQ>(self, o)
    }
    #[inline(always)]
    fn cmp_eq(self, o: Self) -> Self::Mask {
        cmp::<_CMP_EQ_OQ>(self, o)
    }
    /// `|x| < inf`: false on NaN and on infinities, as `wide`'s exponent test.
    #[inline(always)]
    fn finite(self) -> Self::Mask {
        cmp::<_CMP_LT_OQ>(self.abs(), F32x8::splat(f32::INFINITY))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        avx!(F32x8(_mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0)))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        avx!(F32x8(_mm256_sqrt_ps(self.0)))
    }
    /// `vminps` keeps the second operand on NaN; `wide` (and this) then takes `self`
    /// where `o` is NaN.
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        avx!(F32x8(_mm256_blendv_ps(
            _mm256_min_ps(self.0, o.0),
            self.0,
            _mm256_cmp_ps::<_CMP_UNORD_Q>(o.0, o.0),
        )))
    }
    /// As [`Float::min`], with `vmaxps`.
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        avx!(F32x8(_mm256_blendv_ps(
            _mm256_max_ps(self.0, o.0),
            self.0,
            _mm256_cmp_ps::<_CMP_UNORD_Q>(o.0, o.0),
        )))
    }
    #[inline(always)]
    fn min_lt(self, o: Self) -> Self {
        avx!(F32x8(_mm256_min_ps(self.0, o.0)))
    }
    #[inline(always)]
    fn max_gt(self, o: Self) -> Self {
        avx!(F32x8(_mm256_max_ps(self.0, o.0)))
    }
    #[inline(always)]
    fn to_bits(self) -> U32x8 {
        avx!(U32x8(_mm256_castps_si256(self.0)))
    }
    #[inline(always)]
    fn from_bits(u: U32x8) -> Self {
        avx!(F32x8(_mm256_castsi256_ps(u.0)))
    }
    #[inline(always)]
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
        avx!(F32x8(_mm256_blendv_ps(if_false.0, if_true.0, mask.0)))
    }
}

impl Uint for U32x8 {
    type Mask = VBool<__m256>;
    #[inline(always)]
    fn splat(x: u32) -> Self {
        avx!(U32x8(_mm256_set1_epi32(x as i32)))
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> u32) -> Self {
        let a: [u32; 8] = array_fn(f);
        avx!(U32x8(_mm256_loadu_si256(a.as_ptr().cast())))
    }
    #[inline(always)]
    fn lane(&self, i: usize) -> u32 {
        // SAFETY: `U32x8` is a transparent `__m256i`, of the size of and a stricter
        // alignment than `[u32; 8]`; every bit pattern is a valid u32.
        let lanes = unsafe { &*(self as *const U32x8).cast::<[u32; 8]>() };
        lanes[i]
    }
    /// Unsigned: both sides' top bits flipped, then the signed compare.
    #[inline(always)]
    fn cmp_gt(self, o: Self) -> Self::Mask {
        avx!({
            let flip = _mm256_set1_epi32(i32::MIN);
            let gt =
                _mm256_cmpgt_epi32(_mm256_xor_si256(self.0, flip), _mm256_xor_si256(o.0, flip));
            VBool(_mm256_castsi256_ps(gt))
        })
    }
    #[inline(always)]
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
        avx!(U32x8(_mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(if_false.0),
            _mm256_castsi256_ps(if_true.0),
            mask.0,
        ))))
    }
    #[inline(always)]
    fn shr(self, n: u32) -> Self {
        avx!(U32x8(_mm256_srl_epi32(self.0, _mm_cvtsi32_si128(n as i32))))
    }
}

/// Sixteen f32 lanes in two `ymm` registers, lanes 0..8 in the first.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct F32x16([F32x8; 2]);

/// Sixteen u32 lanes in two `ymm` registers.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct U32x16([U32x8; 2]);

/// The masks of [`F32x16`]: two 8-lane masks.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct Mask16([VBool<__m256>; 2]);

macro_rules! halves {
    ($t:ident, $tr:ident, $m:ident) => {
        impl $tr for $t {
            type Output = $t;
            #[inline(always)]
            fn $m(self, o: $t) -> $t {
                $t([self.0[0].$m(o.0[0]), self.0[1].$m(o.0[1])])
            }
        }
    };
}
halves!(F32x16, Add, add);
halves!(F32x16, Sub, sub);
halves!(F32x16, Mul, mul);
halves!(F32x16, Div, div);
halves!(U32x16, Add, add);
halves!(U32x16, Sub, sub);
halves!(U32x16, BitAnd, bitand);
halves!(Mask16, BitAnd, bitand);
halves!(Mask16, BitOr, bitor);

impl Neg for F32x16 {
    type Output = F32x16;
    #[inline(always)]
    fn neg(self) -> F32x16 {
        F32x16(self.0.amap(
            #[inline(always)]
            |x| -x,
        ))
    }
}

impl Not for Mask16 {
    type Output = Mask16;
    #[inline(always)]
    fn not(self) -> Mask16 {
        Mask16(self.0.amap(
            #[inline(always)]
            |x| !x,
        ))
    }
}

impl BitAndAssign for Mask16 {
    #[inline(always)]
    fn bitand_assign(&mut self, o: Self) {
        *self = *self & o;
    }
}

impl BitOrAssign for Mask16 {
    #[inline(always)]
    fn bitor_assign(&mut self, o: Self) {
        *self = *self | o;
    }
}

impl LaneMask for Mask16 {
    const NONE: Self = Mask16([VBool::<__m256>::NONE; 2]);
    #[inline(always)]
    fn from_bits(bits: LaneBits) -> Self {
        Mask16([
            VBool::<__m256>::from_bits(bits & 0xFF),
            VBool::<__m256>::from_bits(bits >> 8),
        ])
    }
    #[inline(always)]
    fn bits(self) -> LaneBits {
        self.0[0].bits() | self.0[1].bits() << 8
    }
    #[inline(always)]
    fn any(self) -> bool {
        avx!(_mm256_movemask_ps(_mm256_or_ps(self.0[0].0, self.0[1].0)) != 0)
    }
}

/// A per-half method of [`F32x16`] with one argument of the same type.
macro_rules! pairwise {
    ($($m:ident -> $out:ident),*) => {
        $(
            #[inline(always)]
            fn $m(self, o: Self) -> $out {
                $out([self.0[0].$m(o.0[0]), self.0[1].$m(o.0[1])])
            }
        )*
    };
}

impl Float for F32x16 {
    type Mask = Mask16;
    type U = U32x16;
    const ZERO: Self = F32x16([F32x8::ZERO; 2]);
    const ONE: Self = F32x16([F32x8::ONE; 2]);
    #[inline(always)]
    fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
        if records.len() != 16 {
            return transpose8_lanes(records);
        }
        Self::transpose8_halves(&records[..8], &records[8..])
    }
    /// The two runs are the two registers: one 8x8 transpose each.
    #[inline(always)]
    fn transpose8_halves(lo: &[[f32; 8]], hi: &[[f32; 8]]) -> [Self; 8] {
        if lo.len() != 8 || hi.len() != 8 {
            return transpose8_halves_lanes(lo, hi);
        }
        let (a, b) = (transpose8_x8(lo), transpose8_x8(hi));
        array_fn(
            #[inline(always)]
            |j| F32x16([a[j], b[j]]),
        )
    }
    #[inline(always)]
    fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
        if out.len() != 16 {
            return transpose4_lanes(v, out);
        }
        let (lo, hi) = out.split_at_mut(8);
        transpose4_x8(
            v.amap(
                #[inline(always)]
                |x| x.0[0],
            ),
            lo,
        );
        transpose4_x8(
            v.amap(
                #[inline(always)]
                |x| x.0[1],
            ),
            hi,
        );
    }
    #[inline(always)]
    fn from_rows4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [Self; 4] {
        let a = rows4_x8(&rows);
        let b = rows4_x8(
            #[inline(always)]
            |i| rows(i + 8),
        );
        array_fn(
            #[inline(always)]
            |j| F32x16([a[j], b[j]]),
        )
    }
    #[inline(always)]
    fn mul_add_fast(self, a: Self, b: Self) -> Self {
        F32x16([
            self.0[0].mul_add_fast(a.0[0], b.0[0]),
            self.0[1].mul_add_fast(a.0[1], b.0[1]),
        ])
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        F32x16([F32x8::splat(x); 2])
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        let a: [f32; 16] = array_fn(&mut f);
        F32x16([
            F32x8::from_fn(
                #[inline(always)]
                |i| a[i],
            ),
            F32x8::from_fn(
                #[inline(always)]
                |i| a[i + 8],
            ),
        ])
    }
    #[inline(always)]
    fn lane(&self, i: usize) -> f32 {
        self.0[i / 8].lane(i % 8)
    }
    pairwise!(cmp_lt -> Mask16, cmp_gt -> Mask16, cmp_le -> Mask16, cmp_ge -> Mask16, cmp_eq -> Mask16);
    pairwise!(min -> F32x16, max -> F32x16, min_lt -> F32x16, max_gt -> F32x16);
    #[inline(always)]
    fn finite(self) -> Mask16 {
        Mask16(self.0.amap(F32x8::finite))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        F32x16(self.0.amap(F32x8::abs))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F32x16(self.0.amap(F32x8::sqrt))
    }
    #[inline(always)]
    fn to_bits(self) -> U32x16 {
        U32x16(self.0.amap(F32x8::to_bits))
    }
    #[inline(always)]
    fn from_bits(u: U32x16) -> Self {
        F32x16(u.0.amap(F32x8::from_bits))
    }
    #[inline(always)]
    fn select(mask: Mask16, if_true: Self, if_false: Self) -> Self {
        F32x16([
            F32x8::select(mask.0[0], if_true.0[0], if_false.0[0]),
            F32x8::select(mask.0[1], if_true.0[1], if_false.0[1]),
        ])
    }
}

impl Uint for U32x16 {
    type Mask = Mask16;
    #[inline(always)]
    fn splat(x: u32) -> Self {
        U32x16([U32x8::splat(x); 2])
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> u32) -> Self {
        let a: [u32; 16] = array_fn(&mut f);
        U32x16([
            U32x8::from_fn(
                #[inline(always)]
                |i| a[i],
            ),
            U32x8::from_fn(
                #[inline(always)]
                |i| a[i + 8],
            ),
        ])
    }
    #[inline(always)]
    fn lane(&self, i: usize) -> u32 {
        self.0[i / 8].lane(i % 8)
    }
    #[inline(always)]
    fn cmp_gt(self, o: Self) -> Mask16 {
        Mask16([self.0[0].cmp_gt(o.0[0]), self.0[1].cmp_gt(o.0[1])])
    }
    #[inline(always)]
    fn select(mask: Mask16, if_true: Self, if_false: Self) -> Self {
        U32x16([
            U32x8::select(mask.0[0], if_true.0[0], if_false.0[0]),
            U32x8::select(mask.0[1], if_true.0[1], if_false.0[1]),
        ])
    }
    #[inline(always)]
    fn shr(self, n: u32) -> Self {
        U32x16(self.0.amap(
            #[inline(always)]
            |x| x.shr(n),
        ))
    }
}

backend!(
    pub(crate) Avx2x4,
    Isa::Avx2,
    enter_avx2,
    wide::f32x4,
    wide::u32x4,
    VBool<wide::f32x4>,
    4,
    [Avx2x4, Avx2x8],
    "4 lanes under AVX2: `wide`'s f32x4, VEX-encoded inside the AVX2 entry."
);
backend!(
    pub(crate) Avx2x8,
    Isa::Avx2,
    enter_avx2,
    F32x8,
    U32x8,
    VBool<__m256>,
    8,
    [Avx2x4, Avx2x8],
    "8 lanes in one AVX2 register."
);
backend!(
    pub(crate) Avx2x16,
    Isa::Avx2,
    enter_avx2,
    F32x16,
    U32x16,
    Mask16,
    16,
    [Avx2x4, Avx2x8],
    "16 lanes in two AVX2 registers."
);
