//! raypack: a CPU ray tracer built around SIMD ray packets (4, 8 or 16 lanes) traced
//! through a SAH kd-tree, with a scalar reference path kept beside every SIMD kernel.
//!
//! Data flows one way through the modules:
//! - [`scene`]: geometry, materials, lights, camera, textures, TOML and OBJ loading;
//! - [`accel`]: the intersection interface, brute force (the oracle), TriAccel and the
//!   kd-tree with scalar and packet traversal;
//! - [`render`]: shading, sampling, tiles and the film;
//! - the `raypack` binary's CLI on top.
//!
//! [`simd`] is the one place that knows the SIMD backend and its widths.

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(clippy::undocumented_unsafe_blocks)]
// `!(x >= 0.0)` is how the kernels reject NaN along with the negatives.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[warn(missing_docs)]
pub mod accel;
pub mod output;
pub mod ray;
pub mod rayset;
pub mod render;
pub mod scene;
#[warn(missing_docs)]
pub mod simd;

/// True when `e` is one of the library's errors about user data (scene files, meshes,
/// textures, ray files), which the CLI reports with exit code 2. Failing to write an
/// output is not one: the input was fine, the disk or the path was not.
pub fn is_input_error(e: &(dyn std::error::Error + 'static)) -> bool {
    e.is::<scene::SceneError>()
        || e.is::<scene::ObjError>()
        || e.is::<scene::TextureError>()
        || e.downcast_ref::<rayset::RaySetError>()
            .is_some_and(rayset::RaySetError::is_input)
        || e.is::<rayset::scenes::BenchSceneError>()
}
