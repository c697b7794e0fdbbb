//! The AVX-512 backends: 16 lanes in one `zmm` register with lane masks in `k`
//! registers (`__mmask16`), so comparisons, mask logic, selects and the lane bits never
//! leave them. `wide`'s f32x16 returns its comparisons as vectors, which costs a
//! `vpmovm2d`/`vpmovd2m` pair around every mask (perf/log/wide.md). Every operation
//! repeats the one `wide` performs (same instruction, same operand order), so all
//! backends and the scalar path give the same bits; the tests in `super` compare them.
//! 4 and 8 lanes are the AVX2 types, compiled inside AVX-512 entries.
//!
//! The types are crate-private and only made inside [`enter_avx512`], which checks the
//! CPU first: that is what makes the `unsafe` intrinsic calls below sound.

use super::avx2::{F32x8, U32x8};
use super::{AMap, Float, Isa, LaneBits, LaneMask, MAX_LANES, Uint, VBool, array_fn, inl};
use core::arch::x86_64::*;
use std::fmt;
use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

/// Runs `f` compiled for AVX-512 (x86-64-v4): the entry of every AVX-512 kernel.
/// Panics when the CPU lacks AVX-512.
#[inline(always)]
pub(crate) fn enter_avx512<R>(f: impl FnOnce() -> R) -> R {
    assert!(
        Isa::Avx512.supported(),
        "AVX-512 kernel on a CPU without AVX-512"
    );
    // SAFETY: the CPU runs every feature of `entry` (checked above).
    unsafe { entry(f) }
}

#[target_feature(
    enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,f16c,movbe,popcnt,avx512f,avx512bw,avx512cd,avx512dq,avx512vl"
)]
#[inline(never)]
unsafe fn entry<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// Calls AVX-512F intrinsics, which Rust marks unsafe unless the calling function
/// itself enables the feature.
macro_rules! avx {
    ($e:expr) => {
        // SAFETY: values of this module's types exist only under `enter_avx512` (or
        // in tests on a CPU that has AVX-512), which checks the CPU.
        unsafe { $e }
    };
}

/// Sixteen f32 lanes in one `zmm` register.
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct F32x16(__m512);

/// Sixteen u32 lanes in one `zmm` register.
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct U32x16(__m512i);

impl F32x16 {
    #[inline(always)]
    fn to_array(self) -> [f32; 16] {
        bytemuck::cast(self.0)
    }
    #[inline(always)]
    fn from_array(a: [f32; 16]) -> F32x16 {
        F32x16(bytemuck::cast(a))
    }
}

impl U32x16 {
    #[inline(always)]
    fn to_array(self) -> [u32; 16] {
        bytemuck::cast(self.0)
    }
    #[inline(always)]
    fn from_array(a: [u32; 16]) -> U32x16 {
        U32x16(bytemuck::cast(a))
    }
}

impl fmt::Debug for F32x16 {
    #[inline(always)]
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.to_array()).finish()
    }
}

impl fmt::Debug for U32x16 {
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
binary!(F32x16, Add, add, _mm512_add_ps);
binary!(F32x16, Sub, sub, _mm512_sub_ps);
binary!(F32x16, Mul, mul, _mm512_mul_ps);
binary!(F32x16, Div, div, _mm512_div_ps);
binary!(U32x16, Add, add, _mm512_add_epi32);
binary!(U32x16, Sub, sub, _mm512_sub_epi32);
binary!(U32x16, BitAnd, bitand, _mm512_and_si512);

impl Neg for F32x16 {
    type Output = F32x16;
    /// Flips the sign bit, as `wide` and the scalar `-x` do (`-0.0` from `0.0`).
    #[inline(always)]
    fn neg(self) -> F32x16 {
        avx!(F32x16(_mm512_castsi512_ps(_mm512_xor_si512(
            _mm512_castps_si512(self.0),
            _mm512_set1_epi32(i32::MIN),
        ))))
    }
}

impl BitAnd for VBool<u16> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, o: Self) -> Self {
        VBool(self.0 & o.0)
    }
}

impl BitOr for VBool<u16> {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, o: Self) -> Self {
        VBool(self.0 | o.0)
    }
}

impl Not for VBool<u16> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        VBool(!self.0)
    }
}

impl BitAndAssign for VBool<u16> {
    #[inline(always)]
    fn bitand_assign(&mut self, o: Self) {
        self.0 &= o.0;
    }
}

