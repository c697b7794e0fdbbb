//! Eric Haines' Standard Procedural Databases ("A Proposal for Standard Graphics
//! Environments", IEEE CG&A, November 1987; the SPD package), written from their
//! published descriptions: scenes whose size grows with one parameter, so that how a
//! tracer's cost grows with the primitive count can be measured on familiar objects.
//!
//! Stage: scene. Each generator returns [`Geometry`] (triangles and spheres, in memory)
//! and a [`View`]; [`write_obj`] exports any geometry as OBJ, spheres tessellated. The
//! databases use z up, as the originals do. Primitive counts at size `s`:
//!
//! | name | what | primitives |
//! | --- | --- | --- |
//! | `balls` (`sphereflake`) | sphereflake: a sphere with nine spheres of a third its radius on its surface (six around the equator, three above), recursively, on a floor | `(9^(s+1) - 1) / 8` spheres + 2 triangles (7,381 spheres at 4) |
//! | `gears` | an `s x s` grid of meshing 36-tooth gears, faces fanned from the centre, on a floor | `576 s^2 + 2` triangles |
//! | `mount` | a fractal mountain (midpoint displacement of a square, crack-free) with 4 spheres above it | `2 * 4^s` triangles + 4 spheres (8,196 at 6) |
//! | `rings` | a stepped pyramid of `sum j^2, j = 1..s` rings, each 30 spheres joined by 30 cylinders (tessellated 6-sided tubes) on a floor | `30 * rings` spheres + `360 * rings` + 2 triangles (140 rings at 7) |
//! | `tetra` | Sierpinski tetrahedron: `4^s` tetrahedra | `4^(s+1)` triangles |
//! | `tree` | a binary tree: every branch a cone (6-sided, tessellated) ending in a sphere, `2^(s+1) - 1` branches, on a floor | `2^(s+1) - 1` spheres + `12 (2^(s+1) - 1)` + 2 triangles |
//!
//! The originals also have cylinders and cones; raypack tessellates them. Camera: the
//! balls database's published viewpoint (from (2.1, 1.3, 1.7) toward the origin, z up,
//! 45 degrees); the others get a view framing their bounds from a fixed direction.

use crate::scene::{Geometry, Sphere, View};
use glam::{DVec3, Vec3};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

/// Primitive count above which a size is refused (memory, not principle).
pub const MAX_PRIMITIVES: u64 = 60_000_000;

/// An SPD scene spec (`NAME[:SIZE]`) that names no database or size raypack generates,
/// or an export that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum SpdError {
    /// The name before `:` is not a database; it is kept as given.
    #[error(
        "spd scene `{0}`: unknown database (expected balls, sphereflake, gears, mount, rings, tetra or tree)"
    )]
    UnknownKind(String),
    #[error("spd scene `{spec}`: size `{size}` is not a whole number")]
    /// The part after `:` is not a whole number.
    BadSize {
        /// The whole spec, as given.
        spec: String,
        /// The part after `:`, as given.
        size: String,
    },
    /// A whole number too large for the database (or for a `u32`).
    #[error(
        "spd scene `{spec}`: size {size} is out of range: {kind} takes sizes 0 to {max} (at most {MAX_PRIMITIVES} primitives)"
    )]
    SizeOutOfRange {
        /// The whole spec, as given.
        spec: String,
        /// The part after `:`, as given (it may not fit a `u32`).
        size: String,
        /// The database's name.
        kind: &'static str,
        /// The largest size of the database within [`MAX_PRIMITIVES`].
        max: u32,
    },
    #[error(
        "spd scene {kind}:{size}: about {count} primitives, more than the limit of {MAX_PRIMITIVES} (sizes 0 to {max})"
    )]
    /// A size whose primitive count exceeds [`MAX_PRIMITIVES`].
    TooLarge {
        /// The database's name.
        kind: &'static str,
        /// The size asked for.
        size: u32,
        /// Primitives the database would have at `size`.
        count: u64,
        /// The largest size of the database within [`MAX_PRIMITIVES`].
        max: u32,
    },
    /// The OBJ export cannot be written; the OS error is the source, not in the message.
    #[error("{}: cannot write", path.display())]
    Write {
        /// The OBJ file being written.
        path: std::path::PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
}

