//! One lane: [`Float`] for `f32`, with `bool` masks and `u32` words. Set-up code that the
//! scalar walk and the SIMD walks share (the kd-tree's box clip and plane bands) is
//! written once against [`Float`] and runs on one ray as on a packet, so the scalar
//! oracle and every backend compute it with the same operations in the same order.

use super::{Float, LaneBits, LaneMask, Uint};

impl LaneMask for bool {
    const NONE: bool = false;
    #[inline(always)]
    fn from_bits(bits: LaneBits) -> bool {
        bits & 1 != 0
    }
    #[inline(always)]
    fn bits(self) -> LaneBits {
        self as LaneBits
    }
    #[inline(always)]
    fn any(self) -> bool {
        self
    }
}

impl Float for f32 {
    type Mask = bool;
    type U = u32;
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> f32 {
        f(0)
    }
    #[inline(always)]
    fn lane(&self, _: usize) -> f32 {
        *self
    }
    #[inline(always)]
    fn cmp_lt(self, o: f32) -> bool {
        self < o
    }
    #[inline(always)]
    fn cmp_gt(self, o: f32) -> bool {
        self > o
    }
    #[inline(always)]
    fn cmp_le(self, o: f32) -> bool {
        self <= o
    }
    #[inline(always)]
    fn cmp_ge(self, o: f32) -> bool {
        self >= o
    }
    #[inline(always)]
    fn cmp_eq(self, o: f32) -> bool {
        self == o
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    /// As the backends (`minps` with a NaN operand giving the other one): on `+-0.0`
    /// the second operand, where `f32::min` may give either.
    #[inline(always)]
    fn min(self, o: f32) -> f32 {
        if self.is_nan() {
            o
        } else if o.is_nan() {
            self
        } else {
            self.min_lt(o)
        }
    }
    /// As [`Float::min`] for `f32`, the larger.
    #[inline(always)]
    fn max(self, o: f32) -> f32 {
        if self.is_nan() {
            o
        } else if o.is_nan() {
            self
        } else {
            self.max_gt(o)
        }
    }
    #[inline(always)]
    fn min_lt(self, o: f32) -> f32 {
        if self < o { self } else { o }
    }
    #[inline(always)]
    fn max_gt(self, o: f32) -> f32 {
        if self > o { self } else { o }
    }
    #[inline(always)]
    fn to_bits(self) -> u32 {
        f32::to_bits(self)
    }
    #[inline(always)]
    fn from_bits(u: u32) -> f32 {
        f32::from_bits(u)
    }
    #[inline(always)]
    fn select(mask: bool, if_true: f32, if_false: f32) -> f32 {
        if mask { if_true } else { if_false }
    }
}

impl Uint for u32 {
    type Mask = bool;
    #[inline(always)]
    fn splat(x: u32) -> u32 {
        x
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> u32) -> u32 {
        f(0)
    }
    #[inline(always)]
    fn lane(&self, _: usize) -> u32 {
        *self
    }
    #[inline(always)]
    fn cmp_gt(self, o: u32) -> bool {
        self > o
    }
    #[inline(always)]
    fn select(mask: bool, if_true: u32, if_false: u32) -> u32 {
        if mask { if_true } else { if_false }
    }
    #[inline(always)]
    fn shr(self, n: u32) -> u32 {
        self >> n
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Isa, Simd, W4, W8, W16};
    use super::*;

    /// A binary operation and a comparison of one lane or of many.
    type Op<F> = fn(F, F) -> F;
    type Cmp<F> = fn(F, F) -> <F as Float>::Mask;

    /// Every operation of the one-lane `f32` gives the bits a backend's lane gives, on
    /// the values where IEEE rules bite (signed zeros, NaN, infinities, subnormals,
    /// the largest finite values) and on a spread of ordinary ones.
    fn agrees_with<W: Simd>() {
        let mut xs = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            2.5,
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE / 8.0,
            -f32::MIN_POSITIVE / 8.0,
            f32::MAX,
            f32::MIN,
        ];
        let mut bits = 0x1234_5678u32;
        for _ in 0..40 {
            bits = bits.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
            xs.push(f32::from_bits(bits));
        }
        let v = |x: f32| W::F::splat(x);
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for &a in &xs {
            assert!(same(Float::abs(a), v(a).abs().lane(0)), "abs({a:?})");
            assert!(same(Float::sqrt(a), v(a).sqrt().lane(0)), "sqrt({a:?})");
            assert_eq!(Float::finite(a), v(a).finite().any(), "finite({a:?})");
            for &b in &xs {
                let what = format!("({a:?}, {b:?}) against {} lanes of {}", W::LANES, W::ISA);
                let ops: [(Op<f32>, Op<W::F>); 8] = [
                    (|a, b| a + b, |a, b| a + b),
                    (|a, b| a - b, |a, b| a - b),
                    (|a, b| a * b, |a, b| a * b),
                    (|a, b| a / b, |a, b| a / b),
                    (Float::min, Float::min),
                    (Float::max, Float::max),
                    (Float::min_lt, Float::min_lt),
                    (Float::max_gt, Float::max_gt),
                ];
                for (k, (one, lanes)) in ops.iter().enumerate() {
                    assert!(same(one(a, b), lanes(v(a), v(b)).lane(0)), "op {k} {what}");
                }
                let cmps: [(Cmp<f32>, Cmp<W::F>); 5] = [
                    (Float::cmp_lt, Float::cmp_lt),
                    (Float::cmp_gt, Float::cmp_gt),
                    (Float::cmp_le, Float::cmp_le),
                    (Float::cmp_ge, Float::cmp_ge),
                    (Float::cmp_eq, Float::cmp_eq),
                ];
                for (k, (one, lanes)) in cmps.iter().enumerate() {
                    assert_eq!(one(a, b), lanes(v(a), v(b)).any(), "comparison {k} {what}");
                }
                for m in [false, true] {
                    let lanes =
                        W::F::select(W::Mask::from_bits(m as u32 * W::all_bits()), v(a), v(b));
                    assert!(
                        same(f32::select(m, a, b), lanes.lane(0)),
                        "select {m} {what}"
                    );
                }
            }
        }
    }

    #[test]
    fn one_lane_agrees_with_every_backend() {
        agrees_with::<W4>();
        agrees_with::<W8>();
        agrees_with::<W16>();
        #[cfg(target_arch = "x86_64")]
        {
            use super::super::{Avx2x4, Avx2x8, Avx2x16, Avx512x4, Avx512x8, Avx512x16};
            if Isa::Avx2.supported() {
                agrees_with::<Avx2x4>();
                agrees_with::<Avx2x8>();
                agrees_with::<Avx2x16>();
            }
            if Isa::Avx512.supported() {
                agrees_with::<Avx512x4>();
                agrees_with::<Avx512x8>();
                agrees_with::<Avx512x16>();
            }
        }
    }

    #[test]
    fn one_lane_masks_and_words() {
        assert!(bool::from_bits(1) && !bool::from_bits(2) && bool::NONE.none());
        assert_eq!((true.bits(), false.bits()), (1, 0));
        assert_eq!(<u32 as Uint>::select(true, 7, 9), 7);
        assert_eq!(Uint::shr(0x80u32, 4), 8);
        assert!(Uint::cmp_gt(3u32, 2) && !Uint::cmp_gt(2u32, 3));
    }
}
