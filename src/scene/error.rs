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
    #[error("{}: cannot read scene file", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// TOML syntax errors, as reported by the TOML parser (`line` 0 when it gives no
    /// position).
    #[error("{}{}: {message}", path.display(), line_text(*line))]
    Syntax {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{}:{line}: unknown key `{key}`{}", path.display(), suggestion_text(suggestion))]
    UnknownKey {
        path: PathBuf,
        line: usize,
        key: String,
        suggestion: Option<String>,
    },
    /// A value of the right type outside its valid range (or not finite).
    #[error("{}:{line}: {key}: {message}", path.display())]
    Invalid {
        path: PathBuf,
        line: usize,
        key: String,
        message: String,
    },
    #[error("{}:{line}: {key}: no {kind} named `{name}`", path.display())]
    UnknownName {
        path: PathBuf,
        line: usize,
        key: String,
        kind: &'static str,
        name: String,
    },
    #[error("{}:{line}: {key}: cannot load the mesh", path.display())]
    Mesh {
        path: PathBuf,
        line: usize,
        key: String,
        source: Box<ObjError>,
    },
    /// A texture named by the scene (or by an MTL file of one of its meshes) that cannot
    /// be used. The message names only the place in the scene file; the texture's own
    /// error, next in the chain, says what is wrong with which file.
    #[error("{}:{line}: {key}", path.display())]
    Texture {
        path: PathBuf,
        line: usize,
        key: String,
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
    #[error("{}: cannot read mesh", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A line that is not valid OBJ or MTL (`element` is its first word).
    #[error("{}:{line}: {element}: {message}", path.display())]
    Malformed {
        path: PathBuf,
        line: usize,
        element: String,
        message: String,
    },
    #[error("{}:{line}: {element}: index 0 is not valid (OBJ indices start at 1)", path.display())]
    ZeroIndex {
        path: PathBuf,
        line: usize,
        element: &'static str,
    },
    #[error(
        "{}:{line}: {element}: index {index} is out of range ({count} {what} available)",
        path.display()
    )]
    IndexOutOfRange {
        path: PathBuf,
        line: usize,
        element: &'static str,
        index: i64,
        count: usize,
        what: &'static str,
    },
    #[error("{}:{line}: {element}: value `{value}` is not a finite number", path.display())]
    NonFinite {
        path: PathBuf,
        line: usize,
        element: String,
        value: String,
    },
    #[error("{}: the mesh has no faces", path.display())]
    Empty { path: PathBuf },
    #[error("{}: more than {max} {what}; raypack numbers them with 32 bits", path.display())]
    TooLarge {
        path: PathBuf,
        what: &'static str,
        max: u64,
    },
    #[error("{}:{line}: mtllib: cannot read material library {}", path.display(), mtl.display())]
    MissingMtl {
        path: PathBuf,
        line: usize,
        mtl: PathBuf,
        source: std::io::Error,
    },
    #[error("{}:{line}: usemtl: no material named `{name}` in the material libraries", path.display())]
    UnknownMaterial {
        path: PathBuf,
        line: usize,
        name: String,
    },
    #[error("{}:{line}: map_Kd: texture {} does not exist", path.display(), texture.display())]
    MissingTexture {
        path: PathBuf,
        line: usize,
        texture: PathBuf,
    },
    /// `tobj` and raypack's own line scan read the file differently (a reader bug, not
    /// bad input; reported rather than loading a mesh with the wrong prim ids).
    #[error("{}: readers disagree: {message}", path.display())]
    Inconsistent { path: PathBuf, message: String },
    /// `tobj` refused a file that raypack's own line check accepted.
    #[error("{}: cannot parse mesh", path.display())]
    Parse {
        path: PathBuf,
        source: tobj::LoadError,
    },
}

/// An image texture that cannot be used. The format is read from the file's first bytes,
/// never from its name, so each message says what the file is.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    #[error("{}: cannot read texture", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: texture file is empty", path.display())]
    Empty { path: PathBuf },
    /// Bytes that no image format starts with; `what` says what they look like instead
    /// (text, a PDF document, or the first bytes in hex).
    #[error("{}: {what}, not a PNG, JPEG or TGA image", path.display())]
    NotAnImage { path: PathBuf, what: String },
    /// An image in a format that raypack does not decode (GIF, WebP, OpenEXR ...).
    #[error("{}: {format} image; textures must be PNG, JPEG or TGA", path.display())]
    Unsupported { path: PathBuf, format: &'static str },
    /// A file that starts as a `format` image but does not decode (truncated, corrupt).
    #[error("{}: cannot decode {format} texture", path.display())]
    Decode {
        path: PathBuf,
        format: &'static str,
        source: DecodeError,
    },
    #[error("{}: texture is {width}x{height}; each side must be 1 to {max} texels", path.display())]
    Size {
        path: PathBuf,
        width: u32,
        height: u32,
        max: u32,
    },
}

/// Why a decoder rejected an image: the innermost message of `image`'s error, whose own
/// messages repeat their causes ("Format error decoding Png: X" with source X), so a
/// chain printed in full would say X twice.
#[derive(Debug)]
pub struct DecodeError(pub image::ImageError);

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
    /// Zero-area triangles of an OBJ file: they keep their prim ids but no ray hits
    /// them, and the kd-tree leaves them out.
    DegenerateTriangles { path: PathBuf, count: u32 },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::DegenerateTriangles { path, count } => write!(
                f,
                "{}: {count} degenerate (zero-area) triangle{} skipped",
                path.display(),
                if *count == 1 { "" } else { "s" }
            ),
        }
    }
}
