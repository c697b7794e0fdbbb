//! OBJ meshes through `tobj`: positions, fan-triangulated faces in file order,
//! per-vertex normals and texture coordinates, and MTL diffuse colours and textures.
//!
//! Stage: scene input. Entry point: [`load`].
//!
//! Invariants of an [`ObjMesh`]:
//! - triangle `i` is the `i`-th triangle of the file after fan triangulation: a face
//!   `v0 v1 ... v(n-1)` gives `(v0,v1,v2), (v0,v2,v3), ...`, counted across all objects
//!   and groups in file order. This index is the `prim` id of RAYS.md, and each
//!   triangle keeps its corner order, so RAYS.md's barycentric `u`, `v` refer to the
//!   file's second and third corner.
//! - `normals` is parallel to `positions`; `uvs` is parallel to `positions` or empty;
//!   `tri_material` is parallel to `triangles`.
//! - Degenerate triangles (zero area, or an area that overflows `f32`) keep their place
//!   and id; they are only counted.
//!
//! Vertex numbering is `tobj`'s, not the file's: `tobj` numbers the vertices of each
//! object and group in order of first use and splits a position used with different
//! texture coordinates or normals, which per-vertex attributes need. Unused positions
//! are dropped.
//!
//! `tobj` neither reports line numbers nor rejects every malformed file (a zero index
//! silently drops a texture coordinate; `Kd` with two numbers panics), so a line scan of
//! our own (`scan`) reads the file first. It checks every line `tobj` reads, so errors name the
//! file and line, and it records the file-order triangles, against which `tobj`'s output
//! is checked corner by corner. The MTL library is read by that scan alone. Every pass
//! is streaming and linear in the file size.

mod scan;

use super::error::{ObjError, Warning};
use scan::{NO_USEMTL, Scan, scan_mtl, scan_obj};

use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// A triangle mesh loaded from an OBJ file (see the module invariants).
#[derive(Clone, Debug, Default)]
pub struct ObjMesh {
    /// Vertex positions (`v` lines), in file order; all finite.
    pub positions: Vec<Vec3>,
    /// Corner indices into `positions`, in file order (the prim ids of RAYS.md).
    pub triangles: Vec<[u32; 3]>,
    /// Unit shading normals, one per position. From the file when every face corner has
    /// one; otherwise the area-weighted sum of the face normals around each position
    /// (zero where only degenerate triangles meet: use the geometric normal there).
    pub normals: Vec<Vec3>,
    /// True when `normals` came from the file's `vn` lines.
    pub normals_from_file: bool,
    /// Texture coordinates, one per position; empty when the file has none, or only
    /// some corners have them in a way that cannot be kept per vertex.
    pub uvs: Vec<Vec2>,
    /// Materials of the file's MTL libraries, in definition order.
    pub materials: Vec<ObjMaterial>,
    /// Index into `materials` of each triangle, or `None` before any `usemtl`.
    pub tri_material: Vec<Option<u32>>,
    /// Degenerate triangles (kept, with their ids; no ray hits them): those of zero area
    /// and those whose area overflows `f32`.
    pub degenerate_count: u32,
    /// Of `degenerate_count`, the triangles whose corners are finite but so far apart
    /// that their area (a cross product) overflows `f32`.
    pub overflow_count: u32,
}

/// The part of an MTL material that raypack uses.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjMaterial {
    /// The `newmtl` name that `usemtl` refers to.
    pub name: String,
    /// `Kd` (default 0.8 grey when the material has none).
    pub diffuse: Vec3,
    /// `map_Kd`, resolved against the MTL file's folder; checked to exist.
    pub diffuse_texture: Option<PathBuf>,
    /// Emitted radiance: `Ke`; without `Ke`, a `Ka` with a component above 1 (see
    /// [`emission_of`]); otherwise zero.
    pub emission: Vec3,
}

