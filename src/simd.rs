//! The one place that knows the SIMD backend and its widths.
//!
//! Packet kernels are written once against the [`Simd`] trait and instantiated for the
//! marker types [`W4`], [`W8`] and [`W16`] (`wide`'s f32x4, f32x8 and f32x16), the way
//! Embree compiles its `vfloat<N>` templates at every width; all three are in one
//! binary and [`native_lanes`] picks one at run time. No other file names `wide`.
//!
//! A lane mask is its own type ([`VBool`], Embree's `vbool<N>`), never the float
//! vector, so a mask cannot be passed where a value belongs; [`LaneBits`] holds one bit
//! per lane of the widest packet.

use std::fmt::Debug;
use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

/// One bit per lane, lane `i` at bit `i`; wide enough for [`MAX_LANES`].
pub type LaneBits = u32;

/// Lanes of the widest packet.
pub const MAX_LANES: usize = 16;

const _: () = assert!(MAX_LANES <= LaneBits::BITS as usize);

/// A SIMD width: the vector types of one packet and its pixel shape.
pub trait Simd: Copy + Clone + Debug + Default + Send + Sync + 'static {
    /// Rays per packet.
    const LANES: usize;
    /// Width and height of the pixel block a camera packet covers (2x2, 4x2, 4x4): the
    /// only place the shape is derived from the size (see [`block_pixel`]).
    const SHAPE: (u32, u32);
    /// Groups of at most this many coherent lanes are traced as single rays: a packet
    /// step costs about the same at every occupancy, a scalar step a fraction of it.
    const SCALAR_GROUP_MAX: u32;
    /// One f32 per lane.
    type F: Float<Mask = Self::Mask, U = Self::U>;
    /// One u32 per lane (primitive ids, float bits).
    type U: Uint<Mask = Self::Mask>;
    /// One bool per lane.
    type Mask: LaneMask;

    /// All lanes set.
    #[inline]
    fn all_bits() -> LaneBits {
        LaneBits::MAX >> (LaneBits::BITS as usize - Self::LANES)
    }
}

/// One f32 per lane of width `W`.
pub type Vf<W> = <W as Simd>::F;
/// One u32 per lane of width `W`.
pub type Vu<W> = <W as Simd>::U;
/// One bool per lane of width `W`.
pub type Mask<W> = <W as Simd>::Mask;

/// Per-lane f32 arithmetic, comparisons and selects. Comparisons follow IEEE (false on
/// NaN); [`Float::min_lt`] and [`Float::max_gt`] repeat the scalar path's order.
pub trait Float:
    Copy
    + Debug
    + Send
    + Sync
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The comparisons' result: its own type, so a mask is never taken for a value.
    type Mask: LaneMask;
    /// u32 lanes of the same width (primitive ids, float bits).
    type U: Uint<Mask = Self::Mask>;
    /// 0.0 in every lane.
    const ZERO: Self;
    /// 1.0 in every lane.
    const ONE: Self;
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// Lane `i` is `f(i)`.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// Lane `i`'s value.
    fn lane(&self, i: usize) -> f32;
    /// Vector `j` holds field `j` of each record, record `i` in lane `i` (the records
    /// of a packet's rays, [`crate::ray::Ray::as_records`]); lanes past `records.len()`
    /// are 0. A transpose, so no bit changes.
    #[inline]
    fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
        transpose8_lanes(records)
    }
    /// [`Float::transpose8`] of `lo` followed by `hi`, each half the width: a packet
    /// made of two runs of records that do not lie side by side (a 4x4 pixel block of
    /// an image set is two runs of 8 rays), without copying them together first.
    #[inline]
    fn transpose8_halves(lo: &[[f32; 8]], hi: &[[f32; 8]]) -> [Self; 8] {
        transpose8_lanes_from(|i| {
            if i < lo.len() {
                lo.get(i)
            } else {
                hi.get(i - lo.len())
            }
        })
    }
    /// The reverse for four fields: record `i` of `out` gets lane `i` of each vector
    /// (a packet's hits, [`crate::ray::Hit::as_records_mut`]); writes `out.len()`
    /// records, at most one per lane. No bit changes.
    #[inline]
    fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
        transpose4_lanes(v, out)
    }
    /// Vector `j` holds word `j` of each 16-byte row, `rows(i)` in lane `i`: one row of
    /// `LANES` array-of-structures records (the leaf test's TriAccel records), as 4x4
    /// transposes where the target has them instead of one insert per lane and word.
    /// No bit changes.
    #[inline(always)]
    fn from_rows4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [Self; 4] {
        rows4_lanes(rows)
    }
    /// `self < o` per lane (false where either is NaN, as the scalar `<`).
    fn cmp_lt(self, o: Self) -> Self::Mask;
    /// `self > o` per lane (false where either is NaN).
    fn cmp_gt(self, o: Self) -> Self::Mask;
    /// `self <= o` per lane (false where either is NaN).
    fn cmp_le(self, o: Self) -> Self::Mask;
    /// `self >= o` per lane (false where either is NaN).
    fn cmp_ge(self, o: Self) -> Self::Mask;
    /// `self == o` per lane (`0.0 == -0.0`; false where either is NaN).
    fn cmp_eq(self, o: Self) -> Self::Mask;
    /// Lanes neither NaN nor infinite.
    fn finite(self) -> Self::Mask;
    /// `|x|` per lane (clears the sign bit).
    fn abs(self) -> Self;
    /// Correctly rounded square root per lane, as the scalar `f32::sqrt`.
    fn sqrt(self) -> Self;
    /// `self * a + b` per lane, rounded as [`mul_add`] rounds it (once where the target
    /// has FMA, else twice), so packet kernels reproduce the scalar ones bit for bit.
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// IEEE-style minimum (a NaN operand gives the other one).
    fn min(self, o: Self) -> Self;
    /// IEEE-style maximum (a NaN operand gives the other one).
    fn max(self, o: Self) -> Self;
    /// `if a < b { a } else { b }` per lane: the order glam's `Vec3::min` and
    /// `min_element` use (the second operand wins on NaN or equality), so packet kernels
    /// reproduce the scalar ones bit for bit. One `minps`.
    fn min_lt(self, o: Self) -> Self;
    /// `if a > b { a } else { b }` per lane, glam's `Vec3::max` order. One `maxps`.
    fn max_gt(self, o: Self) -> Self;
    /// The lanes' IEEE bits.
    fn to_bits(self) -> Self::U;
    /// Floats from IEEE bits.
    fn from_bits(u: Self::U) -> Self;
    /// `if_true` where `mask` is set, `if_false` elsewhere.
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self;
}

