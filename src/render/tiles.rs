//! render: tiles. Splits the image into 32x32 tiles rendered in parallel with rayon,
//! samples pixels (no anti-aliasing, full `n x n`, or adaptive) and sums ray counts.
//!
//! Invariants: a pixel's value depends only on the scene, its seed and the pixel, never
//! on the thread count or on which tile computed it: every camera sample draws from its
//! own generator ([`pixel_rng`]), and adaptive anti-aliasing recomputes the signatures of
//! the pixels left of and above a tile instead of waiting for its neighbours.
//!
//! Camera rays are issued as pixel blocks of the mode's packet shape (2x2 in scalar and
//! 4-lane mode, 4x2 at 8 lanes, 4x4 at 16: [`crate::scene::camera::block_shape`], lanes in the
//! order of [`crate::scene::camera::block_pixel`]) through [`shade_block`], and a supersampled
//! pixel's samples through [`supersample`]. Those are the seams where the packet path
//! plugs in: a [`Mode`] selects how they are traced and shaded; everything else here
//! (tiling, adaptive refinement, counting) is shared.

use super::film::Film;
use super::sample::{pixel_rng, sub_pixel_sample};
use super::shade::{HitSignature, RayCounts, Shader};
use super::shade_packet::{shade_block_packet, supersample_packet};
use crate::accel::Accel;
use crate::accel::Mode;
use crate::scene::camera::block_pixel;
use crate::scene::{AntiAlias, CameraFrame, Scene};
use crate::simd::{MAX_LANES, Simd, by_width};
use glam::Vec3;
use rayon::prelude::*;

/// Tile side in pixels: 32x32 pixels are 256 quads, enough work per task for rayon, and
/// a multiple of every packet shape. This only splits the render's work; it is not
/// RAYS.md's 16-pixel tile (`rayset::TILE`), which fixes the order of rays in files and
/// which the renderer never needs.
pub const TILE: u32 = 32;

/// A rectangle of pixels; edge tiles may be smaller than [`TILE`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

/// The tiles covering a `width x height` image, row-major from the top left.
pub fn tiles(width: u32, height: u32) -> Vec<Tile> {
    let mut out = Vec::new();
    for y0 in (0..height).step_by(TILE as usize) {
        for x0 in (0..width).step_by(TILE as usize) {
            out.push(Tile {
                x0,
                y0,
                width: TILE.min(width - x0),
                height: TILE.min(height - y0),
            });
        }
    }
    out
}

/// A finished image and the rays it took.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub film: Film,
    pub counts: RayCounts,
}

/// Renders `scene` at its settings' resolution on the current rayon pool; `progress` is
/// called once per finished tile (from any thread).
pub fn render(
    scene: &Scene,
    accel: &dyn Accel,
    mode: Mode,
    progress: &(dyn Fn() + Sync),
) -> Rendered {
    // Ray tiles are a bench mode for now: the renderer traces their groups as packets.
    let mode = mode.group_mode();
    let (width, height) = (scene.settings.width, scene.settings.height);
    let ctx = TileContext {
        shader: Shader {
            mode,
            ..Shader::new(scene, accel)
        },
        frame: scene.camera.frame(width, height),
        seed: scene.settings.seed,
        mode,
    };
    let tiles = tiles(width, height);
    let done: Vec<(Vec<Vec3>, RayCounts)> = tiles
        .par_iter()
        .map(|tile| {
            let out = ctx.render_tile(tile);
            progress();
            out
        })
        .collect();
    let mut film = Film::new(width, height);
    let mut counts = RayCounts::default();
    for (tile, (pixels, c)) in tiles.iter().zip(done) {
        counts += c;
        for (i, px) in pixels.into_iter().enumerate() {
            let (x, y) = (i as u32 % tile.width, i as u32 / tile.width);
            film.set(tile.x0 + x, tile.y0 + y, px);
        }
    }
    Rendered { film, counts }
}

/// Pixel offsets, in lane order, of the camera block `mode` traces at once: its
/// packet's shape, 2x2 in scalar mode.
pub fn block_offsets(mode: Mode) -> Vec<(u32, u32)> {
    fn of<W: Simd>() -> Vec<(u32, u32)> {
        (0..W::LANES).map(block_pixel::<W>).collect()
    }
    match mode {
        Mode::Tile64 | Mode::Stream => block_offsets(mode.group_mode()),
        _ => by_width!(mode.packet_size(), W => of::<W>()),
    }
}

