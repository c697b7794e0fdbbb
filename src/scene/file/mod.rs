//! TOML scene files (documented key by key in scenes/README.md).
//!
//! Stage: scene input. Entry points: [`load`] (a file) and [`parse`] (text with the path
//! it came from, which names errors and anchors relative mesh and texture paths).
//!
//! The document is parsed into `toml`'s spanned tree and read by hand rather than through
//! serde, so every check (unknown key, wrong type, value out of range) knows the byte
//! span of what it rejects and reports `file:line: key: what is wrong`. Unknown keys come
//! with the nearest valid key. No input makes the reader panic: every number is range
//! checked before use, and counts that size allocations have limits.
//!
//! Three parts, each below the one before: `schema` (what every section may hold) reads
//! through `reader` (the spanned tree, typed and range-checked reads, errors with line
//! and key) into `build` (the scene under construction, material names, mesh
//! placement).
//!
//! Primitive ids of the scene follow `Geometry`: the triangles of all `[[meshes]]` in
//! file order (each mesh's in OBJ order), then `[[spheres]]`, `[[boxes]]`, `[[planes]]`.

mod build;
mod reader;
mod schema;

use super::Scene;
use super::error::{SceneError, Warning};
use reader::{Doc, Section};
use std::path::Path;
use toml::de::DeTable;

/// Largest image side a scene may ask for.
pub const MAX_SIDE: u32 = 16384;
/// Largest pixel count a scene may ask for (8192 x 8192). The CLI holds its `--width`
/// and `--height` flags and the ray sets to the same limits, so no way in asks for more.
pub const MAX_PIXELS: u64 = 1 << 26;
/// Largest `max_depth` (reflection and refraction bounces) a scene may ask for.
pub const MAX_DEPTH: u32 = 64;
/// Largest per-point sample count (`glossy_samples`, an area light's `samples`): the
/// work per shading point grows linearly with it.
pub const MAX_SAMPLES: u32 = 4096;
/// Largest `antialias_n`: `n x n` rays per pixel, so 256 at most.
pub const MAX_ANTIALIAS_N: u32 = 16;
/// Largest side of a generated texture.
pub const MAX_PROCEDURAL_SIDE: u32 = 4096;
/// Texels of all `[textures]` of a scene together (768 MiB of linear RGB).
pub const MAX_TEXELS: u64 = 1 << 26;

/// Reads and checks the scene file at `path`.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with_warnings(path).map(|(scene, _)| scene)
}

/// [`load`], also returning what the user should be warned about (degenerate triangles
/// of its meshes, one warning per mesh file).
pub fn load_with_warnings(path: &Path) -> Result<(Scene, Vec<Warning>), SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match std::str::from_utf8(&bytes) {
        Ok(text) => parse_with_warnings(path, text),
        Err(e) => {
            let before = &bytes[..e.valid_up_to()];
            Err(SceneError::Syntax {
                path: path.to_path_buf(),
                line: 1 + before.iter().filter(|&&b| b == b'\n').count(),
                message: "the file is not UTF-8 text".into(),
            })
        }
    }
}

/// Builds a scene from the TOML `text` of the file at `path`.
pub fn parse(path: &Path, text: &str) -> Result<Scene, SceneError> {
    parse_with_warnings(path, text).map(|(scene, _)| scene)
}

/// [`parse`], also returning the warnings of [`load_with_warnings`].
pub fn parse_with_warnings(path: &Path, text: &str) -> Result<(Scene, Vec<Warning>), SceneError> {
    let doc = Doc::new(path, text);
    let root = DeTable::parse(text).map_err(|e| SceneError::Syntax {
        path: path.to_path_buf(),
        line: match e.span() {
            Some(s) => doc.line(s.start),
            None => doc.first_failing_line(text, e.message()),
        },
        message: e.message().trim().to_string(),
    })?;
    let root = Section {
        table: root.get_ref(),
        name: String::new(),
        span: root.span(),
    };
    doc.build(&root)
}

#[cfg(test)]
mod tests {
    use super::build::{rotation_deg, sin_cos_deg};
    use super::reader::Doc;
    use super::*;
    use crate::scene::obj::tests::folder;
    use crate::scene::{Light, Material, PrimRef, RenderSettings};
    use glam::Vec3;
    use std::ops::Range;

    const CAMERA: &str = "[camera]\neye = [0, 0, -5]\ntarget = [0, 0, 0]\n";