/// `a * b + c`, rounded once where the target has FMA (every AVX2 and AVX-512 CPU) and
/// twice elsewhere: the scalar twin of [`Float::mul_add`], which rounds the same way at
/// every width.
#[inline(always)]
pub fn mul_add(a: f32, b: f32, c: f32) -> f32 {
    if cfg!(target_feature = "fma") {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Asks for the cache lines of `*x` ahead of a load that may follow (a hint: no
/// effect on results, none on targets without one).
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (x as *const T).cast::<i8>();
        // SAFETY: prefetching never faults and reads nothing; both addresses lie
        // within `*x`.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.add(std::mem::size_of::<T>().saturating_sub(1)));
        }
    }
}

/// [`Float::transpose8`] lane by lane, at any width.
#[inline]
pub fn transpose8_lanes<F: Float>(records: &[[f32; 8]]) -> [F; 8] {
    transpose8_lanes_from(|i| records.get(i))
}

/// Lane `i` of vector `j` is field `j` of `record(i)` (0 where `None`).
#[inline]
fn transpose8_lanes_from<'r, F: Float>(record: impl Fn(usize) -> Option<&'r [f32; 8]>) -> [F; 8] {
    std::array::from_fn(|j| F::from_fn(|i| record(i).map_or(0.0, |r| r[j])))
}

/// [`Float::transpose4_into`] lane by lane, at any width.
#[inline]
pub fn transpose4_lanes<F: Float>(v: [F; 4], out: &mut [[f32; 4]]) {
    for (i, r) in out.iter_mut().enumerate() {
        *r = v.map(|x| x.lane(i));
    }
}

/// Per-lane u32 values.
pub trait Uint:
    Copy + Debug + Send + Sync + Add<Output = Self> + Sub<Output = Self> + BitAnd<Output = Self>
{
    /// The comparisons' result, the same type as the float lanes' mask.
    type Mask: LaneMask;
    /// `x` in every lane.
    fn splat(x: u32) -> Self;
    /// Lane `i` is `f(i)`.
    fn from_fn(f: impl FnMut(usize) -> u32) -> Self;
    /// Lane `i`'s value.
    fn lane(&self, i: usize) -> u32;
    /// Unsigned `self > o` per lane.
    fn cmp_gt(self, o: Self) -> Self::Mask;
    /// `if_true` where `mask` is set, `if_false` elsewhere.
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self;
    /// Each lane shifted right by `n` (< 32) bits.
    fn shr(self, n: u32) -> Self;
    /// Lane `i` of the first vector is `table[2 idx[i]]`, of the second
    /// `table[2 idx[i] + 1]`: the two words of an 8-byte record per lane, all loads
    /// independent, so a lane walk's node loads are in flight together. The indices
    /// are read from memory (the lane walk keeps its nodes in an array): a scalar load
    /// per index, where taking each out of a vector cost two instructions per lane
    /// (1.02-1.06x on every stream, perf/log/stream.md). Panics when an index is out of
    /// bounds.
    #[inline(always)]
    fn gather_pairs(table: &[u32], idx: &[u32; MAX_LANES]) -> (Self, Self) {
        (
            Self::from_fn(|i| table[2 * idx[i] as usize]),
            Self::from_fn(|i| table[2 * idx[i] as usize + 1]),
        )
    }
}

/// A lane mask.
pub trait LaneMask:
    Copy
    + Debug
    + Send
    + Sync
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + Not<Output = Self>
    + BitAndAssign
    + BitOrAssign
{
    /// No lane set.
    const NONE: Self;
    /// Lane `i` set where bit `i` of `bits` is set.
    fn from_bits(bits: LaneBits) -> Self;
    /// Bit `i` set where lane `i` is set.
    fn bits(self) -> LaneBits;
    /// True when any lane is set.
    fn any(self) -> bool;
    /// True when no lane is set.
    #[inline]
    fn none(self) -> bool {
        !self.any()
    }
}

/// A lane mask of width `V` (all bits set or clear per lane, as the comparisons
/// return); its own type so that it cannot be used as a value.
#[derive(Clone, Copy, Debug)]
pub struct VBool<V>(V);

/// Pixel offset of lane `i` of a `W` camera packet inside its `W::SHAPE` block: 2x2
/// quads row-major inside the block, each quad in RAYS.md's lane order ((0,0), (1,0),
/// (0,1), (1,1)). So lanes 0..4 are always a 2x2 quad and lanes 0..8 a 4x2 block, as
/// any 4 or 8 consecutive rays of an image set in RAYS.md's packet order.
#[inline]
pub fn block_pixel<W: Simd>(i: usize) -> (u32, u32) {
    let quads_per_row = W::SHAPE.0 as usize / 2;
    let (q, (dx, dy)) = (i / 4, quad_lane(i));
    (
        (q % quads_per_row) as u32 * 2 + dx,
        (q / quads_per_row) as u32 * 2 + dy,
    )
}