/// Traces and shades up to one packet of camera samples through pixel centres: usually
/// a block of the mode's shape ([`block_offsets`]), `None` where a lane falls outside
/// the tile. Lane `i`'s result belongs to `pixels[i]`; unused lanes return black with
/// [`HitSignature::MISS`].
pub fn shade_block(
    mode: Mode,
    shader: &Shader,
    frame: &CameraFrame,
    seed: u64,
    pixels: [Option<(u32, u32)>; MAX_LANES],
    counts: &mut RayCounts,
) -> [(Vec3, HitSignature); MAX_LANES] {
    match mode {
        Mode::Scalar => pixels.map(|p| match p {
            Some((x, y)) => centre_sample(shader, frame, seed, x, y, counts),
            None => (Vec3::ZERO, HitSignature::MISS),
        }),
        Mode::Tile64 | Mode::Stream => {
            shade_block(mode.group_mode(), shader, frame, seed, pixels, counts)
        }
        _ => by_width!(mode.packet_size(), W => {
            shade_block_packet::<W>(shader, frame, seed, pixels, counts)
        }),
    }
}

/// The single camera sample through the centre of pixel `(x, y)`, sample index 0.
pub fn centre_sample(
    shader: &Shader,
    frame: &CameraFrame,
    seed: u64,
    x: u32,
    y: u32,
    counts: &mut RayCounts,
) -> (Vec3, HitSignature) {
    let mut rng = pixel_rng(seed, x, y, 0);
    let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
    shader.trace_primary(&ray, &mut rng, counts)
}

/// The mean of `n x n` stratified, jittered samples in pixel `(x, y)`, drawing sample
/// indices `first..first + n*n`.
pub fn supersample(
    shader: &Shader,
    frame: &CameraFrame,
    seed: u64,
    (x, y): (u32, u32),
    n: u32,
    first: u32,
    counts: &mut RayCounts,
) -> Vec3 {
    let n = n.max(1);
    let mut sum = Vec3::ZERO;
    for k in 0..n * n {
        let (ray, mut rng) = sub_pixel_sample(frame, seed, (x, y), n, first, k);
        sum += shader.trace_primary(&ray, &mut rng, counts).0;
    }
    sum / (n * n) as f32
}

struct TileContext<'a> {
    shader: Shader<'a>,
    frame: CameraFrame,
    seed: u64,
    mode: Mode,
}

