//! The standard ray sets of RAYS.md, made by the rules of the Embree peer harness
//! (`peers/embree`, command `gen`) so that a set written here and one written there
//! describe the same rays:
//!
//! - primary: the pinhole camera of RAYS.md in packet order, computed in f64, stored as
//!   f32, `tmin = 0`, `tmax = +inf`;
//! - for every primary hit, in primary order (misses give no secondary ray): the hit
//!   point `p = o + t d` in f64, the geometric normal flipped to face the ray, and the
//!   origin `p + 1e-4 * diagonal * n` (diagonal of the bounds of the bounded primitives);
//! - shadow: toward the point light, `tmax` = distance to it;
//! - diffuse: a cosine-weighted direction about `n` from PCG32 (seed 42, sequence 54; two
//!   24-bit draws per hit), in the orthonormal frame of Duff et al. 2017;
//! - the light: halfway between the eye and the first surface above it along the
//!   camera's true up, else the top of the scene box (eye inside it), else half the
//!   diagonal above the eye ([`LightSource`]).
//!
//! Where the harness and raypack can differ: the secondary rays start from each tracer's
//! own primary hits (a ray grazing an edge may hit in one and miss in the other, which
//! changes the secondary set's length and order from there on); the harness's C++ is
//! compiled with floating-point contraction (FMA) allowed, raypack never fuses, so the
//! f32 values may differ in the last bit; and raypack's scenes may hold spheres, boxes
//! and planes, whose normals the harness never needs.

use super::{RaySet, RaySetError, TILE, packet_pixel};
use crate::accel::Accel;
use crate::onb::Onb;
use crate::ray::{Hit, Ray};
use crate::rng::Pcg32;
use crate::scene::file::MAX_PIXELS;
use crate::scene::{Geometry, PrimRef, View, scene_box};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Default image size of the primary set.
pub const WIDTH: u32 = 1024;
pub const HEIGHT: u32 = 768;
/// Secondary origins are offset by this times the scene diagonal.
pub const OFFSET_SCALE: f64 = 1e-4;
/// PCG32 seed and sequence of the diffuse set (the harness's `pcg32_srandom_r(42, 54)`).
pub const PCG_SEED: u64 = 42;
pub const PCG_SEQ: u64 = 54;

/// `forward`, `right`, `up'` of RAYS.md.
struct Frame {
    forward: DVec3,
    right: DVec3,
    up: DVec3,
}

fn normalize(v: DVec3) -> DVec3 {
    v * (1.0 / v.length())
}

/// The basis of RAYS.md in f64, or why `view` has none.
fn frame(view: &View) -> Result<Frame, RaySetError> {
    let bad = |reason: &str| RaySetError::BadParameter {
        what: "camera".into(),
        reason: reason.into(),
    };
    if !(view.eye.is_finite() && view.target.is_finite() && view.up.is_finite()) {
        return Err(bad("eye, target and up must be finite"));
    }
    if !(view.vfov_deg > 0.0 && view.vfov_deg < 180.0) {
        return Err(bad("vfov_deg must be in (0, 180)"));
    }
    let forward = normalize(view.target - view.eye);
    let r = forward.cross(view.up);
    if r.length().is_nan() || r.length() <= 1e-12 {
        return Err(bad(
            "up is parallel to the view direction (or eye == target)",
        ));
    }
    let right = normalize(r);
    Ok(Frame {
        forward,
        right,
        up: right.cross(forward),
    })
}

/// The camera's true up (`up'` of RAYS.md).
pub fn true_up(view: &View) -> Result<DVec3, RaySetError> {
    Ok(frame(view)?.up)
}

