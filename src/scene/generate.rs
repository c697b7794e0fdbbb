//! Deterministic mesh generators for tests and benchmarks: random triangle soups, a
//! tessellated sphere, a grid of axis-aligned triangles lying on likely split planes, a
//! closed box made of triangles, and the OBJ text of a torus knot (scenes/knot.obj).
//!
//! Every generator is a pure function of its arguments (seeded with [`Rng`], a
//! SplitMix64), so a failing test names a scene that anyone can rebuild. Triangles are
//! numbered in generation order.

use super::Geometry;
use glam::Vec3;

/// The generators' random numbers (kept under this name for the tests that draw rays
/// beside generated geometry).
pub use crate::rng::SplitMix64 as Rng;

/// Appends triangle `(a, b, c)` with its own three vertices.
fn push_triangle(g: &mut Geometry, a: Vec3, b: Vec3, c: Vec3) {
    let i = g.vertices.len() as u32;
    g.vertices.extend([a, b, c]);
    g.triangles.push([i, i + 1, i + 2]);
}

/// `count` triangles scattered in the unit cube `[0, 1]^3`, of sizes from tiny to about
/// `max_size`; a few are degenerate (repeated or collinear corners) so builders must
/// leave them out and keep their ids.
pub fn random_soup(count: u32, max_size: f32, seed: u64) -> Geometry {
    let mut rng = Rng::new(seed);
    let mut g = Geometry::default();
    for i in 0..count {
        let a = rng.point(Vec3::ZERO, Vec3::ONE);
        let size = max_size * rng.f32() * rng.f32();
        let b = a + rng.unit_vector() * size;
        let c = if i % 97 == 13 {
            // Degenerate: collinear with a and b.
            a + (b - a) * 0.5
        } else {
            a + rng.unit_vector() * size
        };
        push_triangle(&mut g, a, b, c);
    }
    g
}

/// A UV sphere of `rings` x `segments` quads (split into triangles, the poles as fans),
/// sharing vertices, so the mesh is closed.
pub fn tessellated_sphere(center: Vec3, radius: f32, rings: u32, segments: u32) -> Geometry {
    let rings = rings.max(2);
    let segments = segments.max(3);
    let mut g = Geometry::default();
    g.vertices.push(center + Vec3::Y * radius);
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let dir = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            g.vertices.push(center + dir * radius);
        }
    }
    g.vertices.push(center - Vec3::Y * radius);
    let south = g.vertices.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    for s in 0..segments {
        g.triangles.push([0, ring(1, s + 1), ring(1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b) = (ring(r, s), ring(r, s + 1));
            let (c, d) = (ring(r + 1, s), ring(r + 1, s + 1));
            g.triangles.push([a, b, d]);
            g.triangles.push([a, d, c]);
        }
    }
    for s in 0..segments {
        g.triangles
            .push([south, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    g
}

/// Axis-aligned triangles on the integer lattice of `[0, n]^3`: on every lattice plane
/// `x = i`, `y = j` and `z = k`, each unit square of a checkerboard pattern is split into
/// two triangles. Every triangle lies exactly on a plane a SAH builder will want to split
/// at, and its edges lie on other such planes, so the set stresses planar events, ties
/// and rays that run inside split planes. Coplanar duplicates (the same square twice,
/// with the other diagonal) test equal-`t` ties.
pub fn axis_aligned_grid(n: u32) -> Geometry {
    let mut g = Geometry::default();
    let f = |v: u32| v as f32;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for level in 0..=n {
            for i in 0..n {
                for j in 0..n {
                    if (i + j + level) % 2 != 0 {
                        continue;
                    }
                    let corner = |du: u32, dv: u32| {
                        let mut p = Vec3::ZERO;
                        p[axis] = f(level);
                        p[u] = f(i + du);
                        p[v] = f(j + dv);
                        p
                    };
                    let (p00, p10, p01, p11) =
                        (corner(0, 0), corner(1, 0), corner(0, 1), corner(1, 1));
                    push_triangle(&mut g, p00, p10, p11);
                    push_triangle(&mut g, p00, p11, p01);
                    if (i * 7 + j * 3 + level) % 5 == 0 {
                        push_triangle(&mut g, p10, p11, p01);
                        push_triangle(&mut g, p10, p01, p00);
                    }
                }
            }
        }
    }
    g
}

/// The closed surface of the box `[0, n]^3`, each face an `n` x `n` grid of unit squares
/// split into two triangles, with shared vertices on the integer lattice (so on split
/// planes). Triangles face outward.
pub fn closed_box(n: u32) -> Geometry {
    let n = n.max(1);
    let mut g = Geometry::default();
    let mut index = std::collections::HashMap::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, n] {
            for i in 0..n {
                for j in 0..n {
                    let mut corner = |du: u32, dv: u32| {
                        let mut p = [0u32; 3];
                        p[axis] = side;
                        p[u] = i + du;
                        p[v] = j + dv;
                        *index.entry(p).or_insert_with(|| {
                            g.vertices
                                .push(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32));
                            g.vertices.len() as u32 - 1
                        })
                    };
                    let (a, b, c, d) = (corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1));
                    // (u x v) = +axis: counter-clockwise in (u, v) faces +axis.
                    if side == n {
                        g.triangles.push([a, b, c]);
                        g.triangles.push([a, c, d]);
                    } else {
                        g.triangles.push([a, c, b]);
                        g.triangles.push([a, d, c]);
                    }
                }
            }
        }
    }
    g
}

