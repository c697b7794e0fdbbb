//! render: sampling. The random numbers, bases and sample patterns of the Monte Carlo
//! parts of the Whitted tracer (tutorial parts 3, 5 and 6): jittered sub-pixel camera
//! samples, area-light positions on a stratified 4x4 grid, glossy directions in a cone
//! around the mirror direction; and the [`Sampler`] of the global-illumination
//! integrators: independent numbers, or Owen-scrambled Sobol points.
//!
//! Invariants: every generator is seeded from the scene seed, the pixel and the sample
//! index only ([`pixel_rng`]), so an image never depends on the number of threads or on
//! the order tiles are rendered in. The generator ([`Pcg32`]) and the orthonormal basis
//! ([`Onb`]) are shared with the ray-set generator and live below both ([`crate::rng`],
//! [`crate::onb`]).

use crate::ray::Ray;
use crate::scene::CameraFrame;
use glam::Vec3;

pub use crate::onb::Onb;
pub use crate::rng::Pcg32;
use crate::rng::mix64;

/// The generator of sample `sample` of pixel `(x, y)` under scene seed `seed`. Pixels
/// and samples get independent streams, so rendering them in any order on any number of
/// threads gives the same numbers.
pub fn pixel_rng(seed: u64, x: u32, y: u32, sample: u32) -> Pcg32 {
    let pixel = ((y as u64) << 32) | x as u64;
    Pcg32::new(mix64(seed ^ mix64(pixel)), sample as u64)
}

/// How the global-illumination integrators draw their random numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SamplerKind {
    /// Independent uniforms from [`pixel_rng`].
    Independent,
    /// Owen-scrambled Sobol points, padded per dimension (Burley 2020): the samples of a
    /// pixel fill every 1D and 2D dimension evenly, so the error falls faster than
    /// `1 / sqrt(spp)` on smooth integrands and no slower elsewhere.
    #[default]
    Sobol,
}

impl SamplerKind {
    /// The name the command line and the reports use.
    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Sobol => "sobol",
        }
    }
}

/// The random numbers of sample `k` of one pixel. Integrators draw a dimension at a time
/// in a fixed order: one value ([`Sampler::next_1d`]) for a discrete choice (a light, a
/// lobe, Russian roulette), two ([`Sampler::next_2d`]) for a point on a square (a pixel
/// position, a point on a light, a direction).
#[derive(Clone, Debug)]
pub enum Sampler {
    /// Every value from one PCG32 stream, in the order drawn: `next_2d` is two
    /// `next_1d`s.
    Independent(Pcg32),
    Sobol(Sobol),
}

impl Sampler {
    /// The sampler of sample `k` of pixel `(x, y)` under scene seed `seed`.
    pub fn new(kind: SamplerKind, seed: u64, x: u32, y: u32, k: u32) -> Sampler {
        match kind {
            SamplerKind::Independent => Sampler::Independent(pixel_rng(seed, x, y, k)),
            SamplerKind::Sobol => Sampler::Sobol(Sobol::new(pixel_seed(seed, x, y), k)),
        }
    }

    /// A uniform in `[0, 1)`.
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        match self {
            Sampler::Independent(rng) => rng.next_f32(),
            Sampler::Sobol(s) => s.next_1d(),
        }
    }

    /// A point in `[0, 1)^2`.
    #[inline(always)]
    pub fn next_2d(&mut self) -> (f32, f32) {
        match self {
            Sampler::Independent(rng) => {
                let u = rng.next_f32();
                (u, rng.next_f32())
            }
            Sampler::Sobol(s) => s.next_2d(),
        }
    }

    /// A discrete choice then a point on a square, as light and BSDF sampling take
    /// them: `[next_1d, next_2d]`.
    #[inline(always)]
    pub fn next_choice_2d(&mut self) -> [f32; 3] {
        let c = self.next_1d();
        let (u, v) = self.next_2d();
        [c, u, v]
    }
}