fn to_ray(o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Ray {
    Ray::new(o.as_vec3(), d.as_vec3(), t_min as f32, t_max as f32)
}

/// The camera of RAYS.md at one image size: the ray through any pixel, computed in f64.
struct Pinhole {
    eye: DVec3,
    frame: Frame,
    /// `tan(vfov / 2)`.
    h: f64,
    width: f64,
    height: f64,
}

impl Pinhole {
    /// The camera of `view` for a `width x height` image of at most [`MAX_PIXELS`]
    /// pixels, or why there is none.
    fn new(view: &View, width: u32, height: u32) -> Result<Pinhole, RaySetError> {
        let what = || format!("image size {width}x{height}");
        if width == 0 || height == 0 {
            return Err(RaySetError::BadParameter {
                what: what(),
                reason: "width and height must be positive".into(),
            });
        }
        if width as u64 * height as u64 > MAX_PIXELS {
            return Err(RaySetError::BadParameter {
                what: what(),
                reason: format!("more than {MAX_PIXELS} pixels, the limit of scene files"),
            });
        }
        Ok(Pinhole {
            eye: view.eye,
            frame: frame(view)?,
            h: (view.vfov_deg * std::f64::consts::PI / 180.0 / 2.0).tan(),
            width: width as f64,
            height: height as f64,
        })
    }

    /// The ray through the centre of pixel `(x, y)` (`y = 0` is the top row); pixels
    /// past the image's edge continue the same grid.
    fn ray(&self, x: u32, y: u32) -> Ray {
        let (w, hh, f) = (self.width, self.height, &self.frame);
        let ndc_x = ((x as f64 + 0.5) / w * 2.0 - 1.0) * self.h * (w / hh);
        let ndc_y = (1.0 - (y as f64 + 0.5) / hh * 2.0) * self.h;
        let d = normalize(f.forward + f.right * ndc_x + f.up * ndc_y);
        to_ray(self.eye, d, 0.0, f64::INFINITY)
    }
}

/// The `primary` set: the camera's rays at `width x height` in packet order, at most
/// [`MAX_PIXELS`] of them (the limit of scene files).
pub fn primary(view: &View, width: u32, height: u32) -> Result<RaySet, RaySetError> {
    if width == 0 || height == 0 || !width.is_multiple_of(TILE) || !height.is_multiple_of(TILE) {
        return Err(RaySetError::BadParameter {
            what: format!("image size {width}x{height}"),
            reason: format!(
                "width and height must be positive multiples of {TILE} (packet order uses {TILE}x{TILE} tiles)"
            ),
        });
    }
    // At whole tiles the padded set is the image itself.
    padded_image_set(view, width, height)
}

/// The camera's rays of RAYS.md at any `width x height` (at most [`MAX_PIXELS`]), in
/// row-major order: ray `y * width + x` through pixel `(x, y)`, bit for bit the ray of
/// that pixel in [`primary`].
pub fn camera_rays(view: &View, width: u32, height: u32) -> Result<Vec<Ray>, RaySetError> {
    let camera = Pinhole::new(view, width, height)?;
    Ok((0..height)
        .into_par_iter()
        .flat_map_iter(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| camera.ray(x, y))
        .collect())
}

/// [`camera_rays`] as an image set in packet order, the image padded to the next
/// multiples of [`TILE`] on the same pixel grid (the rays past the right and bottom
/// edges are extra): what [`super::trace::trace_image`] traces in pixel blocks.
pub fn padded_image_set(view: &View, width: u32, height: u32) -> Result<RaySet, RaySetError> {
    let camera = Pinhole::new(view, width, height)?;
    let (pw, ph) = (width.next_multiple_of(TILE), height.next_multiple_of(TILE));
    if pw as u64 * ph as u64 > MAX_PIXELS {
        return Err(RaySetError::BadParameter {
            what: format!("image size {width}x{height}"),
            reason: format!("padded to {pw}x{ph}, more than {MAX_PIXELS} pixels"),
        });
    }
    let rays = (0..pw as usize * ph as usize)
        .into_par_iter()
        .map(|i| {
            let (x, y) = packet_pixel(i, pw);
            camera.ray(x, y)
        })
        .collect();
    Ok(RaySet {
        width: pw,
        height: ph,
        rays,
    })
}

/// Where the default light was put (recorded with the set, as the harness's gen.toml).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSource {
    /// Given by the user.
    Given,
    /// Halfway to the first surface above the eye.
    SurfaceAbove,
    /// Halfway to the top of the scene box (the eye is inside it, nothing above).
    BoxTop,
    /// Half the diagonal above the eye (the eye is outside the scene box).
    HalfDiagonal,
}

