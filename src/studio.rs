//! studio: a scene made ready to render the way `raypack render` makes it ready, for any
//! program that renders (the command line and the Python package share it, so both give
//! the same image): the scene read from what a user names, the lights a bare mesh gets,
//! and the sky of the global-illumination integrators.

use crate::accel::Accel;
use crate::geom::Geometry;
use crate::rayset::RaySetError;
use crate::rayset::standard::default_light;
use crate::scene::catalog::{self, BenchSceneError, SceneArg};
use crate::scene::light::emitter_lights;
use crate::scene::{
    AntiAlias, Camera, Light, Material, ObjError, RenderSettings, Scene, SceneError, View, Warning,
};
use glam::Vec3;

/// The most samples per pixel of the path and photon integrators: 2^16, far past a
/// converged image, and a bound on what a typing slip can start.
pub const MAX_GI_SPP: u32 = 1 << 16;

/// Shadow rays per shading point that the lights of a mesh's emitters share
/// ([`emitter_lights`]).
pub const EMITTER_SAMPLES: u32 = 16;
/// The most emissive triangles that become Whitted lights: each costs a shadow ray per
/// shading point at least.
pub const MAX_EMITTER_LIGHTS: usize = 64;
/// Brightness of the key light of [`light_rig`].
pub const KEY_LIGHT: f32 = 0.6;
/// Brightness of the fill light of [`light_rig`].
pub const FILL_LIGHT: f32 = 0.2;
/// Ambient term of a mesh scene, so that what neither light reaches is not pure black.
pub const MESH_AMBIENT: f32 = 0.05;

/// Where a scene came from: a scene file brings its own lights, a mesh gets them here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// A TOML scene file.
    File,
    /// A bare mesh: an OBJ file, a benchmark scene by name, or arrays a program made.
    Mesh,
}

/// A scene to render, where it came from, and what its loader warned about.
#[derive(Clone, Debug)]
pub struct Staged {
    /// The scene, with its camera (its file's, cameras.toml's, or one framing it).
    pub scene: Scene,
    /// That camera in f64, as the ray sets of RAYS.md are made from it
    /// ([`catalog::load`]'s view of the same scene).
    pub view: View,
    /// File or mesh.
    pub source: Source,
    /// The loader's warnings (degenerate triangles, say).
    pub warnings: Vec<Warning>,
}