/// The emission rule of MTL materials: `Ke` when the material has it. Without `Ke`, an
/// ambient `Ka` with a component above 1 is taken as emitted radiance: no reflectance
/// exceeds 1, so such a `Ka` can only be the old convention of giving a light's radiance
/// as its ambient colour (the Cornell box's `light` material, `Ka 20 20 20`). An ordinary
/// ambient (`Ka 0 0 0`, `Ka 0.2 0.2 0.2`) emits nothing.
pub fn emission_of(ke: Option<Vec3>, ka: Option<Vec3>) -> Vec3 {
    match (ke, ka) {
        (Some(ke), _) => ke.max(Vec3::ZERO),
        (None, Some(ka)) if ka.max_element() > 1.0 => ka.max(Vec3::ZERO),
        _ => Vec3::ZERO,
    }
}

impl From<ObjMesh> for super::Geometry {
    /// The mesh's positions and triangles, for the accelerators (materials, normals and
    /// UVs are the renderer's: [`super::Scene::from_obj`] keeps them).
    fn from(mesh: ObjMesh) -> super::Geometry {
        super::Geometry {
            vertices: mesh.positions,
            triangles: mesh.triangles,
            ..Default::default()
        }
    }
}

impl ObjMesh {
    /// Number of triangles, i.e. of prim ids.
    pub fn triangle_count(&self) -> u32 {
        self.triangles.len() as u32
    }

    /// The warning to give about the mesh loaded from `path`, if any: its degenerate
    /// triangles are skipped by every intersector, which the user should know.
    pub fn warning(&self, path: &Path) -> Option<Warning> {
        (self.degenerate_count > 0).then(|| Warning::DegenerateTriangles {
            path: path.to_path_buf(),
            count: self.degenerate_count,
            overflow: self.overflow_count,
        })
    }
}

/// Loads the OBJ file at `path` with its MTL libraries (resolved against the OBJ file's
/// folder). Errors name the file and the line; the mesh must have at least one face.
pub fn load(path: &Path) -> Result<ObjMesh, ObjError> {
    let io_err = |source| ObjError::Io {
        path: path.to_path_buf(),
        source,
    };
    let scan = scan_obj(path, BufReader::new(File::open(path).map_err(io_err)?))?;
    if scan.tri_pos.is_empty() {
        return Err(ObjError::Empty {
            path: path.to_path_buf(),
        });
    }

    let dir = path.parent().unwrap_or(Path::new(""));
    let mut materials = Vec::new();
    let mut by_name = HashMap::new();
    for (line, name) in &scan.mtllibs {
        let mtl = dir.join(name);
        let text = std::fs::read(&mtl).map_err(|source| ObjError::MissingMtl {
            path: path.to_path_buf(),
            line: *line,
            mtl: mtl.clone(),
            source,
        })?;
        for m in scan_mtl(&mtl, &text)? {
            match by_name.get(&m.name) {
                Some(&i) => materials[i as usize] = m,
                None => {
                    by_name.insert(m.name.clone(), materials.len() as u32);
                    materials.push(m);
                }
            }
        }
    }
    let mut name_to_material = Vec::with_capacity(scan.usemtl.len());
    for (line, name) in &scan.usemtl {
        match by_name.get(name) {
            Some(&i) => name_to_material.push(i),
            None => {
                return Err(ObjError::UnknownMaterial {
                    path: path.to_path_buf(),
                    line: *line,
                    name: name.clone(),
                });
            }
        }
    }
    let tri_material = scan
        .tri_usemtl
        .iter()
        .map(|&u| (u != NO_USEMTL).then(|| name_to_material[u as usize]))
        .collect();

    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let no_mtl = |_: &Path| Ok((Vec::new(), Default::default()));
    let mut reader = WithoutPolylines::new(BufReader::new(File::open(path).map_err(io_err)?));
    let (models, _) =
        tobj::load_obj_buf(&mut reader, &options, no_mtl).map_err(|source| ObjError::Parse {
            path: path.to_path_buf(),
            source,
        })?;
    assemble(path, &scan, models, materials, tri_material)
}

