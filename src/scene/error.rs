//! Errors of the scene stage: what went wrong with a scene file, an OBJ mesh or a texture,
//! always naming the file and, where there is one, the line and the key or field.
//!
//! Messages read `file:line: key: what is wrong`, like a compiler's, so an editor can
//! jump to the place. Every variant is about user data; `crate::is_input_error` maps them
//! all to the CLI's exit code 2.

use std::path::PathBuf;

/// A scene file (TOML) that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file cannot be opened or read.
    #[error("{}: cannot read scene file", path.display())]
    Io {
        /// The scene file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// TOML syntax errors, as reported by the TOML parser (`line` 0 when it gives no
    /// position).
    #[error("{}{}: {message}", path.display(), line_text(*line))]
    Syntax {
        /// The scene file.
        path: PathBuf,
        /// 1-based line, or 0 when the parser gives no position.
        line: usize,
        /// The TOML parser's message.
        message: String,
    },
    /// A key the scene format does not have (often a typo: the nearest valid key is
    /// suggested).
    #[error("{}:{line}: unknown key `{key}`{}", path.display(), suggestion_text(suggestion))]
    UnknownKey {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the key or value at fault.
        line: usize,
        /// The dotted key as written, as `spheres[0].radus`.
        key: String,
        /// The nearest valid key, when one is close enough to be a likely typo.
        suggestion: Option<String>,
    },
    /// A value of the right type outside its valid range (or not finite).
    #[error("{}:{line}: {key}: {message}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the key or value at fault.
        line: usize,
        /// The dotted key, as `spheres[1].radius`.
        key: String,
        /// What is wrong, without the place.
        message: String,
    },
    /// A reference to a material or texture that the file does not define.
    #[error("{}:{line}: {key}: no {kind} named `{name}`", path.display())]
    UnknownName {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the key or value at fault.
        line: usize,
        /// The dotted key, as `spheres[1].radius`.
        key: String,
        /// `material` or `texture`.
        kind: &'static str,
        /// The name that is not defined.
        name: String,
    },
    /// A mesh of `[[meshes]]` that cannot be loaded; the OBJ error, next in the chain,
    /// names the OBJ file and its line.
    #[error("{}:{line}: {key}: cannot load the mesh", path.display())]
    Mesh {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the mesh's `file` key.
        line: usize,
        /// The mesh's `file` key, as `meshes[0].file`.
        key: String,
        /// Why the mesh cannot be loaded.
        source: Box<ObjError>,
    },
    /// A texture named by the scene (or by an MTL file of one of its meshes) that cannot
    /// be used. The message names only the place in the scene file; the texture's own
    /// error, next in the chain, says what is wrong with which file.
    #[error("{}:{line}: {key}", path.display())]
    Texture {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the key naming the texture (the mesh's `file` for an MTL
        /// texture).
        line: usize,
        /// That key, as `textures.wood.file`.
        key: String,
        /// Why the texture cannot be used.
        source: Box<TextureError>,
    },
}

fn line_text(line: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(":{line}")
    }
}

fn suggestion_text(s: &Option<String>) -> String {
    match s {
        Some(s) => format!(" (did you mean `{s}`?)"),
        None => String::new(),
    }
}