/// The warp of [`warped_closed_grid`] for a point of the box `[0, n]^3`: a smooth
/// displacement small enough to stay one-to-one, then a rotation, a scale and an offset
/// that leave no coordinate exactly representable in a simple form. Interior points of
/// the box map to interior points of the warped mesh (up to the mesh's flattening of
/// the smooth surface, under 0.1 lattice units for `n >= 8`).
pub fn warp_point(p: Vec3, n: u32) -> Vec3 {
    let f = std::f32::consts::TAU * 2.0 / n as f32;
    let amp = 0.08 / f;
    let q = p + Vec3::new((p.y * f).sin(), (p.z * f).sin(), (p.x * f).sin()) * amp;
    let rot = glam::Quat::from_axis_angle(Vec3::new(0.3, 0.8, -0.5).normalize(), 0.7);
    rot * (q * (2.3 / n as f32)) + Vec3::new(-1.37, 0.61, 2.89)
}

/// [`closed_box`] of `n` x `n` squares per face, warped by [`warp_point`]: a closed,
/// finely tessellated mesh (`12 n^2` triangles; `n = 105` gives 132,300) whose shared
/// vertices are stored once, so neighbouring triangles see bit-identical corners, but
/// whose planes and edges are all oblique. The stress case for watertightness.
pub fn warped_closed_grid(n: u32) -> Geometry {
    let mut g = closed_box(n);
    for v in &mut g.vertices {
        *v = warp_point(*v, n);
    }
    g
}

/// Concatenates meshes; the triangles of `parts[i]` follow those of `parts[i - 1]`.
pub fn merge(parts: &[Geometry]) -> Geometry {
    let mut g = Geometry::default();
    for p in parts {
        let base = g.vertices.len() as u32;
        g.vertices.extend_from_slice(&p.vertices);
        g.triangles
            .extend(p.triangles.iter().map(|t| t.map(|i| i + base)));
        g.spheres.extend_from_slice(&p.spheres);
        g.boxes.extend_from_slice(&p.boxes);
        g.planes.extend_from_slice(&p.planes);
    }
    g
}