/// The six databases.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpdKind {
    /// The sphereflake: spheres only, on a two-triangle floor.
    Balls,
    /// Meshing gears: triangles only, many long and thin.
    Gears,
    /// A fractal mountain: small triangles over a large, uneven surface.
    Mount,
    /// Rings of spheres and tubes in a stepped pyramid.
    Rings,
    /// The Sierpinski tetrahedron: triangles spread through mostly empty space.
    Tetra,
    /// A binary tree of cones and spheres.
    Tree,
}

impl SpdKind {
    /// Every database, in the order of their names' alphabet.
    pub const ALL: [SpdKind; 6] = [
        SpdKind::Balls,
        SpdKind::Gears,
        SpdKind::Mount,
        SpdKind::Rings,
        SpdKind::Tetra,
        SpdKind::Tree,
    ];

    /// The database called `name` (`sphereflake` is another name of `balls`).
    pub fn parse(name: &str) -> Result<SpdKind, SpdError> {
        Ok(match name {
            "balls" | "sphereflake" => SpdKind::Balls,
            "gears" => SpdKind::Gears,
            "mount" => SpdKind::Mount,
            "rings" => SpdKind::Rings,
            "tetra" => SpdKind::Tetra,
            "tree" => SpdKind::Tree,
            _ => return Err(SpdError::UnknownKind(name.to_string())),
        })
    }

    /// The name [`SpdKind::parse`] reads back (`balls` for the sphereflake).
    pub fn name(self) -> &'static str {
        match self {
            SpdKind::Balls => "balls",
            SpdKind::Gears => "gears",
            SpdKind::Mount => "mount",
            SpdKind::Rings => "rings",
            SpdKind::Tetra => "tetra",
            SpdKind::Tree => "tree",
        }
    }

    /// The size the SPD package uses by default (about 10,000 primitives).
    pub fn default_size(self) -> u32 {
        match self {
            SpdKind::Balls | SpdKind::Gears => 4,
            SpdKind::Mount | SpdKind::Tetra => 6,
            SpdKind::Rings => 7,
            SpdKind::Tree => 11,
        }
    }

    /// Primitives (triangles + spheres) the database has at `size`, saturating at
    /// `u64::MAX`, so that the count of any size is at least the true one and the limit
    /// check cannot be passed by a size whose count wraps around.
    pub fn primitive_count(self, size: u32) -> u64 {
        let s = size as u64;
        let pow = |b: u64, e: u64| {
            u32::try_from(e)
                .ok()
                .and_then(|e| b.checked_pow(e))
                .unwrap_or(u64::MAX)
        };
        match self {
            SpdKind::Balls => (pow(9, s + 1) - 1) / 8 + 2,
            SpdKind::Gears => s.saturating_mul(s).saturating_mul(576).saturating_add(2),
            SpdKind::Mount => pow(4, s).saturating_mul(2).saturating_add(4),
            SpdKind::Rings => ring_count(size).saturating_mul(30 + 360).saturating_add(2),
            SpdKind::Tetra => pow(4, s + 1),
            SpdKind::Tree => (pow(2, s + 1) - 1).saturating_mul(13).saturating_add(2),
        }
    }

    /// The largest size whose primitive count is within [`MAX_PRIMITIVES`].
    pub fn max_size(self) -> u32 {
        // Counts grow with the size and exceed the limit by size 323 (gears, the slowest).
        (1..)
            .find(|&s| self.primitive_count(s) > MAX_PRIMITIVES)
            .map_or(0, |s| s - 1)
    }
}