/// A Wavefront OBJ mesh or its MTL material library that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ObjError {
    /// The OBJ file cannot be opened or read.
    #[error("{}: cannot read mesh", path.display())]
    Io {
        /// The OBJ file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A line that is not valid OBJ or MTL (`element` is its first word).
    #[error("{}:{line}: {element}: {message}", path.display())]
    Malformed {
        /// The OBJ file, or the MTL file for errors in a material library.
        path: PathBuf,
        /// 1-based line of the statement.
        line: usize,
        /// The statement's first word (`f`, `v`, `vt` ...).
        element: String,
        /// What is wrong, without the place.
        message: String,
    },
    /// An index of 0 in a face; OBJ counts from 1.
    #[error("{}:{line}: {element}: index 0 is not valid (OBJ indices start at 1)", path.display())]
    ZeroIndex {
        /// The OBJ file.
        path: PathBuf,
        /// 1-based line of the statement.
        line: usize,
        /// `f`, the statement holding the index.
        element: &'static str,
    },
    /// An index naming a vertex, coordinate or normal not defined above its face
    /// (positive or negative).
    #[error(
        "{}:{line}: {element}: index {index} is out of range ({count} {what} available)",
        path.display()
    )]
    IndexOutOfRange {
        /// The OBJ file.
        path: PathBuf,
        /// 1-based line of the statement.
        line: usize,
        /// `f`, the statement holding the index.
        element: &'static str,
        /// The index as written (negative ones count back from the last definition).
        index: i64,
        /// How many of `what` were defined above the face.
        count: usize,
        /// `vertices`, `texture coordinates` or `normals`.
        what: &'static str,
    },
    /// A coordinate that is `nan`, `inf` or too large for a 32-bit float.
    #[error("{}:{line}: {element}: value `{value}` is not a finite number", path.display())]
    NonFinite {
        /// The OBJ file, or the MTL file for errors in a material library.
        path: PathBuf,
        /// 1-based line of the statement.
        line: usize,
        /// The statement's first word (`f`, `v`, `vt` ...).
        element: String,
        /// The number as written, or the vector it became when only that overflows.
        value: String,
    },
    /// A mesh without a single face.
    #[error("{}: the mesh has no faces", path.display())]
    Empty {
        /// The OBJ file.
        path: PathBuf,
    },
    /// More vertices or triangles than a `u32` prim id can number.
    #[error("{}: more than {max} {what}; raypack numbers them with 32 bits", path.display())]
    TooLarge {
        /// The OBJ file.
        path: PathBuf,
        /// `vertices` or `triangles`.
        what: &'static str,
        /// The largest count that 32-bit ids can number.
        max: u64,
    },
    /// An `mtllib` file that cannot be read.
    #[error("{}:{line}: mtllib: cannot read material library {}", path.display(), mtl.display())]
    MissingMtl {
        /// The OBJ file.
        path: PathBuf,
        /// 1-based line of the `mtllib` statement.
        line: usize,
        /// The material library, resolved against the OBJ file's folder.
        mtl: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A `usemtl` name defined by none of the file's material libraries.
    #[error("{}:{line}: usemtl: no material named `{name}` in the material libraries", path.display())]
    UnknownMaterial {
        /// The OBJ file.
        path: PathBuf,
        /// 1-based line of the `usemtl` statement.
        line: usize,
        /// The name that no `newmtl` defines.
        name: String,
    },
    /// A `map_Kd` texture file that does not exist.
    #[error("{}:{line}: map_Kd: texture {} does not exist", path.display(), texture.display())]
    MissingTexture {
        /// The MTL file.
        path: PathBuf,
        /// 1-based line of the `map_Kd` statement.
        line: usize,
        /// The texture, resolved against the MTL file's folder.
        texture: PathBuf,
    },
    /// A `map_Kd` texture that exists but cannot be used (a scene built straight from an
    /// OBJ file, [`crate::scene::Scene::from_obj`]).
    #[error("{}: material `{material}`: map_Kd", path.display())]
    Texture {
        /// The OBJ file.
        path: PathBuf,
        /// The MTL material whose texture it is.
        material: String,
        /// What is wrong with the texture; names the texture file.
        source: Box<TextureError>,
    },
    /// `tobj` and raypack's own line scan read the file differently (a reader bug, not
    /// bad input; reported rather than loading a mesh with the wrong prim ids).
    #[error("{}: readers disagree: {message}", path.display())]
    Inconsistent {
        /// The OBJ file.
        path: PathBuf,
        /// What the readers disagree on.
        message: String,
    },
    /// `tobj` refused a file that raypack's own line check accepted.
    #[error("{}: cannot parse mesh", path.display())]
    Parse {
        /// The OBJ file.
        path: PathBuf,
        /// `tobj`'s error.
        source: tobj::LoadError,
    },
}