impl LightSource {
    pub fn describe(self) -> &'static str {
        match self {
            LightSource::Given => "given",
            LightSource::SurfaceAbove => "halfway to the surface above the eye",
            LightSource::BoxTop => "halfway to the top of the scene box above the eye",
            LightSource::HalfDiagonal => "0.5 * diagonal above the eye",
        }
    }
}

/// The harness's default light: halfway between the eye and whatever is above it.
pub fn default_light<A: Accel + ?Sized>(
    accel: &A,
    geometry: &Geometry,
    view: &View,
) -> Result<(DVec3, LightSource), RaySetError> {
    let up = true_up(view)?;
    let (lo, hi, diag) = scene_box(geometry);
    let ray = to_ray(view.eye, up, 0.0, f64::INFINITY);
    let (h, how) = if let Some(hit) = accel.intersect(&ray) {
        (hit.t as f64, LightSource::SurfaceAbove)
    } else {
        let (o, d) = (view.eye.to_array(), up.to_array());
        let (lo, hi) = (lo.to_array(), hi.to_array());
        let mut inside = true;
        let mut exit = f64::INFINITY;
        for k in 0..3 {
            inside &= o[k] >= lo[k] && o[k] <= hi[k];
            if d[k] != 0.0 {
                exit = exit.min(((lo[k] - o[k]) / d[k]).max((hi[k] - o[k]) / d[k]));
            }
        }
        if inside {
            (exit, LightSource::BoxTop)
        } else {
            (diag, LightSource::HalfDiagonal)
        }
    };
    Ok((view.eye + up * (0.5 * h.min(diag)), how))
}

/// The geometric normal of `prim` at `p` in f64, facing against `d`. Triangles use
/// `normalize(cross(v1 - v0, v2 - v0))` (a degenerate one gives `-d`), as the harness.
fn facing_normal(geometry: &Geometry, prim: u32, p: DVec3, d: DVec3) -> DVec3 {
    let n = match geometry.prim_ref(prim) {
        PrimRef::Triangle(i) => {
            let [a, b, c] = geometry.triangle(i).map(|v| v.as_dvec3());
            let n = (b - a).cross(c - a);
            let len = n.length();
            if len > 0.0 { n * (1.0 / len) } else { -d }
        }
        PrimRef::Sphere(i) => {
            let s = &geometry.spheres[i as usize];
            let n = p - s.center.as_dvec3();
            if n.length() > 0.0 { normalize(n) } else { -d }
        }
        _ => geometry.geometric_normal(prim, p.as_vec3()).as_dvec3(),
    };
    if n.dot(d) > 0.0 { -n } else { n }
}

/// A cosine-weighted direction about unit `n` from two uniforms (Malley's method), in
/// the branchless orthonormal basis of Duff et al. 2017.
pub fn cosine_direction(n: DVec3, u1: f64, u2: f64) -> DVec3 {
    let phi = 2.0 * std::f64::consts::PI * u1;
    let r = u2.sqrt();
    let (lx, ly, lz) = (r * phi.cos(), r * phi.sin(), (1.0 - u2).max(0.0).sqrt());
    normalize(Onb::from_w(n).to_world(DVec3::new(lx, ly, lz)))
}