/// Joins `tobj`'s models in file order, checks them against the scan, and fills in
/// normals, texture coordinates and the degenerate count.
fn assemble(
    path: &Path,
    scan: &Scan,
    models: Vec<tobj::Model>,
    materials: Vec<ObjMaterial>,
    tri_material: Vec<Option<u32>>,
) -> Result<ObjMesh, ObjError> {
    let vertex_count: usize = models.iter().map(|m| m.mesh.positions.len() / 3).sum();
    let tri_count = scan.tri_pos.len() / 3;
    if vertex_count > u32::MAX as usize {
        return Err(ObjError::TooLarge {
            path: path.to_path_buf(),
            what: "vertices",
            max: u32::MAX as u64,
        });
    }
    let mismatch = |message: String| ObjError::Inconsistent {
        path: path.to_path_buf(),
        message,
    };
    let mut mesh = ObjMesh {
        positions: Vec::with_capacity(vertex_count),
        triangles: Vec::with_capacity(tri_count),
        materials,
        tri_material,
        ..Default::default()
    };
    let any_uv = scan.corner_vt_count > 0;
    let mut uvs_ok = any_uv;
    let mut uvs = Vec::with_capacity(if any_uv { vertex_count } else { 0 });
    let file_normals = scan.corner_count > 0 && scan.corner_vn_count == scan.corner_count;
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        let n = m.positions.len() / 3;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        if m.indices.len() % 3 != 0 {
            return Err(mismatch("index count not a multiple of 3".into()));
        }
        for t in m.indices.chunks_exact(3) {
            mesh.triangles.push([t[0] + base, t[1] + base, t[2] + base]);
        }
        if any_uv {
            if m.texcoords.len() == 2 * n {
                uvs.extend(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])));
            } else if m.texcoords.is_empty() {
                uvs.extend(std::iter::repeat_n(Vec2::ZERO, n));
            } else {
                uvs_ok = false;
            }
        }
        if file_normals {
            if m.normals.len() != 3 * n {
                return Err(mismatch("normal count".into()));
            }
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|v| Vec3::new(v[0], v[1], v[2]).normalize_or_zero()),
            );
        }
    }
    if mesh.triangles.len() != tri_count {
        return Err(mismatch(format!(
            "{} triangles from tobj, {} from the line scan",
            mesh.triangles.len(),
            tri_count
        )));
    }
    // Every corner must be the file's position: this pins the fan order and file order.
    let mut file_index = vec![u32::MAX; vertex_count];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for (c, &v) in tri.iter().enumerate() {
            let orig = scan.tri_pos[3 * t + c];
            let v = v as usize;
            if mesh.positions[v].to_array().map(f32::to_bits)
                != scan.positions[orig as usize].to_array().map(f32::to_bits)
            {
                return Err(mismatch(format!("corner {c} of triangle {t}")));
            }
            file_index[v] = orig;
        }
    }
    if uvs_ok {
        mesh.uvs = uvs;
    }
    mesh.normals_from_file = file_normals;
    if !file_normals {
        mesh.normals = smooth_normals(&scan.positions, &scan.tri_pos, &file_index);
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let n = (b - a).cross(c - a);
        let overflow = !n.is_finite();
        mesh.degenerate_count += (overflow || n == Vec3::ZERO) as u32;
        mesh.overflow_count += overflow as u32;
    }
    Ok(mesh)
}

/// Per-vertex normals: area-weighted face normals summed per file position (so faces
/// of different groups or texture seams that share a position are smoothed together),
/// then handed to every vertex made from that position.
fn smooth_normals(positions: &[Vec3], tri_pos: &[u32], file_index: &[u32]) -> Vec<Vec3> {
    let mut sum = vec![Vec3::ZERO; positions.len()];
    for t in tri_pos.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        if n.is_finite() {
            for &i in t {
                sum[i as usize] += n;
            }
        }
    }
    file_index
        .iter()
        .map(|&i| match sum.get(i as usize) {
            Some(n) => n.normalize_or_zero(),
            None => Vec3::ZERO,
        })
        .collect()
}

/// An OBJ file without its `l` (polyline) lines, for `tobj`, which reads a polyline of
/// three or more points as a face. Streams line by line.
struct WithoutPolylines<R> {
    inner: R,
    line: Vec<u8>,
    pos: usize,
}

impl<R: BufRead> WithoutPolylines<R> {
    fn new(inner: R) -> Self {
        WithoutPolylines {
            inner,
            line: Vec::new(),
            pos: 0,
        }
    }
}

