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

/// Per-lane u32 values.
pub trait Uint: Copy + Debug + Send + Sync + Add<Output = Self> + Sub<Output = Self> {
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

macro_rules! width {
    ($w:ident, $f:ident, $u:ident, $n:literal, $shape:expr, $scalar_max:literal, $doc:literal) => {
        #[doc = $doc]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct $w;

        impl Simd for $w {
            const LANES: usize = $n;
            const SHAPE: (u32, u32) = $shape;
            const SCALAR_GROUP_MAX: u32 = $scalar_max;
            type F = wide::$f;
            type U = wide::$u;
            type Mask = VBool<wide::$f>;
        }

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
        }
    };
}

width!(
    W4,
    f32x4,
    u32x4,
    4,
    (2, 2),
    1,
    "4 lanes (SSE): the Wald packet."
);
width!(W8, f32x8, u32x8, 8, (4, 2), 2, "8 lanes (AVX2).");
width!(W16, f32x16, u32x16, 16, (4, 4), 3, "16 lanes (AVX-512).");

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
/// paired runs (code placement; perf/README.md).
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

    #[test]
    fn min_and_max_follow_the_scalar_order() {
        min_max_order::<W4>();
        min_max_order::<W8>();
        min_max_order::<W16>();
    }
}