    #[test]
    fn ids_run_meshes_spheres_boxes_planes_with_their_materials() {
        let text = format!(
            "{CAMERA}
[materials.red]
color = [1, 0, 0]
[[planes]]
normal = [0, 2, 0]
point = [0, -1, 0]
[[spheres]]
center = [0, 0, 0]
radius = 1
material = \"red\"
[[boxes]]
min = [0, 0, 0]
max = [1, 1, 1]
[[meshes]]
file = \"quad.obj\"
scale = [2, 1, 1]
translate = [0, 0, 3]
"
        );
        let obj =
            "mtllib q.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nusemtl blue\nf 1 3 4\n";
        let mtl = "newmtl blue\nKd 0 0 1\n";
        let dir = folder(
            "ids",
            &[("s.toml", &text), ("quad.obj", obj), ("q.mtl", mtl)],
        );
        let s = load(&dir.join("s.toml")).unwrap();
        let g = &s.geometry;
        assert_eq!(g.prim_count(), 5);
        assert_eq!(g.prim_ref(0), PrimRef::Triangle(0));
        assert_eq!(g.prim_ref(2), PrimRef::Sphere(0));
        assert_eq!(g.prim_ref(3), PrimRef::Box(0));
        assert_eq!(g.prim_ref(4), PrimRef::Plane(0));
        assert_eq!(g.planes[0].normal, Vec3::Y);
        assert_eq!(g.planes[0].offset, -1.0);
        assert_eq!(g.triangle(0)[1], Vec3::new(2.0, 0.0, 3.0));
        assert_eq!(s.material(2).color, Vec3::X);
        assert_eq!(
            s.material(1).color,
            Vec3::Z,
            "MTL material of the second triangle"
        );
        let default = Material::default();
        for p in [0, 3, 4] {
            assert_eq!(s.material(p), &default, "prim {p}");
        }
        assert_eq!(s.normals.len(), g.vertices.len());
    }

    #[test]
    fn area_light_from_center_and_size_is_a_horizontal_rectangle() {
        let text = format!(
            "{CAMERA}[[spheres]]\ncenter = [0, 0, 0]\nradius = 1\n\
             [[lights]]\nkind = \"area\"\ncenter = [1, 5, 2]\nsize = [2, 4]\nsamples = 9\n"
        );
        let s = parse(Path::new("mem.toml"), &text).unwrap();
        assert_eq!(
            s.lights[0],
            Light::Area {
                corner: Vec3::new(0.0, 5.0, 0.0),
                edge_u: Vec3::new(2.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 4.0),
                color: Vec3::ONE,
                samples: 9,
            }
        );
    }

    #[test]
    fn defaults_fill_what_the_file_leaves_out() {
        let text = format!("{CAMERA}[[spheres]]\ncenter = [0, 0, 0]\nradius = 1\n");
        let s = parse(Path::new("mem.toml"), &text).unwrap();
        assert_eq!(s.settings, RenderSettings::default());
        assert_eq!(s.camera.up, Vec3::Y);
        assert_eq!(s.camera.vfov_deg, 60.0);
        assert_eq!(s.materials, vec![Material::default()]);
    }

    /// One triangle at (1, 0, 0), (0, 1, 0), (0, 0, 1) with per-corner normals (1, 0, 0),
    /// placed by the mesh keys `keys`.
    fn placed_triangle(name: &str, keys: &str) -> Scene {
        let text = format!("{CAMERA}[[meshes]]\nfile = \"t.obj\"\n{keys}\n");
        let obj = "v 1 0 0\nv 0 1 0\nv 0 0 1\nvn 1 0 0\nf 1//1 2//1 3//1\n";
        let dir = folder(name, &[("s.toml", &text), ("t.obj", obj)]);
        load(&dir.join("s.toml")).unwrap()
    }

    fn assert_close(got: Vec3, want: Vec3, what: &str) {
        assert!(
            (got - want).abs().max_element() < 1e-6,
            "{what}: got {got}, want {want}"
        );
    }

    #[test]
    fn quarter_turn_about_y_is_exact_and_turns_normals() {
        // Right-hand rule about +y: x goes to -z, z goes to x.
        for keys in [
            "rotate = [0, 90, 0]",
            "rotate = [0, -270, 0]",
            "rotate_axis = [0, 2, 0]\nrotate_angle = 90",
            "rotate_axis = [0, 3e38, 0]\nrotate_angle = 450",
        ] {
            let s = placed_triangle("quarter", keys);
            let v = &s.geometry.vertices;
            assert_eq!(v[0], Vec3::new(0.0, 0.0, -1.0), "{keys}");
            assert_eq!(v[1], Vec3::Y, "{keys}");
            assert_eq!(v[2], Vec3::X, "{keys}");
            assert_eq!(s.normals[0], Vec3::new(0.0, 0.0, -1.0), "{keys}");
        }
    }