/// An image texture that cannot be used. The format is read from the file's first bytes,
/// never from its name, so each message says what the file is.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The file cannot be opened or read (also: a folder).
    #[error("{}: cannot read texture", path.display())]
    Io {
        /// The image file, as the scene or MTL file resolved it.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A file of zero bytes.
    #[error("{}: texture file is empty", path.display())]
    Empty {
        /// The image file, as the scene or MTL file resolved it.
        path: PathBuf,
    },
    /// Bytes that no image format starts with; `what` says what they look like instead
    /// (text, a PDF document, or the first bytes in hex).
    #[error("{}: {what}, not a PNG, JPEG or TGA image", path.display())]
    NotAnImage {
        /// The image file, as the scene or MTL file resolved it.
        path: PathBuf,
        /// What the bytes look like, as a noun phrase.
        what: String,
    },
    /// An image in a format that raypack does not decode (GIF, WebP, OpenEXR ...).
    #[error("{}: {format} image; textures must be PNG, JPEG or TGA", path.display())]
    Unsupported {
        /// The image file, as the scene or MTL file resolved it.
        path: PathBuf,
        /// The format's usual name, as `GIF`.
        format: &'static str,
    },
    /// A file that starts as a `format` image but does not decode (truncated, corrupt).
    #[error("{}: cannot decode {format} texture", path.display())]
    Decode {
        /// The image file, as the scene or MTL file resolved it.
        path: PathBuf,
        /// `PNG`, `JPEG` or `TGA`, as the first bytes say.
        format: &'static str,
        /// The decoder's reason.
        source: DecodeError,
    },
    /// An image with a side of 0 or larger than [`crate::scene::texture::MAX_TEXTURE_SIDE`].
    #[error("{}: texture is {width}x{height}; each side must be 1 to {max} texels", path.display())]
    Size {
        /// The image file, as the scene or MTL file resolved it.
        path: PathBuf,
        /// Width in texels, from the image header.
        width: u32,
        /// Height in texels, from the image header.
        height: u32,
        /// The largest side allowed.
        max: u32,
    },
}

/// Why a decoder rejected an image: the innermost message of `image`'s error, whose own
/// messages repeat their causes ("Format error decoding Png: X" with source X), so a
/// chain printed in full would say X twice.
#[derive(Debug)]
pub struct DecodeError(
    /// The decoder's error, whole, for `Debug` and for callers that match on it.
    pub image::ImageError,
);

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut innermost: &dyn std::error::Error = &self.0;
        while let Some(cause) = innermost.source() {
            innermost = cause;
        }
        write!(f, "{innermost}")
    }
}

impl std::error::Error for DecodeError {}

/// Something in user data that raypack accepts but the user should hear about. Loaders
/// return these beside what they built; the CLI prints each once on stderr.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Warning {
    /// Degenerate triangles of an OBJ file: they keep their prim ids but no ray hits
    /// them, and the kd-tree leaves them out.
    DegenerateTriangles {
        /// The OBJ file.
        path: PathBuf,
        /// How many triangles are degenerate.
        count: u32,
        /// How many of them have finite corners but an area that overflows `f32` (the
        /// rest have zero area).
        overflow: u32,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::DegenerateTriangles {
                path,
                count,
                overflow,
            } => {
                let s = if *count == 1 { "" } else { "s" };
                let why = match (*count - *overflow, *overflow) {
                    (_, 0) => "zero-area".to_string(),
                    (0, _) => "area overflows f32: coordinates too large".to_string(),
                    (zero, over) => format!("{zero} of zero area, {over} whose area overflows f32"),
                };
                write!(
                    f,
                    "{}: {count} degenerate ({why}) triangle{s} skipped",
                    path.display()
                )
            }
        }
    }
}
