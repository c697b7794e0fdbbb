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
//! Primitive ids of the scene follow `Geometry`: the triangles of all `[[meshes]]` in
//! file order (each mesh's in OBJ order), then `[[spheres]]`, `[[boxes]]`, `[[planes]]`.

use super::error::{SceneError, TextureError, Warning};
use super::obj::{self, ObjMesh};
use super::texture::{self, Procedural};
use super::{
    Aabb, AntiAlias, Camera, Light, Material, Plane, RenderSettings, Scene, Sphere, Texture,
};
use glam::{Mat3, Vec2, Vec3};
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;
use toml::de::{DeTable, DeValue};

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

/// The file being read: its path, folder and line starts.
struct Doc<'a> {
    path: &'a Path,
    dir: PathBuf,
    line_starts: Vec<usize>,
}

/// A table of the document with its dotted name (`materials.glass`, `spheres[2]`).
struct Section<'t, 'i> {
    table: &'t DeTable<'i>,
    name: String,
    span: Range<usize>,
}

type Value<'t, 'i> = &'t Spanned<DeValue<'i>>;

impl<'t, 'i> Section<'t, 'i> {
    fn key(&self, k: &str) -> String {
        if self.name.is_empty() {
            k.to_string()
        } else {
            format!("{}.{k}", self.name)
        }
    }

    fn get(&self, k: &str) -> Option<Value<'t, 'i>> {
        self.table
            .iter()
            .find(|(key, _)| key.get_ref().as_ref() == k)
            .map(|(_, v)| v)
    }
}

fn is_number(v: &DeValue) -> bool {
    matches!(v, DeValue::Integer(_) | DeValue::Float(_))
}

impl<'a> Doc<'a> {
    fn new(path: &'a Path, text: &str) -> Doc<'a> {
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Doc {
            path,
            dir: path.parent().unwrap_or(Path::new("")).to_path_buf(),
            line_starts,
        }
    }

    /// 1-based line of byte `offset`.
    fn line(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&s| s <= offset).max(1)
    }

