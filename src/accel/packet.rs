//! Ray packets in structure-of-arrays form: one SIMD register per component, one ray
//! per lane (Wald 2004, chapter 6). The lane count comes from [`crate::simd::LANES`].

use crate::ray::{DIR_MAX, DIR_MIN, Hit, NO_HIT, Ray};
use crate::scene::CameraFrame;
use crate::simd::{LANES, Mask, Vf, Vu, mask_from_bits, max_abs, select, select_u};
use glam::Vec3;

/// `LANES` rays. Lanes whose bit in `active` is clear are ignored by every kernel: their
/// values (NaN included) never influence the active lanes, and their outputs stay as
/// they were.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket {
    pub org: [Vf; 3],
    pub dir: [Vf; 3],
    /// `1 / dir`, computed with a true division (not `rcp`) so traversal matches the
    /// scalar path bit for bit.
    pub inv_dir: [Vf; 3],
    pub t_min: Vf,
    pub t_max: Vf,
    /// Lane mask of the rays to trace.
    pub active: Mask,
}

impl RayPacket {
    /// Packs up to `LANES` rays; lanes past `rays.len()` are inactive.
    pub fn from_rays(rays: &[Ray]) -> RayPacket {
        assert!(rays.len() <= LANES, "a packet holds at most {LANES} rays");
        let mut o = [[0.0f32; LANES]; 3];
        let mut d = [[0.0f32; LANES]; 3];
        let mut t_min = [0.0f32; LANES];
        let mut t_max = [0.0f32; LANES];
        for (i, r) in rays.iter().enumerate() {
            for a in 0..3 {
                o[a][i] = r.org[a];
                d[a][i] = r.dir[a];
            }
            t_min[i] = r.t_min;
            t_max[i] = r.t_max;
        }
        let org = o.map(Vf::from);
        let dir = d.map(Vf::from);
        RayPacket {
            org,
            dir,
            inv_dir: dir.map(|x| Vf::ONE / x),
            t_min: Vf::from(t_min),
            t_max: Vf::from(t_max),
            active: mask_from_bits((1u32 << rays.len()) - 1),
        }
    }

    /// Packs the rays of the `Some` lanes; `None` lanes are inactive.
    pub fn from_lanes(rays: &[Option<Ray>; LANES]) -> RayPacket {
        let fill = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0);
        let mut p = RayPacket::from_rays(&rays.map(|r| r.unwrap_or(fill)));
        let live = (0..LANES).filter(|&i| rays[i].is_some());
        p.active = mask_from_bits(live.fold(0, |m, i| m | (1 << i)));
        p
    }

    /// The camera rays of the 2x2 pixel quad whose top-left pixel is `(x, y)`, in
    /// RAYS.md's lane order: `(x, y)`, `(x + 1, y)`, `(x, y + 1)`, `(x + 1, y + 1)`.
    pub fn camera_quad(frame: &CameraFrame, x: u32, y: u32) -> [Ray; LANES] {
        let pixel = |i: u32| {
            let (px, py) = (x + (i & 1), y + (i >> 1));
            frame.ray(px as f32 + 0.5, py as f32 + 0.5)
        };
        std::array::from_fn(|i| pixel(i as u32))
    }

    /// Lanes that can hit anything; the twin of [`Ray::is_usable`] (finite origin and
    /// direction, the direction's largest component in [`DIR_MIN`, `DIR_MAX`],
    /// `t_min <= t_max`).
    #[inline]
    pub fn usable(&self) -> Mask {
        let finite = |v: &[Vf; 3]| v[0].is_finite() & v[1].is_finite() & v[2].is_finite();
        let d_max = max_abs(&self.dir);
        let scaled = d_max.simd_ge(Vf::splat(DIR_MIN)) & d_max.simd_le(Vf::splat(DIR_MAX));
        finite(&self.org) & finite(&self.dir) & scaled & self.t_min.simd_le(self.t_max)
    }

    /// Bit `i` set when lane `i` is active.
    #[inline]
    pub fn active_bits(&self) -> u32 {
        crate::simd::bits(self.active)
    }

    /// Lane `i` as a scalar ray, or `None` when it is inactive.
    pub fn lane(&self, i: usize) -> Option<Ray> {
        if self.active_bits() & (1 << i) == 0 {
            return None;
        }
        let c = |v: &[Vf; 3]| Vec3::new(v[0].as_array()[i], v[1].as_array()[i], v[2].as_array()[i]);
        Some(Ray::new(
            c(&self.org),
            c(&self.dir),
            self.t_min.as_array()[i],
            self.t_max.as_array()[i],
        ))
    }
}

