//! The one place that knows the SIMD backends, their widths and instruction sets.
//!
//! Packet kernels are written once against the [`Simd`] trait. A [`Simd`] type is a
//! *backend*: a width (4, 8 or 16 lanes) compiled for one instruction set ([`Isa`]).
//! The public widths [`W4`], [`W8`] and [`W16`] are the portable backends (`wide`'s
//! vectors for the x86-64 baseline, SSE2); behind each of them stand an AVX2 + FMA and
//! an AVX-512 backend (`std::arch`, crate-private). Every backend is in every binary:
//! the kernels' public entry points take a portable width and run the backend of the
//! instruction set in use ([`Isa::in_use`], chosen once at run time, `RAYPACK_ISA`
//! forces a lower one), inside a function compiled for it ([`Simd::enter`]). This is
//! how Embree ships SSE, AVX2 and AVX-512 kernels in one library; it keeps raypack
//! fast when built without `-C target-cpu`, as a dependency, by `cargo install` or in
//! a Python wheel.
//!
//! Every backend computes the same bits as the scalar path: IEEE operations in the same
//! order, no fused multiply-add (one rounding on some CPUs and two on others would make
//! the answers depend on the machine), true division and square root.
//!
//! `f32` is the one-lane [`Float`] (`bool` masks, `u32` words): the kd-tree's per-ray
//! set-up is written once against [`Float`] and serves the scalar walk and the SIMD
//! walks alike, and a test holds its every operation to each backend's bits.
//!
//! A lane mask is its own type ([`VBool`], Embree's `vbool<N>`), never the float
//! vector, so a mask cannot be passed where a value belongs; [`LaneBits`] holds one bit
//! per lane of the widest packet.

