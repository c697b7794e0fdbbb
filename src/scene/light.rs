//! Lights: points, and rectangles sampled on a stratified grid (tutorial part 5).

use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    Point {
        position: Vec3,
        color: Vec3,
    },
    /// The parallelogram `corner + s * edge_u + t * edge_v`, `s, t` in `[0, 1]`.
    Area {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
        color: Vec3,
        /// Shadow rays per shading point at the first bounce.
        samples: u32,
    },
}

impl Light {
    pub fn color(&self) -> Vec3 {
        match self {
            Light::Point { color, .. } | Light::Area { color, .. } => *color,
        }
    }

    /// The point a shadow ray aims at for sample `s` in `[0,1)^2` (ignored for points).
    pub fn point_at(&self, s: f32, t: f32) -> Vec3 {
        match self {
            Light::Point { position, .. } => *position,
            Light::Area {
                corner,
                edge_u,
                edge_v,
                ..
            } => *corner + *edge_u * s + *edge_v * t,
        }
    }
}
