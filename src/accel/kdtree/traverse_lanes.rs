//! Stage: accel. The kd-tree's lane walks: one ray per SIMD lane, each lane on its own
//! walk (Wald, Benthin and Boulos 2008 call this the SPMD or "single ray per lane"
//! form; Aila and Laine 2009 run it on GPUs). Incoherent rays share no nodes, so a
//! packet's lanes cannot decide together; here they do not have to. Every iteration
//! loads each lane's node ([`Uint::gather_pairs`]: `W` independent loads in flight, so
//! the cache misses of `W` rays overlap), decides the inner-node step of every lane in
//! SIMD without a branch, and ends the steps at leaves and empty children lane by lane
//! with the scalar code (`Walk::pop`) and the leaves' triangles in lanes
//! (`KdTree::leaf_lanes_step`). A lane whose walk ends takes the
//! next ray of the stream, whose interval in the tree's box and per-axis values were
//! computed with those of its `W - 1` neighbours in the stream (`KdTree::start_block`):
//! one set of vector divisions instead of three scalar ones on each ray's critical path.
//!
//! Those `W` rays also take their first steps together (`KdTree::descend_block`): while
//! every one of them goes on to the same child, one node load and one SIMD step serve
//! them all, and each ray keeps its own interval and pushes. Neighbours in a stream
//! usually start close together (bounces off nearby points, shadow rays from them, a
//! camera's rays), and a third of a conference-room diffuse ray's steps come before
//! its block's rays part (perf/log/stream.md, "Fourteenth session").
//!
//! Invariant, so each ray's answer is the scalar path's bit for bit: a lane repeats
//! `KdTree::step` for its ray operation by operation (the band's ends at the split,
//! the near/far tests, the empty-child skips, the intervals and the pushes on the
//! lane's own stack), so it visits the scalar ray's leaves with its intervals in its
//! order (any-hit walks far child first, as the scalar step); leaves, pops and the
//! best-hit test run the scalar code itself. One exception: where the instruction set
//! has FMA the band's ends round once, not twice
//! ([`Float::mul_add_fast`]; 1.03x on the streams, perf/log/stream.md). Both stay within
//! the plane slack, so a lane may visit a cell more or fewer at a band's edge but
//! finds the same hit (`super::traverse`'s notes). A ray with a zero direction
//! component, or one so small that the step could overflow, takes the scalar walk
//! whole.

use super::KdTree;
use super::node::{LEFT_EMPTY, NodeLanes, RIGHT_EMPTY, as_words};
use super::stats::bump;
use super::traverse::{Bands, Stack, Walk};
use crate::accel::packet::RayPacket;
use crate::ray::{Hit, Ray};
use crate::simd::{
    AMap, Float, LaneBits, LaneMask, MAX_LANES, Mask, Simd, Uint, Vf, Vu, array_fn, inl, prefetch,
};

/// The lane walks (stream queries) test groups of at least this many triangles of a leaf in lanes
/// (one triangle alone is faster scalar: perf/log/stream.md).
const LEAF_LANES_MIN: u32 = 2;

/// The width of those groups: 8 lanes (16 measured slower, perf/log/stream.md: a diffuse
/// ray's leaves hold few triangles), in the walk's instruction set ([`Simd::X8`]: the
/// portable 8 lanes are two SSE registers filled lane by lane).
type LeafLanes<W> = <W as Simd>::X8;

/// Leaves of at most 4 triangles (most of those a diffuse ray meets) are tested in 4
/// lanes: loading half as many lanes' records paid 1.05x on Sponza's and the conference
/// room's diffuse streams (perf/log/stream.md).
type SmallLeafLanes<W> = <W as Simd>::X4;

/// The lanes' walk state as arrays, one entry per lane: what the SIMD step loads and
/// stores, and what the lane-by-lane code reads and writes between steps.
#[repr(C, align(64))]
struct Lanes {
    node: [u32; MAX_LANES],
    t_near: [f32; MAX_LANES],
    t_far: [f32; MAX_LANES],
    /// The lane's best `t` so far (for the skip to a far child past it).
    best_t: [f32; MAX_LANES],
    /// Per axis: `1 / d` and the offsets of the band's ends in `t` ([`Walk`]'s axes).
    inv: [[f32; MAX_LANES]; 3],
    lo_off: [[f32; MAX_LANES]; 3],
    hi_off: [[f32; MAX_LANES]; 3],
}

impl Lanes {
    #[inline(always)]
    fn new() -> Lanes {
        Lanes {
            node: [0; MAX_LANES],
            t_near: [0.0; MAX_LANES],
            t_far: [0.0; MAX_LANES],
            best_t: [f32::INFINITY; MAX_LANES],
            inv: [[0.0; MAX_LANES]; 3],
            lo_off: [[0.0; MAX_LANES]; 3],
            hi_off: [[0.0; MAX_LANES]; 3],
        }
    }