impl TileContext<'_> {
    /// The tile's pixels, row-major, and the rays they took.
    fn render_tile(&self, tile: &Tile) -> (Vec<Vec3>, RayCounts) {
        let mut counts = RayCounts::default();
        let pixels = match self.shader.scene.settings.antialias {
            AntiAlias::Full(n) => (0..tile.height)
                .flat_map(|y| (0..tile.width).map(move |x| (tile.x0 + x, tile.y0 + y)))
                .map(|p| self.supersample(p, n, 0, &mut counts))
                .collect(),
            AntiAlias::None => self
                .centre_pass(tile, &mut counts)
                .into_iter()
                .map(|(c, _)| c)
                .collect(),
            AntiAlias::Adaptive(n) => self.adaptive(tile, n, &mut counts),
        };
        (pixels, counts)
    }

    /// [`supersample`], or its packet twin in packet mode.
    fn supersample(&self, p: (u32, u32), n: u32, first: u32, counts: &mut RayCounts) -> Vec3 {
        let (shader, frame, seed) = (&self.shader, &self.frame, self.seed);
        match self.mode.group_mode() {
            Mode::Scalar | Mode::Stream => supersample(shader, frame, seed, p, n, first, counts),
            // A group mode is a packet mode.
            m => by_width!(m.packet_size(), W => {
                supersample_packet::<W>(shader, frame, seed, p, n, first, counts)
            }),
        }
    }

    /// One centre sample per pixel of the tile, issued as blocks of the mode's packet
    /// shape; row-major results.
    fn centre_pass(&self, tile: &Tile, counts: &mut RayCounts) -> Vec<(Vec3, HitSignature)> {
        let w = tile.width as usize;
        let mut out = vec![(Vec3::ZERO, HitSignature::MISS); w * tile.height as usize];
        let offsets = block_offsets(self.mode);
        let (bw, bh) = offsets
            .iter()
            .fold((0, 0), |(w, h), &(x, y)| (w.max(x + 1), h.max(y + 1)));
        for qy in (0..tile.height).step_by(bh as usize) {
            for qx in (0..tile.width).step_by(bw as usize) {
                let pixels = std::array::from_fn(|i| {
                    let (dx, dy) = *offsets.get(i)?;
                    let (x, y) = (qx + dx, qy + dy);
                    (x < tile.width && y < tile.height).then_some((tile.x0 + x, tile.y0 + y))
                });
                let shaded = shade_block(
                    self.mode,
                    &self.shader,
                    &self.frame,
                    self.seed,
                    pixels,
                    counts,
                );
                for (p, s) in pixels.iter().zip(shaded) {
                    if let Some((x, y)) = p {
                        out[(y - tile.y0) as usize * w + (x - tile.x0) as usize] = s;
                    }
                }
            }
        }
        out
    }

    /// Signatures of the pixels whose centre samples `pixels` lists, in that order,
    /// traced a packet at a time through the same seam as the tile's own pixels.
    fn signatures(&self, pixels: &[(u32, u32)], counts: &mut RayCounts) -> Vec<HitSignature> {
        let mut out = Vec::with_capacity(pixels.len());
        for chunk in pixels.chunks(self.mode.packet_size().max(4)) {
            let lanes = std::array::from_fn(|i| chunk.get(i).copied());
            let shaded = shade_block(
                self.mode,
                &self.shader,
                &self.frame,
                self.seed,
                lanes,
                counts,
            );
            out.extend(shaded[..chunk.len()].iter().map(|s| s.1));
        }
        out
    }

    /// Adaptive anti-aliasing (tutorial part 3): centre samples everywhere, then `n x n`
    /// samples (indices `1..=n*n`) in each pixel whose signature differs from its left or
    /// upper neighbour's.
    fn adaptive(&self, tile: &Tile, n: u32, counts: &mut RayCounts) -> Vec<Vec3> {
        let centre = self.centre_pass(tile, counts);
        let left: Vec<(u32, u32)> = if tile.x0 > 0 {
            (0..tile.height)
                .map(|y| (tile.x0 - 1, tile.y0 + y))
                .collect()
        } else {
            Vec::new()
        };
        let up: Vec<(u32, u32)> = if tile.y0 > 0 {
            (0..tile.width)
                .map(|x| (tile.x0 + x, tile.y0 - 1))
                .collect()
        } else {
            Vec::new()
        };
        let left_sig = self.signatures(&left, counts);
        let up_sig = self.signatures(&up, counts);
        let w = tile.width as usize;
        let mut pixels = Vec::with_capacity(centre.len());
        for (i, &(colour, sig)) in centre.iter().enumerate() {
            let (x, y) = (i % w, i / w);
            let left = if x > 0 {
                Some(centre[i - 1].1)
            } else {
                left_sig.get(y).copied()
            };
            let upper = if y > 0 {
                Some(centre[i - w].1)
            } else {
                up_sig.get(x).copied()
            };
            let edge = left.is_some_and(|s| s != sig) || upper.is_some_and(|s| s != sig);
            pixels.push(if edge {
                let p = (tile.x0 + x as u32, tile.y0 + y as u32);
                self.supersample(p, n, 1, counts)
            } else {
                colour
            });
        }
        pixels
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image_exactly_once() {
        for (w, h) in [(1, 1), (32, 32), (33, 70), (100, 31), (0, 5)] {
            let mut hits = vec![0u8; (w * h) as usize];
            for t in tiles(w, h) {
                assert!(t.width >= 1 && t.width <= TILE && t.height >= 1 && t.height <= TILE);
                for y in t.y0..t.y0 + t.height {
                    for x in t.x0..t.x0 + t.width {
                        hits[(y * w + x) as usize] += 1;
                    }
                }
            }
            assert!(hits.iter().all(|&c| c == 1), "{w}x{h}");
        }
    }
}
