//! Ray packets in structure-of-arrays form: one SIMD register per component, one ray
//! per lane (Wald 2004, chapter 6), at any width `W` of [`crate::simd`].

use crate::ray::{DIR_MAX, DIR_MIN, Hit, NO_HIT, Ray};
use crate::simd::{
    AMap, Float, Isa, LaneBits, LaneMask, MAX_LANES, Mask, Simd, Uint, Vf, Vu, dispatch, inl,
    max_abs, recast, recast_mask, recast_u,
};
use glam::Vec3;

/// `W::LANES` rays. Lanes whose bit in `active` is clear are ignored by every kernel:
/// their values (NaN included) never influence the active lanes, and their outputs stay
/// as they were.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket<W: Simd> {
    /// Origins, x, y and z, one lane per ray.
    pub org: [Vf<W>; 3],
    /// Directions, x, y and z.
    pub dir: [Vf<W>; 3],
    /// `1 / dir`, computed with a true division (not `rcp`) so traversal matches the
    /// scalar path bit for bit.
    pub inv_dir: [Vf<W>; 3],
    /// Start of each ray's interval (exclusive).
    pub t_min: Vf<W>,
    /// End of each ray's interval (exclusive); traversal shrinks it to the best hit.
    pub t_max: Vf<W>,
    /// Lane mask of the rays to trace.
    pub active: Mask<W>,
}

impl<W: Simd> RayPacket<W> {
    /// How many groups the traversal walks the active lanes in: none without an
    /// active lane, 1 for a packet whose lanes agree on every direction sign, else one per
    /// sign octant present. `raypack bench` reports the share of packets of a ray set that split.
    #[inline(always)]
    pub fn sign_group_count(&self) -> usize {
        self.sign_groups(self.active.bits()).1
    }

    /// Lane groups of `active` that agree on every direction sign: none when `active` is
    /// empty, one group when the packet is coherent, else one per sign octant present
    /// (zero components count as positive; they agree with either side), at most eight.
    #[inline(always)]
    pub fn sign_groups(&self, active: LaneBits) -> ([LaneBits; 8], usize) {
        if active == 0 {
            return ([0; 8], 0);
        }
        let neg = self.dir.amap(
            #[inline(always)]
            |d| d.cmp_lt(Vf::<W>::ZERO).bits() & active,
        );
        let pos = self.dir.amap(
            #[inline(always)]
            |d| d.cmp_gt(Vf::<W>::ZERO).bits() & active,
        );
        let mut groups = [0; 8];
        // Written out: `(0..3).all` stays out of line, compiled for the baseline.
        let one_sign = inl(
            #[inline(always)]
            |a: usize| neg[a] == 0 || pos[a] == 0,
        );
        if one_sign(0) && one_sign(1) && one_sign(2) {
            groups[0] = active;
            return (groups, 1);
        }
        let mut count = 0;
        for key in 0..8 {
            let pick = inl(
                #[inline(always)]
                |a: usize| if key & (1 << a) != 0 { neg[a] } else { !neg[a] },
            );
            let group = active & pick(0) & pick(1) & pick(2);
            if group != 0 {
                groups[count] = group;
                count += 1;
            }
        }
        (groups, count)
    }
}

/// The value of an unused lane: a usable ray with an empty interval.
const FILL: Ray = Ray {
    org: Vec3::ZERO,
    dir: Vec3::X,
    t_min: 0.0,
    t_max: 0.0,
};

/// The lowest `n` bits set.
#[inline(always)]
pub fn low_bits(n: usize) -> LaneBits {
    if n == 0 {
        0
    } else {
        LaneBits::MAX >> (LaneBits::BITS as usize - n)
    }
}

