//! Textures: linear f32 RGB texels with bilinear filtering and wrap-around.
//!
//! Image files are decoded by `image` and converted from sRGB to linear; the procedural
//! textures the classic scenes use (checker, bricks, marble) are generated here, so no
//! texture has to come from elsewhere. Generation is deterministic (seeded hashes).

use super::error::{DecodeError, TextureError};
use glam::Vec3;
use image::{ImageFormat, ImageReader};
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

/// An image in linear RGB, decoded or generated once at load time so that lookups while
/// rendering only read memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Texels per row; at least 1 for any texture that is sampled.
    pub width: u32,
    /// Rows; `texels.len() == width * height`.
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

/// Largest side of a texture, decoded or generated (64 Mi texels at most).
pub const MAX_TEXTURE_SIDE: u32 = 8192;

/// The linear value of an sRGB-encoded channel in `[0, 1]` (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Loads a PNG, TGA or JPEG image (format read from its bytes, not its name) as linear
/// RGB: 8- and 16-bit channels are taken as sRGB-encoded, alpha is dropped. The image's
/// top row becomes `v = 1` and its bottom row `v = 0`, the OBJ convention.
pub fn load(path: &Path) -> Result<Texture, TextureError> {
    let io = |source| TextureError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = File::open(path).map_err(io)?;
    let mut head = Vec::with_capacity(HEAD_LEN);
    (&mut file)
        .take(HEAD_LEN as u64)
        .read_to_end(&mut head)
        .map_err(io)?;
    let format = match sniff(&head) {
        Sniffed::Image(f) => f,
        Sniffed::Empty => {
            return Err(TextureError::Empty {
                path: path.to_path_buf(),
            });
        }
        Sniffed::Unsupported(format) => {
            return Err(TextureError::Unsupported {
                path: path.to_path_buf(),
                format,
            });
        }
        Sniffed::Other(what) => {
            return Err(TextureError::NotAnImage {
                path: path.to_path_buf(),
                what,
            });
        }
    };
    let decode = |source| TextureError::Decode {
        path: path.to_path_buf(),
        format: format_name(format),
        source: DecodeError(source),
    };
    fn reader(file: &mut File, format: ImageFormat) -> ImageReader<BufReader<&mut File>> {
        let mut r = ImageReader::with_format(BufReader::new(file), format);
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(1 << 30);
        r.limits(limits);
        r
    }
    // The header first, so an oversized image is refused by its size before decoding.
    file.rewind().map_err(io)?;
    let (width, height) = reader(&mut file, format)
        .into_dimensions()
        .map_err(decode)?;
    if width == 0 || height == 0 || width > MAX_TEXTURE_SIDE || height > MAX_TEXTURE_SIDE {
        return Err(TextureError::Size {
            path: path.to_path_buf(),
            width,
            height,
            max: MAX_TEXTURE_SIDE,
        });
    }
    file.rewind().map_err(io)?;
    let img = reader(&mut file, format).decode().map_err(decode)?;
    let (width, height) = (img.width(), img.height());
    let rgb = img.into_rgb32f();
    let mut texels = Vec::with_capacity(width as usize * height as usize);
    for row in rgb.as_raw().chunks_exact(3 * width as usize).rev() {
        texels.extend(row.chunks_exact(3).map(|c| {
            Vec3::new(
                srgb_to_linear(c[0]),
                srgb_to_linear(c[1]),
                srgb_to_linear(c[2]),
            )
        }));
    }
    Ok(Texture {
        width,
        height,
        texels,
    })
}

/// Bytes read to tell a file's format: every magic number `image` knows, the 18-byte TGA
/// header, and a line of text to quote.
const HEAD_LEN: usize = 64;