    /// Lane `i` from `walk` (after [`KdTree::start_walk`] or [`Walk::pop`]).
    #[inline(always)]
    fn load_walk(&mut self, i: usize, walk: &Walk, best: &Hit) {
        self.node[i] = walk.node;
        self.t_near[i] = walk.t_near;
        self.t_far[i] = walk.t_far;
        self.best_t[i] = best.t;
    }
}

#[inline(always)]
fn vf<W: Simd>(a: &[f32; MAX_LANES]) -> Vf<W> {
    Vf::<W>::from_fn(
        #[inline(always)]
        |i| a[i],
    )
}

#[inline(always)]
fn store_f<W: Simd>(v: Vf<W>, a: &mut [f32; MAX_LANES]) {
    for (i, x) in a.iter_mut().enumerate().take(W::LANES) {
        *x = v.lane(i);
    }
}

/// Set bits of `bits`, lowest first.
#[inline(always)]
fn lanes_of(mut bits: LaneBits) -> impl Iterator<Item = usize> {
    std::iter::from_fn(
        #[inline(always)]
        move || {
            (bits != 0).then(
                #[inline(always)]
                || {
                    let i = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    i
                },
            )
        },
    )
}

/// How a ray of the stream starts ([`Starts`]).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Begin {
    /// At the block's shared node with the interval, stack and per-axis values of
    /// [`Starts`].
    Walk,
    /// Not at all: the ray misses the tree's box or is not usable.
    Miss,
    /// Through the scalar walk, whole: a direction component is zero, or so small that
    /// `org * inv` or `split * inv` may overflow, which the fused node step
    /// ([`Float::mul_add_fast`]) would turn into a band on the wrong side.
    Scalar,
}

/// The starts of `W::LANES` consecutive rays of the stream, computed together before
/// their walks ([`KdTree::start_block`]): the scalar set-up's three divisions and box
/// clip, ray by ray, cost the bunny's short diffuse walks a tenth of their time.
struct Starts {
    /// The stream's rays `base..end` are the block's.
    base: usize,
    end: usize,
    begin: [Begin; MAX_LANES],
    t_near: [f32; MAX_LANES],
    t_far: [f32; MAX_LANES],
    inv: [[f32; MAX_LANES]; 3],
    lo_off: [[f32; MAX_LANES]; 3],
    hi_off: [[f32; MAX_LANES]; 3],
    /// Where the walking rays' shared descent ended ([`KdTree::descend_block`]), after
    /// `steps` inner steps from the root; each ray's interval above is the one it has
    /// there, and `stacks` hold what each pushed on the way.
    node: u32,
    steps: u32,
    stacks: [Stack<(u32, f32, f32)>; MAX_LANES],
}

impl Starts {
    /// No block yet.
    #[inline(always)]
    fn new() -> Starts {
        Starts {
            base: 0,
            end: 0,
            begin: [Begin::Miss; MAX_LANES],
            t_near: [0.0; MAX_LANES],
            t_far: [0.0; MAX_LANES],
            inv: [[0.0; MAX_LANES]; 3],
            lo_off: [[0.0; MAX_LANES]; 3],
            hi_off: [[0.0; MAX_LANES]; 3],
            node: 0,
            steps: 0,
            stacks: array_fn(
                #[inline(always)]
                |_| Stack::new(),
            ),
        }
    }
}

/// The scalar step's tests at one inner node per lane ([`KdTree::step`], in its
/// order): the lane walk's steps and the blocks' shared descent both decide with them.
struct PlaneTests<W: Simd> {
    /// Near is the right child (the direction is negative; never zero here).
    negative: Mask<W>,
    near_empty: Mask<W>,
    far_empty: Mask<W>,
    near_only: Mask<W>,
    far_only: Mask<W>,
    both: Mask<W>,
    /// Where the ray enters the far child, and the band's far end at the split.
    entry: Vf<W>,
    hi: Vf<W>,
}

impl<W: Simd> PlaneTests<W> {
    /// The tests at planes `split` for rays with the axis's `[inv, lo_off, hi_off]` and
    /// intervals `(t_near, t_far)`, whose left and right children are empty leaves
    /// where `empty` says so.
    #[inline(always)]
    fn new(
        split: Vf<W>,
        [inv, lo_off, hi_off]: [Vf<W>; 3],
        (t_near, t_far): (Vf<W>, Vf<W>),
        [left_empty, right_empty]: [Mask<W>; 2],
    ) -> PlaneTests<W> {
        let negative = inv.cmp_lt(Vf::<W>::ZERO);
        let (lo, hi) = (
            split.mul_add_fast(inv, lo_off),
            split.mul_add_fast(inv, hi_off),
        );
        let near_only = lo.cmp_gt(t_far);
        let far_only = !near_only & hi.cmp_lt(t_near);
        PlaneTests {
            negative,
            near_empty: (negative & right_empty) | (!negative & left_empty),
            far_empty: (negative & left_empty) | (!negative & right_empty),
            near_only,
            far_only,
            both: !near_only & !far_only,
            entry: lo.max_gt(t_near),
            hi,
        }
    }