    /// The line of a TOML error reported without a position (the parser's recursion
    /// limit on deeply nested dotted keys): the first line whose prefix of the file fails
    /// with the same `message`, found by bisection (`O(n log n)`, on the error path only).
    fn first_failing_line(&self, text: &str, message: &str) -> usize {
        let fails = |lines: usize| {
            let end = self.line_starts.get(lines).map_or(text.len(), |&e| e);
            DeTable::parse(&text[..end]).is_err_and(|e| e.message() == message)
        };
        let (mut lo, mut hi) = (1, self.line_starts.len());
        if !fails(hi) {
            return 0;
        }
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if fails(mid) { hi = mid } else { lo = mid + 1 }
        }
        lo
    }

    fn invalid(&self, span: &Range<usize>, key: String, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            line: self.line(span.start),
            key,
            message: message.into(),
        }
    }

    /// Rejects keys of `s` not in `allowed`, suggesting the closest allowed one.
    fn check_keys(&self, s: &Section, allowed: &[&str]) -> Result<(), SceneError> {
        for (key, _) in s.table.iter() {
            let k: &str = key.get_ref().as_ref();
            if allowed.contains(&k) {
                continue;
            }
            let suggestion = allowed
                .iter()
                .map(|a| (strsim::damerau_levenshtein(k, a), *a))
                .min()
                .filter(|&(d, a)| d <= (a.len().max(k.len()) / 3).max(2))
                .map(|(_, a)| a.to_string());
            return Err(SceneError::UnknownKey {
                path: self.path.to_path_buf(),
                line: self.line(key.span().start),
                key: s.key(k),
                suggestion,
            });
        }
        Ok(())
    }

    fn required<'t, 'i>(&self, s: &Section<'t, 'i>, k: &str) -> Result<Value<'t, 'i>, SceneError> {
        s.get(k)
            .ok_or_else(|| self.invalid(&s.span, s.key(k), "missing (this key is required)"))
    }

    fn wrong_type(&self, v: &Spanned<DeValue>, key: String, want: &str) -> SceneError {
        self.invalid(
            &v.span(),
            key,
            format!("expected {want}, found {}", v.get_ref().type_str()),
        )
    }

    /// A finite number that fits an `f32` (integers are accepted).
    fn number(&self, v: &Spanned<DeValue>, key: &str) -> Result<f32, SceneError> {
        let x = match v.get_ref() {
            DeValue::Float(f) => f.as_str().parse::<f64>().ok(),
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|i| i as f64),
            _ => return Err(self.wrong_type(v, key.into(), "a number")),
        };
        match x.map(|x| x as f32) {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.invalid(
                &v.span(),
                key.into(),
                "not a finite number (NaN, infinite, or too large for 32-bit floats)",
            )),
        }
    }

    fn integer(&self, v: &Spanned<DeValue>, key: &str) -> Result<i64, SceneError> {
        match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .map_err(|_| self.invalid(&v.span(), key.into(), "integer too large")),
            _ => Err(self.wrong_type(v, key.into(), "an integer")),
        }
    }

    fn string<'v>(&self, v: &'v Spanned<DeValue>, key: &str) -> Result<&'v str, SceneError> {
        v.get_ref()
            .as_str()
            .ok_or_else(|| self.wrong_type(v, key.into(), "a string"))
    }

    fn vector<const N: usize>(
        &self,
        v: &Spanned<DeValue>,
        key: &str,
    ) -> Result<[f32; N], SceneError> {
        let want = || format!("an array of {N} numbers");
        let Some(items) = v.get_ref().as_array() else {
            return Err(self.wrong_type(v, key.into(), &want()));
        };
        if items.len() != N || !items.iter().all(|i| is_number(i.get_ref())) {
            return Err(self.invalid(&v.span(), key.into(), format!("expected {}", want())));
        }
        let mut out = [0.0; N];
        for (o, i) in out.iter_mut().zip(items.iter()) {
            *o = self.number(i, key)?;
        }
        Ok(out)
    }

    /// Optional number in `range` (inclusive ends), with `default`.
    fn f32_in(
        &self,
        s: &Section,
        k: &str,
        default: f32,
        range: (f32, f32),
    ) -> Result<f32, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(default);
        };
        let x = self.number(v, &s.key(k))?;
        if x < range.0 || x > range.1 {
            return Err(self.invalid(
                &v.span(),
                s.key(k),
                format!("{x} is out of range; valid: {} to {}", range.0, range.1),
            ));
        }
        Ok(x)
    }

    /// Optional number greater than 0 and at most `max`, with `default`.
    fn positive(&self, s: &Section, k: &str, default: f32, max: f32) -> Result<f32, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(default);
        };
        let x = self.number(v, &s.key(k))?;
        if !(x > 0.0 && x <= max) {
            return Err(self.invalid(
                &v.span(),
                s.key(k),
                format!("{x} is out of range; must be > 0 and <= {max}"),
            ));
        }
        Ok(x)
    }

    /// Optional integer in `lo..=hi`, with `default`.
    fn u32_in(
        &self,
        s: &Section,
        k: &str,
        default: u32,
        lo: u32,
        hi: u32,
    ) -> Result<u32, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(default);
        };
        let x = self.integer(v, &s.key(k))?;
        if x < lo as i64 || x > hi as i64 {
            return Err(self.invalid(
                &v.span(),
                s.key(k),
                format!("{x} is out of range; valid: {lo} to {hi}"),
            ));
        }
        Ok(x as u32)
    }

    fn vec3(&self, s: &Section, k: &str, default: Option<Vec3>) -> Result<Vec3, SceneError> {
        match (s.get(k), default) {
            (Some(v), _) => Ok(Vec3::from_array(self.vector::<3>(v, &s.key(k))?)),
            (None, Some(d)) => Ok(d),
            (None, None) => Err(self.required(s, k).unwrap_err()),
        }
    }

    /// A colour: three numbers, each >= 0.
    fn color(&self, s: &Section, k: &str, default: Vec3) -> Result<Vec3, SceneError> {
        let c = self.vec3(s, k, Some(default))?;
        if c.min_element() < 0.0 {
            let span = s.get(k).map_or(s.span.clone(), |v| v.span());
            return Err(self.invalid(&span, s.key(k), "colour components must be >= 0"));
        }
        Ok(c)
    }

    fn nonzero_vec3(&self, s: &Section, k: &str) -> Result<(Vec3, Range<usize>), SceneError> {
        let v = self.required(s, k)?;
        let x = Vec3::from_array(self.vector::<3>(v, &s.key(k))?);
        if x.length_squared() == 0.0 || !x.length_squared().is_finite() {
            return Err(self.invalid(&v.span(), s.key(k), "must be a non-zero vector"));
        }
        Ok((x, v.span()))
    }

    /// The named sub-table `k` of `s`, if present.
    fn table<'t, 'i>(
        &self,
        s: &Section<'t, 'i>,
        k: &str,
    ) -> Result<Option<Section<'t, 'i>>, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(None);
        };
        match v.get_ref().as_table() {
            Some(t) => Ok(Some(Section {
                table: t,
                name: s.key(k),
                span: v.span(),
            })),
            None => Err(self.wrong_type(v, s.key(k), "a table")),
        }
    }

    /// The tables of array `k` (`[[k]]`), named `k[0]`, `k[1]`, ...
    fn tables<'t, 'i>(
        &self,
        s: &Section<'t, 'i>,
        k: &str,
    ) -> Result<Vec<Section<'t, 'i>>, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(Vec::new());
        };
        let Some(items) = v.get_ref().as_array() else {
            return Err(self.wrong_type(v, s.key(k), "an array of tables ([[...]])"));
        };
        items
            .iter()
            .enumerate()
            .map(|(i, item)| match item.get_ref().as_table() {
                Some(t) => Ok(Section {
                    table: t,
                    name: format!("{}[{i}]", s.key(k)),
                    span: item.span(),
                }),
                None => Err(self.wrong_type(item, format!("{}[{i}]", s.key(k)), "a table")),
            })
            .collect()
    }

    /// The file named by key `k`, relative to the scene file's folder.
    fn file(&self, s: &Section, k: &str) -> Result<(PathBuf, Range<usize>), SceneError> {
        let v = self.required(s, k)?;
        let name = self.string(v, &s.key(k))?;
        if name.is_empty() {
            return Err(self.invalid(&v.span(), s.key(k), "empty file name"));
        }
        Ok((self.dir.join(name), v.span()))
    }

    fn build(&self, root: &Section) -> Result<(Scene, Vec<Warning>), SceneError> {
        self.check_keys(
            root,
            &[
                "camera",
                "render",
                "textures",
                "materials",
                "lights",
                "spheres",
                "planes",
                "boxes",
                "meshes",
            ],
        )?;
        let mut scene = Scene {
            camera: self.camera(root)?,
            settings: match self.table(root, "render")? {
                Some(r) => self.render(&r)?,
                None => RenderSettings::default(),
            },
            ..Default::default()
        };
        let mut names = Names::default();
        let mut texel_count = 0u64;
        if let Some(t) = self.table(root, "textures")? {
            for (name, v) in t.table.iter() {
                let name: &str = name.get_ref().as_ref();
                let section = self.named(&t, name, v)?;
                names
                    .textures
                    .insert(name.to_string(), scene.textures.len() as u32);
                let texture = self.texture(&section, &mut texel_count)?;
                scene.textures.push(texture);
            }
        }
        if let Some(t) = self.table(root, "materials")? {
            for (name, v) in t.table.iter() {
                let name: &str = name.get_ref().as_ref();
                let section = self.named(&t, name, v)?;
                names
                    .materials
                    .insert(name.to_string(), scene.materials.len() as u32);
                scene.materials.push(self.material(&section, &names)?);
            }
        }
        for l in self.tables(root, "lights")? {
            scene.lights.push(self.light(&l)?);
        }
        let mut b = Builder {
            scene,
            names,
            default_material: None,
            image_cache: HashMap::new(),
            tri_materials: Vec::new(),
            sphere_materials: Vec::new(),
            box_materials: Vec::new(),
            plane_materials: Vec::new(),
            warnings: Vec::new(),
        };
        for m in self.tables(root, "meshes")? {
            self.mesh(&m, &mut b)?;
        }
        for s in self.tables(root, "spheres")? {
            self.check_keys(&s, &["center", "radius", "material"])?;
            let center = self.vec3(&s, "center", None)?;
            let radius_v = self.required(&s, "radius")?;
            let radius = self.number(radius_v, &s.key("radius"))?;
            if radius <= 0.0 {
                return Err(self.invalid(&radius_v.span(), s.key("radius"), "must be > 0"));
            }
            let m = self.material_ref(&s, &mut b)?;
            b.scene.geometry.spheres.push(Sphere { center, radius });
            b.sphere_materials.push(m);
        }
        for s in self.tables(root, "boxes")? {
            self.check_keys(&s, &["min", "max", "material"])?;
            let min = self.vec3(&s, "min", None)?;
            let max = self.vec3(&s, "max", None)?;
            if !min.cmplt(max).all() {
                let span = self.required(&s, "max")?.span();
                return Err(self.invalid(
                    &span,
                    s.key("max"),
                    "must exceed `min` on every axis (the box would be empty or flat)",
                ));
            }
            let m = self.material_ref(&s, &mut b)?;
            b.scene.geometry.boxes.push(Aabb::new(min, max));
            b.box_materials.push(m);
        }
        for s in self.tables(root, "planes")? {
            self.check_keys(&s, &["normal", "offset", "point", "material"])?;
            let (normal, _) = self.nonzero_vec3(&s, "normal")?;
            let normal = normal.normalize();
            let offset = match (s.get("offset"), s.get("point")) {
                (Some(v), None) => self.number(v, &s.key("offset"))?,
                (None, Some(_)) => normal.dot(self.vec3(&s, "point", None)?),
                (Some(v), Some(_)) => {
                    return Err(self.invalid(
                        &v.span(),
                        s.key("offset"),
                        "give `offset` or `point`, not both",
                    ));
                }
                (None, None) => {
                    return Err(self.invalid(
                        &s.span,
                        s.key("offset"),
                        "missing (give `offset` or `point`)",
                    ));
                }
            };
            if !offset.is_finite() {
                return Err(self.invalid(&s.span, s.key("point"), "plane offset is not finite"));
            }
            let m = self.material_ref(&s, &mut b)?;
            b.scene.geometry.planes.push(Plane { normal, offset });
            b.plane_materials.push(m);
        }
        b.finish(self, root)
    }

    /// Entry `name` of a table of named tables (`[materials.NAME]`).
    fn named<'t, 'i>(
        &self,
        parent: &Section<'t, 'i>,
        name: &str,
        v: Value<'t, 'i>,
    ) -> Result<Section<'t, 'i>, SceneError> {
        match v.get_ref().as_table() {
            Some(t) => Ok(Section {
                table: t,
                name: parent.key(name),
                span: v.span(),
            }),
            None => Err(self.wrong_type(v, parent.key(name), "a table")),
        }
    }

    fn camera(&self, root: &Section) -> Result<Camera, SceneError> {
        let Some(c) = self.table(root, "camera")? else {
            return Err(self.invalid(
                &(0..0),
                "camera".into(),
                "missing (a scene needs a [camera])",
            ));
        };
        self.check_keys(&c, &["eye", "target", "up", "vfov"])?;
        let eye = self.vec3(&c, "eye", None)?;
        let target = self.vec3(&c, "target", None)?;
        let up = self.vec3(&c, "up", Some(Vec3::Y))?;
        let vfov_deg = self.f32_in(&c, "vfov", 60.0, (0.0, 180.0))?;
        let at = |k: &str| c.get(k).map_or(c.span.clone(), |v| v.span());
        if vfov_deg <= 0.0 || vfov_deg >= 180.0 {
            return Err(self.invalid(&at("vfov"), c.key("vfov"), "must be > 0 and < 180 degrees"));
        }
        let forward = target - eye;
        if forward.length_squared() == 0.0 {
            return Err(self.invalid(
                &at("target"),
                c.key("target"),
                "equals `eye` (no view direction)",
            ));
        }
        // Finite points can still be too far apart: from about 1.8e19 on, the square of
        // |target - eye| passes f32::MAX, the length comes out infinite and the view
        // direction cannot be normalized. That is not `target == eye`; say what it is.
        if !forward.length_squared().is_finite() {
            return Err(self.invalid(
                &at("target"),
                c.key("target"),
                "is too far from `eye`: the distance between them overflows (is not finite in f32)",
            ));
        }
        let sin = forward.normalize().cross(up.normalize_or_zero()).length();
        if sin.is_nan() || sin <= 1e-6 {
            return Err(self.invalid(
                &at("up"),
                c.key("up"),
                "is zero or parallel to the view direction (target - eye)",
            ));
        }
        Ok(Camera {
            eye,
            target,
            up,
            vfov_deg,
        })
    }

    fn render(&self, r: &Section) -> Result<RenderSettings, SceneError> {
        self.check_keys(
            r,
            &[
                "width",
                "height",
                "max_depth",
                "antialias",
                "antialias_n",
                "glossy_samples",
                "seed",
                "background",
                "ambient",
            ],
        )?;
        let d = RenderSettings::default();
        let width = self.u32_in(r, "width", d.width, 1, MAX_SIDE)?;
        let height = self.u32_in(r, "height", d.height, 1, MAX_SIDE)?;
        if width as u64 * height as u64 > MAX_PIXELS {
            let span = r.get("height").map_or(r.span.clone(), |v| v.span());
            return Err(self.invalid(
                &span,
                r.key("height"),
                format!("{width}x{height} is more than {MAX_PIXELS} pixels"),
            ));
        }
        let n = self.u32_in(r, "antialias_n", 3, 1, MAX_ANTIALIAS_N)?;
        let antialias = match r.get("antialias") {
            None => AntiAlias::None,
            Some(v) => match self.string(v, &r.key("antialias"))? {
                "none" => AntiAlias::None,
                "full" => AntiAlias::Full(n),
                "adaptive" => AntiAlias::Adaptive(n),
                other => {
                    return Err(self.invalid(
                        &v.span(),
                        r.key("antialias"),
                        format!("`{other}` is not one of none, full, adaptive"),
                    ));
                }
            },
        };
        let seed = match r.get("seed") {
            None => d.seed,
            Some(v) => {
                let s = self.integer(v, &r.key("seed"))?;
                u64::try_from(s)
                    .map_err(|_| self.invalid(&v.span(), r.key("seed"), "must be >= 0"))?
            }
        };
        Ok(RenderSettings {
            width,
            height,
            max_depth: self.u32_in(r, "max_depth", d.max_depth, 0, MAX_DEPTH)?,
            antialias,
            glossy_samples: self.u32_in(r, "glossy_samples", d.glossy_samples, 1, MAX_SAMPLES)?,
            seed,
            background: self.color(r, "background", d.background)?,
            ambient: self.f32_in(r, "ambient", d.ambient, (0.0, 1.0))?,
        })
    }

    /// Texture `t`; `texel_count` sums the texels of the scene's textures so far, and
    /// is checked against [`MAX_TEXELS`] before a texture is generated.
    fn texture(&self, t: &Section, texel_count: &mut u64) -> Result<Texture, SceneError> {
        let mut budget = |texels: u64| {
            *texel_count += texels;
            if *texel_count > MAX_TEXELS {
                Err(self.invalid(
                    &t.span,
                    t.name.clone(),
                    format!("the scene's textures exceed {MAX_TEXELS} texels in all"),
                ))
            } else {
                Ok(())
            }
        };
        let kind_v = self.required(t, "kind")?;
        let kind = self.string(kind_v, &t.key("kind"))?;
        const SIZE: [&str; 3] = ["kind", "width", "height"];
        let keys: &[&str] = match kind {
            "image" => &["kind", "file"],
            "checker" => &[SIZE[0], SIZE[1], SIZE[2], "squares", "color_a", "color_b"],
            "bricks" => &[
                SIZE[0],
                SIZE[1],
                SIZE[2],
                "rows",
                "columns",
                "mortar",
                "brick_color",
                "mortar_color",
                "seed",
            ],
            "marble" => &[
                SIZE[0],
                SIZE[1],
                SIZE[2],
                "scale",
                "turbulence",
                "color_a",
                "color_b",
                "seed",
            ],
            other => {
                return Err(self.invalid(
                    &kind_v.span(),
                    t.key("kind"),
                    format!("`{other}` is not one of image, checker, bricks, marble"),
                ));
            }
        };
        self.check_keys(t, keys)?;
        if kind == "image" {
            let (file, span) = self.file(t, "file")?;
            return texture::load(&file)
                .map_err(|source| self.texture_error(&span, t.key("file"), source));
        }
        let width = self.u32_in(t, "width", 256, 1, MAX_PROCEDURAL_SIDE)?;
        let height = self.u32_in(t, "height", 256, 1, MAX_PROCEDURAL_SIDE)?;
        budget(width as u64 * height as u64)?;
        let seed = self.u32_in(t, "seed", 0, 0, u32::MAX)?;
        let p = match kind {
            "checker" => Procedural::Checker {
                squares: self.u32_in(t, "squares", 8, 1, width.min(height))?,
                a: self.color(t, "color_a", Vec3::ONE)?,
                b: self.color(t, "color_b", Vec3::ZERO)?,
            },
            "bricks" => Procedural::Bricks {
                rows: self.u32_in(t, "rows", 8, 1, height)?,
                columns: self.u32_in(t, "columns", 4, 1, width)?,
                mortar: self.f32_in(t, "mortar", 0.1, (0.0, 0.5))?,
                brick: self.color(t, "brick_color", Vec3::new(0.55, 0.2, 0.12))?,
                mortar_color: self.color(t, "mortar_color", Vec3::splat(0.7))?,
                seed,
            },
            _ => Procedural::Marble {
                scale: self.u32_in(t, "scale", 4, 1, 256)?,
                turbulence: self.f32_in(t, "turbulence", 4.0, (0.0, 100.0))?,
                a: self.color(t, "color_a", Vec3::splat(0.9))?,
                b: self.color(t, "color_b", Vec3::new(0.2, 0.2, 0.25))?,
                seed,
            },
        };
        Ok(p.generate(width, height))
    }

    fn texture_error(&self, span: &Range<usize>, key: String, source: TextureError) -> SceneError {
        SceneError::Texture {
            path: self.path.to_path_buf(),
            line: self.line(span.start),
            key,
            source: Box::new(source),
        }
    }

    fn material(&self, m: &Section, names: &Names) -> Result<Material, SceneError> {
        self.check_keys(
            m,
            &[
                "color",
                "diffuse",
                "specular",
                "shininess",
                "reflection",
                "refraction",
                "ior",
                "absorption",
                "glossiness",
                "texture",
                "uv_scale",
            ],
        )?;
        let d = Material::default();
        let texture = match m.get("texture") {
            None => None,
            Some(v) => {
                let name = self.string(v, &m.key("texture"))?;
                match names.textures.get(name) {
                    Some(&i) => Some(i),
                    None => {
                        return Err(SceneError::UnknownName {
                            path: self.path.to_path_buf(),
                            line: self.line(v.span().start),
                            key: m.key("texture"),
                            kind: "texture",
                            name: name.to_string(),
                        });
                    }
                }
            }
        };
        let uv_scale = match m.get("uv_scale") {
            None => d.uv_scale,
            Some(v) => {
                let s = if is_number(v.get_ref()) {
                    Vec2::splat(self.number(v, &m.key("uv_scale"))?)
                } else {
                    Vec2::from_array(self.vector::<2>(v, &m.key("uv_scale"))?)
                };
                if s.x == 0.0 || s.y == 0.0 {
                    return Err(self.invalid(&v.span(), m.key("uv_scale"), "must not be 0"));
                }
                s
            }
        };
        Ok(Material {
            color: self.color(m, "color", d.color)?,
            diffuse: self.f32_in(m, "diffuse", d.diffuse, (0.0, 1.0))?,
            specular: self.f32_in(m, "specular", d.specular, (0.0, 1.0))?,
            shininess: self.f32_in(m, "shininess", d.shininess, (0.0, 100_000.0))?,
            reflection: self.f32_in(m, "reflection", d.reflection, (0.0, 1.0))?,
            refraction: self.f32_in(m, "refraction", d.refraction, (0.0, 1.0))?,
            ior: self.positive(m, "ior", d.ior, 10.0)?,
            absorption: self.f32_in(m, "absorption", d.absorption, (0.0, 1e6))?,
            glossiness: self.f32_in(
                m,
                "glossiness",
                d.glossiness,
                (0.0, std::f32::consts::FRAC_PI_2),
            )?,
            texture,
            uv_scale,
        })
    }

    fn light(&self, l: &Section) -> Result<Light, SceneError> {
        let kind_v = self.required(l, "kind")?;
        let kind = self.string(kind_v, &l.key("kind"))?;
        match kind {
            "point" => {
                self.check_keys(l, &["kind", "position", "color"])?;
                Ok(Light::Point {
                    position: self.vec3(l, "position", None)?,
                    color: self.color(l, "color", Vec3::ONE)?,
                })
            }
            "area" => {
                self.check_keys(
                    l,
                    &[
                        "kind", "corner", "center", "edge_u", "edge_v", "size", "color", "samples",
                    ],
                )?;
                let (corner, edge_u, edge_v) = match (l.get("corner"), l.get("center")) {
                    (Some(_), None) if l.get("size").is_some() => {
                        let span = l.get("size").map_or(l.span.clone(), |v| v.span());
                        return Err(self.invalid(
                            &span,
                            l.key("size"),
                            "`size` goes with `center`, not `corner`",
                        ));
                    }
                    (Some(_), None) => {
                        let (u, _) = self.nonzero_vec3(l, "edge_u")?;
                        let (v, _) = self.nonzero_vec3(l, "edge_v")?;
                        (self.vec3(l, "corner", None)?, u, v)
                    }
                    (None, Some(_)) => {
                        let center = self.vec3(l, "center", None)?;
                        let (u, v) = match l.get("size") {
                            Some(s) => {
                                let [sx, sz] = self.vector::<2>(s, &l.key("size"))?;
                                (Vec3::new(sx, 0.0, 0.0), Vec3::new(0.0, 0.0, sz))
                            }
                            None => (
                                self.nonzero_vec3(l, "edge_u")?.0,
                                self.nonzero_vec3(l, "edge_v")?.0,
                            ),
                        };
                        (center - (u + v) * 0.5, u, v)
                    }
                    (Some(v), Some(_)) => {
                        return Err(self.invalid(
                            &v.span(),
                            l.key("corner"),
                            "give `corner` or `center`, not both",
                        ));
                    }
                    (None, None) => {
                        return Err(self.invalid(
                            &l.span,
                            l.key("corner"),
                            "missing (give `corner` or `center`)",
                        ));
                    }
                };
                let area = edge_u.cross(edge_v).length();
                if !(area > 0.0 && area.is_finite()) {
                    let span = l
                        .get("size")
                        .or(l.get("edge_v"))
                        .map_or(l.span.clone(), |v| v.span());
                    return Err(self.invalid(
                        &span,
                        l.key(if l.get("size").is_some() {
                            "size"
                        } else {
                            "edge_v"
                        }),
                        "the light has zero area (edges parallel or zero)",
                    ));
                }
                Ok(Light::Area {
                    corner,
                    edge_u,
                    edge_v,
                    color: self.color(l, "color", Vec3::ONE)?,
                    samples: self.u32_in(l, "samples", 16, 1, MAX_SAMPLES)?,
                })
            }
            other => Err(self.invalid(
                &kind_v.span(),
                l.key("kind"),
                format!("`{other}` is not one of point, area"),
            )),
        }
    }

    /// The material named by key `material`, or the default material.
    fn material_ref(&self, s: &Section, b: &mut Builder) -> Result<u32, SceneError> {
        match s.get("material") {
            None => Ok(b.default_material()),
            Some(v) => {
                let name = self.string(v, &s.key("material"))?;
                b.names
                    .materials
                    .get(name)
                    .copied()
                    .ok_or_else(|| SceneError::UnknownName {
                        path: self.path.to_path_buf(),
                        line: self.line(v.span().start),
                        key: s.key("material"),
                        kind: "material",
                        name: name.to_string(),
                    })
            }
        }
    }

    /// The rotation of a mesh: `rotate = [x, y, z]` (degrees about the world axes, applied
    /// x, then y, then z) or `rotate_axis` with `rotate_angle` (degrees about that axis);
    /// the identity when neither is given. Positive angles follow the right-hand rule.
    fn rotation(&self, s: &Section) -> Result<Mat3, SceneError> {
        let (euler, axis, angle) = (s.get("rotate"), s.get("rotate_axis"), s.get("rotate_angle"));
        if let Some(e) = euler {
            if axis.or(angle).is_some() {
                return Err(self.invalid(
                    &e.span(),
                    s.key("rotate"),
                    "give `rotate` or `rotate_axis` with `rotate_angle`, not both",
                ));
            }
            let [x, y, z] = self.vector::<3>(e, &s.key("rotate"))?;
            return Ok(rotation_deg(Vec3::Z, z)
                * rotation_deg(Vec3::Y, y)
                * rotation_deg(Vec3::X, x));
        }
        match (axis, angle) {
            (None, None) => Ok(Mat3::IDENTITY),
            (Some(_), None) => Err(self.invalid(
                &s.span,
                s.key("rotate_angle"),
                "missing (`rotate_axis` needs `rotate_angle`, in degrees)",
            )),
            (None, Some(a)) => Err(self.invalid(
                &a.span(),
                s.key("rotate_axis"),
                "missing (`rotate_angle` needs `rotate_axis`)",
            )),
            (Some(v), Some(a)) => {
                let axis = Vec3::from_array(self.vector::<3>(v, &s.key("rotate_axis"))?);
                if axis == Vec3::ZERO {
                    return Err(self.invalid(
                        &v.span(),
                        s.key("rotate_axis"),
                        "the axis is zero; give a direction such as [0, 1, 0]",
                    ));
                }
                let angle = self.number(a, &s.key("rotate_angle"))?;
                // In f64, so any finite f32 axis has a length (1e30 squared overflows f32).
                Ok(rotation_deg(axis.as_dvec3().normalize().as_vec3(), angle))
            }
        }
    }

    fn mesh(&self, s: &Section, b: &mut Builder) -> Result<(), SceneError> {
        self.check_keys(
            s,
            &[
                "file",
                "material",
                "scale",
                "rotate",
                "rotate_axis",
                "rotate_angle",
                "translate",
            ],
        )?;
        let (file, span) = self.file(s, "file")?;
        let scale = match s.get("scale") {
            None => Vec3::ONE,
            Some(v) if is_number(v.get_ref()) => Vec3::splat(self.number(v, &s.key("scale"))?),
            Some(v) => Vec3::from_array(self.vector::<3>(v, &s.key("scale"))?),
        };
        if scale.cmpeq(Vec3::ZERO).any() {
            let span = s.get("scale").map_or(s.span.clone(), |v| v.span());
            return Err(self.invalid(&span, s.key("scale"), "must not be 0 on any axis"));
        }
        let transform = MeshTransform {
            scale,
            rotation: self.rotation(s)?,
            translate: self.vec3(s, "translate", Some(Vec3::ZERO))?,
        };
        let override_material = match s.get("material") {
            Some(_) => Some(self.material_ref(s, b)?),
            None => None,
        };
        let mesh = obj::load(&file).map_err(|source| SceneError::Mesh {
            path: self.path.to_path_buf(),
            line: self.line(span.start),
            key: s.key("file"),
            source: Box::new(source),
        })?;
        let materials = match override_material {
            Some(m) => vec![m; mesh.materials.len()],
            None => {
                let mut ids = Vec::with_capacity(mesh.materials.len());
                for m in &mesh.materials {
                    let texture = match &m.diffuse_texture {
                        Some(p) => Some(
                            b.image(p)
                                .map_err(|e| self.texture_error(&span, s.key("file"), e))?,
                        ),
                        None => None,
                    };
                    ids.push(b.scene.materials.len() as u32);
                    b.scene.materials.push(Material {
                        color: m.diffuse,
                        texture,
                        ..Material::default()
                    });
                }
                ids
            }
        };
        let fallback = match override_material {
            Some(m) => m,
            None => b.default_material(),
        };
        b.warnings.extend(mesh.warning(&file));
        b.add_mesh(mesh, &transform, &materials, fallback);
        if b.scene.geometry.triangles.len() as u64 >= u32::MAX as u64 / 2 {
            return Err(self.invalid(&span, s.key("file"), "too many triangles in the scene"));
        }
        Ok(())
    }
}

