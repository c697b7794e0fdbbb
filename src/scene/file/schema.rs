//! The scene-file schema, section by section (`[camera]`, `[render]`, `[materials.*]`,
//! `[textures.*]`, `[[lights]]`, `[[meshes]]` and the primitives): which keys each
//! takes, their types, ranges and defaults, as scenes/README.md documents them.

use super::build::{Builder, MeshTransform, Names, rotation_deg};
use super::reader::{Doc, Section, Value, is_number};
use super::{
    MAX_ANTIALIAS_N, MAX_DEPTH, MAX_PIXELS, MAX_PROCEDURAL_SIDE, MAX_SAMPLES, MAX_SIDE, MAX_TEXELS,
};
use crate::scene::error::{SceneError, TextureError, Warning};
use crate::scene::obj;
use crate::scene::texture::{self, Procedural};
use crate::scene::{
    Aabb, AntiAlias, Camera, Light, Material, Plane, RenderSettings, Scene, Sphere, Texture,
};
use glam::{Mat3, Vec2, Vec3};
use std::collections::HashMap;
use std::ops::Range;

impl<'a> Doc<'a> {
    pub(super) fn build(&self, root: &Section) -> Result<(Scene, Vec<Warning>), SceneError> {
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
                "emission",
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
            emission: self.color(m, "emission", d.emission)?,
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
                        emission: m.emission,
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
