//! Rendering: Whitted shading (scalar and packet), sampling, tiles and the film.
//!
//! [`tiles::render`] is the entry point: it splits the image into tiles, traces camera
//! quads through [`shade::Shader`] (the scalar reference) and writes a [`film::Film`].
//! [`gi::render_gi`] renders with a global-illumination integrator instead: the path
//! tracer ([`path`]) or the photon mapper ([`photon`]), over physically based materials
//! ([`bsdf`]) and the scene's emitters ([`lights`]).

pub mod batch;
pub mod bsdf;
pub mod counts;
pub mod film;
pub mod gi;
pub mod light_trace;
pub mod lights;
pub mod path;
pub mod photon;
pub mod sample;
pub mod shade;
pub mod shade_packet;
pub mod tiles;

pub use film::{Film, FilmError};
pub use shade::{HitSignature, RayCounts, Shader};
pub use tiles::{Rendered, render};
