//! The exchange formats of RAYS.md: a `.rays` file is a header (magic `RAYS0001`, u64
//! count, u32 width, u32 height) and 32-byte records `ox oy oz tmin dx dy dz tmax`; a
//! `.hits` file is a header (magic `HITS0001`, u64 count) and 16-byte records
//! `t prim u v`; everything little endian. Readers check the magic, that the size is
//! exactly header plus records, and every field they can check, and name the file and
//! the field when something is wrong. Writers write a temporary file beside the target
//! and rename it, so a file is written whole or not at all.
//!
//! Image sets are in packet order (2x2 quads, row-major in 16x16 tiles, tiles
//! row-major): [`packet_pixel`] and [`pixel_packet_index`] convert.

use crate::ray::{Hit, NO_HIT, Ray};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// First 8 bytes of a rays file.
pub const RAYS_MAGIC: [u8; 8] = *b"RAYS0001";
/// First 8 bytes of a hits file.
pub const HITS_MAGIC: [u8; 8] = *b"HITS0001";
/// Bytes before the first ray record.
pub const RAYS_HEADER_BYTES: usize = 24;
/// Bytes per ray record (8 f32).
pub const RAY_RECORD_BYTES: usize = 32;
/// Bytes before the first hit record.
pub const HITS_HEADER_BYTES: usize = 16;
/// Bytes per hit record (f32 t, u32 prim, f32 u, f32 v).
pub const HIT_RECORD_BYTES: usize = 16;
/// Image sets are stored in tiles of this many pixels square.
pub const TILE: u32 = 16;

/// Field names of a ray record, in file order.
const RAY_FIELDS: [&str; 8] = ["ox", "oy", "oz", "tmin", "dx", "dy", "dz", "tmax"];
/// Field names of a hit record, in file order.
const HIT_FIELDS: [&str; 4] = ["t", "prim", "u", "v"];

/// A direction whose length is further than this from 1 is rejected: RAYS.md stores
/// normalized directions, and a tracer fed unnormalized ones reports scaled distances.
const DIR_LENGTH_TOLERANCE: f32 = 1e-3;

/// What can go wrong reading, writing or generating ray sets. Every variant names the
/// file (or the parameter) and the field. The operating system's error is the source of
/// [`RaySetError::Read`] and [`RaySetError::Write`], not part of their message, so the
/// CLI's chain prints it once.
#[derive(Debug, thiserror::Error)]
pub enum RaySetError {
    /// A file the user named cannot be read: bad input.
    #[error("{}: cannot read", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// An output cannot be written (missing directory, full disk): not the input's fault.
    #[error("{}: cannot write", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: bad magic {found:?} (expected {expected:?})", path.display())]
    BadMagic {
        path: PathBuf,
        found: String,
        expected: &'static str,
    },
    #[error("{}: truncated: {field} ends at byte {needed} but the file has {len} bytes", path.display())]
    Truncated {
        path: PathBuf,
        field: String,
        needed: u64,
        len: u64,
    },
    #[error("{}: {extra} bytes after the last of {count} records", path.display())]
    TrailingBytes {
        path: PathBuf,
        count: u64,
        extra: u64,
    },
    #[error("{}: {field}: {reason}", path.display())]
    BadField {
        path: PathBuf,
        field: String,
        reason: String,
    },
    #[error("{what}: {reason}")]
    BadParameter { what: String, reason: String },
}

impl RaySetError {
    /// True unless an output could not be written: everything else is about what the
    /// user gave (a file, a camera, an image size), which the CLI reports with exit code 2.
    pub fn is_input(&self) -> bool {
        !matches!(self, RaySetError::Write { .. })
    }
}

/// A set of rays; `width`, `height` are the image size of an image set in packet order,
/// both 0 otherwise.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RaySet {
    pub width: u32,
    pub height: u32,
    pub rays: Vec<Ray>,
}

impl RaySet {
    /// A set that is not an image.
    pub fn from_rays(rays: Vec<Ray>) -> RaySet {
        RaySet {
            width: 0,
            height: 0,
            rays,
        }
    }