    /// The step goes only to empty children (or to an empty near child and a far one
    /// that starts `past_best`), so it ends at the pops.
    #[inline(always)]
    fn stop(&self, past_best: Mask<W>) -> Mask<W> {
        (self.near_only & self.near_empty)
            | (self.far_only & self.far_empty)
            | (self.both & self.near_empty & (self.far_empty | past_best))
    }

    /// A step that goes on goes to the far child (else to the near one). A walk that
    /// takes the far child first (`FAR_FIRST`, any-hit walks: [`KdTree::step`]) goes
    /// there also where it pushes the near one.
    #[inline(always)]
    fn to_far<const FAR_FIRST: bool>(&self) -> Mask<W> {
        let to_far = self.far_only | (self.both & self.near_empty);
        if FAR_FIRST {
            to_far | self.pushes()
        } else {
            to_far
        }
    }

    /// The step pushes the child it does not take first.
    #[inline(always)]
    fn pushes(&self) -> Mask<W> {
        self.both & !self.near_empty & !self.far_empty
    }

    /// The intervals after the step, in the `moving` lanes.
    #[inline(always)]
    fn intervals<const FAR_FIRST: bool>(
        &self,
        moving: Mask<W>,
        (t_near, t_far): (Vf<W>, Vf<W>),
    ) -> (Vf<W>, Vf<W>) {
        let select = Vf::<W>::select;
        let far_of_both = if FAR_FIRST {
            self.both & (self.near_empty | !self.far_empty)
        } else {
            self.both & self.near_empty
        };
        (
            select(moving & far_of_both, self.entry, t_near),
            select(
                moving & self.both & !far_of_both,
                self.near_exit(t_far),
                t_far,
            ),
        )
    }

    /// Where the ray leaves the near child.
    #[inline(always)]
    fn near_exit(&self, t_far: Vf<W>) -> Vf<W> {
        self.hi.min_lt(t_far)
    }
}

/// A block's per-axis values in lanes, as [`KdTree::start_block`] computes them.
struct Axes<W: Simd> {
    inv: [Vf<W>; 3],
    lo_off: [Vf<W>; 3],
    hi_off: [Vf<W>; 3],
}

/// The walks of `W::LANES` rays, one per lane.
struct Group {
    st: Lanes,
    walks: [Walk; MAX_LANES],
    best: [Hit; MAX_LANES],
    ray_of: [usize; MAX_LANES],
    live: LaneBits,
    starts: Starts,
}

impl Group {
    /// Idle lanes, no block of starts yet.
    #[inline(always)]
    fn new() -> Group {
        Group {
            st: Lanes::new(),
            walks: array_fn(
                #[inline(always)]
                |_| Walk::new(),
            ),
            best: [Hit::MISS; MAX_LANES],
            ray_of: [0; MAX_LANES],
            live: 0,
            starts: Starts::new(),
        }
    }

    /// Lane `i` takes ray `r` at `node` with its interval `(t_near, t_far)` there and
    /// its per-axis `[inv, lo_off, hi_off]`, no hit yet (its walk's stack already set).
    #[inline(always)]
    fn begin(
        &mut self,
        i: usize,
        r: usize,
        node: u32,
        (t_near, t_far): (f32, f32),
        axes: [[f32; 3]; 3],
    ) {
        self.best[i] = Hit::MISS;
        let st = &mut self.st;
        st.node[i] = node;
        st.t_near[i] = t_near;
        st.t_far[i] = t_far;
        st.best_t[i] = Hit::MISS.t;
        let [inv, lo_off, hi_off] = axes;
        for a in 0..3 {
            st.inv[a][i] = inv[a];
            st.lo_off[a][i] = lo_off[a];
            st.hi_off[a][i] = hi_off[a];
        }
        self.ray_of[i] = r;
        self.live |= 1 << i;
    }
}

