//! The random number generators, one of each kind, below every other module.
//!
//! - [`Pcg32`]: O'Neill's PCG32 (XSH RR 64/32) with the reference `pcg32_srandom_r`
//!   seeding. The renderer's samples ([`crate::render::sample::pixel_rng`]) and the
//!   diffuse ray set (seed 42, sequence 54, as the Embree harness) draw from it, so its
//!   sequence is fixed by the reference test below.
//! - [`SplitMix64`] (Steele, Lea & Flood 2014): tiny and seedable, for generated test
//!   geometry and rays; its finaliser [`mix64`] also spreads pixel coordinates into
//!   PCG32 seeds.

use glam::Vec3;

/// O'Neill's PCG32 (XSH RR 64/32): 64 bits of state, a per-stream odd increment.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    const MULT: u64 = 6364136223846793005;

    /// The reference `pcg32_srandom_r(initstate, initseq)` seeding.
    #[inline]
    pub fn new(seed: u64, stream: u64) -> Pcg32 {
        let mut rng = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 random bits (`pcg32_random_r`).
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in `[0, 1)`: the top 24 bits, so every value is exact and below 1.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// The same 24 bits as [`Pcg32::next_f32`] in f64, as the Embree harness draws.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u32() >> 8) as f64 * (1.0 / 16_777_216.0)
    }
}

/// SplitMix64's finaliser of `z` plus the golden-ratio increment: spreads neighbouring
/// integers over all 64 bits.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(SplitMix64::GAMMA);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// SplitMix64 (Steele, Lea & Flood 2014): tiny, seedable, and good enough for test
/// geometry and ray sets.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

    /// The generator whose sequence is fixed by `seed` alone.
    #[inline]
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    /// The next 64 random bits; the other draws are built on it.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let out = mix64(self.0);
        self.0 = self.0.wrapping_add(Self::GAMMA);
        out
    }

    /// Uniform in `[0, 1)`, 24 random bits.
    #[inline]
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in `[lo, hi)`.
    #[inline]
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// Uniform in `0..n`.
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }

    /// A point uniform in the box `[lo, hi]`.
    #[inline]
    pub fn point(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    /// A unit vector, uniform on the sphere.
    #[inline]
    pub fn unit_vector(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg32_matches_the_reference_sequence() {
        // pcg32-global-demo of the minimal C library, seeded with (42, 54).
        let mut rng = Pcg32::new(42, 54);
        let got: Vec<u32> = (0..6).map(|_| rng.next_u32()).collect();
        assert_eq!(
            got,
            [
                0xa15c02b7, 0x7b47f409, 0xba1d3330, 0x83d2f293, 0xbfa4784b, 0xcbed606e
            ]
        );
        // Both floats are the top 24 bits of the next draw.
        let (mut a, mut b, mut c) = (Pcg32::new(1, 2), Pcg32::new(1, 2), Pcg32::new(1, 2));
        for _ in 0..100 {
            let bits = (a.next_u32() >> 8) as f64 / 16_777_216.0;
            assert_eq!(b.next_f32() as f64, bits);
            assert_eq!(c.next_f64(), bits);
        }
    }

    #[test]
    fn splitmix64_matches_the_reference_sequence() {
        // Vigna's splitmix64.c seeded with 0.
        let mut rng = SplitMix64::new(0);
        let got: Vec<u64> = (0..3).map(|_| rng.next_u64()).collect();
        assert_eq!(
            got,
            [0xe220a8397b1dcdaf, 0x6e789e6aa1b965f4, 0x06c45d188009454f]
        );
    }
}
