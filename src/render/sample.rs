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
use crate::simd::Isa;
use glam::Vec3;

pub use crate::onb::Onb;
pub use crate::rng::Pcg32;
use crate::rng::mix64;

/// The generator of sample `sample` of pixel `(x, y)` under scene seed `seed`. Pixels
/// and samples get independent streams, so rendering them in any order on any number of
/// threads gives the same numbers.
pub fn pixel_rng(seed: u64, x: u32, y: u32, sample: u32) -> Pcg32 {
    Pcg32::new(pixel_seed(seed, x, y), sample as u64)
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
        Sampler::for_pixel(kind, pixel_seed(seed, x, y), k)
    }

    /// [`Sampler::new`] from the pixel's [`pixel_seed`], which a renderer taking many
    /// samples of a pixel mixes once.
    #[inline(always)]
    pub fn for_pixel(kind: SamplerKind, pixel_seed: u64, k: u32) -> Sampler {
        match kind {
            SamplerKind::Independent => Sampler::Independent(Pcg32::new(pixel_seed, k as u64)),
            SamplerKind::Sobol => Sampler::Sobol(Sobol::new(pixel_seed, k)),
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
pub fn pixel_seed(seed: u64, x: u32, y: u32) -> u64 {
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
    /// Dimensions drawn ahead by [`draw_ahead`], the same values this point would draw.
    ahead: Ahead,
}

/// How many dimensions [`draw_ahead`] draws at most: a path vertex takes five, six
/// under a sky.
pub const AHEAD: usize = 6;

/// What one dimension of a sampler gives: one value ([`Sampler::next_1d`]) or a point
/// ([`Sampler::next_2d`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Draw {
    One,
    Two,
}

/// A Sobol point's dimensions `first..first + len`, drawn ahead: dimension `first + j`
/// is `values[j]` (a 1D draw is `.0`) when bit `j` of `two` says it was drawn as what
/// is asked of it; any other draw is computed as usual.
#[derive(Clone, Copy, Debug, Default)]
struct Ahead {
    first: u32,
    len: u32,
    two: u32,
    values: [(f32, f32); AHEAD],
}

impl Ahead {
    /// The value drawn ahead for dimension `dim` as `kind`, if there is one.
    #[inline(always)]
    fn get(&self, dim: u32, kind: Draw) -> Option<(f32, f32)> {
        let j = dim.wrapping_sub(self.first);
        let two = (self.two >> (j & 31)) & 1 == 1;
        if j < self.len && two == (kind == Draw::Two) {
            Some(self.values[j as usize])
        } else {
            None
        }
    }
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
/// [`draw_ahead`]'s lanes take `reverse_bits` instead, which vectorises (a byte shuffle).
#[inline(always)]
fn reverse(v: u32) -> u32 {
    let r = |shift: u32| REVERSED_BYTES[(v >> shift) as usize & 0xff] as u32;
    (r(0) << 24) | (r(8) << 16) | (r(16) << 8) | r(24)
}

/// The second Sobol dimension's generator matrix applied to index `i`, bit-reversed
/// (bit `j` is the fraction's digit `j + 1`, as the scrambles take it). The matrix is
/// Pascal's triangle mod 2: by Lucas' theorem digit `j + 1` is the XOR of the index
/// bits `k` whose positions contain `j`'s (`k & j == j`), a transform over the
/// positions' five bits taken one bit at a time: five shift-mask-XOR steps, no table,
/// and it vectorises.
#[inline(always)]
fn sobol_second(i: u32) -> u32 {
    let mut y = i;
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    y ^= y >> 16;
    y
}

/// The hash of Owen scrambling on bit-reversed digits (pbrt-v4's `FastOwenScrambler`
/// between its two reversals, after Vegdahl): bit `j` of the result depends on bits `0..=j`
/// of `v` and the seed only, so reversed back, each digit of a binary fraction is flipped
/// by a hash of the digits above it, which is Owen's nested uniform scramble.
#[inline(always)]
fn owen_hash(mut v: u32, seed: u32) -> u32 {
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v
}

/// The top 24 bits of a binary fraction as an exact f32 below 1.
#[inline(always)]
fn unit(v: u32) -> f32 {
    (v >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The hashes of dimension `dim` of the sequence of `seed`: the index shuffle's, then
/// one scramble's per axis.
#[inline(always)]
fn dimension_hashes(seed: u64, dim: u32) -> (u32, u32, u32) {
    let a = mix64(seed ^ (dim as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let b = a.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    (a as u32, (a >> 32) as u32, (b >> 32) as u32)
}

/// A dimension's shuffle of the point of bit-reversed index `index_reversed` under hash
/// `h0`, with `rev` reversing words: Owen's scramble of the index as an integer (the
/// high digits flip the low ones), so a power-of-two block of indices maps onto an
/// aligned block of the same size and prefixes keep their net property. Before `rev`,
/// the shuffled index is also the first Sobol dimension's fraction (the van der Corput
/// sequence of 1D).
#[inline(always)]
fn shuffled(index_reversed: u32, h0: u32, rev: impl Fn(u32) -> u32) -> u32 {
    rev(owen_hash(index_reversed, h0))
}

/// One coordinate of a point: the fraction whose digits, bit-reversed, are `digits`,
/// Owen-scrambled under hash `h`.
#[inline(always)]
fn scrambled(digits: u32, h: u32, rev: impl Fn(u32) -> u32) -> f32 {
    unit(rev(owen_hash(digits, h)))
}

/// Dimension `dim` of the point of bit-reversed index `index_reversed` in the sequence
/// of `seed`, drawn as `kind` (a 1D value is `.0`), with `rev` reversing words: the
/// computation behind [`Sobol::next_1d`] and [`Sobol::next_2d`], whose steps
/// [`draw_ahead`] takes one at a time over its lanes (a test holds the two to the same
/// bits).
#[inline(always)]
fn dimension(
    seed: u64,
    index_reversed: u32,
    dim: u32,
    kind: Draw,
    rev: impl Fn(u32) -> u32,
) -> (f32, f32) {
    let (h0, h1, h2) = dimension_hashes(seed, dim);
    let i = shuffled(index_reversed, h0, &rev);
    let first = scrambled(i, h1, &rev);
    match kind {
        Draw::One => (first, 0.0),
        Draw::Two => (first, scrambled(sobol_second(i), h2, &rev)),
    }
}

impl Sobol {
    /// Point `index` of the sequence whose scrambles come from `seed`.
    #[inline(always)]
    pub fn new(seed: u64, index: u32) -> Sobol {
        Sobol {
            seed,
            index_reversed: index.reverse_bits(),
            dim: 0,
            ahead: Ahead::default(),
        }
    }

    /// The next dimension, drawn as `kind`.
    #[inline(always)]
    fn next(&mut self, kind: Draw) -> (f32, f32) {
        let dim = self.dim;
        self.dim += 1;
        match self.ahead.get(dim, kind) {
            Some(v) => v,
            None => dimension(self.seed, self.index_reversed, dim, kind, reverse),
        }
    }

    /// The next 1D dimension: the scrambled van der Corput sequence.
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        self.next(Draw::One).0
    }

    /// The next 2D dimension: the first two Sobol dimensions, each scrambled.
    #[inline(always)]
    pub fn next_2d(&mut self) -> (f32, f32) {
        self.next(Draw::Two)
    }
}

/// Lanes [`draw_ahead`] computes together: a multiple of every vector width.
const AHEAD_LANES: usize = 16;

/// Draws the next dimensions of the Sobol samplers `samplers[i]`, `i` in `which`, ahead
/// of their use, `plan[j]` being what dimension `j` from each one's current will be
/// drawn as; a sampler then gives those values as it would have computed them
/// ([`Sobol::next_1d`], [`Sobol::next_2d`]). The samplers go 16 at a time, each step of
/// a dimension (its hashes, the index's shuffle, the scrambles) a loop over the 16
/// lanes that LLVM turns into vector instructions under the instruction set's entry the
/// wavefront runs in: one at a time, the hashes and bit reversals of a path vertex's
/// five dimensions took 12% of a render (`spheres`), drawn ahead about 3%.
/// Independent samplers and plans longer than [`AHEAD`] are left alone, and so is
/// everything under the x86-64 baseline ([`Isa::Sse`]): SSE2 has no 32-bit lane
/// multiply and no byte shuffle, and drawing ahead there made `spheres` 11% slower.
#[inline(always)]
pub fn draw_ahead(samplers: &mut [Sampler], which: &[usize], plan: &[Draw]) {
    if plan.len() > AHEAD || Isa::in_use() == Isa::Sse {
        return;
    }
    let mut two = 0u32;
    for (j, &kind) in plan.iter().enumerate() {
        two |= u32::from(kind == Draw::Two) << j;
    }
    for group in which.chunks(AHEAD_LANES) {
        let mut seed = [0u64; AHEAD_LANES];
        let mut index = [0u32; AHEAD_LANES];
        let mut dim = [0u32; AHEAD_LANES];
        for (lane, &i) in group.iter().enumerate() {
            if let Sampler::Sobol(s) = &samplers[i] {
                (seed[lane], index[lane], dim[lane]) = (s.seed, s.index_reversed, s.dim);
            }
        }
        // `dimension`'s steps one at a time over the lanes, each a loop that vectorises.
        let mut values = [[(0.0f32, 0.0f32); AHEAD_LANES]; AHEAD];
        for (j, &kind) in plan.iter().enumerate() {
            let (mut h0, mut h1, mut h2) = (
                [0u32; AHEAD_LANES],
                [0u32; AHEAD_LANES],
                [0u32; AHEAD_LANES],
            );
            for lane in 0..AHEAD_LANES {
                (h0[lane], h1[lane], h2[lane]) =
                    dimension_hashes(seed[lane], dim[lane].wrapping_add(j as u32));
            }
            let mut i = [0u32; AHEAD_LANES];
            let mut first = [0.0f32; AHEAD_LANES];
            for lane in 0..AHEAD_LANES {
                i[lane] = shuffled(index[lane], h0[lane], u32::reverse_bits);
                first[lane] = scrambled(i[lane], h1[lane], u32::reverse_bits);
            }
            let mut second = [0.0f32; AHEAD_LANES];
            if kind == Draw::Two {
                for lane in 0..AHEAD_LANES {
                    second[lane] = scrambled(sobol_second(i[lane]), h2[lane], u32::reverse_bits);
                }
            }
            for lane in 0..AHEAD_LANES {
                values[j][lane] = (first[lane], second[lane]);
            }
        }
        for (lane, &i) in group.iter().enumerate() {
            if let Sampler::Sobol(s) = &mut samplers[i] {
                s.ahead.first = s.dim;
                s.ahead.len = plan.len() as u32;
                s.ahead.two = two;
                for (dst, src) in s.ahead.values.iter_mut().zip(&values[..plan.len()]) {
                    *dst = src[lane];
                }
            }
        }
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

    #[test]
    fn sobol_second_is_the_pascal_matrix_mod_2() {
        // Column `i` of the second dimension's matrix is `v[i]` (v[0] = 1/2,
        // v[i] = v[i-1] ^ (v[i-1] >> 1)), bit-reversed; the index's set bits pick them.
        let mut columns = [0u32; 32];
        let mut column = 1u32 << 31;
        for c in &mut columns {
            *c = column.reverse_bits();
            column ^= column >> 1;
        }
        let direct = |i: u32| {
            (0..32)
                .filter(|b| i & (1 << b) != 0)
                .fold(0, |y, b| y ^ columns[b])
        };
        let mut rng = Pcg32::new(21, 0);
        let edges = [0, 1, 2, 3, 0x8000_0000, u32::MAX, 0xaaaa_aaaa, 0x5555_5555];
        let values = edges
            .into_iter()
            .chain((0..32).map(|k| 1u32 << k))
            .chain((0..100_000).map(|_| rng.next_u32()));
        for i in values {
            assert_eq!(sobol_second(i), direct(i), "index {i:#010x}");
        }
    }

    /// A sampler of `kind` for `seed` and `index`, after `skip` draws of one value.
    fn drawn(kind: SamplerKind, seed: u64, index: u32, skip: u32) -> Sampler {
        let mut s = match kind {
            SamplerKind::Sobol => Sampler::Sobol(Sobol::new(seed, index)),
            SamplerKind::Independent => Sampler::Independent(Pcg32::new(seed, index as u64)),
        };
        for _ in 0..skip {
            s.next_1d();
        }
        s
    }

    #[test]
    fn values_drawn_ahead_are_the_values_drawn_one_at_a_time() {
        // Many samplers at different dimensions (some independent, some left out), every
        // plan kind, groups of any size, under every instruction set's entry; then the
        // draws in the plan's order, in another order (computed as usual), and past it.
        use crate::simd::{Isa, scalar_entry};
        let plans: [&[Draw]; 5] = [
            &[Draw::One, Draw::Two, Draw::One, Draw::Two, Draw::One],
            &[
                Draw::Two,
                Draw::One,
                Draw::One,
                Draw::Two,
                Draw::Two,
                Draw::Two,
            ],
            &[Draw::Two],
            &[Draw::One; AHEAD],
            &[],
        ];
        let mut rng = Pcg32::new(99, 1);
        let mut seeds = SplitMixSeeds(0xa4ead);
        for isa in Isa::all_supported() {
            for plan in plans {
                for n in [1usize, 15, 16, 17, 40] {
                    let kinds: Vec<SamplerKind> = (0..n)
                        .map(|k| match k % 7 {
                            3 => SamplerKind::Independent,
                            _ => SamplerKind::Sobol,
                        })
                        .collect();
                    let setup: Vec<(u64, u32, u32)> = (0..n)
                        .map(|k| {
                            let index = match k % 5 {
                                0 => 0,
                                1 => u32::MAX,
                                _ => rng.next_u32() % 4096,
                            };
                            (seeds.next(), index, rng.next_u32() % 40)
                        })
                        .collect();
                    let fresh = || -> Vec<Sampler> {
                        (0..n)
                            .map(|k| {
                                let (seed, index, skip) = setup[k];
                                drawn(kinds[k], seed, index, skip)
                            })
                            .collect()
                    };
                    let mut ahead = fresh();
                    let which: Vec<usize> = (0..n).filter(|k| k % 4 != 2).collect();
                    // Under the baseline nothing is drawn ahead; the rest holds anyway.
                    isa.scope(|| scalar_entry(|| draw_ahead(&mut ahead, &which, plan)))
                        .expect("a supported set");
                    let mut plain = fresh();
                    for k in 0..n {
                        // In the plan's order, then two more draws past it.
                        for &kind in plan.iter().chain(&[Draw::Two, Draw::One]) {
                            let (a, b) = match kind {
                                Draw::One => (ahead[k].next_1d(), plain[k].next_1d()),
                                Draw::Two => {
                                    let (a, b) = (ahead[k].next_2d(), plain[k].next_2d());
                                    assert_eq!(a.1.to_bits(), b.1.to_bits(), "{isa} sampler {k}");
                                    (a.0, b.0)
                                }
                            };
                            assert_eq!(a.to_bits(), b.to_bits(), "{isa} sampler {k} {kind:?}");
                        }
                    }
                    // Drawn against the plan: each kind swapped, computed as usual.
                    let (mut ahead, mut plain) = (fresh(), fresh());
                    draw_ahead(&mut ahead, &which, plan);
                    for k in 0..n {
                        for &kind in plan {
                            match kind {
                                Draw::Two => assert_eq!(ahead[k].next_1d(), plain[k].next_1d()),
                                Draw::One => assert_eq!(ahead[k].next_2d(), plain[k].next_2d()),
                            }
                        }
                    }
                }
            }
        }
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
