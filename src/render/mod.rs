//! Rendering: Whitted shading (scalar and packet), sampling, tiles and the film.

pub mod film;
pub mod sample;
pub mod shade;
pub mod shade_packet;
pub mod tiles;