impl KdTree {
    /// Walks every ray of `rays` through the tree, `W::LANES` at a time, one ray per
    /// lane, calling `done(i, answer, best)` once per ray `i` (in no particular order)
    /// with the scalar traversal's answer and closest hit (planes not folded in). With
    /// `ANY_HIT`, a ray a plane occludes is answered without walking.
    ///
    /// `groups` (1 or 2) groups of lanes step in turn; with two, each group's next nodes
    /// are prefetched at the end of its step and load while the other group steps:
    /// twice the loads in flight, which pays in trees much larger than the cache
    /// (perf/log/stream.md, "Two groups of lanes").
    #[inline(always)]
    pub(super) fn walk_lanes<W: Simd, const ANY_HIT: bool>(
        &self,
        rays: &[Ray],
        groups: usize,
        mut done: impl FnMut(usize, bool, Hit),
    ) {
        assert!(
            (1..=2).contains(&groups),
            "walk_lanes: 1 or 2 groups, not {groups}"
        );
        let mut all = [Group::new(), Group::new()];
        let groups = &mut all[..groups];
        let mut next = 0;
        for g in groups.iter_mut() {
            for i in 0..W::LANES {
                self.start_lane::<W, ANY_HIT>(g, i, rays, &mut next, &mut done);
            }
        }
        if let [g] = groups {
            while g.live != 0 {
                self.lanes_step::<W, ANY_HIT>(g, rays, &mut next, &mut done);
            }
            return;
        }
        while groups.iter().any(
            #[inline(always)]
            |g| g.live != 0,
        ) {
            for g in groups.iter_mut().filter(
                #[inline(always)]
                |g| g.live != 0,
            ) {
                self.lanes_step::<W, ANY_HIT>(g, rays, &mut next, &mut done);
                for i in lanes_of(g.live) {
                    prefetch(&self.nodes[g.st.node[i] as usize]);
                }
            }
        }
    }

    /// Starts the next ray of `rays` from `*next` on that needs a walk in lane `i` of
    /// `g`, answering the others at once; the lane goes idle when none is left.
    #[inline(always)]
    fn start_lane<W: Simd, const ANY_HIT: bool>(
        &self,
        g: &mut Group,
        i: usize,
        rays: &[Ray],
        next: &mut usize,
        done: &mut impl FnMut(usize, bool, Hit),
    ) {
        g.live &= !(1 << i);
        g.st.node[i] = 0;
        while *next < rays.len() {
            let r = *next;
            *next += 1;
            let ray = &rays[r];
            if ANY_HIT && self.prims.planes_occlude(ray) {
                done(r, true, Hit::MISS);
                continue;
            }
            if !(g.starts.base..g.starts.end).contains(&r) {
                self.start_block::<W, ANY_HIT>(&mut g.starts, rays, r);
            }
            let (s, k) = (&g.starts, r - g.starts.base);
            match s.begin[k] {
                Begin::Miss => done(r, false, Hit::MISS),
                Begin::Walk => {
                    g.walks[i].stack.copy_from(&s.stacks[k]);
                    let axes = [&s.inv, &s.lo_off, &s.hi_off].amap(
                        #[inline(always)]
                        |v| {
                            [0, 1, 2].amap(
                                #[inline(always)]
                                |a| v[a][k],
                            )
                        },
                    );
                    g.begin(i, r, s.node, (s.t_near[k], s.t_far[k]), axes);
                    return;
                }
                Begin::Scalar => {
                    let mut hit = Hit::MISS;
                    let answer = self.traverse::<ANY_HIT>(ray, &mut hit);
                    done(r, answer, hit);
                }
            }
        }
    }

    /// The starts of the rays of `rays` from `first` on, `W::LANES` of them, into `s`:
    /// [`KdTree::start_walk`]'s interval and per-axis values in lanes, the same
    /// operations in the same order ([`KdTree::start_packet`]), so each
    /// lane that starts a walk starts it as the scalar set-up does; then the walking
    /// rays' shared descent ([`KdTree::descend_block`]).
    /// Out of line (a block starts once per `W::LANES` rays), compiled for `W`'s
    /// instruction set ([`Simd::enter`]).
    #[inline(always)]
    fn start_block<W: Simd, const ANY_HIT: bool>(
        &self,
        s: &mut Starts,
        rays: &[Ray],
        first: usize,
    ) {
        W::enter(
            #[inline(always)]
            || self.start_block_in::<W, ANY_HIT>(s, rays, first),
        )
    }