/// Pixel offset of lane `i % 4` inside its 2x2 quad, in RAYS.md's order: (0,0), (1,0),
/// (0,1), (1,1). The one definition of the quad, for packets and ray files alike.
#[inline]
pub fn quad_lane(i: usize) -> (u32, u32) {
    let p = (i % 4) as u32;
    (p & 1, p >> 1)
}

/// A width marker: its lane count, pixel shape, scalar threshold and vector types.
macro_rules! width {
    ($w:ident, $f:ty, $u:ty, $mask:ty, $n:literal, $shape:expr, $scalar_max:literal, $doc:literal) => {
        #[doc = $doc]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct $w;

        impl Simd for $w {
            const LANES: usize = $n;
            const SHAPE: (u32, u32) = $shape;
            const SCALAR_GROUP_MAX: u32 = $scalar_max;
            type F = $f;
            type U = $u;
            type Mask = $mask;
        }
    };
}

/// [`Float::transpose8`] of `wide`'s f32x8: a full packet's eight records as one 8x8
/// transpose (`wide`'s, 24 shuffles with AVX) instead of 64 single-lane inserts.
#[inline]
fn transpose8_x8(records: &[[f32; 8]]) -> [wide::f32x8; 8] {
    let Ok(records) = <&[[f32; 8]; 8]>::try_from(records) else {
        return transpose8_lanes(records);
    };
    wide::f32x8::transpose(records.map(wide::f32x8::new))
}

/// [`Float::transpose4_into`] of `wide`'s f32x8: the low and the high halves of the
/// four vectors as two 4x4 transposes, eight stores.
#[inline]
fn transpose4_x8(v: [wide::f32x8; 4], out: &mut [[f32; 4]]) {
    let Ok(out) = <&mut [[f32; 4]; 8]>::try_from(&mut *out) else {
        return transpose4_lanes(v, out);
    };
    let a = v.map(|x| x.to_array());
    for h in 0..2 {
        let half = a.map(|x| wide::f32x4::new(std::array::from_fn(|j| x[4 * h + j])));
        for (r, t) in out[4 * h..].iter_mut().zip(wide::f32x4::transpose(half)) {
            *r = t.to_array();
        }
    }
}

/// [`Float::from_rows4`] lane by lane, at any width.
#[inline(always)]
fn rows4_lanes<'r, F: Float>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [F; 4] {
    std::array::from_fn(|j| F::from_fn(|i| rows(i)[j]))
}

/// [`Float::from_rows4`] of `wide`'s f32x4: four row loads and one 4x4 transpose
/// (eight shuffles for sixteen words).
#[inline(always)]
fn rows4_x4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [wide::f32x4; 4] {
    wide::f32x4::transpose(std::array::from_fn(|i| wide::f32x4::new(*rows(i))))
}