/// Rings of the `rings` database at `size`: `sum j^2, j = 1..size`, in closed form.
fn ring_count(size: u32) -> u64 {
    let s = size as u128;
    u64::try_from(s * (s + 1) * (2 * s + 1) / 6).unwrap_or(u64::MAX)
}

/// A generated database.
#[derive(Clone, Debug)]
pub struct SpdScene {
    /// Which database.
    pub kind: SpdKind,
    /// The size it was generated at.
    pub size: u32,
    /// Its triangles and spheres (no boxes or planes).
    pub geometry: Geometry,
    /// The camera: the published one for `balls`, one framing the bounds for the rest.
    pub view: View,
}

/// Parses `NAME[:SIZE]` (e.g. `balls:4`, `tetra`) and generates the database.
pub fn generate_spec(spec: &str) -> Result<SpdScene, SpdError> {
    let (name, size) = match spec.split_once(':') {
        Some((n, s)) => (n, Some(s)),
        None => (spec, None),
    };
    let kind = SpdKind::parse(name)?;
    let size = match size {
        Some(s) if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) => {
            return Err(SpdError::BadSize {
                spec: spec.to_string(),
                size: s.to_string(),
            });
        }
        // A whole number, but perhaps of more digits than any size.
        Some(s) => match s.parse::<u32>() {
            Ok(size) if size <= kind.max_size() => size,
            _ => {
                return Err(SpdError::SizeOutOfRange {
                    spec: spec.to_string(),
                    size: s.to_string(),
                    kind: kind.name(),
                    max: kind.max_size(),
                });
            }
        },
        None => kind.default_size(),
    };
    generate(kind, size)
}

/// Generates database `kind` at `size`.
pub fn generate(kind: SpdKind, size: u32) -> Result<SpdScene, SpdError> {
    let count = kind.primitive_count(size);
    if count > MAX_PRIMITIVES {
        return Err(SpdError::TooLarge {
            kind: kind.name(),
            size,
            count,
            max: kind.max_size(),
        });
    }
    let mut b = Builder::default();
    match kind {
        SpdKind::Balls => balls(&mut b, size),
        SpdKind::Gears => gears(&mut b, size),
        SpdKind::Mount => mount(&mut b, size),
        SpdKind::Rings => rings(&mut b, size),
        SpdKind::Tetra => tetra(&mut b, size),
        SpdKind::Tree => tree(&mut b, size),
    }
    let geometry = b.finish();
    let view = match kind {
        SpdKind::Balls => View {
            eye: DVec3::new(2.1, 1.3, 1.7),
            target: DVec3::ZERO,
            up: DVec3::Z,
            vfov_deg: 45.0,
        },
        SpdKind::Gears => framing(&geometry, DVec3::new(-0.6, -1.0, 1.1)),
        SpdKind::Mount => framing(&geometry, DVec3::new(-1.0, -0.8, 0.6)),
        SpdKind::Rings => framing(&geometry, DVec3::new(-1.0, -0.7, 0.8)),
        SpdKind::Tetra => framing(&geometry, DVec3::new(0.9, -1.0, 0.55)),
        SpdKind::Tree => framing(&geometry, DVec3::new(-0.3, -1.0, 0.35)),
    };
    Ok(SpdScene {
        kind,
        size,
        geometry,
        view,
    })
}

/// A 45-degree view of the whole scene box from direction `dir`, z up.
fn framing(g: &Geometry, dir: DVec3) -> View {
    let b = g.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let vfov: f64 = 45.0;
    let dist = radius / (vfov.to_radians() / 2.0).sin();
    View {
        eye: centre + dir.normalize() * dist,
        target: centre,
        up: DVec3::Z,
        vfov_deg: vfov,
    }
}

/// Collects triangles and spheres in f64, stored as f32 at the end.
#[derive(Default)]
struct Builder {
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    spheres: Vec<(DVec3, f64)>,
}

