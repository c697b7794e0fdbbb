//! The look-at pinhole camera, with exactly the convention of RAYS.md.

use crate::ray::Ray;
use crate::simd::Simd;
use glam::{DVec3, Vec3};

/// Width and height of the pixel block a camera packet of `W` covers: 2x2 quads, two
/// to a row (2x2 at 4 lanes, 4x2 at 8, 4x4 at 16). The one place a packet's shape is
/// derived from its size.
pub const fn block_shape<W: Simd>() -> (u32, u32) {
    let quads = W::LANES as u32 / 4;
    let per_row = if quads >= 2 { 2 } else { 1 };
    (2 * per_row, 2 * (quads / per_row))
}

/// Pixel offset of lane `i` of a `W` camera packet inside its [`block_shape`] block: 2x2
/// quads row-major inside the block, each quad in RAYS.md's lane order ((0,0), (1,0),
/// (0,1), (1,1)). So lanes 0..4 are always a 2x2 quad and lanes 0..8 a 4x2 block, as
/// any 4 or 8 consecutive rays of an image set in RAYS.md's packet order.
#[inline(always)]
pub fn block_pixel<W: Simd>(i: usize) -> (u32, u32) {
    let quads_per_row = block_shape::<W>().0 as usize / 2;
    let (q, (dx, dy)) = (i / 4, quad_lane(i));
    (
        (q % quads_per_row) as u32 * 2 + dx,
        (q / quads_per_row) as u32 * 2 + dy,
    )
}

/// Pixel offset of lane `i % 4` inside its 2x2 quad, in RAYS.md's order: (0,0), (1,0),
/// (0,1), (1,1). The one definition of the quad, for packets and ray files alike.
#[inline(always)]
pub fn quad_lane(i: usize) -> (u32, u32) {
    let p = (i % 4) as u32;
    (p & 1, p >> 1)
}

/// A pinhole camera at `eye` looking at `target`, as a scene file or a benchmark's
/// `cameras.toml` gives it; [`Camera::frame`] turns it into an orthonormal basis.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Where every primary ray starts.
    pub eye: Vec3,
    /// The point at the image centre; must differ from `eye`.
    pub target: Vec3,
    /// A hint for the image's up direction: only its component perpendicular to the
    /// view direction counts, so it must not be parallel to `target - eye`.
    pub up: Vec3,
    /// Vertical field of view in degrees, edge to edge of the image.
    pub vfov_deg: f32,
}

/// A look-at pinhole camera in f64, as the numbers are written in cameras.toml
/// (RAYS.md): the standard ray sets and the benchmark scenes are made from it in f64, and
/// [`Camera`] is its f32 form for rendering.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Where every primary ray starts.
    pub eye: DVec3,
    /// The point at the image centre.
    pub target: DVec3,
    /// A hint for the image's up direction (see [`Camera::up`]).
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub vfov_deg: f64,
}

impl From<&Camera> for View {
    fn from(c: &Camera) -> View {
        View {
            eye: c.eye.as_dvec3(),
            target: c.target.as_dvec3(),
            up: c.up.as_dvec3(),
            vfov_deg: c.vfov_deg as f64,
        }
    }
}

impl From<&View> for Camera {
    fn from(v: &View) -> Camera {
        Camera {
            eye: v.eye.as_vec3(),
            target: v.target.as_vec3(),
            up: v.up.as_vec3(),
            vfov_deg: v.vfov_deg as f32,
        }
    }
}

/// A camera prepared for one image size.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    /// Origin of every ray.
    pub eye: Vec3,
    /// Unit vector from `eye` towards the target: the direction of the image centre.
    pub forward: Vec3,
    /// Unit vector towards the image's right edge, `normalize(forward x up)`.
    pub right: Vec3,
    /// Unit vector towards the image's top edge, `right x forward` (exactly
    /// perpendicular to both, unlike the camera's `up` hint).
    pub up: Vec3,
    /// `tan(vfov / 2)`.
    pub h: f32,
    /// Image width in pixels; with `height` it sets the aspect ratio.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// The basis of RAYS.md: `right = normalize(forward x up)`, `up' = right x forward`.
    pub fn frame(&self, width: u32, height: u32) -> CameraFrame {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        let h = (self.vfov_deg.to_radians() / 2.0).tan();
        CameraFrame {
            eye: self.eye,
            forward,
            right,
            up,
            h,
            width,
            height,
        }
    }
}

impl CameraFrame {
    /// The camera rays of the [`block_shape`] pixel block whose top-left pixel is `(x, y)`,
    /// ray `i` (a packet's lane `i`) through the centre of pixel `(x, y) +
    /// block_pixel(i)`: for 4 lanes RAYS.md's quad, `(x, y)`, `(x + 1, y)`, `(x, y + 1)`,
    /// `(x + 1, y + 1)`.
    pub fn block_rays<W: Simd>(&self, x: u32, y: u32) -> Vec<Ray> {
        (0..W::LANES)
            .map(|i| {
                let (dx, dy) = block_pixel::<W>(i);
                self.ray((x + dx) as f32 + 0.5, (y + dy) as f32 + 0.5)
            })
            .collect()
    }

