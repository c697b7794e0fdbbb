//! The line scan of OBJ and MTL files that runs before `tobj`: it checks every
//! statement `tobj` interprets (so errors name the file and line, and malformed input
//! that `tobj` would accept or panic on is refused), records the file-order triangles
//! that `tobj`'s output is checked against, and is the only reader of MTL libraries.

use super::ObjMaterial;
use crate::scene::error::ObjError;
use glam::Vec3;
use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;

/// `tri_usemtl` value of a triangle before any `usemtl`.
pub(super) const NO_USEMTL: u32 = u32::MAX;

/// What the line scan of an OBJ file found.
#[derive(Default)]
pub(super) struct Scan {
    pub(super) positions: Vec<Vec3>,
    /// File position index of every triangle corner, 3 per triangle, in file order.
    pub(super) tri_pos: Vec<u32>,
    /// Index into `usemtl` of every triangle's material name.
    pub(super) tri_usemtl: Vec<u32>,
    /// Distinct `usemtl` names with the line of their first use.
    pub(super) usemtl: Vec<(usize, String)>,
    pub(super) mtllibs: Vec<(usize, String)>,
    pub(super) corner_count: u64,
    pub(super) corner_vt_count: u64,
    pub(super) corner_vn_count: u64,
}

/// The line scan: checks every statement `tobj` interprets and records triangles.
pub(super) fn scan_obj(path: &Path, mut reader: impl BufRead) -> Result<Scan, ObjError> {
    let mut scan = Scan::default();
    let mut usemtl_index: HashMap<String, u32> = HashMap::new();
    let mut current_usemtl = NO_USEMTL;
    let mut texcoord_count = 0usize;
    let mut normal_count = 0usize;
    // First `v` line with and without vertex colours (tobj fails on a mix).
    let mut colour_lines: [Option<usize>; 2] = [None, None];
    let mut buf = Vec::new();
    let mut face = Vec::new();
    let mut line_no = 0usize;
    loop {
        buf.clear();
        let n = reader
            .read_until(b'\n', &mut buf)
            .map_err(|source| ObjError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let malformed = |element: &str, message: String| ObjError::Malformed {
            path: path.to_path_buf(),
            line: line_no,
            element: element.to_string(),
            message,
        };
        let Ok(line) = std::str::from_utf8(&buf) else {
            return Err(malformed("line", "not UTF-8 text".into()));
        };
        let mut words = line.split_whitespace();
        let Some(element) = words.next() else {
            continue;
        };
        match element {
            "v" => {
                let mut p = [0f32; 3];
                for (k, slot) in p.iter_mut().enumerate() {
                    *slot = number(path, line_no, "v", words.next(), || {
                        format!("needs 3 coordinates, found {k}")
                    })?;
                }
                let extra: Vec<&str> = words.collect();
                match extra.len() {
                    0 => colour_lines[1].get_or_insert(line_no),
                    1 => {
                        let w = number(path, line_no, "v", Some(extra[0]), String::new)?;
                        if w == 0.0 {
                            return Err(malformed("v", "weight w is 0".into()));
                        }
                        for c in &mut p {
                            *c /= w;
                        }
                        colour_lines[1].get_or_insert(line_no)
                    }
                    3 => {
                        for e in &extra {
                            number(path, line_no, "v", Some(e), String::new)?;
                        }
                        colour_lines[0].get_or_insert(line_no)
                    }
                    k => {
                        return Err(malformed(
                            "v",
                            format!(
                                "expected x y z, x y z w or x y z r g b; found {} numbers",
                                3 + k
                            ),
                        ));
                    }
                };
                if let [Some(a), Some(b)] = colour_lines {
                    return Err(malformed(
                        "v",
                        format!(
                            "vertex colours on some `v` lines only (line {a} has them, line {b} not)"
                        ),
                    ));
                }
                let p = Vec3::from_array(p);
                if !p.is_finite() {
                    return Err(ObjError::NonFinite {
                        path: path.to_path_buf(),
                        line: line_no,
                        element: "v".into(),
                        value: format!("{p}"),
                    });
                }
                scan.positions.push(p);
            }
            "vt" => {
                for k in 0..2 {
                    number(path, line_no, "vt", words.next(), || {
                        format!("needs 2 coordinates, found {k}")
                    })?;
                }
                texcoord_count += 1;
            }
            "vn" => {
                for k in 0..3 {
                    number(path, line_no, "vn", words.next(), || {
                        format!("needs 3 components, found {k}")
                    })?;
                }
                normal_count += 1;
            }
            "f" => {
                face.clear();
                let counts = [scan.positions.len(), texcoord_count, normal_count];
                for word in words {
                    let mut parts = [None; 3];
                    for (k, part) in word.split('/').enumerate() {
                        if k >= 3 {
                            return Err(malformed("f", format!("`{word}` has more than v/vt/vn")));
                        }
                        if part.is_empty() {
                            continue;
                        }
                        let Ok(x) = part.parse::<i64>() else {
                            return Err(malformed("f", format!("`{part}` is not an index")));
                        };
                        parts[k] = Some(resolve(path, line_no, k, x, counts[k])?);
                    }
                    let Some(v) = parts[0] else {
                        return Err(malformed("f", format!("`{word}` has no vertex index")));
                    };
                    scan.corner_count += 1;
                    scan.corner_vt_count += parts[1].is_some() as u64;
                    scan.corner_vn_count += parts[2].is_some() as u64;
                    face.push(v);
                }
                if face.len() < 3 {
                    return Err(malformed(
                        "f",
                        format!("a face needs at least 3 vertices, found {}", face.len()),
                    ));
                }
                if (scan.tri_pos.len() / 3 + face.len() - 2) > u32::MAX as usize {
                    return Err(ObjError::TooLarge {
                        path: path.to_path_buf(),
                        what: "triangles",
                        max: u32::MAX as u64,
                    });
                }
                for i in 1..face.len() - 1 {
                    scan.tri_pos.extend([face[0], face[i], face[i + 1]]);
                    scan.tri_usemtl.push(current_usemtl);
                }
            }
            "mtllib" | "usemtl" => {
                let name = line.trim()[element.len()..].trim();
                if name.is_empty() {
                    return Err(malformed(element, "needs a name".into()));
                }
                if element == "mtllib" {
                    scan.mtllibs.push((line_no, name.to_string()));
                } else {
                    current_usemtl = match usemtl_index.get(name) {
                        Some(&i) => i,
                        None => {
                            let i = scan.usemtl.len() as u32;
                            usemtl_index.insert(name.to_string(), i);
                            scan.usemtl.push((line_no, name.to_string()));
                            i
                        }
                    };
                }
            }
            _ => {}
        }
    }
    if scan.positions.len() > u32::MAX as usize {
        return Err(ObjError::TooLarge {
            path: path.to_path_buf(),
            what: "vertices",
            max: u32::MAX as u64,
        });
    }
    Ok(scan)
}

pub(super) const KIND_NAMES: [&str; 3] = ["vertices", "texture coordinates", "normals"];

/// Turns a 1-based (or negative, relative) index of kind `k` into a 0-based one. Both
/// must name one of the `count` elements defined above the face: `tobj` cannot resolve
/// an index pointing forward past a `g`, `o` or `usemtl` line (it closes the mesh there)
/// and reports it without a line, so raypack refuses every forward index at its line.
fn resolve(path: &Path, line: usize, k: usize, x: i64, count: usize) -> Result<u32, ObjError> {
    let out_of_range = || ObjError::IndexOutOfRange {
        path: path.to_path_buf(),
        line,
        element: "f",
        index: x,
        count,
        what: KIND_NAMES[k],
    };
    if x == 0 {
        return Err(ObjError::ZeroIndex {
            path: path.to_path_buf(),
            line,
            element: "f",
        });
    }
    let i = if x < 0 { count as i64 + x } else { x - 1 };
    if i < 0 || i >= count as i64 {
        return Err(out_of_range());
    }
    Ok(i as u32)
}

/// Parses one number of an OBJ or MTL statement as `tobj` does (`f32::from_str`) and
/// requires it to be finite.
fn number(
    path: &Path,
    line: usize,
    element: &str,
    word: Option<&str>,
    missing: impl FnOnce() -> String,
) -> Result<f32, ObjError> {
    let Some(word) = word else {
        return Err(ObjError::Malformed {
            path: path.to_path_buf(),
            line,
            element: element.into(),
            message: missing(),
        });
    };
    match word.parse::<f32>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(_) => Err(ObjError::NonFinite {
            path: path.to_path_buf(),
            line,
            element: element.into(),
            value: word.to_string(),
        }),
        Err(_) => Err(ObjError::Malformed {
            path: path.to_path_buf(),
            line,
            element: element.into(),
            message: format!("`{word}` is not a number"),
        }),
    }
}

