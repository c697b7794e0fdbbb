//! render: the film. Linear RGB pixels, written as 8-bit sRGB PNG, as PFM (32-bit floats,
//! bit-exact, for comparisons between renders) or as OpenEXR (32-bit float or 16-bit
//! half RGB, for HDR tools).
//!
//! Tone mapping applies to PNG only: each linear value is multiplied by
//! `2^exposure` (exposure 0 by default), clamped to `[0, 1]` and encoded with the sRGB
//! transfer function. PFM and EXR keep the linear radiance as rendered.
//!
//! Invariant: a file is written whole or not at all. Bytes go to a temporary file in the
//! target's directory, which is then renamed over the target; on error it is removed.

use crate::output::write_atomic;
use glam::Vec3;
use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// What can go wrong writing or reading a film. The underlying error is the `source`,
/// never part of the message, so a chain printed with `{:#}` names it once.
#[derive(Debug, thiserror::Error)]
pub enum FilmError {
    #[error("{}: cannot read the image", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: cannot write the image", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: PNG encoding failed", path.display())]
    Png {
        path: PathBuf,
        source: image::ImageError,
    },
    #[error("{}: OpenEXR encoding failed", path.display())]
    Exr {
        path: PathBuf,
        source: exr::error::Error,
    },
    #[error("{}: not a colour PFM file: {reason}", path.display())]
    BadPfm { path: PathBuf, reason: String },
    #[error("{}: unknown image format (the name must end in .png, .pfm or .exr)", path.display())]
    UnknownFormat { path: PathBuf },
}

/// The image formats a film is written in, chosen by the output's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB.
    Png,
    /// 32-bit float, bit-exact.
    Pfm,
    /// OpenEXR, RGB in 32-bit float or 16-bit half ([`WriteOptions::exr_half`]).
    Exr,
}

impl ImageFormat {
    /// The format named by `path`'s extension (`.png`, `.pfm` or `.exr`, any case), or
    /// `None`: writing PNG bytes under any other name (`.jpg`) would mislabel the file.
    pub fn from_path(path: &Path) -> Option<ImageFormat> {
        let ext = path.extension()?;
        [
            ("png", ImageFormat::Png),
            ("pfm", ImageFormat::Pfm),
            ("exr", ImageFormat::Exr),
        ]
        .into_iter()
        .find(|(name, _)| ext.eq_ignore_ascii_case(name))
        .map(|(_, format)| format)
    }
}

/// How a film is encoded beyond its format.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WriteOptions {
    /// PNG only: values are scaled by `2^exposure` before the clamp to `[0, 1]`.
    pub exposure: f32,
    /// EXR only: 16-bit half floats instead of 32-bit floats.
    pub exr_half: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            exposure: 0.0,
            exr_half: false,
        }
    }
}

/// A `width x height` image of linear RGB, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