/// Where a mesh goes: `p' = rotation * (scale * p) + translate` (scale, then rotate,
/// then translate).
struct MeshTransform {
    scale: Vec3,
    rotation: Mat3,
    translate: Vec3,
}

impl MeshTransform {
    fn point(&self, p: Vec3) -> Vec3 {
        // Skipping the identity keeps unrotated meshes bit for bit as they were.
        let p = p * self.scale;
        if self.rotation == Mat3::IDENTITY {
            p + self.translate
        } else {
            self.rotation * p + self.translate
        }
    }

    /// Normals transform by the inverse transpose of `rotation * scale`, which is
    /// `rotation * scale^-1`.
    fn normal(&self, n: Vec3) -> Vec3 {
        let n = n / self.scale;
        if self.rotation == Mat3::IDENTITY {
            n.normalize_or_zero()
        } else {
            (self.rotation * n).normalize_or_zero()
        }
    }
}

/// `(sin, cos)` of `degrees`, exact at multiples of 90 so quarter turns keep axis-aligned
/// meshes axis-aligned (`to_radians` would leave `cos(90) = -4.4e-8`).
fn sin_cos_deg(degrees: f32) -> (f32, f32) {
    let d = (degrees as f64).rem_euclid(360.0);
    match d {
        0.0 => (0.0, 1.0),
        90.0 => (1.0, 0.0),
        180.0 => (0.0, -1.0),
        270.0 => (-1.0, 0.0),
        _ => {
            let (s, c) = d.to_radians().sin_cos();
            (s as f32, c as f32)
        }
    }
}

