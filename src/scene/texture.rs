//! Textures: linear f32 RGB texels with bilinear filtering and wrap-around.

use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at `v = 0`.
    pub texels: Vec<Vec3>,
}

impl Texture {
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width as usize + x]
    }

    /// Bilinear lookup with wrap-around in both directions. Texel `(i, j)` has its centre at
    /// `((i + 0.5) / width, (j + 0.5) / height)`, so a lookup there returns it exactly.
    pub fn sample(&self, u: f32, v: f32) -> Vec3 {
        if !(u.is_finite() && v.is_finite()) || self.texels.is_empty() {
            return Vec3::ZERO;
        }
        // Reduce first so huge coordinates keep their fraction.
        let x = u.rem_euclid(1.0) * self.width as f32 - 0.5;
        let y = v.rem_euclid(1.0) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0) * (1.0 - fx) + self.texel(x0 + 1, y0) * fx;
        let bottom = self.texel(x0, y0 + 1) * (1.0 - fx) + self.texel(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}
