//! Scene description: geometry, materials, lights, camera, textures, and the loaders
//! that build them from TOML scene files and OBJ meshes.

#![warn(missing_docs)]

pub mod camera;
pub mod catalog;
pub mod error;
pub mod file;
pub mod generate;
pub mod light;
pub mod material;
pub mod obj;
pub mod spd;
pub mod texture;

pub use crate::geom::{Aabb, Geometry, Plane, PrimRef, Sphere, scene_box};
pub use camera::{Camera, CameraFrame, View};
pub use error::{DecodeError, ObjError, SceneError, TextureError, Warning};
pub use light::Light;
pub use material::Material;
pub use texture::Texture;

use glam::{Vec2, Vec3};

/// How pixels are sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AntiAlias {
    /// One ray through each pixel centre.
    None,
    /// `n x n` jittered rays in every pixel.
    Full(u32),
    /// One ray per pixel, then `n x n` only where a pixel's hit signature differs from its
    /// left or upper neighbour (tutorial part 3).
    Adaptive(u32),
}

/// Image and sampling settings of a scene (overridable from the CLI).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels, 1 to [`file::MAX_SIDE`].
    pub width: u32,
    /// Image height in pixels; `width * height` is at most [`file::MAX_PIXELS`].
    pub height: u32,
    /// Recursion limit for reflection and refraction.
    pub max_depth: u32,
    /// Rays per pixel: one, `n x n` everywhere, or `n x n` only at edges.
    pub antialias: AntiAlias,
    /// Samples per glossy reflection at the first bounce.
    pub glossy_samples: u32,
    /// Seeds every random choice (jitter, glossy and area-light samples): the image
    /// depends only on the scene and this value, whatever the thread count.
    pub seed: u64,
    /// Colour of rays that leave the scene.
    pub background: Vec3,
    /// Constant ambient term added to diffuse surfaces.
    pub ambient: f32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 800,
            height: 600,
            max_depth: 6,
            antialias: AntiAlias::None,
            glossy_samples: 16,
            seed: 0,
            background: Vec3::ZERO,
            ambient: 0.0,
        }
    }
}

/// Everything the renderer needs.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// The primitives, whose order fixes the prim ids of every other table here.
    pub geometry: Geometry,
    /// Per-vertex shading normals, parallel to `geometry.vertices` (empty: use geometric).
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates, parallel to `geometry.vertices` (empty: none).
    pub uvs: Vec<Vec2>,
    /// Material of every primitive, by primitive id (planes included).
    pub prim_material: Vec<u32>,
    /// Materials, indexed by `prim_material`; every index there is valid.
    pub materials: Vec<Material>,
    /// Textures, indexed by [`Material::texture`]; every index there is valid.
    pub textures: Vec<Texture>,
    /// Lights; may be empty (then only `settings.ambient` lights the scene).
    pub lights: Vec<Light>,
    /// The camera of the scene file, which the CLI may override.
    pub camera: Camera,
    /// Image size and sampling, which the CLI may override.
    pub settings: RenderSettings,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            eye: Vec3::new(0.0, 0.0, -5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 60.0,
        }
    }
}

impl Scene {
    /// Material of primitive `prim`.
    pub fn material(&self, prim: u32) -> &Material {
        &self.materials[self.prim_material[prim as usize] as usize]
    }
}