/// The rotation by `degrees` about the unit vector `axis` (Rodrigues' formula,
/// right-hand rule).
fn rotation_deg(axis: Vec3, degrees: f32) -> Mat3 {
    let (s, c) = sin_cos_deg(degrees);
    let k = Mat3::from_cols(
        Vec3::new(0.0, axis.z, -axis.y),
        Vec3::new(-axis.z, 0.0, axis.x),
        Vec3::new(axis.y, -axis.x, 0.0),
    );
    // I + s K + (1 - c) K^2, with K^2 = a a^T - I written out so an axis-aligned `axis`
    // and a quarter turn give exact 0 and 1 entries.
    let outer = Mat3::from_cols(axis * axis.x, axis * axis.y, axis * axis.z);
    Mat3::IDENTITY * c + k * s + outer * (1.0 - c)
}

/// Names of the textures and materials defined so far, to their indices.
#[derive(Default)]
struct Names {
    textures: HashMap<String, u32>,
    materials: HashMap<String, u32>,
}

/// The scene under construction, with the material of each primitive kind kept apart
/// until the id order (triangles, spheres, boxes, planes) is final.
struct Builder {
    scene: Scene,
    names: Names,
    default_material: Option<u32>,
    /// MTL textures by path, so a texture shared by materials is decoded once.
    image_cache: HashMap<PathBuf, u32>,
    tri_materials: Vec<u32>,
    sphere_materials: Vec<u32>,
    box_materials: Vec<u32>,
    plane_materials: Vec<u32>,
    warnings: Vec<Warning>,
}