impl<W: Simd> RayPacket<W> {
    /// Packs up to `W::LANES` rays; lanes past `rays.len()` are inactive.
    #[inline(always)]
    pub fn from_rays(rays: &[Ray]) -> RayPacket<W> {
        assert!(
            rays.len() <= W::LANES,
            "a packet holds at most {} rays",
            W::LANES
        );
        if rays.len() == W::LANES {
            if handed_on::<W>() {
                return dispatch!(W::LANES; fn full_as::<@, W>(rays));
            }
            // A full packet: one transpose of the rays' records.
            return RayPacket::full(Vf::<W>::transpose8(Ray::as_records(rays)));
        }
        let get = inl(
            #[inline(always)]
            |i: usize| rays.get(i).unwrap_or(&FILL),
        );
        let org = [0, 1, 2].amap(
            #[inline(always)]
            |a| {
                Vf::<W>::from_fn(
                    #[inline(always)]
                    |i| get(i).org[a],
                )
            },
        );
        let dir = [0, 1, 2].amap(
            #[inline(always)]
            |a| {
                Vf::<W>::from_fn(
                    #[inline(always)]
                    |i| get(i).dir[a],
                )
            },
        );
        RayPacket {
            org,
            dir,
            inv_dir: dir.amap(
                #[inline(always)]
                |x| Vf::<W>::ONE / x,
            ),
            t_min: Vf::<W>::from_fn(
                #[inline(always)]
                |i| get(i).t_min,
            ),
            t_max: Vf::<W>::from_fn(
                #[inline(always)]
                |i| get(i).t_max,
            ),
            active: Mask::<W>::from_bits(low_bits(rays.len())),
        }
    }

    /// [`RayPacket::from_rays`] of the rays of `lo` followed by those of `hi`, each
    /// run half the width (a 4x4 pixel block of an image set: two runs of 8 rays, see
    /// [`crate::rayset::trace`]).
    #[inline(always)]
    pub fn from_halves(lo: &[Ray], hi: &[Ray]) -> RayPacket<W> {
        assert!(
            lo.len() == W::LANES / 2 && hi.len() == W::LANES / 2,
            "two runs of half a packet"
        );
        if handed_on::<W>() {
            return dispatch!(W::LANES; fn halves_as::<@, W>(lo, hi));
        }
        RayPacket::full(Vf::<W>::transpose8_halves(
            Ray::as_records(lo),
            Ray::as_records(hi),
        ))
    }

    /// A full packet from its rays' record fields, transposed into lanes.
    #[inline(always)]
    fn full([ox, oy, oz, dx, dy, dz, t_min, t_max]: [Vf<W>; 8]) -> RayPacket<W> {
        let dir = [dx, dy, dz];
        RayPacket {
            org: [ox, oy, oz],
            dir,
            inv_dir: dir.amap(
                #[inline(always)]
                |x| Vf::<W>::ONE / x,
            ),
            t_min,
            t_max,
            active: Mask::<W>::from_bits(W::all_bits()),
        }
    }

    /// Packs the rays of the `Some` lanes (at most `W::LANES`); `None` lanes and lanes
    /// past the slice are inactive.
    #[inline(always)]
    pub fn from_lanes(rays: &[Option<Ray>]) -> RayPacket<W> {
        assert!(
            rays.len() <= W::LANES,
            "a packet holds at most {} rays",
            W::LANES
        );
        let mut filled = [FILL; MAX_LANES];
        let mut live = 0;
        for (i, r) in rays.iter().enumerate() {
            if let Some(r) = r {
                filled[i] = *r;
                live |= 1 << i;
            }
        }
        let mut p = RayPacket::from_rays(&filled[..W::LANES]);
        p.active = Mask::<W>::from_bits(live);
        p
    }

    /// Lanes that can hit anything; the twin of [`Ray::is_usable`] (finite origin and
    /// direction, the direction's largest component in [`DIR_MIN`, `DIR_MAX`],
    /// `t_min <= t_max`).
    #[inline(always)]
    pub fn usable(&self) -> Mask<W> {
        let finite = inl(
            #[inline(always)]
            |v: &[Vf<W>; 3]| v[0].finite() & v[1].finite() & v[2].finite(),
        );
        let d_max = max_abs(&self.dir);
        let scaled = d_max.cmp_ge(Vf::<W>::splat(DIR_MIN)) & d_max.cmp_le(Vf::<W>::splat(DIR_MAX));
        finite(&self.org) & finite(&self.dir) & scaled & self.t_min.cmp_le(self.t_max)
    }

    /// The same rays in backend `B` of the same width (the backend of the instruction
    /// set in use, [`crate::simd::dispatch`]): no bit changes.
    #[inline(always)]
    pub(crate) fn recast<B: Simd>(&self) -> RayPacket<B> {
        debug_assert_eq!(W::LANES, B::LANES);
        RayPacket {
            org: self.org.amap(recast),
            dir: self.dir.amap(recast),
            inv_dir: self.inv_dir.amap(recast),
            t_min: recast(self.t_min),
            t_max: recast(self.t_max),
            active: recast_mask(self.active),
        }
    }

    /// Bit `i` set when lane `i` is active.
    #[inline(always)]
    pub fn active_bits(&self) -> LaneBits {
        self.active.bits()
    }