impl<R: BufRead> Read for WithoutPolylines<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let available = self.fill_buf()?;
        let n = available.len().min(out.len());
        out[..n].copy_from_slice(&available[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for WithoutPolylines<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        while self.pos == self.line.len() {
            self.line.clear();
            self.pos = 0;
            if self.inner.read_until(b'\n', &mut self.line)? == 0 {
                break;
            }
            // Split as tobj splits (Unicode whitespace); other bytes pass unchanged.
            let first = std::str::from_utf8(&self.line)
                .ok()
                .and_then(|l| l.split_whitespace().next());
            if first == Some("l") {
                self.line.clear();
            }
        }
        Ok(&self.line[self.pos..])
    }

    fn consume(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.line.len());
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Writes `files` (name, contents) into a fresh folder and returns its path.
    pub(crate) fn folder(test: &str, files: &[(&str, &str)]) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("raypack-scene-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, text) in files {
            std::fs::write(dir.join(name), text).unwrap();
        }
        dir
    }

    /// The file's corner positions of triangle `t`.
    fn corners(m: &ObjMesh, t: usize) -> [Vec3; 3] {
        m.triangles[t].map(|i| m.positions[i as usize])
    }

    /// Position `i` (1-based) of [`FAN_OBJ`]: vertex `i` sits at `(i, i * i, 0)` so
    /// positions are distinct and identify their file index.
    fn p(i: u32) -> Vec3 {
        Vec3::new(i as f32, (i * i) as f32, 0.0)
    }

    const FAN_OBJ: &str = "\
v 1 1 0\nv 2 4 0\nv 3 9 0\nv 4 16 0\nv 5 25 0\nv 6 36 0\nv 7 49 0\nv 8 64 0
o first
f 1 2 3
f 4 5 6 7
g second
f 2 4 6 8 1
o third
f 8 7 6 5
f -1 -2 -3
";

    #[test]
    fn fan_order_and_ids_follow_the_file_across_groups() {
        let dir = folder("fan", &[("fan.obj", FAN_OBJ)]);
        let m = load(&dir.join("fan.obj")).unwrap();
        let expected: [[u32; 3]; 9] = [
            [1, 2, 3],
            [4, 5, 6],
            [4, 6, 7],
            [2, 4, 6],
            [2, 6, 8],
            [2, 8, 1],
            [8, 7, 6],
            [8, 6, 5],
            [8, 7, 6],
        ];
        assert_eq!(m.triangles.len(), expected.len());
        for (t, e) in expected.iter().enumerate() {
            assert_eq!(corners(&m, t), e.map(p), "triangle {t}");
        }
        assert_eq!(m.tri_material, vec![None; 9]);
        assert!(m.uvs.is_empty());
        assert!(!m.normals_from_file);
        assert_eq!(m.normals.len(), m.positions.len());
    }

    #[test]
    fn computed_normals_are_smooth_across_groups() {
        // Two triangles of a roof meeting at the ridge 2-3, in different groups.
        let obj = "v 0 0 0\nv 1 1 0\nv 1 1 1\nv 2 0 0\ng a\nf 1 2 3\ng b\nf 4 3 2\n";
        let dir = folder("smooth", &[("roof.obj", obj)]);
        let m = load(&dir.join("roof.obj")).unwrap();
        let n_left = (p3(1, 1, 0) - p3(0, 0, 0))
            .cross(p3(1, 1, 1) - p3(0, 0, 0))
            .normalize();
        for (v, pos) in m.positions.iter().enumerate() {
            let n = m.normals[v];
            if pos.x == 1.0 {
                // Ridge: the two faces' normals (1,-1,0) and (-1,-1,0) average to -y.
                assert!((n - Vec3::NEG_Y).length() < 1e-6, "ridge normal {n}");
            } else if pos.x == 0.0 {
                assert!((n - n_left).length() < 1e-6, "left normal {n}");
            }
        }
    }

    fn p3(x: i32, y: i32, z: i32) -> Vec3 {
        Vec3::new(x as f32, y as f32, z as f32)
    }

    #[test]
    fn uvs_normals_and_materials_come_from_the_files() {
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                   vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\nvn 0 0 2\n\
                   usemtl red\nf 1/1/1 2/2/1 3/3/1 4/4/1\n\
                   usemtl tex\nf 1/5/1 3/3/1 4/4/1\n";
        let mtl = "newmtl red\nKd 1 0 0\n\nnewmtl tex\nKd 0.5 0.5 0.5\nmap_Kd -s 1 1 1 t.png\n";
        let dir = folder(
            "attrs",
            &[("q.obj", obj), ("m.mtl", mtl), ("t.png", "not read here")],
        );
        let m = load(&dir.join("q.obj")).unwrap();
        assert_eq!(m.triangles.len(), 3);
        assert!(m.normals_from_file);
        assert!(m.normals.iter().all(|&n| n == Vec3::Z));
        assert_eq!(m.uvs.len(), m.positions.len());
        // Vertex 1 appears with uv 1 and with uv 5, so it is split in two.
        let uv_of = |t: usize, c: usize| m.uvs[m.triangles[t][c] as usize];
        assert_eq!(uv_of(0, 1), Vec2::new(1.0, 0.0));
        assert_eq!(uv_of(1, 1), Vec2::new(1.0, 1.0));
        assert_eq!(uv_of(1, 2), Vec2::new(0.0, 1.0));
        assert_eq!(uv_of(2, 0), Vec2::new(0.5, 0.5));
        assert_eq!(corners(&m, 2)[0], Vec3::ZERO);
        assert_eq!(m.tri_material, vec![Some(0), Some(0), Some(1)]);
        assert_eq!(m.materials[0].diffuse, Vec3::X);
        assert_eq!(m.materials[0].diffuse_texture, None);
        assert_eq!(m.materials[1].diffuse_texture, Some(dir.join("t.png")));
    }

    #[test]
    fn emission_is_ke_or_an_ambient_above_one() {
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n";
        let mtl = "newmtl lamp\nKa 20 20 20\nKd 1 1 1\n\
                   newmtl glow\nKa 30 30 30\nKe 1 2 3\n\
                   newmtl dim\nKa 0.2 0.2 0.2\n\
                   newmtl plain\nKd 0.5 0.5 0.5\n";
        let dir = folder("emission", &[("e.obj", obj), ("m.mtl", mtl)]);
        let m = load(&dir.join("e.obj")).unwrap();
        let emission: Vec<Vec3> = m.materials.iter().map(|m| m.emission).collect();
        assert_eq!(
            emission,
            [
                Vec3::splat(20.0),
                Vec3::new(1.0, 2.0, 3.0),
                Vec3::ZERO,
                Vec3::ZERO
            ]
        );
    }

    #[test]
    fn degenerate_triangles_keep_their_ids() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 3 3 3\nf 1 3 2\n";
        let dir = folder("degenerate", &[("d.obj", obj)]);
        let m = load(&dir.join("d.obj")).unwrap();
        assert_eq!(m.triangles.len(), 4);
        assert_eq!(m.degenerate_count, 2);
        assert_eq!(corners(&m, 3), [p3(0, 0, 0), p3(0, 1, 0), p3(1, 0, 0)]);
    }

    #[test]
    fn polylines_and_points_do_not_become_triangles() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\np 1\nf 1 2 3\nl 1 2\n";
        let dir = folder("polyline", &[("l.obj", obj)]);
        let m = load(&dir.join("l.obj")).unwrap();
        assert_eq!(m.triangles.len(), 1);
    }

    #[test]
    fn bad_lines_are_reported_with_their_line() {
        let cases: [(&str, &str); 8] = [
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n",
                "t.obj:4: f: index 0",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
                "t.obj:4: f: index 9 is out of range",
            ),
            (
                "v 0 0 0\nv 1 0 0\nf 1 2 -3\nv 0 1 0\n",
                "t.obj:3: f: index -3",
            ),
            ("v 0 0 0\nv 1 nan 0\n", "t.obj:2: v: value `nan`"),
            ("v 0 0 0\nv 1 1e39 0\n", "t.obj:2: v: value `1e39`"),
            ("v 0 0\n", "t.obj:1: v: needs 3 coordinates"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2 3\n",
                "texture coordinates",
            ),
            (
                "v 0 0 0\nv 1 0 0\nf 1 2\n",
                "t.obj:3: f: a face needs at least 3",
            ),
        ];
        for (i, (obj, want)) in cases.iter().enumerate() {
            let dir = folder(&format!("bad{i}"), &[("t.obj", obj)]);
            let e = load(&dir.join("t.obj")).unwrap_err().to_string();
            assert!(e.contains(want), "case {i}: `{e}` lacks `{want}`");
        }
    }
}