    /// [`KdTree::start_block`]'s body.
    #[inline(always)]
    fn start_block_in<W: Simd, const ANY_HIT: bool>(
        &self,
        s: &mut Starts,
        rays: &[Ray],
        first: usize,
    ) {
        let block = &rays[first..rays.len().min(first + W::LANES)];
        let p = RayPacket::<W>::from_rays(block);
        let (bands, (reach, t_near, t_far)) = self.start_packet(&p, p.active);
        let Bands { lo_off, hi_off, .. } = bands;
        // Rays with a zero component, or whose `org * inv` or `split * inv` could
        // overflow, take the scalar walk: fused, `split * inv + (-inf)` would be `-inf`
        // where the plane lies ahead (rounded twice, it is NaN and visits both children).
        let scalar = self.scalar_lanes(bands.reach, &p.inv_dir);
        let scalar = scalar & p.active & p.usable();
        let walk = reach & !scalar;
        (s.base, s.end) = (first, first + block.len());
        for k in 0..block.len() {
            s.begin[k] = if scalar.bits() >> k & 1 != 0 {
                Begin::Scalar
            } else if walk.bits() >> k & 1 != 0 {
                Begin::Walk
            } else {
                Begin::Miss
            };
        }
        for a in 0..3 {
            store_f::<W>(p.inv_dir[a], &mut s.inv[a]);
            store_f::<W>(lo_off[a], &mut s.lo_off[a]);
            store_f::<W>(hi_off[a], &mut s.hi_off[a]);
        }
        let axes = Axes {
            inv: p.inv_dir,
            lo_off,
            hi_off,
        };
        self.descend_block::<W, ANY_HIT>(s, walk, (t_near, t_far), &axes);
    }

    /// The first steps of the rays in `walk`, taken together from the root while every
    /// one of them goes on to the same child: one node load per step for all of them,
    /// the split axis the same in every lane. Each lane repeats [`KdTree::step`]'s
    /// operations as [`KdTree::lanes_step`] does (the band's ends, the near/far tests,
    /// the skips of empty children, the intervals, the pushes onto the ray's own
    /// stack), so a ray starts its walk where its scalar walk is after as many steps,
    /// with the same interval and stack. The descent ends before the first leaf, the
    /// first step on which the rays part, and the first step that ends at the pops (a
    /// ray going only to empty children); `(t_near, t_far)` are the rays' intervals at
    /// the root, and `s` gets them at the shared node.
    /// Out of line, compiled for `W`'s instruction set ([`Simd::enter`]).
    #[inline(always)]
    fn descend_block<W: Simd, const ANY_HIT: bool>(
        &self,
        s: &mut Starts,
        walk: Mask<W>,
        interval: (Vf<W>, Vf<W>),
        axes: &Axes<W>,
    ) {
        W::enter(
            #[inline(always)]
            || self.descend_block_in::<W, ANY_HIT>(s, walk, interval, axes),
        )
    }

    /// [`KdTree::descend_block`]'s body.
    #[inline(always)]
    fn descend_block_in<W: Simd, const ANY_HIT: bool>(
        &self,
        s: &mut Starts,
        walk: Mask<W>,
        (mut t_near, mut t_far): (Vf<W>, Vf<W>),
        axes: &Axes<W>,
    ) {
        let every = inl(
            #[inline(always)]
            |on: bool| Mask::<W>::from_bits(if on { W::all_bits() } else { 0 }),
        );
        let all = walk.bits();
        for stack in &mut s.stacks[..W::LANES] {
            stack.clear();
        }
        let (mut node, mut steps) = (0u32, 0u32);
        while all != 0 && !self.nodes[node as usize].is_leaf() {
            let n = self.nodes[node as usize];
            let a = n.axis().min(2);
            let empty = n.empty_children();
            let p = PlaneTests::<W>::new(
                Vf::<W>::splat(n.split),
                [axes.inv[a], axes.lo_off[a], axes.hi_off[a]],
                (t_near, t_far),
                [
                    every(empty & LEFT_EMPTY != 0),
                    every(empty & RIGHT_EMPTY != 0),
                ],
            );
            // No hit yet, so no far child lies past the best one.
            let stop = p.stop(Mask::<W>::NONE);
            let to_far = p.to_far::<ANY_HIT>();
            let right = ((to_far & !p.negative) | (!to_far & p.negative)).bits() & all;
            if stop.bits() & all != 0 || (right != 0 && right != all) {
                break;
            }
            let child = inl(
                #[inline(always)]
                |i: usize, far: bool| {
                    n.children() + ((p.negative.bits() >> i & 1 == 0) == far) as u32
                },
            );
            for i in lanes_of((walk & p.pushes()).bits()) {
                s.stacks[i].push(if ANY_HIT {
                    (child(i, false), t_near.lane(i), p.near_exit(t_far).lane(i))
                } else {
                    (child(i, true), p.entry.lane(i), t_far.lane(i))
                });
            }
            (t_near, t_far) = p.intervals::<ANY_HIT>(walk, (t_near, t_far));
            node = n.children() + (right != 0) as u32;
            steps += 1;
            bump(
                #[inline(always)]
                |c| c.node_steps += all.count_ones() as u64,
            );
        }
        (s.node, s.steps) = (node, steps);
        store_f::<W>(t_near, &mut s.t_near);
        store_f::<W>(t_far, &mut s.t_far);
    }