impl Builder {
    fn default_material(&mut self) -> u32 {
        *self.default_material.get_or_insert_with(|| {
            self.scene.materials.push(Material::default());
            self.scene.materials.len() as u32 - 1
        })
    }

    fn image(&mut self, path: &Path) -> Result<u32, TextureError> {
        if let Some(&i) = self.image_cache.get(path) {
            return Ok(i);
        }
        let t = texture::load(path)?;
        let i = self.scene.textures.len() as u32;
        self.scene.textures.push(t);
        self.image_cache.insert(path.to_path_buf(), i);
        Ok(i)
    }

    /// Appends `mesh` placed by `transform`, with `materials[k]` for its MTL material `k`
    /// and `fallback` for triangles before any `usemtl`.
    fn add_mesh(
        &mut self,
        mesh: ObjMesh,
        transform: &MeshTransform,
        materials: &[u32],
        fallback: u32,
    ) {
        let g = &mut self.scene.geometry;
        let base = g.vertices.len() as u32;
        let had_uvs = !self.scene.uvs.is_empty();
        if !mesh.uvs.is_empty() && !had_uvs {
            self.scene.uvs = vec![Vec2::ZERO; g.vertices.len()];
        }
        g.vertices
            .extend(mesh.positions.iter().map(|&p| transform.point(p)));
        g.triangles
            .extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
        self.scene
            .normals
            .extend(mesh.normals.iter().map(|&n| transform.normal(n)));
        if !self.scene.uvs.is_empty() {
            if mesh.uvs.is_empty() {
                self.scene
                    .uvs
                    .extend(std::iter::repeat_n(Vec2::ZERO, mesh.positions.len()));
            } else {
                self.scene.uvs.extend_from_slice(&mesh.uvs);
            }
        }
        self.tri_materials.extend(
            mesh.tri_material
                .iter()
                .map(|m| m.map_or(fallback, |k| materials[k as usize])),
        );
    }

    fn finish(mut self, doc: &Doc, root: &Section) -> Result<(Scene, Vec<Warning>), SceneError> {
        let g = &self.scene.geometry;
        if g.prim_count() == 0 {
            return Err(doc.invalid(&root.span, "spheres".into(), "the scene has no primitives (add [[spheres]], [[planes]], [[boxes]] or [[meshes]])"));
        }
        let mut prim_material = std::mem::take(&mut self.tri_materials);
        prim_material.extend_from_slice(&self.sphere_materials);
        prim_material.extend_from_slice(&self.box_materials);
        prim_material.extend_from_slice(&self.plane_materials);
        self.scene.prim_material = prim_material;
        Ok((self.scene, self.warnings))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::PrimRef;
    use crate::scene::obj::tests::folder;

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
        let readme = include_str!("../../scenes/README.md");
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
