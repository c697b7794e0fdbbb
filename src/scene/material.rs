//! Surface materials of the Whitted model (tutorial parts 1-6).

use glam::{Vec2, Vec3};

/// How a surface shades: the Whitted model's diffuse, Phong, mirror and refraction
/// weights, each in `[0, 1]` as the scene file checks them.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Base colour (linear RGB); multiplied by the texture where there is one.
    pub color: Vec3,
    /// Weight of the diffuse (N.L) term.
    pub diffuse: f32,
    /// Weight of the Phong specular term.
    pub specular: f32,
    /// Phong exponent.
    pub shininess: f32,
    /// Fraction of light mirrored.
    pub reflection: f32,
    /// Fraction of light transmitted.
    pub refraction: f32,
    /// Index of refraction of the inside.
    pub ior: f32,
    /// Beer's law density: transmission through distance `d` is `exp(-color' * absorption * d)`
    /// where `color' = 1 - color`... see `render::shade` for the exact form.
    pub absorption: f32,
    /// Half-angle scale of the glossy reflection cone (0 = perfect mirror).
    pub glossiness: f32,
    /// Index into `Scene::textures`.
    pub texture: Option<u32>,
    /// Texture coordinates are multiplied by this before lookup.
    pub uv_scale: Vec2,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            color: Vec3::splat(0.8),
            diffuse: 1.0,
            specular: 0.0,
            shininess: 20.0,
            reflection: 0.0,
            refraction: 0.0,
            ior: 1.5,
            absorption: 0.0,
            glossiness: 0.0,
            texture: None,
            uv_scale: Vec2::ONE,
        }
    }
}