    /// One iteration: every live lane's node loaded, the inner steps decided in SIMD,
    /// then leaves and stopped steps ended lane by lane and finished lanes restarted.
    #[inline(always)]
    fn lanes_step<W: Simd, const ANY_HIT: bool>(
        &self,
        g: &mut Group,
        rays: &[Ray],
        next: &mut usize,
        done: &mut impl FnMut(usize, bool, Hit),
    ) {
        let words = as_words(&self.nodes);
        let select = Vf::<W>::select;
        let one = Vu::<W>::splat(1);
        let st = &mut g.st;
        // Idle lanes sit at the root, a valid index.
        let node = Vu::<W>::from_fn(
            #[inline(always)]
            |i| st.node[i],
        );
        let (split, bits) = Vu::<W>::gather_pairs(words, &st.node);
        let split = Vf::<W>::from_bits(split);
        let n = NodeLanes::<W>::decode(bits);
        let live_m = Mask::<W>::from_bits(g.live);
        let inner = live_m & !n.leaf;
        let pick = inl(
            #[inline(always)]
            |v: &[[f32; MAX_LANES]; 3]| {
                select(
                    n.axis[0],
                    vf::<W>(&v[0]),
                    select(n.axis[1], vf::<W>(&v[1]), vf::<W>(&v[2])),
                )
            },
        );
        let (inv, lo_off, hi_off) = (pick(&st.inv), pick(&st.lo_off), pick(&st.hi_off));
        let (t_near, t_far) = (vf::<W>(&st.t_near), vf::<W>(&st.t_far));
        let p = PlaneTests::<W>::new(split, [inv, lo_off, hi_off], (t_near, t_far), n.empty);
        let right = n.children + one;
        let near = Vu::<W>::select(p.negative, right, n.children);
        let far = Vu::<W>::select(p.negative, n.children, right);
        let entry = p.entry;
        let past_best = if ANY_HIT {
            Mask::<W>::NONE
        } else {
            entry.cmp_gt(vf::<W>(&st.best_t))
        };
        // Lanes whose step goes only to empty children end it at the pops.
        let stop = inner & p.stop(past_best);
        let push = (inner & p.pushes()).bits();
        let moving = inner & !stop;
        let next_node = Vu::<W>::select(
            moving & p.to_far::<ANY_HIT>(),
            far,
            Vu::<W>::select(moving, near, node),
        );
        let (new_near, new_far) = p.intervals::<ANY_HIT>(moving, (t_near, t_far));
        bump(
            #[inline(always)]
            |c| c.node_steps += inner.bits().count_ones() as u64,
        );
        let near_exit = p.near_exit(t_far);
        for i in lanes_of(push) {
            g.walks[i].stack.push(if ANY_HIT {
                (near.lane(i), t_near.lane(i), near_exit.lane(i))
            } else {
                (far.lane(i), entry.lane(i), t_far.lane(i))
            });
        }
        for (i, x) in st.node.iter_mut().enumerate().take(W::LANES) {
            *x = next_node.lane(i);
        }
        store_f::<W>(new_near, &mut st.t_near);
        store_f::<W>(new_far, &mut st.t_far);
        // Steps that went only to empty children pop at once; then the leaves, lane by
        // lane with the scalar code, and their pops (two loops, so neither branches on
        // which kind of lane it holds).
        for i in lanes_of(stop.bits()) {
            self.pop_lane::<W, ANY_HIT>(g, i, rays, next, done);
        }
        for i in lanes_of((live_m & n.leaf).bits()) {
            let here = self.nodes[g.st.node[i] as usize];
            let ray = &rays[g.ray_of[i]];
            if let Some(answer) = self.leaf_lanes_step::<ANY_HIT, W>(&here, ray, &mut g.best[i]) {
                done(g.ray_of[i], answer, g.best[i]);
                self.start_lane::<W, ANY_HIT>(g, i, rays, next, done);
            } else {
                self.pop_lane::<W, ANY_HIT>(g, i, rays, next, done);
            }
        }
    }

    /// Lane `i` goes on at the next node its stack holds ([`Walk::pop`]); when none is
    /// left its ray is done (no any-hit found) and the lane takes the next ray.
    #[inline(always)]
    fn pop_lane<W: Simd, const ANY_HIT: bool>(
        &self,
        g: &mut Group,
        i: usize,
        rays: &[Ray],
        next: &mut usize,
        done: &mut impl FnMut(usize, bool, Hit),
    ) {
        let walk = &mut g.walks[i];
        if walk.pop::<ANY_HIT>(&g.best[i]) {
            g.st.load_walk(i, walk, &g.best[i]);
        } else {
            done(g.ray_of[i], false, g.best[i]);
            self.start_lane::<W, ANY_HIT>(g, i, rays, next, done);
        }
    }
}

