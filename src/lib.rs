//! raypack: a CPU ray tracer built around SIMD ray packets (4, 8 or 16 lanes) traced
//! through a SAH kd-tree, with a scalar reference path kept beside every SIMD kernel.
//!
//! # Quick start
//!
//! Load a mesh, build the tree, trace (this is the README's library example; a test
//! keeps the two the same):
//!
//! ```
//! use raypack::prelude::*;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mesh = obj::load("scenes/knot.obj".as_ref())?;
//! let tree = KdTree::build(&Geometry::from(mesh));
//!
//! // One ray: `None` on a miss.
//! let ray = Ray::new(Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY);
//! if let Some(hit) = tree.intersect(&ray) {
//!     println!("triangle {} at t = {} (u {}, v {})", hit.prim, hit.t, hit.u, hit.v);
//! }
//! let shadowed = tree.occluded(&ray); // anything between t_min and t_max
//!
//! // Many rays on every core: one call; a miss is `Hit::MISS` (`is_hit()` is false).
//! let rays: Vec<Ray> = (0..10_000)
//!     .map(|i| {
//!         let a = i as f32 * 2.399_963; // the golden angle spreads the directions
//!         let d = Vec3::new(a.cos(), i as f32 / 5_000.0 - 1.0, a.sin());
//!         Ray::new(Vec3::ZERO, d.normalize(), 0.0, f32::INFINITY)
//!     })
//!     .collect();
//! let mut hits = vec![Hit::MISS; rays.len()];
//! tree.intersect_batch(&rays, &mut hits);
//! let mut blocked = vec![false; rays.len()];
//! tree.occluded_batch(&rays, &mut blocked);
//! assert!(hits.iter().zip(&blocked).all(|(h, b)| h.is_hit() == *b));
//!
//! // A packet of 8 coherent rays, one SIMD lane each (W4 and W16 are the other widths).
//! let packet = tree.intersect_packet(&RayPacket::<W8>::from_rays(&rays[..8]));
//! assert_eq!(packet.lane(0), hits[0]);
//! # let _ = shadowed;
//! # Ok(())
//! # }
//! ```
//!
//! [`prelude`] holds every name used above, [`glam`]'s `Vec3` included.
//!
//! Data flows one way through the modules, and imports point only down this list:
//! - `cli` (the `raypack` binary, `src/cli`): the commands, which reach the library as
//!   `raypack::`, and [`prelude`]: the names a program that traces rays needs;
//! - [`render`] (shading, sampling, tiles, the film) and, beside it, [`rayset`] (the
//!   RAYS.md files, the standard ray sets, the benchmark kernel); neither imports the
//!   other;
//! - [`accel`]: the intersection interface, brute force (the oracle), TriAccel, the
//!   kd-tree with scalar and packet traversal, and the 8-wide BVH for incoherent rays;
//!   and, beside it, [`scene`]: materials,
//!   lights, camera, textures, TOML and OBJ loading, scenes by name. Neither imports the
//!   other, so the accelerators build and test without the loaders;
//! - [`geom`]: the primitives and bounds both of them share;
//! - [`ray`]: the ray and hit records every layer passes around;
//! - at the bottom, used by any layer: [`simd`] (the one place that sets the packet
//!   width), [`rng`] (the random number generators), [`onb`] (the orthonormal basis) and
//!   [`output`] (the atomic file writer).
//!
//! No two files import each other. `tests/layering.rs` checks both rules on the source
//! (and lists the exceptions still being worked on).

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(clippy::undocumented_unsafe_blocks)]
// `!(x >= 0.0)` is how the kernels reject NaN along with the negatives.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[warn(missing_docs)]
pub mod accel;
pub mod geom;
pub mod onb;
pub mod output;
pub mod prelude;
pub mod ray;
pub mod rayset;
pub mod render;
pub mod rng;
pub mod scene;
#[warn(missing_docs)]
pub mod simd;
pub mod studio;

/// The vector library of raypack's API ([`prelude::Vec3`] is its `Vec3`).
pub use glam;

/// True when `e` is one of the library's errors about user data (scene files, meshes,
/// textures, ray files), which the CLI reports with exit code 2. Failing to write an
/// output is not one: the input was fine, the disk or the path was not.
pub fn is_input_error(e: &(dyn std::error::Error + 'static)) -> bool {
    e.is::<scene::SceneError>()
        || e.is::<scene::ObjError>()
        || e.is::<scene::TextureError>()
        || e.downcast_ref::<rayset::RaySetError>()
            .is_some_and(rayset::RaySetError::is_input)
        || e.is::<scene::catalog::BenchSceneError>()
        || e.is::<geom::MeshError>()
        || e.is::<studio::StudioError>()
}
