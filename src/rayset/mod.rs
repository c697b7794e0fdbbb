//! Ray sets and hit files: the exchange formats of RAYS.md, the standard sets
//! (primary, shadow, diffuse) and the traced answers that two tracers compare.
//!
//! Stage: between the accelerators and the CLI. [`format`](mod@format) reads and writes the files
//! of RAYS.md, [`standard`] makes the standard sets, [`trace`] traces a set the way the
//! benchmark times it.

pub mod format;
pub mod standard;
pub mod trace;

pub use format::{
    HIT_RECORD_BYTES, HITS_HEADER_BYTES, HITS_MAGIC, RAY_RECORD_BYTES, RAYS_HEADER_BYTES,
    RAYS_MAGIC, RaySet, RaySetError, TILE, hits_bytes, packet_pixel, parse_hits, parse_rays,
    pixel_packet_index, rays_bytes, read_hits, read_rays, write_hits, write_rays,
};
pub use standard::{LightSource, StandardSets};
pub use trace::Checksum;