    #[test]
    fn euler_angles_apply_x_then_y_then_z() {
        // x 90 takes y to z; y 90 takes that z to x; z 90 takes x to y.
        let s = placed_triangle("euler", "rotate = [90, 90, 90]");
        assert_eq!(s.geometry.vertices[1], Vec3::Y);
        // The reverse order would move y elsewhere: z 90 first sends y to -x.
        let r =
            rotation_deg(Vec3::X, 90.0) * rotation_deg(Vec3::Y, 90.0) * rotation_deg(Vec3::Z, 90.0);
        assert_ne!(r * Vec3::Y, Vec3::Y);
    }

    #[test]
    fn scale_then_rotate_then_translate() {
        let s = placed_triangle(
            "order",
            "scale = [2, 3, 4]\nrotate = [0, 0, 90]\ntranslate = [10, 20, 30]",
        );
        // (1,0,0) -> (2,0,0) -> z 90 -> (0,2,0) -> (10,22,30).
        assert_eq!(s.geometry.vertices[0], Vec3::new(10.0, 22.0, 30.0));
        // (0,1,0) -> (0,3,0) -> (-3,0,0) -> (7,20,30).
        assert_eq!(s.geometry.vertices[1], Vec3::new(7.0, 20.0, 30.0));
        assert_eq!(s.geometry.vertices[2], Vec3::new(10.0, 20.0, 34.0));
        // The normal (1,0,0) divides by the scale, then turns with the mesh: (0,1,0).
        assert_eq!(s.normals[0], Vec3::Y);
    }

    #[test]
    fn axis_angle_about_the_diagonal_permutes_the_axes() {
        // 120 degrees about (1,1,1) takes x to y, y to z, z to x.
        let s = placed_triangle("diag", "rotate_axis = [1, 1, 1]\nrotate_angle = 120");
        let v = &s.geometry.vertices;
        assert_close(v[0], Vec3::Y, "x");
        assert_close(v[1], Vec3::Z, "y");
        assert_close(v[2], Vec3::X, "z");
        assert_close(s.normals[0], Vec3::Y, "normal");
    }

    #[test]
    fn rotations_keep_lengths_and_normals_perpendicular() {
        let a = Vec3::new(0.3, -1.2, 0.7).normalize();
        for degrees in [-725.0, -30.0, 1.0, 45.0, 137.5, 359.0] {
            let r = rotation_deg(a, degrees);
            assert_close(r * a, a, "the axis stays put");
            let p = Vec3::new(1.0, 2.0, -3.0);
            assert!(((r * p).length() - p.length()).abs() < 1e-5, "{degrees}");
            let (sin, cos) = sin_cos_deg(degrees);
            assert!((sin * sin + cos * cos - 1.0).abs() < 1e-6, "{degrees}");
            // The angle between p's projection and its image is `degrees`.
            let q = p - a * a.dot(p);
            let rq = r * q;
            assert!((q.cross(rq).dot(a) / q.length_squared() - sin).abs() < 1e-5);
            assert!((q.dot(rq) / q.length_squared() - cos).abs() < 1e-5);
        }
        // A rotated, non-uniformly scaled mesh keeps normals perpendicular to its faces.
        let s = placed_triangle("perp", "scale = [1, 2, 5]\nrotate = [20, -40, 75]");
        let v = &s.geometry.vertices;
        let n = s.normals[0];
        assert!((n.length() - 1.0).abs() < 1e-6);
        // The OBJ's normal (1,0,0) is not the face normal, but the transform must map the
        // plane it is perpendicular to (x = 0: edge v1 - v2) onto one still perpendicular.
        assert!(n.dot(v[1] - v[2]).abs() < 1e-5, "{n} vs {:?}", v[1] - v[2]);
    }

    /// The transform example of scenes/README.md loads, and its flat knot is flat.
    #[test]
    fn readme_transform_example_loads() {
        let readme = include_str!("../../../scenes/README.md");
        let start = readme.find("```toml\n").expect("a toml block") + 8;
        let len = readme[start..].find("```").expect("the block ends");
        let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let s = parse(&scenes.join("example.toml"), &readme[start..start + len]).unwrap();
        let v = &s.geometry.vertices;
        let third = v.len() / 3;
        let y = |r: Range<usize>| {
            v[r].iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                (lo.min(p.y), hi.max(p.y))
            })
        };
        let (upright, flat) = (y(0..third), y(third..2 * third));
        assert!(
            upright.1 - upright.0 > 2.5,
            "upright knot spans {upright:?}"
        );
        assert!(flat.1 - flat.0 < 1.2, "flat knot spans {flat:?}");
        assert!(
            (flat.0 + 1.5).abs() < 1e-3,
            "the flat knot rests on the floor: {flat:?}"
        );
    }

    #[test]
    fn lines_are_counted_from_one() {
        let doc = Doc::new(Path::new("x"), "a\nbb\n\nc");
        assert_eq!([0, 1, 2, 4, 5, 6].map(|o| doc.line(o)), [1, 1, 2, 2, 3, 4]);
    }
}
