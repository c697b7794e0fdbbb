//! Scenes by name: what `raypack bench`, `trace`, `rays`, `info` and `render` accept,
//! with the camera their ray sets are made from. It lives in the library, not in the
//! command, because the criterion benchmarks (which link only the library) load the
//! benchmark scenes by the same names.
//!
//! [`Scene::from_obj`] is the policy that turns a bare mesh into a scene to render.
//!
//! Stage: scene (it reads meshes, scene files and SPD generators, nothing above).
//! Accepted:
//!
//! - the name of a scene in `cameras.toml` of the shared benchmark scenes (`sponza`,
//!   `bunny`, `conference`, `cornell_box`), found in `$RAYPACK_SCENES` when it is set,
//!   else in `../shared/scenes` from the working directory or beside the source tree;
//!   the meshes are never copied into the repository;
//! - an OBJ file (the camera of `cameras.toml` when the file is one of those scenes,
//!   else a view of the whole scene box);
//! - a TOML scene file (its own camera);
//! - `spd:NAME[:SIZE]`, one of Eric Haines' Standard Procedural Databases
//!   ([`super::spd`]) with its published viewpoint.

use super::spd::{self, SpdError};
use super::{
    Camera, Geometry, Material, ObjError, RenderSettings, Scene, SceneError, View, Warning,
    scene_box,
};
use glam::DVec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Environment variable naming the folder of the shared benchmark scenes.
pub const SCENES_ENV: &str = "RAYPACK_SCENES";