/// [`Float::from_rows4`] of `wide`'s f32x8: rows `i` and `i + 4` loaded into the two
/// halves of one register, then a 4x4 transpose within each half (eight shuffles for
/// thirty-two words).
#[inline(always)]
fn rows4_x8<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [wide::f32x8; 4] {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    {
        use std::arch::x86_64::*;
        // SAFETY: AVX is enabled at compile time (the cfg above); each load reads one
        // `[f32; 4]` (unaligned loads), and under AVX `wide::f32x8` is one `__m256`.
        unsafe {
            let half = |i: usize| _mm_loadu_ps(rows(i).as_ptr());
            let row =
                |i: usize| _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(half(i)), half(i + 4));
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
            .map(|x| std::mem::transmute::<__m256, wide::f32x8>(x))
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
    rows4_lanes(rows)
}

/// The [`Float`], [`Uint`] and [`LaneMask`] impls of one pair of `wide` types: masks
/// are float vectors with every bit of a lane set or clear. `$t8` and `$t4` are the
/// type's [`Float::transpose8`] and [`Float::transpose4_into`], `$r4` its
/// [`Float::from_rows4`].
macro_rules! wide_backend {
    ($f:ident, $u:ident, $t8:path, $t4:path, $r4:path) => {
        impl BitAnd for VBool<wide::$f> {
            type Output = Self;
            #[inline]
            fn bitand(self, o: Self) -> Self {
                VBool(self.0 & o.0)
            }
        }

        impl BitOr for VBool<wide::$f> {
            type Output = Self;
            #[inline]
            fn bitor(self, o: Self) -> Self {
                VBool(self.0 | o.0)
            }
        }

        impl Not for VBool<wide::$f> {
            type Output = Self;
            #[inline]
            fn not(self) -> Self {
                VBool(!self.0)
            }
        }

        impl BitAndAssign for VBool<wide::$f> {
            #[inline]
            fn bitand_assign(&mut self, o: Self) {
                self.0 = self.0 & o.0;
            }
        }

        impl BitOrAssign for VBool<wide::$f> {
            #[inline]
            fn bitor_assign(&mut self, o: Self) {
                self.0 = self.0 | o.0;
            }
        }

        impl LaneMask for VBool<wide::$f> {
            const NONE: Self = VBool(wide::$f::ZERO);
            #[inline]
            fn from_bits(bits: LaneBits) -> Self {
                let lanes = wide::$u::new(std::array::from_fn(|i| 1 << i));
                let set = (wide::$u::splat(bits) & lanes).simd_eq(lanes);
                VBool(wide::$f::from_bits(set))
            }
            #[inline]
            fn bits(self) -> LaneBits {
                self.0.to_bitmask()
            }
            #[inline]
            fn any(self) -> bool {
                self.0.any()
            }
        }

        impl Float for wide::$f {
            type Mask = VBool<wide::$f>;
            type U = wide::$u;
            const ZERO: Self = wide::$f::ZERO;
            const ONE: Self = wide::$f::ONE;
            #[inline]
            fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
                $t8(records)
            }
            #[inline]
            fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
                $t4(v, out)
            }
            #[inline(always)]
            fn from_rows4<'r>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [Self; 4] {
                $r4(rows)
            }
            #[inline]
            fn splat(x: f32) -> Self {
                wide::$f::splat(x)
            }
            #[inline]
            fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
                wide::$f::new(std::array::from_fn(f))
            }
            #[inline]
            fn lane(&self, i: usize) -> f32 {
                self.as_array()[i]
            }
            #[inline]
            fn cmp_lt(self, o: Self) -> Self::Mask {
                VBool(self.simd_lt(o))
            }
            #[inline]
            fn cmp_gt(self, o: Self) -> Self::Mask {
                VBool(self.simd_gt(o))
            }
            #[inline]
            fn cmp_le(self, o: Self) -> Self::Mask {
                VBool(self.simd_le(o))
            }
            #[inline]
            fn cmp_ge(self, o: Self) -> Self::Mask {
                VBool(self.simd_ge(o))
            }
            #[inline]
            fn cmp_eq(self, o: Self) -> Self::Mask {
                VBool(self.simd_eq(o))
            }
            #[inline]
            fn finite(self) -> Self::Mask {
                VBool(wide::$f::is_finite(self))
            }
            #[inline]
            fn abs(self) -> Self {
                wide::$f::abs(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                wide::$f::sqrt(self)
            }
            #[inline]
            fn mul_add(self, a: Self, b: Self) -> Self {
                if cfg!(target_feature = "fma") {
                    wide::$f::mul_add(self, a, b)
                } else {
                    self * a + b
                }
            }
            #[inline]
            fn min(self, o: Self) -> Self {
                wide::$f::min(self, o)
            }
            #[inline]
            fn max(self, o: Self) -> Self {
                wide::$f::max(self, o)
            }
            #[inline]
            fn min_lt(self, o: Self) -> Self {
                self.fast_min(o)
            }
            #[inline]
            fn max_gt(self, o: Self) -> Self {
                self.fast_max(o)
            }
            #[inline]
            fn to_bits(self) -> wide::$u {
                wide::$f::to_bits(self)
            }
            #[inline]
            fn from_bits(u: wide::$u) -> Self {
                wide::$f::from_bits(u)
            }
            #[inline]
            fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
                mask.0.bitselect(if_true, if_false)
            }
        }

        impl Uint for wide::$u {
            type Mask = VBool<wide::$f>;
            #[inline]
            fn splat(x: u32) -> Self {
                wide::$u::splat(x)
            }
            #[inline]
            fn from_fn(f: impl FnMut(usize) -> u32) -> Self {
                wide::$u::new(std::array::from_fn(f))
            }
            #[inline]
            fn lane(&self, i: usize) -> u32 {
                self.as_array()[i]
            }
            #[inline]
            fn cmp_gt(self, o: Self) -> Self::Mask {
                VBool(wide::$f::from_bits(self.simd_gt(o)))
            }
            #[inline]
            fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self {
                mask.0.to_bits().bitselect(if_true, if_false)
            }
            #[inline]
            fn shr(self, n: u32) -> Self {
                self >> n
            }
        }
    };
}

wide_backend!(f32x4, u32x4, transpose8_lanes, transpose4_lanes, rows4_x4);
wide_backend!(f32x8, u32x8, transpose8_x8, transpose4_x8, rows4_x8);
wide_backend!(
    f32x16,
    u32x16,
    transpose8_lanes,
    transpose4_lanes,
    rows4_lanes
);

width!(
    W4,
    wide::f32x4,
    wide::u32x4,
    VBool<wide::f32x4>,
    4,
    (2, 2),
    1,
    "4 lanes (SSE): the Wald packet."
);
width!(
    W8,
    wide::f32x8,
    wide::u32x8,
    VBool<wide::f32x8>,
    8,
    (4, 2),
    2,
    "8 lanes (AVX2)."
);
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
width!(
    W16,
    wide::f32x16,
    wide::u32x16,
    VBool<wide::f32x16>,
    16,
    (4, 4),
    3,
    "16 lanes (AVX-512; `wide`'s f32x16, two AVX2 registers on other CPUs)."
);
#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
width!(
    W16,
    avx512::F32x16,
    avx512::U32x16,
    VBool<u16>,
    16,
    (4, 4),
    3,
    "16 lanes (AVX-512, native: masks in `k` registers, see [`avx512`])."
);

/// The native AVX-512 backend of [`W16`]: one `zmm` register per quantity and lane masks
/// in `k` registers (`__mmask16`), so comparisons, mask logic, selects and the lane
/// bits never leave them. `wide`'s f32x16 returns its comparisons as vectors, which
/// costs a `vpmovm2d`/`vpmovd2m` pair around every mask (perf/log/wide.md). Every operation
/// repeats the one `wide` performs (same instruction, same operand order), so both
/// backends and the scalar path give the same bits; a unit test compares them.
#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
pub mod avx512 {
    use super::{Float, LaneBits, LaneMask, MAX_LANES, Uint, VBool};
    use core::arch::x86_64::*;
    use std::fmt;
    use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

    /// Calls AVX-512F intrinsics, which Rust marks unsafe unless the calling function
    /// itself enables the feature.
    macro_rules! avx {
        ($e:expr) => {
            // SAFETY: this module is compiled only when the build enables AVX-512F
            // (`cfg(target_feature = "avx512f")`), so the CPU running it has it.
            unsafe { $e }
        };
    }

    /// Sixteen f32 lanes in one `zmm` register.
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct F32x16(__m512);

    /// Sixteen u32 lanes in one `zmm` register.
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct U32x16(__m512i);