impl BitOrAssign for VBool<u16> {
    #[inline(always)]
    fn bitor_assign(&mut self, o: Self) {
        self.0 |= o.0;
    }
}

impl LaneMask for VBool<u16> {
    const NONE: Self = VBool(0);
    #[inline(always)]
    fn from_bits(bits: LaneBits) -> Self {
        VBool(bits as u16)
    }
    #[inline(always)]
    fn bits(self) -> LaneBits {
        self.0 as LaneBits
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.0 != 0
    }
}

/// `a OP b` per lane into a `k` mask; the `_OQ` predicates are false on NaN, as
/// `wide`'s ordered comparisons and the scalar operators.
#[inline(always)]
fn cmp<const P: i32>(a: F32x16, b: F32x16) -> VBool<u16> {
    avx!(VBool(_mm512_cmp_ps_mask::<P>(a.0, b.0)))
}

/// `_mm512_permutex2var_ps` indices of the three rounds of [`F32x16::transpose8`]:
/// round 1 joins 2+2 records into 4 records x 4 fields (lane = field * 4 + record),
/// round 2 joins 4+4 into 8 records x 2 fields, round 3 8+8 into 16 records x 1
/// field; `part` picks which fields of the inputs an output keeps. Index bit 4
/// selects the second input.
const fn transpose_index(round: usize, part: usize) -> [i32; 16] {
    let mut idx = [0; 16];
    let mut l = 0;
    while l < 16 {
        let (per_field, fields_in) = match round {
            1 => (4, 8),
            2 => (8, 4),
            _ => (16, 2),
        };
        let (r, f) = (l % per_field, l / per_field);
        let half = per_field / 2;
        let (src, r) = if r < half { (0, r) } else { (16, r - half) };
        let field = part * (16 / per_field) + f;
        // Round 1's inputs are record-major (2 records of 8 fields), later rounds'
        // field-major (`half` records per field).
        idx[l] = src
            + if round == 1 {
                r * fields_in + field
            } else {
                field * half + r
            } as i32;
        l += 1;
    }
    idx
}

/// `_mm512_permutex2var_ps` indices of [`F32x16::transpose4_into`]: round 1 (`part`
/// 0 and 1) interleaves two fields of records `8 * part..8 * part + 8`
/// (lane = record * 2 + field), round 2 (`part` 0 to 3) joins two such vectors into
/// the four fields of records `4 * part..4 * part + 4`, record-major.
const fn store_index(round: usize, part: usize) -> [i32; 16] {
    let mut idx = [0; 16];
    let mut l = 0;
    while l < 16 {
        idx[l] = if round == 1 {
            ((l % 2) * 16 + part * 8 + l / 2) as i32
        } else {
            let (r, f) = ((part % 2) * 4 + l / 4, l % 4);
            (if f < 2 { 2 * r + f } else { 16 + 2 * r + f - 2 }) as i32
        };
        l += 1;
    }
    idx
}

static STORE: [[i32; 16]; 6] = [
    store_index(1, 0),
    store_index(1, 1),
    store_index(2, 0),
    store_index(2, 1),
    store_index(2, 2),
    store_index(2, 3),
];

static TRANSPOSE: [[i32; 16]; 6] = [
    transpose_index(1, 0),
    transpose_index(1, 1),
    transpose_index(2, 0),
    transpose_index(2, 1),
    transpose_index(3, 0),
    transpose_index(3, 1),
];

