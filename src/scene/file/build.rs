//! What the schema builds into: the scene under construction, material names, and
//! the placement of meshes (scale, rotation in degrees, translation).

use super::reader::{Doc, Section};
use crate::scene::error::{SceneError, TextureError, Warning};
use crate::scene::obj::ObjMesh;
use crate::scene::texture;
use crate::scene::{Material, Scene};
use glam::{Mat3, Vec2, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where a mesh goes: `p' = rotation * (scale * p) + translate` (scale, then rotate,
/// then translate).
pub(super) struct MeshTransform {
    pub(super) scale: Vec3,
    pub(super) rotation: Mat3,
    pub(super) translate: Vec3,
}

impl MeshTransform {
    pub(super) fn point(&self, p: Vec3) -> Vec3 {
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
    pub(super) fn normal(&self, n: Vec3) -> Vec3 {
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
pub(super) fn sin_cos_deg(degrees: f32) -> (f32, f32) {
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
pub(super) fn rotation_deg(axis: Vec3, degrees: f32) -> Mat3 {
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
pub(super) struct Names {
    pub(super) textures: HashMap<String, u32>,
    pub(super) materials: HashMap<String, u32>,
}

/// The scene under construction, with the material of each primitive kind kept apart
/// until the id order (triangles, spheres, boxes, planes) is final.
pub(super) struct Builder {
    pub(super) scene: Scene,
    pub(super) names: Names,
    pub(super) default_material: Option<u32>,
    /// MTL textures by path, so a texture shared by materials is decoded once.
    pub(super) image_cache: HashMap<PathBuf, u32>,
    pub(super) tri_materials: Vec<u32>,
    pub(super) sphere_materials: Vec<u32>,
    pub(super) box_materials: Vec<u32>,
    pub(super) plane_materials: Vec<u32>,
    pub(super) warnings: Vec<Warning>,
}

impl Builder {
    pub(super) fn default_material(&mut self) -> u32 {
        *self.default_material.get_or_insert_with(|| {
            self.scene.materials.push(Material::default());
            self.scene.materials.len() as u32 - 1
        })
    }

    pub(super) fn image(&mut self, path: &Path) -> Result<u32, TextureError> {
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
    pub(super) fn add_mesh(
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

    pub(super) fn finish(
        mut self,
        doc: &Doc,
        root: &Section,
    ) -> Result<(Scene, Vec<Warning>), SceneError> {
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
