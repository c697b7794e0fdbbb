//! The one place that sets the SIMD width.
//!
//! Every packet kernel is written against these aliases and functions, so changing
//! the lane count (or the backend) means changing this file only. No other file
//! names `wide`. Inspired by Embree's `vfloat<N>` and its single `VSIZEX`.

/// Rays per packet.
pub const LANES: usize = 4;

/// One f32 per lane.
pub type Vf = wide::f32x4;
/// One u32 per lane (primitive ids).
pub type Vu = wide::u32x4;
/// One i32 per lane.
pub type Vi = wide::i32x4;
/// A lane mask: all bits set (true) or clear (false) per lane, as the comparisons return.
pub type Mask = wide::f32x4;

/// The same value in every lane.
#[inline]
pub fn splat(x: f32) -> Vf {
    Vf::splat(x)
}

/// `if_true` where `mask` is set, `if_false` elsewhere.
#[inline]
pub fn select(mask: Mask, if_true: Vf, if_false: Vf) -> Vf {
    mask.bitselect(if_true, if_false)
}

/// `if_true` where `mask` is set, `if_false` elsewhere, for integer lanes.
#[inline]
pub fn select_u(mask: Mask, if_true: Vu, if_false: Vu) -> Vu {
    mask.to_bits().bitselect(if_true, if_false)
}

/// `if a < b { a } else { b }` per lane: the order glam's `Vec3::min` and
/// `min_element` use (the second operand wins on NaN or equality), so packet kernels
/// reproduce the scalar ones bit for bit. One `minps`.
#[inline]
pub fn min_lt(a: Vf, b: Vf) -> Vf {
    a.fast_min(b)
}

/// `if a > b { a } else { b }` per lane, glam's `Vec3::max` order. One `maxps`.
#[inline]
pub fn max_gt(a: Vf, b: Vf) -> Vf {
    a.fast_max(b)
}

/// The largest absolute component per lane, `max_gt(max_gt(|x|, |y|), |z|)`: the twin
/// of the scalar `triaccel::max_abs`.
#[inline]
pub fn max_abs(v: &[Vf; 3]) -> Vf {
    max_gt(max_gt(v[0].abs(), v[1].abs()), v[2].abs())
}

/// A mask with lane `i` set where bit `i` of `bits` is set.
#[inline]
pub fn mask_from_bits(bits: u32) -> Mask {
    let lane = |i: u32| f32::from_bits(if bits & (1 << i) != 0 { u32::MAX } else { 0 });
    Mask::new([lane(0), lane(1), lane(2), lane(3)])
}

/// Bit `i` set where lane `i` of `mask` is set.
#[inline]
pub fn bits(mask: Mask) -> u32 {
    mask.to_bitmask()
}

/// True when any lane of `mask` is set.
#[inline]
pub fn any(mask: Mask) -> bool {
    mask.any()
}

/// True when no lane of `mask` is set.
#[inline]
pub fn none(mask: Mask) -> bool {
    !mask.any()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_round_trip_through_bits() {
        for b in 0..(1u32 << LANES) {
            assert_eq!(bits(mask_from_bits(b)), b);
        }
        let m = mask_from_bits(0b0101);
        let r = select(m, splat(1.0), splat(2.0)).to_array();
        assert_eq!(r, [1.0, 2.0, 1.0, 2.0]);
        let u = select_u(m, Vu::splat(7), Vu::splat(9)).to_array();
        assert_eq!(u, [7, 9, 7, 9]);
        assert!(any(m) && !none(m) && none(mask_from_bits(0)));
    }

    #[test]
    fn min_and_max_follow_the_scalar_order() {
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
                let lo = min_lt(splat(a), splat(b)).to_array()[0];
                let hi = max_gt(splat(a), splat(b)).to_array()[0];
                assert_eq!(lo.to_bits(), pick_min(a, b).to_bits(), "min({a:?}, {b:?})");
                assert_eq!(hi.to_bits(), pick_max(a, b).to_bits(), "max({a:?}, {b:?})");
            }
        }
    }
}