/// The OBJ text of a `(p, q)` torus knot tube: the curve
/// `((major + minor cos qt) cos pt, (major + minor cos qt) sin pt, minor sin qt)`,
/// `t` in `[0, 2 pi)`, swept by a circle of radius `tube` with `sides` vertices at each of
/// `segments` steps. Faces are quads with texture coordinates (`u` along the curve, `v`
/// around the tube; the seams get their own `vt`), and no normals, so loading it
/// exercises quads, UV splits and computed normals. Coordinates are printed to 6
/// decimals, so the text is the same on every machine (scenes/knot.obj is this output).
pub fn torus_knot_obj(
    p: u32,
    q: u32,
    segments: u32,
    sides: u32,
    [major, minor, tube]: [f64; 3],
) -> String {
    use std::f64::consts::TAU;
    use std::fmt::Write;
    let curve = |t: f64| {
        let r = major + minor * (q as f64 * t).cos();
        [
            r * (p as f64 * t).cos(),
            r * (p as f64 * t).sin(),
            minor * (q as f64 * t).sin(),
        ]
    };
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let unit = |a: [f64; 3]| {
        let l = dot(a, a).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let mut out = format!(
        "# ({p}, {q}) torus knot, {segments} x {sides} quads, written by \
         raypack::scene::generate::torus_knot_obj\no knot\n"
    );
    for i in 0..segments {
        let t = TAU * i as f64 / segments as f64;
        let h = 1e-4;
        let c = curve(t);
        let tangent = unit(sub(curve(t + h), curve(t - h)));
        // Away from the torus' core circle, made perpendicular to the tangent.
        let core = [
            major * (p as f64 * t).cos(),
            major * (p as f64 * t).sin(),
            0.0,
        ];
        let out0 = sub(c, core);
        let d = dot(out0, tangent);
        let n = unit(sub(out0, [tangent[0] * d, tangent[1] * d, tangent[2] * d]));
        let b = cross(tangent, n);
        for j in 0..sides {
            let a = TAU * j as f64 / sides as f64;
            let (ca, sa) = (a.cos() * tube, a.sin() * tube);
            let v = [0, 1, 2].map(|k| c[k] + n[k] * ca + b[k] * sa);
            let _ = writeln!(out, "v {:.6} {:.6} {:.6}", v[0], v[1], v[2]);
        }
    }
    for i in 0..=segments {
        for j in 0..=sides {
            let _ = writeln!(
                out,
                "vt {:.6} {:.6}",
                i as f64 / segments as f64,
                j as f64 / sides as f64
            );
        }
    }
    let v = |i: u32, j: u32| (i % segments) * sides + (j % sides) + 1;
    let vt = |i: u32, j: u32| i * (sides + 1) + j + 1;
    for i in 0..segments {
        for j in 0..sides {
            let corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
            out.push('f');
            for (a, b) in corners {
                let _ = write!(out, " {}/{}", v(a, b), vt(a, b));
            }
            out.push('\n');
        }
    }
    out
}

/// scenes/knot.obj, the mesh of scenes/part7.toml: a (2, 3) torus knot of 768 quads.
pub fn part7_knot_obj() -> String {
    torus_knot_obj(2, 3, 96, 8, [1.6, 0.6, 0.35])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_are_deterministic_and_sized() {
        let a = random_soup(500, 0.1, 7);
        let b = random_soup(500, 0.1, 7);
        assert_eq!(a.vertices, b.vertices);
        assert_eq!(a.triangles.len(), 500);
        assert_ne!(random_soup(500, 0.1, 8).vertices, a.vertices);
        let s = tessellated_sphere(Vec3::ZERO, 1.0, 8, 12);
        assert_eq!(s.triangles.len(), 2 * 12 + 2 * 12 * 6);
        for v in &s.vertices {
            assert!((v.length() - 1.0).abs() < 1e-5);
        }
        assert_eq!(closed_box(3).triangles.len(), 6 * 9 * 2);
        assert_eq!(closed_box(3).vertices.len(), 4 * 4 * 4 - 2 * 2 * 2);
    }

    #[test]
    fn closed_meshes_have_every_edge_twice_in_opposite_directions() {
        for g in [tessellated_sphere(Vec3::ONE, 2.0, 6, 9), closed_box(2)] {
            let mut edges = std::collections::HashMap::new();
            for t in &g.triangles {
                for e in 0..3 {
                    *edges.entry((t[e], t[(e + 1) % 3])).or_insert(0) += 1;
                }
            }
            for (&(a, b), &count) in &edges {
                assert_eq!(count, 1, "edge {a}-{b} used twice in one direction");
                assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} is open");
            }
        }
    }

    #[test]
    fn closed_box_faces_outward() {
        let g = closed_box(2);
        let centre = Vec3::splat(1.0);
        for i in 0..g.triangles.len() as u32 {
            let [a, b, c] = g.triangle(i);
            let n = (b - a).cross(c - a);
            assert!(
                n.dot((a + b + c) / 3.0 - centre) > 0.0,
                "triangle {i} faces in"
            );
        }
    }
}