    impl F32x16 {
        #[inline]
        fn to_array(self) -> [f32; 16] {
            // SAFETY: `__m512` and `[f32; 16]` have the same size, every bit pattern is
            // valid for both.
            unsafe { std::mem::transmute::<__m512, [f32; 16]>(self.0) }
        }
        #[inline]
        fn from_array(a: [f32; 16]) -> F32x16 {
            // SAFETY: as in `to_array`.
            F32x16(unsafe { std::mem::transmute::<[f32; 16], __m512>(a) })
        }
    }

    impl U32x16 {
        #[inline]
        fn to_array(self) -> [u32; 16] {
            // SAFETY: `__m512i` and `[u32; 16]` have the same size, every bit pattern is
            // valid for both.
            unsafe { std::mem::transmute::<__m512i, [u32; 16]>(self.0) }
        }
        #[inline]
        fn from_array(a: [u32; 16]) -> U32x16 {
            // SAFETY: as in `to_array`.
            U32x16(unsafe { std::mem::transmute::<[u32; 16], __m512i>(a) })
        }
    }

    impl fmt::Debug for F32x16 {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.debug_list().entries(self.to_array()).finish()
        }
    }

    impl fmt::Debug for U32x16 {
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
        #[inline]
        fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
            if records.len() != 16 {
                return super::transpose8_lanes(records);
            }
            Self::transpose8_halves(&records[..8], &records[8..])
        }
        /// Two runs of eight records: the same loads and permutes as
        /// [`Float::transpose8`], four loads from each run.
        #[inline]
        fn transpose8_halves(lo: &[[f32; 8]], hi: &[[f32; 8]]) -> [Self; 8] {
            if lo.len() != 8 || hi.len() != 8 {
                return super::transpose8_lanes_from(|i| {
                    if i < lo.len() {
                        lo.get(i)
                    } else {
                        hi.get(i - lo.len())
                    }
                });
            }
            let (lo, hi) = (lo.as_ptr().cast::<f32>(), hi.as_ptr().cast::<f32>());
            // SAFETY: each run holds 8 * 8 f32, so each load reads 16 f32 (two records)
            // inside one run (unaligned loads).
            let z: [__m512; 8] = std::array::from_fn(|k| unsafe {
                _mm512_loadu_ps(if k < 4 {
                    lo.add(16 * k)
                } else {
                    hi.add(16 * (k - 4))
                })
            });
            // SAFETY: each row of `TRANSPOSE` is 16 i32, read unaligned.
            let idx = |n: usize| unsafe { _mm512_loadu_si512(TRANSPOSE[n].as_ptr().cast()) };
            let join = |a: __m512, n: usize, b: __m512| avx!(_mm512_permutex2var_ps(a, idx(n), b));
            // b[m][p]: records 4m..4m+4, fields 4p..4p+4.
            let b: [[__m512; 2]; 4] =
                std::array::from_fn(|m| [0, 1].map(|p| join(z[2 * m], p, z[2 * m + 1])));
            // c[q][p][s]: records 8q..8q+8, fields 4p+2s..4p+2s+2.
            let c: [[[__m512; 2]; 2]; 2] = std::array::from_fn(|q| {
                [0, 1].map(|p| [0, 1].map(|s| join(b[2 * q][p], 2 + s, b[2 * q + 1][p])))
            });
            std::array::from_fn(|j| {
                let (p, s, t) = (j / 4, (j / 2) % 2, j % 2);
                F32x16(join(c[0][p][s], 4 + t, c[1][p][s]))
            })
        }
        /// Sixteen records: 8 two-source permutes and 4 stores instead of 64 lane
        /// extractions.
        #[inline]
        fn transpose4_into(v: [Self; 4], out: &mut [[f32; 4]]) {
            if out.len() != 16 {
                return super::transpose4_lanes(v, out);
            }
            // SAFETY: each row of `STORE` is 16 i32, read unaligned.
            let idx = |n: usize| unsafe { _mm512_loadu_si512(STORE[n].as_ptr().cast()) };
            let join = |a: __m512, n: usize, b: __m512| avx!(_mm512_permutex2var_ps(a, idx(n), b));
            // tu[h], vp[h]: records 8h..8h+8, two fields each.
            let tu = [0, 1].map(|h| join(v[0].0, h, v[1].0));
            let vp = [0, 1].map(|h| join(v[2].0, h, v[3].0));
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
        #[inline]
        fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
            F32x16::from_array(std::array::from_fn(f))
        }
        #[inline]
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
        fn abs(self) -> Self {
            avx!(F32x16(_mm512_abs_ps(self.0)))
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            avx!(F32x16(_mm512_sqrt_ps(self.0)))
        }
        /// AVX-512 implies FMA: one rounding, as [`super::mul_add`].
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            avx!(F32x16(_mm512_fmadd_ps(self.0, a.0, b.0)))
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
        #[inline]
        fn from_fn(f: impl FnMut(usize) -> u32) -> Self {
            U32x16::from_array(std::array::from_fn(f))
        }
        #[inline]
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
            let pair = |i: usize| {
                let k = 2 * idx[i] as usize;
                let w = &table[k..k + 2];
                u64::from(w[0]) | u64::from(w[1]) << 32
            };
            let lo: [u64; 8] = std::array::from_fn(pair);
            let hi: [u64; 8] = std::array::from_fn(|i| pair(i + 8));
            // SAFETY: `[u64; 8]` and `__m512i` have the same size, every bit pattern is
            // valid for both; AVX-512F is enabled (see `avx!`).
            unsafe {
                let (lo, hi) = (
                    std::mem::transmute::<[u64; 8], __m512i>(lo),
                    std::mem::transmute::<[u64; 8], __m512i>(hi),
                );
                let even =
                    _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
                let odd =
                    _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
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
}

