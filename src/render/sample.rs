//! render: sampling. The random numbers, bases and sample patterns of the Monte Carlo
//! parts of the Whitted tracer (tutorial parts 5 and 6): area-light positions on a
//! stratified 4x4 grid, glossy directions in a cone around the mirror direction.
//!
//! Invariants: every generator is seeded from the scene seed, the pixel and the sample
//! index only ([`pixel_rng`]), so an image never depends on the number of threads or on
//! the order tiles are rendered in. The orthonormal basis is that of Duff et al.,
//! "Building an Orthonormal Basis, Revisited" (JCGT 2017): branch-free except for the
//! sign of `n.z`, and exact for `n = ±z`.

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

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in `[0, 1)`: the top 24 bits, so every value is exact and below 1.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// SplitMix64's finaliser: spreads neighbouring integers over all 64 bits.
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The generator of sample `sample` of pixel `(x, y)` under scene seed `seed`. Pixels
/// and samples get independent streams, so rendering them in any order on any number of
/// threads gives the same numbers.
pub fn pixel_rng(seed: u64, x: u32, y: u32, sample: u32) -> Pcg32 {
    let pixel = ((y as u64) << 32) | x as u64;
    Pcg32::new(mix64(seed ^ mix64(pixel)), sample as u64)
}

/// A right-handed orthonormal basis `(u, v, w)` with `w` the given unit vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Onb {
    pub u: Vec3,
    pub v: Vec3,
    pub w: Vec3,
}

impl Onb {
    /// Duff et al. 2017, listing 3. `w` must be unit length.
    pub fn from_w(w: Vec3) -> Onb {
        let sign = 1.0f32.copysign(w.z);
        let a = -1.0 / (sign + w.z);
        let b = w.x * w.y * a;
        let u = Vec3::new(1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x);
        let v = Vec3::new(b, sign + w.y * w.y * a, -w.y);
        Onb { u, v, w }
    }

    /// `local.x * u + local.y * v + local.z * w`.
    pub fn to_world(&self, local: Vec3) -> Vec3 {
        self.u * local.x + self.v * local.y + self.w * local.z
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
    fn pcg32_matches_the_reference_sequence() {
        // pcg32-global-demo with seed 42, sequence 54 prints these first values.
        let mut rng = Pcg32::new(42, 54);
        let got: Vec<u32> = (0..6).map(|_| rng.next_u32()).collect();
        assert_eq!(
            got,
            [
                0xa15c02b7, 0x7b47f409, 0xba1d3330, 0x83d2f293, 0xbfa4784b, 0xcbed606e
            ]
        );
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
    fn onb_is_orthonormal_and_right_handed() {
        let mut rng = Pcg32::new(1, 2);
        let mut ws: Vec<Vec3> = (0..2000).map(|_| random_unit(&mut rng)).collect();
        ws.extend([Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z]);
        ws.push(Vec3::new(1.0, 0.0, -0.0));
        for w in ws {
            let b = Onb::from_w(w);
            for (a, name) in [(b.u, "u"), (b.v, "v"), (b.w, "w")] {
                assert!((a.length() - 1.0).abs() < 1e-5, "{name} of {w} not unit");
            }
            assert!(b.u.dot(b.v).abs() < 1e-5, "u.v for {w}");
            assert!(b.u.dot(b.w).abs() < 1e-5, "u.w for {w}");
            assert!(b.v.dot(b.w).abs() < 1e-5, "v.w for {w}");
            assert!((b.u.cross(b.v) - b.w).length() < 1e-5, "handedness for {w}");
            let p = Vec3::new(0.3, -0.2, 0.9);
            let q = b.to_world(p);
            assert!((Vec3::new(q.dot(b.u), q.dot(b.v), q.dot(b.w)) - p).length() < 1e-5);
        }
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
