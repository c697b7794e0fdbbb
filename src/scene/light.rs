//! Lights: points, and rectangles sampled on a stratified grid (tutorial part 5).

use glam::Vec3;

/// A light source. Neither kind falls off with distance (as in the tutorial), so `color`
/// is the light a surface receives at any range.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// A point: hard shadows, one shadow ray per shading point.
    Point {
        /// Where the light is.
        position: Vec3,
        /// Linear RGB intensity; components may exceed 1.
        color: Vec3,
    },
    /// The parallelogram `corner + s * edge_u + t * edge_v`, `s, t` in `[0, 1]`.
    Area {
        /// The corner where `s = t = 0`.
        corner: Vec3,
        /// First edge from `corner`; not parallel to `edge_v` (the area is non-zero).
        edge_u: Vec3,
        /// Second edge from `corner`.
        edge_v: Vec3,
        /// Linear RGB intensity of the whole light: its samples are averaged, so a
        /// fully visible area light lights like a point light of this colour.
        color: Vec3,
        /// Shadow rays per shading point at the first bounce.
        samples: u32,
    },
}

impl Light {
    /// The light's intensity, whatever its kind.
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