/// The 64-bit seed of pixel `(x, y)` under scene seed `seed`, as [`pixel_rng`] mixes it.
fn pixel_seed(seed: u64, x: u32, y: u32) -> u64 {
    let pixel = ((y as u64) << 32) | x as u64;
    mix64(seed ^ mix64(pixel))
}

/// Point `index` of a pixel's Owen-scrambled Sobol sequence, one dimension after another.
/// Each dimension (1D or 2D) has its own scramble and its own shuffle of the point order,
/// both hashed from the pixel's seed and the dimension's number (Burley, "Practical
/// Hash-based Owen Scrambling", JCGT 2020): dimensions are decorrelated from each other
/// and pixels from their neighbours, while the first `2^m` points of every 2D dimension
/// still form a (0, m, 2)-net.
#[derive(Clone, Debug)]
pub struct Sobol {
    seed: u64,
    /// The point's index, bit-reversed once (every dimension's shuffle takes it so).
    index_reversed: u32,
    dim: u32,
}

/// Each byte value with its bits in reverse order.
const REVERSED_BYTES: [u8; 256] = {
    let mut table = [0u8; 256];
    let mut b = 0;
    while b < 256 {
        table[b] = (b as u8).reverse_bits();
        b += 1;
    }
    table
};

/// `v.reverse_bits()` by four byte-table reads: x86-64 has no instruction for it, and
/// the shift-and-mask sequence LLVM expands it into is the longer chain. The sampler
/// reverses two or three words per dimension; those took 6% of a path-traced render.
#[inline(always)]
fn reverse(v: u32) -> u32 {
    let r = |shift: u32| REVERSED_BYTES[(v >> shift) as usize & 0xff] as u32;
    (r(0) << 24) | (r(8) << 16) | (r(16) << 8) | r(24)
}

/// The second Sobol dimension's generator matrix (the first is the bit reversal) applied
/// a byte of the index at a time: entry `[k][b]` is the XOR of the columns of the bits
/// set in byte value `b` at byte `k`, so a point costs four loads and no branch. Columns
/// are `v[0] = 1/2`, `v[i] = v[i-1] ^ (v[i-1] >> 1)` as binary fractions, stored
/// bit-reversed (bit `j` is the fraction's digit `j + 1`), as the scrambles take them.
const SOBOL_1_BYTES: [[u32; 256]; 4] = {
    let mut columns = [0u32; 32];
    let mut column = 1u32 << 31;
    let mut i = 0;
    while i < 32 {
        columns[i] = column.reverse_bits();
        column ^= column >> 1;
        i += 1;
    }
    let mut table = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            let mut y = 0;
            let mut bit = 0;
            while bit < 8 {
                if b & (1 << bit) != 0 {
                    y ^= columns[8 * k + bit];
                }
                bit += 1;
            }
            table[k][b] = y;
            b += 1;
        }
        k += 1;
    }
    table
};

/// The hash of Owen scrambling on bit-reversed digits (pbrt-v4's `FastOwenScrambler`
/// between its two reversals, after Vegdahl): bit `j` of the result depends on bits `0..=j`
/// of `v` and the seed only, so reversed back, each digit of a binary fraction is flipped
/// by a hash of the digits above it, which is Owen's nested uniform scramble.
#[inline]
fn owen_hash(mut v: u32, seed: u32) -> u32 {
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v
}

/// The top 24 bits of a binary fraction as an exact f32 below 1.
#[inline]
fn unit(v: u32) -> f32 {
    (v >> 8) as f32 * (1.0 / 16_777_216.0)
}

impl Sobol {
    /// Point `index` of the sequence whose scrambles come from `seed`.
    pub fn new(seed: u64, index: u32) -> Sobol {
        Sobol {
            seed,
            index_reversed: index.reverse_bits(),
            dim: 0,
        }
    }