impl Builder {
    fn vertex(&mut self, p: DVec3) -> u32 {
        self.vertices.push(p);
        (self.vertices.len() - 1) as u32
    }

    fn triangle(&mut self, a: DVec3, b: DVec3, c: DVec3) {
        let (a, b, c) = (self.vertex(a), self.vertex(b), self.vertex(c));
        self.triangles.push([a, b, c]);
    }

    /// A convex or star-shaped polygon as a fan from `centre` (which must see every edge).
    fn fan(&mut self, centre: DVec3, ring: &[DVec3]) {
        let c = self.vertex(centre);
        let first = self.vertices.len() as u32;
        self.vertices.extend_from_slice(ring);
        let n = ring.len() as u32;
        for i in 0..n {
            self.triangles.push([c, first + i, first + (i + 1) % n]);
        }
    }

    /// The square `[-h, h]^2` at height `z`, facing up.
    fn floor(&mut self, h: f64, z: f64) {
        let p = |x: f64, y: f64| DVec3::new(x, y, z);
        self.triangle(p(-h, -h), p(h, -h), p(h, h));
        self.triangle(p(-h, -h), p(h, h), p(-h, h));
    }

    /// The side of a truncated cone from `a` (radius `ra`) to `b` (radius `rb`),
    /// `sides` quads, capless.
    fn tube(&mut self, a: DVec3, ra: f64, b: DVec3, rb: f64, sides: u32) {
        let (t, s) = basis((b - a).normalize());
        let ring = |c: DVec3, r: f64, i: u32| {
            let phi = 2.0 * PI * i as f64 / sides as f64;
            c + (t * phi.cos() + s * phi.sin()) * r
        };
        for i in 0..sides {
            let (a0, a1) = (ring(a, ra, i), ring(a, ra, i + 1));
            let (b0, b1) = (ring(b, rb, i), ring(b, rb, i + 1));
            self.triangle(a0, a1, b1);
            self.triangle(a0, b1, b0);
        }
    }

    fn sphere(&mut self, c: DVec3, r: f64) {
        self.spheres.push((c, r));
    }

    fn finish(self) -> Geometry {
        Geometry {
            vertices: self.vertices.iter().map(|v| v.as_vec3()).collect(),
            triangles: self.triangles,
            spheres: self
                .spheres
                .iter()
                .map(|&(c, r)| Sphere {
                    center: c.as_vec3(),
                    radius: r as f32,
                })
                .collect(),
            ..Geometry::default()
        }
    }
}

/// Two unit vectors completing `n` to an orthonormal basis.
fn basis(n: DVec3) -> (DVec3, DVec3) {
    let not_parallel = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = n.cross(not_parallel).normalize();
    (t, n.cross(t))
}

fn balls(b: &mut Builder, size: u32) {
    b.floor(12.0, -0.5);
    fn flake(b: &mut Builder, c: DVec3, r: f64, axis: DVec3, level: u32) {
        b.sphere(c, r);
        if level == 0 {
            return;
        }
        let (t, s) = basis(axis);
        let child = r / 3.0;
        for i in 0..9 {
            // Six around the equator, then three above at 60 degrees of elevation,
            // between the equatorial ones.
            let (azimuth, elevation) = if i < 6 {
                (i as f64 * PI / 3.0, 0.0)
            } else {
                ((i - 6) as f64 * 2.0 * PI / 3.0 + PI / 6.0, PI / 3.0)
            };
            let dir =
                (t * azimuth.cos() + s * azimuth.sin()) * elevation.cos() + axis * elevation.sin();
            flake(b, c + dir * (r + child), child, dir, level - 1);
        }
    }
    flake(b, DVec3::ZERO, 0.5, DVec3::Z, size);
}