/// What the first bytes of a file say it is.
#[derive(Debug, PartialEq)]
enum Sniffed {
    Image(ImageFormat),
    Empty,
    Unsupported(&'static str),
    Other(String),
}

fn sniff(head: &[u8]) -> Sniffed {
    match image::guess_format(head) {
        Ok(f @ (ImageFormat::Png | ImageFormat::Jpeg)) => Sniffed::Image(f),
        Ok(f) => Sniffed::Unsupported(format_name(f)),
        Err(_) if head.is_empty() => Sniffed::Empty,
        Err(_) if is_tga_header(head) => Sniffed::Image(ImageFormat::Tga),
        Err(_) => Sniffed::Other(describe(head)),
    }
}

/// TGA has no magic number; its header is recognised by values only a TGA file has
/// together: colour-map type 0 or 1, a known image type, non-zero sides and a valid pixel
/// depth (Truevision TGA 2.0 specification, fields 2, 3, 5.3, 5.4 and 5.5).
fn is_tga_header(h: &[u8]) -> bool {
    let colour_map = match h.get(1) {
        // No colour map: its specification is zero and the image is not colour-mapped.
        Some(0) => h[3..8.min(h.len())].iter().all(|&b| b == 0) && !matches!(h[2], 1 | 9),
        Some(1) => h.len() > 7 && matches!(h[7], 15 | 16 | 24 | 32),
        _ => false,
    };
    h.len() >= 18
        && colour_map
        && matches!(h[2], 1 | 2 | 3 | 9 | 10 | 11)
        && u16::from_le_bytes([h[12], h[13]]) > 0
        && u16::from_le_bytes([h[14], h[15]]) > 0
        && matches!(h[16], 8 | 15 | 16 | 24 | 32)
        && h[17] & 0xc0 == 0
}

/// What a file that is not an image looks like, for the error message.
fn describe(head: &[u8]) -> String {
    const KNOWN: [(&[u8], &str); 5] = [
        (b"%PDF", "a PDF document"),
        (b"PK\x03\x04", "a ZIP archive"),
        (b"\x1f\x8b", "gzip-compressed data"),
        (b"\x7fELF", "an ELF executable"),
        (b"\xef\xbb\xbf", "text with a byte-order mark"),
    ];
    if let Some((_, what)) = KNOWN.iter().find(|(magic, _)| head.starts_with(magic)) {
        return what.to_string();
    }
    // A multi-byte character cut by the end of `head` is still text.
    let text = match std::str::from_utf8(head) {
        Ok(t) => Some(t),
        Err(e) if e.error_len().is_none() => std::str::from_utf8(&head[..e.valid_up_to()]).ok(),
        Err(_) => None,
    };
    match text {
        Some(t)
            if !t
                .chars()
                .any(|c| c.is_control() && !c.is_ascii_whitespace()) =>
        {
            let line = t.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
            let quote: String = line.trim().chars().take(40).collect();
            format!("text (`{}`)", quote.escape_debug())
        }
        _ => {
            let hex: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
            format!("unrecognised data (first bytes {})", hex.join(" "))
        }
    }
}

/// The usual name of an image format, for messages.
fn format_name(f: ImageFormat) -> &'static str {
    match f {
        ImageFormat::Png => "PNG",
        ImageFormat::Jpeg => "JPEG",
        ImageFormat::Tga => "TGA",
        ImageFormat::Gif => "GIF",
        ImageFormat::WebP => "WebP",
        ImageFormat::Tiff => "TIFF",
        ImageFormat::Bmp => "BMP",
        ImageFormat::Ico => "ICO",
        ImageFormat::Hdr => "Radiance HDR",
        ImageFormat::OpenExr => "OpenEXR",
        ImageFormat::Avif => "AVIF",
        ImageFormat::Qoi => "QOI",
        ImageFormat::Pnm => "PNM",
        ImageFormat::Dds => "DDS",
        ImageFormat::Farbfeld => "farbfeld",
        _ => "an unsupported",
    }
}

impl Texture {
    /// A texture of `width x height` texels whose texel `(x, y)` is `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, f: impl Fn(u32, u32) -> Vec3) -> Texture {
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                texels.push(f(x, y));
            }
        }
        Texture {
            width,
            height,
            texels,
        }
    }
}