    /// Lane `i` as a scalar ray, or `None` when it is inactive.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Option<Ray> {
        if self.active_bits() & (1 << i) == 0 {
            return None;
        }
        let c = inl(
            #[inline(always)]
            |v: &[Vf<W>; 3]| Vec3::new(v[0].lane(i), v[1].lane(i), v[2].lane(i)),
        );
        Some(Ray::new(
            c(&self.org),
            c(&self.dir),
            self.t_min.lane(i),
            self.t_max.lane(i),
        ))
    }
}

/// One primitive's hits against a packet: lane `i` hit where `mask` is set (never for an
/// inactive lane); `t`, `u`, `v` are meaningful only there.
#[derive(Clone, Copy, Debug)]
pub struct LaneHits<W: Simd> {
    /// Lanes that hit.
    pub mask: Mask<W>,
    /// Hit distances.
    pub t: Vf<W>,
    /// Barycentric weight of the second vertex (0 for other primitives).
    pub u: Vf<W>,
    /// Barycentric weight of the third vertex (0 for other primitives).
    pub v: Vf<W>,
}

impl<W: Simd> LaneHits<W> {
    /// No lane hit.
    #[inline(always)]
    pub fn none() -> LaneHits<W> {
        LaneHits {
            mask: Mask::<W>::NONE,
            t: Vf::<W>::ZERO,
            u: Vf::<W>::ZERO,
            v: Vf::<W>::ZERO,
        }
    }
}

/// Closest hits of a packet, one lane per ray; a miss has `t = +inf`, `prim = NO_HIT`.
#[derive(Clone, Copy, Debug)]
pub struct HitPacket<W: Simd> {
    /// Hit distances, `+inf` for a miss.
    pub t: Vf<W>,
    /// Barycentric weight of the second vertex.
    pub u: Vf<W>,
    /// Barycentric weight of the third vertex.
    pub v: Vf<W>,
    /// Primitive ids, [`crate::ray::NO_HIT`] for a miss.
    pub prim: Vu<W>,
}

impl<W: Simd> HitPacket<W> {
    /// All lanes missed.
    #[inline(always)]
    pub fn miss() -> HitPacket<W> {
        HitPacket {
            t: Vf::<W>::splat(f32::INFINITY),
            u: Vf::<W>::ZERO,
            v: Vf::<W>::ZERO,
            prim: Vu::<W>::splat(NO_HIT),
        }
    }

    /// Keeps, in each lane where `hits` hit, the closer of the lane's hit and primitive
    /// `prim`'s, in the order of [`Hit::is_closer`] (smaller `t`, ties to the smaller id).
    /// Returns the lanes that changed.
    #[inline(always)]
    pub fn merge(&mut self, hits: &LaneHits<W>, prim: u32) -> Mask<W> {
        let prim_v = Vu::<W>::splat(prim);
        let smaller_id = self.prim.cmp_gt(prim_v);
        let closer = hits.t.cmp_lt(self.t) | (hits.t.cmp_eq(self.t) & smaller_id);
        let take = hits.mask & closer;
        self.t = Vf::<W>::select(take, hits.t, self.t);
        self.u = Vf::<W>::select(take, hits.u, self.u);
        self.v = Vf::<W>::select(take, hits.v, self.v);
        self.prim = Vu::<W>::select(take, prim_v, self.prim);
        take
    }

    /// The same hits in backend `B` of the same width: no bit changes.
    #[inline(always)]
    pub(crate) fn recast<B: Simd>(&self) -> HitPacket<B> {
        debug_assert_eq!(W::LANES, B::LANES);
        HitPacket {
            t: recast(self.t),
            u: recast(self.u),
            v: recast(self.v),
            prim: recast_u(self.prim),
        }
    }

    /// Builds a packet lane by lane (`f` is called once per lane, in lane order).
    #[inline(always)]
    pub fn from_lanes(mut f: impl FnMut(usize) -> Hit) -> HitPacket<W> {
        let mut hits = [Hit::MISS; MAX_LANES];
        for (i, h) in hits.iter_mut().enumerate().take(W::LANES) {
            *h = f(i);
        }
        HitPacket {
            t: Vf::<W>::from_fn(
                #[inline(always)]
                |i| hits[i].t,
            ),
            u: Vf::<W>::from_fn(
                #[inline(always)]
                |i| hits[i].u,
            ),
            v: Vf::<W>::from_fn(
                #[inline(always)]
                |i| hits[i].v,
            ),
            prim: Vu::<W>::from_fn(
                #[inline(always)]
                |i| hits[i].prim,
            ),
        }
    }