fn gears(b: &mut Builder, size: u32) {
    const TEETH: u32 = 36;
    let (pitch, depth, thickness) = (1.0, 0.08, 0.2);
    b.floor(size as f64 * 1.2 + 1.0, -0.01);
    for gy in 0..size {
        for gx in 0..size {
            let centre = DVec3::new(
                (gx as f64 - (size as f64 - 1.0) / 2.0) * 2.0 * pitch,
                (gy as f64 - (size as f64 - 1.0) / 2.0) * 2.0 * pitch,
                0.0,
            );
            // Neighbours turn the other way: offset by half a tooth so teeth mesh.
            let phase = if (gx + gy) % 2 == 0 {
                0.0
            } else {
                PI / TEETH as f64
            };
            let outline: Vec<DVec3> = (0..4 * TEETH)
                .map(|i| {
                    let tooth = (i / 4) as f64;
                    let corner = [0.0, 0.2, 0.5, 0.7][(i % 4) as usize];
                    let r = if matches!(i % 4, 1 | 2) {
                        pitch + depth
                    } else {
                        pitch - depth
                    };
                    let phi = phase + (tooth + corner) * 2.0 * PI / TEETH as f64;
                    centre + DVec3::new(r * phi.cos(), r * phi.sin(), 0.0)
                })
                .collect();
            let top: Vec<DVec3> = outline.iter().map(|p| *p + DVec3::Z * thickness).collect();
            let mut bottom = outline.clone();
            bottom.reverse();
            b.fan(centre + DVec3::Z * thickness, &top);
            b.fan(centre, &bottom);
            let n = outline.len();
            for i in 0..n {
                let (a, c) = (outline[i], outline[(i + 1) % n]);
                let (at, ct) = (top[i], top[(i + 1) % n]);
                b.triangle(a, c, ct);
                b.triangle(a, ct, at);
            }
        }
    }
}

/// A hash of two integers in [-1, 1], the same for every triangle sharing a midpoint.
fn hash_unit(x: i64, y: i64) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

fn mount(b: &mut Builder, size: u32) {
    // Heights live on a (2^s + 1)^2 lattice; a midpoint's displacement depends only on
    // its lattice position and level, so neighbouring triangles agree (no cracks).
    let n = 1usize << size;
    let mut h = vec![0.0f64; (n + 1) * (n + 1)];
    let at = |x: usize, y: usize| y * (n + 1) + x;
    let roughness = 0.55;
    let mut step = n;
    let mut amplitude = 0.5;
    h[at(n / 2, n / 2)] = if n > 1 { 0.9 } else { 0.0 };
    while step > 1 {
        let half = step / 2;
        for y in (0..=n).step_by(half) {
            for x in (0..=n).step_by(half) {
                if x % step == 0 && y % step == 0 {
                    continue;
                }
                // Average of the two ends of the coarser edge this point splits:
                // horizontal, vertical, or the diagonal every square is cut along.
                let (x0, x1) = if x % step == 0 {
                    (x, x)
                } else {
                    (x - half, x + half)
                };
                let (y0, y1) = if y % step == 0 {
                    (y, y)
                } else {
                    (y - half, y + half)
                };
                let mid = 0.5 * (h[at(x0, y0)] + h[at(x1, y1)]);
                h[at(x, y)] +=
                    mid + amplitude * hash_unit(x as i64, y as i64 + (step as i64) * 7919);
            }
        }
        amplitude *= roughness;
        step = half;
    }
    let p = |x: usize, y: usize| {
        DVec3::new(
            x as f64 / n as f64 * 2.0 - 1.0,
            y as f64 / n as f64 * 2.0 - 1.0,
            h[at(x, y)].max(0.0) * 0.6,
        )
    };
    for y in 0..n {
        for x in 0..n {
            b.triangle(p(x, y), p(x + 1, y), p(x + 1, y + 1));
            b.triangle(p(x, y), p(x + 1, y + 1), p(x, y + 1));
        }
    }
    for (x, y) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
        b.sphere(DVec3::new(x, y, 1.0), 0.15);
    }
}