    /// The ray through film position `(x, y)` in pixels (pixel `(i, j)`'s centre is
    /// `(i + 0.5, j + 0.5)`; y = 0 is the top row).
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let (w, h) = (self.width as f32, self.height as f32);
        let ndc_x = (x / w * 2.0 - 1.0) * self.h * w / h;
        let ndc_y = (1.0 - y / h * 2.0) * self.h;
        let dir = (self.forward + self.right * ndc_x + self.up * ndc_y).normalize();
        Ray::new(self.eye, dir, 0.0, f32::INFINITY)
    }

    /// Where the ray toward point `p` crosses the film, `(x, y)` in pixels as
    /// [`CameraFrame::ray`] takes them, with the film's importance along it: the inverse
    /// of `ray`. `None` when `p` lies behind the eye or outside the image.
    ///
    /// The importance `1 / (A cos^3)`, `A` a pixel's area on a film one unit from the eye
    /// and `cos` the cosine between the ray and the view direction, turns radiance
    /// arriving at the eye into the mean over a pixel that [`CameraFrame::ray`]'s uniform
    /// positions estimate: a pixel covers `A / cos^3` of solid angle at that angle.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if !(z > 0.0) {
            return None;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let ndc_x = d.dot(self.right) / z;
        let ndc_y = d.dot(self.up) / z;
        let x = (ndc_x / (self.h * w / h) + 1.0) * 0.5 * w;
        let y = (1.0 - ndc_y / self.h) * 0.5 * h;
        if !(x >= 0.0 && x < w && y >= 0.0 && y < h) {
            return None;
        }
        let side = 2.0 * self.h / h;
        let cos = z / d.length();
        Some((x, y, 1.0 / (side * side * cos * cos * cos)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{W4, W8, W16};

    fn blocks_cover_their_shape<W: Simd>() {
        let (w, h) = block_shape::<W>();
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

    /// The shape depends on the width alone, so the portable backends cover every
    /// instruction set's.
    #[test]
    fn packet_shapes_cover_each_pixel_once() {
        blocks_cover_their_shape::<W4>();
        blocks_cover_their_shape::<W8>();
        blocks_cover_their_shape::<W16>();
        assert_eq!(
            [
                block_shape::<W4>(),
                block_shape::<W8>(),
                block_shape::<W16>()
            ],
            [(2, 2), (4, 2), (4, 4)]
        );
        assert_eq!(block_pixel::<W8>(4), (2, 0));
        assert_eq!(block_pixel::<W16>(8), (0, 2));
    }

    /// `project` inverts `ray`, and its importance integrates to one over a pixel: the
    /// solid angle of pixel `(i, j)`, summed from small patches of its film area, times
    /// the importance at its centre, is 1 up to the importance's change over the pixel.
    #[test]
    fn project_inverts_ray_and_its_importance_covers_a_pixel() {
        let cam = Camera {
            eye: Vec3::new(1.0, 2.0, 3.0),
            target: Vec3::new(4.0, 1.5, -2.0),
            up: Vec3::Y,
            vfov_deg: 50.0,
        };
        let f = cam.frame(64, 48);
        for &(x, y) in &[(0.25f32, 0.5f32), (32.0, 24.0), (63.75, 47.5), (10.3, 40.9)] {
            let r = f.ray(x, y);
            let (px, py, _) = f.project(r.org + r.dir * 7.0).unwrap();
            assert!(
                (px - x).abs() < 1e-3 && (py - y).abs() < 1e-3,
                "{x},{y}: {px},{py}"
            );
        }
        assert!(f.project(f.eye - f.forward).is_none());
        assert!(f.project(f.ray(-0.5, 3.0).dir + f.eye).is_none());
        for &(i, j) in &[(0u32, 0u32), (31, 23), (63, 5)] {
            let n = 64;
            let mut solid = 0.0f64;
            for a in 0..n {
                for b in 0..n {
                    let (x0, y0) = (
                        i as f32 + a as f32 / n as f32,
                        j as f32 + b as f32 / n as f32,
                    );
                    let s = 1.0 / n as f32;
                    let c = |x: f32, y: f32| f.ray(x, y).dir;
                    // The patch's solid angle: two triangles of unit directions.
                    let (p, q, r, t) = (c(x0, y0), c(x0 + s, y0), c(x0, y0 + s), c(x0 + s, y0 + s));
                    solid += 0.5
                        * ((q - p).cross(r - p).length() + (q - t).cross(r - t).length()) as f64;
                }
            }
            let centre = f.ray(i as f32 + 0.5, j as f32 + 0.5);
            let (_, _, importance) = f.project(centre.org + centre.dir).unwrap();
            let total = solid * importance as f64;
            assert!((total - 1.0).abs() < 2e-3, "pixel ({i}, {j}): {total}");
        }
    }

    #[test]
    fn centre_pixel_looks_at_target_and_top_row_looks_up() {
        let cam = Camera {
            eye: Vec3::ZERO,
            target: Vec3::new(0.0, 0.0, -1.0),
            up: Vec3::Y,
            vfov_deg: 90.0,
        };
        let f = cam.frame(4, 2);
        let c = f.ray(2.0, 1.0);
        assert!((c.dir - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        assert!(f.ray(2.0, 0.0).dir.y > 0.0);
        assert!(f.ray(4.0, 1.0).dir.x > 0.0, "x grows to the right");
        // At the top edge with vfov 90, the direction is 45 degrees up.
        let top = f.ray(2.0, 0.0).dir;
        assert!((top.y - top.z.abs()).abs() < 1e-6);
    }
}