/// Why a scene name or path could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum BenchSceneError {
    /// A cameras.toml name, but the shared scenes folder is nowhere to be found.
    #[error(
        "scene `{name}`: the benchmark scenes are expected in ../shared/scenes beside the repository (with cameras.toml); looked in {}; set {SCENES_ENV} to their folder",
        looked.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    SharedMissing {
        /// The name given.
        name: String,
        /// The folders looked in.
        looked: Vec<PathBuf>,
    },
    /// Neither a file, an spd spec, nor a name of cameras.toml.
    #[error("scene `{name}` is not a file, an spd:NAME[:SIZE] scene, or a scene of {} (known: {})", cameras.display(), known.join(", "))]
    Unknown {
        /// The name given.
        name: String,
        /// The cameras.toml read.
        cameras: PathBuf,
        /// The names it holds.
        known: Vec<String>,
    },
    /// cameras.toml cannot be read or parsed.
    #[error("{}: {message}", path.display())]
    CamerasFile {
        /// The cameras.toml.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A file that is not a scene.
    #[error("{}: {message}", path.display())]
    Load {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A bad `spd:` spec.
    #[error(transparent)]
    Spd(#[from] SpdError),
    /// A bad OBJ mesh.
    #[error(transparent)]
    Obj(#[from] ObjError),
    /// A bad TOML scene.
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// A scene ready to trace: its geometry and the camera of its primary set.
#[derive(Clone, Debug)]
pub struct BenchScene {
    /// What the user named (a cameras.toml name, a path, an spd spec).
    pub name: String,
    /// Its primitives.
    pub geometry: Geometry,
    /// The camera its primary set is made from.
    pub view: View,
    /// Seconds spent reading or generating the geometry.
    pub load_seconds: f64,
    /// What the user should be warned about (degenerate triangles of its meshes).
    pub warnings: Vec<Warning>,
}

/// One entry of cameras.toml.
#[derive(Clone, Debug, Deserialize)]
pub struct CameraEntry {
    /// The mesh, relative to the folder of cameras.toml.
    pub obj: String,
    /// Camera position.
    pub eye: [f64; 3],
    /// Point at the image centre.
    pub target: [f64; 3],
    /// Up hint.
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub vfov_deg: f64,
    /// The mesh's triangle count, when recorded.
    pub triangles: Option<u64>,
}

impl CameraEntry {
    /// The entry's camera.
    pub fn view(&self) -> View {
        View {
            eye: DVec3::from_array(self.eye),
            target: DVec3::from_array(self.target),
            up: DVec3::from_array(self.up),
            vfov_deg: self.vfov_deg,
        }
    }
}

/// Where the shared scenes folder may be, in the order it is looked for: only
/// `$RAYPACK_SCENES` when it is set, else `../shared/scenes` from the working directory
/// and from the source tree.
pub fn shared_scenes_candidates() -> Vec<PathBuf> {
    match std::env::var_os(SCENES_ENV) {
        Some(dir) => vec![PathBuf::from(dir)],
        None => vec![
            PathBuf::from("../shared/scenes"),
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"),
        ],
    }
}

/// The shared scenes folder (the first candidate holding cameras.toml).
pub fn shared_scenes_dir() -> Option<PathBuf> {
    shared_scenes_candidates()
        .into_iter()
        .find(|d| d.join("cameras.toml").is_file())
}

/// Parses cameras.toml.
pub fn read_cameras(path: &Path) -> Result<BTreeMap<String, CameraEntry>, BenchSceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| BenchSceneError::CamerasFile {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    toml::from_str(&text).map_err(|e| BenchSceneError::CamerasFile {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// The cameras.toml entry and mesh path of shared scene `name`.
pub fn shared_scene(name: &str) -> Result<(CameraEntry, PathBuf), BenchSceneError> {
    let dir = shared_scenes_dir().ok_or_else(|| BenchSceneError::SharedMissing {
        name: name.to_string(),
        looked: shared_scenes_candidates(),
    })?;
    let cameras = dir.join("cameras.toml");
    let mut entries = read_cameras(&cameras)?;
    match entries.remove(name) {
        Some(e) => {
            let obj = dir.join(&e.obj);
            Ok((e, obj))
        }
        None => Err(BenchSceneError::Unknown {
            name: name.to_string(),
            cameras,
            known: entries.into_keys().collect(),
        }),
    }
}

/// A view of the whole scene box from the front, above and to the right, for meshes
/// without a standard camera.
pub fn overview(geometry: &Geometry) -> View {
    let (lo, hi, diag) = scene_box(geometry);
    let centre = (lo + hi) * 0.5;
    let diag = if diag > 0.0 { diag } else { 1.0 };
    View {
        eye: centre + DVec3::new(0.35, 0.45, 1.0).normalize() * diag,
        target: centre,
        up: DVec3::Y,
        vfov_deg: 50.0,
    }
}

/// Reads an OBJ mesh's geometry (triangle ids in file order, as RAYS.md numbers them)
/// and its warning.
fn load_obj(path: &Path) -> Result<(Geometry, Vec<Warning>), BenchSceneError> {
    let mesh = super::obj::load(path)?;
    let warnings = mesh.warning(path).into_iter().collect();
    let geometry = Geometry {
        vertices: mesh.positions,
        triangles: mesh.triangles,
        ..Geometry::default()
    };
    Ok((geometry, warnings))
}

/// Reads a TOML scene's geometry, camera and warnings.
fn load_toml(path: &Path) -> Result<(Geometry, View, Vec<Warning>), BenchSceneError> {
    let (scene, warnings) = super::file::load_with_warnings(path)?;
    let view = View::from(&scene.camera);
    Ok((scene.geometry, view, warnings))
}

/// The camera of an OBJ file that is one of the shared scenes, if it is one.
pub fn shared_view_of(path: &Path) -> Option<View> {
    let dir = shared_scenes_dir()?;
    let wanted = path.canonicalize().ok()?;
    read_cameras(&dir.join("cameras.toml"))
        .ok()?
        .into_values()
        .find(|e| dir.join(&e.obj).canonicalize().ok().as_deref() == Some(&wanted))
        .map(|e| e.view())
}

/// What a scene argument names, before anything is read: the one reading of the
/// argument that `bench`, `trace`, `rays`, `info` and `render` share.
#[derive(Clone, Debug, PartialEq)]
pub enum SceneArg {
    /// `spd:NAME[:SIZE]`, the text after `spd:`.
    Spd(String),
    /// A TOML scene file.
    Toml(PathBuf),
    /// An OBJ mesh, by path or by its cameras.toml name, with the camera cameras.toml
    /// gives it (`None`: frame its bounds, [`overview`]).
    Obj {
        /// The mesh file.
        path: PathBuf,
        /// Its standard camera, if it is one of the shared scenes.
        view: Option<View>,
    },
}

/// Reads `arg` as the module docs say: `spd:` spec, `.toml` or `.obj` path (any case),
/// or a name of cameras.toml. Any other existing file is refused.
pub fn resolve(arg: &str) -> Result<SceneArg, BenchSceneError> {
    let path = Path::new(arg);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if let Some(spec) = arg.strip_prefix("spd:") {
        Ok(SceneArg::Spd(spec.to_string()))
    } else if ext.as_deref() == Some("obj") {
        Ok(SceneArg::Obj {
            path: path.to_path_buf(),
            view: shared_view_of(path),
        })
    } else if ext.as_deref() == Some("toml") {
        Ok(SceneArg::Toml(path.to_path_buf()))
    } else if path.is_file() {
        Err(BenchSceneError::Load {
            path: path.to_path_buf(),
            message: "not a scene: expected a .toml scene or an .obj mesh".into(),
        })
    } else {
        let (entry, obj) = shared_scene(arg)?;
        Ok(SceneArg::Obj {
            path: obj,
            view: Some(entry.view()),
        })
    }
}

/// Loads the scene named by `arg` (see the module docs).
pub fn load(arg: &str) -> Result<BenchScene, BenchSceneError> {
    let start = Instant::now();
    let (geometry, view, warnings) = match resolve(arg)? {
        SceneArg::Spd(spec) => {
            let s = spd::generate_spec(&spec)?;
            (s.geometry, s.view, Vec::new())
        }
        SceneArg::Toml(path) => load_toml(&path)?,
        SceneArg::Obj { path, view } => {
            let (g, warnings) = load_obj(&path)?;
            let view = view.unwrap_or_else(|| overview(&g));
            (g, view, warnings)
        }
    };
    Ok(BenchScene {
        name: arg.to_string(),
        geometry,
        view,
        load_seconds: start.elapsed().as_secs_f64(),
        warnings,
    })
}

impl Scene {
    /// A scene of one OBJ mesh, for rendering the benchmark meshes and any OBJ file: its
    /// triangles (prim ids as in RAYS.md); the file's normals and texture coordinates
    /// where it has them, geometric normals where it has none (smoothing normals the
    /// author did not give would round off hard edges); one material per MTL material,
    /// with its `Kd` colour and `map_Kd` texture, and the default grey for triangles
    /// before any `usemtl`; no lights (the caller places them); 1024x768, the size of
    /// RAYS.md's standard ray sets. Returns the mesh's warnings beside the scene.
    pub fn from_obj(path: &Path, camera: Camera) -> Result<(Scene, Vec<Warning>), ObjError> {
        let mesh = super::obj::load(path)?;
        let warnings = mesh.warning(path).into_iter().collect();
        let mut textures = Vec::new();
        let mut materials = Vec::with_capacity(mesh.materials.len() + 1);
        for m in &mesh.materials {
            let texture = match &m.diffuse_texture {
                Some(file) => {
                    let t = super::texture::load(file).map_err(|source| ObjError::Texture {
                        path: path.to_path_buf(),
                        material: m.name.clone(),
                        source: Box::new(source),
                    })?;
                    textures.push(t);
                    Some(textures.len() as u32 - 1)
                }
                None => None,
            };
            materials.push(Material {
                color: m.diffuse,
                emission: m.emission,
                texture,
                ..Material::default()
            });
        }
        let fallback = materials.len() as u32;
        materials.push(Material::default());
        let prim_material = mesh
            .tri_material
            .iter()
            .map(|m| m.unwrap_or(fallback))
            .collect();
        let scene = Scene {
            geometry: Geometry {
                vertices: mesh.positions,
                triangles: mesh.triangles,
                ..Default::default()
            },
            normals: if mesh.normals_from_file {
                mesh.normals
            } else {
                Vec::new()
            },
            uvs: mesh.uvs,
            prim_material,
            materials,
            textures,
            lights: Vec::new(),
            camera,
            settings: RenderSettings {
                width: 1024,
                height: 768,
                ..Default::default()
            },
        };
        Ok((scene, warnings))
    }
}