/// A backend marker: its lane count, instruction set, entry (a function compiled for
/// that set) and vector types.
macro_rules! backend {
    ($vis:vis $w:ident, $isa:expr, $enter:path, $f:ty, $u:ty, $mask:ty, $n:literal, [$x4:ty, $x8:ty], $doc:literal) => {
        #[doc = $doc]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        $vis struct $w;

        impl $crate::simd::Simd for $w {
            const LANES: usize = $n;
            const ISA: $crate::simd::Isa = $isa;
            type F = $f;
            type U = $u;
            type Mask = $mask;
            type X4 = $x4;
            type X8 = $x8;
            #[inline(always)]
            fn enter<R>(f: impl FnOnce() -> R) -> R {
                $enter(f)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod isa;
mod one;
mod portable;

#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::{Avx2x4, Avx2x8, Avx2x16};
#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::{Avx512x4, Avx512x8, Avx512x16};
pub use isa::{Isa, IsaError};
pub(crate) use isa::{by_width, dispatch, scalar_entry};
pub use portable::{W4, W8, W16};
/// Other targets have the portable backends only ([`Isa::supported`] is false for the
/// others there).
#[cfg(not(target_arch = "x86_64"))]
mod others {
    pub(crate) use super::{
        W4 as Avx2x4, W4 as Avx512x4, W8 as Avx2x8, W8 as Avx512x8, W16 as Avx2x16,
        W16 as Avx512x16,
    };
}
#[cfg(not(target_arch = "x86_64"))]
pub(crate) use others::*;

use bytemuck::Pod;
use std::fmt::Debug;
use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Mul, Neg, Not, Sub};

/// One bit per lane, lane `i` at bit `i`; wide enough for [`MAX_LANES`].
pub type LaneBits = u32;

/// Lanes of the widest packet.
pub const MAX_LANES: usize = 16;

const _: () = assert!(MAX_LANES <= LaneBits::BITS as usize);

/// A SIMD backend: one width compiled for one instruction set, with its vector types.
/// What a width means elsewhere lives with its concept: the pixel block of a camera
/// packet in [`crate::scene::camera`], the traversal's knobs in the kd-tree's walks.
pub trait Simd: Copy + Clone + Debug + Default + Send + Sync + 'static {
    /// Rays per packet.
    const LANES: usize;
    /// The instruction set the backend's vector types are made of.
    const ISA: Isa;
    /// One f32 per lane (`Pod`: a backend's vectors are their lanes and nothing else,
    /// so two backends of one width trade them as bytes, `recast`).
    type F: Float<Mask = Self::Mask, U = Self::U> + Pod;
    /// One u32 per lane (primitive ids, float bits).
    type U: Uint<Mask = Self::Mask> + Pod;
    /// One bool per lane.
    type Mask: LaneMask + Pod;
    /// The 4- and 8-lane backends of the same instruction set, for a kernel of this
    /// width that works at another inside its entry (the lane walks test a leaf's
    /// triangles in 4 or 8 lanes): the portable `W8` is two SSE registers and
    /// transposes lane by lane, the AVX ones are one register.
    type X4: Simd;
    /// See [`Simd::X4`].
    type X8: Simd;

    /// All lanes set.
    #[inline(always)]
    fn all_bits() -> LaneBits {
        LaneBits::MAX >> (LaneBits::BITS as usize - Self::LANES)
    }

    /// Runs `f` in a function compiled for [`Simd::ISA`] and never inlined into its
    /// caller: the entry of a kernel at this backend. `wide` and `std::arch` operations
    /// become single instructions only where they are inlined into such a function, so
    /// everything a kernel calls below its entry is `#[inline(always)]` (perf/isa.md
    /// shows the check). Panics when the CPU lacks the instruction set.
    fn enter<R>(f: impl FnOnce() -> R) -> R;
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
    #[inline(always)]
    fn transpose8(records: &[[f32; 8]]) -> [Self; 8] {
        transpose8_lanes(records)
    }
    /// [`Float::transpose8`] of `lo` followed by `hi`, each half the width: a packet
    /// made of two runs of records that do not lie side by side (a 4x4 pixel block of
    /// an image set is two runs of 8 rays), without copying them together first.
    #[inline(always)]
    fn transpose8_halves(lo: &[[f32; 8]], hi: &[[f32; 8]]) -> [Self; 8] {
        transpose8_halves_lanes(lo, hi)
    }
    /// The reverse for four fields: record `i` of `out` gets lane `i` of each vector
    /// (a packet's hits, [`crate::ray::Hit::as_records_mut`]); writes `out.len()`
    /// records, at most one per lane. No bit changes.
    #[inline(always)]
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
    /// `self * a + b` per lane, rounded once where the backend has FMA (the AVX2 and
    /// AVX-512 ones) and twice elsewhere, so its bits depend on the instruction set:
    /// only for values a margin covers either way (the node step's bands in `t`).
    #[inline(always)]
    fn mul_add_fast(self, a: Self, b: Self) -> Self {
        self * a + b
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
#[inline(always)]
pub fn transpose8_lanes<F: Float>(records: &[[f32; 8]]) -> [F; 8] {
    transpose8_lanes_from(
        #[inline(always)]
        |i| records.get(i),
    )
}

/// [`Float::transpose8_halves`] lane by lane, at any width.
#[inline(always)]
pub(crate) fn transpose8_halves_lanes<F: Float>(lo: &[[f32; 8]], hi: &[[f32; 8]]) -> [F; 8] {
    transpose8_lanes_from(
        #[inline(always)]
        |i| {
            if i < lo.len() {
                lo.get(i)
            } else {
                hi.get(i - lo.len())
            }
        },
    )
}

/// Lane `i` of vector `j` is field `j` of `record(i)` (0 where `None`).
#[inline(always)]
pub(crate) fn transpose8_lanes_from<'r, F: Float>(
    record: impl Fn(usize) -> Option<&'r [f32; 8]>,
) -> [F; 8] {
    array_fn(
        #[inline(always)]
        |j| {
            F::from_fn(
                #[inline(always)]
                |i| {
                    record(i).map_or(
                        0.0,
                        #[inline(always)]
                        |r| r[j],
                    )
                },
            )
        },
    )
}

/// [`Float::transpose4_into`] lane by lane, at any width.
#[inline(always)]
pub fn transpose4_lanes<F: Float>(v: [F; 4], out: &mut [[f32; 4]]) {
    for (i, r) in out.iter_mut().enumerate() {
        *r = v.amap(
            #[inline(always)]
            |x| x.lane(i),
        );
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
            Self::from_fn(
                #[inline(always)]
                |i| table[2 * idx[i] as usize],
            ),
            Self::from_fn(
                #[inline(always)]
                |i| table[2 * idx[i] as usize + 1],
            ),
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
    #[inline(always)]
    fn none(self) -> bool {
        !self.any()
    }
}

/// A lane mask of width `V` (all bits set or clear per lane, as the comparisons
/// return); its own type so that it cannot be used as a value.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct VBool<V>(V);

/// `f` itself. Rust takes `#[inline(always)]` on a closure only where it is an argument,
/// so a kernel names its closures through this. Kernels mark every closure so: one
/// that LLVM keeps out of line is compiled for the baseline, not for the kernel's
/// instruction set, and each vector operation in it becomes a call (perf/isa.md).
#[inline(always)]
pub fn inl<F>(f: F) -> F {
    f
}

/// `std::array::from_fn`, always inlined. Kernels build their small arrays with this:
/// the standard one runs through helpers that LLVM keeps out of line, compiled for the
/// baseline instead of the kernel's instruction set, so every vector operation in the
/// closure would become a call (perf/isa.md).
#[inline(always)]
pub fn array_fn<T, const N: usize>(mut f: impl FnMut(usize) -> T) -> [T; N] {
    let mut out: [std::mem::MaybeUninit<T>; N] = [const { std::mem::MaybeUninit::uninit() }; N];
    for (i, o) in out.iter_mut().enumerate() {
        o.write(f(i));
    }
    // SAFETY: every element has been written, and `MaybeUninit<T>` has `T`'s layout.
    unsafe { std::mem::transmute_copy(&out) }
}

/// `[T; N]::map`, always inlined (see [`array_fn`]).
pub trait AMap<T, const N: usize> {
    /// Each element through `f`, in order.
    fn amap<U>(self, f: impl FnMut(T) -> U) -> [U; N];
}

impl<T: Copy, const N: usize> AMap<T, N> for [T; N] {
    #[inline(always)]
    fn amap<U>(self, mut f: impl FnMut(T) -> U) -> [U; N] {
        array_fn(
            #[inline(always)]
            |i| f(self[i]),
        )
    }
}

/// [`Float::from_rows4`] lane by lane, at any width.
#[inline(always)]
pub(crate) fn rows4_lanes<'r, F: Float>(rows: impl Fn(usize) -> &'r [f32; 4]) -> [F; 4] {
    array_fn(
        #[inline(always)]
        |j| {
            F::from_fn(
                #[inline(always)]
                |i| rows(i)[j],
            )
        },
    )
}

/// The same lanes in another backend of the same width (a portable packet handed to
/// the backend of the instruction set in use, and its answers back): no bit changes.
/// Every vector type is its lanes in order and nothing else (`wide`'s, `__m256`,
/// `__m512`, pairs of them), so two of one size are the same bytes: a copy
/// (`bytemuck::try_cast`), no shuffles (lane by lane it cost packet8 a fifth of its
/// rate).
#[inline(always)]
pub(crate) fn recast<A: Float + Pod, B: Float + Pod>(x: A) -> B {
    match bytemuck::try_cast(x) {
        Ok(y) => y,
        Err(_) => B::from_fn(
            #[inline(always)]
            |i| x.lane(i),
        ),
    }
}

/// [`recast`] of u32 lanes.
#[inline(always)]
pub(crate) fn recast_u<A: Uint + Pod, B: Uint + Pod>(x: A) -> B {
    match bytemuck::try_cast(x) {
        Ok(y) => y,
        Err(_) => B::from_fn(
            #[inline(always)]
            |i| x.lane(i),
        ),
    }
}

/// [`recast`] of a mask. Masks of one size are full lanes of set or clear bits (a
/// `k` register mask is smaller, and goes through its bits).
#[inline(always)]
pub(crate) fn recast_mask<A: LaneMask + Pod, B: LaneMask + Pod>(m: A) -> B {
    match bytemuck::try_cast(m) {
        Ok(y) => y,
        Err(_) => B::from_bits(m.bits()),
    }
}

/// The widest packet the instruction set in use runs in one register: 16 with
/// AVX-512, 8 with AVX2, else 4 ([`Isa::lanes`]).
pub fn native_lanes() -> usize {
    Isa::in_use().lanes()
}

/// The largest absolute component per lane, `max_gt(max_gt(|x|, |y|), |z|)`: the twin
/// of the scalar `accel::triaccel::max_abs`. The scalar twins of `min_lt`, `max_gt` and
/// `max_abs` stay in triaccel.rs: moved here, they made the renderer 5-9% slower in
/// paired runs (code placement; perf/log/overview.md).
#[inline(always)]
pub fn max_abs<F: Float>(v: &[F; 3]) -> F {
    v[0].abs().max_gt(v[1].abs()).max_gt(v[2].abs())
}
#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `$f` with `B` each backend this CPU runs and `P` the portable backend of its
    /// width; prints the instruction sets that ran.
    macro_rules! each_backend {
        (|$b:ident, $p:ident| $f:expr) => {{
            macro_rules! with {
                ($backend:ty, $portable:ty) => {{
                    type $b = $backend;
                    #[allow(dead_code)]
                    type $p = $portable;
                    $f;
                }};
            }
            with!(W4, W4);
            with!(W8, W8);
            with!(W16, W16);
            #[cfg(target_arch = "x86_64")]
            {
                if Isa::Avx2.supported() {
                    with!(Avx2x4, W4);
                    with!(Avx2x8, W8);
                    with!(Avx2x16, W16);
                }
                if Isa::Avx512.supported() {
                    with!(Avx512x4, W4);
                    with!(Avx512x8, W8);
                    with!(Avx512x16, W16);
                }
            }
        }};
    }

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
        each_backend!(|B, P| masks_round_trip::<B>());
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
        each_backend!(|B, P| transpose8_halves_join_the_runs::<B>());
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
        each_backend!(|B, P| transpose4_moves_every_bit::<B>());
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
        each_backend!(|B, P| rows4_move_every_bit::<B>());
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
        each_backend!(|B, P| uint_ops_match_scalar::<B>());
    }

    #[test]
    fn transpose8_at_every_width() {
        each_backend!(|B, P| transpose8_moves_every_bit::<B>());
    }

    /// Backend `B` repeats the portable backend `P` of its width operation by operation:
    /// every operation of the traits, on every pair of an adversarial set of values,
    /// gives the same bits (and the same mask bits) in both.
    fn matches_portable<B: Simd, P: Simd>() {
        assert_eq!(B::LANES, P::LANES);

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
        // A NaN's sign and payload depend on which operand the compiler puts first (IEEE
        // leaves them open, and no kernel's answer depends on them): any NaN counts as
        // the same value.
        let canon = |x: f32| {
            if x.is_nan() {
                f32::NAN.to_bits()
            } else {
                x.to_bits()
            }
        };
        let bits_n = |v: Vf<B>| (0..B::LANES).map(|i| canon(v.lane(i))).collect::<Vec<_>>();
        let bits_w = |v: Vf<P>| (0..B::LANES).map(|i| canon(v.lane(i))).collect::<Vec<_>>();
        for shift in 0..n {
            let a_n = Vf::<B>::from_fn(|i| xs[i % n]);
            let b_n = Vf::<B>::from_fn(|i| xs[(i + shift) % n]);
            let a_w = Vf::<P>::from_fn(|i| xs[i % n]);
            let b_w = Vf::<P>::from_fn(|i| xs[(i + shift) % n]);
            let values: [(Vf<B>, Vf<P>); 14] = [
                (a_n + b_n, a_w + b_w),
                (a_n - b_n, a_w - b_w),
                (a_n * b_n, a_w * b_w),
                (a_n / b_n, a_w / b_w),
                (-a_n, -a_w),
                (a_n.abs(), a_w.abs()),
                (a_n.sqrt(), a_w.sqrt()),
                (a_n.min(b_n), a_w.min(b_w)),
                (a_n.max(b_n), a_w.max(b_w)),
                (a_n.min_lt(b_n), a_w.min_lt(b_w)),
                (a_n.max_gt(b_n), a_w.max_gt(b_w)),
                (
                    Vf::<B>::select(a_n.cmp_lt(b_n), a_n, b_n),
                    Vf::<P>::select(a_w.cmp_lt(b_w), a_w, b_w),
                ),
                (
                    Vf::<B>::from_bits(a_n.to_bits() + Vu::<B>::splat(1)),
                    Vf::<P>::from_bits(a_w.to_bits() + Vu::<P>::splat(1)),
                ),
                (
                    Vf::<B>::from_bits(a_n.to_bits() - Vu::<B>::splat(1)),
                    Vf::<P>::from_bits(a_w.to_bits() - Vu::<P>::splat(1)),
                ),
            ];
            for (k, (v_n, v_w)) in values.into_iter().enumerate() {
                assert_eq!(bits_n(v_n), bits_w(v_w), "operation {k}, shift {shift}");
            }
            // `mul_add_fast`: the portable backends round twice; every backend rounds
            // either once in all lanes (as `f32::mul_add`) or twice in all lanes.
            let c = |i: usize| xs[(i + 2 * shift + 1) % n];
            let (c_n, c_w) = (Vf::<B>::from_fn(c), Vf::<P>::from_fn(c));
            let twice: Vec<u32> = (0..B::LANES)
                .map(|i| canon(xs[i % n] * xs[(i + shift) % n] + c(i)))
                .collect();
            let once: Vec<u32> = (0..B::LANES)
                .map(|i| canon(xs[i % n].mul_add(xs[(i + shift) % n], c(i))))
                .collect();
            assert_eq!(
                bits_w(a_w.mul_add_fast(b_w, c_w)),
                twice,
                "portable mul_add_fast"
            );
            let fast = bits_n(a_n.mul_add_fast(b_n, c_n));
            assert!(
                fast == once || fast == twice,
                "mul_add_fast, shift {shift}: {fast:?} is neither {once:?} nor {twice:?}"
            );
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
            let u = Vu::<B>::select(m, a_n.to_bits(), b_n.to_bits());
            let v = Vf::<B>::select(m, a_n, b_n);
            assert_eq!(
                (0..B::LANES).map(|i| u.lane(i)).collect::<Vec<_>>(),
                (0..B::LANES)
                    .map(|i| v.lane(i).to_bits())
                    .collect::<Vec<_>>()
            );
        }
    }

    /// Every backend the CPU runs against the portable one of its width.
    #[test]
    fn backends_match_portable() {
        each_backend!(|B, P| matches_portable::<B, P>());
    }

    #[test]
    fn min_and_max_follow_the_scalar_order() {
        each_backend!(|B, P| min_max_order::<B>());
    }
}