impl Float for F32x16 {
    type Mask = VBool<u16>;
    type U = U32x16;
    /// Sixteen records: eight loads and 24 two-source permutes instead of 128
    /// single-lane inserts.
    #[inline(always)]
    fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
        if records.len() != 16 {
            return super::transpose8_lanes(records);
        }
        Self::transpose8_halves(&records[..8], &records[8..])
    }
    /// Two runs of eight records: the same loads and permutes as
    /// [`Float::transpose8`], four loads from each run.
    #[inline(always)]
    fn transpose8_halves(lo: &[[f32; 8]], hi: &[[f32; 8]]) -> [Self; 8] {
        if lo.len() != 8 || hi.len() != 8 {
            return super::transpose8_halves_lanes(lo, hi);
        }
        let (lo, hi) = (lo.as_ptr().cast::<f32>(), hi.as_ptr().cast::<f32>());
        // SAFETY: each run holds 8 * 8 f32, so each load reads 16 f32 (two records)
        // inside one run (unaligned loads).
        let z: [__m512; 8] = array_fn(
            #[inline(always)]
            |k| unsafe {
                _mm512_loadu_ps(if k < 4 {
                    lo.add(16 * k)
                } else {
                    hi.add(16 * (k - 4))
                })
            },
        );
        // SAFETY: each row of `TRANSPOSE` is 16 i32, read unaligned.
        let idx = inl(
            #[inline(always)]
            |n: usize| unsafe { _mm512_loadu_si512(TRANSPOSE[n].as_ptr().cast()) },
        );
        let join = inl(
            #[inline(always)]
            |a: __m512, n: usize, b: __m512| avx!(_mm512_permutex2var_ps(a, idx(n), b)),
        );
        // b[m][p]: records 4m..4m+4, fields 4p..4p+4.
        let b: [[__m512; 2]; 4] = array_fn(
            #[inline(always)]
            |m| {
                [0, 1].amap(
                    #[inline(always)]
                    |p| join(z[2 * m], p, z[2 * m + 1]),
                )
            },
        );
        // c[q][p][s]: records 8q..8q+8, fields 4p+2s..4p+2s+2.
        let c: [[[__m512; 2]; 2]; 2] = array_fn(
            #[inline(always)]
            |q| {
                [0, 1].amap(
                    #[inline(always)]
                    |p| {
                        [0, 1].amap(
                            #[inline(always)]
                            |s| join(b[2 * q][p], 2 + s, b[2 * q + 1][p]),
                        )
                    },
                )
            },
        );
        array_fn(
            #[inline(always)]
            |j| {
                let (p, s, t) = (j / 4, (j / 2) % 2, j % 2);
                F32x16(join(c[0][p][s], 4 + t, c[1][p][s]))
            },
        )
    }
    /// Sixteen records: 8 two-source permutes and 4 stores instead of 64 lane
    /// extractions.
    #[inline(always)]
    fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
        if out.len() != 16 {
            return super::transpose4_lanes(v, out);
        }
        // SAFETY: each row of `STORE` is 16 i32, read unaligned.
        let idx = inl(
            #[inline(always)]
            |n: usize| unsafe { _mm512_loadu_si512(STORE[n].as_ptr().cast()) },
        );
        let join = inl(
            #[inline(always)]
            |a: __m512, n: usize, b: __m512| avx!(_mm512_permutex2var_ps(a, idx(n), b)),
        );
        // tu[h], vp[h]: records 8h..8h+8, two fields each.
        let tu = [0, 1].amap(
            #[inline(always)]
            |h| join(v[0].0, h, v[1].0),
        );
        let vp = [0, 1].amap(
            #[inline(always)]
            |h| join(v[2].0, h, v[3].0),
        );
        let base = out.as_mut_ptr().cast::<f32>();
        for k in 0..4 {
            let r = join(tu[k / 2], 2 + k, vp[k / 2]);
            // SAFETY: `out` holds 16 * 4 f32; store `k` writes f32 16k..16k+16.
            unsafe { _mm512_storeu_ps(base.add(16 * k), r) };
        }
    }
    // SAFETY: sixteen f32 fill a `__m512` exactly.
    const ZERO: Self = F32x16(unsafe { std::mem::transmute::<[f32; 16], __m512>([0.0; 16]) });
    // SAFETY: as for `ZERO`.
    const ONE: Self = F32x16(unsafe { std::mem::transmute::<[f32; 16], __m512>([1.0; 16]) });
    #[inline(always)]
    fn splat(x: f32) -> Self {
        avx!(F32x16(_mm512_set1_ps(x)))
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
        F32x16::from_array(array_fn(f))
    }
    #[inline(always)]
    fn lane(&self, i: usize) -> f32 {
        // SAFETY: `F32x16` is a transparent `__m512`, which has the size of and a
        // stricter alignment than `[f32; 16]`; every bit pattern is a valid f32.
        let lanes = unsafe { &*(self as *const F32x16).cast::<[f32; 16]>() };
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
        cmp::<_CMP_LT_OQ>(self.abs(), F32x16::splat(f32::INFINITY))
    }
    #[inline(always)]
    fn mul_add_fast(self, a: Self, b: Self) -> Self {
        avx!(F32x16(_mm512_fmadd_ps(self.0, a.0, b.0)))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        avx!(F32x16(_mm512_abs_ps(self.0)))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        avx!(F32x16(_mm512_sqrt_ps(self.0)))
    }
    /// `vminps` keeps the second operand on NaN; `wide` (and this) then takes `self`
    /// where `o` is NaN.
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        avx!(F32x16(_mm512_mask_blend_ps(
            _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(o.0, o.0),
            _mm512_min_ps(self.0, o.0),
            self.0,
        )))
    }
    /// As [`Float::min`], with `vmaxps`.
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        avx!(F32x16(_mm512_mask_blend_ps(
            _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(o.0, o.0),
            _mm512_max_ps(self.0, o.0),
            self.0,
        )))
    }
    #[inline(always)]
    fn min_lt(self, o: Self) -> Self {
        avx!(F32x16(_mm512_min_ps(self.0, o.0)))
    }
    #[inline(always)]
    fn max_gt(self, o: Self) -> Self {
        avx!(F32x16(_mm512_max_ps(self.0, o.0)))
    }
    #[inline(always)]
    fn to_bits(self) -> U32x16 {
        avx!(U32x16(_mm512_castps_si512(self.0)))
    }
    #[inline(always)]
    fn from_bits(u: U32x16) -> Self {
        avx!(F32x16(_mm512_castsi512_ps(u.0)))
    }
    #[inline(always)]
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
        avx!(F32x16(_mm512_mask_blend_ps(mask.0, if_false.0, if_true.0)))
    }
}