/// A texture that raypack generates itself, with its parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum Procedural {
    /// `squares x squares` alternating squares of `a` and `b`, `a` at texel (0, 0).
    /// Tiles seamlessly when `squares` is even.
    Checker {
        /// Squares along each side.
        squares: u32,
        /// Colour of the square at texel (0, 0) and its diagonal neighbours.
        a: Vec3,
        /// Colour of the other squares.
        b: Vec3,
    },
    /// A running-bond brick wall: `rows` courses of `columns` bricks, every other course
    /// shifted by half a brick, joints `mortar` (a fraction of a course's height) wide.
    /// Bricks vary slightly in shade, from `seed`. Tiles seamlessly.
    Bricks {
        /// Courses of bricks from bottom to top.
        rows: u32,
        /// Bricks per course.
        columns: u32,
        /// Joint width as a fraction of a course's height, in `[0, 0.5]`.
        mortar: f32,
        /// Mean colour of a brick; each brick's shade varies around it.
        brick: Vec3,
        /// Colour of the joints.
        mortar_color: Vec3,
        /// Chooses the shade of every brick.
        seed: u32,
    },
    /// Marble: `a` with veins of `b` running along v, bent by `turbulence` times a sum of
    /// periodic value noise of base frequency `scale` (so the texture tiles).
    Marble {
        /// Veins across the texture, and the noise's base frequency.
        scale: u32,
        /// How far the noise bends the veins; 0 gives straight stripes.
        turbulence: f32,
        /// Colour of the stone.
        a: Vec3,
        /// Colour of the veins.
        b: Vec3,
        /// Chooses the noise.
        seed: u32,
    },
}

impl Procedural {
    /// The texture at `width x height` texels (both at least 1).
    pub fn generate(&self, width: u32, height: u32) -> Texture {
        match *self {
            Procedural::Checker { squares, a, b } => Texture::from_fn(width, height, |x, y| {
                let i = x as u64 * squares as u64 / width as u64;
                let j = y as u64 * squares as u64 / height as u64;
                if (i + j).is_multiple_of(2) { a } else { b }
            }),
            Procedural::Bricks {
                rows,
                columns,
                mortar,
                brick,
                mortar_color,
                seed,
            } => Texture::from_fn(width, height, |x, y| {
                let fy = (y as f32 + 0.5) / height as f32 * rows as f32;
                let row = fy.floor() as u32;
                let shift = if row % 2 == 1 { 0.5 } else { 0.0 };
                let fx =
                    ((x as f32 + 0.5) / width as f32 * columns as f32 + shift) % columns as f32;
                let col = fx.floor() as u32 % columns;
                let (ux, uy) = (fx - fx.floor(), fy - fy.floor());
                // Joints as wide across as they are high, in texels.
                let mx = mortar * (height as f32 / rows as f32) / (width as f32 / columns as f32);
                if uy < mortar || ux < mx {
                    mortar_color
                } else {
                    brick * (0.85 + 0.3 * hash01(seed, row, col))
                }
            }),
            Procedural::Marble {
                scale,
                turbulence,
                a,
                b,
                seed,
            } => Texture::from_fn(width, height, |x, y| {
                let (u, v) = (x as f32 / width as f32, y as f32 / height as f32);
                let mut noise = 0.0;
                let mut amplitude = 0.5;
                let mut period = scale.max(1);
                for octave in 0..5 {
                    noise += amplitude * value_noise(seed.wrapping_add(octave), period, u, v);
                    amplitude *= 0.5;
                    period = period.saturating_mul(2);
                }
                let phase = (u * scale.max(1) as f32 + turbulence * noise) * std::f32::consts::TAU;
                let t = 0.5 + 0.5 * phase.sin();
                a + (b - a) * t.powf(3.0)
            }),
        }
    }
}