/// Why a scene cannot be made ready to render.
#[derive(Debug, thiserror::Error)]
pub enum StudioError {
    /// A generated `spd:` scene has geometry only.
    #[error(
        "{0}: render takes a scene file, an OBJ mesh or a scene name; spd: scenes are for bench, trace, rays and info"
    )]
    NotRenderable(String),
    /// The name is neither a file nor a benchmark scene.
    #[error(transparent)]
    Name(#[from] BenchSceneError),
    /// A bad scene file.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A bad OBJ mesh.
    #[error(transparent)]
    Obj(#[from] ObjError),
}

/// Reads the scene `arg` names, as every command reads it ([`catalog::resolve`]): a
/// scene file, an OBJ mesh (its camera from cameras.toml, or framing its bounds) or a
/// benchmark scene's name.
pub fn load(arg: &str) -> Result<Staged, StudioError> {
    match catalog::resolve(arg)? {
        SceneArg::Toml(path) => {
            let (scene, warnings) = crate::scene::file::load_with_warnings(&path)?;
            Ok(Staged {
                view: View::from(&scene.camera),
                scene,
                source: Source::File,
                warnings,
            })
        }
        SceneArg::Obj { path, view } => {
            let camera = view.as_ref().map(Camera::from).unwrap_or_default();
            let (mut scene, warnings) = Scene::from_obj(&path, camera)?;
            let view = view.unwrap_or_else(|| catalog::overview(&scene.geometry));
            scene.camera = Camera::from(&view);
            Ok(Staged {
                view,
                scene,
                source: Source::Mesh,
                warnings,
            })
        }
        SceneArg::Spd(_) => Err(StudioError::NotRenderable(arg.into())),
    }
}

/// A bare mesh a program made (no materials, normals or texture coordinates): the
/// default grey material on every triangle, a camera that frames its bounds, and the
/// size of RAYS.md's standard sets, 1024x768, as an OBJ mesh gets.
pub fn mesh(geometry: Geometry) -> Staged {
    let view = catalog::overview(&geometry);
    let camera = Camera::from(&view);
    let prims = geometry.prim_count() as usize;
    Staged {
        view,
        scene: Scene {
            geometry,
            prim_material: vec![0; prims],
            materials: vec![Material::default()],
            camera,
            settings: RenderSettings {
                width: 1024,
                height: 768,
                ..Default::default()
            },
            ..Default::default()
        },
        source: Source::Mesh,
        warnings: Vec::new(),
    }
}

/// The Whitted tracer's anti-aliasing for `spp` samples per pixel, `None` unless `spp`
/// is a square of 1 to 16 (1, 4, 9, ... 256): an `n x n` grid per pixel, adaptive
/// where the scene asked for adaptive sampling, none for 1.
pub fn whitted_antialias(current: AntiAlias, spp: u32) -> Option<AntiAlias> {
    let n = (spp as f64).sqrt().round() as u32;
    if spp == 0 || n * n != spp || n > 16 {
        return None;
    }
    Some(match (n, current) {
        (1, _) => AntiAlias::None,
        (n, AntiAlias::Adaptive(_)) => AntiAlias::Adaptive(n),
        (n, _) => AntiAlias::Full(n),
    })
}

/// Lights a mesh scene for the Whitted tracer: its emissive triangles become area
/// lights (the [`MAX_EMITTER_LIGHTS`] brightest), or, with none, it gets the
/// [`light_rig`]; and the ambient term [`MESH_AMBIENT`]. Returns how many emissive
/// triangles were left out.
pub fn light_mesh<A: Accel + ?Sized>(scene: &mut Scene, accel: &A) -> Result<usize, RaySetError> {
    let emitters = emitter_lights(scene, EMITTER_SAMPLES, MAX_EMITTER_LIGHTS);
    scene.lights = if emitters.lights.is_empty() {
        light_rig(scene, accel)?
    } else {
        emitters.lights
    };
    scene.settings.ambient = MESH_AMBIENT;
    Ok(emitters.left_out)
}

/// The lights of a mesh scene that has no emitters: a white key light where
/// `raypack bench` puts its shadow rays' light (halfway between the eye and whatever is
/// above it, RAYS.md and [`default_light`]), so the image shows the shadows the
/// benchmark traces, and a dim fill light at the eye, so that surfaces in the key
/// light's shadow still show their shape.
pub fn light_rig<A: Accel + ?Sized>(scene: &Scene, accel: &A) -> Result<Vec<Light>, RaySetError> {
    let view = View::from(&scene.camera);
    let (key, _) = default_light(accel, &scene.geometry, &view)?;
    Ok(vec![
        Light::Point {
            position: key.as_vec3(),
            color: Vec3::splat(KEY_LIGHT),
        },
        Light::Point {
            position: scene.camera.eye,
            color: Vec3::splat(FILL_LIGHT),
        },
    ])
}

/// The radiance of what global-illumination rays leaving the scene see: `sky` when
/// given; for a mesh with no emissive material, a uniform white sky of radiance 1 (a
/// bare mesh has no light of its own); else the scene's background. The flag is set
/// when the white sky was chosen here, for the caller to say so.
pub fn gi_environment(staged: &Staged, sky: Option<Vec3>) -> (Vec3, bool) {
    let scene = &staged.scene;
    let emits = (0..scene.geometry.prim_count()).any(|p| scene.material(p).emission != Vec3::ZERO);
    match sky {
        Some(sky) => (sky, false),
        None if staged.source == Source::Mesh && !emits => (Vec3::ONE, true),
        None => (scene.settings.background, false),
    }
}