impl Uint for U32x16 {
    type Mask = VBool<u16>;
    #[inline(always)]
    fn splat(x: u32) -> Self {
        avx!(U32x16(_mm512_set1_epi32(x as i32)))
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> u32) -> Self {
        U32x16::from_array(array_fn(f))
    }
    #[inline(always)]
    fn lane(&self, i: usize) -> u32 {
        // SAFETY: `U32x16` is a transparent `__m512i`, which has the size of and a
        // stricter alignment than `[u32; 16]`; every bit pattern is a valid u32.
        let lanes = unsafe { &*(self as *const U32x16).cast::<[u32; 16]>() };
        lanes[i]
    }
    #[inline(always)]
    fn cmp_gt(self, o: Self) -> Self::Mask {
        avx!(VBool(_mm512_cmpgt_epu32_mask(self.0, o.0)))
    }
    #[inline(always)]
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
        avx!(U32x16(_mm512_mask_blend_epi32(
            mask.0, if_false.0, if_true.0
        )))
    }
    /// One 8-byte load per lane (half the loads of two word gathers), then the
    /// even and the odd words picked out with two permutes.
    #[inline(always)]
    fn gather_pairs(table: &[u32], idx: &[u32; MAX_LANES]) -> (Self, Self) {
        let pair = inl(
            #[inline(always)]
            |i: usize| {
                let k = 2 * idx[i] as usize;
                let w = &table[k..k + 2];
                u64::from(w[0]) | u64::from(w[1]) << 32
            },
        );
        let lo: [u64; 8] = array_fn(pair);
        let hi: [u64; 8] = array_fn(
            #[inline(always)]
            |i| pair(i + 8),
        );
        let (lo, hi): (__m512i, __m512i) = (bytemuck::cast(lo), bytemuck::cast(hi));
        // SAFETY: AVX-512F is enabled (see `avx!`).
        unsafe {
            let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
            let odd = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
            (
                U32x16(_mm512_permutex2var_epi32(lo, even, hi)),
                U32x16(_mm512_permutex2var_epi32(lo, odd, hi)),
            )
        }
    }
    #[inline(always)]
    fn shr(self, n: u32) -> Self {
        avx!(U32x16(_mm512_srlv_epi32(
            self.0,
            _mm512_set1_epi32(n as i32)
        )))
    }
}

backend!(
    pub(crate) Avx512x4,
    Isa::Avx512,
    enter_avx512,
    wide::f32x4,
    wide::u32x4,
    VBool<wide::f32x4>,
    4,
    [Avx512x4, Avx512x8],
    "4 lanes under AVX-512: `wide`'s f32x4 inside the AVX-512 entry."
);
backend!(
    pub(crate) Avx512x8,
    Isa::Avx512,
    enter_avx512,
    F32x8,
    U32x8,
    <F32x8 as Float>::Mask,
    8,
    [Avx512x4, Avx512x8],
    "8 lanes under AVX-512: the AVX2 register type inside the AVX-512 entry."
);
backend!(
    pub(crate) Avx512x16,
    Isa::Avx512,
    enter_avx512,
    F32x16,
    U32x16,
    VBool<u16>,
    16,
    [Avx512x4, Avx512x8],
    "16 lanes in one AVX-512 register, masks in `k` registers."
);