/// The `shadow` and `diffuse` sets made from `primary` and its closest hits.
pub fn secondary(
    geometry: &Geometry,
    primary: &RaySet,
    hits: &[Hit],
    light: DVec3,
) -> (RaySet, RaySet) {
    let (_, _, diag) = scene_box(geometry);
    let eps = OFFSET_SCALE * diag;
    let mut rng = Pcg32::new(PCG_SEED, PCG_SEQ);
    let mut shadow = Vec::new();
    let mut diffuse = Vec::new();
    for (r, h) in primary.rays.iter().zip(hits) {
        if !h.is_hit() {
            continue;
        }
        let (o, d) = (r.org.as_dvec3(), r.dir.as_dvec3());
        let p = o + d * h.t as f64;
        let n = facing_normal(geometry, h.prim, p, d);
        let origin = p + n * eps;
        let to_light = light - origin;
        let dist = to_light.length();
        shadow.push(to_ray(origin, to_light * (1.0 / dist), 0.0, dist));
        let (u1, u2) = (rng.next_f64(), rng.next_f64());
        diffuse.push(to_ray(
            origin,
            cosine_direction(n, u1, u2),
            0.0,
            f64::INFINITY,
        ));
    }
    (RaySet::from_rays(shadow), RaySet::from_rays(diffuse))
}

/// The three standard sets of a scene and how they were made.
#[derive(Clone, Debug)]
pub struct StandardSets {
    pub primary: RaySet,
    /// Closest hits of `primary` (scalar path), from which the secondary sets come.
    pub primary_hits: Vec<Hit>,
    pub shadow: RaySet,
    pub diffuse: RaySet,
    pub light: DVec3,
    pub light_source: LightSource,
    /// Offset of secondary origins along the normal.
    pub offset: f64,
}

/// Closest hits of `rays` on the scalar path, in parallel on the current rayon pool.
pub fn closest_hits<A: Accel + ?Sized>(accel: &A, rays: &[Ray]) -> Vec<Hit> {
    rays.par_iter()
        .with_min_len(1024)
        .map(|r| accel.intersect(r).unwrap_or(Hit::MISS))
        .collect()
}