fn rings(b: &mut Builder, size: u32) {
    const BALLS: u32 = 30;
    let (radius, ball, rod, spacing, rise) = (1.0, 0.12, 0.04, 2.4, 0.5);
    b.floor(size as f64 * spacing, -ball);
    for level in 0..size {
        let side = size - level;
        for j in 0..side {
            for i in 0..side {
                let c = DVec3::new(
                    (i as f64 - (side as f64 - 1.0) / 2.0) * spacing,
                    (j as f64 - (side as f64 - 1.0) / 2.0) * spacing,
                    level as f64 * rise,
                );
                // Rings tilt a little around x, alternating, so their balls interleave.
                let tilt: f64 = if (i + j + level) % 2 == 0 {
                    0.15
                } else {
                    -0.15
                };
                let point = |k: u32| {
                    let phi = 2.0 * PI * k as f64 / BALLS as f64;
                    let (x, y) = (radius * phi.cos(), radius * phi.sin());
                    c + DVec3::new(x, y * tilt.cos(), y * tilt.sin())
                };
                for k in 0..BALLS {
                    b.sphere(point(k), ball);
                    b.tube(point(k), rod, point(k + 1), rod, 6);
                }
            }
        }
    }
}

fn tetra(b: &mut Builder, size: u32) {
    fn recurse(b: &mut Builder, v: [DVec3; 4], level: u32) {
        if level == 0 {
            let [p, q, r, s] = v;
            // Outward faces of a positively oriented tetrahedron.
            b.triangle(p, r, q);
            b.triangle(p, q, s);
            b.triangle(p, s, r);
            b.triangle(q, r, s);
            return;
        }
        for k in 0..4 {
            let c: [DVec3; 4] = std::array::from_fn(|i| (v[k] + v[i]) * 0.5);
            recurse(b, c, level - 1);
        }
    }
    let s = 1.0 / 3f64.sqrt();
    let mut v = [
        DVec3::new(1.0, 1.0, 1.0) * s,
        DVec3::new(-1.0, -1.0, 1.0) * s,
        DVec3::new(-1.0, 1.0, -1.0) * s,
        DVec3::new(1.0, -1.0, -1.0) * s,
    ];
    // Make the orientation positive so the faces above point outward.
    if (v[1] - v[0]).cross(v[2] - v[0]).dot(v[3] - v[0]) < 0.0 {
        v.swap(1, 2);
    }
    recurse(b, v, size);
}

fn tree(b: &mut Builder, size: u32) {
    b.floor(3.0, 0.0);
    fn branch(b: &mut Builder, base: DVec3, dir: DVec3, length: f64, radius: f64, level: u32) {
        let tip = base + dir * length;
        b.tube(base, radius, tip, radius * 0.7, 6);
        b.sphere(tip, radius * 0.7);
        if level == 0 {
            return;
        }
        let (t, s) = basis(dir);
        // The two children lean 30 degrees out, in planes that turn with the level.
        let turn = level as f64 * 1.3;
        let side = t * turn.cos() + s * turn.sin();
        let lean = 30f64.to_radians();
        for sign in [-1.0, 1.0] {
            let d = (dir * lean.cos() + side * (sign * lean.sin())).normalize();
            branch(b, tip, d, length * 0.8, radius * 0.7, level - 1);
        }
    }
    branch(b, DVec3::ZERO, DVec3::Z, 1.0, 0.08, size);
}