/// The sRGB transfer function of IEC 61966-2-1, on a value clamped to `[0, 1]`.
pub fn linear_to_srgb8(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

impl Film {
    /// A black film.
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    #[inline]
    pub fn set(&mut self, x: u32, y: u32, c: Vec3) {
        self.pixels[y as usize * self.width as usize + x as usize] = c;
    }

    /// The image's bright end: the 99th percentile of its pixels' largest channel (NaN
    /// pixels count as black). A few hot pixels do not lift it, a lit scene reaches
    /// about 1.
    pub fn bright_end(&self) -> f32 {
        let mut v: Vec<f32> = self
            .pixels
            .iter()
            .map(|c| c.max_element())
            .map(|m| if m.is_nan() { 0.0 } else { m })
            .collect();
        if v.is_empty() {
            return 0.0;
        }
        let k = (v.len() - 1) * 99 / 100;
        *v.select_nth_unstable_by(k, f32::total_cmp).1
    }

    /// The whole `--exposure` (EV) that brings a dark image's [`Film::bright_end`] to
    /// between 0.5 and 1 of white, with that bright end, when it sits below a quarter of
    /// white; `None` for an image bright enough, or black (nothing to expose).
    pub fn exposure_hint(&self) -> Option<(f32, f32)> {
        let bright = self.bright_end();
        (bright > 0.0 && bright < 0.25).then(|| ((1.0 / bright).log2().floor(), bright))
    }

    /// 8-bit sRGB, row-major from the top, 3 bytes per pixel, after scaling by
    /// `2^exposure` (exposure 0 multiplies by exactly 1).
    pub fn to_srgb8(&self, exposure: f32) -> Vec<u8> {
        let scale = exposure.exp2();
        self.pixels
            .iter()
            .flat_map(|c| [c.x, c.y, c.z].map(|v| linear_to_srgb8(v * scale)))
            .collect()
    }

    /// [`Film::write_with`] the default options.
    pub fn write(&self, path: &Path) -> Result<(), FilmError> {
        self.write_with(path, &WriteOptions::default())
    }

    /// PFM, PNG or EXR as `path`'s extension says (any case); any other name is refused
    /// before anything is written ([`ImageFormat::from_path`]).
    pub fn write_with(&self, path: &Path, options: &WriteOptions) -> Result<(), FilmError> {
        match ImageFormat::from_path(path) {
            Some(ImageFormat::Pfm) => self.write_pfm(path),
            Some(ImageFormat::Png) => self.write_png(path, options.exposure),
            Some(ImageFormat::Exr) => self.write_exr(path, options.exr_half),
            None => Err(FilmError::UnknownFormat {
                path: path.to_owned(),
            }),
        }
    }

    /// OpenEXR, one RGB layer, row 0 at the top (EXR's own orientation).
    pub fn write_exr(&self, path: &Path, half: bool) -> Result<(), FilmError> {
        use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage, f16};
        let size = (self.width as usize, self.height as usize);
        let exr_err = |source| FilmError::Exr {
            path: path.to_owned(),
            source,
        };
        let io_err = |source| FilmError::Write {
            path: path.to_owned(),
            source,
        };
        let pixel = |Vec2(x, y): Vec2<usize>| self.get(x as u32, y as u32);
        write_atomic(path, io_err, |w| {
            let result = if half {
                let rgb = |p| {
                    let c: Vec3 = pixel(p);
                    (f16::from_f32(c.x), f16::from_f32(c.y), f16::from_f32(c.z))
                };
                Image::from_channels(size, SpecificChannels::rgb(rgb))
                    .write()
                    .to_buffered(w)
            } else {
                let rgb = |p| {
                    let c: Vec3 = pixel(p);
                    (c.x, c.y, c.z)
                };
                Image::from_channels(size, SpecificChannels::rgb(rgb))
                    .write()
                    .to_buffered(w)
            };
            result.map_err(exr_err)
        })
    }

    /// 8-bit sRGB PNG of the film scaled by `2^exposure`.
    pub fn write_png(&self, path: &Path, exposure: f32) -> Result<(), FilmError> {
        let bytes = self.to_srgb8(exposure);
        write_atomic(
            path,
            |source| FilmError::Write {
                path: path.to_owned(),
                source,
            },
            |w| {
                image::write_buffer_with_format(
                    w,
                    &bytes,
                    self.width,
                    self.height,
                    image::ExtendedColorType::Rgb8,
                    image::ImageFormat::Png,
                )
                .map_err(|source| FilmError::Png {
                    path: path.to_owned(),
                    source,
                })
            },
        )
    }

    /// Portable float map: header `PF\n<w> <h>\n-1.0\n` (negative scale: little endian),
    /// then rows of RGB f32 from the bottom row up.
    pub fn write_pfm(&self, path: &Path) -> Result<(), FilmError> {
        write_atomic(
            path,
            |source| FilmError::Write {
                path: path.to_owned(),
                source,
            },
            |w| {
                let io = |source| FilmError::Write {
                    path: path.to_owned(),
                    source,
                };
                write!(w, "PF\n{} {}\n-1.0\n", self.width, self.height).map_err(io)?;
                let mut row = Vec::with_capacity(self.width as usize * 12);
                for y in (0..self.height).rev() {
                    row.clear();
                    for x in 0..self.width {
                        let c = self.get(x, y);
                        for v in [c.x, c.y, c.z] {
                            row.extend_from_slice(&v.to_le_bytes());
                        }
                    }
                    w.write_all(&row).map_err(io)?;
                }
                Ok(())
            },
        )
    }

    /// Reads a colour PFM as written by [`Film::write_pfm`] (either byte order).
    pub fn read_pfm(path: &Path) -> Result<Film, FilmError> {
        let mut bytes = Vec::new();
        File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|source| FilmError::Read {
                path: path.to_owned(),
                source,
            })?;
        let bad = |reason: &str| FilmError::BadPfm {
            path: path.to_owned(),
            reason: reason.to_owned(),
        };
        let mut fields = Vec::new();
        let mut pos = 0;
        while fields.len() < 4 {
            while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
                pos += 1;
            }
            let start = pos;
            while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
                pos += 1;
            }
            if start == pos {
                return Err(bad("truncated header"));
            }
            fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
        }
        pos += 1;
        if fields[0] != "PF" {
            return Err(bad("magic is not PF"));
        }
        let width: u32 = fields[1].parse().map_err(|_| bad("bad width"))?;
        let height: u32 = fields[2].parse().map_err(|_| bad("bad height"))?;
        let scale: f32 = fields[3].parse().map_err(|_| bad("bad scale"))?;
        let need = width as usize * height as usize * 12;
        let data = bytes.get(pos..).filter(|d| d.len() == need);
        let data = data.ok_or_else(|| bad("pixel data has the wrong length"))?;
        let mut film = Film::new(width, height);
        let value = |b: &[u8]| {
            let b = [b[0], b[1], b[2], b[3]];
            if scale < 0.0 {
                f32::from_le_bytes(b)
            } else {
                f32::from_be_bytes(b)
            }
        };
        for (i, px) in data.chunks_exact(12).enumerate() {
            let (x, row) = (i % width as usize, i / width as usize);
            let y = height - 1 - row as u32;
            let c = Vec3::new(value(&px[0..4]), value(&px[4..8]), value(&px[8..12]));
            film.set(x as u32, y, c);
        }
        Ok(film)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_dark_image_is_told_the_exposure_that_brightens_it() {
        let mut film = super::Film::new(10, 10);
        assert_eq!(film.exposure_hint(), None, "black: nothing to expose");
        for (i, p) in film.pixels.iter_mut().enumerate() {
            *p = glam::Vec3::splat(0.001 * i as f32);
        }
        // 99th percentile of 0.000 .. 0.099 is 0.098: EV 3 brings it to 0.784.
        assert!(
            (film.bright_end() - 0.098).abs() < 1e-6,
            "{}",
            film.bright_end()
        );
        assert_eq!(film.exposure_hint().map(|(ev, _)| ev), Some(3.0));
        // One hot pixel does not hide the darkness.
        film.pixels[0] = glam::Vec3::splat(50.0);
        assert_eq!(film.exposure_hint().map(|(ev, _)| ev), Some(3.0));
        for p in film.pixels.iter_mut() {
            *p *= 8.0;
        }
        assert_eq!(film.exposure_hint(), None, "bright enough");
    }

    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("raypack-film-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn srgb_encoding_hits_its_anchor_points() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        // 0.5 linear is 0.7354 in sRGB: 187.5 rounds to 188.
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.002), 7);
    }

    #[test]
    fn pfm_round_trips_bit_exactly_and_png_decodes() {
        let dir = temp_dir("rt");
        let mut film = Film::new(3, 2);
        film.set(0, 0, Vec3::new(0.1, -0.0, 1e30));
        film.set(2, 1, Vec3::new(0.5, 2.0, 1.0 / 3.0));
        let pfm = dir.join("a.PFM");
        film.write(&pfm).unwrap();
        let back = Film::read_pfm(&pfm).unwrap();
        assert_eq!(back.width, 3);
        for (a, b) in film.pixels.iter().zip(&back.pixels) {
            for i in 0..3 {
                assert_eq!(a[i].to_bits(), b[i].to_bits());
            }
        }
        let png = dir.join("a.png");
        film.write(&png).unwrap();
        let img = image::open(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (3, 2));
        assert_eq!(img.get_pixel(2, 1).0, [188, 255, 156]);
        assert_eq!(img.get_pixel(0, 0).0, [89, 0, 255]);
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().contains(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exr_round_trips_float_exactly_and_half_to_half_precision() {
        let dir = temp_dir("exr");
        let mut film = Film::new(3, 2);
        film.set(0, 0, Vec3::new(0.1, 0.0, 1e30));
        film.set(2, 1, Vec3::new(0.5, 2.0, 1.0 / 3.0));
        for half in [false, true] {
            let path = dir.join(if half { "h.EXR" } else { "f.exr" });
            film.write_with(
                &path,
                &WriteOptions {
                    exr_half: half,
                    ..Default::default()
                },
            )
            .unwrap();
            let image = exr::prelude::read_first_rgba_layer_from_file(
                &path,
                |size, _| Film::new(size.width() as u32, size.height() as u32),
                |film: &mut Film, p, (r, g, b, _): (f32, f32, f32, f32)| {
                    film.set(p.x() as u32, p.y() as u32, Vec3::new(r, g, b))
                },
            )
            .unwrap();
            let back = image.layer_data.channel_data.pixels;
            assert_eq!((back.width, back.height), (3, 2));
            for (a, b) in film.pixels.iter().zip(&back.pixels) {
                for i in 0..3 {
                    let want = if half {
                        exr::prelude::f16::from_f32(a[i]).to_f32()
                    } else {
                        a[i]
                    };
                    assert_eq!(want.to_bits(), b[i].to_bits(), "half {half}: {a} vs {b}");
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exposure_scales_png_values_by_a_power_of_two_before_the_clamp() {
        let mut film = Film::new(2, 1);
        film.set(0, 0, Vec3::splat(0.25));
        film.set(1, 0, Vec3::splat(0.75));
        let (a, b) = (linear_to_srgb8(0.25), linear_to_srgb8(0.75));
        assert_eq!(film.to_srgb8(0.0), [a, a, a, b, b, b]);
        let plus_one = film.to_srgb8(1.0);
        assert_eq!(plus_one[0], linear_to_srgb8(0.5));
        assert_eq!(plus_one[3], 255, "0.75 * 2 clamps to white");
        assert_eq!(film.to_srgb8(-2.0)[0], linear_to_srgb8(0.0625));
    }

    #[test]
    fn a_failed_write_leaves_nothing_behind() {
        let dir = temp_dir("fail");
        let target = dir.join("missing-dir").join("x.png");
        let err = Film::new(1, 1).write(&target).unwrap_err();
        assert!(matches!(err, FilmError::Write { .. }), "{err}");
        assert!(!target.exists());
        // Names that are not .png, .pfm or .exr are refused, not written as PNG.
        for name in ["x.jpg", "x.tif", "x"] {
            let err = Film::new(1, 1).write(&dir.join(name)).unwrap_err();
            assert!(matches!(err, FilmError::UnknownFormat { .. }), "{err}");
        }
        assert!(std::fs::read_dir(&dir).unwrap().next().is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