    /// The hashes of the next dimension: the index shuffle's, then one scramble's per
    /// axis.
    #[inline]
    fn next_hashes(&mut self) -> (u32, u32, u32) {
        let a = mix64(self.seed ^ (self.dim as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let b = a.wrapping_mul(0xD6E8_FEB8_6659_FD93);
        self.dim += 1;
        (a as u32, (a >> 32) as u32, (b >> 32) as u32)
    }

    /// The point's index after this dimension's shuffle, bit-reversed: Owen's scramble of
    /// the index as an integer (the high digits flip the low ones), so a power-of-two
    /// block of indices maps onto an aligned block of the same size and prefixes keep
    /// their net property. Reversed, it is also the first Sobol dimension's fraction.
    #[inline]
    fn shuffled_reversed(&self, hash: u32) -> u32 {
        owen_hash(self.index_reversed, hash)
    }

    /// The next 1D dimension: the scrambled van der Corput sequence.
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let (h0, h1, _) = self.next_hashes();
        let x = self.shuffled_reversed(h0);
        unit(reverse(owen_hash(reverse(x), h1)))
    }

    /// The next 2D dimension: the first two Sobol dimensions, each scrambled.
    #[inline]
    pub fn next_2d(&mut self) -> (f32, f32) {
        let (h0, h1, h2) = self.next_hashes();
        let x = self.shuffled_reversed(h0);
        // The index, `x` reversed; the second dimension's digits reversed come from the
        // reversed columns.
        let i = reverse(x);
        let [b0, b1, b2, b3] = i.to_le_bytes();
        let t = &SOBOL_1_BYTES;
        let y = t[0][b0 as usize] ^ t[1][b1 as usize] ^ t[2][b2 as usize] ^ t[3][b3 as usize];
        (
            unit(reverse(owen_hash(i, h1))),
            unit(reverse(owen_hash(y, h2))),
        )
    }
}

/// A direction uniformly distributed over the solid angle of the cone around `axis`
/// (unit) with half-angle `acos(cos_max)`, from two uniforms in `[0, 1)`.
pub fn sample_cone(axis: Vec3, cos_max: f32, r1: f32, r2: f32) -> Vec3 {
    let cos_theta = 1.0 - r1 * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * r2;
    let local = Vec3::new(phi.cos() * sin_theta, phi.sin() * sin_theta, cos_theta);
    Onb::from_w(axis).to_world(local).normalize()
}

/// A cosine-weighted direction around `+z` from two uniforms (Malley's method: a
/// uniform point on the unit disc lifted onto the hemisphere); density `cos / pi`.
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Cells per side of the area-light grid.
pub const STRATA: u32 = 4;

/// The `(column, row)` of stratum `cell` (taken mod 16) in the 4x4 grid. Cells are
/// numbered so that every prefix of 4 lands one cell in each quadrant of the light: a
/// secondary bounce that takes only the first few samples (importance sampling, part 6)
/// still sees the whole light rather than one edge of it.
pub fn stratum(cell: u32) -> (u32, u32) {
    let c = cell % (STRATA * STRATA);
    let x = (c & 1) * 2 + ((c >> 2) & 1);
    let y = ((c >> 1) & 1) * 2 + ((c >> 3) & 1);
    (x, y)
}

/// Sample `i` of a stratified pattern over `[0,1)^2`: jittered by `(r1, r2)` inside cell
/// `i % 16` of the 4x4 grid.
pub fn stratified(i: u32, r1: f32, r2: f32) -> (f32, f32) {
    let (x, y) = stratum(i);
    let n = STRATA as f32;
    ((x as f32 + r1) / n, (y as f32 + r2) / n)
}

/// Sample `k` (row-major) of the `n x n` of pixel `(x, y)` whose indices start at
/// `first`: its ray, jittered inside its cell, and its generator after the jitter.
#[inline]
pub fn sub_pixel_sample(
    frame: &CameraFrame,
    seed: u64,
    (x, y): (u32, u32),
    n: u32,
    first: u32,
    k: u32,
) -> (Ray, Pcg32) {
    let (i, j) = (k % n, k / n);
    let mut rng = pixel_rng(seed, x, y, first + k);
    let fx = (i as f32 + rng.next_f32()) / n as f32;
    let fy = (j as f32 + rng.next_f32()) / n as f32;
    (frame.ray(x as f32 + fx, y as f32 + fy), rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_unit(rng: &mut Pcg32) -> Vec3 {
        loop {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let l = p.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return p.normalize();
            }
        }
    }

    #[test]
    fn byte_table_reverse_is_reverse_bits() {
        let mut rng = Pcg32::new(11, 0);
        let edges = [0, 1, 0x8000_0000, u32::MAX, 0x0f0f_0f0f, 0x1234_5678];
        let values = edges
            .into_iter()
            .chain((0..100_000).map(|_| rng.next_u32()));
        for v in values.chain((0..32).map(|k| 1u32 << k)) {
            assert_eq!(reverse(v), v.reverse_bits(), "{v:#010x}");
        }
    }

    #[test]
    fn floats_are_in_the_unit_interval_and_streams_differ() {
        let mut rng = pixel_rng(7, 3, 4, 0);
        for _ in 0..10_000 {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
        }
        let a = pixel_rng(7, 3, 4, 0).next_u32();
        assert_ne!(a, pixel_rng(7, 4, 3, 0).next_u32());
        assert_ne!(a, pixel_rng(7, 3, 4, 1).next_u32());
        assert_ne!(a, pixel_rng(8, 3, 4, 0).next_u32());
        assert_eq!(a, pixel_rng(7, 3, 4, 0).next_u32());
    }

    #[test]
    fn cone_directions_stay_inside_the_cone_and_fill_it() {
        let mut rng = Pcg32::new(3, 4);
        for half_angle in [0.01f32, 0.2, 0.7, 1.5] {
            let cos_max = half_angle.cos();
            let axis = random_unit(&mut rng);
            let mut widest = 1.0f32;
            let mut sum = Vec3::ZERO;
            for _ in 0..5000 {
                let d = sample_cone(axis, cos_max, rng.next_f32(), rng.next_f32());
                assert!((d.length() - 1.0).abs() < 1e-5);
                let c = d.dot(axis);
                assert!(c >= cos_max - 1e-5, "cos {c} outside cone cos {cos_max}");
                widest = widest.min(c);
                sum += d;
            }
            // Samples reach close to the rim, and their mean points along the axis.
            let rim = 1.0 - cos_max;
            assert!(widest - cos_max < 0.01 * rim + 1e-6, "never near the rim");
            assert!(sum.normalize().dot(axis) > 0.999);
        }
    }

    /// The points of samples `first..first + 2^m` of 2D dimension `dim` (after `dim`
    /// earlier 2D draws) of the pixel with seed `seed`.
    fn sobol_points(seed: u64, dim: u32, first: u32, m: u32) -> Vec<(f32, f32)> {
        (first..first + (1 << m))
            .map(|k| {
                let mut s = Sobol::new(seed, k);
                for _ in 0..dim {
                    s.next_2d();
                }
                s.next_2d()
            })
            .collect()
    }

    #[test]
    fn sobol_blocks_are_nets_in_every_dimension() {
        // Any aligned block of 2^m samples of a 2D dimension has exactly one point in
        // every elementary interval of area 2^-m, whatever the seed and the dimension.
        let mut seeds = SplitMixSeeds(0x5eed);
        for m in 0..=8u32 {
            for dim in [0, 1, 5] {
                let seed = seeds.next();
                for first in [0, 1 << m, 3 << m] {
                    let pts = sobol_points(seed, dim, first, m);
                    for a in 0..=m {
                        let (nx, ny) = (1u32 << a, 1u32 << (m - a));
                        let mut seen = vec![0u32; (nx * ny) as usize];
                        for &(x, y) in &pts {
                            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                            let (cx, cy) = ((x * nx as f32) as u32, (y * ny as f32) as u32);
                            seen[(cy * nx + cx) as usize] += 1;
                        }
                        assert!(
                            seen.iter().all(|&c| c == 1),
                            "m {m}, dim {dim}, first {first}, {nx}x{ny} cells: {seen:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn sobol_1d_blocks_are_stratified() {
        for m in 0..=10u32 {
            for dim in [0u32, 3] {
                let mut seen = vec![0u32; 1 << m];
                for k in 0..1u32 << m {
                    let mut s = Sobol::new(77 + m as u64, k);
                    for _ in 0..dim {
                        s.next_1d();
                    }
                    let u = s.next_1d();
                    assert!((0.0..1.0).contains(&u));
                    seen[(u * (1 << m) as f32) as usize] += 1;
                }
                assert!(seen.iter().all(|&c| c == 1), "m {m}, dim {dim}");
            }
        }
    }

    #[test]
    fn sobol_dimensions_and_pixels_are_decorrelated() {
        // The same sample index gives unrelated values in other dimensions and pixels,
        // and the values spread over the unit interval (mean near 1/2, no pairs
        // repeating).
        let (mut first, mut second, mut neighbour) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..256 {
            let mut a = Sampler::new(SamplerKind::Sobol, 3, 10, 20, k);
            let mut b = Sampler::new(SamplerKind::Sobol, 3, 11, 20, k);
            first.push(a.next_2d().0);
            second.push(a.next_2d().0);
            neighbour.push(b.next_2d().0);
        }
        let corr = |x: &[f32], y: &[f32]| {
            let n = x.len() as f32;
            let (mx, my) = (x.iter().sum::<f32>() / n, y.iter().sum::<f32>() / n);
            let cov: f32 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
            let vx: f32 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
            let vy: f32 = y.iter().map(|b| (b - my) * (b - my)).sum();
            cov / (vx * vy).sqrt()
        };
        assert!(
            corr(&first, &second).abs() < 0.2,
            "dimensions 0 and 1 correlate"
        );
        assert!(
            corr(&first, &neighbour).abs() < 0.2,
            "neighbouring pixels correlate"
        );
        assert_ne!(first, neighbour);
    }

    #[test]
    fn independent_sampler_is_the_pixel_generator_in_draw_order() {
        let mut s = Sampler::new(SamplerKind::Independent, 5, 6, 7, 8);
        let mut r = pixel_rng(5, 6, 7, 8);
        assert_eq!(s.next_1d(), r.next_f32());
        assert_eq!(s.next_2d(), (r.next_f32(), r.next_f32()));
        assert_eq!(
            s.next_choice_2d(),
            [r.next_f32(), r.next_f32(), r.next_f32()]
        );
    }

    /// Distinct 64-bit seeds for the tests.
    struct SplitMixSeeds(u64);

    impl SplitMixSeeds {
        fn next(&mut self) -> u64 {
            self.0 = mix64(self.0);
            self.0
        }
    }

    #[test]
    fn sixteen_stratified_samples_cover_every_cell_once() {
        let mut seen = [0u32; 16];
        let mut rng = Pcg32::new(5, 6);
        for i in 0..16 {
            let (s, t) = stratified(i, rng.next_f32(), rng.next_f32());
            assert!((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t));
            let (cx, cy) = ((s * 4.0) as u32, (t * 4.0) as u32);
            assert_eq!((cx, cy), stratum(i), "sample {i} left its cell");
            seen[(cy * 4 + cx) as usize] += 1;
        }
        assert_eq!(seen, [1; 16]);
        // Sample i uses cell i % 16.
        assert_eq!(stratum(3), stratum(19));
        // Any 4 consecutive cells from a multiple of 4 hit all four quadrants.
        for start in [0, 4, 8, 12] {
            let mut q: Vec<(u32, u32)> = (start..start + 4)
                .map(|i| {
                    let (x, y) = stratum(i);
                    (x / 2, y / 2)
                })
                .collect();
            q.sort();
            assert_eq!(q, [(0, 0), (0, 1), (1, 0), (1, 1)]);
        }
    }
}