    pub fn len(&self) -> usize {
        self.rays.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }

    /// Checks the image size against the count (both 0, or positive multiples of
    /// [`TILE`] with `width * height` rays).
    fn check_shape(&self) -> Result<(), String> {
        match (self.width, self.height) {
            (0, 0) => Ok(()),
            (w, h) if w == 0 || h == 0 || w % TILE != 0 || h % TILE != 0 => Err(format!(
                "image size {w}x{h}: both must be 0, or positive multiples of {TILE}"
            )),
            (w, h) if w as u64 * h as u64 != self.rays.len() as u64 => Err(format!(
                "image size {w}x{h} needs {} rays, the set has {}",
                w as u64 * h as u64,
                self.rays.len()
            )),
            _ => Ok(()),
        }
    }
}

/// Pixel `(x, y)` of ray `i` of an image set `width` pixels wide (RAYS.md packet order).
#[inline]
pub fn packet_pixel(i: usize, width: u32) -> (u32, u32) {
    let tiles_x = (width / TILE) as usize;
    let (tile, quad) = (i / 256, (i % 256) / 4);
    let (dx, dy) = crate::scene::camera::quad_lane(i);
    let x = (tile % tiles_x) * 16 + (quad % 8) * 2;
    let y = (tile / tiles_x) * 16 + (quad / 8) * 2;
    (x as u32 + dx, y as u32 + dy)
}

/// Index of pixel `(x, y)` in an image set `width` pixels wide; inverse of [`packet_pixel`].
#[inline]
pub fn pixel_packet_index(x: u32, y: u32, width: u32) -> usize {
    let (x, y, tiles_x) = (x as usize, y as usize, (width / TILE) as usize);
    let tile = (y / 16) * tiles_x + x / 16;
    let quad = ((y % 16) / 2) * 8 + (x % 16) / 2;
    let lane = (y % 2) * 2 + x % 2;
    tile * 256 + quad * 4 + lane
}

