//! Rendering: Whitted shading (scalar and packet), sampling, tiles and the film.
//!
//! [`tiles::render`] is the entry point: it splits the image into tiles, traces camera
//! quads through [`shade::Shader`] (the scalar reference) and writes a [`film::Film`].

pub mod film;
pub mod sample;
pub mod shade;
pub mod shade_packet;
pub mod tiles;

pub use film::{Film, FilmError};
pub use shade::{HitSignature, RayCounts, Shader};
pub use tiles::{Mode, Rendered, render};
