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
    /// The triangle `corner + s * edge_u + t * edge_v`, `s, t >= 0`, `s + t <= 1`: an
    /// emissive triangle of a mesh ([`emitter_lights`]). One-sided, as the emitter is:
    /// it lights only the side that `edge_u x edge_v` faces.
    Triangle {
        /// The first corner.
        corner: Vec3,
        /// From `corner` to the second corner.
        edge_u: Vec3,
        /// From `corner` to the third corner.
        edge_v: Vec3,
        /// Linear RGB intensity of the whole light, as for [`Light::Area`].
        color: Vec3,
        /// Shadow rays per shading point at the first bounce.
        samples: u32,
    },
}

impl Light {
    /// The light's intensity, whatever its kind.
    pub fn color(&self) -> Vec3 {
        match self {
            Light::Point { color, .. }
            | Light::Area { color, .. }
            | Light::Triangle { color, .. } => *color,
        }
    }

    /// Shadow rays per shading point at the first bounce (1 for a point).
    pub fn samples(&self) -> u32 {
        match self {
            Light::Point { .. } => 1,
            Light::Area { samples, .. } | Light::Triangle { samples, .. } => *samples,
        }
    }

    /// The point a shadow ray aims at for sample `s` in `[0,1)^2` (ignored for points).
    /// A triangle folds the square's upper half onto its lower one, so the points stay
    /// uniform over its area.
    pub fn point_at(&self, s: f32, t: f32) -> Vec3 {
        match self {
            Light::Point { position, .. } => *position,
            Light::Area {
                corner,
                edge_u,
                edge_v,
                ..
            } => *corner + *edge_u * s + *edge_v * t,
            Light::Triangle {
                corner,
                edge_u,
                edge_v,
                ..
            } => {
                let (s, t) = if s + t > 1.0 {
                    (1.0 - s, 1.0 - t)
                } else {
                    (s, t)
                };
                *corner + *edge_u * s + *edge_v * t
            }
        }
    }

    /// Whether the light can reach `p`: a one-sided triangle lights only the side it
    /// faces; points and rectangles light both.
    pub fn faces(&self, p: Vec3) -> bool {
        match self {
            Light::Triangle {
                corner,
                edge_u,
                edge_v,
                ..
            } => (p - *corner).dot(edge_u.cross(*edge_v)) > 0.0,
            _ => true,
        }
    }
}

/// The lights [`emitter_lights`] makes of a mesh's emissive triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EmitterLights {
    /// One [`Light::Triangle`] per emissive triangle kept, brightest first.
    pub lights: Vec<Light>,
    /// Emissive triangles left out because there were more than the limit (the dimmest).
    pub left_out: usize,
}

/// The lights of the Whitted tracer for a mesh whose materials emit (MTL `Ke`, or `Ka`
/// above 1): one one-sided [`Light::Triangle`] per emissive triangle, at most
/// `max_lights` of them (the brightest by emitted power, radiance times area).
///
/// The Whitted tracer has no distance falloff, so radiance cannot carry over as it is:
/// the lights' colours are their powers scaled so that their sum is 1 in its largest
/// channel (together they light like one white point light of the tutorial), and the
/// `samples` shadow rays per shading point are shared among them by power, at least one
/// each.
pub fn emitter_lights(scene: &super::Scene, samples: u32, max_lights: usize) -> EmitterLights {
    let g = &scene.geometry;
    let mut emitters: Vec<(Vec3, [Vec3; 3])> = (0..g.triangles.len() as u32)
        .filter_map(|tri| {
            let radiance = scene.material(tri).emission;
            let [a, b, c] = g.triangle(tri);
            let area = 0.5 * (b - a).cross(c - a).length();
            let power = radiance * area;
            (power.max_element() > 0.0 && power.is_finite()).then_some((power, [a, b, c]))
        })
        .collect();
    emitters.sort_by(|x, y| y.0.max_element().total_cmp(&x.0.max_element()));
    let left_out = emitters.len().saturating_sub(max_lights);
    emitters.truncate(max_lights);
    let total: Vec3 = emitters.iter().map(|(power, _)| *power).sum();
    let scale = 1.0 / total.max_element();
    let total_sum = total.element_sum();
    let lights = emitters
        .iter()
        .map(|&(power, [a, b, c])| Light::Triangle {
            corner: a,
            edge_u: b - a,
            edge_v: c - a,
            color: power * scale,
            samples: ((samples as f32 * power.element_sum() / total_sum).round() as u32).max(1),
        })
        .collect();
    EmitterLights { lights, left_out }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Geometry, Material, Scene};

    /// Two emissive triangles of different brightness beside a plain one.
    fn scene() -> Scene {
        let v = |x: f32, z: f32| Vec3::new(x, 1.0, z);
        let geometry = Geometry {
            vertices: vec![v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0), v(1.0, 1.0)],
            triangles: vec![[0, 1, 2], [1, 3, 2], [0, 3, 1]],
            ..Default::default()
        };
        let glow = |e: f32| Material {
            emission: Vec3::splat(e),
            ..Material::default()
        };
        Scene {
            materials: vec![glow(3.0), glow(1.0), Material::default()],
            prim_material: vec![1, 0, 2],
            geometry,
            ..Default::default()
        }
    }

    #[test]
    fn emitters_become_one_sided_triangles_whose_colours_sum_to_one() {
        let e = emitter_lights(&scene(), 16, 8);
        assert_eq!(e.left_out, 0);
        let [bright, dim] = &e.lights[..] else {
            panic!("two lights, not {:?}", e.lights);
        };
        assert_eq!(bright.color(), Vec3::splat(0.75));
        assert_eq!(dim.color(), Vec3::splat(0.25));
        assert_eq!((bright.samples(), dim.samples()), (12, 4));
        // Wound [0, 1, 2] and [1, 3, 2] in the plane y = 1: both face down (-y).
        for light in &e.lights {
            assert!(light.faces(Vec3::new(0.3, 0.0, 0.3)));
            assert!(!light.faces(Vec3::new(0.3, 2.0, 0.3)));
        }
        let limited = emitter_lights(&scene(), 16, 1);
        assert_eq!(limited.left_out, 1);
        assert_eq!(limited.lights[0].color(), Vec3::ONE);
        assert_eq!(limited.lights[0].samples(), 16);
    }

    #[test]
    fn triangle_samples_stay_inside_the_triangle() {
        let light = Light::Triangle {
            corner: Vec3::ZERO,
            edge_u: Vec3::X,
            edge_v: Vec3::Y,
            color: Vec3::ONE,
            samples: 1,
        };
        for (s, t) in [
            (0.0, 0.0),
            (0.9, 0.8),
            (0.5, 0.49),
            (0.99, 0.99),
            (0.2, 0.9),
        ] {
            let p = light.point_at(s, t);
            assert!(p.x >= 0.0 && p.y >= 0.0 && p.x + p.y <= 1.0, "{s} {t}: {p}");
        }
    }
}