fn read_error(path: &Path, source: std::io::Error) -> RaySetError {
    RaySetError::Read {
        path: path.to_path_buf(),
        source,
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// Checks the magic and the exact size of a file of `header` bytes plus `count` records
/// of `record` bytes, returning the count. `fields` names a record's 4-byte fields.
fn check_layout(
    path: &Path,
    bytes: &[u8],
    magic: &'static [u8; 8],
    header: usize,
    record: usize,
    fields: &[&str],
    header_fields: &[(&str, usize)],
) -> Result<usize, RaySetError> {
    let len = bytes.len() as u64;
    let truncated = |field: String, needed: u64| RaySetError::Truncated {
        path: path.to_path_buf(),
        field,
        needed,
        len,
    };
    if bytes.len() < 8 {
        return Err(truncated("magic".into(), 8));
    }
    if &bytes[..8] != magic {
        return Err(RaySetError::BadMagic {
            path: path.to_path_buf(),
            found: String::from_utf8_lossy(&bytes[..8]).into_owned(),
            expected: std::str::from_utf8(magic).expect("ASCII magic"),
        });
    }
    for &(name, end) in header_fields {
        if bytes.len() < end {
            return Err(truncated(format!("header field `{name}`"), end as u64));
        }
    }
    let count = u64_at(bytes, 8);
    let body = (bytes.len() - header) as u64;
    let whole = body / record as u64;
    if whole < count {
        let offset = (body % record as u64) as usize;
        let field = fields[(offset / 4).min(fields.len() - 1)];
        let needed = (header + offset / 4 * 4 + 4) as u64 + whole * record as u64;
        return Err(truncated(
            format!("record {whole} field `{field}` (count is {count})"),
            needed,
        ));
    }
    let extra = len - header as u64 - count * record as u64;
    if extra != 0 {
        return Err(RaySetError::TrailingBytes {
            path: path.to_path_buf(),
            count,
            extra,
        });
    }
    usize::try_from(count).map_err(|_| RaySetError::BadField {
        path: path.to_path_buf(),
        field: "count".into(),
        reason: format!("{count} records do not fit in memory"),
    })
}

/// Parses a rays file already in memory (`path` names it in errors).
pub fn parse_rays(path: &Path, bytes: &[u8]) -> Result<RaySet, RaySetError> {
    let count = check_layout(
        path,
        bytes,
        &RAYS_MAGIC,
        RAYS_HEADER_BYTES,
        RAY_RECORD_BYTES,
        &RAY_FIELDS,
        &[("count", 16), ("width", 20), ("height", 24)],
    )?;
    let bad = |field: String, reason: String| RaySetError::BadField {
        path: path.to_path_buf(),
        field,
        reason,
    };
    let mut set = RaySet {
        width: u32_at(bytes, 16),
        height: u32_at(bytes, 20),
        rays: Vec::with_capacity(count),
    };
    for (i, rec) in bytes[RAYS_HEADER_BYTES..]
        .chunks_exact(RAY_RECORD_BYTES)
        .enumerate()
    {
        let f: [f32; 8] = std::array::from_fn(|k| f32_at(rec, 4 * k));
        let field = |k: usize| format!("ray {i} field `{}`", RAY_FIELDS[k]);
        for k in [0, 1, 2, 4, 5, 6] {
            if !f[k].is_finite() {
                return Err(bad(field(k), format!("{} is not finite", f[k])));
            }
        }
        for k in [3, 7] {
            if f[k].is_nan() {
                return Err(bad(field(k), "is NaN".into()));
            }
        }
        let dir = Vec3::new(f[4], f[5], f[6]);
        let length = dir.length();
        // Finite components give a finite or infinite length, never NaN.
        if (length - 1.0).abs() > DIR_LENGTH_TOLERANCE {
            return Err(bad(
                format!("ray {i} direction (dx, dy, dz)"),
                format!("length {length} is not 1 (directions are normalized)"),
            ));
        }
        set.rays
            .push(Ray::new(Vec3::new(f[0], f[1], f[2]), dir, f[3], f[7]));
    }
    set.check_shape()
        .map_err(|reason| bad("header fields `width`, `height`".into(), reason))?;
    Ok(set)
}

/// Parses a hits file already in memory (`path` names it in errors).
pub fn parse_hits(path: &Path, bytes: &[u8]) -> Result<Vec<Hit>, RaySetError> {
    let count = check_layout(
        path,
        bytes,
        &HITS_MAGIC,
        HITS_HEADER_BYTES,
        HIT_RECORD_BYTES,
        &HIT_FIELDS,
        &[("count", 16)],
    )?;
    let mut hits = Vec::with_capacity(count);
    for (i, rec) in bytes[HITS_HEADER_BYTES..]
        .chunks_exact(HIT_RECORD_BYTES)
        .enumerate()
    {
        let hit = Hit {
            t: f32_at(rec, 0),
            prim: u32_at(rec, 4),
            u: f32_at(rec, 8),
            v: f32_at(rec, 12),
        };
        if hit.t.is_nan() {
            return Err(RaySetError::BadField {
                path: path.to_path_buf(),
                field: format!("hit {i} field `t`"),
                reason: "is NaN".into(),
            });
        }
        hits.push(hit);
    }
    Ok(hits)
}

/// Reads a rays file.
pub fn read_rays(path: &Path) -> Result<RaySet, RaySetError> {
    let bytes = std::fs::read(path).map_err(|e| read_error(path, e))?;
    parse_rays(path, &bytes)
}

/// Reads a hits file.
pub fn read_hits(path: &Path) -> Result<Vec<Hit>, RaySetError> {
    let bytes = std::fs::read(path).map_err(|e| read_error(path, e))?;
    parse_hits(path, &bytes)
}

/// The bytes of a rays file holding `set`.
pub fn rays_bytes(set: &RaySet) -> Vec<u8> {
    let mut b = Vec::with_capacity(RAYS_HEADER_BYTES + set.rays.len() * RAY_RECORD_BYTES);
    b.extend_from_slice(&RAYS_MAGIC);
    b.extend_from_slice(&(set.rays.len() as u64).to_le_bytes());
    b.extend_from_slice(&set.width.to_le_bytes());
    b.extend_from_slice(&set.height.to_le_bytes());
    for r in &set.rays {
        for x in [
            r.org.x, r.org.y, r.org.z, r.t_min, r.dir.x, r.dir.y, r.dir.z, r.t_max,
        ] {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    b
}

/// The bytes of a hits file holding `hits`. A miss is written as RAYS.md's miss record
/// (`t = +inf`, `prim = 0xFFFFFFFF`, `u = v = 0`) whatever the hit holds.
pub fn hits_bytes(hits: &[Hit]) -> Vec<u8> {
    let mut b = Vec::with_capacity(HITS_HEADER_BYTES + hits.len() * HIT_RECORD_BYTES);
    b.extend_from_slice(&HITS_MAGIC);
    b.extend_from_slice(&(hits.len() as u64).to_le_bytes());
    for h in hits {
        let h = if h.prim == NO_HIT { Hit::MISS } else { *h };
        b.extend_from_slice(&h.t.to_le_bytes());
        b.extend_from_slice(&h.prim.to_le_bytes());
        b.extend_from_slice(&h.u.to_le_bytes());
        b.extend_from_slice(&h.v.to_le_bytes());
    }
    b
}

/// Writes a rays file (whole or not at all). The set's shape is checked first.
pub fn write_rays(path: &Path, set: &RaySet) -> Result<(), RaySetError> {
    set.check_shape()
        .map_err(|reason| RaySetError::BadParameter {
            what: format!("{}: header fields `width`, `height`", path.display()),
            reason,
        })?;
    write_whole(path, &rays_bytes(set))
}

/// Writes a hits file (whole or not at all).
pub fn write_hits(path: &Path, hits: &[Hit]) -> Result<(), RaySetError> {
    write_whole(path, &hits_bytes(hits))
}

/// Writes `bytes` whole or not at all through the one atomic writer
/// ([`crate::output::write_bytes_atomic`]), naming the error as a ray-set error.
fn write_whole(path: &Path, bytes: &[u8]) -> Result<(), RaySetError> {
    crate::output::write_bytes_atomic(path, bytes, |source| RaySetError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(i: u32) -> Ray {
        let d = Vec3::new(i as f32, 1.0, -2.0).normalize();
        Ray::new(Vec3::new(1.0, -2.0, i as f32), d, 0.0, f32::INFINITY)
    }

    #[test]
    fn packet_order_round_trips_and_forms_quads() {
        let (w, h) = (48u32, 32u32);
        let mut seen = vec![false; (w * h) as usize];
        for i in 0..(w * h) as usize {
            let (x, y) = packet_pixel(i, w);
            assert!(x < w && y < h);
            assert_eq!(pixel_packet_index(x, y, w), i);
            assert!(!std::mem::replace(&mut seen[(y * w + x) as usize], true));
            if i % 4 == 0 {
                assert_eq!(packet_pixel(i + 1, w), (x + 1, y));
                assert_eq!(packet_pixel(i + 2, w), (x, y + 1));
                assert_eq!(packet_pixel(i + 3, w), (x + 1, y + 1));
            }
        }
        // Tiles are row-major: ray 256 starts the second tile of the first row.
        assert_eq!(packet_pixel(256, w), (16, 0));
        assert_eq!(packet_pixel(3 * 256, w), (0, 16));
    }

    #[test]
    fn rays_and_hits_round_trip_through_bytes() {
        let set = RaySet::from_rays((0..5).map(ray).collect());
        let p = Path::new("mem.rays");
        assert_eq!(parse_rays(p, &rays_bytes(&set)).unwrap(), set);
        let hits = vec![
            Hit {
                t: 1.5,
                u: 0.25,
                v: 0.5,
                prim: 7,
            },
            Hit::MISS,
        ];
        assert_eq!(
            parse_hits(Path::new("mem.hits"), &hits_bytes(&hits)).unwrap(),
            hits
        );
        let b = hits_bytes(&hits);
        assert_eq!(&b[..8], b"HITS0001");
        assert_eq!(u32_at(&b, HITS_HEADER_BYTES + HIT_RECORD_BYTES + 4), NO_HIT);
    }

    #[test]
    fn bad_files_name_the_file_and_the_field() {
        let set = RaySet::from_rays((0..3).map(ray).collect());
        let good = rays_bytes(&set);
        let p = Path::new("set.rays");

        let mut magic = good.clone();
        magic[..8].copy_from_slice(b"RAYS0002");
        let e = parse_rays(p, &magic).unwrap_err();
        assert!(matches!(e, RaySetError::BadMagic { .. }), "{e}");
        assert!(e.to_string().starts_with("set.rays: bad magic"), "{e}");

        let e = parse_rays(p, &good[..good.len() - 6]).unwrap_err();
        assert!(matches!(e, RaySetError::Truncated { .. }), "{e}");
        assert!(e.to_string().contains("record 2 field `dz`"), "{e}");

        let e = parse_rays(p, &good[..18]).unwrap_err();
        assert!(e.to_string().contains("header field `width`"), "{e}");

        let mut extra = good.clone();
        extra.push(0);
        let e = parse_rays(p, &extra).unwrap_err();
        assert!(
            matches!(e, RaySetError::TrailingBytes { extra: 1, .. }),
            "{e}"
        );

        let mut nan = good.clone();
        nan[RAYS_HEADER_BYTES + RAY_RECORD_BYTES + 4..][..4]
            .copy_from_slice(&f32::NAN.to_le_bytes());
        let e = parse_rays(p, &nan).unwrap_err();
        assert!(e.to_string().contains("ray 1 field `oy`"), "{e}");

        let mut unnormalized = good.clone();
        unnormalized[RAYS_HEADER_BYTES + 16..][..4].copy_from_slice(&3.0f32.to_le_bytes());
        let e = parse_rays(p, &unnormalized).unwrap_err();
        assert!(e.to_string().contains("ray 0 direction"), "{e}");

        let mut shape = good.clone();
        shape[16..20].copy_from_slice(&16u32.to_le_bytes());
        let e = parse_rays(p, &shape).unwrap_err();
        assert!(e.to_string().contains("`width`, `height`"), "{e}");

        let hits = hits_bytes(&[Hit::MISS]);
        let e = parse_hits(Path::new("a.hits"), &hits[..HITS_HEADER_BYTES + 5]).unwrap_err();
        assert!(e.to_string().contains("record 0 field `prim`"), "{e}");
        let e = parse_hits(Path::new("a.hits"), &good).unwrap_err();
        assert!(matches!(e, RaySetError::BadMagic { .. }), "{e}");
    }

    #[test]
    fn writes_are_whole_or_nothing() {
        let dir = std::env::temp_dir().join(format!("raypack-rayset-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.rays");
        let set = RaySet::from_rays((0..2).map(ray).collect());
        write_rays(&path, &set).unwrap();
        assert_eq!(read_rays(&path).unwrap(), set);
        // A set with an impossible shape is refused and the old file stays.
        let bad = RaySet {
            width: 16,
            height: 16,
            rays: set.rays.clone(),
        };
        assert!(write_rays(&path, &bad).is_err());
        assert_eq!(read_rays(&path).unwrap(), set);
        // Writing into a missing directory fails, is not bad input, and leaves no
        // temporary file behind.
        let e = write_hits(&dir.join("missing/a.hits"), &[Hit::MISS]).unwrap_err();
        assert!(
            matches!(e, RaySetError::Write { .. }) && !e.is_input(),
            "{e}"
        );
        let e = read_rays(&dir.join("missing.rays")).unwrap_err();
        assert!(matches!(e, RaySetError::Read { .. }) && e.is_input(), "{e}");
        let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(leftovers.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