impl KdTree {
    /// [`KdTree::leaf_step`] for the lane walks: the leaf's triangles tested in lanes
    /// (perf/log/stream.md), for closest and any hits, at the 4- and 8-lane backends of
    /// the walk's `W`; a leaf of one triangle, and groups holding other primitives, one
    /// by one.
    #[inline(always)]
    fn leaf_lanes_step<const ANY_HIT: bool, W: Simd>(
        &self,
        n: &super::node::KdNode,
        ray: &Ray,
        best: &mut Hit,
    ) -> Option<bool> {
        let prims = self.visit_leaf(n)?;
        let count = prims.len() as u32;
        // In a scene of triangles alone no leaf needs its slots checked (a loop whose
        // exit, at the leaf's size, the branch predictor misses: 1.03x on the bunny).
        let tris_only = self.prims.triangles_only();
        let all_tris = inl(
            #[inline(always)]
            |g: &[u32]| tris_only || g.iter().all(|&p| p < self.prims.sphere_base),
        );
        // The `stats` feature's count of primitive tests.
        let count_tests = inl(
            #[inline(always)]
            |g: &[u32]| bump(|c| c.prim_tests += g.len() as u64),
        );
        if (LEAF_LANES_MIN..=SmallLeafLanes::<W>::LANES as u32).contains(&count) && all_tris(prims)
        {
            count_tests(prims);
            if self
                .prims
                .tris_lanes::<SmallLeafLanes<W>, ANY_HIT>(prims, ray, best)
            {
                return Some(true);
            }
        } else if count >= LEAF_LANES_MIN {
            for group in prims.chunks(LeafLanes::<W>::LANES) {
                let hit = if group.len() as u32 >= LEAF_LANES_MIN && all_tris(group) {
                    count_tests(group);
                    self.prims
                        .tris_lanes::<LeafLanes<W>, ANY_HIT>(group, ray, best)
                } else {
                    self.one_by_one::<ANY_HIT>(group, ray, best)
                };
                if hit {
                    return Some(true);
                }
            }
        } else if self.one_by_one::<ANY_HIT>(prims, ray, best) {
            return Some(true);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generate::{Rng, random_soup};
    use crate::simd::{W4, W8, W16};
    use glam::Vec3;

    /// Random rays from inside and around the box, rays on its faces and corners,
    /// axis-parallel rays with signed zeros, subnormal and tiny direction components,
    /// unusable rays and cut intervals.
    fn rays(b: &crate::geom::Aabb, rng: &mut Rng) -> Vec<Ray> {
        let (lo, hi) = (b.min - b.extent(), b.max + b.extent());
        let mut out = Vec::new();
        for i in 0..400 {
            let o = rng.point(lo, hi);
            let mut d = rng.unit_vector();
            match i % 8 {
                1 => d[i % 3] = 0.0,
                2 => d[i % 3] = -0.0,
                3 => d[i % 3] = if i % 16 < 8 { 1e-40 } else { -1e-40 },
                4 => d[i % 3] = f32::MIN_POSITIVE,
                _ => {}
            }
            let o = match i % 5 {
                1 => b.min,
                2 => b.max,
                3 => Vec3::new(b.min.x, o.y, o.z),
                _ => o,
            };
            let t_min = if i % 7 == 3 { 0.5 } else { 0.0 };
            let t_max = if i % 6 == 5 { 1.0 } else { f32::INFINITY };
            out.push(Ray::new(o, d, t_min, t_max));
        }
        out.push(Ray::new(Vec3::splat(f32::NAN), Vec3::X, 0.0, 1.0));
        out.push(Ray::new(b.min, Vec3::ZERO, 0.0, 1.0));
        out.push(Ray::new(b.min, Vec3::X, 2.0, 1.0));
        out
    }

    /// Rays that start together, as a stream's neighbours do: blocks from one point
    /// (inside the box, on its corner, outside it) in every direction, and blocks from
    /// nearby points in nearby directions, some of them axis-parallel with signed zeros.
    fn neighbours(b: &crate::geom::Aabb, rng: &mut Rng) -> Vec<Ray> {
        let mut out = Vec::new();
        for (j, o) in [
            (b.min + b.max) * 0.5,
            b.min,
            b.max + b.extent(),
            rng.point(b.min, b.max),
        ]
        .into_iter()
        .enumerate()
        {
            for i in 0..48 {
                let mut d = rng.unit_vector();
                if i % 7 == 3 {
                    d[j % 3] = if i % 2 == 0 { 0.0 } else { -0.0 };
                }
                out.push(Ray::new(o, d, 0.0, f32::INFINITY));
            }
            let d0 = rng.unit_vector();
            for _ in 0..48 {
                let o = o + (rng.unit_vector() * 1e-3 * b.extent().length());
                let d = (d0 + rng.unit_vector() * 0.05).normalize();
                out.push(Ray::new(o, d, 0.0, f32::INFINITY));
            }
        }
        out
    }

    /// [`KdTree::start_block`] sets up every ray as [`KdTree::start_walk`] does, bit for
    /// bit (closest-hit and any-hit walks, which order the children differently), and
    /// sends to the scalar walk exactly the rays with a direction component whose
    /// inverse may overflow the node step; a walking ray starts at the block's
    /// shared node with the interval and stack its scalar walk has after as many steps.
    #[inline(always)]
    fn blocks_match_scalar<W: Simd, const ANY_HIT: bool>() {
        let g = random_soup(500, 0.2, 11);
        let tree = KdTree::build(&g);
        let mut rng = Rng::new(W::LANES as u64);
        let mut rays = rays(&tree.bounds, &mut rng);
        rays.extend(neighbours(&tree.bounds, &mut rng));
        let mut s = Starts::new();
        let (mut walks, mut scalar, mut shared) = (0, 0, 0);
        for first in (0..rays.len()).step_by(W::LANES - 1) {
            tree.start_block::<W, ANY_HIT>(&mut s, &rays, first);
            for (k, ray) in rays[s.base..s.end].iter().enumerate() {
                let mut w = Walk::new();
                let reaches = tree.start_walk(ray, &mut w);
                let reach = Vec3::splat(super::super::traverse::box_coord_max(&tree.bounds))
                    + Vec3::splat(crate::accel::triaccel::max_abs(ray.org));
                let odd =
                    ray.is_usable() && !(reach * (Vec3::ONE / ray.dir).abs() * 2.0).is_finite();
                let what = format!("{} lanes, ray {} {ray:?}", W::LANES, s.base + k);
                match s.begin[k] {
                    Begin::Scalar => {
                        assert!(odd, "{what}: scalar set-up");
                        scalar += 1;
                    }
                    Begin::Miss => assert!(!reaches && !odd, "{what}: missed"),
                    Begin::Walk => {
                        assert!(reaches && !odd, "{what}: walked");
                        for _ in 0..s.steps {
                            let at = tree.nodes[w.node as usize];
                            assert!(!at.is_leaf(), "{what}: shared steps end before a leaf");
                            let mut best = Hit::MISS;
                            assert_eq!(tree.step::<ANY_HIT>(&mut w, ray, &mut best), None);
                        }
                        shared += s.steps;
                        assert_eq!(w.node, s.node, "{what}: node after {} steps", s.steps);
                        let entry = |&(n, a, b): &(u32, f32, f32)| (n, a.to_bits(), b.to_bits());
                        assert_eq!(
                            s.stacks[k].as_slice().iter().map(entry).collect::<Vec<_>>(),
                            w.stack.as_slice().iter().map(entry).collect::<Vec<_>>(),
                            "{what}: stack after {} steps",
                            s.steps
                        );
                        let bits = |v: [f32; 3]| v.map(f32::to_bits);
                        let col = |a: &[[f32; MAX_LANES]; 3]| [a[0][k], a[1][k], a[2][k]];
                        assert_eq!(
                            (s.t_near[k].to_bits(), s.t_far[k].to_bits()),
                            (w.t_near.to_bits(), w.t_far.to_bits()),
                            "{what}: interval"
                        );
                        assert_eq!(
                            bits(col(&s.inv)),
                            bits(w.axes.inv[..3].try_into().unwrap()),
                            "{what}"
                        );
                        assert_eq!(
                            bits(col(&s.lo_off)),
                            bits(w.axes.lo_off[..3].try_into().unwrap()),
                            "{what}"
                        );
                        assert_eq!(
                            bits(col(&s.hi_off)),
                            bits(w.axes.hi_off[..3].try_into().unwrap()),
                            "{what}"
                        );
                        walks += 1;
                    }
                }
            }
        }
        assert!(
            walks > 100 && scalar > 50 && shared > 200,
            "{walks} walks, {scalar} scalar set-ups, {shared} shared steps"
        );
    }

    #[test]
    fn blocks_match_scalar_at_every_width() {
        blocks_match_scalar::<W4, false>();
        blocks_match_scalar::<W8, false>();
        blocks_match_scalar::<W16, false>();
        blocks_match_scalar::<W4, true>();
        blocks_match_scalar::<W8, true>();
        blocks_match_scalar::<W16, true>();
    }
}