/// Makes the standard sets of a scene at `width x height`; `light` overrides the
/// default light rule.
pub fn standard_sets<A: Accel + ?Sized>(
    accel: &A,
    geometry: &Geometry,
    view: &View,
    width: u32,
    height: u32,
    light: Option<Vec3>,
) -> Result<StandardSets, RaySetError> {
    let primary = primary(view, width, height)?;
    let primary_hits = closest_hits(accel, &primary.rays);
    let (light, light_source) = match light {
        Some(l) => (l.as_dvec3(), LightSource::Given),
        None => default_light(accel, geometry, view)?,
    };
    let (shadow, diffuse) = secondary(geometry, &primary, &primary_hits, light);
    Ok(StandardSets {
        primary,
        primary_hits,
        shadow,
        diffuse,
        light,
        light_source,
        offset: OFFSET_SCALE * scene_box(geometry).2,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;

    #[test]
    fn cosine_directions_are_unit_and_in_the_hemisphere() {
        let mut rng = Pcg32::new(1, 2);
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            DVec3::new(1.0, -2.0, 0.5).normalize(),
        ] {
            let mut mean_cos = 0.0;
            for _ in 0..4000 {
                let d = cosine_direction(n, rng.next_f64(), rng.next_f64());
                assert!((d.length() - 1.0).abs() < 1e-12);
                assert!(d.dot(n) >= 0.0);
                mean_cos += d.dot(n) / 4000.0;
            }
            // E[cos] under the cosine density is 2/3.
            assert!((mean_cos - 2.0 / 3.0).abs() < 0.02, "{mean_cos}");
        }
    }

    fn quad_room() -> Geometry {
        // A floor (y = 0) and a ceiling (y = 4) over [-10, 10]^2, facing each other.
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        Geometry {
            vertices: vec![
                v(-10.0, 0.0, -10.0),
                v(10.0, 0.0, -10.0),
                v(10.0, 0.0, 10.0),
                v(-10.0, 0.0, 10.0),
                v(-10.0, 4.0, -10.0),
                v(10.0, 4.0, -10.0),
                v(10.0, 4.0, 10.0),
                v(-10.0, 4.0, 10.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]],
            ..Geometry::default()
        }
    }

    #[test]
    fn light_rule_and_secondary_rays_follow_the_harness() {
        let g = quad_room();
        let accel = BruteForce::new(&g);
        let view = View {
            eye: DVec3::new(0.0, 1.0, -5.0),
            target: DVec3::new(0.0, 0.0, 5.0),
            up: DVec3::Y,
            vfov_deg: 60.0,
        };
        let sets = standard_sets(&accel, &g, &view, 32, 16, None).unwrap();
        assert_eq!(sets.light_source, LightSource::SurfaceAbove);
        // Straight up from the eye the ceiling is 3 away; up' leans forward a little.
        assert!((sets.light.y - 2.5).abs() < 0.05, "{}", sets.light);
        let hit_count = sets.primary_hits.iter().filter(|h| h.is_hit()).count();
        assert!(hit_count > 0);
        assert_eq!(sets.shadow.len(), hit_count);
        assert_eq!(sets.diffuse.len(), hit_count);
        let diag = (DVec3::new(20.0, 4.0, 20.0)).length();
        assert!((sets.offset - 1e-4 * diag).abs() < 1e-12);
        for ((p, h), (s, d)) in sets
            .primary
            .rays
            .iter()
            .zip(&sets.primary_hits)
            .filter(|(_, h)| h.is_hit())
            .zip(sets.shadow.rays.iter().zip(&sets.diffuse.rays))
        {
            // Origins sit just off the surface on the ray's side.
            let n = if p.dir.y < 0.0 { 1.0 } else { -1.0 };
            let surface_y = p.at(h.t).y;
            assert!(((s.org.y - surface_y) * n - sets.offset as f32).abs() < 1e-3);
            assert_eq!(s.org, d.org);
            let to_light = sets.light.as_vec3() - s.org;
            assert!((s.t_max - to_light.length()).abs() < 1e-4);
            assert!((s.dir - to_light.normalize()).length() < 1e-5);
            assert!(d.dir.y * n > 0.0, "diffuse ray leaves the surface");
            assert!(d.t_max == f32::INFINITY && d.t_min == 0.0);
        }
        // Nothing is between a floor point and a light under the ceiling.
        assert!(sets.shadow.rays.iter().all(|r| !accel.occluded(r)));
    }

    #[test]
    fn light_outside_the_box_is_half_a_diagonal_up() {
        let g = quad_room();
        let accel = BruteForce::new(&g);
        let view = View {
            eye: DVec3::new(0.0, 10.0, -30.0),
            target: DVec3::new(0.0, 10.0, 0.0),
            up: DVec3::Y,
            vfov_deg: 45.0,
        };
        let (l, how) = default_light(&accel, &g, &view).unwrap();
        assert_eq!(how, LightSource::HalfDiagonal);
        let diag = DVec3::new(20.0, 4.0, 20.0).length();
        assert!((l - (view.eye + DVec3::Y * 0.5 * diag)).length() < 1e-9);
    }

    #[test]
    fn bad_image_sizes_and_cameras_are_refused() {
        let view = View {
            eye: DVec3::ZERO,
            target: DVec3::Z,
            up: DVec3::Y,
            vfov_deg: 60.0,
        };
        assert!(primary(&view, 1000, 768).is_err());
        assert!(primary(&view, 0, 16).is_err());
        let parallel = View {
            up: DVec3::Z,
            ..view
        };
        assert!(primary(&parallel, 16, 16).is_err());
        let set = primary(&view, 16, 16).unwrap();
        // The centre of the image looks down the view direction.
        let c = set.rays[super::super::pixel_packet_index(8, 8, 16)].dir;
        assert!(c.z > 0.99);
    }
}