/// Top-left pixels of the 2x2 quads of a `width` x `height` image in RAYS.md's packet
/// order: quads row-major inside 16x16 tiles, tiles row-major. Edge tiles are cut to the
/// image; `width` and `height` must be even.
pub fn quad_order(width: u32, height: u32) -> Vec<(u32, u32)> {
    assert!(
        width.is_multiple_of(2) && height.is_multiple_of(2),
        "quads need an even image size"
    );
    let mut quads = Vec::with_capacity((width * height / 4) as usize);
    for ty in (0..height).step_by(16) {
        for tx in (0..width).step_by(16) {
            for y in (ty..(ty + 16).min(height)).step_by(2) {
                for x in (tx..(tx + 16).min(width)).step_by(2) {
                    quads.push((x, y));
                }
            }
        }
    }
    quads
}

/// One primitive's hits against a packet: lane `i` hit where `mask` is set (never for an
/// inactive lane); `t`, `u`, `v` are meaningful only there.
#[derive(Clone, Copy, Debug)]
pub struct LaneHits {
    pub mask: Mask,
    pub t: Vf,
    pub u: Vf,
    pub v: Vf,
}

impl LaneHits {
    /// No lane hit.
    #[inline]
    pub fn none() -> LaneHits {
        LaneHits {
            mask: Mask::ZERO,
            t: Vf::ZERO,
            u: Vf::ZERO,
            v: Vf::ZERO,
        }
    }
}

/// Closest hits of a packet, one lane per ray; a miss has `t = +inf`, `prim = NO_HIT`.
#[derive(Clone, Copy, Debug)]
pub struct HitPacket {
    pub t: Vf,
    pub u: Vf,
    pub v: Vf,
    pub prim: Vu,
}

impl HitPacket {
    /// All lanes missed.
    pub fn miss() -> HitPacket {
        HitPacket {
            t: Vf::splat(f32::INFINITY),
            u: Vf::ZERO,
            v: Vf::ZERO,
            prim: Vu::splat(NO_HIT),
        }
    }

    /// Keeps, in each lane where `hits` hit, the closer of the lane's hit and primitive
    /// `prim`'s, in the order of [`Hit::is_closer`] (smaller `t`, ties to the smaller id).
    /// Returns the lanes that changed.
    #[inline]
    pub fn merge(&mut self, hits: &LaneHits, prim: u32) -> Mask {
        let prim_v = Vu::splat(prim);
        let smaller_id = Mask::from_bits(self.prim.simd_gt(prim_v));
        let closer = hits.t.simd_lt(self.t) | (hits.t.simd_eq(self.t) & smaller_id);
        let take = hits.mask & closer;
        self.t = select(take, hits.t, self.t);
        self.u = select(take, hits.u, self.u);
        self.v = select(take, hits.v, self.v);
        self.prim = select_u(take, prim_v, self.prim);
        take
    }

    /// Builds a packet lane by lane.
    pub fn from_lanes(mut f: impl FnMut(usize) -> Hit) -> HitPacket {
        let hits: [Hit; LANES] = std::array::from_fn(&mut f);
        HitPacket {
            t: Vf::from(hits.map(|h| h.t)),
            u: Vf::from(hits.map(|h| h.u)),
            v: Vf::from(hits.map(|h| h.v)),
            prim: Vu::from(hits.map(|h| h.prim)),
        }
    }

    /// Lane `i` as a scalar hit.
    pub fn lane(&self, i: usize) -> Hit {
        Hit {
            t: self.t.as_array()[i],
            u: self.u.as_array()[i],
            v: self.v.as_array()[i],
            prim: self.prim.as_array()[i],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quad_order_covers_every_pixel_once_in_tiles() {
        let quads = quad_order(48, 20);
        let mut seen = vec![0u8; 48 * 20];
        for &(x, y) in &quads {
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                seen[((y + dy) * 48 + x + dx) as usize] += 1;
            }
        }
        assert!(seen.iter().all(|&n| n == 1));
        // The first tile's 64 quads come before the second tile's.
        assert_eq!(quads[7], (14, 0));
        assert_eq!(quads[8], (0, 2));
        assert_eq!(quads[64], (16, 0));
    }
}