    /// Lanes `0..out.len()` (at most `W::LANES`) into `out`, lane `i` to `out[i]`: one
    /// transpose ([`Float::transpose4_into`]).
    #[inline(always)]
    pub fn write(&self, out: &mut [Hit]) {
        if handed_on::<W>() {
            return dispatch!(W::LANES; fn write_as::<@, W>(self, out));
        }
        let prim = Vf::<W>::from_bits(self.prim);
        Vf::<W>::transpose4_into([self.t, self.u, self.v, prim], Hit::as_records_mut(out));
    }

    /// Lane `i` as a scalar hit.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Hit {
        Hit {
            t: self.t.lane(i),
            u: self.u.lane(i),
            v: self.v.lane(i),
            prim: self.prim.lane(i),
        }
    }
}

/// True when `W` is a portable width of 8 or 16 lanes and a wider instruction set is in
/// use: the transposes that fill and empty its packets then run in that set's backend,
/// inside its entry. In a baseline build `wide` transposes 8 and 16 lanes one lane at a
/// time; AVX2 does a full packet's in a few shuffles (perf/isa.md).
#[inline(always)]
fn handed_on<W: Simd>() -> bool {
    W::ISA == Isa::Sse && W::LANES > 4 && Isa::in_use() != Isa::Sse
}

/// [`RayPacket::from_rays`] of a full packet, transposed by backend `B`.
#[inline(always)]
fn full_as<B: Simd, W: Simd>(rays: &[Ray]) -> RayPacket<W> {
    RayPacket::<B>::full(Vf::<B>::transpose8(Ray::as_records(rays))).recast()
}

/// [`RayPacket::from_halves`], transposed by backend `B`.
#[inline(always)]
fn halves_as<B: Simd, W: Simd>(lo: &[Ray], hi: &[Ray]) -> RayPacket<W> {
    RayPacket::<B>::full(Vf::<B>::transpose8_halves(
        Ray::as_records(lo),
        Ray::as_records(hi),
    ))
    .recast()
}

/// [`HitPacket::write`], transposed by backend `B`.
#[inline(always)]
fn write_as<B: Simd, W: Simd>(hits: &HitPacket<W>, out: &mut [Hit]) {
    let hits = hits.recast::<B>();
    let prim = Vf::<B>::from_bits(hits.prim);
    Vf::<B>::transpose4_into([hits.t, hits.u, hits.v, prim], Hit::as_records_mut(out));
}

/// Groups of at most this many coherent lanes of a `W` packet are traced as single
/// rays ([`trace_lanes_alone`]), by both trees' packet walks: a packet step costs about
/// the same at every occupancy, a single-ray step a fraction of it (1 of 4 lanes, 2 of
/// 8, 3 of 16; measured on the kd-tree).
pub(crate) const fn alone_max<W: Simd>() -> u32 {
    match W::LANES {
        4 => 1,
        8 => 2,
        _ => 3,
    }
}

/// Traces the lanes `bits` of `rays` one at a time through `trace(ray, hit)` (a single
/// walk that folds the closest hit into `hit`, or with `ANY_HIT` returns whether the ray
/// is occluded), and puts their answers into `best`'s lanes or `occluded`: the packet
/// walks' way out for lanes a packet step would not pay for.
#[inline(always)]
pub(crate) fn trace_lanes_alone<W: Simd, const ANY_HIT: bool>(
    rays: &RayPacket<W>,
    mut bits: LaneBits,
    best: &mut HitPacket<W>,
    occluded: &mut Mask<W>,
    mut trace: impl FnMut(&Ray, &mut Hit) -> bool,
) {
    if bits == 0 {
        return;
    }
    let mut alone = [None; MAX_LANES];
    let mut hit_bits = 0;
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if let Some(ray) = rays.lane(i) {
            let mut hit = Hit::MISS;
            if trace(&ray, &mut hit) {
                hit_bits |= 1 << i;
            }
            alone[i] = Some(hit);
        }
    }
    if ANY_HIT {
        *occluded |= Mask::<W>::from_bits(hit_bits);
    } else {
        let grouped = *best;
        *best = HitPacket::from_lanes(
            #[inline(always)]
            |i| {
                alone[i].unwrap_or_else(
                    #[inline(always)]
                    || grouped.lane(i),
                )
            },
        );
    }
}
