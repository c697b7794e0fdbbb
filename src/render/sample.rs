//! render: sampling. The random numbers, bases and sample patterns of the Monte Carlo
//! parts of the Whitted tracer (tutorial parts 3, 5 and 6): jittered sub-pixel camera
//! samples, area-light positions on a stratified 4x4 grid, glossy directions in a cone
//! around the mirror direction.
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
