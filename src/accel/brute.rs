//! The oracle: every ray against every primitive. Slow, obviously correct, and the
//! reference that the kd-tree and packet paths are tested against.

use super::{Accel, Prims};
use crate::geom::{Aabb, Geometry};
use crate::ray::{Hit, Ray};

/// Tests every primitive for every ray: the accelerator the kd-tree must agree with.
pub struct BruteForce {
    prims: Prims,
    bounds: Aabb,
}

impl BruteForce {
    /// The oracle over `g`'s primitives (no build: it keeps the records only).
    pub fn new(g: &Geometry) -> Self {
        BruteForce {
            prims: Prims::new(g),
            bounds: g.bounds(),
        }
    }
}

impl Accel for BruteForce {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_usable() {
            return None;
        }
        let mut best = Hit::MISS;
        for prim in 0..self.prims.plane_base {
            if let Some(h) = self.prims.intersect_prim(prim, ray, ray.t_max)
                && Hit::is_closer(h.t, h.prim, &best)
            {
                best = h;
            }
        }
        self.prims.intersect_planes(ray, &mut best);
        best.is_hit().then_some(best)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        ray.is_usable()
            && (0..self.prims.plane_base)
                .any(|p| self.prims.intersect_prim(p, ray, ray.t_max).is_some())
            || self.prims.planes_occlude(ray)
    }
}