/// Reads an MTL library: checks every statement raypack or `tobj` would interpret and
/// returns the materials with their diffuse colour and diffuse texture.
pub(super) fn scan_mtl(path: &Path, text: &[u8]) -> Result<Vec<ObjMaterial>, ObjError> {
    let mut out: Vec<ObjMaterial> = Vec::new();
    // `Ke` and `Ka` of each material, resolved into `emission` at the end.
    let mut emitted: Vec<(Option<Vec3>, Option<Vec3>)> = Vec::new();
    let dir = path.parent().unwrap_or(Path::new(""));
    for (i, raw) in text.split(|&b| b == b'\n').enumerate() {
        let line_no = i + 1;
        let malformed = |element: &str, message: String| ObjError::Malformed {
            path: path.to_path_buf(),
            line: line_no,
            element: element.to_string(),
            message,
        };
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(malformed("line", "not UTF-8 text".into()));
        };
        let line = line.trim();
        let mut words = line.split_whitespace();
        let Some(element) = words.next() else {
            continue;
        };
        let rest = line[element.len()..].trim();
        let current = out.last_mut();
        match element {
            "newmtl" => {
                if rest.is_empty() {
                    return Err(malformed(element, "needs a name".into()));
                }
                out.push(ObjMaterial {
                    name: rest.to_string(),
                    diffuse: Vec3::splat(0.8),
                    diffuse_texture: None,
                    emission: Vec3::ZERO,
                });
                emitted.push((None, None));
            }
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" => {
                let mut c = [0f32; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    *slot = number(path, line_no, element, words.next(), || {
                        format!("needs 3 numbers, found {k}")
                    })?;
                }
                if matches!(element, "Kd" | "Ke" | "Ka") {
                    let Some(m) = current else {
                        return Err(malformed(element, "comes before any `newmtl`".into()));
                    };
                    let c = Vec3::from_array(c);
                    let e = emitted.last_mut().expect("one entry per material");
                    match element {
                        "Kd" => m.diffuse = c,
                        "Ke" => e.0 = Some(c),
                        _ => e.1 = Some(c),
                    }
                }
            }
            "Ns" | "Ni" | "d" | "Tr" => {
                number(path, line_no, element, words.next(), || {
                    "needs a number".into()
                })?;
            }
            "illum" if words.next().and_then(|w| w.parse::<u8>().ok()).is_none() => {
                return Err(malformed(element, "needs an integer 0 to 255".into()));
            }
            e if e.starts_with("map_") || e == "bump" => {
                // Options (`-s 1 1 1 file.png`) come first; the file name is last.
                let file = if rest.starts_with('-') {
                    rest.split_whitespace().last().unwrap_or("")
                } else {
                    rest
                };
                if file.is_empty() {
                    return Err(malformed(element, "needs a file name".into()));
                }
                if e == "map_Kd" {
                    let Some(m) = current else {
                        return Err(malformed(element, "comes before any `newmtl`".into()));
                    };
                    let texture = dir.join(file);
                    if !texture.is_file() {
                        return Err(ObjError::MissingTexture {
                            path: path.to_path_buf(),
                            line: line_no,
                            texture,
                        });
                    }
                    m.diffuse_texture = Some(texture);
                }
            }
            _ => {}
        }
    }
    for (m, (ke, ka)) in out.iter_mut().zip(emitted) {
        m.emission = super::emission_of(ke, ka);
    }
    Ok(out)
}