/// The widest packet this CPU runs natively: 16 with AVX-512F, 8 with AVX2, else 4.
/// The build targets the CPU it runs on (`.cargo/config.toml`), so a wider packet on a
/// CPU without the registers would be emulated with narrower ones.
pub fn native_lanes() -> usize {
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return 16;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            return 8;
        }
    }
    4
}

/// The largest absolute component per lane, `max_gt(max_gt(|x|, |y|), |z|)`: the twin
/// of the scalar `accel::triaccel::max_abs`. The scalar twins of `min_lt`, `max_gt` and
/// `max_abs` stay in triaccel.rs: moved here, they made the renderer 5-9% slower in
/// paired runs (code placement; perf/log/overview.md).
#[inline]
pub fn max_abs<F: Float>(v: &[F; 3]) -> F {
    v[0].abs().max_gt(v[1].abs()).max_gt(v[2].abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn masks_round_trip<W: Simd>() {
        let patterns = [
            0,
            1,
            0b0101,
            W::all_bits(),
            W::all_bits() >> 1,
            1 << (W::LANES - 1),
        ];
        for b in patterns.into_iter().chain(0..64.min(1 << W::LANES)) {
            assert_eq!(W::Mask::from_bits(b).bits(), b, "{} lanes", W::LANES);
        }
        let m = W::Mask::from_bits(0b0101);
        let r = W::F::select(m, W::F::splat(1.0), W::F::splat(2.0));
        assert_eq!([0, 1, 2, 3].map(|i| r.lane(i)), [1.0, 2.0, 1.0, 2.0]);
        let u = W::U::select(m, W::U::splat(7), W::U::splat(9));
        assert_eq!([0, 1, 2, 3].map(|i| u.lane(i)), [7, 9, 7, 9]);
        assert!(m.any() && !m.none() && W::Mask::NONE.none() && W::Mask::from_bits(0).none());
        assert_eq!(W::all_bits().count_ones() as usize, W::LANES);
    }

    #[test]
    fn masks_round_trip_through_bits() {
        masks_round_trip::<W4>();
        masks_round_trip::<W8>();
        masks_round_trip::<W16>();
    }

    fn blocks_cover_their_shape<W: Simd>() {
        let (w, h) = W::SHAPE;
        assert_eq!((w * h) as usize, W::LANES);
        let mut seen = vec![0; W::LANES];
        for i in 0..W::LANES {
            let (x, y) = block_pixel::<W>(i);
            assert!(x < w && y < h);
            seen[(y * w + x) as usize] += 1;
        }
        assert!(seen.iter().all(|&n| n == 1));
        // The first four lanes are RAYS.md's quad.
        assert_eq!(
            (0..4).map(block_pixel::<W>).collect::<Vec<_>>(),
            [(0, 0), (1, 0), (0, 1), (1, 1)]
        );
    }

    #[test]
    fn packet_shapes_cover_each_pixel_once() {
        blocks_cover_their_shape::<W4>();
        blocks_cover_their_shape::<W8>();
        blocks_cover_their_shape::<W16>();
        assert_eq!(block_pixel::<W8>(4), (2, 0));
        assert_eq!(block_pixel::<W16>(8), (0, 2));
    }

    fn min_max_order<W: Simd>() {
        let pick_min = |a: f32, b: f32| if a < b { a } else { b };
        let pick_max = |a: f32, b: f32| if a > b { a } else { b };
        let xs = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            2.5,
        ];
        for &a in &xs {
            for &b in &xs {
                let lo = W::F::splat(a).min_lt(W::F::splat(b)).lane(W::LANES - 1);
                let hi = W::F::splat(a).max_gt(W::F::splat(b)).lane(0);
                assert_eq!(lo.to_bits(), pick_min(a, b).to_bits(), "min({a:?}, {b:?})");
                assert_eq!(hi.to_bits(), pick_max(a, b).to_bits(), "max({a:?}, {b:?})");
            }
        }
    }

    /// `transpose8` puts field `j` of record `i` in lane `i` of vector `j`, bits
    /// unchanged (NaN payloads and -0.0 included), at every width and for short inputs.
    fn transpose8_moves_every_bit<W: Simd>() {
        let records: Vec<[f32; 8]> = (0..W::LANES)
            .map(|i| {
                std::array::from_fn(|j| match (i + j) % 5 {
                    0 => -0.0,
                    1 => f32::from_bits(0x7fc0_0000 | (i * 8 + j) as u32),
                    _ => (i * 8 + j) as f32 + 0.25,
                })
            })
            .collect();
        for n in [W::LANES, W::LANES - 1, 1, 0] {
            let v = Vf::<W>::transpose8(&records[..n]);
            for (j, vj) in v.iter().enumerate() {
                for (i, record) in records.iter().enumerate() {
                    let want = if i < n { record[j] } else { 0.0 };
                    assert_eq!(
                        vj.lane(i).to_bits(),
                        want.to_bits(),
                        "n {n} lane {i} field {j}"
                    );
                }
            }
        }
    }

    /// `transpose8_halves` of two runs equals `transpose8` of the runs side by side,
    /// bit for bit, for full and short runs.
    fn transpose8_halves_join_the_runs<W: Simd>() {
        let records: Vec<[f32; 8]> = (0..W::LANES)
            .map(|i| {
                std::array::from_fn(|j| match (i + 3 * j) % 5 {
                    0 => -0.0,
                    1 => f32::from_bits(0x7fc0_0000 | (i * 8 + j) as u32),
                    _ => (i * 8 + j) as f32 + 0.75,
                })
            })
            .collect();
        let h = W::LANES / 2;
        let bits = |v: [Vf<W>; 8]| {
            v.map(|x| {
                (0..W::LANES)
                    .map(|i| x.lane(i).to_bits())
                    .collect::<Vec<_>>()
            })
        };
        for (lo, hi) in [(h, h), (h, h - 1), (h - 1, h), (1, 0)] {
            let joined: Vec<[f32; 8]> = records[..lo]
                .iter()
                .chain(&records[h..h + hi])
                .copied()
                .collect();
            assert_eq!(
                bits(Vf::<W>::transpose8_halves(
                    &records[..lo],
                    &records[h..h + hi]
                )),
                bits(Vf::<W>::transpose8(&joined)),
                "runs of {lo} and {hi}"
            );
        }
    }

    #[test]
    fn transpose8_halves_at_every_width() {
        transpose8_halves_join_the_runs::<W4>();
        transpose8_halves_join_the_runs::<W8>();
        transpose8_halves_join_the_runs::<W16>();
    }

    /// `transpose4_into` writes lane `i` of vector `j` to field `j` of record `i`, bits
    /// unchanged, and leaves records past `out.len()` alone.
    fn transpose4_moves_every_bit<W: Simd>() {
        let v: [Vf<W>; 4] = std::array::from_fn(|j| {
            Vf::<W>::from_fn(|i| match (i + j) % 4 {
                0 => -0.0,
                1 => f32::from_bits(0xffc0_0000 | (i * 4 + j) as u32),
                _ => (i * 4 + j) as f32 + 0.5,
            })
        });
        for n in [W::LANES, W::LANES - 1, 1, 0] {
            let mut out = vec![[7.0f32; 4]; W::LANES];
            Vf::<W>::transpose4_into(v, &mut out[..n]);
            for (i, r) in out.iter().enumerate() {
                for (j, x) in r.iter().enumerate() {
                    let want = if i < n { v[j].lane(i) } else { 7.0 };
                    assert_eq!(x.to_bits(), want.to_bits(), "n {n} record {i} field {j}");
                }
            }
        }
    }

    #[test]
    fn transpose4_at_every_width() {
        transpose4_moves_every_bit::<W4>();
        transpose4_moves_every_bit::<W8>();
        transpose4_moves_every_bit::<W16>();
    }

    /// `from_rows4` puts word `j` of row `i` in lane `i` of vector `j`, bits unchanged
    /// (signed zeros, NaN payloads, integer bit patterns), whichever row each lane reads.
    fn rows4_move_every_bit<W: Simd>() {
        let rows: Vec<[f32; 4]> = (0..2 * W::LANES as u32)
            .map(|i| {
                [
                    -0.0,
                    f32::from_bits(0xffc0_0000 | i),
                    i as f32 + 0.5,
                    f32::from_bits((i << 2) | (i % 3)),
                ]
            })
            .collect();
        for pick in [|i: usize| i, |i: usize| 2 * i + 1, |i: usize| i.min(2)] {
            let v = Vf::<W>::from_rows4(|i| &rows[pick(i)]);
            for (j, x) in v.iter().enumerate() {
                for i in 0..W::LANES {
                    assert_eq!(
                        x.lane(i).to_bits(),
                        rows[pick(i)][j].to_bits(),
                        "{} lanes: lane {i} word {j}",
                        W::LANES
                    );
                }
            }
        }
    }

    #[test]
    fn rows4_at_every_width() {
        rows4_move_every_bit::<W4>();
        rows4_move_every_bit::<W8>();
        rows4_move_every_bit::<W16>();
    }

    /// `&`, `shr` and `gather_pairs` against the scalar operations lane by lane.
    fn uint_ops_match_scalar<W: Simd>() {
        let words: Vec<u32> = (0..100u32)
            .map(|i| i.wrapping_mul(0x9e37_79b9) ^ 0xf00d)
            .collect();
        let a = Vu::<W>::from_fn(|i| (i as u32).wrapping_mul(0x0101_0101) | 0x8000_0003);
        for n in [0, 1, 2, 4, 31] {
            let r = a.shr(n);
            for i in 0..W::LANES {
                assert_eq!(r.lane(i), a.lane(i) >> n, "shr {n} lane {i}");
            }
        }
        let m = a & Vu::<W>::splat(0xf0f0_000f);
        // Lanes past `W::LANES` hold an index out of bounds: they are never read.
        let idx: [u32; MAX_LANES] = std::array::from_fn(|i| {
            if i < W::LANES {
                (i as u32 * 13) % 50
            } else {
                1000
            }
        });
        let (even, odd) = Vu::<W>::gather_pairs(&words, &idx);
        for (i, &at) in idx.iter().enumerate().take(W::LANES) {
            assert_eq!(m.lane(i), a.lane(i) & 0xf0f0_000f, "and lane {i}");
            let k = 2 * at as usize;
            assert_eq!(even.lane(i), words[k], "gather_pairs even lane {i}");
            assert_eq!(odd.lane(i), words[k + 1], "gather_pairs odd lane {i}");
        }
        // An index out of bounds in any lane panics, the last word's pair included.
        for lane in [0, W::LANES - 1] {
            for bad in [50, 1000] {
                let mut out = idx;
                out[lane] = bad;
                let r = std::panic::catch_unwind(|| Vu::<W>::gather_pairs(&words, &out));
                assert!(r.is_err(), "{} lanes: index {bad} in lane {lane}", W::LANES);
            }
        }
    }

    #[test]
    fn uint_ops_at_every_width() {
        uint_ops_match_scalar::<W4>();
        uint_ops_match_scalar::<W8>();
        uint_ops_match_scalar::<W16>();
    }

    #[test]
    fn transpose8_at_every_width() {
        transpose8_moves_every_bit::<W4>();
        transpose8_moves_every_bit::<W8>();
        transpose8_moves_every_bit::<W16>();
    }

    /// The native AVX-512 backend repeats `wide`'s f32x16 operation by operation: every
    /// operation of the traits, on every pair of an adversarial set of values, gives the
    /// same bits (and the same mask bits) in both.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    #[test]
    fn native_avx512_matches_wide() {
        use wide::{f32x16, u32x16};
        type N = Vf<W16>;
        let xs = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -2.5,
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE / 4.0,
            f32::MAX,
            f32::MIN,
            1e-30,
            3.0e7,
        ];
        let n = xs.len();
        let bits_n = |v: N| std::array::from_fn::<u32, 16, _>(|i| v.lane(i).to_bits());
        let bits_w = |v: f32x16| std::array::from_fn::<u32, 16, _>(|i| v.lane(i).to_bits());
        for shift in 0..n {
            let a_n = N::from_fn(|i| xs[i % n]);
            let b_n = N::from_fn(|i| xs[(i + shift) % n]);
            let a_w = f32x16::from_fn(|i| xs[i % n]);
            let b_w = f32x16::from_fn(|i| xs[(i + shift) % n]);
            let values: [(N, f32x16); 14] = [
                (a_n + b_n, a_w + b_w),
                (a_n - b_n, a_w - b_w),
                (a_n * b_n, a_w * b_w),
                (a_n / b_n, a_w / b_w),
                (-a_n, -a_w),
                (a_n.abs(), a_w.abs()),
                (a_n.sqrt(), Float::sqrt(a_w)),
                (a_n.min(b_n), Float::min(a_w, b_w)),
                (a_n.max(b_n), Float::max(a_w, b_w)),
                (a_n.min_lt(b_n), a_w.min_lt(b_w)),
                (a_n.max_gt(b_n), a_w.max_gt(b_w)),
                (
                    N::select(a_n.cmp_lt(b_n), a_n, b_n),
                    <f32x16 as Float>::select(a_w.cmp_lt(b_w), a_w, b_w),
                ),
                (
                    N::from_bits(a_n.to_bits() + Vu::<W16>::splat(1)),
                    f32x16::from_bits(a_w.to_bits() + u32x16::splat(1)),
                ),
                (
                    N::from_bits(a_n.to_bits() - Vu::<W16>::splat(1)),
                    f32x16::from_bits(a_w.to_bits() - u32x16::splat(1)),
                ),
            ];
            for (k, (v_n, v_w)) in values.into_iter().enumerate() {
                assert_eq!(bits_n(v_n), bits_w(v_w), "operation {k}, shift {shift}");
            }
            let masks = [
                (a_n.cmp_lt(b_n), a_w.cmp_lt(b_w)),
                (a_n.cmp_gt(b_n), a_w.cmp_gt(b_w)),
                (a_n.cmp_le(b_n), a_w.cmp_le(b_w)),
                (a_n.cmp_ge(b_n), a_w.cmp_ge(b_w)),
                (a_n.cmp_eq(b_n), a_w.cmp_eq(b_w)),
                (a_n.finite(), a_w.finite()),
                (
                    a_n.to_bits().cmp_gt(b_n.to_bits()),
                    a_w.to_bits().cmp_gt(b_w.to_bits()),
                ),
            ];
            for (k, (m_n, m_w)) in masks.into_iter().enumerate() {
                assert_eq!(m_n.bits(), m_w.bits(), "comparison {k}, shift {shift}");
                assert_eq!(m_n.any(), m_w.any());
            }
            let m = a_n.cmp_lt(b_n);
            let u = Vu::<W16>::select(m, a_n.to_bits(), b_n.to_bits());
            assert_eq!(
                std::array::from_fn::<u32, 16, _>(|i| u.lane(i)),
                bits_n(N::select(m, a_n, b_n))
            );
        }
    }

    /// `Float::mul_add` rounds as the scalar `mul_add` does, lane by lane: once where
    /// the target has FMA (a product that overflows or cancels shows it), twice
    /// elsewhere. NaN results need only be NaN in both.
    fn mul_add_matches_scalar<W: Simd>() {
        let xs = [
            0.0,
            -0.0,
            1.0 + f32::EPSILON,
            -(1.0 - f32::EPSILON / 2.0),
            -1.0,
            3.0e7,
            -2.5e-8,
            f32::MAX,
            f32::MIN_POSITIVE / 8.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1.0 / 3.0,
        ];
        let n = xs.len();
        for (ka, &a) in xs.iter().enumerate() {
            for &b in &xs {
                let c = Vf::<W>::from_fn(|i| xs[(ka + i) % n]);
                let got = Vf::<W>::splat(a).mul_add(Vf::<W>::splat(b), c);
                for i in 0..W::LANES {
                    let want = mul_add(a, b, c.lane(i));
                    let got = got.lane(i);
                    assert!(
                        got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                        "{a:?} * {b:?} + {:?}: {got:?} against {want:?}",
                        c.lane(i)
                    );
                }
            }
        }
        // One rounding shows: (1 + e)(1 - e) - 1 is -e^2 fused and 0 unfused.
        let (p, q) = (1.0 + f32::EPSILON, 1.0 - f32::EPSILON);
        let fused = Vf::<W>::splat(p)
            .mul_add(Vf::<W>::splat(q), Vf::<W>::splat(-1.0))
            .lane(0);
        assert_eq!(fused != 0.0, cfg!(target_feature = "fma"));
    }

    #[test]
    fn mul_add_at_every_width() {
        mul_add_matches_scalar::<W4>();
        mul_add_matches_scalar::<W8>();
        mul_add_matches_scalar::<W16>();
    }

    #[test]
    fn min_and_max_follow_the_scalar_order() {
        min_max_order::<W4>();
        min_max_order::<W8>();
        min_max_order::<W16>();
    }
}