/// A deterministic pseudo-random number in `[0, 1)` for lattice point `(i, j)`.
fn hash01(seed: u32, i: u32, j: u32) -> f32 {
    let mut h = seed
        .wrapping_mul(0x9E37_79B9)
        .wrapping_add(i.wrapping_mul(0x85EB_CA6B))
        ^ j.wrapping_mul(0xC2B2_AE35);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^= h >> 16;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Smoothly interpolated lattice noise in `[0, 1)` on `[0, 1)^2` with `period` cells per
/// side, wrapping at the edges.
fn value_noise(seed: u32, period: u32, u: f32, v: f32) -> f32 {
    let (x, y) = (u * period as f32, v * period as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (i, j) = (x0 as u32 % period, y0 as u32 % period);
    let (i1, j1) = ((i + 1) % period, (j + 1) % period);
    let top = hash01(seed, i, j) * (1.0 - sx) + hash01(seed, i1, j) * sx;
    let bottom = hash01(seed, i, j1) * (1.0 - sx) + hash01(seed, i1, j1) * sx;
    top * (1.0 - sy) + bottom * sy
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bytes` written to a fresh temporary file called `name`.
    fn temp_file(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("raypack-sniff-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    fn png_bytes(img: &image::RgbImage) -> Vec<u8> {
        let mut bytes = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut bytes), ImageFormat::Png)
            .unwrap();
        bytes
    }

    /// An uncompressed true-colour TGA of `w x h` BGR texels, rows from the top.
    fn tga_bytes(w: u16, h: u16, bgr: &[u8]) -> Vec<u8> {
        let mut b = vec![0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        b.extend_from_slice(&w.to_le_bytes());
        b.extend_from_slice(&h.to_le_bytes());
        b.extend_from_slice(&[24, 0x20]);
        b.extend_from_slice(bgr);
        b
    }

    #[test]
    fn the_format_comes_from_the_bytes_not_the_name() {
        let red = image::RgbImage::from_raw(1, 1, vec![255, 0, 0]).unwrap();
        let t = load(&temp_file("red.jpg", &png_bytes(&red))).unwrap();
        assert_eq!(t.texels, vec![Vec3::X], "a PNG named .jpg");
        let t = load(&temp_file(
            "green.png",
            &tga_bytes(2, 1, &[0, 255, 0, 0, 255, 0]),
        ))
        .unwrap();
        assert_eq!(t.texels, vec![Vec3::Y; 2], "a TGA named .png");
        let t = load(&temp_file("blue", &tga_bytes(1, 1, &[255, 0, 0]))).unwrap();
        assert_eq!(t.texels, vec![Vec3::Z], "a TGA without extension");
    }

    #[test]
    fn non_images_are_named_for_what_they_are() {
        assert_eq!(sniff(b""), Sniffed::Empty);
        assert_eq!(sniff(b"GIF89a\x01\x00"), Sniffed::Unsupported("GIF"));
        assert_eq!(
            sniff(b"\x76\x2f\x31\x01...."),
            Sniffed::Unsupported("OpenEXR")
        );
        assert_eq!(
            sniff(b"%PDF-1.7\n"),
            Sniffed::Other("a PDF document".into())
        );
        assert_eq!(
            sniff(b"\n\n  v 1 0 0\nv 0 1 0\n"),
            Sniffed::Other("text (`v 1 0 0`)".into())
        );
        // A character cut by the end of the sniffed bytes is still text.
        assert_eq!(
            sniff("caf\u{e9}".as_bytes().split_last().unwrap().1),
            Sniffed::Other("text (`caf`)".into())
        );
        let counting: Vec<u8> = (0..40).collect();
        assert_eq!(
            sniff(&counting),
            Sniffed::Other("unrecognised data (first bytes 00 01 02 03 04 05 06 07)".into())
        );
        assert_eq!(
            sniff(&tga_bytes(1, 1, &[0; 3])),
            Sniffed::Image(ImageFormat::Tga)
        );
        let mut mapped_without_map = tga_bytes(1, 1, &[0; 3]);
        mapped_without_map[2] = 9;
        assert!(matches!(sniff(&mapped_without_map), Sniffed::Other(_)));
    }

    #[test]
    fn png_is_decoded_to_linear_with_the_top_row_at_v_1() {
        let path = std::env::temp_dir().join(format!("raypack-tex-{}.png", std::process::id()));
        // Top pixel white, bottom pixel sRGB 128.
        let img = image::RgbImage::from_raw(1, 2, vec![255, 255, 255, 128, 128, 128]).unwrap();
        img.save(&path).unwrap();
        let t = load(&path).unwrap();
        assert_eq!((t.width, t.height), (1, 2));
        let grey = srgb_to_linear(128.0 / 255.0);
        assert!((grey - 0.21586).abs() < 1e-4, "{grey}");
        assert_eq!(t.texels[0], Vec3::splat(grey));
        assert_eq!(t.texels[1], Vec3::ONE);
    }

    #[test]
    fn tga_and_jpeg_load_and_the_format_comes_from_the_bytes() {
        let dir = std::env::temp_dir();
        let img = image::RgbImage::from_fn(8, 4, |x, _| image::Rgb([x as u8 * 30, 200, 0]));
        let id = std::process::id();
        let tga = dir.join(format!("raypack-tex-{id}.tga"));
        img.save(&tga).unwrap();
        let t = load(&tga).unwrap();
        assert_eq!((t.width, t.height), (8, 4));
        assert_eq!(
            t.texels[3],
            Vec3::new(
                srgb_to_linear(90.0 / 255.0),
                srgb_to_linear(200.0 / 255.0),
                0.0
            )
        );
        let jpg = dir.join(format!("raypack-tex-{id}.jpg"));
        img.save(&jpg).unwrap();
        let j = load(&jpg).unwrap();
        assert_eq!((j.width, j.height), (8, 4));
        assert!((j.texels[0].y - srgb_to_linear(200.0 / 255.0)).abs() < 0.05);
        // PNG bytes under a .jpg name still decode as PNG.
        let misnamed = dir.join(format!("raypack-tex-{id}-png.jpg"));
        img.save_with_format(&misnamed, image::ImageFormat::Png)
            .unwrap();
        assert_eq!(load(&misnamed).unwrap(), load(&tga).unwrap());
    }

    #[test]
    fn srgb_curve_is_continuous_and_fixes_the_ends() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        let below = srgb_to_linear(0.04045);
        let above = srgb_to_linear(0.040451);
        assert!((above - below).abs() < 1e-5);
    }

    #[test]
    fn checker_alternates_squares() {
        let (a, b) = (Vec3::ONE, Vec3::ZERO);
        let t = Procedural::Checker { squares: 4, a, b }.generate(8, 8);
        assert_eq!(t.texels[0], a);
        assert_eq!(t.texels[1], a);
        assert_eq!(t.texels[2], b);
        assert_eq!(t.texels[2 * 8], b);
        assert_eq!(t.texels[2 * 8 + 2], a);
    }

    #[test]
    fn generated_textures_are_deterministic_and_bounded() {
        let kinds = [
            Procedural::Bricks {
                rows: 8,
                columns: 4,
                mortar: 0.1,
                brick: Vec3::new(0.6, 0.2, 0.1),
                mortar_color: Vec3::splat(0.7),
                seed: 5,
            },
            Procedural::Marble {
                scale: 4,
                turbulence: 3.0,
                a: Vec3::splat(0.9),
                b: Vec3::splat(0.2),
                seed: 9,
            },
        ];
        for k in &kinds {
            let t = k.generate(64, 32);
            assert_eq!(t, k.generate(64, 32));
            assert_eq!(t.texels.len(), 64 * 32);
            assert!(
                t.texels
                    .iter()
                    .all(|c| c.is_finite() && c.min_element() >= 0.0)
            );
            let first = t.texels[0];
            assert!(t.texels.iter().any(|&c| c != first), "{k:?} is flat");
        }
    }
}