/// Writes `g` as OBJ: triangles as faces, each sphere as a UV sphere of `rings` rings
/// and `2 * rings` segments. Boxes become 12 triangles; planes are not written (they
/// have no finite OBJ form). Whole or not at all (temporary file, then rename).
pub fn write_obj(path: &Path, g: &Geometry, rings: u32) -> Result<(), SpdError> {
    let rings = rings.max(2);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# raypack: {} triangles, {} spheres as {}x{} UV spheres",
        g.triangles.len(),
        g.spheres.len(),
        rings,
        2 * rings
    );
    for v in &g.vertices {
        let _ = writeln!(out, "v {} {} {}", v.x, v.y, v.z);
    }
    for t in &g.triangles {
        let _ = writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let mut next = g.vertices.len() as u32 + 1;
    for s in &g.spheres {
        let segments = 2 * rings;
        let pole = |z: f32| s.center + Vec3::new(0.0, 0.0, z * s.radius);
        let (top, bottom) = (pole(1.0), pole(-1.0));
        let _ = writeln!(out, "v {} {} {}", top.x, top.y, top.z);
        for r in 1..rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for k in 0..segments {
                let phi = 2.0 * std::f32::consts::PI * k as f32 / segments as f32;
                let p = s.center
                    + Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    ) * s.radius;
                let _ = writeln!(out, "v {} {} {}", p.x, p.y, p.z);
            }
        }
        let _ = writeln!(out, "v {} {} {}", bottom.x, bottom.y, bottom.z);
        let ring_vertex = |r: u32, k: u32| next + 1 + (r - 1) * segments + k % segments;
        let last = next + 1 + (rings - 1) * segments;
        for k in 0..segments {
            let _ = writeln!(
                out,
                "f {} {} {}",
                next,
                ring_vertex(1, k),
                ring_vertex(1, k + 1)
            );
            for r in 1..rings - 1 {
                let _ = writeln!(
                    out,
                    "f {} {} {} {}",
                    ring_vertex(r, k),
                    ring_vertex(r + 1, k),
                    ring_vertex(r + 1, k + 1),
                    ring_vertex(r, k + 1)
                );
            }
            let _ = writeln!(
                out,
                "f {} {} {}",
                last,
                ring_vertex(rings - 1, k + 1),
                ring_vertex(rings - 1, k)
            );
        }
        next = last + 1;
    }
    for bx in &g.boxes {
        let c = |i: u32| {
            Vec3::new(
                if i & 1 == 0 { bx.min.x } else { bx.max.x },
                if i & 2 == 0 { bx.min.y } else { bx.max.y },
                if i & 4 == 0 { bx.min.z } else { bx.max.z },
            )
        };
        for i in 0..8 {
            let p = c(i);
            let _ = writeln!(out, "v {} {} {}", p.x, p.y, p.z);
        }
        for [a, b2, c2, d] in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            let _ = writeln!(
                out,
                "f {} {} {} {}",
                next + a,
                next + b2,
                next + c2,
                next + d
            );
        }
        next += 8;
    }
    crate::output::write_bytes_atomic(path, out.as_bytes(), |source| SpdError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Accel;
    use crate::accel::brute::BruteForce;

    #[test]
    fn primitive_counts_match_the_formulas() {
        for kind in SpdKind::ALL {
            for size in 0..3 {
                let s = generate(kind, size).unwrap();
                let got = s.geometry.triangles.len() as u64 + s.geometry.spheres.len() as u64;
                assert_eq!(got, kind.primitive_count(size), "{}:{size}", kind.name());
            }
        }
        // The published default sizes.
        assert_eq!(SpdKind::Balls.primitive_count(4) - 2, 7381);
        assert_eq!(SpdKind::Mount.primitive_count(6), 8196);
        assert_eq!(ring_count(7), 140);
        assert!(matches!(
            generate(SpdKind::Tetra, 14),
            Err(SpdError::TooLarge { .. })
        ));
        assert!(matches!(
            generate_spec("teapot:3"),
            Err(SpdError::UnknownKind(_))
        ));
        assert!(matches!(
            generate_spec("balls:x"),
            Err(SpdError::BadSize { .. })
        ));
        // Whole numbers too large are out of range, even those whose count would wrap
        // around u64 or whose exponent would wrap around u32.
        for spec in [
            "tree:99999999999",
            "gears:2147483648",
            "tetra:4294967295",
            "tetra:14",
        ] {
            assert!(
                matches!(generate_spec(spec), Err(SpdError::SizeOutOfRange { .. })),
                "{spec}"
            );
        }
        for kind in SpdKind::ALL {
            let max = kind.max_size();
            assert!(
                kind.primitive_count(max) <= MAX_PRIMITIVES,
                "{}",
                kind.name()
            );
            assert!(
                kind.primitive_count(max + 1) > MAX_PRIMITIVES,
                "{}",
                kind.name()
            );
            assert!(kind.default_size() <= max, "{}", kind.name());
            assert!(
                kind.primitive_count(u32::MAX) > MAX_PRIMITIVES,
                "{}",
                kind.name()
            );
        }
        assert_eq!(ring_count(1000), (1..=1000u64).map(|j| j * j).sum::<u64>());
        assert_eq!(
            generate_spec("sphereflake:1")
                .unwrap()
                .geometry
                .spheres
                .len(),
            10
        );
    }

    #[test]
    fn sphereflake_children_touch_their_parent() {
        let s = generate(SpdKind::Balls, 1).unwrap();
        let root = s.geometry.spheres[0];
        for c in &s.geometry.spheres[1..] {
            let gap = (c.center - root.center).length() - (root.radius + c.radius);
            assert!(gap.abs() < 1e-6, "{gap}");
            assert!((c.radius - root.radius / 3.0).abs() < 1e-7);
            assert!(c.center.z >= -1e-6, "children sit on the upper half");
        }
        // No two children overlap.
        for (i, a) in s.geometry.spheres[1..].iter().enumerate() {
            for b in &s.geometry.spheres[i + 2..] {
                assert!((a.center - b.center).length() > a.radius + b.radius);
            }
        }
    }

    #[test]
    fn tetra_faces_point_outward_and_camera_sees_the_scene() {
        for kind in SpdKind::ALL {
            let s = generate(kind, 2).unwrap();
            let accel = BruteForce::new(&s.geometry);
            let set = crate::rayset::standard::primary(&s.view, 32, 32).unwrap();
            let hits = set
                .rays
                .iter()
                .filter(|r| accel.intersect(r).is_some())
                .count();
            assert!(
                hits > 32 * 32 / 10,
                "{}: {hits} of 1024 primary rays hit",
                kind.name()
            );
        }
        let s = generate(SpdKind::Tetra, 1).unwrap();
        let g = &s.geometry;
        for t in 0..g.triangles.len() as u32 {
            let [a, b, c] = g.triangle(t);
            let n = (b - a).cross(c - a);
            // Each small tetrahedron's faces point away from its own centre.
            let small = (t / 4 * 4..t / 4 * 4 + 4)
                .flat_map(|u| g.triangle(u))
                .fold(Vec3::ZERO, |acc, v| acc + v)
                / 12.0;
            assert!(n.dot(a - small) > 0.0, "triangle {t}");
        }
    }

    #[test]
    fn obj_export_writes_every_primitive() {
        let s = generate(SpdKind::Balls, 1).unwrap();
        let dir = std::env::temp_dir().join(format!("raypack-spd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("balls.obj");
        write_obj(&path, &s.geometry, 4).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let faces = text.lines().filter(|l| l.starts_with("f ")).count();
        let verts = text.lines().filter(|l| l.starts_with("v ")).count();
        // 2 floor triangles; each sphere: 8 segments x (2 caps + 2 quad rows).
        assert_eq!(faces, 2 + 10 * 8 * 4);
        assert_eq!(verts, 6 + 10 * (2 + 3 * 8));
        // Every face index is in range.
        for l in text.lines().filter(|l| l.starts_with("f ")) {
            for i in l[2..].split_whitespace() {
                let i: usize = i.parse().unwrap();
                assert!(i >= 1 && i <= verts, "{l}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
